"""``model.json`` (version 2) and a replayable record from a solved ``[geometry]`` scenario.

``arfem run`` on a mesh scenario writes, beside the sensors' histories:

* ``model.json``: the reduced modal model as a discrete state-space model at the
  sensors' interval (``[fem] output_interval_s``), exactly discretised
  (:func:`arfem.models.modal_export.modal_state_space`); inputs each heat source's power
  ``P_<source>_W`` [W] (or flux ``q_<source>_W_m2``) and ``ambient_C`` (the cycle's
  ambient, counted from ``reference_C``); outputs each displacement sensor along x, y or
  z (``d_<sensor>_um``, axis X, Y, Z; a sensor along another direction, or a second one
  on an axis, is its own axis named after it);
* ``record.toml`` + ``record.csv``: the run as a measured-data record of contract v3
  (``[model] scenario = "scenario.toml"``, the run's copy of its scenario beside it;
  columns ``time_s``, ``speed_rpm``, ``ambient_C``, each source's input
  ``P_<source>_W``, each displacement sensor ``d_<sensor>_um``, each thermometer
  ``T_<sensor>_C``, and ``growth_um`` = the Z sensor's displacement for a one-output
  compensator), for ``arfem compensate model.json record.toml`` to replay and ``arfem
  diagnose record.toml`` to check against the mesh.

With speed-independent h the model is linear time-invariant and reproduces the
reduced solve to round-off (tested). Where a convection group's h depends on the speed
(h = a + b·n^m) the model is speed-scheduled (issue 32): it reads ``speed_rpm`` too, and
its A, B, D are tabulated at each distinct speed of the cycle (at most
:data:`MAX_SCHEDULE_SPEEDS`, else that many evenly over its range) in the coordinates of the
reduced solve's one basis (the modes of the first phase's h, the others' by Galerkin
projection, :func:`arfem.models.modal_export.speed_scheduled_state_space`), so at the
cycle's speeds it is the reduced solve again (tested); a speed between two tabulated
ones gets the matrices interpolated linearly in the speed, one outside them the end's
(the compensator's ``outside_schedule:speed_rpm`` alarm). Its own A, B, D are those at
each group's time-weighted mean h (the plausible ranges' model).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arfem.io import atomic_write_text, write_csv
from arfem.models.compensator import StateSpaceModel
from arfem.models.modal_export import (galerkin_modes, modal_state_space,
                                       speed_scheduled_state_space)
from arfem.scenarios.compensation.model_file import write_model

__all__ = ["ExportedModel", "export_state_space", "record_columns", "write_exports",
           "WRITES", "sensor_axes"]

#: files :func:`write_exports` adds to a geometry run's output
WRITES = ("model.json", "record.toml", "record.csv")
_AXES = {(1.0, 0.0, 0.0): "X", (0.0, 1.0, 0.0): "Y", (0.0, 0.0, 1.0): "Z"}
#: most speeds a schedule tabulates: a cycle with more distinct speeds (a duty CSV) gets
#: this many evenly over its range instead (each costs a dense n × n A in model.json:
#: 3.5 MB for the spindle unit's 400 states)
MAX_SCHEDULE_SPEEDS = 8


@dataclass(frozen=True)
class ExportedModel:
    """The exported model, or why there is none.

    Attributes
    ----------
    model : StateSpaceModel or None
    h_W_m2K : tuple
        The convection coefficient of each group at its time-weighted mean [W/(m²K)]:
        the model's (speed-independent h), or its nominal A, B, D's (a schedule).
    note : str
        Why no model was exported ('' when one was).
    """

    model: StateSpaceModel | None
    h_W_m2K: tuple = ()
    note: str = ""


def sensor_axes(sensors) -> list:
    """(sensor, axis) of each displacement sensor: X/Y/Z by its direction, else (or
    when an axis is taken) the sensor's name. The axis names of model.json, the twin
    and the mesh diagnosis's exported model alike.

    Parameters
    ----------
    sensors : sequence of SensorSpec
        The scenario's sensors; only ``quantity == "displacement"`` ones count.

    Returns
    -------
    list of (SensorSpec, str)
        In the sensors' order.
    """
    out, used = [], set()
    for s in sensors:
        if s.quantity != "displacement":
            continue
        ax = _AXES.get(tuple(float(round(v, 12)) for v in s.direction))
        if ax is None or ax in used:
            ax = s.name
        used.add(ax)
        out.append((s, ax))
    return out


def _input_map(gmodel, h_ref: np.ndarray):
    """(T, inputs, note): body inputs per model input; the sources' inputs, then the
    ambient through the groups that follow the cycle's ambient."""
    sc = gmodel.scenario
    S, Gc = len(sc.sources), len(sc.convections)
    follow = [c.ambient_C is None for c in sc.convections]
    fixed = [c for c in sc.convections
             if c.ambient_C is not None and c.ambient_C != sc.reference_C]
    if fixed:
        return None, None, (f"convection on {fixed[0].spec.group!r} has its own ambient "
                            f"{fixed[0].ambient_C:g} °C, not the reference; a constant "
                            "forcing has no input of the model")
    T = np.zeros((S + Gc, S + 1))
    T[np.arange(S), np.arange(S)] = 1.0
    T[S:, S] = np.where(follow, h_ref, 0.0)
    inputs = [((f"P_{s.spec.name}_W", "W") if s.spec.kind == "power"
               else (f"q_{s.spec.name}_W_m2", "W/m²")) for s in sc.sources]
    return T, inputs + [("ambient_C", "°C")], ""


