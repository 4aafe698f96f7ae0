"""A channel's measurement noise as white noise plus a random walk (a local-level
model) or an AR(1), fitted from a residual's variogram, and the exact whitening of that noise by
the Kalman filter's innovations (issue 33: causes under correlated noise).

A displacement probe's electronics and a thermometer's junction wander slowly; a
random walk w_k (increments of variance σ_w² per sample, from 0 at the record's first
row) on top of white noise e_k (variance σ_e²) has the covariance

    Σ_ij = σ_e² δ_ij + σ_w² min(k_i, k_j),        k_i = row index of sample i + 1.

Least squares weighted by 1/σ_e alone (ordinary least squares) is then inefficient and
its intervals need a sandwich that swamps real effects; generalised least squares on
Σ is efficient and its covariance (JᵀΣ⁻¹J)⁻¹ honest. Σ⁻¹ᐟ² is applied in O(N) by the
Kalman filter of the local-level model: the innovations v_k / √F_k are white with unit
variance (the prediction-error decomposition), so every fit, test and interval works on
whitened rows.

A probe's electronics may instead forget their past: the slow state is then an AR(1),
x_k = φ x_{k−1} + w_k (φ < 1; the walk is φ = 1), whose covariance is stationary after
a few 1/(1 − φ) rows. The filter is the same with φ in its prediction; the REML fit
(:func:`profile_noise`) keeps the walk unless an AR(1) fits better by a 1 % test's
margin. A walk fitted to AR(1) noise (ρ 0.6-0.93 per sample) took a sensor's drift or a
frame's slow rise for its own wander (issue 41: seed 11010, and the speed-only plant's
drift records named 2 of 6).

The variogram ½E[(r_{k+h} − r_k)²] = σ_e² + h σ_w²/2 is linear in the lag h for the walk; a smooth misfit adds ~h², so it is fitted on the residual of the LARGEST model
(every candidate cause at once, linearised), where the misfit is gone, as an F test's
error variance is taken from its full model.

References: Harvey A. C., "Forecasting, structural time series models and the Kalman
filter", CUP 1989, sec. 2.3 and 3.4 (local level, prediction-error decomposition);
Cressie N., "Statistics for spatial data", Wiley 1993, sec. 2.4 (variogram fit).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_banded

__all__ = ["LevelNoise", "fit_level_noise", "reml_level_noise", "reml_level_noise_pooled",
           "reml_joint", "Whitener", "whitener", "drift_vs_walk_p", "columns_vs_walk_p",
           "walk_profiled_lr_p", "UnitFilters"]


@dataclass(frozen=True)
class LevelNoise:
    """One channel's noise: ``sigma_white`` σ_e and ``sigma_walk`` σ_w per sample
    (record unit: µm or K) of its slow state x_k = φ x_{k−1} + w_k, ``phi`` φ [-]:
    1 a random walk (a local level), below 1 an AR(1) that forgets its past."""

    sigma_white: float
    sigma_walk: float = 0.0
    phi: float = 1.0


def fit_level_noise(r: np.ndarray, idx: np.ndarray, floor: float,
                    max_lag: int = 120) -> LevelNoise:
    """σ_e and σ_w of a residual from its variogram (module docstring).

    Parameters
    ----------
    r : ndarray (n,), residual [record unit] on the rows ``idx``
    idx : ndarray (n,) of int, their row indices (gaps allowed)
    floor : float, smallest σ_e [record unit] (e.g. the quantum/√12)
    max_lag : int, largest lag fitted [samples] (at most a quarter of the rows)

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> n = 3000
    >>> r = rng.normal(0, 1.0, n) + np.cumsum(rng.normal(0, 0.1, n))
    >>> z = fit_level_noise(r - r.mean(), np.arange(n), 1e-3)
    >>> round(z.sigma_white, 1), 0.05 < z.sigma_walk < 0.2
    (1.0, True)
    """
    n = r.size
    H = int(min(max_lag, max(n // 4, 2)))
    pos = np.full(int(idx[-1]) + 1 if n else 1, np.nan)
    pos[idx] = r
    lags, gam, cnt = [], [], []
    for h in range(1, H + 1):
        d = pos[h:] - pos[:-h]
        d = d[np.isfinite(d)]
        if d.size > 10:
            lags.append(h)
            gam.append(0.5 * float(np.mean(d * d)))
            cnt.append(d.size)
    if len(lags) < 3:
        s = float(np.std(r)) if n else floor
        return LevelNoise(max(s, floor), 0.0)
    lags, gam, cnt = map(np.asarray, (lags, gam, cnt))
    X = np.column_stack([np.ones(lags.size), lags / 2.0])
    w = np.sqrt(cnt)
    a, b = np.linalg.lstsq(X * w[:, None], gam * w, rcond=None)[0]
    if b <= 0:
        return LevelNoise(max(float(np.sqrt(max(gam[0], 0.0))), floor), 0.0)
    if a <= floor ** 2:
        a = floor ** 2
        b = max(float(np.sum(w * w * (gam - a) * lags / 2) / np.sum(w * w * (lags / 2) ** 2)), 0.0)
    return LevelNoise(float(np.sqrt(a)), float(np.sqrt(b)))


@dataclass(frozen=True)
class Whitener:
    """Σ⁻¹ᐟ² of one channel's noise on a set of rows, as the scalar Kalman filter of its
    slow state (module docstring): gains ``K`` (n,), innovation variances ``F`` (n,)
    and the state's transition ``A`` (n,) into each row (φ^gap; None: all 1, the walk).
    """

    K: np.ndarray
    F: np.ndarray
    A: np.ndarray | None = None

    def apply(self, X: np.ndarray) -> np.ndarray:
        """Whitened X (n,) or (n, m): the innovations divided by √F."""
        X = np.asarray(X, float)
        one = X.ndim == 1
        X2 = X[:, None] if one else X
        if not np.any(self.K):
            out = X2 / np.sqrt(self.F)[:, None]
        else:
            # the state's prediction x̂_i = A_i (x̂_{i-1} + K_{i-1} (X_{i-1} - x̂_{i-1})):
            # one lower-bidiagonal solve for every column
            n = X2.shape[0]
            ab = np.zeros((2, n))
            ab[0] = 1.0
            ab[1, :-1] = -(1.0 - self.K[:-1])
            rhs = np.zeros_like(X2)
            rhs[1:] = self.K[:-1, None] * X2[:-1]
            if self.A is not None:
                ab[1, :-1] *= self.A[1:]
                rhs[1:] *= self.A[1:, None]
            pred = solve_banded((1, 0), ab, rhs, check_finite=False)
            out = (X2 - pred) / np.sqrt(self.F)[:, None]
        return out[:, 0] if one else out


def whitener(noise: LevelNoise, idx: np.ndarray) -> Whitener:
    """The :class:`Whitener` of ``noise`` on rows ``idx`` (int, increasing; the slow
    state starts at 0 before row 0 and steps once per row, gaps included).

    The filter's variance settles to the fixed point of its Riccati recursion; once the
    prior variance repeats bit for bit on a run of unit steps, the rest of that run is
    filled with it (the same numbers the loop would compute, at no cost).

    Examples
    --------
    >>> z = LevelNoise(1.0, 0.3)
    >>> idx = np.arange(6)
    >>> S = np.eye(6) + 0.09 * np.minimum.outer(idx + 1, idx + 1)
    >>> W = whitener(z, idx).apply(np.eye(6))
    >>> bool(np.allclose(W @ S @ W.T, np.eye(6)))
    True
    >>> z = LevelNoise(1.0, 0.3, phi=0.8)       # white + AR(1) of coefficient 0.8
    >>> k = idx + 1
    >>> S = np.eye(6) + 0.09 * 0.8 ** np.abs(np.subtract.outer(k, k)) * (
    ...     1 - 0.64 ** np.minimum.outer(k, k)) / (1 - 0.64)
    >>> W = whitener(z, idx).apply(np.eye(6))
    >>> bool(np.allclose(W @ S @ W.T, np.eye(6)))
    True
    """
    se2, sw2 = float(noise.sigma_white) ** 2, float(noise.sigma_walk) ** 2
    phi = float(noise.phi)
    n = idx.size
    if sw2 <= 0:
        return Whitener(np.zeros(n), np.full(n, se2))
    gaps = np.diff(np.asarray(idx), prepend=-1)
    if phi == 1.0:
        A, Q = None, sw2 * gaps
    else:
        A = phi ** gaps.astype(float)
        Q = sw2 * (1.0 - A * A) / (1.0 - phi * phi)
    K, F = np.empty(n), np.empty(n)
    # Python floats in the loop (a numpy scalar per step costs several times more)
    a2 = None if A is None else (A * A).tolist()
    q, unit = Q.astype(float).tolist(), (gaps == 1).tolist()
    # next row at or after i that does not step by one (n: none)
    nxt = np.append(np.flatnonzero(gaps != 1), n)
    post, prior_last, i = 0.0, -1.0, 0
    while i < n:
        prior = (post if a2 is None else a2[i] * post) + q[i]
        f = prior + se2
        k = prior / f
        F[i], K[i] = f, k
        post = prior * (1.0 - k)
        if unit[i] and prior == prior_last:
            # a fixed point on a unit step: rows up to the next gap repeat it exactly
            j = int(nxt[np.searchsorted(nxt, i + 1)])
            K[i + 1:j], F[i + 1:j] = k, f
            i = j
            prior_last = -1.0
            continue
        prior_last = prior if unit[i] else -1.0
        i += 1
    return Whitener(K, F, A)


@dataclass(frozen=True, eq=False)
class UnitFilters:
    """A caller's memo of unit-noise filters: the :func:`whitener` of unit white noise
    with walk-to-white ratio λ and AR coefficient φ on a set of rows, by (λ, φ, rows).
    The grids of :func:`profile_noise` recur in every profile of a record's residual on
    the same rows (a sensor kind's φ, the tests of a drift and of the thermometers), and
    each filter is a loop over the rows; a filter is a pure function of its key, so a
    cold and a warm memo give the same bits.

    Owned by whoever calls: a diagnosis's fit context holds one
    (:attr:`arfem.models.geodiagnosis.fit.FitContext.filters`, empty when the context
    is made); a function of this module given none makes its own for that call. No
    memo is shared between two owners. It is emptied when it holds ``max_entries``
    filters (at most ~60 MB at 256 on a record of 10 000 rows).

    Examples
    --------
    >>> filters = UnitFilters()
    >>> W = filters.get(1e-3, 1.0, np.arange(5))
    >>> filters.get(1e-3, 1.0, np.arange(5)) is W, len(filters)
    (True, 1)
    """

    max_entries: int = 256
    _memo: dict = field(default_factory=dict, init=False, repr=False)

    def __len__(self) -> int:
        return len(self._memo)

    def get(self, lam: float, phi: float, idx: np.ndarray) -> Whitener:
        """The :func:`whitener` of :class:`LevelNoise` (1, √λ, φ) on rows ``idx``,
        made once per (λ, φ, rows); its arrays are read-only (shared by every caller).
        """
        idx = np.asarray(idx)
        key = (float(lam), float(phi), idx.dtype.str, idx.tobytes())
        W = self._memo.get(key)
        if W is None:
            if len(self._memo) >= self.max_entries:
                self._memo.clear()
            W = whitener(LevelNoise(1.0, float(np.sqrt(lam)), phi), idx)
            for a in (W.K, W.F, W.A):
                if a is not None:
                    a.flags.writeable = False
            self._memo[key] = W
        return W


#: the walk-to-white ratios λ = σ_w²/σ_e² searched for a random walk (φ = 1)
WALK_RATIOS = np.concatenate([[0.0], 10.0 ** np.arange(-7.0, -0.49, 0.25)])
#: the AR coefficients φ searched for a stationary slow state, and the stationary ratios
#: κ = σ_w²/((1 − φ²) σ_e²) (the AR part's variance over the white part's) with each
AR_COEFFICIENTS = (0.8, 0.9, 0.95, 0.98, 0.99, 0.995, 0.999)
AR_RATIOS = 10.0 ** np.arange(-2.0, 2.01, 1.0)
#: the range of log10(1 − φ) the refinement keeps to: φ within the grid's ends. A slow
#: state remembers at least ~5 samples: an AR(1) of small φ is white noise of another
#: variance, and across sensor kinds (whose white σ the fit keeps in the ratio of their
#: second differences) it freed one kind's variance instead (the coarse unit's probes at
#: φ 0.002, seeds 1102 and 1105 of tests/test_geodiagnosis_verdicts.py, their verdicts
#: lost)
_LOG_1M_PHI = (float(np.log10(1.0 - max(AR_COEFFICIENTS))),
               float(np.log10(1.0 - min(AR_COEFFICIENTS))))
#: −2 log-likelihood an AR coefficient must gain over the random walk to be adopted: the
#: χ² 99 % point on one degree of freedom (a parameter must pass a 1 % test, as the
#: record's other extra parameters do); a walk stays a walk unless the data refuse it
AR_PENALTY = 6.635


def profile_noise(m2ll) -> tuple:
    """The slow state that minimises ``m2ll(λ, φ)`` (−2 log-likelihood, any constant):
    (−2ℓ, λ, φ). A random walk first (φ = 1, λ on :data:`WALK_RATIOS`); then an AR(1)
    (φ on :data:`AR_COEFFICIENTS`, κ on :data:`AR_RATIOS`, the best refined three times
    on a 3 × 3 pattern in log κ and log(1 − φ), its steps halved each time), adopted only
    where it gains more than :data:`AR_PENALTY`. One rule for every fit and test of the
    noise.

    A random walk's increments never forget: fitted to stationary correlated noise
    (e.g. a probe's AR(1) electronics, ρ 0.6-0.9 per sample) it takes a sensor's drift
    or a slow frame for its own wander; the AR(1) does not.

    Reference: Harvey (1989) sec. 2.3 (the AR(1) plus noise model); Box G. E. P.,
    Jenkins G. M., "Time series analysis", 1970, sec. 7.1 (profiling the likelihood).

    Examples
    --------
    >>> profile_noise(lambda lam, phi: (lam - 0.01) ** 2 + (phi < 1) * 1.0)[1:]
    (0.01, 1.0)
    """
    walk = min((m2ll(float(v), 1.0), float(v)) for v in WALK_RATIOS)
    best = min((m2ll(float(k * (1 - f * f)), f), np.log10(k), np.log10(1 - f))
               for f in AR_COEFFICIENTS for k in AR_RATIOS)
    sk, sf = 0.5, 0.2
    for _ in range(3):
        _, lk, lf = best
        for dk in (-sk, 0.0, sk):
            for df in (-sf, 0.0, sf):
                f = 1.0 - 10.0 ** min(max(lf + df, _LOG_1M_PHI[0]), _LOG_1M_PHI[1])
                k = 10.0 ** (lk + dk)
                if dk or df:
                    v = m2ll(float(k * (1 - f * f)), f)
                    if v < best[0]:
                        best = (v, lk + dk, np.log10(1 - f))
        sk, sf = sk / 2.0, sf / 2.0
    v, lk, lf = best
    if v < walk[0] - AR_PENALTY:
        f = 1.0 - 10.0 ** lf
        return v, float(10.0 ** lk * (1 - f * f)), f
    return walk[0], walk[1], 1.0


def reml_level_noise(y: np.ndarray, X: np.ndarray, idx: np.ndarray,
                     floor: float, filters: UnitFilters | None = None) -> LevelNoise:
    """σ_e and σ_w of ``y`` = X β + noise by restricted maximum likelihood (REML):
    the ratio λ = σ_w²/σ_e² on a log grid (and 0), σ_e² profiled out, the regression's
    own degrees of freedom accounted for (a walk partly absorbed by X's columns, e.g. a
    sensor's offset and drift, is not taken for "no walk", as a variogram of the
    residual would). :func:`reml_level_noise_pooled` of one channel. The slow state is a
    random walk unless an AR(1) fits better by :data:`AR_PENALTY` (:func:`profile_noise`).

    Parameters
    ----------
    y : ndarray (n,), readings minus the nominal prediction [record unit] on rows ``idx``
    X : ndarray (n, p), the largest model's columns on those rows
    idx : ndarray (n,) of int
    floor : float, smallest σ_e [record unit]
    filters : UnitFilters, optional, the caller's memo of filters (None: one for this
        call)

    Reference: Harville D. A., J. Amer. Statist. Assoc. 72 (1977) 320-338 (REML);
    Harvey (1989) sec. 3.4 (its prediction-error decomposition).

    Examples
    --------
    >>> rng = np.random.default_rng(3)
    >>> n = 600
    >>> X = np.column_stack([np.ones(n), np.arange(n) / n])
    >>> y = rng.normal(0, 1.0, n) + np.cumsum(rng.normal(0, 0.05, n)) + X @ [2., 1.]
    >>> z = reml_level_noise(y, X, np.arange(n), 1e-3)
    >>> round(z.sigma_white, 1), 0.02 < z.sigma_walk < 0.1
    (1.0, True)
    """
    return reml_level_noise_pooled([(y, X, idx, floor)], filters)[0]


def _reml_terms(y, X, idx, lam, phi, filters: UnitFilters):
    """(−2 × restricted log-likelihood with σ_e² profiled out, σ_e²) at ratio λ and AR
    coefficient φ (the filter from ``filters``)."""
    W = filters.get(lam, phi, idx)
    yw, Xw = _split(W.apply(np.column_stack([y, X])), (1, X.shape[1]))
    yw = yw[:, 0]
    n = y.size
    if X.shape[1]:
        U, sv, _ = np.linalg.svd(Xw, full_matrices=False)
        r = yw - U @ (U.T @ yw)
        p, logdet = X.shape[1], float(2.0 * np.sum(np.log(np.maximum(sv, 1e-300))))
    else:
        r, p, logdet = yw, 0, 0.0
    s2 = max(float(r @ r) / max(n - p, 1), 1e-300)
    return (n - p) * np.log(s2) + float(np.sum(np.log(W.F))) + logdet, s2


def _prepared(channels) -> list:
    """(y, X, idx, floor) with X replaced by an orthonormal basis of its column space,
    its rank fixed once: the restricted likelihood of different λ must see the same
    regression."""
    prep = []
    for y, X, idx, floor in channels:
        if X.size and np.any(X):
            U, sv, _ = np.linalg.svd(X, full_matrices=False)
            X = U[:, sv > sv[0] * 1e-7]
        else:
            X = np.zeros((y.size, 0))
        prep.append((y, X, idx, floor))
    return prep


def _pooled_profile(prep, filters: UnitFilters) -> tuple:
    """:func:`profile_noise` of the summed restricted log-likelihood of channels
    ``prep`` (:func:`_prepared`), each with its own σ_e and regression: (−2ℓ, λ, φ)."""
    return profile_noise(lambda lam, phi: sum(
        _reml_terms(y, X, idx, lam, phi, filters)[0] for y, X, idx, _ in prep))


def reml_level_noise_pooled(channels, filters: UnitFilters | None = None) -> list:
    """REML of one ratio λ = σ_w²/σ_e² shared by several channels (sensors of one kind,
    e.g. the probes of one five-probe test), each with its own σ_e and its own
    regression: the summed restricted log-likelihood is maximised over λ. A weak walk
    (σ_w/σ_e ~ 0.05) is poorly determined by one channel of a few hundred rows, and an
    estimate of 0 on one channel made its intervals far too narrow.

    Parameters
    ----------
    channels : sequence of (y, X, idx, floor) as :func:`reml_level_noise`
    filters : UnitFilters, optional, the caller's memo of filters (None: one for this
        call)

    Returns
    -------
    list of LevelNoise, one per channel
    """
    filters = UnitFilters() if filters is None else filters
    prep = _prepared(channels)
    _, lam, phi = _pooled_profile(prep, filters)
    s2s = [_reml_terms(y, X, idx, lam, phi, filters)[1] for y, X, idx, _ in prep]
    return [LevelNoise(max(float(np.sqrt(s2)), floor), float(np.sqrt(lam * s2)), phi)
            for s2, (_, _, _, floor) in zip(s2s, prep)]


def _joint_terms(Y, Xs, idxs, sig, lams, phis):
    """(−2 restricted log-likelihood up to a constant, s²) of the joint regression:
    channel c's noise σ_c² s² (I + λ_c K_c(φ_c)), the columns shared across channels."""
    ys, xs, logF = [], [], 0.0
    for y, X, idx, sc, lam, phi in zip(Y, Xs, idxs, sig, lams, phis):
        W = whitener(LevelNoise(sc, sc * float(np.sqrt(lam)), phi), idx)
        yw, Xw = _split(W.apply(np.column_stack([y, X])), (1, X.shape[1]))
        ys.append(yw[:, 0])
        xs.append(Xw)
        logF += float(np.sum(np.log(W.F)))
    y, X = np.concatenate(ys), np.concatenate(xs)
    n, p = y.size, X.shape[1]
    if p:
        Q, R = np.linalg.qr(X)
        r = y - Q @ (Q.T @ y)
        logdet = float(2.0 * np.sum(np.log(np.maximum(np.abs(np.diag(R)), 1e-300))))
    else:
        r, logdet = y, 0.0
    s2 = max(float(r @ r) / max(n - p, 1), 1e-300)
    return (n - p) * np.log(s2) + logF + logdet, s2


