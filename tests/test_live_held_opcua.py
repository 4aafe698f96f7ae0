"""What the controller holds, over OPC UA (issue 40): a value beyond the clamp is never
taken up, limits typed with ``--live`` are honoured, a change by hand is never jumped
over; one axis (tests/live_fault_machine.py) and three (tests/axes_machine.py).

Both machines are asyncua servers on a free loopback port, written apart from
``arfem twin``, in lockstep on their clock (one interval per write request, also one
that carries only an alarm), recording every offset written with what that axis held
when it came. Faults are injected after request n, so request n + 1 is the first to see
them, whatever the load; nothing depends on timing except the bounds on how long to
wait for the compensator.

What is verified and why:

* the issue's done-criterion, on EVERY write of every axis: |offset| <= the axis's clamp
  and |offset - what the machine held| <= its step, with the limits TYPED on the command
  line, tighter than the config's (``--max-offset-um 10 --max-step-um 0.2`` over 20/0.5;
  ``--axis-limits X=10:0.25 --axis-limits Z=3:0.1`` over 15/0.3 and 50/1);
* a held value beyond the clamp (1e300 at start; 50 mid-run) or not finite (NaN) is not
  written over: that axis's offset node is not written at all (its alarm node is, with
  ``held_beyond_clamp`` / ``held_nonfinite``) until the operator sets a value inside,
  and the first write after is within one step of it; the other axes are written and
  accepted every request, with no such alarm;
* an offset changed by hand mid-run is read back before the next write (the offsets
  are read in the cycle's one read request): ``external_change`` on that request's alarm
  and the write within a step of the new value -- never the 5.8 µm jump of the issue;
* one code path: every offset the three-axis machine received equals (==) that of a
  Compensator stepped in this process through the same rows, given the same read-backs;
* the log's warm start carrying a value beyond the clamp (its last line edited to
  1e300): the state is restored from it, the offsets are not -- the first write is within
  a step of what the machine holds;
* the ``stopped`` line holds one offset per axis and what each axis holds.
"""
from __future__ import annotations

import asyncio
import json
import math
from pathlib import Path

import pytest

pytest.importorskip("asyncua")

from axes_machine import AxesMachine, box_run, write_config as axes_config  # noqa: E402
from live_fault_machine import (FaultMachine, free_port, log_lines,  # noqa: E402
                                paper_model, start_compensator, until, write_config)

# serves OPC UA on a TCP port: one xdist worker runs all such tests (see conftest.py)
pytestmark = pytest.mark.xdist_group("tcp_ports")

CYCLES = 60


def edit_last_state(log: Path, edit) -> None:
    """Apply ``edit`` to the log's last line that holds a state (as a looser config or
    a bad write would have left it)."""
    lines = log.read_text().splitlines()
    i = max(j for j, x in enumerate(lines) if '"state"' in x)
    doc = json.loads(lines[i])
    edit(doc)
    lines[i] = json.dumps(doc)
    log.write_text("\n".join(lines) + "\n")


async def finish(p, what, done):
    try:
        await until(lambda: p.returncode is not None or done(), what)
        return await asyncio.wait_for(p.wait(), 120)
    finally:
        if p.returncode is None:
            p.kill()
            await p.wait()


