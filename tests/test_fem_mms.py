"""Method of manufactured solutions for the transient heat operator of :mod:`arfem.fem.heat`.

Spatial and temporal accuracy are measured apart:

* spatial: θ*(x, t) = φ0(x) + (t/T) φ1(x) is linear in time. Crank–Nicolson with
  the load taken at the step midpoint reproduces any solution linear in time
  exactly, so the error at t = T is purely spatial; its observed L2 order under
  uniform refinement must be p + 1 (Q1/Q2 axisymmetric, Hex1/serendipity Hex20 3D).
* temporal: θ*(x, t) = φ(x) sin³(ωt) on one fixed mesh, compared with the exact
  semi-discrete solution (modal superposition with the sinusoidal forcing
  integrated in closed form), which removes the spatial error exactly; the
  observed order of Crank–Nicolson must be 2. sin³ vanishes with its first two
  derivatives at t = 0, so the stiff modes start compatible and Crank–Nicolson's
  undamped stiff components do not pollute the order.

The manufactured load is the weak residual of θ* itself,
ℓ(v) = ∫ρc θ*_t v + λ∫∇θ*·∇v + h∫_lateral θ* v (the Neumann/Robin data of θ* are
implied), which is what a body source plus boundary data would assemble to.
The fields are smooth functions of s = r²/R² and z, hence smooth in 3D too.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.sparse.linalg import cg
from skfem import Basis, ElementHex1, ElementHexS2, ElementQuad1, ElementQuad2, \
    FacetBasis, Functional, LinearForm

from arfem.fem.heat import HeatFEM, solve_theta
from arfem.fem.mesh import axisymmetric_mesh, cylinder_mesh
from arfem.params import Rod, Schedule

ROD = Rod()
R, L = ROD.radius_m, ROD.length_m
RHOC = ROD.density_kg_m3 * ROD.specific_heat_J_kgK
LAM, H = ROD.conductivity_W_mK, ROD.convection_W_m2K
T_END = 3600.0


# -- manufactured fields: value, d/ds, d/dz as functions of (s = r²/R², z) -------------
def phi0(s, z):
    c = np.cos(1.3 * np.pi * z / L)
    return ((1 + 0.5 * s) * c, 0.5 * c, -(1 + 0.5 * s) * 1.3 * np.pi / L * np.sin(1.3 * np.pi * z / L))


def phi1(s, z):
    e = np.exp(-z / L)
    return (e * np.cos(s), -e * np.sin(s), -e * np.cos(s) / L)


def _sz(x, axi):
    if axi:
        return x[0] ** 2 / R ** 2, x[1]
    return (x[0] ** 2 + x[1] ** 2) / R ** 2, x[2]


def _grad(x, axi, ds, dz):
    """∇ of a function of (s, z) given its partial derivatives."""
    if axi:
        return [ds * 2 * x[0] / R ** 2, dz]
    return [ds * 2 * x[0] / R ** 2, ds * 2 * x[1] / R ** 2, dz]


def _weight(x, axi):
    return 2 * np.pi * x[0] if axi else 1.0 + 0 * x[0]


def weak_load(model: HeatFEM, phi, coef_rate: float, coef_value: float):
    """ℓ(v) = coef_rate ∫ρc φ v + coef_value (λ∫∇φ·∇v + h∫_lat φ v)."""
    axi = model.axisymmetric

    @LinearForm
    def vol(v, w):
        s, z = _sz(w.x, axi)
        f, fs, fz = phi(s, z)
        g = _grad(w.x, axi, fs, fz)
        return (coef_rate * RHOC * f * v + coef_value * LAM * sum(gi * vi for gi, vi in zip(g, v.grad))) \
            * _weight(w.x, axi)

    @LinearForm
    def lat(v, w):
        s, z = _sz(w.x, axi)
        return coef_value * H * phi(s, z)[0] * v * _weight(w.x, axi)

    return vol.assemble(model.basis) + lat.assemble(_lateral_basis(model))


_FACET_CACHE: dict = {}


def _lateral_basis(model: HeatFEM) -> FacetBasis:
    """Lateral-surface basis, built once per model (curved 3D facets are slow to map)."""
    key = id(model)
    if key not in _FACET_CACHE or _FACET_CACHE[key][0] is not model:
        mesh = model.basis.mesh
        kw = {} if model.axisymmetric else {"intorder": 4}
        _FACET_CACHE.clear()
        _FACET_CACHE[key] = (model, FacetBasis(mesh, model.basis.elem,
                                               facets=mesh.boundaries["lateral"], **kw))
    return _FACET_CACHE[key][1]


def l2_error(model: HeatFEM, u, exact) -> float:
    """‖u_h − exact‖_L2 with a quadrature well above the element order."""
    axi = model.axisymmetric
    eb = Basis(model.basis.mesh, model.basis.elem, intorder=8 if axi else 6)

    @Functional
    def err2(w):
        s, z = _sz(w.x, axi)
        return (w["uh"] - exact(s, z)) ** 2 * _weight(w.x, axi)

    return float(np.sqrt(err2.assemble(eb, uh=eb.interpolate(u))))


def _model(axi: bool, p: int, n: int) -> HeatFEM:
    if axi:
        mesh = axisymmetric_mesh(ROD, nr=n, nz=4 * n, ratio_r=1.0, ratio_z=1.0)
        return HeatFEM.build(mesh, (ElementQuad1 if p == 1 else ElementQuad2)(), ROD, True)
    mesh = cylinder_mesh(ROD, n_core=n, n_ring=n, nz=4 * n, ratio_ring=1.0, ratio_z=1.0)
    return HeatFEM.build(mesh, (ElementHex1 if p == 1 else ElementHexS2)(), ROD, False,
                         intorder=4)


def spatial_error(axi: bool, p: int, n: int, nsteps: int = 4) -> tuple[float, float]:
    """(mesh size [m], L2 error [K·m^(3/2)]) at t = T for θ* = φ0 + (t/T) φ1."""
    model = _model(axi, p, n)
    L0 = weak_load(model, phi0, 0.0, 1.0) + weak_load(model, phi1, 1.0 / T_END, 0.0)
    L1 = weak_load(model, phi1, 0.0, 1.0 / T_END)
    dt = T_END / nsteps
    sched = Schedule(np.full(nsteps, dt), 0.0)
    # initial state: M-projection of φ0
    m0 = weak_load(model, phi0, 1.0, 0.0)
    u0, info = cg(model.M, m0, rtol=1e-14, atol=0.0, maxiter=2000)
    assert info == 0
    res = solve_theta(model, sched, dt, theta=0.5, theta0=u0, store_fields=True,
                      source=lambda x, i: L0 + (i + 0.5) * dt * L1)
    exact = lambda s, z: phi0(s, z)[0] + phi1(s, z)[0]
    return R / n, l2_error(model, res.fields[-1], exact)


def observed_order(hs, errs) -> float:
    """Slope of log(error) against log(h), as scikit-fem's tests/test_convergence.py."""
    return float(np.polyfit(np.log(hs), np.log(errs), 1)[0])


