"""Allocation scenario files (TOML): strict reading into a validated object, and the chain.

Layout (every key carries its unit; unknown keys are refused with a "did you mean")::

    [scenario]     name, description, formula = "screw"|"paper_literal",
                   constraint = "worst_case"|"rss"|"yield",
                   reference_accuracy_mm = {unit = mm, ...}   (e.g. a paper's table)
    [tolerance]    delta_E_mm (> 0), working_radius_mm (>= 0, default 0);
                   constraint "yield": target_yield, yield_dist = "normal"|"uniform",
                   yield_draws (>= 10 000)
    [cost]         model = "reciprocal_power"|"exponential", A, B, k, b_um,
                   angular_length_mm (screw formula, tolerances in µm);
                   a, b_mm (paper eq. 14, paper_literal)
    [optimizer]    pop_size, n_gen, converge, crossover_prob, mutation_prob, eta_crossover,
                   eta_mutation, seed, pick = "knee"|"min_cost"|"min_stack"|"compromise"
    [tool]         offset_mm = [x, y, z], rpy_deg = [r, p, y]   functional point in the
                   frame of the last "tool"-branch unit
    [[units]]      name, motion = "translation"|"rotation", axis = "x"|"y"|"z",
                   branch = "tool"|"workpiece"|"drive",
                   offset_mm, rpy_deg, joint_mm (translation) | joint_deg (rotation),
                   free = [...of dx dy dz dalpha dbeta dgamma],
                   translation_mm = [lo, hi], rotation_mrad = [lo, hi],
                   fixed = {dx_mm = .., dalpha_mrad = ..}   (components not free)
    [transmission] type = "rack_pinion", drive_unit, driven_unit, pitch_radius_mm,
                   mesh_point_mm = [x, y, z] (base frame), rack_axis = "x"|"y"|"z"
    [travel]       unit = "<rotation unit>", angles_deg = [...]   poses to check
    [spindle]      unit = "<tool-branch unit whose axis is the spindle axis>", q_W_m2,
                   model = "fem"|"ar"|"ar_corrected", dtau_s, cycle = "paper",
                   compensated, compensation_model = "ar"|"ar_corrected",
                   measurement_noise_um, noise_seed

Each branch is a serial chain from the base. A unit's nominal pose is
Trans(offset)·Rot(rpy)·Joint, Joint being a translation of ``joint_mm`` along, or a
rotation of ``joint_deg`` about, its axis. "tool" units carry the tool, "workpiece"
units the workpiece (their errors enter the tool-to-workpiece loop with the opposite
sign); "drive" units act only through the transmission.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from arfem.models.allocation import screw
from arfem.models.allocation.problem import (COMPONENTS, COMPONENT_UNIT, CONSTRAINTS,
                                             COST_MODELS, FORMULAS, PICKS, ROTATIONS, Chain,
                                             Settings, Thermal, Unit)
from arfem.params import PAPER_PHASES_S, PLAUSIBLE_RANGES, InputError, steps_per_segment
from arfem import strict
from arfem.strict import check_keys

__all__ = ["AllocationScenario", "SpindleSpec", "UnitSpec", "TransmissionSpec", "parse_scenario",
           "build_chain", "chain_maps"]

_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
_AXES = {"x": 0, "y": 1, "z": 2}
BRANCHES = ("tool", "workpiece", "drive")


@dataclass(frozen=True)
class UnitSpec:
    name: str
    motion: str
    axis: str
    offset: np.ndarray          # Trans(offset)·Rot(rpy), before the joint
    joint: float                # mm (translation) or deg (rotation)
    free: tuple
    bounds: dict
    fixed: dict
    branch: str = "tool"

    def pose(self, joint=None) -> np.ndarray:
        """Nominal pose in the previous unit's frame for a joint value [mm or deg]."""
        q = self.joint if joint is None else joint
        J = np.eye(4)
        if self.motion == "translation":
            J[_AXES[self.axis], 3] = q
        else:
            ang = [0.0, 0.0, 0.0]
            ang[_AXES[self.axis]] = q
            J = screw.pose([0, 0, 0], ang)
        return self.offset @ J


