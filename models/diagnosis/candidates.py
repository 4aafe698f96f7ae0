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

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property, partial

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from arfem.models.diagnosis.forward import RodModel, ar_first_order, first_order_lag, intervals
from arfem.models.plant import BOUNDS
from arfem.params import Rod

__all__ = ["CAUSES", "H_CAUSES", "CandidateFit", "JointFit", "FrameFit", "FemPhysics",
           "ArPhysics", "fit_candidate",
           "fit_rod_causes", "compatible", "parameter_ci95", "project"]

#: the contract's vocabulary, in the order candidates are tried
CAUSES = ("none", "ambient_drift", "convection_mismatch", "speed_dependent_convection",
          "heat_input_scale", "frame_expansion", "sensor_drift", "nonlinear_convection")

#: surface-to-air temperature difference at which the natural-convection h is reported [K]
DT_REF_K = 10.0


@dataclass(frozen=True)
class JointFit:
    """What a fit of :func:`fit_rod_causes` keeps beside its prediction, for its intervals
    (:func:`parameter_ci95`), the pair searches that start from it and the export as a
    compensator (:func:`arfem.models.diagnosis.export.fem_state_space`).

    Attributes
    ----------
    theta : dict of str to float
        The searched nonlinear coordinates at the optimum (``log_h`` = ln h with h in
        [W/(m²·K)], ``log_tau_h`` = ln τ with τ in [h], ``exponent`` [-], ...).
    linear : dict of str to float
        The linear coefficients at that θ, named by their unit
        (``ambient_gain_um_per_K`` [µm/K], ``drift_um_per_h`` [µm/h], ``scale`` [-],
        ``frame_gain`` [-]; ``_initial_offset_um``, ``_initial_decay_um`` [µm] for an
        unknown initial state, not counted as the cause's parameters).
    coordinates : tuple of str
        The names of θ then of the linear coefficients: the columns of ``jacobian``.
    jacobian : ndarray, shape (n, p)
        ∂prediction/∂(θ, linear) on the n fit rows [µm per coordinate unit]; (n, 0)
        for the baseline.
    ambient_K : ndarray, shape (N,), optional
        The recorded ambient minus the nominal ambient the fit ran on [K]
        (``ambient_drift`` only, else None).
    refit_with_ambient : callable, optional
        ``refit_with_ambient(ambient_K) -> dict`` of the linear coefficients at the same θ
        with another recorded ambient (``ambient_drift`` only, else None): the draws of
        the ambient's own noise in :func:`parameter_ci95`.
    physical_ambient_gain_um_per_K : float, optional
        αL·1e6 of the physics [µm/K], beside a fitted ``ambient_drift`` (else None).
    frame_sensor_note : str, optional
        Why a recorded ``T_frame_C`` is not an input of ``frame_expansion`` (where
        recorded, else None).
    """

    theta: dict
    linear: dict
    coordinates: tuple = ()
    jacobian: np.ndarray | None = None
    ambient_K: np.ndarray | None = None
    refit_with_ambient: Callable | None = None
    physical_ambient_gain_um_per_K: float | None = None
    frame_sensor_note: str | None = None


@dataclass(frozen=True)
class FrameFit:
    """The thermometer frame part of a speed record's ``frame_expansion`` fit
    (:func:`arfem.models.diagnosis.speed_frame.fit_frame_thermometers`).

    Attributes
    ----------
    sensors : tuple of str
        The complete temperature columns used [their names, °C series].
    frame_um : ndarray, shape (N,)
        The frame part of the prediction over the record [µm].
    coefficients : tuple of float
        The linear coefficients in column order: a steady gain per seen speed [µm],
        the initial-state decay [µm], the offset [µm], then (slow response) the slow
        gains and decay, then one per temperature component [µm per unit component].
        Empty for an average of structures.
    structure : str
        Label of the frame structure (:class:`~arfem.models.diagnosis.speed_frame.FrameStructure`).
    members : tuple of str
        An average of structures: the labels of its members (else empty).
    """

    sensors: tuple
    frame_um: np.ndarray
    coefficients: tuple
    structure: str
    members: tuple = ()


