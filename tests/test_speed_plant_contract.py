"""The contract fields of a speed diagnosis on the plant path (``speed_engine="pipeline"``,
branch speedswitch), on synth_speed's records (AR(1) noise), each interval's tolerance
being the interval itself:

* the plant's own nonlinear parameter τ (``time_constant_h``, searched in every fit)
  gets a 95 % interval from the pipeline's one covariance (Gauss–Newton on the whitened
  residual, :func:`arfem.models.geodiagnosis.fit.fit_mesh_causes`), with its covariance
  beside a cause's ``h_scale``; on seed 1 of ``speed_dependent_convection`` it holds the
  truth τ = ρcR/(2 h_stopped) (paper eq. 13);
* ``speed_dependent_convection`` then writes ``h_stopped_W_m2K`` with an interval (the
  delta method on τ) and ``h_running_W_m2K`` with one that carries τ's uncertainty and
  its covariance with h_scale; both hold the truth on seed 1; the screen's candidate is
  written in the two h too;
* the contract's rule for it (the two intervals do not overlap,
  :func:`arfem.models.diagnosis.verdict.two_h_failures`) is the one the plant path
  applies: with overlapping intervals the pipeline's "established" becomes
  ``unconfirmed`` and says why;
* a frame writes its contract parameters with their units in the name
  (``frame_gain_um_per_K``) and interval, holding the truth on seed 1, and the verdict
  text shows them (it read "`frame_expansion` ()" before).
"""
from __future__ import annotations

import numpy as np
import pytest

from arfem.models.diagnosis import speed_plant
from arfem.models.diagnosis.engine import (CONTRACT_PARAMETERS,
                                          SPEED_PLANT_CONTRACT_PARAMETERS, diagnose)
from arfem.models.diagnosis.speed_plant import (TIME_CONSTANT, convection_h_W_m2K,
                                                speed_plant as make_speed_plant)
from arfem.models.diagnosis.synth_speed import SPEED_SYNTH_CAUSES, generate_speed
from arfem.models.diagnosis.verdict import two_h_failures
from arfem.models.geodiagnosis.engine import diagnose_plant
from arfem.scenarios.records.dataset import load_dataset

RHO_C_R = 7850.0 * 460.0 * 0.1          # the synth's rod, ρ c R [J/(m²K)]


def _dataset(tmp_path, case):
    cols = {"time_s": case.time_s, "speed_rpm": case.speed_rpm,
            "growth_um": case.growth_um, **case.temperatures}
    np.savetxt(tmp_path / "rec.csv", np.column_stack(list(cols.values())), delimiter=",",
               fmt="%.6f", header=",".join(cols), comments="")
    (tmp_path / "rec.toml").write_text('[dataset]\nname = "rec"\ncsv = "rec.csv"\n')
    return load_dataset(tmp_path / "rec.toml")


def _causes(d):
    doc = d.evidence.document
    return doc.get("causes") or (doc.get("best_candidate") or {}).get("causes", [])


@pytest.fixture(scope="module")
def convection(tmp_path_factory):
    case = generate_speed("speed_dependent_convection", 1)
    return case, _dataset(tmp_path_factory.mktemp("conv"), case)


def test_tau_of_the_named_fit_has_an_interval_holding_the_truth(convection):
    case, _ = convection
    plant = make_speed_plant("rec", case.time_s, case.growth_um, case.speed_rpm)
    ev = diagnose_plant(plant, holdout_start_s=case.holdout_start_s).evidence
    named = ev.named
    tau_truth_h = RHO_C_R / (2.0 * case.truth["h_stopped_W_m2K"]) / 3600.0
    lo, hi = named.nominal_ci95[TIME_CONSTANT.name]
    assert lo < named.nominal[TIME_CONSTANT.name] < hi
    assert lo <= tau_truth_h <= hi, (lo, tau_truth_h, hi)
    # the same matrix as the causes' intervals: its diagonal is their half-widths / 1.96
    cov = named.covariance
    k = ("convection_scale:running", "h_scale")
    s_lo, s_hi = named.ci95[0]["h_scale"]
    assert np.isclose((s_hi - s_lo) / 2.0, 1.959964 * np.sqrt(cov.of(k, k)), rtol=1e-6)
    t = (None, TIME_CONSTANT.name)
    assert np.isclose((hi - lo) / 2.0, 1.959964 * np.sqrt(cov.of(t, t)), rtol=1e-6)
    # a correlation, not a bare number: within [-1, 1]
    assert abs(cov.of(k, t)) <= np.sqrt(cov.of(k, k) * cov.of(t, t))
    # the nominal fit reports τ too; the screens (no intervals) its value alone
    assert TIME_CONSTANT.name in ev.baseline.nominal_ci95
    assert all(TIME_CONSTANT.name in r.nominal for r in ev.ranking)


