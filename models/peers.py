"""Two models the field deploys, as peers of the extended model (issue 34).

* **Multi-input transfer functions**, in the manner of Mareš, Horejš et al., Precision
  Engineering 66 (2020): the growth is a constant plus, for each input (the spindle
  speed, a thermometer), that input through a first- or second-order discrete transfer
  function with real poles,

      G(z) = d + Σ_j c_j (1 − a_j) / (1 − a_j z⁻¹),     a_j = exp(−Δτ/τ_j),

  fitted by output error (simulation, no measured growth fed back); orders and inputs
  chosen by time-blocked cross-validation on the fit window
  (:func:`fit_transfer_functions`).
* **ARX** with the thermometers as exogenous inputs, identified by SysIdentPy's FROLS
  with a degree-1 polynomial basis and BIC order selection (:func:`fit_arx`); in
  compensation it runs in simulation mode (its own past predictions as y[k−1], y[k−2]),
  since a compensator does not measure the growth between probes.

Both return a typed fit and export a :class:`~arfem.models.compensator.StateSpaceModel`
(``model.json``) that reproduces the fitted model's simulation exactly, so that they are
replayed by the same causal compensator as every other model.

Convention for every array here: row 0 is the first interval the compensator steps;
before it the machine is at rest, at the ``reference`` input values (the state is 0 for
the transfer functions; the ARX starts from the given initial growth).

Pure: arrays in, dataclasses out; nothing here reads or writes a file.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from arfem.models.compensator import InputSpec, StateSpaceModel
from arfem.params import InputError

__all__ = ["TAU_GRID_H", "TFTerm", "TransferFunctionFit", "fit_transfer_functions",
           "tf_simulate", "tf_state_space", "ARXFit", "fit_arx", "arx_simulate",
           "arx_state_space"]

#: grid of time constants [h] the transfer-function poles are chosen on (PREREGISTRATION.md)
TAU_GRID_H = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
#: bounds [h] of the final refinement of the time constants
TAU_BOUNDS_H = (0.05, 100.0)


# ----------------------------------------------------------------------------------------
# transfer functions


@dataclass(frozen=True)
class TFTerm:
    """One input through its transfer function.

    Attributes
    ----------
    name, unit : str
        Input name as in the measured-data contract (``speed_rpm``, ``T_t3_C``) and unit.
    reference : float
        Value subtracted from the reading [input unit] (the machine at rest).
    taus_s : tuple of float
        Time constants τ_j of the real poles [s] (1: first order, 2: second order).
    gains : tuple of float
        DC gain c_j of each pole [µm per input unit].
    direct : float
        Direct term d [µm per input unit] (0 for the speed).
    """

    name: str
    unit: str
    reference: float
    taus_s: tuple
    gains: tuple
    direct: float = 0.0

    @property
    def order(self) -> int:
        return len(self.taus_s)


@dataclass(frozen=True)
class TransferFunctionFit:
    """A fitted multi-input transfer-function model.

    Attributes
    ----------
    terms : tuple of TFTerm
    d0_um : float
        Constant growth [µm].
    dtau_s : float
        Interval Δτ [s].
    fit_rms_um : float
        Simulation RMS on the fit rows [µm].
    cv_rms_um : float
        Time-blocked CV score of the chosen structure [µm] (before the final refit).
    selection : tuple of (str, int, float)
        The steps of the forward selection: (input, order, CV score [µm] after it).
    """

    terms: tuple
    d0_um: float
    dtau_s: float
    fit_rms_um: float
    cv_rms_um: float
    selection: tuple


def _lag(u, tau_s, dtau_s):
    """Unit-DC-gain first-order lag: x_k = a x_{k−1} + (1 − a) u_k, x_{−1} = 0."""
    a = np.exp(-dtau_s / tau_s)
    return lfilter([1.0 - a], [1.0, -a], u)


def _columns(u, taus_s, direct, dtau_s):
    cols = [_lag(u, t, dtau_s) for t in taus_s]
    if direct:
        cols.append(np.asarray(u, float))
    return cols


def _lstsq(cols, y, rows):
    X = np.column_stack([np.ones(y.size)] + list(cols))
    coef, *_ = np.linalg.lstsq(X[rows], y[rows], rcond=None)
    return coef, X @ coef


class _Blocks:
    """Least squares on sums of contiguous row blocks through per-block Gram matrices of
    standardised columns (the grid and CV search solve thousands of small problems on
    the same rows; a full QR each time was 60 ms at 6700 rows under load)."""

    def __init__(self, y, folds):
        self.y, self.masks = y, folds
        self.yy = np.array([float(y[m] @ y[m]) for m in folds])

    def grams(self, cols):
        X = np.column_stack([np.ones(self.y.size)] + list(cols))
        s = np.sqrt(np.mean(X ** 2, axis=0))
        s[s == 0] = 1.0
        X = X / s
        G = np.array([X[m].T @ X[m] for m in self.masks])
        h = np.array([X[m].T @ self.y[m] for m in self.masks])
        return G, h

    def sse(self, G, h, train, test=None):
        """SSE on the ``train`` blocks (and on ``test``) of the fit on ``train``."""
        Gt, ht = G[train].sum(0), h[train].sum(0)
        c, *_ = np.linalg.lstsq(Gt, ht, rcond=1e-12)
        out = float(self.yy[train].sum() - 2 * c @ ht + c @ Gt @ c)
        if test is None:
            return out
        return out, float(self.yy[test] - 2 * c @ h[test] + c @ G[test] @ c)


def _grid(order):
    g = [h * 3600.0 for h in TAU_GRID_H]
    return [(t,) for t in g] if order == 1 else list(itertools.combinations(g, 2))


def _best_taus(base_cols, u, order, direct, blk, train, cache):
    """Grid τ of one new input (``order`` poles) with the least squares on the blocks
    ``train`` (boolean per block)."""
    best = None
    for taus in _grid(order):
        cols = base_cols + [cache(u, t) for t in taus] + ([u] if direct else [])
        G, h = blk.grams(cols)
        sse = blk.sse(G, h, train)
        if best is None or sse < best[0]:
            best = (sse, taus)
    return best[1]


def _cv_score(base_cols, u, order, direct, blk, cache):
    """Time-blocked CV RMS [µm]: grid τ and gains fitted on 3 blocks (the τ with the
    least squares there), scored on the 4th; the RMS over the held-out blocks."""
    nb = len(blk.masks)
    sets = [()] if u is None else _grid(order)
    grams = [blk.grams(base_cols + [cache(u, t) for t in taus] + ([u] if direct else []))
             for taus in sets]
    sq = 0.0
    for i in range(nb):
        train = np.arange(nb) != i
        fits = [blk.sse(G, h, train, i) for G, h in grams]
        sq += min(fits)[1]
    n = sum(int(m.sum()) for m in blk.masks)
    return float(np.sqrt(max(sq, 0.0) / max(n, 1)))


def fit_transfer_functions(growth_um, inputs: dict, units: dict, *, dtau_s: float,
                           heat_source: str = "speed_rpm", reference: dict | None = None,
                           valid=None, n_blocks: int = 4, min_gain: float = 0.05,
                           max_added: int = 3, refine: bool = True) -> TransferFunctionFit:
    """Multi-input transfer functions, orders and inputs chosen by time-blocked CV.

    The procedure of PREREGISTRATION.md (2026-11-25): the heat source (``heat_source``,
    no direct term) with order 1 or 2, whichever has the lower CV score; then forward
    selection over the other inputs (each with a direct term, order 1 or 2), adding the
    one that lowers the CV score most, keeping the time constants already chosen, until
    the best addition lowers it by less than ``min_gain`` (relative) or ``max_added``
    inputs are in. Time constants on :data:`TAU_GRID_H`; the final structure is refitted
    on every valid row, its time constants refined by bounded least squares (``refine``).

    Parameters
    ----------
    growth_um : array_like
        Measured growth [µm] on the fit rows (row 0 is the first stepped interval).
    inputs : dict
        Input name → readings on the same rows [input unit] (raw; ``reference`` is
        subtracted). Must contain ``heat_source``.
    units : dict
        Input name → unit, for the exported model.
    dtau_s : float
        Interval Δτ [s].
    heat_source : str
        The input always in the model (the spindle speed [1/min]).
    reference : dict, optional
        Input name → value at rest [input unit], subtracted; default the first row's.
    valid : array_like of bool, optional
        Rows whose error counts in the fit (default: every finite growth).
    n_blocks : int
        Contiguous CV blocks of equal rows.
    min_gain : float
        Least relative decrease of the CV score for an input to be added.
    max_added : int
        Most inputs added besides the heat source.
    refine : bool
        Refine the final time constants off the grid.

    Returns
    -------
    TransferFunctionFit

    Examples
    --------
    >>> dt = 60.0
    >>> sp = np.repeat([0.0, 3000.0, 0.0, 5000.0, 1000.0], 300)
    >>> y = 2e-3 * _lag(sp, 3600.0, dt) + np.random.default_rng(0).normal(0, 0.01, sp.size)
    >>> f = fit_transfer_functions(y, {"speed_rpm": sp}, {"speed_rpm": "1/min"}, dtau_s=dt)
    >>> [round(t / 3600, 3) for t in f.terms[0].taus_s], round(f.terms[0].gains[0] * 1e3, 2)
    ([1.0], 2.0)
    """
    y = np.asarray(growth_um, float)
    ref, U = _referenced_inputs(y, inputs, heat_source, reference)
    valid = np.isfinite(y) if valid is None else (np.asarray(valid, bool) & np.isfinite(y))
    y = np.where(np.isfinite(y), y, 0.0)
    idx = np.flatnonzero(valid)
    folds = [np.isin(np.arange(y.size), b) for b in np.array_split(idx, n_blocks)]
    memo = {}

    def cache(u, tau):
        key = (id(u), tau)
        if key not in memo:
            memo[key] = _lag(u, tau, dtau_s)
        return memo[key]

    chosen, selection, cv = _forward_selection(U, heat_source, _Blocks(y, folds), cache,
                                               min_gain, max_added)
    terms, intercept, rms = _final_fit(chosen, U, y, valid, dtau_s, refine, units, ref)
    return TransferFunctionFit(terms, intercept, float(dtau_s), rms, float(cv),
                               tuple(selection))


def _final_fit(chosen: list, U: dict, y: np.ndarray, valid: np.ndarray, dtau_s: float,
               refine: bool, units: dict, ref: dict) -> tuple[tuple, float, float]:
    """The chosen structure refitted on every valid row, its time constants refined off
    the grid (``refine``): the terms, the intercept [µm] and the fit RMS [µm]."""
    taus_all = [t for _, taus, _ in chosen for t in taus]
    if refine:
        taus_all = _refine_taus(chosen, taus_all, U, y, valid, dtau_s)
    groups, k = [], 0
    for nm, taus, d in chosen:
        groups.append((nm, tuple(float(t) for t in taus_all[k:k + len(taus)]), d))
        k += len(taus)
    cols = [c for nm, ts, d in groups for c in _columns(U[nm], ts, d, dtau_s)]
    coef, pred = _lstsq(cols, y, valid)
    terms, j = [], 1
    for nm, ts, d in groups:
        p = len(ts)
        gains = tuple(float(c) for c in coef[j:j + p])
        direct = float(coef[j + p]) if d else 0.0
        j += p + (1 if d else 0)
        terms.append(TFTerm(nm, str(units.get(nm, "")), ref[nm], ts, gains, direct))
    rms = float(np.sqrt(np.mean((y[valid] - pred[valid]) ** 2)))
    return tuple(terms), float(coef[0]), rms


def _referenced_inputs(y: np.ndarray, inputs: dict, heat_source: str,
                       reference: dict | None) -> tuple[dict, dict]:
    """Each input's value at rest (``reference``, default its first reading) and the
    readings less it; an :class:`InputError` for a missing heat source or an input not
    finite or not as long as the growth."""
    if heat_source not in inputs:
        raise InputError(f"needs the heat source {heat_source!r}", "inputs")
    ref = {k: float(np.asarray(v, float)[0]) for k, v in inputs.items()}
    ref.update(reference or {})
    U = {k: np.asarray(v, float) - ref[k] for k, v in inputs.items()}
    for k, v in U.items():
        if v.shape != y.shape or not np.all(np.isfinite(v)):
            raise InputError("must be finite and as long as the growth", f"inputs: {k}")
    return ref, U


def _forward_selection(U: dict, heat_source: str, blk, cache, min_gain: float,
                       max_added: int) -> tuple[list, list, float]:
    """The preregistered structure search: the heat source with order 1 or 2 (lower CV
    score; a tie to the lower order), then the other inputs added one at a time while
    the best lowers the CV score by at least ``min_gain``. Returns the chosen terms
    (name, time constants [s] on the grid, direct term), the selection steps (name,
    order, CV score) and the final CV score."""
    every = np.ones(len(blk.masks), bool)
    hs = U[heat_source]
    scores = {o: _cv_score([], hs, o, False, blk, cache) for o in (1, 2)}
    # a tie (within 1e-6 relative or 1e-9 µm) goes to the lower order
    o_hs = 2 if scores[2] < (1.0 - 1e-6) * scores[1] - 1e-9 else 1
    chosen = [(heat_source, _best_taus([], hs, o_hs, False, blk, every, cache), False)]
    cv = scores[o_hs]
    selection = [(heat_source, o_hs, cv)]

    def base():
        return [c for nm, taus, d in chosen for c in
                [cache(U[nm], t) for t in taus] + ([U[nm]] if d else [])]

    while len(chosen) - 1 < max_added:
        cand = None
        for nm in U:
            if nm == heat_source or any(nm == c[0] for c in chosen):
                continue
            for o in (1, 2):
                s = _cv_score(base(), U[nm], o, True, blk, cache)
                if cand is None or s < cand[0]:
                    cand = (s, nm, o)
        if cand is None or cand[0] > (1.0 - min_gain) * cv:
            break
        cv, nm, o = cand
        chosen.append((nm, _best_taus(base(), U[nm], o, True, blk, every, cache), True))
        selection.append((nm, o, cv))
    return chosen, selection, cv

def _refine_taus(chosen, taus0, U, y, valid, dtau_s):
    """Bounded least squares on log τ, gains by linear least squares (variable projection)."""
    from scipy.optimize import least_squares
    lo, hi = (np.log(h * 3600.0) for h in TAU_BOUNDS_H)

    def resid(logt):
        cols, k = [], 0
        for nm, taus, d in chosen:
            cols += _columns(U[nm], np.exp(logt[k:k + len(taus)]), d, dtau_s)
            k += len(taus)
        _, pred = _lstsq(cols, y, valid)
        return (y - pred)[valid]

    x0 = np.clip(np.log(np.asarray(taus0, float)), lo + 1e-9, hi - 1e-9)
    sol = least_squares(resid, x0, bounds=(lo, hi), x_scale=1.0, diff_step=1e-4,
                        max_nfev=200)
    if np.sum(resid(sol.x) ** 2) <= np.sum(resid(x0) ** 2):
        return [float(v) for v in np.exp(sol.x)]
    return [float(v) for v in taus0]


def tf_simulate(fit: TransferFunctionFit, inputs: dict) -> np.ndarray:
    """The fitted transfer functions' growth [µm] on rows of raw ``inputs`` (row 0 the
    first stepped interval, the machine at rest before it).

    Examples
    --------
    >>> f = TransferFunctionFit((TFTerm("speed_rpm", "1/min", 0.0, (60.0,), (1e-3,)),),
    ...                         0.5, 60.0, 0.0, 0.0, ())
    >>> tf_simulate(f, {"speed_rpm": np.array([1000.0, 1000.0])}).round(4).tolist()
    [1.1321, 1.3647]
    """
    out = None
    for tm in fit.terms:
        u = np.asarray(inputs[tm.name], float) - tm.reference
        y = tm.direct * u
        for tau, c in zip(tm.taus_s, tm.gains):
            y = y + c * _lag(u, tau, fit.dtau_s)
        out = y if out is None else out + y
    return out + fit.d0_um


def tf_state_space(fit: TransferFunctionFit, *, R_um2: float = 0.0, description: str = "",
                   arfem_version: str = "") -> StateSpaceModel:
    """The transfer functions as one diagonal state space: a state per pole,
    A = diag(a_j), B = (1 − a_j) into the pole's input, C = c_j, D = d_i, the references
    as ``input_offsets``. Q = 0 (output error: no noise model, a probe changes nothing).

    Examples
    --------
    >>> f = TransferFunctionFit((TFTerm("speed_rpm", "1/min", 0.0, (60.0,), (1e-3,)),),
    ...                         0.5, 60.0, 0.0, 0.0, ())
    >>> m = tf_state_space(f)
    >>> round(float(m.A[0, 0]), 6), round(float(m.B[0, 0]), 6)
    (0.367879, 0.632121)
    """
    n = sum(t.order for t in fit.terms)
    m = len(fit.terms)
    A, B, C, D = np.zeros((n, n)), np.zeros((n, m)), np.zeros((1, n)), np.zeros((1, m))
    j = 0
    for i, tm in enumerate(fit.terms):
        for tau, c in zip(tm.taus_s, tm.gains):
            a = np.exp(-fit.dtau_s / tau)
            A[j, j], B[j, i], C[0, j] = a, 1.0 - a, c
            j += 1
        D[0, i] = tm.direct
    kind = "transfer_functions:" + "+".join(f"{t.name}/{t.order}" for t in fit.terms)
    return StateSpaceModel(
        kind=kind, dtau_s=fit.dtau_s, A=A, B=B, C=C, D=D,
        inputs=tuple(InputSpec(t.name, t.unit) for t in fit.terms), x0=np.zeros(n),
        d0_um=fit.d0_um, Q=0.0, R=float(R_um2), description=description,
        arfem_version=arfem_version,
        input_offsets={t.name: t.reference for t in fit.terms if t.reference != 0.0})


# ----------------------------------------------------------------------------------------
# ARX


@dataclass(frozen=True)
class ARXFit:
    """A linear ARX y_k = Σ a_i y_{k−i} + Σ_j Σ_l b_jl u_j[k−l] + c, with u_j = (reading −
    reference) · scale.

    Attributes
    ----------
    a : tuple of float
        a_1 … a_na (na = the largest output lag chosen; 0 where a lag is not chosen).
    b : dict
        Input name → tuple b_j1 … b_jL [µm per scaled input unit].
    c_um : float
        Constant [µm].
    names, units : tuple of str
        Inputs with at least one chosen lag, and their units.
    reference, scale : dict
        Input name → value at rest (subtracted) and factor applied to the reading minus it.
    dtau_s : float
        Interval Δτ [s].
    terms : tuple of str
        The regressors SysIdentPy chose, in its order (e.g. ``y(k-1)``, ``T_t3_C(k-2)``).
    one_step_rms_um : float
        RMS of the one-step-ahead residual on the fit rows [µm].
    """

    a: tuple
    b: dict
    c_um: float
    names: tuple
    units: tuple
    reference: dict
    scale: dict
    dtau_s: float
    terms: tuple
    one_step_rms_um: float

    @property
    def max_lag(self) -> int:
        return max([len(self.a)] + [len(v) for v in self.b.values()] + [1])

    @property
    def stable(self) -> bool:
        """True if every root of z^na − Σ a_i z^{na−i} is inside the unit circle."""
        if not any(self.a):
            return True
        return bool(np.max(np.abs(np.roots(np.r_[1.0, -np.asarray(self.a)]))) < 1.0)


def _sysidentpy_frols(y, X, ylag, xlag, n_info_values):
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.parameter_estimation import LeastSquares
    m = X.shape[1]
    model = FROLS(order_selection=True, n_info_values=n_info_values, info_criteria="bic",
                  ylag=ylag, xlag=[list(range(1, xlag + 1))] * m if m > 1 else
                  list(range(1, xlag + 1)), basis_function=Polynomial(degree=1),
                  estimator=LeastSquares(), model_type="NARMAX")
    model.fit(X=X, y=y[:, None])
    return model


def fit_arx(growth_um, inputs: dict, units: dict, *, dtau_s: float, ylag: int = 2,
            xlag: int = 2, n_info_values: int = 20, reference: dict | None = None,
            scale: dict | None = None, return_model: bool = False):
    """Linear ARX identified by SysIdentPy's FROLS, the number of terms by BIC.

    Candidate regressors: y[k−1] … y[k−ylag], u_j[k−1] … u_j[k−xlag] for every input,
    and a constant (SysIdentPy's degree-1 ``Polynomial`` basis); the terms are ranked by
    their error reduction ratio and their number chosen by BIC (``info_criteria="bic"``,
    up to ``n_info_values``); parameters by least squares (one step ahead).

    Parameters
    ----------
    growth_um : array_like
        Growth [µm] on the fit rows.
    inputs : dict
        Input name → raw readings on the same rows.
    units : dict
        Input name → unit.
    dtau_s : float
        Interval Δτ [s].
    ylag, xlag : int
        Largest output and input lags.
    reference : dict, optional
        Input name → value at rest, subtracted (default: the first row's).
    scale : dict, optional
        Input name → factor applied after the reference (default 1; e.g. 1e-3 to give
        the speed in 1000/min for the conditioning of the regression).
    return_model : bool
        Also return SysIdentPy's fitted model (for its own simulation, in the tests).

    Returns
    -------
    ARXFit (, sysidentpy model)
    """
    y = np.asarray(growth_um, float)
    names = list(inputs)
    ref = {k: float(np.asarray(inputs[k], float)[0]) for k in names}
    ref.update(reference or {})
    sc = {k: 1.0 for k in names}
    sc.update(scale or {})
    X = np.column_stack([(np.asarray(inputs[k], float) - ref[k]) * sc[k] for k in names])
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))):
        raise InputError("the ARX needs finite growth and inputs on every fit row", "inputs")
    model = _sysidentpy_frols(y, X, ylag, xlag, n_info_values)
    codes = np.asarray(model.final_model).reshape(len(model.theta), -1)
    theta = np.asarray(model.theta, float).ravel()
    a, b, c, labels = {}, {}, 0.0, []
    for row, th in zip(codes, theta):
        nz = [int(v) for v in row if v != 0]
        if not nz:
            c += th
            labels.append("constant")
            continue
        if len(nz) != 1:
            raise InputError("degree-1 basis returned a product term", "sysidentpy")
        var, lag = divmod(nz[0], 1000)
        if var == 1:
            a[lag] = a.get(lag, 0.0) + th
            labels.append(f"y(k-{lag})")
        else:
            nm = names[var - 2]
            b.setdefault(nm, {})[lag] = b.get(nm, {}).get(lag, 0.0) + th
            labels.append(f"{nm}(k-{lag})")
    na = max(a) if a else 0
    used = [k for k in names if k in b]
    fit = ARXFit(a=tuple(a.get(i, 0.0) for i in range(1, na + 1)),
                 b={k: tuple(b[k].get(i, 0.0) for i in range(1, max(b[k]) + 1)) for k in used},
                 c_um=float(c), names=tuple(used), units=tuple(str(units.get(k, "")) for k in used),
                 reference={k: ref[k] for k in used}, scale={k: sc[k] for k in used},
                 dtau_s=float(dtau_s), terms=tuple(labels), one_step_rms_um=0.0)
    pred1 = _arx_one_step(fit, y, inputs)
    r = (y - pred1)[fit.max_lag:]
    fit = ARXFit(**{**fit.__dict__, "one_step_rms_um": float(np.sqrt(np.mean(r ** 2)))})
    return (fit, model) if return_model else fit


def _scaled(fit, inputs):
    return {k: (np.asarray(inputs[k], float) - fit.reference[k]) * fit.scale[k]
            for k in fit.names}


def _arx_one_step(fit, y, inputs):
    U = _scaled(fit, inputs)
    n = y.size
    p = np.full(n, fit.c_um)
    for i, ai in enumerate(fit.a, 1):
        p[i:] += ai * y[:n - i]
    for k, bs in fit.b.items():
        for l, bl in enumerate(bs, 1):
            p[l:] += bl * U[k][:n - l]
    p[:fit.max_lag] = y[:fit.max_lag]
    return p


def arx_simulate(fit: ARXFit, inputs: dict, y_init_um) -> np.ndarray:
    """Free-run simulation [µm]: the first ``len(y_init_um)`` outputs are given (the
    measured growth), every later one uses the model's own past outputs.
    Rows before row 0 are taken at rest (inputs at reference, growth at ``y_init[0]``)
    where a lag reaches before the given rows.

    Examples
    --------
    >>> f = ARXFit((0.5,), {"speed_rpm": (1e-3,)}, 0.0, ("speed_rpm",), ("1/min",),
    ...            {"speed_rpm": 0.0}, {"speed_rpm": 1.0}, 60.0, (), 0.0)
    >>> arx_simulate(f, {"speed_rpm": np.full(4, 1000.0)}, [0.0]).tolist()
    [0.0, 1.0, 1.5, 1.75]
    """
    U = _scaled(fit, inputs)
    y0 = np.atleast_1d(np.asarray(y_init_um, float))
    n = len(next(iter(inputs.values())))
    out = np.empty(n)
    k0 = min(y0.size, n)
    out[:k0] = y0[:k0]
    for k in range(k0, n):
        v = fit.c_um
        for i, ai in enumerate(fit.a, 1):
            v += ai * (out[k - i] if k - i >= 0 else y0[0])
        for nm, bs in fit.b.items():
            for l, bl in enumerate(bs, 1):
                v += bl * (U[nm][k - l] if k - l >= 0 else 0.0)
        out[k] = v
    return out


def arx_state_space(fit: ARXFit, *, y_start_um: float, Q_um2: float = 0.0,
                    R_um2: float = 0.0, description: str = "",
                    arfem_version: str = "") -> StateSpaceModel:
    """The ARX as a companion-form state space, in simulation mode.

    States x_k = [ỹ_k … ỹ_{k−na'+1}, then for each input u_j[k] … u_j[k−L_j+1]] with
    ỹ = y − d0, d0 = c / (1 − Σ a_i), na' = max(na, 1): ỹ_k is computed from x_{k−1}
    (its past outputs and past inputs), the input lags shift in from ``B u_k``; the
    output is ŷ_k = ỹ_k + d0 (C picks ỹ_k, D = 0). The inputs enter raw: the reference
    is ``input_offsets``, the scale is in B. x0 is the machine at rest: ỹ at
    ``y_start_um`` − d0 on every output lag, the inputs at their reference.

    Parameters
    ----------
    fit : ARXFit
    y_start_um : float
        Measured growth [µm] of the row before the first stepped one.
    Q_um2, R_um2 : float
        Innovation variance (one-step residual) and measurement noise [µm²], for probes.

    Raises
    ------
    InputError
        If the ARX is not stable (Σ a_i = 1 or a root outside the unit circle).

    Examples
    --------
    >>> f = ARXFit((0.5,), {"speed_rpm": (1e-3,)}, 0.0, ("speed_rpm",), ("1/min",),
    ...            {"speed_rpm": 0.0}, {"speed_rpm": 1.0}, 60.0, (), 0.0)
    >>> from arfem.models.compensator import Compensator
    >>> c = Compensator(arx_state_space(f, y_start_um=0.0))
    >>> [round(c.step({"speed_rpm": 1000.0}).predicted_growth_um, 6) for _ in range(3)]
    [0.0, 1.0, 1.5]
    """
    if not fit.stable:
        raise InputError(f"the identified ARX has a root on or outside the unit circle "
                         f"(a = {[round(v, 6) for v in fit.a]}): it would not settle in "
                         "simulation, so it cannot run as a compensator", "arx")
    na = max(len(fit.a), 1)
    lags = [len(fit.b[k]) for k in fit.names]
    n = na + sum(lags)
    m = len(fit.names)
    A, B = np.zeros((n, n)), np.zeros((n, m))
    a = np.r_[np.asarray(fit.a, float), np.zeros(na - len(fit.a))]
    A[0, :na] = a
    for i in range(1, na):
        A[i, i - 1] = 1.0
    off = na
    for j, (nm, L) in enumerate(zip(fit.names, lags)):
        s = fit.scale[nm]
        # ỹ_k gets b_jl u_j[k−l] = b_jl · (state u_j at lag l−1 of x_{k−1}); the state
        # holds the raw reading minus its reference, the scale goes into the gain
        A[0, off:off + L] = np.asarray(fit.b[nm], float) * s
        B[off, j] = 1.0
        for i in range(1, L):
            A[off + i, off + i - 1] = 1.0
        off += L
    d0 = fit.c_um / (1.0 - float(np.sum(a)))
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    x0 = np.zeros(n)
    x0[:na] = float(y_start_um) - d0
    terms = ", ".join(fit.terms)
    return StateSpaceModel(
        kind=f"arx:na={len(fit.a)}", dtau_s=fit.dtau_s, A=A, B=B, C=C, D=np.zeros((1, m)),
        inputs=tuple(InputSpec(k, u) for k, u in zip(fit.names, fit.units)), x0=x0,
        d0_um=float(d0), Q=float(Q_um2), R=float(R_um2),
        description=description or f"ARX (SysIdentPy FROLS, BIC): {terms}",
        arfem_version=arfem_version,
        input_offsets={k: fit.reference[k] for k in fit.names if fit.reference[k] != 0.0})
