"""The compensator (issue 21, core part): one causal cycle, its safety rules, the
``model.json`` contract, and the replay on a record.

What is verified and why:
* clamps, rate limit and the hold on a missing/non-finite/stale input: the rules a
  controller relies on so that a bad reading never moves the axis;
* the probe update follows the Kalman gain (no noise in the state: no correction);
* ``model.json`` round-trips and is refused, in one line with exit status 2, when its
  version, shape or inputs do not fit the record;
* the replay is causal: cutting the record after row k leaves the offsets up to k
  unchanged; and it compensates: on a record whose truth is the paper's rod, the paper
  AR(1) removes >= 90 % of the RMS error (it tracks the FEM within ~3 % of the peak).
"""
import json
import subprocess
import sys

import numpy as np
import pytest

from arfem.models.compensator import Compensator, ar1_model
from arfem.params import InputError
from arfem.scenarios.compensation.model_file import model_from_doc, model_to_doc

M = ar1_model(0.99, 1e-3, dtau_s=60.0)


def test_clamp_and_rate_limit():
    c = Compensator(M, max_offset_um=1.5, max_step_um=0.4)
    offs = [c.step({"q_W_m2": 1000.0}) for _ in range(200)]
    assert all(abs(o.offset_um) <= 1.5 + 1e-12 for o in offs)
    assert all(abs(b.offset_um - a.offset_um) <= 0.4 + 1e-12 for a, b in zip(offs, offs[1:]))
    assert any("clamped" in o.alarms for o in offs)
    assert any("rate_limited" in o.alarms for o in offs)


@pytest.mark.parametrize("bad, alarm", [({"q_W_m2": None}, "missing:q_W_m2"),
                                        ({"q_W_m2": float("nan")}, "nonfinite:q_W_m2"),
                                        ({}, "missing:q_W_m2")])
def test_bad_input_holds_the_offset_and_keeps_time(bad, alarm):
    c = Compensator(M)
    ref = Compensator(M)
    for _ in range(10):
        c.step({"q_W_m2": 500.0})
        ref.step({"q_W_m2": 500.0})
    held = c.step(bad)
    assert held.held and alarm in held.alarms and held.offset_um == c.offset_um
    ref.step({"q_W_m2": 500.0})          # the state advanced with the last good input
    assert c.x == pytest.approx(ref.x, rel=1e-15)


def test_stale_alarm_from_the_transport_holds():
    c = Compensator(M)
    c.step({"q_W_m2": 500.0})
    cyc = c.step({"q_W_m2": 500.0}, alarms=("stale:q_W_m2",))
    assert cyc.held and "stale:q_W_m2" in cyc.alarms


def test_probe_follows_the_kalman_gain():
    noisy = model_from_doc({**model_to_doc(M), "noise": {"Q_um2": 0.01, "R_um2": 1e-6}})
    c = Compensator(noisy)
    for _ in range(50):
        c.step({"q_W_m2": 100.0})
    gain = c.probe(5.0)
    assert gain == pytest.approx(1.0, abs=1e-3) and c.x[0] == pytest.approx(5.0, abs=0.01)
    quiet = Compensator(M)                       # Q = 0: the model is trusted entirely
    quiet.step({"q_W_m2": 100.0})
    x = quiet.x.copy()
    assert quiet.probe(5.0) == 0.0 and np.array_equal(quiet.x, x)


