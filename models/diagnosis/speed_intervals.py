"""95 % intervals of the named cause's parameters on speed-only records.

The speed-only candidates (:mod:`arfem.models.diagnosis.speed`) are output-error fits of
a calibrated AR(1) whose parameters come from nested searches (grids, Nelder-Mead,
linear least squares inside) and, for a frame with thermometers, are derived summaries
of the fitted frame part (:func:`~arfem.models.diagnosis.speed_frame.fit_frame_thermometers`)
or medians over an ensemble of such fits (``FrameEnsemble``). None of them carries a
Jacobian, so the intervals come from refitting, with one method for all of them:

**Grouped (delete-a-block) jackknife.** The fit rows are cut into B contiguous blocks of
equal row count; the candidate is refitted with the same, already chosen structure on
the rows minus each block in turn (the free-run simulation still runs through the
deleted block: only its rows leave the objective), giving θ_1..θ_B. Then

    var(θ) = (B − 1)/B Σ_b (θ_b − θ̄)²,    θ̂ ± t_{0.975, B−1} √var,

with θ̂ the full fit. Contiguous blocks keep the residual's autocorrelation inside a
block, so the block values are nearly independent when a block is long against the
residual's correlation time (Künsch 1989, Ann. Statist. 17(3):1217-1241, the
delete-a-block jackknife for stationary observations; Carlstein 1986, Ann. Statist.
14(3):1171-1179; the grouped jackknife of Efron & Tibshirani 1993, *An Introduction to
the Bootstrap*, §11.5). As in :func:`arfem.models.diagnosis.candidates.parameter_ci95`,
each block is at least ``BLOCK_CORR`` correlation times of the fit's residual long
(the lag where its autocorrelation falls below 1/e), and ``MIN_BLOCKS`` <= B <=
``MAX_BLOCKS``; Student's t on B − 1 degrees of freedom accounts for the few blocks.
Where the model fits some stretches of the record differently from others (model
error, not noise) the refits disagree and the interval widens: it includes what the
data cannot tell apart, not only the noise. Positive quantities (time constants, h)
get the interval of their logarithm, exponentiated, cut to the values the fits can
return (:data:`SEARCH_RANGES`).

Why this and not a moving-block bootstrap of the residuals: a bootstrap needs ~200
refits for percentile ends where this needs B <= 10, and the frame searches take
seconds each; and a residual bootstrap resamples around the fitted model, so model
error that differs between stretches of the record would not widen it. Measured
coverage on generated records: ``benchmarks/bench_speed_intervals.py``.
"""
from __future__ import annotations

import numpy as np
from scipy import stats as _sst

from arfem.models.diagnosis import stats as st

__all__ = ["jackknife_ci95", "jackknife_blocks", "LOG_PARAMETERS", "SEARCH_RANGES", "MAX_BLOCKS",
           "MIN_BLOCKS", "BLOCK_CORR"]

#: most and fewest blocks of the jackknife
MAX_BLOCKS = 10
MIN_BLOCKS = 4
#: least block length in correlation times of the fit's residual
BLOCK_CORR = 5
#: contract parameters that are positive: intervals on the log scale
LOG_PARAMETERS = ("frame_time_constant_h", "h_running_W_m2K", "h_stopped_W_m2K")
#: values no speed-only fit can return (the union of the search ranges of every form:
#: 0.1-200 h for the thermometer frame's summary, 2-200 h for a slow frame response): an
#: interval is cut there, and one that reaches an end says the data do not bound the
#: parameter on that side
SEARCH_RANGES = {"frame_time_constant_h": (0.1, 200.0)}
#: an estimate within this fraction of an end of its search range sits at that end: the
#: refits cannot move past it, so the data do not bound the parameter on that side
EDGE_TOL = 0.01


def at_search_edge(name: str, value: float) -> bool:
    """Whether ``value`` of parameter ``name`` lies within ``EDGE_TOL`` of an end of
    the range a speed-only fit can return (:data:`SEARCH_RANGES`).

    Examples
    --------
    >>> at_search_edge("frame_time_constant_h", 199.9), at_search_edge("frame_time_constant_h", 12.7)
    (True, False)
    """
    lo, hi = SEARCH_RANGES.get(name, (None, None))
    return lo is not None and (value <= lo * (1 + EDGE_TOL) or value >= hi * (1 - EDGE_TOL))


def jackknife_blocks(residual) -> int:
    """Number of jackknife blocks B for a fit whose residual on the fit rows is given.

    Parameters
    ----------
    residual : array_like
        Measured − fitted growth on the fit rows, in time order [µm].

    Returns
    -------
    int
        B in [``MIN_BLOCKS``, ``MAX_BLOCKS``]: as many as keep each block at least
        ``BLOCK_CORR`` correlation times long.

    Examples
    --------
    >>> jackknife_blocks(np.random.default_rng(0).normal(size=1000))
    10
    >>> jackknife_blocks(np.sin(np.arange(1000) / 100.0))
    4
    """
    return st.contiguous_blocks(residual, BLOCK_CORR, MIN_BLOCKS, MAX_BLOCKS)


