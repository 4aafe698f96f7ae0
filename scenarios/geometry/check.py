"""``arfem check`` on a mesh scenario (issue 32 item 4): the AR(1)s of
:mod:`arfem.models.geometry_ar1` against the FEM, per displacement sensor.

The FEM is the scenario's own solve (:mod:`arfem.scenarios.geometry.scenario`), sampled
every Δτ (``[check] dtau_s``, default the scenario's ``output_interval_s``). Both
AR(1)s are built from the same assembled body and superposed over every input (each
heat source and each convection group's h·θ_amb, so a cycle with a varying ambient is
predicted too):

* the **slowest-mode** AR(1) (``model = "corrected"``, the default for a mesh: the rod's
  corrected AR is the slowest radial mode): C1 = exp(−μ₁Δτ) from the reduced model's
  slowest eigenvalue, the FEM's exact static gain per input;
* the **lumped** AR(1) (``model = "paper"``): paper eqs. 12-14 generalised from the
  mesh (β = Σh_gA_g/Σρ_ic_iV_i, gain from the uniform-rise expansion).

The gated criterion, per displacement sensor: max|AR − FEM| over the cycle in % of the
largest FEM drift peak among the scenario's displacement sensors (so that a sensor
the loads hardly move, the TCP across a plane of symmetry, is judged in the µm that
matter for a compensation, not against its own near-zero peak). Default limit 15 %
(:data:`DEFAULT_MAX_ABS_PCT_GEOMETRY`, see docs/geometry.md for the data). The other
AR's errors are reported, not gated. The rod's C1 criterion does not apply: C1 of the
slowest-mode AR is the FEM's own eigenvalue, and one C1 fitted to a multi-source,
multi-mode series with speed-dependent h mixes the modes.

A tilt sensor (``quantity = "tilt"``, µrad) is held to the same AR(1) and reported in
the notes against the largest FEM tilt, not gated: a tilt is not compensated (the
exported model's outputs are the displacement axes), and a tilt, a difference of two
displacements, carries more of the fast modes that one time constant per input
misses.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from arfem.fem.body import lumped_geometry
from arfem.fem.thermal3d import solve_body_reduced, solve_body_theta
from arfem.models.geometry_ar1 import GeometryAR1, lumped_ar1, modal_ar1, step_inputs
from arfem.params import InputError
from arfem.scenarios.gate import Criterion, ScenarioResult
from arfem.strict import check_keys as _unknown
from arfem.strict import number as _number
from arfem.strict import string as _string

__all__ = ["GeometryCheckCase", "geometry_case_from_dict", "load_geometry_case", "GeometryARComparison",
           "compare_geometry_ar1", "check_geometry_case", "ar_errors", "DEFAULT_MAX_ABS_PCT_GEOMETRY",
           "GEOMETRY_MODELS"]

#: Default limit on max|AR − FEM| [% of the largest FEM drift peak] for a mesh scenario.
#: The slowest-mode AR(1) misses the shipped spindle unit by 12.7 % (tcp_z: 3.55 µm of
#: a 28.0 µm drift; tcp_y 7.2 %, tcp_x 0.9 %): one time constant per input cannot follow
#: the shaft's fast share of the transient. 15 % passes it with that margin and fails
#: the paper's rod mesh made of a poor conductor (λ = 2 W/(m·K), Bi = 2.75: 27.7 %),
#: where no first-order model describes the drift (the rod mesh as shipped: 3.3 %).
DEFAULT_MAX_ABS_PCT_GEOMETRY = 15.0

#: ``--model`` / ``[check] model`` on a mesh -> the AR(1) gated.
GEOMETRY_MODELS = {"corrected": "slowest-mode", "paper": "lumped"}

_KEYS = {"max_abs_diff_pct_of_peak", "model", "dtau_s"}


@dataclass(frozen=True)
class GeometryCheckCase:
    """A mesh scenario with its own ``[check]`` values (None where the file sets none)."""

    scenario: object                 # GeometryScenario
    max_abs_diff_pct_of_peak: float | None = None
    model: str | None = None         # "corrected" (slowest-mode) | "paper" (lumped)
    dtau_s: float | None = None

    @property
    def name(self) -> str:
        return self.scenario.name

    @property
    def source(self) -> str:
        return self.scenario.source

    @property
    def kind(self) -> str:
        """``"mesh"``: a scenario on a mesh (the rod's is ``"rod"``)."""
        return "mesh"

    @property
    def check_dtau_s(self) -> float:
        """The Δτ the AR(1)s are held to the FEM at [s]: ``[check] dtau_s``, else the
        scenario's ``output_interval_s``."""
        return self.dtau_s if self.dtau_s is not None else self.scenario.output_interval_s


def geometry_case_from_dict(data: dict, source: str, base: Path) -> GeometryCheckCase:
    """Validate a mesh scenario and its ``[check]`` table (keys ``max_abs_diff_pct_of_peak``,
    ``model``, ``dtau_s``); refusals name the file and key."""
    from arfem.scenarios.rod.scenario import check_limit
    from arfem.scenarios.geometry.scenario import geometry_scenario_from_dict
    data = dict(data)
    chk = data.pop("check", {})
    try:
        if not isinstance(chk, dict):
            raise InputError("must be a table", "check")
        _unknown(chk, _KEYS, "check")
        kw = {}
        if "max_abs_diff_pct_of_peak" in chk:
            kw["max_abs_diff_pct_of_peak"] = check_limit(
                "max_abs_diff_pct_of_peak", chk["max_abs_diff_pct_of_peak"],
                "check.max_abs_diff_pct_of_peak")
        if "model" in chk:
            kw["model"] = _string(chk["model"], "check.model", tuple(GEOMETRY_MODELS))
        if "dtau_s" in chk:
            kw["dtau_s"] = _number(chk["dtau_s"], "check.dtau_s", positive=True)
        sc = geometry_scenario_from_dict(data, source, base)
    except InputError as exc:
        if exc.where and exc.where.startswith(source):
            raise
        raise exc.at(source) from None
    if kw.get("dtau_s", 0.0) > sc.total_s / 2:
        raise InputError(f"must be at most half the cycle ({sc.total_s / 2:g} s), got "
                         f"{kw['dtau_s']:g}", f"{source}: check.dtau_s")
    return GeometryCheckCase(sc, **kw)


def load_geometry_case(path) -> GeometryCheckCase:
    """Read a mesh scenario file with its ``[check]`` table (:func:`geometry_case_from_dict`)."""
    from arfem.io import read_toml
    p = Path(path)
    return geometry_case_from_dict(read_toml(p), str(p), p.parent)


@dataclass(frozen=True)
class GeometryARComparison:
    """The FEM and both superposed AR(1)s on the Δτ grid.

    Attributes
    ----------
    times_s : ndarray, shape (n + 1,)
    sensors : tuple of str, every sensor (temperature and displacement)
    displacement : ndarray of bool, shape (r,)
    inputs : tuple of str, the inputs (sources, then ``ambient@<group>``)
    fem : ndarray, shape (n + 1, r), [m or K]
    slowest_mode, lumped : GeometryAR1
    slowest_mode_y, lumped_y : ndarray, shape (n + 1, r, p), each input's share [m or K]
    """

    times_s: np.ndarray
    sensors: tuple
    displacement: np.ndarray
    inputs: tuple
    fem: np.ndarray
    slowest_mode: GeometryAR1
    lumped: GeometryAR1
    slowest_mode_y: np.ndarray
    lumped_y: np.ndarray
    tilt: np.ndarray | None = None      # bool (r,): the tilt sensors [rad]

    def prediction(self, model: str) -> np.ndarray:
        """Sum over the inputs of ``model``'s ("slowest-mode"/"lumped") AR(1)s, (n + 1, r)."""
        return (self.slowest_mode_y if model == "slowest-mode" else self.lumped_y).sum(axis=2)


def _modes_per_step(model, h_steps, kinds, cache):
    """Slowest rate and static gains of the reduced model at each step's h."""
    mus, gains = [], []
    for row in h_steps:
        key = tuple(float(v) for v in row)
        if key not in cache:             # a speed the FEM run never met (θ-method runs)
            from arfem.fem.thermal3d import InputHistory
            one = InputHistory(np.array([0.0, 1.0]), np.zeros((1, model.thermal.n_inputs)),
                               np.array([row]))
            solve_body_reduced(model.thermal, one, model.G, [0.0, 1.0], kinds=kinds,
                          mode_cache=cache)
        md = cache[key]
        mus.append(md.mu[0])
        gains.append(md.Gk.T @ (md.Fk / md.mu[:, None]) + md.D)
    return np.asarray(mus), np.asarray(gains)


def compare_geometry_ar1(model, dtau_s: float) -> GeometryARComparison:
    """Solve the FEM of a built :class:`~arfem.scenarios.geometry.scenario.GeometryModel`
    every ``dtau_s`` [s] and both AR(1)s on the same grid."""
    sc = model.scenario
    hist = model.history
    n = int(np.floor(hist.total_s / dtau_s + 1e-9))
    t = np.arange(n + 1) * dtau_s
    kinds = [s.kind_index for s in sc.sensors]
    cache: dict = {}
    if sc.solver == "reduced":
        fem = solve_body_reduced(model.thermal, hist, model.G, t, kinds=kinds,
                            mode_cache=cache).outputs
    else:
        th = 0.5 if sc.solver == "crank-nicolson" else 1.0
        full = solve_body_theta(model.thermal, hist, model.G, min(sc.dt_s, dtau_s), th)
        pick = np.clip(np.searchsorted(full.times_s, t - 1e-6), 0, full.times_s.size - 1)
        fem = full.outputs[pick]
    u = step_inputs(hist.edges_s, hist.u, dtau_s, n)
    h = step_inputs(hist.edges_s, hist.h_W_m2K, dtau_s, n)
    mu, gain = _modes_per_step(model, h, kinds, cache)
    slow = modal_ar1(dtau_s, mu, gain)
    lg = lumped_geometry(model.thermal, model.G)
    areas = np.array([lg.areas_m2[c.spec.group] for c in sc.convections])
    lump = lumped_ar1(dtau_s, lg.total_heat_capacity_J_K, areas, h, lg.input_power_W,
                      lg.uniform_gain)
    names = tuple(s.spec.name for s in sc.sources) + tuple(
        f"ambient@{c.spec.group}" for c in sc.convections)
    return GeometryARComparison(t, tuple(s.name for s in sc.sensors),
                                np.array([k == 1 for k in kinds]), names, fem, slow, lump,
                                slow.simulate(u), lump.simulate(u),
                                np.array([s.quantity == "tilt" for s in sc.sensors]))


def ar_errors(cmp: GeometryARComparison, model: str, tilts: bool = False):
    """Per displacement sensor (per tilt with ``tilts``): (name, max|AR − FEM| [m or
    rad], own peak [m or rad]); the largest peak of the kind."""
    d = np.flatnonzero(cmp.tilt if tilts else cmp.displacement)
    ar = cmp.prediction(model)
    rows = [(cmp.sensors[i], float(np.max(np.abs(ar[:, i] - cmp.fem[:, i]))),
             float(np.max(np.abs(cmp.fem[:, i])))) for i in d]
    return rows, max((r[2] for r in rows), default=0.0)


def _criteria(rows, peak: float, pct: float, gated: str, unit: str, what: str) -> list:
    """One criterion per sensor of one kind: max|AR − FEM| in % of the largest FEM peak
    of that kind (displacements in µm, gated; tilts in µrad, against their own largest
    tilt, reported in the notes). ``pct`` None: reported only, no limit is stated (a
    tilt: the displacements' limit does not apply to it)."""
    out = []
    for name, err, own in rows:
        v = 100.0 * err / peak
        out.append(Criterion(
            f"max_abs_diff_pct_of_peak[{name}]", v, pct, f"% of the largest FEM {what}",
            bool(pct is None or v <= pct),
            f"{name}: max|{gated} AR - FEM| = {err * 1e6:.3g} {unit} = {v:.2f} % of the "
            f"largest FEM {what} ({peak * 1e6:.4g} {unit}; own peak {own * 1e6:.4g} "
            f"{unit})" + ("" if pct is None else f", limit {pct:g} %")))
    return out


def check_geometry_case(case: GeometryCheckCase, max_abs_pct: float | None = None,
                        model: str | None = None):
    """Run a mesh scenario's FEM and hold the chosen AR(1) to the FEM at every
    displacement sensor; returns a :class:`arfem.scenarios.gate.ScenarioResult`
    (criteria per sensor; the other AR's errors and the C1 range in ``notes``)."""
    from arfem.scenarios.geometry.scenario import build_geometry_model
    sc = case.scenario
    pct = next(v for v in (max_abs_pct, case.max_abs_diff_pct_of_peak,
                           DEFAULT_MAX_ABS_PCT_GEOMETRY) if v is not None)
    key = next(v for v in (model, case.model, "corrected") if v is not None)
    gated = GEOMETRY_MODELS[key]
    other = "lumped" if gated == "slowest-mode" else "slowest-mode"
    dtau = case.check_dtau_s
    t0 = time.perf_counter()
    if not any(s.quantity == "displacement" for s in sc.sensors):
        raise InputError("has no displacement sensor: arfem check gates the AR(1) of a "
                         "displacement (add a [[sensor]] with a direction)", f"{sc.source}: sensor")
    cmp = compare_geometry_ar1(build_geometry_model(sc), dtau)
    rows, peak = ar_errors(cmp, gated)
    if not peak > 0:
        raise InputError("the FEM drift is zero at every displacement sensor: nothing to "
                         "compare (no heat input?)", f"{sc.source}: heat_source")
    crit = _criteria(rows, peak, pct, gated, "µm", "drift")
    tilt_note = ()
    if cmp.tilt is not None and cmp.tilt.any():       # reported, not gated: a tilt is
        trows, tpeak = ar_errors(cmp, gated, tilts=True)     # not compensated
        if tpeak > 0:
            tilt_note = (f"tilts (reported, not gated; {gated} AR): " + ", ".join(
                c.message for c in _criteria(trows, tpeak, None, gated, "µrad", "tilt")),)
    orow, _ = ar_errors(cmp, other)
    ar = cmp.slowest_mode if gated == "slowest-mode" else cmp.lumped
    notes = (f"{other} AR (reported, not gated): " + ", ".join(
        f"{n} {e * 1e6:.3g} µm = {100 * e / peak:.2f} %" for n, e, _ in orow),
             f"{gated} AR: C1 = {_span(ar.c1.min(), ar.c1.max())} at Δτ = {dtau:g} s, "
             f"{len(cmp.inputs)} inputs superposed") + tilt_note
    return ScenarioResult(sc.name, sc.source, gated, crit, time.perf_counter() - t0,
                          notes=notes)


def _span(lo: float, hi: float, fmt: str = ".6f") -> str:
    """``lo..hi``, or one value when both print the same (a constant h: one C1).

    >>> _span(0.9950271, 0.9950274), _span(0.99584, 0.99772)
    ('0.995027', '0.995840..0.997720')
    """
    a, b = format(lo, fmt), format(hi, fmt)
    return a if a == b else f"{a}..{b}"
