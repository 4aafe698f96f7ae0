"""Benchmark of ``arfem sweep``: the shipped Δτ × h × q sweep, and cost per point.

Prints
1. wall time, points per second and peak memory of the shipped sweep
   (``scenarios/data/sweep_dtau_h.toml``) on local worker processes (all cores),
   then of a resume of the finished store (0 points to compute);
2. time per point against FEM dofs (mesh refinement) at Δτ = 30 s, cold (model
   assembly + dense eigen-decomposition) and warm (eigen-decomposition cached,
   as for a worker's second point with the same h);
3. time per point against the number of AR/FEM time steps (Δτ), warm.

Run:  python benchmarks/bench_sweep.py [--workers N]
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from arfem.scenarios.rod.scenario import apply_override, builtin_scenario_path
from arfem.io import read_toml
from arfem.scenarios.sweep import (blas_threads, clear_worker_cache, evaluate_point,
                                  load_sweep, run_sweep)


def peak_mb() -> tuple[float, float]:
    """Peak resident memory [MB] of this process and of its largest finished child."""
    me = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    ch = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return me, ch


def time_point(data: dict, warm: bool, repeat: int = 3) -> tuple[float, dict]:
    """Best-of-``repeat`` wall time [s] of one point; warm = eigen-decomposition cached."""
    best, res = float("inf"), None
    for _ in range(repeat):
        clear_worker_cache()
        if warm:
            evaluate_point(data)
        t0 = time.perf_counter()
        res = evaluate_point(data)
        best = min(best, time.perf_counter() - t0)
    return best, res["metrics"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=None)
    args = ap.parse_args(argv)
    ncpu = os.cpu_count()
    print(f"machine: {ncpu} cores, load average {os.getloadavg()[0]:.1f}")

    # 1. the shipped sweep
    sweep = load_sweep(ROOT / "scenarios" / "data" / "sweep_dtau_h.toml")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "sweep"
        t0 = time.perf_counter()
        rep = run_sweep(sweep, out, workers=args.workers, progress=False)
        wall = time.perf_counter() - t0
        t1 = time.perf_counter()
        rep2 = run_sweep(sweep, out, workers=args.workers, progress=False)
        wall_resume = time.perf_counter() - t1
    me, ch = peak_mb()
    print(f"\n1. shipped sweep {sweep.name!r}: {rep.n_points} points, {rep.executor}")
    print(f"   wall time            {wall:8.2f} s   (target <= 60 s)")
    print(f"   of which computing   {rep.wall_s:8.2f} s   (incl. worker start-up; rest = "
          "csv, plots, README)")
    print(f"   points per second    {rep.n_points / wall:8.2f}   (end to end)")
    print(f"   resume, 0 to compute {wall_resume:8.2f} s   (computed {rep2.n_computed})")
    print(f"   peak RSS             {me:8.1f} MB main process, {ch:.1f} MB largest worker")

    # 2./3. cost per point (in this process, single-threaded BLAS like a worker)
    base = read_toml(builtin_scenario_path("paper_fig2"))
    with blas_threads(1):
        print("\n2. time per point against mesh size (q = 2000 W/m², h = 55, Δτ = 30 s, "
              "2881 samples)")
        print(f"   {'nr x nz':>8} {'dofs':>6} {'cold [s]':>9} {'warm [s]':>9} "
              f"{'cold/warm':>9} {'peak um':>9}")
        prev = None
        for nr, nz in ((2, 8), (4, 24), (6, 32), (8, 48), (10, 64)):
            d = apply_override(apply_override(base, "fem.mesh.nr", nr), "fem.mesh.nz", nz)
            cold, m = time_point(d, warm=False, repeat=2)
            warm, _ = time_point(d, warm=True, repeat=2)
            print(f"   {nr:>3} x {nz:<3} {m['fem_dofs']:>6} {cold:9.3f} {warm:9.3f} "
                  f"{cold / warm:9.1f} {m['fem_peak_um']:9.4f}")
        print("\n3. time per point against number of time steps (default mesh, warm cache)")
        print(f"   {'dtau_s':>7} {'samples':>8} {'warm [s]':>9} {'us/sample':>10}")
        for dtau in (600, 300, 120, 60, 30, 10):
            d = apply_override(base, "dtau_s", dtau)
            warm, m = time_point(d, warm=True)
            print(f"   {dtau:>7} {m['n_samples']:>8} {warm:9.4f} "
                  f"{1e6 * warm / m['n_samples']:10.1f}")
    me, ch = peak_mb()
    print(f"\npeak RSS after all: {me:.1f} MB main process")
    return 0


if __name__ == "__main__":
    sys.exit(main())
