"""A quantised growth sensor (issue 24, item 4): its one-quantum flickers are the sensor,
not outliers, and its quantisation noise is a floor for every noise scale.

Why these checks: on a real record resolving ~0.255 µm, 12 % of the rows were flagged as
outliers and dropped everywhere, because the Hampel σ was floored at the smallest
non-zero step (a 0.009 µm offset step) instead of the resolution, and the noise σ of the
rules (second differences, 0.035 µm) sat below the quantisation noise (0.074 µm).
"""
import numpy as np
import pytest

from arfem.models.diagnosis.dataset import hampel_outliers
from arfem.models.diagnosis.engine import diagnose
from arfem.models.diagnosis.stats import resolution
from arfem.scenarios.records.dataset import load_dataset
from arfem.scenarios.diagnosis.document import document

QUANTUM = 0.255


#: the real record's sensor zero shifted once by a fraction of a quantum
OFFSET_UM = 0.009


#: the real record's sensor zero shifted once by a fraction of a quantum
OFFSET_UM = 0.009


@pytest.fixture(scope="module")
def quantised(tmp_path_factory):
    """48 h at 60 s: the FEM growth of an 8 h heating, read by a sensor that resolves
    0.255 µm and whose reading rests near a quantisation edge (so it flickers by one
    quantum for single samples, ~7 % of the rows, as the real record did), plus one
    offset step of 0.009 µm of the sensor's zero."""
    from arfem.api import Rod, Schedule, solve_fem
    d = tmp_path_factory.mktemp("q")
    cycle = Schedule([8 * 3600.0, 40 * 3600.0], [2000.0, 0.0])
    truth = solve_fem(Rod(), cycle, dtau_s=60.0)
    rng = np.random.default_rng(7)
    raw = truth.growth_um + (QUANTUM / 2 - 0.03) + rng.normal(0.0, 0.02, truth.times_s.size)
    g = QUANTUM * np.round(raw / QUANTUM)
    g[g.size // 2:] += OFFSET_UM
    q = np.r_[0.0, cycle.subdivided(60.0).q_W_m2]
    lines = ["time_s,q_W_m2,growth_um"] + [f"{t:.0f},{qq:.1f},{gg:.6f}"
                                          for t, qq, gg in zip(truth.times_s, q, g)]
    (d / "q.csv").write_text("\n".join(lines) + "\n")
    (d / "q.toml").write_text('[dataset]\nname = "quantised"\ncsv = "q.csv"\n')
    return load_dataset(d / "q.toml")


def test_resolution_is_estimated_within_one_percent(quantised):
    """The quantum of the generator, recovered from the steps (lattice refinement of the
    median step; 1 % allows for the CSV's decimals)."""
    assert quantised.growth_resolution_um == pytest.approx(QUANTUM, rel=0.01)
    assert any("quantised at" in n for n in quantised.notes)


def test_quantised_record_loses_no_row_to_outlier_flagging(quantised):
    """No row flagged; the old floor (smallest non-zero step) did flag flickers on this
    very record, so the test would fail against the former rule."""
    g = np.asarray(quantised.growth_um)
    assert int(quantised.outliers.sum()) == 0
    steps = np.abs(np.diff(g))
    old_floor = float(steps[steps > 1e-9].min())
    assert old_floor == pytest.approx(OFFSET_UM, abs=1e-6)
    assert hampel_outliers(g, floor=old_floor).sum() > 0.03 * g.size


def test_noise_scale_is_floored_at_quantisation_noise(quantised):
    """Every rule's noise σ is at least resolution/√12 (second differences read 0.03 µm
    here, below the quantisation noise of 0.074 µm). Whether a cause is then named is the
    noise-model question of issue 24's item 2, not checked here."""
    from arfem.models.diagnosis.stats import noise_sigma
    assert noise_sigma(quantised.growth_um) < QUANTUM / np.sqrt(12)     # what was used
    d = diagnose(quantised)
    assert document(d)["selection"]["noise_sigma_um"] >= QUANTUM / np.sqrt(12) * 0.99


def test_unquantised_record_has_no_resolution():
    """Continuous noise: about a fifth of the steps sit near the lattice of the median
    step, far below the 80 % that marks a quantised sensor."""
    rng = np.random.default_rng(3)
    y = np.cumsum(rng.normal(0, 0.05, 5000)) * 0.01 + rng.normal(0, 0.05, 5000)
    assert resolution(y) == 0.0
