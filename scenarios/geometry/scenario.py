"""Scenarios on a user's own mesh: ``[geometry]`` instead of ``[rod]`` (issue 32).

A geometry scenario ties the named physical groups of a Gmsh mesh to materials, heat
sources, convection, a support and sensors, and ``arfem run`` solves it (heat, then
thermo-elasticity) and writes each sensor's history. The format (every key carries its
unit; lengths in the file are in the mesh's ``unit``)::

    [scenario]
    name = "spindle_unit"

    [geometry]
    mesh = "spindle_unit.msh"     # relative to this file; Gmsh 4.1 or any meshio volume
    unit = "mm"                   # "m" | "mm": the unit of the mesh's coordinates
    order = 2                     # 1 | 2 (P1/P2 tetrahedra; 8/20-node bricks)
    reference_C = 20.0            # start and stress-free temperature [°C]

    [[material]]                  # one per volume group
    group = "shaft"
    conductivity_W_mK = 45.0
    density_kg_m3 = 7850.0
    specific_heat_J_kgK = 460.0
    expansion_1_K = 11.5e-6
    youngs_modulus_Pa = 210e9
    poisson_ratio = 0.3

    [cycle]                       # the common time base: spindle speed and ambient
    phases = [ { duration_h = 2.0, speed_rpm = 8000.0, ambient_C = 20.0 }, ... ]
    # or: csv = "duty.csv"  (columns time_s = start of each interval, speed_rpm,
    #      ambient_C, any source columns) and total_h = 24.0

    [[heat_source]]               # one per heated surface or volume group
    name = "front_bearing"
    group = "front_bearing_seat"  # a surface group (power spread over its area) or a
                                  # volume group (spread over its volume: P/V [W/m³])
    power_W = 150.0               # a constant, or a list (one value per cycle phase),
                                  # or a CSV column name: power_W = "P_front_W";
                                  # flux_W_m2 instead of power_W for a flux (surfaces)
    # phases = [ { duration_h = 1.0, power_W = 80.0 }, ... ]   its own schedule instead
    # power_W = { a = 0.0, b = 0.003, m = 1.0 }   from the cycle's speed n [rpm]:
    #                               P = a + b·n^m [W]
    # bearing = { f0 = 2.0, nu_mm2_s = 22.0, dm_mm = 90.0, f1 = 3.2e-4, P1_N = 1000.0,
    #             count = 2 }       Palmgren's friction moment × ω from the speed
    #                               (arfem.models.bearing: coefficients and units)
    # scale = 1.0               optional factor on every value of the schedule [-]
    #                           (e.g. the part of the friction heat the structure takes)

    [[convection]]                # one per cooled surface group
    group = "housing_outer"
    h_W_m2K = 8.0                 # or { a = 10.0, b = 0.01, m = 0.8 }: h = a + b·n^m
                                  # with n the cycle's speed_rpm
    ambient_C = 20.0              # optional: default the cycle's ambient

    [support]
    type = "clamped"              # clamped face group, or "3-2-1" on three points
    group = "column_foot"         # points = ["A", "B", "C"] (point groups) or [[x,y,z], …]

    [[sensor]]
    name = "tcp_z"
    point = [0.0, 0.0, -250.0]    # mesh unit
    direction = "z"               # "x" | "y" | "z" | [a, b, c]; or quantity = "temperature"
    # group = "far"               # a displacement averaged over a surface group instead

    [fem]
    solver = "reduced"            # "reduced" (exact in time) | "crank-nicolson" | "backward-euler"
    dt_s = 60.0                   # θ-method step
    output_interval_s = 60.0      # sensor sampling

    [outputs]
    fields = false                # XDMF 3 time series of θ and u for ParaView; default
                                  # false (it factors the stiffness: about 2x the memory)
    picture = true                # geometry.png: the mesh and its groups (default true)
    field_interval_s = 3600.0

Every refusal is one line naming the file and the key (exit 2).
"""
from __future__ import annotations

import csv
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from arfem.fem.body import (ConvectionSpec, ElasticBody, Material, SensorSpec, SourceSpec,
                            Support, ThermalBody)
from arfem.fem.gmsh_io import GroupedMesh, UNITS, check_memory, read_grouped_mesh
from arfem.fem.thermal3d import BodyResult, InputHistory, solve_body_reduced, solve_body_theta
from arfem.io import atomic_write_text, read_text_utf8, read_toml, write_csv, write_json
from arfem.limits import Limits, resolve
from arfem.params import InputError
from arfem.ranges import check_range
from arfem.scenarios.geometry.export import write_exports
from arfem.strict import boolean as _bool
from arfem.strict import check_keys as _unknown
from arfem.strict import number as _number
from arfem.strict import string as _string
from arfem.strict import table as _table

__all__ = ["GeometryScenario", "is_geometry_scenario", "load_geometry_scenario",
           "geometry_scenario_from_dict", "GeometryModel", "build_geometry_model",
           "GeometryRun", "solve_geometry", "run_geometry", "main_run_geometry", "WRITES",
           "check_geometry_scenario", "source_power_at_speed", "MATERIAL_KEYS",
           "input_history"]

_TOP = {"scenario", "geometry", "material", "cycle", "heat_source", "convection", "support",
        "diagnosis",            # read by the mesh diagnosis (issue 33), ignored by arfem run
        "observer",             # the exported observer's noise levels (issue 43)
        "sensor", "fem", "outputs", "check"}   # [check]: arfem check's (scenarios/geometry/check.py)
_GEOM = {"mesh", "unit", "order", "reference_C"}
#: The keys of a ``[[material]]`` table (its volume ``group`` and its properties, each
#: unit in its name); a geometry sweep varies the properties by these names.
MATERIAL_KEYS = {"group", "conductivity_W_mK", "density_kg_m3", "specific_heat_J_kgK",
                 "expansion_1_K", "youngs_modulus_Pa", "poisson_ratio"}
_CYCLE = {"phases", "csv", "total_h", "total_s"}
_PHASE = {"duration_s", "duration_min", "duration_h", "speed_rpm", "ambient_C", "label"}
_SRC = {"name", "group", "power_W", "flux_W_m2", "phases", "scale", "bearing"}
_BEARING = {"f0", "nu_mm2_s", "dm_mm", "f1", "P1_N", "count"}
_CONV = {"name", "group", "h_W_m2K", "ambient_C"}
_SUP = {"type", "group", "points"}
_SENS = {"name", "point", "direction", "quantity", "group", "points"}
_FEM = {"solver", "dt_s", "output_interval_s"}
_OUT = {"fields", "picture", "field_interval_s"}
_SOLVERS = {"reduced": None, "crank-nicolson": 0.5, "backward-euler": 1.0}
_DIRS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
#: Files ``arfem run`` writes for a geometry scenario.
WRITES = ("sensors.csv", "sensors.json", "summary.json", "summary.md", "geometry.png",
          "sensors.png", "scenario.toml", "report.html", "fields/fields.xdmf3",
          "fields/fields.h5", "model.json", "record.toml", "record.csv")


@dataclass(frozen=True)
class Schedule3D:
    """The cycle on its own phases: edges [s], speed [rpm] and ambient [°C] per phase."""

    edges_s: np.ndarray
    speed_rpm: np.ndarray
    ambient_C: np.ndarray
    columns: dict = field(default_factory=dict)     # CSV columns per phase


@dataclass(frozen=True)
class SourceSetting:
    spec: SourceSpec
    edges_s: np.ndarray          # own schedule's edges (or the cycle's)
    values: np.ndarray           # power [W] or flux [W/m²] per segment of edges_s
    law: object = None           # PowerLaw / PalmgrenBearing: power from the speed [W]
    scale: float = 1.0           # the source's ``scale`` (already in ``values``)

    def power_at_speed_W(self, speed_rpm) -> np.ndarray | None:
        """The power [W] its speed law gives at ``speed_rpm`` (times ``scale``), or None
        for a source without one."""
        if self.law is None:
            return None
        return self.scale * self.law.power_W(speed_rpm)


@dataclass(frozen=True)
class ConvectionSetting:
    spec: ConvectionSpec
    h: tuple                     # (a, b, m): h = a + b·n^m [W/(m²K)], n in rpm
    ambient_C: float | None


