"""``arfem compensate --live`` over OPC UA with a version-2 model: three axis nodes
(issue 32 item 5).

The machine is tests/axes_machine.py (an asyncua server on a free loopback port with an
offset and an alarm node per axis X, Y, Z), serving in lockstep the inputs of the record
``arfem run`` wrote for a small box (two heat sources and the ambient; the model's axes
Y, Z, X). Nothing depends on timing except the bounds on how long to wait.

What is verified and why (X: clamp 15 µm, step 0.3 µm; Y: 2 µm, 0.2 µm; Z the common
50 µm, 1 µm):

* bumpless start per axis: the machine holds X = 3, Y = -1, Z = 0.5 µm when the
  compensator connects; each axis's first write is within that axis's step of it;
* for EVERY write of every axis, |offset| <= that axis's clamp and |offset - the value
  that axis held| <= its step (1e-9 µm: float's last digit); the clamps of X and Y bind
  in this run (asserted), Z's does not;
* a refused write on one axis: Y's offset node is made read-only after request 20 and
  writable again after request 30. Y's writes 21-30 are refused, Y's alarm node carries
  ``write_refused`` from the next request until one of Y's writes is accepted, Y's
  command never runs away from the value Y holds; X and Z are written and accepted all
  along and their alarms never name the refusal;
* one code path: every offset the machine received, on every axis, equals (==) that of
  a Compensator stepped in this process through the same inputs, resumed where the
  machine's axes stood (the read-back at start, Y's last accepted value after each
  refusal);
* the cycle log holds each cycle's per-axis offsets before they were written, and
  ``write_refused`` events name their axis.
"""
from __future__ import annotations

import asyncio
import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("asyncua")

from axes_machine import AxesMachine, box_run, write_config  # noqa: E402
from live_fault_machine import free_port, log_lines, until  # noqa: E402

# serves OPC UA on a TCP port: one xdist worker runs all such tests (see conftest.py)
pytestmark = pytest.mark.xdist_group("tcp_ports")

LIMITS = {"X": (15.0, 0.3), "Y": (2.0, 0.2), "Z": (50.0, 1.0)}
HELD = {"X": 3.0, "Y": -1.0, "Z": 0.5}
CYCLES = 60


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    return box_run(tmp_path_factory.mktemp("box"))


def expected(model, rows, refused) -> dict:
    """What each request should have carried: the compensator stepped here, resumed as
    the machine's axes stood (``refused``: request numbers whose Y write was refused)."""
    from arfem.models.compensator import Compensator
    axes = model.axes
    comp = Compensator(model, max_offset_um=tuple(LIMITS[a][0] for a in axes),
                       max_step_um=tuple(LIMITS[a][1] for a in axes))
    comp.resume([HELD[a] for a in axes])
    held_y = HELD["Y"]
    out = {}
    for n in range(1, CYCLES + 1):
        cyc = comp.step({k: v for k, v in rows[n].items() if k != "time_s"})
        out[n] = {a.axis: a.offset_um for a in cyc.axes}
        if n in refused:
            comp.resume_axis(axes.index("Y"), held_y)
        else:
            held_y = out[n]["Y"]
    return out


def test_three_axes_over_opcua_with_a_refused_axis(box, tmp_path):
    run_dir, model, rows = box

    async def on_advance(m, n):
        if n == 20:
            await m.set_writable("Y", False)
        elif n == 30:
            await m.set_writable("Y", True)

    async def scenario():
        m = AxesMachine(free_port(), rows, held=HELD, on_advance=on_advance)
        await m.start()
        try:
            cfg = write_config(tmp_path, m.endpoint, [i.name for i in model.inputs],
                               limits={"X": LIMITS["X"], "Y": LIMITS["Y"]}, cycles=CYCLES)
            err = open(tmp_path / "c.stderr", "w")
            p = await asyncio.create_subprocess_exec(
                sys.executable, "-m", "arfem", "compensate", str(run_dir / "model.json"),
                "--live", str(cfg), stdout=asyncio.subprocess.DEVNULL, stderr=err)
            err.close()
            try:
                await until(lambda: p.returncode is not None or m.requests >= CYCLES,
                            "the cycles")
                rc = await asyncio.wait_for(p.wait(), 120)
            finally:
                if p.returncode is None:
                    p.kill()
                    await p.wait()
        finally:
            await m.stop()
        return m, rc

    m, rc = asyncio.run(scenario())
    assert rc == 0, (tmp_path / "c.stderr").read_text()
    assert m.requests == CYCLES
    by = {(w.n, w.axis): w for w in m.writes}
    for w in m.writes:
        clamp, step = LIMITS[w.axis]
        assert abs(w.value) <= clamp + 1e-9, w
        assert abs(w.value - w.held_before_um) <= step + 1e-9, w
    for ax in "XYZ":
        assert abs(by[(1, ax)].value - HELD[ax]) <= LIMITS[ax][1] + 1e-9
    assert any(abs(w.value) == 15.0 for w in m.writes if w.axis == "X")
    assert any(abs(w.value) == 2.0 for w in m.writes if w.axis == "Y")
    assert all(abs(w.value) < 50.0 for w in m.writes if w.axis == "Z")
    refused = {n for n in range(1, CYCLES + 1) if not by[(n, "Y")].accepted}
    assert refused == set(range(21, 31))
    for n in range(22, 32):
        assert "write_refused" in (by[(n, "Y")].alarm or ""), n
    assert "write_refused" not in (by[(33, "Y")].alarm or "")
    for w in m.writes:
        if w.axis != "Y":
            assert w.accepted and "write_refused" not in (w.alarm or ""), w
    want = expected(model, rows, refused)
    for n in range(1, CYCLES + 1):
        for ax in "XYZ":
            assert by[(n, ax)].value == want[n][ax], (n, ax)
    log = log_lines(tmp_path / "live.log")
    cycles = [e for e in log if "cycle" in e and "axes" in e]
    assert [c["axes"]["X"]["offset_um"] for c in cycles] == \
        [by[(n, "X")].value for n in range(1, CYCLES + 1)]
    ev = [e for e in log if e.get("event") == "write_refused"]
    assert len(ev) == 10 and {e["axis"] for e in ev} == {"Y"}
    assert json.loads(Path(tmp_path / "live.log").read_text().splitlines()[0])["event"] \
        == "started"


