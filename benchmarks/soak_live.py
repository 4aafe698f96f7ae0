"""kill -9 soak of the live compensator (issues 28, 40): never a write beyond a clamp or a
step limit, measured from the value the controller holds; one axis and three.

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

Issue 40 adds the controller's own faults, at random on one axis at a time while the
others run: a value beyond the clamp (1.5 x the clamp, 50 µm, 1e300) or NaN set on the
offset node (at start, mid-run, and while the compensator is down), released back inside
the clamp by the "operator" 3 to 12 requests later, and offsets changed by hand inside
the clamp (external changes). ``--axes 3`` runs the same soak against the three-axis
machine of ``tests/axes_machine.py`` with the version-2 model ``arfem run`` writes for
the small box of ``tests/test_model_v2_export.py`` (axes X, Y, Z with their own clamps
and steps: X 15/0.3, Y 2/0.2, Z 3/0.1 µm).

Prints: requests, writes (per axis), writes beyond the step limit of what the machine
held (target 0) and beyond the clamp (target 0), requests on which an axis was not
written because it held a value beyond its clamp (the hold), external changes seen,
warm/cold starts, torn log lines seen, and the time to handle a clock jump -- in process
(``clocked_step`` on a jump of 3e6 s, 1e15 s beyond the horizon, and 1e15 s stepped in
closed form) and on the wire (from the write before a jump to the write after it,
against the period).

Run:  python benchmarks/soak_live.py [--axes 1|3] [--kills 20] [--seed 1] [--model-dir DIR]

``--model-dir DIR``: the three-axis soak with the model of a folder ``arfem run`` wrote
for a mesh scenario, e.g. the shipped spindle unit
(``arfem run scenarios/data/spindle_unit.toml --out DIR``: 197 states, inputs the bearings'
and motor's powers, the ambient and the speed), with the limits issue 40 typed (X
0.01/0.0005, Y 0.3/0.02, Z 3/0.1 µm).
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



def _tests_module(name: str):
    """``tests/<name>.py``, loaded from its file (the tests' helpers: the machines, the
    box scenario), once."""
    if name in sys.modules:
        return sys.modules[name]
    import importlib.util
    path = Path(__file__).resolve().parent.parent / "tests" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod            # (its dataclasses look their module up)
    spec.loader.exec_module(mod)
    return mod


_fm = _tests_module("live_fault_machine")
FaultMachine, free_port, CLAMP, STEP = _fm.FaultMachine, _fm.free_port, _fm.CLAMP, _fm.STEP
log_lines, paper_model, start_compensator = _fm.log_lines, _fm.paper_model, \
    _fm.start_compensator
until, write_config = _fm.until, _fm.write_config

#: the three-axis soak's limits per axis: (clamp, step) [µm], with the box's model
AXES_LIMITS = {"X": (15.0, 0.3), "Y": (2.0, 0.2), "Z": (3.0, 0.1)}
#: ... and with a run folder's (``--model-dir``, e.g. the shipped spindle unit's): the
#: limits issue 40 typed with --axis-limits
RUN_LIMITS = {"X": (0.01, 0.0005), "Y": (0.3, 0.02), "Z": (3.0, 0.1)}


class ControllerFaults:
    """The controller's own faults, one axis at a time (issue 40): with probability
    ``p_beyond`` per request an axis not already held is set beyond its clamp (or NaN)
    and released inside it 3-12 requests later; with ``p_hand`` one is changed by hand
    inside its clamp. ``set_held(axis, value)`` is the machine's."""

    def __init__(self, rng, limits: dict, p_beyond=0.02, p_hand=0.02):
        self.rng, self.limits = rng, limits
        self.p_beyond, self.p_hand = p_beyond, p_hand
        self.release = {}                          # axis -> request to release it at
        self.beyond = self.hand = 0

    def bad_value(self, axis) -> float:
        clamp = self.limits[axis][0]
        return self.rng.choice([1.5 * clamp, -1.5 * clamp, 50.0 + clamp, 1e300,
                                float("nan")])

    async def __call__(self, set_held, n: int) -> None:
        for ax, at in list(self.release.items()):
            if n >= at:
                del self.release[ax]
                await set_held(ax, self.rng.uniform(-1, 1) * self.limits[ax][0])
        r = self.rng.random()
        free = [ax for ax in self.limits if ax not in self.release]
        if r < self.p_beyond and free:
            ax = self.rng.choice(free)
            await set_held(ax, self.bad_value(ax))
            self.release[ax] = n + self.rng.randint(3, 12)
            self.beyond += 1
        elif r < self.p_beyond + self.p_hand and free:
            ax = self.rng.choice(free)
            await set_held(ax, self.rng.uniform(-1, 1) * self.limits[ax][0])
            self.hand += 1

    async def while_down(self, set_held, n: int) -> None:
        """While the compensator is down: an axis set by hand, inside (70 %) or beyond
        its clamp (30 %, released a few requests after the restart)."""
        ax = self.rng.choice([a for a in self.limits if a not in self.release]
                             or list(self.limits))
        if self.rng.random() < 0.3:
            await set_held(ax, self.bad_value(ax))
            self.release[ax] = n + self.rng.randint(3, 12)
            self.beyond += 1
        else:
            await set_held(ax, self.rng.uniform(-1, 1) * self.limits[ax][0])


