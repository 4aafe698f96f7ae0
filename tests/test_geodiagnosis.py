"""Diagnosis of a user's mesh model (issue 33) on a coarse spindle unit (48 mm
elements, P1; tests/data/geodiag): the parametric reduced model against the full solve,
hidden causes found on their groups with intervals covering the truth, nothing named
on a clean record, and contract v3's refusals.

Development seeds only (1000-1099); the fresh batch of benchmarks/bench_geodiagnosis.py
uses other seeds and is kept apart.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arfem.fem.thermal3d import InputHistory, solve_body_reduced
from arfem.models.geodiagnosis.engine import diagnose_geometry
from arfem.models.geodiagnosis.fit import make_context
from arfem.models.geodiagnosis.problem import Setting, make_record, trial_for
from arfem.models.geodiagnosis.rom import ScaledBody, group_conduction, rom_error
from arfem.models.geodiagnosis.synth import Hidden, covers, duty_cycle, generate
from arfem.scenarios.diagnosis.mesh_model import load_diagnosis_scenario, plant_of, reduced_model
from arfem.scenarios.records.georecord import write_record

DATA = Path(__file__).parent / "data" / "geodiag"
SCENARIO = DATA / "spindle_coarse.toml"


@pytest.fixture(scope="module")
def setup():
    sc, spec = load_diagnosis_scenario(SCENARIO)
    plant, _ = plant_of(sc)
    model, _ = reduced_model(plant, sc, spec, 8000.0, keep_basis=False)
    return sc, spec, plant, model


def _record(plant, hidden, seed, noise="white", hours=24.0, dt_s=120.0):
    rng = np.random.default_rng(seed)
    t, speed, power, amb = duty_cycle(rng, hours, dt_s, plant.sources)
    y = generate(plant, hidden, t, speed, power, amb, rng, noise)
    cols = plant.columns
    return make_record(f"seed{seed}", t, y, cols, plant.names, plant.kinds, power, speed, amb,
                       plant.reference_C), (t, speed, power, amb, y, cols)


def test_reduced_model_matches_full_solve_at_changed_parameters(setup):
    """The one basis carries a trial far from where it was grown (housing h × 2, the
    front ring's conductivity × 0.3): every sensor within 0.5 % of its largest value
    of the full solve with a basis grown at that operator (the reduced-modal solver's
    own tolerance is 1e-5; 0.5 % is what a diagnosis can afford against ~1 µm noise on
    a ~30 µm response)."""
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [], 1000)
    s = Setting(np.array([2.0, 1.0, 1.0, 1.0]), np.array([0.3, 1.0]))
    ctx = make_context(model, rec)
    tr = trial_for(model, rec, s, ctx.shape)
    S, G = len(model.sources), len(model.convections)
    t = np.concatenate([[0.0], np.cumsum(tr.durations_s)])
    sb = ScaledBody(plant.body, [0.3], [group_conduction(plant.body, "front_bearing")])
    full = solve_body_reduced(sb, InputHistory(t, tr.inputs[:, :S + G], tr.h_W_m2K), plant.G, t,
                         kinds=[int(k == "displacement") for k in plant.kinds]).outputs
    tr0 = type(tr)(tr.durations_s, tr.h_W_m2K, tr.kappa,
                   np.column_stack([tr.inputs[:, :S + G],
                                    np.zeros((t.size - 1, len(model.candidates)))]))
    err = rom_error(model.rb, full, tr0)
    big = [j for j, n in enumerate(plant.names) if n != "tcp_x"]   # tcp_x ~ 0 by symmetry
    assert np.all(err[big] < 5e-3), dict(zip(plant.names, err))


@pytest.mark.parametrize("hidden", [
    Hidden("convection_scale", "housing_outer", 2.0),
    Hidden("contact_conductance", "front_bearing", 0.3),
    Hidden("missing_source", "spindle_bore", 15.0),
    Hidden("source_scale", "motor", 1.5),
    Hidden("warm_start", "", 2.0),
], ids=lambda h: h.kind)
def test_hidden_cause_named_on_its_group_with_interval(setup, hidden):
    """A cause hidden in a full-order record (white noise 0.3 µm, 0.03 K) is
    established, on the right group, and its 95 % interval holds the true value."""
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [hidden], 1001)
    d = diagnose_geometry(model, rec)
    assert d.verdict == "established", (d.text, d.evidence.ranking[:3])
    c = d.evidence.named.causes[0]
    assert (c.kind, c.target) == (hidden.kind, hidden.target), d.text
    key = hidden.parameter
    lo, hi = d.evidence.named.ci95[0][key]
    assert lo <= hidden.value <= hi, (key, d.evidence.named.params[0][key], (lo, hi))


@pytest.mark.parametrize("noise", ["walk", "quantised"])
def test_hidden_cause_under_slow_and_quantised_noise(setup, noise):
    """Noise regime: the housing's h × 2 is named, and named alone, under a random walk
    (0.05 σ per sample on top of the white noise) or a 4 σ quantiser, whether
    established or not (a regime may widen or, quantised, narrow the interval, so the
    interval is not asserted: quantised, h 1.997 [1.995, 2.000] just misses 2.0).

    A robustness check, not the guard of one fix: it passed before the noise model and
    the quantisation floor existed, and with either reverted (the fit back to weighted
    least squares without the fitted walk, or the floor back to none) the cause is
    still named alone (either or both reverted; checked 2026-11-28). No tolerance: the ranking is not close (the
    housing's BIC beats the next single by ~480 under the walk, ~690 quantised). About
    6 s on the coarse unit."""
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [Hidden("convection_scale", "housing_outer", 2.0)], 1002, noise)
    d = diagnose_geometry(model, rec)
    assert d.evidence.named is not None and [c.name for c in d.evidence.named.causes] == [
        "convection_scale:housing_outer"], d.text


@pytest.mark.parametrize("noise", ["white", "quantised"])
def test_clean_record_names_no_cause(setup, noise):
    """Noise regime: a record of the nominal model plus white or 4 σ quantised noise
    establishes no cause (the benchmark's target: 0 causes on clean records). An
    invariant, not the guard of one fix: with the quantisation floor and the fitted
    noise model both reverted the quantised record is still "explained" (checked
    2026-11-28). No tolerance: the best single's F test gives p = 0.33 (quantised) and
    0.003 (white) against the naming level 0.01/19 = 5.3e-4. About 3 s each."""
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [], 1003, noise)
    d = diagnose_geometry(model, rec)
    assert d.verdict != "established", d.text
    assert d.established == ()


def test_clean_record_with_sensor_wander_is_explained(setup):
    """A record of the nominal model plus white noise and a random walk (the synth's
    sensor wander) is "explained": the check that the residual follows a thermometer
    has the walk in both of its hypotheses (likelihood ratio, the walk's strength
    profiled under each). The raw correlation against the bound on N_eff, which holds
    for a white residual only, called this record "not explained" (d_tcp_x_um
    "following" the ambient), as it did 23 of 30 clean records with a walk (seeds
    1010-1039; 5 of 30 after the change, 3 of them by Ljung-Box, the test's own
    false-alarm rate). No tolerance: the verdict is a word, and every thermometer
    test's p is checked against its Bonferroni level inside the engine. About 4 s."""
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [], 1015, "walk")
    d = diagnose_geometry(model, rec)
    assert d.verdict == "explained", d.text
    assert all(c.thermometers_beyond == () for c in d.channels), d.channels


def _write_case(tmp_path, plant, y_scale=1.0, drop=None, extra=None, scenario=None):
    rec, (t, speed, power, amb, y, cols) = _record(plant, [], 1004, hours=12.0, dt_s=300.0)
    for f in ("spindle_coarse.toml", "spindle_coarse.msh"):
        shutil.copy(DATA / f, tmp_path / f)
    columns = {"time_s": t, "speed_rpm": speed, "ambient_C": amb}
    for j, c in enumerate(cols):
        columns[c] = y[:, j] * (y_scale if c.startswith("d_") else 1.0)
    for j, s in enumerate(plant.sources):
        columns[f"P_{s}_W"] = power[:, j]
    for k in drop or ():
        columns.pop(k)
    columns.update(extra or {})
    return write_record(tmp_path / "rec.toml", scenario or "spindle_coarse.toml", columns)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "arfem.scenarios.cli", "diagnose", *args,
                           "--no-progress"], capture_output=True, text=True)


