"""The diagnosis engine's internals are typed values, not dicts of string keys (issue 31).

Why: a candidate's fit, the branches' results and the slow-noise covariances were dicts
whose keys (some private, ``_res``, ``_nominal``) were read in other modules; a typo or
a key one branch forgot failed far from its cause. These tests hold the typed values to
what the dicts carried: a fit is frozen and its residual is the one the rules used, the
Jacobian's columns are named, and the public result's typed views read exactly the
document written as diagnosis.json. Exact equality is asserted where the typed value is
the same number read another way (no tolerance is needed or wanted).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from arfem.models.diagnosis import stats as st
from arfem.models.diagnosis.candidates import CandidateFit, FemPhysics, fit_rod_causes
from arfem.models.diagnosis.forward import RodModel
from arfem.params import Rod


@pytest.fixture(scope="module")
def small_fit():
    """A heat-scale fit on a coarse rod (the export doctest's case), with noise."""
    phys = FemPhysics(Rod(), RodModel(Rod(), nr=2, nz=8))
    t = np.arange(1, 601) * 60.0
    q = np.where((t % 36000) < 18000, 2000.0, 0.0)
    y = 1.2 * phys.response(t, q) + np.random.default_rng(5).normal(0.0, 0.05, t.size)
    rows = t < 400 * 60.0
    return fit_rod_causes(("heat_input_scale",), phys, t, q, y, rows, initial_known=False), y, rows


def test_a_fit_is_frozen_and_carries_its_own_residual(small_fit):
    """The rules read a fit's residual on the fit rows (once the private ``_res`` key the
    engine wrote): it is measured minus predicted on exactly those rows, and the fit
    cannot be changed in place."""
    fit, y, rows = small_fit
    assert isinstance(fit, CandidateFit)
    np.testing.assert_array_equal(fit.residual_um, (y - fit.prediction)[rows])
    np.testing.assert_array_equal(fit.fit_rows, rows)
    assert fit.causes == ("heat_input_scale",) and fit.cause == "heat_input_scale"
    with pytest.raises(dataclasses.FrozenInstanceError):
        fit.rss = 0.0


def test_the_jacobian_columns_are_named_by_the_fit_coordinates(small_fit):
    """Every column of the Jacobian has a name (θ, then the linear coefficients, the
    nuisance terms of an unknown initial state among them), and the linear values are
    those the parameters come from."""
    fit, _, rows = small_fit
    j = fit.joint
    assert j.jacobian.shape == (int(rows.sum()), len(j.coordinates))
    assert set(j.coordinates) == set(j.theta) | set(j.linear)
    assert {"_initial_offset_um", "_initial_decay_um"} <= set(j.linear)
    assert fit.parameters["scale"] == j.linear["scale"]
    assert j.refit_with_ambient is None and j.ambient_K is None     # no ambient_drift


def test_slow_noise_covariances_are_named_and_white_noise_gives_no_slow_part():
    """Under white noise no slow part is fitted: ρ and the slow variances are 0 and both
    covariances are the white s² A; a record too short for the long lags gives None."""
    rng = np.random.default_rng(3)
    n = 2000
    J = np.column_stack([np.ones(n), np.linspace(0.0, 1.0, n)])
    e = rng.normal(0.0, 0.1, n)
    r = e - J @ np.linalg.lstsq(J, e, rcond=None)[0]
    out = st.slow_noise_sandwich(J, r)
    assert isinstance(out, st.SlowNoiseCovariances)
    assert out.ar1_rho == 0.0 and out.ar1_slow_var == 0.0 and out.walk_step_var == 0.0
    np.testing.assert_array_equal(out.ar1_cov, out.walk_cov)
    assert out.ar1_cov.shape == (2, 2)
    assert st.slow_noise_sandwich(J[:40], r[:40]) is None


def test_the_public_result_typed_views_read_the_written_document():
    """``DiagnosisResult.causes/holdout/warnings/verdict/arrays`` are the values of
    ``summary`` (diagnosis.json) and ``series`` (series.csv), read typed; the documents
    themselves are what the command writes."""
    import arfem
    from arfem.params import Schedule
    cycle = Schedule([4 * 3600.0] * 6, [2000.0, 0.0] * 3)
    truth = arfem.solve_fem(Rod(convection_W_m2K=80.0), cycle, dtau_s=300.0)
    noise = np.random.default_rng(1).normal(0.0, 0.02, truth.times_s.size)
    import pandas as pd
    df = pd.DataFrame({"time_s": truth.times_s,
                       "q_W_m2": np.r_[0.0, cycle.subdivided(300.0).q_W_m2],
                       "growth_um": truth.growth_um + noise})
    d = arfem.diagnose(df, initial="equilibrium")
    s = d.summary
    assert [c.cause for c in d.causes] == [c["cause"] for c in s["causes"]]
    assert d.causes and d.causes[0].parameters == s["causes"][0]["parameters"]
    assert {k: list(v) for k, v in d.causes[0].ci95.items()} == s["causes"][0]["ci95"]
    h = s["holdout"]
    assert (d.holdout.start_s, d.holdout.how_chosen, d.holdout.gain_pct,
            d.holdout.n_samples) == (h["start_s"], h["how_chosen"], h["gain_pct"],
                                     h["n_samples"])
    g = d.holdout.channel("growth_um")
    assert (g.baseline_rmse, g.extended_rmse) == (h["baseline_rmse_um"], h["extended_rmse_um"])
    assert d.causes[0].no_effect == {"h_W_m2K": 55.0}        # the [rod]'s nominal h
    assert d.warnings == tuple(s["warnings"]) and d.verdict == s["verdict"]
    for k in ("time_s", "growth_um", "baseline_um", "extended_um", "outlier"):
        np.testing.assert_array_equal(getattr(d.arrays, k), d.series[k])
    assert d.arrays.mlr_um is None             # no thermometers recorded
