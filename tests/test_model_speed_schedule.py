"""The speed-scheduled model.json version 2 (issue 32): where a convection coefficient
depends on the spindle speed (h = a + b·n), the export tabulates A, B, D at each of the
cycle's speeds in the reduced solve's one basis, and the compensator steps the
matrices of each interval's speed.

The box of tests/test_model_v2_export.py (324 cells, P1, two sources, three axes), with
h = 10 + 0.01·n W/m²K on its cooled face: 20 at 1000 rpm for 1 h, 10 at rest for 1 h.

What is verified and why:

* at the cycle's speeds the scheduled model stepped by the compensator IS the run's
  reduced solve at every axis, to 1e-9 of each axis's range (measured 3.4e-12): the same
  basis, the same Galerkin projection, the state carried across the speed change as the
  solve carries θ; the linearised model of before missed by 2.2 % (Z), and a wrong
  basis, a lost static term or a state not carried would show at 1e-3 or more;
* a speed between two tabulated ones gets each matrix linear in the speed (exactly the
  mean at the midpoint: the stated rule), a speed outside the table the end's matrices
  and the informative alarm ``outside_schedule:speed_rpm`` (never extrapolated, the
  offset still written), a held cycle and intervals not seen advance with the last good
  speed's matrices, and a warm start restores that speed;
* ``arfem run`` writes the schedule (schema-valid, ``speed_rpm`` an input),
  ``arfem compensate`` replays it per axis within 1 % of each axis's RMS (the CSV's 10
  digits), and the JSON-lines live loop answers exactly (==) what the replay computes,
  flagging an out-of-table speed on that cycle only; the replay counts such cycles
  (`cycles_outside_schedule`, and says so in summary.md).
"""
from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest

from test_model_v2_export import box_scenario, rel_errors, solved


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    return solved(tmp_path_factory.mktemp("sched"), 0.01)


def test_scheduled_model_is_the_reduced_solve_at_the_cycles_speeds(box):
    run, ex, cols = box
    m = ex.model
    assert m.schedule is not None and m.schedule.speeds_rpm.tolist() == [0.0, 1000.0]
    assert [i.name for i in m.inputs] == ["P_heater_W", "P_side_W", "ambient_C",
                                          "speed_rpm"]
    assert np.all(m.B[:, -1] == 0) and np.all(m.schedule.B[:, :, -1] == 0)
    assert set(np.unique(cols["speed_rpm"])) == {0.0, 1000.0}   # both speeds exercised
    err = rel_errors(m, cols)
    assert max(err.values()) < 1e-9, err
    assert ex.h_W_m2K == pytest.approx((15.0,))     # the nominal A, B, D's h


def test_between_and_outside_the_table(box):
    from arfem.models.compensator import Compensator
    m = box[1].model
    s = m.schedule
    A, B, D, out = m.matrices(500.0)
    assert not out and np.allclose(A, 0.5 * (s.A[0] + s.A[1]), rtol=0, atol=1e-15)
    assert np.allclose(B, 0.5 * (s.B[0] + s.B[1]), rtol=0, atol=1e-15 * np.abs(B).max())
    assert np.max(np.abs(np.linalg.eigvals(A))) < 1       # the interpolated model settles
    A2, B2, _, out2 = m.matrices(2500.0)
    assert out2 and np.array_equal(A2, s.A[1]) and np.array_equal(B2, s.B[1])
    u = {"P_heater_W": 10.0, "P_side_W": 5.0, "ambient_C": 21.0}
    c_in, c_out = Compensator(m), Compensator(m)
    a = c_in.step({**u, "speed_rpm": 1000.0})
    b = c_out.step({**u, "speed_rpm": 2500.0})
    assert "outside_schedule:speed_rpm" in b.alarms and not b.held
    assert "outside_schedule:speed_rpm" not in a.alarms
    assert np.array_equal(c_in.x, c_out.x)                 # clamped to the end's matrices
    assert [x.offset_um for x in a.axes] == [x.offset_um for x in b.axes]
    # a held cycle (speed missing) and unseen intervals: the last good speed's matrices
    held = c_out.step({**u, "speed_rpm": None})
    assert held.held and np.allclose(c_out.x, s.A[1] @ c_in.x + s.B[1] @ np.array(
        [10.0, 5.0, 1.0, 2500.0]), rtol=1e-12, atol=0)
    x = c_out.x.copy()
    c_out.advance_idle(3)
    for _ in range(3):
        x = s.A[1] @ x + s.B[1] @ np.array([10.0, 5.0, 1.0, 2500.0])
    assert np.allclose(c_out.x, x, rtol=1e-12, atol=0)
    st = json.loads(json.dumps(c_out.state()))
    assert st["speed_rpm"] == 2500.0
    warm = Compensator(m)
    warm.restore(st)
    assert warm._speed_last == 2500.0


