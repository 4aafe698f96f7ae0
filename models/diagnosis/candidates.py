"""Candidate causes as physical changes to a forward model, each fitted by least squares.

Every candidate is *variable projection*: a few nonlinear physical parameters θ (an h,
a time constant, an exponent) are searched by a bounded optimiser; for each θ the
forward model is run once and the remaining parameters that enter linearly (a gain, a
drift rate, a scale, and the nuisance terms for an unknown initial state) are solved
exactly by linear least squares on the fit rows. The loss is ordinary least squares
on the rows before the hold-out that the loader did not flag as outliers.

Two physics back-ends realise the causes:

* :class:`FemPhysics` -- the FEM rod (:class:`arfem.models.diagnosis.forward.RodModel`), for
  datasets that record the heat flux ``q_W_m2``;
* :class:`ArPhysics` -- the paper's AR(1) (eqs. 12-14) with the same physical
  parameters (b = 2h/(ρcR), steady gain qαR/(2h)), the form a compensation controller
  would run.

Datasets that only record ``speed_rpm`` use :mod:`arfem.models.diagnosis.speed`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from arfem.models.diagnosis.forward import RodModel, ar_first_order, first_order_lag, intervals
from arfem.params import Rod

__all__ = ["CAUSES", "CandidateFit", "FemPhysics", "ArPhysics", "fit_candidate", "project"]

#: the contract's vocabulary, in the order candidates are tried
CAUSES = ("none", "ambient_drift", "convection_mismatch", "speed_dependent_convection",
          "heat_input_scale", "frame_expansion", "sensor_drift", "nonlinear_convection")

#: surface-to-air temperature difference at which the natural-convection h is reported [K]
DT_REF_K = 10.0


@dataclass
class CandidateFit:
    """One cause fitted on the rows before the hold-out.

    ``prediction`` covers the whole record; ``k`` counts the cause's own parameters
    (nuisance terms shared with the baseline are not counted).
    """

    cause: str
    model: str
    parameters: dict
    prediction: np.ndarray
    k: int
    rss: float = float("nan")
    n: int = 0
    extra: dict = field(default_factory=dict)


def project(columns: list[np.ndarray], target: np.ndarray, rows: np.ndarray):
    """Linear least squares of ``target`` on ``columns`` over ``rows``.

    Returns (coefficients, fitted values over the whole record).

    Examples
    --------
    >>> x = np.arange(5.0)
    >>> c, f = project([np.ones(5), x], 2 + 3 * x, np.ones(5, bool))
    >>> np.round(c, 6).tolist()
    [2.0, 3.0]
    """
    if not columns:
        return np.zeros(0), np.zeros_like(target)
    X = np.column_stack(columns)
    scale = np.linalg.norm(X[rows], axis=0)
    scale[scale == 0] = 1.0
    coef, *_ = np.linalg.lstsq(X[rows] / scale, target[rows], rcond=None)
    coef = coef / scale
    return coef, X @ coef


class FemPhysics:
    """The FEM rod as the physics of every candidate (``q_W_m2`` datasets)."""

    label = "fem"

    def __init__(self, rod: Rod, model: RodModel | None = None):
        self.rod = rod
        self.m = model or RodModel(rod)

    def response(self, t, q, h=None, ambient_K=None):
        """Growth [µm] for flux q [W/m²], convection h [W/(m²K)], ambient rise [K].

        Parameters
        ----------
        t : array_like
            Sample times [s] (the first interval starts at t = 0).
        q : array_like
            Heat flux into the heated end on the interval ending at each sample [W/m²].
        h : float or array_like, optional
            Lateral convection coefficient, scalar or per interval [W/(m²·K)];
            default the rod's nominal.
        ambient_K : array_like, optional
            Ambient minus the nominal ambient on each interval [K]; default 0.

        Returns
        -------
        ndarray
            Axial growth at each sample [µm], from equilibrium at t = 0.
        """
        return self.m.simulate(t, q, ambient_K=ambient_K, h_W_m2K=h)

    def nonlinear(self, t, q, exponent, h_ref, ambient_K=None):
        """Growth [µm] with h = h_ref (ΔT_s/DT_REF_K)^exponent (semi-implicit).

        ΔT_s is the lateral-surface mean temperature minus the ambient [K]; see
        :meth:`arfem.models.diagnosis.forward.RodModel.simulate_nonlinear`.

        Parameters
        ----------
        t : array_like
            Sample times [s] (the first interval starts at t = 0).
        q : array_like
            Heat flux into the heated end on the interval ending at each sample [W/m²].
        exponent : float
            n in h ∝ ΔT^n [-].
        h_ref : float
            h at ΔT = DT_REF_K = 10 K [W/(m²·K)].
        ambient_K : array_like, optional
            Ambient minus the nominal ambient on each interval [K]; default 0.

        Returns
        -------
        ndarray
            Axial growth at each sample [µm], from equilibrium at t = 0.
        """
        return self.m.simulate_nonlinear(t, q, exponent, DT_REF_K, ambient_K=ambient_K,
                                         h_ref_W_m2K=h_ref)

    def slowest_rate(self, h=None) -> float:
        """Decay rate of the FEM rod's slowest growth mode [1/s].

        Parameters
        ----------
        h : float, optional
            Lateral convection coefficient [W/(m²·K)]; default the rod's nominal.

        Returns
        -------
        float
            μ_1 [1/s] (1/time constant).
        """
        return self.m.slowest_rate_1_s(h)

    def steady_gain_um_per_W_m2(self) -> float:
        """Steady growth per unit flux at the nominal h [µm/(W/m²)]."""
        return self.m.steady_growth_um(1.0)

    def ambient_gain_um_per_K(self) -> float:
        """Steady growth per kelvin of ambient [µm/K] = αL·1e6 for a free rod."""
        return self.rod.expansion_1_K * self.rod.length_m * 1e6


class ArPhysics:
    """The paper's AR(1) (eqs. 12-14) with physical coefficients as the physics."""

    label = "ar"

    def __init__(self, rod: Rod):
        self.rod = rod
        self.rhocR = rod.density_kg_m3 * rod.specific_heat_J_kgK * rod.radius_m

    def _b(self, h):
        return 2.0 * np.asarray(h, float) / self.rhocR

    def response(self, t, q, h=None, ambient_K=None):
        """1D fin growth G' = −b G + b (αR/(2h) q + αL θ_amb) [µm], exact per interval.

        The AR(1) of paper eqs. 12-14 for uneven steps: C1 = e^{−bΔτ} with
        b = 2h/(ρcR), steady gain αR/(2h) per unit q (= αa/(λb)).

        Parameters
        ----------
        t : array_like
            Sample times [s] (the first interval starts at t = 0).
        q : array_like
            Heat flux into the heated end on the interval ending at each sample [W/m²].
        h : float or array_like, optional
            Lateral convection coefficient, scalar or per interval [W/(m²·K)];
            default the rod's nominal.
        ambient_K : array_like, optional
            Ambient minus the nominal ambient on each interval [K]; default 0.

        Returns
        -------
        ndarray
            Axial growth at each sample [µm], from equilibrium at t = 0.

        References
        ----------
        Du et al., J. Harbin Inst. Technol. 53(7), 2021, eqs. 12-14.
        """
        rod = self.rod
        h = rod.convection_W_m2K if h is None else h
        hh = np.broadcast_to(np.asarray(h, float), np.shape(t))
        u = np.asarray(q, float) * rod.expansion_1_K * rod.radius_m / (2.0 * hh) * 1e6
        if ambient_K is not None:
            u = u + np.asarray(ambient_K, float) * rod.expansion_1_K * rod.length_m * 1e6
        return ar_first_order(t, u, self._b(hh), 1.0)

    def nonlinear(self, t, q, exponent, h_ref, ambient_K=None):
        """AR(1) whose b follows h = h_ref (ΔT/DT_REF_K)^n, ΔT = mean rise G/(αL).

        ΔT = |G/(αL) − θ_amb| [K] at the start of each interval, held over it; h is
        floored at 5 % of the rod's nominal h. Paper eqs. 12-14 with a varying b.

        Parameters
        ----------
        t : array_like
            Sample times [s] (the first interval starts at t = 0).
        q : array_like
            Heat flux into the heated end on the interval ending at each sample [W/m²].
        exponent : float
            n in h ∝ ΔT^n [-].
        h_ref : float
            h at ΔT = DT_REF_K = 10 K [W/(m²·K)].
        ambient_K : array_like, optional
            Ambient minus the nominal ambient on each interval [K]; default 0.

        Returns
        -------
        ndarray
            Axial growth at each sample [µm], from equilibrium at t = 0.
        """
        rod = self.rod
        t = np.asarray(t, float)
        d = intervals(t)
        q = np.asarray(q, float)
        amb = np.zeros(t.size) if ambient_K is None else np.asarray(ambient_K, float)
        aL = rod.expansion_1_K * rod.length_m * 1e6
        g = 0.0
        out = np.empty(t.size)
        for i in range(t.size):
            dT = abs(g / aL - amb[i])
            h = h_ref * max(dT / DT_REF_K, 1e-12) ** exponent if exponent else h_ref
            h = max(h, 0.05 * rod.convection_W_m2K)
            b = 2.0 * h / self.rhocR
            gss = q[i] * rod.expansion_1_K * rod.radius_m / (2.0 * h) * 1e6 + aL * amb[i]
            a = np.exp(-b * d[i])
            g = gss + a * (g - gss)
            out[i] = g
        return out

    def slowest_rate(self, h=None) -> float:
        """Fin rate b = 2h/(ρcR) [1/s] of C1 = e^{−bΔτ} (paper eq. 13).

        Parameters
        ----------
        h : float, optional
            Lateral convection coefficient [W/(m²·K)]; default the rod's nominal.

        Returns
        -------
        float
            b [1/s].

        References
        ----------
        Du et al., J. Harbin Inst. Technol. 53(7), 2021, eq. 13.
        """
        return float(self._b(self.rod.convection_W_m2K if h is None else h))

    def steady_gain_um_per_W_m2(self) -> float:
        """Steady growth per unit flux αR/(2h) [µm/(W/m²)] (fixed point of eq. 12)."""
        return self.rod.expansion_1_K * self.rod.radius_m / (2 * self.rod.convection_W_m2K) * 1e6

    def ambient_gain_um_per_K(self) -> float:
        return self.rod.expansion_1_K * self.rod.length_m * 1e6