@dataclass(frozen=True, eq=False)
class CandidateFit:
    """One cause (or set of causes) fitted on the rows before the hold-out.

    Compared by identity (``eq=False``): the rules ask whether two names hold the same fit.

    Attributes
    ----------
    cause : str
        The cause(s), joined by ``+`` (``none`` for the baseline).
    model : str
        The physics and causes, e.g. ``"fem+heat_input_scale"`` or ``"ar+sensor_drift"``.
    parameters : dict of str to float
        Physical parameters, named with their unit (``h_W_m2K`` [W/(m²·K)], ...).
    prediction : ndarray, shape (N,)
        Growth over the whole record [µm].
    k : int
        The cause's own parameters (nuisance terms shared with the baseline not counted).
    rss : float
        Residual sum of squares on the fit rows [µm²].
    n : int
        Number of fit rows.
    causes : tuple of str
        The causes in the order the pair search ranks them (empty for the baseline and
        for the speed-record candidates).
    at_bound : tuple of str
        Searched coordinates that ran to the edge of their search range.
    residual_um : ndarray, shape (n,), optional
        Measured minus predicted growth on the fit rows [µm].
    fit_rows : ndarray of bool, shape (N,), optional
        The fit rows.
    time_constant_h : float, optional
        Speed records: the AR(1) rod's time constant 1/b [h].
    joint : JointFit, optional
        :func:`fit_rod_causes` fits: the coordinates, Jacobian and refits.
    frame : FrameFit, optional
        Speed records' thermometer ``frame_expansion``: its frame part.
    note : str, optional
        What a reader of the parameters must know (e.g. how h was derived).
    """

    cause: str
    model: str
    parameters: dict
    prediction: np.ndarray
    k: int
    rss: float = float("nan")
    n: int = 0
    causes: tuple = ()
    at_bound: tuple = ()
    residual_um: np.ndarray | None = None
    fit_rows: np.ndarray | None = None
    time_constant_h: float | None = None
    joint: JointFit | None = None
    frame: FrameFit | None = None
    note: str | None = None

    @property
    def theta(self) -> dict:
        """The searched coordinates of a :func:`fit_rod_causes` fit (else empty)."""
        return self.joint.theta if self.joint is not None else {}


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
        """Growth [µm] with h = h_ref (ΔT/DT_REF_K)^exponent at every point of the surface.

        ΔT is the local lateral-surface temperature minus the ambient [K]: the law is
        applied point by point, as it holds physically (not to the surface's mean
        temperature); see :class:`arfem.models.diagnosis.local_convection.LocalConvectionRod`.

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
        return self._local.simulate(t, q, exponent, h_ref, DT_REF_K, ambient_K=ambient_K)

    @cached_property
    def _local(self):
        """The rod with pointwise convection, built on first use (only natural-convection
        candidates need it)."""
        from arfem.models.diagnosis.local_convection import LocalConvectionRod
        return LocalConvectionRod(self.m.fem, all_modes=self.m.all_modes)

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


def _nuisance(t, initial_known: bool, rate_1_s) -> list[np.ndarray]:
    """Columns for an unknown initial state: an offset and the slowest mode's decay
    (``rate_1_s`` [1/s] scalar, or per interval where h switches: exp(−Σ μ_i Δτ_i))."""
    if initial_known:
        return []
    t = np.asarray(t, float)
    if np.ndim(rate_1_s) == 0:
        return [np.ones_like(t), np.exp(-rate_1_s * t)]
    return [np.ones_like(t), np.exp(-np.cumsum(np.asarray(rate_1_s, float) * intervals(t)))]


#: causes that change the convection coefficient: at most one of them in a combination
H_CAUSES = ("convection_mismatch", "speed_dependent_convection", "nonlinear_convection")
#: the nonlinear parameters θ of each cause (searched), with their search bounds as
#: functions of the nominal h0; ln h is searched in [ln(h0/8), ln(8 h0)]
_THETA = {
    "convection_mismatch": ("log_h",),
    "speed_dependent_convection": ("log_h_running", "log_h_stopped"),
    "nonlinear_convection": ("exponent", "log_h_ref"),
    "frame_expansion": ("log_tau_h",),
}
#: finite-difference step of each θ for the Jacobian (the natural-convection steps are
#: those chosen when that model quantised ln h to 0.25 % steps; kept, as its optimum and
#: intervals are what the benchmark measured with them)
_FD_STEP = {"log_h": 1e-3, "log_h_running": 1e-3, "log_h_stopped": 1e-3, "exponent": 0.02,
            "log_h_ref": 0.02, "log_tau_h": 1e-3}


def compatible(causes) -> bool:
    """True if ``causes`` can be realised together (at most one h-changing cause).

    >>> compatible(("ambient_drift", "sensor_drift")), compatible(("convection_mismatch", "nonlinear_convection"))
    (True, False)
    """
    causes = tuple(causes)
    return (len(set(causes)) == len(causes) and "none" not in causes
            and sum(c in H_CAUSES for c in causes) <= 1)


def _bounds(name, h0):
    """The search range of θ coordinate ``name``; the exponent's and the frame's time
    constant's are the pipeline's (:data:`arfem.models.plant.BOUNDS`, one table)."""
    if name.startswith("log_h"):
        return np.log(h0 / 8), np.log(h0 * 8)
    if name == "exponent":
        return BOUNDS["exponent"]
    if name == "log_tau_h":
        lo, hi = BOUNDS["frame_time_constant_h"]
        return np.log(lo), np.log(hi)
    raise KeyError(name)


def _design(causes, phys, t, q, initial_known, ambient_K):
    """θ names and ``build(θ) -> (base, columns, column names)`` of a set of causes.

    The forward model of the combination: the h-changing cause (if any) sets the
    convection of the physics run; ``heat_input_scale`` turns that run into a column
    (its coefficient is the scale); ``ambient_drift``, ``sensor_drift`` and
    ``frame_expansion`` add columns; an unknown initial state adds the nuisance columns.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float)
    running = q > 0
    names = [n for c in causes for n in _THETA.get(c, ())]
    hc = next((c for c in causes if c in H_CAUSES), None)
    cache = {}

    def nominal():
        if "base0" not in cache:
            cache["base0"] = phys.response(t, q)
        return cache["base0"]

    def build(x):
        d = dict(zip(names, np.asarray(x, float)))
        h = None
        if hc is None:
            g, rate = nominal(), phys.slowest_rate()
        elif hc == "convection_mismatch":
            h = float(np.exp(d["log_h"]))
            g, rate = phys.response(t, q, h=h), phys.slowest_rate(h)
        elif hc == "speed_dependent_convection":
            hr, hs = float(np.exp(d["log_h_running"])), float(np.exp(d["log_h_stopped"]))
            h = np.where(running, hr, hs)
            # the initial state's slowest mode decays at the rate of the h in force
            rate = np.where(running, phys.slowest_rate(hr), phys.slowest_rate(hs))
            g = phys.response(t, q, h=h)
        else:
            href = float(np.exp(d["log_h_ref"]))
            g = phys.nonlinear(t, q, float(d["exponent"]), href)
            h, rate = href, phys.slowest_rate(href)
        cols, cn = [], []
        base = g
        if "heat_input_scale" in causes:
            cols.append(g)
            cn.append("scale")
            base = np.zeros_like(g)
        if "ambient_drift" in causes:
            key = ("amb", None if h is None else np.asarray(h).tobytes())
            if key not in cache:
                cache.clear() if len(cache) > 64 else None
                cache[key] = (phys.response(t, np.zeros_like(t), h=h, ambient_K=ambient_K)
                              / phys.ambient_gain_um_per_K())
            cols.append(cache[key])
            cn.append("ambient_gain_um_per_K")
        if "sensor_drift" in causes:
            cols.append(t / 3600.0)
            cn.append("drift_um_per_h")
        if "frame_expansion" in causes:
            # the frame is a slower body heated by the same source: its growth is a
            # first-order lag of the rod's steady growth target (q times the rod's
            # steady gain), so the coefficient is the frame's steady growth per unit of
            # rod growth
            tau_s = float(np.exp(d["log_tau_h"])) * 3600.0
            cols.append(first_order_lag(t, q * phys.steady_gain_um_per_W_m2(), tau_s))
            cn.append("frame_gain")
        nu = _nuisance(t, initial_known, rate)
        cols += nu
        cn += ["_initial_offset_um", "_initial_decay_um"][:len(nu)]
        return base, cols, cn

    return names, build


