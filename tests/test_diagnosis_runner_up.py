"""The runner-up of a ``q_W_m2`` diagnosis says why the ONE pipeline did not name it.

Since the rod moved onto the pipeline (issue 41), ``runner_up.why_lost`` still read the
old rod engine's "the one with the least BIC on N_eff among the candidates that pass the
naming test is named" for every cause that passed its F test, also for one the pipeline
refused: on synthetic seed 21 (a heat scale and an h) the runner-up was a frame fitted
at its lower time-constant bound, 2.02 h, refused by :func:`arfem.models.geodiagnosis.fit.implausible`,
and the report said it lost on BIC. Verified here, and why:

* each rule of the pipeline's screen of single causes (step 2's F test, physical fit,
  practical-size floor and random walk; step 3's parsimony, cut at three, BIC window
  and hold-out) writes its own reason, with the numbers it read, into
  :attr:`~arfem.models.geodiagnosis.engine.Ranked.refused`, where the rule is applied
  (one implementation of each rule); the single cause named has none;
* a ``q_W_m2`` record's ``runner_up.why_lost`` is that reason, in the contract's names,
  and never the old sentence when the runner-up did not pass;
* a record whose magnitude is implausible (growth written in mm) gives rule 5's reason.

Short synthetic records (10-12 h; each diagnosis a few seconds at most on the rod plant).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from arfem.models.diagnosis.rod_plant import rod_plant
from arfem.models.diagnosis.stats import f_test_p
from arfem.models.diagnosis.synth import generate
from arfem.models.diagnosis.verdict import naming_level
from arfem.models.geodiagnosis.engine import DELTA_BIC, _refusal, diagnose_plant
from arfem.models.geodiagnosis.fit import (candidate_causes, fit_mesh_causes, make_context,
                                           with_noise)
from arfem.scenarios.records.dataset import load_dataset
from arfem.scenarios.records.synth_files import write_case

SHORT_H = 10.0
OLD = "among the candidates that pass the naming test"


def _plant(tmp_path, cause, seed, **overrides):
    case = generate(cause, seed, **{"duration_h": SHORT_H, **overrides})
    return rod_plant(load_dataset(write_case(case, tmp_path / case.name)))


def _document(tmp_path, cause, seed, **overrides):
    from arfem.scenarios.diagnosis.document import document
    from arfem.scenarios.diagnosis.run import diagnose_file
    case = generate(cause, seed, **{"duration_h": SHORT_H, **overrides})
    return document(diagnose_file(write_case(case, tmp_path / case.name)))


def _ranked(tmp_path, cause, seed):
    d = diagnose_plant(_plant(tmp_path, cause, seed))
    return d, {r.cause: r for r in d.evidence.ranking}


# -- the reason of each rule, where the rule is applied -----------------------------------

@pytest.fixture(scope="module")
def screened(tmp_path_factory):
    """A heat-scale record (scale 0.82, seed 3) as the screen sees it: the context with
    the fitted noise, the nominal fit, and every single cause's row (cause, Fit, BIC,
    F test p, hold-out score) on the fit window (the first 60 %)."""
    plant = _plant(tmp_path_factory.mktemp("rod"), "heat_input_scale", 3)
    ctx = make_context(plant)
    train = plant.time_s < 0.6 * plant.time_s[-1]
    ctx = with_noise(ctx, train)
    base = fit_mesh_causes(ctx, (), train)
    rows = {}
    for c in candidate_causes(ctx):
        f = fit_mesh_causes(ctx, (c,), train, intervals=False)
        rows[c.name] = (c, f, 0.0, f_test_p(base.sse_w, f.sse_w, f.n_params,
                                            float(train.sum())), 1.0)
    return ctx, base, train, rows, naming_level(len(rows))


def test_the_f_test_reason_gives_p_and_the_level(screened):
    """A cause whose F test p is not below the naming level is refused by that test
    first, and says both numbers (p 0.5 here, set; the level 0.01 / 7 causes)."""
    ctx, base, train, rows, level = screened
    row = rows["source_scale:end_flux"]
    why = _refusal(ctx, row[:3] + (0.5,) + row[4:], base, train, level)
    assert why == f"its F test p = 0.5 is not below the naming level {level:.2g}", why
    assert level == pytest.approx(0.01 / 7)


def test_a_fit_at_an_end_of_its_bounds_is_refused_as_not_physical(screened):
    """The frame's time constant at its lower bound (2 h of (2, 200)): refused as not
    physical, the parameter, its value and the bounds in the reason (seed 21's case)."""
    ctx, base, train, rows, level = screened
    c, f = rows["frame_lag"][:2]
    at_edge = replace(f, params=({**f.params[0], "frame_time_constant_h": 2.0},))
    why = _refusal(ctx, (c, at_edge, 0.0, 1e-30, 1.0), base, train, level)
    assert why.startswith("the screen refuses its fit as not physical "
                          "(frame_time_constant_h = 2 at an end of (2.0, 200.0))"), why


def test_an_effect_within_the_quantiser_bias_is_below_the_floor(screened):
    """With the growth channel quantised at 100 µm (noise ~0.1 µm ahead of it, a
    quantiser bias near 50 µm) the heat scale's effect (a few µm) is below the
    resolution; on the record as it is (unquantised) the same row passes."""
    ctx, base, train, rows, level = screened
    row = rows["source_scale:end_flux"]
    assert _refusal(ctx, row, base, train, level) is None
    coarse = replace(ctx, quantum=np.array([100.0]))
    why = _refusal(coarse, row, base, train, level)
    assert why.startswith("its effect is below the instruments' resolution"), why


def test_a_drift_the_sensors_walk_explains_says_so(screened):
    """On this record the heat scale's misfit, seen by the growth sensor alone, is
    explained as well by the channel's random walk as by an offset and a drift: the
    sensor drift is refused for that (its F test passes, p < 1e-100)."""
    ctx, base, train, rows, level = screened
    row = rows["sensor_drift:growth_um"]
    assert row[3] < 1e-100
    why = _refusal(ctx, row, base, train, level)
    assert why.startswith("the sensor's own slow noise (a random walk or an AR(1)) explains "
                          "its channel"), why


def test_the_screen_records_why_each_passing_cause_lost(tmp_path):
    """Step 3's reasons on two short records: on a plain h × 0.55 (seed 13) the natural
    convection nests the plain h and its exponent fails the nested F test, and the
    running-only h, at the same BIC, loses on the whitened hold-out (both scores in the
    reason); on a frame record (seed 5) a passing cause more than ΔBIC 10 behind the
    best says by how much, and a fourth passing cause says only three go on. The named
    single has no reason."""
    d, r = _ranked(tmp_path, "convection_mismatch", 13)
    level = naming_level(len(r))
    assert r["convection_scale:lateral_surface"].refused is None
    nest = r["natural_convection:lateral_surface"].refused
    assert nest.startswith("it nests convection_scale:lateral_surface, which passes too, "
                           "and its extra parameters fail the nested F test"), nest
    p = float(nest.split("p = ")[1].split(",")[0])
    assert p >= level, nest
    run = r["convection_scale:lateral_surface_running"]
    named = r["convection_scale:lateral_surface"]
    assert abs(run.bic - named.bic) <= DELTA_BIC
    assert run.refused == (f"it passes, and its BIC is within 10 of the best, but "
                           f"convection_scale:lateral_surface has the lower whitened "
                           f"hold-out RMS ({named.holdout_whitened_rms:.3g} against "
                           f"{run.holdout_whitened_rms:.3g})"), run.refused
    assert named.holdout_whitened_rms < run.holdout_whitened_rms
    d, r = _ranked(tmp_path, "frame_expansion", 5)
    assert [c.name for c in d.causes] == ["frame_lag"] and r["frame_lag"].refused is None
    h = r["convection_scale:lateral_surface"]
    gap = h.bic - r["frame_lag"].bic
    assert gap > DELTA_BIC
    assert h.refused.startswith(f"it passes, but frame_lag has a BIC lower by {gap:.1f}, "
                                "more than ΔBIC 10"), h.refused
    cut = [x for x in d.evidence.ranking if x.refused and "only the three" in x.refused]
    assert cut and all(x.f_test_p < level for x in cut), cut
    assert all(x.bic > h.bic for x in cut)


# -- the runner-up of a q_W_m2 record reads the pipeline's reason --------------------------

def test_runner_up_refused_at_its_bound_says_so_not_that_it_lost_on_bic(tmp_path):
    """A sensor drift of 0.24 µm/h (seed 4): the best cause not named is the frame, its
    time constant fitted at the upper bound (200 h). Its F test passes (p ~ 1e-211), so
    the old text said it lost on BIC among the passing causes; the pipeline refused it
    as not physical, and the runner-up says that, with the contract's name."""
    s = _document(tmp_path, "sensor_drift", 4)
    assert [c["cause"] for c in s["causes"]] == ["sensor_drift"], s["verdict_detail"]["text"]
    r = s["runner_up"]
    assert r["cause"] == "frame_expansion"
    assert r["why_lost"].startswith("fitted alone, the screen refuses its fit as not "
                                    "physical (frame_time_constant_h = 200 at an end of "
                                    "(2.0, 200.0))"), r["why_lost"]
    assert r["why_lost"].endswith(f"(BIC {r['score']:.1f}, sensor_drift "
                                  f"{s['candidates'][0]['score']:.1f})"), r["why_lost"]
    assert OLD not in r["why_lost"]


def test_runner_up_that_failed_its_f_test_gives_p_on_a_clean_record(tmp_path):
    """A clean record (seed 7): nothing is named, and the runner-up's reason is its F
    test: p and the naming level, in the contract's cause name (no plant name)."""
    s = _document(tmp_path, "none", 7)
    r = s["runner_up"]
    assert r["cause"] == "convection_mismatch", r
    cand = next(c for c in s["candidates"] if c["cause"] == r["cause"])
    assert not cand["significant"]
    assert r["why_lost"].startswith(
        f"fitted alone, its F test p = {cand['p_value']:.2g} is not below the naming "
        f"level {cand['p_threshold']:.2g}"), r["why_lost"]
    assert OLD not in r["why_lost"] and ":" not in r["why_lost"]


def test_runner_up_that_passed_names_the_cause_that_beat_it(tmp_path):
    """A frame record (seed 5): the runner-up passed and lost on BIC by more than ΔBIC,
    the reason in the contract's names (frame_expansion, not the plant's frame_lag)."""
    s = _document(tmp_path, "frame_expansion", 5)
    r = s["runner_up"]
    assert r["why_lost"].startswith("fitted alone, it passes, but frame_expansion has a "
                                    "BIC lower by"), r["why_lost"]
    assert "frame_lag" not in r["why_lost"]


def test_every_candidate_carries_the_screens_reason_and_the_table_shows_it(tmp_path):
    """The same frame record: every single cause in diagnosis.json's candidates says
    why the screen did not name it alone (None for the one it named, the baseline
    without the key), and report.md's candidate table has that column, the named cause
    reading "the screen named it"."""
    from arfem.scenarios.diagnosis.report import _heat_flux_candidates
    s = _document(tmp_path, "frame_expansion", 5)
    why = {c["cause"]: c.get("not_named_alone_because", "absent") for c in s["candidates"]}
    assert why.pop("none") == "absent"
    assert why.pop("frame_expansion") is None, why
    assert why and all(isinstance(v, str) and v for v in why.values()), why
    rows = _heat_flux_candidates(s)
    assert rows[0].endswith("| alone, not named because |"), rows[0]
    named = next(r for r in rows if r.startswith("| frame_expansion |"))
    assert named.endswith("| the screen named it |"), named
    runner = next(r for r in rows if r.startswith(f"| {s['runner_up']['cause']} |"))
    assert "it passes, but frame_expansion has a BIC lower by" in runner, runner


def test_runner_up_of_a_record_in_the_wrong_unit_gives_rule_5s_reason(tmp_path):
    """Growth written in mm (a heat scale record, seed 3): rule 5 refuses every cause,
    and the runner-up says the record's magnitude is implausible, not a naming rule."""
    s = _document(tmp_path, "heat_input_scale", 3, growth_unit_factor=1e-3)
    assert s["causes"] == [] and s["refused"], s["warnings"]
    r = s["runner_up"]
    assert r["why_lost"].startswith("the record's magnitude is implausible (see warnings)"), r
    assert OLD not in r["why_lost"] and "--drift-last" not in r["why_lost"]


def test_runner_up_the_screen_named_alone_lost_in_the_pair_search(tmp_path):
    """A heat scale with an h (seed 32, 12 h): the natural convection is the best single
    cause, named by the screen (its Ranked.refused is None), and the pair search replaced
    it by the true pair; the runner-up says so, not that it failed a naming test or lost
    on BIC among passing causes (its single BIC is the lowest)."""
    s = _document(tmp_path, "heat_input_scale+convection_mismatch", 32, duration_h=12.0)
    assert sorted(c["cause"] for c in s["causes"]) == ["convection_mismatch",
                                                       "heat_input_scale"], s["causes"]
    r = s["runner_up"]
    assert r["cause"] == "nonlinear_convection" and r["score"] == s["candidates"][0]["score"]
    assert r["why_lost"].startswith("alone it is the screen's choice, but the pair search "
                                    "(step 4 of the pipeline"), r["why_lost"]
    assert "ended with convection_mismatch and heat_input_scale" in r["why_lost"]
    assert OLD not in r["why_lost"]
