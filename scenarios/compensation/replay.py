"""The one replay of a compensator on a measured record, strictly causal, for one axis
or several.

The record is stepped through row by row, and every axis's offset for interval k is
computed by :meth:`arfem.models.compensator.Compensator.step` from the inputs of rows
up to k only (the same call every live transport makes), clamped and rate-limited by
that axis's limits. What is left on each axis after its offset is applied -- the
residual the seed paper's Fig. 8 shows -- is its measured displacement + its offset.

A version-1 model is one axis: its output ``growth_um`` is the record's growth (contract
v1/v2), the axis named after it (:data:`arfem.models.compensator.GROWTH_AXIS`,
``growth``). A version-2 model has one axis per output, each the record's
``d_<sensor>_um`` column (a contract-v3 record, or one ``arfem run`` writes beside its
``model.json``). Both run through the same loop, give the same :class:`Replay` and are
written by the same writer (:mod:`arfem.scenarios.compensation.report`).

``arfem compensate`` (:mod:`arfem.scenarios.commands.compensate`) writes a :class:`Replay`
to files; the FL_THERMAL compensation table, the mesh diagnosis, the benchmarks and the
tests call :func:`replay` directly.
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass

import numpy as np

from arfem.models.compensator import Compensator, StateSpaceModel
from arfem.params import InputError
from arfem.scenarios.records.georecord import refuse_unit_slip

__all__ = ["Replay", "ReplaySummary", "ReplaySeries", "AxisSummary", "AxisSeries",
           "ObserverSummary", "replay", "scored_from_s", "record_columns",
           "observer_readings", "axis_limits", "SCORE_BASES"]

#: How the first scored row was chosen (``ReplaySummary.score_basis``)
SCORE_BASES = ("after_fit_window", "no_fit_window", "given")


@dataclass(frozen=True)
class AxisSummary:
    """One axis of a replay: RMS and peak to peak of the measured displacement
    ("before") and of the residual ("after") over the scored rows [µm], the
    compensation rates 100 (1 − after/before) of both [%] (None where before is 0), the
    largest offset step [µm], this axis's limits [µm] (None: none) and the cycles it
    was clamped and rate-limited in. ``output`` is the record's column (``growth_um``
    for a version-1 model, ``d_<sensor>_um`` for a version-2 one)."""

    axis: str
    output: str
    rms_before_um: float
    rms_after_um: float
    peak_to_peak_before_um: float
    peak_to_peak_after_um: float
    compensation_rate_rms_pct: float | None
    compensation_rate_pp_pct: float | None
    largest_offset_step_um: float
    max_offset_um: float | None
    max_step_um: float | None
    cycles_clamped: int
    cycles_rate_limited: int


#: the figures of an axis (every field of :class:`AxisSummary` but its names): a
#: one-axis summary reads them as its own (``summary.rms_after_um``)
AXIS_FIGURES = tuple(f.name for f in dataclasses.fields(AxisSummary))[2:]


@dataclass(frozen=True)
class ObserverSummary:
    """What the thermometers' observer did in a replay.

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


class _OneAxis:
    """What a replay's summary and series have alike: their ``axes``, and for a one-axis
    replay that axis's fields (``_OWN``) read as their own."""

    _OWN: tuple = ()

    @property
    def axis(self):
        """The one axis of a one-axis replay (ValueError for several)."""
        if len(self.axes) != 1:
            raise ValueError(f"a replay of {len(self.axes)} axes has no one axis")
        return self.axes[0]

    def __getattr__(self, name):
        if name in type(self)._OWN:                # a one-axis replay's own
            return getattr(self.axis, name)
        raise AttributeError(name)


