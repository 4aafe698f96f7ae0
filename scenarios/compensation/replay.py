"""The replay of a compensator on a measured record, strictly causal.

The record is stepped through row by row, and the offset for interval k is computed by
:meth:`arfem.models.compensator.Compensator.step` from the inputs of rows up to k only
(the same call a live loop makes). What is left after the offset is applied -- the
residual the seed paper's Fig. 8 shows -- is measured growth + offset.

``arfem compensate`` (:mod:`arfem.scenarios.commands.compensate`) writes a :class:`Replay` to
files; the FL_THERMAL compensation table, the benchmarks and the tests call
:func:`replay` directly.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from arfem.models.compensator import Compensator, StateSpaceModel
from arfem.params import InputError
from arfem.scenarios.compensation.model_file import check_inputs

__all__ = ["Replay", "ReplaySummary", "ReplaySeries", "replay", "scored_from_s"]

#: How the first scored row was chosen (``ReplaySummary.score_basis``)
SCORE_BASES = ("after_fit_window", "no_fit_window", "given")


@dataclass(frozen=True)
class ReplaySummary:
    """The figures of one replay (``summary.json``; keys in this order).

    Error measures are over the scored rows (``time_s >= score_from_s``): RMS and peak
    to peak of the measured growth ("before") and of the residual ("after") [µm], and
    the compensation rates 100 (1 − after / before) [%] (None where "before" is 0).
    ``score_basis`` says how ``score_from_s`` was chosen: ``after_fit_window`` (the
    first row after the model's ``fit_window_s``, the default), ``no_fit_window`` (the
    model carries none, so every row is scored) or ``given`` (``--score-from``).
    """

    model_kind: str
    model_description: str
    dataset: str
    dtau_s: float
    n_cycles: int
    score_from_s: float
    n_scored: int
    rms_before_um: float
    rms_after_um: float
    peak_to_peak_before_um: float
    peak_to_peak_after_um: float
    compensation_rate_rms_pct: float | None
    compensation_rate_pp_pct: float | None
    largest_offset_step_um: float
    max_offset_um: float | None
    max_step_um: float | None
    cycles_held: int
    cycles_clamped: int
    cycles_rate_limited: int
    probe_every_s: float | None
    n_probes: int
    probe_gain_mean: float | None
    score_basis: str = "given"
    score_to_s: float = math.nan
    fit_window_s: tuple | None = None

    def to_dict(self) -> dict:
        """The ``summary.json`` document (the fit window as a list, or absent)."""
        d = dataclasses.asdict(self)
        if self.fit_window_s is None:
            del d["fit_window_s"]
        else:
            d["fit_window_s"] = [float(v) for v in self.fit_window_s]
        return d

    def score_window_text(self) -> str:
        """Which rows the figures are taken over, in words, for a headline.

        >>> s = ReplaySummary("ar1", "", "r", 60.0, 10, 111132.0, 5, *[1.0] * 4, 0.0,
        ...                   0.0, 0.0, None, None, 0, 0, 0, None, 0, None,
        ...                   "after_fit_window", 166680.0, (0.0, 111072.0))
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
class ReplaySeries:
    """The per-row series of a replay (``compensated.csv``), each of shape (n,).

    ``inputs`` maps each of the model's inputs, in its order, to the record's column
    (its unit as the model's ``inputs`` state). Growths, offset and residual in µm;
    ``predicted_growth_um`` is NaN on a first row at t = 0 (no interval ends there).
    """

    time_s: np.ndarray
    inputs: dict
    measured_growth_um: np.ndarray
    predicted_growth_um: np.ndarray
    offset_um: np.ndarray
    residual_um: np.ndarray

    def columns(self) -> dict:
        """Column name → values, in the order ``compensated.csv`` has them."""
        return {"time_s": self.time_s, **self.inputs,
                "measured_growth_um": self.measured_growth_um,
                "predicted_growth_um": self.predicted_growth_um,
                "offset_um": self.offset_um, "residual_um": self.residual_um}


@dataclass(frozen=True)
class Replay:
    """One replay: its :class:`ReplaySummary` and its :class:`ReplaySeries`."""

    summary: ReplaySummary
    series: ReplaySeries


def _record_inputs(ds) -> dict:
    cols = {}
    for name in ("q_W_m2", "speed_rpm", "ambient_C"):
        v = getattr(ds, name)
        if v is not None:
            cols[name] = np.asarray(v, float)
    cols.update({k: np.asarray(v, float) for k, v in ds.temperatures.items()})
    return cols


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
    """What stepping a compensator through a record gave, row by row and in counts."""

    predicted_um: np.ndarray
    offset_um: np.ndarray
    held: int
    clamped: int
    rate_limited: int
    probe_gains: tuple


def _step_causally(comp: Compensator, inputs: dict, t, g, first: int,
                   probe_every_s: float | None) -> _Stepped:
    """Step ``comp`` through rows ``first``… of the record: each row's offset from the
    inputs of rows up to it only, and a probe (the measured growth ``g`` [µm]) at every
    ``probe_every_s`` [s]; the predicted growth and offset [µm] per row (NaN and 0
    before ``first``)."""
    n = t.size
    pred, off = np.full(n, np.nan), np.zeros(n)
    held = clamped = limited = 0
    next_probe = probe_every_s if probe_every_s else math.inf
    gains = []
    for k in range(first, n):
        cyc = comp.step({nm: col[k] for nm, col in inputs.items()})
        pred[k], off[k] = cyc.predicted_growth_um, cyc.offset_um
        held += cyc.held
        clamped += "clamped" in cyc.alarms
        limited += "rate_limited" in cyc.alarms
        if t[k] >= next_probe:                       # a touch probe at this instant
            gains.append(comp.probe(float(g[k])))
            next_probe += probe_every_s
    return _Stepped(pred, off, int(held), int(clamped), int(limited), tuple(gains))