@dataclass(frozen=True)
class TransmissionSpec:
    drive_unit: str
    driven_unit: str
    pitch_radius_mm: float
    mesh_point_mm: np.ndarray
    rack_axis: str


@dataclass(frozen=True)
class SpindleSpec:
    unit: str
    q_W_m2: float
    model: str
    dtau_s: float
    compensated: bool
    compensation_model: str
    measurement_noise_um: float
    noise_seed: int


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
    transmission: TransmissionSpec | None = None
    travel_unit: str | None = None
    travel_angles_deg: tuple = ()


class _Reader:
    """The allocation file's reader: defaults, ranges and key paths around the one
    strict reader (:mod:`arfem.strict`), which checks every type, finiteness and unknown
    key."""

    def __init__(self, where: str):
        self.where = where

    def at(self, key: str) -> str:
        return f"{self.where}: {key}"

    def err(self, key: str, msg: str) -> InputError:
        return InputError(msg, self.at(key))

    def table(self, d, key, allowed, required=()):
        if not isinstance(d, dict):
            raise self.err(key, f"must be a table, got {type(d).__name__}")
        try:
            check_keys(d, allowed, key)
        except InputError as exc:
            raise InputError(exc.message, f"{self.where}: {exc.where}") from None
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
        v = strict.number(d[key], self.at(path))
        if low is not None and (v < low or (low_open and v == low)):
            raise self.err(path, f"must be {'>' if low_open else '>='} {low:g}, got {v:g}")
        if high is not None and (v > high or (high_open and v == high)):
            raise self.err(path, f"must be {'<' if high_open else '<='} {high:g}, got {v:g}")
        return v

    def integer(self, d, key, path, default, low, high):
        if key not in d:
            return int(default)
        v = d[key]
        strict.number(v, self.at(path), integer=True)
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
        return strict.string(d[key], self.at(path), choices=options)

    def string(self, d, key, path, default=None, pattern=None):
        if key not in d:
            if default is None:
                raise self.err(path, "is required")
            return default
        v = strict.string(d[key], self.at(path))
        if pattern is not None and not pattern.match(v):
            raise self.err(path, f"must be a name of letters, digits, '_' or '-', got {v!r}")
        return v

    def boolean(self, d, key, path, default):
        if key not in d:
            return default
        return strict.boolean(d[key], self.at(path))

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
            f = strict.number(x, self.at(f"{path}[{i}]"))
            if abs(f) > bound:
                raise self.err(f"{path}[{i}]", f"must be within ±{bound:g} (wrong unit?), "
                                               f"got {f:g}")
            out.append(f)
        return np.array(out)

    def interval(self, d, key, path, default):
        lo, hi = self.vector(d, key, path, 2, default, bound=1e3)
        if lo < 0:
            raise self.err(path, f"lower bound must be >= 0 (an error magnitude), got {lo:g}")
        for v in (lo, hi):
            if 0 < v < MIN_BOUND:
                raise self.err(path, f"a bound of {v:g} is below {MIN_BOUND:g} (a nanometre "
                                     "or nanoradian: no part is made or measured finer); "
                                     "use 0 or at least that")
        if not hi > lo:
            raise self.err(path, f"upper bound must exceed the lower, got [{lo:g}, {hi:g}]")
        return float(lo), float(hi)


#: Smallest nonzero bound of a tolerance [mm or mrad]: 1 nm, 1 nrad. Below it no part is
#: made or measured, and reciprocal costs overflow (a bound of 1e-320 did, issue 29).
MIN_BOUND = 1e-6

_UNIT_KEYS = {"name", "motion", "axis", "branch", "offset_mm", "rpy_deg", "joint_mm", "joint_deg",
              "free", "translation_mm", "rotation_mrad", "fixed"}


