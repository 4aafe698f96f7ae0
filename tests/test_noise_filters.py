"""The memo of unit-noise filters (:class:`arfem.models.geodiagnosis.noise.UnitFilters`)
belongs to its caller, not to the module (the project's style: no hidden global state).

Verified: the noise module keeps no mutable module-level container; two fit contexts
made by :func:`~arfem.models.geodiagnosis.fit.make_context` start with empty memos of
their own and never share an entry; a context derived from one keeps its memo; and every
noise fit and test gives the same bits with a cold memo, a warm one, a memo warmed on
other rows, or none (a filter is a pure function of (λ, φ, rows): equality is exact,
not a tolerance).
"""
import numpy as np
import pytest

from arfem.models.diagnosis.holdout import default_holdout
from arfem.models.diagnosis.speed_plant import speed_plant
from arfem.models.diagnosis.synth_speed import generate_speed
from arfem.models.geodiagnosis import noise
from arfem.models.geodiagnosis.fit import make_context, with_noise
from arfem.models.geodiagnosis.noise import (UnitFilters, columns_vs_walk_p, drift_vs_walk_p,
                                             reml_joint, reml_level_noise, walk_profiled_lr_p)


def test_the_noise_module_keeps_no_mutable_state():
    """No dict, list or set at module level (the memo it had was one): what a call
    returns cannot depend on what ran before it in the process."""
    mutable = {k for k, v in vars(noise).items()
               if not k.startswith("__") and isinstance(v, (dict, list, set, bytearray))}
    assert mutable == set()


def _plant():
    c = generate_speed("sensor_drift", 1)
    return speed_plant("rec", c.time_s, c.growth_um, c.speed_rpm)


def test_two_contexts_own_their_filters_and_a_derived_one_keeps_its_own():
    """Each made context starts empty; the noise fit of one fills its memo only; the
    context ``with_noise`` derives keeps that memo; a second fit on the warm memo makes
    no filter and returns the same noise as the cold fit on the other context."""
    plant = _plant()
    a, b = make_context(plant), make_context(plant)
    assert a.filters is not b.filters and len(a.filters) == len(b.filters) == 0
    rows = plant.time_s < default_holdout(plant.time_s, a.shape)[0]
    fitted_a = with_noise(a, rows)
    n_a = len(a.filters)
    assert n_a > 0 and len(b.filters) == 0
    assert fitted_a.filters is a.filters
    fitted_b = with_noise(b, rows)                        # cold, on its own memo
    assert len(b.filters) == n_a and a.filters is not b.filters
    again = with_noise(a, rows)                           # warm: every filter a hit
    assert len(a.filters) == n_a
    assert fitted_a.noise == fitted_b.noise == again.noise


def _channels(rng, n=400):
    """Three channels of white noise plus a walk and a drift, on rows with gaps."""
    idx = np.sort(rng.choice(n + 40, n, replace=False))
    t = idx / 30.0
    ys = [rng.normal(0, 1.0, n) + np.cumsum(rng.normal(0, 0.1, n)) + 0.2 * t
          for _ in range(3)]
    return idx, t, ys


def _all_tests(idx, t, ys, filters):
    """Every public fit and test of the noise module that uses the filters."""
    one = np.ones((idx.size, 1))
    X = np.column_stack([one, t])
    return (reml_level_noise(ys[0], X, idx, 1e-3, filters),
            reml_joint(ys, [X] * 3, [idx] * 3, [1.0] * 3, ["a", "a", "b"], [1e-3] * 3,
                       filters=filters),
            drift_vs_walk_p(ys[1], idx, t, filters),
            columns_vs_walk_p(ys[2], idx, one, X, filters),
            walk_profiled_lr_p(ys, [y - 0.2 * t for y in ys], [idx] * 3, [1.0] * 3,
                               ["a", "a", "b"], 1, filters))


@pytest.mark.parametrize("seed", [1, 2])
def test_cold_warm_and_foreign_memos_give_the_same_bits(seed):
    """The same results (==) with no memo, a cold one, the same memo warm, and a memo
    warmed on other rows of the same length (a key that forgot the rows would hand
    those rows' filters back)."""
    rng = np.random.default_rng(seed)
    idx, t, ys = _channels(rng)
    other_idx, other_t, other_ys = _channels(rng)
    assert other_idx.size == idx.size and not np.array_equal(other_idx, idx)
    reference = _all_tests(idx, t, ys, None)
    memo = UnitFilters()
    assert _all_tests(idx, t, ys, memo) == reference                 # cold
    n = len(memo)
    assert n > 0
    assert _all_tests(idx, t, ys, memo) == reference and len(memo) == n   # warm
    foreign = UnitFilters()
    _all_tests(other_idx, other_t, other_ys, foreign)
    assert _all_tests(idx, t, ys, foreign) == reference              # warmed elsewhere


def test_the_memo_is_bounded_and_its_filters_read_only():
    """Full at ``max_entries``, it is emptied before the next filter; a filter it hands
    out cannot be written into (every caller shares it)."""
    memo = UnitFilters(max_entries=3)
    idx = np.arange(50)
    W = memo.get(1e-3, 1.0, idx)
    assert memo.get(1e-3, 1.0, idx) is W and len(memo) == 1
    assert not W.K.flags.writeable and not W.F.flags.writeable
    for lam in (1e-2, 1e-1):
        memo.get(lam, 1.0, idx)
    assert len(memo) == 3
    memo.get(1.0, 0.9, idx)
    assert len(memo) == 1 and memo.get(1e-3, 1.0, idx) is not W
