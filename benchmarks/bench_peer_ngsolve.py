"""arfem's 3D transient solve against NGSolve, back to back, at four sizes.

The problem is the paper's: steel rod R = 0.1 m, L = 0.8 m, flux q into z = 0 over the
24 h duty cycle (4 h at 2000 W/m², 1.5 h off, 4 h on, 14.5 h off), h = 55 W/(m²K) on
the lateral surface, growth α∫θ dV / A at all 2881 instants of a 30 s grid.

For each size, one after the other in this run, each case in its own child process
(so that its peak memory is its own); the parent polls the child's resident memory and
ends it past 8 GB, so that no size above 8 GB runs to completion on a 24 GB machine:

* ``arfem``     arfem's default 3D solve (``solve_modal`` → reduced-modal on 3D, block
                Krylov Ritz modes), 20-node serendipity bricks (``build_3d``); the
                conductance is factored by PARDISO where the optional ``fast`` extra
                is installed (the note says which);
* ``arfem-superlu`` the same with METIS + SuperLU, i.e. without the ``fast`` extra;
* ``arfem-eigsh`` the reduced-modal solve by eigsh's 8 slowest modes, arfem's default
                before the Krylov reduction (``--modal-sizes``; by default 10k, 40k);
* ``arfem-cn``  arfem's Crank–Nicolson, Δt = 30 s, symmetric factorisation
                (``--cn-sizes``; by default only at the ~10k size);
* ``arfem-cn-lu`` the same with SuperLU's general LU, the factorisation arfem used
                before (the "today" baseline of issue 23), at the same sizes;
* ``ngsolve``   NGSolve's Crank–Nicolson, Δt = 30 s, P2 tetrahedra on a curved
                Netgen mesh of the same cylinder, ``sparsecholesky``, one thread.

Printed per case: dofs, build seconds (mesh + assembly), solve seconds (factorisation
and time loop, or the reduced-modal solve), peak growth [µm], peak RSS [MB]; per size
the ratio NGSolve solve / arfem solve (> 1: arfem faster). One BLAS thread throughout.

    pip install -e ".[bench]"       # NGSolve is a benchmark dependency only
    python benchmarks/bench_peer_ngsolve.py [--sizes 2.5k,10k,40k,150k] [--cn-sizes 10k]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

#: size label -> (arfem (n_core, n_ring, nz) for 20-node bricks, NGSolve maxh [m] for P2)
SIZES = {
    "2.5k": ((3, 2, 16), 0.038),
    "10k": ((5, 3, 26), 0.0245),
    "40k": ((8, 5, 40), 0.0152),
    "150k": ((12, 8, 64), 0.0098),
}
MEM_CAP_BYTES = 8 * 1024 ** 3
DT_S = 30.0
Q_W_M2 = 2000.0


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def case_arfem(size: str, kind: str) -> dict:
    import numpy as np
    from arfem.fem.heat import build_3d, solve_modal, solve_theta
    from arfem.params import Rod, paper_cycle

    nc, nr, nz = SIZES[size][0]
    rod = Rod()
    fine = paper_cycle(Q_W_M2).subdivided(DT_S)
    t0 = time.perf_counter()
    model = build_3d(rod, order=2, n_core=nc, n_ring=nr, nz=nz)
    t1 = time.perf_counter()
    extra = {}
    if kind in ("arfem", "arfem-superlu", "arfem-eigsh"):
        from arfem.fem.linsolve import default_method
        from arfem.fem.reduced import solve_reduced
        if kind == "arfem":
            res = solve_modal(model, fine)
            factor = default_method(few_solves=True, n=model.ndofs)
        else:
            factor = "symmetric"
            res = solve_reduced(model, fine, factor_method=factor,
                                method="eigsh" if kind == "arfem-eigsh" else "krylov")
        extra = {"error_estimate_rel": float(res.error_estimate_m.max() / res.growth_m.max()),
                 "n_modes": res.n_modes, "factor": factor}
    else:
        res = solve_theta(model, fine, DT_S,
                          factor_method="lu" if kind == "arfem-cn-lu" else "symmetric")
    t2 = time.perf_counter()
    assert res.growth_m.size == 2881
    return {"dofs": model.ndofs, "build_s": t1 - t0, "solve_s": t2 - t1,
            "peak_um": float(np.max(res.growth_m) * 1e6), **extra}


def case_ngsolve(size: str) -> dict:
    import ngsolve as ng
    from netgen.occ import Cylinder, OCCGeometry, Pnt, Z
    from arfem.params import Rod, paper_cycle

    rod = Rod()
    R, L = rod.radius_m, rod.length_m
    rhoc = rod.density_kg_m3 * rod.specific_heat_J_kgK
    lam, h, alpha = rod.conductivity_W_mK, rod.convection_W_m2K, rod.expansion_1_K
    ng.SetNumThreads(1)
    t0 = time.perf_counter()
    cyl = Cylinder(Pnt(0, 0, 0), Z, r=R, h=L)
    for f in cyl.faces:
        z = f.center.z
        f.name = "heated" if abs(z) < 1e-9 else ("far" if abs(z - L) < 1e-9 else "lateral")
    mesh = ng.Mesh(OCCGeometry(cyl).GenerateMesh(maxh=SIZES[size][1]))
    mesh.Curve(2)
    fes = ng.H1(mesh, order=2)
    u, v = fes.TnT()
    a = ng.BilinearForm(lam * ng.grad(u) * ng.grad(v) * ng.dx
                        + h * u * v * ng.ds("lateral")).Assemble()
    mstar = ng.BilinearForm(rhoc * u * v * ng.dx
                            + DT_S / 2 * (lam * ng.grad(u) * ng.grad(v) * ng.dx
                                          + h * u * v * ng.ds("lateral"))).Assemble()
    fq = ng.LinearForm(v * ng.ds("heated")).Assemble()
    vol = ng.LinearForm(v * ng.dx).Assemble()
    area = ng.Integrate(1.0, mesh, definedon=mesh.Boundaries("heated"))
    t1 = time.perf_counter()
    inv = mstar.mat.Inverse(fes.FreeDofs(), inverse="sparsecholesky")
    gfu = ng.GridFunction(fes)
    x = gfu.vec
    x[:] = 0.0
    r = x.CreateVector()
    fine = paper_cycle(Q_W_M2).subdivided(DT_S)
    growth = [0.0]
    for q in fine.q_W_m2:
        # (M + Δt/2 A)(x_{n+1} − x_n) = Δt q f_q − Δt A x_n  (Crank–Nicolson, increment form)
        r.data = a.mat * x
        r.data *= -DT_S
        r.data += (DT_S * q) * fq.vec
        x.data += inv * r
        growth.append(alpha * ng.InnerProduct(vol.vec, x) / area)
    t2 = time.perf_counter()
    return {"dofs": fes.ndof, "build_s": t1 - t0, "solve_s": t2 - t1,
            "peak_um": max(growth) * 1e6}


def _child(case: str, size: str) -> None:
    out = case_ngsolve(size) if case == "ngsolve" else case_arfem(size, case)
    out["peak_rss_MB"] = _peak_mb()
    print(json.dumps(out))


def _run(case: str, size: str) -> dict:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1"}
    p = subprocess.Popen([sys.executable, __file__, "--_one", f"{case}:{size}"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    over = False
    while p.poll() is None:                        # resident-memory watchdog (Linux)
        try:
            with open(f"/proc/{p.pid}/status") as fh:
                rss = next((int(ln.split()[1]) * 1024 for ln in fh if ln.startswith("VmRSS")), 0)
        except OSError:
            rss = 0
        if rss > MEM_CAP_BYTES:
            over = True
            p.kill()
            break
        time.sleep(0.2)
    out, err = p.communicate()
    if over:
        return {"error": f"ended: resident memory passed {MEM_CAP_BYTES / 1024 ** 3:.0f} GB"}
    lines = [ln for ln in out.splitlines() if ln.startswith("{")]
    if p.returncode != 0 or not lines:
        tail = (err.strip().splitlines() or ["?"])[-1]
        return {"error": f"exit {p.returncode}: {tail[:200]}"}
    return json.loads(lines[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default=",".join(SIZES))
    ap.add_argument("--cn-sizes", default="10k",
                    help="sizes at which arfem's Crank–Nicolson also runs (both factorisations)")
    ap.add_argument("--modal-sizes", default="10k,40k",
                    help="sizes at which the SuperLU and eigsh variants of the reduced "
                         "solve also run")
    ap.add_argument("--json", help="also write every result to this file")
    ap.add_argument("--_one", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args._one:
        case, size = args._one.split(":")
        _child(case, size)
        return 0
    try:
        import ngsolve  # noqa: F401
    except ImportError:
        print("bench_peer_ngsolve: NGSolve is not installed; pip install -e \".[bench]\"",
              file=sys.stderr)
        return 2
    sizes = [s for s in args.sizes.split(",") if s]
    cn_sizes = {s for s in args.cn_sizes.split(",") if s}
    modal_sizes = {s for s in args.modal_sizes.split(",") if s}
    bad = [s for s in sizes + sorted(cn_sizes | modal_sizes) if s not in SIZES]
    if bad:
        print(f"bench_peer_ngsolve: unknown size(s) {bad}; known: {list(SIZES)}", file=sys.stderr)
        return 2
    print(f"load average at start: {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores, "
          "one BLAS thread per case; each case its own process, ended past 8 GB resident")
    hdr = f"{'size':>5} {'case':<13} {'dofs':>7} {'build s':>8} {'solve s':>8} " \
          f"{'peak µm':>10} {'RSS MB':>7}  note"
    print(hdr)
    results = []
    for size in sizes:
        cases = ["arfem"] \
            + (["arfem-superlu", "arfem-eigsh"] if size in modal_sizes else []) \
            + (["arfem-cn", "arfem-cn-lu"] if size in cn_sizes else []) + ["ngsolve"]
        row = {}
        for case in cases:
            r = _run(case, size)
            row[case] = r
            results.append({"size": size, "case": case, **r})
            if "error" in r:
                print(f"{size:>5} {case:<13} {'—':>7}  {r['error']}")
                continue
            note = ""
            if "error_estimate_rel" in r:
                note = (f"{r['n_modes']} modes, {r['factor']}, "
                        f"stated error {r['error_estimate_rel']:.1e} of peak")
            print(f"{size:>5} {case:<13} {r['dofs']:>7} {r['build_s']:>8.2f} "
                  f"{r['solve_s']:>8.2f} {r['peak_um']:>10.5f} {r['peak_rss_MB']:>7.0f}  {note}",
                  flush=True)
        ng_r, ar = row.get("ngsolve", {}), row.get("arfem", {})
        if "solve_s" in ng_r and "solve_s" in ar:
            dpk = abs(ar["peak_um"] / ng_r["peak_um"] - 1) * 100
            print(f"{size:>5} ratio NGSolve CN solve / arfem default solve = "
                  f"{ng_r['solve_s'] / ar['solve_s']:.1f}x; peaks differ by {dpk:.3f} %")
        if "solve_s" in row.get("arfem-cn", {}) and "solve_s" in row.get("arfem-cn-lu", {}):
            print(f"{size:>5} ratio arfem CN: LU / symmetric = "
                  f"{row['arfem-cn-lu']['solve_s'] / row['arfem-cn']['solve_s']:.2f}x; "
                  f"NGSolve CN / arfem CN = "
                  f"{ng_r.get('solve_s', float('nan')) / row['arfem-cn']['solve_s']:.2f}x")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