def _kind_phi(Y, Xs, idxs, members, filters: UnitFilters) -> float:
    """φ of one sensor kind's slow state (1: a random walk): the pooled REML of its
    channels ``members``, each with its own regression and its own white σ profiled
    (:func:`profile_noise`). In the joint fit the kinds' white σ keep the ratio of their
    second differences, and an AR(1) of short memory there bought a kind a variance of
    its own: on a clean white record of the coarse unit the probes took φ 0.8 and the
    nominal model was "not explained" (tests/test_geodiagnosis.py, seed 1004). Decided
    here, the AR(1) is adopted on its correlation alone."""
    return _pooled_profile(_prepared([(Y[i], Xs[i], idxs[i], 0.0) for i in members]),
                           filters)[2]


def _joint_ratios(Y, Xs, idxs, sigma, groups, sweeps: int,
                  filters: UnitFilters) -> dict:
    """{group: (λ, φ)} minimising :func:`_joint_terms` by coordinate sweeps on the grid:
    each group's φ decided first (:func:`_kind_phi`), then its λ on
    :data:`WALK_RATIOS` for a walk, on κ (1 − φ²), κ on a quarter-decade grid over
    :data:`AR_RATIOS`' range, for an AR(1)."""
    names = list(dict.fromkeys(groups))
    phi = {g: _kind_phi(Y, Xs, idxs, [i for i, k in enumerate(groups) if k == g], filters)
           for g in names}
    kappas = 10.0 ** np.arange(np.log10(AR_RATIOS[0]), np.log10(AR_RATIOS[-1]) + 0.01, 0.25)
    lam = {g: 0.0 for g in names}
    for _ in range(sweeps if len(names) > 1 else 1):
        for g in names:
            grid = WALK_RATIOS if phi[g] == 1.0 else kappas * (1.0 - phi[g] ** 2)
            best = None
            for v in grid:
                trial = {**lam, g: float(v)}
                obj, _ = _joint_terms(Y, Xs, idxs, sigma, [trial[k] for k in groups],
                                      [phi[k] for k in groups])
                if best is None or obj < best[0]:
                    best = (obj, float(v))
            lam[g] = best[1]
    return {g: (lam[g], phi[g]) for g in names}


