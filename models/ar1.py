"""First-order autoregressive (AR(1)) model of axial thermal growth.

Paper model (Du et al. 2021, eqs. 12-14)::

    ΔL_n = C1 ΔL_{n-1} + C2(q_n)
    C1 = exp(-b Δτ)                               (eq. 13)
    C2 = -q α a / (λ b) · (exp(-b Δτ) - 1)        (eq. 14)

with a = λ/(ρc) and b = 2h/(ρcR). In the 1D fin theory the volume-integrated
temperature obeys d(∫θ dx)/dt = q a/λ − b ∫θ dx exactly, so eq. 12 is exact for
the 1D rod; the 3D rod departs from it only through radial conduction.

Physics-corrected model (:func:`corrected_coefficients`): for a cylinder with
uniform lateral h, uniform end flux and an adiabatic far end, the growth
α∫θ dV / A couples only to the axially uniform modes J0(μ_m r/R), where
μ J1(μ) = Bi J0(μ) and Bi = hR/λ. The slowest one (m = 1) carries all but
O(Bi²) of the response, so an AR(1) with C1 = exp(−a μ1² Δτ / R²) and C2 from
that mode's exact steady weight tracks the 3D rod -- derived, not fitted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.special import j0, j1, jn_zeros

from arfem.params import InputError, Rod, Schedule

__all__ = ["c1_paper", "c2_paper", "steady_growth_m", "radial_eigenvalue",
           "corrected_coefficients", "ar1_simulate", "ar1_on_schedule", "fit_ar1", "AR1Fit",
           "eq17_least_squares"]


def _dtau(dtau_s) -> float:
    try:
        d = float(dtau_s)
    except (TypeError, ValueError):
        raise InputError(f"must be a number, got {dtau_s!r}", "dtau_s") from None
    if not (math.isfinite(d) and d > 0):
        raise InputError(f"must be > 0, got {dtau_s!r}", "dtau_s")
    return d


def _flux(q_W_m2) -> float:
    try:
        q = float(q_W_m2)
    except (TypeError, ValueError):
        raise InputError(f"must be a number, got {q_W_m2!r}", "q_W_m2") from None
    if not math.isfinite(q):
        raise InputError(f"must be finite, got {q_W_m2!r}", "q_W_m2")
    return q


def c1_paper(rod: Rod, dtau_s: float) -> float:
    """Autoregressive coefficient C1 = exp(−bΔτ), paper eq. 13.

    Parameters
    ----------
    rod : Rod
        Supplies b = 2h/(ρcR) [1/s].
    dtau_s : float
        AR time step Δτ [s].

    Returns
    -------
    float
        C1 [-].

    References
    ----------
    Du et al., J. Harbin Inst. Technol. 53(7), 2021, eq. 13.

    Examples
    --------
    >>> round(c1_paper(Rod(), 30.0), 4)
    0.9909
    """
    return math.exp(-rod.fin_rate_1_s * _dtau(dtau_s))


def steady_growth_m(rod: Rod, q_W_m2: float) -> float:
    """Steady 1D growth q α a / (λ b) = q α R / (2h) [m] (the fixed point of eq. 12).

    Parameters
    ----------
    rod : Rod
    q_W_m2 : float
        Constant heat flux into the heated end [W/m²].

    Returns
    -------
    float
        ΔL_∞ = C2 / (1 − C1) [m], paper eqs. 8 and 12 at t → ∞.

    Examples
    --------
    >>> round(steady_growth_m(Rod(), 2000.0) * 1e6, 3)
    21.818
    """
    return _flux(q_W_m2) * rod.expansion_1_K * rod.diffusivity_m2_s / (
        rod.conductivity_W_mK * rod.fin_rate_1_s)


def c2_paper(rod: Rod, dtau_s: float, q_W_m2: float) -> float:
    """Input coefficient C2 = −qαa/(λb)·(e^{−bΔτ} − 1) [m], paper eq. 14.

    Parameters
    ----------
    rod : Rod
    dtau_s : float
        AR time step Δτ [s].
    q_W_m2 : float
        Heat flux into the heated end [W/m²].

    Returns
    -------
    float
        C2 [m] (multiply by 1e6 for µm).

    References
    ----------
    Du et al., J. Harbin Inst. Technol. 53(7), 2021, eq. 14.

    Examples
    --------
    >>> round(c2_paper(Rod(), 30.0, 2000.0) * 1e6, 4), round(c2_paper(Rod(), 30.0, 3000.0) * 1e6, 4)
    (0.1985, 0.2977)
    """
    return -steady_growth_m(rod, q_W_m2) * (math.exp(-rod.fin_rate_1_s * _dtau(dtau_s)) - 1.0)


def radial_eigenvalue(biot: float, m: int = 1) -> float:
    """m-th root μ of μ J1(μ) = Bi J0(μ) (radial modes of a convectively cooled cylinder).

    Parameters
    ----------
    biot : float
        Biot number Bi = hR/λ [-], > 0.
    m : int
        Which root, 1 = the slowest mode.

    Returns
    -------
    float
        μ_m [-]. It lies between the (m−1)-th zero of J1 (0 for m = 1) and the
        m-th zero of J0, where the function changes sign; Brent's method in that
        bracket finds it for any Bi > 0.

    Examples
    --------
    >>> mu = radial_eigenvalue(0.11)
    >>> round(mu, 5), round(mu**2 / (2 * 0.11), 4)   # μ² → 2 Bi as Bi → 0
    (0.46267, 0.973)
    """
    try:
        bi = float(biot)
    except (TypeError, ValueError):
        raise InputError(f"must be a number, got {biot!r}", "biot") from None
    if not (bi > 0 and math.isfinite(bi)):
        raise InputError(f"must be > 0, got {biot!r}", "biot")
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
        raise InputError(f"must be an integer >= 1, got {m!r}", "m")
    lo = 0.0 if m == 1 else float(jn_zeros(1, m - 1)[-1])
    hi = float(jn_zeros(0, m)[-1])
    f = lambda x: x * j1(x) - bi * j0(x)
    return float(brentq(f, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps))


def _mode_weight(rod: Rod, mu: float) -> float:
    """(∫φ dA)² / (A ∫φ² dA) for φ = J0(μ r/R), in closed form."""
    R, A = rod.radius_m, rod.area_m2
    i1 = 2 * math.pi * R * R * j1(mu) / mu                       # ∫ J0(μr/R) 2πr dr
    i2 = math.pi * R * R * (j0(mu) ** 2 + j1(mu) ** 2)            # ∫ J0² 2πr dr
    return i1 * i1 / (A * i2)


def corrected_coefficients(rod: Rod, dtau_s: float, q_W_m2: float) -> tuple[float, float]:
    """C1, C2 [-, m] of the AR(1) derived from the slowest radial mode of the 3D rod.

    The growth response to a unit step of flux is Σ_m w_m (1 − e^{−a μ_m² t/R²}),
    exactly, for the rod with uniform lateral h (see :mod:`arfem.models.analytic`).
    Keeping m = 1:

        C1 = exp(−a μ1² Δτ / R²)
        C2 = w_1 (1 − C1),   w_1 = α q (∫φ1 dA)² / (A ρc ∫φ1² dA · a μ1²/R²)

    As Bi → 0, μ1² → 2 Bi and both reduce to paper eqs. 13-14; the relative
    differences are O(Bi) (μ1² = 2Bi(1 − Bi/4 + …)).

    Parameters
    ----------
    rod : Rod
        Supplies a [m²/s], R [m], ρc [J/(m³·K)], α [1/K] and Bi = hR/λ [-].
    dtau_s : float
        AR time step Δτ [s].
    q_W_m2 : float
        Heat flux into the heated end [W/m²].

    Returns
    -------
    (float, float)
        C1 [-] and C2 [m].

    Examples
    --------
    >>> c1, c2 = corrected_coefficients(Rod(), 30.0, 2000.0)
    >>> round(c1, 5), round(c2 * 1e6, 4)
    (0.99115, 0.1985)
    """
    d = _dtau(dtau_s)
    q = _flux(q_W_m2)
    mu = radial_eigenvalue(rod.biot)
    rate = rod.diffusivity_m2_s * mu * mu / rod.radius_m ** 2
    rhoc = rod.density_kg_m3 * rod.specific_heat_J_kgK
    w1 = rod.expansion_1_K * q * _mode_weight(rod, mu) / (rhoc * rate)
    c1 = math.exp(-rate * d)
    return c1, float(w1 * (1.0 - c1))


def ar1_simulate(c1, c2, g0: float = 0.0) -> np.ndarray:
    """Run ΔL_n = C1_n ΔL_{n−1} + C2_n for n = 1..N (paper eq. 12).

    Parameters
    ----------
    c1 : float or array_like
        C1 per step [-] (scalar: the same every step).
    c2 : array_like
        C2 per step, in the unit of the output (m or µm).
    g0 : float
        ΔL_0, in the unit of the output.

    Returns
    -------
    ndarray
        ΔL_0 … ΔL_N (length N + 1).

    Examples
    --------
    >>> ar1_simulate(0.5, [1.0, 1.0, 0.0]).tolist()
    [0.0, 1.0, 1.5, 0.75]
    >>> ar1_simulate(0.5, [1.0, float("nan")])
    Traceback (most recent call last):
    ...
    arfem.params.InputError: c2: must be finite
    """
    try:
        c2 = np.asarray(c2, float)
        c1 = np.asarray(c1, float)
        g0 = float(g0)
    except (TypeError, ValueError):
        raise InputError("c1, c2 and g0 must be numbers", "c2") from None
    if c2.ndim != 1:
        c2 = np.atleast_1d(c2)
        if c2.ndim != 1:
            raise InputError(f"must be 1D, got shape {c2.shape}", "c2")
    try:
        c1 = np.broadcast_to(c1, c2.shape)
    except ValueError:
        raise InputError(f"has shape {c1.shape}, needs a scalar or {c2.shape}", "c1") from None
    for name, v in (("c1", c1), ("c2", c2), ("g0", np.asarray(g0))):
        if not np.all(np.isfinite(v)):
            raise InputError("must be finite", name)
    out = np.empty(c2.size + 1)
    out[0] = g0
    if c2.size == 0:
        return out
    if np.all(c1 == c1.flat[0]):
        from scipy.signal import lfilter
        a = float(c1.flat[0])
        y, _ = lfilter([1.0], [1.0, -a], c2, zi=[a * g0])
        out[1:] = y
    else:
        g = g0
        for n in range(c2.size):
            g = c1[n] * g + c2[n]
            out[n + 1] = g
    return out


def ar1_on_schedule(rod: Rod, schedule: Schedule, dtau_s: float, corrected: bool = False):
    """AR(1) growth on a schedule sampled every ``dtau_s`` (paper eqs. 12-14).

    Parameters
    ----------
    rod : Rod
    schedule : Schedule
        Flux q [W/m²] per segment; every segment must be a multiple of Δτ
        (:meth:`Schedule.subdivided` says what to do if not). Ambient and h
        variations are ignored (the paper's AR has no such inputs); h is the
        rod's nominal value.
    dtau_s : float
        AR step Δτ [s].
    corrected : bool
        Use :func:`corrected_coefficients` (3D slowest radial mode) instead of
        the paper's eqs. 13-14.

    Returns
    -------
    (ndarray, ndarray)
        ``(times_s, growth_m)``: times 0, Δτ, 2Δτ, … [s] and ΔL there [m].

    Examples
    --------
    >>> from arfem.params import paper_cycle
    >>> t, g = ar1_on_schedule(Rod(), paper_cycle(2000.0), 30.0)
    >>> t.size, round(float(t[-1]) / 3600, 1), round(float(g.max()) * 1e6, 3)
    (2881, 24.0, 21.598)
    """
    fine = schedule.subdivided(dtau_s)
    if corrected:
        c1, c2_unit = corrected_coefficients(rod, dtau_s, 1.0)
    else:
        c1, c2_unit = c1_paper(rod, dtau_s), c2_paper(rod, dtau_s, 1.0)
    g = ar1_simulate(c1, c2_unit * np.asarray(fine.q_W_m2))      # C2 is linear in q
    return fine.edges_s, g


@dataclass(frozen=True)
class AR1Fit:
    """Least-squares AR(1) fit (paper eq. 17): C1 shared, one C2 per input level.

    Attributes
    ----------
    c1 : float
        Fitted C1 [-].
    c2 : dict
        ``{level: C2}``, C2 in the unit of the fitted series.
    residual_rms : float
        RMS of the one-step-ahead residuals, in the unit of the series.
    """

    c1: float
    c2: dict            # {level: C2 in the unit of the fitted series}
    residual_rms: float


def eq17_least_squares(previous, following, level, level_values) -> AR1Fit:
    """The least squares of paper eq. 17 on given one-step pairs, with no check: the one
    implementation behind :func:`fit_ar1` (the model ``arfem compensate`` runs) and
    :func:`arfem.models.diagnosis.speed.paper_ar` (the baseline of ``arfem diagnose``).

    Parameters
    ----------
    previous, following : array_like
        ΔL_{n−1} and ΔL_n of each pair (any unit; C2 comes back in it).
    level : array_like
        The input level on step n of each pair.
    level_values : array_like
        The levels that get a C2, in this order (a level with no pair gets 0, the
        least-norm solution).

    Returns
    -------
    AR1Fit
        C1 unclipped; ``residual_rms`` of the one-step residuals.

    Examples
    --------
    >>> g = ar1_simulate(0.9, [1.0] * 20 + [0.0] * 20)
    >>> f = eq17_least_squares(g[:-1], g[1:], [1.0] * 20 + [0.0] * 20, [0.0, 1.0])
    >>> round(f.c1, 6), round(f.c2[1.0], 6)
    (0.9, 1.0)
    """
    prev = np.asarray(previous, float)
    lv = np.asarray(level, float)
    X = np.column_stack([prev] + [(lv == u).astype(float) for u in level_values])
    y = np.asarray(following, float)
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    res = y - X @ coef
    return AR1Fit(float(coef[0]), {float(u): float(c) for u, c in zip(level_values, coef[1:])},
                  float(np.sqrt(np.mean(res ** 2))) if res.size else 0.0)


def fit_ar1(growth, levels) -> AR1Fit:
    """Fit ΔL_n = C1 ΔL_{n−1} + C2(level_n) by linear least squares (paper eq. 17).

    Parameters
    ----------
    growth : array_like
        ΔL_0 … ΔL_N, equally spaced in time (any unit; C2 comes back in it).
    levels : array_like
        Input level on each of the N steps (e.g. q_n [W/m²]); one C2 is fitted
        per distinct level.

    Returns
    -------
    AR1Fit

    Notes
    -----
    Ordinary least squares on the one-step regression. With white innovations
    (noise entering the recursion) the estimates are consistent, with the usual
    OLS standard errors σ √diag((XᵀX)⁻¹). White *measurement* noise on ΔL
    instead biases C1 toward zero (errors in the regressor); filter first.
    A design that cannot identify the coefficients (too few samples, or a
    series that never changes within a level) is refused.

    Examples
    --------
    >>> g = ar1_simulate(0.9, [1.0] * 20 + [0.0] * 20)
    >>> f = fit_ar1(g, [1.0] * 20 + [0.0] * 20)
    >>> round(f.c1, 6), round(f.c2[1.0], 6), round(abs(f.c2[0.0]), 6)
    (0.9, 1.0, 0.0)
    >>> fit_ar1([0.0, 1.0, 2.0], [1.0])
    Traceback (most recent call last):
    ...
    arfem.params.InputError: levels: needs 2 levels for 3 growth values
    """
    try:
        g = np.asarray(growth, float)
        lv = np.asarray(levels, float)
    except (TypeError, ValueError):
        raise InputError("growth and levels must be numbers", "growth") from None
    if g.ndim != 1:
        raise InputError(f"must be 1D, got shape {g.shape}", "growth")
    if lv.shape != (g.size - 1,):
        raise InputError(f"needs {g.size - 1} levels for {g.size} growth values", "levels")
    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(lv))):
        raise InputError("growth and levels must be finite", "growth")
    uniq = np.unique(lv)
    X = np.column_stack([g[:-1]] + [(lv == u).astype(float) for u in uniq])
    if X.shape[0] < X.shape[1] or np.linalg.matrix_rank(X) < X.shape[1]:
        raise InputError(f"cannot identify C1 and {uniq.size} C2 values from {g.size} samples "
                         "(too few, or the series never changes within a level)", "growth")
    return eq17_least_squares(g[:-1], g[1:], lv, uniq)