@dataclass(frozen=True)
class GeometryScenario:
    """A validated geometry scenario (module docstring)."""

    name: str
    description: str
    source: str
    mesh_path: Path
    unit: str
    order: int
    reference_C: float
    materials: dict
    cycle: Schedule3D
    sources: tuple
    convections: tuple
    support: Support
    support_names: tuple
    sensors: tuple
    solver: str
    dt_s: float
    output_interval_s: float
    fields: bool
    picture: bool
    field_interval_s: float
    #: ``[observer]``: the noise levels the exported model's observer is designed for
    #: (:class:`arfem.models.observer.ObserverNoise`); None: its defaults
    observer_noise: object = None

    @property
    def total_s(self) -> float:
        return float(self.cycle.edges_s[-1])


def is_geometry_scenario(path) -> bool:
    """True when ``path`` is a TOML file with a ``[geometry]`` table (cheap text test)."""
    from arfem.io import toml_has_table
    return toml_has_table(path, "geometry")


def load_geometry_scenario(path, limits: Limits | None = None,
                           toml=None) -> GeometryScenario:
    """Read and validate a geometry scenario file; refusals name the file and key.
    ``toml``: the file already read (:class:`arfem.io.TomlFile`), not read again."""
    p = Path(path)
    data = read_toml(p, limits) if toml is None else toml.data
    try:
        return geometry_scenario_from_dict(data, str(p), p.parent, limits)
    except InputError as exc:
        if exc.where and exc.where.startswith(str(p)):
            raise
        raise exc.at(str(p)) from None


def _durations(ph: dict, where: str) -> float:
    given = [k for k in ("duration_s", "duration_min", "duration_h") if k in ph]
    if len(given) != 1:
        raise InputError("needs exactly one of duration_s, duration_min, duration_h", where)
    k = given[0]
    return _number(ph[k], f"{where}.{k}", positive=True) * {
        "duration_s": 1.0, "duration_min": 60.0, "duration_h": 3600.0}[k]


def _read_cycle_csv(path: Path, where: str, total_s: float) -> tuple:
    text = read_text_utf8(path)
    rows = list(csv.reader(line for line in text.splitlines() if line.strip()))
    if len(rows) < 2:
        raise InputError("needs a header and at least one row", where)
    head = [h.strip() for h in rows[0]]
    if "time_s" not in head:
        raise InputError(f"has no time_s column (columns: {', '.join(head)})", where)
    vals = {}
    for j, h in enumerate(head):
        col = []
        for i, r in enumerate(rows[1:], start=2):
            try:
                v = float(r[j])
            except (ValueError, IndexError):
                raise InputError(f"row {i}, column {h!r}: not a number", where) from None
            if not np.isfinite(v):
                raise InputError(f"row {i}, column {h!r}: not finite", where)
            col.append(v)
        vals[h] = np.asarray(col)
    t = vals.pop("time_s")
    if t[0] != 0.0 or np.any(np.diff(t) <= 0) or t[-1] >= total_s:
        raise InputError(f"time_s must start at 0, increase and end before total "
                         f"{total_s:g} s", where)
    return np.append(t, total_s), vals


def _cycle(data: dict, reference_C: float, base: Path) -> Schedule3D:
    cyc = _table(data, "cycle", "")
    _unknown(cyc, _CYCLE, "cycle")
    total = None
    for key, unit in (("total_h", 3600.0), ("total_s", 1.0)):
        if key in cyc:
            total = _number(cyc[key], f"cycle.{key}", positive=True) * unit
    if "csv" in cyc:
        if total is None:
            raise InputError("a CSV cycle needs total_h (the end of its last row)", "cycle")
        f = base / _string(cyc["csv"], "cycle.csv")
        edges, cols = _read_cycle_csv(f, f"cycle.csv ({f})", total)
        n = edges.size - 1
        speed = cols.pop("speed_rpm", np.zeros(n))
        amb = cols.pop("ambient_C", np.full(n, reference_C))
        return Schedule3D(edges, speed, amb, cols)
    phases = cyc.get("phases")
    if not isinstance(phases, list) or not phases:
        raise InputError("must be a non-empty list of phases ({ duration_h = 2.0, "
                         "speed_rpm = 8000.0 }, ...) or give csv = \"file.csv\"",
                         "cycle.phases")
    d, n_, a = [], [], []
    for i, ph in enumerate(phases):
        w = f"cycle.phases[{i}]"
        if not isinstance(ph, dict):
            raise InputError("must be a table", w)
        _unknown(ph, _PHASE, w)
        d.append(_durations(ph, w))
        n_.append(_number(ph.get("speed_rpm", 0.0), f"{w}.speed_rpm", positive=True,
                          allow_zero=True))
        a.append(_number(ph.get("ambient_C", reference_C), f"{w}.ambient_C"))
    edges = np.concatenate([[0.0], np.cumsum(d)])
    if total is not None and abs(edges[-1] - total) > 1e-9 * total:
        raise InputError(f"the phases add up to {edges[-1] / 3600:g} h, not {total / 3600:g} h",
                         "cycle")
    return Schedule3D(edges, np.asarray(n_), np.asarray(a))


def _point(v, scale: float, where: str) -> tuple:
    if (not isinstance(v, list) or len(v) != 3
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in v)):
        raise InputError(f"must be [x, y, z] in the mesh unit, got {v!r}", where)
    return tuple(float(x) * scale for x in v)


def geometry_scenario_from_dict(data: dict, source: str = "<scenario>",
                                base: Path | None = None,
                                limits: Limits | None = None) -> GeometryScenario:
    """Validate a geometry scenario given as a dict (as read from TOML).

    One reader per table, in the order a refusal is looked for: ``[scenario]`` and
    ``[geometry]``, ``[[material]]``, ``[cycle]``, ``[[heat_source]]``,
    ``[[convection]]``, ``[support]``, ``[[sensor]]``, ``[fem]`` and ``[outputs]``;
    then every number against its physical range (:func:`_check_ranges`) and the
    sizes against the limits (``limits``: :class:`arfem.limits.Limits`).
    """
    sc = _from_dict(data, source, base)
    _check_ranges(sc, data)
    _check_sizes(sc, resolve(limits))
    return sc


def _from_dict(data: dict, source: str, base: Path | None) -> GeometryScenario:
    """The tables of a geometry scenario, each read and checked (no ranges yet)."""
    base = Path(".") if base is None else base
    _unknown(data, _TOP, "")
    sc = _table(data, "scenario", "")
    _unknown(sc, {"name", "description"}, "scenario")
    g, unit, scale, order, ref = _geometry_table(data)
    materials = _materials(data)
    cycle = _cycle(data, ref, base)
    sources = _sources(data, cycle)
    convs = _convections(data)
    support, names = _support(data, scale)
    sensors = _sensors(data, scale)
    solver, dt, oi, fi, out = _fem_and_outputs(data, cycle)
    return GeometryScenario(
        name=_string(sc.get("name", Path(source).stem), "scenario.name"),
        description=_string(sc.get("description", ""), "scenario.description"),
        source=source, mesh_path=base / _string(g["mesh"], "geometry.mesh"), unit=unit,
        order=order, reference_C=ref, materials=materials, cycle=cycle,
        sources=tuple(sources), convections=tuple(convs), support=support,
        support_names=names, sensors=tuple(sensors), solver=solver, dt_s=dt,
        output_interval_s=oi, fields=_bool(out.get("fields", False), "outputs.fields"),
        picture=_bool(out.get("picture", True), "outputs.picture"), field_interval_s=fi,
        observer_noise=_observer_noise(data))


def _observer_noise(data: dict):
    """``[observer]`` (issue 43): noise levels, or None where the table is absent."""
    if "observer" not in data:
        return None
    from arfem.models.observer import noise_from_table
    return noise_from_table(data["observer"], "observer")