@pytest.mark.parametrize("case, says", [
    (dict(scenario="nowhere.toml"), "not found"),
    (dict(extra={"d_spindle_nose_um": np.zeros(145)}), "names no displacement sensor"),
    (dict(extra={"T_motor_C": np.zeros(145)}), "thermometer column without a temperature"),
    (dict(y_scale=1e-3), "mm declared as µm"),
    (dict(drop=["P_motor_W"]), "own schedule"),
], ids=["missing-scenario", "unknown-sensor", "thermometer-no-point", "mm-as-um",
        "unknown-input"])
def test_contract_v3_refusals(setup, tmp_path, case, says):
    """Bad v3 input: one line naming what is wrong, exit 2, --out not created."""
    sc, spec, plant, model = setup
    toml = _write_case(tmp_path, plant, **case)
    out = tmp_path / "out"
    r = _cli(str(toml), "--out", str(out))
    assert r.returncode == 2, r.stderr
    assert says in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not out.exists()


def test_record_naming_a_rod_scenario_is_one_line(tmp_path):
    """A v3 record whose [model] names a rod scenario is refused naming model.scenario and
    the missing [geometry] table (the rod scenario's own [rod] table was reported as an
    unknown key of a mesh scenario), exit 2, --out not created."""
    shutil.copy(Path(__file__).parents[1] / "scenarios" / "data" / "paper_fig2.toml",
                tmp_path / "rod.toml")
    toml = write_record(tmp_path / "rec.toml", "rod.toml",
                        {"time_s": np.arange(3.0), "d_tcp_z_um": np.zeros(3)})
    out = tmp_path / "out"
    r = _cli(str(toml), "--out", str(out))
    assert r.returncode == 2, r.stderr
    assert "model.scenario" in r.stderr and "no [geometry] table" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not out.exists(), r.stderr