def test_one_axis_held_values_and_typed_limits(tmp_path):
    clamp, step = 10.0, 0.2                       # typed; the config says 20 / 0.5
    typed = ["--max-offset-um", str(clamp), "--max-step-um", str(step)]
    plan = {5: 3.0, 20: 50.0, 25: -2.0, 35: 5.0, 45: math.nan, 50: 1.0}

    async def on_advance(m, n):
        if n in plan:
            await m.set_held(plan[n])

    async def scenario():
        paper_model(tmp_path)
        m = FaultMachine(free_port(), held_um=1e300, on_advance=on_advance)
        await m.start()
        try:
            cfg = write_config(tmp_path, m.endpoint, cycles=CYCLES)
            p = await start_compensator(tmp_path, cfg, "c1", typed)
            rc = await finish(p, "the cycles", lambda: len(m.requests) >= CYCLES)
            n0 = len(m.requests)
            await m.set_held(-4.0)
            edit_last_state(tmp_path / "live.log", lambda d: d.update(
                offset_um=1e300, controller_offset_um=1e300))
            cfg2 = write_config(tmp_path, m.endpoint, cycles=5, name="live2.toml")
            p = await start_compensator(tmp_path, cfg2, "c2", typed)
            rc2 = await finish(p, "the warm restart", lambda: len(m.requests) >= n0 + 5)
        finally:
            await m.stop()
        return m, rc, rc2, n0

    m, rc, rc2, n0 = asyncio.run(scenario())
    assert rc == rc2 == 0, (tmp_path / "c1.stderr").read_text()
    assert len(m.requests) == CYCLES + 5
    for w in m.writes:                            # the done-criterion, every write
        assert abs(w.value) <= clamp + 1e-12, w
        assert abs(w.value - w.held_before_um) <= step + 1e-9, w
    by = {w.n: w for w in m.writes}
    held = {**{n: "held_beyond_clamp" for n in list(range(1, 6)) + list(range(21, 26))},
            **{n: "held_nonfinite" for n in range(46, 51)}}
    for n in range(1, CYCLES + 6):
        alarm = m.requests[n - 1][1]
        if n in held:
            assert n not in by and held[n] in alarm, (n, alarm)
        else:
            assert n in by and by[n].accepted and "held_" not in alarm, (n, alarm)
    for n, base in ((6, 3.0), (26, -2.0), (36, 5.0), (51, 1.0), (n0 + 1, -4.0)):
        assert by[n].held_before_um == base and abs(by[n].value - base) <= step + 1e-9, n
    assert "external_change" in m.requests[35][1]
    # by hand at 35 only: a restart adopts what it reads (-4.0 at n0 + 1) without alarm
    assert sum("external_change" in a for _, a in m.requests) == 1
    assert any(abs(w.value) == clamp for w in m.writes) or \
        any("rate_limited" in (w.alarm or "") for w in m.writes)
    log = log_lines(tmp_path / "live.log")
    starts = [e for e in log if e.get("event") == "started"]
    assert [s["start"] for s in starts] == ["cold", "warm"]
    assert starts[0]["limits_um"]["offset"] == {"max_offset_um": clamp, "max_step_um": step}
    assert starts[0]["controller_offset_um"] == 1e300
    assert [e["event"] for e in log if e.get("source") == "start"] == ["held_beyond_clamp"]
    stops = [e for e in log if e.get("event") == "stopped"]
    assert len(stops) == 2 and stops[-1]["controller_offset_um"] == by[n0 + 5].value


LIMITS = {"X": (15.0, 0.3), "Y": (2.0, 0.2), "Z": (50.0, 1.0)}       # the config's
TYPED = {"X": (10.0, 0.25), "Y": (2.0, 0.2), "Z": (3.0, 0.1)}        # in effect
HELD = {"X": 3.0, "Y": -1.0, "Z": 50.0}                              # Z beyond 3


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    return box_run(tmp_path_factory.mktemp("box"))


def expected(model, rows, seen) -> dict:
    """What request n should carry per axis (NaN: not written): a Compensator stepped
    here through the same rows, given the read-back ``seen[n]`` before each step."""
    from arfem.models.compensator import Compensator
    axes = model.axes
    comp = Compensator(model, max_offset_um=tuple(TYPED[a][0] for a in axes),
                       max_step_um=tuple(TYPED[a][1] for a in axes))
    comp.resume([seen[1][a] for a in axes])
    out = {}
    for n in range(1, CYCLES + 1):
        for j, a in enumerate(axes):
            comp.resume_axis(j, seen[n][a], readback=True)
        cyc = comp.step({k: v for k, v in rows[n].items() if k != "time_s"})
        out[n] = {x.axis: x.offset_um for x in cyc.axes}
    return out