def _scored_rows(model, t, g, first: int, start: float, basis: str, where: str):
    """The rows a replay scores: a measured growth, at or after ``start`` [s], an
    interval closed (from ``first``); refused in one line when there is none."""
    ok = np.isfinite(g) & (t >= start)
    ok[:first] = False
    if not ok.any():
        why = (f" (the end of the model's fit window, {model.fit_window_s[1]:g} s; score "
               "the fitted rows with --score-from 0)" if basis == "after_fit_window" else "")
        raise InputError(f"has no row at or after {start:g} s to score{why}", where)
    return ok


def _check_interval(model: StateSpaceModel, t: np.ndarray, where: str) -> None:
    """Refuse a record whose median sample interval is not the model's Δτ (within 1 %)."""
    dt = np.diff(t)
    med = float(np.median(dt)) if dt.size else float("nan")
    if not (abs(med - model.dtau_s) <= 0.01 * model.dtau_s):
        raise InputError(f"is sampled every {med:g} s, the model steps every "
                         f"{model.dtau_s:g} s; make a model at the record's interval", where)


def replay(model: StateSpaceModel, ds, *, max_offset_um: float = math.inf,
           max_step_um: float = math.inf, probe_every_s: float | None = None,
           score_from_s: float | None = None, where: str = "record") -> Replay:
    """Step ``model`` through the dataset ``ds`` causally; the series and the figures.

    Parameters
    ----------
    model : StateSpaceModel
        The compensator's model (``model.json``).
    ds : Dataset
        The measured record (:func:`arfem.scenarios.records.dataset.load_dataset`); its sample
        interval must be the model's ``dtau_s`` [s] (within 1 %).
    max_offset_um, max_step_um : float
        Limits of the offset written [µm] and of its change per cycle [µm].
    probe_every_s : float, optional
        Use the measured growth only every this many seconds, as a Kalman update.
    score_from_s : float, optional
        The error measures are taken over the rows at or after this time [s]. None (the
        default): after the model's fit window (:func:`scored_from_s`), or every row for
        a model that carries none. The whole record is stepped through either way (the
        state starts at the model's ``x0`` at the first row).
    where : str
        Names the record in error messages.

    Returns
    -------
    Replay

    Raises
    ------
    InputError
        The model reads an input the record lacks, the sample intervals differ, or no
        row is left to score.
    """
    inputs = _record_inputs(ds)
    check_inputs(model, inputs, where)
    t = np.asarray(ds.time_s, float)
    _check_interval(model, t, where)
    g = np.asarray(ds.growth_um, float)
    comp = Compensator(model, max_offset_um=max_offset_um, max_step_um=max_step_um)
    names = [i.name for i in model.inputs]
    # a first row at t = 0 is the equilibrium start, no interval ends there; a later
    # first row closes the interval that began at t = 0 (the contract), so it is stepped
    first = 1 if t[0] <= 0.0 else 0
    run = _step_causally(comp, {nm: inputs[nm] for nm in names}, t, g, first, probe_every_s)
    n, pred, off, gains = t.size, run.predicted_um, run.offset_um, run.probe_gains
    held, clamped, limited = run.held, run.clamped, run.rate_limited
    resid = g + off
    start, basis = scored_from_s(model, t, score_from_s)
    ok = _scored_rows(model, t, g, first, start, basis, where)

    def rms(x):
        return float(np.sqrt(np.mean(x[ok] ** 2)))

    def pp(x):
        return float(np.ptp(x[ok]))

    summary = ReplaySummary(
        model_kind=model.kind, model_description=model.description, dataset=ds.name,
        dtau_s=model.dtau_s, n_cycles=int(n - first), score_from_s=start,
        n_scored=int(ok.sum()), rms_before_um=rms(g), rms_after_um=rms(resid),
        peak_to_peak_before_um=pp(g), peak_to_peak_after_um=pp(resid),
        compensation_rate_rms_pct=100.0 * (1.0 - rms(resid) / rms(g)) if rms(g) else None,
        compensation_rate_pp_pct=100.0 * (1.0 - pp(resid) / pp(g)) if pp(g) else None,
        largest_offset_step_um=float(np.max(np.abs(np.diff(off)))) if n > 1 else 0.0,
        max_offset_um=max_offset_um if math.isfinite(max_offset_um) else None,
        max_step_um=max_step_um if math.isfinite(max_step_um) else None,
        cycles_held=int(held), cycles_clamped=int(clamped), cycles_rate_limited=int(limited),
        probe_every_s=probe_every_s, n_probes=len(gains),
        probe_gain_mean=float(np.mean(gains)) if gains else None,
        score_basis=basis, score_to_s=float(t[ok][-1]),
        fit_window_s=None if model.fit_window_s is None else tuple(model.fit_window_s))
    series = ReplaySeries(time_s=t, inputs={nm: inputs[nm] for nm in names},
                          measured_growth_um=g, predicted_growth_um=pred, offset_um=off,
                          residual_um=resid)
    return Replay(summary, series)