def _unit(rd: _Reader, d, i, names) -> UnitSpec:
    key = f"units[{i}]"
    rd.table(d, key, _UNIT_KEYS, required=("name", "motion", "axis"))
    name = rd.string(d, "name", f"{key}.name", pattern=_NAME_RE)
    if name in names:
        raise rd.err(f"{key}.name", f"duplicate unit name {name!r}")
    motion = rd.choice(d, "motion", f"{key}.motion", ("translation", "rotation"))
    axis = rd.choice(d, "axis", f"{key}.axis", tuple(_AXES))
    branch = rd.choice(d, "branch", f"{key}.branch", BRANCHES, "tool")
    wrong = "joint_deg" if motion == "translation" else "joint_mm"
    if wrong in d:
        raise rd.err(f"{key}.{wrong}", f"does not apply to a {motion} unit "
                                      f"(use {'joint_mm' if wrong == 'joint_deg' else 'joint_deg'})")
    g = screw.pose(rd.vector(d, "offset_mm", f"{key}.offset_mm"),
                   rd.vector(d, "rpy_deg", f"{key}.rpy_deg"))
    jkey = "joint_mm" if motion == "translation" else "joint_deg"
    joint = rd.number(d, jkey, f"{key}.{jkey}", default=0.0)
    free = d.get("free", list(COMPONENTS))
    if not isinstance(free, list) or not all(isinstance(c, str) for c in free):
        raise rd.err(f"{key}.free", f"must be a list of component names, got {free!r}")
    for c in free:
        if c not in COMPONENTS:
            raise rd.err(f"{key}.free", f"unknown component {c!r} (allowed: {', '.join(COMPONENTS)})")
    if len(set(free)) != len(free):
        raise rd.err(f"{key}.free", "lists a component twice")
    tb = rd.interval(d, "translation_mm", f"{key}.translation_mm", [0.0001, 0.005])
    rb = rd.interval(d, "rotation_mrad", f"{key}.rotation_mrad", [0.0001, 0.005])
    fixed_in = d.get("fixed", {})
    allowed_fixed = {f"{c}_{COMPONENT_UNIT[c]}" for c in COMPONENTS if c not in free}
    rd.table(fixed_in, f"{key}.fixed", allowed_fixed)
    fixed = {}
    for c in COMPONENTS:
        if c not in free:
            k = f"{c}_{COMPONENT_UNIT[c]}"
            fixed[c] = rd.number(fixed_in, k, f"{key}.fixed.{k}", default=0.0, low=0.0)
    bounds = {c: (rb if c in ROTATIONS else tb) for c in free}
    return UnitSpec(name, motion, axis, g, joint, tuple(c for c in COMPONENTS if c in free),
                    bounds, fixed, branch)


def parse_scenario(data: dict, source: str = "<scenario>") -> AllocationScenario:
    """Validate a parsed TOML mapping; raise :class:`InputError` naming ``source`` and the key."""
    rd = _Reader(source)
    rd.table(data, "", {"scenario", "tolerance", "cost", "optimizer", "tool", "units", "spindle",
                        "transmission", "travel"}, required=("tolerance", "units"))
    sc = rd.table(data.get("scenario", {}), "scenario",
                  {"name", "description", "formula", "constraint", "reference_accuracy_mm"})
    name = rd.string(sc, "name", "scenario.name", default=Path(source).stem)
    desc = rd.string(sc, "description", "scenario.description", default="")
    formula = rd.choice(sc, "formula", "scenario.formula", FORMULAS, "screw")
    constraint = rd.choice(sc, "constraint", "scenario.constraint", CONSTRAINTS, "worst_case")
    settings = _settings(rd, data, formula, constraint)
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
    if formula != "paper_literal" and settings.cost_model == "reciprocal_power":
        for i, u in enumerate(units):
            for c, (lo, _) in u.bounds.items():
                if lo == 0.0:
                    which = "rotation_mrad" if c in ROTATIONS else "translation_mm"
                    raise rd.err(f"units[{i}].{which}", "lower bound 0 with the "
                                 "reciprocal_power cost (A + B/t^k): a zero tolerance costs "
                                 "infinitely much; give a lower bound > 0")
    byname = {u.name: u for u in units}
    if formula == "screw" and not any(u.branch == "tool" for u in units):
        raise rd.err("units", "no unit has branch = \"tool\": the functional point needs one")
    trans = _transmission(rd, data, units, byname)
    travel_unit, angles = _travel(rd, data, byname)
    spindle = _spindle(rd, data, byname)
    ref = _reference(rd, sc, byname)
    return AllocationScenario(source, name, desc, settings, tuple(units), tool, spindle, ref,
                              trans, travel_unit, angles)