@pytest.mark.parametrize("p, ns", [(1, (2, 4, 8, 16)), (2, (2, 4, 8))])
def test_spatial_order_axisymmetric(p, ns):
    """Observed L2 order of the axisymmetric Qp heat operator is p + 1 (± 0.2).

    Property: M, K, B and the loads with the 2πr weight converge at the optimal
    rate p + 1 in L2 on uniformly refined meshes. Tolerance 0.2: the rate of a
    3-4 level least-squares fit on pre-asymptotic meshes wanders by ~0.1; a wrong
    weight, a missing hoop/axis term or a wrong boundary term drops the order by
    >= 1 or stalls it at O(1).
    """
    hs, errs = zip(*[spatial_error(True, p, n) for n in ns])
    assert errs[-1] < errs[0] / 2 ** (p + 1)          # it converges at all
    assert abs(observed_order(hs, errs) - (p + 1)) < 0.2, (hs, errs)


@pytest.mark.parametrize("p, ns", [(1, (1, 2, 4)), (2, (1, 2, 4))])
def test_spatial_order_3d(p, ns):
    """Observed L2 order of the 3D Hex1 / serendipity Hex20 heat operator on the curved
    butterfly mesh is p + 1 (± 0.2).

    Property: the curved (quadratic-geometry) cylinder mesh and the 3D assembly
    converge optimally; serendipity elements keep their order because uniform
    refinement of a smooth block map makes the cells asymptotically affine.
    Tolerance 0.2 as for the axisymmetric case (3 levels, the coarsest n = 1).
    """
    hs, errs = zip(*[spatial_error(False, p, n) for n in ns])
    assert errs[-1] < errs[0] / 2 ** (p + 1)
    assert abs(observed_order(hs, errs) - (p + 1)) < 0.2, (hs, errs)


