"""Tests of the AR(1) core, models/ar1.py (paper eqs. 12-14 and the mode-1 correction)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from arfem.models import analytic
from arfem.models.ar1 import (ar1_on_schedule, ar1_simulate, c1_paper, c2_paper,
                        corrected_coefficients, fit_ar1, radial_eigenvalue, steady_growth_m)
from arfem.params import InputError, Rod, Schedule, paper_cycle
from scipy.special import j0, j1

ROD = Rod()
DTAU = 30.0


def test_paper_coefficients_match_published_values():
    """C1, C2 at Δτ = 30 s equal the values printed in the paper (eqs. 13-14).

    The paper prints 4 significant digits, so the tolerance is half a unit in the
    last printed digit (5e-5). The expected numbers are recomputed here from the raw
    material data as well, to 1e-12, so a wrong formula cannot hide behind rounding.
    """
    b = 2 * 55.0 / (7850.0 * 460.0 * 0.1)
    a = 50.0 / (7850.0 * 460.0)
    c1 = c1_paper(ROD, DTAU)
    assert abs(c1 - 0.9909) <= 5e-5
    assert c1 == pytest.approx(math.exp(-b * DTAU), rel=1e-12)
    for q, printed_um in ((2000.0, 0.1985), (3000.0, 0.2977)):
        c2 = c2_paper(ROD, DTAU, q)
        assert abs(c2 * 1e6 - printed_um) <= 5e-5
        assert c2 == pytest.approx(q * 12e-6 * a / (50.0 * b) * (1 - math.exp(-b * DTAU)),
                                   rel=1e-12)
        # the fixed point of eq. 12 is the steady growth of eq. 8
        assert c2 / (1 - c1) == pytest.approx(steady_growth_m(ROD, q), rel=1e-12)


@pytest.mark.parametrize("q", [2000.0, 3000.0])
def test_ar1_equals_closed_form_growth_on_paper_cycle(q):
    """The AR(1) recursion equals the closed-form 1D growth (eq. 8) at every sample.

    The AR(1) is exact for the 1D rod when q is constant over each Δτ, so the
    only difference is floating-point rounding accumulated over 2880 steps
    (measured 8e-15 of the peak); 1e-12 relative leaves room for platform
    differences while any modelling error (>= 1e-6) would fail.
    """
    t, g = ar1_on_schedule(ROD, paper_cycle(q), DTAU)
    exact = analytic.growth_1d(ROD, paper_cycle(q), t)
    assert t.size == 24 * 120 + 1
    assert np.max(np.abs(g - exact)) <= 1e-12 * np.max(exact)


def test_ar1_exact_on_irregular_schedule_and_other_dtau():
    """Exactness holds for any Δτ and any piecewise-constant q on the Δτ grid.

    A random 3-level schedule at Δτ = 90 s; same 1e-12 rounding tolerance.
    """
    rng = np.random.default_rng(3)
    n = 60
    sched = Schedule(90.0 * rng.integers(1, 20, n), rng.choice([0.0, 2000.0, 3000.0], n))
    t, g = ar1_on_schedule(ROD, sched, 90.0)
    exact = analytic.growth_1d(ROD, sched, t)
    assert np.max(np.abs(g - exact)) <= 1e-12 * np.max(exact)


def test_ar1_simulate_time_varying_c1_matches_loop():
    """Per-step C1 (the slow path) gives the textbook recursion; exact arithmetic check."""
    c1 = np.array([0.5, 0.25, 1.0])
    c2 = np.array([1.0, 2.0, 3.0])
    assert ar1_simulate(c1, c2, g0=4.0).tolist() == [4.0, 3.0, 2.75, 5.75]


def test_radial_eigenvalue_solves_the_bessel_condition():
    """μ_m solves μ J1(μ) = Bi J0(μ), the roots increase, and the limits hold.

    Residual tolerance 1e-12 (Brent's method to machine precision on an O(1)
    function). Limits: μ1² / (2Bi) → 1 as Bi → 0 (error O(Bi), so within 1e-3
    at Bi = 1e-3) and μ_m → m-th zero of J0 as Bi → ∞ (within 1e-4 at Bi = 1e5,
    the error being O(1/Bi)).
    """
    for bi in (1e-3, 0.11, 1.0, 10.0):
        mus = [radial_eigenvalue(bi, m) for m in range(1, 6)]
        assert np.all(np.diff(mus) > 0)
        for mu in mus:
            assert abs(mu * j1(mu) - bi * j0(mu)) <= 1e-12
        # agrees with the vectorised version of models.analytic
        assert np.allclose(mus, analytic.radial_eigenvalues(bi, 5), rtol=1e-13, atol=0)
    assert radial_eigenvalue(1e-3) ** 2 / 2e-3 == pytest.approx(1.0, abs=1e-3)
    assert radial_eigenvalue(1e5, 3) == pytest.approx(8.653727912911013, abs=1e-4)


def test_corrected_coefficients_tend_to_paper_as_biot_vanishes():
    """Corrected → paper coefficients as Bi → 0, with relative differences O(Bi).

    Bi is lowered by lowering h over four decades. The relative differences of
    the decay rate (−ln C1 / Δτ) and of the steady gain C2/(1 − C1) shrink with
    observed log-log slope 1 (asserted within 0.03), and the constant approaches
    1/4 (rate: μ1² = 2Bi(1 − Bi/4 + …); gain: the exact 3D steady growth is
    (1 + Bi/4) times the 1D one). At the paper's Bi = 0.11 the rate differs by
    2.7 %, which is the 2.57 % AR-vs-FEM gap on the paper cycle.
    """
    bis, d_rate, d_gain = [], [], []
    for h in 55.0 * np.logspace(0, -4, 5):
        rod = ROD.with_(convection_W_m2K=h)
        c1c, c2c = corrected_coefficients(rod, DTAU, 2000.0)
        c1p, c2p = c1_paper(rod, DTAU), c2_paper(rod, DTAU, 2000.0)
        bis.append(rod.biot)
        d_rate.append(abs(math.log(c1c) / math.log(c1p) - 1))
        d_gain.append(abs(c2c / (1 - c1c) / (c2p / (1 - c1p)) - 1))
    bis, d_rate, d_gain = map(np.asarray, (bis, d_rate, d_gain))
    for d in (d_rate, d_gain):
        slopes = np.diff(np.log(d)) / np.diff(np.log(bis))
        assert np.all(np.abs(slopes - 1.0) <= 0.03), slopes
        assert d[-1] / bis[-1] == pytest.approx(0.25, rel=1e-3)
    assert d_rate[0] == pytest.approx(0.027, abs=5e-4)


def test_corrected_ar_is_the_first_radial_mode_exactly():
    """The corrected AR(1) samples the m = 1 term of the exact 3D step response.

    Both are closed forms of the same exponential, so they agree to rounding
    (1e-12 of the final value).
    """
    sched = Schedule([3600.0], [2000.0])
    t, g = ar1_on_schedule(ROD, sched, DTAU, corrected=True)
    ref = analytic.growth_3d_step(ROD, 2000.0, t, n_modes=1)
    assert np.max(np.abs(g - ref)) <= 1e-12 * ref[-1]


def _random_levels(rng, n_steps):
    """Piecewise-constant levels in runs of 20-200 steps over {0, 2000, 3000}."""
    out = []
    while len(out) < n_steps:
        out += [rng.choice([0.0, 2000.0, 3000.0])] * int(rng.integers(20, 200))
    return np.asarray(out[:n_steps])


def test_fit_ar1_recovers_coefficients_from_noiseless_series():
    """Noiseless data generated by an AR(1) are fitted exactly (to 1e-9).

    The regression is then consistent with zero residual; 1e-9 allows for the
    conditioning of the least-squares problem (C1 near 1) in double precision.
    """
    rng = np.random.default_rng(0)
    lv = _random_levels(rng, 3000)
    c2 = {0.0: 0.0, 2000.0: 0.1985, 3000.0: 0.2977}
    g = ar1_simulate(0.9909, [c2[v] for v in lv])
    fit = fit_ar1(g, lv)
    assert fit.c1 == pytest.approx(0.9909, abs=1e-9)
    for level, value in c2.items():
        assert fit.c2[level] == pytest.approx(value, abs=1e-9)
    assert fit.residual_rms <= 1e-9


def test_fit_ar1_recovers_coefficients_from_noisy_series():
    """With white innovation noise σ the estimates are within 5 OLS standard errors.

    Tolerance: the standard error of each coefficient is σ √diag((XᵀX)⁻¹) for the
    realised design X; 5 SE is exceeded with probability < 1e-6 (and the seed is
    fixed). We also check the SE is small (C1 to < 1e-3), so the test has teeth,
    and that the residual RMS estimates σ within 5 of its standard deviations
    σ/√(2N).
    """
    rng = np.random.default_rng(1)
    n = 5000
    lv = _random_levels(rng, n)
    c1, c2 = 0.9909, {0.0: 0.0, 2000.0: 0.1985, 3000.0: 0.2977}
    sigma = 0.02
    g = ar1_simulate(c1, np.array([c2[v] for v in lv]) + sigma * rng.standard_normal(n))
    fit = fit_ar1(g, lv)
    X = np.column_stack([g[:-1]] + [(lv == u).astype(float) for u in sorted(c2)])
    se = sigma * np.sqrt(np.diag(np.linalg.inv(X.T @ X)))
    assert se[0] < 1e-3
    assert abs(fit.c1 - c1) <= 5 * se[0]
    for k, level in enumerate(sorted(c2)):
        assert abs(fit.c2[level] - c2[level]) <= 5 * se[k + 1]
    assert abs(fit.residual_rms - sigma) <= 5 * sigma / math.sqrt(2 * n)


@pytest.mark.parametrize("call, where", [
    (lambda: c1_paper(ROD, 0.0), "dtau_s"),
    (lambda: c1_paper(ROD, float("nan")), "dtau_s"),
    (lambda: c1_paper(ROD, "thirty"), "dtau_s"),
    (lambda: c2_paper(ROD, 30.0, float("inf")), "q_W_m2"),
    (lambda: corrected_coefficients(ROD, -30.0, 2000.0), "dtau_s"),
    (lambda: radial_eigenvalue(0.0), "biot"),
    (lambda: radial_eigenvalue(0.11, 0), "m"),
    (lambda: ar1_simulate(0.5, [1.0, float("nan")]), "c2"),
    (lambda: ar1_simulate([0.5, 0.4], [1.0, 1.0, 1.0]), "c1"),
    (lambda: fit_ar1([0.0, 1.0, 2.0], [1.0]), "levels"),
    (lambda: fit_ar1([0.0, float("nan"), 2.0], [1.0, 1.0]), "growth"),
    (lambda: fit_ar1([0.0, 1.0], [1.0]), "growth"),              # too few samples
    (lambda: fit_ar1([5.0] * 10, [1.0] * 9), "growth"),          # never changes: unidentifiable
    (lambda: ar1_on_schedule(ROD, paper_cycle(2000.0), 7.0), "dt_s"),
])
def test_bad_input_is_refused_with_one_line_message(call, where):
    """Non-physical or malformed input raises InputError naming the field, on one line.

    The CLI relies on this to print `arfem: error: ...` without a traceback.
    """
    with pytest.raises(InputError) as err:
        call()
    assert err.value.where == where
    assert "\n" not in str(err.value)