def _starts(causes, names, h0, start):
    """Starting points of the θ search: the given single-cause optima where known."""
    base = {"log_h": np.log(h0), "log_h_running": np.log(h0), "log_h_stopped": np.log(h0),
            "exponent": 0.25, "log_h_ref": np.log(h0), "log_tau_h": np.log(4.0)}
    base.update(start or {})
    x0 = [np.array([base[n] for n in names])]
    if "speed_dependent_convection" in causes and not start:
        for fr in (1.6, 1 / 1.5):
            v = dict(base, log_h_running=np.log(h0 * fr))
            x0.append(np.array([v[n] for n in names]))
    return x0


def fit_rod_causes(causes, phys, t, q, y, rows, initial_known: bool = True, ambient_K=None,
               frame_C=None, start: dict | None = None) -> CandidateFit | None:
    """Fit a set of causes together (``()`` = the baseline) by variable projection.

    Returns None if a cause does not apply to the record (``ambient_drift`` without
    ``ambient_C``; ``speed_dependent_convection`` when the input never or always runs)
    or the causes cannot act together (:func:`compatible`). The fit carries what its
    intervals need (:class:`JointFit`: θ, the linear coefficients and the Jacobian in
    all of them, for :func:`parameter_ci95`).

    Parameters
    ----------
    causes : tuple of str
        Causes of :data:`CAUSES` (not ``none``).
    phys : FemPhysics or ArPhysics
    t, q, y : ndarray
        Sample times [s], heat flux [W/m²], measured growth [µm] (NaN where not observed).
    rows : ndarray of bool
        Fit rows (before the hold-out, observed, not outliers).
    initial_known : bool
        False adds nuisance columns (offset, slowest-mode decay) to every candidate.
    ambient_K : ndarray, optional
        Recorded ambient minus the nominal ambient [K] (``ambient_drift`` needs it).
    frame_C : ndarray, optional
        Recorded frame temperature [°C] (reported only).
    start : dict, optional
        Starting θ values (e.g. the single-cause optima for a pair).
    """
    causes = tuple(c for c in causes if c != "none")
    t = np.asarray(t, float)
    q = np.asarray(q, float)
    if not _applies(causes, q, ambient_K):
        return None
    h0 = phys.rod.convection_W_m2K
    names, build = _design(causes, phys, t, q, initial_known, ambient_K)
    yr = np.where(rows, y, 0.0)

    def solve(x):
        base, cols, cn = build(x)
        coef, fit = project(cols, yr - base, rows) if cols else (np.zeros(0), np.zeros_like(y))
        pred = base + fit
        r = (y - pred)[rows]
        return float(r @ r), coef, pred, cols, cn

    lo = np.array([_bounds(n, h0)[0] for n in names])
    hi = np.array([_bounds(n, h0)[1] for n in names])
    x = _search_theta(solve, names, lo, hi, y, rows, _starts(causes, names, h0, start))
    rss, coef, pred, cols, cn = solve(x)
    theta = dict(zip(names, x.tolist()))
    lin = dict(zip(cn, coef.tolist()))
    at_bound = tuple(n for n, v, a, b in zip(names, x, lo, hi)
                     if min(v - a, b - v) < 1e-3 * (b - a))
    ambient = "ambient_drift" in causes
    joint = JointFit(
        theta, lin, tuple(names + cn) if causes else (),
        _jacobian(build, x, names, coef, pred, cols, rows) if causes else None,
        ambient_K if ambient else None,
        partial(_refit_linear, causes, phys, t, q, initial_known, yr, rows, x)
        if ambient else None,
        phys.ambient_gain_um_per_K() if ambient else None,
        _frame_sensor_note(causes, frame_C))
    tag = f"{phys.label}+" + "+".join(causes) if causes else phys.label
    k = len(names) + sum(not n.startswith("_") for n in cn)
    return CandidateFit("+".join(causes) or "none", tag, _physical(causes, theta, lin), pred,
                        k, rss, int(rows.sum()), causes=causes, at_bound=at_bound,
                        residual_um=(y - pred)[rows], fit_rows=rows, joint=joint)


