"""The computation of one scenario: the FEM and both AR(1) models on its cycle, compared.

Data flow: :class:`~arfem.scenarios.rod.scenario.Scenario` → :func:`evaluate` (FEM, paper
AR(1), corrected AR(1), least-squares fit) → :class:`Evaluation`. No file is read or
written here; the writers are in :mod:`arfem.scenarios.rod.outputs` (``arfem run``), and
``arfem check``, the sweep workers and the Python API call :func:`evaluate` directly.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from arfem.fem.heat import HeatFEM, build_3d, build_axisymmetric, solve_modal, solve_theta
from arfem.models.ar1 import (ar1_on_schedule, c1_paper, c2_paper, corrected_coefficients, fit_ar1)
from arfem.params import Schedule
from arfem.scenarios.rod.scenario import Scenario

__all__ = ["Evaluation", "build_model", "evaluate", "no_progress"]


@dataclass(frozen=True)
class Evaluation:
    """Result of one scenario: time series on the AR grid and summary metrics."""

    scenario: Scenario
    times_s: np.ndarray
    q_W_m2: np.ndarray              # input on the interval ending at each sample
    fem_growth_um: np.ndarray
    ar_growth_um: np.ndarray
    ar_corrected_growth_um: np.ndarray
    metrics: dict
    model: HeatFEM | None = field(default=None, repr=False)


def build_model(scenario: Scenario, cache: dict | None = None) -> HeatFEM:
    """The scenario's FEM model (assembled once per rod/mesh when ``cache`` is given)."""
    f = scenario.fem
    key = (scenario.rod, f.model, f.order, tuple(sorted(f.mesh.items())))
    if cache is not None and key in cache:
        return cache[key]
    build = build_axisymmetric if f.model == "axisymmetric" else build_3d
    model = build(scenario.rod, order=f.order, **f.mesh)
    if cache is not None:
        cache[key] = model
    return model


def _fem_growth(scenario: Scenario, model: HeatFEM, cache: dict | None):
    """FEM growth [m] at the AR sample times 0, Δτ, 2Δτ, …"""
    fine = scenario.schedule.subdivided(scenario.dtau_s)
    if scenario.fem.theta is None:
        return fine, _modal_growth(scenario, model, fine, cache)
    res = solve_theta(model, fine, scenario.fem.dt_s, theta=scenario.fem.theta)
    k = int(round(scenario.dtau_s / scenario.fem.dt_s))
    return fine, res.growth_m[::k]


def _modal_growth(scenario: Scenario, model: HeatFEM, fine, cache: dict | None) -> np.ndarray:
    """Growth [m] of the exact modal solve on ``fine``, shared across a sweep's points.

    With the ambient at its nominal value the growth is linear in q, so it is computed
    for the flux pattern q / max|q| and scaled. Every run takes that path, cached or not,
    so a sweep's table is bit-identical however its points are spread over workers; in
    one worker the points that differ only in the flux level share one solve.
    """
    modes = None if cache is None else cache.setdefault(("modes", id(model)), {})
    sched = scenario.schedule
    q = np.asarray(sched.q_W_m2, float)
    qmax = float(np.max(np.abs(q)))
    amb = sched.ambient_for(model.rod) - model.rod.ambient_C
    if qmax == 0.0 or np.any(amb != 0.0):
        return solve_modal(model, fine, mode_cache=modes).growth_m
    key = ("unit_growth", id(model), scenario.dtau_s, tuple(sched.durations_s),
           tuple(q / qmax), tuple(sched.h_for(model.rod)))
    unit = None if cache is None else cache.get(key)
    if unit is None:
        unit_sched = Schedule(fine.durations_s, np.asarray(fine.q_W_m2) / qmax,
                              fine.ambient_C, fine.h_W_m2K)
        unit = solve_modal(model, unit_sched, mode_cache=modes).growth_m
        if cache is not None:
            cache[key] = unit
    return qmax * unit


