"""The model side of a mesh diagnosis (issue 33): a geometry scenario with its
``[diagnosis]`` table, assembled once and reduced into the parametric model the
search uses.

The scenario may carry (and ``arfem run`` ignores)::

    [diagnosis]
    candidate_groups = ["spindle_bore", "housing_outer"]   # surface (or volume) groups
                                                           # where a source may be missing
    interface_groups = ["front_bearing", "rear_bearing"]   # thin volume groups whose
                                                           # conductivity stands for a
                                                           # contact resistance

Without the table (or without one of its keys) the search is the whole model's
(issue 41): every surface group that carries no heat source is a candidate for a
missing source, and every volume group that is a thin layer between two others
(:func:`arfem.models.geodiagnosis.rom.interface_layers`) an interface. The table
narrows the search; what it leaves out is listed in the verdict
(``GeoModel.unsearched``). A group the mesh lacks is refused by name (one line,
exit 2).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from arfem.io import read_toml
from arfem.models.geodiagnosis.problem import GeoModel
from arfem.models.geodiagnosis.rom import build_reduced, surface_power_column
from arfem.models.geodiagnosis.synth import Plant
from arfem.params import InputError
from arfem.strict import check_keys
from arfem.scenarios.geometry.scenario import (GeometryScenario, build_geometry_model,
                                               geometry_scenario_from_dict)

__all__ = ["DiagnosisSpec", "load_diagnosis_scenario", "plant_of", "reduced_model",
           "search_groups"]


@dataclass(frozen=True)
class DiagnosisSpec:
    """The scenario's ``[diagnosis]`` table; None where a key is not given (the whole
    model is searched, :func:`search_groups`)."""

    candidate_groups: tuple | None = None
    interface_groups: tuple | None = None


def _names(v, where: str) -> tuple:
    if not isinstance(v, list) or not all(isinstance(x, str) and x for x in v):
        raise InputError("must be a list of group names", where)
    return tuple(v)


def load_diagnosis_scenario(path, toml=None) -> tuple[GeometryScenario, DiagnosisSpec]:
    """Read a geometry scenario and its ``[diagnosis]`` table (module docstring);
    ``toml``: the file already read (:class:`arfem.io.TomlFile`), not read again."""
    p = Path(path)
    data = dict(read_toml(p) if toml is None else toml.data)
    d = data.pop("diagnosis", {}) or {}
    if not isinstance(d, dict):
        raise InputError("must be a table", f"{p}: diagnosis")
    try:
        check_keys(d, {"candidate_groups", "interface_groups"}, "diagnosis")
        spec = DiagnosisSpec(*(_names(d[k], f"diagnosis.{k}") if k in d else None
                               for k in ("candidate_groups", "interface_groups")))
        sc = geometry_scenario_from_dict(data, str(p), p.parent)
    except InputError as exc:
        if exc.where and exc.where.startswith(str(p)):
            raise
        raise exc.at(str(p)) from None
    return sc, spec


def plant_of(sc: GeometryScenario, progress=None):
    """Assemble the scenario (heat, elasticity, sensor rows): (Plant, GeometryModel)."""
    gm = build_geometry_model(sc, progress)
    hl = np.array([c.h for c in sc.convections]).reshape(-1, 3)
    plant = Plant(gm.thermal, gm.G, tuple(s.quantity for s in sc.sensors),
                  tuple(s.name for s in sc.sensors), tuple(s.spec.name for s in sc.sources),
                  tuple(c.spec.name for c in sc.convections), hl, sc.reference_C)
    return plant, gm


def search_groups(body, sc: GeometryScenario, spec: DiagnosisSpec):
    """(candidate surface groups, interface volume groups, what the table left out).

    By default every surface group of the mesh without a heat source is a candidate
    for a missing source, and every thin layer between two volume groups an interface
    (module docstring); a ``[diagnosis]`` key replaces its default, and the defaults it
    leaves out are returned as ``missing_source:<group>`` / ``contact_conductance:<group>``.
    """
    from arfem.models.geodiagnosis.rom import interface_layers
    with_source = {s.spec.group for s in sc.sources}
    all_cand = tuple(g for g in sorted(body.gmesh.surfaces) if g not in with_source)
    all_intf = interface_layers(body)
    cand = all_cand if spec.candidate_groups is None else spec.candidate_groups
    intf = all_intf if spec.interface_groups is None else spec.interface_groups
    left = tuple(f"missing_source:{g}" for g in all_cand if g not in cand) + \
        tuple(f"contact_conductance:{g}" for g in all_intf if g not in intf)
    return tuple(cand), tuple(intf), left


def reduced_model(plant: Plant, sc: GeometryScenario, spec: DiagnosisSpec,
                  h_speed_rpm: float = 0.0, keep_basis: bool = False):
    """The parametric reduced model (:mod:`arfem.models.geodiagnosis.rom`) with the
    candidate groups' unit-power columns; grown at the h of ``h_speed_rpm``.

    Returns (GeoModel, seconds spent).
    """
    t0 = time.perf_counter()
    body = plant.body
    where = f"{sc.source}: diagnosis.candidate_groups"
    groups, interfaces, unsearched = search_groups(body, sc, spec)
    try:
        cand = [surface_power_column(body, g, where) for g in groups]
        for g in interfaces:
            body.gmesh.volume_group(g, f"{sc.source}: diagnosis.interface_groups")
    except InputError as exc:
        if exc.where and exc.where.startswith(sc.source):
            raise
        raise exc.at(sc.source) from None
    loads = np.column_stack([body.F] + cand) if cand else body.F
    a, b, m = plant.h_law.T
    h0 = a + b * np.power(max(h_speed_rpm, 0.0), m)
    rb = build_reduced(body, plant.G, loads, h0, interfaces, keep_basis=keep_basis)

    def regrow(h_scale, kappa):
        return build_reduced(body, plant.G, loads, h0 * np.asarray(h_scale),
                             interfaces, kappa0=kappa)
    own = np.array([np.nan if c.ambient_C is None else c.ambient_C for c in sc.convections])
    model = GeoModel(rb, plant.sources, plant.convections,
                     tuple(c.spec.group for c in sc.convections), plant.h_law, own,
                     sc.reference_C, groups, interfaces, regrow, unsearched)
    return model, time.perf_counter() - t0
