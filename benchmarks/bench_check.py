"""Benchmark: `arfem check scenarios/data/` and `arfem reproduce --check` as a CI job runs them.

Target (issue 12): `arfem check` on the shipped rod scenarios (paper_fig2, paper_fig3)
<= 5 s wall on the 2-core reference machine. Since issue 32 item 4, `arfem check
scenarios/` also solves the shipped spindle unit (a mesh scenario, tens of seconds of
CPU); it is timed once on its own line, without a target (``--no-mesh`` skips it). Each command is timed as a fresh process (what a CI step
pays: interpreter start, imports, FEM assembly and solve of every scenario), best of
``--repeat`` runs, with the peak RSS of that process; the in-process time of the check
alone is printed beside it (the rest is start-up and imports).

    python benchmarks/bench_check.py [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 5.0


_CHILD = ("import resource, sys\n"
          "from arfem.scenarios.cli import main\n"
          "rc = main(sys.argv[1:])\n"
          "print('MAXRSS_KB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, "
          "file=sys.stderr)\n"
          "sys.exit(rc)\n")


def _timed(args: list[str]) -> tuple[float, float, int, str]:
    """(wall s, peak RSS MB, exit status, last output line) of one fresh process running
    ``arfem ARGS`` (the same entry point as the console script)."""
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", _CHILD] + args, cwd=ROOT, capture_output=True,
                       text=True)
    wall = time.perf_counter() - t0
    rss = [ln.split()[1] for ln in p.stderr.splitlines() if ln.startswith("MAXRSS_KB")]
    peak_mb = int(rss[-1]) / 1024 if rss else float("nan")
    last = (p.stdout.strip().splitlines() or [p.stderr.strip()])[-1]
    return wall, peak_mb, p.returncode, last


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-mesh", action="store_true",
                    help="skip the spindle unit's check (a mesh scenario)")
    args = ap.parse_args()
    rods = ["scenarios/data/paper_fig2.toml", "scenarios/data/paper_fig3.toml"]
    arfem: list[str] = []
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        junit = os.path.join(tmp, "junit.xml")
        cases = [("arfem check " + " ".join(rods), arfem + ["check", *rods, "--junit", junit],
                  TARGET_S, args.repeat),
                 ("arfem reproduce --check", arfem + ["reproduce", "--check"], None,
                  args.repeat)]
        if not args.no_mesh:
            cases.append(("arfem check scenarios/data/spindle_unit.toml",
                          arfem + ["check", "scenarios/data/spindle_unit.toml"], None, 1))
        for label, argv, target, repeat in cases:
            runs = [_timed(argv) for _ in range(repeat)]
            best = min(r[0] for r in runs)
            rc, last = runs[-1][2], runs[-1][3]
            peak = max(r[1] for r in runs)
            verdict = "" if target is None else (
                f" (target <= {target:g} s: {'met' if best <= target else 'MISSED'})")
            print(f"{label}: best {best:.2f} s wall of {repeat} fresh processes, "
                  f"median {sorted(r[0] for r in runs)[len(runs) // 2]:.2f} s, peak RSS "
                  f"{peak:.0f} MB, exit {rc}{verdict}")
            print(f"    -> {last}")
            ok &= rc == 0 and (target is None or best <= target)
    # in-process: the check without interpreter start-up and imports
    from arfem.scenarios.rod.checking import run_checks
    t0 = time.perf_counter()
    results, skipped = run_checks([str(ROOT / r) for r in rods], echo=lambda s: None)
    inproc = time.perf_counter() - t0
    print(f"in-process run_checks(paper_fig2, paper_fig3): {inproc:.2f} s for {len(results)} scenarios "
          f"({len(skipped)} files skipped); per scenario "
          + ", ".join(f"{r.scenario} {r.wall_s:.2f} s" for r in results)
          + f"; peak RSS of this process "
            f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    print("targets met" if ok else "TARGET MISSED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