def _geometry_table(data: dict) -> tuple:
    """``[geometry]``: the table, the mesh unit, its scale to metres [m per unit], the
    element order (1 | 2) and the reference temperature [°C]."""
    g = _table(data, "geometry", "")
    _unknown(g, _GEOM, "geometry")
    if "mesh" not in g:
        raise InputError("missing mesh (the .msh file)", "geometry")
    if "unit" not in g:
        raise InputError("missing unit: declare the mesh's unit, \"m\" or \"mm\"", "geometry")
    unit = _string(g["unit"], "geometry.unit", choices=tuple(UNITS))
    scale = UNITS[unit]
    order = int(_number(g.get("order", 2), "geometry.order", integer=True))
    if order not in (1, 2):
        raise InputError(f"must be 1 or 2, got {order}", "geometry.order")
    ref = _number(g.get("reference_C", 20.0), "geometry.reference_C")
    return g, unit, scale, order, ref


def _materials(data: dict) -> dict:
    """``[[material]]``: {volume group: :class:`Material`}, one material per group."""
    mats = data.get("material", [])
    if not isinstance(mats, list) or not mats:
        raise InputError("needs one [[material]] per volume group of the mesh", "material")
    materials = {}
    for i, m in enumerate(mats):
        w = f"material[{i}]"
        mat = _material(m, w)
        if mat.group in materials:
            raise InputError(f"group {mat.group!r} has two materials", f"{w}.group")
        materials[mat.group] = mat
    return materials


def _material(m, w: str) -> Material:
    """One ``[[material]]`` table (``w`` names it): every property given, each plausible."""
    if not isinstance(m, dict):
        raise InputError("must be a table", w)
    _unknown(m, MATERIAL_KEYS, w)
    missing = sorted(MATERIAL_KEYS - set(m))
    if missing:
        raise InputError(f"missing {', '.join(missing)}", w)
    kw = {k: _number(m[k], f"{w}.{k}", positive=k != "poisson_ratio")
          for k in MATERIAL_KEYS - {"group"}}
    if not 0.0 <= kw["poisson_ratio"] < 0.5:
        raise InputError(f"must lie in [0, 0.5), got {kw['poisson_ratio']}",
                         f"{w}.poisson_ratio")
    if kw["expansion_1_K"] > 1e-3:
        raise InputError(f"{kw['expansion_1_K']:g} 1/K is not a solid's expansion "
                         "(µm/(m·K) given as 1/K? 12 µm/(m·K) = 12e-6)",
                         f"{w}.expansion_1_K")
    grp = _string(m["group"], f"{w}.group")
    return Material(group=grp, **kw)


def _sources(data: dict, cycle: Schedule3D) -> list:
    """``[[heat_source]]``: one :class:`SourceSetting` per table, each on its own schedule
    (its ``phases``) or on the cycle's (a constant, a value per phase, a CSV column)."""
    sources = []
    src_list = data.get("heat_source", [])
    if not isinstance(src_list, list):
        raise InputError("must be an array of tables [[heat_source]]", "heat_source")
    for i, s in enumerate(src_list):
        w = f"heat_source[{i}]"
        if not isinstance(s, dict):
            raise InputError("must be a table", w)
        _unknown(s, _SRC, w)
        grp = _string(s.get("group"), f"{w}.group")
        name = _string(s.get("name", grp), f"{w}.name")
        law = _speed_law(s, w)
        if law is not None:
            edges, values, kind = cycle.edges_s, law.power_W(cycle.speed_rpm), "power_W"
        elif "phases" in s:
            edges, values, kind = _source_own_phases(s["phases"], w, cycle)
        else:
            edges, values, kind = _source_on_cycle(s, w, cycle)
        scale = 1.0
        if "scale" in s:          # a factor on the whole schedule (e.g. swept: 0.5, 1, 2)
            scale = _number(s["scale"], f"{w}.scale", positive=True, allow_zero=True)
            values = values * scale
        spec = SourceSpec(name=name, group=grp, kind="power" if kind == "power_W" else "flux")
        sources.append(SourceSetting(spec, edges, values, law, scale))
    return sources


def _speed_law(s: dict, w: str):
    """A source's power as a function of the cycle's speed (:mod:`arfem.models.bearing`):
    ``power_W = {a, b, m}`` (P = a + b·n^m [W]) or ``bearing = {f0, nu_mm2_s, dm_mm, f1,
    P1_N, count}`` (Palmgren's friction moment × ω); None for a source without one.
    Every value range-checked (:data:`arfem.models.bearing.RANGES`)."""
    from arfem.models.bearing import PalmgrenBearing, PowerLaw, check_range
    if "bearing" in s:
        others = [k for k in ("power_W", "flux_W_m2", "phases") if k in s]
        if others:
            raise InputError(f"gives both bearing and {others[0]}: the bearing model gives "
                             "the power from the speed", w)
        b = s["bearing"]
        if not isinstance(b, dict):
            raise InputError("must be a table { f0, nu_mm2_s, dm_mm, f1, P1_N, count }",
                             f"{w}.bearing")
        _unknown(b, _BEARING, f"{w}.bearing")
        missing = sorted({"f0", "nu_mm2_s", "dm_mm"} - set(b))
        if missing:
            raise InputError(f"missing {', '.join(missing)} (Palmgren's M0 = 1e-7·f0·"
                             "(ν·n)^(2/3)·dm³ needs them)", f"{w}.bearing")
        kw = {k: check_range(k, _number(b[k], f"{w}.bearing.{k}", integer=k == "count"),
                             f"{w}.bearing.{k}") for k in _BEARING if k in b}
        if "count" in kw:
            kw["count"] = int(kw["count"])
        return PalmgrenBearing(**kw)
    p = s.get("power_W")
    if isinstance(p, dict):
        if "phases" in s:
            raise InputError("gives both power_W = {a, b, m} (from the speed) and phases",
                             w)
        _unknown(p, {"a", "b", "m"}, f"{w}.power_W")
        _require_exponent(p, f"{w}.power_W")
        abm = {k: check_range(k, _number(p.get(k, d), f"{w}.power_W.{k}"), f"{w}.power_W.{k}")
               for k, d in (("a", 0.0), ("b", 0.0), ("m", 1.0))}
        return PowerLaw(**abm)
    return None


def _require_exponent(law: dict, where: str) -> None:
    """Refuse a speed law ``{a, b, m}`` (a + b·n^m) with a speed term (b given, not 0)
    but no exponent ``m``: m sets how the heat or the h grows with the speed, so no
    default can stand in for it (a, and b, default to 0: no term)."""
    b = law.get("b", 0.0)
    if "m" not in law and isinstance(b, (int, float)) and b != 0.0:
        raise InputError("b is given but not m, the exponent of b·n^m: give it (m = 1 for "
                         "a law linear in the speed)", where)


def source_power_at_speed(sc: "GeometryScenario", src: SourceSetting, speed_rpm,
                          where: str) -> np.ndarray:
    """A source's power [W] at each recorded speed: its speed law where it has one
    (``bearing`` or ``power_W = {a, b, m}``), else linear between its scenario's
    (speed, power) pairs on the cycle's phases; a source on its own schedule is refused
    (its power does not follow the speed): one line naming ``where``."""
    own = src.power_at_speed_W(speed_rpm)
    if own is not None:
        return own
    if src.edges_s.shape != sc.cycle.edges_s.shape or not np.allclose(src.edges_s,
                                                                        sc.cycle.edges_s):
        raise InputError(f"source {src.spec.name!r} follows its own schedule in the scenario, "
                         f"so speed_rpm does not give its power: add a column "
                         f"P_{src.spec.name}_W", where)
    n = np.concatenate([[0.0], sc.cycle.speed_rpm])
    p = np.concatenate([[0.0], src.values])
    o = np.argsort(n, kind="stable")
    return np.interp(speed_rpm, n[o], p[o])


def _source_own_phases(ph, w: str, cycle: Schedule3D) -> tuple:
    """A source's own ``phases``: (edges [s], power [W] or flux [W/m²] per phase, kind);
    they must add up to the cycle's length."""
    if not isinstance(ph, list) or not ph:
        raise InputError("must be a non-empty list of phases", f"{w}.phases")
    d, v, kind = [], [], None
    for j, p in enumerate(ph):
        wj = f"{w}.phases[{j}]"
        if not isinstance(p, dict):
            raise InputError("must be a table", wj)
        _unknown(p, {"duration_s", "duration_min", "duration_h", "power_W",
                     "flux_W_m2", "label"}, wj)
        d.append(_durations(p, wj))
        k = [x for x in ("power_W", "flux_W_m2") if x in p]
        if len(k) != 1:
            raise InputError("needs power_W or flux_W_m2", wj)
        if kind is not None and k[0] != kind:
            raise InputError("mixes power_W and flux_W_m2", wj)
        kind = k[0]
        v.append(_number(p[kind], f"{wj}.{kind}", positive=True, allow_zero=True))
    edges = np.concatenate([[0.0], np.cumsum(d)])
    if abs(edges[-1] - cycle.edges_s[-1]) > 1e-9 * cycle.edges_s[-1]:
        raise InputError(f"its phases add up to {edges[-1] / 3600:g} h, the cycle "
                         f"to {cycle.edges_s[-1] / 3600:g} h", f"{w}.phases")
    return edges, np.asarray(v), kind


