"""``arfem compensate --live`` with the JSON-lines transport (issue 21, item 3 in part).

What is verified and why:
* live equals replay: the offsets answered for a record's rows, fed as JSON lines, are
  exactly those of ``arfem compensate``'s replay (one ``Compensator.step`` for both);
* the safety rules on a stream: clamp and rate limit hold; a malformed line, a missing
  or NaN input, a repeated time (stale) and a gap hold the offset with an alarm;
* SIGTERM while the loop waits for a line ends it with exit 0 and a final log line, and
  every cycle before it is already in the log: the log is write-ahead (a cycle's line is
  written, flushed and fsync'ed before its answer reaches standard output), so reading
  an answer implies its line is in the file -- the ordering the test relies on, not a
  race it usually wins (issue 28: it once failed 3 == 4 when stdout came first);
* a config naming an unknown key, no bounds, or the OPC UA transport without its table is
  refused in one line with exit status 2 before any offset is written.
"""
import json
import signal
import subprocess
import sys

import numpy as np
import pytest

from arfem.models.compensator import ar1_model
from arfem.scenarios.compensation.model_file import write_model

CONFIG = '[live]\ntransport = "jsonl"\nmax_offset_um = {mo}\nmax_step_um = {ms}\nstale_after_s = 120\n'


@pytest.fixture
def setup(tmp_path):
    model = ar1_model(0.99, 1e-4, dtau_s=60.0)
    write_model(tmp_path / "model.json", model)
    (tmp_path / "live.toml").write_text(CONFIG.format(mo=1e6, ms=1e6))
    return tmp_path, model


def _live(d, lines, config="live.toml"):
    return subprocess.run([sys.executable, "-m", "arfem", "compensate", str(d / "model.json"),
                           "--live", str(d / config)], input="".join(lines),
                          capture_output=True, text=True)


def test_live_equals_replay(setup):
    from arfem.models.compensator import Compensator
    d, model = setup
    q = np.random.default_rng(5).choice([0.0, 1500.0, 3000.0], 300)
    lines = [json.dumps({"time_s": 60.0 * (k + 1), "q_W_m2": float(v)}) + "\n"
             for k, v in enumerate(q)]
    r = _live(d, lines)
    assert r.returncode == 0, r.stderr
    live = [json.loads(x)["offset_um"] for x in r.stdout.splitlines()]
    c = Compensator(model, max_offset_um=1e6, max_step_um=1e6)
    ref = [c.step({"q_W_m2": float(v)}).offset_um for v in q]
    assert live == ref                       # the same floats: one code path


def test_safety_rules_on_a_stream(setup):
    d, _ = setup
    (d / "tight.toml").write_text(CONFIG.format(mo=0.3, ms=0.05))
    good = [json.dumps({"time_s": 60.0 * k, "q_W_m2": 3000.0}) + "\n" for k in range(1, 40)]
    bad = ["not json\n", '{"time_s": 2340, "q_W_m2": NaN}\n', '{"time_s": 2400}\n',
           '{"time_s": 2460, "q_W_m2": 3000}\n', '{"time_s": 2340, "q_W_m2": 3000}\n',
           '{"time_s": 9000, "q_W_m2": 3000}\n']
    r = _live(d, good + bad, "tight.toml")
    out = [json.loads(x) for x in r.stdout.splitlines()]
    offs = [o["offset_um"] for o in out]
    assert max(abs(o) for o in offs) <= 0.3 + 1e-12
    assert max(abs(b - a) for a, b in zip(offs, offs[1:])) <= 0.05 + 1e-12
    tail = out[len(good):]
    want = ["malformed_line", "nonfinite:q_W_m2", "missing:q_W_m2", None, "clock_backwards",
            "gap:time_s"]
    for o, w in zip(tail, want):
        if w is None:
            assert not o["held"]
        else:
            assert o["held"] and w in o["alarms"] and o["offset_um"] == tail[0]["offset_um"]
    log = (d / "compensate.log.jsonl").read_text().splitlines()
    assert json.loads(log[-1])["event"] == "stopped" and len(log) == len(out) + 2


