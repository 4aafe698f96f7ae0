"""Transient heat conduction in the rod: assembly and two time integrators.

The problem (θ = T − T_ref, T_ref = the rod's nominal ambient):

    ρc ∂θ/∂t − ∇·(λ∇θ) = 0                         in the rod
    λ ∂θ/∂n = q(t)                                  on ``heated`` (flux in)
    λ ∂θ/∂n = −h(t) (θ − θ_amb(t))                  on ``lateral``
    ∂θ/∂n = 0                                       on ``far``

Semi-discretised: M θ' + (K + h B) θ = q f_q + h θ_amb f_b, with every input
piecewise constant in time (a :class:`arfem.params.Schedule`).

Two integrators:

* :func:`solve_theta` -- the θ-method (Crank–Nicolson by default, backward Euler
  with ``theta=1``); each distinct (step, h) system is factored once
  (:func:`arfem.fem.linsolve.factorize_spd`: a symmetric, nested-dissection
  factorisation of the SPD matrix) and reused, as in scikit-fem's ex19.
* :func:`solve_modal` -- exact in time for piecewise-constant inputs: the
  generalised eigenproblem (K + hB) φ = μ M φ is solved once per distinct h and
  each mode is advanced by its exponential. Arbitrary (uneven) output times,
  no time-step error; the tool of choice for sweeps and measured data. On 3D
  models it hands over to the reduced-modal solve of :mod:`arfem.fem.reduced`
  (slowest modes by shift-invert Lanczos, the rest by a static correction).

Axial growth is reported as α∫θ dV / A, which for a free bar held axially at one
end equals the face-averaged axial displacement of the far face (reciprocity;
see :mod:`arfem.fem.elastic`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.linalg

from arfem.fem.heat_problem import (ELEMENTS, HeatFEM, HeatResult, initial_state_K, schedule_inputs,
                                    breakpoints)
from arfem.fem.linsolve import factorize_spd
from arfem.fem.reduced import solve_reduced
from arfem.params import InputError, Rod, Schedule

__all__ = ["HeatFEM", "HeatResult", "solve_theta", "solve_modal", "build_axisymmetric",
           "build_3d", "ELEMENTS"]


def build_axisymmetric(rod: Rod, order: int = 2, nr: int = 4, nz: int = 24,
                       ratio_r: float = 3.0, ratio_z: float = 6.0) -> HeatFEM:
    """Axisymmetric model on :func:`arfem.fem.mesh.axisymmetric_mesh` with Q1 or Q2 elements.

    The default mesh (Q2, nr=4, nz=24) has a paper-cycle peak-growth error below
    1e-4 µm (Richardson over Q1 refinements; ``benchmarks/study_convergence.py``).

    Parameters
    ----------
    rod : Rod
        Geometry [m], material and nominal boundary conditions.
    order : {1, 2}
        Element order: Q1 or Q2 (9-node Lagrange) quadrilaterals.
    nr, nz : int
        Elements across the radius and along the length.
    ratio_r : float
        Largest/smallest radial element; small ones at the lateral surface [-].
    ratio_z : float
        Largest/smallest axial element; small ones at the heated end [-].

    Returns
    -------
    HeatFEM
        Axisymmetric model; integrals are over the whole rod (2πr weight).

    Raises
    ------
    InputError
        If ``order`` is not 1 or 2, or a mesh count is invalid.
    """
    from arfem.fem.mesh import axisymmetric_mesh
    if order not in (1, 2):
        raise InputError(f"must be 1 or 2, got {order!r}", "order")
    mesh = axisymmetric_mesh(rod, nr=nr, nz=nz, ratio_r=ratio_r, ratio_z=ratio_z)
    return HeatFEM.build(mesh, ELEMENTS[("axisymmetric", order)](), rod, axisymmetric=True)


def build_3d(rod: Rod, order: int | str = 2, n_core: int = 3, n_ring: int = 2, nz: int = 16,
             ratio_ring: float = 2.0, ratio_z: float = 6.0) -> HeatFEM:
    """3D model on :func:`arfem.fem.mesh.cylinder_mesh` (order 2 = 20-node serendipity bricks).

    The default mesh (n_core=3: 12 elements around the circumference) has a
    paper-cycle peak-growth error of ~0.002 µm by Richardson extrapolation over
    n_core = 2, 3, 4 (n_core=2: ~0.009 µm); see ``benchmarks/study_convergence.py``.

    Parameters
    ----------
    rod : Rod
        Geometry [m], material and nominal boundary conditions.
    order : {1, 2, "2-lagrange"}
        Element: 8-node, 20-node serendipity or 27-node Lagrange hexahedra.
    n_core : int
        Elements along each side of the square core (``4 * n_core`` around the
        circumference).
    n_ring : int
        Element layers from the core to the circle.
    nz : int
        Elements along the axis.
    ratio_ring, ratio_z : float
        Grading ratios toward the lateral surface and the heated end [-].

    Returns
    -------
    HeatFEM
        3D model, assembled with quadrature order 4.

    Raises
    ------
    InputError
        If ``order`` is not one of the above, or a mesh count is invalid.
    """
    from arfem.fem.mesh import cylinder_mesh
    if ("3d", order) not in ELEMENTS:
        raise InputError(f"must be 1, 2 or '2-lagrange', got {order!r}", "order")
    mesh = cylinder_mesh(rod, n_core=n_core, n_ring=n_ring, nz=nz, ratio_ring=ratio_ring,
                         ratio_z=ratio_z)
    return HeatFEM.build(mesh, ELEMENTS[("3d", order)](), rod, axisymmetric=False,
                         intorder=4)


def solve_theta(model: HeatFEM, schedule: Schedule, dt_s: float, theta: float = 0.5,
                store_fields: bool = False, theta0=None,
                source: Callable[[np.ndarray, int], np.ndarray] | None = None,
                factor_method: str | None = None) -> HeatResult:
    """θ-method time integration; outputs at t = 0 and at every step end.

    Each segment of ``schedule`` is split into ``ceil(duration / dt_s)`` equal
    steps. Each distinct (step, h) matrix M + θΔt(K + hB) is factored once.

    Parameters
    ----------
    model : HeatFEM
    schedule : Schedule
    dt_s : float
        Largest time step [s].
    theta : float
        0.5 = Crank–Nicolson (2nd order), 1 = backward Euler (1st order).
    store_fields : bool
        Keep θ at every output time.
    theta0 : array_like or float, optional
        Initial temperature rise [K]; default 0 (equilibrium with ambient).
    source : callable, optional
        ``source(theta_prev, segment_index) -> extra load [W]`` added explicitly
        on each step (used for nonlinear boundary terms held at the previous state).
    factor_method : {"symmetric", "lu"}, optional
        How M + θΔt(K + hB) is factored (:func:`arfem.fem.linsolve.factorize_spd`);
        default: symmetric where pymetis is installed. Both give the same θ to round-off.
    """
    if not (0.5 <= theta <= 1.0):
        raise InputError(f"must lie in [0.5, 1], got {theta!r}", "theta")
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise InputError(f"must be > 0, got {dt_s!r}", "dt_s")
    q, h, amb = schedule_inputs(model, schedule)
    x = initial_state_K(model, theta0)
    M = model.M
    cache: dict = {}
    times = [0.0]
    out = [x.copy()] if store_fields else None
    growth = [model.growth @ x]
    heat = [model.volume @ x]
    t = 0.0
    for i, dur in enumerate(schedule.durations_s):
        n = max(1, int(np.ceil(dur / dt_s - 1e-9)))
        step = dur / n
        key = (round(step, 9), h[i])
        if key not in cache:
            A = model.operator(h[i])
            lhs = factorize_spd(M + theta * step * A, factor_method)
            rhs = (M - (1.0 - theta) * step * A).tocsr()
            cache[key] = (lhs, rhs)
        lhs, rhs = cache[key]
        f = step * model.load(q[i], h[i], amb[i])
        for _ in range(n):
            b = rhs @ x + f
            if source is not None:
                b += step * source(x, i)
            x = lhs.solve(b)
            t += step
            times.append(t)
            growth.append(model.growth @ x)
            heat.append(model.volume @ x)
            if store_fields:
                out.append(x.copy())
    rhoc = model.rod.density_kg_m3 * model.rod.specific_heat_J_kgK
    return HeatResult(np.asarray(times), np.asarray(growth), rhoc * np.asarray(heat),
                      np.asarray(out) if store_fields else None)


@dataclass(frozen=True)
class _Modes:
    mu: np.ndarray        # eigenvalues μ_i [1/s]
    phi: np.ndarray       # M-orthonormal eigenvectors (ndofs, nmodes)
    fq: np.ndarray        # Φᵀ f_q
    fb: np.ndarray        # Φᵀ f_b
    g: np.ndarray         # growthᵀ Φ
    v: np.ndarray         # volumeᵀ Φ


def modes(model: HeatFEM, h_W_m2K: float) -> _Modes:
    """All modes of M θ' = −(K + hB)θ by a dense generalised eigensolve.

    Parameters
    ----------
    model : HeatFEM
    h_W_m2K : float
        Lateral convection coefficient h [W/(m²·K)].

    Returns
    -------
    _Modes
        ``mu``: decay rates μ_i [1/s], ascending; ``phi``: M-orthonormal modes
        (ndofs, nmodes), φᵀMφ = I with M in [J/K]; ``fq``, ``fb``: Φᵀf_q, Φᵀf_b
        (modal loads per unit q [W/m²] and per unit h θ_amb [W/m²]); ``g``: growthᵀΦ
        (growth [m] per unit modal amplitude); ``v``: volumeᵀΦ (∫θ dV [K·m³] per unit
        modal amplitude).
    """
    A = model.operator(h_W_m2K).toarray()
    mu, phi = scipy.linalg.eigh(A, model.M.toarray())
    return _Modes(mu, phi, phi.T @ model.f_q, phi.T @ model.f_b, model.growth @ phi,
                  model.volume @ phi)


def _modal_amplitudes(md: _Modes, c0: np.ndarray, q: np.ndarray, hamb: np.ndarray,
                      d: np.ndarray) -> np.ndarray:
    """Modal amplitudes at the ends of consecutive intervals of one h.

    Over a run of intervals with the same input, c(τ) = c_ss + e^{−μτ}(c(0) − c_ss)
    with τ the time since the run began, evaluated in closed form for all intervals at
    once instead of interval by interval. A mode's transient is evaluated only while
    μτ ≤ 40: beyond, e^{−μτ} < 5e-18 and the amplitude is c_ss to round-off, so fast
    modes cost a few rows, not the whole run (modes are taken in bands of rows, by
    powers of two).

    Parameters
    ----------
    md : _Modes
    c0 : ndarray, shape (nmodes,)
        Amplitudes at the start of the first interval.
    q, hamb : ndarray, shape (n,)
        Flux q [W/m²] and h·θ_amb [W/m²] on each interval.
    d : ndarray, shape (n,)
        Interval lengths [s].

    Returns
    -------
    ndarray, shape (n, nmodes)
    """
    n = q.size
    mu = md.mu
    C = np.empty((n, mu.size))
    change = np.flatnonzero((np.diff(q) != 0.0) | (np.diff(hamb) != 0.0)) + 1
    c = c0
    for a, b in zip(np.concatenate([[0], change]), np.concatenate([change, [n]])):
        css = (q[a] * md.fq + hamb[a] * md.fb) / mu
        tau = np.cumsum(d[a:b])
        dc = c - css
        C[a:b] = css
        need = np.searchsorted(tau, 40.0 / mu, side="right")     # rows with μτ ≤ 40
        band = np.ceil(np.log2(np.maximum(need, 1))).astype(int)
        for lv in np.unique(band[need > 0]):
            cols = np.flatnonzero((band == lv) & (need > 0))
            rows = min(2 ** int(lv), b - a)
            C[a:a + rows, cols] += np.exp(-np.outer(tau[:rows], mu[cols])) * dc[cols]
        c = C[b - 1]
    return C


def solve_modal(model: HeatFEM, schedule: Schedule, output_times_s=None, store_fields=False,
                theta0=None, mode_cache: dict | None = None) -> HeatResult:
    """Exact-in-time solution for piecewise-constant inputs, by modal superposition.

    Parameters
    ----------
    model : HeatFEM
    schedule : Schedule
    output_times_s : array_like, optional
        Times [s] at which to report, within [0, schedule.total_s]; default:
        t = 0 and every segment end.
    store_fields : bool
        Keep θ at every output time.
    theta0 : array_like or float, optional
        Initial temperature rise [K]; default 0.
    mode_cache : dict, optional
        ``{h: modes}`` reused across calls with the same model (sweeps, fits).

    Notes
    -----
    Between breakpoints each modal amplitude obeys c' = −μ c + φᵀf, so
    c(t + d) = c_ss + e^{−μ d}(c(t) − c_ss) with c_ss = φᵀf / μ, exactly.
    Where h changes, the state is carried across in nodal form.

    On a 3D model (``model.axisymmetric`` false) the dense eigensolve of every mode
    would cost O(n³) time and O(n²) memory; there this function returns
    :func:`arfem.fem.reduced.solve_reduced` instead (the slowest modes exactly, the
    rest quasi-statically, with its own error estimate; same arguments and result
    fields). ``mode_cache`` is then keyed by (h, n_modes, method).
    """
    if not model.axisymmetric:
        return solve_reduced(model, schedule, output_times_s, store_fields=store_fields,
                             theta0=theta0, mode_cache=mode_cache)
    q, h, amb = schedule_inputs(model, schedule)
    b = breakpoints(schedule, output_times_s)       # segment edges and output times
    bps, seg, d, out_t = b.times_s, b.segment, b.dt_s, b.output_times_s

    cache = {} if mode_cache is None else mode_cache
    x = initial_state_K(model, theta0)
    hs = h[seg]
    states = np.empty((bps.size, model.ndofs)) if store_fields else None
    growth = np.empty(bps.size)
    heat = np.empty(bps.size)
    growth[0], heat[0] = model.growth @ x, model.volume @ x
    if store_fields:
        states[0] = x
    k = 0
    while k < seg.size:
        # run of intervals with the same h
        j = k
        while j + 1 < seg.size and hs[j + 1] == hs[k]:
            j += 1
        hk = float(hs[k])
        if hk not in cache:
            cache[hk] = modes(model, hk)
        md = cache[hk]
        c = md.phi.T @ (model.M @ x)
        idx = np.arange(k, j + 1)
        C = _modal_amplitudes(md, c, q[seg[idx]], hk * amb[seg[idx]], d[idx])
        c = C[-1]
        growth[k + 1:j + 2] = C @ md.g
        heat[k + 1:j + 2] = C @ md.v
        if store_fields:
            states[k + 1:j + 2] = C @ md.phi.T
        x = md.phi @ c
        k = j + 1
    pick = b.pick
    rhoc = model.rod.density_kg_m3 * model.rod.specific_heat_J_kgK
    return HeatResult(out_t.copy(), growth[pick], rhoc * heat[pick],
                      states[pick] if store_fields else None)