def _source_on_cycle(s: dict, w: str, cycle: Schedule3D) -> tuple:
    """A source on the cycle's phases: (edges [s], values per phase, kind) from a
    constant, a list (one value per phase) or the name of a column of the cycle's CSV."""
    nph = cycle.edges_s.size - 1
    kinds = [k for k in ("power_W", "flux_W_m2") if k in s]
    if len(kinds) != 1:
        raise InputError("needs power_W [W] or flux_W_m2 [W/m²] (or phases)", w)
    kind = kinds[0]
    val = s[kind]
    edges = cycle.edges_s
    if isinstance(val, str):
        if val not in cycle.columns:
            raise InputError(f"no column {val!r} in the cycle's CSV (columns: "
                             f"{', '.join(sorted(cycle.columns)) or 'none'})",
                             f"{w}.{kind}")
        values = cycle.columns[val]
    elif isinstance(val, list):
        if len(val) != nph:
            raise InputError(f"has {len(val)} values for {nph} cycle phases",
                             f"{w}.{kind}")
        values = np.asarray([_number(x, f"{w}.{kind}", positive=True, allow_zero=True)
                             for x in val])
    else:
        values = np.full(nph, _number(val, f"{w}.{kind}", positive=True,
                                      allow_zero=True))
    if np.any(values < 0):
        raise InputError("must be >= 0", f"{w}.{kind}")
    return edges, values, kind


def _convections(data: dict) -> list:
    """``[[convection]]``: one :class:`ConvectionSetting` per table, h = a + b·n^m
    [W/(m²K)] with n the cycle's speed [rpm] (a constant h is (h, 0, 1))."""
    convs = []
    for i, c in enumerate(data.get("convection", []) or []):
        w = f"convection[{i}]"
        if not isinstance(c, dict):
            raise InputError("must be a table", w)
        _unknown(c, _CONV, w)
        grp = _string(c.get("group"), f"{w}.group")
        h = c.get("h_W_m2K")
        if isinstance(h, dict):
            _unknown(h, {"a", "b", "m"}, f"{w}.h_W_m2K")
            _require_exponent(h, f"{w}.h_W_m2K")
            abm = (_number(h.get("a", 0.0), f"{w}.h_W_m2K.a", positive=True, allow_zero=True),
                   _number(h.get("b", 0.0), f"{w}.h_W_m2K.b", positive=True, allow_zero=True),
                   _number(h.get("m", 1.0), f"{w}.h_W_m2K.m", positive=True))
        else:
            abm = (_number(h, f"{w}.h_W_m2K", positive=True), 0.0, 1.0)
        if abm[0] > 1e4:
            raise InputError(f"{abm[0]:g} W/(m²K) is beyond forced air or oil cooling",
                             f"{w}.h_W_m2K")
        amb = _number(c["ambient_C"], f"{w}.ambient_C") if "ambient_C" in c else None
        convs.append(ConvectionSetting(ConvectionSpec(_string(c.get("name", grp), f"{w}.name"),
                                                      grp), abm, amb))
    return convs


def _support(data: dict, scale: float) -> tuple:
    """``[support]``: (:class:`Support`, point-group names of a 3-2-1 support or None per
    point); coordinates scaled to metres by ``scale``."""
    sup = data.get("support")
    if not isinstance(sup, dict) or not sup:
        raise InputError("the body has no support: add [support] type = \"clamped\" with "
                         "a face group, or type = \"3-2-1\" with three points (without it "
                         "displacements are not defined)", "support")
    _unknown(sup, _SUP, "support")
    kind = _string(sup.get("type"), "support.type", choices=("clamped", "3-2-1"))
    names: tuple = ()
    if kind == "clamped":
        support = Support("clamped", group=_string(sup.get("group"), "support.group"))
    else:
        pts = sup.get("points")
        if not isinstance(pts, list) or len(pts) != 3:
            raise InputError("needs three points (point group names or [x, y, z])",
                             "support.points")
        names = tuple(p if isinstance(p, str) else None for p in pts)
        coords = tuple(None if isinstance(p, str) else _point(p, scale, f"support.points[{j}]")
                       for j, p in enumerate(pts))
        support = Support("3-2-1", points=coords)
    return support, names


def _sensors(data: dict, scale: float) -> list:
    """``[[sensor]]``: at least one :class:`SensorSpec`, names unique."""
    sensors, seen = [], set()
    for i, s in enumerate(data.get("sensor", []) or []):
        sensors.append(_sensor(s, f"sensor[{i}]", scale, seen))
    if not sensors:
        raise InputError("needs at least one [[sensor]] (e.g. name = \"tcp_z\", point = "
                         "[x, y, z], direction = \"z\")", "sensor")
    return sensors


def _sensor(s, w: str, scale: float, seen: set) -> SensorSpec:
    """One ``[[sensor]]`` table (``w`` names it; ``seen``: the names so far, updated): a
    temperature at a point, or a displacement at a point or over a surface group along
    x, y, z or a unit vector."""
    if not isinstance(s, dict):
        raise InputError("must be a table", w)
    _unknown(s, _SENS, w)
    name = _string(s.get("name"), f"{w}.name")
    if name in seen or not name.replace("_", "").isalnum():
        raise InputError(f"sensor names must be unique letters, digits and _, got "
                         f"{name!r}", f"{w}.name")
    seen.add(name)
    q = _string(s.get("quantity", "displacement"), f"{w}.quantity",
                choices=("displacement", "temperature", "tilt"))
    if q == "tilt":
        return _tilt_sensor(s, w, name, scale)
    if "points" in s:
        raise InputError("points (two of them) belong to a quantity = \"tilt\" sensor; a "
                         "displacement or a thermometer has one point", f"{w}.points")
    if q == "temperature" and name.startswith("T_"):
        raise InputError(f"a thermometer's column is T_<name>_C (the measured-data "
                         f"contract); name it without \"T_\" ({name[2:]!r}), or its "
                         f"column reads T_{name}_C", f"{w}.name")
    point = _point(s["point"], scale, f"{w}.point") if "point" in s else None
    grp = _string(s["group"], f"{w}.group") if "group" in s else None
    if (point is None) == (grp is None) or (q == "temperature" and point is None):
        raise InputError("needs a point (or, for a displacement, a surface group)", w)
    return SensorSpec(name, q, point, grp, _direction(s.get("direction", "z"), w))


def _direction(d, w: str) -> tuple:
    """A sensor's ``direction``: ``"x"``, ``"y"``, ``"z"`` or a vector, as a unit vector."""
    if isinstance(d, str):
        return _DIRS.get(_string(d, f"{w}.direction", choices=tuple(_DIRS)))
    d = _point(d, 1.0, f"{w}.direction")
    _finite_vector(d, f"{w}.direction")
    if np.linalg.norm(d) == 0:
        raise InputError("must not be zero", f"{w}.direction")
    return tuple(float(v) for v in np.asarray(d) / np.linalg.norm(d))


