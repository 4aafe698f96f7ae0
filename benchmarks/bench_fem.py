"""FEM benchmark: the whole 24 h paper cycle, q = 2000 W/m², growth at every 30 s step.

Cases (each in its own process, so peak memory is per case):

* ``axi-theta``  axisymmetric default mesh, Crank–Nicolson Δt = 30 s   (target ≤ 0.5 s)
* ``axi-modal``  axisymmetric default mesh, exact modal solution at the same 2881 times
* ``3d-theta``   3D 20-node serendipity mesh (default of ``build_3d``), Crank–Nicolson
                 (targets ≤ 30 s, ≤ 4 GB, growth within 0.2 % of the axisymmetric one)
* ``3d-theta-coarse``  the same with n_core=2 (the mesh measured in the brief)

Every case also builds the thermo-elastic operator and reports the far-face
average and the on-axis growth at every step (adjoint vectors, see fem.elastic).
Printed: dofs (heat / elastic), wall times of build, solve and growth, peak RSS.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_fem.py [--cases axi-theta,3d-theta]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CASES = ["axi-theta", "axi-modal", "3d-theta", "3d-theta-coarse"]


def run_case(name: str) -> dict:
    import numpy as np
    from arfem.fem.elastic import ThermoElastic
    from arfem.fem.heat import build_3d, build_axisymmetric, solve_modal, solve_theta
    from arfem.params import Rod, paper_cycle

    rod = Rod()
    sched = paper_cycle(2000.0)
    t0 = time.perf_counter()
    if name.startswith("axi"):
        model = build_axisymmetric(rod)
    elif name == "3d-theta-coarse":
        model = build_3d(rod, n_core=2, n_ring=2, nz=16)
    else:
        model = build_3d(rod)
    t1 = time.perf_counter()
    te = ThermoElastic.build(model)
    t2 = time.perf_counter()
    if name.endswith("modal"):
        res = solve_modal(model, sched, output_times_s=np.arange(0.0, sched.total_s + 1, 30.0),
                          store_fields=True)
    else:
        res = solve_theta(model, sched, 30.0, store_fields=True)
    t3 = time.perf_counter()
    face, axis = te.growth(res.fields)
    t4 = time.perf_counter()
    return {
        "case": name, "heat_dofs": model.ndofs, "elastic_dofs": te.ndofs,
        "steps": int(res.times_s.size - 1),
        "build_heat_s": t1 - t0, "build_elastic_s": t2 - t1, "solve_s": t3 - t2,
        "growth_s": t4 - t3, "total_s": t4 - t0,
        "peak_growth_um": float(res.growth_um.max()),
        "peak_face_um": float(face.max() * 1e6), "peak_axis_um": float(np.nanmax(axis) * 1e6),
        "growth_um": (res.growth_um).tolist(),
        "peak_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="FEM paper-cycle benchmark")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--_one", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args._one:
        print(json.dumps(run_case(args._one)))
        return 0
    import numpy as np
    out = {}
    for c in args.cases.split(","):
        p = subprocess.run([sys.executable, __file__, "--_one", c], capture_output=True,
                           text=True, cwd=ROOT)
        if p.returncode:
            print(p.stderr, file=sys.stderr)
            return 1
        out[c] = json.loads(p.stdout.strip().splitlines()[-1])
    print(f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    hdr = (f"{'case':<17}{'dofs':>12}{'steps':>6}{'build_s':>9}{'solve_s':>9}{'growth_s':>9}"
           f"{'total_s':>9}{'RSS_MB':>8}{'peak_um':>10}{'axis_um':>10}")
    print(hdr)
    for c, r in out.items():
        print(f"{c:<17}{r['heat_dofs']:>5}/{r['elastic_dofs']:<6}{r['steps']:>6}"
              f"{r['build_heat_s'] + r['build_elastic_s']:>9.2f}{r['solve_s']:>9.2f}"
              f"{r['growth_s']:>9.3f}{r['total_s']:>9.2f}{r['peak_rss_MB']:>8.0f}"
              f"{r['peak_growth_um']:>10.4f}{r['peak_axis_um']:>10.4f}")
    if "axi-theta" in out:
        ref = np.asarray(out["axi-theta"]["growth_um"])
        for c, r in out.items():
            if c == "axi-theta":
                continue
            g = np.asarray(r["growth_um"])
            print(f"{c}: max |growth − axi-theta| = {np.max(np.abs(g - ref)):.2e} µm = "
                  f"{np.max(np.abs(g - ref)) / ref.max() * 100:.3f} % of peak")
    return 0


if __name__ == "__main__":
    sys.exit(main())
