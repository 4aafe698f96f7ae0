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

Both default to none (the causes on them are then not searched). A group the mesh
lacks is refused by name (one line, exit 2).
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

__all__ = ["DiagnosisSpec", "load_diagnosis_scenario", "plant_of", "reduced_model"]


@dataclass(frozen=True)
class DiagnosisSpec:
    """The scenario's ``[diagnosis]`` table."""

    candidate_groups: tuple = ()
    interface_groups: tuple = ()


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
        spec = DiagnosisSpec(_names(d.get("candidate_groups", []), "diagnosis.candidate_groups"),
                             _names(d.get("interface_groups", []), "diagnosis.interface_groups"))
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


def reduced_model(plant: Plant, sc: GeometryScenario, spec: DiagnosisSpec,
                  h_speed_rpm: float = 0.0, keep_basis: bool = False):
    """The parametric reduced model (:mod:`arfem.models.geodiagnosis.rom`) with the
    candidate groups' unit-power columns; grown at the h of ``h_speed_rpm``.

    Returns (GeoModel, seconds spent).
    """
    t0 = time.perf_counter()
    body = plant.body
    where = f"{sc.source}: diagnosis.candidate_groups"
    try:
        cand = [surface_power_column(body, g, where) for g in spec.candidate_groups]
        for g in spec.interface_groups:
            body.gmesh.volume_group(g, f"{sc.source}: diagnosis.interface_groups")
    except InputError as exc:
        if exc.where and exc.where.startswith(sc.source):
            raise
        raise exc.at(sc.source) from None
    loads = np.column_stack([body.F] + cand) if cand else body.F
    a, b, m = plant.h_law.T
    h0 = a + b * np.power(max(h_speed_rpm, 0.0), m)
    rb = build_reduced(body, plant.G, loads, h0, spec.interface_groups, keep_basis=keep_basis)

    def regrow(h_scale, kappa):
        return build_reduced(body, plant.G, loads, h0 * np.asarray(h_scale),
                             spec.interface_groups, kappa0=kappa)
    own = np.array([np.nan if c.ambient_C is None else c.ambient_C for c in sc.convections])
    model = GeoModel(rb, plant.sources, plant.convections,
                     tuple(c.spec.group for c in sc.convections), plant.h_law, own,
                     sc.reference_C, spec.candidate_groups, spec.interface_groups, regrow)
    return model, time.perf_counter() - t0