def _tilt_sensor(s: dict, w: str, name: str, scale: float) -> SensorSpec:
    """A ``quantity = "tilt"`` sensor: ``points = [p1, p2]`` (mesh unit) and the
    ``direction`` both probes read; the tilt (d(p2) − d(p1))/|p2 − p1| [rad, reported in
    µrad]. The direction must be across the line p1→p2 (along it the difference is a
    strain, not a tilt)."""
    pts = s.get("points")
    if not isinstance(pts, list) or len(pts) != 2:
        raise InputError("a tilt needs points = [[x1, y1, z1], [x2, y2, z2]] (the two "
                         "probes, mesh unit)", f"{w}.points")
    if "point" in s or "group" in s:
        raise InputError("a tilt is read at its two points, not at point or group", w)
    if "direction" not in s:
        raise InputError("a tilt needs the direction its two probes read (e.g. \"y\" "
                         "for A, the tilt about X of a spindle along Z)", w)
    p = tuple(_point(v, scale, f"{w}.points[{k}]") for k, v in enumerate(pts))
    d = _direction(s["direction"], w)
    line = np.subtract(p[1], p[0])
    base = float(np.linalg.norm(line))
    if base == 0.0:
        raise InputError("the two points coincide: a tilt needs a base", f"{w}.points")
    if abs(float(np.dot(line / base, d))) > 0.01:
        raise InputError("direction must be across the line between the two points (a "
                         "difference along it is a strain, not a tilt)", f"{w}.direction")
    return SensorSpec(name, "tilt", direction=d, points=p)


def _fem_and_outputs(data: dict, cycle: Schedule3D) -> tuple:
    """``[fem]`` and ``[outputs]``: (solver, dt [s], output interval [s], field interval
    [s], the outputs table); the sample and snapshot counts bounded."""
    fem = _table(data, "fem", "")
    _unknown(fem, _FEM, "fem")
    solver = _string(fem.get("solver", "reduced"), "fem.solver", choices=tuple(_SOLVERS))
    dt = _number(fem.get("dt_s", 60.0), "fem.dt_s", positive=True)
    oi = _number(fem.get("output_interval_s", 60.0), "fem.output_interval_s", positive=True)
    out = _table(data, "outputs", "")
    _unknown(out, _OUT, "outputs")
    total = float(cycle.edges_s[-1])
    fi = _number(out.get("field_interval_s", 3600.0), "outputs.field_interval_s", positive=True)
    if total / fi > 2000:
        raise InputError(f"{total / fi:.0f} field snapshots; at most 2000",
                         "outputs.field_interval_s")
    return solver, dt, oi, fi, out


# -- physical ranges and sizes (arfem.ranges: the table the rod's reader uses too) ----------

#: Largest number of sensor samples and θ-method steps over the cycle without
#: ``--allow-large`` (the rod's limit: :data:`arfem.scenarios.rod.scenario.MAX_TIME_STEPS`).
MAX_SAMPLES = 200_000
MAX_STEPS = 2_000_000
#: Largest mesh file read without ``--allow-large`` [bytes] (the limit of any text input).
MAX_MESH_BYTES = 256 * 1024 ** 2


def _finite_vector(v, where: str) -> None:
    """Refuse a vector with a NaN or an infinite component (one line, before any
    arithmetic on it could warn)."""
    if not all(np.isfinite(x) for x in v):
        raise InputError(f"must be finite, got {list(v)!r}", where)


def _check_ranges(sc: GeometryScenario, data: dict) -> None:
    """Every number of a validated scenario within its physical range
    (:data:`arfem.ranges.RANGES`: the same entries as the rod's reader for λ, ρ, c, α,
    E, h, an ambient, a heat input and a speed): one line naming the key."""
    check_range("ambient_C", sc.reference_C, "geometry.reference_C")
    for i, mat in enumerate(sc.materials.values()):
        for k in ("conductivity_W_mK", "density_kg_m3", "specific_heat_J_kgK",
                  "expansion_1_K", "youngs_modulus_Pa"):
            check_range(k, getattr(mat, k), f"material[{i}].{k}")
    cyc = sc.cycle
    check_range("duration_s", float(cyc.edges_s[-1]), "cycle (its total length)")
    csv_cycle = isinstance(data.get("cycle"), dict) and "csv" in data["cycle"]
    for j in range(cyc.speed_rpm.size):
        w = f"cycle.csv: row {j + 2}" if csv_cycle else f"cycle.phases[{j}]"
        check_range("speed_rpm", float(cyc.speed_rpm[j]), f"{w}.speed_rpm")
        check_range("ambient_C", float(cyc.ambient_C[j]), f"{w}.ambient_C")
    for i, src in enumerate(sc.sources):
        key, kind = (("power_W", "power_W") if src.spec.kind == "power"
                     else ("q_W_m2", "flux_W_m2"))
        for v in np.asarray(src.values, float):
            check_range(key, float(v), f"heat_source[{i}].{kind}")
    for i, conv in enumerate(sc.convections):
        _check_convection(conv, cyc.speed_rpm, f"convection[{i}]")
    for i, sen in enumerate(sc.sensors):
        _check_point(sen.point, f"sensor[{i}].point")
        for k, pt in enumerate(sen.points or ()):          # a tilt's two probes
            _check_point(pt, f"sensor[{i}].points[{k}]")
        _finite_vector(sen.direction, f"sensor[{i}].direction")
    for j, pt in enumerate(sc.support.points):
        _check_point(pt, f"support.points[{j}]")


def _check_convection(conv: "ConvectionSetting", speeds_rpm, where: str) -> None:
    """A convection group's h = a + b·n^m at every speed of the cycle (and at rest)
    within the range of an h, and its own ambient within the ambient's."""
    a, b, m = conv.h
    n = np.concatenate([[0.0], np.maximum(np.asarray(speeds_rpm, float), 0.0)])
    with np.errstate(over="ignore", invalid="ignore"):
        h = a + b * np.power(n, m)
    for hv, nv in zip(h, n):
        at = f" (at {nv:g} rpm)" if b else ""
        check_range("h_W_m2K", float(hv), f"{where}.h_W_m2K{at}")
    if conv.ambient_C is not None:
        check_range("ambient_C", conv.ambient_C, f"{where}.ambient_C")


def _check_point(point, where: str) -> None:
    """A point [m] (None: none given): finite, each coordinate a machine's."""
    if point is None:
        return
    _finite_vector(point, where)
    for x in point:
        check_range("coordinate_m", float(x), where)


def _check_sizes(sc: GeometryScenario, limits: Limits) -> None:
    """The sample and step counts and the mesh file's size within arfem's limits,
    unless ``limits.large`` (``--allow-large``): refused before anything is read or
    built."""
    if limits.large:
        return
    lift = "pass --allow-large to run it anyway"
    n_out = sc.total_s / sc.output_interval_s
    if n_out > MAX_SAMPLES:
        raise InputError(f"{n_out:.0f} samples; at most {MAX_SAMPLES} ({lift})",
                         "fem.output_interval_s")
    if sc.solver != "reduced" and sc.total_s / sc.dt_s > MAX_STEPS:
        raise InputError(f"{sc.total_s / sc.dt_s:.3g} {sc.solver} steps over the "
                         f"{sc.total_s:g} s cycle; at most {MAX_STEPS:g} ({lift})", "fem.dt_s")
    try:
        size = sc.mesh_path.stat().st_size
    except OSError:
        return                              # missing: the mesh reader says so
    if size > MAX_MESH_BYTES:
        raise InputError(f"{sc.mesh_path} is {size / 1024 ** 2:.0f} MiB; arfem reads at most "
                         f"{MAX_MESH_BYTES / 1024 ** 2:.0f} MiB ({lift})", "geometry.mesh")


# -- the model ------------------------------------------------------------------------------

@dataclass(frozen=True)
class GeometryModel:
    """Everything assembled for one geometry scenario.

    ``G`` holds one column per sensor (θ-functionals: temperature rows of the
    interpolation, displacement rows TᵀK⁻¹w); ``history`` the inputs on the union of
    every schedule's breakpoints.
    """

    scenario: GeometryScenario
    gmesh: GroupedMesh
    thermal: ThermalBody
    elastic: ElasticBody | None
    G: np.ndarray
    history: InputHistory
    timings_s: dict
    memory_estimate_bytes: int