def test_candidate_group_the_mesh_lacks_is_refused(setup, tmp_path):
    """A [diagnosis] group the mesh lacks: one line naming the key, exit 2."""
    sc, spec, plant, model = setup
    toml = _write_case(tmp_path, plant)
    p = tmp_path / "spindle_coarse.toml"
    p.write_text(p.read_text().replace('"housing_outer"]', '"coolant_jacket"]'))
    r = _cli(str(toml), "--out", str(tmp_path / "out"))
    assert r.returncode == 2 and "diagnosis.candidate_groups" in r.stderr, r.stderr
    assert "coolant_jacket" in r.stderr and not (tmp_path / "out").exists()


def test_command_writes_the_report_opening_with_the_verdict(setup, tmp_path):
    """arfem diagnose record.csv on a v3 record: the outputs exist, diagnosis.json is
    contract v3, report.md's first paragraph after the title is the verdict."""
    import json
    sc, spec, plant, model = setup
    toml = _write_case(tmp_path, plant)
    out = tmp_path / "out"
    r = _cli(str(toml.with_suffix(".csv")), "--out", str(out))
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "diagnosis.json").read_text())
    assert s["contract_version"] == 3 and s["verdict"] in (
        "established", "explained", "unconfirmed", "not_explained")
    assert s["cause"] == "none" or s["verdict"] == "established"
    # the record is clean (nominal model + white noise): "explained" (it came out
    # not_explained when the whiteness test kept every 2nd row of a white residual)
    assert s["verdict"] == "explained", s["verdict"]
    md = (out / "report.md").read_text().splitlines()
    assert md[2] == "## Verdict" and md[4].startswith(f"**Verdict: {s['verdict']}.**")
    # the picture's caption claims a named group only for an established cause
    assert ("named group in red" in md[6]) == (s["verdict"] == "established"), md[6]
    # every candidate says why the screen did not name it alone (the pipeline's own
    # reason, Ranked.refused); nothing is named on this clean record, so each has one,
    # and the report's table shows it beside the candidate
    why = {r["cause"]: r["not_named_alone_because"] for r in s["ranking"]}
    assert why and all(why.values()), why
    for c, w in list(why.items())[:12]:
        assert any(ln.startswith(f"| {c} |") and ln.endswith(f"| {w} |") for ln in md), (c, w)
    for f in ("report.html", "geometry_named.png", "channels.png", "series.csv"):
        assert (out / f).stat().st_size > 0


def test_clean_quantised_record_names_no_cause(setup):
    """The first scoring's false positive (fresh seed 50028, now development data): a
    clean record quantised at 4 σ (1.2 µm) got sensor_drift on d_tcp_x_um, a channel
    the model holds near 0, from the quantiser's own bias (up to q/2, ~0.11 µm here).
    With the practical-size floor and the fitted noise, nothing is established."""
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [], 50028, "quantised")      # the benchmark's recipe
    d = diagnose_geometry(model, rec)
    assert d.established == (), d.text


