"""A residual model over the thermometers, run beside a growth model (issue 43).

Where a model of the growth does not predict the machine's thermometers (the extended
model of a speed record reads them as inputs and outputs only the growth), an observer
has nothing to compare them with; they can still correct it online as the inputs of a
model of what it leaves. Here that model is a regression of the base model's causal
residual r = y − ŷ_base [µm] on the thermometers seen through a fixed bank of
first-order lags (an output-error model with fixed real poles, in the manner of
orthonormal-basis / Laguerre identification, Heuberger, Van den Hof & Wahlberg,
*Modelling and Identification with Rational Orthogonal Basis Functions*, Springer 2005):

    r̂_k = c + Σ_i [ β_i0 ΔT_i[k] + Σ_j β_ij L_j(ΔT_i)[k] ],     ΔT_i = T_i − T_i,ref,
    L_j(u)[k] = a_j L_j(u)[k−1] + (1 − a_j) u[k],   a_j = exp(−Δτ/τ_j),

with each lag started at rest at row 0 (L_j(u)[0] = u[0]). No measured growth is fed
back, so it runs in simulation like every compensator here; its poles are fixed, so it
is stable whatever the coefficients. The coefficients are a ridge regression on
standardised columns (intercept not penalised); the lag bank and the ridge weight are
chosen together by time-blocked cross-validation on the fit rows
(:func:`fit_thermometer_residual`), and where no choice beats "no correction" in that
cross-validation the residual model is zero.

Exported as a :class:`~arfem.models.compensator.StateSpaceModel` (one state per
thermometer and lag, the raw term through D) and connected in parallel with the base
model (:func:`parallel_state_space`), so the sum is replayed by the same causal
compensator as every other model.

Convention: row 0 of every array is the record's first row (t = 0, the machine at rest,
not stepped); the compensator steps rows 1, 2, …, and the prediction at row k uses the
thermometers of rows 0 … k only.

Pure: arrays in, dataclasses out; nothing here reads or writes a file.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from arfem.models.compensator import InputSpec, StateSpaceModel
from arfem.params import InputError

__all__ = ["LAG_BANKS_H", "RIDGE_GRID", "ThermometerResidualFit", "lag_features",
           "fit_thermometer_residual", "residual_simulate", "residual_state_space",
           "parallel_state_space"]

#: the candidate lag banks [h] (besides the raw reading, always in): the "orders"
LAG_BANKS_H = ((), (2.0,), (0.5, 4.0), (0.25, 1.0, 4.0))
#: the candidate ridge weights: λ in ‖r − c − Zβ‖² + λ·n·‖β‖² (Z standardised columns)
RIDGE_GRID = tuple(float(v) for v in 10.0 ** np.arange(-4.0, 2.01, 0.5))


@dataclass(frozen=True)
class ThermometerResidualFit:
    """A fitted residual model over the thermometers.

    Attributes
    ----------
    names : tuple of str
        The thermometer inputs (``T_<sensor>_C``), in column order.
    reference_C : tuple of float
        Reading subtracted from each thermometer [°C] (its ``input_offsets`` value).
    taus_s : tuple of float
        Time constants of the lag bank [s] (empty: the raw readings only).
    raw_um_K : tuple of float
        β_i0, the gain of each raw reading [µm/K].
    lag_um_K : tuple of tuple of float
        β_ij, per thermometer, per lag [µm/K].
    intercept_um : float
        c [µm].
    ridge : float
        The chosen λ (:data:`RIDGE_GRID`); NaN where the model is zero.
    cv_rms_um : float
        Time-blocked CV RMS of the chosen (bank, λ) [µm].
    cv_zero_rms_um : float
        The same CV's RMS of "no correction" (the residual itself) [µm].
    dtau_s : float
        Interval Δτ [s].
    active : bool
        False: no (bank, λ) beat "no correction" in the CV; every gain is 0.
    """

    names: tuple
    reference_C: tuple
    taus_s: tuple
    raw_um_K: tuple
    lag_um_K: tuple
    intercept_um: float
    ridge: float
    cv_rms_um: float
    cv_zero_rms_um: float
    dtau_s: float
    active: bool


def _thermometer_matrix(temperatures: dict, names, n_rows: int | None = None) -> np.ndarray:
    """(N, m) readings [°C] of ``names``; an :class:`InputError` for a missing, ragged or
    non-finite one."""
    cols = []
    for nm in names:
        if nm not in temperatures:
            raise InputError("is not among the thermometers given", nm)
        v = np.asarray(temperatures[nm], float)
        if v.ndim != 1 or (n_rows is not None and v.size != n_rows) or not np.all(np.isfinite(v)):
            raise InputError("must be finite on every row and as long as the others", nm)
        n_rows = v.size
        cols.append(v)
    return np.column_stack(cols)


def lag_features(T_C: np.ndarray, reference_C, taus_s, dtau_s: float) -> np.ndarray:
    """The regression columns: for each thermometer the raw ΔT, then ΔT through each lag.

    Parameters
    ----------
    T_C : ndarray, shape (N, m)
        Readings [°C], row 0 the first row of the record (the machine at rest).
    reference_C : array_like, shape (m,)
        Subtracted from the readings [°C].
    taus_s : sequence of float
        Lag time constants [s].
    dtau_s : float
        Interval Δτ [s].

    Returns
    -------
    ndarray, shape (N, m·(1 + len(taus_s)))
        Columns thermometer by thermometer: [ΔT_i, L_1(ΔT_i), …]; row k uses rows ≤ k.

    Examples
    --------
    >>> T = np.array([[20.0], [21.0], [21.0]])
    >>> lag_features(T, [20.0], [60.0], 60.0).round(4).tolist()
    [[0.0, 0.0], [1.0, 0.6321], [1.0, 0.8647]]
    """
    dT = np.asarray(T_C, float) - np.asarray(reference_C, float)[None, :]
    out = []
    for i in range(dT.shape[1]):
        u = dT[:, i]
        out.append(u)
        for tau in taus_s:
            a = np.exp(-dtau_s / tau)
            # started at rest at row 0: L[0] = u[0], then L[k] = a L[k-1] + (1-a) u[k]
            out.append(lfilter([1.0 - a], [1.0, -a], u - u[0]) + u[0])
    return np.column_stack(out)


def _ridge_solve(G, h, lam, n):
    """Ridge on an augmented Gram (column 0 the constant, not penalised)."""
    P = np.full(G.shape[0], lam * n)
    P[0] = 0.0
    return np.linalg.solve(G + np.diag(P) + 1e-12 * np.eye(G.shape[0]), h)


def _cv_bank(Z, r, folds, ridges, forward: bool = False):
    """Time-blocked CV RMS [µm] for each λ: fit on every block but one, score on it
    (``forward``: fit on the blocks before it only, the first block never scored)."""
    X = np.column_stack([np.ones(r.size), Z])
    G = np.array([X[f].T @ X[f] for f in folds])
    h = np.array([X[f].T @ r[f] for f in folds])
    rr = np.array([float(r[f] @ r[f]) for f in folds])
    n = np.array([f.size for f in folds])
    sse = np.zeros(len(ridges))
    scored = range(1, len(folds)) if forward else range(len(folds))
    for i in scored:
        tr = np.arange(len(folds)) < i if forward else np.arange(len(folds)) != i
        Gt, ht, nt = G[tr].sum(0), h[tr].sum(0), int(n[tr].sum())
        for j, lam in enumerate(ridges):
            b = _ridge_solve(Gt, ht, lam, nt)
            sse[j] += max(rr[i] - 2 * b @ h[i] + b @ G[i] @ b, 0.0)
    return np.sqrt(sse / sum(n[i] for i in scored))


def fit_thermometer_residual(residual_um, temperatures: dict, *, dtau_s: float,
                             fit_rows, reference_C: dict, banks_h=LAG_BANKS_H,
                             ridges=RIDGE_GRID, n_blocks: int = 4,
                             forward: bool = False) -> ThermometerResidualFit:
    """The residual model, its lag bank and ridge weight chosen by time-blocked CV.

    The rule (fixed before FL_THERMAL was scored, ``reports/fl_thermal/thermometers.py``):
    the fit rows are cut into ``n_blocks`` contiguous blocks of equal count; for every
    bank of :data:`LAG_BANKS_H` and every λ of :data:`RIDGE_GRID` the ridge regression is
    fitted on all blocks but one and scored on it; the (bank, λ) with the lowest CV RMS
    is refitted on every fit row. If that CV RMS is not below the CV RMS of no correction
    (r̂ = 0), the model is zero (``active`` False).

    Parameters
    ----------
    residual_um : array_like, shape (N,)
        The base model's causal residual y − ŷ [µm] (any value outside ``fit_rows``).
    temperatures : dict
        Thermometer name → readings [°C] on the same N rows (row 0 at rest).
    dtau_s : float
        Interval Δτ [s].
    fit_rows : array_like of bool, shape (N,)
        Rows the regression is fitted on (finite residual required there).
    reference_C : dict
        Thermometer name → reference [°C] subtracted (the base model's
        ``input_offsets``, so that both share each input's reference).
    banks_h, ridges : sequence
        The candidate lag banks [h] and ridge weights.
    n_blocks : int
        Contiguous CV blocks.
    forward : bool
        Forward-chaining CV (each block scored by a fit on the blocks before it only;
        "no correction" scored on the same blocks) instead of leave-one-block-out.

    Returns
    -------
    ThermometerResidualFit

    Examples
    --------
    >>> t = np.arange(2000) * 60.0
    >>> T = 20 + 3 * (1 - np.exp(-t / 7200.0)) + np.sin(t / 5000.0)
    >>> r = 2.0 * (T - 20)
    >>> f = fit_thermometer_residual(r, {"T_a_C": T}, dtau_s=60.0,
    ...                              fit_rows=np.arange(2000) > 0, reference_C={"T_a_C": 20.0})
    >>> f.active, round(f.raw_um_K[0] + sum(f.lag_um_K[0]), 2)
    (True, 2.0)
    """
    names = tuple(temperatures)
    r = np.asarray(residual_um, float)
    T = _thermometer_matrix(temperatures, names, r.size)
    ref = np.array([float(reference_C[nm]) for nm in names])
    rows = np.flatnonzero(np.asarray(fit_rows, bool))
    if rows.size < 4 * n_blocks or not np.all(np.isfinite(r[rows])):
        raise InputError(f"needs a finite residual on at least {4 * n_blocks} fit rows",
                         "residual_um")
    rf = r[rows]
    folds = [np.asarray(b) for b in np.array_split(np.arange(rows.size), n_blocks)]
    scored = np.concatenate(folds[1:] if forward else folds)
    zero = float(np.sqrt(np.mean(rf[scored] ** 2)))
    cv_best, taus, lam = _choose(T, ref, rows, rf, dtau_s, banks_h, ridges, folds, forward)
    m, L = len(names), len(taus)
    if not cv_best < zero:
        return ThermometerResidualFit(names, tuple(ref), taus, (0.0,) * m,
                                      ((0.0,) * L,) * m, 0.0, float("nan"), cv_best, zero,
                                      float(dtau_s), False)
    Z, mu, sd = _standardised(lag_features(T, ref, taus, dtau_s)[rows])
    X = np.column_stack([np.ones(rows.size), Z])
    b = _ridge_solve(X.T @ X, X.T @ rf, lam, rows.size)
    beta = b[1:] / sd
    c = float(b[0] - beta @ mu)
    beta = beta.reshape(m, 1 + L)
    return ThermometerResidualFit(names, tuple(ref), taus, tuple(float(v) for v in beta[:, 0]),
                                  tuple(tuple(float(v) for v in row[1:]) for row in beta), c,
                                  lam, cv_best, zero, float(dtau_s), True)


def _standardised(F):
    """Columns less their mean, over their standard deviation (1 where constant)."""
    mu, sd = F.mean(0), F.std(0)
    sd[sd == 0] = 1.0
    return (F - mu) / sd, mu, sd


def _choose(T, ref, rows, rf, dtau_s, banks_h, ridges, folds, forward):
    """(CV RMS [µm], lag time constants [s], λ) of the (bank, λ) with the lowest
    time-blocked CV RMS; a tie goes to the earlier (smaller) bank and larger λ."""
    best = None
    for bank in banks_h:
        taus = tuple(h * 3600.0 for h in bank)
        Z, _, _ = _standardised(lag_features(T, ref, taus, dtau_s)[rows])
        cv = _cv_bank(Z, rf, folds, ridges, forward)
        j = max(range(len(ridges)), key=lambda i: (-cv[i], ridges[i]))
        if best is None or cv[j] < best[0]:
            best = (float(cv[j]), taus, float(ridges[j]))
    return best


def _gains(fit: ThermometerResidualFit) -> np.ndarray:
    return np.column_stack([np.asarray(fit.raw_um_K, float)[:, None],
                            np.asarray(fit.lag_um_K, float).reshape(len(fit.names), -1)]
                           ).ravel()


def residual_simulate(fit: ThermometerResidualFit, temperatures: dict) -> np.ndarray:
    """The residual model's prediction r̂ [µm] on every row of ``temperatures`` (row 0 at
    rest); row k uses rows 0 … k only.

    Examples
    --------
    >>> f = ThermometerResidualFit(("T_a_C",), (20.0,), (60.0,), (1.0,), ((2.0,),), 0.5,
    ...                            0.1, 0.0, 0.0, 60.0, True)
    >>> residual_simulate(f, {"T_a_C": np.array([20.0, 21.0, 21.0])}).round(4).tolist()
    [0.5, 2.7642, 3.2293]
    """
    T = _thermometer_matrix(temperatures, fit.names)
    F = lag_features(T, fit.reference_C, fit.taus_s, fit.dtau_s)
    return F @ _gains(fit) + fit.intercept_um


def residual_state_space(fit: ThermometerResidualFit, first_C: dict, *,
                         description: str = "", arfem_version: str = "") -> StateSpaceModel:
    """The residual model as a state space: one state per thermometer and lag
    (A = a_j, B = 1 − a_j on that thermometer, C = β_ij), the raw readings through
    D = β_i0, d0 = c, the references as ``input_offsets``; x0 the lags at rest at the
    first readings ``first_C`` [°C] (name → row 0's value). Q = 0: a probe changes
    nothing in it.

    Examples
    --------
    >>> f = ThermometerResidualFit(("T_a_C",), (20.0,), (60.0,), (1.0,), ((2.0,),), 0.5,
    ...                            0.1, 0.0, 0.0, 60.0, True)
    >>> m = residual_state_space(f, {"T_a_C": 20.0})
    >>> from arfem.models.compensator import Compensator
    >>> c = Compensator(m)
    >>> [round(c.step({"T_a_C": 21.0}).predicted_growth_um, 4) for _ in range(2)]
    [2.7642, 3.2293]
    """
    m, L = len(fit.names), len(fit.taus_s)
    n = m * L
    A, B, C = np.zeros((n, n)), np.zeros((n, m)), np.zeros((1, n))
    x0 = np.zeros(n)
    for i, nm in enumerate(fit.names):
        for j, tau in enumerate(fit.taus_s):
            s = i * L + j
            a = np.exp(-fit.dtau_s / tau)
            A[s, s], B[s, i], C[0, s] = a, 1.0 - a, fit.lag_um_K[i][j]
            x0[s] = float(first_C[nm]) - fit.reference_C[i]
    D = np.asarray(fit.raw_um_K, float)[None, :]
    return StateSpaceModel(
        kind=f"thermometer_residual:lags_h={[round(t / 3600, 3) for t in fit.taus_s]}",
        dtau_s=fit.dtau_s, A=A, B=B, C=C, D=D,
        inputs=tuple(InputSpec(nm, "°C") for nm in fit.names), x0=x0,
        d0_um=float(fit.intercept_um), Q=0.0, R=0.0, description=description,
        arfem_version=arfem_version,
        input_offsets={nm: float(r) for nm, r in zip(fit.names, fit.reference_C)})


def parallel_state_space(base: StateSpaceModel, extra: StateSpaceModel, *, kind: str = "",
                         description: str = "") -> StateSpaceModel:
    """Two one-output models in parallel: the states stacked (A block-diagonal), the
    outputs and constants summed, the inputs the union by name (``base``'s first).

    An input both read must have the same unit, reference and map in both (else an
    :class:`InputError`): the compensator subtracts one reference per input. The noise
    (Q, R), fit window and version stamp are ``base``'s (the compensator applies Q to
    every state, so a probe update would move ``extra``'s states too; the FL_THERMAL
    comparison uses no probe).

    Examples
    --------
    >>> from arfem.models.compensator import ar1_model
    >>> a = ar1_model(0.5, 1.0, dtau_s=60.0)
    >>> p = parallel_state_space(a, a)
    >>> p.A.tolist(), p.B.tolist(), p.C.tolist()
    ([[0.5, 0.0], [0.0, 0.5]], [[1.0], [1.0]], [[1.0, 1.0]])
    """
    if base.outputs or extra.outputs or base.schedule or extra.schedule:
        raise InputError("only one-output, time-invariant models are put in parallel",
                         "model")
    if abs(base.dtau_s - extra.dtau_s) > 1e-9 * base.dtau_s:
        raise InputError("the two models step at different intervals", "dtau_s")
    names = [i.name for i in base.inputs]
    specs = list(base.inputs)
    for spec in extra.inputs:
        if spec.name in names:
            j = names.index(spec.name)
            same_map = (spec.name not in base.input_maps and spec.name not in extra.input_maps)
            if (specs[j].unit != spec.unit or not same_map or
                    base.input_offsets.get(spec.name, 0.0) != extra.input_offsets.get(spec.name, 0.0)):
                raise InputError("is read with a different unit, reference or map by the "
                                 "two models", spec.name)
        else:
            names.append(spec.name)
            specs.append(spec)
    n1, n2, m = base.n_states, extra.n_states, len(names)
    A = np.zeros((n1 + n2, n1 + n2))
    A[:n1, :n1], A[n1:, n1:] = base.A, extra.A
    B, D = np.zeros((n1 + n2, m)), np.zeros((1, m))
    for j, spec in enumerate(base.inputs):
        B[:n1, j], D[0, j] = base.B[:, j], base.D[0, j]
    for j, spec in enumerate(extra.inputs):
        k = names.index(spec.name)
        B[n1:, k] += extra.B[:, j]
        D[0, k] += extra.D[0, j]
    offsets = {**base.input_offsets, **extra.input_offsets}
    return StateSpaceModel(
        kind=kind or f"{base.kind}+{extra.kind}", dtau_s=base.dtau_s, A=A, B=B,
        C=np.concatenate([base.C, extra.C], axis=1), D=D, inputs=tuple(specs),
        x0=np.concatenate([base.x0, extra.x0]), d0_um=float(base.d0_um + extra.d0_um),
        Q=base.Q, R=base.R, description=description or base.description,
        arfem_version=base.arfem_version, input_maps=dict(base.input_maps),
        input_offsets=offsets, fit_window_s=base.fit_window_s)