def _applies(causes, q, ambient_K) -> bool:
    """Whether a set of causes can be fitted to the record: they can act together
    (:func:`compatible`), ``ambient_drift`` has a recorded ambient, and
    ``speed_dependent_convection`` an input that both runs and stops."""
    if causes and not compatible(causes):
        return False
    if "ambient_drift" in causes and ambient_K is None:
        return False
    if "speed_dependent_convection" in causes:
        running = q > 0
        if running.all() or not running.any():
            return False
    return True


def _search_theta(solve, names, lo, hi, y, rows, starts) -> np.ndarray:
    """The optimum of the nonlinear coordinates θ (variable projection: ``solve(θ)``
    gives the RSS with the linear coefficients solved): none to search, one by a
    bounded scalar search, more by Gauss-Newton (trust-region reflective) on the
    projected residual from each of ``starts``, with a forward-difference Jacobian of
    the steps of ``_FD_STEP``."""
    if not names:
        return np.zeros(0)
    if len(names) == 1:
        res = minimize_scalar(lambda v: solve([v])[0], bounds=(lo[0], hi[0]),
                              method="bounded", options={"xatol": 1e-4})
        return np.array([res.x])
    steps = np.array([_FD_STEP[n] for n in names])
    last = {}

    def resid(v):
        r = (y - solve(v)[2])[rows]
        last["x"], last["r"] = np.array(v, float), r
        return r

    def jac(v):
        r0 = last["r"] if "x" in last and np.array_equal(last["x"], v) else resid(v)
        v = np.array(v, float)
        J = np.empty((r0.size, v.size))
        for i in range(v.size):
            vi = v.copy()
            vi[i] += steps[i] if vi[i] + steps[i] <= hi[i] else -steps[i]
            J[:, i] = (resid(vi) - r0) / (vi[i] - v[i])
        return J

    best = None
    for x0 in starts:
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        r = least_squares(resid, x0, jac=jac, bounds=(lo, hi), method="trf",
                          x_scale=steps * 100, max_nfev=25 * len(names))
        if best is None or r.cost < best.cost:
            best = r
    return np.clip(best.x, lo, hi)