def reml_joint(Y, Xs, idxs, sigma, groups, floors, sweeps: int = 2,
               filters: UnitFilters | None = None) -> list:
    """REML of one walk-to-white ratio λ_g per group of channels (sensors of one kind)
    in a JOINT regression whose columns are shared across channels (a cause moves every
    channel by one parameter): far fewer free columns than one regression per channel,
    which absorbed a weak walk (σ_w/σ_e ~ 0.05 over a day) into its many smooth
    columns and then returned λ = 0.

    Parameters
    ----------
    Y : list of ndarray (n_c,), per channel readings minus the nominal prediction
    Xs : list of ndarray (n_c, p), the shared columns on each channel's rows
    idxs : list of int ndarray (n_c,), the rows
    sigma : array_like (C,), each channel's white σ_c (from second differences); the
        fit scales them by one common factor s
    groups : sequence (C,) of hashable, the channel's sensor kind
    floors : array_like (C,), smallest σ_e per channel
    sweeps : int, coordinate sweeps over the groups (each group's slow state a walk or
        an AR(1), :func:`profile_noise`)
    filters : UnitFilters, optional, the caller's memo of filters (None: one for this
        call)

    Returns
    -------
    list of LevelNoise
    """
    Xcat = np.concatenate(Xs) if Xs else np.zeros((0, 0))
    if Xcat.size and np.any(Xcat):
        _, sv, Vt = np.linalg.svd(Xcat, full_matrices=False)
        T = Vt[sv > sv[0] * 1e-7].T
        Xs = [X @ T for X in Xs]
    state = _joint_ratios(Y, Xs, idxs, sigma, groups, sweeps,
                          UnitFilters() if filters is None else filters)
    _, s2 = _joint_terms(Y, Xs, idxs, sigma, [state[k][0] for k in groups],
                         [state[k][1] for k in groups])
    s = float(np.sqrt(s2))
    return [LevelNoise(max(sc * s, fl), sc * s * float(np.sqrt(state[g][0])), state[g][1])
            for sc, g, fl in zip(sigma, groups, floors)]


