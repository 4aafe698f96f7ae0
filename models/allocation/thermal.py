"""Spindle thermal growth as a term of a precision budget, instant by instant.

The spindle rod of Du et al. (2021) grows along its axis while it runs a duty cycle.
In an allocation the growth is a translation of the tool along the spindle axis in the
workpiece-to-tool loop, known at every instant of the cycle (not a design variable):
the growth a model predicts, or -- if the machine compensates it with a model -- what a
(simulated, noisy) measurement shows is left after the prediction is subtracted.
"""
from __future__ import annotations

import numpy as np

from arfem.params import InputError, Rod, paper_cycle

__all__ = ["MODELS", "growth_on_paper_cycle_m", "spindle_series"]

#: growth models a scenario may name
MODELS = ("ar", "ar_corrected", "fem")


def growth_on_paper_cycle_m(rod: Rod, q_W_m2: float, model: str, dtau_s: float = 30.0):
    """Axial growth [m] on the paper's 24 h duty cycle, sampled every ``dtau_s``.

    Parameters
    ----------
    rod : Rod
    q_W_m2 : float
        Heat flux during the on-phases [W/m²].
    model : {"ar", "ar_corrected", "fem"}
        ``"ar"``: AR(1) with the paper's C1, C2 (Du et al. eqs. 12-14);
        ``"ar_corrected"``: AR(1) from the slowest radial mode
        (:func:`arfem.models.ar1.corrected_coefficients`); ``"fem"``: axisymmetric Q2
        FEM (nr = 6, nz = 32) advanced exactly in time by :func:`arfem.fem.heat.solve_modal`.
    dtau_s : float
        Sampling step [s]; must divide the cycle's phases.

    Returns
    -------
    times_s, growth_m : ndarray

    Examples
    --------
    >>> t, g = growth_on_paper_cycle_m(Rod(), 2000.0, "ar_corrected", 30.0)
    >>> round(float(g.max()) * 1e6, 2)
    22.17
    """
    sched = paper_cycle(q_W_m2)
    if model in ("ar", "ar_corrected"):
        from arfem.models.ar1 import ar1_on_schedule
        return ar1_on_schedule(rod, sched, dtau_s, corrected=(model == "ar_corrected"))
    if model == "fem":
        from arfem.fem.heat import build_axisymmetric, solve_modal
        fem = build_axisymmetric(rod, order=2, nr=6, nz=32)
        t = sched.subdivided(dtau_s).edges_s
        res = solve_modal(fem, sched, output_times_s=t)
        return res.times_s, res.growth_m
    raise InputError(f"must be one of {', '.join(MODELS)}, got {model!r}", "model")


def spindle_series(rod: Rod, q_W_m2: float, model: str = "fem", dtau_s: float = 30.0,
                   compensated: bool = False, compensation_model: str = "ar",
                   noise_um: float = 0.2, seed: int = 0):
    """Spindle growth along its axis at every instant of the paper duty cycle, for a budget.

    Uncompensated: the growth of ``model`` [mm]. Compensated: the machine subtracts what
    ``compensation_model`` predicts; what is left is judged against a simulated
    measurement of the real growth (the FEM, standing in for the machine) with white
    noise of ``noise_um`` (1σ, a displacement probe): residual(t) = FEM(t) + ε(t) −
    prediction(t).

    Parameters
    ----------
    rod : Rod
    q_W_m2 : float
        Heat flux of the on-phases [W/m²].
    model : {"fem", "ar", "ar_corrected"}
        Growth model of the uncompensated budget.
    dtau_s : float
        Sampling step [s].
    compensated : bool
    compensation_model : {"ar", "ar_corrected"}
        Model whose prediction is subtracted.
    noise_um : float
        Measurement noise, standard deviation [µm].
    seed : int
        Seed of the noise.

    Returns
    -------
    times_s : ndarray
    series_mm : ndarray
        Growth, or the measured compensation residual, along the spindle axis [mm].
    info : dict
        ``peak_um`` (max |series|), ``t_peak_s`` and, compensated, ``peak_fem_um``,
        ``peak_prediction_um``, ``true_residual_um`` (max |FEM − prediction|), ``noise_um``.

    Examples
    --------
    >>> t, d, info = spindle_series(Rod(), 2000.0, "ar", 30.0)
    >>> round(info["peak_um"], 2)
    21.6
    """
    out = {"model": model, "q_W_m2": float(q_W_m2), "dtau_s": float(dtau_s),
           "compensated": bool(compensated)}
    if not compensated:
        t, g = growth_on_paper_cycle_m(rod, q_W_m2, model, dtau_s)
        series = g * 1e3
    else:
        t, g_fem = growth_on_paper_cycle_m(rod, q_W_m2, "fem", dtau_s)
        _, g_pred = growth_on_paper_cycle_m(rod, q_W_m2, compensation_model, dtau_s)
        eps = np.random.default_rng(seed).normal(0.0, noise_um * 1e-3, len(t))
        series = (g_fem * 1e3 + eps) - g_pred * 1e3
        out.update(compensation_model=compensation_model, noise_um=float(noise_um),
                   noise_seed=int(seed), peak_fem_um=float(np.max(g_fem) * 1e6),
                   peak_prediction_um=float(np.max(g_pred) * 1e6),
                   true_residual_um=float(np.max(np.abs(g_fem - g_pred)) * 1e6))
    k = int(np.argmax(np.abs(series)))
    out.update(peak_um=float(abs(series[k]) * 1e3), t_peak_s=float(t[k]))
    return np.asarray(t, float), series, out