def test_practical_size_floor_of_a_quantised_channel(setup):
    """below_floor: on a channel quantised at 1.2 µm with ~0.2-0.3 µm noise ahead of
    the quantiser, a change of 0.1 µm stays under the quantiser's slow bias (~0.11-0.21
    µm, :func:`quantiser_bias`); 0.4 µm does not (until the fifth pre-registration the
    floor was the half quantum, 0.6 µm, which refused a real rear contact on seed
    90023); on an unquantised channel any change counts (the F test decides there)."""
    from arfem.models.geodiagnosis.engine import below_floor
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [], 1006, "quantised")
    ctx = make_context(model, rec)
    j = 2
    assert abs(ctx.quantum[j] - 1.2) < 0.05, ctx.quantum
    ref = np.zeros_like(rec.data)
    d = ref.copy()
    d[:, j] = 0.1
    rows = np.ones(rec.time_s.size, bool)
    assert below_floor(ctx, d, ref, rows)
    d[:, j] = 0.4
    assert not below_floor(ctx, d, ref, rows)
    rec2, _ = _record(plant, [], 1006, "white")
    ctx2 = make_context(model, rec2)
    d[:, j] = 0.05
    assert not below_floor(ctx2, d, ref, rows)


def test_whitener_is_the_inverse_square_root_of_the_walk_covariance():
    """The Kalman innovations of white plus random-walk noise, on rows with a gap,
    whiten Σ = σ_e² I + σ_w² min(k_i, k_j) exactly (W Σ Wᵀ = I to round-off): every
    GLS fit, test and interval rests on it."""
    from arfem.models.geodiagnosis.noise import LevelNoise, whitener
    idx = np.array([0, 1, 2, 5, 6, 9, 10, 11])
    k = idx + 1
    S = 0.3 ** 2 * np.eye(idx.size) + 0.05 ** 2 * np.minimum.outer(k, k)
    W = whitener(LevelNoise(0.3, 0.05), idx).apply(np.eye(idx.size))
    assert np.allclose(W @ S @ W.T, np.eye(idx.size), atol=1e-10)


def test_random_walk_record_with_a_clear_cause_gets_it(setup):
    """Under white noise plus a random walk (0.05 σ per sample, ~1.3 σ over the day),
    a clear cause (the rear bearing's heat × 0.7) is established on its source with
    an interval holding the truth: the walk is modelled (REML, GLS), not left to widen
    the intervals until they hold 'no effect' (the first scoring: 1/8 under a walk)."""
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [Hidden("source_scale", "rear_bearing", 0.7)], 1005, "walk")
    d = diagnose_geometry(model, rec)
    assert d.verdict == "established", (d.text, d.evidence.ranking[:3])
    assert [c.name for c in d.evidence.named.causes] == ["source_scale:rear_bearing"], d.text
    lo, hi = d.evidence.named.ci95[0]["scale"]
    assert lo <= 0.7 <= hi, (d.evidence.named.params, (lo, hi))


def test_ar1_noise_record_gets_its_cause_and_a_clean_one_none(setup):
    """Under a probe's AR(1) noise (ρ 0.9 per sample, stationary 2σ, on white σ: the
    synth's ``ar1`` kind) the rear bearing's heat × 0.7 is established with an interval
    holding the truth, and a clean record of the same noise gets no cause. With a
    noise model of white plus a random walk only, the walk took the AR(1)'s wander and
    the cause's smooth effect alike: the bearing record was "not explained" with no
    cause (main at 0cc64af, seed 2004; issue 41)."""
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [Hidden("source_scale", "rear_bearing", 0.7)], 2004, "ar1")
    d = diagnose_geometry(model, rec)
    assert d.verdict == "established", d.text
    assert [c.name for c in d.evidence.named.causes] == ["source_scale:rear_bearing"], d.text
    lo, hi = d.evidence.named.ci95[0]["scale"]
    assert lo <= 0.7 <= hi, (d.evidence.named.params, (lo, hi))
    clean, _ = _record(plant, [], 2001, "ar1")
    assert diagnose_geometry(model, clean).causes == ()