@dataclass(frozen=True)
class ReplaySummary(_OneAxis):
    """The figures of one replay (``summary.json``), per axis in ``axes``.

    ``score_basis`` says how ``score_from_s`` was chosen: ``after_fit_window`` (the
    first row after the model's ``fit_window_s``, the default), ``no_fit_window`` (the
    model carries none, so every row is scored) or ``given`` (``--score-from``).
    ``displacement_zero`` is the record's (``first_row``: the probes were zeroed at the
    first row, so each residual is counted from the first row), ``not_compensated`` the
    record's channels no axis compensates (its tilts ``tilt_<sensor>_urad``, and
    displacement columns the model does not predict). A one-axis replay (a version-1
    model) reads its axis's figures as its own: ``summary.rms_after_um``.
    """

    model_version: int
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
    probe_every_s: float | None = None
    n_probes: int = 0
    probe_gain_mean: float | None = None
    fit_window_s: tuple | None = None
    displacement_zero: str = "reference"
    not_compensated: tuple = ()
    #: the thermometers' observer; None for a model without one
    observer: ObserverSummary | None = None
    _OWN = AXIS_FIGURES

    def to_dict(self) -> dict:
        """The ``summary.json`` document: the replay's figures and ``axes``, one entry
        per axis; a version-1 model's also at the top level, where its summary.json has
        always had them (``rms_after_um``, ``compensation_rate_rms_pct``, …). No
        ``fit_window_s`` for a model without one, no ``observer`` for a model without
        one."""
        d = dataclasses.asdict(self)
        if self.model_version == 1:
            d.update({k: getattr(self.axis, k) for k in AXIS_FIGURES})
            d["axes"] = d.pop("axes")               # after the figures, as for several
        for key in ("fit_window_s", "observer"):
            if d[key] is None:
                del d[key]
        return d

    def score_window_text(self) -> str:
        """Which rows the figures are taken over, in words, for a headline.

        >>> s = ReplaySummary(1, "ar1", "", "r", 60.0, 10, 111132.0, 166680.0,
        ...                   "after_fit_window", 5, 0, (), fit_window_s=(0.0, 111072.0))
        >>> s.score_window_text()
        'scored on 30.9–46.3 h, the part not fitted'
        """
        span = f"{self.score_from_s / 3600:.1f}–{self.score_to_s / 3600:.1f} h"
        if self.score_basis == "after_fit_window":
            return f"scored on {span}, the part not fitted"
        if self.score_basis == "no_fit_window":
            return (f"scored on every row, {span} (the model carries no fit window, so "
                    "the rows it was fitted on, if any, are scored too)")
        if self.fit_window_s is not None and self.score_from_s <= self.fit_window_s[1]:
            return f"scored on {span}, which includes rows the model was fitted on"
        return f"scored on {span}"


@dataclass(frozen=True)
class AxisSeries:
    """One axis's per-row series, each (n,) [µm]: the record's displacement (its
    ``output`` column), the model's prediction (NaN on a first row at t = 0: no interval
    ends there), the offset written and the residual left."""

    axis: str
    output: str
    measured_um: np.ndarray
    predicted_um: np.ndarray
    offset_um: np.ndarray
    residual_um: np.ndarray


#: the per-row series of an axis (a one-axis series reads them as its own)
AXIS_SERIES = ("measured_um", "predicted_um", "offset_um", "residual_um")


@dataclass(frozen=True)
class ReplaySeries(_OneAxis):
    """The per-row series of a replay (``compensated.csv``): the time [s], the inputs
    (the model's, in its order, each the record's column in the unit the model's
    ``inputs`` state), one :class:`AxisSeries` per axis, and the observer's columns
    (``estimate_<input>_<unit>``, ``innovation_<thermometer>_K``; {} without one). A
    one-axis series reads its axis's series as its own: ``series.offset_um``."""

    time_s: np.ndarray
    inputs: dict
    axes: tuple
    observer: dict = dataclasses.field(default_factory=dict)
    _OWN = AXIS_SERIES

    def columns(self) -> dict:
        """``compensated.csv``: time, inputs, then per axis ``measured_<A>_um``,
        ``predicted_<A>_um``, ``offset_<A>_um``, ``residual_<A>_um``, then the
        observer's columns. A version-1 model's one axis keeps the names its file has
        always had: ``measured_growth_um``, ``predicted_growth_um``, ``offset_um``,
        ``residual_um``."""
        cols = {"time_s": self.time_s, **self.inputs}
        for a in self.axes:
            tag = "" if a.output == "growth_um" else f"_{a.axis}"
            cols.update({f"measured_{a.axis}_um": a.measured_um,
                         f"predicted_{a.axis}_um": a.predicted_um,
                         f"offset{tag}_um": a.offset_um,
                         f"residual{tag}_um": a.residual_um})
        return {**cols, **self.observer}