def _split(Zw: np.ndarray, widths) -> list:
    """The blocks of consecutive columns of ``Zw`` of ``widths``, each a C-contiguous
    copy: a whitener's solve treats every column alone (the same bits whitened together
    or apart), and each block is laid out as if it had been whitened by itself."""
    out, at = [], 0
    for w in widths:
        out.append(np.ascontiguousarray(Zw[:, at:at + w]))
        at += w
    return out


def _ml_terms(yw: np.ndarray, Xw: np.ndarray, log_F: float) -> float:
    """−2 × log-likelihood (up to a constant) of y = X β + white + slow state, β and σ_e²
    profiled out (maximum likelihood: comparable across different X), from the whitened
    ``yw`` (n,) and ``Xw`` (n, p) at some ratio λ and AR coefficient φ, and Σ log F of
    that whitener."""
    if Xw.shape[1]:
        b, *_ = np.linalg.lstsq(Xw, yw, rcond=None)
        yw = yw - Xw @ b
    n = yw.size
    return n * np.log(max(float(yw @ yw) / n, 1e-300)) + log_F


def drift_vs_walk_p(y: np.ndarray, idx: np.ndarray, time_h: np.ndarray,
                    filters: UnitFilters | None = None) -> float:
    """p of a sensor's offset and linear drift against that sensor's own random walk:
    the likelihood-ratio test of y = a + b t + white + walk against y = white + walk,
    the walk-to-white ratio λ and σ_e profiled out under EACH hypothesis (χ² on 2
    degrees of freedom).

    A random walk wanders away from its start as √k; over a record of a few hundred
    rows a weak walk's excursion is as large as a small drift's, and a drift fitted
    with the walk's strength fixed from elsewhere (or estimated at 0 because smooth
    regressors absorbed it) takes that excursion for evidence. A drift is evidence only
    when the channel's best-fitting walk does not explain the channel as well.

    Parameters
    ----------
    y : ndarray (n,), the channel's readings minus the reference prediction
        [record unit] on rows ``idx``
    idx : ndarray (n,) of int, their row indices
    time_h : ndarray (n,), their times [h]
    filters : UnitFilters, optional, the caller's memo of filters (None: one for this
        call)

    Reference: Harvey (1989) sec. 5.1 (testing a deterministic trend against a
    stochastic level); Wilks S. S., Ann. Math. Statist. 9 (1938) 60-62 (LR test).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> n = 480
    >>> idx, t = np.arange(n), np.arange(n) / 30.0
    >>> walk = rng.normal(0, 1.0, n) + np.cumsum(rng.normal(0, 0.05, n))
    >>> drift = rng.normal(0, 1.0, n) + 0.5 * t
    >>> drift_vs_walk_p(walk, idx, t) > 0.01, drift_vs_walk_p(drift, idx, t) < 1e-6
    (True, True)
    """
    y = np.asarray(y, float)
    X = np.column_stack([np.ones(y.size), np.asarray(time_h, float)])
    return columns_vs_walk_p(y, idx, np.zeros((y.size, 0)), X, filters)


