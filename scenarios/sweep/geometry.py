"""``arfem sweep`` over a mesh scenario (issue 32 item 6): a ``[geometry]`` scenario as
the base, and any of its groups' h, sources' powers, materials' properties and solver
settings swept::

    [sweep]
    name = "housing_h"
    base = "../spindle_unit.toml"          # a scenario with [geometry]
    [sweep.grid]
    "convection.housing_outer.h_W_m2K" = [4.0, 8.0, 16.0]
    "heat_source.motor.scale" = [0.5, 1.0]

The keys (``<group>`` a ``[[convection]]``'s or ``[[material]]``'s group, ``<name>`` a
``[[heat_source]]``'s name or group):

- ``convection.<group>.h_W_m2K`` (a number, or a table ``{a, b, m}``), or one of its
  speed law's ``.a``, ``.b``, ``.m``; ``convection.<group>.ambient_C``;
- ``heat_source.<name>.power_W`` or ``.flux_W_m2`` (replaces the value, a list per
  phase is allowed), ``heat_source.<name>.scale`` (a factor on its whole schedule, the
  way to sweep a source with its own ``phases``);
- ``material.<group>.<property>``, any property of ``[[material]]``;
- ``fem.solver``, ``fem.dt_s``, ``fem.output_interval_s``.

An unknown key or group is one line naming the key and listing what the base has
(exit 2). Every point is a whole scenario dict, validated before anything runs; its key
is the SHA-256 of that dict (the mesh by its SHA-256, names and outputs left out), so
an interrupted sweep resumes as the rod's does.

What is reused between points (per process: in-process, per local worker, per Dask
worker), and why it gives the same numbers as a run of each point on its own (on
workers, each worker gets one task of adjacent points, in the order that shares the
most, so that it builds the model once for its task:
:func:`arfem.scenarios.sweep.geometry_run.plan_tasks`):

- the mesh read, the heat assembly (M, K, the convection matrices B_g, the input
  matrix F), the elasticity's factored stiffness and the sensors' rows G: none depends
  on h (it enters as Σ h_g B_g per step), on the powers (inputs) or on Δt;
- a material's conductivity or ρc: only K or M is assembled again; its expansion: only
  the thermal load T, and G = Tᵀ(K⁻¹w) from the stored adjoint solves K⁻¹w (no new
  factorisation); Young's modulus or Poisson's ratio: the model is built anew;
- the reduced solve's modes, between points with the same model and the same h on
  every step (a sweep over powers or ambients): the modes do not depend on the inputs.
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import os
import socket
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from arfem.params import InputError
from arfem.scenarios.sweep.points import (MAX_POINTS, STORE_VERSION, Point, Sweep,
                                          distinct_values, flatten_keys, normalise,
                                          sha256_key)

__all__ = ["GeometrySweep", "geometry_sweep_from_dict", "geometry_override", "geometry_keys",
           "evaluate_geometry_point", "sensor_metrics", "clear_geometry_cache",
           "metric_columns", "GEOMETRY_KIND"]

GEOMETRY_KIND = "geometry"
_CONV_FIELDS = ("h_W_m2K", "h_W_m2K.a", "h_W_m2K.b", "h_W_m2K.m", "ambient_C")
_SRC_FIELDS = ("power_W", "flux_W_m2", "scale")
_FEM_FIELDS = ("solver", "dt_s", "output_interval_s")


@dataclass(frozen=True)
class GeometrySweep(Sweep):
    """A sweep whose base is a mesh scenario; ``sensors``: ((name, quantity), ...) of the
    base, ``mesh_sha256``: the mesh file's digest (part of every point's key)."""

    base_source: str
    sensors: tuple
    mesh_sha256: str
    reference_C: float

    kind = GEOMETRY_KIND

    def manifest(self) -> dict:
        return {**super().manifest(), "kind": GEOMETRY_KIND, "mesh_sha256": self.mesh_sha256}


# -- the keys -----------------------------------------------------------------------------

def _tables(data: dict, family: str) -> list:
    v = data.get(family, [])
    return v if isinstance(v, list) else []


def _label(family: str, t: dict) -> str:
    if family == "heat_source":
        return str(t.get("name", t.get("group")))
    return str(t.get("group"))


def geometry_keys(data: dict) -> list:
    """Every key a sweep may vary on the geometry scenario ``data`` (for messages)."""
    keys = [f"convection.{_label('convection', t)}.{f}" for t in _tables(data, "convection")
            for f in _CONV_FIELDS]
    keys += [f"heat_source.{_label('heat_source', t)}.{f}"
             for t in _tables(data, "heat_source") for f in _SRC_FIELDS]
    from arfem.scenarios.geometry.scenario import MATERIAL_KEYS
    keys += [f"material.{_label('material', t)}.{f}" for t in _tables(data, "material")
             for f in sorted(MATERIAL_KEYS - {"group"})]
    return keys + [f"fem.{f}" for f in _FEM_FIELDS]


def _families_line(data: dict) -> str:
    have = {f: [_label(f, t) for t in _tables(data, f)]
            for f in ("convection", "heat_source", "material")}
    return ("a mesh sweep varies convection.<group>.h_W_m2K (or .h_W_m2K.a/.b/.m, "
            f".ambient_C) with <group> one of {', '.join(have['convection']) or 'none'}; "
            f"heat_source.<name>.power_W, .flux_W_m2 or .scale with <name> one of "
            f"{', '.join(have['heat_source']) or 'none'}; material.<group>.<property> with "
            f"<group> one of {', '.join(have['material']) or 'none'}; fem.solver, fem.dt_s, "
            "fem.output_interval_s")


def geometry_override(data: dict, key: str, value) -> dict:
    """A deep copy of the geometry scenario dict ``data`` with ``key`` set to ``value``.

    Examples
    --------
    >>> d = {"convection": [{"group": "skin", "h_W_m2K": 8.0}]}
    >>> geometry_override(d, "convection.skin.h_W_m2K", 16.0)["convection"][0]["h_W_m2K"]
    16.0
    >>> geometry_override(d, "convection.skin.h_W_m2K.b", 0.1)["convection"][0]["h_W_m2K"]
    {'a': 8.0, 'b': 0.1, 'm': 1.0}
    """
    parts = key.split(".")
    fam = parts[0]
    out = copy.deepcopy(data)
    if fam == "fem" and len(parts) == 2 and parts[1] in _FEM_FIELDS:
        out.setdefault("fem", {})[parts[1]] = value
        return out
    if fam not in ("convection", "heat_source", "material") or len(parts) < 3:
        raise InputError(f"unknown key {key!r}: {_families_line(data)}", key)
    grp, fld = parts[1], ".".join(parts[2:])
    tabs = [t for t in _tables(out, fam) if isinstance(t, dict)
            and (grp == _label(fam, t) or grp == t.get("group"))]
    if not tabs:
        have = ", ".join(_label(fam, t) for t in _tables(data, fam) if isinstance(t, dict))
        raise InputError(f"the base scenario has no [[{fam}]] {grp!r} (it has: "
                         f"{have or 'none'})", key)
    t = tabs[0]
    if fam == "convection":
        return _set_convection(out, t, fld, value, key)
    if fam == "heat_source":
        return _set_source(out, t, fld, value, key)
    from arfem.scenarios.geometry.scenario import MATERIAL_KEYS
    if fld not in MATERIAL_KEYS - {"group"}:
        raise InputError(f"unknown material property {fld!r} (properties: "
                         f"{', '.join(sorted(MATERIAL_KEYS - {'group'}))})", key)
    t[fld] = value
    return out


def _set_convection(out: dict, t: dict, fld: str, value, key: str) -> dict:
    if fld not in _CONV_FIELDS:
        raise InputError(f"unknown convection field {fld!r} (fields: "
                         f"{', '.join(_CONV_FIELDS)})", key)
    if fld.startswith("h_W_m2K."):
        h = t.get("h_W_m2K")
        law = dict(h) if isinstance(h, dict) else {"a": h, "b": 0.0, "m": 1.0}
        law[fld.split(".")[1]] = value
        t["h_W_m2K"] = law
    else:
        t[fld] = value
    return out


def _set_source(out: dict, t: dict, fld: str, value, key: str) -> dict:
    if fld not in _SRC_FIELDS:
        raise InputError(f"unknown heat-source field {fld!r} (fields: "
                         f"{', '.join(_SRC_FIELDS)})", key)
    if fld != "scale" and "phases" in t:
        raise InputError("this source follows its own phases; sweep "
                         f"heat_source.{_label('heat_source', t)}.scale instead", key)
    other = "flux_W_m2" if fld == "power_W" else "power_W"
    if fld != "scale" and other in t:
        raise InputError(f"this source gives {other}; sweep heat_source."
                         f"{_label('heat_source', t)}.{other} or .scale instead", key)
    t[fld] = value
    return out


# -- the sweep ----------------------------------------------------------------------------

def _file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _absolute_paths(data: dict, base_dir: Path) -> dict:
    """The scenario dict with its mesh (and cycle CSV) as absolute paths and no outputs
    but the sensors (a point writes no fields and no picture)."""
    d = copy.deepcopy(data)
    g = d.get("geometry")
    if isinstance(g, dict) and isinstance(g.get("mesh"), str):
        g["mesh"] = str((base_dir / g["mesh"]).resolve())
    c = d.get("cycle")
    if isinstance(c, dict) and isinstance(c.get("csv"), str):
        c["csv"] = str((base_dir / c["csv"]).resolve())
    d["outputs"] = {"fields": False, "picture": False}
    return d


def _key_of(data: dict, mesh_sha: str) -> str:
    """A point's key: its scenario dict without name and outputs, the mesh by digest."""
    d = {k: v for k, v in data.items() if k not in ("scenario", "outputs")}
    d["geometry"] = {**d["geometry"], "mesh": mesh_sha}
    return sha256_key({"store_version": STORE_VERSION, "kind": GEOMETRY_KIND,
                       "scenario": normalise(d)})