@dataclass(frozen=True)
class Replay:
    """One replay: its :class:`ReplaySummary` and its :class:`ReplaySeries`."""

    summary: ReplaySummary
    series: ReplaySeries


def _record_inputs(ds) -> dict:
    cols = {}
    for name in ("q_W_m2", "speed_rpm", "ambient_C"):
        v = getattr(ds, name, None)
        if v is not None:
            cols[name] = np.asarray(v, float)
    cols.update({k: np.asarray(v, float) for k, v in ds.temperatures.items()})
    return cols


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


def _missing_text(missing: list, have: set, ds) -> str:
    """What the record lacks, in one line. The powers its scenario gives from the speed
    (``speed_powers`` of a contract-v3 record) are not listed as needed beside a missing
    speed: the speed alone gives them."""
    from_speed = set(getattr(ds, "speed_powers", ()) or ())
    follow = [nm for nm in missing if nm in from_speed] if "speed_rpm" not in have else []
    has = ", ".join(sorted(have)) or "no column"
    if not follow:
        return (f"the model reads {', '.join(missing)}, which this record does not have "
                f"(it has {has})")
    rest = [nm for nm in missing if nm not in from_speed]
    them = "it" if len(follow) == 1 else "them"
    if "speed_rpm" in rest:
        return (f"the model reads {', '.join(rest)}, which this record does not have "
                f"(with speed_rpm, its scenario gives {', '.join(follow)} too; the record "
                f"has {has})")
    return (f"the model reads {', '.join(missing)}, which this record does not have (give "
            f"{them} as column{'s' if len(follow) > 1 else ''}, or speed_rpm, from which "
            f"its scenario gives {them}; the record has {has})")


def record_columns(model: StateSpaceModel, ds, where: str) -> tuple[dict, np.ndarray]:
    """(inputs, measured (n, p)): every input the model reads and each axis's measured
    column (``growth_um`` for a version-1 model), from the record; one line naming
    what the record lacks."""
    cols = _record_inputs(ds)
    growth = getattr(ds, "growth_um", None)
    have = set(cols) | set(getattr(ds, "extra_columns", None) or {}) | (
        {"growth_um"} if growth is not None else set())
    outs = [o.name for o in model.axis_outputs]
    missing = [nm for nm in [i.name for i in model.inputs] + outs if nm not in have]
    if missing:
        raise InputError(_missing_text(missing, have, ds), where)
    inputs = {i.name: (cols[i.name] if i.name in cols else _column(ds, i.name, where))
              for i in model.inputs}
    measured = np.column_stack([np.asarray(growth, float) if nm == "growth_um"
                                else _column(ds, nm, where) for nm in outs])
    return inputs, measured


def observer_readings(model: StateSpaceModel, ds, use_observer: bool) -> tuple:
    """(thermometer columns {name: (n,)}, why not): the record's readings of the model's
    observer's thermometers, or ({}, why the replay runs open loop: no observer,
    ``--no-observer``, or a thermometer the record lacks)."""
    if model.observer is None:
        return {}, "the model has no observer"
    if not use_observer:
        return {}, "--no-observer"
    have = dict(getattr(ds, "temperatures", None) or {})
    missing = [t for t in model.observer.thermometers if t not in have]
    if missing:
        return {}, f"the record has no {', '.join(missing)}"
    return {t: np.asarray(have[t], float) for t in model.observer.thermometers}, ""


def scored_from_s(model: StateSpaceModel, time_s, score_from_s: float | None
                  ) -> tuple[float, str]:
    """The first time [s] a replay scores, and why (one of :data:`SCORE_BASES`).

    ``score_from_s`` given: that time (``given``). None: the first row after the end of
    the model's ``fit_window_s`` (``after_fit_window``), so the figure is out of sample;
    for a model without a fit window (the paper's AR(1) from the rod's values), 0
    (``no_fit_window``).

    >>> from arfem.models.compensator import ar1_model
    >>> import dataclasses
    >>> m = dataclasses.replace(ar1_model(0.99, 1e-4, dtau_s=60.0), fit_window_s=(0.0, 120.0))
    >>> scored_from_s(m, [0.0, 60.0, 120.0, 180.0, 240.0], None)
    (180.0, 'after_fit_window')
    >>> scored_from_s(m, [0.0, 60.0], 0.0)
    (0.0, 'given')
    """
    if score_from_s is not None:
        return float(score_from_s), "given"
    if model.fit_window_s is None:
        return 0.0, "no_fit_window"
    t = np.asarray(time_s, float)
    after = t[t > float(model.fit_window_s[1])]
    # nothing after the window: score from past its end, which finds no row to score
    start = float(after[0]) if after.size else math.nextafter(float(model.fit_window_s[1]),
                                                              math.inf)
    return start, "after_fit_window"


