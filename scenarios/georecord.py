"""Measured-data contract v3 (issue 33): a record checked against a mesh scenario.

The record's TOML names the scenario (``[model] scenario = "spindle_unit.toml"``,
relative to the TOML) and its CSV's columns map onto that scenario's sensors and
sources:

* ``time_s`` (required, strictly increasing);
* ``d_<sensor>_um``: a displacement sensor of the scenario [µm] (at least one);
* ``T_<sensor>_C``: a temperature sensor of the scenario (a point) [°C];
* ``P_<source>_W``: a heat source's input per row (its power [W]; for a flux source
  its flux [W/m²]), or ``speed_rpm``, from which every source without a ``P`` column
  takes the power its scenario gives at that speed (linear between the scenario's
  (speed, power) pairs of its cycle phases) and every speed-dependent h its value;
* ``ambient_C`` (optional): the ambient air, driving every convection group without an
  ambient of its own;
* ``tilt_<sensor>_urad``: a tilt sensor of the scenario [µrad] (evidence).

``[dataset] displacement_zero`` says what the displacement and tilt channels are read
from: ``"reference"`` (the stress-free state at the reference temperature; the
default) or ``"first_row"`` (the probes zeroed at the start, as ISO 230-3 does); the
diagnosis and the replay then compare the model minus its first-row value.

Bad input is refused in one line (exit 2), before anything is written: a missing
scenario; a column naming a sensor or source the scenario lacks; a thermometer column
whose sensor is not a temperature point; displacements whose spread is under 1/100
of the nominal model's (mm declared as µm); a ``[diagnosis]`` group the mesh lacks.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from arfem.io import read_toml
from arfem.params import InputError
from arfem.strict import check_keys

__all__ = ["RecordFiles", "is_mesh_record", "refuse_mesh_record", "refuse_mesh_channels",
           "read_record_files", "record_toml_of", "DISPLACEMENT_ZERO", "displacement_zero",
           "RecordTable", "read_table", "write_record"]

_TOP = ("dataset", "model", "columns", "sensors")


@dataclass(frozen=True)
class RecordFiles:
    """The two files of a v3 record and the scenario it names."""

    toml: Path
    csv: Path
    scenario: Path
    name: str
    renames: dict
    displacement_zero: str = "reference"


def record_toml_of(path) -> Path:
    """The record's TOML: ``path`` itself, or the ``.toml`` beside a ``.csv``."""
    p = Path(path)
    return p.with_suffix(".toml") if p.suffix == ".csv" else p


def is_mesh_record(path) -> bool:
    """True when the record's TOML has a ``[model]`` table: a cheap text test, then
    (for a ``model = {...}`` inline table or a dotted key) the parsed document."""
    import tomllib

    from arfem.io import toml_has_table
    p = record_toml_of(path)
    if toml_has_table(p, "model"):
        return True
    if p.suffix != ".toml" or not p.is_file():
        return False
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):          # unreadable or malformed: the reader says why
        return False
    return isinstance(doc.get("model"), dict)


def refuse_mesh_record(path) -> None:
    """Refuse (one line) to read ``path`` as a record on the rod where its TOML names a
    mesh scenario (``[model]``, contract v3): such a record is diagnosed against that
    mesh (``arfem diagnose`` routes it; :func:`arfem.scenarios.geodiagnose.run_geodiagnosis`),
    never silently against the paper's rod."""
    if is_mesh_record(path):
        raise InputError("names a mesh scenario ([model]): a contract-v3 record is "
                         "diagnosed against that mesh (arfem diagnose RECORD.toml routes it "
                         "there), not by the rod's diagnosis", f"{record_toml_of(path)}: model")


def refuse_mesh_channels(ds) -> None:
    """Refuse (one line) a record read for the rod's diagnosis whose columns are a
    mesh model's displacement channels (``d_<sensor>_um``) while its TOML names no
    scenario: the rod's diagnosis would read only ``growth_um`` and cannot tell which
    model the channels belong to."""
    extra = getattr(ds, "extra_columns", None) or {}     # (a test's stand-in has none)
    chans = sorted(c for c in extra if c.startswith("d_") and c.endswith("_um"))
    if chans:
        raise InputError(f"has displacement channels ({', '.join(chans)}) but no [model] "
                         "table naming the mesh scenario they belong to: add [model] "
                         "scenario = \"<scenario>.toml\" (contract v3, docs/measured-data.md)"
                         "; a record on the rod has growth_um only", f"{ds.source}")