def columns_vs_walk_p(y: np.ndarray, idx: np.ndarray, X0: np.ndarray,
                      X1: np.ndarray, filters: UnitFilters | None = None) -> float:
    """p of the likelihood-ratio test of y = X1 β + white + walk against
    y = X0 β + white + walk (X0's columns among X1's), the walk-to-white ratio λ, β and
    σ_e profiled out under EACH hypothesis (χ² on the number of extra columns).

    The test of :func:`drift_vs_walk_p` for any columns, e.g. a thermometer's reading
    that a residual may follow: a random walk and a slowly varying signal correlate by
    chance far beyond the bound of independent samples (Granger C. W. J., Newbold P.,
    J. Econometrics 2 (1974) 111-120), and a misfit that follows the signal may pass
    for a walk; with the walk in both hypotheses, neither is taken for the other.

    Parameters
    ----------
    y : ndarray (n,), a residual [record unit] on rows ``idx``
    idx : ndarray (n,) of int, their row indices
    X0, X1 : ndarray (n, p0), (n, p1), the smaller and the larger model's columns
    filters : UnitFilters, optional, the caller's memo of filters (None: one for this
        call)

    Examples
    --------
    >>> rng = np.random.default_rng(4)
    >>> n = 480
    >>> idx, x = np.arange(n), np.sin(np.arange(n) / 80.0)
    >>> one, both = np.ones((n, 1)), np.column_stack([np.ones(n), x])
    >>> walk = rng.normal(0, 1.0, n) + np.cumsum(rng.normal(0, 0.2, n))
    >>> follows = rng.normal(0, 1.0, n) + 0.5 * x
    >>> columns_vs_walk_p(walk, idx, one, both) > 0.01, columns_vs_walk_p(follows, idx, one, both) < 1e-4
    (True, True)
    """
    from scipy.stats import chi2
    y = np.asarray(y, float)
    filters = UnitFilters() if filters is None else filters
    # y, X0 and X1 whitened at once per (λ, φ), shared by the two hypotheses
    Z, widths = np.column_stack([y, X0, X1]), (1, X0.shape[1], X1.shape[1])
    cache: dict = {}

    def whitened(lam, phi):
        key = (float(lam), float(phi))
        if key not in cache:
            W = filters.get(lam, phi, idx)
            cache[key] = (_split(W.apply(Z), widths), float(np.sum(np.log(W.F))))
        return cache[key]

    def m2ll(lam, phi, k):
        (yw, *Xw), log_F = whitened(lam, phi)
        return _ml_terms(yw[:, 0], Xw[k], log_F)
    l0 = profile_noise(lambda lam, phi: m2ll(lam, phi, 0))[0]
    l1 = profile_noise(lambda lam, phi: m2ll(lam, phi, 1))[0]
    return float(chi2.sf(max(l0 - l1, 0.0), max(X1.shape[1] - X0.shape[1], 1)))


