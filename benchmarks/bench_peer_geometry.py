"""arfem's geometry path against NGSolve on the same spindle-unit ``.msh``, back to back.

For each mesh size, one after the other in this run, each case in its own child process
(so that its peak resident memory, ru_maxrss, is its own):

* ``arfem``   ``arfem run``'s default path without the files: mesh read (meshio),
              assembly (scikit-fem; the elastic one vectorised), elastic adjoints of the
              TCP sensors (CG with the P2/P1 p-multigrid, or SuperLU), the 24 h
              reduced-modal solve of all six sensors;
* ``ngsolve`` the same scenario in NGSolve: the same ``.msh`` read by meshio into a
              Netgen mesh with the same nodes, tetrahedra and named groups
              (``netgen.read_gmsh`` reads only ASCII Gmsh 2 files; the shipped mesh is
              binary Gmsh 4.1), P2 ``H1``/``VectorH1``, the same materials, loads, h(n)
              and clamped foot; Crank–Nicolson at Δt = 60 s, each (Δt, h) matrix factored
              once by ``sparsecholesky``; the TCP sensors by the same adjoint
              (g = TᵀK⁻¹w, point-evaluation functionals); one thread.

Printed per case: wall and CPU [s] by stage (read, assembly, factorisation and adjoints,
solve), total wall and CPU, peak RSS; per size the ratio NGSolve / arfem of total wall and
CPU (> 1: arfem faster) and, per sensor, the largest difference over the 24 h relative to
the sensor's largest value (displacements) or its largest rise above 20 °C (temperatures).

    pip install -e ".[bench,mesh]"
    python benchmarks/bench_peer_geometry.py [--sizes 24,14] [--dt 60]

``--sizes`` are ``SpindleUnit.size`` values [mm] (``size_min`` = size / 3, minimum 5);
24 is the shipped mesh (25k P2 temperature unknowns), 14 about 100k. Quote the load.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCEN = REPO / "scenarios" / "data" / "spindle_unit.toml"


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


class _Clock:
    """Wall and CPU [s] per named stage."""

    def __init__(self):
        self.stages: dict = {}
        self._last = (time.perf_counter(), time.process_time())
        self._name = None
        self.t0 = self._last

    def mark(self, name):
        now = (time.perf_counter(), time.process_time())
        if self._name is not None:
            w, c = self.stages.get(self._name, (0.0, 0.0))
            self.stages[self._name] = (w + now[0] - self._last[0], c + now[1] - self._last[1])
        self._name, self._last = name, now

    def total(self):
        return time.perf_counter() - self.t0[0], time.process_time() - self.t0[1]


def _scenario(mesh: Path) -> Path:
    """The shipped scenario with its mesh replaced (a TOML beside the mesh)."""
    text = SCEN.read_text(encoding="utf-8").replace('mesh = "spindle_unit.msh"',
                                                    f'mesh = "{mesh.name}"')
    out = mesh.with_suffix(".toml")
    out.write_text(text, encoding="utf-8")
    return out


def case_arfem(mesh: Path, dt_s: float) -> dict:
    import numpy as np
    from arfem.scenarios.geometry.scenario import (build_geometry_model,
                                                   load_geometry_scenario, solve_geometry)
    clock = _Clock()
    names = {"reading the mesh": "read", "assembling heat": "assembly",
             "assembling and factoring elasticity":
                 "elastic (assembly, CG set-up/factor, adjoints)",
             "transient heat": "solve (reduced-modal)"}
    sc = load_geometry_scenario(_scenario(mesh))
    sc = type(sc)(**{**sc.__dict__, "fields": False})
    model = build_geometry_model(sc, progress=lambda s: clock.mark(names.get(s, s)))
    run = solve_geometry(model, progress=lambda s: clock.mark(names.get(s, s)))
    clock.mark(None)
    wall, cpu = clock.total()
    el = model.elastic
    return {"ndofs": model.thermal.ndofs, "ndofs_u": model.elastic.ndofs,
            "stages": clock.stages, "wall_s": wall, "cpu_s": cpu, "peak_mb": _peak_mb(),
            "times_s": run.result.times_s.tolist(),
            "outputs": np.asarray(run.result.outputs).T.tolist(),
            "names": [s.name for s in sc.sensors],
            "note": f"{run.result.n_modes} modes; elastic "
                    + (f"{type(el.factor).__name__} CG "
                       f"{getattr(el.factor, 'iterations', [])} iterations"
                       if hasattr(el.factor, "iterations") else f"factor nnz {el.nnz_factor}")}


def _netgen_mesh(path: Path):
    """A Netgen mesh [m] with the .msh's nodes, tetrahedra (one material per physical
    volume) and the triangles of its physical surfaces (one boundary name each)."""
    import meshio
    import numpy as np
    from netgen.meshing import FaceDescriptor, Mesh
    m = meshio.read(str(path))
    phys = m.cell_data["gmsh:physical"]
    names = {(int(v[1]), int(v[0])): k for k, v in m.field_data.items()}
    mesh = Mesh(dim=3)
    mesh.AddPoints(np.ascontiguousarray(m.points * 1e-3))          # mm -> m
    vol_index, bnd_index = {}, {}
    for cb, tags in zip(m.cells, phys):
        if cb.type not in ("tetra", "triangle"):
            continue
        dim = 3 if cb.type == "tetra" else 2
        for tag in np.unique(tags):
            name = names[(dim, int(tag))]
            sel = np.ascontiguousarray(cb.data[tags == tag], dtype=np.int32)
            if dim == 3:
                k = vol_index.setdefault(name, len(vol_index) + 1)
                mesh.SetMaterial(k, name)
                mesh.AddElements(dim=3, index=k, data=sel, base=0)
            else:
                if name not in bnd_index:
                    bnd_index[name] = len(bnd_index) + 1
                    mesh.Add(FaceDescriptor(bc=bnd_index[name], domin=1, domout=0,
                                            surfnr=bnd_index[name]))
                    mesh.SetBCName(bnd_index[name] - 1, name)
                mesh.AddElements(dim=2, index=bnd_index[name], data=sel, base=0)
    return mesh


def case_ngsolve(mesh_path: Path, dt_s: float) -> dict:
    import numpy as np
    import ngsolve as ng
    from arfem.scenarios.geometry.scenario import input_history, load_geometry_scenario
    ng.SetNumThreads(1)
    clock = _Clock()
    sc = load_geometry_scenario(_scenario(mesh_path))
    clock.mark("read")
    mesh = ng.Mesh(_netgen_mesh(mesh_path))
    clock.mark("assembly")
    mats = sc.materials
    mcf = {k: mesh.MaterialCF({g: getattr(mt, k) for g, mt in mats.items()})
           for k in ("conductivity_W_mK", "expansion_1_K")}
    rhoc = mesh.MaterialCF({g: mt.density_kg_m3 * mt.specific_heat_J_kgK
                            for g, mt in mats.items()})
    lam = mesh.MaterialCF({g: mt.lame[0] for g, mt in mats.items()})
    mu = mesh.MaterialCF({g: mt.lame[1] for g, mt in mats.items()})
    V = ng.H1(mesh, order=2)
    u, v = V.TnT()
    hp = [ng.Parameter(0.0) for _ in sc.convections]
    dtp = ng.Parameter(dt_s)

    def cn_form(sign):
        """M ± ½Δt A(h) with Δt and h as parameters."""
        f = rhoc * u * v * ng.dx
        f += sign * 0.5 * dtp * mcf["conductivity_W_mK"] * ng.grad(u) * ng.grad(v) * ng.dx
        for c, h in zip(sc.convections, hp):
            f += sign * 0.5 * dtp * h * u * v * ng.ds(c.spec.group)
        return f
    cols = []
    for s in sc.sources:
        f = ng.LinearForm(v * ng.ds(s.spec.group)).Assemble().vec
        area = ng.Integrate(1.0, mesh, definedon=mesh.Boundaries(s.spec.group))
        cols.append(f.FV().NumPy() / (area if s.spec.kind == "power" else 1.0))
    for c in sc.convections:
        cols.append(ng.LinearForm(v * ng.ds(c.spec.group)).Assemble().vec.FV().NumPy().copy())
    F = np.column_stack(cols)
    # elasticity: clamped foot, thermal load (3λ + 2μ) α θ div v
    W = ng.VectorH1(mesh, order=2, dirichlet=sc.support.group)
    uu, vv = W.TnT()

    def eps(w):
        return ng.Sym(ng.Grad(w))
    Kel = ng.BilinearForm(2 * mu * ng.InnerProduct(eps(uu), eps(vv)) * ng.dx
                          + lam * ng.div(uu) * ng.div(vv) * ng.dx).Assemble()
    T = ng.BilinearForm(trialspace=V, testspace=W)
    T += (3 * lam + 2 * mu) * mcf["expansion_1_K"] * u * ng.div(vv) * ng.dx
    T.Assemble()
    clock.mark("factorisation and adjoints")
    Kinv = Kel.mat.Inverse(W.FreeDofs(), inverse="sparsecholesky")
    G = []
    for s in sc.sensors:
        x, y, z = (float(c) for c in s.point)          # [m], as the scenario holds it
        if s.quantity == "temperature":
            g = ng.LinearForm(V)
            g += v(x, y, z)
            G.append(g.Assemble().vec.FV().NumPy().copy())
            continue
        d = np.asarray(s.direction, float)
        d = d / np.linalg.norm(d)
        wf = ng.LinearForm(W)
        wf += (float(d[0]) * vv[0] + float(d[1]) * vv[1] + float(d[2]) * vv[2])(x, y, z)
        w = wf.Assemble().vec
        zvec = Kel.mat.CreateColVector()
        zvec.data = Kinv * w
        gv = ng.GridFunction(V).vec
        gv.data = T.mat.T * zvec
        G.append(gv.FV().NumPy().copy())
    G = np.column_stack(G)
    hist = input_history(sc).subdivided(dt_s)
    clock.mark("solve (CN time loop)")
    cache = {}
    x = ng.GridFunction(V).vec
    x[:] = 0.0
    rhs = x.CreateVector()
    tmp = x.CreateVector()
    ys = [np.zeros(G.shape[1])]
    for i, d in enumerate(hist.durations_s):
        key = (round(float(d), 6), tuple(hist.h_W_m2K[i]))
        if key not in cache:
            clock.mark("CN matrices (assembly, factorisation)")
            dtp.Set(float(d))
            for h, val in zip(hp, hist.h_W_m2K[i]):
                h.Set(float(val))
            L = ng.BilinearForm(V, symmetric=True)
            L += cn_form(1.0)
            L.Assemble()
            R = ng.BilinearForm(V, symmetric=True)
            R += cn_form(-1.0)
            R.Assemble()
            cache[key] = (L.mat.Inverse(inverse="sparsecholesky"), R.mat, L)
            clock.mark("solve (CN time loop)")
        Linv, R, _ = cache[key]
        tmp.FV().NumPy()[:] = d * (F @ hist.u[i])
        rhs.data = R * x
        rhs.data += tmp
        x.data = Linv * rhs
        ys.append(G.T @ x.FV().NumPy())
    clock.mark(None)
    wall, cpu = clock.total()
    return {"ndofs": V.ndof, "ndofs_u": W.ndof, "stages": clock.stages, "wall_s": wall,
            "cpu_s": cpu, "peak_mb": _peak_mb(), "times_s": hist.edges_s.tolist(),
            "outputs": np.asarray(ys).T.tolist(), "names": [s.name for s in sc.sensors],
            "note": f"CN dt = {dt_s:g} s, {len(cache)} factorisations"}


def _mesh_for(size: float, work: Path) -> Path:
    if size == 24.0:
        return REPO / "scenarios" / "data" / "spindle_unit.msh"
    from arfem.scenarios.geometry.gmsh_models import SpindleUnit, spindle_unit_mesh
    out = work / f"spindle_unit_{size:g}.msh"
    if not out.exists():
        spindle_unit_mesh(out, SpindleUnit(size=size, size_min=max(5.0, size / 3)))
    return out


def _child(case: str, mesh: Path, dt_s: float) -> dict:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, __file__, "--case", case, "--mesh", str(mesh),
                          "--dt", str(dt_s)], capture_output=True, text=True, env=env)
    if out.returncode != 0:
        return {"error": (out.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def _compare(a: dict, b: dict) -> list:
    import numpy as np
    ta, tb = np.asarray(a["times_s"]), np.asarray(b["times_s"])
    ya, yb = np.asarray(a["outputs"]), np.asarray(b["outputs"])
    pick = np.searchsorted(tb, ta - 1e-6)
    rows = []
    for j, n in enumerate(a["names"]):
        ref = np.max(np.abs(ya[j]))
        rows.append((n, float(np.max(np.abs(ya[j] - yb[j][pick])) / ref) if ref else 0.0,
                     float(ya[j][np.argmax(np.abs(ya[j]))]),
                     float(yb[j][pick][np.argmax(np.abs(yb[j][pick]))])))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="24,14")
    ap.add_argument("--dt", type=float, default=60.0)
    ap.add_argument("--case")
    ap.add_argument("--mesh")
    args = ap.parse_args()
    if args.case:
        fn = case_arfem if args.case == "arfem" else case_ngsolve
        print(json.dumps(fn(Path(args.mesh), args.dt)))
        return
    print("load:", os.getloadavg())
    work = Path(tempfile.mkdtemp(prefix="arfem-peer-geometry-"))
    for size in (float(s) for s in args.sizes.split(",")):
        mesh = _mesh_for(size, work)
        res = {c: _child(c, mesh, args.dt) for c in ("arfem", "ngsolve")}
        print(f"\n== SpindleUnit(size={size:g}) {mesh.name}")
        for c, r in res.items():
            if "error" in r:
                print(f"  {c:<8} failed: {r['error']}")
                continue
            print(f"  {c:<8} {r['ndofs']} temperature, {r['ndofs_u']} displacement dofs; "
                  f"{r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} s CPU, peak RSS "
                  f"{r['peak_mb']:.0f} MB ({r['note']})")
            for k, (w, cp) in r["stages"].items():
                print(f"      {k:<42} {w:7.2f} s wall {cp:7.2f} s CPU")
        a, b = res["arfem"], res["ngsolve"]
        if "error" in a or "error" in b:
            continue
        print(f"  NGSolve / arfem: wall {b['wall_s'] / a['wall_s']:.2f}, "
              f"CPU {b['cpu_s'] / a['cpu_s']:.2f} (> 1: arfem faster)")
        print("  max |arfem − NGSolve| over 24 h / sensor's max |value| (θ = T − 20 °C), "
              "and the peaks:")
        for n, rel, pa, pb in _compare(a, b):
            print(f"      {n:<16} {rel:.2e}   peak arfem {pa:.6g}  NGSolve {pb:.6g}")


if __name__ == "__main__":
    main()
