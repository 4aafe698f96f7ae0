"""Read a measured dataset (``NAME.toml`` + ``NAME.csv``) exactly per the measured-data contract.

The contract (``docs/measured-data.md``) fixes the form of every measured dataset: a CSV of
samples with the columns ``time_s``, ``growth_um``, ``q_W_m2`` or ``speed_rpm``,
optionally ``ambient_C`` and ``T_<name>_C``, and a TOML beside it with the tables
``[dataset]``, ``[rod]``, ``[columns]`` and ``[sensors.*]``. :func:`load_dataset`
turns the pair into a validated, immutable :class:`~arfem.models.diagnosis.dataset.Dataset` or refuses it with one
:class:`arfem.params.InputError` whose message names the file, the CSV line or the
column/key, and what is wrong.

Data flow: file -> ``Dataset`` (this module) -> models. Nothing here fits or
simulates; the only processing is what the contract prescribes (drop <= 5 % rows with
an empty ``time_s``/``growth_um``, fill short ``ambient_C`` gaps) plus robust flags
that the models may use (growth outliers, sampling gaps), each reported in ``notes``.

``[dataset] initial`` may be ``"equilibrium"`` (the default: at t = 0 the rod is in
equilibrium with the nominal ambient) or ``"unknown"``.
"""
from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np

from arfem.io import read_text_utf8, read_toml
from arfem.limits import Limits, resolve
from arfem.strict import check_keys
from arfem.models.diagnosis.dataset import GAP_FACTOR, Dataset, hampel_outliers, sampling_gaps
from arfem.models.diagnosis.stats import resolution
from arfem.params import InputError, Rod, check_plausible

__all__ = ["load_dataset", "ROD_KEYS", "MAX_MISSING_FRACTION", "MAX_ROWS", "MAX_CSV_BYTES"]

#: ``[rod]`` keys of the contract (a subset of :class:`arfem.params.Rod`'s fields).
ROD_KEYS = ("radius_m", "length_m", "conductivity_W_mK", "density_kg_m3",
            "specific_heat_J_kgK", "expansion_1_K", "convection_W_m2K", "ambient_C")
#: Rows with an empty ``time_s``/``growth_um`` are dropped up to this fraction, refused above.
MAX_MISSING_FRACTION = 0.05
#: Largest record diagnosed without ``--allow-large`` (28 h at 1 s, 12 days at 10 s; the
#: shipped record has 11 115 rows); the CSV's lines are counted before it is parsed.
#: Measured: 20 000 rows diagnose in 93 s, 200 000 in 652 s (256 MB peak) on a shared
#: 2-core machine, so this keeps a run to minutes.
MAX_ROWS = 100_000
#: Largest dataset CSV read without ``--allow-large`` [bytes]: MAX_ROWS rows of ~600
#: characters; checked from the file's size before it is read.
MAX_CSV_BYTES = 64 * 1024 ** 2

#: ``model``: a contract-v3 record's (the mesh scenario it belongs to); read here only
#: so that ``arfem compensate`` can replay a mesh run's record on its ``growth_um``; the
#: rod's diagnosis refuses such a record (:func:`arfem.scenarios.georecord.refuse_mesh_record`)
_TOP_TABLES = ("dataset", "rod", "columns", "sensors", "model")
_DATASET_KEYS = ("name", "csv", "initial")
_INITIAL_VALUES = ("equilibrium", "unknown")
_SENSOR_KEYS = ("description",)
_BASE_COLUMNS = ("time_s", "growth_um", "q_W_m2", "speed_rpm", "ambient_C")
_TEMP_RE = re.compile(r"^T_.+_C$")
_NUMBER_RE = re.compile(r"^[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$")
_NONFINITE_RE = re.compile(r"^[+-]?(?:nan|inf|infinity)$", re.IGNORECASE)


# -- reading ------------------------------------------------------------------------

def _fail(message: str, where: str):
    raise InputError(message, where)





