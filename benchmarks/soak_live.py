"""kill -9 soak of the live compensator (issue 28): never a write beyond the step limit.

Starts the fault machine of ``tests/live_fault_machine.py`` (an asyncua server apart
from ``arfem twin``, on a free loopback port, lockstep on its clock node, recording
every write with what it held when the write came) and ``arfem compensate --live``
against it (clamp 20 µm, step limit 0.5 µm, period 0.05 s, the paper's AR(1)). Then
``--kills`` times (default 20): let the compensator write a random number of times (3 to
40), SIGKILL it at a random moment (0 to 0.2 s later, so also in the middle of a
cycle), sometimes change the controller's offset by hand while it is down (as an
operator or a controller reboot would), and start it again on the same log (warm start).
On the way the machine's clock jumps at random (forward 1e3 to 1e15 s, or back to 0) and
the heat input sometimes reads 1e9 W/m².

Prints: writes, writes beyond the step limit of what the machine held (target 0) and
beyond the clamp (target 0), warm/cold starts, torn log lines seen, and the time to
handle a clock jump -- in process (``clocked_step`` on a jump of 3e6 s, 1e15 s beyond
the horizon, and 1e15 s stepped in closed form) and on the wire (from the write before
a jump to the write after it, against the period).

Run:  python benchmarks/soak_live.py [--kills 20] [--seed 1]
"""
from __future__ import annotations

import argparse
import asyncio
import json
import random
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np



def _fault_machine():
    """``tests/live_fault_machine.py``, loaded from its file (the tests' helper)."""
    import importlib.util
    path = Path(__file__).resolve().parent.parent / "tests" / "live_fault_machine.py"
    spec = importlib.util.spec_from_file_location("live_fault_machine", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod            # (its dataclasses look their module up)
    spec.loader.exec_module(mod)
    return mod


_fm = _fault_machine()
FaultMachine, free_port, CLAMP, STEP = _fm.FaultMachine, _fm.free_port, _fm.CLAMP, _fm.STEP
log_lines, paper_model, start_compensator = _fm.log_lines, _fm.paper_model, \
    _fm.start_compensator
until, write_config = _fm.until, _fm.write_config


def in_process_jump_times() -> dict:
    """Wall time of one clocked_step over a clock jump [s], median of 25."""
    from arfem.models.compensator import Compensator
    from arfem.scenarios.live import Clock, clocked_step
    from arfem.scenarios.model_file import read_model
    d = Path(tempfile.mkdtemp())
    model = read_model(paper_model(d))
    out = {}
    for label, jump, horizon in (("3e6 s (closed form)", 3e6, 1e7),
                                 ("1e15 s beyond the horizon", 1e15, 86400.0),
                                 ("1e15 s in closed form", 1e15, float("inf"))):
        ts = []
        for _ in range(25):
            c = Compensator(model, max_offset_um=CLAMP, max_step_um=STEP)
            _, clock = clocked_step(c, {"q_W_m2": 2000.0}, 60.0, Clock(),
                                    stale_after_s=1e3, max_clock_jump_s=horizon)
            t0 = time.perf_counter()
            clocked_step(c, {"q_W_m2": 2000.0}, 60.0 + jump, clock, stale_after_s=1e3,
                         max_clock_jump_s=horizon)
            ts.append(time.perf_counter() - t0)
        out[label] = float(np.median(ts))
    return out


async def soak(kills: int, seed: int) -> dict:
    rng = random.Random(seed)
    d = Path(tempfile.mkdtemp(prefix="arfem-soak-live-"))
    paper_model(d)
    jumps = {}                                  # write n after which the clock jumped

    async def on_advance(m, n):
        r = rng.random()
        if r < 0.03:
            m.time_s += rng.choice([1e3, 1e5, 3e6, 1e15])
            jumps[n] = True
        elif r < 0.04:
            m.time_s = 0.0
            jumps[n] = True
        m.q = 1e9 if rng.random() < 0.02 else 2000.0

    m = FaultMachine(free_port(), held_um=-9.5, on_advance=on_advance)
    await m.start()
    cfg = write_config(d, m.endpoint)
    stamps = []                                 # (write count, wall time) samples
    p = None
    try:
        for k in range(kills + 1):
            p = await start_compensator(d, cfg, f"c{k}")
            n0 = len(m.writes)
            want = n0 + rng.randint(3, 40)
            t_last = len(m.writes)

            def progress():
                nonlocal t_last
                if len(m.writes) != t_last:
                    t_last = len(m.writes)
                    stamps.append((t_last, time.perf_counter()))
                return len(m.writes) >= want
            await until(progress, f"writes of run {k}", p, timeout=300)
            if k == kills:
                break
            await asyncio.sleep(rng.uniform(0.0, 0.2))
            p.send_signal(signal.SIGKILL)
            await p.wait()
            if rng.random() < 0.3:              # the controller's offset changed meanwhile
                await m.set_held(rng.uniform(-CLAMP, CLAMP))
        p.send_signal(signal.SIGTERM)
        await p.wait()
    finally:
        if p is not None and p.returncode is None:
            p.kill()
            await p.wait()
        await m.stop()
    beyond_step = [w for w in m.writes if abs(w.value - w.held_before_um) > STEP + 1e-9]
    beyond_clamp = [w for w in m.writes if abs(w.value) > CLAMP + 1e-12]
    raw = (d / "live.log").read_text().splitlines()
    torn = 0
    for x in raw:
        try:
            json.loads(x)
        except ValueError:
            torn += 1
    starts = [e.get("start") for e in log_lines(d / "live.log") if e.get("event") == "started"]
    wall = dict(stamps)
    gaps = [wall[n + 1] - wall[n] for n in jumps if n in wall and n + 1 in wall]
    return {"dir": d, "writes": len(m.writes), "beyond_step": beyond_step,
            "beyond_clamp": beyond_clamp, "torn": torn, "starts": starts, "jump_gaps": gaps,
            "jumps": len(jumps)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kills", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    t0 = time.perf_counter()
    r = asyncio.run(soak(a.kills, a.seed))
    print(f"kill -9 restarts: {a.kills}; writes: {r['writes']}; starts: "
          f"{r['starts'].count('warm')} warm, {r['starts'].count('cold')} cold; torn log "
          f"lines: {r['torn']} (log in {r['dir']})")
    print(f"writes beyond the step limit ({STEP} um) of what the machine held: "
          f"{len(r['beyond_step'])} (target 0)")
    print(f"writes beyond the clamp ({CLAMP} um): {len(r['beyond_clamp'])} (target 0)")
    for w in r["beyond_step"][:5]:
        print("   ", w)
    g = np.array(r["jump_gaps"]) * 1e3
    if g.size:
        print(f"clock jumps on the wire: {r['jumps']}; write before -> write after: median "
              f"{np.median(g):.1f} ms, max {g.max():.1f} ms (period 50 ms)")
    for label, s in in_process_jump_times().items():
        print(f"clock jump of {label}: {s * 1e6:.0f} us in process (median of 25)")
    print(f"soak wall time {time.perf_counter() - t0:.1f} s")
    return 0 if not r["beyond_step"] and not r["beyond_clamp"] else 1


if __name__ == "__main__":
    sys.exit(main())
