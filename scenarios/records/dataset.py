"""The one reader of a measured record (``NAME.toml`` + ``NAME.csv``), every version of
the measured-data contract (``docs/measured-data.md``).

A record is a CSV of samples -- ``time_s``, ``growth_um``, ``q_W_m2`` or ``speed_rpm``,
optionally ``ambient_C`` and ``T_<name>_C`` (versions 1-2, on the rod); or ``d_<sensor>_um``,
``T_<sensor>_C``, ``P_<source>_W``, ``speed_rpm``, ``ambient_C`` (version 3, a
``[model]`` table naming a mesh scenario) -- and a TOML beside it with the tables
``[dataset]``, ``[rod]``, ``[model]``, ``[columns]`` and ``[sensors.*]``.

Reading is in two steps, each done once per command and passed along:
:func:`read_record_doc` (the TOML, checked, the CSV's place confined to the TOML's
folder, a v3 record's scenario read) and :func:`read_record_columns` (the CSV through
:func:`arfem.io.read_csv_table`: size, rows, NUL, duplicate columns, numbers; then
every contract column finite and within its physical range, :mod:`arfem.ranges`).
:func:`load_dataset` turns a record into the rod's validated, immutable
:class:`~arfem.models.diagnosis.dataset.Dataset`; :func:`arfem.scenarios.records.georecord.read_mesh_record`
into a v3 record. A refusal is one :class:`arfem.params.InputError` naming the file,
the CSV line or the column/key, and what is wrong.

Data flow: file -> ``Dataset`` (this module) -> models. Nothing here fits or
simulates; the only processing is what the contract prescribes (drop <= 5 % rows with
an empty ``time_s``/``growth_um``, fill short ``ambient_C`` gaps) plus robust flags
that the models may use (growth outliers, sampling gaps), each reported in ``notes``.
A cell outside its physical range refuses the record (the live loop, which cannot
refuse a machine, holds such a reading instead).

``[dataset] initial`` may be ``"equilibrium"`` (the default: at t = 0 the rod is in
equilibrium with the nominal ambient) or ``"unknown"``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING
from pathlib import Path

import numpy as np

from arfem.io import CsvTable, TomlFile, read_csv_table, read_toml_file
from arfem.limits import Limits, resolve
from arfem.ranges import check_range, first_outside, reading_quantity

if TYPE_CHECKING:
    from arfem.models.diagnosis.dataset import Dataset
from arfem.strict import check_keys
# the rod's Dataset and its robust flags (arfem.models.diagnosis.dataset, .stats) are
# imported where a Dataset is built: they load scipy.stats (~1 s), which a replay of a
# mesh record never needs
from arfem.params import InputError, Rod

__all__ = ["load_dataset", "ROD_KEYS", "MAX_MISSING_FRACTION", "MAX_ROWS", "MAX_CSV_BYTES",
           "RecordDoc", "read_record_doc", "RecordColumns", "read_record_columns",
           "record_toml_of", "check_columns", "drop_missing_rows", "check_time_steps_s",
           "ambient_filled_C", "input_complete"]

#: ``[rod]`` keys of the contract (a subset of :class:`arfem.params.Rod`'s fields).
ROD_KEYS = ("radius_m", "length_m", "conductivity_W_mK", "density_kg_m3",
            "specific_heat_J_kgK", "expansion_1_K", "convection_W_m2K", "ambient_C")
#: Rows with an empty ``time_s``/``growth_um`` are dropped up to this fraction, refused above.
MAX_MISSING_FRACTION = 0.05
#: Largest record read without ``--allow-large`` (28 h at 1 s, 12 days at 10 s; the
#: shipped record has 11 115 rows); the CSV's lines are counted before it is parsed.
#: Measured: 20 000 rows diagnose in 93 s, 200 000 in 652 s (256 MB peak) on a shared
#: 2-core machine, so this keeps a run to minutes.
MAX_ROWS = 100_000
#: Largest record CSV read without ``--allow-large`` [bytes]: MAX_ROWS rows of ~600
#: characters; checked from the file's size before it is read.
MAX_CSV_BYTES = 64 * 1024 ** 2

#: ``model``: a contract-v3 record's (the mesh scenario it belongs to); the rod's
#: diagnosis refuses such a record (:func:`arfem.scenarios.records.georecord.refuse_mesh_record`)
_TOP_TABLES = ("dataset", "rod", "columns", "sensors", "model")
_DATASET_KEYS = ("name", "csv", "initial", "displacement_zero")
#: ``[dataset] displacement_zero`` of a v3 record: where the displacement (and tilt)
#: channels are read from: the stress-free reference state (the default), or the first
#: row (probes zeroed at the start of the test, as ISO 230-3 does)
DISPLACEMENT_ZERO = ("reference", "first_row")
_INITIAL_VALUES = ("equilibrium", "unknown")
_SENSOR_KEYS = ("description",)
_BASE_COLUMNS = ("time_s", "growth_um", "q_W_m2", "speed_rpm", "ambient_C")
_TEMP_RE = re.compile(r"^T_.+_C$")
#: the v3 contract's own columns: a displacement sensor, a source's power
_MESH_RE = re.compile(r"^(?:d_.+_um|tilt_.+_urad|P_.+_W)$")


def _fail(message: str, where: str):
    raise InputError(message, where)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def is_contract_column(name: str) -> bool:
    """True for a column name of the contract (any version)."""
    return name in _BASE_COLUMNS or bool(_TEMP_RE.match(name) or _MESH_RE.match(name))


@dataclass(frozen=True)
class RecordDoc:
    """A record's TOML, read and checked once (:func:`read_record_doc`).

    Attributes
    ----------
    toml : TomlFile
    name : str
    csv_path : Path, the CSV (inside the TOML's folder unless the user allowed otherwise)
    initial_unknown : bool
    rod : Rod, the ``[rod]`` table (the paper's rod where absent)
    mapping : dict, contract name -> the CSV's column name (``[columns]``)
    sensors : dict, column -> description (``[sensors.*]``)
    scenario : Path or None, the mesh scenario of a v3 record (``[model]``)
    scenario_toml : TomlFile or None, that scenario read (once)
    displacement_zero : {"reference", "first_row"}, what the displacement channels are
        measured from (:data:`DISPLACEMENT_ZERO`; a v3 record's key)
    """

    toml: TomlFile
    name: str
    csv_path: Path
    initial_unknown: bool
    rod: Rod
    mapping: dict
    sensors: dict
    scenario: Path | None = None
    scenario_toml: TomlFile | None = None
    displacement_zero: str = "reference"

    @property
    def path(self) -> Path:
        return self.toml.path

    @property
    def is_mesh(self) -> bool:
        """A contract-v3 record (its TOML names a mesh scenario)."""
        return self.scenario is not None


def record_toml_of(path) -> Path:
    """The record's TOML: ``path`` itself, or the ``.toml`` beside a ``.csv``."""
    p = Path(path)
    return p.with_suffix(".toml") if p.suffix == ".csv" else p


def read_record_doc(path, limits: Limits | None = None,
                    toml: TomlFile | None = None) -> RecordDoc:
    """Read and check a record's TOML (any contract version), once.

    ``path`` is the TOML (or the CSV beside it); ``toml`` an already read copy. A v3
    record's scenario (``[model] scenario``) is read here too, and must be a mesh
    scenario. A ``[dataset] csv`` outside the TOML's folder (an absolute path, ``..``,
    a symbolic link out) is refused before anything of it is read, unless
    ``limits.csv_outside`` (``--allow-csv-outside``).
    """
    p = record_toml_of(path)
    limits = resolve(limits)
    toml = read_toml_file(p, limits) if toml is None else toml
    return _parse_meta(p, toml, limits)


def _parse_meta(path: Path, toml: TomlFile, limits: Limits) -> RecordDoc:
    """Validate the TOML's tables into a :class:`RecordDoc`."""
    where, doc = str(path), toml.data
    try:
        check_keys(doc, _TOP_TABLES, "")
    except InputError as e:
        raise e.at(where) from None
    for key in doc:
        if not isinstance(doc[key], dict):
            _fail(f"must be a table, got {type(doc[key]).__name__}", f"{where}: {key}")
    ds = doc.get("dataset", {})
    check_keys(ds, _DATASET_KEYS, f"{where}: dataset")
    name = ds.get("name", path.stem)
    if not isinstance(name, str) or not name.strip():
        _fail(f"must be a non-empty string, got {name!r}", f"{where}: dataset.name")
    csv_name = ds.get("csv", path.stem + ".csv")
    if not isinstance(csv_name, str) or not csv_name.strip():
        _fail(f"must be a non-empty string, got {csv_name!r}", f"{where}: dataset.csv")
    initial = ds.get("initial", "equilibrium")
    if initial not in _INITIAL_VALUES:
        _fail(f"must be one of {', '.join(repr(v) for v in _INITIAL_VALUES)}, got {initial!r}",
              f"{where}: dataset.initial")
    rod = _rod_table(doc.get("rod", {}), where)
    mapping = _columns_table(doc.get("columns", {}), where)
    sensors = _sensors_table(doc.get("sensors", {}), where)
    csv_path = path.parent / csv_name
    if not _inside(csv_path, path.parent) and not limits.csv_outside:
        _fail(f"{csv_name!r} is outside the dataset's folder; arfem reads only files beside "
              "the TOML (pass --allow-csv-outside to read it anyway)", f"{where}: dataset.csv")
    scenario, sc_toml = _model_table(doc, path, limits)
    zero = displacement_zero(ds, f"{where}: dataset.displacement_zero")
    if zero != "reference" and scenario is None:
        _fail("applies to a record of a mesh scenario's displacement channels ([model]); "
              "a record on the rod reads growth_um from the reference state",
              f"{where}: dataset.displacement_zero")
    return RecordDoc(toml, name, csv_path, initial == "unknown", rod, mapping, sensors,
                     scenario, sc_toml, zero)


def displacement_zero(ds: dict, where: str) -> str:
    """The record's ``displacement_zero`` (:data:`DISPLACEMENT_ZERO`; default
    ``"reference"``), or one line naming ``where``."""
    v = ds.get("displacement_zero", "reference")
    if not isinstance(v, str) or v not in DISPLACEMENT_ZERO:
        raise InputError(f"must be \"reference\" (read from the stress-free state) or "
                         f"\"first_row\" (probes zeroed at the start), got {v!r}", where)
    return v


def _rod_table(rod_doc: dict, where: str) -> Rod:
    """``[rod]``: each key a number of the contract, plausible (:mod:`arfem.ranges`)."""
    check_keys(rod_doc, ROD_KEYS, f"{where}: rod")
    for key, value in rod_doc.items():
        if not _is_number(value):
            _fail(f"must be a number, got {value!r}", f"{where}: rod.{key}")
    try:
        rod = Rod(**rod_doc)
    except InputError as e:
        raise e.in_table("rod").at(where) from None
    for key, value in rod_doc.items():       # physical, so now: in the right unit?
        check_range(key, float(value), f"{where}: rod.{key}")
    return rod


def _columns_table(columns: dict, where: str) -> dict:
    """``[columns]``: contract name -> the CSV's column name, each used once."""
    seen: dict[str, str] = {}
    for key, value in columns.items():
        if not is_contract_column(key):
            _fail("is not a contract column name (time_s, growth_um, q_W_m2, speed_rpm, "
                  "ambient_C, T_<name>_C; a mesh record's d_<sensor>_um, tilt_<sensor>_urad, P_<source>_W)",
                  f"{where}: columns.{key}")
        if not isinstance(value, str) or not value:
            _fail(f"must be a column name (string), got {value!r}", f"{where}: columns.{key}")
        if value in seen:
            _fail(f"maps to {value!r}, which columns.{seen[value]} already maps to",
                  f"{where}: columns.{key}")
        seen[value] = key
    return dict(columns)


def _sensors_table(table_doc: dict, where: str) -> dict:
    """``[sensors.<column>]``: column -> description."""
    sensors: dict[str, str] = {}
    for key, table in table_doc.items():
        if not isinstance(table, dict):
            _fail("must be a table [sensors.<column>]", f"{where}: sensors.{key}")
        check_keys(table, _SENSOR_KEYS, f"{where}: sensors.{key}")
        for k, v in table.items():
            if not isinstance(v, str):
                _fail(f"must be a string, got {v!r}", f"{where}: sensors.{key}.{k}")
        sensors[key] = table.get("description", "")
    return sensors


def _model_table(doc: dict, path: Path, limits: Limits):
    """A v3 record's ``[model]``: (the scenario's path, the scenario read), or (None,
    None) without ``[model]``. The scenario must exist, beside or below nothing in
    particular (it is the user's model, not data), and be a mesh scenario."""
    if "model" not in doc:
        return None, None
    where = str(path)
    m = doc["model"]
    check_keys(m, ("scenario",), f"{where}: model")
    if "scenario" not in m:
        _fail('needs scenario = "<mesh scenario>.toml"', f"{where}: model")
    if not isinstance(m["scenario"], str) or not m["scenario"].strip():
        _fail("must be a file name", f"{where}: model.scenario")
    if "rod" in doc:
        _fail("a record with [model] takes its materials from the mesh scenario; "
              "[rod] belongs to a record on the rod", f"{where}: rod")
    sc = path.parent / m["scenario"]
    if not sc.is_file():
        _fail(f"scenario file {sc} not found", f"{where}: model.scenario")
    sc_toml = read_toml_file(sc, limits)
    if not sc_toml.has_table("geometry"):    # a rod scenario: say so, not "rod: unknown key"
        _fail(f"{sc} has no [geometry] table: a record with [model] is checked against a "
              "mesh scenario (a rod record has no [model] table)", f"{where}: model.scenario")
    return sc, sc_toml


def _inside(p: Path, folder: Path) -> bool:
    """True if ``p`` (symbolic links resolved) lies within ``folder``."""
    try:
        p.resolve().relative_to(folder.resolve())
        return True
    except (ValueError, OSError, RuntimeError):
        return False


@dataclass(frozen=True)
class RecordColumns:
    """A record's CSV read once and mapped onto the contract's names
    (:func:`read_record_columns`).

    Attributes
    ----------
    values : dict, contract name -> float ndarray (NaN for an empty cell), each cell
        finite and within its physical range
    extra : dict, every other CSV column -> its raw cells (object ndarray)
    lines : ndarray of int, the CSV line of each row
    csv_path : Path
    header : dict, contract name -> the CSV's column name
    """

    values: dict
    extra: dict
    lines: np.ndarray
    csv_path: Path
    header: dict

    def label(self, key: str) -> str:
        """How a message names column ``key``: ``'growth_um' ('ch1(um)')`` where the CSV
        calls it otherwise."""
        foreign = self.header.get(key, key)
        return f"{key!r}" if foreign == key else f"{key!r} ({foreign!r})"


def read_record_columns(doc: RecordDoc, limits: Limits | None = None) -> RecordColumns:
    """Read the record's CSV once (:func:`arfem.io.read_csv_table`, with the record's
    size and row limits unless ``limits.large``), map its columns onto the contract's
    names, and check every cell of each contract column against its physical range
    (:func:`check_columns`)."""
    limits = resolve(limits)
    mapping = doc.mapping
    foreign = set(mapping.values())

    def numeric(h: str) -> bool:
        return h in foreign or (h not in mapping and is_contract_column(h))

    back = {v: k for k, v in mapping.items()}

    def label(h: str) -> str:
        key = back.get(h, h)
        return f"{key!r}" if key == h else f"{key!r} ({h!r})"
    table = read_csv_table(doc.csv_path, numeric, max_bytes=MAX_CSV_BYTES,
                           max_rows=MAX_ROWS, limits=limits,
                           missing=f"CSV file not found (named by {doc.path})",
                           echo=_inside(doc.csv_path, doc.path.parent), label=label)
    col = _column_names(mapping, table, doc.path)
    rc = RecordColumns({k: table.numbers[h] for k, h in col.items()},
                       {h: table.cells[h] if h in table.cells else table.numbers[h]
                        for h in table.header if h not in col.values()},
                       table.lines, doc.csv_path, col)
    check_columns(rc.values, rc.lines, doc.csv_path, rc.label)
    return rc


def _column_names(mapping: dict, table: CsvTable, toml_path: Path) -> dict:
    """Contract name -> the CSV's column name: mapped names first, then the contract's
    own names found in the header."""
    header = table.header
    for key, foreign in mapping.items():
        if foreign not in header:
            _fail(f"maps to column {foreign!r}, which is not in the header of "
                  f"{table.path}", f"{toml_path}: columns.{key}")
    for key, foreign in mapping.items():
        if key in header and key not in mapping.values():
            _fail(f"maps {foreign!r} onto {key}, and the CSV has a column {key!r} of its own: "
                  "two columns would be one (rename or drop one of them)",
                  f"{toml_path}: columns.{key}")
    col = dict(mapping)
    for h in header:
        if h not in col and h not in col.values() and h in table.numbers:
            col[h] = h
    return col


def check_columns(values: dict, lines, where, label) -> None:
    """Every cell of each contract column within its physical range
    (:func:`arfem.ranges.reading_range`: the live loop's ranges), empty cells aside: one
    line naming the first cell out of range. ``ambient_C`` is judged by its median first,
    whose message names a column in kelvin. Shared by every contract version and by a
    record held in memory."""
    amb = values.get("ambient_C")
    if amb is not None and np.isfinite(amb).any():
        check_range("ambient_C", float(np.nanmedian(amb)),
                    f"{where}: column {label('ambient_C')} (median)")
    for key, v in values.items():
        q = reading_quantity(key)
        if q is None:
            continue
        i = first_outside(key, v)
        if i is not None:
            check_range(q, float(v[i]), f"{where}: line {lines[i]}, column {label(key)}")


def _fill_short_gaps(t, y):
    """Linear interpolation in time over NaN runs (nearest value at the ends)."""
    bad = np.isnan(y)
    y = y.copy()
    y[bad] = np.interp(t[bad], t[~bad], y[~bad])
    return y


def _required_columns(col: dict, toml_path: Path, csv_path: Path, mapped: bool) -> None:
    """A record on the rod needs time_s, growth_um and an input (q_W_m2 or speed_rpm)."""
    for req in ("time_s", "growth_um"):
        if req not in col:
            _fail(f"required column {req!r} is missing"
                  + (f" (map a column onto it under [columns] in {toml_path})" if mapped else ""),
                  str(csv_path))
    if "q_W_m2" not in col and "speed_rpm" not in col:
        _fail("needs a q_W_m2 or a speed_rpm column; it has neither", str(csv_path))


def drop_missing_rows(values: dict, lines, csv_path: Path, notes: list,
                      keys: tuple = ("time_s", "growth_um")):
    """Drop the rows with an empty cell in ``keys`` (time and growth; a mesh record's
    time) up to 5 % (:data:`MAX_MISSING_FRACTION`), else refuse. Where only the growth
    is empty, the row's input is kept aside as unobserved.

    Parameters
    ----------
    values : dict
        {column: (n,) float array, NaN where the cell is empty}, in the contract's units.
    lines : numpy.ndarray
        (n,) the CSV line of each row, for messages.
    csv_path : Path
        The record's CSV, named in messages.
    notes : list
        Appended: one note saying which rows were dropped.
    keys : tuple
        The columns a row needs.

    Returns
    -------
    tuple
        (values, lines, keep, unobserved): the kept rows' columns and lines, the (n,)
        bool mask of kept rows, and {column: array} of the rows with an input but no
        growth.

    Raises
    ------
    InputError
        More than 5 % of the rows lack a key, or none is left.
    """
    n_all = len(lines)
    missing = np.zeros(n_all, bool)
    for k in keys:
        missing |= np.isnan(values[k])
    n_missing = int(missing.sum())
    what = " or ".join(keys)
    if n_missing > MAX_MISSING_FRACTION * n_all:
        _fail(f"{n_missing} of {n_all} rows ({100 * n_missing / n_all:.1f} %) have an empty "
              f"{what}; at most {100 * MAX_MISSING_FRACTION:g} % may be dropped "
              f"(first at line {lines[missing][0]})", str(csv_path))
    if n_missing:
        shown = ", ".join(str(x) for x in lines[missing][:10])
        notes.append(f"dropped {n_missing} of {n_all} rows ({100 * n_missing / n_all:.2f} %) "
                     f"with an empty {what}: CSV lines {shown}"
                     + (" ..." if n_missing > 10 else "")
                     + ("; where only growth_um is empty the row's input is kept"
                        if "growth_um" in keys else ""))
    unobserved = {}
    if "growth_um" in keys:   # a time and an input but no growth: the input is kept
        inp = "q_W_m2" if "q_W_m2" in values else "speed_rpm"
        unobs = (np.isnan(values["growth_um"]) & ~np.isnan(values["time_s"])
                 & np.isfinite(values[inp]) & (values[inp] >= 0))
        unobserved = {k: v[unobs].copy() for k, v in values.items()
                      if k in ("time_s", inp, "ambient_C") or _TEMP_RE.match(k)}
    keep = ~missing
    lines = lines[keep]
    values = {k: v[keep] for k, v in values.items()}
    if lines.size == 0:
        _fail(f"no row has {' and '.join(keys)}", str(csv_path))
    return values, lines, keep, unobserved


def check_time_steps_s(t, lines, csv_path: Path, label) -> np.ndarray:
    """time_s >= 0 and strictly increasing; returns its steps [s].

    Parameters
    ----------
    t : numpy.ndarray
        (n,) time_s [s].
    lines : numpy.ndarray
        (n,) the CSV line of each row, for messages.
    csv_path : Path
        The record's CSV, named in messages.
    label : callable
        ``label(key)``: the column's name in the file, for messages.

    Returns
    -------
    numpy.ndarray
        (n − 1,) the steps t[i] − t[i − 1] [s], all > 0.

    Raises
    ------
    InputError
        The first time is negative, or a time does not increase.
    """
    if t[0] < 0:
        _fail(f"time_s = {t[0]:g} is negative; time counts from the start of the record",
              f"{csv_path}: line {lines[0]}, column {label('time_s')}")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.flatnonzero(dt <= 0)[0]) + 1
        _fail(f"time_s = {t[i]:g} does not increase (previous row, line {lines[i - 1]}, "
              f"has {t[i - 1]:g})", f"{csv_path}: line {lines[i]}, column {label('time_s')}")
    return dt


def input_complete(v, key: str, lines, csv_path, label) -> None:
    """An input column (a heat flux, a speed, a source's power): given on every row
    and >= 0, else one line naming the first row that is not."""
    if np.any(np.isnan(v)):
        i = int(np.flatnonzero(np.isnan(v))[0])
        _fail("is empty; the input must be given on every row with a reading",
              f"{csv_path}: line {lines[i]}, column {label(key)}")
    if np.any(v < 0):
        i = int(np.flatnonzero(v < 0)[0])
        _fail(f"{v[i]:g} is negative; it must be >= 0",
              f"{csv_path}: line {lines[i]}, column {label(key)}")


def _check_input(values: dict, lines, csv_path: Path, label, notes: list) -> None:
    """The input (q_W_m2 where given, else speed_rpm): complete and >= 0 (its range:
    :func:`check_columns`)."""
    for key in ("q_W_m2", "speed_rpm")[:1 if "q_W_m2" in values else 2]:
        if key in values:
            input_complete(values[key], key, lines, csv_path, label)
    if "q_W_m2" in values and "speed_rpm" in values:
        notes.append("both q_W_m2 and speed_rpm are given; the heat flux q_W_m2 is the input, "
                     "speed_rpm is carried along")


def ambient_filled_C(values: dict, t, lines, csv_path: Path, label, notes: list):
    """ambient_C [°C] with short gaps filled by linear interpolation in time (None where
    absent or empty throughout).

    Parameters
    ----------
    values : dict
        The record's columns; ``"ambient_C"`` [°C] is used when present.
    t : numpy.ndarray
        (n,) time_s [s].
    lines : numpy.ndarray
        (n,) the CSV line of each row, for messages.
    csv_path : Path
        The record's CSV, named in messages.
    label : callable
        ``label(key)``: the column's name in the file, for messages.
    notes : list
        Appended: a note when the column is empty or cells were filled.

    Returns
    -------
    numpy.ndarray or None
        (n,) ambient [°C], or None.

    Raises
    ------
    InputError
        More than 5 % of its cells are empty.
    """
    amb = values.get("ambient_C")
    if amb is not None and np.isnan(amb).all():
        notes.append("ambient_C: the column has no value; treated as absent")
        amb = None
    if amb is not None:
        nan = np.isnan(amb)
        if nan.sum() > MAX_MISSING_FRACTION * amb.size:
            i = int(np.flatnonzero(nan)[0])
            _fail(f"{int(nan.sum())} of {amb.size} cells are empty; at most "
                  f"{100 * MAX_MISSING_FRACTION:g} % may be filled",
                  f"{csv_path}: line {lines[i]}, column {label('ambient_C')}")
        if nan.any():
            amb = _fill_short_gaps(t, amb)
            notes.append(f"filled {int(nan.sum())} empty ambient_C cells by linear "
                         f"interpolation in time")
    return amb


def _growth_outliers(g, lines, csv_path: Path, label, notes: list) -> tuple[np.ndarray, float]:
    """The growth's Hampel outlier flags, with the σ floored at the sensor's resolution
    where the growth is quantised (a one-quantum flicker of a quantised reading is the
    sensor, not an outlier); and that resolution [µm]."""
    from arfem.models.diagnosis.dataset import hampel_outliers
    from arfem.models.diagnosis.stats import resolution
    res = resolution(g)
    if res > 0:
        notes.append(f"growth_um is quantised at {res:.4g} µm (the sensor's resolution, "
                     f"estimated from the steps): outlier and noise scales are floored at "
                     f"it (quantisation noise σ = {res / np.sqrt(12):.3g} µm)")
    outliers = hampel_outliers(g, floor=res)
    if outliers.any():
        shown = ", ".join(str(x) for x in lines[outliers][:10])
        notes.append(f"flagged {int(outliers.sum())} growth outliers (Hampel, 6 robust σ from a "
                     f"median of the 10 neighbouring samples): CSV lines {shown}"
                     + (" ..." if outliers.sum() > 10 else ""))
    return outliers, res


def _record_notes(t, dt, gaps, extra, sensors, col, initial_unknown, notes: list) -> None:
    """Notes on the sampling, the gaps, the carried columns and the sensor tables."""
    from arfem.models.diagnosis.dataset import GAP_FACTOR
    if dt.size:
        notes.append(f"{t.size} rows over {t[-1] - t[0]:g} s; sampling interval median "
                     f"{np.median(dt):g} s, min {dt.min():g} s, max {dt.max():g} s")
    if gaps:
        total = sum(b - a for a, b in gaps)
        notes.append(f"{len(gaps)} sampling gaps longer than {GAP_FACTOR:g}x the median interval, "
                     f"{total:g} s in all, the longest {max(b - a for a, b in gaps):g} s "
                     f"from {max(gaps, key=lambda ab: ab[1] - ab[0])[0]:g} s")
    if extra:
        notes.append(f"extra columns carried and ignored: {', '.join(extra)}")
    for key in sensors:
        if key in extra:
            notes.append(f"[sensors.{key}] describes a column that is carried but not used: "
                         "it is not a temperature T_<name>_C")
        elif key not in col:
            notes.append(f"[sensors.{key}] describes a column that is not in the CSV")
    if initial_unknown:
        notes.append('initial = "unknown": the record does not start at equilibrium')


def _frozen(a) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=float)
    a.setflags(write=False)
    return a


def load_dataset(toml_path, limits: Limits | None = None) -> Dataset:
    """Load and validate a measured dataset per the measured-data contract.

    Parameters
    ----------
    toml_path : str or path-like, or RecordDoc
        The dataset's TOML file (or its CSV; or the TOML as read,
        :func:`read_record_doc`); its ``[dataset] csv`` (default ``<stem>.csv``) is read
        relative to it.
    limits : arfem.limits.Limits, optional
        What the user allows: a larger file or more rows (``large``), a CSV outside the
        TOML's folder (``csv_outside``). Default: :meth:`Limits.from_environment`.

    Returns
    -------
    Dataset

    Raises
    ------
    arfem.params.InputError
        One line naming the file, the key/line/column and what is wrong.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "c.csv").write_text("time_s,growth_um,q_W_m2\\n0,0,0\\n30,0.2,2000\\n60,0.4,2000\\n")
    >>> _ = (d / "c.toml").write_text('[dataset]\\nname = "c"\\ncsv = "c.csv"\\n')
    >>> ds = load_dataset(d / "c.toml")
    >>> ds.input_kind, ds.growth_um.tolist(), ds.rod.convection_W_m2K
    ('q_W_m2', [0.0, 0.2, 0.4], 55.0)
    """
    doc = toml_path if isinstance(toml_path, RecordDoc) else read_record_doc(toml_path, limits)
    return dataset_of(doc, limits)


def dataset_of(doc: RecordDoc, limits: Limits | None = None,
               columns: RecordColumns | None = None) -> Dataset:
    """The rod's :class:`Dataset` of a record whose TOML is read (``doc``) and, where
    given, whose CSV is read (``columns``; else it is read here): the contract's
    version-2 view (a v3 record's ``growth_um``, its other columns carried)."""
    rc = read_record_columns(doc, limits) if columns is None else columns
    base = {k: v for k, v in rc.values.items() if k in _BASE_COLUMNS or _TEMP_RE.match(k)}
    _required_columns(base, doc.path, doc.csv_path, bool(doc.mapping))
    extra = {h: v for h, v in rc.extra.items()}
    extra.update({k: v for k, v in rc.values.items() if k not in base})
    return _checked_dataset(dict(base), rc.lines, extra, doc.sensors, base, rc.label, [],
                            name=doc.name, source=doc.path, csv_path=doc.csv_path,
                            rod=doc.rod, initial_unknown=doc.initial_unknown,
                            where=doc.csv_path)


def _checked_dataset(values, lines, extra_raw, sensors, col, label, notes, *, name, source,
                     csv_path, rod, initial_unknown, where) -> Dataset:
    """The contract's checks and notes on parsed columns, and the frozen
    :class:`~arfem.models.diagnosis.dataset.Dataset`: one pass shared by the CSV reader
    (:func:`load_dataset`) and the in-memory one (:func:`dataset_from_columns`), so that
    both refuse and note the same things. ``where`` names the data in messages;
    ``extra_raw`` holds the carried (non-contract) columns, one cell per row of
    ``lines``."""
    values, lines, keep, unobserved = drop_missing_rows(values, lines, where, notes)
    t = values["time_s"]
    dt = check_time_steps_s(t, lines, where, label)
    _check_input(values, lines, where, label, notes)
    amb = ambient_filled_C(values, t, lines, where, label, notes)
    temps = {k: v for k, v in values.items() if _TEMP_RE.match(k)}
    for k, v in temps.items():
        if np.isnan(v).any():
            notes.append(f"{k}: {int(np.isnan(v).sum())} empty cells (NaN)")
    g = values["growth_um"]
    outliers, res = _growth_outliers(g, lines, where, label, notes)
    from arfem.models.diagnosis.dataset import Dataset, sampling_gaps
    gaps = sampling_gaps(t)
    _record_notes(t, dt, gaps, list(extra_raw), sensors, col, initial_unknown, notes)
    extra_cols = {h: a[keep] for h, a in extra_raw.items()}
    for a in (outliers, lines, *extra_cols.values()):
        a.setflags(write=False)
    return Dataset(
        name=name, source=source, time_s=_frozen(t), growth_um=_frozen(g),
        q_W_m2=_frozen(values["q_W_m2"]) if "q_W_m2" in values else None,
        speed_rpm=_frozen(values["speed_rpm"]) if "speed_rpm" in values else None,
        ambient_C=_frozen(amb) if amb is not None else None,
        temperatures={k: _frozen(v) for k, v in temps.items()}, rod=rod,
        initial_known=not initial_unknown, outliers=outliers, gaps=gaps, notes=notes,
        sensors=sensors, csv_path=csv_path, line_numbers=lines, extra_columns=extra_cols,
        unobserved=unobserved, growth_resolution_um=res)


# -- a record held in memory (a pandas DataFrame or a dict of columns) ------------------

_ROW_RE = re.compile(r"\bline (\d+)")


def _in_memory_error(exc: InputError, where: str) -> InputError:
    """The file-reader's wording for an in-memory record: ``line N`` becomes ``row N``
    (counted from 0, as ``DataFrame.iloc`` does)."""
    return InputError(_ROW_RE.sub(r"row \1", str(exc)))


def _numeric_column(key: str, values, where: str) -> np.ndarray:
    """A column as floats (None/NaN = an empty cell); text or ±inf refused by row."""
    raw = np.asarray(values)
    if raw.ndim != 1:
        _fail(f"must be one-dimensional, got shape {raw.shape}", f"{where}: column {key!r}")
    if raw.dtype.kind in "fiu":                   # numbers already: one pass, no loop
        out = raw.astype(float)
        if not np.isinf(out).any():
            return out
    raw = raw.astype(object)
    out = np.empty(raw.size)
    for i, v in enumerate(raw):
        if v is None:
            out[i] = np.nan
            continue
        if isinstance(v, (bool, np.bool_)) or isinstance(v, (str, bytes)):
            _fail(f"{v!r} is not a number", f"{where}: row {i}, column {key!r}")
        try:
            out[i] = float(v)
        except (TypeError, ValueError):
            _fail(f"{v!r} is not a number", f"{where}: row {i}, column {key!r}")
        if np.isinf(out[i]):
            _fail(f"{v!r} is not a finite number (use NaN for a missing value)",
                  f"{where}: row {i}, column {key!r}")
    return out


def dataset_from_columns(columns, *, name: str = "dataframe", rod: Rod | None = None,
                         initial: str = "equilibrium",
                         where: str = "<DataFrame>") -> Dataset:
    """A record held in memory, validated exactly as :func:`load_dataset` validates a file.

    No file is written or read: the columns go through the contract's checks (time
    strictly increasing from >= 0, an input >= 0 on every row, plausible units, at most
    5 % rows without a growth, short ambient gaps filled, outliers flagged), and a
    message names ``where``, the row (counted from 0) and the column.

    Parameters
    ----------
    columns : mapping of str to array_like
        Contract names (``time_s`` [s], ``growth_um`` [µm], ``q_W_m2`` [W/m²] or
        ``speed_rpm`` [1/min], optional ``ambient_C`` [°C] and ``T_<name>_C`` [°C]), e.g.
        a pandas DataFrame; other columns are carried and ignored, as in a CSV. NaN or
        None is an empty cell.
    name : str
        The record's name in the results.
    rod : Rod, optional
        The rod the simulation assumes (default: the seed paper's).
    initial : {"equilibrium", "unknown"}
        ``"unknown"`` when the record did not start at equilibrium with the ambient.
    where : str
        What the messages call the record.

    Returns
    -------
    Dataset

    Raises
    ------
    arfem.params.InputError
        One line naming ``where``, the row or column, and what is wrong.

    Examples
    --------
    >>> ds = dataset_from_columns({"time_s": [0.0, 30.0, 60.0], "growth_um": [0, 0.2, 0.4],
    ...                            "q_W_m2": [0.0, 2000.0, 2000.0]}, initial="unknown")
    >>> ds.input_kind, ds.initial_known, str(ds.source)
    ('q_W_m2', False, '<DataFrame>')
    """
    if initial not in _INITIAL_VALUES:
        _fail(f"must be one of {', '.join(repr(v) for v in _INITIAL_VALUES)}, got {initial!r}",
              "initial")
    if not isinstance(name, str) or not name.strip():
        _fail(f"must be a non-empty string, got {name!r}", "name")
    rod = Rod() if rod is None else rod
    for key in ROD_KEYS:
        check_range(key, float(getattr(rod, key)), f"rod.{key}")
    header = [str(c) for c in columns.keys()]
    for i, h in enumerate(header):
        if header.index(h) != i:
            _fail(f"column {h!r} appears twice", where)
    try:
        col = {h: h for h in header if h in _BASE_COLUMNS or _TEMP_RE.match(h)}
        extra = [h for h in header if h not in col]
        for req in ("time_s", "growth_um"):
            if req not in col:
                _fail(f"required column {req!r} is missing (columns: {', '.join(header)})",
                      where)
        if "q_W_m2" not in col and "speed_rpm" not in col:
            _fail("needs a q_W_m2 or a speed_rpm column; it has neither", where)
        data = {str(k): v for k, v in columns.items()}
        values = {k: _numeric_column(k, data[k], where) for k in col}
        n = {k: v.size for k, v in values.items()}
        if len(set(n.values())) != 1:
            _fail(f"columns differ in length: {n}", where)
        if not n["time_s"]:
            _fail("has no rows", where)
        lines = np.arange(n["time_s"])
        return _dataset_from_values(values, lines, extra, {k: np.asarray(data[k], dtype=object)
                                                            for k in extra},
                                    name=name, rod=rod, initial_unknown=initial == "unknown",
                                    where=where)
    except InputError as exc:
        raise _in_memory_error(exc, where) from None


def _dataset_from_values(values, lines, extra, extra_raw, *, name, rod, initial_unknown,
                         where) -> Dataset:
    """The contract's processing of parsed columns (:func:`_checked_dataset`, as
    :func:`load_dataset` does after reading the CSV), for a record held in memory: its
    notes count rows, not CSV lines."""
    notes: list[str] = []
    check_columns(values, lines, where, lambda key: f"{key!r}")
    ds = _checked_dataset(values, lines, {h: extra_raw[h] for h in extra}, {}, values,
                          lambda key: f"{key!r}", notes, name=name, source=Path(where),
                          csv_path=None, rod=rod, initial_unknown=initial_unknown,
                          where=Path(where))
    notes[:] = [n.replace("CSV lines", "rows") for n in notes]
    return ds