def read_record_files(path) -> RecordFiles:
    """Check the record's TOML (contract v3) and find its CSV and scenario."""
    p = record_toml_of(path)
    doc = read_toml(p)
    check_keys(doc, _TOP, f"{p}")
    ds = doc.get("dataset", {})
    if not isinstance(ds, dict):
        raise InputError("must be a table", f"{p}: dataset")
    check_keys(ds, ("name", "csv", "initial", "displacement_zero"), f"{p}: dataset")
    zero = displacement_zero(ds, f"{p}: dataset.displacement_zero")
    m = doc.get("model")
    if not isinstance(m, dict) or "scenario" not in m:
        raise InputError("needs scenario = \"<mesh scenario>.toml\"", f"{p}: model")
    check_keys(m, ("scenario",), f"{p}: model")
    if not isinstance(m["scenario"], str):
        raise InputError("must be a file name", f"{p}: model.scenario")
    sc = p.parent / m["scenario"]
    if not sc.is_file():
        raise InputError(f"scenario file {sc} not found", f"{p}: model.scenario")
    from arfem.scenarios.geometry_scenario import is_geometry_scenario
    if not is_geometry_scenario(sc):        # a rod scenario: say so, not "rod: unknown key"
        raise InputError(f"{sc} has no [geometry] table: a record with [model] is checked "
                         "against a mesh scenario (a rod record has no [model] table)",
                         f"{p}: model.scenario")
    csv = p.parent / str(ds.get("csv", p.with_suffix(".csv").name))
    if not csv.is_file():
        raise InputError(f"CSV file {csv} not found", f"{p}: dataset.csv")
    ren = doc.get("columns", {})
    if not isinstance(ren, dict) or not all(isinstance(v, str) for v in ren.values()):
        raise InputError("must map contract names to the CSV's column names", f"{p}: columns")
    return RecordFiles(p, csv, sc, str(ds.get("name", p.stem)), dict(ren), zero)


#: ``[dataset] displacement_zero``: where the displacement (and tilt) channels are read
#: from: the stress-free reference state (the default), or the first row (probes
#: zeroed at the start of the test, as ISO 230-3 does).
DISPLACEMENT_ZERO = ("reference", "first_row")


def displacement_zero(ds: dict, where: str) -> str:
    """The record's ``displacement_zero`` (:data:`DISPLACEMENT_ZERO`; default
    ``"reference"``), or one line naming ``where``."""
    v = ds.get("displacement_zero", "reference")
    if not isinstance(v, str) or v not in DISPLACEMENT_ZERO:
        raise InputError(f"must be \"reference\" (read from the stress-free state) or "
                         f"\"first_row\" (probes zeroed at the start), got {v!r}", where)
    return v


@dataclass(frozen=True)
class RecordTable:
    """The CSV's columns by contract name (renames applied), as float arrays."""

    columns: dict
    source: str


def read_table(files: RecordFiles) -> RecordTable:
    """Read the CSV (header row, ``.`` decimals, empty cells missing)."""
    import pandas as pd
    try:
        df = pd.read_csv(files.csv)
    except Exception as exc:                       # noqa: BLE001 (any parser error)
        raise InputError(f"cannot read the CSV ({exc.__class__.__name__}: "
                         f"{str(exc).splitlines()[0]})", str(files.csv)) from None
    back = {v: k for k, v in files.renames.items()}
    cols = {}
    for c in df.columns:
        name = back.get(str(c), str(c))
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        bad = np.flatnonzero(np.isnan(v) & df[c].notna().to_numpy())
        if bad.size:
            raise InputError(f"{df[c].iloc[bad[0]]!r} is not a number",   # header = line 1
                             f"{files.csv}: line {bad[0] + 2}, column {c}")
        cols[name] = v
    if "time_s" not in cols:
        raise InputError("missing column time_s", str(files.csv))
    t = cols["time_s"]
    if np.any(~np.isfinite(t)) or np.any(np.diff(t) <= 0) or t[0] < 0:
        i = int(np.flatnonzero(~np.isfinite(t) | np.concatenate([[t[0] < 0], np.diff(t) <= 0]))[0])
        raise InputError(f"row {i + 2}: time_s must be finite, >= 0 and strictly increasing",
                         f"{files.csv}: column time_s")
    return RecordTable(cols, str(files.csv))


def write_record(toml_path, scenario: str, columns: dict, name: str | None = None,
                 displacement_zero: str = "reference") -> Path:
    """Write a v3 record: ``<stem>.csv`` with ``columns`` ({contract name: values}) and
    ``<stem>.toml`` naming ``scenario`` (relative to the TOML); ``displacement_zero``
    written where it is not the default. Returns the TOML's path."""
    from arfem.io import atomic_write_text, write_csv
    p = Path(toml_path)
    write_csv(p.with_suffix(".csv"), {k: np.asarray(v, float) for k, v in columns.items()})
    zero = ("" if displacement_zero == "reference"
            else f'\ndisplacement_zero = "{displacement_zero}"')
    atomic_write_text(p, f'[dataset]\nname = "{name or p.stem}"\ncsv = "{p.with_suffix(".csv").name}"'
                         f'{zero}\n\n[model]\nscenario = "{scenario}"\n')
    return p