def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _parse_meta(path: Path, doc: dict, limits: Limits):
    """Validate the TOML tables; return (name, csv_path, initial_known, rod, columns, sensors)."""
    where = str(path)
    try:
        check_keys(doc, _TOP_TABLES, "")
    except InputError as e:
        raise e.at(where) from None
    for key in doc:
        if not isinstance(doc[key], dict):
            _fail(f"must be a table, got {type(doc[key]).__name__}", f"{where}: {key}")

    check_keys(doc.get("model", {}), ("scenario",), f"{where}: model")
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

    rod_doc = doc.get("rod", {})
    check_keys(rod_doc, ROD_KEYS, f"{where}: rod")
    for key, value in rod_doc.items():
        if not _is_number(value):
            _fail(f"must be a number, got {value!r}", f"{where}: rod.{key}")
    try:
        rod = Rod(**rod_doc)
    except InputError as e:
        raise e.at(f"{where}: rod") from None
    for key, value in rod_doc.items():       # physical, so now: in the right unit?
        check_plausible(key, float(value), f"{where}: rod.{key}")

    columns = doc.get("columns", {})
    seen: dict[str, str] = {}
    for key, value in columns.items():
        if key not in _BASE_COLUMNS and not _TEMP_RE.match(key):
            _fail("is not a contract column name (time_s, growth_um, q_W_m2, speed_rpm, "
                  "ambient_C, T_<name>_C)", f"{where}: columns.{key}")
        if not isinstance(value, str) or not value:
            _fail(f"must be a column name (string), got {value!r}", f"{where}: columns.{key}")
        if value in seen:
            _fail(f"maps to {value!r}, which columns.{seen[value]} already maps to",
                  f"{where}: columns.{key}")
        seen[value] = key

    sensors: dict[str, str] = {}
    for key, table in doc.get("sensors", {}).items():
        if not isinstance(table, dict):
            _fail("must be a table [sensors.<column>]", f"{where}: sensors.{key}")
        check_keys(table, _SENSOR_KEYS, f"{where}: sensors.{key}")
        for k, v in table.items():
            if not isinstance(v, str):
                _fail(f"must be a string, got {v!r}", f"{where}: sensors.{key}.{k}")
        sensors[key] = table.get("description", "")
    csv_path = path.parent / csv_name
    if not _inside(csv_path, path.parent) and not limits.csv_outside:
        _fail(f"{csv_name!r} is outside the dataset's folder; arfem reads only files beside "
              "the TOML (pass --allow-csv-outside to read it anyway)", f"{where}: dataset.csv")
    return name, csv_path, initial == "unknown", rod, dict(columns), sensors


def _inside(p: Path, folder: Path) -> bool:
    """True if ``p`` (symbolic links resolved) lies within ``folder``."""
    try:
        p.resolve().relative_to(folder.resolve())
        return True
    except (ValueError, OSError, RuntimeError):
        return False


def _read_csv(path: Path, toml_path: Path, limits: Limits):
    """Return (header, rows, line_numbers) of a strict, rectangular CSV."""
    text = read_text_utf8(path, missing=f"CSV file not found (named by {toml_path})",
                          max_bytes=MAX_CSV_BYTES, limits=limits)
    n_rows = text.count("\n") - 1                 # minus the header
    if n_rows > MAX_ROWS and not limits.large:
        _fail(f"has about {n_rows:,} rows; arfem diagnoses at most {MAX_ROWS:,} (resample "
              "the record, or pass --allow-large)", str(path))
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    rows, lines = [], []
    header = None
    start = 1
    try:
        while True:
            start = reader.line_num + 1           # where the next record begins
            try:
                row = next(reader)
            except StopIteration:
                break
            if not row or (len(row) == 1 and not row[0].strip()):
                continue          # blank line
            if header is None:
                header = [c.strip() for c in row]
                header_line = reader.line_num
                continue
            if len(row) != len(header):
                _fail(f"has {len(row)} fields, the header has {len(header)}",
                      f"{path}: line {reader.line_num}")
            rows.append(row)
            lines.append(reader.line_num)
    except csv.Error as e:
        if reader.line_num > start:               # e.g. a quote never closed
            _fail(f"broken CSV: {e} (the record starting here runs on to line "
                  f"{reader.line_num}: a quote opened here is never closed?)",
                  f"{path}: line {start}")
        _fail(f"broken CSV: {e}", f"{path}: line {reader.line_num}")
    if header is None:
        _fail("is empty (no header row)", str(path))
    for i, name in enumerate(header):
        if not name:
            _fail(f"header field {i + 1} is empty", f"{path}: line {header_line}")
        if header.index(name) != i:
            _fail(f"column {name!r} appears twice in the header", f"{path}: line {header_line}")
    if not rows:
        _fail("has a header but no data rows", str(path))
    return header, rows, np.asarray(lines, dtype=int)


