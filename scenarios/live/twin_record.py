"""The twin's history (``arfem twin --record``) and what tests and benchmarks of the twin
need besides the command: a typed cycle, the record writer, a free port."""
from __future__ import annotations

import math
import socket
from dataclasses import dataclass
from pathlib import Path

from arfem.io import atomic_write_text
from arfem.models.twin import AxesReading, TwinReading

__all__ = ["TwinCycle", "AxesTwinCycle", "write_record", "free_port", "RECORD_COLUMNS"]

#: the columns of the record's CSV, in order
RECORD_COLUMNS = ("time_s", "growth_um", "speed_rpm", "q_W_m2", "ambient_C", "T_face_C",
                  "T_mid_C", "true_growth_um", "offset_um", "error_um", "alarm_set")


@dataclass(frozen=True)
class TwinCycle:
    """One interval of the twin server: the readings at its end, the offset a client
    wrote during it [µm], whether the alarm was set (1.0 or 0.0) and the error left,
    true growth + offset [µm]."""

    reading: TwinReading
    offset_um: float
    alarm_set: float
    error_um: float

    def as_dict(self) -> dict:
        """Column name → value (the readings, then offset, alarm and error)."""
        return {**self.reading.as_dict(), "offset_um": self.offset_um,
                "alarm_set": self.alarm_set, "error_um": self.error_um}


@dataclass(frozen=True)
class AxesTwinCycle:
    """One interval of a twin with several axes: the readings at its end, per axis the
    offset a client wrote during it [µm], whether its alarm was set (1.0 or 0.0), and
    the error left, true displacement + offset [µm] (``error_<AXIS>_um``)."""

    reading: AxesReading
    offsets_um: dict
    alarms_set: dict
    errors_um: dict

    def as_dict(self) -> dict:
        """Column name → value: the readings, then per axis offset, alarm and error."""
        return {**self.reading.as_dict(),
                **{f"offset_{ax}_um": v for ax, v in self.offsets_um.items()},
                **{f"alarm_{ax}_set": v for ax, v in self.alarms_set.items()},
                **self.errors_um}


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now (the OS's choice)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def write_record(directory, rows: list, name: str = "twin", scenario=None) -> None:
    """The twin's history (:class:`TwinCycle`, or bare :class:`TwinReading` with no
    offset) as a measured-data record (contract TOML + CSV), atomically; a NaN or absent
    reading is an empty cell, every number is written exactly (repr). ``scenario``: the
    ``[geometry]`` scenario served (``--scenario``), named by the record's ``[model]``
    table (contract v3, relative to the record where it can be) so that ``arfem
    diagnose`` checks the record against that mesh."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)

    def cell(v):
        return "" if v is None or not math.isfinite(v) else repr(float(v))
    axes = bool(rows) and isinstance(rows[0], AxesTwinCycle)
    columns = list(rows[0].as_dict()) if axes else RECORD_COLUMNS
    lines = [",".join(columns)]
    for r in rows:
        values = r.as_dict()
        lines.append(",".join(cell(values.get(c)) for c in columns))
    atomic_write_text(d / f"{name}.csv", "\n".join(lines) + "\n")
    what = ("# arfem twin: a [geometry] scenario's FEM served interval by interval; each\n"
            "# d_<sensor>_um = true displacement + sensor noise, growth_um = the Z axis's\n"
            if axes else
            "# arfem twin: FEM rod (Q2 axisymmetric, Crank-Nicolson) under a speed program with\n"
            "# a daily ambient swing; growth_um = true growth + sensor noise\n")
    model = ""
    if scenario is not None:
        import json
        import os
        sc, here = Path(scenario).resolve(), d.resolve()
        try:                                # relative where the two share a folder
            shared = os.path.commonpath([sc, here]) != sc.anchor
        except ValueError:                  # another drive (Windows)
            shared = False
        ref = os.path.relpath(sc, here) if shared else str(sc)
        model = f"\n[model]\nscenario = {json.dumps(Path(ref).as_posix())}\n"
    atomic_write_text(d / f"{name}.toml",
                      what + f'[dataset]\nname = "{name}"\ncsv = "{name}.csv"\n' + model)