def _base_modes(gmodel, kinds, mode_cache):
    """The reduced solve's basis: the modes it grew (the entry of ``mode_cache`` that
    was grown, not projected), else grown here as it does, at the first segment's h."""
    from arfem.fem.thermal3d import body_modes
    grown = [md for md in (mode_cache or {}).values() if md.n_blocks > 0]
    if grown:
        return grown[0]
    rows = [tuple(float(v) for v in r) for r in gmodel.history.h_W_m2K]
    h0 = rows[0] if rows else ()
    others = [np.array(h) for h in dict.fromkeys(rows) if h != h0]
    return body_modes(gmodel.thermal, np.array(h0), gmodel.G, kinds=kinds,
                      t_min_s=gmodel.scenario.output_interval_s, other_h=others)


def _speed_rows(gmodel) -> tuple:
    """(speeds, h rows): each distinct speed of the cycle [1/min], ascending, and the
    history's h of each group at it [W/(m²K)] (the very floats the run solved with);
    more than :data:`MAX_SCHEDULE_SPEEDS` distinct speeds: that many evenly over their
    range, h = a + b·n^m there."""
    hist, cyc = gmodel.history, gmodel.scenario.cycle
    mid = 0.5 * (hist.edges_s[1:] + hist.edges_s[:-1])
    cseg = np.clip(np.searchsorted(cyc.edges_s, mid) - 1, 0, len(cyc.speed_rpm) - 1)
    sp = np.asarray(cyc.speed_rpm, float)[cseg]
    speeds = np.unique(sp)
    if speeds.size <= MAX_SCHEDULE_SPEEDS:
        return speeds, [hist.h_W_m2K[int(np.flatnonzero(sp == v)[0])] for v in speeds]
    grid = np.linspace(speeds[0], speeds[-1], MAX_SCHEDULE_SPEEDS)
    return grid, [np.array([c.h[0] + c.h[1] * np.power(np.maximum(v, 0.0), c.h[2])
                            for c in gmodel.scenario.convections]) for v in grid]


def _scheduled(gmodel, kinds, cols, axes, h_ref, mode_cache, arfem_version):
    """The speed-scheduled model (h depends on the speed): A, B, D at each distinct
    speed of the cycle in the coordinates of the reduced solve's basis."""
    sc = gmodel.scenario
    base = _base_modes(gmodel, kinds, mode_cache)
    V = base.phi
    speeds, rows = _speed_rows(gmodel)

    def table(h):
        T, _, _ = _input_map(gmodel, h)
        T = np.column_stack([T, np.zeros(T.shape[0])])       # speed: through the matrices
        if tuple(float(v) for v in h) == base.h_W_m2K:       # the basis's own h
            return base.mu, None, base.D[cols], T
        mu, Y = galerkin_modes(V, gmodel.thermal.operator(np.asarray(h, float)))
        return mu, Y, np.zeros((len(cols), T.shape[0])), T
    _, inputs, _ = _input_map(gmodel, h_ref)
    desc = (f"reduced modal model of {sc.name} ({base.n_modes} modes), exact zero-order-"
            f"hold discretisation at {sc.output_interval_s:g} s, scheduled over the speed "
            "(h depends on it): A, B, D at " + ", ".join(f"{v:.6g}" for v in speeds)
            + " rpm in the modes of h = " + ", ".join(f"{h:.4g}" for h in base.h_W_m2K)
            + " W/m²K (Galerkin), linear in the speed between them, the end's outside; "
            "its own A, B, D at the time-weighted mean h: "
            + ", ".join(f"{c.spec.group} {h:.4g}" for c, h in zip(sc.convections, h_ref))
            + " W/m²K")
    return base, speed_scheduled_state_space(
        speeds, [table(h) for h in rows], table(h_ref), base.Fk, base.Gk[:, cols],
        dtau_s=sc.output_interval_s, inputs=inputs + [("speed_rpm", "1/min")],
        outputs=[(f"d_{s.name}_um", ax) for s, ax in axes],
        input_offsets={"ambient_C": sc.reference_C}, description=desc,
        arfem_version=arfem_version)