def _parse_column(csv_path: Path, rows, lines, j: int, label: str,
                  echo: bool = True) -> np.ndarray:
    """Numbers of column ``j``; empty cells -> NaN; text/NaN/inf -> InputError.

    With ``echo`` False (a file outside the dataset's folder) a message never shows the
    cell's content, only its place."""
    out = np.empty(len(rows))
    match = _NUMBER_RE.match
    for i, row in enumerate(rows):
        cell = row[j].strip()
        if not cell:
            out[i] = np.nan
            continue
        if match(cell):
            out[i] = float(cell)
            continue
        # only a bad cell is shown (a repr per cell was a tenth of a real record's run)
        shown = repr(cell if len(cell) <= 40 else cell[:40] + "…") if echo else "the cell"
        if _NONFINITE_RE.match(cell):
            _fail(f"{shown} is not a finite number (NaN/inf are refused; leave the cell "
                  f"empty for a missing value)", f"{csv_path}: line {lines[i]}, column {label}")
        else:
            _fail(f"{shown} is not a number", f"{csv_path}: line {lines[i]}, column {label}")
    if not np.all(np.isfinite(out[~np.isnan(out)])):      # e.g. 1e999
        i = int(np.flatnonzero(np.isinf(out))[0])
        _fail(f"{repr(rows[i][j].strip()) if echo else 'the cell'} overflows to infinity",
              f"{csv_path}: line {lines[i]}, column {label}")
    return out


def _fill_short_gaps(t, y):
    """Linear interpolation in time over NaN runs (nearest value at the ends)."""
    bad = np.isnan(y)
    y = y.copy()
    y[bad] = np.interp(t[bad], t[~bad], y[~bad])
    return y


def _column_indices(mapping: dict, header: list, toml_path: Path, csv_path: Path):
    """Contract name -> header index (mapped names first, then the contract's own names
    found in the header), and the header names no contract column uses."""
    for key, foreign in mapping.items():
        if foreign not in header:
            _fail(f"maps to column {foreign!r}, which is not in the header of {csv_path}",
                  f"{toml_path}: columns.{key}")
    col: dict[str, int] = {key: header.index(foreign) for key, foreign in mapping.items()}
    mapped_foreign = set(mapping.values())
    for j, h in enumerate(header):
        if h in mapped_foreign or h in col:
            continue
        if h in _BASE_COLUMNS or _TEMP_RE.match(h):
            col[h] = j
    used = set(col.values())
    extra = [h for j, h in enumerate(header) if j not in used]
    for req in ("time_s", "growth_um"):
        if req not in col:
            _fail(f"required column {req!r} is missing"
                  + (f" (map a column onto it under [columns] in {toml_path})" if mapping else ""),
                  str(csv_path))
    if "q_W_m2" not in col and "speed_rpm" not in col:
        _fail("needs a q_W_m2 or a speed_rpm column; it has neither", str(csv_path))
    return col, extra