def test_clean_walk_record_names_no_drift_on_a_thermometer(setup):
    """The second scoring's false positive (fresh seed 70019, now development data): a
    clean random-walk record (0.05 σ per sample) got sensor_drift on T_housing_C, the
    thermometer's own walk taken for a drift (the thermometers' walk ratio came out 0
    on the largest model). A drift is now evidence only when the channel's own walk,
    its strength profiled, does not explain it as well (likelihood ratio, the naming
    level): nothing is established, no drift is even named, and the walk-vs-drift test
    on T_housing_C is far from the naming level (p ≥ 1e-3 against 0.01/19 = 5.3e-4)."""
    from arfem.models.geodiagnosis.noise import drift_vs_walk_p
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [], 70019, "walk")       # the benchmark's recipe
    d = diagnose_geometry(model, rec)
    assert d.established == (), d.text
    assert d.evidence.named is None or all(c.kind != "sensor_drift" for c in d.evidence.named.causes), d.text
    j = [c.column for c in rec.channels].index("T_housing_C")
    train = rec.time_s < d.holdout.start_s
    idx = np.flatnonzero(train & np.isfinite(rec.data[:, j]))
    y = rec.data[idx, j] - d.evidence.baseline.prediction[idx, j]
    assert drift_vs_walk_p(y, idx, rec.time_s[idx] / 3600.0) >= 1e-3


def test_drift_vs_walk_keeps_a_real_drift_under_a_walk(setup):
    """The walk-vs-drift test does not discard a real drift: the smallest drift the
    benchmark draws (0.1 µm/h on d_tcp_z_um, 1.6 µm over the 16 h fit window) under
    white noise plus a walk of 0.05 σ per sample gives p below the naming level
    (the power the drift check leaves) and the drift is established. Near the edge:
    here p ~ 1e-4 against the level 0.01/(number of candidates) = 0.01/19 = 5.3e-4; a smaller drift
    under this walk is, rightly, not told from the walk."""
    from arfem.models.diagnosis.verdict import ALPHA
    from arfem.models.geodiagnosis.fit import candidate_causes
    from arfem.models.geodiagnosis.noise import drift_vs_walk_p
    sc, spec, plant, model = setup
    rec, _ = _record(plant, [Hidden("sensor_drift", "d_tcp_z_um", 0.1)], 1007, "walk")
    d = diagnose_geometry(model, rec)
    level = ALPHA / len(candidate_causes(make_context(model, rec)))
    j = [c.column for c in rec.channels].index("d_tcp_z_um")
    train = rec.time_s < d.holdout.start_s
    idx = np.flatnonzero(train & np.isfinite(rec.data[:, j]))
    y = rec.data[idx, j] - d.evidence.baseline.prediction[idx, j]
    assert drift_vs_walk_p(y, idx, rec.time_s[idx] / 3600.0) < level
    assert [c.name for c in d.established] == ["sensor_drift:d_tcp_z_um"], d.text


def test_pair_first_cause_revisited_beside_the_second(setup):
    """The third scoring's wrong pair (fresh seed 80017, now development data): a
    weaker front contact (κ 0.22) with a missing source of 16.4 W in the spindle bore
    was named front contact + more heat at the front bearing, the single cause that
    best stood in for the sum and was never revisited. With the first cause
    re-screened beside the second (stepwise selection), the right pair is established
    and its intervals hold the truth.

    Guards the pair search's reach beyond the forward pick: with both ``engine._swap``
    and ``engine._best_pair``'s beam reverted (a forward search from the best single,
    source_scale:front_bearing), front_bearing × 1.36 + contact κ 0.51 is named again,
    "not_explained" (checked 2026-11-28). Either alone now finds the pair (the beam
    screens a partner beside the contact, the second-best single), so reverting one
    of them does not fail it. Tolerance: the 95 % intervals; 16.45 W [16.08, 16.82]
    and κ 0.2174 [0.2137, 0.2212], each truth within 0.2 half-widths of its estimate.
    The benchmark's own draw (24 h at 2 min); about 25 s on the coarse unit."""
    sc, spec, plant, model = setup
    rng = np.random.default_rng(80017)          # the benchmark's draw of its pair
    rng.choice(7, 2, replace=False)
    hidden = [Hidden("contact_conductance", str(rng.choice(model.interfaces)),
                     float(rng.uniform(0.2, 0.5))),
              Hidden("missing_source", str(rng.choice(model.candidates)),
                     float(rng.uniform(8.0, 20.0)))]
    assert [(h.target, round(h.value, 3)) for h in hidden] == [
        ("front_bearing", 0.218), ("spindle_bore", 16.448)]
    t, speed, power, amb = duty_cycle(rng, 24.0, 120.0, plant.sources)
    y = generate(plant, hidden, t, speed, power, amb, rng, "walk")
    cols = plant.columns
    rec = make_record("s80017", t, y, cols, plant.names, plant.kinds, power, speed, amb,
                      plant.reference_C)
    d = diagnose_geometry(model, rec)
    assert sorted(c.name for c in d.established) == [
        "contact_conductance:front_bearing", "missing_source:spindle_bore"], d.text
    assert [covers(d.causes, h) for h in hidden] == [True, True]


