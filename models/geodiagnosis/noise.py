"""A channel's measurement noise as white noise plus a random walk (a local-level
model), fitted from a residual's variogram, and the exact whitening of that noise by
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

The variogram ½E[(r_{k+h} − r_k)²] = σ_e² + h σ_w²/2 is linear in the lag h for this
noise; a smooth misfit adds ~h², so it is fitted on the residual of the LARGEST model
(every candidate cause at once, linearised), where the misfit is gone, as an F test's
error variance is taken from its full model.

References: Harvey A. C., "Forecasting, structural time series models and the Kalman
filter", CUP 1989, sec. 2.3 and 3.4 (local level, prediction-error decomposition);
Cressie N., "Statistics for spatial data", Wiley 1993, sec. 2.4 (variogram fit).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_banded

__all__ = ["LevelNoise", "fit_level_noise", "reml_level_noise", "reml_level_noise_pooled",
           "reml_joint", "Whitener", "whitener", "drift_vs_walk_p", "columns_vs_walk_p",
           "walk_profiled_lr_p"]


@dataclass(frozen=True)
class LevelNoise:
    """One channel's noise: ``sigma_white`` σ_e and ``sigma_walk`` σ_w per sample
    (record unit: µm or K)."""

    sigma_white: float
    sigma_walk: float = 0.0


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
    """Σ⁻¹ᐟ² of one channel's noise on a set of rows, as the local-level Kalman filter
    (module docstring): gains ``K`` (n,), innovation variances ``F`` (n,)."""

    K: np.ndarray
    F: np.ndarray

    def apply(self, X: np.ndarray) -> np.ndarray:
        """Whitened X (n,) or (n, m): the innovations divided by √F."""
        X = np.asarray(X, float)
        one = X.ndim == 1
        X2 = X[:, None] if one else X
        if not np.any(self.K):
            out = X2 / np.sqrt(self.F)[:, None]
        else:
            n = X2.shape[0]
            ab = np.zeros((2, n))
            ab[0] = 1.0
            ab[1, :-1] = -(1.0 - self.K[:-1])
            rhs = np.zeros_like(X2)
            rhs[1:] = self.K[:-1, None] * X2[:-1]
            pred = solve_banded((1, 0), ab, rhs, check_finite=False)
            out = (X2 - pred) / np.sqrt(self.F)[:, None]
        return out[:, 0] if one else out


def whitener(noise: LevelNoise, idx: np.ndarray) -> Whitener:
    """The :class:`Whitener` of ``noise`` on rows ``idx`` (int, increasing; the walk
    starts at 0 before row 0 and steps once per row, gaps included).

    Examples
    --------
    >>> z = LevelNoise(1.0, 0.3)
    >>> idx = np.arange(6)
    >>> S = np.eye(6) + 0.09 * np.minimum.outer(idx + 1, idx + 1)
    >>> W = whitener(z, idx).apply(np.eye(6))
    >>> bool(np.allclose(W @ S @ W.T, np.eye(6)))
    True
    """
    se2, sw2 = noise.sigma_white ** 2, noise.sigma_walk ** 2
    n = idx.size
    if sw2 <= 0:
        return Whitener(np.zeros(n), np.full(n, se2))
    K, F = np.empty(n), np.empty(n)
    P, last = 0.0, -1
    for i, k in enumerate(idx):
        P += sw2 * (k - last)
        last = k
        F[i] = P + se2
        K[i] = P / F[i]
        P = P * (1.0 - K[i])
    return Whitener(K, F)


def reml_level_noise(y: np.ndarray, X: np.ndarray, idx: np.ndarray, floor: float,
                     ratios=None) -> LevelNoise:
    """σ_e and σ_w of ``y`` = X β + noise by restricted maximum likelihood (REML):
    the ratio λ = σ_w²/σ_e² on a log grid (and 0), σ_e² profiled out, the regression's
    own degrees of freedom accounted for (a walk partly absorbed by X's columns, e.g. a
    sensor's offset and drift, is not taken for "no walk", as a variogram of the
    residual would). :func:`reml_level_noise_pooled` of one channel.

    Parameters
    ----------
    y : ndarray (n,), readings minus the nominal prediction [record unit] on rows ``idx``
    X : ndarray (n, p), the largest model's columns on those rows
    idx : ndarray (n,) of int
    floor : float, smallest σ_e [record unit]
    ratios : array_like, the λ grid (default 0 and 10^-7 … 10^-0.5)

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
    return reml_level_noise_pooled([(y, X, idx, floor)], ratios)[0]


