"""The replay of a version-2 (several axes) compensator on a record, strictly causal.

As :func:`arfem.scenarios.replay.replay` for one axis: the record is stepped through row
by row with :meth:`arfem.models.compensator.Compensator.step` (the call every live
transport makes), each axis's offset from the inputs of rows up to k only, clamped and
rate-limited by that axis's limits; what is left on each axis is its measured
displacement + its offset.

The record is a measured-data record (``docs/measured-data.md``) whose CSV also holds
every input the model reads (``P_<source>_W``, ``ambient_C``, …) and every output it
predicts (``d_<sensor>_um``: the measured displacement along that axis); ``arfem run``
on a ``[geometry]`` scenario writes one (``record.toml``) beside its ``model.json``.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from arfem.models.compensator import Compensator, StateSpaceModel
from arfem.params import InputError
from arfem.scenarios.replay import _check_interval, _record_inputs, scored_from_s

__all__ = ["AxisSummary", "AxesSummary", "AxesSeries", "AxesReplay", "replay_axes",
           "record_columns"]


@dataclass(frozen=True)
class AxisSummary:
    """One axis of a replay: RMS and peak to peak of the measured displacement
    ("before") and of the residual ("after") over the scored rows [µm], the
    compensation rate 100 (1 − after/before) of the RMS [%] (None where before is 0),
    the largest offset step [µm], this axis's limits [µm] (None: none) and the cycles
    it was clamped and rate-limited in."""

    axis: str
    output: str
    rms_before_um: float
    rms_after_um: float
    peak_to_peak_before_um: float
    peak_to_peak_after_um: float
    compensation_rate_rms_pct: float | None
    largest_offset_step_um: float
    max_offset_um: float | None
    max_step_um: float | None
    cycles_clamped: int
    cycles_rate_limited: int


@dataclass(frozen=True)
class AxesSummary:
    """The figures of a several-axes replay (``summary.json``)."""

    model_kind: str
    model_description: str
    dataset: str
    dtau_s: float
    n_cycles: int
    score_from_s: float
    score_to_s: float
    score_basis: str
    n_scored: int
    cycles_held: int
    axes: tuple
    #: cycles whose speed lay beyond a speed schedule's table (the end's matrices used)
    cycles_outside_schedule: int = 0

    def to_dict(self) -> dict:
        return {"model_version": 2, **dataclasses.asdict(self),
                "axes": [dataclasses.asdict(a) for a in self.axes]}


@dataclass(frozen=True)
class AxesSeries:
    """Per-row series, each (n,): the inputs (model order), and per axis the measured
    displacement, the predicted one, the offset and the residual [µm]."""

    time_s: np.ndarray
    inputs: dict
    axes: tuple                  # axis names, in the model's order
    measured_um: np.ndarray      # (n, p)
    predicted_um: np.ndarray     # (n, p)
    offset_um: np.ndarray        # (n, p)
    residual_um: np.ndarray      # (n, p)

    def columns(self) -> dict:
        """``compensated.csv``: time, inputs, then per axis ``measured_<A>_um``,
        ``predicted_<A>_um``, ``offset_<A>_um``, ``residual_<A>_um``."""
        cols = {"time_s": self.time_s, **self.inputs}
        for j, a in enumerate(self.axes):
            cols.update({f"measured_{a}_um": self.measured_um[:, j],
                         f"predicted_{a}_um": self.predicted_um[:, j],
                         f"offset_{a}_um": self.offset_um[:, j],
                         f"residual_{a}_um": self.residual_um[:, j]})
        return cols


@dataclass(frozen=True)
class AxesReplay:
    summary: AxesSummary
    series: AxesSeries


def _column(ds, name: str, where: str) -> np.ndarray:
    """A carried column of the record as floats: empty cells NaN, anything else that
    is not a finite number refused naming the CSV's line and the column."""
    raw = ds.extra_columns[name]
    out = np.empty(raw.size)
    for i, cell in enumerate(raw):
        text = str(cell).strip()
        try:
            out[i] = float(text) if text else math.nan
        except ValueError:
            out[i] = math.inf
        if math.isinf(out[i]) or text.lower() == "nan":
            line = ds.line_numbers[i] if i < len(ds.line_numbers) else i + 2
            raise InputError(f"line {line}: column {name!r}: {text[:40]!r} is not a finite "
                             "number", str(ds.csv_path or where))
    return out


