"""The JSON-lines live loop and the safety parts every transport shares (issue 28).

What is verified and why:

* a line that is not a reading -- nested 5000 deep, 200 KiB of brackets, 2 MB of junk,
  blank, an array, a string -- is held and logged and does NOT advance the model: the
  offsets of the readings around them are exactly (==) those of the stream without
  them; the loop ends at the end of input with exit 0 and a ``stopped`` line;
* an input outside its plausible range (1e308, -1e308, negative heat) is held with
  ``out_of_range`` and never fed to the state: the offsets that follow are exactly those
  of the stream with that input missing (held with the last inputs either way);
* write-ahead: every answer on standard output is already in the log with the same
  offset, in the same order;
* warm start: a second process continuing a stream on the same log answers exactly what
  one process would have; a torn last line (kill -9 in the middle of a write) is
  skipped and the next line starts on a line of its own; a log of another model gives a
  cold start, and the ``started`` line says which;
* time: missed intervals in closed form agree with stepping them one by one to 1e-12
  relative (the closed form sums the same geometric series in another order), and a jump
  of 1e15 s costs one call; ``clock_jump`` and ``clock_backwards`` hold and re-sync;
* the plausible ranges' defaults follow the model (heat >= 0, speed 0 to twice the
  map's top, ambient -10..50 °C, 1 mm of steady-state growth) and ``[live.ranges]``
  overrides them; a range for an input the model does not read is one line, exit 2;
* the status on standard error names an alarm when it is raised and says when it clears.
"""
import io
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from arfem.models.compensator import (Compensator, ar1_model, fit_speed_ar1_model,
                                      plausible_ranges, propagate)
from arfem.scenarios.live.jsonl import Clock, clocked_step, load_config, run_jsonl
from arfem.scenarios.compensation.model_file import write_model

CONFIG = ('[live]\ntransport = "jsonl"\nmax_offset_um = 20\nmax_step_um = 0.5\n'
          'stale_after_s = 600\nstatus_every = 0\n{extra}')


@pytest.fixture
def setup(tmp_path):
    model = ar1_model(0.99, 1e-3, dtau_s=60.0)
    write_model(tmp_path / "model.json", model)
    (tmp_path / "live.toml").write_text(CONFIG.format(extra=""))
    return tmp_path, model


def run(d, model, lines, log="compensate.log.jsonl"):
    (d / "run.toml").write_text(CONFIG.format(extra=f'log = "{log}"\n'))
    cfg = load_config(d / "run.toml", model)
    out, err = io.StringIO(), io.StringIO()
    from arfem.scenarios.live.jsonl import Status
    rc = run_jsonl(model, cfg, io.StringIO("".join(lines)), out, Status(0, err))
    answers = [json.loads(x) for x in out.getvalue().splitlines()]
    return rc, answers, err.getvalue()


def reading(k, q=1500.0):
    return json.dumps({"time_s": 60.0 * k, "q_W_m2": q}) + "\n"


def offsets(answers):
    return [a["offset_um"] for a in answers if not a["held"]]


def test_lines_that_are_not_readings_are_held_and_never_advance_the_model(setup):
    d, model = setup
    junk = ["[" * 5000 + "\n", "[" * 200_000 + "\n", "x" * 2_000_000 + "\n", "\n",
            "   \n", "[1, 2]\n", '"text"\n', "{not json\n"]
    clean = [reading(k) for k in range(1, 30)]
    mixed = clean[:10] + junk + clean[10:]
    rc0, ref, _ = run(d, model, clean, "a.log")
    rc, ans, _ = run(d, model, mixed, "b.log")
    assert rc == rc0 == 0
    assert offsets(ans) == offsets(ref)             # the model never moved on junk
    bad = ans[10:10 + len(junk)]
    assert all(a["held"] for a in bad)
    kinds = [a["alarms"][0] for a in bad if len(a["alarms"]) == 1]
    assert kinds == ["nested_line", "oversized_line", "oversized_line", "blank_line",
                     "blank_line", "malformed_line", "malformed_line", "malformed_line"]
    log = [json.loads(x) for x in (d / "b.log").read_text().splitlines()]
    assert log[-1]["event"] == "stopped" and log[-1]["reason"] == "end of input"
    assert len(log) == len(mixed) + 2


def test_a_reading_outside_its_range_is_held_and_never_fed_to_the_state(setup):
    d, model = setup
    for bad in (1e308, -1e308, -500.0):
        stream = [reading(k) for k in range(1, 30)]
        missing = list(stream)
        stream[12] = reading(13, bad)
        missing[12] = json.dumps({"time_s": 780.0}) + "\n"
        _, ans, _ = run(d, model, stream, f"r{bad}.log")
        _, ref, _ = run(d, model, missing, f"m{bad}.log")
        assert ans[12]["held"] and "out_of_range:q_W_m2" in ans[12]["alarms"]
        assert [a["offset_um"] for a in ans] == [a["offset_um"] for a in ref]
        assert all(abs(a["offset_um"]) <= 20.0 for a in ans)


def test_every_answer_is_in_the_log_before_it_is_sent(setup):
    d, model = setup
    lines = [reading(k, q) for k, q in enumerate([0, 1500, 3000, 3000, 1500] * 8, 1)]
    _, ans, _ = run(d, model, lines)
    log = [json.loads(x) for x in (d / "compensate.log.jsonl").read_text().splitlines()]
    cyc = [e for e in log if "state" in e]
    assert [c["offset_um"] for c in cyc] == [a["offset_um"] for a in ans]
    assert [c["alarms"] for c in cyc] == [a["alarms"] for a in ans]