def _reml_terms(y, X, idx, lam):
    """(−2 × restricted log-likelihood with σ_e² profiled out, σ_e²) at ratio λ."""
    W = whitener(LevelNoise(1.0, float(np.sqrt(lam))), idx)
    yw = W.apply(y)
    n = y.size
    if X.shape[1]:
        U, sv, _ = np.linalg.svd(W.apply(X), full_matrices=False)
        r = yw - U @ (U.T @ yw)
        p, logdet = X.shape[1], float(2.0 * np.sum(np.log(np.maximum(sv, 1e-300))))
    else:
        r, p, logdet = yw, 0, 0.0
    s2 = max(float(r @ r) / max(n - p, 1), 1e-300)
    return (n - p) * np.log(s2) + float(np.sum(np.log(W.F))) + logdet, s2


def reml_level_noise_pooled(channels, ratios=None) -> list:
    """REML of one ratio λ = σ_w²/σ_e² shared by several channels (sensors of one kind,
    e.g. the probes of one five-probe test), each with its own σ_e and its own
    regression: the summed restricted log-likelihood is maximised over λ. A weak walk
    (σ_w/σ_e ~ 0.05) is poorly determined by one channel of a few hundred rows, and an
    estimate of 0 on one channel made its intervals far too narrow.

    Parameters
    ----------
    channels : sequence of (y, X, idx, floor) as :func:`reml_level_noise`
    ratios : array_like, the λ grid

    Returns
    -------
    list of LevelNoise, one per channel
    """
    if ratios is None:
        ratios = np.concatenate([[0.0], 10.0 ** np.arange(-7.0, -0.49, 0.25)])
    prep = []
    for y, X, idx, floor in channels:
        if X.size and np.any(X):
            # an orthonormal basis of X's column space, its rank fixed once: the
            # restricted likelihood of different λ must see the same regression
            U, sv, _ = np.linalg.svd(X, full_matrices=False)
            X = U[:, sv > sv[0] * 1e-7]
        else:
            X = np.zeros((y.size, 0))
        prep.append((y, X, idx, floor))
    best = None
    for lam in ratios:
        terms = [_reml_terms(y, X, idx, lam) for y, X, idx, _ in prep]
        tot = sum(t[0] for t in terms)
        if best is None or tot < best[0]:
            best = (tot, lam, [t[1] for t in terms])
    _, lam, s2s = best
    return [LevelNoise(max(float(np.sqrt(s2)), floor), float(np.sqrt(lam * s2)))
            for s2, (_, _, _, floor) in zip(s2s, prep)]


def _joint_terms(Y, Xs, idxs, sig, lams):
    """(−2 restricted log-likelihood up to a constant, s²) of the joint regression:
    channel c's noise σ_c² s² (I + λ_c K_c), the columns shared across channels."""
    ys, xs, logF = [], [], 0.0
    for y, X, idx, sc, lam in zip(Y, Xs, idxs, sig, lams):
        W = whitener(LevelNoise(sc, sc * float(np.sqrt(lam))), idx)
        ys.append(W.apply(y))
        xs.append(W.apply(X))
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


