"""The AR(1) side for records that give only the spindle speed (no heat flux, no geometry).

* :func:`paper_ar` -- the seed paper's AR(1) calibrated by least squares on one-step
  prediction (paper eq. 17): ΔL_n = C1 ΔL_{n−1} + C2(speed_n), one C2 per speed seen
  before the hold-out; C2 of a speed not seen is mapped from the ratio of early
  temperature rises (paper eqs. 20-21, :func:`speed_to_heat_map`).
* :func:`fit_speed_candidate` -- the same AR(1) extended by one cause, fitted by
  output error (free-run simulation) on the rows before the hold-out.
* :func:`mlr` -- multiple linear regression of growth on the temperatures (paper eq. 18).

Speed-to-heat mapping (what is done, eqs. 20-21): the heat input of a speed is judged
from how fast the temperatures rise just after the spindle steps to it; the early rise
r(s) of a sensor is its mean increase over the first 10 min after every step into speed
s. A sensor is usable only if r(s) is positive and strictly increasing over the non-zero
speeds seen before the hold-out (the premise of eqs. 20-21); among usable sensors the one
with the largest corr(s, r)·min r is taken. For a speed s not seen before the hold-out
the steady gain is K(s) = K(0) + (K(s_ref) − K(0))·r(s)/r(s_ref), s_ref the nearest seen
non-zero speed. Without a usable sensor, r(s) ∝ s (heat proportional to speed).

Speed-only records with thermometers also get
:func:`arfem.models.diagnosis.speed_frame.fit_frame_thermometers` as their
``frame_expansion`` candidate, its structure chosen by forward-chaining validation
(:mod:`arfem.models.diagnosis.speed_select`) among the structures of
:func:`arfem.models.diagnosis.speed_frame.frame_structures`:
thermometer components and their lag, the speed-to-heat law (per-speed gains with the
eqs. 20-21 mapping, or heat ∝ n^p, zero at rest, p in :data:`HEAT_EXPONENTS`) and a
frame that also follows the spindle heat with its own slow time constant. With
``search="average"`` (added post hoc, after the rolling-origin evaluation of the real
record) no structure is chosen: the candidate is the equal-weight average of every
"narrow" structure (:class:`arfem.models.diagnosis.speed_frame.FrameEnsemble`).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from arfem.models.ar1 import eq17_least_squares
from arfem.models.diagnosis.candidates import CandidateFit, project
from arfem.models.diagnosis.forward import (ar_columns_rates, ar_first_order, first_order_lag,
                                            intervals)

__all__ = ["speed_to_heat_map", "level_inputs", "paper_ar", "fit_speed_candidate", "mlr",
           "SPEED_CAUSES"]

#: causes identifiable for a calibrated AR(1) (h and heat scale are absorbed by C1, C2)
SPEED_CAUSES = ("none", "ambient_drift", "speed_dependent_convection", "frame_expansion",
                "sensor_drift")


def speed_to_heat_map(t, speed, temperatures: dict, rows, window_s: float = 600.0):
    """Early-rise mapping (paper eqs. 20-21): weights W with K(unseen) = Σ_s W[u][s] K(s).

    Parameters
    ----------
    t : array_like
        Sample times [s].
    speed : array_like
        Spindle speed on each row [1/min].
    temperatures : dict
        Sensor name -> temperature series [°C].
    rows : ndarray of bool
        Fit rows (before the hold-out); define the seen speeds and usable sensors.
    window_s : float
        Early-rise window after a speed step [s].

    Returns
    -------
    levels : ndarray
        Every speed in the record [1/min].
    seen : ndarray
        Speeds present in ``rows`` [1/min].
    W : dict
        Unseen speed [1/min] -> {seen speed [1/min]: weight [-]}.
    info : dict
        ``unseen_rpm``, ``sensor`` (chosen sensor or None), ``early_rise_K``
        ({speed [1/min]: early rise [K]}), ``sensors_rejected`` and ``mapping``
        (reference speed, ratio and how, per unseen speed).

    References
    ----------
    Du et al., J. Harbin Inst. Technol. 53(7), 2021, eqs. 20-21.
    """
    t = np.asarray(t, float)
    speed = np.asarray(speed, float)
    levels = np.unique(speed)
    seen = np.unique(speed[rows])
    unseen = [u for u in levels if u not in seen]
    info: dict = {"unseen_rpm": [float(u) for u in unseen]}
    best, rise, rejected = _speed_following_sensor(t, speed, levels, seen, temperatures,
                                                   rows, window_s)
    info.update(sensor=best, early_rise_K=rise, sensors_rejected=sorted(rejected))
    W = {}
    for u in unseen:
        nz = [s for s in seen if s != 0]
        if not nz:
            W[float(u)] = {float(s): 1.0 / len(seen) for s in seen}
            continue
        ref = min(nz, key=lambda s: abs(s - u))
        r_u, r_ref = rise.get(float(u)), rise.get(float(ref))
        if r_u is not None and r_ref not in (None, 0.0):
            ratio, how = r_u / r_ref, "early temperature rise"
        else:
            ratio, how = u / ref, "speed ratio (no usable temperature rise)"
        w = {float(ref): ratio}
        if 0.0 in seen:
            w[0.0] = 1.0 - ratio
        W[float(u)] = w
        info.setdefault("mapping", {})[str(float(u))] = {"ref_rpm": float(ref), "ratio": ratio,
                                                          "how": how}
    return levels, seen, W, info


def _early_rise(t, speed, levels, T, window_s) -> dict:
    """Speed [1/min] -> mean rise [K] of ``T`` within ``window_s`` [s] after each step to
    that speed (steps whose speed holds over the window only)."""
    steps = np.flatnonzero(np.diff(speed) != 0) + 1
    out = {}
    for lv in levels:
        vals = []
        for i in steps:
            if speed[i] != lv:
                continue
            j = np.searchsorted(t, t[i - 1] + window_s)
            if j < t.size and np.all(speed[i:j + 1] == lv):
                vals.append(T[j] - T[i - 1])
        if vals:
            out[float(lv)] = float(np.mean(vals))
    return out


def _speed_following_sensor(t, speed, levels, seen, temperatures, rows, window_s):
    """The sensor whose early rise follows the speed best: eqs. 20-21 assume the early
    rise grows with the heat, so a sensor is usable only if its early rise is positive
    and strictly increasing with speed over the non-zero speeds seen before the hold-out
    (checked on fit rows); of those, the largest |correlation| x smallest rise. Returns
    (its name or None, its early rises {speed [1/min]: rise [K]}, {rejected: why})."""
    best, best_c, rise = None, 0.0, {}
    rejected = {}
    nz_seen = sorted(float(s) for s in seen if s != 0)
    for name, T in temperatures.items():
        T = np.asarray(T, float)
        if not np.all(np.isfinite(T[rows])):
            continue
        r = _early_rise(t, speed, levels, T, window_s)
        rs = [r.get(s) for s in nz_seen]
        if len(nz_seen) < 2 or any(v is None for v in rs):
            continue
        if not (rs[0] > 0 and np.all(np.diff(rs) > 0)):
            rejected[name] = "early rise not positive and increasing with speed"
            continue
        c = abs(np.corrcoef(nz_seen, rs)[0, 1]) * min(rs)
        if np.isfinite(c) and c > best_c:
            best, best_c, rise = name, float(c), r
    return best, rise, rejected


def level_inputs(speed, seen, W):
    """Unit inputs per seen level {seen speed [1/min]: (N,) [-]}, with unseen levels
    folded in by the mapping weights ``W`` of :func:`speed_to_heat_map` (a weight on a
    level not in ``seen`` is dropped: that level has no gain)."""
    speed = np.asarray(speed, float)
    cols = {}
    for s in seen:
        u = (speed == s).astype(float)
        for lv, w in W.items():
            if s in w:
                u = u + w[s] * (speed == lv)
        cols[float(s)] = u
    return cols


def paper_ar(t, y, speed, rows, W, seen):
    """Paper eq. 17 calibration on one-step pairs before the hold-out, then free run.

    Parameters
    ----------
    t : array_like
        Sample times [s]; Δτ is the median step, and only pairs one Δτ apart are fitted.
    y : array_like
        Measured growth [µm].
    speed : array_like
        Spindle speed on each row [1/min].
    rows : ndarray of bool
        Fit rows (before the hold-out, not outliers).
    W : dict
        Unseen-speed mapping of :func:`speed_to_heat_map`.
    seen : array_like
        Speeds seen in ``rows`` [1/min]; one C2 each.

    Returns
    -------
    prediction : ndarray
        Free-run growth over the whole record from y[0] [µm].
    coefficients : dict
        ``C1`` [-], ``C2_um`` ({speed [1/min]: C2 [µm]}), ``dtau_s`` [s] and
        ``C2_mapped_um`` (C2 of the unseen speeds by eqs. 20-21 [µm]).

    References
    ----------
    Du et al., J. Harbin Inst. Technol. 53(7), 2021, eqs. 12, 17, 20-21.
    """
    t, y, speed = (np.asarray(a, float) for a in (t, y, speed))
    d = intervals(t)
    dtau = float(np.median(d[1:])) if t.size > 1 else 1.0
    pair = np.zeros(t.size, bool)
    pair[1:] = rows[1:] & rows[:-1] & np.isclose(d[1:], dtau)
    p = pair[1:]
    fit = eq17_least_squares(y[:-1][p], y[1:][p], speed[1:][p], seen)
    c1 = float(np.clip(fit.c1, 1e-6, 1 - 1e-9))
    c2 = fit.c2
    b = -np.log(c1) / dtau
    K = {s: c / (1 - c1) for s, c in c2.items()}
    for lv, w in W.items():
        K[lv] = sum(wt * K[s] for s, wt in w.items())
    u = np.array([K[float(s)] for s in speed])
    pred = ar_first_order(t, u, b, 1.0, x0=y[0])
    return pred, {"C1": c1, "C2_um": c2, "dtau_s": dtau,
                  "C2_mapped_um": {lv: K[lv] * (1 - c1) for lv in W}}


def fit_speed_candidate(cause, t, y, speed, rows, seen, W, ambient_K=None,
                        rho_c_R=None) -> CandidateFit | None:
    """AR(1) extended by ``cause``, output-error least squares on ``rows``.

    Gains per seen speed enter linearly; b (and the cause's own nonlinear parameters)
    are searched. ``rho_c_R`` [J/(m²K)] turns rates b into an equivalent h = bρcR/2.

    Parameters
    ----------
    cause : str
        One of :data:`SPEED_CAUSES`.
    t : array_like
        Sample times [s].
    y : array_like
        Measured growth [µm].
    speed : array_like
        Spindle speed on each row [1/min].
    rows : ndarray of bool
        Fit rows (before the hold-out, not outliers).
    seen : array_like
        Speeds seen in ``rows`` [1/min]; one steady gain each.
    W : dict
        Unseen-speed mapping of :func:`speed_to_heat_map`.
    ambient_K : array_like, optional
        Recorded ambient minus the nominal ambient [K] (``ambient_drift`` needs it).
    rho_c_R : float, optional
        ρcR [J/(m²·K)] of the rod, to report h [W/(m²·K)] for
        ``speed_dependent_convection``.

    Returns
    -------
    CandidateFit or None
        Prediction [µm] over the record; parameters in the units their names carry
        (``drift_um_per_h`` [µm/h], ``ambient_gain_um_per_K`` [µm/K], ``b_*_1_s``
        [1/s], ``h_*_W_m2K`` [W/(m²·K)], ``frame_time_constant_h`` [h],
        ``frame_gain`` [-]); ``time_constant_h`` = 1/b [h]. None if the
        cause does not apply to this record.
    """
    t, y, speed = (np.asarray(a, float) for a in (t, y, speed))
    pb = _SpeedProblem(t, y, rows, level_inputs(speed, seen, W),
                       "ar" if cause == "none" else f"ar+{cause}")
    if cause in ("none", "sensor_drift"):
        return _fit_rate(pb, cause, [t / 3600.0] if cause == "sensor_drift" else [])
    if cause == "ambient_drift":
        return None if ambient_K is None else _fit_ambient(pb, ambient_K)
    if cause == "speed_dependent_convection":
        running = speed > 0
        if running.all() or not running.any():
            return None
        return _fit_running_stopped(pb, running, rho_c_R)
    if cause == "frame_expansion":
        return _fit_frame_lag(pb)
    return None


#: search range of ln b [ln(1/s)]: time constants 1 min .. 200 h
_LOG_RATE_BOUNDS = (np.log(1 / (200 * 3600.0)), np.log(1 / 60.0))


def _search1(fun, lo, hi):
    """The minimum of ``fun`` on [lo, hi]: a 13-point grid, then a bounded search
    between the best point's neighbours."""
    grid = np.linspace(lo, hi, 13)
    vals = [fun(g) for g in grid]
    i = int(np.argmin(vals))
    res = minimize_scalar(fun, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, 12)]),
                          method="bounded", options={"xatol": 1e-4})
    return res.x