def geometry_sweep_from_dict(sw: dict, name: str, description: str, source: str,
                             base_data: dict, base_path: Path | None, base_name: str,
                             max_points: int | None = None) -> GeometrySweep:
    """A validated :class:`GeometrySweep` from the ``[sweep]`` table ``sw`` (its name and
    description read already) on the mesh scenario ``base_data`` (read from
    ``base_path``): every key resolved on the base, every value and every point
    validated as a whole scenario before anything is computed."""
    from arfem.scenarios.geometry.scenario import geometry_scenario_from_dict
    grid_d = sw.get("grid")
    if not isinstance(grid_d, dict) or not grid_d:
        raise InputError("must be a non-empty table of key = [values, ...]", "sweep.grid")
    grid_flat = flatten_keys(grid_d)
    base_dir = Path(".") if base_path is None else base_path.parent
    base_source = str(base_path) if base_path is not None else "<base>"
    data0 = _absolute_paths(base_data, base_dir)
    base_sc = geometry_scenario_from_dict(data0, base_source, base_dir)
    if not base_sc.mesh_path.is_file():
        raise InputError(f"no mesh file {str(base_sc.mesh_path)!r}",
                         f"{base_source}: geometry.mesh")
    from arfem.scenarios.geometry.scenario import check_geometry_scenario
    check_geometry_scenario(base_sc)     # a bad mesh: one line before any point (issue 32)
    _check_size(grid_flat, max_points)
    grid = {}
    for key, values in grid_flat.items():
        where = f"sweep.grid.{key}"
        if not isinstance(values, list) or not values:
            raise InputError("must be a non-empty list of values", where)
        distinct_values(values, where)
        try:
            geometry_override(data0, key, values[0])
        except InputError as exc:                    # unknown key or group
            raise InputError(exc.message, where) from None
        for i, v in enumerate(values):
            try:
                geometry_scenario_from_dict(geometry_override(data0, key, v), base_source,
                                            base_dir)
            except InputError as exc:
                raise InputError(f"{v!r} is refused: {exc}", f"{where}[{i}]") from None
        grid[key] = list(values)
    digest = _file_sha256(base_sc.mesh_path)
    points = []
    cols = list(grid)
    for i, combo in enumerate(itertools.product(*(grid[c] for c in cols))):
        d = data0
        for c, v in zip(cols, combo):
            d = geometry_override(d, c, v)
        inputs = dict(zip(cols, combo))
        try:
            geometry_scenario_from_dict(d, base_source, base_dir)
        except InputError as exc:
            raise InputError(f"point {inputs} is refused: {exc}", "sweep.grid") from None
        points.append(Point(i, inputs, d, _key_of(d, digest)))
    return GeometrySweep(name=name, description=description, source=source, base=base_name,
                         grid=grid, paths={c: c for c in grid}, points=tuple(points),
                         base_source=base_source,
                         sensors=tuple((s.name, s.quantity) for s in base_sc.sensors),
                         mesh_sha256=digest, reference_C=base_sc.reference_C)


