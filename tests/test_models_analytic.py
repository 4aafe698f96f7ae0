"""Tests of the closed-form rod solutions, models/analytic.py (paper eqs. 5-8, 3D radial modes)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, simpson
from scipy.special import erf

from arfem.models import analytic
from arfem.models.ar1 import corrected_coefficients, steady_growth_m
from arfem.params import InputError, Rod, Schedule, paper_cycle

ROD = Rod()
Q = 2000.0
A_DIFF = ROD.diffusivity_m2_s
B_FIN = ROD.fin_rate_1_s
LAM = ROD.conductivity_W_mK
RHOC = ROD.density_kg_m3 * ROD.specific_heat_J_kgK
AREA = ROD.area_m2
PERIM = 2 * math.pi * ROD.radius_m
H = ROD.convection_W_m2K
#: one hour on, one hour off: a switch-on and a switch-off transient
ON_OFF = Schedule([3600.0, 3600.0], [Q, 0.0])


def test_steady_profile_energy_balance_and_boundary_conditions():
    """θ_s satisfies qA = hP∫θ_s dx, −λθ'(0) = q, θ'(L) = 0 and the fin ODE.

    Quadrature (adaptive, rel 1e-13) and analytic derivatives by central
    differences with step 1e-5 m (error O(1e-10) relative): tolerance 1e-8.
    """
    integral, _ = quad(lambda x: analytic.steady_profile_1d(ROD, Q, x), 0, ROD.length_m,
                       epsabs=0, epsrel=1e-13)
    assert H * PERIM * integral == pytest.approx(Q * AREA, rel=1e-10)
    d = 1e-5
    th = lambda x: analytic.steady_profile_1d(ROD, Q, np.asarray(x, float))
    slope0 = (-3 * th(0.0) + 4 * th(d) - th(2 * d)) / (2 * d)
    assert -LAM * slope0 == pytest.approx(Q, rel=1e-8)
    slopeL = (3 * th(ROD.length_m) - 4 * th(ROD.length_m - d) + th(ROD.length_m - 2 * d)) / (2 * d)
    assert abs(slopeL) <= 1e-8 * abs(slope0)
    x = np.array([0.1, 0.4, 0.7])
    curv = (th(x + d) - 2 * th(x) + th(x - d)) / d ** 2
    assert np.allclose(A_DIFF * curv, B_FIN * th(x), rtol=1e-4)   # 2nd difference: O(1e-5)


def test_series_matches_semi_infinite_erf_solution_at_short_times():
    """θ(0, t) = (q/λ)√(a/b) erf(√(bt)) while the far end is not yet felt.

    An independent closed form (Laplace inversion for the semi-infinite fin with
    end flux). The far-end correction is of order exp(−L²/(a t)) < 1e-30 at
    t <= 600 s, so agreement to 1e-12 relative is expected (measured 1e-16).
    """
    for t in (5.0, 60.0, 600.0):
        exact = Q / LAM * math.sqrt(A_DIFF / B_FIN) * erf(math.sqrt(B_FIN * t))
        got = analytic.temperature_1d(ROD, ON_OFF, [0.0], [t])[0, 0]
        assert got == pytest.approx(exact, rel=1e-12)


def test_series_tends_to_steady_profile():
    """After a long flux step the series equals the closed-form steady profile (eqs. 5-7).

    At t = 2·10⁵ s the slowest transient is e^{−bt} ≈ 4e-27; tolerance 1e-12.
    """
    x = np.linspace(0, ROD.length_m, 9)
    got = analytic.temperature_1d(ROD, Schedule([2e5], [Q]), x, [2e5])[0]
    assert np.allclose(got, analytic.steady_profile_1d(ROD, Q, x), rtol=1e-12, atol=0)


def test_series_converges_with_n_terms():
    """The error against a 4000-term reference falls monotonically with n_terms.

    Checked just after the switch-on (t = 0.5 s) and the switch-off (t = 3601 s),
    where the high modes matter most. Measured: 1.4 (25 terms) → 1.5e-10
    (400 terms) at 0.5 s; asserted: monotone decrease and < 1e-8 at 400 terms.
    (The reference's own error is below 1e-16: the truncation error decays
    like e^{−a(nπ/L)²t}, see :func:`arfem.models.analytic.temperature_1d`.)
    """
    x = np.linspace(0, ROD.length_m, 401)
    t = [0.5, 3601.0]
    ref = analytic.temperature_1d(ROD, ON_OFF, x, t, n_terms=4000)
    errs = []
    for n in (25, 50, 100, 200, 400):
        got = analytic.temperature_1d(ROD, ON_OFF, x, t, n_terms=n)
        errs.append(np.max(np.abs(got - ref), axis=1) / np.max(np.abs(ref), axis=1))
    errs = np.asarray(errs)
    assert np.all(np.diff(errs, axis=0) < 0), errs
    assert np.all(errs[-1] < 1e-8), errs[-1]
    assert np.all(errs[0] > 1e-3), "coarse series should visibly differ, else the test is vacuous"


def test_series_satisfies_the_pde_and_the_flux_condition():
    """θ_t = aθ_xx − bθ inside and −λθ_x(0) = q(t) at the heated end.

    Finite differences of the series (Δt = 0.5 s, Δx = 1 mm in the PDE; one-sided
    2nd order with 0.1 mm at x = 0) have truncation errors ~1e-6 of the terms
    (measured 3e-6); tolerances 1e-4 (PDE, relative to max|aθ_xx|) and 1e-5 (flux).
    After switch-off the end flux must be zero: 1e-5 q.
    """
    xs = np.array([0.05, 0.2, 0.5])
    dx, dt = 1e-3, 0.5
    for t in (600.0, 3700.0):
        T = analytic.temperature_1d(ROD, ON_OFF, np.concatenate([xs - dx, xs, xs + dx]),
                                    [t - dt, t, t + dt])
        th = T[1, 3:6]
        th_t = (T[2, 3:6] - T[0, 3:6]) / (2 * dt)
        th_xx = (T[1, 6:] - 2 * th + T[1, :3]) / dx ** 2
        assert np.max(np.abs(th_t - (A_DIFF * th_xx - B_FIN * th))) <= 1e-4 * np.max(
            np.abs(A_DIFF * th_xx))
    d = 1e-4
    for t, q in ((600.0, Q), (3500.0, Q), (3700.0, 0.0), (7000.0, 0.0)):
        T = analytic.temperature_1d(ROD, ON_OFF, [0.0, d, 2 * d], [t])[0]
        flux = -LAM * (-3 * T[0] + 4 * T[1] - T[2]) / (2 * d)
        assert abs(flux - q) <= 1e-5 * Q


def test_series_energy_balance_and_growth_eq8():
    """ρcA d/dt∫θ dx = qA − hP∫θ dx, integrated over each phase; α∫θ dx = eq. 8.

    ∫θ dx by Simpson on 1601 points, time integral by Simpson with 1 s steps
    (the integrand is smooth: only the n = 0 mode survives the x-integral);
    measured residual 3e-13 of the energy input; tolerance 1e-9. The growth
    α∫θ dx must equal :func:`growth_1d` (eq. 8) to 1e-10 of its maximum.
    """
    x = np.linspace(0, ROD.length_m, 1601)
    for t0, t1, q in ((0.0, 3600.0, Q), (3600.0, 7200.0, 0.0)):
        t = np.linspace(t0, t1, 3601)
        integral = simpson(analytic.temperature_1d(ROD, ON_OFF, x, t), x=x, axis=1)
        heat = RHOC * AREA * integral
        supplied = simpson(q * AREA - H * PERIM * integral, x=t)
        assert heat[-1] - heat[0] == pytest.approx(supplied, abs=1e-9 * Q * AREA * 3600)
        growth = analytic.growth_1d(ROD, ON_OFF, t)
        err = np.max(np.abs(ROD.expansion_1_K * integral - growth))
        assert err <= 1e-10 * np.max(growth)   # measured 2.5e-13 (Simpson in x)


def test_growth_1d_is_superposition_of_steps():
    """Eq. 8 on a schedule = Σ of step responses Δq_j G(t − t_j) (linearity).

    Independent of the recursive evaluation used by growth_1d; 1e-12 relative.
    """
    sched = paper_cycle(3000.0)
    t = np.linspace(0, sched.total_s, 97)
    edges, q = sched.edges_s, np.asarray(sched.q_W_m2)
    dq = np.diff(np.concatenate([[0.0], q]))
    ref = sum(analytic.growth_1d_step(ROD, dqj, np.maximum(t - tj, 0.0))
              for dqj, tj in zip(dq, edges[:-1]))
    got = analytic.growth_1d(ROD, sched, t)
    assert np.max(np.abs(got - ref)) <= 1e-12 * np.max(np.abs(ref))
    # and the step response obeys dG/dt = αqa/λ − bG (central difference, Δt = 1 s)
    g = analytic.growth_1d_step(ROD, Q, [999.0, 1000.0, 1001.0])
    rhs = ROD.expansion_1_K * Q * A_DIFF / LAM - B_FIN * g[1]
    assert (g[2] - g[0]) / 2.0 == pytest.approx(rhs, rel=1e-7)


def test_radial_mode_sum_converges_and_first_mode_dominates():
    """Σ w_m → 1 (tail ~ m⁻³), 1 − w_1 = O(Bi²), and mode 1 carries the growth.

    * 1 − Σ_{m≤n} w_m falls by ≈ 8 per doubling of n (measured 8.07); asserted
      between 6 and 10, and below 1e-8 at n = 40.
    * 1 − w_1 → Bi²/48: the ratio (1 − w_1)/Bi² is within 3 % of 1/48 for
      Bi <= 0.11 (measured 0.0203-0.0208).
    * The modal gains sum to the exact steady 3D growth (1 + Bi/4)·qαR/(2h)
      (closed form, independent of the Bessel roots) to 1e-9 with 80 modes.
    * At the paper's Bi, modes m >= 2 carry < 1e-5 of the steady growth
      (measured 3.2e-6) and < 1e-3 of the 30 s step response (measured 3.6e-4).
    """
    tails = [1 - analytic.radial_mode_weights(ROD.biot, n).sum() for n in (10, 20, 40, 80)]
    ratios = np.array(tails[:-1]) / np.array(tails[1:])
    assert np.all((ratios > 6) & (ratios < 10)), ratios
    assert tails[2] < 1e-8
    for bi in (0.11, 0.011, 0.0011):
        w1 = analytic.radial_mode_weights(bi, 1)[0]
        assert (1 - w1) / bi ** 2 == pytest.approx(1 / 48, rel=0.03)
    rates, gains = analytic.growth_3d_modes(ROD, 80)
    assert Q * gains.sum() == pytest.approx(analytic.steady_growth_3d_m(ROD, Q), rel=1e-9)
    assert np.all(np.diff(rates) > 0)
    assert gains[1:].sum() / gains.sum() < 1e-5
    parts = analytic.growth_3d_step(ROD, Q, [30.0], n_modes=40, per_mode=True)[0]
    assert parts[1:].sum() / parts.sum() < 1e-3
    # the m = 1 mode is the corrected AR(1): same rate and gain
    c1, c2 = corrected_coefficients(ROD, 30.0, Q)
    assert math.exp(-rates[0] * 30.0) == pytest.approx(c1, rel=1e-13)
    assert Q * gains[0] * (1 - c1) == pytest.approx(c2, rel=1e-12)


def test_3d_steady_growth_tends_to_1d_as_biot_vanishes():
    """(1 + Bi/4) factor: 3D/1D steady growth − 1 = Bi/4 exactly, → 0 with Bi."""
    for h in (55.0, 5.5, 0.55):
        rod = ROD.with_(convection_W_m2K=h)
        ratio = analytic.steady_growth_3d_m(rod, Q) / steady_growth_m(rod, Q)
        assert ratio - 1 == pytest.approx(rod.biot / 4, rel=1e-12)


def test_3d_modal_growth_matches_axisymmetric_fem_on_paper_cycle():
    """The exact modal growth and the axisymmetric Q2 FEM agree on the paper cycle.

    Two independent solutions of the same 3D problem (series in Bessel modes vs
    finite elements with exact modal time integration). Measured max difference
    1.8e-9 of the peak on the default mesh; tolerance 1e-6 of the peak leaves
    room for mesh changes while any modelling slip (a wrong weight, a missing
    mode, 1D instead of 3D: 2.6 %) fails.
    """
    from arfem.fem.heat import build_axisymmetric, solve_modal
    sched = paper_cycle(Q)
    t = sched.subdivided(300.0).edges_s
    fem = solve_modal(build_axisymmetric(ROD), sched, output_times_s=t).growth_m
    exact = analytic.growth_3d(ROD, sched, t)
    assert np.max(np.abs(fem - exact)) <= 1e-6 * np.max(exact)
    assert np.max(exact) == pytest.approx(22.1666e-6, abs=1e-10)


@pytest.mark.parametrize("call, where", [
    (lambda: analytic.temperature_1d(ROD, ON_OFF, [0.0], [0.0], n_terms=0), "n_terms"),
    (lambda: analytic.temperature_1d(ROD, ON_OFF, [0.0, 0.9], [0.0]), "x_m"),
    (lambda: analytic.temperature_1d(ROD, ON_OFF, [0.0], [8000.0]), "t_s"),
    (lambda: analytic.temperature_1d(ROD, ON_OFF, [0.0], [-1.0]), "t_s"),
    (lambda: analytic.temperature_1d(ROD, ON_OFF, [float("nan")], [0.0]), "x_m"),
    (lambda: analytic.growth_1d_step(ROD, float("nan"), [0.0]), "q_W_m2"),
    (lambda: analytic.growth_1d(ROD, ON_OFF, [[0.0]]), "t_s"),
    (lambda: analytic.steady_profile_1d(ROD, Q, [-0.1]), "x_m"),
    (lambda: analytic.radial_eigenvalues(-0.1, 3), "biot"),
    (lambda: analytic.radial_eigenvalues(0.1, 2.5), "n_modes"),
    (lambda: analytic.growth_3d_step(ROD, Q, [0.0], n_modes=0), "n_modes"),
])
def test_bad_input_is_refused(call, where):
    """Malformed or out-of-range input raises a one-line InputError naming the field."""
    with pytest.raises(InputError) as err:
        call()
    assert err.value.where == where
    assert "\n" not in str(err.value)