def test_quantiser_bias_bounds_the_mean_reading_error():
    """quantiser_bias is the largest slow error of a quantiser's mean reading: by Monte
    Carlo (80 000 noise draws at each of 41 signal levels over one quantum, q = 1.2,
    σ = 0.3 ahead of the quantiser) the largest |mean(Q(x + n)) − x| is within 5 % +
    3 Monte Carlo standard errors (0.46/√80000 ≈ 0.0016 each) of the bound, which is
    tight here (the first harmonic dominates); without noise the bound is q/2."""
    from arfem.models.geodiagnosis.engine import quantiser_bias
    q, sig = 1.2, 0.3
    rng = np.random.default_rng(7)
    n = rng.normal(0.0, sig, 80_000)
    err = [abs(float(np.mean(q * np.round((x + n) / q))) - x)
           for x in np.linspace(0.0, q, 41)]
    b = quantiser_bias(q, sig)
    assert abs(max(err) - b) <= 0.05 * b + 3 * 0.0016, (max(err), b)
    assert quantiser_bias(q, 0.0) == pytest.approx(q / 2)
    assert quantiser_bias(0.0, sig) == 0.0


def test_quantised_contact_at_its_true_size_is_named(setup):
    """The fourth scoring's miss 90023 (now development data): a rear contact κ 0.41
    under 4 σ quantisation, F test p = 7e-62 and the best BIC by 73, was refused by a
    floor of half a quantum (0.6 µm) although the quantiser's slow bias with 0.3 µm
    noise ahead of it is 0.11 µm. With the floor at that bias it is established and its
    interval holds the truth.

    Guards ``engine.quantiser_bias`` as the floor: with the floor put back at q/2 the
    record comes out "not_explained", nothing named (checked 2026-11-28). Tolerance:
    the 95 % interval itself; κ 0.398 [0.370, 0.425], the truth 0.411 half a half-width
    from the estimate. The record is the benchmark's own draw (24 h at 2 min), so
    the regression is the one scored; about 6 s on the coarse unit."""
    sc, spec, plant, model = setup
    rng = np.random.default_rng(90023)           # the benchmark's draw of its cause
    hidden = [Hidden("contact_conductance", str(rng.choice(model.interfaces)),
                     float(rng.uniform(0.2, 0.5)))]
    assert [(h.target, round(h.value, 3)) for h in hidden] == [("rear_bearing", 0.411)]
    rec = _rng_record(plant, hidden, rng, "s90023", "quantised")
    d = diagnose_geometry(model, rec)
    assert [c.name for c in d.established] == ["contact_conductance:rear_bearing"], d.text
    assert covers(d.causes, hidden[0]) is True


def test_pair_out_of_reach_of_the_best_single_is_found(setup):
    """The fourth scoring's miss 90027 (now development data): a front contact κ 0.45
    + a missing source of 16.9 W in the housing, quantised at 4 σ, was named a missing
    source in the spindle bore (the best single) + a column convection (right pair BIC
    28 against 615). With the pair screened beside each passing single of step 3 and
    both causes revisited, the right pair is established, both intervals hold the
    truth.

    Guards ``engine._best_pair``'s beam: with the pair search put back to a forward
    search from the named first (and the swap to its one-sided first version) the
    wrong pair spindle_bore + column_faces is named, "not_explained" (checked
    2026-11-28). The two-sided ``_swap`` alone is not needed here (reverted, the beam
    still finds the pair). Tolerance: the 95 % intervals; 16.85 W [16.76, 16.95] and κ
    0.453 [0.447, 0.459], each truth within 0.15 half-widths of its estimate. The
    benchmark's own draw (24 h at 2 min: a shorter record changes the noise and the
    search's path); about 25 s on the coarse unit."""
    sc, spec, plant, model = setup
    rng = np.random.default_rng(90027)           # the benchmark's draw of its pair
    rng.choice(7, 2, replace=False)
    hidden = [Hidden("contact_conductance", str(rng.choice(model.interfaces)),
                     float(rng.uniform(0.2, 0.5))),
              Hidden("missing_source", str(rng.choice(model.candidates)),
                     float(rng.uniform(8.0, 20.0)))]
    assert [(h.target, round(h.value, 3)) for h in hidden] == [
        ("front_bearing", 0.452), ("housing_outer", 16.862)]
    rec = _rng_record(plant, hidden, rng, "s90027", "quantised")
    d = diagnose_geometry(model, rec)
    assert sorted(c.name for c in d.established) == [
        "contact_conductance:front_bearing", "missing_source:housing_outer"], d.text
    assert [covers(d.causes, h) for h in hidden] == [True, True]