def record_columns(model: StateSpaceModel, ds, where: str) -> tuple[dict, np.ndarray]:
    """(inputs, measured (n, p)): every input the model reads and every output's
    measured column, from the record; one line naming what the record lacks."""
    cols = _record_inputs(ds)
    have = set(cols) | set(ds.extra_columns)
    need = [i.name for i in model.inputs] + [o.name for o in model.outputs]
    missing = [nm for nm in need if nm not in have]
    if missing:
        raise InputError(f"the model reads {', '.join(missing)}, which this record does not "
                         f"have (it has {', '.join(sorted(have)) or 'no column'})", where)
    inputs = {i.name: (cols[i.name] if i.name in cols else _column(ds, i.name, where))
              for i in model.inputs}
    measured = np.column_stack([_column(ds, o.name, where) for o in model.outputs])
    return inputs, measured


def replay_axes(model: StateSpaceModel, ds, *, max_offset_um=math.inf,
                max_step_um=math.inf, score_from_s: float | None = None,
                where: str = "record") -> AxesReplay:
    """Step a version-2 ``model`` through the record ``ds`` causally, every axis.

    Parameters
    ----------
    model : StateSpaceModel
        Version 2 (``outputs`` with their axes).
    ds : Dataset
        The record; sampled at the model's ``dtau_s`` [s] (within 1 %).
    max_offset_um, max_step_um : float or tuple of float
        Each axis's clamp and step limit [µm] (one for all, or one per axis).
    score_from_s : float, optional
        As :func:`arfem.scenarios.replay.replay`.
    """
    inputs, meas = record_columns(model, ds, where)
    t = np.asarray(ds.time_s, float)
    _check_interval(model, t, where)
    comp = Compensator(model, max_offset_um=max_offset_um, max_step_um=max_step_um)
    n, p = t.size, len(model.outputs)
    pred, off = np.full((n, p), np.nan), np.zeros((n, p))
    held = outside = 0
    clamped, limited = np.zeros(p, int), np.zeros(p, int)
    first = 1 if t[0] <= 0.0 else 0
    for k in range(first, n):
        cyc = comp.step({nm: col[k] for nm, col in inputs.items()})
        held += cyc.held
        outside += any(x.startswith("outside_schedule") for x in cyc.alarms)
        for j, a in enumerate(cyc.axes):
            pred[k, j], off[k, j] = a.predicted_um, a.offset_um
            clamped[j] += "clamped" in a.alarms
            limited[j] += "rate_limited" in a.alarms
    resid = meas + off
    if getattr(ds, "displacement_zero", "reference") == "first_row":
        resid = resid - off[:1]          # zeroed probes: the model minus its first row
    start, basis = scored_from_s(model, t, score_from_s)
    ok = np.all(np.isfinite(meas), axis=1) & (t >= start)
    ok[:first] = False
    if not ok.any():
        raise InputError(f"has no row at or after {start:g} s with every axis measured "
                         "to score", where)
    axes = tuple(_axis_summary(model, comp, j, meas[:, j], resid[:, j], off[:, j], ok,
                               int(clamped[j]), int(limited[j])) for j in range(p))
    summary = AxesSummary(model.kind, model.description, ds.name, model.dtau_s,
                          int(n - first), start, float(t[ok][-1]), basis, int(ok.sum()),
                          int(held), axes, int(outside))
    series = AxesSeries(t, inputs, model.axes, meas, pred, off, resid)
    return AxesReplay(summary, series)


def _axis_summary(model, comp, j, g, resid, off, ok, clamped, limited) -> AxisSummary:
    def rms(x):
        return float(np.sqrt(np.mean(x[ok] ** 2)))

    def pp(x):
        return float(np.ptp(x[ok]))
    lim, step = comp.limits(j)
    return AxisSummary(
        axis=model.outputs[j].axis, output=model.outputs[j].name, rms_before_um=rms(g),
        rms_after_um=rms(resid), peak_to_peak_before_um=pp(g),
        peak_to_peak_after_um=pp(resid),
        compensation_rate_rms_pct=100.0 * (1.0 - rms(resid) / rms(g)) if rms(g) else None,
        largest_offset_step_um=float(np.max(np.abs(np.diff(off)))) if off.size > 1 else 0.0,
        max_offset_um=lim if math.isfinite(lim) else None,
        max_step_um=step if math.isfinite(step) else None,
        cycles_clamped=clamped, cycles_rate_limited=limited)