def _with_observer(model, gmodel, md, T, noise):
    """``model`` with the thermometers' observer (issue 43, :mod:`arfem.models.observer`)
    where the scenario has thermometers: their rows over the state of the basis ``md``
    (``Gk``, unscaled: K per amplitude) and over the model's inputs (``D`` through the
    input map ``T``), read at rest as the reference temperature, the state of a uniform
    1 K rise (Φᵀ M 1), and the steady-state gain for ``noise`` (the scenario's
    ``[observer]`` table, else the defaults)."""
    from dataclasses import replace

    from arfem.models.observer import ObserverNoise, design_observer
    sc = gmodel.scenario
    tcols = [j for j, s in enumerate(sc.sensors) if s.quantity == "temperature"]
    if not tcols:
        return model
    uniform = md.phi.T @ (gmodel.thermal.M @ np.ones(md.phi.shape[0]))
    ob = design_observer(model, [f"T_{sc.sensors[j].name}_C" for j in tcols],
                         md.Gk[:, tcols].T, md.D[tcols] @ T,
                         np.full(len(tcols), sc.reference_C), uniform,
                         noise if noise is not None else ObserverNoise())
    return replace(model, observer=ob)


def export_state_space(gmodel, arfem_version: str = "",
                       mode_cache: dict | None = None) -> ExportedModel:
    """The scenario's reduced modal model as a version-2 :class:`StateSpaceModel`.

    Parameters
    ----------
    gmodel : GeometryModel
        The assembled scenario (:func:`arfem.scenarios.geometry.scenario.build_geometry_model`).
    mode_cache : dict, optional
        The run's reduced-solve cache (``{h tuple: BodyModes}``): its grown basis is
        reused instead of grown again (the same modes, at the cost of none).

    Returns
    -------
    ExportedModel
        No model (and why) when the scenario has no displacement sensor or a convection
        group with a fixed ambient other than the reference.
    """
    from arfem.fem.thermal3d import body_modes
    sc = gmodel.scenario
    axes = sensor_axes(sc.sensors)
    if not axes:
        return ExportedModel(None, note="no displacement sensor to compensate")
    hist = gmodel.history
    w = hist.durations_s / hist.total_s
    h_ref = (w @ hist.h_W_m2K) if hist.h_W_m2K.size else np.zeros(0)
    T, inputs, note = _input_map(gmodel, h_ref)
    if T is None:
        return ExportedModel(None, tuple(h_ref), note)
    cols = [j for j, s in enumerate(sc.sensors) if s.quantity == "displacement"]
    # the space the run's reduced solve grows (every sensor, the same tolerance, step
    # responses compared from the model's interval on: a discrete model at Δτ never samples
    # sooner after a step), so that at the same h the model and the run agree to round-off
    kinds = [s.kind_index for s in sc.sensors]
    noise = sc.observer_noise                       # the scenario's [observer] table
    if len(_speed_rows(gmodel)[0]) > 1 and any(c.h[1] != 0.0 for c in sc.convections):
        base, model = _scheduled(gmodel, kinds, cols, axes, h_ref, mode_cache, arfem_version)
        T = np.column_stack([T, np.zeros(T.shape[0])])         # speed: through the matrices
        return ExportedModel(_with_observer(model, gmodel, base, T, noise),
                             tuple(float(h) for h in h_ref))
    key = tuple(float(h) for h in h_ref)
    md = (mode_cache[key] if mode_cache and key in mode_cache
          and mode_cache[key].n_blocks > 0
          else body_modes(gmodel.thermal, h_ref, gmodel.G, kinds=kinds,
                           t_min_s=sc.output_interval_s))
    desc = (f"reduced modal model of {sc.name} ({md.n_modes} modes), exact zero-order-hold "
            f"discretisation at {sc.output_interval_s:g} s; convection h at its constant "
            "value: " + ", ".join(f"{c.spec.group} {h:.4g}" for c, h in zip(sc.convections,
                                                                          h_ref))
            + " W/m²K")
    model = modal_state_space(
        md.mu, md.Fk, md.Gk[:, cols], md.D[cols], dtau_s=sc.output_interval_s, input_map=T,
        inputs=inputs, outputs=[(f"d_{s.name}_um", ax) for s, ax in axes],
        input_offsets={"ambient_C": sc.reference_C}, kind="fem_modal",
        description=desc, arfem_version=arfem_version)
    return ExportedModel(_with_observer(model, gmodel, md, T, noise),
                         tuple(float(h) for h in h_ref))