class _SpeedProblem:
    """The output-error AR(1) of a speed record: the columns of a rate b, their least
    squares on the fit rows, and the fit made of them (:func:`fit_speed_candidate`).

    ``t`` [s], ``y`` [µm] and ``rows`` (bool) of shape (N,); ``units`` the unit input of
    each speed level (:func:`level_inputs`); ``tag`` the model's name."""

    def __init__(self, t, y, rows, units: dict, tag: str):
        self.t, self.y, self.rows, self.units, self.tag = t, y, rows, units, tag
        self.d = intervals(t)

    def columns(self, b):
        """One AR(1) column per level at rate(s) b [1/s] and the unknown initial state's
        decay."""
        t = self.t
        b_arr = np.broadcast_to(b, t.shape)
        # one pass for every level (they share the rate): the same numbers as one
        # ar_first_order(t, u / b, b, 1.0) per level
        U = np.column_stack([u / b_arr for u in self.units.values()])
        cols = list(ar_columns_rates(t, U, b_arr).T)
        cols.append(np.exp(-np.cumsum(b_arr * self.d)))   # unknown initial state
        return cols

    def solve(self, cols):
        """(RSS [µm²], coefficients, prediction [µm]) of the least squares on ``cols``."""
        coef, pred = project(cols, self.y, self.rows)
        r = (self.y - pred)[self.rows]
        return float(r @ r), coef, pred

    def fit(self, cause, params, pred, k, rss, **detail) -> CandidateFit:
        """The :class:`CandidateFit` of ``cause`` with its residual on the fit rows."""
        rows = self.rows
        return CandidateFit(cause, self.tag, params, pred, k, rss, int(rows.sum()),
                            residual_um=(self.y - pred)[rows], fit_rows=rows, **detail)


