"""Scenario files: TOML → validated :class:`Scenario`.

A scenario describes one FEM-vs-AR(1) comparison. Every key carries its unit::

    [scenario]
    name = "paper_fig2"
    description = "Du et al. 2021, Fig. 2: q = 2000 W/m2"

    [rod]                        # optional; each key defaults to the paper's value
    radius_m = 0.1
    convection_W_m2K = 55.0      # ... any field of models.params.Rod

    [cycle]
    total_h = 24.0               # optional: the phases must add up to this
    phases = [
      { duration_h = 4.0,  q_W_m2 = 2000.0 },   # duration_s | duration_min | duration_h
      { duration_h = 1.5,  q_W_m2 = 0.0 },      # optional per phase: ambient_C, h_W_m2K
    ]

    [ar]
    dtau_s = 30.0                # AR time step; must divide every phase

    [fem]
    model = "axisymmetric"       # or "3d"
    order = 2                    # 1 or 2 (3d: 2 = 20-node serendipity brick)
    solver = "modal"             # "modal" (exact in time), "crank-nicolson", "backward-euler"
    dt_s = 30.0                  # θ-method step (defaults to dtau_s)
    [fem.mesh]                   # axisymmetric: nr, nz, ratio_r, ratio_z
    nr = 4                       # 3d: n_core, n_ring, nz, ratio_ring, ratio_z
    nz = 24

    [outputs]
    fields = true                # XDMF time series of temperature and displacement
    picture = true               # off-screen 3D PNG of the temperature
    field_interval_s = 1800.0    # spacing of the field snapshots

    [check]                      # optional: limits of `arfem check` (the command line wins)
    max_abs_diff_pct_of_peak = 3.0   # max|AR - FEM| as % of the FEM peak growth
    max_C1_abs_diff = 5e-4       # |C1 fitted to the FEM - C1 of the AR| [-]
    model = "paper"              # the AR checked: "paper" (eqs. 13-14) or "corrected"
    ar_rod = { convection_W_m2K = 55.0 }   # the AR's own rod values, where they differ
                                 # from [rod] (e.g. the h your compensation uses)

Unknown keys, wrong types, phases that do not add up, negative durations, a Δτ
that does not divide the phases and values in units that cannot be right are
refused with one line naming the file and the key.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from arfem.params import InputError, Rod, Schedule, check_plausible, steps_per_segment
from arfem.io import read_toml
from arfem.limits import Limits, resolve
from arfem.strict import boolean as _bool
from arfem.strict import check_keys as _unknown
from arfem.strict import number as _number
from arfem.strict import string as _string
from arfem.strict import table as _table
from arfem.scenarios.shipped import builtin_scenario_path, scenario_file


__all__ = ["Scenario", "FemSettings", "OutputSettings", "load_scenario", "scenario_file",
           "scenario_from_dict", "apply_override", "builtin_scenario_path", "ALIASES",
           "PAPER_SCENARIOS"]
__all__ += ["CheckLimits", "check_limit", "CHECK_MODELS"]

#: Built-in scenarios reproducing the paper's figures.
PAPER_SCENARIOS = ("paper_fig2", "paper_fig3")

#: Short names usable in sweeps and overrides.
ALIASES = {"dtau_s": "ar.dtau_s", "h_W_m2K": "rod.convection_W_m2K", "q_W_m2": "cycle.q_W_m2"}

#: Resource bounds, far above any study here, that turn a typo (nz = 100000000) into a
#: clear refusal instead of an allocation failure minutes later.
MAX_ELEMENTS_PER_DIRECTION = 4096
MAX_FIELD_SNAPSHOTS = 5000


_TOP = {"scenario", "rod", "cycle", "ar", "fem", "outputs", "check"}
_SCENARIO_KEYS = {"name", "description"}
_CYCLE_KEYS = {"phases", "total_h", "total_s"}
_PHASE_KEYS = {"duration_s", "duration_min", "duration_h", "q_W_m2", "ambient_C", "h_W_m2K",
               "label"}
_AR_KEYS = {"dtau_s"}
_FEM_KEYS = {"model", "order", "solver", "dt_s", "mesh", "elastic"}
_MESH_KEYS = {"axisymmetric": {"nr", "nz", "ratio_r", "ratio_z"},
              "3d": {"n_core", "n_ring", "nz", "ratio_ring", "ratio_z"}}
_OUT_KEYS = {"fields", "picture", "field_interval_s"}
_CHECK_KEYS = {"max_abs_diff_pct_of_peak", "max_C1_abs_diff", "model", "ar_rod"}
#: the AR(1) models ``arfem check`` can compare with the FEM
CHECK_MODELS = ("paper", "corrected")
_SOLVERS = {"modal": None, "crank-nicolson": 0.5, "backward-euler": 1.0}


@dataclass(frozen=True)
class FemSettings:
    """How the FEM is built and integrated."""

    model: str = "axisymmetric"
    order: int = 2
    solver: str = "modal"
    dt_s: float | None = None
    elastic: bool = True
    mesh: dict = field(default_factory=dict)

    @property
    def theta(self) -> float | None:
        """θ of the θ-method, or None for the exact modal integrator."""
        return _SOLVERS[self.solver]


@dataclass(frozen=True)
class OutputSettings:
    fields: bool = True
    picture: bool = True
    field_interval_s: float = 1800.0


@dataclass(frozen=True)
class CheckLimits:
    """The scenario's own ``[check]`` limits; None where the file sets none."""

    max_abs_diff_pct_of_peak: float | None = None   # [% of the FEM peak growth]
    max_C1_abs_diff: float | None = None            # [-]
    model: str | None = None                        # "paper" | "corrected"
    ar_rod: tuple = ()      # ((Rod field, value), ...): the AR's rod where it differs


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (see module docstring for the file format)."""

    name: str
    description: str
    source: str
    rod: Rod
    schedule: Schedule
    phase_labels: tuple
    dtau_s: float
    fem: FemSettings
    outputs: OutputSettings
    data: dict = field(repr=False, default_factory=dict)
    check: CheckLimits = field(default_factory=CheckLimits)

    @property
    def kind(self) -> str:
        """``"rod"``: the paper's rod (a mesh scenario's is ``"mesh"``)."""
        return "rod"

    @property
    def q_levels(self) -> list[float]:
        """Distinct non-zero heat fluxes of the cycle [W/m²], ascending."""
        return sorted({float(q) for q in self.schedule.q_W_m2 if q > 0})


def load_scenario(path, limits: Limits | None = None, toml=None) -> Scenario:
    """Load and validate a scenario file (or a built-in name such as ``paper_fig2``);
    ``limits`` (:class:`arfem.limits.Limits`) as the user allows; ``toml`` the file
    already read (:class:`arfem.io.TomlFile`), not read again."""
    p = scenario_file(path)
    return scenario_from_dict(read_toml(p, limits) if toml is None else toml.data, str(p),
                              limits)


# -- validation helpers ---------------------------------------------------------------

def scenario_from_dict(data: dict, source: str = "<scenario>",
                       limits: Limits | None = None) -> Scenario:
    """Validate a scenario given as a dict (as read from TOML).

    Errors name ``source`` and the key path, e.g.
    ``paper.toml: cycle.phases[2].duration_h: must be > 0, got -1``.
    """
    try:
        sc = _from_dict(data, source)
        check_size(sc, limits)
        return sc
    except InputError as exc:
        if exc.where and exc.where.startswith(source):
            raise
        raise exc.at(source) from None


def _rod_from(data: dict) -> Rod:
    """The ``[rod]`` table: the paper's values where a key is not given."""
    rod_d = _table(data, "rod", "")
    rod_fields = {f.name for f in fields(Rod)}
    _unknown(rod_d, rod_fields, "rod")
    rod_kw = {}
    for k, v in rod_d.items():
        where = f"rod.{k}"
        f = _number(v, where)
        check_plausible(k, f, where)
        rod_kw[k] = f
    try:
        rod = Rod(**rod_kw)
    except InputError as exc:
        raise exc.in_table("rod") from None
    return rod