def test_a_cycle_of_many_speeds_gets_an_even_grid(tmp_path):
    """Twelve phases at twelve speeds (more than MAX_SCHEDULE_SPEEDS): the schedule
    tabulates 8 speeds evenly from the slowest to the fastest (so model.json stays
    bounded), and between them the interpolated model stays within 1e-4 of each axis's
    range of the reduced solve (measured 4.1e-6 at most: h is linear in n on this box,
    so only the matrices' curvature in h remains; the linearised model missed the
    two-speed cycle by 2.2e-2)."""
    from arfem.scenarios.geometry.export import (MAX_SCHEDULE_SPEEDS, export_state_space,
                                                 record_columns)
    from arfem.scenarios.geometry.scenario import (build_geometry_model,
                                                   load_geometry_scenario, solve_geometry)
    toml = box_scenario(tmp_path, 0.01)
    speeds = [0.0, 2400.0, 300.0, 1500.0, 700.0, 2000.0, 100.0, 1100.0, 1800.0, 500.0,
              2200.0, 900.0]
    phases = ", ".join(f"{{ duration_min = 10.0, speed_rpm = {v} }}" for v in speeds)
    text = toml.read_text()
    start = text.index("phases = [", text.index("[cycle]"))
    text = text[:start] + f"phases = [ {phases} ]" + text[text.index("\n", start):]
    text = text.replace("power_W = [50.0, 0.0]", "power_W = [" + ", ".join(
        "50.0" if i % 3 else "0.0" for i in range(12)) + "]")
    toml.write_text(text)
    gm = build_geometry_model(load_geometry_scenario(toml))
    run = solve_geometry(gm)
    m = export_state_space(gm).model
    assert m.schedule.speeds_rpm.size == MAX_SCHEDULE_SPEEDS == 8
    assert m.schedule.speeds_rpm[0] == 0.0 and m.schedule.speeds_rpm[-1] == 2400.0
    err = rel_errors(m, record_columns(run, m))
    assert max(err.values()) < 1e-4, err


def test_run_compensate_and_live_with_a_schedule(tmp_path):
    import jsonschema

    from arfem.scenarios.cli import main
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.live.jsonl import Status, load_config, run_jsonl
    from arfem.scenarios.compensation.model_file import read_model
    from arfem.scenarios.compensation.replay import record_columns
    toml = box_scenario(tmp_path, 0.01)
    assert main(["run", str(toml), "--out", str(tmp_path / "run")]) == 0
    doc = json.loads((tmp_path / "run" / "model.json").read_text("utf-8"))
    schema = json.loads((Path(__file__).resolve().parents[1] / "docs" /
                         "model.schema.json").read_text("utf-8"))
    jsonschema.validate(doc, schema)
    assert doc["speed_schedule"]["speeds_rpm"] == [0.0, 1000.0]
    rec = tmp_path / "run" / "record.toml"
    assert main(["compensate", str(tmp_path / "run" / "model.json"), str(rec), "--out",
                 str(tmp_path / "free")]) == 0
    s = json.loads((tmp_path / "free" / "summary.json").read_text("utf-8"))
    for a in s["axes"]:
        assert a["rms_after_um"] < 0.01 * a["rms_before_um"], a
    assert s["cycles_outside_schedule"] == 0           # the record's speeds are the table's
    orig = (tmp_path / "run" / "record.csv").read_text()
    text = orig.splitlines()
    j = text[0].split(",").index("speed_rpm")
    text[30] = ",".join("1500" if i == j else c for i, c in enumerate(text[30].split(",")))
    (tmp_path / "run" / "record.csv").write_text("\n".join(text) + "\n")
    assert main(["compensate", str(tmp_path / "run" / "model.json"), str(rec), "--out",
                 str(tmp_path / "beyond")]) == 0
    s = json.loads((tmp_path / "beyond" / "summary.json").read_text("utf-8"))
    assert s["cycles_outside_schedule"] == 1 and s["cycles_held"] == 0
    assert "beyond the model's speed schedule" in (tmp_path / "beyond" /
                                                   "summary.md").read_text("utf-8")
    (tmp_path / "run" / "record.csv").write_text(orig)      # back to the run's record
    # live over JSON lines: the same offsets as a replay of the same readings, and an
    # out-of-table speed on one line flagged on that answer only
    model = read_model(tmp_path / "run" / "model.json")
    ds = load_dataset(rec)
    inputs, _ = record_columns(model, ds, "record")
    bad = 30
    lines = []
    for k in range(1, ds.time_s.size):
        row = {"time_s": float(ds.time_s[k]), **{n: float(v[k]) for n, v in inputs.items()}}
        if k == bad:
            row["speed_rpm"] = 1500.0      # beyond the table, within the plausible range
        lines.append(json.dumps(row) + "\n")
    (tmp_path / "live.toml").write_text(
        '[live]\ntransport = "jsonl"\nmax_offset_um = 1000\nmax_step_um = 1000\n'
        f'stale_after_s = 600\nstatus_every = 0\nlog = "{tmp_path / "live.log"}"\n')
    cfg = load_config(tmp_path / "live.toml", model)
    out = io.StringIO()
    assert run_jsonl(model, cfg, io.StringIO("".join(lines)), out,
                     Status(0, io.StringIO())) == 0
    ans = [json.loads(x) for x in out.getvalue().splitlines()]
    ans = [a for a in ans if "axes" in a]
    from arfem.models.compensator import Compensator, plausible_ranges
    assert plausible_ranges(model)["speed_rpm"] == (0.0, 2000.0)   # twice the table's top
    comp = Compensator(model, 1000.0, 1000.0, plausible_ranges(model))
    for k, a in enumerate(ans, start=1):
        row = json.loads(lines[k - 1])
        cyc = comp.step({i.name: row[i.name] for i in model.inputs})
        assert [a["axes"][x.axis]["offset_um"] for x in cyc.axes] == [
            x.offset_um for x in cyc.axes]
        flagged = "outside_schedule:speed_rpm" in a["alarms"]
        assert flagged == (k == bad) and not a["held"], (k, a)
