"""The frame model of speed-only records with thermometers: the structures compared, the
lagged principal components of the temperatures, and the output-error fit
(:func:`fit_frame_thermometers`; an equal-weight average of structures with
:class:`FrameEnsemble`). Which structure is used is decided by
:func:`arfem.models.diagnosis.speed_select.select_frame_structure`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from arfem.models.diagnosis.candidates import CandidateFit, FrameFit, project
from arfem.models.diagnosis.forward import ar_columns, first_order_lag
from arfem.models.diagnosis.speed import level_inputs

__all__ = ["FrameStructure", "FrameEnsemble", "frame_structures", "heat_law",
           "frame_components", "fit_frame_thermometers", "FRAME_SEARCHES",
           "centred_mean", "temperature_matrix"]


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


@dataclass(frozen=True)
class SpeedFrameInputs:
    """What a speed record's thermometer ``frame_expansion`` fit ran on, for its export
    as a compensator (:func:`arfem.models.diagnosis.export.speed_state_space`).

    Attributes
    ----------
    t : ndarray, shape (N,)
        Sample times [s].
    speed : ndarray, shape (N,)
        Spindle speed [1/min].
    rows : ndarray of bool, shape (N,)
        The fit rows.
    seen : ndarray
        The speeds seen on the fit rows [1/min] (one steady gain each).
    W : dict
        Unseen speed [1/min] -> {seen speed: weight [-]} (eqs. 20-21 mapping of
        :func:`arfem.models.diagnosis.speed.speed_to_heat_map`).
    temps : dict of str to ndarray
        The temperatures by column [°C], shape (N,) each.
    structure : FrameStructure or FrameEnsemble
        The frame structure fitted.
    """

    t: np.ndarray
    speed: np.ndarray
    rows: np.ndarray
    seen: np.ndarray
    W: dict
    temps: dict
    structure: FrameStructure | FrameEnsemble


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


def temperature_matrix(temperatures: dict):
    """(names, T (N, m) [°C]) of the complete thermometers of ``temperatures`` (a series
    with a missing reading is left out); ([], None) when none is complete."""
    names = [k for k, v in temperatures.items() if np.all(np.isfinite(np.asarray(v, float)))]
    if not names:
        return [], None
    return names, np.column_stack([np.asarray(temperatures[k], float) for k in names])


def centred_mean(time_s, x, half_width_s: float) -> np.ndarray:
    """Each sample's mean over the finite samples within ±``half_width_s`` of it in time
    (a zero-phase moving average; NaN where none is finite).

    What a thermometer is smoothed by before it is a regressor of the growth: its own
    noise is then an error in the variable, and under a slow noise model (whose
    whitening nearly differences the rows) a thermometer's white noise dominates its
    differenced rise and draws its gain towards zero (attenuation; Fuller W. A.,
    "Measurement error models", Wiley 1987, sec. 1.1). A mean over 2h + 1 samples cuts
    the noise of the differenced series by 2h + 1 and, being centred, adds no lag.

    Parameters
    ----------
    time_s : array_like (N,), sample times [s], increasing
    x : array_like (N,), the series [any unit], NaN missing
    half_width_s : float, half-width of the window [s] (0: ``x`` itself)

    Examples
    --------
    >>> centred_mean([0.0, 1.0, 2.0, 3.0], [0.0, 3.0, 0.0, np.nan], 1.0).tolist()
    [1.5, 1.0, 1.5, 0.0]
    """
    t, x = np.asarray(time_s, float), np.asarray(x, float)
    ok = np.isfinite(x)
    c_sum = np.concatenate([[0.0], np.cumsum(np.where(ok, x, 0.0))])
    c_n = np.concatenate([[0], np.cumsum(ok)])
    lo = np.searchsorted(t, t - half_width_s, side="left")
    hi = np.searchsorted(t, t + half_width_s, side="right")
    n = c_n[hi] - c_n[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, (c_sum[hi] - c_sum[lo]) / np.maximum(n, 1), np.nan)


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
        ``rod_time_constant_h`` [h], ``heat_exponent`` [-], ...; ``frame.frame_um``
        the frame part [µm]. None if the structure needs thermometers and there is no
        complete one, or the heat law has no running speed in ``rows``.
    """
    if isinstance(structure, FrameEnsemble):
        return _fit_frame_ensemble(t, y, speed, rows, seen, W, temperatures, structure)
    names, T = temperature_matrix(temperatures)
    k = structure.components
    if k and T is None:
        return None
    t, y, speed = (np.asarray(a, float) for a in (t, y, speed))
    p = structure.heat_exponent
    units = _heat_inputs(speed, seen, W, p, rows)
    if units is None:
        return None
    pcs = frame_components(t, T, rows, k, structure.sensor_lag_h) if k else []
    nl, U = len(units), np.column_stack(units)
    fixed = [np.ones_like(t)] + pcs
    proj = _Projection(fixed, y, rows)
    b, bf = _search_rates(lambda b, bf=None: proj.rss(_rate_columns(t, U, b, bf)),
                          structure.slow_lag)
    V = np.hstack(_rate_columns(t, U, b, bf))
    coef, pred = project(list(V.T) + fixed, y, rows)
    r = (y - pred)[rows]
    gamma = coef[V.shape[1] + 1:]            # thermometer components, after the offset
    # per-speed gains + offset + initial decays are collinear (Σ_s u_s = 1): the gains
    # are known relative to the rest level only, so that is what the summaries use
    rest = next((j for j, sv in enumerate(seen) if sv == 0), None) if p is None else None
    if bf is not None:
        params, frame = _slow_frame_summary(coef, V, nl, pcs, gamma, seen, p, rest, bf)
    else:
        params, frame = _lagged_frame_summary(t, coef[:nl], units, pcs, gamma, rows, rest)
    params.update(_structure_parameters(structure, b))
    return CandidateFit("frame_expansion", "ar+frame_expansion(thermometers)", params, pred,
                        len(pcs) + (nl + 2 if bf is not None else 0), float(r @ r),
                        int(rows.sum()), time_constant_h=float(1 / b / 3600.0),
                        residual_um=r, fit_rows=rows,
                        frame=FrameFit(tuple(names), frame, tuple(coef.tolist()),
                                       structure.label))