def jackknife_ci95(refit, fit, y, rows, names, blocks: int | None = None,
                   log_names=LOG_PARAMETERS, detail: dict | None = None) -> dict:
    """95 % intervals of ``fit``'s parameters ``names`` by the grouped jackknife.

    Parameters
    ----------
    refit : callable
        ``refit(rows_subset) -> CandidateFit or None``: the same candidate, with the same
        structure (speeds seen, mapping, frame structure), fitted on ``rows_subset``.
    fit : CandidateFit
        The fit on all of ``rows``; its parameters are the interval centres.
    y : array_like
        Measured growth [µm] (for the residual's correlation time).
    rows : ndarray of bool
        The fit rows.
    names : iterable of str
        Parameters of ``fit.parameters`` to give intervals for.
    blocks : int, optional
        B; default :func:`jackknife_blocks` of the fit's residual.
    log_names : iterable of str
        Parameters whose interval is made on the log scale (must be positive).
    detail : dict, optional
        Filled with ``blocks`` (B), ``refits`` (parameter -> the B refitted values) and
        ``not_bounded`` (parameter -> why the data do not bound it).

    Returns
    -------
    dict
        Parameter -> [low, high] in its unit; a parameter is left out where fewer than
        ``MIN_BLOCKS`` refits gave a finite value (or a log one a non-positive value).
        Where the data do not bound a parameter the interval says so instead of
        shrinking: an estimate at an end of its search range (:func:`at_search_edge`;
        its refits are held at that bound too, so their spread measures nothing) and
        refits that all return the same value (a part of the model switched off) give
        the whole search range, or no interval for a parameter without one.

    Examples
    --------
    The mean of AR(1) noise (true mean 0) with its refit, the mean without a block:

    >>> from types import SimpleNamespace as NS
    >>> from arfem.models.diagnosis.synth_speed import ar1_noise
    >>> e = ar1_noise(np.random.default_rng(0), 2000, 1.0, 0.8)
    >>> rows = np.ones(2000, bool)
    >>> def mean(r):
    ...     return NS(parameters={"m": float(e[r].mean())}, prediction=np.full(2000, e[r].mean()))
    >>> lo, hi = jackknife_ci95(mean, mean(rows), e, rows, ["m"])["m"]
    >>> bool(lo < 0.0 < hi)
    True
    """
    rows = np.asarray(rows, bool)
    idx = np.flatnonzero(rows)
    y = np.asarray(y, float)
    names = [k for k in names if k in fit.parameters]
    if not names or idx.size < 2 * MIN_BLOCKS:
        return {}
    B = blocks if blocks is not None else jackknife_blocks((y - fit.prediction)[rows])
    vals = _block_refits(refit, rows, idx, B, names)
    not_bounded = {}
    if detail is not None:
        detail.update(blocks=int(B), refits=vals, not_bounded=not_bounded)
    out = {}
    for k in names:
        ci = _jackknife_interval(k, np.asarray(vals[k], float), float(fit.parameters[k]),
                                 k in log_names, not_bounded)
        if ci is not None:
            out[k] = ci
    return out


def _block_refits(refit, rows, idx, B, names) -> dict:
    """Parameter -> its value refitted without each of ``B`` contiguous blocks of the fit
    rows ``idx`` (NaN where the refit failed or lacks it)."""
    vals = {k: [] for k in names}
    for part in np.array_split(idx, B):
        sub = rows.copy()
        sub[part] = False
        g = refit(sub)
        for k in names:
            v = None if g is None else g.parameters.get(k)
            vals[k].append(np.nan if v is None else float(v))
    return vals


def _jackknife_interval(k, v, est, log, not_bounded) -> list | None:
    """The grouped-jackknife 95 % interval [low, high] of parameter ``k`` (estimate
    ``est``, refits ``v``; on the log scale if ``log``), clipped to its search range, or
    None where too few refits are usable; records in ``not_bounded`` why the data do
    not bound it (see :func:`jackknife_ci95`)."""
    end_lo, end_hi = SEARCH_RANGES.get(k, (-np.inf, np.inf))
    fin = v[np.isfinite(v)]
    if fin.size >= MIN_BLOCKS and np.ptp(fin) <= 1e-9 * max(1.0, abs(est)):
        not_bounded[k] = "the refits without each block all returned the same value"
        return [end_lo, end_hi] if k in SEARCH_RANGES else None
    edge = at_search_edge(k, est)
    if edge:
        not_bounded[k] = "at the edge of its search range"
    if log:
        if est <= 0:
            return None
        v = np.log(np.where(v > 0, v, np.nan))
        est = np.log(est)
    v = v[np.isfinite(v)]
    if v.size < MIN_BLOCKS:
        return None
    b = v.size
    half = float(_sst.t.ppf(0.975, b - 1)) * np.sqrt((b - 1) / b * np.sum((v - v.mean()) ** 2))
    lo, hi = est - half, est + half
    lo, hi = (float(np.exp(lo)), float(np.exp(hi))) if log else (float(lo), float(hi))
    if edge:           # refits held at the bound: their spread says nothing
        lo, hi = end_lo, end_hi
    return [max(lo, end_lo), min(hi, end_hi)]