def _nuisance(t, initial_known: bool, rate_1_s: float) -> list[np.ndarray]:
    """Columns for an unknown initial state: an offset and the slowest mode's decay."""
    if initial_known:
        return []
    return [np.ones_like(t), np.exp(-rate_1_s * np.asarray(t, float))]


def fit_candidate(cause: str, phys, t, q, y, rows, initial_known: bool = True,
                  ambient_K=None, frame_C=None) -> CandidateFit | None:
    """Fit one cause with physics back-end ``phys`` on ``rows``; None if not applicable.

    Parameters
    ----------
    cause : str
        One of :data:`CAUSES`.
    phys : FemPhysics or ArPhysics
    t, q, y : ndarray
        Sample times [s], heat flux [W/m²], measured growth [µm].
    rows : ndarray of bool
        Fit rows (before the hold-out, not outliers).
    initial_known : bool
        False adds nuisance columns (offset, slowest-mode decay) to every candidate.
    ambient_K : ndarray, optional
        Recorded ambient minus the nominal ambient [K] (``ambient_drift`` needs it).
    frame_C : ndarray, optional
        Recorded frame temperature [°C] (used by ``frame_expansion`` when present).
    """
    rod = phys.rod
    h0 = rod.convection_W_m2K
    t = np.asarray(t, float)
    tag = f"{phys.label}+{cause}" if cause != "none" else phys.label

    def lin(base, extra_cols, rate=None):
        cols = list(extra_cols) + _nuisance(t, initial_known, rate or phys.slowest_rate())
        coef, fit = project(cols, y - base, rows) if cols else (np.zeros(0), np.zeros_like(y))
        pred = base + fit
        r = (y - pred)[rows]
        return float(r @ r), coef, pred

    def done(params, pred, k, rss, **extra):
        return CandidateFit(cause, tag, params, pred, k, rss, int(rows.sum()), extra)

    base0 = phys.response(t, q)
    if cause == "none":
        rss, coef, pred = lin(base0, [])
        return done({}, pred, 0, rss)

    if cause == "heat_input_scale":
        # y ≈ s·base0 (+ nuisance): s enters linearly
        cols = [base0] + _nuisance(t, initial_known, phys.slowest_rate())
        coef, pred = project(cols, y, rows)
        r = (y - pred)[rows]
        return done({"scale": float(coef[0])}, pred, 1, float(r @ r))

    if cause == "sensor_drift":
        rss, coef, pred = lin(base0, [t / 3600.0])
        return done({"drift_um_per_h": float(coef[0])}, pred, 1, rss)

    if cause == "ambient_drift":
        if ambient_K is None:
            return None
        gain = phys.ambient_gain_um_per_K()
        col = phys.response(t, np.zeros_like(t), ambient_K=ambient_K) / gain
        rss, coef, pred = lin(base0, [col])
        return done({"ambient_gain_um_per_K": float(coef[0])}, pred, 1, rss,
                    physical_gain_um_per_K=gain)

    if cause == "convection_mismatch":
        def run(logh):
            h = float(np.exp(logh))
            return lin(phys.response(t, q, h=h), [], phys.slowest_rate(h))
        res = minimize_scalar(lambda x: run(x)[0], bounds=(np.log(h0 / 8), np.log(h0 * 8)),
                              method="bounded", options={"xatol": 1e-4})
        rss, coef, pred = run(res.x)
        return done({"h_W_m2K": float(np.exp(res.x))}, pred, 1, rss)

    if cause == "speed_dependent_convection":
        running = np.asarray(q) > 0
        if running.all() or not running.any():
            return None

        def run(x):
            hr, hs = np.exp(x)
            h = np.where(running, hr, hs)
            return lin(phys.response(t, q, h=h), [], phys.slowest_rate(min(hr, hs)))
        best = None
        for start in ([np.log(h0), np.log(h0)], [np.log(h0 * 1.6), np.log(h0)],
                      [np.log(h0 / 1.5), np.log(h0)]):
            r = minimize(lambda x: run(np.clip(x, np.log(h0 / 8), np.log(h0 * 8)))[0],
                         np.array(start), method="Nelder-Mead",
                         options={"xatol": 1e-4, "fatol": 1e-10, "maxiter": 400})
            if best is None or r.fun < best.fun:
                best = r
        x = np.clip(best.x, np.log(h0 / 8), np.log(h0 * 8))
        rss, coef, pred = run(x)
        return done({"h_running_W_m2K": float(np.exp(x[0])),
                     "h_stopped_W_m2K": float(np.exp(x[1]))}, pred, 2, rss)

    if cause == "frame_expansion":
        # the frame is a slower body heated by the same source: its growth is a first-order
        # lag of the rod's steady growth target (q times the rod's steady gain), so the
        # coefficient is directly the frame's steady growth per unit of rod growth
        target = np.asarray(q, float) * phys.steady_gain_um_per_W_m2()

        def run(log_tau_h):
            tau_s = float(np.exp(log_tau_h)) * 3600.0
            col = first_order_lag(t, target, tau_s)
            return lin(base0, [col])
        res = minimize_scalar(lambda x: run(x)[0], bounds=(np.log(2.0), np.log(200.0)),
                              method="bounded", options={"xatol": 1e-4})
        rss, coef, pred = run(res.x)
        params = {"frame_time_constant_h": float(np.exp(res.x)), "frame_gain": float(coef[0])}
        extra = {}
        if frame_C is not None and np.all(np.isfinite(frame_C)):
            extra["frame_sensor"] = "T_frame_C recorded; the frame state is the lag of the "\
                                    "rod's own growth, T_frame_C is reported in the cross-correlations"
        return done(params, pred, 2, rss, **extra)

    if cause == "nonlinear_convection":
        def run(x):
            n, logh = x
            g = phys.nonlinear(t, q, float(n), float(np.exp(logh)))
            return lin(g, [], phys.slowest_rate(float(np.exp(logh))))
        best = None
        for start in ([0.25, np.log(h0)],):
            r = minimize(lambda x: run(np.clip(x, [-0.5, np.log(h0 / 8)], [1.5, np.log(h0 * 8)]))[0],
                         np.array(start), method="Nelder-Mead",
                         options={"xatol": 2e-3, "fatol": 1e-9, "maxiter": 90})
            if best is None or r.fun < best.fun:
                best = r
        x = np.clip(best.x, [-0.5, np.log(h0 / 8)], [1.5, np.log(h0 * 8)])
        rss, coef, pred = run(x)
        return done({"exponent": float(x[0]), "h_at_10K_W_m2K": float(np.exp(x[1]))},
                    pred, 2, rss)

    raise ValueError(f"unknown cause {cause!r}")
