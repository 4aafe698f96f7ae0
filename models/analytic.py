"""Closed-form solutions for the spindle rod: the paper's 1D fin and the exact 3D growth.

1D rod (Du et al. 2021, Sec. 1, eqs. 5-8). With θ = T − T_amb [K] the fin equation

    ∂θ/∂t = a ∂²θ/∂x² − b θ,    0 < x < L,          a = λ/(ρc), b = 2h/(ρcR)
    −λ ∂θ/∂x = q(t)  at x = 0,   ∂θ/∂x = 0 at x = L,  θ(x, 0) = 0

is solved by a cosine series (paper eqs. 5-7). For a step of flux q at t = 0

    θ(x, t) = (q a / (λ L)) Σ_{n≥0} ε_n cos(k_n x) (1 − e^{−s_n t}) / s_n,
    k_n = nπ/L,  s_n = a k_n² + b,  ε_0 = 1, ε_n = 2 (n ≥ 1),

and a piecewise-constant q(t) is the superposition of such steps. Only the n = 0
term survives the axial integral, so the growth of paper eq. 8, ΔL = α∫θ dx,
obeys dΔL/dt = α q a / λ − b ΔL exactly: the AR(1) of paper eq. 12 is exact for
the 1D rod at any Δτ.

3D rod (this package's extension). For the cylinder with uniform lateral h, a
uniform end flux and an adiabatic far end, the temperature separates into
J0(μ_m r/R) cos(k_n z). The growth α∫θ dV / A again sees only the axially
uniform modes (n = 0), whose radial eigenvalues solve μ J1(μ) = Bi J0(μ),
Bi = hR/λ. The growth step response is

    ΔL(t) = Σ_{m≥1} α q w_m R² / (λ μ_m²) · (1 − e^{−a μ_m² t / R²}),
    w_m = (∫φ_m dA)² / (A ∫φ_m² dA) = 4 Bi² / (μ_m² (μ_m² + Bi²)),  Σ_m w_m = 1,

of which :func:`arfem.models.ar1.corrected_coefficients` keeps m = 1. The modes
m ≥ 2 carry 1 − w_1 ≈ Bi²/48 of the weight (see :func:`radial_mode_weights`)
and, being fast, only ~3e-6 of the steady growth at the paper's Bi = 0.11. The
steady 3D growth is exactly (1 + Bi/4) times the 1D one
(:func:`steady_growth_3d_m`), and the slowest rate is b (1 − Bi/4 + O(Bi²)):
both O(Bi) departures from the paper's eqs. 13-14, which is the paper AR's
2.6 % miss against the FEM on the paper cycle.

All functions are small and pure; units are SI and stated in brackets.

References
----------
.. [1] Du L., et al., "First-order autoregressive modeling method for axial
   thermal error of machine tool spindle", J. Harbin Inst. Technol. 53(7), 2021.
.. [2] Carslaw H. S., Jaeger J. C., "Conduction of Heat in Solids", 2nd ed.,
   Oxford, 1959, Sec. 7.8 (cylinder with surface heat transfer).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq
from scipy.special import j0, j1, jn_zeros

from arfem.models.ar1 import steady_growth_m
from arfem.params import InputError, Rod, Schedule

__all__ = ["fin_parameter_1_m", "steady_profile_1d", "series_rates_1d", "temperature_1d",
           "growth_1d_step", "growth_1d", "radial_eigenvalues", "radial_mode_weights",
           "steady_growth_3d_m", "growth_3d_modes", "growth_3d_step", "growth_3d"]


# --------------------------------------------------------------------------- helpers
def _count(name: str, n, minimum: int = 1) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < minimum:
        raise InputError(f"must be an integer >= {minimum}, got {n!r}", name)
    return int(n)


def _finite_array(name: str, values, ndim_max: int = 1) -> np.ndarray:
    try:
        a = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"must be numbers, got {values!r}", name) from None
    if a.ndim > ndim_max:
        raise InputError(f"must be a scalar or 1D array, got shape {a.shape}", name)
    if not np.all(np.isfinite(a)):
        raise InputError("must be finite", name)
    return a


def _times(schedule: Schedule | None, t_s) -> np.ndarray:
    t = _finite_array("t_s", t_s)
    if np.any(t < 0):
        raise InputError(f"must be >= 0, got {t.min()!r}", "t_s")
    if schedule is not None and t.size and t.max() > schedule.total_s * (1 + 1e-12):
        raise InputError(f"must lie within [0, {schedule.total_s:g}] s (the schedule's end), "
                         f"got {t.max()!r}", "t_s")
    return t


def _unit_gain_response(rates_1_s: np.ndarray, schedule: Schedule, t_s: np.ndarray):
    """Exact y(t) of y' = s (q(t) − y), y(0) = 0, for each rate s, at times ``t_s``.

    Returns ``(Y, q_left)``: Y [W/m²] of shape (t.size, rates.size) and the flux in
    force just before each output time (0 at t = 0). Each interval between
    breakpoints is advanced by its exponential, so there is no time-step error;
    this is the superposition of the schedule's flux steps evaluated recursively.
    """
    t = np.asarray(t_s, float).ravel()
    edges = schedule.edges_s
    q = np.asarray(schedule.q_W_m2, float)
    bps = np.union1d(edges, np.clip(t, 0.0, edges[-1]))
    seg = np.clip(np.searchsorted(edges, bps[1:], side="left") - 1, 0, schedule.n_segments - 1)
    d = np.diff(bps)
    Y = np.zeros((bps.size, rates_1_s.size))
    y = np.zeros(rates_1_s.size)
    for i in range(d.size):
        qi = q[seg[i]]
        y = qi + np.exp(-rates_1_s * d[i]) * (y - qi)
        Y[i + 1] = y
    q_left = np.concatenate([[0.0], q[seg]])
    pick = np.searchsorted(bps, np.clip(t, 0.0, edges[-1]))
    return Y[pick], q_left[pick]


# --------------------------------------------------------------------------- 1D rod
def fin_parameter_1_m(rod: Rod) -> float:
    """Fin parameter m = √(b/a) = √(2h/(λR)) [1/m] of the 1D rod.

    Parameters
    ----------
    rod : Rod
        Supplies a = λ/(ρc) [m²/s] and b = 2h/(ρcR) [1/s].

    Returns
    -------
    float
        m [1/m]; 1/m is the decay length of the steady profile.

    References
    ----------
    Du et al. (2021), eq. 4 (the fin equation θ_t = a θ_xx − b θ).

    Examples
    --------
    >>> round(fin_parameter_1_m(Rod()), 4)
    4.6904
    """
    return math.sqrt(rod.fin_rate_1_s / rod.diffusivity_m2_s)


def steady_profile_1d(rod: Rod, q_W_m2: float, x_m) -> np.ndarray:
    """Steady temperature rise of the 1D rod, θ_s(x) = q cosh(m(L−x)) / (λ m sinh(mL)) [K].

    Parameters
    ----------
    rod : Rod
        Geometry and material (L [m], λ [W/(m·K)], h [W/(m²·K)], R [m]).
    q_W_m2 : float
        Constant heat flux into the end x = 0 [W/m²].
    x_m : array_like
        Positions along the rod [m], within [0, L].

    Returns
    -------
    ndarray
        θ_s [K] at ``x_m`` (same shape).

    Notes
    -----
    The t → ∞ limit of paper eqs. 5-7; it satisfies the energy balance
    q A = h (2πR) ∫θ_s dx, i.e. ∫θ_s dx = q a / (λ b).

    References
    ----------
    Du et al. (2021), eqs. 5-7.

    Examples
    --------
    >>> th = steady_profile_1d(Rod(), 2000.0, [0.0, 0.8])
    >>> np.round(th, 4).tolist()
    [8.5374, 0.4004]
    """
    q = float(_finite_array("q_W_m2", q_W_m2, ndim_max=0))
    x = _x_grid(rod, x_m)
    m, L = fin_parameter_1_m(rod), rod.length_m
    # cosh(m(L−x))/sinh(mL) written without overflow for large mL
    ratio = (np.exp(-m * x) + np.exp(-m * (2 * L - x))) / (1.0 - np.exp(-2 * m * L))
    return q / (rod.conductivity_W_mK * m) * ratio


def _x_grid(rod: Rod, x_m) -> np.ndarray:
    x = _finite_array("x_m", x_m)
    tol = 1e-12 * rod.length_m
    if x.size and (x.min() < -tol or x.max() > rod.length_m + tol):
        raise InputError(f"must lie within [0, {rod.length_m:g}] m", "x_m")
    return np.clip(x, 0.0, rod.length_m)


def series_rates_1d(rod: Rod, n_terms: int) -> np.ndarray:
    """Decay rates s_n = a (nπ/L)² + b [1/s] of the cosine modes n = 0 … n_terms−1.

    Parameters
    ----------
    rod : Rod
    n_terms : int
        Number of cosine terms (>= 1).

    Returns
    -------
    ndarray
        s_n [1/s]; s_0 = b is the rate of the AR(1), paper eq. 13.

    References
    ----------
    Du et al. (2021), eqs. 5-7.

    Examples
    --------
    >>> s = series_rates_1d(Rod(), 2)
    >>> bool(np.isclose(s[0], Rod().fin_rate_1_s)), float(np.round(s[1] / s[0], 3))
    (True, 1.701)
    """
    n = np.arange(_count("n_terms", n_terms))
    k = n * math.pi / rod.length_m
    return rod.diffusivity_m2_s * k * k + rod.fin_rate_1_s


def temperature_1d(rod: Rod, schedule: Schedule, x_m, t_s, n_terms: int = 200) -> np.ndarray:
    """Temperature rise θ(x, t) [K] of the 1D rod under a piecewise-constant flux.

    Parameters
    ----------
    rod : Rod
        Geometry and material; h is the rod's nominal value (the schedule's h
        and ambient columns are ignored, as in the paper).
    schedule : Schedule
        Heat flux q(t) into the end x = 0 [W/m²], constant on each segment.
    x_m : array_like
        Positions [m], within [0, L].
    t_s : array_like
        Times [s], within [0, schedule.total_s], any order.
    n_terms : int
        Cosine terms kept (n = 0 … n_terms − 1).

    Returns
    -------
    ndarray
        θ [K] of shape (len(t_s), len(x_m)).

    Notes
    -----
    Implements the series of paper eqs. 5-7, superposed over the flux steps:
    θ = Σ_n c_n cos(k_n x) y_n(t) with c_n = ε_n a / (λ L s_n) and y_n' = s_n (q − y_n).
    The steady part of the series is summed in closed form
    (:func:`steady_profile_1d`), i.e. θ = q⁻ θ_s/q − Σ_n c_n cos(k_n x)(q⁻ − y_n)
    with q⁻ the flux just before t; this is the same infinite series, but the
    truncation error then decays with e^{−s_n (t − t_jump)} and not as 1/n.
    The axial integral ∫θ dx is exact for any ``n_terms`` (only n = 0 contributes).

    References
    ----------
    Du et al. (2021), eqs. 5-7; Carslaw & Jaeger (1959), Sec. 4.3.

    Examples
    --------
    >>> rod = Rod()
    >>> th = temperature_1d(rod, Schedule([1e6], [2000.0]), [0.0, 0.4], [0.0, 1e6])
    >>> np.round(th, 4).tolist()
    [[0.0, 0.0], [8.5374, 1.3377]]
    """
    x = _x_grid(rod, x_m).ravel()
    t = _times(schedule, t_s).ravel()
    s = series_rates_1d(rod, n_terms)
    n = np.arange(s.size)
    eps = np.where(n == 0, 1.0, 2.0)
    c = eps * rod.diffusivity_m2_s / (rod.conductivity_W_mK * rod.length_m * s)   # [K/(W/m²)]
    Y, q_left = _unit_gain_response(s, schedule, t)
    cosx = np.cos(np.outer(n * math.pi / rod.length_m, x))                     # (n, x)
    steady_unit = steady_profile_1d(rod, 1.0, x)                                 # [K/(W/m²)]
    return np.outer(q_left, steady_unit) - ((q_left[:, None] - Y) * c) @ cosx


def growth_1d_step(rod: Rod, q_W_m2: float, t_s) -> np.ndarray:
    """Growth of the 1D rod after a flux step at t = 0, ΔL = α∫θ dx [m], paper eq. 8.

    Parameters
    ----------
    rod : Rod
    q_W_m2 : float
        Flux switched on at t = 0 [W/m²].
    t_s : array_like
        Times since the step [s], >= 0.

    Returns
    -------
    ndarray
        ΔL(t) = (α q a / (λ b)) (1 − e^{−bt}) [m].

    References
    ----------
    Du et al. (2021), eq. 8.

    Examples
    --------
    >>> np.round(growth_1d_step(Rod(), 2000.0, [0.0, 30.0, 1e6]) * 1e6, 4).tolist()
    [0.0, 0.1985, 21.8182]
    """
    q = float(_finite_array("q_W_m2", q_W_m2, ndim_max=0))
    t = _times(None, t_s)
    return steady_growth_m(rod, q) * -np.expm1(-rod.fin_rate_1_s * t)


def growth_1d(rod: Rod, schedule: Schedule, t_s) -> np.ndarray:
    """Exact growth ΔL(t) = α∫θ dx [m] of the 1D rod on a piecewise-constant schedule.

    Parameters
    ----------
    rod : Rod
        h is the rod's nominal value (schedule h/ambient are ignored, as in the paper).
    schedule : Schedule
        Flux q(t) [W/m²].
    t_s : array_like
        Times [s] within [0, schedule.total_s].

    Returns
    -------
    ndarray
        ΔL [m], the solution of dΔL/dt = α q(t) a / λ − b ΔL, ΔL(0) = 0.

    Notes
    -----
    Paper eq. 8 superposed over the flux steps. Sampled every Δτ on a schedule
    whose segments are multiples of Δτ it equals the AR(1) of paper eqs. 12-14
    (:func:`arfem.models.ar1.ar1_on_schedule`) to rounding.

    References
    ----------
    Du et al. (2021), eqs. 8 and 12.

    Examples
    --------
    >>> from arfem.params import paper_cycle
    >>> g = growth_1d(Rod(), paper_cycle(2000.0), [4 * 3600.0, 9.5 * 3600.0])
    >>> np.round(g * 1e6, 3).tolist()
    [21.547, 21.598]
    """
    t = _times(schedule, t_s)
    Y, _ = _unit_gain_response(np.array([rod.fin_rate_1_s]), schedule, t.ravel())
    return (steady_growth_m(rod, 1.0) * Y[:, 0]).reshape(t.shape)


# --------------------------------------------------------------------------- 3D rod
def radial_eigenvalues(biot: float, n_modes: int) -> np.ndarray:
    """First ``n_modes`` roots μ_m of μ J1(μ) = Bi J0(μ) [-], increasing.

    Parameters
    ----------
    biot : float
        Biot number Bi = hR/λ [-], > 0.
    n_modes : int
        How many roots (>= 1).

    Returns
    -------
    ndarray
        μ_1 < μ_2 < … [-]. The m-th root lies between the (m−1)-th zero of J1
        (0 for m = 1) and the m-th zero of J0, where the function changes sign;
        each is found by Brent's method in that bracket.

    References
    ----------
    Carslaw & Jaeger (1959), Sec. 7.8, eq. (2) (radial modes with surface transfer).

    Examples
    --------
    >>> np.round(radial_eigenvalues(0.11, 3), 5).tolist()
    [0.46267, 3.8603, 7.03125]
    """
    try:
        bi = float(biot)
    except (TypeError, ValueError):
        raise InputError(f"must be a number, got {biot!r}", "biot") from None
    if not (math.isfinite(bi) and bi > 0):
        raise InputError(f"must be > 0, got {biot!r}", "biot")
    n = _count("n_modes", n_modes)
    lo = np.concatenate([[0.0], jn_zeros(1, n - 1)]) if n > 1 else np.array([0.0])
    hi = jn_zeros(0, n)
    f = lambda x: x * j1(x) - bi * j0(x)
    return np.array([brentq(f, a, b, xtol=1e-15, rtol=4 * np.finfo(float).eps)
                     for a, b in zip(lo, hi)])


def radial_mode_weights(biot: float, n_modes: int) -> np.ndarray:
    """Growth weights w_m = 4 Bi² / (μ_m² (μ_m² + Bi²)) [-] of the radial modes.

    Parameters
    ----------
    biot : float
        Bi = hR/λ [-].
    n_modes : int
        How many modes.

    Returns
    -------
    ndarray
        w_m = (∫φ_m dA)² / (A ∫φ_m² dA) for φ_m = J0(μ_m r/R); Σ_{m≥1} w_m = 1
        (Parseval for the constant function), and w_1 = 1 − O(Bi²).

    References
    ----------
    Carslaw & Jaeger (1959), Sec. 7.8.

    Examples
    --------
    >>> w = radial_mode_weights(0.11, 40)
    >>> round(float(w[0]), 6), round(float(w.sum()), 6)
    (0.999755, 1.0)
    """
    mu = radial_eigenvalues(biot, n_modes)
    bi = float(biot)
    return 4.0 * bi * bi / (mu * mu * (mu * mu + bi * bi))


def steady_growth_3d_m(rod: Rod, q_W_m2: float) -> float:
    """Exact steady growth of the 3D rod, (1 + Bi/4) q α R / (2h) [m].

    Parameters
    ----------
    rod : Rod
        Cylinder with uniform lateral h, flux on z = 0, adiabatic z = L.
    q_W_m2 : float
        Constant end flux [W/m²].

    Returns
    -------
    float
        α ∫θ dV / A at t → ∞ [m].

    Notes
    -----
    Integrating the steady heat equation over z leaves λ ∇²_r Θ + q = 0 for
    Θ(r) = ∫θ dz, with −λΘ'(R) = hΘ(R); so Θ = qR/(2h) + q(R² − r²)/(4λ), whose
    area mean is (qR/(2h))(1 + Bi/4). The 1D value of paper eq. 8 is the Bi → 0
    limit (:func:`arfem.models.ar1.steady_growth_m`); the sum of the modal gains of
    :func:`growth_3d_modes` converges to this.

    Examples
    --------
    >>> round(steady_growth_3d_m(Rod(), 2000.0) * 1e6, 4)
    22.4182
    """
    q = float(_finite_array("q_W_m2", q_W_m2, ndim_max=0))
    return (1.0 + rod.biot / 4.0) * steady_growth_m(rod, q)


def growth_3d_modes(rod: Rod, n_modes: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Rates [1/s] and steady gains [m/(W/m²)] of the axially uniform radial modes.

    Parameters
    ----------
    rod : Rod
        Cylinder with uniform lateral h, flux on z = 0, adiabatic z = L.
    n_modes : int
        Radial modes kept (m = 1 … n_modes).

    Returns
    -------
    rates_1_s : ndarray
        a μ_m² / R² [1/s].
    gains_m_per_W_m2 : ndarray
        α w_m R² / (λ μ_m²) [m per W/m²]: the steady growth each mode carries per
        unit flux. As Bi → 0, rates[0] → b and gains[0] → α a / (λ b), the paper's
        values (eqs. 13-14).

    Examples
    --------
    >>> s, g = growth_3d_modes(Rod(), 3)
    >>> np.round(s / Rod().fin_rate_1_s, 4).tolist()[:2], round(float(g[1:].sum() / g.sum()), 8)
    ([0.973, 67.736], 3.21e-06)
    """
    mu = radial_eigenvalues(rod.biot, n_modes)
    w = radial_mode_weights(rod.biot, n_modes)
    R, a = rod.radius_m, rod.diffusivity_m2_s
    rates = a * mu * mu / (R * R)
    gains = rod.expansion_1_K * w * R * R / (rod.conductivity_W_mK * mu * mu)
    return rates, gains