def _refit_linear(causes, phys, t, q, initial_known, yr, rows, x, ambient_K) -> dict:
    """The linear coefficients of a fit at the same θ ``x`` with another recorded
    ambient ``ambient_K`` [K] (``yr``: the growth on the fit rows, 0 elsewhere)."""
    _, build = _design(causes, phys, t, q, initial_known, ambient_K)
    base, cols, cn = build(x)
    coef, _ = project(cols, yr - base, rows)
    return dict(zip(cn, coef.tolist()))


def _frame_sensor_note(causes, frame_C) -> str | None:
    """Why a recorded frame temperature is not an input of ``frame_expansion``."""
    if "frame_expansion" in causes and frame_C is not None and np.all(np.isfinite(frame_C)):
        return ("T_frame_C recorded; the frame state is the lag of the rod's own growth, "
                "T_frame_C is reported in the cross-correlations")
    return None


def _jacobian(build, x, names, coef, pred, cols, rows):
    """∂prediction/∂(θ, c) on the fit rows: central differences in θ (the linear
    coefficients held), the columns themselves for c."""
    J = []
    for i, n in enumerate(names):
        step = _FD_STEP[n]
        out = []
        for sgn in (1.0, -1.0):
            xi = np.array(x, float)
            xi[i] += sgn * step
            b, c, _ = build(xi)
            out.append(b + (np.column_stack(c) @ coef if c else 0.0))
        J.append((out[0] - out[1]) / (2 * step))
    J += list(cols)
    return np.column_stack(J)[rows] if J else np.zeros((int(rows.sum()), 0))