def _fit_rate(pb: _SpeedProblem, cause, extra_cols) -> CandidateFit:
    """The AR(1) alone (``none``) or with a drift column in time (``sensor_drift``): b
    searched, the gains (and the drift [µm/h]) linear."""
    lb = _LOG_RATE_BOUNDS
    xb = _search1(lambda x: pb.solve(pb.columns(np.exp(x)) + extra_cols)[0], *lb)
    rss, coef, pred = pb.solve(pb.columns(np.exp(xb)) + extra_cols)
    params = {} if cause == "none" else {"drift_um_per_h": float(coef[-1])}
    return pb.fit(cause, params, pred, len(extra_cols), rss,
                  time_constant_h=float(np.exp(-xb) / 3600))


def _fit_ambient(pb: _SpeedProblem, ambient_K) -> CandidateFit:
    """``ambient_drift``: the AR(1) plus the recorded ambient [K] through the same AR(1),
    its gain [µm/K] linear."""
    def cols_amb(b):
        return pb.columns(b) + [ar_first_order(pb.t, ambient_K, b, 1.0)]
    xb = _search1(lambda x: pb.solve(cols_amb(np.exp(x)))[0], *_LOG_RATE_BOUNDS)
    rss, coef, pred = pb.solve(cols_amb(np.exp(xb)))
    return pb.fit("ambient_drift", {"ambient_gain_um_per_K": float(coef[-1])}, pred, 1, rss,
                  time_constant_h=float(np.exp(-xb) / 3600))


