"""What the controller holds, over JSON lines (issue 40): a value beyond the clamp is
never taken up, limits typed on the command line are honoured, a change behind the
compensator's back is never jumped over; one axis and three.

The gateway is tests/jsonl_gateway.py, in process and in lockstep with the loop: each
line carries what the controller holds (read back), each answer is written to the
controller where its offset is a number, and every write is recorded with what that
axis held when it came. Nothing depends on timing.

What is verified and why:

* for EVERY write and EVERY answer, in every run below: |offset| <= that axis's clamp,
  and |offset - what the axis held| <= its step (1e-9 µm: the rate limit is exact
  arithmetic on the held value; the tolerance absorbs the float's last digit) -- the
  issue's done-criterion, measured from the value the controller holds;
* a value beyond the clamp (1e300, 50 against 3) or not a number (NaN), at start or
  mid-run, is not adopted: that axis answers null (not to be written) with
  ``held_beyond_clamp`` / ``held_nonfinite`` until the operator brings it inside, then
  ramps from that value; the other axes run on, their answers exactly (==) those of the
  run without the fault (the state is shared, each axis's limits its own);
* a change behind the compensator's back (the gateway's read-back differs from the
  last answer) raises ``external_change`` on that axis, and the next offset is within a
  step of the new value;
* the log's warm start carrying a value beyond the clamp (a log written under a looser
  config) holds that axis (``held_beyond_clamp``, source ``log``) until a line reports a
  value inside; the others continue exactly as one process would have;
* ``--axis-limits`` / ``--max-offset-um`` / ``--max-step-um`` with ``--live`` tighten the
  config (every write within the typed limits) and a looser one is refused in one line;
  ``--probe-every``, ``--score-from``, ``--force`` are refused in one line, exit 2;
* 40 random streams (one axis and three) with random read-backs -- inside, beyond the
  clamp, NaN, changed by hand, not reported -- give 0 answers beyond a clamp and 0 writes
  beyond a step (the issue found 1394 of 5811 answers beyond their clamp);
* the ``stopped`` line carries one offset per axis (and no one-axis ``last_offset_um``
  beside them).
"""
from __future__ import annotations

import io
import json
import math
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from jsonl_gateway import Gateway
from arfem.models.compensator import ar1_model
from arfem.params import InputError
from arfem.scenarios.live.jsonl import Status, load_config, run_jsonl, run_live
from arfem.scenarios.compensation.model_file import write_model

ONE = {None: (3.0, 0.1)}                       # one axis: clamp, step [µm]
AXES = {"X": (15.0, 0.3), "Y": (2.0, 0.2), "Z": (3.0, 0.1)}


def config(d, limits, log="live.log", name="live.toml"):
    text = ('[live]\ntransport = "jsonl"\nstale_after_s = 600\nstatus_every = 0\n'
            f'log = "{log}"\n')
    if None in limits:
        text += f"max_offset_um = {limits[None][0]}\nmax_step_um = {limits[None][1]}\n"
    else:
        text += "max_offset_um = 50.0\nmax_step_um = 1.0\n"
        for ax, (c, s) in limits.items():
            text += f"[live.axes.{ax}]\nmax_offset_um = {c}\nmax_step_um = {s}\n"
    (d / name).write_text(text)
    return d / name


def go(d, model, rows, held, limits, *, on_advance=None, report=None, log="live.log"):
    """One run of the loop against a fresh gateway; (gateway, log lines)."""
    cfg = load_config(config(d, limits, log), model)
    g = Gateway(rows, held, on_advance=on_advance, report=report)
    assert run_jsonl(model, cfg, g, g, Status(0, io.StringIO())) == 0
    assert len(g.answers) == len(rows)
    clamp, step = g.beyond(limits)
    assert clamp == [] and step == [], (clamp[:3], step[:3])
    return g, [json.loads(x) for x in (d / log).read_text().splitlines()]


