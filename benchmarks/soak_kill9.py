"""kill -9 soak (issue 16): every writing command killed at random times, then run again;
nothing may be lost, duplicated or half-written.

For each of ``sweep``, ``diagnose``, ``reproduce`` and ``allocate``: one clean run into a
reference folder (its wall time sets the range of kill times), then rounds of [start the
command into its soak folder, SIGKILL it at a uniformly random time between 0.05 and 0.9 x
its fastest run so far, run the same command again to the end] until each command has
been killed ``--kills`` times (default 5: 20 kills). After every
re-run the soak folder is checked against the clean one:

- the same files (relative paths), and no staging debris (no hidden temporary file
  inside, no ``.NAME.staging-*`` folder beside it);
- every file parses: JSON, CSV (every row as wide as the header, as many rows as the
  clean run's), TOML, Markdown (UTF-8), PNG (signature and IEND chunk), XDMF (XML);
- the sweep store holds each point once (``points/<key>.json`` = the sweep's keys) and
  ``results.csv`` one row per point with the clean run's numbers (timing excepted).

Inputs are kept small so a round takes seconds: a 12-point coarse sweep, the shipped
recording's first 2000 samples (8.3 h) for ``diagnose``, ``pallet_changer`` for
``allocate``; ``reproduce`` runs the paper's two scenarios as shipped.

Prints kills per command, failures (with what failed), orphans left after a kill, and time.

Run:  python benchmarks/soak_kill9.py [--kills 5] [--seed 1]
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FL = ROOT / "scenarios" / "fl_thermal"

BASE = """[scenario]
name = "coarse"
[cycle]
phases = [
  { duration_h = 4.0,  q_W_m2 = 2000.0 },
  { duration_h = 1.5,  q_W_m2 = 0.0 },
  { duration_h = 4.0,  q_W_m2 = 2000.0 },
  { duration_h = 14.5, q_W_m2 = 0.0 },
]
[ar]
dtau_s = 300.0
[fem]
model = "axisymmetric"
[fem.mesh]
nr = 3
nz = 10
"""
SWEEP = ('[sweep]\nname = "soak"\nbase = "base.toml"\n[sweep.grid]\n'
         'dtau_s = [300, 600]\nh_W_m2K = [20, 55, 150]\nq_W_m2 = [2000, 3000]\n')


def inputs(d: Path) -> dict:
    """Command lines (without --out) of the four commands, on inputs written into ``d``."""
    (d / "base.toml").write_text(BASE, "utf-8")
    (d / "soak.toml").write_text(SWEEP, "utf-8")
    with open(FL / "fl_thermal_whole.csv", encoding="utf-8") as fh:
        (d / "fl_thermal_whole.csv").write_text("".join(next(fh) for _ in range(2001)), "utf-8")
    (d / "case.toml").write_text((FL / "fl_thermal_ch1.toml").read_text("utf-8"), "utf-8")
    return {"sweep": ["sweep", str(d / "soak.toml"), "--workers", "2", "--no-progress"],
            "diagnose": ["diagnose", str(d / "case.toml"), "--force"],
            "reproduce": ["reproduce", "--force"],
            "allocate": ["allocate", str(ROOT / "scenarios" / "pallet_changer.toml"), "--force"]}


def run(argv, out: Path, timeout=900) -> tuple[int, float, str]:
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "arfem", *argv, "--out", str(out)],
                       capture_output=True, text=True, timeout=timeout, cwd=out.parent)
    return p.returncode, time.perf_counter() - t0, p.stderr.strip().splitlines()[-1:] and \
        p.stderr.strip().splitlines()[-1]


def group_alive(pgid: int) -> int:
    """Processes still alive in process group ``pgid`` (orphans of a killed command)."""
    n = 0
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[2]) == pgid and fields[0] != "Z":
                n += 1
    return n


def kill_at(argv, out: Path, at_s: float) -> tuple[bool, int]:
    """Start the command, SIGKILL its main process at ``at_s``; (was it still running,
    processes of its group alive 3 s later — they are then killed too)."""
    p = subprocess.Popen([sys.executable, "-m", "arfem", *argv, "--out", str(out)],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         cwd=out.parent, start_new_session=True)
    try:
        p.wait(timeout=at_s)
        return False, 0                       # finished before the kill time
    except subprocess.TimeoutExpired:
        pass
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    time.sleep(3.0)
    orphans = group_alive(p.pid)
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    return True, orphans


def files(d: Path) -> set[str]:
    return {str(p.relative_to(d)) for p in d.rglob("*") if p.is_file()}


def parse_errors(d: Path, clean: Path) -> list[str]:
    """What is wrong with folder ``d`` against the clean run's folder ``clean``."""
    errs = []
    got, want = files(d), files(clean)
    if got != want:
        errs.append(f"files differ: missing {sorted(want - got)[:3]}, extra {sorted(got - want)[:3]}")
    hidden = [f for f in got if any(part.startswith(".") for part in Path(f).parts)]
    if hidden:
        errs.append(f"hidden temporaries {hidden[:3]}")
    debris = list(d.parent.glob(f".{d.name}.staging-*")) + list(d.parent.glob(f".{d.name}.*"))
    if debris:
        errs.append(f"staging debris {[p.name for p in debris][:3]}")
    for rel in sorted(got & want):
        p = d / rel
        try:
            if p.suffix == ".json":
                json.loads(p.read_text("utf-8"))
            elif p.suffix == ".jsonl":
                [json.loads(x) for x in p.read_text("utf-8").splitlines()]
            elif p.suffix == ".csv":
                rows = list(csv.reader(p.open(encoding="utf-8", newline="")))
                crow = list(csv.reader((clean / rel).open(encoding="utf-8", newline="")))
                if any(len(r) != len(rows[0]) for r in rows) or len(rows) != len(crow):
                    errs.append(f"{rel}: {len(rows)} rows (clean {len(crow)}) or ragged rows")
            elif p.suffix == ".toml":
                tomllib.loads(p.read_text("utf-8"))
            elif p.suffix == ".md":
                p.read_text("utf-8")
            elif p.suffix == ".png":
                b = p.read_bytes()
                if not (b.startswith(b"\x89PNG\r\n\x1a\n") and b"IEND" in b[-16:]):
                    errs.append(f"{rel}: not a whole PNG")
            elif p.suffix in (".xdmf", ".xdmf3"):
                ET.parse(p)
        except Exception as exc:                # noqa: BLE001 - any failure to parse
            errs.append(f"{rel}: {type(exc).__name__}: {exc}"[:160])
    return errs