def _schedule_from(data: dict, rod: Rod):
    """The ``[cycle]`` table: (schedule, phase labels, phase durations [s])."""
    cyc = _table(data, "cycle", "")
    _unknown(cyc, _CYCLE_KEYS, "cycle")
    phases = cyc.get("phases")
    if not isinstance(phases, list) or not phases:
        raise InputError("must be a non-empty list of phases "
                         "({ duration_h = 4.0, q_W_m2 = 2000.0 }, ...)", "cycle.phases")
    durations, qs, ambs, hs, labels = [], [], [], [], []
    for i, ph in enumerate(phases):
        where = f"cycle.phases[{i}]"
        if not isinstance(ph, dict):
            raise InputError(f"must be a table, got {type(ph).__name__}", where)
        _unknown(ph, _PHASE_KEYS, where)
        given = [k for k in ("duration_s", "duration_min", "duration_h") if k in ph]
        if len(given) != 1:
            raise InputError("needs exactly one of duration_s, duration_min, duration_h"
                             + (f" (got {', '.join(given)})" if given else ""), where)
        k = given[0]
        d = _number(ph[k], f"{where}.{k}", positive=True)
        durations.append(d * {"duration_s": 1.0, "duration_min": 60.0, "duration_h": 3600.0}[k])
        if "q_W_m2" not in ph:
            raise InputError("missing q_W_m2 (heat flux in W/m²; 0 for a pause)", where)
        q = _number(ph["q_W_m2"], f"{where}.q_W_m2", positive=True, allow_zero=True)
        check_plausible("q_W_m2", q, f"{where}.q_W_m2")
        qs.append(q)
        a = _number(ph.get("ambient_C", rod.ambient_C), f"{where}.ambient_C")
        check_plausible("ambient_C", a, f"{where}.ambient_C")
        ambs.append(a)
        h = _number(ph.get("h_W_m2K", rod.convection_W_m2K), f"{where}.h_W_m2K", positive=True)
        check_plausible("h_W_m2K", h, f"{where}.h_W_m2K")
        hs.append(h)
        labels.append(_string(ph.get("label", "heating" if q > 0 else "cooling"),
                              f"{where}.label"))
    total = sum(durations)
    for key, unit in (("total_h", 3600.0), ("total_s", 1.0)):
        if key in cyc:
            want = _number(cyc[key], f"cycle.{key}", positive=True) * unit
            if abs(want - total) > 1e-9 * max(want, 1.0):
                raise InputError(f"the phases add up to {total / unit:g}, not {want / unit:g}",
                                 f"cycle.{key}")
    any_amb = any("ambient_C" in ph for ph in phases)
    any_h = any("h_W_m2K" in ph for ph in phases)
    schedule = Schedule(durations, qs, ambs if any_amb else None, hs if any_h else None)
    if not any(q > 0 for q in qs) and len(set(ambs)) == 1:
        raise InputError("no phase heats the rod (every q_W_m2 is 0) and the ambient is "
                         "constant: the growth is zero and AR(1) cannot be identified",
                         "cycle.phases")
    return schedule, labels, durations