def input_history(sc: GeometryScenario) -> InputHistory:
    """The scenario's inputs per interval between any two changes of its cycle or its
    sources, as the body's time solvers take them.

    Parameters
    ----------
    sc : GeometryScenario
        Its cycle (speed [rpm], ambient [°C]), sources and convections.

    Returns
    -------
    InputHistory
        ``edges_s`` [s]; per interval, the sources' inputs (power [W] or flux [W/m²],
        each source's own unit) followed by h·(ambient − reference) [W/m²] per
        convection, and each convection's h [W/(m²·K)] at the interval's speed.
    """
    edges = sc.cycle.edges_s
    for s in sc.sources:
        edges = np.union1d(edges, s.edges_s)
    edges = edges[np.concatenate([[True], np.diff(edges) > 1e-9 * edges[-1]])]
    mid = 0.5 * (edges[1:] + edges[:-1])

    def on(e, v):
        return np.asarray(v, float)[np.clip(np.searchsorted(e, mid) - 1, 0, len(v) - 1)]
    speed = on(sc.cycle.edges_s, sc.cycle.speed_rpm)
    amb = on(sc.cycle.edges_s, sc.cycle.ambient_C)
    cols = [on(s.edges_s, s.values) for s in sc.sources]
    hs = []
    for c in sc.convections:
        a, b, m = c.h
        h = a + b * np.power(np.maximum(speed, 0.0), m)
        hs.append(h)
        th_amb = (np.full_like(amb, c.ambient_C) if c.ambient_C is not None else amb) \
            - sc.reference_C
        cols.append(h * th_amb)
    u = np.column_stack(cols) if cols else np.zeros((mid.size, 0))
    H = np.column_stack(hs) if hs else np.zeros((mid.size, 0))
    return InputHistory(edges, u, H)


def _read_checked(sc: GeometryScenario) -> tuple:
    """(grouped mesh, memory estimate [bytes], support): the mesh read and every check
    that needs no assembly (cells, orientation, unit, memory, material and support
    point groups)."""
    gm = read_grouped_mesh(sc.mesh_path, sc.unit, where=f"{sc.source}: geometry.mesh "
                                                       f"({sc.mesh_path})")
    mesh = gm.mesh
    nv = int(mesh.t.max()) + 1
    n_heat = nv + (mesh.edges.shape[1] if sc.order == 2 else 0)
    if gm.cell_type == "hexahedron" and sc.order == 2:
        n_heat = nv + mesh.edges.shape[1]
    need = check_memory(n_heat, f"{sc.source}: geometry.mesh",
                        nnz_per_row_heat=30.0 if sc.order == 2 else 14.0)
    for grp in sc.materials:
        gm.volume_group(grp, f"{sc.source}: material.group")
    support = sc.support
    if sc.support.kind == "3-2-1" and any(sc.support_names):
        pts = []
        for j, (nm, c) in enumerate(zip(sc.support_names, sc.support.points)):
            if nm is None:
                pts.append(c)
            elif nm in gm.points:
                pts.append(tuple(gm.points[nm]))
            else:
                raise InputError(f"the mesh has no point group {nm!r} (it has "
                                 f"{gm.describe_groups()})", f"{sc.source}: support.points[{j}]")
        support = Support("3-2-1", points=tuple(pts))
    return gm, need, support


def check_geometry_scenario(sc: GeometryScenario) -> None:
    """Refuse (one line) what :func:`build_geometry_model` would refuse, at the cost of
    the mesh read and the heat assembly, without the elastic one: every group, the
    cells, the unit, the memory estimate, each sensor point inside the mesh. ``arfem
    sweep`` calls it once on its base before the first point (every point shares the
    mesh), so a bad mesh is exit 2 with nothing written, not a failed point each."""
    from arfem.fem.body import locate
    gm, _, support = _read_checked(sc)
    try:
        th = ThermalBody.build(gm, sc.materials, [s.spec for s in sc.sources],
                               [c.spec for c in sc.convections], order=sc.order)
        for s in sc.sensors:
            if s.group is not None:
                gm.surface_group(s.group, f"sensor {s.name!r}.group")
            for k, p in enumerate([s.point] if s.point is not None else s.points):
                locate(th.basis, p, f"sensor {s.name!r}.point" + (f"s[{k}]" if s.points
                                                                   else ""), gm.source)
        if support.kind == "clamped":
            gm.surface_group(support.group, "support.group")
    except InputError as exc:
        if exc.where and exc.where.startswith(sc.source):
            raise
        raise exc.at(sc.source) from None


