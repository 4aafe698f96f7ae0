"""The replay of a version-2 (several axes) compensator on a record, strictly causal.

As :func:`arfem.scenarios.compensation.replay.replay` for one axis: the record is stepped through row
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
import re
from dataclasses import dataclass

import numpy as np

from arfem.models.compensator import Compensator, StateSpaceModel
from arfem.params import InputError
from arfem.scenarios.compensation.replay import _check_interval, _record_inputs, scored_from_s

__all__ = ["axis_limits", "AxisSummary", "AxesSummary", "AxesSeries", "AxesReplay", "replay_axes",
           "record_columns", "ObserverSummary", "observer_readings"]


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
class ObserverSummary:
    """What the thermometers' observer did in a replay (issue 43).

    Attributes
    ----------
    on : bool
        Whether it ran.
    why : str
        Why it did not run ('' when it did): no observer in the model, ``--no-observer``,
        or thermometers the record lacks.
    thermometers : tuple of str
    disturbances : tuple of dict
        Per disturbance: ``input``, ``unit`` (W, W/m² or K), its estimate at the last
        cycle (``final``) and its mean, smallest and largest over the scored rows.
    cycles_thermometer_held : int
        Cycles in which at least one thermometer was held (missing, not finite, out of
        range): its correction was not made.
    """

    on: bool
    why: str = ""
    thermometers: tuple = ()
    disturbances: tuple = ()
    cycles_thermometer_held: int = 0


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
    #: the thermometers' observer (issue 43); None for a model without one
    observer: ObserverSummary | None = None

    def to_dict(self) -> dict:
        d = {"model_version": 2, **dataclasses.asdict(self),
             "axes": [dataclasses.asdict(a) for a in self.axes]}
        if self.observer is None:               # a model without one: as before
            del d["observer"]
        return d


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
    #: the observer's per-row columns (issue 43): ``estimate_<input>_<unit>`` (each
    #: disturbance's estimate, W or K) and ``innovation_<thermometer>_K`` (measured −
    #: predicted, empty where held); {} without an observer
    observer: dict = dataclasses.field(default_factory=dict)

    def columns(self) -> dict:
        """``compensated.csv``: time, inputs, then per axis ``measured_<A>_um``,
        ``predicted_<A>_um``, ``offset_<A>_um``, ``residual_<A>_um``, then the
        observer's columns."""
        cols = {"time_s": self.time_s, **self.inputs}
        for j, a in enumerate(self.axes):
            cols.update({f"measured_{a}_um": self.measured_um[:, j],
                         f"predicted_{a}_um": self.predicted_um[:, j],
                         f"offset_{a}_um": self.offset_um[:, j],
                         f"residual_{a}_um": self.residual_um[:, j]})
        return {**cols, **self.observer}


@dataclass(frozen=True)
class AxesReplay:
    summary: AxesSummary
    series: AxesSeries


def _column(ds, name: str, where: str) -> np.ndarray:
    """A carried column of the record as floats: empty cells NaN, anything else that
    is not a finite number refused naming the CSV's line and the column."""
    raw = ds.extra_columns[name]
    if np.asarray(raw).dtype.kind == "f":      # a contract column: read and checked already
        return np.asarray(raw, dtype=float)
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


def observer_readings(model: StateSpaceModel, ds, use_observer: bool) -> tuple:
    """(thermometer columns {name: (n,)}, why not): the record's readings of the model's
    observer's thermometers (issue 43), or ({}, why the replay runs open loop: no
    observer, ``--no-observer``, or a thermometer the record lacks)."""
    if model.observer is None:
        return {}, "the model has no observer"
    if not use_observer:
        return {}, "--no-observer"
    have = dict(getattr(ds, "temperatures", None) or {})
    missing = [t for t in model.observer.thermometers if t not in have]
    if missing:
        return {}, f"the record has no {', '.join(missing)}"
    return {t: np.asarray(have[t], float) for t in model.observer.thermometers}, ""


def _observer_columns(ob, est, innov) -> dict:
    """The observer's compensated.csv columns from per-row estimates and innovations."""
    cols = {f"estimate_{d.input}_{'K' if d.unit == 'K' else d.unit.replace('/', '_')}":
            est[:, i] for i, d in enumerate(ob.disturbances)}
    cols.update({f"innovation_{t[:-2]}_K": innov[:, i]
                 for i, t in enumerate(ob.thermometers)})
    return cols