def _fem_from(data: dict, dtau: float) -> FemSettings:
    """The ``[fem]`` table (model, order, solver, time step, elastic, mesh)."""
    fem_d = _table(data, "fem", "")
    _unknown(fem_d, _FEM_KEYS, "fem")
    model = _string(fem_d.get("model", "axisymmetric"), "fem.model", ("axisymmetric", "3d"))
    order = fem_d.get("order", 2)
    if isinstance(order, bool) or order not in (1, 2):
        raise InputError(f"must be 1 or 2, got {order!r}", "fem.order")
    solver = _string(fem_d.get("solver", "modal"), "fem.solver", tuple(_SOLVERS))
    dt = _number(fem_d.get("dt_s", dtau), "fem.dt_s", positive=True)
    if abs(dtau / dt - round(dtau / dt)) > 1e-9 * max(dtau / dt, 1.0):
        raise InputError(f"{dt:g} s must divide ar.dtau_s = {dtau:g} s so that FEM and AR "
                         "share their sample times", "fem.dt_s")
    elastic = _bool(fem_d.get("elastic", True), "fem.elastic")
    mesh_d = _table(fem_d, "mesh", "fem")
    _unknown(mesh_d, _MESH_KEYS[model], "fem.mesh")
    mesh = {}
    for k, v in mesh_d.items():
        if k.startswith("ratio"):
            r = _number(v, f"fem.mesh.{k}", positive=True)
            if r < 1:
                raise InputError(f"must be >= 1 (largest/smallest element), got {v!r}",
                                 f"fem.mesh.{k}")
            mesh[k] = r
        else:
            n = _number(v, f"fem.mesh.{k}", integer=True)
            if n < 1:
                raise InputError(f"a mesh needs at least 1 element, got {v!r}", f"fem.mesh.{k}")
            if n > MAX_ELEMENTS_PER_DIRECTION:
                raise InputError(f"{n:g} elements in one direction is more than this solver "
                                 f"is built for (at most {MAX_ELEMENTS_PER_DIRECTION})",
                                 f"fem.mesh.{k}")
            mesh[k] = int(n)
    return FemSettings(model=model, order=int(order), solver=solver, dt_s=dt,
                       elastic=elastic, mesh=mesh)