def _levels_metrics(prefix: str, by_q: dict) -> dict:
    return {f"{prefix}_by_q_W_m2": {f"{q:g}": v for q, v in by_q.items()},
            prefix: by_q[max(by_q)] if by_q else 0.0}


def evaluate(scenario: Scenario, cache: dict | None = None, progress=None) -> Evaluation:
    """Run the FEM and both AR(1) models on the scenario's cycle; compare them.

    Parameters
    ----------
    scenario : Scenario
    cache : dict, optional
        Reuse assembled models and eigen-decompositions across calls (sweeps).
    progress : callable, optional
        Called with the name of each slow step as it starts
        (:class:`arfem.scenarios.progress.Progress`).
    """
    progress = progress or no_progress
    progress("FEM solve")
    t0 = time.perf_counter()
    rod, dtau = scenario.rod, scenario.dtau_s
    model = build_model(scenario, cache)
    fine, fem_m = _fem_growth(scenario, model, cache)
    t_fem = time.perf_counter() - t0
    progress("AR(1) models and fit")
    times, ar_m = ar1_on_schedule(rod, scenario.schedule, dtau)
    _, arc_m = ar1_on_schedule(rod, scenario.schedule, dtau, corrected=True)
    q = np.concatenate([[fine.q_W_m2[0]], fine.q_W_m2])
    fem, ar, arc = fem_m * 1e6, ar_m * 1e6, arc_m * 1e6
    fit = fit_ar1(fem, fine.q_W_m2)
    levels = scenario.q_levels
    peak = float(np.max(np.abs(fem)))
    d, dc = ar - fem, arc - fem
    c1c = corrected_coefficients(rod, dtau, 1.0)[0]
    m = {
        "scenario": scenario.name,
        "dtau_s": dtau,
        "h_W_m2K": rod.convection_W_m2K,
        "q_W_m2": max(levels) if levels else 0.0,
        "biot": rod.biot,
        "fem_model": scenario.fem.model,
        "fem_order": scenario.fem.order,
        "fem_solver": scenario.fem.solver,
        "fem_dofs": model.ndofs,
        "n_samples": int(times.size),
        "C1": c1_paper(rod, dtau),
        **_levels_metrics("C2_um", {q_: c2_paper(rod, dtau, q_) * 1e6 for q_ in levels}),
        "C1_fitted": fit.c1,
        **_levels_metrics("C2_fitted_um", {q_: fit.c2.get(q_, float("nan")) for q_ in levels}),
        "C2_fitted_um_at_q0": fit.c2.get(0.0, 0.0),
        "corrected_C1": c1c,
        **_levels_metrics("corrected_C2_um",
                          {q_: corrected_coefficients(rod, dtau, q_)[1] * 1e6 for q_ in levels}),
        "fem_peak_um": peak,
        "fem_peak_time_h": float(times[np.argmax(np.abs(fem))] / 3600.0),
        "ar_peak_um": float(np.max(np.abs(ar))),
        "ar_corrected_peak_um": float(np.max(np.abs(arc))),
        "max_abs_diff_um": float(np.max(np.abs(d))),
        "max_abs_diff_pct_of_peak": float(100 * np.max(np.abs(d)) / peak) if peak else 0.0,
        "rmse_um": float(np.sqrt(np.mean(d ** 2))),
        "corrected_max_abs_diff_um": float(np.max(np.abs(dc))),
        "corrected_max_abs_diff_pct_of_peak": float(100 * np.max(np.abs(dc)) / peak) if peak else 0.0,
        "corrected_rmse_um": float(np.sqrt(np.mean(dc ** 2))),
        "corrected_peak_diff_pct": float(100 * (np.max(np.abs(arc)) - peak) / peak) if peak else 0.0,
        "fem_wall_s": t_fem,
        "wall_s": time.perf_counter() - t0,
    }
    return Evaluation(scenario, times, q, fem, ar, arc, m, model)


def no_progress(step: str) -> None:
    """The default progress hook: nothing."""