def test_sigterm_ends_cleanly_with_the_log_flushed(setup):
    d, _ = setup
    p = subprocess.Popen([sys.executable, "-m", "arfem", "compensate", str(d / "model.json"),
                          "--live", str(d / "live.toml")], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for k in range(1, 4):
        p.stdin.write(json.dumps({"time_s": 60.0 * k, "q_W_m2": 1000.0}) + "\n")
        p.stdin.flush()
        p.stdout.readline()                  # the answer: the cycle is done and logged
    log = (d / "compensate.log.jsonl").read_text().splitlines()
    assert len(log) == 4                     # started + 3 cycles, before any exit
    p.send_signal(signal.SIGTERM)            # while it waits for the next line
    try:
        rc = p.wait(timeout=20)
    finally:
        p.kill()
    assert rc == 0
    last = json.loads((d / "compensate.log.jsonl").read_text().splitlines()[-1])
    assert last["event"] == "stopped" and last["reason"] == "SIGTERM" and last["cycles"] == 3


@pytest.mark.parametrize("text, msg", [
    ('[live]\ntransport = "jsonl"\nmax_offset_um = 1\nmax_step_um = 1\nperiod = 1\n', "unknown"),
    ('[live]\ntransport = "jsonl"\nmax_step_um = 1\n', "live.max_offset_um: is required"),
    ('[live]\ntransport = "opcua"\nmax_offset_um = 1\nmax_step_um = 1\n', "needs an [opcua] table"),
    ('[live]\ntransport = "jsonl"\nmax_offset_um = -1\nmax_step_um = 1\n', "positive"),
])
def test_bad_config_is_one_line_exit_2(setup, text, msg):
    d, _ = setup
    (d / "bad.toml").write_text(text)
    r = _live(d, ['{"time_s": 60, "q_W_m2": 1}\n'], "bad.toml")
    assert r.returncode == 2 and msg in r.stderr and r.stdout == ""
    assert len(r.stderr.strip().splitlines()) == 1


def test_the_machine_clock_decides_how_far_the_model_advances():
    """clocked_step (every transport): a stale time holds the offset without advancing
    the state (no interval passed); a time two intervals on advances through the unseen
    one first (held, last inputs); with clock_only and no readable time, nothing moves.
    The reference steps a Compensator interval by interval by hand (== : up to
    EXACT_STEPS missed intervals are stepped one by one, the replay's floats)."""
    from arfem.models.compensator import Compensator
    from arfem.scenarios.live.jsonl import Clock, clocked_step
    m = ar1_model(0.9, 0.01, dtau_s=60.0)
    c, ref, clock = Compensator(m), Compensator(m), Clock()
    kw = {"stale_after_s": 600.0}
    for t, q in ((60.0, 100.0), (120.0, 200.0)):
        _, clock = clocked_step(c, {"q_W_m2": q}, t, clock, **kw)
        ref.step({"q_W_m2": q})
    x = c.x.copy()
    cyc, clock = clocked_step(c, {"q_W_m2": 900.0}, 120.0, clock, **kw)
    assert cyc.held and "stale:q_W_m2" in cyc.alarms and np.array_equal(c.x, x)
    cyc, clock = clocked_step(c, {"q_W_m2": 900.0}, None, clock, clock_only=True, **kw)
    assert np.array_equal(c.x, x)
    cyc, clock = clocked_step(c, {"q_W_m2": 300.0}, 240.0, clock, **kw)
    ref.step({"q_W_m2": None})                      # the unseen interval: last inputs
    want = ref.step({"q_W_m2": 300.0})
    assert clock.missed == 1 and not cyc.held
    assert cyc.predicted_growth_um == want.predicted_growth_um