def _physical(causes, theta, lin) -> dict:
    """The contract's parameter names from θ and the linear coefficients."""
    p = {}
    for c in causes:
        if c == "convection_mismatch":
            p["h_W_m2K"] = float(np.exp(theta["log_h"]))
        elif c == "speed_dependent_convection":
            p["h_running_W_m2K"] = float(np.exp(theta["log_h_running"]))
            p["h_stopped_W_m2K"] = float(np.exp(theta["log_h_stopped"]))
        elif c == "nonlinear_convection":
            p["exponent"] = float(theta["exponent"])
            p["h_at_10K_W_m2K"] = float(np.exp(theta["log_h_ref"]))
        elif c == "frame_expansion":
            p["frame_time_constant_h"] = float(np.exp(theta["log_tau_h"]))
            # the frame column is the lag of the *recorded* flux times the rod's nominal
            # steady gain; the contract's frame_gain is per unit of the rod's own growth,
            # which a heat scale multiplies: divide it out
            p["frame_gain"] = float(lin["frame_gain"] / lin.get("scale", 1.0))
        elif c == "heat_input_scale":
            p["scale"] = float(lin["scale"])
        elif c == "ambient_drift":
            p["ambient_gain_um_per_K"] = float(lin["ambient_gain_um_per_K"])
        elif c == "sensor_drift":
            p["drift_um_per_h"] = float(lin["drift_um_per_h"])
    return p


#: which (θ or linear) coordinate each physical parameter is, and whether it is ln(value)
_COORD = {"h_W_m2K": ("log_h", True), "h_running_W_m2K": ("log_h_running", True),
          "h_stopped_W_m2K": ("log_h_stopped", True), "exponent": ("exponent", False),
          "h_at_10K_W_m2K": ("log_h_ref", True), "frame_time_constant_h": ("log_tau_h", True),
          "frame_gain": ("frame_gain", False), "scale": ("scale", False),
          "ambient_gain_um_per_K": ("ambient_gain_um_per_K", False),
          "drift_um_per_h": ("drift_um_per_h", False)}


#: contiguous blocks of the fit window for the block-sandwich covariance: at most this
#: many, at least CI_MIN_BLOCKS, each at least CI_BLOCK_CORR residual correlation times long
CI_BLOCKS = 10
CI_MIN_BLOCKS = 4
CI_BLOCK_CORR = 5


#: draws of the recorded ambient's own noise propagated into the intervals
CI_AMBIENT_DRAWS = 8


def _ambient_noise_var(fit) -> dict:
    """Variance [unit²] of each linear coefficient caused by the noise of the recorded
    ambient, an input of the model (errors in the regressor): the ambient's noise σ is
    estimated from its second differences, the ambient is perturbed by that much again
    ``CI_AMBIENT_DRAWS`` times, and the coefficients refitted at the same θ."""
    from arfem.models.diagnosis import stats as st
    joint = fit.joint
    if joint is None or joint.refit_with_ambient is None or joint.ambient_K is None:
        return {}
    refit, amb = joint.refit_with_ambient, joint.ambient_K
    sig = st.noise_sigma(amb)
    if not np.isfinite(sig) or sig <= 0:
        return {}
    rng = np.random.default_rng(12345)
    draws = [refit(amb + rng.normal(0.0, sig, amb.size)) for _ in range(CI_AMBIENT_DRAWS)]
    return {k: float(np.var([d[k] for d in draws], ddof=1)) for k in draws[0]}


