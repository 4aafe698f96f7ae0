"""Allocation scenario files (TOML): strict reading into a validated object.

Layout (every key carries its unit; unknown keys are refused)::

    [scenario]   name, description, formula = "screw"|"paper",
                 constraint = "composed"|"worst_case",
                 reference_accuracy_mm = {unit = mm, ...}   (e.g. a paper's table)
    [tolerance]  delta_E_mm (> 0), working_radius_mm (>= 0, default 0)
    [cost]       a (> 0), b_mm (> 0)                      paper eq. 14
    [optimizer]  pop_size, n_gen, crossover_prob, mutation_prob, eta_crossover,
                 eta_mutation, seed, pick = "compromise"|"min_cost"|"min_pitch"
    [tool]       offset_mm = [x, y, z], rpy_deg = [r, p, y]   functional point
    [[units]]    name, motion = "translation"|"rotation", axis = "x"|"y"|"z",
                 offset_mm, rpy_deg, joint_mm (translation) | joint_deg (rotation),
                 free = [...of dx dy dz dalpha dbeta dgamma],
                 translation_mm = [lo, hi], rotation_mrad = [lo, hi],
                 fixed = {dx_mm = .., dalpha_mrad = ..}   (components not free)
    [spindle]    optional thermal unit: name, q_W_m2, model = "ar"|"ar_corrected"|"fem",
                 dtau_s, cycle = "paper", compensated, after = "<unit>", offset_mm, rpy_deg

The unit's nominal pose is Trans(offset)·Rot(rpy)·Joint, Joint being a
translation of ``joint_mm`` along, or a rotation of ``joint_deg`` about, its axis.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np


from arfem.models.allocation import screw
from arfem.models.allocation.problem import COMPONENTS, COMPONENT_UNIT, ROTATIONS, Chain, Settings, Unit
from arfem.params import PAPER_PHASES_S, PLAUSIBLE_RANGES, InputError, steps_per_segment

__all__ = ["AllocationScenario", "SpindleSpec", "UnitSpec", "parse_scenario",
           "build_chain"]

_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")


@dataclass(frozen=True)
class UnitSpec:
    name: str
    motion: str
    axis: str
    pose: np.ndarray
    free: tuple
    bounds: dict
    fixed: dict


@dataclass(frozen=True)
class SpindleSpec:
    name: str
    q_W_m2: float
    model: str
    dtau_s: float
    compensated: bool
    after: str
    pose: np.ndarray


@dataclass(frozen=True)
class AllocationScenario:
    """A validated allocation scenario (see the module docstring for the file layout)."""

    source: str
    name: str
    description: str
    settings: Settings
    units: tuple
    tool: np.ndarray
    spindle: SpindleSpec | None = None
    reference_accuracy_mm: dict | None = None


class _Reader:
    def __init__(self, where: str):
        self.where = where

    def err(self, key: str, msg: str) -> InputError:
        return InputError(msg, f"{self.where}: {key}")

    def table(self, d, key, allowed, required=()):
        if not isinstance(d, dict):
            raise self.err(key, f"must be a table, got {type(d).__name__}")
        for k in d:
            if k not in allowed:
                raise self.err(f"{key}.{k}" if key else k,
                               f"unknown key (allowed: {', '.join(sorted(allowed))})")
        for k in required:
            if k not in d:
                raise self.err(f"{key}.{k}" if key else k, "is required")
        return d

    def number(self, d, key, path, default=None, low=None, high=None, low_open=False,
               high_open=False):
        if key not in d:
            if default is None:
                raise self.err(path, "is required")
            return float(default)
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.err(path, f"must be a number, got {type(v).__name__} {v!r}")
        v = float(v)
        if not math.isfinite(v):
            raise self.err(path, f"must be finite, got {v!r}")
        if low is not None and (v < low or (low_open and v == low)):
            raise self.err(path, f"must be {'>' if low_open else '>='} {low:g}, got {v:g}")
        if high is not None and (v > high or (high_open and v == high)):
            raise self.err(path, f"must be {'<' if high_open else '<='} {high:g}, got {v:g}")
        return v

    def integer(self, d, key, path, default, low, high):
        if key not in d:
            return int(default)
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(path, f"must be an integer, got {type(v).__name__} {v!r}")
        if v < low:
            raise self.err(path, f"must be >= {low}, got {v}")
        if v > high:
            raise self.err(path, f"must be <= {high}, got {v}")
        return int(v)

    def choice(self, d, key, path, options, default=None):
        if key not in d:
            if default is None:
                raise self.err(path, "is required")
            return default
        v = d[key]
        if not isinstance(v, str) or v not in options:
            raise self.err(path, f"must be one of {', '.join(map(repr, options))}, got {v!r}")
        return v

    def string(self, d, key, path, default=None, pattern=None):
        if key not in d:
            if default is None:
                raise self.err(path, "is required")
            return default
        v = d[key]
        if not isinstance(v, str):
            raise self.err(path, f"must be a string, got {type(v).__name__} {v!r}")
        if pattern is not None and not pattern.match(v):
            raise self.err(path, f"must be a name of letters, digits, '_' or '-', got {v!r}")
        return v

    def boolean(self, d, key, path, default):
        if key not in d:
            return default
        v = d[key]
        if not isinstance(v, bool):
            raise self.err(path, f"must be true or false, got {v!r}")
        return v

    def vector(self, d, key, path, n=3, default=None, bound=1e5):
        """``n`` finite numbers, each within ±``bound`` (in the unit the key names: a
        larger value is a wrong unit, and would overflow the error model)."""
        if key not in d:
            return np.array(default if default is not None else [0.0] * n, float)
        v = d[key]
        if not isinstance(v, list) or len(v) != n:
            raise self.err(path, f"must be a list of {n} numbers, got {v!r}")
        out = []
        for i, x in enumerate(v):
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise self.err(f"{path}[{i}]", f"must be a finite number, got {x!r}")
            if abs(x) > bound:
                raise self.err(f"{path}[{i}]", f"must be within ±{bound:g} (wrong unit?), "
                                               f"got {x:g}")
            out.append(float(x))
        return np.array(out)

    def interval(self, d, key, path, default):
        lo, hi = self.vector(d, key, path, 2, default, bound=1e3)
        if lo < 0:
            raise self.err(path, f"lower bound must be >= 0 (an error magnitude), got {lo:g}")
        if not hi > lo:
            raise self.err(path, f"upper bound must exceed the lower, got [{lo:g}, {hi:g}]")
        return float(lo), float(hi)


_UNIT_KEYS = {"name", "motion", "axis", "offset_mm", "rpy_deg", "joint_mm", "joint_deg", "free",
              "translation_mm", "rotation_mrad", "fixed"}
_AXES = {"x": 0, "y": 1, "z": 2}


def _unit(rd: _Reader, d, i, names) -> UnitSpec:
    key = f"units[{i}]"
    rd.table(d, key, _UNIT_KEYS, required=("name", "motion", "axis"))
    name = rd.string(d, "name", f"{key}.name", pattern=_NAME_RE)
    if name in names:
        raise rd.err(f"{key}.name", f"duplicate unit name {name!r}")
    motion = rd.choice(d, "motion", f"{key}.motion", ("translation", "rotation"))
    axis = rd.choice(d, "axis", f"{key}.axis", tuple(_AXES))
    wrong = "joint_deg" if motion == "translation" else "joint_mm"
    if wrong in d:
        raise rd.err(f"{key}.{wrong}", f"does not apply to a {motion} unit "
                                      f"(use {'joint_mm' if wrong == 'joint_deg' else 'joint_deg'})")
    g = screw.pose(rd.vector(d, "offset_mm", f"{key}.offset_mm"),
                   rd.vector(d, "rpy_deg", f"{key}.rpy_deg"))
    joint = np.eye(4)
    if motion == "translation":
        joint[_AXES[axis], 3] = rd.number(d, "joint_mm", f"{key}.joint_mm", default=0.0)
    else:
        ang = [0.0, 0.0, 0.0]
        ang[_AXES[axis]] = rd.number(d, "joint_deg", f"{key}.joint_deg", default=0.0)
        joint = screw.pose([0, 0, 0], ang)
    free = d.get("free", list(COMPONENTS))
    if not isinstance(free, list) or not all(isinstance(c, str) for c in free):
        raise rd.err(f"{key}.free", f"must be a list of component names, got {free!r}")
    for c in free:
        if c not in COMPONENTS:
            raise rd.err(f"{key}.free", f"unknown component {c!r} (allowed: {', '.join(COMPONENTS)})")
    if len(set(free)) != len(free):
        raise rd.err(f"{key}.free", "lists a component twice")
    tb = rd.interval(d, "translation_mm", f"{key}.translation_mm", [0.0, 0.005])
    rb = rd.interval(d, "rotation_mrad", f"{key}.rotation_mrad", [0.0, 0.005])
    fixed_in = d.get("fixed", {})
    allowed_fixed = {f"{c}_{COMPONENT_UNIT[c]}" for c in COMPONENTS if c not in free}
    rd.table(fixed_in, f"{key}.fixed", allowed_fixed)
    fixed = {}
    for c in COMPONENTS:
        if c not in free:
            k = f"{c}_{COMPONENT_UNIT[c]}"
            fixed[c] = rd.number(fixed_in, k, f"{key}.fixed.{k}", default=0.0)
    bounds = {c: (rb if c in ROTATIONS else tb) for c in free}
    return UnitSpec(name, motion, axis, g @ joint, tuple(c for c in COMPONENTS if c in free),
                    bounds, fixed)


def parse_scenario(data: dict, source: str = "<scenario>") -> AllocationScenario:
    """Validate a parsed TOML mapping; raise :class:`InputError` naming ``source`` and the key."""
    rd = _Reader(source)
    rd.table(data, "", {"scenario", "tolerance", "cost", "optimizer", "tool", "units", "spindle"},
             required=("tolerance", "units"))
    sc = rd.table(data.get("scenario", {}), "scenario",
                  {"name", "description", "formula", "constraint", "reference_accuracy_mm"})
    name = rd.string(sc, "name", "scenario.name", default=Path(source).stem)
    desc = rd.string(sc, "description", "scenario.description", default="")
    formula = rd.choice(sc, "formula", "scenario.formula", ("screw", "paper"), "screw")
    constraint = rd.choice(sc, "constraint", "scenario.constraint", ("composed", "worst_case"),
                           "composed")
    tol = rd.table(data["tolerance"], "tolerance", {"delta_E_mm", "working_radius_mm"},
                   required=("delta_E_mm",))
    dE = rd.number(tol, "delta_E_mm", "tolerance.delta_E_mm", low=0.0, low_open=True)
    rw = rd.number(tol, "working_radius_mm", "tolerance.working_radius_mm", default=0.0, low=0.0)
    co = rd.table(data.get("cost", {}), "cost", {"a", "b_mm"})
    a = rd.number(co, "a", "cost.a", default=1.2, low=0.0, low_open=True)
    b = rd.number(co, "b_mm", "cost.b_mm", default=1.6, low=0.0, low_open=True)
    op = rd.table(data.get("optimizer", {}), "optimizer",
                  {"pop_size", "n_gen", "crossover_prob", "mutation_prob", "eta_crossover",
                   "eta_mutation", "seed", "pick"})
    settings = Settings(
        delta_E_mm=dE, working_radius_mm=rw, a=a, b_mm=b, formula=formula, constraint=constraint,
        pop_size=rd.integer(op, "pop_size", "optimizer.pop_size", 16, 4, 10_000),
        n_gen=rd.integer(op, "n_gen", "optimizer.n_gen", 30, 1, 100_000),
        crossover_prob=rd.number(op, "crossover_prob", "optimizer.crossover_prob", 0.9, 0.0, 1.0),
        mutation_prob=rd.number(op, "mutation_prob", "optimizer.mutation_prob", 0.1, 0.0, 1.0),
        eta_crossover=rd.number(op, "eta_crossover", "optimizer.eta_crossover", 20.0, 0.0,
                                low_open=True),
        eta_mutation=rd.number(op, "eta_mutation", "optimizer.eta_mutation", 20.0, 0.0,
                               low_open=True),
        seed=rd.integer(op, "seed", "optimizer.seed", 1, 0, 2**32 - 1),
        pick=rd.choice(op, "pick", "optimizer.pick", ("compromise", "min_cost", "min_pitch"),
                       "compromise"))
    tl = rd.table(data.get("tool", {}), "tool", {"offset_mm", "rpy_deg"})
    tool = screw.pose(rd.vector(tl, "offset_mm", "tool.offset_mm"),
                      rd.vector(tl, "rpy_deg", "tool.rpy_deg"))
    ulist = data["units"]
    if not isinstance(ulist, list) or not ulist:
        raise rd.err("units", "must be a non-empty array of tables ([[units]])")
    units = []
    for i, d in enumerate(ulist):
        units.append(_unit(rd, d, i, {u.name for u in units}))
    if not any(u.free for u in units):
        raise rd.err("units", "no unit has a free component: nothing to allocate")
    spindle = None
    if "spindle" in data:
        sp = rd.table(data["spindle"], "spindle",
                      {"name", "q_W_m2", "model", "dtau_s", "cycle", "compensated", "after",
                       "offset_mm", "rpy_deg"}, required=("q_W_m2",))
        sname = rd.string(sp, "name", "spindle.name", default="spindle", pattern=_NAME_RE)
        if sname in {u.name for u in units}:
            raise rd.err("spindle.name", f"duplicate unit name {sname!r}")
        model = rd.choice(sp, "model", "spindle.model", ("ar", "ar_corrected", "fem"), "ar")
        rd.choice(sp, "cycle", "spindle.cycle", ("paper",), "paper")
        comp = rd.boolean(sp, "compensated", "spindle.compensated", False)
        if comp and model == "fem":
            raise rd.err("spindle.compensated", "needs model 'ar' or 'ar_corrected' (the FEM "
                                                "is the reference the residual is taken against)")
        dtau = rd.number(sp, "dtau_s", "spindle.dtau_s", default=30.0, low=0.0, low_open=True)
        try:
            steps_per_segment([d for d, _ in PAPER_PHASES_S], dtau, what="paper-cycle phase")
        except InputError as exc:
            raise rd.err("spindle.dtau_s", exc.message) from None
        after = rd.string(sp, "after", "spindle.after", default=units[-1].name)
        if after not in {u.name for u in units}:
            raise rd.err("spindle.after", f"names no unit, got {after!r}")
        q = rd.number(sp, "q_W_m2", "spindle.q_W_m2", low=0.0, high=PLAUSIBLE_RANGES["q_W_m2"][1])
        spindle = SpindleSpec(
            sname, q, model, dtau, comp, after,
            screw.pose(rd.vector(sp, "offset_mm", "spindle.offset_mm"),
                       rd.vector(sp, "rpy_deg", "spindle.rpy_deg")))
    ref = None
    if "reference_accuracy_mm" in sc:
        names = {u.name for u in units}
        rt = rd.table(sc["reference_accuracy_mm"], "scenario.reference_accuracy_mm", names)
        ref = {k: rd.number(rt, k, f"scenario.reference_accuracy_mm.{k}", low=0.0)
               for k in rt}
    return AllocationScenario(source, name, desc, settings, tuple(units), tool, spindle, ref)


def build_chain(sc: AllocationScenario, rod=None) -> tuple[Chain, dict | None]:
    """Turn a scenario into a :class:`Chain`, resolving the spindle's thermal Δz.

    The spindle, if any, becomes a unit with every error fixed: Δz [mm] from
    :func:`arfem.models.allocation.thermal.spindle_dz_mm`, the others 0, inserted after
    the unit it names.

    Parameters
    ----------
    sc : AllocationScenario
        Unit and tool poses (translation [mm]), error bounds and fixed errors in
        scenario units ([mm], [mrad]); spindle heat flux [W/m²], AR step [s].
    rod : Rod, optional
        Spindle rod for the thermal growth (default :class:`arfem.params.Rod`).

    Returns
    -------
    chain : Chain
        Units in chain order and the tool pose (translation [mm]).
    spindle_info : dict or None
        What :func:`arfem.models.allocation.thermal.spindle_dz_mm` returned (``dz_mm``
        [mm], ``peak_growth_um`` [µm], ...) plus ``position``; None without a spindle.
    """
    units = [Unit(u.name, u.motion, u.pose, u.free, u.bounds, u.fixed, True) for u in sc.units]
    info = None
    if sc.spindle is not None:
        from arfem.models.allocation.thermal import spindle_dz_mm
        from arfem.params import Rod
        s = sc.spindle
        info = spindle_dz_mm(rod or Rod(), s.q_W_m2, s.model, s.dtau_s, s.compensated)
        fixed = {c: 0.0 for c in COMPONENTS}
        fixed["dz"] = info["dz_mm"]
        k = [u.name for u in units].index(s.after) + 1
        units.insert(k, Unit(s.name, "thermal", s.pose, (), {}, fixed, False))
        info["position"] = f"after {s.after}"
    return Chain(tuple(units), sc.tool), info
