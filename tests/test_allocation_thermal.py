"""The spindle's thermal term in the workpiece-to-tool loop, instant by instant."""
from pathlib import Path

import numpy as np
import pytest

from arfem.models.allocation.problem import evaluate_design, worst_case_over_cycle
from arfem.models.allocation.scenario import build_chain
from arfem.models.allocation.thermal import growth_on_paper_cycle_m, spindle_series
from arfem.params import Rod
from arfem.scenarios.allocation.file import load_allocation_scenario

SCEN = Path(__file__).resolve().parents[1] / "scenarios" / "data"


@pytest.fixture(scope="module")
def loop():
    sc = load_allocation_scenario(SCEN / "hmc_spindle_loop_compensated.toml")
    return sc, build_chain(sc)[0]


def test_compensation_residual_is_measurement_minus_prediction():
    """Compensated: series = FEM + noise − AR prediction. Removing the noise-free
    residual leaves the probe noise: mean ≈ 0 and standard deviation ≈ 0.2 µm (2881
    samples: standard errors 0.004 µm and 1.3 %, so 0.02 µm and 6 % are > 4σ)."""
    t, r, info = spindle_series(Rod(), 2000.0, compensated=True, noise_um=0.2, seed=3)
    _, fem = growth_on_paper_cycle_m(Rod(), 2000.0, "fem", 30.0)
    _, ar = growth_on_paper_cycle_m(Rod(), 2000.0, "ar", 30.0)
    noise_um = (r - (fem - ar) * 1e3) * 1e3
    assert abs(noise_um.mean()) < 0.02 and noise_um.std() == pytest.approx(0.2, rel=0.06)
    assert info["true_residual_um"] == pytest.approx(np.max(np.abs(fem - ar)) * 1e6, rel=1e-12)


def test_growth_is_along_the_horizontal_spindle_axis(loop):
    """The tool moves along the spindle unit's axis (base z, horizontal on an HMC), at
    every pose of the B table; never along the vertical y."""
    _, chain = loop
    np.testing.assert_allclose(chain.thermal.direction, np.tile([0.0, 0.0, 1.0], (4, 1)),
                               atol=1e-12)


def test_constraint_equals_the_check_at_every_instant(loop):
    """The optimiser's constraint uses only the extreme instants (|x + d·a| is convex in
    d); it must equal the maximum of the worst case computed at every one of the 2881
    instants, for random designs (round-off tolerance)."""
    _, chain = loop
    lo, hi = chain.bounds()
    rng = np.random.default_rng(5)
    for _ in range(3):
        X = rng.uniform(lo, hi)[None]
        full = worst_case_over_cycle(chain, X)
        assert len(full) == len(chain.thermal.times_s)
        assert evaluate_design(chain, X, load_allocation_scenario(
            SCEN / "hmc_spindle_loop_compensated.toml").settings).worst_case_mm[0] == \
            pytest.approx(full.max(), rel=1e-10)


def test_thermal_term_combines_as_a_vector(loop):
    """The kinematic worst case and the thermal term add as vectors: the total is at
    least each of them and at most their sum (triangle inequality)."""
    sc, chain = loop
    lo, hi = chain.bounds()
    X = (0.5 * (lo + hi))[None]
    ev = evaluate_design(chain, X, sc.settings)
    d = np.max(np.abs(chain.thermal.growth_mm))
    kin = ev.kinematic_worst_case_mm[0]
    assert max(kin, d) - 1e-12 <= ev.worst_case_mm[0] <= kin + d + 1e-12


def test_workpiece_errors_enter_the_loop_with_the_opposite_sign(loop):
    """A pallet-clamp error that lifts the workpiece by Δy moves the tool by −Δy
    relative to it (base y), at every B angle; an x-column error Δx moves the tool by
    +Δx. The loop is tool minus workpiece (exact: pure translations)."""
    _, chain = loop
    names = chain.component_names()
    Jv, _ = chain.sensitivities()
    np.testing.assert_allclose(Jv[:, names.index("pallet_clamp.dy")], np.tile([0, -1.0, 0], (4, 1)),
                               atol=1e-12)
    np.testing.assert_allclose(Jv[:, names.index("x_column.dx")], np.tile([1.0, 0, 0], (4, 1)),
                               atol=1e-12)
