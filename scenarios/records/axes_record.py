"""A contract-v3 record (``docs/measured-data.md``, version 3) as the record a
several-axes replay steps through (``arfem compensate MODEL.json RECORD.toml``).

A v3 record names the mesh scenario it belongs to (``[model] scenario = ...``) and has
one column per displacement channel (``d_<sensor>_um``), no ``growth_um``; a version-2
model (one output per axis) predicts exactly those columns. :func:`load_axes_record`
reads it through the one record reader (:mod:`arfem.scenarios.records.georecord`: the TOML's
keys, the scenario file, the CSV's numbers, limits and ranges, and ``time_s``) and hands
:func:`arfem.scenarios.compensation.replay.replay` what it reads of a record: the time,
the inputs (``speed_rpm``, ``ambient_C``, ``T_<sensor>_C``) and every other column
(``P_<source>_W``, ``d_<sensor>_um``, …) as cells, an empty cell missing.

Its columns are checked against the scenario's sensors and sources by the one check
``arfem diagnose`` makes (:func:`arfem.scenarios.records.georecord.sensor_columns`: a
``d_``, ``tilt_`` or ``T_`` column naming no such sensor, a ``P_`` column naming no
source, is refused in one line); the replay then needs each of the model's inputs and
outputs to have its column, and refuses in one line, naming what the record has, when
one is missing (a speed that would give the sources' powers counted as giving them:
:attr:`AxesRecord.speed_powers`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from arfem.params import InputError

__all__ = ["AxesRecord", "load_axes_record", "require_axes_model"]


@dataclass(frozen=True)
class AxesRecord:
    """What a several-axes replay reads of a record (the attributes of
    :class:`arfem.scenarios.records.dataset.Dataset` it uses).

    Attributes
    ----------
    name : str
    time_s : ndarray (n,), sample times [s]
    speed_rpm, ambient_C : ndarray (n,) or None, [1/min], [°C]
    temperatures : dict, ``T_<sensor>_C`` → ndarray (n,) [°C]
    extra_columns : dict, every other column: a contract column's values (float, NaN
        missing), a column the contract does not know as its cells (str)
    line_numbers : tuple of int, the CSV line of each row
    csv_path : Path
    scenario : Path, the mesh scenario the record names
    speed_powers : tuple of str, the ``P_<source>_W`` that the scenario's speed laws (or
        its (speed, power) pairs) give from ``speed_rpm``: filled from the speed where
        the record has one, named as following from it where it has none
    """

    name: str
    time_s: np.ndarray
    speed_rpm: np.ndarray | None
    ambient_C: np.ndarray | None
    temperatures: dict
    extra_columns: dict
    line_numbers: tuple
    csv_path: Path
    scenario: Path
    q_W_m2: None = field(default=None)
    displacement_zero: str = "reference"     # or "first_row": probes zeroed at the start
    speed_powers: tuple = ()


def load_axes_record(path, limits=None) -> AxesRecord:
    """A contract-v3 record for a replay: ``path`` its TOML (or the CSV beside it), or a
    :class:`arfem.scenarios.records.georecord.MeshRecord` already read (nothing is read again).

    Raises
    ------
    InputError
        One line naming the file and key or column (the one record reader's refusals).
    """
    from arfem.scenarios.geometry.scenario import load_geometry_scenario
    from arfem.scenarios.records.georecord import MeshRecord, read_mesh_record, sensor_columns
    rec = path if isinstance(path, MeshRecord) else read_mesh_record(path, limits)
    doc = rec.files.doc
    sc = load_geometry_scenario(rec.files.scenario, limits,
                                toml=None if doc is None else doc.scenario_toml)
    sensor_columns(list(rec.table.columns) + list(rec.table.extra), sc, str(rec.files.csv))
    cols = dict(rec.table.columns)
    t = cols.pop("time_s")
    temps = {k: cols.pop(k) for k in list(cols) if k.startswith("T_") and k.endswith("_C")}
    speed = cols.pop("speed_rpm", None)
    amb = cols.pop("ambient_C", None)
    from_speed = _powers_from_speed(sc, cols, np.zeros(1) if speed is None else speed,
                                    str(rec.files.csv))
    if speed is not None:
        cols.update(from_speed)
    lines = rec.table.lines
    return AxesRecord(rec.files.name, t, speed, amb, temps, {**rec.table.extra, **cols},
                      tuple(int(x) for x in lines) if lines.size else
                      tuple(range(2, t.size + 2)), rec.files.csv, rec.files.scenario,
                      displacement_zero=rec.files.displacement_zero,
                      speed_powers=tuple(from_speed))


def _powers_from_speed(sc, cols: dict, speed: np.ndarray, where: str) -> dict:
    """``P_<source>_W`` for every source of the record's scenario ``sc`` that has no
    column, from the recorded speed (its speed law or its (speed, power) pairs:
    :func:`arfem.scenarios.geometry.scenario.source_power_at_speed`), so that a record of
    the speed alone drives every source; a source whose power the speed does not give
    is left out (the replay then names its missing column)."""
    from arfem.scenarios.geometry.scenario import source_power_at_speed
    out = {}
    for src in sc.sources:
        name = f"P_{src.spec.name}_W"
        if name in cols or src.spec.kind != "power":
            continue
        try:
            out[name] = source_power_at_speed(sc, src, speed, where)
        except InputError:
            continue
    return out


def require_axes_model(model, record: AxesRecord, where: str) -> None:
    """Refuse a version-1 model (one ``growth_um`` output) on a v3 record, whose
    displacement is one column per channel (one line naming the record's channels)."""
    if model.outputs:
        return
    chans = sorted(k for k in record.extra_columns if k.startswith("d_") and k.endswith("_um"))
    raise InputError("is a contract-v3 record (displacement channels "
                     f"{', '.join(chans) or 'none'}, no growth_um): replay it with a "
                     "version-2 model (one output per axis, e.g. the model.json of arfem run "
                     "on its scenario)", where)
