"""Tolerance stack-up: exact worst case over signs, RSS, Monte Carlo yield, sensitivity."""
import itertools

import numpy as np
import pytest

from arfem.models.allocation import tolerance


def _brute(t, J):
    S = np.array(list(itertools.product([-1.0, 1.0], repeat=len(t))))
    return np.linalg.norm((S * t) @ J, axis=1).max()


@pytest.mark.parametrize("kind", ["generic", "coplanar", "parallel+coplanar", "zero rows"])
@pytest.mark.parametrize("seed", range(4))
def test_worst_case_equals_brute_force_over_all_signs(kind, seed):
    """The zonotope-vertex enumeration gives the same maximum as trying all 2^K sign
    combinations (K = 11), also for the degenerate geometries a machine produces
    (generators in one plane, parallel ones, components with no effect). Tolerance 1e-12
    relative: both are the same sums in floating point."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(11, 3))
    if kind == "coplanar":
        J[:, 2] = 0.0
    elif kind == "parallel+coplanar":
        J[:4] = J[0] * rng.uniform(-2, 2, (4, 1))
        J[5:9, 2] = 0.0
    elif kind == "zero rows":
        J[[1, 4]] = 0.0
    t = rng.uniform(0.1, 1.0, 11)
    assert tolerance.worst_case(t[None], J)[0] == pytest.approx(_brute(t, J), rel=1e-12)


def test_stack_orderings():
    """For any tolerances: RSS <= exact worst case <= arithmetic sum of |t_k J_k|, and
    the worst case is at least the largest single contribution (definitions)."""
    rng = np.random.default_rng(9)
    J = rng.normal(size=(24, 3))
    T = rng.uniform(0.0, 1.0, (50, 24))
    wc = tolerance.worst_case(T, J)
    rs = tolerance.rss(T, J)
    arith = T @ np.linalg.norm(J, axis=1)
    single = (T * np.linalg.norm(J, axis=1)).max(axis=1)
    assert np.all(rs <= wc * (1 + 1e-12)) and np.all(wc <= arith * (1 + 1e-12))
    assert np.all(wc >= single * (1 - 1e-12))


def test_monte_carlo_yield_matches_closed_form():
    """Two orthogonal generators, tolerances a and b, uniform errors: P(|δ| <= R) for
    R = a = b is the area of a quarter disc in the unit square, π/4. With 10⁵ draws the
    binomial standard error is 0.0013, so the tolerance is 0.005 (≈ 4σ). Normal errors
    with t = 3σ: |δ|²/σ² is χ²₂, P(|δ| <= 3σ) = 1 − exp(−4.5)."""
    t = np.array([1e-3, 1e-3])
    J = np.array([[[1.0, 0, 0], [0, 1.0, 0]]])
    u = tolerance.monte_carlo(t, J, 1e-3, 100_000, "uniform", seed=3)
    assert u["yield"] == pytest.approx(np.pi / 4, abs=0.005)
    n = tolerance.monte_carlo(t, J, 1e-3, 100_000, "normal", seed=3)
    assert n["yield"] == pytest.approx(1 - np.exp(-4.5), abs=0.005)


def test_monte_carlo_never_exceeds_worst_case():
    """No simulated assembly can be worse than the worst case over all signs (uniform
    errors stay inside the zonotope), at every pose."""
    rng = np.random.default_rng(2)
    Js = rng.normal(size=(3, 10, 3))
    t = rng.uniform(0.1, 1.0, 10)
    r = tolerance.monte_carlo(t, Js, 1.0, 20_000, "uniform", seed=1)
    wc = max(tolerance.worst_case(t[None], J)[0] for J in Js)
    assert r["max_mm"] <= wc * (1 + 1e-12)


def test_sensitivity_shares_sum_to_one():
    """Variance shares are a partition of the RSS² (sum 1) and the gain is the largest
    |J_k| over the poses."""
    rng = np.random.default_rng(4)
    Js = rng.normal(size=(2, 6, 3))
    t = rng.uniform(0.1, 1.0, 6)
    s = tolerance.sensitivity(t, Js)
    assert s["variance_share"].sum() == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_allclose(s["gain"], np.linalg.norm(Js, axis=2).max(axis=0), rtol=1e-14)


def test_yield_constraint_agrees_with_an_independent_monte_carlo():
    """constraint = "yield": the in-loop yield (10⁴ common random numbers) agrees with an
    independent 10⁵-draw Monte Carlo of the same design within 0.02 (binomial standard
    error of the 10⁴ estimate <= 0.005, so 4σ), and its quantile is <= ΔE exactly when
    the yield reaches the target (definition of the quantile)."""
    from pathlib import Path

    from arfem.models.allocation.problem import evaluate_design, unit_values, with_settings
    from arfem.models.allocation.scenario import build_chain
    from arfem.scenarios.allocation.file import load_allocation_scenario

    sc = load_allocation_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "data"
                                  / "pallet_changer.toml")
    chain, _ = build_chain(sc)
    st = with_settings(sc.settings, constraint="yield", target_yield=0.9, yield_dist="normal")
    lo, hi = chain.bounds()
    X = np.random.default_rng(1).uniform(lo, 0.4 * hi, (6, len(lo)))
    ev = evaluate_design(chain, X, st)
    Jv, _ = chain.sensitivities()
    for c in range(len(X)):
        t = unit_values(chain, X[c:c + 1])[0] * np.tile([1, 1, 1, 1e-3, 1e-3, 1e-3], 4)
        ref = tolerance.monte_carlo(t, Jv, st.delta_E_mm, 100_000, "normal", seed=11)["yield"]
        assert ev.yield_[c] == pytest.approx(ref, abs=0.02)
        assert (ev.stack_mm[c] <= st.delta_E_mm) == (ev.yield_[c] >= 0.9)