def in_process_jump_times() -> dict:
    """Wall time of one clocked_step over a clock jump [s], median of 25."""
    from arfem.models.compensator import Compensator
    from arfem.scenarios.live.jsonl import Clock, clocked_step
    from arfem.scenarios.compensation.model_file import read_model
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


class _One:
    """The one-axis machine (tests/live_fault_machine.py) behind the soak's interface."""

    limits = {None: (CLAMP, STEP)}

    def __init__(self, d, on_advance):
        paper_model(d)
        self.model_path = d / "model.json"
        self.m = FaultMachine(free_port(), held_um=-9.5, on_advance=on_advance)
        self.inputs = ["q_W_m2"]

    def config(self, d):
        return write_config(d, self.m.endpoint)

    @property
    def requests(self) -> int:
        return len(self.m.requests)

    async def set_held(self, axis, value):
        await self.m.set_held(value)

    def absurd(self):
        self.m.q = 1e9

    def calm(self):
        self.m.q = 2000.0

    def writes(self) -> list:
        """(request, axis, value, held before) of every offset written."""
        return [(w.n, None, w.value, w.held_before_um) for w in self.m.writes]


class _Three(_One):
    """The three-axis machine (tests/axes_machine.py) with the box's model."""

    limits = AXES_LIMITS

    def __init__(self, d, on_advance, run_dir=None):
        _tests_module("geometry_meshes")           # (the box scenario's imports)
        _tests_module("test_model_v2_export")
        run_dir, model, rows = _tests_module("axes_machine").box_run(d, run_dir)
        self.model_path = run_dir / "model.json"
        if run_dir != d / "run":
            self.limits = RUN_LIMITS
        self.inputs = [i.name for i in model.inputs]
        self.rows = rows
        am = _tests_module("axes_machine")
        self._config = am.write_config
        held = {ax: sign * 0.5 * self.limits[ax][0]      # inside each clamp at start
                for ax, sign in zip(("X", "Y", "Z"), (1, -1, 1))}
        self.m = am.AxesMachine(free_port(), list(rows), held=held, on_advance=on_advance)

    def config(self, d):
        return self._config(d, self.m.endpoint, self.inputs, limits=self.limits)

    @property
    def requests(self) -> int:
        return self.m.requests

    async def set_held(self, axis, value):
        await self.m.set_held(axis, value)

    def absurd(self):
        k = min(self.m.k, len(self.m.rows) - 1)
        heat = next(nm for nm in self.inputs if nm.startswith(("P_", "q_")))
        self.m.rows[k] = dict(self.m.rows[k], **{heat: 1e9})

    def calm(self):
        pass

    def writes(self) -> list:
        return [(w.n, w.axis, w.value, w.held_before_um) for w in self.m.writes]


