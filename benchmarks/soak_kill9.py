"""kill -9 soak (issues 16 and 29): every writing command killed at random times, then
``arfem report`` on what the kill left, then the command again; nothing may be lost,
duplicated, half-written or left behind, and no folder made unresumable.

Commands: ``run``, ``sweep``, ``compensate``, ``compensate_axes`` (a three-axis replay:
the version-2 model ``arfem run`` writes for the tests' small box, on its record, with
``--axis-limits`` per axis; issue 40), ``allocate`` and ``diagnose``. For each, one
clean run into a reference folder (its wall time bounds the kill times); then rounds of

1. a fresh start (the soak folder removed) or a ``--force`` re-run into the finished
   folder (a sweep: its resume), chosen at random;
2. SIGKILL of the whole process group at a uniformly random time in 0.3 s .. min(6 s,
   0.9 x the command's fastest run so far);
3. ``arfem report`` on the soak folder: exit 0, or exit 2 in one line when the folder is
   absent or arfem's manifest does not show it wrote it (then no ``report.html`` may
   appear); never a traceback;
4. the command again (``--force`` except for the sweep, which resumes) to the end,

until each command has been killed ``--kills`` times (default 10: 60 kills;
``--commands compensate,compensate_axes`` soaks only those). After every
re-run the soak folder is checked against the clean one:

- exit 0; the same files (relative paths); no staging folder ``.arfem-staging-*`` left
  inside it or beside it (counted), no hidden temporary file;
- every file parses: JSON, CSV (every row as wide as the header, as many rows as the
  clean run's), TOML, Markdown (UTF-8), PNG (signature and IEND chunk), XDMF (XML);
- ``report.html`` is listed in ``.arfem-outputs.json`` with its current SHA-256;
- the sweep store holds each point once and ``results.csv`` one row per point with the
  clean run's numbers (timing excepted).

Prints kills per command, fresh/force rounds, report exits, failures (with what failed),
staging folders left after the re-run, orphans left after a kill, and time.

Run:  nice -n 10 python benchmarks/soak_kill9.py [--kills 10] [--seed 1] [--commands a,b]
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import json
import shutil
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
FL = ROOT / "scenarios" / "data" / "fl_thermal"

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
         'dtau_s = [300, 600]\nh_W_m2K = [20, 55, 150]\n')


def inputs(d: Path) -> dict:
    """Command lines (without --out and --force) of the five commands, on inputs written
    into ``d``."""
    import re
    from arfem.api import Rod, ar1, ar1_model, paper_cycle
    from arfem.models.diagnosis.synth import generate
    from arfem.scenarios.compensation.model_file import write_model
    from arfem.scenarios.records.synth_files import write_case
    (d / "base.toml").write_text(BASE, "utf-8")
    (d / "soak.toml").write_text(SWEEP, "utf-8")
    with open(FL / "fl_thermal_whole.csv", encoding="utf-8") as fh:
        (d / "fl_thermal_whole.csv").write_text("".join(next(fh) for _ in range(2001)), "utf-8")
    (d / "case.toml").write_text((FL / "fl_thermal_ch1.toml").read_text("utf-8"), "utf-8")
    a = ar1(Rod(), paper_cycle(2000.0), dtau_s=15.0)
    write_model(d / "model.json", ar1_model(a.C1, a.C2_um_per_W_m2, dtau_s=15.0,
                                             Q_um2=0.01, R_um2=0.01))
    case = generate("none", 46, duration_h=46.3, interval_s=15, jitter_s=0.0, n_gaps=0,
                    empty_fraction=0.0, n_outliers=0)
    rec = write_case(case, d / "rec")
    alloc = (ROOT / "scenarios" / "data" / "pallet_changer.toml").read_text("utf-8")
    alloc = re.sub(r"n_gen\s*=\s*\d+", "n_gen = 50", alloc)
    (d / "alloc.toml").write_text(alloc, "utf-8")
    box = _box_run(d / "box")
    return {"run": ["run", str(d / "base.toml")],
            "sweep": ["sweep", str(d / "soak.toml"), "--workers", "2", "--no-progress"],
            "compensate": ["compensate", str(d / "model.json"), str(rec), "--probe-every",
                           "1h"],
            "compensate_axes": ["compensate", str(box / "model.json"),
                                str(box / "record.toml"), "--axis-limits", "X=15:0.3",
                                "--axis-limits", "Y=2:0.2", "--axis-limits", "Z=3:0.1"],
            "allocate": ["allocate", str(d / "alloc.toml")],
            "diagnose": ["diagnose", str(d / "case.toml")]}


def _box_run(d: Path) -> Path:
    """The folder ``arfem run`` writes for the tests' small box (three axes), written into
    ``d`` (the tests' box scenario, loaded from its file)."""
    import importlib.util
    for name in ("geometry_meshes", "test_model_v2_export"):
        spec = importlib.util.spec_from_file_location(name, ROOT / "tests" / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    d.mkdir()
    scen = sys.modules["test_model_v2_export"].box_scenario(d, 0.0)
    subprocess.run([sys.executable, "-m", "arfem", "run", str(scen), "--out",
                    str(d / "run")], check=True, capture_output=True, timeout=900)
    return d / "run"


def run(argv, out: Path, timeout=900) -> tuple[int, float, str]:
    t0 = time.perf_counter()
    tail = ["--out", str(out)] if argv[0] != "report" else []
    p = subprocess.run([sys.executable, "-m", "arfem", *argv, *tail],
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
    hidden = [f for f in got if any(part.startswith(".") for part in Path(f).parts)
              and f != ".arfem-outputs.json"]
    if hidden:
        errs.append(f"hidden temporaries {hidden[:3]}")
    debris = staging(d)
    if debris:
        errs.append(f"staging folders left {debris[:3]}")
    try:
        man = json.loads((d / ".arfem-outputs.json").read_text("utf-8"))["files"]
        h = hashlib.sha256((d / "report.html").read_bytes()).hexdigest()
        if man.get("report.html") != h:
            errs.append("report.html not in .arfem-outputs.json with its current hash")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        errs.append(f"manifest or report.html unreadable: {exc}"[:120])
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


def staging(d: Path) -> list[str]:
    """Staging folders of arfem inside ``d`` and beside it."""
    return [p.name for p in list(d.glob(".arfem-staging-*"))
            + list(d.parent.glob(".arfem-staging-*"))]


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
    ap.add_argument("--kills", type=int, default=10, help="kills per command (6 commands)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--commands", default=None,
                    help="comma-separated: soak only these (e.g. compensate_axes)")
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    t_start = time.perf_counter()
    print(f"load average {os.getloadavg()[0]:.2f}", flush=True)
    with tempfile.TemporaryDirectory(prefix="arfem-soak-") as tmp:
        d = Path(tmp)
        cmds = inputs(d)
        if args.commands:
            keep = args.commands.split(",")
            unknown = sorted(set(keep) - set(cmds))
            if unknown:
                ap.error(f"--commands: unknown {unknown}; the commands are {sorted(cmds)}")
            cmds = {k: v for k, v in cmds.items() if k in keep}
        clean_s = {}
        print("clean runs:")
        for name, argv_ in cmds.items():
            rc, wall, err = run(argv_, d / f"clean_{name}")
            clean_s[name] = wall
            print(f"   {name:<10} exit {rc} in {wall:6.1f} s", flush=True)
            if rc != 0:
                print(f"   clean run failed: {err}")
                return 1
        stats = {n: {"kills": 0, "finished_first": 0, "fresh": 0, "force": 0, "failures": 0,
                     "orphans": 0, "report_0": 0, "report_2": 0, "report_bad": 0,
                     "staging_left": 0} for n in cmds}
        fails = []
        want = {n: args.kills for n in cmds}
        i = 0
        while any(stats[n]["kills"] < want[n] for n in cmds) and i < 4 * args.kills * len(cmds):
            name = rng.choice([n for n in cmds if stats[n]["kills"] < want[n]])
            i += 1
            # each command in its own folder: the parent holds only its staging folders
            out = d / f"soak_{name}" / "out"
            out.parent.mkdir(exist_ok=True)
            fresh = not out.is_dir() or rng.random() < 0.4
            if fresh:
                shutil.rmtree(out, ignore_errors=True)
            st = stats[name]
            st["fresh" if fresh else "force"] += 1
            force = [] if name == "sweep" else ["--force"]
            at = rng.uniform(0.3, max(0.35, min(6.0, 0.9 * clean_s[name])))
            killed, orphans = kill_at(cmds[name] + force, out, at)
            st["kills" if killed else "finished_first"] += 1
            st["orphans"] += orphans
            errs = []
            had_manifest = (out / ".arfem-outputs.json").is_file()
            had_report = (out / "report.html").is_file()
            p = subprocess.run([sys.executable, "-m", "arfem", "report", str(out)],
                               capture_output=True, text=True, timeout=300, cwd=d)
            lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
            if p.returncode == 0:
                st["report_0"] += 1
            elif p.returncode == 2 and len(lines) == 1 and lines[0].startswith("arfem: error:"):
                st["report_2"] += 1
                if out.is_dir() and had_manifest:
                    errs.append(f"report refused an arfem folder: {lines[0][:160]}")
            else:
                st["report_bad"] += 1
                errs.append(f"report exit {p.returncode}: {(lines[-1] if lines else '')[:160]}")
            if not had_manifest and not had_report and (out / "report.html").exists():
                errs.append("report wrote into a folder arfem's manifest does not own")
            rc, wall, err = run(cmds[name] + force, out)
            clean_s[name] = min(clean_s[name], wall)
            if rc != 0:
                errs.append(f"re-run exit {rc}: {err}")
            left = staging(out)
            st["staging_left"] += len(left)
            if not errs:
                errs += parse_errors(out, d / f"clean_{name}")
            if name == "sweep" and not errs:
                errs += sweep_errors(out, d / f"clean_{name}")
            if errs:
                st["failures"] += 1
                fails.append((name, at, errs))
            print(f"   round {i:>2}: {name:<10} {'fresh' if fresh else 'force':<5} killed at "
                  f"{at:5.2f} s {'(had finished)' if not killed else '':<15} report exit "
                  f"{p.returncode}, re-run {wall:5.1f} s, staging left {len(left)} "
                  f"{'OK' if not errs else 'FAIL: ' + '; '.join(errs)[:200]}", flush=True)
        n_rounds = i
    total = time.perf_counter() - t_start
    print(f"\n{'command':<10} {'kills':>6} {'ended 1st':>9} {'fresh':>6} {'force':>6} "
          f"{'report 0':>9} {'report 2':>9} {'report ?':>9} {'failures':>9} {'staging':>8} "
          f"{'orphans':>8}")
    for name, st in stats.items():
        print(f"{name:<10} {st['kills']:>6} {st['finished_first']:>9} {st['fresh']:>6} "
              f"{st['force']:>6} {st['report_0']:>9} {st['report_2']:>9} {st['report_bad']:>9} "
              f"{st['failures']:>9} {st['staging_left']:>8} {st['orphans']:>8}")
    n_k = sum(s["kills"] for s in stats.values())
    n_f = sum(s["failures"] for s in stats.values())
    n_s = sum(s["staging_left"] for s in stats.values())
    print(f"\n{n_k} kills in {n_rounds} rounds, each followed by arfem report and a re-run: "
          f"{n_f} failures, {n_s} staging folders left after the re-runs, "
          f"{total:.0f} s in all (load average now {os.getloadavg()[0]:.2f})")
    for name, at, errs in fails:
        print(f"  {name} killed at {at:.2f} s: {errs}")
    return 1 if (n_f or n_s) else 0


if __name__ == "__main__":
    sys.exit(main())