def _settings(rd: _Reader, data: dict, formula: str, constraint: str) -> Settings:
    """The [tolerance], [cost] and [optimizer] tables as :class:`Settings`."""
    tol = rd.table(data["tolerance"], "tolerance",
                   {"delta_E_mm", "working_radius_mm", "target_yield", "yield_dist",
                    "yield_draws"}, required=("delta_E_mm",))
    # upper bounds (issue 29): a kinematic tolerance of 1e308 mm made the figures' axis
    # limits inf (a traceback); no machine's allowance exceeds a metre, no cost factor 1e12
    dE = rd.number(tol, "delta_E_mm", "tolerance.delta_E_mm", low=0.0, low_open=True,
                   high=1000.0)
    rw = rd.number(tol, "working_radius_mm", "tolerance.working_radius_mm", default=0.0, low=0.0,
                   high=1e5)
    co = rd.table(data.get("cost", {}), "cost",
                  {"model", "A", "B", "k", "b_um", "angular_length_mm", "a", "b_mm"})
    op = rd.table(data.get("optimizer", {}), "optimizer",
                  {"pop_size", "n_gen", "converge", "crossover_prob", "mutation_prob",
                   "eta_crossover", "eta_mutation", "seed", "pick"})
    settings = Settings(
        delta_E_mm=dE, working_radius_mm=rw, formula=formula, constraint=constraint,
        target_yield=rd.number(tol, "target_yield", "tolerance.target_yield", default=0.9973,
                               low=0.5, high=1.0, high_open=True),
        yield_dist=rd.choice(tol, "yield_dist", "tolerance.yield_dist", ("normal", "uniform"),
                             "normal"),
        yield_draws=rd.integer(tol, "yield_draws", "tolerance.yield_draws", 10_000, 10_000,
                               1_000_000),
        cost_model=rd.choice(co, "model", "cost.model", COST_MODELS, "reciprocal_power"),
        cost_A=rd.number(co, "A", "cost.A", default=0.0, low=0.0, high=1e12),
        cost_B=rd.number(co, "B", "cost.B", default=1.0, low=0.0, low_open=True, high=1e12),
        cost_k=rd.number(co, "k", "cost.k", default=1.0, low=0.0, low_open=True, high=10.0),
        cost_b_um=rd.number(co, "b_um", "cost.b_um", default=1.0, low=0.0, low_open=True,
                            high=1e9),
        angular_length_mm=rd.number(co, "angular_length_mm", "cost.angular_length_mm",
                                    default=100.0, low=0.0, low_open=True, high=1e5),
        a=rd.number(co, "a", "cost.a", default=1.2, low=0.0, low_open=True, high=1e6),
        b_mm=rd.number(co, "b_mm", "cost.b_mm", default=1.6, low=0.0, low_open=True, high=1e5),
        pop_size=rd.integer(op, "pop_size", "optimizer.pop_size", 200, 4, 1_000_000),
        n_gen=rd.integer(op, "n_gen", "optimizer.n_gen", 1000, 1, 100_000_000),
        converge=rd.boolean(op, "converge", "optimizer.converge", True),
        crossover_prob=rd.number(op, "crossover_prob", "optimizer.crossover_prob", 0.9, 0.0, 1.0),
        mutation_prob=rd.number(op, "mutation_prob", "optimizer.mutation_prob", 0.1, 0.0, 1.0),
        eta_crossover=rd.number(op, "eta_crossover", "optimizer.eta_crossover", 20.0, 0.0,
                                low_open=True),
        eta_mutation=rd.number(op, "eta_mutation", "optimizer.eta_mutation", 20.0, 0.0,
                               low_open=True),
        seed=rd.integer(op, "seed", "optimizer.seed", 1, 0, 2**32 - 1),
        pick=rd.choice(op, "pick", "optimizer.pick", PICKS, "knee"))
    return settings


