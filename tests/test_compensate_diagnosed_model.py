"""The diagnosis's extended model exported as a compensator (issue 21, items 1 and 4).

What is verified and why:
* the export is the fitted model: stepping the exported state-space model through the
  record's inputs reproduces the fit's own prediction (``fit_rod_causes``, the forward run
  the diagnosis scored) to 1e-9 of its peak, for every cause with a linear
  time-invariant form and for pairs -- so a compensator runs what the diagnosis scored;
* causes with no such form (speed-dependent or natural convection) are refused with a
  reason, and a sensor drift is left out (and said so): a drifting sensor is not growth;
* on the twin (the FEM rod with a hidden daily ambient swing), ``arfem diagnose`` names
  the ambient, writes ``model_extended.json`` with ``ambient_C`` as an input, and that
  model, replayed on the next two days of the twin (not seen by the fit), leaves at most
  1/3 of the paper AR(1)'s compensated RMS (the issue's target);
* a model without state (the MLR) survives the JSON round trip (``[]`` matrices).
"""
import subprocess
import sys

import numpy as np
import pytest

from arfem.models.compensator import Compensator
from arfem.models.diagnosis.candidates import FemPhysics, fit_rod_causes
from arfem.models.diagnosis.export import fem_state_space
from arfem.models.diagnosis.forward import RodModel
from arfem.params import InputError, Rod
from arfem.scenarios.compensation.model_file import model_from_doc, model_to_doc


@pytest.fixture(scope="module")
def phys():
    return FemPhysics(Rod(), RodModel(Rod(), nr=3, nz=12))


def _record(phys):
    t = np.arange(1, 1441) * 60.0                         # 24 h at 60 s
    q = np.where((t % 21600) < 10800, 2500.0, 0.0)
    amb = 1.5 * np.sin(2 * np.pi * t / 86400.0)
    y = 1.1 * phys.response(t, q, h=70.0, ambient_K=amb) + 0.2 * (1 - np.exp(-t / 18000.0))
    return t, q, amb, y


@pytest.mark.parametrize("causes", [
    ("convection_mismatch",), ("heat_input_scale",), ("ambient_drift",),
    ("frame_expansion",), ("heat_input_scale", "frame_expansion"),
    ("ambient_drift", "convection_mismatch"),
])
def test_export_reproduces_the_fitted_model(phys, causes):
    t, q, amb, y = _record(phys)
    fit = fit_rod_causes(causes, phys, t, q, y, np.ones(t.size, bool), ambient_K=amb)
    m = fem_state_space(fit, phys, 60.0)
    c = Compensator(m)
    pred = np.array([c.step({"q_W_m2": qk, "ambient_C": 20.0 + ak}).predicted_growth_um
                     for qk, ak in zip(q, amb)])
    assert np.max(np.abs(pred - fit.prediction)) <= 1e-9 * np.max(np.abs(fit.prediction))
    assert ("ambient_C" in [i.name for i in m.inputs]) == ("ambient_drift" in causes)


def test_causes_without_a_linear_form_are_refused_and_drift_is_left_out(phys):
    t, q, amb, y = _record(phys)
    rows = np.ones(t.size, bool)
    fit = fit_rod_causes(("speed_dependent_convection",), phys, t, q, y, rows)
    with pytest.raises(InputError, match="not a linear time-invariant model"):
        fem_state_space(fit, phys, 60.0)
    fit = fit_rod_causes(("sensor_drift",), phys, t, q, y, rows)
    m = fem_state_space(fit, phys, 60.0)
    assert "sensor_drift left out" in m.description
    c = Compensator(m)
    pred = [c.step({"q_W_m2": qk}).predicted_growth_um for qk in q]
    assert np.allclose(pred, phys.response(t, q), rtol=0, atol=1e-9 * np.max(y))


def test_mlr_model_survives_the_json_round_trip(tmp_path):
    from arfem.models.compensator import fit_mlr_model
    from arfem.scenarios.compensation.model_file import read_model, write_model
    T = np.linspace(20, 30, 100)
    m = fit_mlr_model(3.0 * (T - 20), {"T_a_C": T, "T_b_C": T ** 0.5}, dtau_s=60.0)
    write_model(tmp_path / "m.json", m)
    back = read_model(tmp_path / "m.json")
    assert back.n_states == 0 and back.B.shape == (0, 2)
    a, b = Compensator(m), Compensator(back)
    for v in (21.0, 25.0):
        u = {"T_a_C": v, "T_b_C": v ** 0.5}
        assert a.step(u).offset_um == b.step(u).offset_um