def _structure_parameters(structure: FrameStructure, b) -> dict:
    """The structure's own parameters as the fit reports them, with the rod's time
    constant 1/b [h] (b [1/s])."""
    p = structure.heat_exponent
    return {"frame_components": int(structure.components),
            "frame_sensor_lag_h": float(structure.sensor_lag_h),
            "heat_exponent": None if p is None else float(p),
            "frame_slow_response": bool(structure.slow_lag),
            "rod_time_constant_h": float(1 / b / 3600.0)}


def _heat_inputs(speed, seen, W, p, rows):
    """The rod's unit heat inputs: one per seen speed level (unseen ones by the mapping
    ``W``) or, with a heat-law exponent ``p``, the one input (n/n_ref)^p with n_ref the
    fastest speed on ``rows``; None where ``rows`` hold no running speed."""
    if p is None:
        return list(level_inputs(speed, seen, W).values())
    ref = float(np.max(speed[rows], initial=0.0))
    if ref <= 0:
        return None
    return [heat_law(speed, p, ref)]


def _rate_columns(t, U, b, bf=None):
    """Columns that depend on the rates: the rod's responses to the inputs ``U`` (N, l)
    at rate b [1/s] and its initial-state decay, then (slow frame) the same at rate bf."""
    c = [ar_columns(t, U, b), np.exp(-b * t)[:, None]]
    if bf is not None:
        c += [ar_columns(t, U, bf), np.exp(-bf * t)[:, None]]
    return c


def _search_rates(rss, slow_lag: bool):
    """The rod's rate b [1/s] (τ in [5 min, 50 h]) and, with ``slow_lag``, the slow frame
    response's bf <= b [1/s] (τ_f in ``SLOW_TAU_H``) minimising ``rss(b, bf)``: a grid,
    then Nelder-Mead (two rates) or a bounded search (one); bf None without ``slow_lag``."""
    lb = (np.log(1 / (50 * 3600.0)), np.log(1 / 300.0))
    lf = (np.log(1 / (SLOW_TAU_H[1] * 3600.0)), np.log(1 / (SLOW_TAU_H[0] * 3600.0)))
    if not slow_lag:
        grid = np.linspace(*lb, 13)
        vals = [rss(np.exp(g)) for g in grid]
        i = int(np.argmin(vals))
        res = minimize_scalar(lambda x: rss(np.exp(x)),
                              bounds=(grid[max(i - 1, 0)], grid[min(i + 1, 12)]),
                              method="bounded", options={"xatol": 1e-3})
        return float(np.exp(res.x)), None
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
    return b, bf


def _slow_frame_summary(coef, V, nl, pcs, gamma, seen, p, rest, bf):
    """With a slow frame response: ``frame_time_constant_h`` = 1/bf [h] and
    ``frame_gain`` [-] the slow response's steady gains per unit of the rod's (least
    squares over the running levels, relative to the rest level); and the frame part
    [µm] over the record."""
    gains = coef[:nl]
    slow = coef[nl + 1:2 * nl + 1]
    nz = [j for j, sv in enumerate(seen) if sv != 0] if p is None else [0]
    g1 = np.array([gains[j] for j in nz])
    g2 = np.array([slow[j] for j in nz])
    if rest is not None:
        g1, g2 = g1 - gains[rest], g2 - slow[rest]
    fg = float(g1 @ g2 / (g1 @ g1)) if g1 @ g1 > 0 else float("nan")
    params = {"frame_time_constant_h": float(1 / bf / 3600.0), "frame_gain": fg}
    frame = V[:, nl + 1:2 * nl + 1] @ slow + (np.column_stack(pcs) @ gamma if pcs else 0.0)
    return params, frame


def _lagged_frame_summary(t, gains, units, pcs, gamma, rows, rest):
    """Without a slow response: the thermometer frame part [µm] fitted on ``rows`` as a
    first-order lag (τ in [0.1, 200] h) of the rod's steady growth target:
    ``frame_time_constant_h`` [h] and ``frame_gain`` [-]; and the frame part."""
    one = np.ones_like(t)
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
    return {"frame_time_constant_h": float(np.exp(rs.x)), "frame_gain": float(cg[0])}, frame


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
                        int(rows.sum()), time_constant_h=params["rod_time_constant_h"],
                        residual_um=r, fit_rows=rows,
                        frame=FrameFit(fits[0].frame.sensors,
                                       np.mean([f.frame.frame_um for f in fits], axis=0), (),
                                       ens.label, tuple(f.frame.structure for f in fits)))