def _outputs_from(data: dict, schedule: Schedule) -> OutputSettings:
    """The ``[outputs]`` table, with the number of field snapshots bounded."""
    out = _table(data, "outputs", "")
    _unknown(out, _OUT_KEYS, "outputs")
    outputs = OutputSettings(
        fields=_bool(out.get("fields", True), "outputs.fields"),
        picture=_bool(out.get("picture", True), "outputs.picture"),
        field_interval_s=_number(out.get("field_interval_s", 1800.0), "outputs.field_interval_s",
                                 positive=True))
    n_snap = schedule.total_s / outputs.field_interval_s
    if outputs.fields and n_snap > MAX_FIELD_SNAPSHOTS:
        raise InputError(f"{outputs.field_interval_s:g} s asks for {n_snap:.3g} field snapshots "
                         f"over the {schedule.total_s:g} s cycle; at most "
                         f"{MAX_FIELD_SNAPSHOTS} (or set outputs.fields = false)",
                         "outputs.field_interval_s")
    return outputs


def _from_dict(data: dict, source: str) -> Scenario:
    if not isinstance(data, dict):
        raise InputError("a scenario must be a TOML document (a table)")
    _unknown(data, _TOP, "")
    sc = _table(data, "scenario", "")
    _unknown(sc, _SCENARIO_KEYS, "scenario")
    name = _string(sc.get("name", Path(source).stem), "scenario.name")
    description = _string(sc.get("description", ""), "scenario.description")
    rod = _rod_from(data)
    schedule, labels, durations = _schedule_from(data, rod)
    ar = _table(data, "ar", "")
    _unknown(ar, _AR_KEYS, "ar")
    dtau = _number(ar.get("dtau_s", 30.0), "ar.dtau_s", positive=True)
    steps_per_segment(durations, dtau, where="ar.dtau_s", what="phase")
    fem = _fem_from(data, dtau)
    outputs = _outputs_from(data, schedule)
    check = _check_limits(_table(data, "check", ""), rod)
    return Scenario(name=name, description=description, source=source, rod=rod,
                    schedule=schedule, phase_labels=tuple(labels), dtau_s=dtau, fem=fem,
                    outputs=outputs, data=copy.deepcopy(data), check=check)


