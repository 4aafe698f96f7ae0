"""Diagnosis benchmark on the real record (issue 30): ``arfem diagnose`` of FL_THERMAL
channels at the default split, timed as whole processes beside ``arfem run
scenarios/data/paper_fig2.toml`` in the same run, in turn (run, diagnose, run, diagnose...),
so that the CPU ratio -- the robust figure on a shared machine -- compares like with
like.

Prints per channel: wall [s], CPU [s] (user + system of the finished child, the
operating system's own accounting, as ``/usr/bin/time`` gives it), peak memory [MB],
and the ratio of its CPU to the median CPU of ``arfem run paper_fig2``; the load
average before and after. Targets (issue 30): one channel <= 10 s wall on this machine
and <= 2.5x the CPU of ``arfem run paper_fig2``.

    python benchmarks/bench_diagnosis_real.py [--channels 2] [--repeat 1]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ARFEM = [sys.executable, "-m", "arfem.scenarios.cli"]


def timed(cmd) -> tuple[float, float, float]:
    """Run ``cmd`` (output discarded); wall [s], CPU [s] and peak RSS [MB] of the child."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed: {proc.stderr.strip()[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    # ru_maxrss of RUSAGE_CHILDREN is the largest child so far: exact for the first, a
    # bound afterwards; each command is therefore also measured in a fresh child below
    return wall, cpu, after.ru_maxrss / 1024


def peak_of(cmd) -> float:
    """Peak RSS [MB] of one run of ``cmd`` alone (a wrapper process of its own)."""
    code = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], "
            "stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    out = subprocess.run([sys.executable, "-c", code, *map(str, cmd)], cwd=ROOT,
                         capture_output=True, text=True, check=True)
    return int(out.stdout.strip()) / 1024


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--channels", type=int, nargs="+", default=[2], choices=range(1, 6),
                    help="FL_THERMAL channels to diagnose (default: 2, the issue's)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each command")
    ap.add_argument("--no-peak", action="store_true",
                    help="skip the extra runs that measure each command's peak memory")
    a = ap.parse_args(argv)
    load0 = os.getloadavg()
    print(f"machine: {os.cpu_count()} cores, load average {load0[0]:.1f} {load0[1]:.1f} "
          f"{load0[2]:.1f} (shared: compare CPU, and the ratio)")
    ref_cpu, ref_wall = [], []
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(a.repeat):
            for ch in a.channels:
                w, c, _ = timed(ARFEM + ["run", "scenarios/data/paper_fig2.toml", "--out",
                                         f"{tmp}/fig2_{ch}_{i}"])
                ref_wall.append(w)
                ref_cpu.append(c)
                w, c, _ = timed(ARFEM + ["diagnose", f"scenarios/data/fl_thermal/fl_thermal_ch{ch}.toml",
                                         "--out", f"{tmp}/ch{ch}_{i}", "--no-progress",
                                         "--speed-engine", "branch"])
                rows.setdefault(ch, []).append((w, c))
        peaks = {}
        if not a.no_peak:
            peaks["fig2"] = peak_of(ARFEM + ["run", "scenarios/data/paper_fig2.toml", "--out",
                                             f"{tmp}/fig2_peak"])
            for ch in a.channels:
                peaks[ch] = peak_of(ARFEM + ["diagnose",
                                             f"scenarios/data/fl_thermal/fl_thermal_ch{ch}.toml",
                                             "--out", f"{tmp}/ch{ch}_peak", "--no-progress",
                                             "--speed-engine", "branch"])
    load1 = os.getloadavg()
    ref = statistics.median(ref_cpu)
    print(f"\narfem run scenarios/data/paper_fig2.toml: CPU {ref:.2f} s (median of {len(ref_cpu)}), "
          f"wall {statistics.median(ref_wall):.1f} s"
          + (f", peak {peaks['fig2']:.0f} MB" if "fig2" in peaks else ""))
    print(f"{'channel':8s} {'wall [s]':>9s} {'CPU [s]':>8s} {'peak [MB]':>10s} "
          f"{'CPU / run paper_fig2':>21s}")
    for ch, r in rows.items():
        w = statistics.median(x[0] for x in r)
        c = statistics.median(x[1] for x in r)
        pk = f"{peaks[ch]:10.0f}" if ch in peaks else f"{'-':>10s}"
        print(f"ch{ch:<6d} {w:9.1f} {c:8.2f} {pk} {c / ref:20.2f}x")
    print(f"targets: <= 10 s wall (this machine), <= 2.5x the CPU of arfem run paper_fig2; "
          f"load average before {load0[0]:.1f}, after {load1[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