def _transmission(rd: _Reader, data: dict, units, byname) -> TransmissionSpec | None:
    """The [transmission] table (a rack and pinion from the drive branch to a rotation
    unit); required when a unit has branch = "drive"."""
    trans = None
    if "transmission" in data:
        tr = rd.table(data["transmission"], "transmission",
                      {"type", "drive_unit", "driven_unit", "pitch_radius_mm", "mesh_point_mm",
                       "rack_axis"}, required=("drive_unit", "driven_unit", "pitch_radius_mm"))
        rd.choice(tr, "type", "transmission.type", ("rack_pinion",), "rack_pinion")
        drive = rd.string(tr, "drive_unit", "transmission.drive_unit")
        driven = rd.string(tr, "driven_unit", "transmission.driven_unit")
        drive_units = [u.name for u in units if u.branch == "drive"]
        if not drive_units or drive != drive_units[-1]:
            raise rd.err("transmission.drive_unit", f"must name the last unit with branch = "
                                                    f"\"drive\" ({drive_units or 'none'}), got {drive!r}")
        if driven not in byname or byname[driven].branch == "drive" \
                or byname[driven].motion != "rotation":
            raise rd.err("transmission.driven_unit", f"must name a rotation unit of the tool or "
                                                     f"workpiece branch, got {driven!r}")
        trans = TransmissionSpec(
            drive, driven,
            rd.number(tr, "pitch_radius_mm", "transmission.pitch_radius_mm", low=0.0,
                      low_open=True),
            rd.vector(tr, "mesh_point_mm", "transmission.mesh_point_mm"),
            rd.choice(tr, "rack_axis", "transmission.rack_axis", tuple(_AXES), "x"))
    elif any(u.branch == "drive" for u in units):
        raise rd.err("transmission", "is required when a unit has branch = \"drive\"")
    return trans


def _travel(rd: _Reader, data: dict, byname) -> tuple:
    """The [travel] table: the rotation unit whose angles are visited and its 1 to 36
    angles [°]; (None, ()) without one."""
    travel_unit, angles = None, ()
    if "travel" in data:
        tv = rd.table(data["travel"], "travel", {"unit", "angles_deg"},
                      required=("unit", "angles_deg"))
        travel_unit = rd.string(tv, "unit", "travel.unit")
        if travel_unit not in byname or byname[travel_unit].motion != "rotation":
            raise rd.err("travel.unit", f"must name a rotation unit, got {travel_unit!r}")
        av = tv["angles_deg"]
        if not isinstance(av, list) or not 1 <= len(av) <= 36:
            raise rd.err("travel.angles_deg", f"must be a list of 1 to 36 angles, got {av!r}")
        angles = tuple(float(rd.vector(tv, "angles_deg", "travel.angles_deg", n=len(av),
                                       bound=3600.0)[j]) for j in range(len(av)))
    return travel_unit, angles