def check_limit(name: str, value, where: str) -> float:
    """Validate one ``arfem check`` limit (from ``[check]`` or the command line).

    ``max_abs_diff_pct_of_peak`` must be in (0, 100] [% of the FEM peak]: above 100 %
    an AR that predicts no growth at all would pass. ``max_C1_abs_diff`` must be in
    (0, 1) [-]: C1 itself lies in (0, 1).

    >>> check_limit("max_C1_abs_diff", 5e-4, "check.max_C1_abs_diff")
    0.0005
    """
    v = _number(value, where, positive=True)
    if name == "max_abs_diff_pct_of_peak" and v > 100.0:
        raise InputError(f"must be in (0, 100] (% of the FEM peak), got {value!r}", where)
    if name == "max_C1_abs_diff" and v >= 1.0:
        raise InputError(f"must be in (0, 1) (C1 itself lies in (0, 1)), got {value!r}", where)
    return v


def _check_limits(d: dict, rod: Rod) -> CheckLimits:
    _unknown(d, _CHECK_KEYS, "check")
    kw = {k: check_limit(k, d[k], f"check.{k}") for k in _CHECK_KEYS - {"model", "ar_rod"}
          if k in d}
    if "model" in d:
        kw["model"] = _string(d["model"], "check.model", CHECK_MODELS)
    ar_rod = _table(d, "ar_rod", "check")
    _unknown(ar_rod, {f.name for f in fields(Rod)}, "check.ar_rod")
    for k, v in ar_rod.items():
        check_plausible(k, _number(v, f"check.ar_rod.{k}"), f"check.ar_rod.{k}")
    kw["ar_rod"] = tuple(sorted((k, float(v)) for k, v in ar_rod.items()))
    try:
        rod.with_(**dict(kw["ar_rod"]))         # the AR's rod must be a valid rod too
    except InputError as exc:
        raise exc.in_table("check.ar_rod") from None
    return CheckLimits(**kw)


def apply_override(data: dict, key: str, value: Any) -> dict:
    """Return a deep copy of scenario ``data`` with ``key`` set to ``value``.

    ``key`` is a dotted path (``rod.convection_W_m2K``, ``fem.mesh.nz``) or an alias
    from :data:`ALIASES`; ``q_W_m2`` / ``cycle.q_W_m2`` sets the flux of every
    heated phase. Unknown keys are refused.

    Examples
    --------
    >>> d = apply_override({"cycle": {"phases": [{"duration_h": 1, "q_W_m2": 5.0},
    ...                                          {"duration_h": 1, "q_W_m2": 0.0}]}}, "q_W_m2", 7.0)
    >>> [p["q_W_m2"] for p in d["cycle"]["phases"]]
    [7.0, 0.0]
    """
    path = ALIASES.get(key, key)
    out = copy.deepcopy(data)
    if path == "cycle.q_W_m2":
        phases = out.get("cycle", {}).get("phases")
        if not isinstance(phases, list) or not any(
                isinstance(p, dict) and p.get("q_W_m2", 0) > 0 for p in phases):
            raise InputError("the base scenario has no heated phase to set", key)
        for p in phases:
            if isinstance(p, dict) and p.get("q_W_m2", 0) > 0:
                p["q_W_m2"] = value
        return out
    parts = path.split(".")
    allowed = {
        (): _TOP, ("scenario",): _SCENARIO_KEYS, ("rod",): {f.name for f in fields(Rod)},
        ("cycle",): {"total_h", "total_s"}, ("ar",): _AR_KEYS, ("fem",): _FEM_KEYS - {"mesh"},
        ("fem", "mesh"): _MESH_KEYS["axisymmetric"] | _MESH_KEYS["3d"], ("outputs",): _OUT_KEYS,
    }
    parent = tuple(parts[:-1])
    if parent not in allowed or parts[-1] not in allowed[parent]:
        raise InputError("is not a scenario key that can be set (use a dotted path such as "
                         "rod.convection_W_m2K, ar.dtau_s, fem.mesh.nz, or dtau_s, h_W_m2K, "
                         "q_W_m2)", key)
    node = out
    for p in parts[:-1]:
        node = node.setdefault(p, {})
        if not isinstance(node, dict):
            raise InputError("cannot be set: its parent is not a table", key)
    node[parts[-1]] = value
    return out