def _check_size(grid: dict, max_points: int | None) -> int:
    """Refuse (one line) a grid of more points than ``max_points`` (default
    :data:`~arfem.scenarios.sweep.spec.MAX_POINTS`) before any point is resolved."""
    limit = MAX_POINTS if max_points is None else int(max_points)
    sizes = [len(v) if isinstance(v, list) else 1 for v in grid.values()]
    n = int(np.prod(sizes)) if sizes else 0
    if n > limit:
        raise InputError(f"{n} points ({' × '.join(map(str, sizes))}) is more than the "
                         f"limit of {limit} points; split the grid, or pass --max-points {n} "
                         "to run it anyway", "sweep.grid")
    return n


# -- one point ----------------------------------------------------------------------------

def metric_columns(sensors) -> list:
    """The per-sensor columns of a mesh sweep's table, in sensor order: a displacement's
    ``d_<name>_peak_um``, ``d_<name>_peak_time_h``, ``d_<name>_final_um``; a
    temperature's ``T_<name>_peak_C``, ``T_<name>_peak_time_h``, ``T_<name>_final_C``.
    The peak is the value farthest from zero (from the reference temperature)."""
    cols = []
    for name, q in sensors:
        if q == "temperature":
            cols += [f"T_{name}_peak_C", f"T_{name}_peak_time_h", f"T_{name}_final_C"]
        elif q == "tilt":
            cols += [f"tilt_{name}_peak_urad", f"tilt_{name}_peak_time_h",
                     f"tilt_{name}_final_urad"]
        else:
            cols += [f"d_{name}_peak_um", f"d_{name}_peak_time_h", f"d_{name}_final_um"]
    return cols