def _fit_running_stopped(pb: _SpeedProblem, running, rho_c_R) -> CandidateFit:
    """``speed_dependent_convection``: one rate while the spindle runs and one while it
    stands (Nelder-Mead from the single rate's optimum); with ``rho_c_R`` [J/(m²K)] also
    as h = bρcR/2 [W/(m²K)]."""
    lb = _LOG_RATE_BOUNDS
    x0 = _search1(lambda x: pb.solve(pb.columns(np.exp(x)))[0], *lb)

    def f(x):
        x = np.clip(x, *lb)
        return pb.solve(pb.columns(np.where(running, np.exp(x[0]), np.exp(x[1]))))[0]
    res = minimize(f, np.array([x0, x0]), method="Nelder-Mead",
                   options={"xatol": 1e-4, "fatol": 1e-12, "maxiter": 300})
    x = np.clip(res.x, *lb)
    rss, coef, pred = pb.solve(pb.columns(np.where(running, np.exp(x[0]), np.exp(x[1]))))
    params = {"b_running_1_s": float(np.exp(x[0])), "b_stopped_1_s": float(np.exp(x[1]))}
    if rho_c_R:
        params = {"h_running_W_m2K": float(np.exp(x[0]) * rho_c_R / 2),
                  "h_stopped_W_m2K": float(np.exp(x[1]) * rho_c_R / 2), **params}
    return pb.fit("speed_dependent_convection", params, pred, 1, rss,
                  note="h from b = 2h/(ρcR) with the [rod] values")


