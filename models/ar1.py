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
from scipy.special import j0, j1

from models.params import InputError, Rod, Schedule

__all__ = ["c1_paper", "c2_paper", "steady_growth_m", "radial_eigenvalue",
           "corrected_coefficients", "ar1_simulate", "ar1_on_schedule", "fit_ar1", "AR1Fit"]


def _dtau(dtau_s) -> float:
    d = float(dtau_s)
    if not (math.isfinite(d) and d > 0):
        raise InputError(f"must be > 0, got {dtau_s!r}", "dtau_s")
    return d


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

    Examples
    --------
    >>> round(steady_growth_m(Rod(), 2000.0) * 1e6, 3)
    21.818
    """
    return q_W_m2 * rod.expansion_1_K * rod.diffusivity_m2_s / (
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

    Examples
    --------
    >>> mu = radial_eigenvalue(0.11)
    >>> round(mu, 5), round(mu**2 / (2 * 0.11), 4)   # μ² → 2 Bi as Bi → 0
    (0.46267, 0.973)
    """
    if not (biot > 0 and math.isfinite(biot)):
        raise InputError(f"must be > 0, got {biot!r}", "biot")
    f = lambda x: x * j1(x) - biot * j0(x)
    # roots interlace the zeros of J0 and J1: bracket the m-th one by scanning
    grid = np.linspace(1e-9, 3.2 * m + 3.0, 4000 * m)
    vals = f(grid)
    roots = [brentq(f, grid[i], grid[i + 1]) for i in range(grid.size - 1)
             if vals[i] == 0 or vals[i] * vals[i + 1] < 0]
    # discard the sign changes at poles (none for this smooth f) and keep the m-th
    return float(roots[m - 1])


def _mode_weight(rod: Rod, mu: float) -> float:
    """(∫φ dA)² / (A ∫φ² dA) for φ = J0(μ r/R), in closed form."""
    R, A = rod.radius_m, rod.area_m2
    i1 = 2 * math.pi * R * R * j1(mu) / mu                       # ∫ J0(μr/R) 2πr dr
    i2 = math.pi * R * R * (j0(mu) ** 2 + j1(mu) ** 2)            # ∫ J0² 2πr dr
    return i1 * i1 / (A * i2)


def corrected_coefficients(rod: Rod, dtau_s: float, q_W_m2: float) -> tuple[float, float]:
    """C1, C2 [-, m] of the AR(1) derived from the slowest radial mode of the 3D rod.

    The growth response to a unit step of flux is Σ_m w_m (1 − e^{−a μ_m² t/R²}),
    exactly, for the rod with uniform lateral h. Keeping m = 1:

        C1 = exp(−a μ1² Δτ / R²)
        C2 = w_1 (1 − C1),   w_1 = α q (∫φ1 dA)² / (A ρc ∫φ1² dA · a μ1²/R²)

    As Bi → 0, μ1² → 2 Bi and both reduce to paper eqs. 13-14.

    Examples
    --------
    >>> c1, c2 = corrected_coefficients(Rod(), 30.0, 2000.0)
    >>> round(c1, 5), round(c2 * 1e6, 4)
    (0.99115, 0.1985)
    """
    d = _dtau(dtau_s)
    mu = radial_eigenvalue(rod.biot)
    rate = rod.diffusivity_m2_s * mu * mu / rod.radius_m ** 2
    rhoc = rod.density_kg_m3 * rod.specific_heat_J_kgK
    w1 = rod.expansion_1_K * q_W_m2 * _mode_weight(rod, mu) / (rhoc * rate)
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
        ΔL_0.

    Returns
    -------
    ndarray
        ΔL_0 … ΔL_N (length N + 1).

    Examples
    --------
    >>> ar1_simulate(0.5, [1.0, 1.0, 0.0]).tolist()
    [0.0, 1.0, 1.5, 0.75]
    """
    c2 = np.asarray(c2, float)
    c1 = np.broadcast_to(np.asarray(c1, float), c2.shape)
    out = np.empty(c2.size + 1)
    out[0] = g0
    from scipy.signal import lfilter
    if np.all(c1 == c1.flat[0]) if c1.size else True:
        a = float(c1.flat[0]) if c1.size else 0.0
        y, _ = lfilter([1.0], [1.0, -a], c2, zi=[a * g0])
        out[1:] = y
    else:
        g = g0
        for n in range(c2.size):
            g = c1[n] * g + c2[n]
            out[n + 1] = g
    return out


def ar1_on_schedule(rod: Rod, schedule: Schedule, dtau_s: float, corrected: bool = False):
    """AR(1) growth on a schedule sampled every ``dtau_s``.

    Returns ``(times_s, growth_m)`` with times 0, Δτ, 2Δτ, … . Every segment
    must be a multiple of Δτ (:meth:`Schedule.subdivided` says what to do if not).
    Ambient and h variations in the schedule are ignored here (the paper's AR has
    no such inputs); h is the rod's nominal value.
    """
    fine = schedule.subdivided(dtau_s)
    coef = corrected_coefficients if corrected else (
        lambda r, d, q: (c1_paper(r, d), c2_paper(r, d, q)))
    c1 = coef(rod, dtau_s, 1.0)[0]
    c2_unit = coef(rod, dtau_s, 1.0)[1]      # C2 is linear in q
    g = ar1_simulate(c1, c2_unit * np.asarray(fine.q_W_m2))
    return fine.edges_s, g


@dataclass(frozen=True)
class AR1Fit:
    """Least-squares AR(1) fit (paper eq. 17): C1 shared, one C2 per input level."""

    c1: float
    c2: dict            # {level: C2 in the unit of the fitted series}
    residual_rms: float


def fit_ar1(growth, levels) -> AR1Fit:
    """Fit ΔL_n = C1 ΔL_{n−1} + C2(level_n) by linear least squares (paper eq. 17).

    Parameters
    ----------
    growth : array_like
        ΔL_0 … ΔL_N, equally spaced in time.
    levels : array_like
        Input level on each of the N steps (e.g. q_n); one C2 is fitted per
        distinct level.

    Examples
    --------
    >>> g = ar1_simulate(0.9, [1.0] * 20 + [0.0] * 20)
    >>> f = fit_ar1(g, [1.0] * 20 + [0.0] * 20)
    >>> round(f.c1, 6), round(f.c2[1.0], 6), round(abs(f.c2[0.0]), 6)
    (0.9, 1.0, 0.0)
    """
    g = np.asarray(growth, float)
    lv = np.asarray(levels, float)
    if g.ndim != 1 or lv.shape != (g.size - 1,):
        raise InputError(f"needs {g.size - 1} levels for {g.size} growth values", "levels")
    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(lv))):
        raise InputError("growth and levels must be finite", "growth")
    uniq = np.unique(lv)
    X = np.column_stack([g[:-1]] + [(lv == u).astype(float) for u in uniq])
    coef, *_ = np.linalg.lstsq(X, g[1:], rcond=None)
    res = g[1:] - X @ coef
    return AR1Fit(float(coef[0]), {float(u): float(c) for u, c in zip(uniq, coef[1:])},
                  float(np.sqrt(np.mean(res ** 2))))
