"""A JSON-lines gateway and its controller, in process, for fault tests of
``arfem compensate --live`` with ``transport = "jsonl"`` (issue 40).

:class:`Gateway` is the standard input and the standard output of
:func:`arfem.scenarios.live.jsonl.run_jsonl` at once. Each line it serves is the next
interval's reading, carrying what the controller holds (``controller_offset_um`` for a
one-axis model, ``controller_offsets_um`` per axis), as a gateway that reads the
controller back would send it; each answer it receives is written to the controller,
axis by axis, where its offset is a number (null: not to be written), and recorded with
what that axis held when it came.

Lockstep without threads: the loop reads a line, answers it, reads the next; the
gateway serves line n + 1 only after answer n was applied and ``on_advance(gateway, n)``
ran (it may change an axis's value behind the compensator's back, set one beyond the
clamp, or stop reporting an axis). Nothing depends on timing.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class AxisWrite:
    """One axis's offset written to the controller: answer n, axis (None: a one-axis
    model), the value and what the axis held when it came."""

    n: int
    axis: str | None
    value: float
    held_before_um: float


class Gateway:
    """``rows``: the readings (``time_s`` and the inputs), one per interval; ``held``:
    axis → what the controller holds at start (the key None for a one-axis model);
    ``report``: the axes whose value each line carries (default every axis)."""

    def __init__(self, rows: list, held: dict, *, on_advance=None, report=None):
        self.rows, self.held = rows, dict(held)
        self.report = set(held) if report is None else set(report)
        self.on_advance = on_advance
        self.k = 0                                   # lines served
        self.answers: list[dict] = []
        self.writes: list[AxisWrite] = []

    # ---- the loop's standard input
    def readline(self, size: int = -1) -> str:
        if self.k >= len(self.rows):
            return ""
        row = dict(self.rows[self.k])
        if None in self.report:
            row["controller_offset_um"] = self.held[None]
        else:
            row["controller_offsets_um"] = {ax: v for ax, v in self.held.items()
                                            if ax in self.report}
        self.k += 1
        return json.dumps(row) + "\n"

    # ---- the loop's standard output
    def write(self, text: str) -> None:
        for line in text.splitlines():
            if line.strip():
                self._apply(json.loads(line))

    def flush(self) -> None:
        pass

    def _apply(self, ans: dict) -> None:
        self.answers.append(ans)
        n = len(self.answers)
        offs = ({None: ans["offset_um"]} if "axes" not in ans
                else {ax: a["offset_um"] for ax, a in ans["axes"].items()})
        for ax, v in offs.items():
            if v is not None:                        # null: not to be written
                self.writes.append(AxisWrite(n, ax, float(v), self.held[ax]))
                self.held[ax] = float(v)
        if self.on_advance is not None:
            self.on_advance(self, n)

    # ---- what the tests measure
    def beyond(self, limits: dict) -> tuple[list, list]:
        """(writes beyond their axis's clamp, writes more than its step from what the
        axis held), ``limits`` axis → (clamp, step) [µm]; also every answer's offset
        counts against the clamp (a gateway might write any it is given)."""
        clamp = [w for w in self.writes
                 if not abs(w.value) <= limits[w.axis][0] + 1e-12]
        step = [w for w in self.writes
                if not abs(w.value - w.held_before_um) <= limits[w.axis][1] + 1e-9]
        for ans in self.answers:
            offs = ({None: ans["offset_um"]} if "axes" not in ans
                    else {ax: a["offset_um"] for ax, a in ans["axes"].items()})
            clamp += [(ax, v) for ax, v in offs.items()
                      if v is not None and not (math.isfinite(v)
                                                and abs(v) <= limits[ax][0] + 1e-12)]
        return clamp, step

    def alarms(self, n: int, axis: str | None = None) -> list:
        """The alarms of answer n (1-based), of ``axis`` where given."""
        ans = self.answers[n - 1]
        return ans["alarms"] if axis is None else ans["axes"][axis]["alarms"]

    def offset(self, n: int, axis: str | None = None):
        ans = self.answers[n - 1]
        return ans["offset_um"] if axis is None else ans["axes"][axis]["offset_um"]