def q_rows(n, q=3000.0):
    return [{"time_s": 60.0 * k, "q_W_m2": q if (k // 25) % 2 == 0 else 0.0}
            for k in range(1, n + 1)]


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    """The version-2 model ``arfem run`` writes for a small box (axes Y, Z, X) and its
    record's rows from row 1 (a reading ends each interval)."""
    from axes_machine import box_run
    run_dir, model, rows = box_run(tmp_path_factory.mktemp("box"))
    return run_dir, model, rows[1:]


def test_one_axis_never_takes_up_a_value_beyond_its_clamp(tmp_path):
    """The issue's cases on one axis: 1e300 at start, 50 mid-run (clamp 3), NaN, and a
    change by hand inside the clamp."""
    model = ar1_model(0.99, 1e-3, dtau_s=60.0)
    set_at = {8: 2.0, 20: 50.0, 30: -1.0, 40: 2.5, 50: math.nan, 55: 0.0}

    def on_advance(g, n):
        if n in set_at:
            g.held[None] = set_at[n]
    g, log = go(tmp_path, model, q_rows(70), {None: 1e300}, ONE, on_advance=on_advance)
    # the line of answer n carries what on_advance(n - 1) set
    held = {**{n: "held_beyond_clamp" for n in list(range(1, 9)) + list(range(21, 31))},
            **{n: "held_nonfinite" for n in range(51, 56)}}
    for n in range(1, 71):
        if n in held:
            assert g.offset(n) is None and g.answers[n - 1]["held"], n
            assert held[n] in g.alarms(n), (n, g.alarms(n))
        else:
            assert g.offset(n) is not None and not g.answers[n - 1]["held"], n
            assert not any(a.startswith("held_") for a in g.alarms(n)), (n, g.alarms(n))
    for n, base in ((9, 2.0), (31, -1.0), (41, 2.5), (56, 0.0)):
        assert abs(g.offset(n) - base) <= 0.1 + 1e-12, n        # ramps from what it holds
    assert "external_change" in g.alarms(41)
    assert all("external_change" not in g.alarms(n) for n in range(1, 71) if n != 41)
    assert len(g.writes) == 70 - len(held)
    ev = [e["event"] for e in log if e.get("event") not in (None, "started", "stopped")]
    assert ev == ["held_beyond_clamp", "held_cleared", "held_beyond_clamp", "held_cleared",
                  "external_change", "held_nonfinite", "held_cleared"]
    assert log[-1]["event"] == "stopped" and log[-1]["last_offset_um"] == g.offset(70)


def test_a_cold_starts_first_read_back_is_taken_without_an_external_change(tmp_path):
    """At a cold start the compensator assumes 0 until told: the first line's 2.0 is
    adopted (the first write within a step of it) and is not someone else's change; a
    later difference is."""
    model = ar1_model(0.99, 1e-3, dtau_s=60.0)

    def on_advance(g, n):
        if n == 5:
            g.held[None] = -1.0
    g, _ = go(tmp_path, model, q_rows(10), {None: 2.0}, ONE, on_advance=on_advance)
    assert abs(g.offset(1) - 2.0) <= 0.1 + 1e-12 and "external_change" not in g.alarms(1)
    assert [n for n in range(1, 11) if "external_change" in g.alarms(n)] == [6]


def _reference(tmp_path, model, rows):
    g, _ = go(tmp_path, model, rows, {ax: 0.0 for ax in model.axes}, AXES, log="ref.log")
    return g


@pytest.mark.parametrize("case", ["start_beyond", "mid_run_beyond", "nonfinite",
                                  "external_change"])
def test_three_axes_a_held_value_on_one_axis_while_the_others_run(box, tmp_path, case):
    _, model, rows = box
    rows = rows[:60]
    ref = _reference(tmp_path, model, rows)
    held0 = {ax: 0.0 for ax in model.axes}
    ax, plan, off = {
        "start_beyond": ("Z", {10: 1.0}, range(1, 11)),          # 50 held at start
        "mid_run_beyond": ("Y", {20: 9.0, 30: -1.5}, range(21, 31)),
        "nonfinite": ("Z", {25: math.inf, 35: -2.0}, range(26, 36)),
        "external_change": ("X", {40: 4.0}, ()),
    }[case]
    if case == "start_beyond":
        held0["Z"] = 50.0

    def on_advance(g, n):
        if n in plan:
            g.held[ax] = plan[n]
    g, log = go(tmp_path, model, rows, held0, AXES, on_advance=on_advance)
    for other in model.axes:
        if other != ax:                           # the others run exactly as without it
            assert [g.offset(n, other) for n in range(1, 61)] == \
                [ref.offset(n, other) for n in range(1, 61)], other
            assert not any("held_" in a or "external" in a
                           for n in range(1, 61) for a in g.alarms(n, other))
    kind = {"start_beyond": "held_beyond_clamp", "mid_run_beyond": "held_beyond_clamp",
            "nonfinite": "held_nonfinite"}.get(case)
    for n in range(1, 61):
        a = g.answers[n - 1]["axes"][ax]
        if n in off:
            assert a["offset_um"] is None and a["held"] and kind in a["alarms"], (n, a)
            assert f"{kind}@{ax}" in g.alarms(n)
        else:
            assert a["offset_um"] is not None and not a["held"], (n, a)
    back = {n + 1: v for n, v in plan.items() if abs(v) <= AXES[ax][0]}
    for n, v in back.items():                    # ramps from the value it now holds
        assert abs(g.offset(n, ax) - v) <= AXES[ax][1] + 1e-12, (n, g.offset(n, ax), v)
    if case == "external_change":
        assert "external_change" in g.alarms(41, ax) and "external_change@X" in g.alarms(41)
        assert g.offset(41, ax) != ref.offset(41, ax)
    stopped = log[-1]
    assert stopped["event"] == "stopped" and "last_offset_um" not in stopped
    assert stopped["offsets_um"] == {a: g.offset(60, a) for a in model.axes}


def test_the_logs_warm_start_carrying_a_value_beyond_the_clamp(box, tmp_path):
    """Run 1 writes a log; its last line's Z is then set to 50 (as a looser config
    would have left it). Run 2 warm-starts from it: Z is held with
    ``held_beyond_clamp`` (source ``log``) while no line reports Z, X and Y continue
    exactly as one process would have; a line reporting Z = 1.0 releases it."""
    _, model, rows = box
    rows = rows[:60]
    one = _reference(tmp_path, model, rows)
    first, _ = go(tmp_path, model, rows[:30], {ax: 0.0 for ax in model.axes}, AXES,
                  log="split.log")
    lines = (tmp_path / "split.log").read_text().splitlines()
    i = max(j for j, x in enumerate(lines) if '"state"' in x)
    doc = json.loads(lines[i])
    doc["axes"]["Z"]["offset_um"] = 50.0
    lines[i] = json.dumps(doc)
    (tmp_path / "split.log").write_text("\n".join(lines) + "\n")
    for release in (None, 5):                  # Z never reported; reported after 5
        (tmp_path / "warm.log").write_text((tmp_path / "split.log").read_text())

        def on_advance(g, n, release=release):
            if n == release:                      # the gateway reads Z back: 1.0
                g.held["Z"] = 1.0
                g.report.add("Z")
        g = Gateway(rows[30:], dict(first.held, Z=50.0), on_advance=on_advance,
                    report=("X", "Y"))
        cfg = load_config(config(tmp_path, AXES, "warm.log"), model)
        assert run_jsonl(model, cfg, g, g, Status(0, io.StringIO())) == 0
        assert g.beyond(AXES) == ([], [])
        log = [json.loads(x) for x in (tmp_path / "warm.log").read_text().splitlines()]
        i0 = max(j for j, e in enumerate(log) if e.get("event") == "started")
        assert log[i0]["start"] == "warm" and log[i0]["offsets_um"]["Z"] is None
        ev = log[i0 + 1]
        assert ev["event"] == "held_beyond_clamp" and ev["axis"] == "Z" \
            and ev["source"] == "log" and ev["controller_offset_um"] == 50.0
        for n in range(1, 31):
            z = g.answers[n - 1]["axes"]["Z"]
            if release is None or n <= release:
                assert z["offset_um"] is None and "held_beyond_clamp" in z["alarms"], n
            else:
                assert z["offset_um"] is not None and not z["held"], (n, z)
            for ax in ("X", "Y"):
                assert g.offset(n, ax) == one.offset(n + 30, ax), (n, ax)
        if release is not None:
            assert abs(g.offset(release + 1, "Z") - 1.0) <= 0.1 + 1e-12


def _args(model_path, cfg, **kw):
    base = {"model": str(model_path), "live": str(cfg), "record": None, "out": None,
            "max_offset_um": math.inf, "max_step_um": math.inf, "axis_limits": None,
            "probe_every": None, "score_from": None, "force": False, "limits": None}
    return SimpleNamespace(**{**base, **kw})


def test_limits_typed_with_live_tighten_the_config(box, tmp_path):
    """The issue's run: a config of 15/0.3, 2/0.2, 3/0.1 and --axis-limits X=0.01:0.0005
    Y=0.3:0.02 Z=3:0.1 -- every write within the TYPED limits; the started line names
    them. One axis: --max-offset-um 1 --max-step-um 0.05 over a config of 3/0.1."""
    run_dir, model, rows = box
    typed = {"X": (0.01, 0.0005), "Y": (0.3, 0.02), "Z": (3.0, 0.1)}
    cfg = config(tmp_path, AXES, "cli.log")
    g = Gateway(rows[:60], {ax: 0.0 for ax in model.axes})
    args = _args(run_dir / "model.json", cfg,
                 axis_limits=[f"{a}={c}:{s}" for a, (c, s) in typed.items()])
    assert run_live(args, g, g, Status(0, io.StringIO())) == 0
    assert len(g.writes) == 3 * 60 and g.beyond(typed) == ([], [])
    for ax in typed:                      # the typed limits bind (the config's would not)
        assert any(f"rate_limited@{ax}" in a["alarms"] or f"clamped@{ax}" in a["alarms"]
                   for a in g.answers), ax
    started = json.loads((tmp_path / "cli.log").read_text().splitlines()[0])
    assert started["limits_um"]["X"] == {"max_offset_um": 0.01, "max_step_um": 0.0005}
    # one axis
    model1 = ar1_model(0.99, 1e-3, dtau_s=60.0)
    write_model(tmp_path / "m1.json", model1)
    cfg1 = config(tmp_path, ONE, "one.log", "one.toml")
    g1 = Gateway(q_rows(60), {None: 0.0})
    assert run_live(_args(tmp_path / "m1.json", cfg1, max_offset_um=1.0, max_step_um=0.05),
                    g1, g1, Status(0, io.StringIO())) == 0
    assert g1.beyond({None: (1.0, 0.05)}) == ([], [])
    assert max(abs(w.value) for w in g1.writes) == 1.0            # the typed clamp binds
    with pytest.raises(InputError, match="--max-step-um: .*looser than the config"):
        run_live(_args(tmp_path / "m1.json", cfg1, max_step_um=0.5), g1, g1)
    with pytest.raises(InputError, match="--axis-limits: .*for axis X is looser"):
        run_live(_args(run_dir / "model.json", cfg, axis_limits=["X=20:0.1"]), g, g)


@pytest.mark.parametrize("extra, key", [
    (["--probe-every", "nonsense"], "--probe-every"),
    (["--score-from", "5"], "--score-from"),
    (["--score-from", "0"], "--score-from"),
    (["--force"], "--force"),
    (["--max-offset-um", "nan"], "--max-offset-um"),
    (["--max-offset-um", "30"], "--max-offset-um"),
    (["--axis-limits", "X=1:0.1"], "--axis-limits"),
])
def test_options_a_live_run_cannot_honour_are_refused_in_one_line(tmp_path, extra, key):
    write_model(tmp_path / "m.json", ar1_model(0.99, 1e-3, dtau_s=60.0))
    cfg = config(tmp_path, {None: (20.0, 0.5)})
    p = subprocess.run([sys.executable, "-m", "arfem", "compensate", str(tmp_path / "m.json"),
                        "--live", str(cfg), *extra], input='{"time_s": 60, "q_W_m2": 1}\n',
                       capture_output=True, text=True, timeout=300)
    err = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode == 2 and len(err) == 1 and key in err[0], err
    assert err[0].startswith("arfem: error:") and p.stdout == ""
    assert not (tmp_path / "live.log").exists()


def test_random_streams_never_answer_beyond_a_clamp(box, tmp_path):
    """40 streams, one axis and three alternately, each line's read-back drawn at random:
    the value last written (70 %), a change by hand inside the clamp, a value beyond it
    (up to 1e300), NaN, or nothing reported."""
    _, model3, rows3 = box
    model1 = ar1_model(0.99, 1e-3, dtau_s=60.0)
    rng = np.random.default_rng(40)
    n_answers = n_held = 0
    for s in range(40):
        model, limits, rows = ((model1, ONE, q_rows(80)) if s % 2 == 0
                               else (model3, AXES, rows3[:80]))
        axes = list(limits)

        def on_advance(g, n):
            for ax in axes:
                r = rng.random()
                clamp = limits[ax][0]
                if r < 0.70:
                    continue
                g.held[ax] = (rng.uniform(-clamp, clamp) if r < 0.80 else
                              float(rng.choice([1.5 * clamp, -50.0, 1e300])) if r < 0.88
                              else math.nan if r < 0.92 else g.held[ax])
                if r >= 0.92:                     # this axis is not reported this line
                    g.report.discard(ax)
                else:
                    g.report.add(ax)
        g, _ = go(tmp_path, model, rows, {ax: 0.0 for ax in axes}, limits,
                  on_advance=on_advance, log=f"r{s}.log")
        n_answers += len(g.answers) * len(axes)
        n_held += sum(1 for a in g.answers for v in ([a["offset_um"]] if "axes" not in a
                      else [x["offset_um"] for x in a["axes"].values()]) if v is None)
    assert n_answers == 40 * 80 * 2 and n_held > 100     # the faults did hold axes