def growth_3d_step(rod: Rod, q_W_m2: float, t_s, n_modes: int = 40,
                   per_mode: bool = False) -> np.ndarray:
    """Exact growth α∫θ dV / A [m] of the 3D rod after a flux step, by radial modes.

    Parameters
    ----------
    rod : Rod
    q_W_m2 : float
        Flux switched on at t = 0 [W/m²], uniform on the end face z = 0.
    t_s : array_like
        Times since the step [s], >= 0.
    n_modes : int
        Radial modes summed. ``n_modes=1`` is the response of the corrected
        AR(1) (:func:`arfem.models.ar1.corrected_coefficients`).
    per_mode : bool
        Return the contribution of every mode, shape (len(t_s), n_modes).

    Returns
    -------
    ndarray
        ΔL(t) = Σ_m q gains_m (1 − e^{−rates_m t}) [m].

    Notes
    -----
    The 3D counterpart of paper eq. 8; see the module docstring.

    Examples
    --------
    >>> g1, g40 = (growth_3d_step(Rod(), 2000.0, [30.0, 1e6], n_modes=n) for n in (1, 40))
    >>> np.round(g40 * 1e6, 4).tolist(), float(np.round((g40 - g1)[1] * 1e6, 6))
    ([0.1985, 22.4182], 7.2e-05)
    """
    q = float(_finite_array("q_W_m2", q_W_m2, ndim_max=0))
    t = _times(None, t_s)
    rates, gains = growth_3d_modes(rod, n_modes)
    parts = q * gains * -np.expm1(-np.outer(t.ravel(), rates))
    if per_mode:
        return parts
    return parts.sum(axis=1).reshape(t.shape)


def growth_3d(rod: Rod, schedule: Schedule, t_s, n_modes: int = 40) -> np.ndarray:
    """Exact growth α∫θ dV / A [m] of the 3D rod on a piecewise-constant flux schedule.

    Parameters
    ----------
    rod : Rod
        h is the rod's nominal value (schedule h/ambient are ignored).
    schedule : Schedule
        Flux q(t) [W/m²].
    t_s : array_like
        Times [s] within [0, schedule.total_s].
    n_modes : int
        Radial modes summed.

    Returns
    -------
    ndarray
        ΔL [m] at ``t_s``; the reference the axisymmetric FEM converges to.

    Examples
    --------
    >>> from arfem.params import paper_cycle
    >>> g = growth_3d(Rod(), paper_cycle(2000.0), [4 * 3600.0, 9.5 * 3600.0])
    >>> np.round(g * 1e6, 4).tolist()      # 9.5 h: the cycle's peak
    [22.1042, 22.1666]
    """
    t = _times(schedule, t_s)
    rates, gains = growth_3d_modes(rod, n_modes)
    Y, _ = _unit_gain_response(rates, schedule, t.ravel())
    return (Y @ gains).reshape(t.shape)