@dataclass(frozen=True)
class _Stepped:
    """What stepping a compensator through a record gave: per row and axis the
    prediction and the offset [µm] (NaN and 0 before the first row stepped), the counts,
    the probes' gains and the observer's per-row estimates and innovations."""

    predicted_um: np.ndarray
    offset_um: np.ndarray
    held: int
    outside: int
    clamped: np.ndarray
    rate_limited: np.ndarray
    probe_gains: tuple
    probe_every_s: float | None
    estimates: np.ndarray | None
    innovations: np.ndarray | None
    thermometer_held: int


def _step_causally(comp: Compensator, inputs: dict, therm: dict, t, measured, first: int,
                   probe_every_s: float | None) -> _Stepped:
    """Step ``comp`` through rows ``first``… of the record: each row's offsets from the
    inputs (and thermometers) of rows up to it only, every axis by the same loop; a
    probe (the measured growth [µm] of the one axis) at every ``probe_every_s`` [s]."""
    (n, p), ob = measured.shape, (comp.model.observer if therm else None)
    preds, offs = [], []                        # per cycle, per axis (arrays at the end)
    clamped, limited = np.zeros(p, int), np.zeros(p, int)
    held = outside = t_held = 0
    est = np.full((n, ob.n_disturbances), np.nan) if ob else None
    innov = np.full((n, len(ob.thermometers)), np.nan) if ob else None
    next_probe = probe_every_s if probe_every_s else math.inf
    gains = []
    for k in range(first, n):
        values = {nm: col[k] for nm, col in inputs.items()}
        if therm:
            values.update({nm: (None if math.isnan(col[k]) else col[k])
                           for nm, col in therm.items()})
        cyc = comp.step(values)
        if cyc.observer is not None:
            est[k] = [v for _, _, v in cyc.observer.disturbances]
            innov[k] = [v for _, v in cyc.observer.innovations_K]
            t_held += bool(cyc.observer.held)
        elif ob is not None and k > first:          # a held cycle: the estimates stand
            est[k] = est[k - 1]
        held += cyc.held
        axes = cyc.per_axis()
        preds.append([a.predicted_um for a in axes])
        offs.append([a.offset_um for a in axes])
        if cyc.alarms:                              # (an axis's alarms are the cycle's too)
            outside += any(x.startswith("outside_schedule") for x in cyc.alarms)
            for j, a in enumerate(axes):
                clamped[j] += "clamped" in a.alarms
                limited[j] += "rate_limited" in a.alarms
        if t[k] >= next_probe:                       # a touch probe at this instant
            gains.append(comp.probe(float(measured[k, 0])))
            next_probe += probe_every_s
    pred, off = np.full((n, p), np.nan), np.zeros((n, p))
    if preds:
        pred[first:], off[first:] = preds, offs
    return _Stepped(pred, off, int(held), int(outside), clamped, limited, tuple(gains),
                    probe_every_s, est, innov, int(t_held))


def _check_interval(model: StateSpaceModel, t: np.ndarray, where: str) -> None:
    """Refuse a record whose median sample interval is not the model's Δτ (within 1 %)."""
    dt = np.diff(t)
    med = float(np.median(dt)) if dt.size else float("nan")
    if not (abs(med - model.dtau_s) <= 0.01 * model.dtau_s):
        raise InputError(f"is sampled every {med:g} s, the model steps every "
                         f"{model.dtau_s:g} s; make a model at the record's interval", where)


def _scored_rows(model, t, measured, first: int, start: float, basis: str, where: str):
    """The rows a replay scores: every axis measured, at or after ``start`` [s], an
    interval closed (from ``first``); refused in one line when there is none."""
    ok = np.all(np.isfinite(measured), axis=1) & (t >= start)
    ok[:first] = False
    if not ok.any():
        every = " with every axis measured" if measured.shape[1] > 1 else ""
        why = (f" (the end of the model's fit window, {model.fit_window_s[1]:g} s; score "
               "the fitted rows with --score-from 0)" if basis == "after_fit_window" else "")
        raise InputError(f"has no row at or after {start:g} s{every} to score{why}", where)
    return ok


