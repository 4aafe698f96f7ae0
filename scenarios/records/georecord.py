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
  ambient of its own.

Bad input is refused in one line (exit 2), before anything is written: a missing
scenario; a column naming a sensor or source the scenario lacks; a thermometer column
whose sensor is not a temperature point; displacements whose spread is under 1/100
of the nominal model's (mm declared as µm); a ``[diagnosis]`` group the mesh lacks.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from arfem.limits import Limits
from arfem.models.diagnosis.verdict import units_suspect
from arfem.params import InputError
from arfem.scenarios.records.dataset import (DISPLACEMENT_ZERO, RecordColumns, RecordDoc,
                                             ambient_filled_C, check_time_steps_s,
                                             displacement_zero, drop_missing_rows,
                                             input_complete, read_record_columns,
                                             read_record_doc, record_toml_of)

__all__ = ["RecordFiles", "is_mesh_record", "refuse_mesh_record", "refuse_mesh_channels",
           "read_record_files", "record_toml_of", "MeshRecord", "read_mesh_record",
           "DISPLACEMENT_ZERO", "displacement_zero",
           "RecordTable", "read_table", "write_record", "sensor_columns",
           "refuse_unit_slip"]


@dataclass(frozen=True)
class RecordFiles:
    """The two files of a v3 record and the scenario it names (``doc``: the TOML as
    read, with the scenario read beside it, passed along so nothing reads them again)."""

    toml: Path
    csv: Path
    scenario: Path
    name: str
    renames: dict
    doc: RecordDoc | None = field(default=None, repr=False, compare=False)
    displacement_zero: str = "reference"     # or "first_row": probes zeroed at the start


def is_mesh_record(path) -> bool:
    """True when the record's TOML has a ``[model]`` table: a cheap text test, then
    (for a ``model = {...}`` inline table or a dotted key) the parsed document. A
    command reads the record once (:func:`arfem.scenarios.records.dataset.read_record_doc`) and
    asks its :attr:`~arfem.scenarios.records.dataset.RecordDoc.is_mesh` instead."""
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
    """Refuse (one line) to read ``path`` (or a read :class:`RecordDoc`) as a record on
    the rod where its TOML names a mesh scenario (``[model]``, contract v3): such a
    record is diagnosed against that mesh (``arfem diagnose`` routes it;
    :func:`arfem.scenarios.diagnosis.mesh.run_geodiagnosis`), never silently against the
    paper's rod."""
    mesh = path.is_mesh if isinstance(path, RecordDoc) else is_mesh_record(path)
    if mesh:
        p = path.path if isinstance(path, RecordDoc) else record_toml_of(path)
        raise InputError("names a mesh scenario ([model]): a contract-v3 record is "
                         "diagnosed against that mesh (arfem diagnose RECORD.toml routes it "
                         "there), not by the rod's diagnosis", f"{p}: model")


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


def read_record_files(path, limits: Limits | None = None,
                      doc: RecordDoc | None = None) -> RecordFiles:
    """Check the record's TOML (contract v3) and find its CSV and scenario: the TOML and
    the scenario are read once (:func:`arfem.scenarios.records.dataset.read_record_doc`), or
    taken from ``doc``."""
    doc = read_record_doc(path, limits) if doc is None else doc
    if not doc.is_mesh:
        raise InputError("needs scenario = \"<mesh scenario>.toml\"", f"{doc.path}: model")
    if not doc.csv_path.is_file():
        raise InputError(f"CSV file {doc.csv_path} not found", f"{doc.path}: dataset.csv")
    return RecordFiles(doc.path, doc.csv_path, doc.scenario, doc.name, dict(doc.mapping), doc,
                       doc.displacement_zero)


@dataclass(frozen=True)
class RecordTable:
    """The CSV's columns by contract name (renames applied), as float arrays, each
    cell finite and within its physical range (empty cells NaN in a channel; an empty
    ambient cell filled, an empty time refused or its row dropped, as the contract
    says); ``extra``: the columns the contract does not know, as their cells; ``lines``:
    each row's CSV line; ``notes``: what the reader did."""

    columns: dict
    source: str
    lines: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    extra: dict = field(default_factory=dict)
    notes: tuple = ()


def read_table(files: RecordFiles, limits: Limits | None = None) -> RecordTable:
    """Read the CSV once (:func:`arfem.scenarios.records.dataset.read_record_columns`: every
    limit and range of the contract) and apply the missing-value rules of every
    version: rows with an empty ``time_s`` dropped (at most 5 %), ``time_s`` from >= 0
    strictly increasing, each input (``speed_rpm``, ``P_<source>_W``) on every row and
    >= 0, ``ambient_C``'s short gaps filled."""
    doc = files.doc if files.doc is not None else read_record_doc(files.toml, limits)
    rc: RecordColumns = read_record_columns(doc, limits)
    where = files.csv
    if "time_s" not in rc.values:
        raise InputError("missing column time_s", str(where))
    notes: list[str] = []
    values, lines, _, _ = drop_missing_rows(dict(rc.values), rc.lines, where, notes,
                                            keys=("time_s",))
    check_time_steps_s(values["time_s"], lines, where, rc.label)
    for k, v in values.items():
        if k == "speed_rpm" or (k.startswith("P_") and k.endswith("_W")):
            input_complete(v, k, lines, where, rc.label)
    amb = ambient_filled_C(values, values["time_s"], lines, where, rc.label, notes)
    if amb is None:
        values.pop("ambient_C", None)
    else:
        values["ambient_C"] = amb
    keep = np.isin(rc.lines, lines)
    extra = {h: np.asarray(v)[keep] for h, v in rc.extra.items()}
    return RecordTable(values, str(files.csv), lines, extra, tuple(notes))