def _drop_missing_rows(values: dict, lines, csv_path: Path, notes: list):
    """Drop the rows with an empty time or growth (up to 5 %, else refuse). Where only
    the growth is empty, the row's input is kept aside as unobserved.

    Returns (values, lines, keep, unobserved) over the kept rows."""
    n_all = len(lines)
    missing = np.isnan(values["time_s"]) | np.isnan(values["growth_um"])
    n_missing = int(missing.sum())
    if n_missing > MAX_MISSING_FRACTION * n_all:
        _fail(f"{n_missing} of {n_all} rows ({100 * n_missing / n_all:.1f} %) have an empty "
              f"time_s or growth_um; at most {100 * MAX_MISSING_FRACTION:g} % may be dropped "
              f"(first at line {lines[missing][0]})", str(csv_path))
    if n_missing:
        shown = ", ".join(str(x) for x in lines[missing][:10])
        notes.append(f"dropped {n_missing} of {n_all} rows ({100 * n_missing / n_all:.2f} %) "
                     f"with an empty time_s or growth_um: CSV lines {shown}"
                     + (" ..." if n_missing > 10 else "")
                     + "; where only growth_um is empty the row's input is kept")
    # rows with a time and an input but no growth: the observation is dropped, the input kept
    inp = "q_W_m2" if "q_W_m2" in values else "speed_rpm"
    unobs = (np.isnan(values["growth_um"]) & ~np.isnan(values["time_s"])
             & np.isfinite(values[inp]) & (values[inp] >= 0))
    unobserved = {k: v[unobs].copy() for k, v in values.items()
                  if k in ("time_s", inp, "ambient_C") or _TEMP_RE.match(k)}
    keep = ~missing
    lines = lines[keep]
    values = {k: v[keep] for k, v in values.items()}
    if lines.size == 0:
        _fail("no row has both time_s and growth_um", str(csv_path))
    return values, lines, keep, unobserved


def _check_time(t, lines, csv_path: Path, label) -> np.ndarray:
    """time_s >= 0 and strictly increasing; returns its steps."""
    if t[0] < 0:
        _fail(f"time_s = {t[0]:g} is negative; time counts from the start of the record",
              f"{csv_path}: line {lines[0]}, column {label('time_s')}")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.flatnonzero(dt <= 0)[0]) + 1
        _fail(f"time_s = {t[i]:g} does not increase (previous row, line {lines[i - 1]}, "
              f"has {t[i - 1]:g})", f"{csv_path}: line {lines[i]}, column {label('time_s')}")
    return dt


def _check_input(values: dict, lines, csv_path: Path, label, notes: list) -> None:
    """The input (q_W_m2 where given, else speed_rpm): complete, >= 0 and plausible."""
    for key in ("q_W_m2", "speed_rpm")[:1 if "q_W_m2" in values else 2]:
        if key not in values:
            continue
        v = values[key]
        if np.any(np.isnan(v)):
            i = int(np.flatnonzero(np.isnan(v))[0])
            _fail("is empty; the input must be given on every row with a growth value",
                  f"{csv_path}: line {lines[i]}, column {label(key)}")
        if np.any(v < 0):
            i = int(np.flatnonzero(v < 0)[0])
            _fail(f"{v[i]:g} is negative; it must be >= 0",
                  f"{csv_path}: line {lines[i]}, column {label(key)}")
        i = int(np.argmax(v))
        check_plausible(key, float(v[i]), f"{csv_path}: line {lines[i]}, column {label(key)}")
    if "q_W_m2" in values and "speed_rpm" in values:
        notes.append("both q_W_m2 and speed_rpm are given; the heat flux q_W_m2 is the input, "
                     "speed_rpm is carried along")


#: A temperature reading of a machine tool outside this range [°C] is not one (below
#: absolute zero, or far above any spindle part): the cell is refused (issue 29: a
#: reading of -1e308 °C made a hold-out RMSE of inf with exit 0).
TEMPERATURE_CELL_RANGE_C = (-273.15, 1000.0)


def _check_temperature_cells(values: dict, lines, csv_path: Path, label,
                             ambient: bool = False) -> None:
    """Every cell of each ``T_<name>_C`` (:data:`TEMPERATURE_CELL_RANGE_C`), and with
    ``ambient`` of ``ambient_C`` (the plausible ambient range; :func:`_ambient` asks after
    its median check, whose message names a column in K), that is given: one line naming
    the row and column of the first one out of range."""
    for key, v in values.items():
        if not (key == "ambient_C" and ambient or _TEMP_RE.match(key)):
            continue
        fin = np.flatnonzero(np.isfinite(v))
        if np.any(np.isinf(v)):
            i = int(np.flatnonzero(np.isinf(v))[0])
            _fail(f"{v[i]:g} is not a temperature", f"{csv_path}: line {lines[i]}, "
                                                   f"column {label(key)}")
        if not fin.size:
            continue
        for i in (int(fin[np.argmin(v[fin])]), int(fin[np.argmax(v[fin])])):
            where = f"{csv_path}: line {lines[i]}, column {label(key)}"
            if key == "ambient_C":
                check_plausible("ambient_C", float(v[i]), where)
            else:
                lo, hi = TEMPERATURE_CELL_RANGE_C
                if not lo <= v[i] <= hi:
                    _fail(f"{v[i]:g} °C is outside [{lo:g}, {hi:g}] °C, no machine "
                          "reading", where)


