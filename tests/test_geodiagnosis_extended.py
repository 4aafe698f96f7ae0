"""The extended model of a mesh diagnosis as a compensator (issue 33 item 4):
``arfem diagnose`` on a contract-v3 record writes ``model_extended.json`` (version 2,
the named causes built into the parametric reduced model) and ``model_nominal.json``,
and ``arfem compensate`` replays them per axis.

The record is generated from the coarse spindle unit (tests/data/geodiag) by the
FULL-order model (:mod:`arfem.models.geodiagnosis.synth`) with the housing's h hidden
× 2 (development seed 1010, kept apart from the benchmark's fresh batch).

What is verified and why:

* the diagnosis establishes the cause and writes model_extended.json whose kind names
  it; both files validate against docs/model.schema.json and read back through the
  strict reader (what compensate runs);
* replayed by ``arfem compensate`` on the record and scored on the hold-out (the fit
  never saw it), the extended model's residual RMS on the displacement axes that move
  is at most half the nominal's: the hidden h × 2 changes the TCP's drift by tens of
  percent, which the nominal cannot follow, while the extended model is left with the
  0.3 µm noise and the reduced model's ~1 % error; a cause not built in, or built in
  with the wrong sign or column, leaves a residual near the nominal's or above it;
* the replay figures written in diagnosis.json are those compensate gives (one
  replay, not two procedures);
* the built-in cause is the fitted one: the extended model's A differs from the
  nominal's (h re-assembled), the input columns are unchanged in name;
* a clean record (no hidden cause) writes no model_extended.json and says why, nor
  does an established cause that cannot be built in (a sensor drift alone);
  model_nominal.json is flagged NOMINAL;
* a version-1 model.json is still read and replayed on a contract-v2 record;
* report.html opens with the verdict section: the verdict, the highlighted geometry
  embedded, the compensator's residuals, before the table of contents.
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arfem.models.geodiagnosis.synth import Hidden, duty_cycle, generate
from arfem.scenarios.diagnosis.mesh_model import load_diagnosis_scenario, plant_of
from arfem.scenarios.records.georecord import write_record

DATA = Path(__file__).parent / "data" / "geodiag"
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def plant():
    sc, _ = load_diagnosis_scenario(DATA / "spindle_coarse.toml")
    return plant_of(sc)[0]


def _case(d: Path, plant, hidden, seed: int) -> Path:
    rng = np.random.default_rng(seed)
    t, speed, power, amb = duty_cycle(rng, 24.0, 120.0, plant.sources)
    y = generate(plant, hidden, t, speed, power, amb, rng, "white")
    for f in ("spindle_coarse.toml", "spindle_coarse.msh"):
        shutil.copy(DATA / f, d / f)
    cols = {"time_s": t, "speed_rpm": speed, "ambient_C": amb}
    cols.update({c: y[:, j] for j, c in enumerate(plant.columns)})
    for j, s in enumerate(plant.sources):
        cols[f"P_{s}_W"] = power[:, j]
    return write_record(d / "rec.toml", "spindle_coarse.toml", cols)


def _arfem(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "arfem.scenarios.cli", *args],
                          capture_output=True, text=True)


@pytest.fixture(scope="module")
def hidden_h(tmp_path_factory, plant):
    d = tmp_path_factory.mktemp("ext")
    toml = _case(d, plant, [Hidden("convection_scale", "housing_outer", 2.0)], 1010)
    r = _arfem("diagnose", str(toml), "--out", str(d / "diag"), "--no-progress")
    assert r.returncode == 0, r.stderr
    return d, toml


def _validate(path: Path) -> dict:
    import jsonschema
    doc = json.loads(path.read_text("utf-8"))
    jsonschema.validate(doc, json.loads((ROOT / "docs" / "model.schema.json").read_text()))
    from arfem.scenarios.compensation.model_file import read_model
    read_model(path)
    return doc


def test_extended_model_written_valid_and_replays_below_the_nominal(hidden_h):
    d, toml = hidden_h
    s = json.loads((d / "diag" / "diagnosis.json").read_text("utf-8"))
    assert s["verdict"] == "established", s["verdict_text"]
    em = s["extended_model"]
    assert em["written"] and em["file"] == "model_extended.json", em
    assert em["causes"][0]["cause"] == "convection_scale:housing_outer"
    assert em["causes"][0]["built_in"] and "h of housing_outer" in em["causes"][0]["enters_as"]
    ext = _validate(d / "diag" / "model_extended.json")
    nom = _validate(d / "diag" / "model_nominal.json")
    assert ext["model_version"] == 2 and ext["kind"] == "extended:convection_scale:housing_outer"
    assert nom["kind"] == "fem_reduced_nominal" and nom["description"].startswith("NOMINAL")
    assert [i["name"] for i in ext["inputs"]] == [i["name"] for i in nom["inputs"]]
    assert not np.allclose(ext["A"], nom["A"])                    # h re-assembled
    assert "convection_scale:housing_outer: h_scale" in ext["description"]
    start = str(s["holdout"]["start_s"])
    res = {}
    for name in ("model_nominal.json", "model_extended.json"):
        out = d / name.replace(".json", "_replay")
        r = _arfem("compensate", str(d / "diag" / name), str(toml), "--out", str(out),
                   "--score-from", start)
        assert r.returncode == 0, r.stderr
        res[name] = {a["axis"]: a for a in
                     json.loads((out / "summary.json").read_text("utf-8"))["axes"]}
    rep = em["replay"]
    moving = [ax for ax, a in res["model_nominal.json"].items() if a["rms_before_um"] > 2.0]
    assert moving, res
    for ax in moving:
        n_after = res["model_nominal.json"][ax]["rms_after_um"]
        e_after = res["model_extended.json"][ax]["rms_after_um"]
        assert e_after <= 0.5 * n_after, (ax, e_after, n_after)
        assert rep[ax]["nominal_rms_after_um"] == pytest.approx(n_after, rel=1e-9)
        assert rep[ax]["extended_rms_after_um"] == pytest.approx(e_after, rel=1e-9)


def test_clean_record_writes_no_extended_model(tmp_path, plant):
    toml = _case(tmp_path, plant, [], 1011)
    r = _arfem("diagnose", str(toml), "--out", str(tmp_path / "diag"), "--no-progress")
    assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "diag" / "diagnosis.json").read_text("utf-8"))
    assert s["verdict"] != "established", s["verdict_text"]
    assert not (tmp_path / "diag" / "model_extended.json").exists()
    em = s["extended_model"]
    assert not em["written"] and "no cause established" in em["why_not"], em
    doc = _validate(tmp_path / "diag" / "model_nominal.json")
    assert doc["kind"] == "fem_reduced_nominal"


def test_version_1_model_still_reads_and_replays(tmp_path):
    """A version-1 model.json (one growth output) on a contract-v2 record: read and
    replayed as before (the record's own growth is the paper's AR(1) of the model, so
    the residual is its rounding)."""
    from arfem.models.compensator import ar1_model
    from arfem.scenarios.compensation.model_file import read_model, write_model
    m = ar1_model(0.99, 1e-3, dtau_s=60.0)
    write_model(tmp_path / "m.json", m)
    assert read_model(tmp_path / "m.json").outputs == ()
    t = np.arange(0.0, 6000.0, 60.0)
    q = np.where(t < 3000.0, 2000.0, 0.0)
    g = np.zeros_like(t)
    for k in range(1, t.size):
        g[k] = 0.99 * g[k - 1] + 1e-3 * q[k]
    (tmp_path / "r.csv").write_text("time_s,growth_um,q_W_m2\n" + "".join(
        f"{float(a)!r},{float(b)!r},{float(c)!r}\n" for a, b, c in zip(t, -g, q)))
    (tmp_path / "r.toml").write_text('[dataset]\nname = "v1"\ncsv = "r.csv"\n\n'
                                     '[rod]\nconvection_W_m2K = 10.0\n')
    r = _arfem("compensate", str(tmp_path / "m.json"), str(tmp_path / "r.toml"), "--out",
               str(tmp_path / "o"))
    assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "o" / "summary.json").read_text("utf-8"))
    assert s["rms_before_um"] > 1.0


CAUSES = {
    "convection_scale": ([("convection_scale", "housing_outer")], {"h_scale": 2.0}),
    "contact_conductance": ([("contact_conductance", "front_bearing")],
                            {"conductivity_scale": 0.3}),
    "source_scale": ([("source_scale", "motor")], {"scale": 1.5}),
    "missing_source": ([("missing_source", "spindle_bore")], {"power_W": 15.0}),
    "ambient_lag": ([("ambient_lag", "")], {"lag_h": 3.0}),
    "warm_start": ([("warm_start", "")], {"initial_offset_K": 2.0}),
}


@pytest.mark.parametrize("which", list(CAUSES) + ["pair"])
def test_exported_model_is_the_reduced_model_with_the_cause(plant, which):
    """For every cause that can be built in (and a pair: the housing's h with an
    ambient lag), the exported model stepped by the compensator gives the parametric
    reduced model's own prediction of the fit (:func:`arfem.models.geodiagnosis.fit`'s
    ``_predict``, the curve the diagnosis scores) at every displacement channel to 1e-8
    of its range: both are the exact zero-order-hold solution of the same reduced
    model at the record's four speeds, so only round-off separates them; a cause built
    in on the wrong column, with the wrong tie or lag, or a state started wrong misses
    by 1e-3 or more."""
    from arfem.models.compensator import Compensator
    from arfem.models.geodiagnosis.extended import export_reduced, reads_speed
    from arfem.models.geodiagnosis.fit import Cause, Fit, _predict, _setting, make_context
    from arfem.models.geodiagnosis.problem import make_record
    from arfem.scenarios.diagnosis.mesh_model import reduced_model
    sc, spec = load_diagnosis_scenario(DATA / "spindle_coarse.toml")
    model, _ = reduced_model(plant, sc, spec, 8000.0)
    rng = np.random.default_rng(1012)
    t, speed, power, amb = duty_cycle(rng, 12.0, 120.0, plant.sources)
    cols = plant.columns
    rec = make_record("r", t, np.zeros((t.size, len(cols))), cols, plant.names, plant.kinds,
                      power, speed, amb, plant.reference_C)
    if which == "pair":
        pairs = CAUSES["convection_scale"][0] + CAUSES["ambient_lag"][0]
        params = [CAUSES["convection_scale"][1], CAUSES["ambient_lag"][1]]
    else:
        pairs, params = CAUSES[which][0], [CAUSES[which][1]]
    causes = tuple(Cause(k, g) for k, g in pairs)
    nl = {c.name: p[c.nonlinear] for c, p in zip(causes, params) if c.nonlinear}
    beta = [v - (1.0 if k == "scale" else 0.0) for c, p in zip(causes, params)
            for k, v in p.items() if k != c.nonlinear]
    ctx = make_context(model, rec)
    ref = _predict(ctx, causes, nl, beta)
    fit = Fit(causes, tuple(params), tuple({} for _ in causes), ref, 0.0, 0,
              _setting(ctx, causes, nl))
    disp = [(c.output, c.column, c.sensor) for c in rec.channels if c.kind == "displacement"]
    ins = [(f"P_{s}_W", "W") for s in plant.sources] + [("ambient_C", "°C")]
    ins += [("speed_rpm", "1/min")] if reads_speed(model, rec, fit) else []
    ex = export_reduced(model, rec, fit, dtau_s=120.0, outputs=disp, inputs=ins,
                        kind="extended:test", description="test")
    assert ex.model is not None, ex.note
    assert all(built for _, _, built in ex.entered)
    comp = Compensator(ex.model)
    feed = {f"P_{s}_W": power[:, j] for j, s in enumerate(plant.sources)}
    feed.update(ambient_C=amb, speed_rpm=speed)
    out = np.zeros((t.size, len(disp)))
    for k in range(1, t.size):
        cyc = comp.step({i.name: float(feed[i.name][k]) for i in ex.model.inputs})
        out[k] = [a.predicted_um for a in cyc.axes]
    for j, (_, col, _) in enumerate(disp):
        y = ref[:, [c.column for c in rec.channels].index(col)]
        err = np.max(np.abs(out[1:, j] - y[1:])) / max(np.ptp(y), 1e-9)
        assert err < 1e-8, (col, err)


def test_report_opens_with_the_verdict_on_the_highlighted_geometry(hidden_h):
    """report.html shows the verdict first (before its table of contents), with the
    geometry picture embedded in that section and the compensator's residuals in the
    same place: a reader meets the answer, the named group and the gain first."""
    d, _ = hidden_h
    html = (d / "diag" / "report.html").read_text("utf-8")
    i = html.index('<section class="verdict"')
    j = html.index("</section>", i)
    verdict = html[i:j]
    assert i < html.index("<ul")                       # before the table of contents
    assert "Verdict: established" in verdict and "convection_scale:housing_outer" in verdict
    assert 'src="data:image/png;base64,' in verdict    # the picture, embedded
    assert "nominal → extended model" in verdict
    md = (d / "diag" / "report.md").read_text("utf-8")
    assert "## The extended model as a compensator" in md


def test_a_cause_that_cannot_be_built_in_writes_no_extended_model(plant):
    """An established sensor drift is an error of the measurement: nothing enters the
    machine's model, so no model_extended.json (it would be the nominal under another
    name) and the statement says why; a pair with one buildable cause is written and
    marks the other as not built in."""
    from types import SimpleNamespace as N

    from arfem.models.diagnosis.result import Diagnosis, Holdout
    from arfem.models.geodiagnosis.engine import MeshEvidence, named_causes
    from arfem.models.geodiagnosis.fit import Cause, Fit, make_context, _setting
    from arfem.models.geodiagnosis.problem import make_record
    from arfem.scenarios.diagnosis.mesh_export import diagnosis_models
    from arfem.scenarios.diagnosis.mesh_model import reduced_model
    sc, spec = load_diagnosis_scenario(DATA / "spindle_coarse.toml")
    model, _ = reduced_model(plant, sc, spec, 8000.0)
    rng = np.random.default_rng(1013)
    t, speed, power, amb = duty_cycle(rng, 6.0, 120.0, plant.sources)
    cols = plant.columns
    rec = make_record("r", t, np.zeros((t.size, len(cols))), cols, plant.names, plant.kinds,
                      power, speed, amb, plant.reference_C)
    ctx = make_context(model, rec)
    files = N(toml=Path("r.toml"), scenario=Path("spindle_coarse.toml"))
    have = {f"P_{s}_W" for s in plant.sources}
    drift = Cause("sensor_drift", "d_tcp_z_um")
    for causes, params, written in (
            ((drift,), ({"offset_um": 1.0, "drift_um_per_h": 0.1},), False),
            ((Cause("source_scale", "motor"), drift),
             ({"scale": 1.5}, {"offset_um": 1.0, "drift_um_per_h": 0.1}), True)):
        fit = Fit(causes, params, tuple({k: (v, v) for k, v in p.items()} for p in params),
                  np.zeros((t.size, len(cols))), 0.0, 0, _setting(ctx, causes, {}))
        d = Diagnosis("r", "mesh", "established", "", named_causes(fit), None, (), (), (),
                      Holdout(float(t[-100]), "", 0, 0.0, None, ()), (), (), False, False,
                      {}, MeshEvidence(fit, fit, (), {}, {}))
        m = diagnosis_models(d, model, rec, sc, files, have)
        st = m.statement
        assert m.nominal is not None and (m.extended is not None) == written, st
        assert st["written"] == written
        by = {c["cause"]: c for c in st["causes"]}
        assert not by[drift.name]["built_in"] and "measurement" in by[drift.name]["enters_as"]
        if not written:
            assert "model_nominal.json" in st["why_not"] and "sensor_drift" in st["why_not"]