def test_warm_start_continues_as_one_process_would(setup):
    d, model = setup
    qs = np.random.default_rng(3).choice([0.0, 1500.0, 3000.0], 80)
    lines = [reading(k, float(q)) for k, q in enumerate(qs, 1)]
    _, whole, _ = run(d, model, lines, "whole.log")
    _, first, _ = run(d, model, lines[:40], "split.log")
    torn = '{"time_s": 2460.0, "inputs": {"q_W_m2": 15'
    with open(d / "split.log", "a") as f:           # kill -9 in the middle of a line
        f.write(torn)
    _, second, _ = run(d, model, lines[40:], "split.log")
    assert [a["offset_um"] for a in first + second] == [a["offset_um"] for a in whole]
    raw = (d / "split.log").read_text().splitlines()
    starts = [json.loads(x) for x in raw if '"started"' in x]
    assert [s["start"] for s in starts] == ["cold", "warm"]
    i = raw.index(torn)                             # the torn line stands alone,
    assert all(json.loads(x) for x in raw[:i] + raw[i + 1:])   # every other line parses
    # another model: the log's state is not used
    other = ar1_model(0.98, 1e-3, dtau_s=60.0)
    write_model(d / "other.json", other)
    run(d, other, lines[:3], "split.log")
    last_start = [json.loads(x) for x in (d / "split.log").read_text().splitlines()
                  if '"started"' in x][-1]
    assert last_start["start"] == "cold" and "another model" in last_start["start_reason"]


def test_missed_intervals_in_closed_form_and_clock_faults():
    m = ar1_model(0.995, 1e-3, dtau_s=60.0)
    A = np.array([[0.9, 0.05], [0.0, 0.8]])
    for k in (1, 2, 7, 65, 1000):
        P, G, S = np.eye(2), np.zeros((2, 2)), np.zeros((2, 2))
        for _ in range(k):
            G, S, P = G + P, S + P @ P.T, A @ P
        Ak, Gk, Sk = propagate(A, k)
        for a, b in ((Ak, P), (Gk, G), (Sk, S)):
            assert np.allclose(a, b, rtol=1e-12, atol=1e-15)
    a, b = Compensator(m, max_offset_um=20, max_step_um=0.5), Compensator(m)
    kw = {"stale_after_s": 1e9, "max_clock_jump_s": 1e9}
    _, ca = clocked_step(a, {"q_W_m2": 2000.0}, 60.0, Clock(), **kw)
    clocked_step(b, {"q_W_m2": 2000.0}, 60.0, Clock(), **kw)
    cyc, ca = clocked_step(a, {"q_W_m2": 2000.0}, 60.0 * 502, ca, **kw)
    for _ in range(500):
        b.step({"q_W_m2": None})
    ref = b.step({"q_W_m2": 2000.0})
    assert ca.missed == 500
    assert math.isclose(cyc.predicted_growth_um, ref.predicted_growth_um, rel_tol=1e-12)
    # a jump beyond the horizon: held, alarm, state re-initialised, clock re-synchronised
    cyc, cj = clocked_step(a, {"q_W_m2": 2000.0}, 1e15, ca, stale_after_s=600.0,
                           max_clock_jump_s=86400.0)
    assert cyc.held and "clock_jump" in cyc.alarms and cj.last_t == 1e15
    assert np.array_equal(a.x, m.x0)
    cyc, cb = clocked_step(a, {"q_W_m2": 2000.0}, 0.0, cj, stale_after_s=600.0)
    assert cyc.held and "clock_backwards" in cyc.alarms and cb.last_t == 0.0
    cyc, _ = clocked_step(a, {"q_W_m2": 2000.0}, 60.0, cb, stale_after_s=600.0)
    assert not cyc.held                              # re-synchronised: runs again


def test_plausible_ranges_follow_the_model_and_the_config(tmp_path):
    sp = np.repeat([0.0, 3000.0, 0.0, 6000.0, 0.0], 200)
    from arfem.models.ar1 import ar1_simulate
    g = ar1_simulate(0.99, np.where(sp == 3000, 0.1, np.where(sp == 6000, 0.25, 0.0)))
    speed = fit_speed_ar1_model(g, sp, dtau_s=15.0)
    assert plausible_ranges(speed)["speed_rpm"] == (0.0, 12000.0)
    heat = ar1_model(0.99, 1e-3, dtau_s=60.0)     # 0.1 µm of growth per W/m² at rest
    lo, hi = plausible_ranges(heat)["q_W_m2"]
    assert lo == 0.0 and math.isclose(hi, 1e4, rel_tol=1e-9)
    write_model(tmp_path / "m.json", heat)
    (tmp_path / "c.toml").write_text(CONFIG.format(extra="[live.ranges]\nq_W_m2 = [0, 5000]\n"))
    assert load_config(tmp_path / "c.toml", heat).ranges_dict()["q_W_m2"] == (0.0, 5000.0)
    (tmp_path / "c.toml").write_text(CONFIG.format(extra="[live.ranges]\nspeed_rpm = [0, 1]\n"))
    r = subprocess.run([sys.executable, "-m", "arfem", "compensate", str(tmp_path / "m.json"),
                        "--live", str(tmp_path / "c.toml")], input="", capture_output=True,
                       text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "live.ranges.speed_rpm: the model does not read this input" in r.stderr


def test_the_terminal_status_names_an_alarm_and_its_end(setup):
    d, model = setup
    lines = [reading(k) for k in range(1, 6)] + ['{"time_s": 360, "q_W_m2": NaN}\n'] + \
        [reading(k) for k in range(7, 10)]
    _, _, err = run(d, model, lines)
    msgs = err.splitlines()
    assert any("ALARM nonfinite:q_W_m2" in x and "cycle 6" in x for x in msgs), err
    assert any("cycle 7" in x and "no alarm" in x for x in msgs), err
    assert "cold start" in msgs[0] and "stopped after 9 cycles" in msgs[-1]