def _spindle(rd: _Reader, data: dict, byname) -> SpindleSpec | None:
    """The [spindle] table: the tool-branch unit that heats, its flux and thermal model."""
    spindle = None
    if "spindle" in data:
        sp = rd.table(data["spindle"], "spindle",
                      {"unit", "q_W_m2", "model", "dtau_s", "cycle", "compensated",
                       "compensation_model", "measurement_noise_um", "noise_seed"},
                      required=("unit", "q_W_m2"))
        sunit = rd.string(sp, "unit", "spindle.unit")
        if sunit not in byname or byname[sunit].branch != "tool":
            raise rd.err("spindle.unit", f"must name a unit of the tool branch (the spindle "
                                         f"carries the tool), got {sunit!r}")
        model = rd.choice(sp, "model", "spindle.model", ("fem", "ar", "ar_corrected"), "fem")
        rd.choice(sp, "cycle", "spindle.cycle", ("paper",), "paper")
        comp = rd.boolean(sp, "compensated", "spindle.compensated", False)
        cmodel = rd.choice(sp, "compensation_model", "spindle.compensation_model",
                           ("ar", "ar_corrected"), "ar")
        dtau = rd.number(sp, "dtau_s", "spindle.dtau_s", default=30.0, low=0.0, low_open=True)
        try:
            steps_per_segment([d for d, _ in PAPER_PHASES_S], dtau, what="paper-cycle phase")
        except InputError as exc:
            raise rd.err("spindle.dtau_s", exc.message) from None
        q = rd.number(sp, "q_W_m2", "spindle.q_W_m2", low=0.0, high=PLAUSIBLE_RANGES["q_W_m2"][1])
        noise = rd.number(sp, "measurement_noise_um", "spindle.measurement_noise_um", default=0.2,
                          low=0.0, high=100.0)
        seed = rd.integer(sp, "noise_seed", "spindle.noise_seed", 0, 0, 2**32 - 1)
        spindle = SpindleSpec(sunit, q, model, dtau, comp, cmodel, noise, seed)
    return spindle


def _reference(rd: _Reader, sc: dict, byname) -> dict | None:
    """``scenario.reference_accuracy_mm``: a published allocation to compare with [mm]."""
    ref = None
    if "reference_accuracy_mm" in sc:
        names = set(byname)
        rt = rd.table(sc["reference_accuracy_mm"], "scenario.reference_accuracy_mm", names)
        ref = {k: rd.number(rt, k, f"scenario.reference_accuracy_mm.{k}", low=0.0)
               for k in rt}
    return ref


def _blk(R) -> np.ndarray:
    B = np.zeros((6, 6))
    B[:3, :3] = R
    B[3:, 3:] = R
    return B


def chain_maps(units, tool, transmission=None, joints=None) -> tuple[np.ndarray, dict]:
    """6×6 maps of every unit's error twist to the functional point, at one pose.

    The functional point is the tool point (``tool`` in the last tool-branch frame);
    the twist is the tool's small motion relative to the workpiece, in base-aligned
    axes at that point: Rblk·Ad(H_i⁻¹) for a tool-branch unit (H_i: unit i → point,
    paper eqs. 6-8 done with the geometry), −Rblk·Ad(H_j⁻¹) for a workpiece-branch unit
    (its frame → the same point), and for a drive unit the rank-one map
    Δθ = e_rack·δp_mesh / r about the driven unit's joint axis (rack and pinion).

    Parameters
    ----------
    units : sequence of UnitSpec
    tool : (4, 4) array
        Functional point in the last tool-branch unit's frame [mm].
    transmission : TransmissionSpec, optional
    joints : dict, optional
        Unit name -> joint value [mm or deg] overriding the nominal.

    Returns
    -------
    maps : ndarray, shape (n_units, 6, 6)
    geometry : dict
        ``tool_base`` (4, 4) pose of the functional point in the base [mm];
        ``frames`` {unit: (4, 4) base pose}.
    """
    joints = joints or {}
    n = len(units)
    maps = np.zeros((n, 6, 6))
    frames = {}

    def branch(name):
        idx = [i for i, u in enumerate(units) if u.branch == name]
        G = np.eye(4)
        poses = []
        for i in idx:
            g = units[i].pose(joints.get(units[i].name))
            poses.append(g)
            G = G @ g
            frames[units[i].name] = G.copy()
        return idx, poses, G

    ti, tp, Gt = branch("tool")
    tool_base = Gt @ tool
    Rb = _blk(tool_base[:3, :3])
    if ti:
        A = screw.chain_adjoints(tp, tool)
        for k, i in enumerate(ti):
            maps[i] = Rb @ A[k]
    wi, wp, Gw = branch("workpiece")
    if wi:
        A = screw.chain_adjoints(wp, screw.inverse(Gw) @ tool_base)
        for k, i in enumerate(wi):
            maps[i] = -Rb @ A[k]
    di, dp, Gd = branch("drive")
    if di:
        tr = transmission
        mesh = np.eye(4)
        mesh[:3, :3] = Gd[:3, :3]
        mesh[:3, 3] = tr.mesh_point_mm
        A = screw.chain_adjoints(dp, screw.inverse(Gd) @ mesh)
        j = [u.name for u in units].index(tr.driven_unit)
        ax = _AXES[units[j].axis]
        col = maps[j][:, ax]                       # the driven unit turning about its axis
        for k, i in enumerate(di):
            row = A[k][3 + _AXES[tr.rack_axis], :] / tr.pitch_radius_mm
            maps[i] = np.outer(col, row)
    return maps, {"tool_base": tool_base, "frames": frames}


