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

Speed-only records with thermometers also get :func:`fit_frame_thermometers` as their
``frame_expansion`` candidate, its structure chosen by forward-chaining validation
(:func:`forward_folds`, :func:`select_frame_structure`) among :func:`frame_structures`:
thermometer components and their lag, the speed-to-heat law (per-speed gains with the
eqs. 20-21 mapping, or heat ∝ n^p, zero at rest, p in :data:`HEAT_EXPONENTS`) and a
frame that also follows the spindle heat with its own slow time constant. With
``search="average"`` (added post hoc, after the rolling-origin evaluation of the real
record) no structure is chosen: the candidate is the equal-weight average of every
"narrow" structure (:class:`FrameEnsemble`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from arfem.models.diagnosis.candidates import CandidateFit, project
from arfem.models.diagnosis.forward import ar_columns, ar_first_order, first_order_lag, intervals

__all__ = ["speed_to_heat_map", "paper_ar", "fit_speed_candidate", "mlr", "SPEED_CAUSES",
           "FrameStructure", "FrameEnsemble", "frame_structures", "heat_law", "fit_frame_thermometers",
           "select_frame_structure", "forward_folds", "cv_rmse", "median_block_ratio",
           "drift_last", "INPUT_FREE_CAUSES"]

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
    # the speed-following sensor: eq. 20-21 assume the early rise grows with the heat,
    # so a sensor is usable only if its early rise is positive and strictly increasing
    # with speed over the non-zero speeds seen before the hold-out (checked on fit rows)
    steps = np.flatnonzero(np.diff(speed) != 0) + 1

    def early_rise(T):
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

    best, best_c, rise = None, 0.0, {}
    rejected = {}
    nz_seen = sorted(float(s) for s in seen if s != 0)
    for name, T in temperatures.items():
        T = np.asarray(T, float)
        if not np.all(np.isfinite(T[rows])):
            continue
        r = early_rise(T)
        rs = [r.get(s) for s in nz_seen]
        if len(nz_seen) < 2 or any(v is None for v in rs):
            continue
        if not (rs[0] > 0 and np.all(np.diff(rs) > 0)):
            rejected[name] = "early rise not positive and increasing with speed"
            continue
        c = abs(np.corrcoef(nz_seen, rs)[0, 1]) * min(rs)
        if np.isfinite(c) and c > best_c:
            best, best_c, rise = name, float(c), r
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


def _level_inputs(speed, seen, W):
    """Unit inputs per seen level, with unseen levels folded in by the mapping weights."""
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
    X = np.column_stack([y[:-1]] + [(speed[1:] == s).astype(float) for s in seen])
    coef, *_ = np.linalg.lstsq(X[pair[1:]], y[1:][pair[1:]], rcond=None)
    c1 = float(np.clip(coef[0], 1e-6, 1 - 1e-9))
    c2 = {float(s): float(c) for s, c in zip(seen, coef[1:])}
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
        ``frame_gain`` [-]); ``extra["time_constant_h"]`` = 1/b [h]. None if the
        cause does not apply to this record.
    """
    t, y, speed = (np.asarray(a, float) for a in (t, y, speed))
    units = _level_inputs(speed, seen, W)
    running = speed > 0
    tag = "ar" if cause == "none" else f"ar+{cause}"

    def columns(b):
        b_arr = np.broadcast_to(b, t.shape)
        cols = [ar_first_order(t, u / b_arr, b_arr, 1.0) for u in units.values()]
        cols.append(np.exp(-np.cumsum(b_arr * intervals(t))))   # unknown initial state
        return cols

    def solve(cols):
        coef, pred = project(cols, y, rows)
        r = (y - pred)[rows]
        return float(r @ r), coef, pred

    def search1(fun, lo, hi):
        grid = np.linspace(lo, hi, 13)
        vals = [fun(g) for g in grid]
        i = int(np.argmin(vals))
        res = minimize_scalar(fun, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, 12)]),
                              method="bounded", options={"xatol": 1e-4})
        return res.x

    lb = (np.log(1 / (200 * 3600.0)), np.log(1 / 60.0))   # time constants 1 min .. 200 h
    extra_cols = []
    if cause == "sensor_drift":
        extra_cols = [t / 3600.0]
    elif cause == "ambient_drift":
        if ambient_K is None:
            return None
    if cause in ("none", "sensor_drift"):
        xb = search1(lambda x: solve(columns(np.exp(x)) + extra_cols)[0], *lb)
        rss, coef, pred = solve(columns(np.exp(xb)) + extra_cols)
        params = {} if cause == "none" else {"drift_um_per_h": float(coef[-1])}
        return CandidateFit(cause, tag, params, pred, len(extra_cols), rss, int(rows.sum()),
                            {"time_constant_h": float(np.exp(-xb) / 3600)})
    if cause == "ambient_drift":
        def cols_amb(b):
            return columns(b) + [ar_first_order(t, ambient_K, b, 1.0)]
        xb = search1(lambda x: solve(cols_amb(np.exp(x)))[0], *lb)
        rss, coef, pred = solve(cols_amb(np.exp(xb)))
        return CandidateFit(cause, tag, {"ambient_gain_um_per_K": float(coef[-1])}, pred, 1,
                            rss, int(rows.sum()), {"time_constant_h": float(np.exp(-xb) / 3600)})
    if cause == "speed_dependent_convection":
        if running.all() or not running.any():
            return None
        x0 = search1(lambda x: solve(columns(np.exp(x)))[0], *lb)

        def f(x):
            x = np.clip(x, *lb)
            return solve(columns(np.where(running, np.exp(x[0]), np.exp(x[1]))))[0]
        res = minimize(f, np.array([x0, x0]), method="Nelder-Mead",
                       options={"xatol": 1e-4, "fatol": 1e-12, "maxiter": 300})
        x = np.clip(res.x, *lb)
        rss, coef, pred = solve(columns(np.where(running, np.exp(x[0]), np.exp(x[1]))))
        params = {"b_running_1_s": float(np.exp(x[0])), "b_stopped_1_s": float(np.exp(x[1]))}
        if rho_c_R:
            params = {"h_running_W_m2K": float(np.exp(x[0]) * rho_c_R / 2),
                      "h_stopped_W_m2K": float(np.exp(x[1]) * rho_c_R / 2), **params}
        return CandidateFit(cause, tag, params, pred, 1, rss, int(rows.sum()),
                            {"note": "h from b = 2h/(ρcR) with the [rod] values"})
    if cause == "frame_expansion":
        x0 = search1(lambda x: solve(columns(np.exp(x)))[0], *lb)

        def build(x):
            # G: the frame's steady growth per unit of the rod's [-] (a level's rod column
            # settles at u/b, its frame column at G u/b)
            b, tau_s, G = np.exp(x[0]), np.exp(x[1]) * 3600.0, x[2]
            base = columns(b)
            cols = [c + (G / b) * first_order_lag(t, u, tau_s)
                    for c, u in zip(base[:-1], units.values())]
            return cols + [base[-1]]

        best = None
        for tau0 in (3.0, 10.0, 30.0):
            for G0 in (-1.0, 1.0):
                def f(x):
                    x = np.array([np.clip(x[0], *lb), np.clip(x[1], np.log(2), np.log(200)), x[2]])
                    return solve(build(x))[0]
                r = minimize(f, np.array([x0, np.log(tau0), G0]), method="Nelder-Mead",
                             options={"xatol": 1e-4, "fatol": 1e-12, "maxiter": 400})
                if best is None or r.fun < best.fun:
                    best = r
        x = np.array([np.clip(best.x[0], *lb), np.clip(best.x[1], np.log(2), np.log(200)),
                      best.x[2]])
        rss, coef, pred = solve(build(x))
        return CandidateFit(cause, tag, {"frame_time_constant_h": float(np.exp(x[1])),
                                         "frame_gain": float(x[2])}, pred, 2, rss,
                            int(rows.sum()), {"time_constant_h": float(np.exp(-x[0]) / 3600)})
    return None


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


#: structures tried for the frame: number of principal components of the temperature
#: changes (0: none), the extra first-order lag [h] between them and the frame, the
#: speed-to-heat law (None: one gain per seen speed, unseen speeds by eqs. 20-21; p: heat
#: ∝ (n/n_ref)^p, zero at rest) and whether the frame also responds to the spindle heat
#: with its own slower time constant (>= 2 h, the contract's frame_expansion)
FRAME_COMPONENTS = (0, 1, 2, 3, 4, 6, 8)
FRAME_LAGS_H = (0.0, 0.5, 2.0)
HEAT_EXPONENTS = (None, 1.0, 4.0 / 3.0, 5.0 / 3.0, 2.0)
SLOW_TAU_H = (2.0, 200.0)


@dataclass(frozen=True)
class FrameStructure:
    """One structure of the frame model (see :func:`fit_frame_thermometers`).

    Attributes
    ----------
    components : int
        Principal components of the standardised temperatures [-] (0: no thermometers).
    sensor_lag_h : float
        First-order lag of the frame behind the thermometers [h].
    heat_exponent : float or None
        p of the heat law (n/n_ref)^p [-]; None: one steady gain per seen speed.
    slow_lag : bool
        The frame also follows the spindle heat with its own time constant (>= 2 h).
    """
    components: int
    sensor_lag_h: float = 0.0
    heat_exponent: float | None = None
    slow_lag: bool = False

    @property
    def label(self) -> str:
        heat = "per-speed gains" if self.heat_exponent is None else f"n^{self.heat_exponent:.3g}"
        return (f"k={self.components},lag={self.sensor_lag_h:g}h,heat={heat},"
                f"slow={'yes' if self.slow_lag else 'no'}")


#: structure searches: "narrow" -- thermometer components and their lag only, per-speed
#: gains, no slow response (the procedure fixed before the real record's hold-out was
#: first scored); "wide" -- also the heat laws and the slow frame response; "average" --
#: no search: the equal-weight average of every "narrow" structure (:class:`FrameEnsemble`,
#: added post hoc, after the rolling-origin scores of "narrow" on the real record)
FRAME_SEARCHES = ("narrow", "wide", "average")


@dataclass(frozen=True)
class FrameEnsemble:
    """The equal-weight average of several frame structures' predictions.

    Picking one structure by forward-chaining validation over three or four blocks chose
    among validation errors that differ by a factor 5 between neighbouring structures
    (real record, README of reports/fl_thermal): the choice was mostly noise, and the
    hold-out error of the pick varied accordingly. Averaging the structures' predictions
    with fixed, equal weights involves no choice made on the data, and a mean of
    predictors whose errors are not perfectly correlated has a smaller error than their
    average error (Jensen), which is what a selection could not guarantee.

    Attributes
    ----------
    members : tuple of FrameStructure
        The structures averaged.
    """
    members: tuple

    @property
    def components(self) -> list:
        """Numbers of principal components of the members [-]."""
        return sorted({m.components for m in self.members})

    @property
    def sensor_lag_h(self) -> list:
        """Sensor lags of the members [h]."""
        return sorted({m.sensor_lag_h for m in self.members})

    @property
    def heat_exponent(self):
        ps = {m.heat_exponent for m in self.members}
        return ps.pop() if len(ps) == 1 else sorted(ps, key=lambda p: -1 if p is None else p)

    @property
    def slow_lag(self) -> bool:
        return any(m.slow_lag for m in self.members)

    @property
    def label(self) -> str:
        return (f"average of {len(self.members)}: k in {{{','.join(map(str, self.components))}}}"
                f" x lag in {{{','.join(f'{v:g}' for v in self.sensor_lag_h)}}}h")


def frame_structures(n_sensors: int, search: str = "narrow") -> list[FrameStructure]:
    """Every structure the forward-chaining selection compares.

    Examples
    --------
    >>> len(frame_structures(16)), len(frame_structures(16, "wide")), len(frame_structures(0, "wide"))
    (18, 185, 5)
    """
    if search not in FRAME_SEARCHES:
        raise ValueError(f"frame search must be one of {FRAME_SEARCHES}, not {search!r}")
    narrow = search in ("narrow", "average")
    out = []
    for p in ((None,) if narrow else HEAT_EXPONENTS):
        for slow in ((False,) if narrow else (False, True)):
            for k in FRAME_COMPONENTS:
                if k > n_sensors or (k == 0 and not slow):
                    continue
                for lag in (FRAME_LAGS_H if k else (0.0,)):
                    out.append(FrameStructure(k, lag, p, slow))
    return out


def heat_law(speed_rpm, exponent: float, ref_rpm: float) -> np.ndarray:
    """Relative heat input of a spindle speed: (n/n_ref)^p, zero at rest.

    Bearing friction heat grows as n^(5/3) for its viscous part and as n for its load
    part (Palmgren), motor iron losses as n^1.5..2; p is not known for a machine, so
    it is chosen by validation among :data:`HEAT_EXPONENTS`.

    Parameters
    ----------
    speed_rpm : array_like
        Spindle speed [1/min], >= 0.
    exponent : float
        p [-].
    ref_rpm : float
        Reference speed n_ref [1/min], > 0 (input 1 there).

    Returns
    -------
    ndarray
        Heat input relative to that at n_ref [-].

    Examples
    --------
    >>> heat_law([0.0, 1000.0, 2000.0], 2.0, 1000.0).tolist()
    [0.0, 1.0, 4.0]
    """
    n = np.clip(np.asarray(speed_rpm, float), 0.0, None)
    return (n / float(ref_rpm)) ** float(exponent)


def forward_folds(t, speed, rows, min_train_frac: float = 0.25, max_folds: int = 4):
    """Forward-chaining validation blocks inside the fit window (``rows``).

    Each block starts at a speed step (so it usually opens with a speed the training
    part has not seen -- the situation of the hold-out) once at least ``min_train_frac``
    of the fit window lies before it, and ends at the next start or at the end of the
    fit window. Without such steps: the last half of the fit window in three blocks.

    Parameters
    ----------
    t : array_like
        Sample times [s].
    speed : array_like
        Spindle speed on each row [1/min].
    rows : ndarray of bool
        Fit window.
    min_train_frac : float
        Least fraction of the fit window's time span before the first block [-].
    max_folds : int
        Most blocks kept (the last ones).

    Returns
    -------
    list of (ndarray of bool, ndarray of bool)
        (train rows, validation rows) per block; training rows precede the block.

    Examples
    --------
    >>> t = np.arange(1, 1201) * 60.0            # 20 h
    >>> sp = np.where((t // 14400) % 2 == 0, 1000.0, 0.0)
    >>> f = forward_folds(t, sp, np.ones(t.size, bool))
    >>> [(round(t[v][0] / 3600), round(t[v][-1] / 3600)) for _, v in f]
    [(8, 12), (12, 16), (16, 20)]
    """
    t = np.asarray(t, float)
    speed = np.asarray(speed, float)
    tf = t[rows]
    t0, t1 = float(tf[0]), float(tf[-1])
    steps = t[np.flatnonzero(np.diff(speed) != 0) + 1]
    starts = [s for s in steps if t0 + min_train_frac * (t1 - t0) <= s < t1 - 0.05 * (t1 - t0)]
    if len(starts) < 2:
        starts = list(t0 + (t1 - t0) * np.array([0.5, 2 / 3, 5 / 6]))
    starts = starts[-max_folds:]
    ends = starts[1:] + [np.inf]
    return [(rows & (t < a), rows & (t >= a) & (t < b)) for a, b in zip(starts, ends)]


def _temperature_matrix(temperatures: dict):
    names = [k for k, v in temperatures.items() if np.all(np.isfinite(np.asarray(v, float)))]
    if not names:
        return [], None
    return names, np.column_stack([np.asarray(temperatures[k], float) for k in names])


def frame_components(t, T, rows, k: int, lag_h: float):
    """Leading principal components of the standardised temperature changes, lagged.

    The components (and the standardisation) come from ``rows`` only; each is then passed
    through the first-order lag τ P' = pc − P with τ = ``lag_h`` (none for 0).

    Parameters
    ----------
    t : ndarray
        Sample times [s].
    T : ndarray, shape (n, m)
        Temperatures [°C].
    rows : ndarray of bool
        Rows that define the components.
    k : int
        Number of components [-].
    lag_h : float
        Extra lag of the frame behind the thermometers [h].

    Returns
    -------
    list of ndarray
        k series [-] (unit variance on ``rows`` before the lag).

    Examples
    --------
    >>> t = np.arange(1, 101) * 60.0
    >>> T = np.column_stack([np.sin(t / 900), 2 * np.sin(t / 900)])
    >>> p = frame_components(t, T, np.ones(100, bool), 1, 0.0)
    >>> round(float(abs(np.corrcoef(p[0], T[:, 0])[0, 1])), 6)
    1.0
    """
    mu = T[rows].mean(0)
    sd = T[rows].std(0)
    sd[sd == 0] = 1.0
    Z = (T - mu) / sd
    lam, V = np.linalg.eigh(Z[rows].T @ Z[rows])    # = right singular vectors of Z[rows]
    lam, V = lam[::-1], V[:, ::-1]
    k = int(min(k, V.shape[1]))
    pcs = [Z @ V[:, j] / max(np.sqrt(max(lam[j], 0.0) / rows.sum()), 1e-12) for j in range(k)]
    if lag_h > 0:
        pcs = [first_order_lag(t, p, lag_h * 3600.0, p[0]) for p in pcs]
    return pcs


class _Projection:
    """Residual sum of squares of ``y`` on fixed columns plus varying ones, over ``rows``.

    The fixed columns (thermometer components, offset) are projected out once by a QR
    factorisation; each call then solves only the small normal equations of the varying
    columns (eigen-decomposition, directions below 1e-12 of the largest dropped), which
    is what makes the structure search affordable. Used for the search only; the final
    coefficients come from :func:`~arfem.models.diagnosis.candidates.project`.
    """

    def __init__(self, fixed: list, y, rows):
        self.rows = rows
        yr = np.asarray(y, float)[rows]
        if fixed:
            F = np.column_stack(fixed)[rows]
            nrm = np.linalg.norm(F, axis=0)
            F = F / np.where(nrm > 0, nrm, 1.0)
            self.Q, _ = np.linalg.qr(F)
            yr = yr - self.Q @ (self.Q.T @ yr)
        else:
            self.Q = None
        self.y = yr

    def rss(self, varying: list) -> float:
        X = np.hstack(varying)[self.rows]
        if self.Q is not None:
            X = X - self.Q @ (self.Q.T @ X)
        nrm = np.linalg.norm(X, axis=0)
        X = X / np.where(nrm > 0, nrm, 1.0)
        lam, V = np.linalg.eigh(X.T @ X)
        keep = lam > 1e-12 * max(lam[-1], 1e-300)
        c = V[:, keep].T @ (X.T @ self.y)
        return float(self.y @ self.y - np.sum(c * c / lam[keep]))


def fit_frame_thermometers(t, y, speed, rows, seen, W, temperatures: dict,
                           structure: FrameStructure) -> CandidateFit | None:
    """AR(1) of the heat input plus a frame, output error on ``rows``.

    Reading = rod + frame + c. The rod is the AR(1) of the heat input at rate b: one
    steady gain per seen speed (unseen speeds by the eqs. 20-21 mapping ``W``) or, with
    ``structure.heat_exponent`` p, one gain on (n/n_ref)^p, n_ref the fastest speed seen
    in ``rows``. The frame is (a) with ``slow_lag`` a second first-order response to the
    same heat input at its own rate b_f (τ_f = 1/b_f in [2, 200] h), and (b) Σ_j γ_j P_j,
    P_j the ``components`` leading principal components of the temperatures lagged by
    ``sensor_lag_h`` (:func:`frame_components`). Gains, γ, c and the initial-state decays
    are linear (least squares); b and b_f are searched.

    ``frame_gain`` and ``frame_time_constant_h``: with ``slow_lag``, the slow response's
    steady gain per unit of the rod's and τ_f; otherwise the frame part fitted, on
    ``rows``, as a first-order lag of the rod's steady growth target.

    Parameters
    ----------
    t : array_like
        Sample times [s].
    y : array_like
        Measured growth [µm].
    speed : array_like
        Spindle speed on each row [1/min].
    rows : ndarray of bool
        Fit rows (before the hold-out, not outliers).
    seen : array_like
        Speeds seen in ``rows`` [1/min]; one steady gain each without
        ``structure.heat_exponent``.
    W : dict
        Unseen-speed mapping of :func:`speed_to_heat_map` (idem).
    temperatures : dict
        Sensor name -> temperature series [°C]; only complete series are used.
    structure : FrameStructure

    Returns
    -------
    CandidateFit or None
        ``frame_expansion`` fit: prediction [µm] over the record; parameters
        ``frame_time_constant_h`` [h], ``frame_gain`` [-], ``frame_sensor_lag_h`` [h],
        ``rod_time_constant_h`` [h], ``heat_exponent`` [-], ...; ``extra["frame_um"]``
        the frame part [µm]. None if the structure needs thermometers and there is no
        complete one, or the heat law has no running speed in ``rows``.
    """
    if isinstance(structure, FrameEnsemble):
        return _fit_frame_ensemble(t, y, speed, rows, seen, W, temperatures, structure)
    names, T = _temperature_matrix(temperatures)
    k = structure.components
    if k and T is None:
        return None
    t, y, speed = (np.asarray(a, float) for a in (t, y, speed))
    p = structure.heat_exponent
    if p is None:
        units = list(_level_inputs(speed, seen, W).values())
    else:
        ref = float(np.max(speed[rows], initial=0.0))
        if ref <= 0:
            return None
        units = [heat_law(speed, p, ref)]
    pcs = frame_components(t, T, rows, k, structure.sensor_lag_h) if k else []
    one = np.ones_like(t)
    nl = len(units)

    U = np.column_stack(units)

    def varying(b, bf=None):
        """Columns that depend on the rates: rod responses and initial-state decay, then
        (slow frame) the same at rate bf."""
        c = [ar_columns(t, U, b), np.exp(-b * t)[:, None]]
        if bf is not None:
            c += [ar_columns(t, U, bf), np.exp(-bf * t)[:, None]]
        return c

    fixed = [one] + pcs
    proj = _Projection(fixed, y, rows)

    def rss(b, bf=None):
        return proj.rss(varying(b, bf))

    lb = (np.log(1 / (50 * 3600.0)), np.log(1 / 300.0))
    lf = (np.log(1 / (SLOW_TAU_H[1] * 3600.0)), np.log(1 / (SLOW_TAU_H[0] * 3600.0)))
    if structure.slow_lag:
        # the frame's response is the slower one (bf <= b): the rod and the frame are both
        # per-speed first-order responses, so without this order their roles can swap
        # (a fast "frame" at its 2 h bound beside a slow "rod") and τ_f means nothing
        gb, gf = np.linspace(*lb, 7), np.linspace(*lf, 5)
        vals = np.array([[rss(np.exp(a), np.exp(c)) if c <= a else np.inf for c in gf]
                         for a in gb])
        i, j = np.unravel_index(int(np.argmin(vals)), vals.shape)

        def clip2(x):
            xb = float(np.clip(x[0], *lb))
            return xb, float(np.clip(x[1], lf[0], min(lf[1], xb)))

        def f(x):
            xb, xf = clip2(x)
            return rss(np.exp(xb), np.exp(xf))
        res = minimize(f, np.array([gb[i], gf[j]]), method="Nelder-Mead",
                       options={"xatol": 1e-3, "fatol": 1e-10, "maxiter": 120,
                                "initial_simplex": np.array([[gb[i], gf[j]],
                                                             [gb[i] + 0.3, gf[j]],
                                                             [gb[i], gf[j] + 0.3]])})
        b, bf = (float(np.exp(v)) for v in clip2(res.x))
    else:
        grid = np.linspace(*lb, 13)
        vals = [rss(np.exp(g)) for g in grid]
        i = int(np.argmin(vals))
        res = minimize_scalar(lambda x: rss(np.exp(x)),
                              bounds=(grid[max(i - 1, 0)], grid[min(i + 1, 12)]),
                              method="bounded", options={"xatol": 1e-3})
        b, bf = float(np.exp(res.x)), None
    V = np.hstack(varying(b, bf))
    coef, pred = project(list(V.T) + fixed, y, rows)
    r = (y - pred)[rows]
    gains = coef[:nl]
    gamma = coef[V.shape[1] + 1:]            # thermometer components, after the offset
    params = {}
    # per-speed gains + offset + initial decays are collinear (Σ_s u_s = 1): the gains
    # are known relative to the rest level only, so that is what the summaries use
    rest = next((j for j, sv in enumerate(seen) if sv == 0), None) if p is None else None
    if bf is not None:
        slow = coef[nl + 1:2 * nl + 1]
        nz = [j for j, sv in enumerate(seen) if sv != 0] if p is None else [0]
        g1 = np.array([gains[j] for j in nz])
        g2 = np.array([slow[j] for j in nz])
        if rest is not None:
            g1, g2 = g1 - gains[rest], g2 - slow[rest]
        fg = float(g1 @ g2 / (g1 @ g1)) if g1 @ g1 > 0 else float("nan")
        params = {"frame_time_constant_h": float(1 / bf / 3600.0), "frame_gain": fg}
        frame = V[:, nl + 1:2 * nl + 1] @ slow + (np.column_stack(pcs) @ gamma if pcs else 0.0)
    else:
        target = sum(g * u for g, u in zip(gains, units))
        if rest is not None:
            target = target - gains[rest] * sum(units)
        frame = np.column_stack(pcs) @ gamma

        def summ(x):
            c, f = project([first_order_lag(t, target, np.exp(x) * 3600.0), one], frame, rows)
            rr = (frame - f)[rows]
            return float(rr @ rr)
        rs = minimize_scalar(summ, bounds=(np.log(0.1), np.log(200.0)), method="bounded",
                             options={"xatol": 1e-3})
        cg, _ = project([first_order_lag(t, target, np.exp(rs.x) * 3600.0), one], frame, rows)
        params = {"frame_time_constant_h": float(np.exp(rs.x)), "frame_gain": float(cg[0])}
    params.update({"frame_components": int(k), "frame_sensor_lag_h": float(structure.sensor_lag_h),
                   "heat_exponent": None if p is None else float(p),
                   "frame_slow_response": bool(structure.slow_lag),
                   "rod_time_constant_h": float(1 / b / 3600.0)})
    return CandidateFit("frame_expansion", "ar+frame_expansion(thermometers)", params, pred,
                        len(pcs) + (nl + 2 if bf is not None else 0), float(r @ r),
                        int(rows.sum()),
                        {"time_constant_h": float(1 / b / 3600.0), "sensors": names,
                         "frame_um": frame, "coefficients": coef.tolist(),
                         "structure": structure.label})


def _fit_frame_ensemble(t, y, speed, rows, seen, W, temperatures, ens: FrameEnsemble):
    """:func:`fit_frame_thermometers` of every member of ``ens``, averaged with equal
    weights: the prediction and the frame part are the members' means; the contract
    parameters (``frame_time_constant_h``, ``frame_gain``) and the rod's time constant
    are the members' medians."""
    fits = [fit_frame_thermometers(t, y, speed, rows, seen, W, temperatures, m)
            for m in ens.members]
    fits = [f for f in fits if f is not None]
    if not fits:
        return None
    y = np.asarray(y, float)
    pred = np.mean([f.prediction for f in fits], axis=0)
    r = (y - pred)[rows]

    def med(key):
        return float(np.median([f.parameters[key] for f in fits]))
    params = {"frame_time_constant_h": med("frame_time_constant_h"),
              "frame_gain": med("frame_gain"), "rod_time_constant_h": med("rod_time_constant_h"),
              "frame_members": len(fits), "frame_structure": ens.label}
    return CandidateFit("frame_expansion", "ar+frame_expansion(thermometers, averaged)", params,
                        pred, int(round(np.mean([f.k for f in fits]))), float(r @ r),
                        int(rows.sum()),
                        {"time_constant_h": params["rod_time_constant_h"],
                         "sensors": fits[0].extra["sensors"],
                         "frame_um": np.mean([f.extra["frame_um"] for f in fits], axis=0),
                         "structure": ens.label,
                         "members": [f.extra["structure"] for f in fits]})


def median_block_ratio(per, base_per) -> float:
    """Median over the validation blocks of a candidate's RMSE over the baseline's [-].

    The naming test of ``frame_search="average"`` (post hoc): a cause is named if this is
    <= 1 − MIN_GAIN, i.e. it cuts the baseline's error by >= MIN_GAIN on the typical
    block. The pooled RMSE and the block count it replaces were each decided by one
    block: the pooled RMSE by the worst (one badly extrapolated speed outweighs three
    blocks cut by half), and "wins a majority" by whichever block sits at the margin
    (2 of 4 blocks with a 48 % pooled cut was ``none``).

    Examples
    --------
    >>> median_block_ratio([1.0, 1.0, 6.0, 0.5], [2.0, 2.0, 3.0, 2.5])
    0.5
    """
    r = [a / b for a, b in zip(per, base_per) if b > 0]
    return float(np.median(r)) if r else float("nan")


#: speed-only causes whose prediction is driven by no recorded input: a trend in time
INPUT_FREE_CAUSES = ("sensor_drift",)


def drift_last(named, tests) -> list:
    """Order of the candidate causes with the input-free ones (:data:`INPUT_FREE_CAUSES`,
    a linear drift in time) put behind every input-driven cause that passes its naming
    test (``tests[c]["significant"]``); otherwise ``named`` unchanged.

    The rule of ``drift_last=True`` (post hoc, after the rolling-origin evaluation of the
    real record). On a fit window in which the machine mostly warms up, a linear drift
    in time and a slow thermal response (a frame that follows the thermometers) both
    fit the slow rise, and validation blocks inside that window cannot tell them apart.
    They part only after the window: the thermal response follows the recorded
    temperatures when the machine cools, the drift goes on rising. So where an
    explanation from the recorded inputs passes the test, the drift is not preferred to
    it on a validation score; it is named only when no input-driven cause passes.

    Parameters
    ----------
    named : sequence of str
        Candidate causes, best first (``"none"`` excluded).
    tests : dict
        Cause -> its naming test, with the bool ``"significant"``.

    Returns
    -------
    list of str

    Examples
    --------
    >>> t = {"sensor_drift": {"significant": True}, "frame_expansion": {"significant": True},
    ...      "ambient_drift": {"significant": False}}
    >>> drift_last(["sensor_drift", "ambient_drift", "frame_expansion"], t)
    ['ambient_drift', 'frame_expansion', 'sensor_drift']
    >>> t["frame_expansion"]["significant"] = False
    >>> drift_last(["sensor_drift", "ambient_drift", "frame_expansion"], t)
    ['sensor_drift', 'ambient_drift', 'frame_expansion']
    """
    named = list(named)
    if not any(c not in INPUT_FREE_CAUSES and tests[c]["significant"] for c in named):
        return named
    return ([c for c in named if c not in INPUT_FREE_CAUSES]
            + [c for c in named if c in INPUT_FREE_CAUSES])


def cv_rmse(fitter, y, folds) -> tuple[float, list[float]]:
    """Forward-chaining validation RMSE [µm]: pooled over the blocks, and per block.

    ``fitter(train_rows) -> prediction over the record`` (or None: not applicable).
    """
    errs, per = [], []
    for tr, va in folds:
        p = fitter(tr)
        if p is None:
            return float("nan"), []
        r = (y - p)[va]
        errs.append(r)
        per.append(float(np.sqrt(np.mean(r * r))))
    e = np.concatenate(errs) if errs else np.zeros(0)
    return (float(np.sqrt(np.mean(e * e))) if e.size else float("nan")), per


def select_frame_structure(t, y, speed, temperatures, rows, folds, fold_maps,
                           search: str = "narrow"):
    """The frame structure with the least forward-chaining validation RMSE.

    ``fold_maps[i] = (seen, W)``: the speed mapping rebuilt from fold i's training rows
    (used by the per-speed-gain structures). Every structure of
    :func:`frame_structures` (``search``) is scored on the same blocks; a tie keeps the
    structure earlier in that list.

    Parameters
    ----------
    t : array_like
        Sample times [s].
    y : array_like
        Measured growth [µm].
    speed : array_like
        Spindle speed on each row [1/min].
    temperatures : dict
        Sensor name -> temperature series [°C].
    rows : ndarray of bool
        Fit window (before the hold-out, not outliers); the scoring uses ``folds`` only.
    folds : list of (ndarray of bool, ndarray of bool)
        (train, validation) rows, as from :func:`forward_folds`.
    fold_maps : list of (seen, W)
        Speed mapping per fold, as from :func:`speed_to_heat_map` on its training rows.
    search : {"narrow", "wide", "average"}
        Which structures to compare (:data:`FRAME_SEARCHES`); "average" compares none
        and returns the :class:`FrameEnsemble` of the "narrow" structures with an empty
        table (its validation RMSE is the ``frame_expansion`` candidate's own).

    Returns
    -------
    structure : FrameStructure or None
        The best structure; None if none could be scored.
    table : dict
        Structure label -> pooled validation RMSE [µm] (nan if not applicable).
    """
    names, _ = _temperature_matrix(temperatures)
    if search == "average":
        # no choice to make: the candidate's own validation (by the caller) scores it
        members = tuple(frame_structures(len(names), "average"))
        return (FrameEnsemble(members) if members else None), {}
    table, best = {}, None
    for st in frame_structures(len(names), search):
        it = iter(fold_maps)

        def fitter(tr, st=st, it=it):
            seen, W = next(it)
            f = fit_frame_thermometers(t, y, speed, tr, seen, W, temperatures, st)
            return None if f is None else f.prediction
        score, _ = cv_rmse(fitter, y, folds)
        table[st.label] = score
        if np.isfinite(score) and (best is None or score < best[0]):
            best = (score, st)
    return (None if best is None else best[1]), table