def test_model_json_refusals():
    d = model_to_doc(M)
    with pytest.raises(InputError, match="model_version"):
        model_from_doc({**d, "model_version": 2})
    with pytest.raises(InputError, match="B: has shape"):
        model_from_doc({**d, "B": [[1.0, 2.0]]})
    with pytest.raises(InputError, match="unit circle"):
        model_from_doc({**d, "A": [[1.01]]})
    with pytest.raises(InputError, match="unknown key 'gain'"):
        model_from_doc({**d, "gain": 1})
    with pytest.raises(InputError, match="max_step_um"):
        Compensator(M, max_step_um=0.0)


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    from arfem.models.diagnosis.synth import generate
    from arfem.scenarios.records.synth_files import write_case
    d = tmp_path_factory.mktemp("comp")
    case = generate("none", 21, duration_h=24, interval_s=60, jitter_s=0.0, n_gaps=0,
                    empty_fraction=0.0, n_outliers=0, noise_um=0.02)
    rec = write_case(case, d / "rec")
    (d / "sc.toml").write_text('[scenario]\nname = "m"\n[ar]\ndtau_s = 60.0\n'
                               '[cycle]\nphases = [{duration_h = 4.0, q_W_m2 = 2000.0}]\n')
    r = subprocess.run([sys.executable, "-m", "arfem", "run", str(d / "sc.toml"), "--out",
                        str(d / "run"), "--no-progress"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return d, rec


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "arfem", "compensate", *map(str, args)],
                          capture_output=True, text=True)


def test_replay_compensates_and_writes_every_output(workspace):
    d, rec = workspace
    r = _cli(d / "run" / "model.json", rec, "--out", d / "out")
    assert r.returncode == 0, r.stderr
    s = json.loads((d / "out" / "summary.json").read_text())
    assert s["compensation_rate_rms_pct"] >= 90.0, s
    for f in ("compensated.csv", "summary.md", "figure.png", "report.html"):
        assert (d / "out" / f).is_file()
    assert (d / "out" / "summary.md").read_text().splitlines()[2] == "## Verdict"


def test_replay_is_causal(workspace):
    """Offsets up to row k do not depend on rows after k."""
    from arfem.scenarios.compensation.replay import replay
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.compensation.model_file import read_model
    import dataclasses
    d, rec = workspace
    model, ds = read_model(d / "run" / "model.json"), load_dataset(rec)
    full = replay(model, ds).series.offset_um
    k = ds.n_rows // 2
    cut = dataclasses.replace(ds, time_s=ds.time_s[:k], growth_um=ds.growth_um[:k],
                              q_W_m2=ds.q_W_m2[:k])
    part = replay(model, cut).series.offset_um
    assert np.array_equal(part, full[:k])


def test_bad_model_or_mismatch_is_one_line_exit_2(workspace, tmp_path):
    d, rec = workspace
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**json.loads((d / "run" / "model.json").read_text()),
                               "dtau_s": 30.0}))
    r = _cli(bad, rec, "--out", tmp_path / "o1")
    assert r.returncode == 2 and "sampled every 60 s" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "o1").exists()
    speed = {**json.loads((d / "run" / "model.json").read_text()),
             "inputs": [{"name": "speed_rpm", "unit": "1/min"}]}
    bad.write_text(json.dumps(speed))
    r = _cli(bad, rec, "--out", tmp_path / "o2")
    assert r.returncode == 2 and "reads speed_rpm" in r.stderr
    bad.write_text("{not json")
    r = _cli(bad, rec, "--out", tmp_path / "o3")
    assert r.returncode == 2 and "is not JSON" in r.stderr
    r = _cli(d / "run" / "model.json", rec, "--out", tmp_path / "o4", "--probe-every", "soon")
    assert r.returncode == 2 and "--probe-every" in r.stderr


def test_speed_fit_that_would_not_settle_is_refused():
    """FL_THERMAL ch5 fitted by eq. 17 gives C1 = 1.0007: such a model would run away
    (its replay reached 4000 µm), so it is not exported as a compensator."""
    from arfem.models.compensator import fit_speed_ar1_model
    g = np.cumsum(np.full(400, 0.01))                    # a ramp: C1 fits at/above 1
    sp = np.repeat([0.0, 1000.0], 200)[1:]
    with pytest.raises(InputError, match="would not settle"):
        fit_speed_ar1_model(g[:400], np.r_[sp, 1000.0][:399], dtau_s=15.0)