def test_warm_start_under_a_walk_is_judged_on_the_whitened_hold_out(setup):
    """The fifth scoring's miss 100016 (now development data): a warm start of 2.11 K
    under white noise + a random walk, named at 2.11 K [2.10, 2.12], was left
    "unconfirmed" because the raw hold-out RMS rose by 10.8 % (a thermometer's walk
    sets its level there) while the whitened one-step error fell. Judged on the
    whitened hold-out, step 3's own score, it is established; the raw gain is still
    reported as it is, negative.

    Guards the verdict's use of ``gain_whitened_pct``: with the raw gain passed to the
    verdict instead, "unconfirmed" again (checked 2026-11-28). Tolerance: the 95 %
    interval, 2.1145 [2.1045, 2.1244], the truth 2.1104 within half a half-width; the
    gains' signs are the point (-10.8 % raw, +0.5 % whitened). The noise-regime
    regression: it needs the benchmark's own walk draw (24 h at 2 min); about 6 s."""
    sc, spec, plant, model = setup
    rng = np.random.default_rng(100016)          # the benchmark's draw of its cause
    hidden = [Hidden("warm_start", "", float(rng.uniform(1.0, 3.0)))]
    assert round(hidden[0].value, 3) == 2.110
    rec = _rng_record(plant, hidden, rng, "s100016", "walk")
    d = diagnose_geometry(model, rec)
    assert [c.name for c in d.established] == ["warm_start"], d.text
    assert covers(d.causes, hidden[0]) is True
    assert d.holdout.gain_whitened_pct > 0 > d.holdout.gain_pct
    assert "one-step hold-out error" in d.text


def test_partner_failing_the_hold_out_does_not_end_the_pair_search(setup):
    """The fifth scoring's miss 100027 (now development data): a missing source of
    10.2 W in the spindle bore + a warm start of 1.69 K, quantised at 4 σ, was named a
    housing source alone: beside it the lowest-BIC partner (a spindle-bore convection)
    failed the hold-out and the search stopped, the warm start (next by BIC, hold-out
    error 1.35 against 4.88) untried. With the passing partners tried in BIC order the
    right pair is established, both intervals holding the truth.

    Guards ``engine._second``'s loop over the passing partners: with only the
    lowest-BIC partner tried, missing_source:housing_outer is established alone again
    (checked 2026-11-28). Tolerance: the 95 % intervals; 10.22 W [10.16, 10.28] (the
    truth 10.198 0.4 half-widths off) and 1.6874 K [1.6813, 1.6936] (0.2 off). The
    benchmark's own draw (24 h at 2 min); about 20 s on the coarse unit."""
    sc, spec, plant, model = setup
    rng = np.random.default_rng(100027)          # the benchmark's draw of its pair
    rng.choice(7, 2, replace=False)
    hidden = [Hidden("missing_source", str(rng.choice(model.candidates)),
                     float(rng.uniform(8.0, 20.0))),
              Hidden("warm_start", "", float(rng.uniform(1.0, 3.0)))]
    assert [(h.target, round(h.value, 3)) for h in hidden] == [
        ("spindle_bore", 10.198), ("", 1.686)]
    rec = _rng_record(plant, hidden, rng, "s100027", "quantised")
    d = diagnose_geometry(model, rec)
    assert sorted(c.name for c in d.established) == [
        "missing_source:spindle_bore", "warm_start"], d.text
    assert [covers(d.causes, h) for h in hidden] == [True, True]