def test_twin_extended_model_beats_the_paper_ar1_threefold(tmp_path):
    from arfem.models.twin import SpindleTwin, TwinProgram
    from arfem.scenarios.compensation.replay import replay
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.compensation.model_file import read_model
    from arfem.scenarios.live.twin_record import write_record
    tw = SpindleTwin(TwinProgram(seed=3))
    rows = [tw.advance() for _ in range(4 * 1440)]        # four days at 60 s
    write_record(tmp_path / "fit", rows[:2880])            # the first two: diagnosed
    write_record(tmp_path / "new", rows)                   # all: replayed, scored on 48 h+
    r = subprocess.run([sys.executable, "-m", "arfem", "diagnose",
                        str(tmp_path / "fit" / "twin.toml"), "--out", str(tmp_path / "d"),
                        "--no-progress"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "cause = ambient_drift" in r.stdout
    ds = load_dataset(tmp_path / "new" / "twin.toml")
    rms = {f: replay(read_model(tmp_path / "d" / f), ds, score_from_s=48 * 3600.0)
           .summary.rms_after_um for f in ("model.json", "model_extended.json")}
    assert rms["model_extended.json"] <= rms["model.json"] / 3.0, rms


def test_every_kind_of_model_arfem_writes_meets_the_published_schema(tmp_path, phys):
    """docs/model.schema.json is the documented layout: the paper AR(1), the speed AR(1)
    with its map, the extended model with input offsets and a frame, and the stateless
    MLR all validate; a file with an unknown key or a wrong output does not."""
    import json
    from pathlib import Path

    import jsonschema

    from arfem.models.compensator import ar1_model, fit_mlr_model, fit_speed_ar1_model
    from arfem.models.ar1 import ar1_simulate
    schema = json.loads((Path(__file__).parents[1] / "docs" / "model.schema.json").read_text())
    t, q, amb, y = _record(phys)
    ext = fem_state_space(fit_rod_causes(("ambient_drift", "frame_expansion"), phys, t, q, y,
                                     np.ones(t.size, bool), ambient_K=amb), phys, 60.0)
    sp = np.repeat([0.0, 3000.0, 0.0, 6000.0, 0.0], 200)
    g = ar1_simulate(0.99, np.where(sp == 3000, 0.1, np.where(sp == 6000, 0.25, 0.0)))
    T = np.linspace(20, 30, 100)
    models = [ar1_model(0.99, 1e-4, dtau_s=30.0), fit_speed_ar1_model(g, sp, dtau_s=15.0),
              ext, fit_mlr_model(3.0 * (T - 20), {"T_a_C": T}, dtau_s=60.0)]
    for m in models:
        doc = json.loads(json.dumps(model_to_doc(m)))
        jsonschema.validate(doc, schema)
    bad = json.loads(json.dumps(model_to_doc(models[0])))
    for change in ({"colour": 1}, {"output": {"name": "growth_mm", "unit": "mm"}}):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate({**bad, **change}, schema)


@pytest.mark.parametrize("ch", [2, 5])
def test_speed_record_frame_model_export_reproduces_the_fit(ch):
    """FL_THERMAL, the pre-registered split (fit before 28 h): the thermometer frame
    model the diagnosis names, exported, reproduces its prediction over the whole 46 h
    record (fit window and hold-out) to 1e-9 of its peak -- ch2 with unlagged components
    (the D path), ch5 with components lagged 2 h (one state each, initial values from
    the record's first row)."""
    from pathlib import Path

    from arfem.models.diagnosis.engine import diagnose
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.diagnosis.document import document
    from arfem.scenarios.diagnosis.run import compensator_models
    root = Path(__file__).parents[1]
    ds = load_dataset(root / "scenarios" / "data" / "fl_thermal" / f"fl_thermal_ch{ch}.toml")
    d = diagnose(ds, 100800.0, intervals=False)
    # named by the selection rules, but without intervals not established (issue 30):
    # the extended model is still exported, as the best candidate's
    from arfem.models.diagnosis.verdict import named_cause
    assert named_cause(document(d)) == "frame_expansion" and document(d)["cause"] == "none"
    models = compensator_models(ds, 100800.0, d)
    m = models["model_extended.json"]
    assert (m.n_states > 1) == (ch == 5)
    t = ds.time_s[ds.time_s < 100800.0]
    assert m.fit_window_s == (float(t[0]), float(t[-1]))      # what it was fitted on
    assert models["model_mlr.json"].fit_window_s == m.fit_window_s
    cols = {"speed_rpm": ds.speed_rpm, **ds.temperatures}
    c = Compensator(m)
    pred = [c.step({i.name: float(cols[i.name][k]) for i in m.inputs}).predicted_growth_um
            for k in range(1, ds.time_s.size)]
    ref = d.evidence.extended.prediction[1:]
    assert np.max(np.abs(np.array(pred) - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_fit_window_is_checked_when_read():
    """``fit_window_s`` round-trips, and a malformed one is one line naming the key."""
    from arfem.models.compensator import ar1_model
    import dataclasses
    m = dataclasses.replace(ar1_model(0.99, 1e-4, dtau_s=60.0), fit_window_s=(0.0, 3600.0))
    assert model_from_doc(model_to_doc(m)).fit_window_s == (0.0, 3600.0)
    assert "fit_window_s" not in model_to_doc(ar1_model(0.99, 1e-4, dtau_s=60.0))
    for bad in ([3600.0, 0.0], [0.0], "0-3600", [0.0, float("nan")]):
        with pytest.raises(InputError, match="fit_window_s: must be"):
            model_from_doc({**model_to_doc(m), "fit_window_s": bad})