def test_speed_model_maps_and_flags_extrapolation():
    """The speed → C2 map interpolates between fitted levels and flags a speed beyond
    them (informative: the offset is not held)."""
    m = model_from_doc({**model_to_doc(M), "inputs": [{"name": "speed_rpm",
                                                              "unit": "1/min"}],
                                   "B": [[1.0]], "input_maps": {"speed_rpm": {
                                       "x": [0.0, 1000.0], "y": [0.0, 0.2]}}})
    c = Compensator(m)
    mid = c.step({"speed_rpm": 500.0})
    assert mid.predicted_growth_um == pytest.approx(0.1) and not mid.alarms
    far = c.step({"speed_rpm": 2000.0})
    assert "extrapolated:speed_rpm" in far.alarms and not far.held


def _with_fit_window(src, dst, window):
    doc = json.loads(src.read_text())
    doc["fit_window_s"] = list(window)
    dst.write_text(json.dumps(doc))
    return dst


def test_replay_scores_after_the_fit_window_by_default(workspace):
    """Issue 30 item 3: a model that carries ``fit_window_s`` is scored, by default, on
    the rows after it only (an out-of-sample figure), and the headline of summary.md and
    the terminal line say which hours were scored; ``--score-from 0`` still scores every
    row and says that the fitted rows are in it. Exact row counts: the record is sampled
    every 60 s from t = 0, so nothing here needs a tolerance."""
    from arfem.scenarios.records.dataset import load_dataset
    d, rec = workspace
    t = np.asarray(load_dataset(rec).time_s, float)
    model = _with_fit_window(d / "run" / "model.json", d / "fitted.json", (0.0, 12 * 3600.0))
    r = _cli(model, rec, "--out", d / "after")
    assert r.returncode == 0, r.stderr
    s = json.loads((d / "after" / "summary.json").read_text())
    assert s["score_basis"] == "after_fit_window"
    assert s["score_from_s"] == float(t[t > 12 * 3600.0][0])
    assert s["n_scored"] == int(np.sum(t > 12 * 3600.0))
    assert s["fit_window_s"] == [0.0, 12 * 3600.0]
    span = f"scored on {s['score_from_s'] / 3600:.1f}–{t[-1] / 3600:.1f} h, the part not fitted"
    assert span in (d / "after" / "summary.md").read_text()
    assert span in r.stdout

    r = _cli(model, rec, "--out", d / "all", "--score-from", "0")
    assert r.returncode == 0, r.stderr
    s0 = json.loads((d / "all" / "summary.json").read_text())
    assert s0["score_basis"] == "given" and s0["score_from_s"] == 0.0
    assert s0["n_scored"] == int(np.sum(t > 0.0))        # a first row at t = 0 is no interval
    assert "includes rows the model was fitted on" in (d / "all" / "summary.md").read_text()
    # the same replay, only scored on more rows: the offsets are the same
    a = np.loadtxt(d / "after" / "compensated.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(d / "all" / "compensated.csv", delimiter=",", skiprows=1)
    assert np.array_equal(a, b, equal_nan=True)


def test_replay_of_a_model_without_fit_window_scores_every_row_and_says_so(workspace):
    """The paper's AR(1) from the rod's values (arfem run's model.json) was fitted on
    nothing: the default scores from t = 0, and the headline says why."""
    d, rec = workspace
    assert "fit_window_s" not in json.loads((d / "run" / "model.json").read_text())
    r = _cli(d / "run" / "model.json", rec, "--out", d / "nowindow")
    assert r.returncode == 0, r.stderr
    s = json.loads((d / "nowindow" / "summary.json").read_text())
    assert s["score_basis"] == "no_fit_window" and s["score_from_s"] == 0.0
    assert "fit_window_s" not in s
    assert "the model carries no fit window" in (d / "nowindow" / "summary.md").read_text()


def test_a_fit_window_covering_the_record_is_one_line(workspace):
    """Nothing after the fit window: exit 2, one line pointing at --score-from 0, and no
    --out written."""
    from arfem.scenarios.records.dataset import load_dataset
    d, rec = workspace
    t_end = float(np.asarray(load_dataset(rec).time_s)[-1])
    model = _with_fit_window(d / "run" / "model.json", d / "whole.json", (0.0, t_end))
    r = _cli(model, rec, "--out", d / "nothing")
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "--score-from 0" in r.stderr
    assert not (d / "nothing").exists() or not any((d / "nothing").iterdir())