def test_first_cause_without_evidence_beside_the_second_is_dropped(setup):
    """The second scoring's miss 70015 (now development data): a sensor drift of
    0.13 µm/h on d_tcp_z under a random walk was named beside a shaft convection of
    h × 0.94, the best single, which had stood in for the drift on the thermometers'
    wander (their walk fitted at a tenth of the truth). Tested against the drift alone
    with the walk re-fitted under both models, the convection is dropped; the drift is
    established and its interval holds the truth.

    Guards ``engine._prune`` with ``engine.walk_profiled_p``: with either reverted
    (the prune skipped, or the profiled-walk test always passing) shaft_exposed
    h × 0.94 + the drift is named again, "unconfirmed" (each checked 2026-11-28).
    Tolerance: the 95 % interval; 0.151 µm/h [0.115, 0.188], the truth 0.132 half a
    half-width off. The noise-regime regression: it needs the benchmark's own walk
    draw (24 h at 2 min); about 25 s on the coarse unit."""
    sc, spec, plant, model = setup
    rng = np.random.default_rng(70015)           # the benchmark's draw of its cause
    hidden = [Hidden("sensor_drift", "d_tcp_z_um",
                     float(rng.choice([-1, 1]) * rng.uniform(0.1, 0.3)))]
    assert round(hidden[0].value, 3) == 0.132
    rec = _rng_record(plant, hidden, rng, "s70015", "walk")
    d = diagnose_geometry(model, rec)
    assert [c.name for c in d.established] == ["sensor_drift:d_tcp_z_um"], d.text
    assert covers(d.causes, hidden[0]) is True


def test_named_pair_of_two_nonlinear_causes_is_at_its_joint_optimum(setup):
    """Development seed 70007: a shaft convection h × 0.44 + a rear contact κ 0.27
    under white noise. Two coordinate sweeps stopped at (0.458, 0.311), a weighted SSE
    above the truth's, and both intervals missed the truth; the joint polish reaches
    the optimum, where both hold it.

    Guards ``fit._polish``: with it skipped the same pair is established but both
    intervals miss the truth again (checked 2026-11-28). Tolerance: the 95 %
    intervals; h 0.4439 [0.4360, 0.4519] (the truth 0.44 half a half-width off) and
    κ 0.288 [0.266, 0.310] (the truth 0.270 at 0.82 of the half-width: the closest
    margin of these regressions, deterministic on a seeded record and one BLAS
    thread). The benchmark's own draw (24 h at 2 min); about 25 s on the coarse
    unit."""
    sc, spec, plant, model = setup
    rng = np.random.default_rng(70007)           # the benchmark's draw of its pair
    rng.choice(7, 2, replace=False)
    hidden = [Hidden("convection_scale", str(rng.choice(plant.convections)),
                     float(rng.choice([rng.uniform(0.4, 0.65), rng.uniform(1.6, 2.5)]))),
              Hidden("contact_conductance", str(rng.choice(model.interfaces)),
                     float(rng.uniform(0.2, 0.5)))]
    assert [(h.target, round(h.value, 3)) for h in hidden] == [
        ("shaft_exposed", 0.44), ("rear_bearing", 0.27)]
    rec = _rng_record(plant, hidden, rng, "s70007", "white")
    d = diagnose_geometry(model, rec)
    assert sorted(c.name for c in d.established) == [
        "contact_conductance:rear_bearing", "convection_scale:shaft_exposed"], d.text
    assert [covers(d.causes, h) for h in hidden] == [True, True]


def test_channel_far_from_white_is_not_within_the_noise():
    """A residual with too few effective samples to thin (a thermometer 30 σ off along a
    slow curve, N_eff ~ 2) cannot be tested (NaN), and the verdict's rule counts an
    untestable channel as not within the noise (NaN had been skipped by the mesh
    verdict, so such a channel counted as within the noise; found by an audit; issue
    41: one answer, NaN, for both engines). A white residual still passes."""
    from arfem.models.diagnosis.verdict import channels_white, whiteness_p
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 1.0, 400)
    far = whiteness_p(30.0 * np.sin(np.pi * t) + rng.normal(size=t.size))
    white = whiteness_p(rng.normal(size=t.size))
    assert np.isnan(far) and white > 0.01
    assert not channels_white([white, far]) and channels_white([white, white])
    assert np.isnan(whiteness_p(rng.normal(size=8)))


def _rng_record(plant, hidden, rng, name, noise):
    t, speed, power, amb = duty_cycle(rng, 24.0, 120.0, plant.sources)
    y = generate(plant, hidden, t, speed, power, amb, rng, noise)
    cols = plant.columns
    return make_record(name, t, y, cols, plant.names, plant.kinds, power, speed, amb,
                       plant.reference_C)