def sensor_metrics(run) -> dict:
    """Peak (farthest from 0 µm or from the reference °C), its time [h] and the final
    value of every sensor of a :class:`~arfem.scenarios.geometry.scenario.GeometryRun`."""
    sc = run.model.scenario
    t_h = run.result.times_s / 3600.0
    out = {}
    for s in sc.sensors:
        if s.quantity == "temperature":
            v = run.result.outputs[:, list(sc.sensors).index(s)] + sc.reference_C
            j = int(np.argmax(np.abs(v - sc.reference_C)))
            pre, unit = f"T_{s.name}", "C"
        else:
            v = run.result.outputs[:, list(sc.sensors).index(s)] * 1e6
            j = int(np.argmax(np.abs(v)))
            pre, unit = ((f"tilt_{s.name}", "urad") if s.quantity == "tilt"
                         else (f"d_{s.name}", "um"))
        out[f"{pre}_peak_{unit}"] = float(v[j])
        out[f"{pre}_peak_time_h"] = float(t_h[j])
        out[f"{pre}_final_{unit}"] = float(v[-1])
    return out


#: per-process caches: {structure key: _Entry}, {(structure, materials): GeometryModel},
#: {(structure, materials, h history): mode cache}; each keeps its newest few entries
_STRUCTURES: dict = {}
_VARIANTS: dict = {}
_MODES: dict = {}
#: models kept per process (sparse K, M and a dense G each: tens of MB for the spindle)
_KEEP = 4
#: mode sets kept: one (a mode set of the spindle unit holds ~100 MB per h on its
#: steps); the runner orders the points so that those sharing modes come together
_KEEP_MODES = 1


@dataclass
class _Entry:
    base: object               # the GeometryModel built for the first point
    adjoint: np.ndarray | None = None     # K⁻¹w per displacement sensor, when needed


def clear_geometry_cache() -> None:
    """Forget the meshes, models and modes cached in this process (tests, benchmarks)."""
    _STRUCTURES.clear()
    _VARIANTS.clear()
    _MODES.clear()


def _remember(cache: dict, key, value, keep: int = _KEEP):
    cache[key] = value
    while len(cache) > keep:
        cache.pop(next(iter(cache)))
    return value


def _structure_key(sc) -> tuple:
    st = sc.mesh_path.stat()
    return (str(sc.mesh_path), st.st_mtime_ns, st.st_size, sc.unit, sc.order,
            tuple(s.spec for s in sc.sources), tuple(c.spec for c in sc.convections),
            sc.support, sc.support_names, tuple(sc.sensors))


def _adjoint(entry: _Entry) -> np.ndarray:
    """K⁻¹w for every displacement sensor (the solves inside ElasticBody.functional)."""
    if entry.adjoint is None:
        m = entry.base
        el = m.elastic
        W = np.column_stack([el.sensor_weight(s, f"sensor {s.name!r}")
                             for s in m.scenario.sensors if s.elastic])
        Y = np.zeros_like(W)
        Y[el.free] = el.factor.solve(np.ascontiguousarray(W[el.free]))
        entry.adjoint = Y
    return entry.adjoint


