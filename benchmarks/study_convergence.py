"""Mesh and time-step convergence of the paper-cycle peak growth (q = 2000 W/m²).

Prints one table per study with the peak growth [µm] at t = 9.5 h, the observed
order and the Richardson estimate of the remaining error. Run:

    python benchmarks/study_convergence.py            # axisymmetric + time step + 3D
    python benchmarks/study_convergence.py --no-3d    # skip the (slower) 3D study

The CI checks the same numbers in ``tests/test_fem_convergence.py`` (3D: ``-m slow``).
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import time


from scipy.optimize import brentq

from arfem.fem.heat import build_3d, build_axisymmetric, solve_theta
from arfem.params import Rod, Schedule, paper_cycle

ROD = Rod()
CYCLE = paper_cycle(2000.0)
TO_PEAK = Schedule(CYCLE.durations_s[:3], CYCLE.q_W_m2[:3])


def richardson(h, g):
    """(order p, limit) from three values at sizes h (any ratios)."""
    h1, h2, h3 = map(float, h)
    g1, g2, g3 = map(float, g)
    ratio = (g1 - g2) / (g2 - g3)
    p = brentq(lambda p: (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - ratio, 0.05, 12.0)
    return p, g3 + (g3 - g2) * h3 ** p / (h2 ** p - h3 ** p)


def peak_um(model, dt_s=30.0) -> float:
    return float(solve_theta(model, TO_PEAK, dt_s).growth_um[-1])


def table(title, rows, g_inf, p):
    print(f"\n{title}")
    print(f"{'mesh':<42}{'dofs':>7}{'peak_um':>14}{'err_est_um':>13}{'wall_s':>9}")
    for label, n, g, w in rows:
        print(f"{label:<42}{n:>7}{g:>14.7f}{g - g_inf:>13.2e}{w:>9.2f}")
    print(f"Richardson (3 finest): order {p:.2f}, limit {g_inf:.7f} µm")


def study(label_fn, build_fn, params, h_fn):
    rows = []
    for prm in params:
        t0 = time.perf_counter()
        m = build_fn(prm)
        g = peak_um(m)
        rows.append((label_fn(prm), m.ndofs, g, time.perf_counter() - t0))
    p, g_inf = richardson([h_fn(q) for q in params[-3:]], [r[2] for r in rows[-3:]])
    return rows, p, g_inf


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-3d", action="store_true", help="skip the 3D study")
    args = ap.parse_args(argv)
    print(f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; "
          "peak growth at t = 9.5 h, Crank–Nicolson Δt = 30 s")

    # axisymmetric Q1 refinement (h halves), giving the mesh-converged value
    q1 = [(1, 6), (2, 12), (4, 24), (8, 48), (16, 96)]
    rows, p, g_inf = study(lambda x: f"axi Q1 nr={x[0]} nz={x[1]}",
                           lambda x: build_axisymmetric(ROD, order=1, nr=x[0], nz=x[1]),
                           q1, lambda x: 1.0 / x[0])
    table("Axisymmetric Q1 (ratios 3, 6)", rows, g_inf, p)
    q2 = [(1, 6), (2, 12), (4, 24), (8, 48)]
    rows2 = []
    for nr, nz in q2:
        t0 = time.perf_counter()
        m = build_axisymmetric(ROD, order=2, nr=nr, nz=nz)
        rows2.append((f"axi Q2 nr={nr} nz={nz}" + ("  (default)" if (nr, nz) == (4, 24) else ""),
                      m.ndofs, peak_um(m), time.perf_counter() - t0))
    table("Axisymmetric Q2 against the Q1 Richardson limit", rows2, g_inf, p)
    g_ref = g_inf

    # time step on the default mesh (limit: exact-in-time modal value)
    from arfem.fem.heat import solve_modal
    m = build_axisymmetric(ROD)
    exact = float(solve_modal(m, CYCLE, output_times_s=[9.5 * 3600]).growth_um[0])
    dts = [240.0, 120.0, 60.0, 30.0, 15.0]
    gs = [peak_um(m, dt) for dt in dts]
    p_t, g_t = richardson(dts[-3:], gs[-3:])
    print("\nCrank–Nicolson time step, default axisymmetric mesh")
    print(f"{'dt_s':>8}{'peak_um':>14}{'err_vs_modal_um':>17}")
    for dt, g in zip(dts, gs):
        print(f"{dt:>8.0f}{g:>14.7f}{g - exact:>17.2e}")
    print(f"Richardson: order {p_t:.3f}, limit {g_t:.8f} µm; modal (exact in time) {exact:.8f} µm")

    if not args.no_3d:
        ns = [2, 3, 4]
        rows3, p3, g3 = study(lambda n: f"3D S2 n_core={n} n_ring=2 nz=16" +
                              ("  (default)" if n == 3 else ""),
                              lambda n: build_3d(ROD, n_core=n, n_ring=2, nz=16), ns,
                              lambda n: 1.0 / n)
        table("3D serendipity (20-node) bricks", rows3, g3, p3)
        print(f"3D limit − axisymmetric limit: {g3 - g_ref:+.2e} µm")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"\npeak memory (max RSS): {peak_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
