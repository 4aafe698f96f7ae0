"""``arfem compensate --live`` with a version-2 model: one offset per axis over JSON lines
(issue 32 item 5; the OPC UA side is in tests/test_live_axes_opcua.py).

The model and its record are those ``arfem run`` writes for a small box with three
displacement sensors (tests/test_model_v2_export.py's scenario): axes Y, Z, X.

What is verified and why:

* live equals replay: the offsets the JSON-lines loop answers, axis by axis, are
  exactly (==) those of ``arfem compensate``'s replay of the same record with the same
  per-axis limits: one code path (``Compensator.step``) for both;
* each axis keeps its own clamp and step limit ([live.axes.X], [live.axes.Y]; Z the
  common ones) on every answer, and a binding limit is that axis's alarm only
  (``clamped`` in X's alarms, ``clamped@X`` in the cycle's);
* an input fault (a NaN power, a negative one outside its plausible range, a missing
  ambient) holds every axis (they share the inputs) with the alarm, and is never fed to
  the state: the answers that follow equal those of the stream with that reading
  missing;
* ``controller_offsets_um`` on a line (what the gateway read back) sets where each
  named axis's rate limit counts from: the next offset of that axis is within its step
  of the value read, the other axes are untouched;
* write-ahead and warm start per axis: every answer is in the log first; a second
  process continuing the stream on the same log answers exactly what one process would
  have, each axis ramping from the offset its log line holds;
* config refusals (an axis the model lacks, per-axis limits for a one-output model, a
  negative limit): one line, exit 2.
"""
from __future__ import annotations

import io
import json
import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from arfem.scenarios.live.jsonl import Status, load_config, run_jsonl
from arfem.scenarios.compensation.model_file import read_model

CONFIG = ('[live]\ntransport = "jsonl"\nmax_offset_um = 50\nmax_step_um = 1.0\n'
          'stale_after_s = 600\nstatus_every = 0\nlog = "{log}"\n'
          '[live.axes.X]\nmax_offset_um = 15.0\nmax_step_um = 0.3\n'
          '[live.axes.Y]\nmax_offset_um = 2.0\nmax_step_um = 0.2\n')
LIMITS = {"X": (15.0, 0.3), "Y": (2.0, 0.2), "Z": (50.0, 1.0)}


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    """model.json (version 2) and record.csv of the box, from ``arfem run``."""
    from test_model_v2_export import box_scenario

    from arfem.scenarios.cli import main
    d = tmp_path_factory.mktemp("box")
    assert main(["run", str(box_scenario(d, 0.0)), "--out", str(d / "run")]) == 0
    model = read_model(d / "run" / "model.json")
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.compensation.replay import record_columns
    ds = load_dataset(d / "run" / "record.toml")
    inputs, _ = record_columns(model, ds, "record")
    from arfem.scenarios.compensation.replay import observer_readings
    inputs.update(observer_readings(model, ds, True)[0])   # its thermometer (issue 43)
    return d / "run", model, ds, inputs


def lines_of(ds, inputs, start=1, stop=None, edit=None):
    out = []
    for k in range(start, stop or ds.time_s.size):
        row = {"time_s": float(ds.time_s[k]), **{nm: float(v[k]) for nm, v in inputs.items()}}
        if edit is not None:
            row = edit(k, row)
        out.append(json.dumps(row) + "\n")
    return out


def run(d, model, lines, log):
    (d / "live.toml").write_text(CONFIG.format(log=log))
    cfg = load_config(d / "live.toml", model)
    out, err = io.StringIO(), io.StringIO()
    rc = run_jsonl(model, cfg, io.StringIO("".join(lines)), out, Status(0, err))
    return rc, [json.loads(x) for x in out.getvalue().splitlines()]


def offsets(answers, ax):
    return [a["axes"][ax]["offset_um"] for a in answers]


def test_live_equals_replay_per_axis_and_each_axis_keeps_its_limits(box, tmp_path):
    run_dir, model, ds, inputs = box
    from arfem.scenarios.compensation.replay import replay
    rc, ans = run(tmp_path, model, lines_of(ds, inputs), "a.log")
    assert rc == 0 and len(ans) == ds.time_s.size - 1
    axes = model.axes
    res = replay(model, ds, max_offset_um=tuple(LIMITS[a][0] for a in axes),
                 max_step_um=tuple(LIMITS[a][1] for a in axes))
    for j, ax in enumerate(axes):
        assert offsets(ans, ax) == res.series.axes[j].offset_um[1:].tolist()
        off = np.array([0.0] + offsets(ans, ax))
        clamp, step = LIMITS[ax]
        assert np.max(np.abs(off)) <= clamp + 1e-12
        assert np.max(np.abs(np.diff(off))) <= step + 1e-12
    assert any("clamped" in a["axes"]["X"]["alarms"] for a in ans)
    assert any("clamped@X" in a["alarms"] for a in ans)
    assert not any("clamped" in a["axes"]["Z"]["alarms"] for a in ans)
    log = [json.loads(x) for x in (tmp_path / "a.log").read_text().splitlines()]
    cycles = [e for e in log if "axes" in e and "event" not in e]
    assert [c["axes"] for c in cycles] == [a["axes"] for a in ans]      # write-ahead