def parameter_ci95(fit: CandidateFit, y, rows) -> dict:
    """95 % intervals of a fit's physical parameters [their units].

    Three covariances of the nonlinear least-squares estimate, each respecting the
    residual's autocorrelation, and the widest interval of the three is reported:

    * effective sample size: s² (JᵀJ)⁻¹ · N/N_eff with s² = RSS/(N − p), J the Jacobian of
      the prediction in all p parameters on the N fit rows and N_eff the smaller of
      N(1 − ρ1)/(1 + ρ1) (the residual's lag-1 autocorrelation) and the batch-means N/τ,
      which sees slow wander (:func:`arfem.models.diagnosis.stats.noise_n_eff`);
      Student's t on N_eff − p degrees of freedom;
    * block sandwich (the linearised delete-a-block jackknife): (JᵀJ)⁻¹ [Σ_b g_b g_bᵀ]
      (JᵀJ)⁻¹ · B/(B − 1) with g_b = J_bᵀ r_b summed over B contiguous blocks of the fit
      window, each at least ``CI_BLOCK_CORR`` correlation times of the residual long (the
      lag where its autocorrelation falls below 1/e), 4 <= B <= 10; Student's t on B − 1
      degrees of freedom. Where the model
      fits some stretches of the record differently from others (model error, not
      noise) the block scores disagree and the interval widens accordingly;
    * fitted noise model (issue 24): the sandwich A JᵀΣJ A with Σ a slow + white noise
      fitted through the fit, so that the slow noise the fitted cause absorbed is
      counted (:func:`arfem.models.diagnosis.stats.slow_noise_sandwich`); the wider of
      its stationary AR(1) and random-walk forms; Student's t on N_eff − p degrees of
      freedom.

    Where the model takes a recorded ambient as input, the variance its sensor noise
    causes in the linear coefficients (:func:`_ambient_noise_var`) is added to each.
    A parameter that is a ratio of coordinates (``frame_gain`` beside a heat scale:
    frame coefficient / scale) gets the first-order (delta-method) variance of the ratio.

    References
    ----------
    Effective sample size of an AR(1) residual: Bretherton C. S. et al., "The effective
    number of spatial degrees of freedom of a time-varying field", J. Climate 12 (1999)
    1990-2009 (N_eff = N(1 − ρ1)/(1 + ρ1)). Block sandwich / delete-a-block jackknife:
    Künsch H. R., "The jackknife and the bootstrap for general stationary observations", Ann. Statist. 17
    (1989) 1217-1241; White H., "A heteroskedasticity-consistent covariance matrix
    estimator", Econometrica 48 (1980) 817-838. Delta method: Casella G., Berger R. L.,
    Statistical Inference, 2nd ed. (2002), sec. 5.5.4.
    Parameters searched as ln(value) (h, τ) get the interval of the logarithm,
    exponentiated (positive, asymmetric).
    """
    J = fit.joint.jacobian if fit.joint is not None else None
    if J is None or J.shape[1] == 0:
        return {}
    r = (np.asarray(y, float) - fit.prediction)[rows]
    cov = _covariances(J, r)
    idx = {nm: i for i, nm in enumerate(fit.joint.coordinates)}
    vals = {**fit.joint.theta, **fit.joint.linear}
    eiv = _ambient_noise_var(fit)
    out = {}
    for k in fit.parameters:
        coord, log = _COORD[k]
        lo, hi = _interval(cov, idx, vals, eiv, k, coord)
        out[k] = [float(np.exp(lo)), float(np.exp(hi))] if log else [float(lo), float(hi)]
    return out


@dataclass(frozen=True)
class _Covariances:
    """The three covariances of :func:`parameter_ci95`, each (p, p) in the fit's
    coordinates [coordinate unit²], with their Student-t quantiles [-]."""

    ess: np.ndarray
    block: np.ndarray
    slow_ar1: np.ndarray
    slow_walk: np.ndarray
    t_ess: float
    t_block: float