@dataclass(frozen=True)
class MeshRecord:
    """A v3 record read once: its files (TOML, CSV, the scenario read) and its table."""

    files: RecordFiles
    table: RecordTable


def read_mesh_record(path, limits: Limits | None = None,
                     doc: RecordDoc | None = None) -> MeshRecord:
    """Read a v3 record (its TOML, or the CSV beside it) once: the TOML and its
    scenario, then the CSV (:func:`read_record_files`, :func:`read_table`)."""
    files = read_record_files(path, limits, doc)
    return MeshRecord(files, read_table(files, limits))


def sensor_columns(cols, sc, where: str) -> tuple[list, dict]:
    """(channel columns, {source: power column}) of a v3 record's columns ``cols``
    (names, or a mapping name → values) against its mesh scenario ``sc``: the one check
    of ``arfem diagnose`` and ``arfem compensate``. Refused, one line naming the column
    and what the scenario has: a ``tilt_<s>_urad``, ``d_<s>_um`` or ``T_<s>_C`` whose
    ``<s>`` is no tilt, displacement or temperature sensor of the scenario, a
    ``d_<s>_mm``, a ``P_<s>_W`` naming no heat source, and a record without any
    displacement column."""
    disp = [s.name for s in sc.sensors if s.quantity == "displacement"]
    temp = [s.name for s in sc.sensors if s.quantity == "temperature"]
    tilts = [s.name for s in sc.sensors if s.quantity == "tilt"]
    srcs = [s.spec.name for s in sc.sources]
    chans, power = [], {}
    for c in cols:
        if c.startswith("tilt_") and c.endswith("_urad"):      # a tilt: evidence
            if c[5:-5] not in tilts:
                raise InputError(f"names no tilt sensor of {sc.source} (its tilts: "
                                 f"{', '.join(tilts) or 'none'})", f"{where}: column {c}")
            chans.append(c)
            continue
        if c.startswith("d_") and c.endswith("_um"):
            if c[2:-3] not in disp:
                raise InputError(f"names no displacement sensor of {sc.source} (it has "
                                 f"{', '.join(disp) or 'none'})", f"{where}: column {c}")
            chans.append(c)
        elif c.startswith("d_") and c.endswith("_mm"):
            raise InputError("displacements are read in µm: give d_<sensor>_um", f"{where}: "
                             f"column {c}")
        elif c.startswith("T_") and c.endswith("_C") and c != "T_ambient_C":
            if c[2:-2] not in temp:
                raise InputError(f"thermometer column without a temperature sensor point "
                                 f"{c[2:-2]!r} in {sc.source} (its thermometers: "
                                 f"{', '.join(temp) or 'none'})", f"{where}: column {c}")
            chans.append(c)
        elif c.startswith("P_") and c.endswith("_W"):
            if c[2:-2] not in srcs:
                raise InputError(f"names no heat source of {sc.source} (it has "
                                 f"{', '.join(srcs)})", f"{where}: column {c}")
            power[c[2:-2]] = c
    if not any(c.startswith("d_") for c in chans):
        raise InputError("needs at least one displacement column d_<sensor>_um (sensors: "
                         f"{', '.join(disp)})", where)
    return chans, power


def refuse_unit_slip(column: str, measured_um, model_um, where: str) -> None:
    """Refuse a displacement column whose spread is out of proportion to its model's
    (``model_um``: the nominal model's response in ``arfem diagnose``, the compensator's
    prediction in ``arfem compensate``) where the model moves it by more than 1 µm:
    displacements in mm (or nm) declared as µm, by the verdict module's one rule
    (:func:`arfem.models.diagnosis.verdict.units_suspect`). One line naming the column;
    NaN cells are left out of both spreads.

    >>> import numpy as np
    >>> refuse_unit_slip("d_x_um", np.r_[0.0, 0.012], np.r_[0.0, 12.0], "r.csv")
    Traceback (most recent call last):
    ...
    arfem.params.InputError: r.csv: column d_x_um: spread 0.006 µm against the model's 6 µm: displacements in mm declared as µm?
    """
    sn = float(np.nanstd(model_um))
    sm = float(np.nanstd(measured_um))
    if sn > 1.0 and units_suspect(sm, sn):
        slip = "mm" if sm < sn else "nm"
        raise InputError(f"spread {sm:.3g} µm against the model's {sn:.3g} µm: "
                         f"displacements in {slip} declared as µm?", f"{where}: column {column}")


def write_record(toml_path, scenario: str, columns: dict, name: str | None = None) -> Path:
    """Write a v3 record: ``<stem>.csv`` with ``columns`` ({contract name: values}) and
    ``<stem>.toml`` naming ``scenario`` (relative to the TOML). Returns the TOML's path."""
    from arfem.io import atomic_write_text, write_csv
    p = Path(toml_path)
    write_csv(p.with_suffix(".csv"), {k: np.asarray(v, float) for k, v in columns.items()})
    atomic_write_text(p, f'[dataset]\nname = "{name or p.stem}"\ncsv = "{p.with_suffix(".csv").name}"'
                         f'\n\n[model]\nscenario = "{scenario}"\n')
    return p
