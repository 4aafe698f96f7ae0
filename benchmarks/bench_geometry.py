"""Benchmark of the geometry path (issue 32): the shipped spindle unit from its .msh.

Prints, per stage, wall and CPU time: mesh read, heat assembly, elastic assembly and
factorisation (or AMG set-up) with the sensors' adjoint solves, and the 24 h reduced solve
of all sensors (sampled every minute); then peak memory (ru_maxrss), the Krylov size, and
the reduced solve against Crank–Nicolson at Δt = 60 s on the same model (max difference
per sensor); with ``--cn30`` also CN at 30 s, i.e. CN's own Δt error, and the reduced
solve against the Richardson extrapolation of the two.

    python benchmarks/bench_geometry.py [--scenario scenarios/data/spindle_unit.toml] [--no-cn]
                                        [--cn30]

Targets (issue 32): ≤ 20 s and ≤ 4 GB for read + assembly + 24 h reduced solve on a
2-core machine. Quote the load (uptime) with the figures.
"""
from __future__ import annotations

import argparse
import os
import resource
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenario", default=str(Path(__file__).resolve().parents[1]
                                              / "scenarios" / "data" / "spindle_unit.toml"))
    ap.add_argument("--no-cn", action="store_true", help="skip the Crank–Nicolson comparison")
    ap.add_argument("--cn30", action="store_true",
                    help="also Crank–Nicolson at dt = 30 s: CN's own dt error, and the reduced "
                         "solve against the Richardson extrapolation (4 CN30 − CN60)/3")
    args = ap.parse_args()
    from arfem.fem.thermal3d import solve_body_theta
    from arfem.scenarios.geometry.scenario import (build_geometry_model,
                                                   load_geometry_scenario, solve_geometry)
    print("load:", os.getloadavg())
    c0, w0 = time.process_time(), time.perf_counter()
    cpu_at = [("load scenario", c0)]

    rss_at = []

    def mark(stage):                    # CPU time per stage, from the progress messages
        cpu_at.append((stage, time.process_time()))
        rss_at.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6)
    sc = load_geometry_scenario(args.scenario)
    sc = type(sc)(**{**sc.__dict__, "fields": False})
    model = build_geometry_model(sc, progress=mark)
    run = solve_geometry(model, progress=mark)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    cpu_at.append(("end", time.process_time()))
    t = run.timings_s
    print(f"mesh: {model.gmesh.mesh.nelements} {model.gmesh.cell_type} cells, "
          f"{model.thermal.ndofs} temperature and {model.elastic.ndofs} displacement unknowns"
          f", elastic factor nnz {model.elastic.nnz_factor}")
    for k, v in t.items():
        print(f"  {k:<18} {v:8.2f} s wall")
    rss_at.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6)
    print("CPU by stage (and the peak RSS at its end):")
    for (k, a), (_, b), r in zip(cpu_at[:-1], cpu_at[1:], rss_at):
        print(f"  {k:<38} {b - a:8.2f} s CPU  {r:5.2f} GB")
    its = getattr(model.elastic.factor, "iterations", None) if model.elastic else None
    if its:
        print(f"elastic adjoints by CG ({type(model.elastic.factor).__name__}): {its} iterations")
    print(f"total: {wall:.2f} s wall, {cpu:.2f} s CPU (this process, all threads); "
          f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6:.2f} GB; "
          f"memory estimate {model.memory_estimate_bytes / 1e9:.2f} GB")
    print(f"reduced: {run.result.n_modes} modes; sensors at peak:")
    for k, v in run.sensor_series().items():
        print(f"  {k:<20} peak {v[np.argmax(np.abs(v - (20.0 if k.startswith('T_') else 0)))]:10.4f}")
    if not args.no_cn:
        c1 = time.process_time()
        cn = solve_body_theta(model.thermal, model.history, model.G, 60.0)
        pick = np.searchsorted(cn.times_s, run.result.times_s - 1e-6)
        diff = np.max(np.abs(cn.outputs[pick] - run.result.outputs), axis=0)
        rng = np.max(np.abs(run.result.outputs), axis=0)
        print(f"Crank–Nicolson dt = 60 s ({time.process_time() - c1:.1f} s CPU): "
              "max |reduced − CN| per sensor, relative to the sensor's max:")
        for s, d, r in zip(sc.sensors, diff, rng):
            print(f"  {s.name:<20} {d / r if r else 0.0:.2e}")
        if args.cn30:
            cn30 = solve_body_theta(model.thermal, model.history, model.G, 30.0)
            y30 = cn30.outputs[np.searchsorted(cn30.times_s, run.result.times_s - 1e-6)]
            y60 = cn.outputs[pick]
            rich = (4 * y30 - y60) / 3
            print("CN's own dt error |CN30 − CN60| and |reduced − Richardson(CN30, CN60)|, "
                  "relative to the sensor's max:")
            for j, s in enumerate(sc.sensors):
                r = rng[j] if rng[j] else 1.0
                print(f"  {s.name:<20} {np.max(np.abs(y30[:, j] - y60[:, j])) / r:.2e}  "
                      f"{np.max(np.abs(rich[:, j] - run.result.outputs[:, j])) / r:.2e}")


if __name__ == "__main__":
    main()