def build_chain(sc: AllocationScenario, rod=None) -> tuple[Chain, dict | None]:
    """Turn a scenario into a :class:`Chain`: the maps at every pose of the travel, and
    the spindle's thermal series if the scenario has one.

    Over the travel the named unit takes each angle; with a rack and pinion whose
    driven unit it is, the first drive unit moves by r·θ [mm] (θ in rad) with it.

    Parameters
    ----------
    sc : AllocationScenario
    rod : Rod, optional
        Spindle rod for the thermal growth (default :class:`arfem.params.Rod`).

    Returns
    -------
    chain : Chain
    spindle_info : dict or None
        How the thermal series was made (see
        :func:`arfem.models.allocation.thermal.spindle_series`); None without a spindle.
    """
    units = [Unit(u.name, u.motion, u.free, u.bounds, u.fixed, True, u.branch) for u in sc.units]
    angles = sc.travel_angles_deg or (None,)
    maps, labels, geoms = [], [], []
    drive = [u for u in sc.units if u.branch == "drive"]
    for a in angles:
        joints = {}
        if a is not None:
            joints[sc.travel_unit] = a
            tr = sc.transmission
            if tr is not None and tr.driven_unit == sc.travel_unit and drive:
                joints[drive[0].name] = drive[0].joint + tr.pitch_radius_mm * math.radians(a)
        m, g = chain_maps(sc.units, sc.tool, sc.transmission, joints)
        maps.append(m)
        geoms.append(g)
        labels.append("nominal" if a is None else f"{sc.travel_unit} {a:g}°")
    info = None
    thermal = None
    if sc.spindle is not None:
        from arfem.models.allocation.thermal import spindle_series
        from arfem.params import Rod
        s = sc.spindle
        t, d_mm, info = spindle_series(rod or Rod(), s.q_W_m2, s.model, s.dtau_s, s.compensated,
                                       s.compensation_model, s.measurement_noise_um,
                                       s.noise_seed)
        u = next(x for x in sc.units if x.name == s.unit)
        dirs = np.array([g["frames"][s.unit][:3, _AXES[u.axis]] for g in geoms])
        thermal = Thermal(t, d_mm, dirs, info)
        info = dict(info, unit=s.unit)
    geometry = {"tool_base_mm": geoms[0]["tool_base"][:3, 3].tolist(),
                "frames_mm": {k: v[:3, 3].tolist() for k, v in geoms[0]["frames"].items()}}
    return Chain(tuple(units), np.array(maps), tuple(labels), thermal, geometry), info
