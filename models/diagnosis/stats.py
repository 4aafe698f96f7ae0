"""Residual statistics for the diagnosis: error measures, whiteness, cross-correlation,
effective sample size and the model-comparison test.

Residuals of a thermal model against a record are autocorrelated (a missing slow
effect leaves a slow residual), so every test here counts *effective* samples
N_eff = N (1 − ρ1)/(1 + ρ1) (the AR(1) variance-inflation rule), not raw samples;
otherwise a 10 000-sample record makes every candidate "significant".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats as _st

__all__ = ["rmse", "fit_percent", "lag1", "effective_n", "ljung_box_p", "xcorr", "noise_sigma",
           "resolution",
           "bic", "f_test_p", "corr_bound", "ccf", "acf", "contiguous_blocks",
           "slow_noise_sandwich", "SlowNoiseCovariances", "P_FLOOR", "format_p", "p_text"]


def rmse(r) -> float:
    """Root-mean-square of a residual [unit of r].

    Examples
    --------
    >>> rmse([3.0, -4.0])
    3.5355339059327378
    """
    r = np.asarray(r, float)
    return float(np.sqrt(np.mean(r * r))) if r.size else float("nan")


def fit_percent(y, yhat) -> float:
    """NRMSE fit 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) [%] (100 = perfect, 0 = the mean).

    Examples
    --------
    >>> fit_percent([0.0, 2.0], [0.0, 2.0])
    100.0
    """
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    den = np.linalg.norm(y - y.mean())
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / den)) if den > 0 else float("nan")


def lag1(r) -> float:
    """Lag-1 autocorrelation ρ1 [-] of a residual.

    Examples
    --------
    >>> lag1(np.sin(np.linspace(0, 3, 300))) > 0.98
    True
    """
    r = np.asarray(r, float) - np.mean(r)
    den = float(r @ r)
    return float((r[1:] @ r[:-1]) / den) if den > 0 and r.size > 2 else 0.0


def effective_n(n: int, rho1: float) -> float:
    """Effective number of independent samples N (1 − ρ)/(1 + ρ) [-], ρ clipped to [0, 0.995].

    Examples
    --------
    >>> effective_n(1000, 0.0), round(effective_n(1000, 0.9), 1)
    (1000.0, 52.6)
    """
    rho = min(max(float(rho1), 0.0), 0.995)
    return max(float(n) * (1.0 - rho) / (1.0 + rho), 2.0)


def effective_n_slow(r, blocks: int = 20) -> float:
    """Effective sample size that sees low-frequency noise: N/τ, with τ the variance
    inflation of the mean over ``blocks`` contiguous blocks (batch means) [-].

    The lag-1 form N(1 − ρ1)/(1 + ρ1) sees only the correlation between neighbours: a
    residual of white noise plus a slow wander (a displacement sensor's electronics)
    has a small ρ1 and yet a variance at the record's slow frequencies, where the
    candidate causes live, many times the white part's. The batch-means estimate
    τ = m·var(block means)/var(r) (m samples per block) measures it there.

    Parameters
    ----------
    r : array_like
        Residual [any unit], in time order; non-finite values are dropped.
    blocks : int
        Number of contiguous blocks [-].

    Returns
    -------
    float
        N/τ, at least 2 (N where τ < 1).

    References
    ----------
    Batch means: Geyer C. J., "Practical Markov chain Monte Carlo", Statist. Sci. 7 (1992)
    473-483, sec. 3.1.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> w = rng.normal(size=4000)
    >>> effective_n_slow(w) > 1500, effective_n_slow(w + np.cumsum(rng.normal(0, 0.1, 4000))) < 100
    (True, True)
    """
    r = np.asarray(r, float)
    r = r[np.isfinite(r)]
    n = r.size
    m = n // blocks
    if m < 2:
        return effective_n(n, lag1(r)) if n > 2 else 2.0
    r = r - r.mean()
    v = float(r @ r) / n
    if v <= 0:
        return float(n)
    means = r[:m * blocks].reshape(blocks, m).mean(axis=1)
    tau = m * float(np.var(means, ddof=1)) / v
    return float(max(n / max(tau, 1.0), 2.0))


def noise_n_eff(r) -> float:
    """The effective sample size of a residual for every test and interval of the
    diagnosis: the smaller of the lag-1 form (:func:`effective_n`) and the batch-means
    form (:func:`effective_n_slow`), so that neither a correlated neighbourhood nor a
    slow wander passes for independent samples [-].

    Examples
    --------
    >>> rng = np.random.default_rng(2)
    >>> round(noise_n_eff(rng.normal(size=1000)) / 1000, 1)
    1.0
    """
    r = np.asarray(r, float)
    r = r[np.isfinite(r)]
    return min(effective_n(r.size, lag1(r)), effective_n_slow(r))


def ljung_box_p(r, lags: int = 20) -> float:
    """Ljung–Box portmanteau p-value of residual whiteness (paper eq. 19).

    Q = N(N+2) Σ_k ρ_k²/(N − k), χ² with ``lags`` degrees of freedom
    (:func:`statsmodels.stats.diagnostic.acorr_ljungbox`). Small p: not white.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> ljung_box_p(rng.normal(size=2000)) > 0.01, ljung_box_p(np.sin(np.arange(500) / 20)) < 1e-6
    (True, True)
    """
    from statsmodels.stats.diagnostic import acorr_ljungbox
    r = np.asarray(r, float)
    lags = int(min(lags, max(1, r.size // 5)))
    res = acorr_ljungbox(r - r.mean(), lags=[lags], return_df=True)
    return float(res["lb_pvalue"].iloc[-1])


def acf(r, max_lag: int) -> np.ndarray:
    """Autocorrelation ρ_0..ρ_max_lag [-] of a residual.

    Every lag from one FFT correlation, O(N log N): for the figures' 2880 lags of a
    real record, the lag-by-lag products (:func:`_acf_direct`) took seconds (issue 30).
    Equal to them to round-off (~1e-16 of ρ_0).

    Examples
    --------
    >>> r = np.sin(np.arange(500) / 7.0)
    >>> bool(np.allclose(acf(r, 100), _acf_direct(r, 100), rtol=0, atol=1e-13))
    True
    """
    r = np.asarray(r, float) - np.mean(r)
    m = int(min(max_lag, r.size - 1))
    den = float(r @ r) or 1.0
    if m < 16 or not np.all(np.isfinite(r)):
        return _acf_direct(r, max_lag)
    from scipy.signal import correlate
    return correlate(r, r, mode="full", method="fft")[r.size - 1:r.size + m] / den


def _acf_direct(r, max_lag: int) -> np.ndarray:
    """:func:`acf` lag by lag (one dot product each): the reference, and the form whose
    every value the interval rules' thresholds see (:func:`contiguous_blocks`)."""
    r = np.asarray(r, float) - np.mean(r)
    den = float(r @ r) or 1.0
    m = int(min(max_lag, r.size - 1))
    return np.array([float(r[k:] @ r[:r.size - k]) / den for k in range(m + 1)])


def contiguous_blocks(r, block_corr: int, min_blocks: int, max_blocks: int) -> int:
    """How many contiguous blocks to cut a residual into so that each is at least
    ``block_corr`` correlation times long (the lag where its autocorrelation first falls
    below 1/e), kept within [``min_blocks``, ``max_blocks``] -- the blocks of the
    block-sandwich and block-jackknife intervals.

    Examples
    --------
    >>> contiguous_blocks(np.random.default_rng(0).normal(size=1000), 5, 4, 10)
    10
    >>> contiguous_blocks(np.sin(np.arange(1000) / 100.0), 5, 4, 10)
    4
    """
    r = np.asarray(r, float)
    n = r.size
    a = _acf_direct(r, min(n // 2, 5000))    # the exact products: a threshold reads them
    below = np.flatnonzero(a < np.exp(-1.0))
    corr = int(below[0]) if below.size else n
    return int(np.clip(n // max(block_corr * corr, 1), min_blocks, max_blocks))


def xcorr(r, x) -> float:
    """Zero-lag normalised cross-correlation of residual ``r`` with signal ``x`` [-],
    over the samples where both are finite (a sensor may have empty cells).

    Examples
    --------
    >>> xcorr([1.0, 2.0, 3.0], [2.0, 4.0, 6.5]) > 0.99
    True
    >>> xcorr([1.0, 2.0, 3.0, 9.0], [2.0, 4.0, 6.5, float("nan")]) > 0.99
    True
    """
    r, x = np.asarray(r, float), np.asarray(x, float)
    ok = np.isfinite(r) & np.isfinite(x)
    r = r[ok] - np.mean(r[ok]) if ok.any() else r[:0]
    x = x[ok] - np.mean(x[ok]) if ok.any() else x[:0]
    den = np.linalg.norm(r) * np.linalg.norm(x)
    return float(r @ x / den) if den > 0 else 0.0


def noise_sigma(y, trim: float = 0.02) -> float:
    """Standard deviation of the measurement noise on ``y`` [unit of y], from its second
    differences: for white noise E[(Δ²y)²] = 6σ², while a smooth thermal response adds
    almost nothing at one sample; the largest ``trim`` fraction (outliers, the kinks where
    the input switches) is left out.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(5000) * 60.0
    >>> y = 20 * (1 - np.exp(-t / 3600)) + rng.normal(0, 0.1, t.size)
    >>> round(noise_sigma(y), 2)
    0.09
    """
    d2 = np.diff(np.asarray(y, float), 2)
    d2 = np.sort(np.abs(d2[np.isfinite(d2)]))
    if d2.size < 10:
        return float("nan")
    d2 = d2[:max(1, int(np.ceil((1.0 - trim) * d2.size)))]
    return float(np.sqrt(np.mean(d2 ** 2) / 6.0))


#: a record is quantised when at least this share of its non-zero steps lie within
#: ±10 % of a whole number of quanta (continuous noise gives about 0.2)
LATTICE_SHARE = 0.8


def resolution(y) -> float:
    """The sensor's resolution (quantum) [unit of y], or 0 where ``y`` is not quantised.

    A quantised sensor moves in whole quanta: its non-zero steps |Δy| cluster at
    integer multiples of one value. The quantum is first taken as the median non-zero
    step (a quantised record's typical move is one quantum), then refined as the median
    of Δy / round(Δy / q) over the steps on the lattice. The record counts as quantised
    when at least :data:`LATTICE_SHARE` of its non-zero steps sit within ±10 % of the
    lattice; continuous noise puts about 20 % there, so a rare offset step (a sensor's
    zero shifting by a fraction of a quantum) does not hide the quantisation. Its
    quantisation noise is then resolution/√12, a floor for every noise scale.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(4000) * 60.0
    >>> y = 5 * (1 - np.exp(-t / 7200)) + rng.normal(0, 0.05, t.size)
    >>> round(resolution(np.round(y / 0.255) * 0.255), 3), resolution(y)
    (0.255, 0.0)
    """
    d = np.abs(np.diff(np.asarray(y, float)))
    d = d[np.isfinite(d)]
    nz = d[d > 1e-9 * max(float(np.max(d)) if d.size else 0.0, 1e-300)]
    if nz.size < 10:
        return 0.0
    q = float(np.median(nz))
    k = np.round(nz / q)
    on = (k >= 1) & (np.abs(nz / q - k) < 0.1)
    if on.mean() < LATTICE_SHARE:
        return 0.0
    return float(np.median(nz[on] / k[on]))


def bic(rss: float, n: int, n_eff: float, k: int) -> float:
    """Bayesian information criterion on effective samples: N_eff ln(RSS/N) + k ln N_eff.

    Examples
    --------
    >>> bic(10.0, 100, 100.0, 0) < bic(10.0, 100, 100.0, 1)
    True
    """
    return float(n_eff * np.log(max(rss, 1e-300) / n) + k * np.log(n_eff))


def f_test_p(rss0: float, rss1: float, k: int, n_eff: float) -> float:
    """p-value of the nested F test that ``k`` extra parameters cut RSS0 to RSS1.

    F = ((RSS0 − RSS1)/k) / (RSS1/(N_eff − k)), on effective samples.

    Examples
    --------
    >>> f_test_p(100.0, 50.0, 1, 200.0) < 1e-6, f_test_p(100.0, 99.9, 1, 200.0) > 0.5
    (True, True)
    """
    if k <= 0 or rss1 <= 0:
        return 1.0
    dof = max(n_eff - k, 1.0)
    F = max(rss0 - rss1, 0.0) / k / (rss1 / dof)
    return float(_st.f.sf(F, k, dof))


#: the smallest p-value shown as a number: below it (and where the tail probability
#: underflows to 0 in double precision) a p-value is shown as "< 1e-16". Below about
#: machine epsilon the value rests on the far tail of a χ² or F approximation and says
#: no more than "far below any significance level"; R's format.pval uses the same floor.
P_FLOOR = 1e-16


def format_p(p) -> str:
    """A p-value [-] as shown in every text of the diagnosis (Markdown, HTML, terminal):
    three significant digits, ``"< 1e-16"`` below :data:`P_FLOOR` (a value that
    underflowed to 0 is not "p = 0"), ``"–"`` where none was computed. ``diagnosis.json``
    keeps the float.

    Examples
    --------
    >>> format_p(0.013512), format_p(2.2e-5), format_p(0.0), format_p(3e-300), format_p(None)
    ('0.0135', '2.2e-05', '< 1e-16', '< 1e-16', '–')
    >>> format_p(1.0), format_p(float("nan"))
    ('1', '–')
    """
    if p is None or not np.isfinite(p):
        return "–"
    return f"< {P_FLOOR:g}" if p < P_FLOOR else f"{p:.3g}"


def p_text(p) -> str:
    """``"p = 0.0135"``, ``"p < 1e-16"`` or ``"p not computed"``: :func:`format_p` in a
    sentence.

    Examples
    --------
    >>> p_text(0.00221), p_text(0.0), p_text(None)
    ('p = 0.00221', 'p < 1e-16', 'p not computed')
    """
    v = format_p(p)
    return "p not computed" if v == "–" else ("p " + v if v.startswith("<") else "p = " + v)


def corr_bound(n_eff: float, level: float = 0.95) -> float:
    """Two-sided significance bound of a correlation coefficient on ``n_eff`` independent
    samples [-]: r* = t*/√(N_eff − 2 + t*²), t* the Student quantile on N_eff − 2 degrees
    of freedom (the exact test of a Pearson correlation); always <= 1, and 1 (nothing
    is significant) when N_eff <= 3. For large N it tends to 1.96/√N.

    Examples
    --------
    >>> round(corr_bound(10000), 4), corr_bound(2.5)
    (0.0196, 1.0)
    """
    dof = float(n_eff) - 2.0
    if dof < 1.0:
        return 1.0
    tq = float(_st.t.ppf(0.5 + level / 2.0, dof))
    return float(tq / np.sqrt(dof + tq * tq))


def ccf(r, x, max_lag: int) -> np.ndarray:
    """Normalised cross-correlation of residual ``r`` with signal ``x`` at lags
    −max_lag..max_lag [samples]: entry k is corr(r_t, x_{t−lag}) (positive lag: the
    residual follows the signal), over the samples where both are finite.

    Each entry is :func:`xcorr` of the overlapping parts (their own means removed). For
    finite series all lags are computed at once -- the lagged products by one FFT
    correlation, the overlaps' sums and sums of squares by prefix sums -- O(N log N)
    instead of O(N·max_lag) (issue 30: the per-lag loop took most of a real record's
    diagnosis, 2 × 2880 lags of 11 000 samples per signal); the result equals the
    per-lag one to round-off (:func:`_ccf_loop`, which series with gaps still use).

    Examples
    --------
    >>> x = np.sin(np.arange(400) / 10.0)
    >>> c = ccf(np.roll(x, 5), x, 10)
    >>> int(np.argmax(c)) - 10
    5
    >>> bool(np.allclose(c, _ccf_loop(np.roll(x, 5), x, 10), rtol=0, atol=1e-12))
    True
    """
    r, x = np.asarray(r, float), np.asarray(x, float)
    n = min(r.size, x.size)
    if (r.size != x.size or n < 2 or max_lag >= n - 1
            or not (np.all(np.isfinite(r)) and np.all(np.isfinite(x)))):
        return _ccf_loop(r, x, max_lag)
    from scipy.signal import correlate
    # centring by constants leaves every correlation unchanged and keeps the
    # sum-of-squares differences below free of cancellation
    r = r - r.mean()
    x = x - x.mean()
    lags = np.arange(-max_lag, max_lag + 1)
    sab = correlate(r, x, mode="full", method="fft")[lags + n - 1]
    cr, cx = (np.concatenate([[0.0], np.cumsum(v)]) for v in (r, x))
    cr2, cx2 = (np.concatenate([[0.0], np.cumsum(v * v)]) for v in (r, x))
    pos = lags >= 0
    L = np.abs(lags)
    m = (n - L).astype(float)
    # lag >= 0: r[L:] with x[:n-L]; lag < 0: r[:n-L] with x[L:]
    a_lo, a_hi = np.where(pos, L, 0), np.where(pos, n, n - L)
    b_lo, b_hi = np.where(pos, 0, L), np.where(pos, n - L, n)
    sa, saa = cr[a_hi] - cr[a_lo], cr2[a_hi] - cr2[a_lo]
    sb, sbb = cx[b_hi] - cx[b_lo], cx2[b_hi] - cx2[b_lo]
    num = sab - sa * sb / m
    var = np.maximum(saa - sa * sa / m, 0.0) * np.maximum(sbb - sb * sb / m, 0.0)
    den = np.sqrt(var)
    out = np.zeros(lags.size)
    ok = den > 0
    out[ok] = num[ok] / den[ok]
    return out


def _ccf_loop(r, x, max_lag: int) -> np.ndarray:
    """:func:`ccf` lag by lag (:func:`xcorr` of each overlap): the reference, and the
    form used for series with non-finite samples."""
    r, x = np.asarray(r, float), np.asarray(x, float)
    out = np.zeros(2 * max_lag + 1)
    for k, lag in enumerate(range(-max_lag, max_lag + 1)):
        if lag >= 0:
            a, b = r[lag:], x[:x.size - lag]
        else:
            a, b = r[:r.size + lag], x[-lag:]
        out[k] = xcorr(a, b)
    return out


def _ar1_apply(X: np.ndarray, rho: float) -> np.ndarray:
    """R X with R_ij = ρ^|i−j| (the correlation matrix of a stationary AR(1)), by a
    forward and a backward first-order filter: O(N) per column."""
    from scipy.signal import lfilter
    if rho == 0.0:
        return X.copy()
    f = lfilter([1.0], [1.0, -rho], X, axis=0)
    b = lfilter([1.0], [1.0, -rho], X[::-1], axis=0)[::-1]
    return f + b - X


#: How far above white noise's own scatter the residual's long-lag sums must stand
#: before :func:`slow_noise_sandwich` fits a slow part [standard deviations]: 3, a
#: false alarm rate of about 0.1 % per lag on white noise.
SLOW_NOISE_Z = 3.0


@dataclass(frozen=True)
class SlowNoiseCovariances:
    """The covariances of a least-squares estimate under two slow + white noise models
    fitted through the fit (:func:`slow_noise_sandwich`).

    Attributes
    ----------
    ar1_cov : ndarray, shape (p, p)
        Under a stationary AR(1) slow part plus white noise [parameter units²].
    ar1_rho : float
        ρ of that AR(1), per sample [-] (0 where no slow part was fitted).
    ar1_slow_var : float
        σa², the AR(1) part's variance [unit²].
    ar1_white_var : float
        σw², the white part's variance beside it [unit²].
    walk_cov : ndarray, shape (p, p)
        Under a random walk plus white noise [parameter units²].
    walk_step_var : float
        σrw², the walk's variance per sample [unit² per sample].
    walk_white_var : float
        σw², the white part's variance beside it [unit²].
    """

    ar1_cov: np.ndarray
    ar1_rho: float
    ar1_slow_var: float
    ar1_white_var: float
    walk_cov: np.ndarray
    walk_step_var: float
    walk_white_var: float


def slow_noise_sandwich(J, r, long_lag: int = 240) -> SlowNoiseCovariances | None:
    """Covariances of a least-squares estimate under two models of slow + white noise,
    each fitted through the fit.

    A cause fitted to a record absorbs part of the record's slow noise, so the residual
    r = (I − H)e under-reads it: its variance and autocorrelation are those of the
    projected noise, not of the noise. For any noise covariance Σ the expected residual
    lag-k sums are exact linear functions of Σ and of the Jacobian J:

        E[rᵀ D_k r] = tr(D_k Σ) − 2 tr(A (ΣJ)ᵀ D_k J) + tr(A JᵀΣJ A JᵀD_k J)

    with H = J A Jᵀ, A = (JᵀJ)⁻¹ and D_k the symmetric lag-k pairing (D_0 = I). Two
    noise models are fitted to the observed sums at lags 0, 1, L/4 and L (non-negative
    least squares; L = ``long_lag``, 4 h at 60 s, at most N/8):

    * AR(1) (``ar1_*``): Σ = σa² R(ρ) + σw² I, R_ij = ρ^|i−j| (stationary slow noise), ρ on a
      grid in (1 − ρ) from 1 to 5e-4;
    * random walk (``walk_*``): Σ = σrw² W + σw² I, W_ij = min(i, j) + 1 (a random walk, e.g. a
      displacement sensor's electronics).

    Lag 1 separates the white part; the long lags see the wander at the causes' own time
    scales. A slow part is fitted only where the sum at lag 1, L/4 or L stands more than
    :data:`SLOW_NOISE_Z` of white noise's own scatter (σ²√(N − k)) above zero; otherwise
    both covariances are the white s² A. A stationary AR(1) cannot carry a random walk's power at the slowest
    frequencies (an interval from it covered 84 % under a walk in a simulation of 1500
    samples), and a walk model over-covers a stationary noise (100 %), so the caller
    takes the wider.
    Each covariance is the sandwich A JᵀΣJ A.

    Parameters
    ----------
    J : ndarray, shape (N, p)
        Jacobian of the prediction on the fit rows, in time order [unit per parameter].
    r : ndarray, shape (N,)
        Residual on the same rows [unit].
    long_lag : int
        The long lag L [samples].

    Returns
    -------
    SlowNoiseCovariances or None
        Both covariances and the fitted noise models; None where the record is too
        short (N < 64) or the residual is zero.

    References
    ----------
    Sandwich covariance: White H., Econometrica 48 (1980) 817-838; the residual of a
    linear fit as a projection of the noise: Seber G. A. F., Lee A. J., Linear
    Regression Analysis, 2nd ed. (2003), sec. 3.3.

    Examples
    --------
    >>> rng = np.random.default_rng(3)
    >>> t = np.linspace(0.0, 1.0, 3000)
    >>> J = np.column_stack([np.ones_like(t), t])
    >>> e = np.zeros(3000)
    >>> for i in range(1, 3000):
    ...     e[i] = 0.99 * e[i - 1] + rng.normal(0, 0.02)
    >>> e += rng.normal(0, 0.1, 3000)
    >>> r = e - J @ np.linalg.lstsq(J, e, rcond=None)[0]
    >>> out = slow_noise_sandwich(J, r)
    >>> bool(abs(out.ar1_rho - 0.99) < 0.007), bool(abs(out.ar1_white_var / 0.01 - 1) < 0.1)
    (True, True)
    """
    J, r = np.asarray(J, float), np.asarray(r, float)
    n, p = J.shape
    A = np.linalg.pinv(J.T @ J)
    lags, obs = _observed_lag_sums(r, long_lag)
    if obs is None:
        return None
    sums = _LagSums(J, A, lags)
    m_white, MI = sums.expected(J, [n if k == 0 else 0.0 for k in lags])
    s2, z = _white_noise_z(obs, lags, n, p)
    if z < SLOW_NOISE_Z:       # white: both covariances are s² A
        return SlowNoiseCovariances(s2 * A, 0.0, 0.0, float(s2), s2 * A, 0.0, float(s2))
    sw, MW = _fit_walk_noise(sums, J, n, lags, m_white, obs)
    rho, sa, MR = _fit_ar1_noise(sums, J, n, lags, m_white, obs)
    return SlowNoiseCovariances(A @ (sa[0] * MR + sa[1] * MI) @ A, rho, float(sa[0]),
                                float(sa[1]), A @ (sw[0] * MW + sw[1] * MI) @ A,
                                float(sw[0]), float(sw[1]))


def _observed_lag_sums(r, long_lag):
    """The lags 0, 1, L/4 and L (L = ``long_lag``, at most N/8) and the residual's sums
    rᵀD_k r at them [unit²]; (None, None) where L < 8 or the residual is zero."""
    n = r.size
    L = int(min(long_lag, n // 8))
    if float(r @ r) <= 0 or L < 8:
        return None, None
    lags = (0, 1, L // 4, L)
    return lags, np.array([float(r[k:] @ r[:n - k]) for k in lags])


class _LagSums:
    """The expected residual lag-k sums E[rᵀD_k r] of a least-squares fit with Jacobian
    ``J`` (N, p) and A = (JᵀJ)⁻¹, under a noise covariance Σ (see
    :func:`slow_noise_sandwich`); D_k the symmetric lag-k pairing."""

    def __init__(self, J, A, lags):
        self.A, self.lags, self.J = A, lags, J
        self.DJ = {k: _lag_pairing(J, k) for k in lags}
        self.MD = {k: J.T @ self.DJ[k] for k in lags}

    def expected(self, SJ, tr_d):
        """E[rᵀD_k r] per lag for noise covariance S (S J given, tr(D_k S) given), and
        JᵀSJ."""
        A = self.A
        MS = self.J.T @ SJ
        AMA = A @ MS @ A
        return np.array([tr_d[i] - 2.0 * float(np.sum(A * (SJ.T @ self.DJ[k])))
                         + float(np.sum(AMA * self.MD[k]))
                         for i, k in enumerate(self.lags)]), MS


def _lag_pairing(X, k):
    """D_k X: the symmetric lag-k pairing (D_0 = I)."""
    if k == 0:
        return X
    Y = np.zeros_like(X)
    Y[:-k] += 0.5 * X[k:]
    Y[k:] += 0.5 * X[:-k]
    return Y


def _fit_noise_variances(m_slow, m_white, obs):
    """Non-negative least squares of the observed lag sums on a slow and a white
    model's expected ones (each per unit variance), scaled by the lag-0 sum: the two
    variances [unit²] and the residual norm."""
    from scipy.optimize import nnls
    return nnls(np.column_stack([m_slow, m_white]) / obs[0], obs / obs[0])


def _white_noise_z(obs, lags, n, p):
    """The white variance s² = RSS/(N − p) [unit²] and how many of white noise's own
    scatter the largest lag-k sum (k >= 1) stands above zero [-]. Under white noise a
    lag-k sum scatters by about σ²√(N − k): a slow part is fitted only where the long-lag
    sums stand above that by SLOW_NOISE_Z, since a spurious slow part of a few % of the
    variance, near ρ = 1, would multiply the interval."""
    s2 = obs[0] / max(n - p, 1)
    return s2, max(obs[i] / (s2 * np.sqrt(n - k)) for i, k in enumerate(lags) if k >= 1)


def _fit_walk_noise(sums, J, n, lags, m_white, obs):
    """The random walk + white noise that best fits the lag sums: ((σrw², σw²) [unit²],
    JᵀWJ) with W_ij = min(i, j) + 1."""
    WJ = np.cumsum(np.cumsum(J[::-1], axis=0)[::-1], axis=0)    # W_ij = min(i, j) + 1
    m_walk, MW = sums.expected(WJ, [(n - k) * (n - k + 1) / 2.0 for k in lags])
    sw, _ = _fit_noise_variances(m_walk, m_white, obs)
    return sw, MW


def _fit_ar1_noise(sums, J, n, lags, m_white, obs):
    """The stationary AR(1) + white noise that best fits the lag sums, ρ on a grid in
    (1 − ρ) from 1 to 5e-4: (ρ, (σa², σw²) [unit²], JᵀR(ρ)J)."""
    best = None
    for rho in np.concatenate([[0.0], 1.0 - np.geomspace(1.0, 5e-4, 40)[1:]]):
        m_ar, MR = sums.expected(_ar1_apply(J, rho), [(n - k) * rho ** k for k in lags])
        sa, res = _fit_noise_variances(m_ar, m_white, obs)
        if best is None or res < best[0]:
            best = (res, float(rho), sa, MR)
    _, rho, sa, MR = best
    return rho, sa, MR
