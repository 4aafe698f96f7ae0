"""The figures of an ISO 230-3 thermal test of a spindle: each quantity's drift over
time and its maxima over the test.

ISO 230-3 (*Test code for machine tools — Part 3: Determination of thermal effects*)
measures the thermal distortion caused by a rotating spindle with five probes (or
pairs of probes) on a test mandrel: the displacements along X, Y and Z and the tilts
A (about X) and B (about Y), all zeroed at the start of the test, while the spindle
runs at a constant speed and then stands still. It reports each quantity against
time and, per quantity, the largest drift over the test.

Here, per quantity (a record column ``d_<name>_um`` or ``tilt_<name>_urad``):

* the drift δ(t) = v(t) − v(t₀), from the first row (the probes' zero);
* ``max_abs`` the largest |δ| over the test and when it occurred;
* ``range`` max δ − min δ over the test (the band the quantity moved in);
* ``at_stop`` δ when the spindle stopped (the last row at n > 0 that a row at n = 0
  follows: the end of the running phase) and ``final`` δ at the end of the record. A
  record whose spindle never stops (it runs on its last row) or never runs has no
  stop: ``at_stop`` and ``stop_s`` are then None.

Pure (arrays in, frozen dataclasses out; layer ``models``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["QuantityDrift", "ThermalTest", "thermal_test", "quantity_columns"]


@dataclass(frozen=True)
class QuantityDrift:
    """One quantity's figures (units of its column: µm or µrad; times in h)."""

    column: str
    name: str
    unit: str
    max_abs: float
    max_abs_time_h: float
    range: float
    at_stop: float | None
    final: float


@dataclass(frozen=True)
class ThermalTest:
    """A thermal test's drifts and figures.

    Attributes
    ----------
    time_s : ndarray (n,)
    speed_rpm : ndarray (n,) or None
    drift : dict, column → δ (n,) from the first row
    quantities : tuple of QuantityDrift, in column order (displacements, then tilts)
    stop_s : float or None, when the spindle stopped (the last running row's time, where
        a stopped row follows it); None without a speed, or when the spindle never
        runs or still runs on the last row
    """

    time_s: np.ndarray
    speed_rpm: np.ndarray | None
    drift: dict
    quantities: tuple
    stop_s: float | None


def quantity_columns(columns) -> list:
    """The record columns a thermal test reports, displacements then tilts.

    >>> quantity_columns(["time_s", "tilt_A_urad", "d_X_um", "T_housing_C", "d_Z_um"])
    ['d_X_um', 'd_Z_um', 'tilt_A_urad']
    """
    cols = list(columns)
    return ([c for c in cols if c.startswith("d_") and c.endswith("_um")]
            + [c for c in cols if c.startswith("tilt_") and c.endswith("_urad")])


def _name_unit(column: str) -> tuple:
    if column.startswith("tilt_"):
        return column[5:-5], "µrad"
    return column[2:-3], "µm"


def thermal_test(time_s, columns: dict, speed_rpm=None) -> ThermalTest:
    """Drifts from the first row and the figures of every quantity in ``columns``.

    Parameters
    ----------
    time_s : array_like (n,)
        Sample times [s], increasing.
    columns : dict
        Column name → values (n,), µm (``d_*_um``) or µrad (``tilt_*_urad``); other
        columns are ignored; empty cells (NaN) are skipped.
    speed_rpm : array_like (n,), optional
        The spindle speed per row; the stop is the last row with n > 0, provided a
        row with n = 0 follows it (a spindle still running at the end has not stopped).

    Examples
    --------
    >>> t = np.arange(5) * 3600.0
    >>> tt = thermal_test(t, {"d_Z_um": np.array([2.0, -5.0, -9.0, -7.0, -4.0])},
    ...                   speed_rpm=np.array([8000.0, 8000.0, 8000.0, 0.0, 0.0]))
    >>> q = tt.quantities[0]
    >>> (q.name, q.max_abs, q.max_abs_time_h, q.range, q.at_stop, q.final)
    ('Z', -11.0, 2.0, 11.0, -11.0, -6.0)

    A test cut short while the spindle still runs has no stop:

    >>> thermal_test(t[:3], {"d_Z_um": np.array([0.0, -5.0, -9.0])},
    ...              speed_rpm=np.array([8000.0, 8000.0, 8000.0])).stop_s is None
    True
    """
    t = np.asarray(time_s, float)
    n = None if speed_rpm is None else np.asarray(speed_rpm, float)
    running = np.flatnonzero(n > 0) if n is not None else np.zeros(0, int)
    stop = int(running[-1]) if running.size and running[-1] < t.size - 1 else None
    drift, out = {}, []
    for c in quantity_columns(columns):
        v = np.asarray(columns[c], float)
        ok = np.isfinite(v)
        if not ok.any():
            continue
        d = v - v[ok][0]
        drift[c] = d
        k = int(np.nanargmax(np.abs(d)))
        name, unit = _name_unit(c)
        out.append(QuantityDrift(
            c, name, unit, float(d[k]), float(t[k] / 3600.0),
            float(np.nanmax(d) - np.nanmin(d)),
            None if stop is None or not np.isfinite(d[stop]) else float(d[stop]),
            float(d[ok][-1])))
    return ThermalTest(t, n, drift, tuple(out), None if stop is None else float(t[stop]))