def walk_profiled_lr_p(R0, R1, idxs, sigma, groups, df: int,
                       filters: UnitFilters | None = None) -> float:
    """p of the likelihood-ratio test of a larger fitted model (residuals ``R1``)
    against a smaller one (``R0``), each channel's noise white plus a random walk whose
    walk-to-white ratio λ per group (sensor kind) and common scale are profiled out
    under EACH model (χ² on ``df``).

    A test at one λ fitted once on the largest model takes a walk's excursion for an
    effect wherever that λ came out low; here the smaller model may explain the same
    wander by a larger walk, and the effect counts only beyond that.

    Parameters
    ----------
    R0, R1 : lists of ndarray (n_c,), per channel residual of the smaller / larger model
        on the rows ``idxs`` [record unit]
    idxs : list of int ndarray (n_c,)
    sigma : array_like (C,), each channel's white σ_c (second differences)
    groups : sequence (C,), the channel's sensor kind
    df : int, the larger model's extra parameters
    filters : UnitFilters, optional, the caller's memo of filters (None: one for this
        call)

    Examples
    --------
    >>> rng = np.random.default_rng(3)
    >>> n = 500; idx = np.arange(n); t = idx / 60.0
    >>> walk = [rng.normal(0, 1, n) + np.cumsum(rng.normal(0, 0.1, n)) for _ in range(3)]
    >>> fake = [w - (w[-1] - w[0]) * t / t[-1] for w in walk]   # a "drift" fitted away
    >>> walk_profiled_lr_p(walk, fake, [idx] * 3, [1.0] * 3, ["d"] * 3, 3) > 0.01
    True
    >>> real = [rng.normal(0, 1, n) + 0.5 * t for _ in range(3)]
    >>> walk_profiled_lr_p(real, [r - 0.5 * t for r in real], [idx] * 3, [1.0] * 3,
    ...                    ["d"] * 3, 1) < 1e-6
    True
    """
    from scipy.stats import chi2
    empty = [np.zeros((np.asarray(r).size, 0)) for r in R0]
    filters = UnitFilters() if filters is None else filters

    def m2ll(R):
        state = _joint_ratios(R, empty, idxs, sigma, groups, 2, filters)
        return _joint_terms(R, empty, idxs, sigma, [state[g][0] for g in groups],
                            [state[g][1] for g in groups])[0]
    lr = max(m2ll(list(R0)) - m2ll(list(R1)), 0.0)
    return float(chi2.sf(lr, max(int(df), 1)))
