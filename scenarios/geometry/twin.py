"""The twin of a ``[geometry]`` scenario (``arfem twin --scenario``): its FEM solved once,
then served interval by interval as an :class:`arfem.models.twin.AxesTwin`.

It sits above both the scenario's solve (:mod:`arfem.scenarios.geometry.scenario`) and
its export (:mod:`arfem.scenarios.geometry.export`), which need neither this nor each
other's insides.
"""
from __future__ import annotations

import numpy as np

from arfem.models.twin import AxesTwin
from arfem.params import InputError
from arfem.scenarios.geometry.export import sensor_axes
from arfem.scenarios.geometry.scenario import (build_geometry_model, load_geometry_scenario,
                                               solve_geometry)

__all__ = ["axes_twin"]


def axes_twin(path, noise_um: float = 0.0, seed: int = 0, progress=None):
    """An :class:`arfem.models.twin.AxesTwin` of the ``[geometry]`` scenario at ``path``:
    its FEM solved once (where h depends on the speed, the exported model is scheduled
    over it), then served interval by interval (``arfem twin --scenario``).

    Returns
    -------
    (AxesTwin, float)
        The twin and its interval Δτ [s] (the scenario's ``output_interval_s``).
    """
    sc = load_geometry_scenario(path)
    axes = sensor_axes(sc.sensors)
    if not axes:
        raise InputError("has no displacement sensor: a twin needs an axis to compensate",
                         str(path))
    run = solve_geometry(build_geometry_model(sc, progress), progress)
    ser = run.sensor_series()
    hist = run.model.history
    t = run.result.times_s
    prev = np.concatenate([[0.0], t[:-1]])
    mid = np.where(t > 0, 0.5 * (prev + t), 0.0)
    seg = np.clip(np.searchsorted(hist.edges_s, mid, side="right") - 1, 0, hist.u.shape[0] - 1)
    cseg = np.clip(np.searchsorted(sc.cycle.edges_s, mid, side="right") - 1, 0,
                   len(sc.cycle.speed_rpm) - 1)
    readings = {"speed_rpm": np.asarray(sc.cycle.speed_rpm, float)[cseg],
                "ambient_C": np.asarray(sc.cycle.ambient_C, float)[cseg]}
    for j, src in enumerate(sc.sources):
        name = (f"P_{src.spec.name}_W" if src.spec.kind == "power"
                else f"q_{src.spec.name}_W_m2")
        readings[name] = hist.u[seg, j]
    readings.update({k: v for k, v in ser.items() if k.startswith("T_")})
    true = {ax: ser[f"d_{s.name}_um"] for s, ax in axes}
    measured = {ax: f"d_{s.name}_um" for s, ax in axes}
    return AxesTwin(t, readings, true, measured, noise_um, seed), sc.output_interval_s