def _joint_ratios(Y, Xs, idxs, sigma, groups, ratios=None, sweeps: int = 2) -> dict:
    """{group: λ} minimising :func:`_joint_terms` by coordinate sweeps on the grid."""
    if ratios is None:
        ratios = np.concatenate([[0.0], 10.0 ** np.arange(-7.0, -0.49, 0.25)])
    names = list(dict.fromkeys(groups))
    lam = {g: 0.0 for g in names}
    for _ in range(sweeps):
        for g in names:
            best = None
            for v in ratios:
                trial = {**lam, g: float(v)}
                obj, _ = _joint_terms(Y, Xs, idxs, sigma, [trial[k] for k in groups])
                if best is None or obj < best[0]:
                    best = (obj, float(v))
            lam[g] = best[1]
    return lam


def reml_joint(Y, Xs, idxs, sigma, groups, floors, ratios=None, sweeps: int = 2) -> list:
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
    ratios : the λ grid (default 0 and 10^-7 … 10^-0.5)
    sweeps : int, coordinate sweeps over the groups

    Returns
    -------
    list of LevelNoise
    """
    if ratios is None:
        ratios = np.concatenate([[0.0], 10.0 ** np.arange(-7.0, -0.49, 0.25)])
    Xcat = np.concatenate(Xs) if Xs else np.zeros((0, 0))
    if Xcat.size and np.any(Xcat):
        _, sv, Vt = np.linalg.svd(Xcat, full_matrices=False)
        T = Vt[sv > sv[0] * 1e-7].T
        Xs = [X @ T for X in Xs]
    lam = _joint_ratios(Y, Xs, idxs, sigma, groups, ratios, sweeps)
    _, s2 = _joint_terms(Y, Xs, idxs, sigma, [lam[k] for k in groups])
    s = float(np.sqrt(s2))
    return [LevelNoise(max(sc * s, fl), sc * s * float(np.sqrt(lam[g])))
            for sc, g, fl in zip(sigma, groups, floors)]


def _ml_terms(y: np.ndarray, X: np.ndarray, idx: np.ndarray, lam: float) -> float:
    """−2 × log-likelihood (up to a constant) of y = X β + white + walk at ratio λ,
    β and σ_e² profiled out (maximum likelihood: comparable across different X)."""
    W = whitener(LevelNoise(1.0, float(np.sqrt(lam))), idx)
    yw = W.apply(y)
    if X.shape[1]:
        Xw = W.apply(X)
        b, *_ = np.linalg.lstsq(Xw, yw, rcond=None)
        yw = yw - Xw @ b
    n = y.size
    return n * np.log(max(float(yw @ yw) / n, 1e-300)) + float(np.sum(np.log(W.F)))


def drift_vs_walk_p(y: np.ndarray, idx: np.ndarray, time_h: np.ndarray,
                    ratios=None) -> float:
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
    ratios : array_like, the λ grid (default 0 and 10^-7 … 10^-0.5)

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
    return columns_vs_walk_p(y, idx, np.zeros((y.size, 0)), X, ratios)


def columns_vs_walk_p(y: np.ndarray, idx: np.ndarray, X0: np.ndarray, X1: np.ndarray,
                      ratios=None) -> float:
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
    ratios : array_like, the λ grid (default 0 and 10^-7 … 10^-0.5)

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
    if ratios is None:
        ratios = np.concatenate([[0.0], 10.0 ** np.arange(-7.0, -0.49, 0.25)])
    y = np.asarray(y, float)
    l0 = min(_ml_terms(y, X0, idx, float(v)) for v in ratios)
    l1 = min(_ml_terms(y, X1, idx, float(v)) for v in ratios)
    return float(chi2.sf(max(l0 - l1, 0.0), max(X1.shape[1] - X0.shape[1], 1)))


def walk_profiled_lr_p(R0, R1, idxs, sigma, groups, df: int, ratios=None) -> float:
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
    ratios : the λ grid (default 0 and 10^-7 … 10^-0.5)

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

    def m2ll(R):
        lam = _joint_ratios(R, empty, idxs, sigma, groups, ratios)
        return _joint_terms(R, empty, idxs, sigma, [lam[g] for g in groups])[0]
    lr = max(m2ll(list(R0)) - m2ll(list(R1)), 0.0)
    return float(chi2.sf(lr, max(int(df), 1)))
