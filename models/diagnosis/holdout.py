"""The default hold-out of a diagnosis, one rule for every plant (issue 41: the rod and
the mesh had two): where the record is split into the window every fit sees and the
rows it is scored on.

Pure: arrays in, a start time and a sentence out.
"""
from __future__ import annotations

import numpy as np

__all__ = ["default_holdout"]


def default_holdout(t, u) -> tuple[float, str]:
    """The default hold-out start [s] and how it was chosen: the last third of the record
    if it contains a change of the input ``u`` (heating or cooling) whose response it
    sees for at least an hour; else the last such change that still leaves 40 % of the
    record to fit (the hold-out starts at the sample before it); else the last third."""
    t0, t1 = float(t[0]), float(t[-1])
    span = t1 - t0
    hs = t0 + span * 2.0 / 3.0
    u = np.asarray(u, float)
    idx = np.flatnonzero(u[1:] != u[:-1]) + 1          # first sample with the new input
    seen = idx[t[idx] <= t1 - max(3600.0, 0.05 * span)]
    late = seen[t[seen] >= hs]
    if late.size:
        return hs, (f"not given: the last third of the record (from 2/3 of its duration), "
                    f"which contains {late.size} change(s) of the input")
    early = seen[t[seen] >= t0 + 0.4 * span]
    if early.size:
        i = int(early[-1])
        kind = "heating" if u[i] > u[i - 1] else "cooling"
        start = float(t[i - 1])
        return start, (f"not given: the last third of the record (from {hs:g} s) holds no "
                       f"change of the input, so the hold-out starts at the last change that "
                       f"leaves >= 40 % of the record to fit ({kind} at {t[i - 1]:g} s)")
    return hs, ("not given: the last third of the record (from 2/3 of its duration); the "
                "record has no change of the input it could start at instead")