def _axis_summary(spec, comp, j, g, resid, off, ok, clamped, limited) -> AxisSummary:
    def rms(x):
        return float(np.sqrt(np.mean(x[ok] ** 2)))

    def pp(x):
        return float(np.ptp(x[ok]))
    lim, step = comp.limits(j)
    return AxisSummary(
        axis=spec.axis, output=spec.name, rms_before_um=rms(g), rms_after_um=rms(resid),
        peak_to_peak_before_um=pp(g), peak_to_peak_after_um=pp(resid),
        compensation_rate_rms_pct=100.0 * (1.0 - rms(resid) / rms(g)) if rms(g) else None,
        compensation_rate_pp_pct=100.0 * (1.0 - pp(resid) / pp(g)) if pp(g) else None,
        largest_offset_step_um=float(np.max(np.abs(np.diff(off)))) if off.size > 1 else 0.0,
        max_offset_um=lim if math.isfinite(lim) else None,
        max_step_um=step if math.isfinite(step) else None,
        cycles_clamped=int(clamped), cycles_rate_limited=int(limited))


def _observer_parts(model, run: _Stepped, ok, why: str) -> tuple:
    """(ObserverSummary or None, the observer's compensated.csv columns)."""
    if model.observer is None:
        return None, {}
    if run.estimates is None:
        return ObserverSummary(False, why), {}
    ob, est = model.observer, run.estimates
    rows = est[ok & np.all(np.isfinite(est), axis=1)]
    dist = tuple({"input": d.input, "unit": d.unit, "final": float(est[-1, i]),
                  "mean_scored": float(np.mean(rows[:, i])),
                  "min_scored": float(np.min(rows[:, i])),
                  "max_scored": float(np.max(rows[:, i]))}
                 for i, d in enumerate(ob.disturbances))
    cols = {f"estimate_{d.input}_{'K' if d.unit == 'K' else d.unit.replace('/', '_')}":
            est[:, i] for i, d in enumerate(ob.disturbances)}
    cols.update({f"innovation_{t[:-2]}_K": run.innovations[:, i]
                 for i, t in enumerate(ob.thermometers)})
    return ObserverSummary(True, "", tuple(ob.thermometers), dist, run.thermometer_held), cols


def _not_compensated(model, ds) -> tuple:
    """The record's channels no axis compensates: its tilts and the displacement
    columns the model does not predict."""
    outs = {o.name for o in model.axis_outputs}
    return tuple(sorted(c for c in (getattr(ds, "extra_columns", None) or {})
                        if (c.startswith("tilt_") and c.endswith("_urad"))
                        or (c.startswith("d_") and c.endswith("_um") and c not in outs)))