def test_three_axes_each_fault_on_one_axis_while_the_others_run(box, tmp_path):
    run_dir, model, rows = box
    plan = {10: ("Z", 1.0), 20: ("Y", 9.0), 30: ("Y", -1.5), 40: ("X", 4.0),
            45: ("X", math.nan), 50: ("X", 0.0)}
    not_written = {"Z": set(range(1, 11)), "Y": set(range(21, 31)), "X": set(range(46, 51))}
    seen = {1: dict(HELD)}

    async def on_advance(m, n):
        if n in plan:
            await m.set_held(*plan[n])
        seen[n + 1] = dict(m.held)                 # what request n + 1 reads back

    async def scenario():
        m = AxesMachine(free_port(), rows, held=HELD, on_advance=on_advance)
        await m.start()
        try:
            names = [i.name for i in model.inputs]
            cfg = axes_config(tmp_path, m.endpoint, names, limits=LIMITS, cycles=CYCLES)
            typed = ["--axis-limits", "X=10:0.25", "--axis-limits", "Z=3:0.1"]
            p = await start_compensator(tmp_path, cfg, "c1", typed,
                                        model=run_dir / "model.json")
            rc = await finish(p, "the cycles", lambda: m.requests >= CYCLES)
            n0 = m.requests
            edit_last_state(tmp_path / "live.log", lambda d: (
                d["axes"]["Z"].update(offset_um=1e300),
                d["controller_offsets_um"].update(Z=1e300)))
            cfg2 = axes_config(tmp_path, m.endpoint, names, limits=LIMITS, cycles=5,
                               name="live2.toml")
            p = await start_compensator(tmp_path, cfg2, "c2", typed,
                                        model=run_dir / "model.json")
            rc2 = await finish(p, "the warm restart", lambda: m.requests >= n0 + 5)
        finally:
            await m.stop()
        return m, rc, rc2, n0

    m, rc, rc2, n0 = asyncio.run(scenario())
    assert rc == rc2 == 0, (tmp_path / "c1.stderr").read_text()
    assert m.requests == CYCLES + 5
    for w in m.writes:                            # the done-criterion, every write
        clamp, step = TYPED[w.axis]
        assert abs(w.value) <= clamp + 1e-12, w
        assert abs(w.value - w.held_before_um) <= step + 1e-9, w
    by = {(w.n, w.axis): w for w in m.writes}
    want = expected(model, rows, seen)
    for n in range(1, CYCLES + 1):
        for ax in "XYZ":
            alarm = m.alarms[n - 1][ax]
            if n in not_written[ax]:
                assert (n, ax) not in by and math.isnan(want[n][ax]), (n, ax)
                kind = "held_nonfinite" if ax == "X" else "held_beyond_clamp"
                assert kind in alarm, (n, ax, alarm)
            else:                                 # written, accepted, == in process
                assert by[(n, ax)].accepted and by[(n, ax)].value == want[n][ax], (n, ax)
                assert "held_" not in alarm, (n, ax, alarm)
    for (n, (ax, v)) in plan.items():
        if abs(v) <= TYPED[ax][0]:                # brought inside: one step from it
            w = by[(n + 1, ax)]
            assert w.held_before_um == v and abs(w.value - v) <= TYPED[ax][1] + 1e-9
    assert "external_change" in m.alarms[40]["X"]
    assert all("external_change" not in m.alarms[n - 1][ax] for n in range(1, CYCLES + 1)
               for ax in "YZ")
    assert any(w.value == 3.0 or w.value == -3.0 for w in m.writes if w.axis == "Z") or \
        any("rate_limited" in (w.alarm or "") for w in m.writes if w.axis == "Z")
    log = log_lines(tmp_path / "live.log")
    starts = [e for e in log if e.get("event") == "started"]
    assert [s["start"] for s in starts] == ["cold", "warm"]
    assert starts[0]["limits_um"]["Z"] == {"max_offset_um": 3.0, "max_step_um": 0.1}
    # after the warm start every axis is written at once, from what the machine holds
    # (checked above for every write), not held by the log's 1e300
    assert all((n, ax) in by for n in range(n0 + 1, n0 + 6) for ax in "XYZ")
    assert not any("held_" in a for n in range(n0 + 1, n0 + 6)
                   for a in m.alarms[n - 1].values())
    stop = [e for e in log if e.get("event") == "stopped"][-1]
    assert "last_offset_um" not in stop and set(stop["offsets_um"]) == {"X", "Y", "Z"}
    assert stop["offsets_um"] == {ax: by[(n0 + 5, ax)].value for ax in "XYZ"}
    assert stop["controller_offsets_um"] == stop["offsets_um"]