def build_geometry_model(sc: GeometryScenario, progress=None) -> GeometryModel:
    """Read the mesh, check memory, assemble heat and elasticity, form the sensors' rows."""
    progress = progress or (lambda s: None)
    tm = {}
    t0 = time.perf_counter()
    progress("reading the mesh")
    gm, need, support = _read_checked(sc)
    tm["read_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    progress("assembling heat")
    try:
        th = ThermalBody.build(gm, sc.materials, [s.spec for s in sc.sources],
                               [c.spec for c in sc.convections], order=sc.order)
        tm["assemble_heat_s"] = time.perf_counter() - t0
        cols = []
        temp = [s for s in sc.sensors if s.quantity == "temperature"]
        if temp:
            P = th.probe(np.array([s.point for s in temp]).T, [s.name for s in temp])
        t0 = time.perf_counter()
        disp = [s for s in sc.sensors if s.elastic]
        el = None
        if disp or sc.fields:
            progress("assembling and factoring elasticity")
            n_fields = int(sc.total_s // sc.field_interval_s) + 1 if sc.fields else 0
            el = ElasticBody.build(th, support, n_solves=len(disp) + n_fields)
        tm["elastic_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        W = []
        for i, s in enumerate(sc.sensors):
            if s.elastic:
                W.append(el.sensor_weight(s, f"sensor {s.name!r}"))
        Gd = el.functional(np.column_stack(W)) if W else None
        k_t = k_d = 0
        for s in sc.sensors:
            if s.quantity == "temperature":
                cols.append(np.asarray(P[k_t].toarray()).ravel())
                k_t += 1
            else:
                cols.append(Gd[:, k_d])
                k_d += 1
        tm["sensors_s"] = time.perf_counter() - t0
    except InputError as exc:
        if exc.where and exc.where.startswith(sc.source):
            raise
        raise exc.at(sc.source) from None
    return GeometryModel(sc, gm, th, el, np.column_stack(cols), input_history(sc), tm, need)


@dataclass(frozen=True)
class GeometryRun:
    """A solved geometry scenario: sensor histories (temperatures in °C, displacements
    in µm) and, where asked, fields."""

    model: GeometryModel
    result: BodyResult
    timings_s: dict

    def sensor_series(self) -> dict:
        """{column name: values}: ``T_<name>_C`` [°C], ``d_<name>_um`` [µm] and
        ``tilt_<name>_urad`` [µrad]."""
        out = {}
        sc = self.model.scenario
        for j, s in enumerate(sc.sensors):
            y = self.result.outputs[:, j]
            out[s.column] = (y + sc.reference_C if s.quantity == "temperature"
                             else y * s.record_scale)
        return out


def solve_geometry(model: GeometryModel, progress=None,
                   mode_cache: dict | None = None) -> GeometryRun:
    """The scenario's transient: sensors every ``output_interval_s`` and fields every
    ``field_interval_s``, by the reduced-modal solve or the θ-method.

    ``mode_cache``: the reduced solve's ``{h tuple: BodyModes}``, to be shared only
    between runs of one model with the same h history (``arfem sweep`` over powers)."""
    progress = progress or (lambda s: None)
    sc = model.scenario
    total = sc.total_s
    t_out = np.union1d(np.arange(0.0, total, sc.output_interval_s), [total])
    t_f = (np.union1d(np.arange(0.0, total, sc.field_interval_s), [total])
           if sc.fields else None)
    t0 = time.perf_counter()
    progress("transient heat")
    theta = _SOLVERS[sc.solver]
    if theta is None:
        kinds = [s.kind_index for s in sc.sensors]
        res = solve_body_reduced(model.thermal, model.history, model.G, t_out, t_f, kinds=kinds,
                            mode_cache=mode_cache)
    else:
        full = solve_body_theta(model.thermal, model.history, model.G, sc.dt_s, theta, t_f)
        pick = np.clip(np.searchsorted(full.times_s, t_out - 1e-6), 0, full.times_s.size - 1)
        res = BodyResult(full.times_s[pick], full.outputs[pick], full.field_times_s,
                         full.fields)
    return GeometryRun(model, res, {**model.timings_s, "solve_s": time.perf_counter() - t0})


# -- outputs ---------------------------------------------------------------------------------

def _vertex_values(model: GeometryModel, theta: np.ndarray) -> np.ndarray:
    nv = int(model.gmesh.mesh.t.max()) + 1
    return theta[..., model.thermal.basis.nodal_dofs[0, :nv]]


def write_fields_xdmf(run: GeometryRun, path: Path) -> None:
    """θ [K above reference] and u [m] at the mesh vertices, an XDMF 3 time series."""
    import meshio
    m = run.model
    mesh = m.gmesh.mesh
    nv = int(mesh.t.max()) + 1
    ctype = "hexahedron" if m.gmesh.cell_type == "hexahedron" else "tetra"
    t = mesh.t
    if ctype == "hexahedron":
        from arfem.fem.gmsh_io import VTK_TO_SKFEM_HEX
        inv = np.argsort(VTK_TO_SKFEM_HEX)
        t = t[inv]
    path.parent.mkdir(parents=True, exist_ok=True)
    res = run.result
    U = (m.elastic.displacement(res.fields) if m.elastic is not None else None)
    # meshio's TimeSeriesWriter puts the .h5 in the working directory (meshio 5.3), so
    # write from inside the target directory
    import os
    here = os.getcwd()
    os.chdir(path.parent)
    try:
        with meshio.xdmf.TimeSeriesWriter(path.name) as w:
            w.write_points_cells(mesh.p[:, :nv].T, [(ctype, t.T)])
            for k, tk in enumerate(res.field_times_s):
                data = {"temperature_C": _vertex_values(m, res.fields[k])
                        + m.scenario.reference_C}
                if U is not None:
                    nd = m.elastic.basis.nodal_dofs[:, :nv]
                    data["displacement_m"] = U[k][nd].T
                w.write_data(float(tk), point_data=data)
    finally:
        os.chdir(here)


#: distinct, saturated colours for the surface groups (tab20's pale halves left out, which
#: made half the groups and their legend entries unreadable on white)
_GROUP_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b",
                  "#e377c2", "#17becf", "#bcbd22", "#393b79", "#637939", "#843c39")


def group_roles(sc: GeometryScenario) -> dict:
    """{surface group: what the scenario does with it}, for the picture's legend:
    ``heat source <name>``, ``convection h = … W/(m²K)``, ``support (clamped)``."""
    roles: dict = {}

    def add(g, text):
        roles[g] = f"{roles[g]}; {text}" if g in roles else text
    for s in sc.sources:
        add(s.spec.group, f"heat source {s.spec.name}")
    for c in sc.convections:
        a, b, m = c.h
        add(c.spec.group, f"convection h = {a:g}" + (f" + {b:g}·n^{m:g}" if b else "")
            + " W/(m²K)")
    if sc.support.kind == "clamped":
        add(sc.support.group, "support (clamped)")
    return roles


def _sensor_labels(sensors) -> list:
    """[(point [m], label)]: sensors at one point share a label (``tcp_x, tcp_y, tcp_z``);
    a thermometer's name carries ``(°C)``."""
    at: dict = {}
    for s in sensors:
        pts = [s.point] if s.point is not None else list(s.points)
        for k, p in enumerate(pts):
            key = tuple(round(float(c), 12) for c in p)
            at.setdefault(key, []).append(
                s.name + (" (°C)" if s.quantity == "temperature" else "")
                + (f" (tilt, probe {k + 1})" if s.quantity == "tilt" else ""))
    return [(np.array(k), ", ".join(v)) for k, v in at.items()]


def geometry_picture(gm: GroupedMesh, path: Path, sensors=(), title: str = "",
                     roles: dict | None = None) -> None:
    """Off-screen PNG of the mesh's surface groups and the sensors.

    Every surface group in its own saturated colour with a legend entry (its role from
    ``roles``, e.g. :func:`group_roles`); faces on the outside drawn half transparent, so
    that groups inside the body (a bearing seat, the motor's air gap) and the sensors
    show through; each sensor point marked and labelled with its name, in front of the
    geometry.
    """
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)     # no X-server chatter
    roles = roles or {}
    mesh = gm.mesh
    nv = int(mesh.t.max()) + 1
    P = mesh.p[:, :nv].T
    size = float(np.ptp(P, axis=0).max())
    pl = pv.Plotter(off_screen=True, window_size=(1000, 860))
    bnd = set(mesh.boundary_facets().tolist())

    def surface(fac):
        f = mesh.facets[:, np.asarray(fac)].T
        return pv.PolyData(P, np.column_stack([np.full(len(f), f.shape[1]), f]).ravel())
    entries = []
    for i, (name, fac) in enumerate(sorted(gm.surfaces.items())):
        fac = np.asarray(fac)
        if fac.size == 0:
            continue
        colour = _GROUP_COLOURS[i % len(_GROUP_COLOURS)]
        # a heated face, or an interface inside the body, is drawn opaque
        outside = np.isin(fac, list(bnd)) & ("heat source" not in roles.get(name, ""))
        if outside.any():
            pl.add_mesh(surface(fac[outside]), color=colour, opacity=0.3)
        if (~outside).any():
            pl.add_mesh(surface(fac[~outside]), color=colour, opacity=1.0)
        entries.append([f"{name}: {roles[name]}" if name in roles else name, colour])
    grouped = set(np.concatenate([np.asarray(v) for v in gm.surfaces.values()]).tolist()) \
        if gm.surfaces else set()
    rest = np.asarray(sorted(bnd - grouped))
    if rest.size:                                  # outer faces in no group
        pl.add_mesh(surface(rest), color="lightgrey", opacity=0.25)
        entries.append(["(faces in no group)", "lightgrey"])
    for point, label in _sensor_labels(sensors):
        pl.add_mesh(pv.Sphere(radius=0.012 * size, center=point), color="black")
        pl.add_point_labels(point[None, :], [label], font_size=20, point_size=1,
                            shape_opacity=0.85, shape_color="white", text_color="black",
                            always_visible=True, margin=4)
    # from the front (−y), to the side (+x) and a little from below: a spindle unit's
    # nose and the TCP face the viewer, the column stub (+y) stays behind; orthographic,
    # so that one scale bar holds at every depth
    c = 0.5 * (P.min(axis=0) + P.max(axis=0))
    r = float(np.linalg.norm(np.ptp(P, axis=0)))
    from arfem.fem.export import ParallelView
    pl.enable_parallel_projection()
    pl.camera_position = [tuple(c + r * np.array([1.2, -2.0, -0.6])), tuple(c), (0, 0, 1)]
    cam = pl.camera
    view = ParallelView.of(cam.position, cam.focal_point, cam.up, 1.0, 2)
    w, h = pl.window_size
    half_w = float(np.ptp((P - c) @ np.asarray(view.right))) / 2
    half_h = float(np.ptp((P - c) @ np.asarray(view.up))) / 2
    cam.parallel_scale = 1.12 * max(half_h, half_w * h / w)    # the body fills the view
    img = pl.screenshot(None, return_img=True)
    view = ParallelView.of(cam.position, cam.focal_point, cam.up, cam.parallel_scale,
                           img.shape[0])
    pl.close()
    _picture_with_legend(img, entries, title, path, view)


def _picture_with_legend(img: np.ndarray, entries: list, title: str, path: Path,
                         view=None) -> None:
    """The rendered view with the groups' legend beside it (never over the geometry), a
    scale bar and the model's axes (``view``: :class:`arfem.fem.export.ParallelView`)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch
    fig = plt.figure(figsize=(14, 8.4))
    ax = fig.add_axes([0.30, 0.0, 0.70, 0.94])
    ax.imshow(img)
    ax.set_axis_off()
    if view is not None:
        from arfem.fem.export import draw_axis_triad, draw_scale_bar
        draw_scale_bar(ax, view, img.shape)
        draw_axis_triad(ax, view, (0.06 * img.shape[1], 0.9 * img.shape[0]),
                        0.07 * img.shape[1])
    handles = [Patch(facecolor=col, edgecolor="black", label=lab) for lab, col in entries]
    if handles:
        fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.01, 0.92),
                   fontsize=11, frameon=True, title="surface groups (outer faces "
                   "translucent)", title_fontsize=11)
    if title:
        fig.suptitle(title, fontsize=13)
    fig.savefig(path, dpi=100, bbox_inches="tight", pad_inches=0.15)
    plt.close(fig)


def _sensor_figure(run: GeometryRun, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ser = run.sensor_series()
    t_h = run.result.times_s / 3600.0
    d = {k: v for k, v in ser.items() if k.startswith("d_")}
    T = {k: v for k, v in ser.items() if k.startswith("T_")}
    a = {k: v for k, v in ser.items() if k.startswith("tilt_")}
    n = int(bool(d)) + int(bool(T)) + int(bool(a))
    fig, axes = plt.subplots(n, 1, figsize=(9, 3.2 * n), sharex=True, squeeze=False)
    i = 0
    for group, unit in ((d, "displacement [µm]"), (a, "tilt [µrad]"),
                        (T, "temperature [°C]")):
        if not group:
            continue
        ax = axes[i, 0]
        for k, v in group.items():
            ax.plot(t_h, v, label=k)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, ncol=3)
        i += 1
    axes[-1, 0].set_xlabel("time [h]")
    axes[0, 0].set_title(f"{run.model.scenario.name}: sensors")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def summary(run: GeometryRun) -> dict:
    """Summary figures: mesh size, per-sensor peak and final values, timings."""
    m = run.model
    ser = run.sensor_series()
    per = {}
    for k, v in ser.items():
        j = int(np.argmax(np.abs(v - (m.scenario.reference_C if k.startswith("T_") else 0))))
        per[k] = {"peak": float(v[j]), "peak_time_h": float(run.result.times_s[j] / 3600),
                  "final": float(v[-1])}
    return {"scenario": m.scenario.name, "mesh": str(m.scenario.mesh_path.name),
            "cell_type": m.gmesh.cell_type, "order": m.scenario.order,
            "n_elements": int(m.gmesh.mesh.nelements), "heat_dofs": m.thermal.ndofs,
            "elastic_dofs": m.elastic.ndofs if m.elastic is not None else 0,
            "memory_estimate_GB": m.memory_estimate_bytes / 1e9,
            "solver": m.scenario.solver, "n_modes": run.result.n_modes,
            "reduced_step_change_per_unit_input": (
                None if run.result.step_change is None else
                {s.name: float(c) for s, c in zip(m.scenario.sensors,
                                                  run.result.step_change)}),
            "groups": {"volumes": sorted(m.gmesh.volumes), "surfaces": sorted(m.gmesh.surfaces),
                       "points": sorted(m.gmesh.points)},
            "areas_m2": m.thermal.areas_m2, "sensors": per}


def _summary_md(s: dict, run: GeometryRun) -> str:
    lines = [f"# {s['scenario']}: spindle unit from a mesh", "",
             f"Mesh `{s['mesh']}`: {s['n_elements']} {s['cell_type']} cells, order "
             f"{s['order']}, {s['heat_dofs']} temperature and {s['elastic_dofs']} "
             f"displacement unknowns; solver {s['solver']}"
             + (f" ({s['n_modes']} modes)" if s['n_modes'] else "") + ".", "",
             "| sensor | peak | at [h] | final |", "|---|---|---|---|"]
    for k, v in s["sensors"].items():
        lines.append(f"| {k} | {v['peak']:.4f} | {v['peak_time_h']:.2f} | {v['final']:.4f} |")
    lines += ["", "![geometry](geometry.png)", "", "![sensors](sensors.png)", ""]
    return "\n".join(lines)


def write_geometry_outputs(run: GeometryRun, out_dir: Path, progress=None,
                           mode_cache: dict | None = None, copy_plan=None) -> None:
    """sensors.csv, sensors.json, summary.json/.md, geometry.png, sensors.png, fields;
    ``mode_cache``: the run's reduced-solve modes, reused by the model's export;
    ``copy_plan``: the scenario copy planned by the caller (from the text it read)."""
    progress = progress or (lambda s: None)
    sc = run.model.scenario
    ser = run.sensor_series()
    t = run.result.times_s
    write_csv(out_dir / "sensors.csv", {"time_s": t, "time_h": t / 3600.0, **ser})
    write_json(out_dir / "sensors.json", {
        "scenario": sc.name, "time_s": t.tolist(),
        "sensors": [{"name": s.name, "quantity": s.quantity, "column": s.column,
                     "unit": s.unit, "point_m": s.point, "group": s.group,
                     "direction": s.direction if s.elastic else None,
                     **({"points_m": list(s.points), "about": s.about, "base_m": s.base_m}
                        if s.quantity == "tilt" else {}),
                     "values": ser[s.column].tolist()}
                    for s in sc.sensors]})
    s = summary(run)
    write_json(out_dir / "summary.json", s)
    atomic_write_text(out_dir / "summary.md", _summary_md(s, run))
    _sensor_figure(run, out_dir / "sensors.png")
    if sc.picture:
        progress("geometry picture")
        vols = [f"{s.spec.name} in {s.spec.group}" for s in sc.sources
                if s.spec.group in run.model.thermal.source_volumes_m3]
        geometry_picture(run.model.gmesh, out_dir / "geometry.png", sc.sensors,
                         title=f"{sc.name}: physical groups and sensors" + (
                             "\nheat generated in volume groups: " + ", ".join(vols)
                             if vols else ""), roles=group_roles(sc))
    if sc.fields and run.result.fields is not None:
        progress("fields.xdmf3")
        write_fields_xdmf(run, out_dir / "fields" / "fields.xdmf3")
    from arfem.scenarios.geometry.copy import plan_scenario_copy, write_copy
    copy, text = (plan_scenario_copy(sc.source, WRITES) if copy_plan is None
                  else copy_plan)                          # re-runnable from anywhere
    if copy is not None:
        write_copy(copy, text, out_dir)
    progress("model.json")                      # issue 32 item 5: the MIMO model
    from arfem import __version__
    write_exports(run, out_dir, __version__, mode_cache,
                  scenario_copy=None if copy is None else copy.names[0])


def run_geometry(path, out, force: bool = False, progress=None, limits: Limits | None = None,
                 toml=None) -> GeometryRun:
    """Load, solve and write one geometry scenario into ``out`` (atomically); ``limits``
    as the user allows (``--allow-large``), ``toml`` the file already read (once)."""
    from arfem.io import read_toml_file
    from arfem.scenarios.html_report import write_html_report
    from arfem.scenarios.outdir import prepare_out_dir, staged_out_dir
    progress = progress or (lambda s: None)
    from arfem.scenarios.geometry.copy import plan_scenario_copy
    toml = read_toml_file(path, limits) if toml is None else toml
    sc = load_geometry_scenario(path, limits, toml)
    copy, text = plan_scenario_copy(sc.source, WRITES, toml.text)
    prepare_out_dir(out, force, writes=WRITES + (copy.names if copy else ()),
                    inputs=[p for p, _ in copy.files] if copy else ())
    model = build_geometry_model(sc, progress)
    modes = {}                                  # the reduced solve's, for the export
    run = solve_geometry(model, progress, mode_cache=modes)
    modes = {h: md for h, md in modes.items() if md.n_blocks > 0}   # the grown basis
    with staged_out_dir(out, force) as stage:
        write_geometry_outputs(run, stage, progress, modes, (copy, text))
        progress("report.html")
        write_html_report(stage)
    return run


def main_run_geometry(args, toml=None, path=None) -> int:
    """``arfem run`` on a scenario with ``[geometry]`` (``toml``: the file as read;
    ``path``: its file, where ``args.scenario`` is a shipped name), with its progress and
    the user's limits (``--allow-large``)."""
    from arfem.scenarios.progress import Progress
    t0 = time.perf_counter()
    with Progress(8, "arfem run", enabled=not getattr(args, "no_progress", False)) as pr:
        run = run_geometry(args.scenario if path is None else path, args.out, args.force, pr,
                           getattr(args, "limits", None), toml)
    s = summary(run)
    parts = [f"{k} peak {v['peak']:.3f}" for k, v in s["sensors"].items()]
    print(f"{s['scenario']}: {s['n_elements']} {s['cell_type']} cells, {s['heat_dofs']} "
          f"temperature unknowns; " + ", ".join(parts)
          + f" -> {args.out} ({time.perf_counter() - t0:.1f} s)")
    return 0
