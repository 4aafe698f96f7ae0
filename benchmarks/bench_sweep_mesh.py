"""Benchmark of ``arfem sweep`` on a mesh scenario: what reuse between points saves.

Evaluates points of the shipped spindle unit (``scenarios/data/spindle_unit.toml``, P2 unless
``--order 1``) one after the other in this process, as a sweep does, and prints each
point's CPU time (user + system of this process) and what it reused:

1. the base scenario (cold: mesh read, heat and elasticity assembly, factorisation of the
   elastic stiffness, sensor rows, reduced modes);
2. the motor's power scaled (same model, same h: everything reused, the modes too);
3. the housing's h changed (same model: new modes only);
4. the housing's expansion changed (T and the sensor rows rebuilt from the stored
   adjoint solves; new modes, since the rows span the Krylov space);
5. the housing's conductivity changed (K reassembled; new modes);
6. the base again through a fresh process cache (cold, to show the first point's cost
   is not an accident of order).

Each reused point's sensors are compared with a cold build of the same scenario when
``--verify`` is given (doubles the time). Run: python benchmarks/bench_sweep_mesh.py
"""
from __future__ import annotations

import argparse
import os
import time

from arfem.io import read_toml
from arfem.scenarios.rod.scenario import builtin_scenario_path
from arfem.scenarios.rod.deterministic import blas_threads
from arfem.scenarios.geometry.scenario import (build_geometry_model, geometry_scenario_from_dict,
                                               solve_geometry)
from arfem.scenarios.sweep.geometry import (clear_geometry_cache, evaluate_geometry_point,
                                            geometry_override, sensor_metrics)


def cpu() -> float:
    t = os.times()
    return t.user + t.system


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--order", type=int, default=None, help="element order (default: the file's)")
    ap.add_argument("--verify", action="store_true", help="compare with cold builds")
    args = ap.parse_args()
    path = builtin_scenario_path("spindle_unit")
    base = read_toml(path)
    base["geometry"]["mesh"] = str((path.parent / base["geometry"]["mesh"]).resolve())
    if args.order:
        base["geometry"]["order"] = args.order
    steps = [("base (cold)", None, None),
             ("motor power x0.5", "heat_source.motor.scale", 0.5),
             ("housing h 8 -> 16", "convection.housing_outer.h_W_m2K", 16.0),
             ("housing expansion 10.5e-6 -> 12e-6", "material.housing.expansion_1_K", 12e-6),
             ("housing conductivity 48 -> 40", "material.housing.conductivity_W_mK", 40.0)]
    print(f"load average {os.getloadavg()[0]:.1f}; order {base['geometry']['order']}")
    with blas_threads(1):
        for label, key, value in steps:
            data = base if key is None else geometry_override(base, key, value)
            c0, w0 = cpu(), time.perf_counter()
            res = evaluate_geometry_point(data, label)
            m = res["metrics"]
            print(f"{label:<36} CPU {cpu() - c0:7.2f} s  wall {time.perf_counter() - w0:7.2f} s"
                  f"  {m['heat_dofs']} dofs, {m['n_modes']} modes; reused: {m['reused']}")
            if args.verify and key is not None:
                sc = geometry_scenario_from_dict(data, "cold", path.parent)
                cold = sensor_metrics(solve_geometry(build_geometry_model(sc)))
                err = max(abs(m[k] - v) / max(abs(v), 1e-12) for k, v in cold.items())
                print(f"{'':<36} largest relative difference to a cold build {err:.1e}")
        clear_geometry_cache()
        c0, w0 = cpu(), time.perf_counter()
        evaluate_geometry_point(base, "base again")
        print(f"{'base again, cache cleared (cold)':<36} CPU {cpu() - c0:7.2f} s  "
              f"wall {time.perf_counter() - w0:7.2f} s")
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