# -- temporal ---------------------------------------------------------------------------
OMEGA = 2 * np.pi / (4 * 3600.0)
T_FINAL = 3 * 3600.0
#: sin³(ωt) = (3 sin ωt − sin 3ωt)/4 ; d/dt = (3ω/4)(cos ωt − cos 3ωt)
SIN3 = {1: 0.75, 3: -0.25}


def semi_discrete_exact(model: HeatFEM, ell_value, ell_rate, t: float) -> np.ndarray:
    """Exact solution at t of M u' + (K + hB) u = sin³(ωt) ℓ_value + (sin³)'(ωt) ℓ_rate, u(0)=0.

    Each M-orthonormal mode obeys c' = −μ c + Σ_k (α_k sin kωt + β_k cos kωt); the
    sinusoidal particular solution plus the decaying transient is closed form.
    """
    A = model.operator(H).toarray()
    mu, Phi = scipy.linalg.eigh(A, model.M.toarray())
    gv, gr = Phi.T @ ell_value, Phi.T @ ell_rate
    c = np.zeros_like(mu)
    c0 = np.zeros_like(mu)
    for k, a_k in SIN3.items():
        w = k * OMEGA
        alpha = a_k * gv              # coefficient of sin(kωt)
        beta = a_k * w * gr           # coefficient of cos(kωt)
        den = mu ** 2 + w ** 2
        A_ = (mu * alpha + w * beta) / den
        B_ = (mu * beta - w * alpha) / den
        c += A_ * np.sin(w * t) + B_ * np.cos(w * t)
        c0 += B_
    c -= c0 * np.exp(-mu * t)
    return Phi @ c


def temporal_errors(model: HeatFEM, ns) -> tuple[np.ndarray, np.ndarray]:
    lv = weak_load(model, phi0, 0.0, 1.0)
    lr = weak_load(model, phi0, 1.0, 0.0)
    ref = semi_discrete_exact(model, lv, lr, T_FINAL)
    s3 = lambda t: np.sin(OMEGA * t) ** 3
    ds3 = lambda t: 3 * OMEGA * np.sin(OMEGA * t) ** 2 * np.cos(OMEGA * t)
    dts, errs = [], []
    for n in ns:
        dt = T_FINAL / n
        tm = (np.arange(n) + 0.5) * dt
        res = solve_theta(model, Schedule(np.full(n, dt), 0.0), dt, theta=0.5, store_fields=True,
                          source=lambda x, i: s3(tm[i]) * lv + ds3(tm[i]) * lr)
        e = res.fields[-1] - ref
        dts.append(dt)
        errs.append(np.sqrt(e @ (model.M @ e) / RHOC))     # L2 norm of the error field
    return np.asarray(dts), np.asarray(errs)


@pytest.mark.parametrize("axi", [True, False], ids=["axisymmetric", "3d"])
def test_temporal_order_crank_nicolson(axi):
    """Observed temporal order of Crank–Nicolson (midpoint load) is 2 (± 0.1).

    Property: solve_theta(theta=0.5) is second order in time for a smooth
    forcing. The reference is the exact semi-discrete solution on the same mesh,
    so the spatial error cancels exactly and the only error left is the time
    step's. Steps of T/8 … T/128 with ωT = 4.7 are in the asymptotic range (the
    error falls by 4.00 ± 0.05 per halving); tolerance 0.1 separates order 2
    from backward Euler's 1 and from a first-order load treatment.
    """
    model = _model(axi, 2, 2 if axi else 1)
    dts, errs = temporal_errors(model, (8, 16, 32, 64, 128))
    assert errs[0] > 1e3 * 1e-12          # far above round-off, so the slope is meaningful
    assert abs(observed_order(dts, errs) - 2.0) < 0.1, (dts, errs)