# -- size limits (issue 17): estimated before anything is built ---------------------

__all__ += ["estimate_cost", "check_size", "MAX_TIME_STEPS", "MAX_MEMORY_BYTES",
            "MAX_WORK_FLOP"]

#: Size limits checked on the estimate of :func:`estimate_cost` before any work; each
#: is far above the paper's case (441 unknowns, 2880 steps, ~70 MB) and is lifted by
#: ``--allow-large`` (:class:`arfem.limits.Limits`; or ``ARFEM_ALLOW_LARGE=1``).
MAX_TIME_STEPS = 2_000_000          # AR samples or FEM θ-steps over the cycle
MAX_MEMORY_BYTES = 2 * 1024 ** 3    # estimated peak of the arrays one run holds [bytes]
MAX_WORK_FLOP = 5e11                # estimated floating-point operations (minutes)

_MESH_DEFAULTS = {"axisymmetric": {"nr": 4, "nz": 24}, "3d": {"n_core": 3, "n_ring": 2, "nz": 16}}


def estimate_cost(sc: Scenario) -> dict:
    """What one run of ``sc`` will cost, from its inputs alone (nothing is built).

    Returns ``ndofs`` (FEM unknowns, exact for these meshes), ``n_samples`` (AR(1)
    samples), ``n_steps`` (θ-method steps, 0 for the modal solver), ``n_snapshots``,
    ``memory_bytes`` (estimated peak of the arrays held [bytes]) and ``work_flop``
    (estimated floating-point operations). The model: the axisymmetric modal solver
    holds dense n×n matrices (eigh ~10 n³ flop) and (samples × n) modal blocks; on 3D
    it is reduced-modal (one sparse factor and ~60 solves with it); the θ-method a
    sparse LU with ~30x fill and, for fields, every step's state; the AR(1) and the
    writers ~20 arrays per sample.
    """
    f = sc.fem
    m = {**_MESH_DEFAULTS[f.model], **f.mesh}
    o = f.order
    if f.model == "axisymmetric":
        n = (o * m["nr"] + 1) * (o * m["nz"] + 1)
        row = 25 if o == 2 else 9
    else:
        nc, nr, nz = m["n_core"], m["n_ring"], m["nz"]
        v = (nc + 1) ** 2 + 4 * nc * nr
        e = v + nc * nc + 4 * nc * nr - 1
        n = v * (nz + 1) if o == 1 else (v + e) * (nz + 1) + v * nz
        row = 81 if o == 2 else 27
    total = sc.schedule.total_s
    n_samples = total / sc.dtau_s + len(sc.schedule.durations_s)
    snaps = total / sc.outputs.field_interval_s + 3
    any_fields = sc.outputs.fields or sc.outputs.picture or f.elastic
    mem = 20.0 * 8 * n_samples
    if f.theta is None and f.model == "axisymmetric":
        n_steps = 0.0
        mem += 8.0 * (4 * n * n + 4 * n_samples * n + (5 * snaps * n if any_fields else 0))
        work = 10.0 * n ** 3 + 6.0 * n_samples * n + (2.0 * snaps * n * n if any_fields else 0)
    elif f.theta is None:           # 3D: reduced-modal (fem.reduced): one sparse factor,
        n_steps = 0.0               # ~60 Lanczos solves, 9 modes, snapshots from them
        mem += 8.0 * (30 * row * n + 12 * n + (2 * snaps * n if any_fields else 0))
        work = 30.0 * row * n * 50 + 60 * 4.0 * 30 * row * n + 40.0 * n_samples \
            + (20.0 * snaps * n if any_fields else 0)
    else:
        n_steps = total / f.dt_s
        mem += 8.0 * (30 * row * n + (n_steps * n if any_fields else 0) + 10 * n_steps)
        work = 4.0 * row * n * n_steps * (2 if any_fields else 1) + 30.0 * row * n * 50
    if any_fields:                  # thermo-elastic solve: 3 unknowns per node, sparse LU
        mem += 8.0 * 30 * 3 * row * 3 * n
        work += 30.0 * (3 * n) * 3 * row * 50
    return {"ndofs": int(n), "n_samples": n_samples, "n_steps": n_steps,
            "n_snapshots": snaps if any_fields else 0.0, "memory_bytes": mem,
            "work_flop": work}