async def soak(kills: int, seed: int, n_axes: int = 1, run_dir=None) -> dict:
    rng = random.Random(seed)
    d = Path(tempfile.mkdtemp(prefix="arfem-soak-live-"))
    jumps = {}                                  # request n after which the clock jumped
    box = {}

    async def on_advance(m, n):
        r = rng.random()
        if r < 0.03:
            m.time_s += rng.choice([1e3, 1e5, 3e6, 1e15])
            jumps[n] = True
        elif r < 0.04:
            m.time_s = 0.0
            jumps[n] = True
        if rng.random() < 0.02:
            box["m"].absurd()
        else:
            box["m"].calm()
        await box["faults"](box["m"].set_held, n)

    mach = _One(d, on_advance) if n_axes == 1 else _Three(d, on_advance, run_dir)
    box["m"] = mach
    box["faults"] = faults = ControllerFaults(rng, mach.limits)
    await mach.m.start()
    cfg = mach.config(d)
    stamps = []                                 # (request count, wall time) samples
    p = None
    try:
        for k in range(kills + 1):
            p = await start_compensator(d, cfg, f"c{k}", model=mach.model_path)
            want = mach.requests + rng.randint(3, 40)
            t_last = mach.requests

            def progress():
                nonlocal t_last
                if mach.requests != t_last:
                    t_last = mach.requests
                    stamps.append((t_last, time.perf_counter()))
                return mach.requests >= want
            await until(progress, f"requests of run {k}", p, timeout=300)
            if k == kills:
                break
            await asyncio.sleep(rng.uniform(0.0, 0.2))
            p.send_signal(signal.SIGKILL)
            await p.wait()
            if rng.random() < 0.3:              # the controller's offset changed meanwhile
                await faults.while_down(mach.set_held, mach.requests)
        p.send_signal(signal.SIGTERM)
        await p.wait()
    finally:
        if p is not None and p.returncode is None:
            p.kill()
            await p.wait()
        await mach.m.stop()
    writes = mach.writes()
    lim = mach.limits
    beyond_step = [w for w in writes if not abs(w[2] - w[3]) <= lim[w[1]][1] + 1e-9]
    beyond_clamp = [w for w in writes if not abs(w[2]) <= lim[w[1]][0] + 1e-12]
    written = {(w[0], w[1]) for w in writes}
    not_written = sum((n, ax) not in written for n in range(1, mach.requests + 1)
                      for ax in lim)
    raw = (d / "live.log").read_text().splitlines()
    torn = 0
    for x in raw:
        try:
            json.loads(x)
        except ValueError:
            torn += 1
    log = log_lines(d / "live.log")
    starts = [e.get("start") for e in log if e.get("event") == "started"]
    events = {k: sum(e.get("event") == k for e in log)
              for k in ("held_beyond_clamp", "held_nonfinite", "held_cleared",
                        "external_change")}
    wall = dict(stamps)
    gaps = [wall[n + 1] - wall[n] for n in jumps if n in wall and n + 1 in wall]
    return {"dir": d, "requests": mach.requests, "writes": len(writes),
            "per_axis": {ax: sum(w[1] == ax for w in writes) for ax in lim},
            "beyond_step": beyond_step, "beyond_clamp": beyond_clamp,
            "not_written": not_written, "faults_beyond": faults.beyond,
            "faults_hand": faults.hand, "events": events, "torn": torn, "starts": starts,
            "jump_gaps": gaps, "jumps": len(jumps), "limits": lim}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kills", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--axes", type=int, choices=(1, 3), default=1)
    ap.add_argument("--model-dir", type=Path, default=None,
                    help="with --axes 3: a folder arfem run wrote for a mesh scenario "
                         "(model.json, record.toml), e.g. of scenarios/data/spindle_unit.toml; "
                         "limits X 0.01/0.0005, Y 0.3/0.02, Z 3/0.1 um. Default: the "
                         "tests' small box, run here")
    a = ap.parse_args()
    t0 = time.perf_counter()
    r = asyncio.run(soak(a.kills, a.seed, a.axes, a.model_dir))
    lim = ", ".join(f"{ax or 'offset'} {c:g}/{s:g}" for ax, (c, s) in r["limits"].items())
    print(f"{a.axes} axis/axes (clamp/step um: {lim}); kill -9 restarts: {a.kills}; "
          f"requests: {r['requests']}; writes: {r['writes']}"
          + (f" ({', '.join(f'{k} {v}' for k, v in r['per_axis'].items())})"
             if a.axes == 3 else "")
          + f"; starts: {r['starts'].count('warm')} warm, {r['starts'].count('cold')} cold; "
          f"torn log lines: {r['torn']} (log in {r['dir']})")
    print(f"controller faults injected: {r['faults_beyond']} values beyond the clamp or "
          f"NaN, {r['faults_hand']} changes by hand; log events: "
          + ", ".join(f"{k} {v}" for k, v in r["events"].items())
          + f"; axis-requests not written (held): {r['not_written']}")
    print(f"writes beyond the step limit of what the machine held: "
          f"{len(r['beyond_step'])} (target 0)")
    print(f"writes beyond the clamp: {len(r['beyond_clamp'])} (target 0)")
    for w in (r["beyond_step"] + r["beyond_clamp"])[:5]:
        print("   ", w)
    g = np.array(r["jump_gaps"]) * 1e3
    if g.size:
        print(f"clock jumps on the wire: {r['jumps']}; write before -> write after: median "
              f"{np.median(g):.1f} ms, max {g.max():.1f} ms (period 50 ms)")
    if a.axes == 1:
        for label, s in in_process_jump_times().items():
            print(f"clock jump of {label}: {s * 1e6:.0f} us in process (median of 25)")
    print(f"soak wall time {time.perf_counter() - t0:.1f} s")
    return 0 if not r["beyond_step"] and not r["beyond_clamp"] else 1


if __name__ == "__main__":
    sys.exit(main())