def test_speed_dependent_convection_writes_both_h_with_intervals_holding_the_truth(
        convection):
    case, ds = convection
    d = diagnose(ds, case.holdout_start_s, speed_engine="pipeline")
    assert d.verdict == "established"
    (c,) = _causes(d)
    assert c["cause"] == "speed_dependent_convection"
    assert set(c["parameters"]) == set(CONTRACT_PARAMETERS["speed_dependent_convection"])
    for k in ("h_running_W_m2K", "h_stopped_W_m2K"):
        lo, hi = c["ci95"][k]
        assert lo < c["parameters"][k] < hi
        assert lo <= case.truth[k] <= hi, (k, lo, case.truth[k], hi)
    assert two_h_failures(c) == []
    cand = {x["cause"]: x for x in d.evidence.document["candidates"]}
    assert set(cand["speed_dependent_convection"]["parameters"]) == {
        "h_running_W_m2K", "h_stopped_W_m2K"}


def test_the_plant_path_applies_the_contracts_two_h_rule(convection, monkeypatch):
    """Intervals that overlap (forced) keep the cause from being established, however
    far the plant's own h_scale interval is from 1."""
    case, ds = convection

    def overlapping(h_scale, tau_h, rho_c_R, *var):
        h = convection_h_W_m2K(h_scale, tau_h, rho_c_R)
        return {k: (0.5 * v, 2.0 * v) for k, v in h.items()}
    monkeypatch.setattr(speed_plant, "convection_h_ci95", overlapping)
    d = diagnose(ds, case.holdout_start_s, speed_engine="pipeline")
    assert d.verdict == "unconfirmed"
    failed = d.evidence.document["verdict_detail"]["failed_checks"]
    assert any("do not overlap" in f for f in failed), failed


def test_two_h_rule_wants_both_intervals_apart():
    e = {"cause": "speed_dependent_convection",
         "ci95": {"h_running_W_m2K": [50.0, 60.0], "h_stopped_W_m2K": [59.0, 70.0]}}
    assert "do not overlap" in two_h_failures(e)[0]
    assert "none was computed" in two_h_failures(
        {"cause": "speed_dependent_convection", "ci95": {"h_running_W_m2K": [1, 2]}})[0]


def test_a_frame_writes_its_gain_per_kelvin_with_its_interval(tmp_path):
    case = generate_speed("frame_expansion", 1)
    # the truth per kelvin of the frame's thermometer (the synth's draws replayed, as
    # benchmarks/bench_speed_plant.py frame_truth_um_per_K)
    cr = np.random.default_rng([1, SPEED_SYNTH_CAUSES.index("frame_expansion")])
    cr.choice([-1.0, 1.0]), cr.uniform(0.3, 0.8), cr.uniform(3.0, 10.0)
    truth = case.truth["frame_gain"] * case.settings["steady_growth_um"] / cr.uniform(2, 6)
    d = diagnose(_dataset(tmp_path, case), case.holdout_start_s, speed_engine="pipeline")
    assert d.verdict == "established"
    doc = d.evidence.document
    (c,) = _causes(d)
    assert c["cause"] == "frame_expansion"
    assert "frame_gain_um_per_K" in c["parameters"]
    lo, hi = c["ci95"]["frame_gain_um_per_K"]
    assert lo <= truth <= hi, (lo, truth, hi)
    assert doc["parameters"] == c["parameters"]
    assert "frame_gain_um_per_K = " in doc["verdict_detail"]["text"]
    assert "`frame_expansion` ()" not in doc["verdict_detail"]["text"]


def test_frame_component_gains_are_contract_parameters_of_the_speed_plant_only():
    """The speed plant's frame names its own parameters; the rod's contract stays."""
    assert {"frame_gain_um_per_K", "frame_time_constant_h", "frame_gain_pc1_um",
            "frame_gain_pc3_um"} <= set(SPEED_PLANT_CONTRACT_PARAMETERS["frame_expansion"])
    assert CONTRACT_PARAMETERS["frame_expansion"] == ("frame_time_constant_h", "frame_gain")