def _variant(entry: _Entry, sc) -> tuple:
    """The model of ``entry``'s structure with ``sc``'s materials: (model, what was
    assembled again), or (None, why) when the stiffness changes (built anew)."""
    from arfem.fem.body import (capacity, conduction, material_arrays, per_element,
                                thermal_coupling)
    base = entry.base
    th, el = base.thermal, base.elastic
    props = material_arrays(base.gmesh, sc.materials)
    same = {k: np.array_equal(props[k], th.props[k]) for k in ("k", "rhoc", "beta", "lam",
                                                               "mu")}
    if el is not None and not (same["lam"] and same["mu"]):
        return None, "Young's modulus or Poisson's ratio changed"
    redone = []
    K, M = th.K, th.M
    if not same["k"]:
        K = conduction.assemble(th.basis, k=per_element(th.basis, props["k"])).tocsr()
        redone.append("K")
    if not same["rhoc"]:
        M = capacity.assemble(th.basis, rhoc=per_element(th.basis, props["rhoc"])).tocsr()
        redone.append("M")
    th2 = replace(th, K=K, M=M, props=props)
    G = base.G
    el2 = None if el is None else replace(el, thermal=th2)
    if el is not None and not same["beta"]:
        T = thermal_coupling.assemble(th.basis, el.basis,
                                      beta=per_element(th.basis, props["beta"])).tocsr()
        el2 = replace(el, thermal=th2, T=T)
        cols = [j for j, s in enumerate(base.scenario.sensors) if s.elastic]
        G = G.copy()
        G[:, cols] = np.asarray(T.T @ _adjoint(entry))
        redone.append("T and G = Tᵀ(K⁻¹w)")
    return replace(base, thermal=th2, elastic=el2, G=G), redone


def _model_for(sc) -> tuple:
    """(GeometryModel for ``sc``, what was reused): from the caches where possible."""
    from arfem.scenarios.geometry.scenario import build_geometry_model, input_history
    skey = _structure_key(sc)
    mkey = (skey, tuple(sorted(sc.materials.items())))
    if mkey in _VARIANTS:
        model, reused = _VARIANTS[mkey], "mesh, heat and elasticity assembly, sensor rows"
    elif skey in _STRUCTURES:
        model, redone = _variant(_STRUCTURES[skey], sc)
        if model is None:
            model, reused = build_geometry_model(sc), f"nothing ({redone})"
        else:
            reused = ("mesh, heat and elasticity assembly, factored stiffness; assembled "
                      f"again: {', '.join(redone) or 'nothing'}")
        _remember(_VARIANTS, mkey, model)
    else:
        model = build_geometry_model(sc)
        _remember(_STRUCTURES, skey, _Entry(model))
        _remember(_VARIANTS, mkey, model)
        reused = "nothing (first point of this mesh and model)"
    return replace(model, scenario=sc, history=input_history(sc)), mkey, reused


def evaluate_geometry_point(data: dict, source: str = "<sweep point>", limits=None) -> dict:
    """Solve one resolved mesh scenario dict; its per-sensor metrics and run time.

    Runs in the sweep's process, a local worker or a Dask worker; what it reuses from
    earlier points in the same process is in the module docstring and in the returned
    ``metrics["reused"]``. ``limits`` is accepted for the sweep runner's signature.
    """
    from arfem.scenarios.geometry.scenario import geometry_scenario_from_dict, solve_geometry
    t0 = time.perf_counter()
    sc = geometry_scenario_from_dict(data, source, Path(data["geometry"]["mesh"]).parent)
    sc = replace(sc, fields=False, picture=False)
    t_model = time.perf_counter()
    model, mkey, reused = _model_for(sc)
    model_s = time.perf_counter() - t_model
    modes = None
    if sc.solver == "reduced":
        h = model.history.h_W_m2K
        hkey = (mkey, h.shape, h.tobytes())
        if hkey in _MODES:
            reused += "; reduced modes"
            modes = _MODES[hkey]
        else:
            modes = _remember(_MODES, hkey, {}, _KEEP_MODES)
    run = solve_geometry(model, mode_cache=modes)
    metrics = sensor_metrics(run)
    metrics.update({"heat_dofs": int(model.thermal.ndofs), "n_modes": int(run.result.n_modes),
                    "n_samples": int(run.result.times_s.size),
                    "reference_C": float(sc.reference_C),
                    "total_h": float(sc.total_s / 3600.0), "reused": reused})
    return {"metrics": metrics, "run_time_s": time.perf_counter() - t0, "model_s": model_s,
            "worker": f"{socket.gethostname()}:{os.getpid()}"}
