"""Spindle thermal growth as a fixed term in a precision budget.

The spindle rod of Du et al. (2021) grows axially while it runs a duty cycle.
For allocation the growth enters a chain as a unit whose Δz is fixed (not a
design variable): the peak growth predicted for the cycle, or -- if the machine
compensates growth with a model -- the largest error that model leaves against
the FEM reference.
"""
from __future__ import annotations

import numpy as np

from arfem.params import InputError, Rod, paper_cycle

__all__ = ["MODELS", "growth_on_paper_cycle_m", "spindle_dz_mm"]

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


def spindle_dz_mm(rod: Rod, q_W_m2: float, model: str, dtau_s: float = 30.0,
                  compensated: bool = False) -> dict:
    """Fixed spindle Δz [mm] for the budget, with the numbers behind it.

    Parameters
    ----------
    rod : Rod
    q_W_m2 : float
        Heat flux of the on-phases [W/m²].
    model : {"ar", "ar_corrected", "fem"}
        Growth model (see :func:`growth_on_paper_cycle_m`).
    dtau_s : float
        Sampling step [s].
    compensated : bool
        False: Δz = peak growth of ``model`` over the cycle. True: the machine
        subtracts the growth ``model`` predicts, so Δz = max |model − FEM| (the
        FEM is the reference; ``model`` must then be an AR model).

    Returns
    -------
    dict
        ``dz_mm`` (the fixed error), ``peak_growth_um`` of the model,
        ``peak_growth_fem_um`` and ``residual_um`` when compensated.

    Examples
    --------
    >>> d = spindle_dz_mm(Rod(), 2000.0, "ar", 30.0)
    >>> round(d["dz_mm"] * 1e3, 2)
    21.6
    """
    t, g = growth_on_paper_cycle_m(rod, q_W_m2, model, dtau_s)
    out = {"model": model, "q_W_m2": float(q_W_m2), "dtau_s": float(dtau_s),
           "compensated": bool(compensated), "peak_growth_um": float(np.max(g) * 1e6)}
    if not compensated:
        out["dz_mm"] = float(np.max(g) * 1e3)
        return out
    if model == "fem":
        raise InputError("compensation residual needs an AR model, not the FEM reference",
                         "model")
    _, g_fem = growth_on_paper_cycle_m(rod, q_W_m2, "fem", dtau_s)
    res = float(np.max(np.abs(g - g_fem)))
    out.update(peak_growth_fem_um=float(np.max(g_fem) * 1e6), residual_um=res * 1e6,
               dz_mm=res * 1e3)
    return out