def _covariances(J, r) -> _Covariances:
    """Effective-sample-size, block-sandwich and fitted-noise-model covariances of the
    estimate with Jacobian ``J`` (n, p) and residual ``r`` (n,) on the fit rows (see
    :func:`parameter_ci95`)."""
    from arfem.models.diagnosis import stats as st
    from scipy import stats as _sst
    n, p = J.shape
    n_eff = st.noise_n_eff(r)
    s2 = float(r @ r) / max(n - p, 1)
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    Js = J / scale
    A = np.linalg.pinv(Js.T @ Js)
    cov_ess = A / np.outer(scale, scale) * s2 * (n / n_eff)
    B = st.contiguous_blocks(r, CI_BLOCK_CORR, CI_MIN_BLOCKS, CI_BLOCKS)
    G = np.array([Js[ix].T @ r[ix] for ix in np.array_split(np.arange(n), B)])
    cov_blk = (A @ (G.T @ G) @ A) / np.outer(scale, scale) * B / (B - 1.0)
    # slow + white noise fitted through the fit, as a stationary AR(1) and as a random
    # walk: each parameter gets the wider of the two (stats.slow_noise_sandwich)
    slow = st.slow_noise_sandwich(Js, r)
    zero = np.zeros((p, p))
    cov_ar = (slow.ar1_cov if slow else zero) / np.outer(scale, scale)
    cov_walk = (slow.walk_cov if slow else zero) / np.outer(scale, scale)
    return _Covariances(cov_ess, cov_blk, cov_ar, cov_walk,
                        float(_sst.t.ppf(0.975, max(n_eff - p, 1.0))),
                        float(_sst.t.ppf(0.975, B - 1)))


def _interval(cov: _Covariances, idx, vals, eiv, k, coord) -> tuple[float, float]:
    """The 95 % interval of parameter ``k`` in its searched coordinate ``coord`` (ln of
    the value where it is searched so): the estimate ± the widest half-width of the
    three covariances, each with the ambient's noise variance ``eiv`` added; a
    ``frame_gain`` beside a heat scale by the delta method on the ratio."""
    i = idx[coord]
    add = eiv.get(coord, 0.0)
    v = vals[coord]
    if k == "frame_gain" and "scale" in idx:
        # frame_gain = c_frame / scale (see _physical): delta method on the pair
        w = np.zeros(cov.ess.shape[0])
        s_ = vals["scale"]
        w[i], w[idx["scale"]] = 1.0 / s_, -v / s_ ** 2
        var_e, var_b = float(w @ cov.ess @ w), float(w @ cov.block @ w)
        var_a = max(float(w @ cov.slow_ar1 @ w), float(w @ cov.slow_walk @ w))
        add = add / s_ ** 2 + eiv.get("scale", 0.0) * v ** 2 / s_ ** 4
        v = v / s_
    else:
        var_e, var_b = cov.ess[i, i], cov.block[i, i]
        var_a = max(cov.slow_ar1[i, i], cov.slow_walk[i, i])
    h_e = cov.t_ess * np.sqrt(max(var_e, 0.0) + add)
    h_b = cov.t_block * np.sqrt(max(var_b, 0.0) + add)
    h_a = cov.t_ess * np.sqrt(max(var_a, 0.0) + add)
    half = max(h_e, h_b, h_a)
    return v - half, v + half


def fit_candidate(cause: str, phys, t, q, y, rows, initial_known: bool = True,
                  ambient_K=None, frame_C=None) -> CandidateFit | None:
    """Fit one cause (``none`` = the baseline) -- :func:`fit_rod_causes` of one cause."""
    if cause not in CAUSES:
        raise ValueError(f"unknown cause {cause!r}")
    return fit_rod_causes(() if cause == "none" else (cause,), phys, t, q, y, rows, initial_known,
                      ambient_K, frame_C)