def test_an_input_fault_holds_every_axis_and_never_reaches_the_state(box, tmp_path):
    run_dir, model, ds, inputs = box

    def nan_at_20(k, row):                     # a NaN power at 20, no ambient at 30,
        if k == 20:                            # a negative power at 25
            return {**row, "P_heater_W": math.nan}
        if k == 25:
            return {**row, "P_side_W": -5.0}
        if k == 30:
            return {kk: v for kk, v in row.items() if kk != "ambient_C"}
        return row

    def missing(k, row):
        return {"time_s": row["time_s"]} if k in (20, 25, 30) else row
    _, bad = run(tmp_path, model, lines_of(ds, inputs, edit=nan_at_20), "b.log")
    _, ref = run(tmp_path, model, lines_of(ds, inputs, edit=missing), "c.log")
    for k, tag in ((20, "nonfinite:P_heater_W"), (25, "out_of_range:P_side_W"),
                   (30, "missing:ambient_C")):
        a = bad[k - 1]
        assert a["held"] and tag in a["alarms"]
        assert all(a["axes"][ax]["offset_um"] == bad[k - 2]["axes"][ax]["offset_um"]
                   for ax in model.axes)
    for ax in model.axes:
        assert offsets(bad, ax) == offsets(ref, ax)


def test_controller_offsets_set_where_each_axis_ramps_from(box, tmp_path):
    run_dir, model, ds, inputs = box

    def readback(k, row):
        return {**row, "controller_offsets_um": {"Z": 7.5}} if k == 40 else row
    _, ans = run(tmp_path, model, lines_of(ds, inputs, edit=readback), "d.log")
    _, ref = run(tmp_path, model, lines_of(ds, inputs), "e.log")
    z = ans[39]["axes"]["Z"]["offset_um"]
    assert abs(z - 7.5) <= LIMITS["Z"][1] + 1e-12 and z != ref[39]["axes"]["Z"]["offset_um"]
    for ax in ("X", "Y"):
        assert offsets(ans, ax) == offsets(ref, ax)


def test_warm_start_continues_each_axis(box, tmp_path):
    run_dir, model, ds, inputs = box
    all_lines = lines_of(ds, inputs)
    _, one = run(tmp_path, model, all_lines, "one.log")
    _, first = run(tmp_path, model, all_lines[:50], "two.log")
    _, second = run(tmp_path, model, all_lines[50:], "two.log")
    for ax in model.axes:
        assert offsets(first, ax) + offsets(second, ax) == offsets(one, ax)
    started = [json.loads(x) for x in (tmp_path / "two.log").read_text().splitlines()
               if '"started"' in x]
    assert started[-1]["start"] == "warm"
    assert set(started[-1]["offsets_um"]) == set(model.axes)


def test_the_command_runs_a_version_2_model_and_refuses_bad_axes_config(box, tmp_path):
    run_dir, model, ds, inputs = box
    (tmp_path / "live.toml").write_text(CONFIG.format(log="cli.log"))
    p = subprocess.run([sys.executable, "-m", "arfem", "compensate",
                        str(run_dir / "model.json"), "--live", str(tmp_path / "live.toml")],
                       input="".join(lines_of(ds, inputs, stop=11)), capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    ans = [json.loads(x) for x in p.stdout.splitlines()]
    assert len(ans) == 10 and set(ans[0]["axes"]) == {"X", "Y", "Z"}
    bad = {"W": CONFIG.format(log="x.log") + "[live.axes.W]\nmax_step_um = 1.0\n",
           "max_step_um": CONFIG.format(log="x.log").replace(
               "max_step_um = 0.3", "max_step_um = -0.3")}
    for key, text in bad.items():
        (tmp_path / "bad.toml").write_text(text)
        p = subprocess.run([sys.executable, "-m", "arfem", "compensate",
                            str(run_dir / "model.json"), "--live", str(tmp_path / "bad.toml")],
                           input="", capture_output=True, text=True, timeout=300)
        err = [ln for ln in p.stderr.splitlines() if ln.strip()]
        assert p.returncode == 2 and len(err) == 1 and key in err[0], err
        assert not (tmp_path / "x.log").exists()
    from arfem.models.compensator import ar1_model
    from arfem.params import InputError
    with pytest.raises(InputError, match="several axes"):
        load_config(tmp_path / "live.toml", ar1_model(0.99, 1e-3, dtau_s=60.0))


def test_the_machine_clock_holds_and_advances_every_axis_together(box, tmp_path):
    """Missed intervals (a jump of 5 Δτ) are stepped for the shared state: the predicted
    values after the gap equal (==) those of the stream that carried the missing rows
    with the last inputs (at most 64 intervals are stepped one by one, the same floats);
    a clock set back holds every axis with ``clock_backwards``. (The model open loop:
    with its observer, the rows carried would also be corrected by the thermometers.)"""
    run_dir, model, ds, inputs = box
    model = replace(model, observer=None)
    gap = set(range(41, 46))

    def hold_last(k, row):                 # rows 41-45 repeat row 40's inputs
        if k in gap:
            return {"time_s": row["time_s"],
                    **{nm: float(v[40]) for nm, v in inputs.items()}}
        return row
    full = lines_of(ds, inputs, edit=hold_last)
    jumped = [x for k, x in enumerate(full, start=1) if k not in gap]
    _, ref = run(tmp_path, model, full, "f.log")
    _, ans = run(tmp_path, model, jumped, "g.log")
    after = ans[40]                                   # the reading at row 46
    assert after["time_s"] == ref[45]["time_s"] and not after["held"]
    for ax in model.axes:
        assert after["axes"][ax]["predicted_um"] == ref[45]["axes"][ax]["predicted_um"]
    log = [json.loads(x) for x in (tmp_path / "g.log").read_text().splitlines()]
    assert any(e.get("missed_intervals") == 5 for e in log)

    def back(k, row):
        return {**row, "time_s": 0.0} if k == 30 else row
    _, bk = run(tmp_path, model, lines_of(ds, inputs, stop=35, edit=back), "h.log")
    a = bk[29]
    assert a["held"] and "clock_backwards" in a["alarms"]
    assert all(a["axes"][ax]["offset_um"] == bk[28]["axes"][ax]["offset_um"]
               for ax in model.axes)