def sweep_errors(d: Path, clean: Path) -> list[str]:
    errs = []
    keys = json.loads((clean / "summary.json").read_text("utf-8"))
    rows = list(csv.DictReader((d / "results.csv").open(encoding="utf-8")))
    crows = list(csv.DictReader((clean / "results.csv").open(encoding="utf-8")))
    pk = [r["point_key"] for r in rows]
    if len(pk) != len(set(pk)) or len(pk) != keys["n_points"]:
        errs.append(f"results.csv: {len(pk)} rows, {len(set(pk))} distinct keys, "
                    f"want {keys['n_points']}")
    stored = sorted(p.stem for p in (d / "points").glob("*.json"))
    if stored != sorted(r["point_key"] for r in crows):
        errs.append(f"points/: {len(stored)} files, not the sweep's keys once each")
    strip = lambda rs: [{k: v for k, v in r.items() if k != "run_time_s"} for r in rs]
    if strip(rows) != strip(crows):
        errs.append("results.csv numbers differ from the clean run")
    return errs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kills", type=int, default=5, help="kills per command (4 commands)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="arfem-soak-") as tmp:
        d = Path(tmp)
        cmds = inputs(d)
        clean_s = {}
        print("clean runs:")
        for name, argv_ in cmds.items():
            rc, wall, err = run(argv_, d / f"clean_{name}")
            clean_s[name] = wall
            print(f"   {name:<10} exit {rc} in {wall:6.1f} s")
            if rc != 0:
                print(f"   clean run failed: {err}")
                return 1
        stats = {n: {"kills": 0, "finished_first": 0, "failures": 0, "orphans": 0}
                 for n in cmds}
        fails = []
        # rounds until every command has been killed --kills times (a command that ends
        # before its kill time is a round without a kill); kill times track the fastest run
        want = {n: args.kills for n in cmds}
        i = 0
        while any(stats[n]["kills"] < want[n] for n in cmds) and i < 4 * args.kills * len(cmds):
            name = rng.choice([n for n in cmds if stats[n]["kills"] < want[n]])
            i += 1
            out = d / f"soak_{name}"
            at = rng.uniform(0.05, 0.9) * clean_s[name]
            killed, orphans = kill_at(cmds[name], out, at)
            st = stats[name]
            st["kills" if killed else "finished_first"] += 1
            st["orphans"] += orphans
            rc, wall, err = run(cmds[name], out)
            clean_s[name] = min(clean_s[name], wall)
            errs = [f"re-run exit {rc}: {err}"] if rc != 0 else []
            errs += parse_errors(out, d / f"clean_{name}")
            if name == "sweep" and not errs:
                errs += sweep_errors(out, d / f"clean_{name}")
            if errs:
                st["failures"] += 1
                fails.append((name, at, errs))
            print(f"   round {i:>2}: {name:<10} killed at {at:6.2f} s "
                  f"{'(had finished)' if not killed else '':<15} re-run {wall:5.1f} s "
                  f"{'OK' if not errs else 'FAIL: ' + '; '.join(errs)[:200]}", flush=True)
        order = range(i)
    total = time.perf_counter() - t_start
    print(f"\n{'command':<10} {'kills':>6} {'ended first':>12} {'failures':>9} {'orphans':>8}")
    for name, st in stats.items():
        print(f"{name:<10} {st['kills']:>6} {st['finished_first']:>12} {st['failures']:>9} "
              f"{st['orphans']:>8}")
    n_k = sum(s["kills"] for s in stats.values())
    n_f = sum(s["failures"] for s in stats.values())
    print(f"\n{n_k} kills in {len(order)} rounds, {n_f} failures, {total:.0f} s in all")
    for name, at, errs in fails:
        print(f"  {name} killed at {at:.2f} s: {errs}")
    return 1 if n_f else 0


if __name__ == "__main__":
    sys.exit(main())
