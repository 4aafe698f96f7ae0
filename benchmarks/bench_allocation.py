"""Benchmark of ``arfem allocate``: a converged allocation, the Monte Carlo yield, and the
pre-fix design read as tolerances.

Prints
1. the machine load it ran under (1-min load average, cores);
2. wall and CPU time of the pallet changer's allocation (population 200) run to pymoo's
   convergence criteria, and of the same run forced through all 1000 generations
   (200 × 1000 = 200,000 evaluations), target <= 60 s;
3. wall time of the Monte Carlo yield of 10⁵ draws at all 5 poses, target <= 2 s;
4. the design published before issue 14 (signed errors on a chain where the rack carried
   the gear, one pose), read as ± tolerances: worst case, RSS, yields.

Run:  python benchmarks/bench_allocation.py
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from arfem.models.allocation import tolerance
from arfem.models.allocation.problem import allocate, unit_values, with_settings
from arfem.models.allocation.scenario import UnitSpec, build_chain, chain_maps
from arfem.models.allocation import screw
from arfem.scenarios.allocation.file import load_allocation_scenario

ROOT = Path(__file__).resolve().parents[1]

#: the picked design of the pre-fix report (commit eb07995, reports/allocation), signed
#: errors per unit: dx dy dz [mm], dalpha dbeta dgamma [mrad]
OLD_DESIGN = {
    "piston": [0.003342994, 0.000182009, 0.000221674, 0.002865532, 0.001595661, 0.004917337],
    "rack": [0.001545986, 0.0000594878, 0.001716268, 0.004852002, 0.003666656, 0.001724148],
    "gear": [0.000218391, 0.004304523, 0.000978094, 0.002132559, 0.0000926006, 0.0000475532],
    "carrier": [0.004959932, 0.004152702, 0.0000298973, 0.004265726, 0.004438644, 0.000230436],
}


def _timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def old_design_as_tolerances():
    """The old chain: piston -> rack (+250 x) -> gear (+40 y, carried by the rack) ->
    carrier (+120 z, turned 180°) -> pallet point (500, 0, 50); one pose."""
    g0 = np.eye(4)
    units = [UnitSpec("piston", "translation", "x", g0, 0.0, (), {}, {}),
             UnitSpec("rack", "translation", "x", screw.pose([250, 0, 0]), 0.0, (), {}, {}),
             UnitSpec("gear", "rotation", "z", screw.pose([0, 40, 0]), 0.0, (), {}, {}),
             UnitSpec("carrier", "rotation", "z", screw.pose([0, 0, 120]), 180.0, (), {}, {})]
    maps, _ = chain_maps(units, screw.pose([500, 0, 50]))
    t = np.concatenate([np.abs(v) * np.array([1, 1, 1, 1e-3, 1e-3, 1e-3])
                        for v in OLD_DESIGN.values()])
    cols = [3, 4, 5, 0, 1, 2]
    J = maps[:, 3:, :][:, :, cols].transpose(0, 2, 1).reshape(24, 3)
    dE = 0.005
    return {"worst_case_um": tolerance.worst_case(t[None], J)[0] * 1e3,
            "rss_um": tolerance.rss(t[None], J)[0] * 1e3,
            "yield_uniform": tolerance.monte_carlo(t, J[None], dE, 100_000, "uniform", 1)["yield"],
            "yield_normal": tolerance.monte_carlo(t, J[None], dE, 100_000, "normal", 1)["yield"]}


def main() -> None:
    print(f"load average (1 min) {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    sc = load_allocation_scenario(ROOT / "scenarios" / "data" / "pallet_changer.toml")
    chain, _ = build_chain(sc)
    st = sc.settings
    r, w, c = _timed(lambda: allocate(chain, st))
    print(f"converged allocation, pop {st.pop_size}: {r.n_generations} generations, "
          f"{r.n_evaluations:,} evaluations, stopped by criteria: {r.converged}; "
          f"wall {w:.1f} s, CPU {c:.1f} s (target <= 60 s)")
    r2, w2, c2 = _timed(lambda: allocate(chain, with_settings(st, converge=False)))
    print(f"forced 200 x 1000: {r2.n_generations} generations, {r2.n_evaluations:,} evaluations; "
          f"wall {w2:.1f} s, CPU {c2:.1f} s (target <= 60 s); hypervolume {r2.history['hv'][-1]:.5f} "
          f"vs {r.history['hv'][-1]:.5f} at convergence")
    X = r.front_X[r.chosen:r.chosen + 1]
    t = unit_values(chain, X)[0] * np.tile([1, 1, 1, 1e-3, 1e-3, 1e-3], 4)
    Jv, _ = chain.sensitivities()
    mc, wm, _ = _timed(lambda: tolerance.monte_carlo(t, Jv, st.delta_E_mm, 100_000, "uniform"))
    print(f"Monte Carlo 10^5 draws x {len(Jv)} poses: wall {wm:.3f} s (target <= 2 s), "
          f"yield {100 * mc['yield']:.2f} %")
    o = old_design_as_tolerances()
    print(f"pre-fix design read as tolerances: worst case {o['worst_case_um']:.2f} um, "
          f"RSS {o['rss_um']:.2f} um, yield uniform {100 * o['yield_uniform']:.1f} %, "
          f"normal (t = 3 sigma) {100 * o['yield_normal']:.1f} % (delta_E = 5 um)")
    print(f"load average (1 min) at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