def _fit_frame_lag(pb: _SpeedProblem) -> CandidateFit:
    """``frame_expansion`` without thermometers: each level's rod column plus G times its
    first-order lag at τ in [2, 200] h; b, τ and G searched (Nelder-Mead from six
    starts), the gains linear."""
    lb = _LOG_RATE_BOUNDS
    t = pb.t
    x0 = _search1(lambda x: pb.solve(pb.columns(np.exp(x)))[0], *lb)

    def build(x):
        # G: the frame's steady growth per unit of the rod's [-] (a level's rod column
        # settles at u/b, its frame column at G u/b)
        b, tau_s, G = np.exp(x[0]), np.exp(x[1]) * 3600.0, x[2]
        base = pb.columns(b)
        cols = [c + (G / b) * first_order_lag(t, u, tau_s)
                for c, u in zip(base[:-1], pb.units.values())]
        return cols + [base[-1]]

    def clipped(x):
        return np.array([np.clip(x[0], *lb), np.clip(x[1], np.log(2), np.log(200)), x[2]])

    best = None
    for tau0 in (3.0, 10.0, 30.0):
        for G0 in (-1.0, 1.0):
            r = minimize(lambda x: pb.solve(build(clipped(x)))[0],
                         np.array([x0, np.log(tau0), G0]), method="Nelder-Mead",
                         options={"xatol": 1e-4, "fatol": 1e-12, "maxiter": 400})
            if best is None or r.fun < best.fun:
                best = r
    x = clipped(best.x)
    rss, coef, pred = pb.solve(build(x))
    return pb.fit("frame_expansion", {"frame_time_constant_h": float(np.exp(x[1])),
                                      "frame_gain": float(x[2])}, pred, 2, rss,
                  time_constant_h=float(np.exp(-x[0]) / 3600))


def mlr(y, temperatures: dict, rows):
    """Multiple linear regression of growth on every complete temperature (paper eq. 18).

    Parameters
    ----------
    y : array_like
        Measured growth [µm].
    temperatures : dict
        Sensor name -> temperature series [°C]; series with a non-finite value are skipped.
    rows : ndarray of bool
        Fit rows.

    Returns
    -------
    prediction : ndarray or None
        Offset + Σ coefficient [µm/K] × temperature [°C] over the record [µm];
        None without a complete sensor.
    names : list of str
        Sensors used.

    References
    ----------
    Du et al., J. Harbin Inst. Technol. 53(7), 2021, eq. 18.
    """
    names = [k for k, v in temperatures.items() if np.all(np.isfinite(np.asarray(v, float)))]
    if not names:
        return None, []
    X = [np.ones_like(y)] + [np.asarray(temperatures[k], float) for k in names]
    coef, pred = project(X, np.asarray(y, float), rows)
    return pred, names