def check_size(sc: Scenario, limits: Limits | None = None) -> dict:
    """Refuse (one line) a scenario whose :func:`estimate_cost` exceeds the limits
    (:data:`MAX_TIME_STEPS`, :data:`MAX_MEMORY_BYTES`, :data:`MAX_WORK_FLOP`) unless
    the user lifted them (``limits.large``, ``--allow-large``), or that asks for more
    than :data:`MAX_FIELD_SNAPSHOTS` snapshots (not lifted). Returns the estimate."""
    n_snap = sc.schedule.total_s / sc.outputs.field_interval_s
    if (sc.outputs.picture or sc.fem.elastic) and n_snap > MAX_FIELD_SNAPSHOTS:
        # the snapshots are solved for the picture and the elastic growth too
        raise InputError(f"{sc.outputs.field_interval_s:g} s asks for {n_snap:.3g} field "
                         f"snapshots over the {sc.schedule.total_s:g} s cycle; at most "
                         f"{MAX_FIELD_SNAPSHOTS} (or set outputs.fields, outputs.picture and "
                         "fem.elastic to false)", "outputs.field_interval_s")
    c = estimate_cost(sc)
    if resolve(limits).large:
        return c
    lift = "pass --allow-large to run it anyway"
    if c["n_samples"] > MAX_TIME_STEPS:
        raise InputError(f"{sc.dtau_s:g} s gives {c['n_samples']:.3g} AR samples over the "
                         f"{sc.schedule.total_s:g} s cycle; at most {MAX_TIME_STEPS:g} ({lift})",
                         "ar.dtau_s")
    if c["n_steps"] > MAX_TIME_STEPS:
        raise InputError(f"{sc.fem.dt_s:g} s gives {c['n_steps']:.3g} {sc.fem.solver} steps "
                         f"over the {sc.schedule.total_s:g} s cycle; at most "
                         f"{MAX_TIME_STEPS:g} ({lift})", "fem.dt_s")
    what = (f"{c['ndofs']:,} FEM unknowns ({sc.fem.model}, order {sc.fem.order}, "
            f"{sc.fem.solver}), {c['n_samples']:.3g} samples")
    if c["memory_bytes"] > MAX_MEMORY_BYTES:
        raise InputError(f"{what} need about {c['memory_bytes'] / 1024 ** 3:.3g} GiB of memory; "
                         f"the limit is {MAX_MEMORY_BYTES / 1024 ** 3:g} GiB ({lift})",
                         "fem.mesh" if c["ndofs"] > 5000 else "fem")
    if c["work_flop"] > MAX_WORK_FLOP:
        raise InputError(f"{what} need about {c['work_flop']:.2g} floating-point operations "
                         f"(many minutes); the limit is {MAX_WORK_FLOP:g} ({lift})",
                         "fem.mesh" if c["ndofs"] > 5000 else "fem")
    return c
