"""Generated speed-only records (``speed_rpm``, no heat flux) with a known injected cause.

The counterpart of :mod:`arfem.models.diagnosis.synth` for the speed-only path: what the
intervals of :mod:`arfem.models.diagnosis.speed_intervals` are scored on
(``benchmarks/bench_speed_intervals.py``). The truth is the model family of the speed-only
candidates (:func:`arfem.models.diagnosis.speed.fit_speed_candidate`), so a miss of an
interval is a miss of the interval, not a model-form error:

* the spindle steps between a few speeds (0 and three or four of 1000-4000 1/min, each
  phase 1.5-4 h); the heat of speed n is (n/n_max)^(5/3) (a viscous bearing-friction
  law, Palmgren), and the rod's growth is the AR(1) of that heat (paper eqs. 12-14) at
  rate b = 1/τ_rod, τ_rod 0.6-2 h, steady growth at n_max 12-30 µm;
* one cause with known parameters:

  ============================== =======================================================
  ``sensor_drift``               + drift_um_per_h · t, |drift| 0.03-0.3 µm/h
  ``ambient_drift``              + gain · AR(1) at rate b of the ambient change (a daily
                                 wave plus a slower one, amplitude 1-3 K, recorded with
                                 0.02 K noise), |gain| 1-5 µm/K
  ``frame_expansion``            + frame_gain × the rod's steady growth, through a
                                 first-order lag of τ_f = 3-10 h, |frame_gain| 0.3-0.8;
                                 the frame's temperature is recorded (``T_frame_C``)
  ``speed_dependent_convection`` rate b_running while the spindle turns, b_stopped at rest
                                 (their ratio 1.5-2.5 either way), reported as
                                 h = bρcR/2 with the default :class:`~arfem.params.Rod`
  ============================== =======================================================

* with ``heat_law="per_speed"`` (off by default: the records above are unchanged) the
  heat of a speed level is NOT a power law of the speed: each non-zero level's heat is
  (n/n_max)^(5/3) times its own factor exp(N(0, 0.35²)) (drawn from
  ``default_rng([seed, 60])``, levels in increasing speed), then scaled so that the
  largest level's heat is 1 -- one steady gain per speed, the paper's eq. 17 structure,
  which no one law (n/n_max)^p follows (:func:`per_speed_heat`);
* measurement noise: AR(1) with ρ 0.6-0.9 (as real records have) and marginal σ
  0.03-0.15 µm.

With ``thermometers`` m > 1 every record carries m thermometers ``T_t1_C`` ..
(:func:`_thermometers`, their own draws ``default_rng([seed, 50])``, the records of one
thermometer unchanged): max(2, m // 2) on the machine, each a mix of a fast (τ 0.3-1.5 h,
near the bearings) and a slow (τ 3-10 h, the frame's body) first-order response to the
heat, 2-6 K per unit, the rest only the room (a daily and a 7 h wave of 0.5-2 K; the
recorded ambient where there is one), every one with some room in it and 0.01 K noise.
A ``frame_expansion`` then grows as a mix of the first two thermometers' rises (the
fast-dominated and the slow-dominated one), |frame_gain| 0.3-0.8 of the rod's steady
growth at their peak, in place of the one thermometer's lag.

With ``frame_modes`` K > 2 (off by default: every record above is unchanged; needs m >= K
thermometers) the machine has K independent thermal modes in place of the fast and slow
one (:func:`_mode_thermometers`, every draw from ``default_rng([seed, 70])``): mode k is
the first-order response, time constant τ_k [h] (log-evenly spread over 0.3-12 h, each
jittered by a factor 0.8-1.25), to a heat of its own speed law (n/n_max)^p_k, p_k
1-3 (load-independent losses to windage), applied as heat^(p_k/(5/3)) so that the
``per_speed`` heat keeps its per-level factors. Thermometer j < K sits on mode j (0.8 of
it, the rest a random mix of the others), the others of the max(K, m // 2) on the
machine read a random mix, 2-6 K per unit, each with 0-0.3 of the room; the rest read
the room only, as above. The frame of a ``frame_expansion`` grows as a mix of all K
modes with weights of either sign, |w_k| 0.3-1 (a structural loop whose members expand
against each other), scaled to |frame_gain| × the rod's steady growth at its peak, so
its growth needs about K + 1 principal components of the standardised thermometers
(the room's one and the K modes').

Reproducible: ``default_rng(seed)`` draws the schedule, rod and noise, ``default_rng([seed,
k])`` the cause's magnitudes (k its index in :data:`SPEED_SYNTH_CAUSES`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arfem.models.diagnosis.forward import ar_first_order, first_order_lag
from arfem.params import Rod

__all__ = ["SPEED_SYNTH_CAUSES", "HEAT_LAWS", "SpeedCase", "generate_speed", "ar1_noise",
           "per_speed_heat"]

SPEED_SYNTH_CAUSES = ("sensor_drift", "ambient_drift", "frame_expansion",
                      "speed_dependent_convection")
HEAT_EXPONENT = 5.0 / 3.0
#: the speed-to-heat laws of :func:`generate_speed` (``heat_law``)
HEAT_LAWS = ("power", "per_speed")
#: σ of the log of each speed level's factor off the power law (``heat_law="per_speed"``)
PER_SPEED_LOG_SIGMA = 0.35


def per_speed_heat(seed: int, speed_rpm, n_max_rpm: float) -> np.ndarray:
    """The heat [-] of each row when each speed level has its own steady heat (module
    docstring, ``heat_law="per_speed"``): (n/n_max)^(5/3) times a factor
    exp(N(0, :data:`PER_SPEED_LOG_SIGMA`²)) per non-zero level, the largest level's heat
    scaled to 1; zero at rest.

    Examples
    --------
    >>> sp = np.array([0.0, 1000.0, 2000.0, 4000.0, 1000.0])
    >>> q = per_speed_heat(1, sp, 4000.0)
    >>> float(q.max()), float(q[0]), bool(q[1] == q[4])
    (1.0, 0.0, True)
    """
    speed = np.asarray(speed_rpm, float)
    levels = np.unique(speed[speed > 0])
    f = np.exp(np.random.default_rng([seed, 60]).normal(0.0, PER_SPEED_LOG_SIGMA, levels.size))
    q = (levels / float(n_max_rpm)) ** HEAT_EXPONENT * f
    q = q / q.max()
    out = np.zeros(speed.size)
    for lv, h in zip(levels, q):
        out[speed == lv] = h
    return out


@dataclass
class SpeedCase:
    """One generated speed-only record.

    Attributes
    ----------
    time_s, speed_rpm, growth_um : ndarray
        Sample times [s], spindle speed [1/min], measured growth [µm].
    ambient_K : ndarray or None
        Recorded ambient change [K] (``ambient_drift`` only).
    cause : str
        The injected cause.
    truth : dict
        Injected contract parameters, in the units their names carry.
    settings : dict
        Every other draw (rod time constant, noise σ [µm] and ρ, ...).
    holdout_start_s : float
        Start of the hold-out [s] (the last quarter of the record).
    temperatures : dict
        Sensor name -> temperature [°C]: ``frame_expansion`` records carry ``T_frame_C``,
        the frame body's temperature (20 °C + 2-6 K per unit of the steady frame
        response, recorded with 0.01 K noise), whose growth is the frame part.
    """
    time_s: np.ndarray
    speed_rpm: np.ndarray
    growth_um: np.ndarray
    ambient_K: np.ndarray | None
    cause: str
    truth: dict
    settings: dict = field(default_factory=dict)
    holdout_start_s: float = 0.0
    temperatures: dict = field(default_factory=dict)


def ar1_noise(rng, n: int, sigma: float, rho: float) -> np.ndarray:
    """Stationary AR(1) noise e_n = ρ e_{n−1} + w_n with marginal standard deviation σ.

    Parameters
    ----------
    rng : numpy.random.Generator
    n : int
        Samples.
    sigma : float
        Marginal standard deviation [any unit].
    rho : float
        Lag-1 autocorrelation [-], |ρ| < 1.

    Returns
    -------
    ndarray

    Examples
    --------
    >>> e = ar1_noise(np.random.default_rng(0), 20000, 2.0, 0.8)
    >>> round(float(np.std(e)), 1), round(float(np.corrcoef(e[1:], e[:-1])[0, 1]), 2)
    (2.0, 0.8)
    """
    from scipy.signal import lfilter
    w = rng.normal(0.0, sigma * np.sqrt(1.0 - rho * rho), n)
    e0 = rng.normal(0.0, sigma)
    out, _ = lfilter([1.0], [1.0, -rho], w, zi=[rho * e0])
    return out


def _heat(heat_law: str, seed: int, speed, n_max: float) -> np.ndarray:
    """The heat [-] of each row by ``heat_law`` (one of :data:`HEAT_LAWS`)."""
    if heat_law not in HEAT_LAWS:
        raise ValueError(f"heat_law must be one of {HEAT_LAWS}, not {heat_law!r}")
    if heat_law == "power":
        return (speed / n_max) ** HEAT_EXPONENT
    return per_speed_heat(seed, speed, n_max)


def _schedule(rng, duration_h: float, step_s: float):
    levels = np.sort(rng.choice([1000.0, 1500.0, 2000.0, 2500.0, 3000.0, 3500.0, 4000.0],
                                size=int(rng.integers(3, 5)), replace=False))
    phases, total = [], 0.0
    while total < duration_h:
        on = float(rng.uniform(1.5, 4.0))
        off = float(rng.uniform(1.5, 3.0))
        phases += [(float(rng.choice(levels)), on), (0.0, off)]
        total += on + off
    edges = np.cumsum([0.0] + [h * 3600.0 for _, h in phases])
    t = np.arange(1, int(duration_h * 3600.0 / step_s) + 1) * step_s
    k = np.searchsorted(edges, t, side="left") - 1
    return t, np.array([phases[i][0] for i in k]), float(levels[-1])


def _thermometers(seed: int, t, heat, m: int, room_K=None):
    """m thermometers [°C] of a speed record (module docstring) and the noise-free rises
    [K] of the first two (the frame's mix): ({``T_t<j>_C``: (N,)}, (rise 1, rise 2))."""
    rng = np.random.default_rng([seed, 50])
    fast = first_order_lag(t, heat, float(rng.uniform(0.3, 1.5)) * 3600.0)
    slow = first_order_lag(t, heat, float(rng.uniform(3.0, 10.0)) * 3600.0)
    if room_K is None:
        room_K = _room(rng, t)
    n_heat = max(2, m // 2)
    out, clean = {}, []
    for j in range(m):
        if j < n_heat:
            # the first is fast-dominated, the second slow-dominated, the rest any mix
            w = (0.85, 0.15)[j] if j < 2 else float(rng.uniform(0.0, 1.0))
            T = float(rng.uniform(2.0, 6.0)) * (w * fast + (1.0 - w) * slow) \
                + float(rng.uniform(0.0, 0.3)) * room_K
        else:
            T = float(rng.uniform(0.7, 1.0)) * room_K
        clean.append(T)
        out[f"T_t{j + 1}_C"] = 20.0 + T + rng.normal(0.0, 0.01, t.size)
    return out, (clean[0] - clean[0][0], clean[1] - clean[1][0])


#: range of the time constants of the thermal modes of ``frame_modes`` > 2 [h]
MODE_TAU_H = (0.3, 12.0)
#: range of the speed exponents p of the thermal modes' heat (n/n_max)^p [-]
MODE_EXPONENTS = (1.0, 3.0)


def _room(rng, t, daily_K=(0.5, 2.0), seven_h_K=(0.5, 2.0)):
    """A room's temperature change [K]: a daily and a 7 h wave, their amplitudes drawn
    from ``daily_K`` and ``seven_h_K`` [K], then their phases."""
    a1, a2 = rng.uniform((daily_K[0], seven_h_K[0]), (daily_K[1], seven_h_K[1]))
    ph = rng.uniform(0, 2 * np.pi, 2)
    return (a1 * np.sin(2 * np.pi * t / 86400.0 + ph[0])
            + a2 * np.sin(2 * np.pi * t / (7 * 3600.0) + ph[1]))


def _mode_thermometers(seed: int, t, heat, m: int, modes: int, room_K=None):
    """m thermometers [°C] over ``modes`` independent thermal modes (module docstring,
    ``frame_modes``) and the modes' noise-free responses [-] (modes, N), each starting at 0.

    Parameters
    ----------
    seed : int
        The record's seed; the draws are ``default_rng([seed, 70])``.
    t : ndarray (N,)
        Sample times [s].
    heat : ndarray (N,)
        Heat of each row [-], 1 at the top speed, (n/n_max)^(5/3) under the power law.
    m, modes : int
        Thermometers and thermal modes [-], m >= modes > 2.
    room_K : ndarray (N,), optional
        The room's change [K] (the recorded ambient); default a drawn one.
    """
    rng = np.random.default_rng([seed, 70])
    edges = np.geomspace(*MODE_TAU_H, modes)
    tau_h = edges * rng.uniform(0.8, 1.25, modes)
    p = rng.uniform(*MODE_EXPONENTS, modes)
    resp = np.array([first_order_lag(t, heat ** (pk / HEAT_EXPONENT), tk * 3600.0)
                     for pk, tk in zip(p, tau_h)])
    resp = resp - resp[:, :1]
    room_K = _room(rng, t) if room_K is None else room_K
    out = {}
    for j in range(m):
        if j < max(modes, m // 2):
            w = rng.dirichlet(np.ones(modes))
            if j < modes:
                w = 0.2 * np.where(np.arange(modes) == j, 0.0, w) / (1.0 - w[j]) \
                    + 0.8 * (np.arange(modes) == j)
            T = float(rng.uniform(2.0, 6.0)) * (w @ resp) \
                + float(rng.uniform(0.0, 0.3)) * room_K
        else:
            T = float(rng.uniform(0.7, 1.0)) * room_K
        out[f"T_t{j + 1}_C"] = 20.0 + T + rng.normal(0.0, 0.01, t.size)
    return out, resp


def _mode_frame(seed: int, t, heat, thermometers: int, modes: int):
    """The frame's response [-] (peak |.| = 1) over ``modes`` thermal modes with weights
    of either sign (module docstring), the thermometers [°C] and the weights [-]."""
    temps, resp = _mode_thermometers(seed, t, heat, thermometers, modes)
    rng = np.random.default_rng([seed, 71])
    w = rng.choice([-1.0, 1.0], modes) * rng.uniform(0.3, 1.0, modes)
    mix = w @ (resp / np.max(np.abs(resp), axis=1, keepdims=True))
    return mix / np.max(np.abs(mix)), temps, w


def _frame(cr, sign: float, seed: int, t, heat, k_um: float, y, thermometers: int,
           modes: int = 2):
    """A ``frame_expansion`` record's growth [µm] (``y``, the rod's, plus the frame's),
    thermometers [°C] and truth: on one thermometer, the frame's lag of the heat; on
    several, a mix of the first two, or of ``modes`` > 2 thermal modes (module
    docstring). ``cr`` draws the cause."""
    g = sign * float(cr.uniform(0.3, 0.8))
    if modes > 2:
        mix, temps, w = _mode_frame(seed, t, heat, thermometers, modes)
        return y + g * k_um * mix, temps, {"frame_gain": g, "frame_modes": modes,
                                           "frame_mode_weights": tuple(map(float, w))}
    if thermometers > 1:
        w = float(cr.uniform(0.2, 0.8))
        temps, (r1, r2) = _thermometers(seed, t, heat, thermometers)
        mix = w * r1 / np.max(np.abs(r1)) + (1.0 - w) * r2 / np.max(np.abs(r2))
        return y + g * k_um * mix / np.max(np.abs(mix)), temps, {"frame_gain": g,
                                                                  "frame_mix": w}
    tau_f = float(cr.uniform(3.0, 10.0))
    frame = first_order_lag(t, heat, tau_f * 3600.0)
    temps = {"T_frame_C": 20.0 + float(cr.uniform(2.0, 6.0)) * frame
             + cr.normal(0.0, 0.01, t.size)}
    return y + g * k_um * frame, temps, {"frame_time_constant_h": tau_f, "frame_gain": g}


def _check_options(cause: str, thermometers: int, frame_modes) -> None:
    """ValueError unless ``cause`` and ``frame_modes`` are ones :func:`generate_speed` takes."""
    if cause not in SPEED_SYNTH_CAUSES:
        raise ValueError(f"cause must be one of {SPEED_SYNTH_CAUSES}, not {cause!r}")
    if int(frame_modes) != frame_modes or frame_modes < 2 or \
            (frame_modes > 2 and thermometers < frame_modes):
        raise ValueError(f"frame_modes must be an integer >= 2 and, above 2, at most "
                         f"thermometers ({thermometers}), not {frame_modes!r}")


def _ambient(cr, sign: float, t, b: float, y):
    """An ``ambient_drift`` record's growth [µm] (``y``, the rod's, plus the ambient's
    AR(1) at rate ``b`` [1/s]), recorded ambient change [K] and truth (module
    docstring). ``cr`` draws the cause."""
    g = sign * float(cr.uniform(1.0, 5.0))
    true_amb = _room(cr, t, (1.0, 3.0), (0.3, 1.0))
    y = y + g * ar_first_order(t, true_amb, b, 1.0)
    return y, true_amb + cr.normal(0.0, 0.02, t.size), {"ambient_gain_um_per_K": g}


def generate_speed(cause: str, seed: int, noise_um: float | None = None,
                   duration_h: float = 30.0, step_s: float = 120.0,
                   thermometers: int = 1, heat_law: str = "power",
                   frame_modes: int = 2) -> SpeedCase:
    """A speed-only record with ``cause`` injected at known parameters.

    Parameters
    ----------
    cause : str
        One of :data:`SPEED_SYNTH_CAUSES`.
    seed : int
        Seed of every draw.
    noise_um : float, optional
        Marginal σ of the AR(1) measurement noise [µm]; default drawn in 0.03-0.15.
    duration_h : float
        Record length [h].
    step_s : float
        Sampling interval [s].
    thermometers : int
        1: the record of one cause as always (a ``frame_expansion`` carries its frame's
        thermometer ``T_frame_C``); m > 1: m thermometers on every record (module
        docstring).
    heat_law : str
        ``"power"``: heat (n/n_max)^(5/3); ``"per_speed"``: :func:`per_speed_heat`.
    frame_modes : int
        Independent thermal modes [-] the thermometers observe and a frame grows with:
        2 the fast and slow responses above; K > 2 (``thermometers`` >= K) K modes of
        their own τ [h] and speed law (module docstring), new streams: no draw moves.

    Returns
    -------
    SpeedCase

    Examples
    --------
    >>> c = generate_speed("sensor_drift", 1)
    >>> c.time_s.size, sorted(c.truth)
    (900, ['drift_um_per_h'])
    """
    _check_options(cause, thermometers, frame_modes)
    rng = np.random.default_rng(seed)
    t, speed, n_max = _schedule(rng, duration_h, step_s)
    heat = _heat(heat_law, seed, speed, n_max)
    tau_rod_h = float(rng.uniform(0.6, 2.0))
    k_um = float(rng.uniform(12.0, 30.0))
    sigma = float(rng.uniform(0.03, 0.15)) if noise_um is None else float(noise_um)
    rho = float(rng.uniform(0.6, 0.9))
    noise = ar1_noise(rng, t.size, sigma, rho)
    b = 1.0 / (tau_rod_h * 3600.0)
    cr = np.random.default_rng([seed, SPEED_SYNTH_CAUSES.index(cause)])
    sign = float(cr.choice([-1.0, 1.0]))
    amb = None
    temps = {}
    if cause == "speed_dependent_convection":
        ratio = float(cr.uniform(1.5, 2.5)) ** sign
        b_run, b_stop = b, b / ratio
        rod = ar_first_order(t, k_um * heat, np.where(speed > 0, b_run, b_stop), 1.0)
        rcr = Rod()
        rcr = rcr.density_kg_m3 * rcr.specific_heat_J_kgK * rcr.radius_m
        truth = {"h_running_W_m2K": b_run * rcr / 2, "h_stopped_W_m2K": b_stop * rcr / 2}
        y = rod
    else:
        y = ar_first_order(t, k_um * heat, b, 1.0)
        if cause == "sensor_drift":
            d = sign * float(cr.uniform(0.03, 0.3))
            y = y + d * t / 3600.0
            truth = {"drift_um_per_h": d}
        elif cause == "ambient_drift":
            y, amb, truth = _ambient(cr, sign, t, b, y)
        else:
            y, temps, truth = _frame(cr, sign, seed, t, heat, k_um, y, thermometers,
                                     int(frame_modes))
    if thermometers > 1 and not temps:
        temps = (_mode_thermometers(seed, t, heat, thermometers, int(frame_modes), amb)
                 if frame_modes > 2 else _thermometers(seed, t, heat, thermometers, amb))[0]
    return SpeedCase(t, speed, y + noise, amb, cause, truth,
                     {"rod_time_constant_h": tau_rod_h, "steady_growth_um": k_um,
                      "noise_sigma_um": sigma, "noise_rho": rho, "n_max_rpm": n_max},
                     float(t[0] + 0.75 * (t[-1] - t[0])), temps)
