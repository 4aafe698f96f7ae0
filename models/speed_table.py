"""Matrices tabulated over the spindle speed, read at a speed: the one rule by which a
speed-scheduled ``model.json`` (:class:`arfem.models.compensator.SpeedSchedule`) and its
observer's gains (:class:`arfem.models.observer.Observer`) are interpolated."""
from __future__ import annotations

import numpy as np

__all__ = ["at_speed"]


def at_speed(speeds_rpm: np.ndarray, tables: tuple, speed_rpm: float) -> tuple:
    """Each of ``tables`` (arrays of shape (S, ...), one slice per tabulated speed) at
    ``speed_rpm`` [rpm]: linear in the speed between two tabulated speeds, a tabulated
    speed's own slice, the end's beyond them; and whether ``speed_rpm`` lies outside.

    Parameters
    ----------
    speeds_rpm : ndarray (S,)
        The tabulated speeds [rpm], increasing.
    tables : tuple of ndarray
        Each (S, ...).
    speed_rpm : float
        The speed to read them at [rpm].

    Returns
    -------
    (tuple of ndarray, bool)

    Examples
    --------
    >>> x = np.array([0.0, 1000.0]); A = np.array([[0.5], [0.9]])
    >>> (a,), out = at_speed(x, (A,), 250.0); float(a[0]), out
    (0.6, False)
    >>> (a,), out = at_speed(x, (A,), 2000.0); float(a[0]), out
    (0.9, True)
    """
    x = speeds_rpm
    v = float(speed_rpm)
    if v <= x[0] or v >= x[-1]:
        i = 0 if v <= x[0] else x.size - 1
        return tuple(M[i] for M in tables), bool(v < x[0] or v > x[-1])
    i = int(np.searchsorted(x, v, side="right")) - 1
    w = (v - x[i]) / (x[i + 1] - x[i])
    if w == 0.0:                                 # a tabulated speed: its own slice
        return tuple(M[i] for M in tables), False
    return tuple((1.0 - w) * M[i] + w * M[i + 1] for M in tables), False