def replay(model: StateSpaceModel, ds, *, max_offset_um=math.inf, max_step_um=math.inf,
           probe_every_s: float | None = None, score_from_s: float | None = None,
           where: str = "record", use_observer: bool = True) -> Replay:
    """Step ``model`` through the record ``ds`` causally, every axis; the series and
    the figures.

    Parameters
    ----------
    model : StateSpaceModel
        The compensator's model (``model.json``): version 1 (one axis, the growth) or 2
        (one axis per output).
    ds : Dataset or AxesRecord
        The measured record (:func:`arfem.scenarios.records.dataset.load_dataset`, or a
        contract-v3 record, :func:`arfem.scenarios.records.axes_record.load_axes_record`);
        its sample interval must be the model's ``dtau_s`` [s] (within 1 %).
    max_offset_um, max_step_um : float or tuple of float
        Each axis's clamp of the offset written and limit of its change per cycle [µm]
        (one for all, or one per axis).
    probe_every_s : float, optional
        Use the measured growth only every this many seconds, as a Kalman update (a
        version-1 model).
    score_from_s : float, optional
        The error measures are taken over the rows at or after this time [s]. None (the
        default): after the model's fit window (:func:`scored_from_s`), or every row for
        a model that carries none. The whole record is stepped through either way (the
        state starts at the model's ``x0`` at the first row).
    where : str
        Names the record in error messages.
    use_observer : bool
        Run the model's observer where it has one and the record has its thermometers
        (default); False: open loop (``--no-observer``).

    Returns
    -------
    Replay

    Raises
    ------
    InputError
        The model reads a column the record lacks, the sample intervals differ, a
        displacement's spread is under 1 % of the model's (mm declared as µm,
        :func:`arfem.scenarios.records.georecord.refuse_unit_slip`), no row is left to
        score, or probes are asked of a model with several axes.
    """
    if probe_every_s is not None and model.outputs:
        raise InputError("probe updates need a one-output (version 1) model",
                         "--probe-every")
    inputs, meas = record_columns(model, ds, where)
    t = np.asarray(ds.time_s, float)
    _check_interval(model, t, where)
    therm, why = observer_readings(model, ds, use_observer)
    comp = Compensator(model, max_offset_um=max_offset_um, max_step_um=max_step_um,
                       use_observer=bool(therm))
    # a first row at t = 0 is the equilibrium start, no interval ends there; a later
    # first row closes the interval that began at t = 0 (the contract), so it is stepped
    first = 1 if t[0] <= 0.0 else 0
    run = _step_causally(comp, inputs, therm, t, meas, first, probe_every_s)
    specs = model.axis_outputs
    for j, s in enumerate(specs):                # mm declared as µm: diagnose's one rule
        if s.name.startswith("d_"):
            refuse_unit_slip(s.name, meas[:, j], run.predicted_um[:, j], where)
    off = run.offset_um
    resid = meas + off
    if getattr(ds, "displacement_zero", "reference") == "first_row":
        resid = resid - off[:1]          # zeroed probes: the model minus its first row
    start, basis = scored_from_s(model, t, score_from_s)
    ok = _scored_rows(model, t, meas, first, start, basis, where)
    obs, ob_cols = _observer_parts(model, run, ok, why)
    axes = tuple(_axis_summary(s, comp, j, meas[:, j], resid[:, j], off[:, j], ok,
                               run.clamped[j], run.rate_limited[j])
                 for j, s in enumerate(specs))
    series = ReplaySeries(t, inputs, tuple(
        AxisSeries(s.axis, s.name, meas[:, j], run.predicted_um[:, j], off[:, j], resid[:, j])
        for j, s in enumerate(specs)), ob_cols)
    return Replay(_summary(model, ds, run, t, ok, first, start, basis, axes, obs), series)


def _summary(model, ds, run: _Stepped, t, ok, first: int, start: float, basis: str,
             axes: tuple, obs) -> ReplaySummary:
    """The replay's figures: its axes', the rows scored and the counts."""
    g = run.probe_gains
    return ReplaySummary(
        model.version, model.kind, model.description, ds.name, model.dtau_s,
        int(t.size - first), start, float(t[ok][-1]), basis, int(ok.sum()), run.held, axes,
        run.outside, run.probe_every_s, len(g), float(np.mean(g)) if g else None,
        None if model.fit_window_s is None else tuple(model.fit_window_s),
        getattr(ds, "displacement_zero", "reference"), _not_compensated(model, ds), obs)


def axis_limits(model, items, max_offset_um: float, max_step_um: float) -> tuple:
    """(max offsets, max steps) per axis of a version-2 model [µm] from ``--axis-limits
    AXIS=OFFSET:STEP`` items over the common limits; one line naming a bad item. A
    version-1 model's one axis takes the common limits (``--axis-limits`` refused).

    >>> from types import SimpleNamespace as N
    >>> m = N(outputs=(N(axis="X"), N(axis="Z")))
    >>> axis_limits(m, ["Z=20:0.5"], 50.0, 1.0)
    ((50.0, 20.0), (1.0, 0.5))
    """
    axes = [o.axis for o in model.outputs]
    if not axes:
        if items:
            raise InputError("is for a model with several axes (model_version 2)",
                             "--axis-limits")
        return max_offset_um, max_step_um
    off, step = [max_offset_um] * len(axes), [max_step_um] * len(axes)
    seen = set()
    for item in items or ():
        m = re.fullmatch(r"\s*([A-Za-z][A-Za-z0-9_]*)\s*=\s*([^:]+):(.+)", item)
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