def _observer_summary(ob, est, ok, held) -> ObserverSummary:
    rows = est[ok]
    dist = tuple({"input": d.input, "unit": d.unit, "final": float(est[-1, i]),
                  "mean_scored": float(np.mean(rows[:, i])),
                  "min_scored": float(np.min(rows[:, i])),
                  "max_scored": float(np.max(rows[:, i]))}
                 for i, d in enumerate(ob.disturbances))
    return ObserverSummary(True, "", tuple(ob.thermometers), dist, int(held))


def replay_axes(model: StateSpaceModel, ds, *, max_offset_um=math.inf,
                max_step_um=math.inf, score_from_s: float | None = None,
                where: str = "record", use_observer: bool = True) -> AxesReplay:
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
        As :func:`arfem.scenarios.compensation.replay.replay`.
    use_observer : bool
        Run the model's observer where it has one and the record has its thermometers
        (default); False: open loop (``--no-observer``).
    """
    inputs, meas = record_columns(model, ds, where)
    t = np.asarray(ds.time_s, float)
    _check_interval(model, t, where)
    therm, why = observer_readings(model, ds, use_observer)
    comp = Compensator(model, max_offset_um=max_offset_um, max_step_um=max_step_um,
                       use_observer=bool(therm))
    n, p = t.size, len(model.outputs)
    pred, off = np.full((n, p), np.nan), np.zeros((n, p))
    held = outside = 0
    clamped, limited = np.zeros(p, int), np.zeros(p, int)
    first = 1 if t[0] <= 0.0 else 0
    ob = model.observer if therm else None
    est = np.full((n, ob.n_disturbances), np.nan) if ob else None
    innov = np.full((n, len(ob.thermometers)), np.nan) if ob else None
    t_held = 0
    for k in range(first, n):
        cyc = comp.step({**{nm: col[k] for nm, col in inputs.items()},
                         **{nm: (None if math.isnan(col[k]) else col[k])
                            for nm, col in therm.items()}})
        if cyc.observer is not None:
            est[k] = [v for _, _, v in cyc.observer.disturbances]
            innov[k] = [v for _, v in cyc.observer.innovations_K]
            t_held += bool(cyc.observer.held)
        elif ob is not None and k > first:          # a held cycle: the estimates stand
            est[k] = est[k - 1]
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
    obs = None if model.observer is None else (
        _observer_summary(ob, est, ok & np.all(np.isfinite(est), axis=1), t_held) if ob
        else ObserverSummary(False, why))
    summary = AxesSummary(model.kind, model.description, ds.name, model.dtau_s,
                          int(n - first), start, float(t[ok][-1]), basis, int(ok.sum()),
                          int(held), axes, int(outside), obs)
    series = AxesSeries(t, inputs, model.axes, meas, pred, off, resid,
                        _observer_columns(ob, est, innov) if ob else {})
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


def axis_limits(model, items, max_offset_um: float, max_step_um: float) -> tuple:
    """(max offsets, max steps) per axis of a version-2 model [µm] from ``--axis-limits
    AXIS=OFFSET:STEP`` items over the common limits; one line naming a bad item.

    >>> from types import SimpleNamespace as N
    >>> m = N(outputs=(N(axis="X"), N(axis="Z")))
    >>> axis_limits(m, ["Z=20:0.5"], 50.0, 1.0)
    ((50.0, 20.0), (1.0, 0.5))
    """
    axes = [o.axis for o in model.outputs]
    off, step = [max_offset_um] * len(axes), [max_step_um] * len(axes)
    seen = set()
    for item in items or ():
        m = re.fullmatch(r"\s*([A-Za-z][A-Za-z0-9_]*)\s*=\s*([^:]+):(.+)", item)
        if not axes:
            raise InputError("is for a model with several axes (model_version 2)",
                             "--axis-limits")
        if not m or m.group(1) not in axes:
            raise InputError(f"must be AXIS=OFFSET:STEP with AXIS one of "
                             f"{', '.join(axes)}, got {item!r}", "--axis-limits")
        try:
            vals = float(m.group(2)), float(m.group(3))
        except ValueError:
            vals = (math.nan, math.nan)
        if not all(math.isfinite(v) and v > 0 for v in vals):
            raise InputError(f"needs two numbers > 0 [µm], got {item!r}", "--axis-limits")
        if m.group(1) in seen:             # two limits for one axis: which one is meant?
            raise InputError(f"axis {m.group(1)} is given more than once, got {item!r}",
                             "--axis-limits")
        seen.add(m.group(1))
        j = axes.index(m.group(1))
        off[j], step[j] = vals
    return tuple(off), tuple(step)