def _ambient(values: dict, t, lines, csv_path: Path, label, notes: list):
    """ambient_C with short gaps filled (None where absent or empty throughout)."""
    amb = values.get("ambient_C")
    if amb is not None and np.isnan(amb).all():
        notes.append("ambient_C: the column has no value; treated as absent")
        amb = None
    if amb is not None:
        med = float(np.nanmedian(amb))
        check_plausible("ambient_C", med, f"{csv_path}: column {label('ambient_C')} (median)")
        _check_temperature_cells({"ambient_C": amb}, lines, csv_path, label, ambient=True)
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
    """The growth in a plausible range; its Hampel outlier flags, with the σ floored at
    the sensor's resolution where the growth is quantised (a one-quantum flicker of a
    quantised reading is the sensor, not an outlier); and that resolution [µm]."""
    if g.size and np.isfinite(g).any():
        i = int(np.nanargmax(np.abs(g)))
        check_plausible("growth_um", float(g[i]),
                        f"{csv_path}: line {lines[i]}, column {label('growth_um')}")
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
    toml_path : str or path-like
        The dataset's TOML file; its ``[dataset] csv`` (default ``<stem>.csv``) is
        read relative to it.
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
    toml_path = Path(toml_path)
    limits = resolve(limits)
    doc = read_toml(toml_path, limits)
    name, csv_path, initial_unknown, rod, mapping, sensors = _parse_meta(toml_path, doc, limits)
    header, rows, lines = _read_csv(csv_path, toml_path, limits)
    notes: list[str] = []
    col, extra = _column_indices(mapping, header, toml_path, csv_path)

    def label(key):
        foreign = header[col[key]]
        return f"{key!r}" if foreign == key else f"{key!r} ({foreign!r})"

    echo = _inside(csv_path, toml_path.parent)
    values = {key: _parse_column(csv_path, rows, lines, j, label(key), echo)
              for key, j in col.items()}
    extra_raw = {h: np.array([row[header.index(h)] for row in rows], dtype=object)
                 for h in extra}
    return _checked_dataset(values, lines, extra_raw, sensors, col, label, notes,
                            name=name, source=toml_path, csv_path=csv_path, rod=rod,
                            initial_unknown=initial_unknown, where=csv_path)


def _checked_dataset(values, lines, extra_raw, sensors, col, label, notes, *, name, source,
                     csv_path, rod, initial_unknown, where) -> Dataset:
    """The contract's checks and notes on parsed columns, and the frozen
    :class:`~arfem.models.diagnosis.dataset.Dataset`: one pass shared by the CSV reader
    (:func:`load_dataset`) and the in-memory one (:func:`dataset_from_columns`), so that
    both refuse and note the same things. ``where`` names the data in messages;
    ``extra_raw`` holds the carried (non-contract) columns, one cell per row of
    ``lines``."""
    values, lines, keep, unobserved = _drop_missing_rows(values, lines, where, notes)
    t = values["time_s"]
    dt = _check_time(t, lines, where, label)
    _check_input(values, lines, where, label, notes)
    amb = _ambient(values, t, lines, where, label, notes)
    _check_temperature_cells(values, lines, where, label)
    temps = {k: v for k, v in values.items() if _TEMP_RE.match(k)}
    for k, v in temps.items():
        if np.isnan(v).any():
            notes.append(f"{k}: {int(np.isnan(v).sum())} empty cells (NaN)")
    g = values["growth_um"]
    outliers, res = _growth_outliers(g, lines, where, label, notes)
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
        check_plausible(key, float(getattr(rod, key)), f"rod.{key}")
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
    ds = _checked_dataset(values, lines, {h: extra_raw[h] for h in extra}, {}, values,
                          lambda key: f"{key!r}", notes, name=name, source=Path(where),
                          csv_path=None, rod=rod, initial_unknown=initial_unknown,
                          where=Path(where))
    notes[:] = [n.replace("CSV lines", "rows") for n in notes]
    return ds
