"""``model_extended.json`` of a ``speed_rpm`` record diagnosed on the speed plant
(``speed_engine="pipeline"``; :func:`arfem.models.diagnosis.export.speed_plant_state_space`).

Synthetic records only (:func:`arfem.models.diagnosis.synth_speed.generate_speed`, seed 1,
as ``benchmarks/bench_speed_plant.py`` writes them): never FL_THERMAL (pre-registration). What is verified and why:

* the exported model, written and read back, replayed by ``arfem compensate``'s replay
  on the same record with its thermometers smoothed as the diagnosis smooths them, IS
  the diagnosis's extended prediction: to 1e-9 of its peak (measured 3e-13 µm on a
  22 µm peak: the same zero-order-hold recursions in another order; a wrong step
  factor, gain, map point, initial state or offset shows at 1e-3 or more) -- a frame
  on one thermometer, a frame on the leading components of eight, an ambient drift,
  and the nominal model of a clean record;
* on the raw thermometers (what a running compensator reads: the diagnosis's ±6 min
  centred mean needs readings ahead of the cycle), the difference is exactly the
  frame's gain times the smoothing's change of the thermometer;
* a sensor drift is left out, said so in the model's description, and the replay is
  the prediction minus exactly the drift's offset and ramp;
* a running-only rate (speed_dependent_convection) is not exported, with its reason;
  a clean record (nothing named) gets no model_extended.json, as a q_W_m2 record;
* the speed map is the fitted law at the record's speeds (exact) and near it between
  them; a speed above the record's fastest is flagged ``extrapolated:speed_rpm``;
* ``arfem diagnose --speed-engine pipeline`` writes model_extended.json (no "not
  exported yet" note) and ``arfem compensate`` runs it.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from arfem.models.compensator import Compensator
from arfem.models.diagnosis.engine import diagnose
from arfem.models.diagnosis.export import speed_plant_state_space
from arfem.models.diagnosis.synth_speed import generate_speed
from arfem.scenarios.compensation.model_file import read_model, write_model
from arfem.scenarios.compensation.replay import replay
from arfem.scenarios.diagnosis.run import compensator_models
from arfem.scenarios.records.dataset import load_dataset

_CACHE = {}


def _write(directory: Path, case, y) -> Path:
    """The record as a measured dataset (CSV + TOML), as benchmarks/bench_speed_plant.py
    writes it."""
    cols = {"time_s": case.time_s, "speed_rpm": case.speed_rpm, "growth_um": y}
    if case.ambient_K is not None:
        cols["ambient_C"] = 20.0 + case.ambient_K
    cols.update(case.temperatures)
    np.savetxt(directory / "rec.csv", np.column_stack(list(cols.values())), delimiter=",",
               fmt="%.6f", header=",".join(cols), comments="")
    (directory / "rec.toml").write_text('[dataset]\nname = "rec"\ncsv = "rec.csv"\n')
    return directory / "rec.toml"


def diagnosed(tmp_path_factory, cause: str, thermometers: int = 1):
    """(dataset, the plant's diagnosis, the record's TOML) of synth_speed's record of
    ``cause``, seed 1, AR noise (``clean``: the sensor_drift record without its drift,
    as benchmarks/bench_speed_plant.py makes it)."""
    key = (cause, thermometers)
    if key not in _CACHE:
        case = generate_speed("sensor_drift" if cause == "clean" else cause, 1,
                              thermometers=thermometers)
        y = case.growth_um
        if cause == "clean":
            y = y - case.truth["drift_um_per_h"] * case.time_s / 3600.0
        toml = _write(tmp_path_factory.mktemp(f"{cause}{thermometers}"), case, y)
        ds = load_dataset(toml)
        _CACHE[key] = ds, diagnose(ds, case.holdout_start_s, speed_engine="pipeline"), toml
    return _CACHE[key]


def _round_trip(m, tmp_path):
    write_model(tmp_path / "m.json", m)
    return read_model(tmp_path / "m.json")


def _smoothed(ds, plant):
    """The record with its thermometers smoothed as the plant smooths them."""
    return dataclasses.replace(ds, temperatures={k: plant.smoothed_temperature_C(k)
                                                 for k in ds.temperatures})


def _replayed(m, ds) -> np.ndarray:
    return replay(m, ds, score_from_s=0.0).series.axes[0].predicted_um


@pytest.mark.parametrize("cause,thermometers", [("frame_expansion", 1),
                                                ("frame_expansion", 8),
                                                ("ambient_drift", 1)])
def test_exported_model_replays_the_extended_prediction(cause, thermometers,
                                                        tmp_path_factory, tmp_path):
    ds, d, _ = diagnosed(tmp_path_factory, cause, thermometers)
    assert d.causes and d.causes[0].cause == cause
    models = compensator_models(ds, d.holdout.start_s, d)
    assert "not_exported" not in models, models.get("not_exported")
    m = _round_trip(models["model_extended.json"], tmp_path)
    plant, fit = d.evidence.plant_fit
    ref = d.evidence.extended.prediction
    pred = _replayed(m, _smoothed(ds, plant))
    ok = ds.time_s > 0
    assert np.max(np.abs(pred - ref)[ok]) <= 1e-9 * np.max(np.abs(ref))
    if cause == "frame_expansion":
        # the raw thermometers: the frame's D times what the smoothing changed, exactly
        names = [i.name for i in m.inputs]
        raw = _replayed(m, ds)
        dT = np.column_stack([ds.temperatures[n] - plant.smoothed_temperature_C(n) for n in names[1:]])
        assert np.max(np.abs(raw - pred - dT @ m.D[0, 1:])[ok]) <= 1e-9 * np.max(np.abs(ref))
        assert np.max(np.abs(raw - pred)) > 1e-3         # the smoothing is not nothing


def test_a_clean_record_gets_no_extended_model_and_its_nominal_replays(tmp_path_factory,
                                                                      tmp_path):
    ds, d, _ = diagnosed(tmp_path_factory, "clean")
    assert not d.causes
    assert "model_extended.json" not in compensator_models(ds, d.holdout.start_s, d)
    plant, fit = d.evidence.plant_fit
    assert fit.causes == ()
    m = _round_trip(speed_plant_state_space(fit, plant, 120.0), tmp_path)
    ref = d.evidence.extended.prediction
    assert np.max(np.abs(_replayed(m, ds) - ref)) <= 1e-9 * np.max(np.abs(ref))
    assert m.kind == "speed_plant" and [i.name for i in m.inputs] == ["speed_rpm"]


def test_a_sensor_drift_is_left_out_with_its_reason(tmp_path_factory, tmp_path):
    ds, d, _ = diagnosed(tmp_path_factory, "sensor_drift")
    assert [c.cause for c in d.causes] == ["sensor_drift"]
    m = _round_trip(compensator_models(ds, d.holdout.start_s, d)["model_extended.json"],
                    tmp_path)
    assert "sensor_drift left out: a sensor's drift is not growth of the machine" \
        in m.description
    _, fit = d.evidence.plant_fit
    p = fit.params[0]
    ramp = p["offset_um"] + p["drift_um_per_h"] * ds.time_s / 3600.0
    ref = d.evidence.extended.prediction
    assert np.max(np.abs(_replayed(m, ds) - (ref - ramp))) <= 1e-9 * np.max(np.abs(ref))


def test_a_running_only_rate_is_not_exported_and_says_why(tmp_path_factory):
    ds, d, _ = diagnosed(tmp_path_factory, "speed_dependent_convection")
    assert [c.cause for c in d.causes] == ["speed_dependent_convection"]
    models = compensator_models(ds, d.holdout.start_s, d)
    assert "model_extended.json" not in models
    assert any("speed_dependent_convection changes the rod's rate with the speed: not a "
               "linear time-invariant model" in w for w in models["not_exported"])


def test_the_speed_map_is_the_fitted_law_and_flags_a_speed_beyond_it(tmp_path_factory):
    ds, d, _ = diagnosed(tmp_path_factory, "frame_expansion")
    plant, fit = d.evidence.plant_fit
    m = compensator_models(ds, d.holdout.start_s, d)["model_extended.json"]
    x, g = m.input_maps["speed_rpm"]
    n_max, p = float(np.max(ds.speed_rpm)), fit.setting.heat_exponent
    G = g[-1]                                   # the steady growth at n_max [µm]
    for n in np.unique(ds.speed_rpm):           # the record's speeds: exact
        assert m.mapped("speed_rpm", n) == (pytest.approx(G * (n / n_max) ** p,
                                                          rel=1e-12, abs=1e-12), False)
    n = np.linspace(0.0, n_max, 1001)           # between: the law within 2e-4 of G
    err = [m.mapped("speed_rpm", v)[0] - G * (v / n_max) ** p for v in n]
    assert 1.0 < p and np.max(np.abs(err)) <= 2e-4 * abs(G)
    c = Compensator(m)
    cyc = c.step({"speed_rpm": 1.2 * n_max, "T_frame_C": float(ds.temperatures["T_frame_C"][0])})
    assert "extrapolated:speed_rpm" in cyc.alarms and not cyc.held


def test_arfem_diagnose_on_the_plant_writes_a_model_compensate_runs(tmp_path_factory,
                                                                     tmp_path, monkeypatch,
                                                                     capsys):
    from arfem.scenarios.cli import main
    _, _, toml = diagnosed(tmp_path_factory, "frame_expansion")
    out = tmp_path / "diag"
    assert main(["diagnose", str(toml), "--out", str(out), "--no-progress",
                 "--speed-engine", "pipeline"]) == 0
    assert "not exported" not in capsys.readouterr().out
    doc = json.loads((out / "model_extended.json").read_text())
    assert doc["kind"] == "extended:frame_expansion:T_frame_C"
    assert main(["compensate", str(out / "model_extended.json"), str(toml), "--out",
                 str(tmp_path / "comp"), "--score-from", "0"]) == 0
    s = json.loads((tmp_path / "comp" / "summary.json").read_text())
    assert s["axes"][0]["rms_after_um"] < 0.2 * s["axes"][0]["rms_before_um"], s["axes"]


@pytest.mark.parametrize("thermometers,target", [(1, "T_frame_C"), (8, "pc1-3")])
def test_a_lagged_frame_is_one_state_per_component_and_replays_its_fit(thermometers,
                                                                       target):
    """frame_lag (not named on seed 1's records, so fitted directly on the plant): one
    lag state per thermometer or component, initial values from the record's first
    row; the model on the smoothed thermometers is the fit's prediction to 1e-9 of
    its peak (measured 3e-13 / 6e-13 µm)."""
    from arfem.models.diagnosis.speed_plant import speed_plant
    from arfem.models.geodiagnosis.fit import fit_mesh_causes, make_context
    from arfem.models.plant import cause
    case = generate_speed("frame_expansion", 1, thermometers=thermometers)
    pl = speed_plant("r", case.time_s, case.growth_um, case.speed_rpm, case.temperatures)
    f = fit_mesh_causes(make_context(pl), (cause("frame_lag", target),),
                        np.ones(case.time_s.size, bool), intervals=False)
    m = speed_plant_state_space(f, pl, 120.0)
    assert m.n_states == 1 + (3 if target.startswith("pc") else 1)
    cols = ({k: pl.smoothed_temperature_C(k) for k in pl.temperatures}
            | {"speed_rpm": case.speed_rpm})
    c = Compensator(m)
    pred = [c.step({i.name: float(cols[i.name][k]) for i in m.inputs}).predicted_growth_um
            for k in range(case.time_s.size)]
    ref = f.prediction[:, 0]
    assert np.max(np.abs(np.array(pred) - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_the_smoothed_thermometer_the_export_reads_is_public_and_read_only():
    """SpeedPlant.smoothed_temperature_C, what the frame's export starts from: the
    centred mean of the readings within ±THERMOMETER_SMOOTHING_S, NaN where the reading
    is missing (compared exactly: the same function on the same readings), and
    read-only, so that no caller can change what the plant's later fits read."""
    from arfem.models.diagnosis.speed_frame import centred_mean
    from arfem.models.diagnosis.speed_plant import THERMOMETER_SMOOTHING_S, speed_plant
    case = generate_speed("frame_expansion", 1)
    T = np.array(case.temperatures["T_frame_C"], float)
    T[40] = np.nan
    pl = speed_plant("r", case.time_s, case.growth_um, case.speed_rpm, {"T_frame_C": T})
    got = pl.smoothed_temperature_C("T_frame_C")
    ref = centred_mean(case.time_s, T, THERMOMETER_SMOOTHING_S)
    ref[40] = np.nan
    assert np.array_equal(got, ref, equal_nan=True)
    assert np.isnan(got[40]) and np.isfinite(got[39]) and np.isfinite(got[41])
    assert np.max(np.abs(got[1:-1] - T[1:-1])[np.isfinite(T[1:-1])]) > 0.0  # smoothed
    with pytest.raises(ValueError, match="read-only"):
        got[0] = 0.0
    assert np.array_equal(pl.smoothed_temperature_C("T_frame_C"), ref, equal_nan=True)