def record_columns(run, model: StateSpaceModel) -> dict:
    """The run as a record's columns: each row's inputs over the interval that ends at
    it (the contract's zero-order hold), the sensors' displacements [µm] and the
    thermometers ``T_<sensor>_C`` [°C] (a diagnosis against the mesh reads them as
    evidence)."""
    sc = run.model.scenario
    hist = run.model.history
    t = run.result.times_s
    prev = np.concatenate([[0.0], t[:-1]])
    mid = np.where(t > 0, 0.5 * (prev + t), 0.0)
    seg = np.clip(np.searchsorted(hist.edges_s, mid, side="right") - 1, 0,
                  hist.u.shape[0] - 1)
    cyc = sc.cycle
    cseg = np.clip(np.searchsorted(cyc.edges_s, mid, side="right") - 1, 0,
                   len(cyc.speed_rpm) - 1)
    ser = run.sensor_series()
    cols = {"time_s": t}
    z = next((o.name for o in model.outputs if o.axis == "Z"), model.outputs[0].name)
    cols["growth_um"] = ser[z]
    cols["speed_rpm"] = np.asarray(cyc.speed_rpm, float)[cseg]
    cols["ambient_C"] = np.asarray(cyc.ambient_C, float)[cseg]
    for j, spec in enumerate(model.inputs[:len(sc.sources)]):   # the sources, in order
        cols[spec.name] = hist.u[seg, j]
        if not spec.name.startswith("P_"):       # a flux: contract v3 reads P_<source>_W
            cols[f"P_{sc.sources[j].spec.name}_W"] = hist.u[seg, j]
    for o in model.outputs:
        cols[o.name] = ser[o.name]
    for name, v in ser.items():          # thermometers and tilts: evidence for arfem
        if name.startswith(("T_", "tilt_")):      # diagnose (a tilt is not compensated)
            cols[name] = v
    return cols


def _record_toml(name: str, scenario: str | None) -> str:
    """The record's TOML: contract v3 (``[model] scenario``, the run's copy of its
    scenario beside it) where there is a copy, else without ``[model]`` (and then
    ``arfem diagnose`` refuses it, since it cannot tell the model)."""
    import json
    head = (f'# {name} as a measured-data record (docs/measured-data.md, contract v3), '
            'written by arfem run.\n# Replay it with arfem compensate model.json '
            'record.toml --out DIR; diagnose it against\n# the mesh with arfem diagnose '
            'record.toml --out DIR. growth_um is the Z sensor\'s d_..._um.\n')
    body = f'[dataset]\nname = {json.dumps(name)}\ncsv = "record.csv"\n'
    if scenario is None:
        return head + body
    return head + body + f'\n[model]\nscenario = {json.dumps(scenario)}\n'


def write_exports(run, out_dir, arfem_version: str = "",
                  mode_cache: dict | None = None,
                  scenario_copy: str | None = None) -> ExportedModel:
    """Write ``model.json``, ``record.toml`` and ``record.csv`` into ``out_dir`` (a
    staging directory); nothing where the scenario has no model (see
    :class:`ExportedModel`). ``mode_cache``: the run's (:func:`export_state_space`);
    ``scenario_copy``: the name of the scenario's copy in ``out_dir``, which the
    record's ``[model]`` table names (contract v3), or None (no ``[model]``)."""
    ex = export_state_space(run.model, arfem_version, mode_cache)
    if ex.model is None:
        return ex
    write_model(out_dir / "model.json", ex.model)
    write_csv(out_dir / "record.csv", record_columns(run, ex.model))
    atomic_write_text(out_dir / "record.toml", _record_toml(run.model.scenario.name,
                                                          scenario_copy))
    return ex