def test_axis_config_refusals_are_one_line(box, tmp_path):
    """An axis the model lacks, an axis without its node, a single offset_node for a
    model with several axes: one line, exit 2, before anything is written."""
    import subprocess
    run_dir, model, rows = box
    cfg = write_config(tmp_path, "opc.tcp://127.0.0.1:9/x", [i.name for i in model.inputs])
    good = cfg.read_text()
    cases = {
        "axes.W": good + '[opcua.axes.W]\noffset_node = "ns=2;s=M.w"\n',
        "axes.Z": good.replace('[opcua.axes.Z]\noffset_node = "ns=2;s=M.offset_Z_um"\n'
                               'alarm_node = "ns=2;s=M.alarm_Z"\n', ""),
        "offset_node": good.replace("[opcua]\n", '[opcua]\noffset_node = "ns=2;s=M.o"\n'),
    }
    for key, text in cases.items():
        assert text != good
        (tmp_path / "bad.toml").write_text(text)
        p = subprocess.run([sys.executable, "-m", "arfem", "compensate",
                            str(run_dir / "model.json"), "--live", str(tmp_path / "bad.toml")],
                           capture_output=True, text=True, timeout=300)
        err = [ln for ln in p.stderr.splitlines() if ln.strip()]
        assert p.returncode == 2 and len(err) == 1 and key in err[0], (key, err)
        assert not (tmp_path / "live.log").exists()


def test_a_lost_server_that_comes_back_is_read_back_per_axis(box, tmp_path):
    """The machine goes away after request 15 and comes back with other offsets on its
    axes (set by hand meanwhile): the cycles in between hold with ``connection_lost``
    and send nothing, the compensator reconnects and each axis's first write after it is
    within that axis's step of what the axis now holds (and so is every write). The
    loop runs until SIGTERM, sent once the machine has seen 15 requests after its
    return, so the count of lost cycles (which depends on the load) is never asserted."""
    import signal
    run_dir, model, rows = box
    back = {"X": -4.0, "Y": 1.5, "Z": -2.0}
    state = {"restarted": False, "task": None}

    async def restart(m):
        await m.stop()
        m.held = dict(back)
        await asyncio.sleep(0.3)
        await m.start()
        state["restarted"] = True

    async def on_advance(m, n):
        if n == 15:
            state["task"] = asyncio.get_running_loop().create_task(restart(m))

    async def scenario():
        m = AxesMachine(free_port(), rows, held=HELD, on_advance=on_advance)
        await m.start()
        try:
            cfg = write_config(tmp_path, m.endpoint, [i.name for i in model.inputs],
                               limits={"X": LIMITS["X"], "Y": LIMITS["Y"]}, cycles=0)
            err = open(tmp_path / "c.stderr", "w")
            p = await asyncio.create_subprocess_exec(
                sys.executable, "-m", "arfem", "compensate", str(run_dir / "model.json"),
                "--live", str(cfg), stdout=asyncio.subprocess.DEVNULL, stderr=err)
            err.close()
            try:
                await until(lambda: state["restarted"] and m.requests >= 30,
                            "15 requests after the return", p)
                p.send_signal(signal.SIGTERM)
                rc = await asyncio.wait_for(p.wait(), 120)
            finally:
                if p.returncode is None:
                    p.kill()
                    await p.wait()
        finally:
            await m.stop()
        return m, rc

    m, rc = asyncio.run(scenario())
    assert rc == 0, (tmp_path / "c.stderr").read_text()
    for w in m.writes:
        clamp, step = LIMITS[w.axis]
        assert abs(w.value) <= clamp + 1e-9, w
        assert abs(w.value - w.held_before_um) <= step + 1e-9, w
    for ax in "XYZ":
        first = next(w for w in m.writes if w.axis == ax and w.n == 16)
        assert first.held_before_um == back[ax]
        assert abs(first.value - back[ax]) <= LIMITS[ax][1] + 1e-9
    log = log_lines(tmp_path / "live.log")
    assert any(e.get("event") == "reconnected" and
               e.get("controller_offsets_um") == back for e in log)
    lost = [e for e in log if "cycle" in e and "connection_lost" in e.get("alarms", [])]
    assert lost and all(e["held"] and not e["sent"] for e in lost)
    assert log[-1]["event"] == "stopped"
