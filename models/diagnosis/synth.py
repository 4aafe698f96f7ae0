"""Synthetic measured datasets with a hidden physical effect, simulated in the FEM.

Each cause of the measured-data contract's vocabulary is produced *physically* by the
axisymmetric heat FEM (:func:`arfem.fem.heat.build_axisymmetric`), never by the equations of
a diagnosis model:

=============================  ==================================================================
cause                          how the truth is simulated
=============================  ==================================================================
``none``                       nominal rod, recorded q, nominal h and ambient
``ambient_drift``              ambient air follows a daily sinusoid plus a ramp (piecewise constant
                               per sample) -> the convection boundary input of the FEM
``convection_mismatch``        true h = factor x nominal on the lateral surface, at all times
``speed_dependent_convection`` h = h_running while q > 0, h_stopped otherwise (modal solve with a
                               switching operator, state carried across)
``heat_input_scale``           true flux = scale x recorded flux
``frame_expansion``            a second, larger steel body (its own FEM, slowest time constant
                               2-6 h) heated by a fixed fraction of the rod's heat; its growth,
                               times a gain, adds to the reading
``sensor_drift``               the displacement sensor adds drift_um_per_h x t
``nonlinear_convection``       lateral h = h0 (|θ_s − θ_amb| / ΔT_ref)^n, by the θ-method with the
                               nonlinear part of the surface flux as an explicit, extrapolated source
=============================  ==================================================================

On top of the physical reading come measurement errors (none of them a cause): Gaussian
noise, quantisation, a few spikes, missing stretches of rows, a few empty growth cells,
and jittered sampling. :func:`write_case` writes the pair ``<name>.csv`` +
``<name>.toml`` exactly per the contract, with no hint of the cause: every dataset has an
``ambient_C`` column, and a ``T_frame_C`` column is present in about half of *all*
datasets (it follows the frame body's mean temperature, which is heated by the rod only in
``frame_expansion`` cases).

Reproducibility: the common draws (duration, sampling, duty cycle, noise) come from
``numpy.random.default_rng(seed)`` and do not depend on the cause, so one seed gives the
same record for every cause; the cause's magnitudes come from a separate stream
``default_rng([seed, k])``.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from arfem.fem.heat import HeatFEM, build_axisymmetric, modes, solve_modal, solve_theta
from arfem.params import InputError, Rod, Schedule

__all__ = ["CAUSES", "COMMON_RANGES", "CAUSE_RANGES", "SynthCase", "generate", "random_case",
           "ambient_gain_um_per_K", "rod_model", "frame_model"]

CAUSES = ("none", "ambient_drift", "convection_mismatch", "speed_dependent_convection",
          "heat_input_scale", "frame_expansion", "sensor_drift", "nonlinear_convection")

#: Ranges of the measurement and duty-cycle draws (same for every cause).
COMMON_RANGES = {
    "duration_h": (24.0, 72.0),           # record length
    "interval_s": (30, 60),               # nominal sampling interval (integer s)
    "jitter_s": (0, 0.2),                 # max |jitter| as a fraction of the interval (0 in 1/3 of cases)
    "phase_h": (0.5, 5.0),                # each on and each off phase
    "q_levels_W_m2": (1000.0, 4000.0),    # in steps of 500
    "noise_um": (0.05, 0.25),             # Gaussian σ of the displacement sensor
    "quantum_um": (0.1, 0.2),             # one of 0.1, 0.15, 0.2
    "n_outliers": (2, 6),                 # spikes of 3-10 µm, either sign
    "outlier_um": (3.0, 10.0),
    "n_gaps": (0, 3),                     # missing stretches of rows, each 10-60 min
    "gap_min": (10.0, 60.0),
    "empty_fraction": (0.0, 0.02),        # growth cells left empty
    "ambient_noise_K": (0.05, 0.05),
    "frame_noise_K": (0.05, 0.05),
}

#: Ranges of the hidden effect's magnitude, per cause (chosen clearly above the noise).
CAUSE_RANGES = {
    "none": {},
    "ambient_drift": {"ambient_amplitude_K": (1.0, 4.0), "ambient_ramp_K_per_h": (-1.5 / 24, 1.5 / 24),
                      "ambient_period_h": (24.0, 24.0), "ambient_phase_rad": (0.0, 2 * math.pi)},
    "convection_mismatch": {"h_factor": ((0.5, 0.75), (1.33, 2.0))},
    "speed_dependent_convection": {"h_running_factor": (1.4, 2.5), "h_stopped_W_m2K": (55.0, 55.0)},
    "heat_input_scale": {"scale": ((0.6, 0.85), (1.15, 1.5))},
    "frame_expansion": {"frame_time_constant_h": (2.0, 6.0), "frame_gain": ((-0.6, -0.15), (0.15, 0.6)),
                        "frame_heat_fraction": (0.2, 0.5)},
    "sensor_drift": {"drift_um_per_h": ((-0.5, -0.1), (0.1, 0.5))},
    "nonlinear_convection": {"exponent": (0.25, 0.33), "delta_T_ref_K": (1.0, 3.0)},
}

_FRAME_RADIUS_M = 0.25
_FRAME_LENGTH_M = 1.2
_MESH = dict(order=2, nr=3, nz=12)
_FRAME_MESH = dict(order=2, nr=3, nz=8)


@dataclass(frozen=True)
class SynthCase:
    """A generated dataset: the truth, the injected effect and the measured samples.

    Arrays are over the written rows (``time_s``); row 0 is at t = 0. Per-interval
    inputs hold over (t_{i-1}, t_i] (entry 0 is the empty interval at t = 0).

    Attributes
    ----------
    name, cause : str
    seed : int
    parameters : dict
        Injected magnitudes in the contract's parameter names (``{}`` for ``none``).
    settings : dict
        Every drawn or overridden knob (measurement and cause), for the record.
    rod : Rod
        The nominal rod written to ``[rod]``.
    time_s : ndarray [s]
    q_W_m2 : ndarray [W/m²], recorded heat flux (what the file says)
    q_true_W_m2 : ndarray [W/m²], the flux that entered the rod
    ambient_true_C : ndarray [°C], true ambient air per interval
    h_true_W_m2K : ndarray [W/(m²K)], true lateral h per interval (NaN where nonlinear)
    clean_growth_um : ndarray [µm], the physical reading without measurement error
    rod_growth_um : ndarray [µm], the rod's own growth α∫θdV/A
    nominal_growth_um : ndarray [µm], the nominal FEM with the recorded inputs
    growth_um : ndarray [µm], measured reading (NaN = empty cell)
    ambient_C : ndarray [°C], recorded ambient
    temperatures : dict, recorded ``T_<name>_C`` columns [°C]
    outlier_rows, empty_rows : ndarray of int
    gaps : list of (start_s, end_s), the missing stretches
    sensors : dict, ``[sensors]`` descriptions
    causes : tuple of str, the injected causes (one or two; ``()`` for ``none``)
    initial_known : bool, False when the record starts warm (``initial = "unknown"``)
    declared_rod : Rod or None, the ``[rod]`` written to the file when it differs from
        the true ``rod`` (a wrong-unit record)
    """

    name: str
    cause: str
    seed: int
    parameters: dict
    settings: dict
    rod: Rod
    time_s: np.ndarray
    q_W_m2: np.ndarray
    q_true_W_m2: np.ndarray
    ambient_true_C: np.ndarray
    h_true_W_m2K: np.ndarray
    clean_growth_um: np.ndarray
    rod_growth_um: np.ndarray
    nominal_growth_um: np.ndarray
    growth_um: np.ndarray
    ambient_C: np.ndarray
    temperatures: dict = field(default_factory=dict)
    outlier_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    empty_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    gaps: list = field(default_factory=list)
    sensors: dict = field(default_factory=dict)
    causes: tuple = ()
    initial_known: bool = True
    declared_rod: Rod | None = None


# -- physics helpers ------------------------------------------------------------------

def ambient_gain_um_per_K(rod: Rod) -> float:
    """Steady growth per kelvin of uniform ambient change, α L [µm/K].

    A uniform temperature rise θ gives α∫θ dV / A = α L θ.

    Parameters
    ----------
    rod : Rod
        Uses ``expansion_1_K`` [1/K] and ``length_m`` [m].

    Returns
    -------
    float
        Growth per kelvin [µm/K].

    Examples
    --------
    >>> round(ambient_gain_um_per_K(Rod()), 6)
    9.6
    """
    return rod.expansion_1_K * rod.length_m * 1e6


@functools.lru_cache(maxsize=8)
def rod_model(rod: Rod = Rod()) -> HeatFEM:
    """The rod's axisymmetric Q2 model, nr=3, nz=12 (175 dofs), cached per rod.

    Its paper-cycle peak at q = 2000 W/m² is 22.16664 µm, the nr=6, nz=32 reference
    22.1666 µm to all digits quoted.

    Parameters
    ----------
    rod : Rod
        Geometry [m], material, nominal h [W/(m²·K)] and ambient [°C].

    Returns
    -------
    HeatFEM
        See :func:`arfem.fem.heat.build_axisymmetric`; ``growth @ θ`` is the axial growth
        [m] of a temperature rise θ [K].
    """
    return build_axisymmetric(rod, **_MESH)


@functools.lru_cache(maxsize=32)
def frame_model(convection_W_m2K: float, ambient_C: float = 20.0) -> HeatFEM:
    """The frame body: a steel cylinder R = 0.25 m, L = 1.2 m, heated on one end face.

    Axisymmetric Q2, nr=3, nz=8 (119 dofs), the default :class:`Rod` steel; cached.

    Parameters
    ----------
    convection_W_m2K : float
        Lateral convection coefficient h of the frame [W/(m²·K)].
    ambient_C : float
        Nominal ambient [°C].

    Returns
    -------
    HeatFEM
        The frame's heat model; ``growth @ θ`` is its axial growth [m] of a
        temperature rise θ [K].
    """
    frod = Rod(radius_m=_FRAME_RADIUS_M, length_m=_FRAME_LENGTH_M,
               convection_W_m2K=convection_W_m2K, ambient_C=ambient_C)
    return build_axisymmetric(frod, **_FRAME_MESH)


_MODE_CACHES: dict = {}


def _mode_cache(model: HeatFEM) -> dict:
    """``{h: modes}`` of one model, shared across cases (the model is kept referenced so
    its id cannot be reused; the whole cache is dropped beyond 64 models)."""
    if id(model) not in _MODE_CACHES and len(_MODE_CACHES) >= 64:
        _MODE_CACHES.clear()
    return _MODE_CACHES.setdefault(id(model), (model, {}))[1]


def _modes(model: HeatFEM, h: float):
    cache = _mode_cache(model)
    if h not in cache:
        cache[h] = modes(model, h)
    return cache[h]


def _slowest_time_constant_h(model: HeatFEM, h: float) -> float:
    return 1.0 / float(_modes(model, h).mu[0]) / 3600.0


def _steady_growth_per_flux(model: HeatFEM, h: float) -> float:
    """Steady growth per unit heated-face flux [m per W/m²] at ambient = reference."""
    md = _modes(model, h)
    return float(np.sum(md.g * md.fq / md.mu))


@functools.lru_cache(maxsize=64)
def _frame_for_time_constant(tau_h: float, ambient_C: float) -> tuple[HeatFEM, float, float]:
    """Frame model whose slowest FEM time constant is ``tau_h``: (model, h, exact τ [h])."""
    rhoc = 7850.0 * 460.0
    h = rhoc * _FRAME_RADIUS_M / (2.0 * tau_h * 3600.0)       # lumped first guess
    for _ in range(6):                                        # μ1(h) is smooth, nearly ∝ h
        tau = _slowest_time_constant_h(frame_model(round(h, 12), ambient_C), round(h, 12))
        if abs(tau / tau_h - 1.0) < 1e-4:
            break
        h *= tau / tau_h
    h = round(h, 12)
    m = frame_model(h, ambient_C)
    return m, h, _slowest_time_constant_h(m, h)


def _nonlinear_source(model: HeatFEM, schedule: Schedule, dt_s: float, h0: float,
                      exponent: float, delta_T_ref_K: float):
    """Explicit surface term −∫(h(ΔT) − h0)(θ − θ_amb) v dS for :func:`solve_theta`.

    The flux is interpolated from nodal values (group finite elements, B = lateral
    surface mass) and evaluated at the state extrapolated to mid-step,
    θ* = θ_n + Δt_n/(2Δt_{n−1}) (θ_n − θ_{n−1}), so the split scheme stays second order
    with Crank–Nicolson. θ_amb = 0 (constant nominal ambient).
    """
    B = model.B
    lateral = np.flatnonzero(np.asarray(abs(B).sum(axis=1)).ravel() > 0)
    Bl = B[:, lateral].tocsr()
    steps = []
    for d in schedule.durations_s:
        n = max(1, int(np.ceil(d / dt_s - 1e-9)))
        steps.append(d / n)
    state = {"prev": None, "dt_prev": None}

    def source(x, seg):
        dt = steps[seg]
        prev = state["prev"]
        xs = x if prev is None else x + (dt / (2.0 * state["dt_prev"])) * (x - prev)
        state["prev"], state["dt_prev"] = x.copy(), dt
        dT = xs[lateral]
        ratio = np.abs(dT) / delta_T_ref_K
        g = h0 * (np.power(ratio, exponent) - 1.0) * dT
        return -(Bl @ g)

    return source


# -- generation -----------------------------------------------------------------------

def _draw_interval(rng, lo_hi):
    """Uniform draw from (lo, hi) or from one of two ranges ((lo, hi), (lo, hi))."""
    if isinstance(lo_hi[0], tuple):
        lo_hi = lo_hi[int(rng.integers(2))]
    lo, hi = lo_hi
    return float(rng.uniform(lo, hi)) if hi > lo else float(lo)


def _common_settings(rng) -> dict:
    r = COMMON_RANGES
    interval = int(rng.integers(r["interval_s"][0], r["interval_s"][1] + 1))
    jitter_frac = 0.0 if rng.random() < 1 / 3 else float(rng.uniform(0.02, r["jitter_s"][1]))
    return {
        "duration_h": float(rng.uniform(*r["duration_h"])),
        "interval_s": interval,
        "jitter_s": int(round(jitter_frac * interval)),
        "noise_um": float(rng.uniform(*r["noise_um"])),
        "quantum_um": float(rng.choice([0.1, 0.15, 0.2])),
        "n_outliers": int(rng.integers(r["n_outliers"][0], r["n_outliers"][1] + 1)),
        "n_gaps": int(rng.integers(r["n_gaps"][0], r["n_gaps"][1] + 1)),
        "empty_fraction": float(rng.uniform(*r["empty_fraction"])),
        "ambient_noise_K": 0.05,
        "frame_noise_K": 0.05,
        "frame_sensor": bool(rng.random() < 0.5),
        "phases": None,                     # drawn on the grid below unless overridden
        # not drawn (the draws above stay the same for every seed): the v2 record kinds
        "noise_ar1": 0.0,                   # lag-1 correlation of coloured (AR(1)) noise
        "noise_walk_um": 0.0,               # random-walk sensor wander: its σ at the end [µm]
        "growth_unit_factor": 1.0,          # written growth = reading x this (1e-3: in mm)
        "warm_start_h": 0.0,                # > 0: heated this long before t = 0 (initial unknown)
        "warm_q_W_m2": 2500.0,              # the flux of that warm-up
        "declared_rod": {},                 # [rod] values written instead of the true ones
    }


def _cause_settings(cause: str, rng, rod: Rod) -> dict:
    R = CAUSE_RANGES[cause]
    h0 = rod.convection_W_m2K
    if cause == "ambient_drift":
        return {k: _draw_interval(rng, v) for k, v in R.items()}
    if cause == "convection_mismatch":
        return {"h_W_m2K": h0 * _draw_interval(rng, R["h_factor"])}
    if cause == "speed_dependent_convection":
        return {"h_running_W_m2K": h0 * _draw_interval(rng, R["h_running_factor"]),
                "h_stopped_W_m2K": h0}
    if cause in ("heat_input_scale", "sensor_drift", "nonlinear_convection", "frame_expansion"):
        out = {k: _draw_interval(rng, v) for k, v in R.items()}
        if cause == "nonlinear_convection":
            out["nonlinear_dt_s"] = 15.0
        return out
    return {}


def _draw_phases(rng, duration_s: float) -> list[tuple[float, float]]:
    """Alternating on/off phases [(duration_s, q_W_m2)], 0.5-5 h each, starting off briefly."""
    lo, hi = COMMON_RANGES["phase_h"]
    levels = np.arange(1000.0, 4000.0 + 1, 500.0)
    phases = [(float(rng.uniform(0.05, 0.5)) * 3600.0, 0.0)]
    total, on = phases[0][0], True
    while total < duration_s:
        d = float(rng.uniform(lo, hi)) * 3600.0
        phases.append((d, float(rng.choice(levels)) if on else 0.0))
        total += d
        on = not on
    return phases


def _grid(rng, s: dict):
    """Sample times (integer s, jittered), the duty-cycle phases, gaps removed within a phase."""
    duration = s["duration_h"] * 3600.0
    if s["phases"] is None:
        phases = _draw_phases(rng, duration)
    else:
        phases = [(float(d) * 3600.0, float(q)) for d, q in s["phases"]]
    n_est = int(duration / s["interval_s"]) + 10
    j = int(s["jitter_s"])
    steps = s["interval_s"] + (rng.integers(-j, j + 1, n_est) if j else np.zeros(n_est, int))
    t = np.concatenate([[0], np.cumsum(np.maximum(steps, 1))]).astype(float)
    t = t[t <= duration]
    edges = np.concatenate([[0.0], np.cumsum([d for d, _ in phases])])
    gaps = []
    for _ in range(int(s["n_gaps"])):
        length = float(rng.uniform(*COMMON_RANGES["gap_min"])) * 60.0
        ok = [k for k in range(len(phases))
              if edges[k + 1] - edges[k] > length + 4 * s["interval_s"] and edges[k + 1] < t[-1]]
        if not ok:
            break
        k = int(rng.choice(ok))
        a = float(rng.uniform(edges[k] + 2 * s["interval_s"],
                              edges[k + 1] - length - 2 * s["interval_s"]))
        inside = (t > a) & (t < a + length)
        if inside.sum() >= 2:
            lo, hi = np.flatnonzero(inside)[[0, -1]]
            gaps.append((float(t[lo - 1]), float(t[hi + 1])))
            t = t[~inside]
    # zero-order hold: the interval (t_{i-1}, t_i] takes the phase that contains t_i
    k = np.clip(np.searchsorted(edges, t, side="left") - 1, 0, len(phases) - 1)
    q = np.array([phases[i][1] for i in k])
    q[0] = 0.0
    return t, q, phases, sorted(gaps)


def _modal_growth(model: HeatFEM, t, q, amb=None, h=None):
    sched = Schedule(np.diff(t), q[1:], None if amb is None else amb[1:],
                     None if h is None else h[1:])
    return solve_modal(model, sched, t, mode_cache=_mode_cache(model))


def _parse_causes(cause) -> tuple:
    """``"a"``, ``"a+b"`` or ``("a", "b")`` -> a tuple of known causes (``()`` for none)."""
    parts = tuple(cause.split("+")) if isinstance(cause, str) else tuple(cause)
    for c in parts:
        if c not in CAUSES:
            raise InputError(f"must be one of {', '.join(CAUSES)}, got {c!r}", "cause")
    parts = tuple(c for c in parts if c != "none")
    if len(parts) > 2 or len(set(parts)) != len(parts):
        raise InputError("at most two different causes", "cause")
    h_like = {"convection_mismatch", "speed_dependent_convection", "nonlinear_convection"}
    if len(parts) == 2 and (len(h_like & set(parts)) > 1 or (
            "nonlinear_convection" in parts and "ambient_drift" in parts)):
        raise InputError(f"{parts[0]} and {parts[1]} cannot be simulated together", "cause")
    return parts


def generate(cause, seed: int, name: str | None = None, rod: Rod | None = None,
             **overrides) -> SynthCase:
    """Simulate one measured dataset whose truth differs from nominal by ``cause``.

    Parameters
    ----------
    cause : str or tuple of str
        One of :data:`CAUSES`, or two of them (``"a+b"`` or ``("a", "b")``; at most one
        that changes h, and not natural convection with ambient drift).
    seed : int
        Seed of the random draws (same seed -> same record for every cause).
    name : str, optional
        Dataset name; default ``synth-<seed>`` (carries no hint of the cause).
    rod : Rod, optional
        The true rod (geometry, material, nominal h); default the seed paper's.
    **overrides
        Replace any drawn setting: the common ones (``duration_h``, ``interval_s``,
        ``jitter_s``, ``noise_um``, ``quantum_um``, ``n_outliers``, ``n_gaps``,
        ``empty_fraction``, ``ambient_noise_K``, ``frame_noise_K``, ``frame_sensor``,
        ``phases`` = [(duration_h, q_W_m2), ...], ``noise_ar1`` (coloured noise),
        ``noise_walk_um`` (random-walk wander, its σ at the record's end [µm]),
        ``growth_unit_factor`` (1e-3 writes growth in mm), ``warm_start_h`` and
        ``warm_q_W_m2`` (a warm start: ``initial = "unknown"``), ``declared_rod`` (a dict
        of [rod] values written instead of the true ones)) and the cause's own (e.g. ``scale``,
        ``h_W_m2K``, ``frame_time_constant_h``, ``exponent``; see :data:`CAUSE_RANGES`
        and ``case.settings``). Quantities in [h], [s], [µm], [K], [W/m²], [W/(m²K)].

    Returns
    -------
    SynthCase

    Examples
    --------
    >>> c = generate("heat_input_scale", 1, duration_h=24, scale=1.3)
    >>> c.parameters
    {'scale': 1.3}
    >>> bool(np.allclose(c.q_true_W_m2, 1.3 * c.q_W_m2))
    True
    """
    causes = _parse_causes(cause)
    cause = "+".join(causes) or "none"
    rod = Rod() if rod is None else rod
    rng = np.random.default_rng(seed)
    s = _settings(causes, cause, seed, rod, rng, overrides)

    t, q_rec, phases, gaps = _grid(rng, s)
    s["phases"] = [(d / 3600.0, qq) for d, qq in phases]
    warm_s = float(s["warm_start_h"]) * 3600.0
    t, q_rec, n_pre = _with_warm_up(t, q_rec, warm_s, float(s["warm_q_W_m2"]))
    n = t.size
    model = rod_model(rod)
    q_true, amb, h, params = _true_inputs(causes, s, t, q_rec, rod)
    rod_growth, h_rec = _rod_growth(model, causes, s, t, q_true, amb, h)
    nominal = _modal_growth(model, t, q_rec).growth_um
    frame_growth, temps, sensors = _frame(causes, s, t, q_true, amb, model, rng, params)

    drift = np.zeros(n)
    if "sensor_drift" in causes:
        drift = float(s["drift_um_per_h"]) * np.maximum(t - warm_s, 0.0) / 3600.0
    clean = rod_growth + frame_growth + drift
    if n_pre:               # the record starts at the end of the warm-up
        cut = slice(n_pre, None)
        t = t[cut] - warm_s
        q_rec, q_true, amb, h_rec = q_rec[cut], q_true[cut], amb[cut], h_rec[cut]
        clean, rod_growth, nominal = clean[cut], rod_growth[cut], nominal[cut]
        temps = {k: v[cut] for k, v in temps.items()}
        q_rec[0] = q_true[0] = 0.0
    meas, outl, empty, amb_rec = _measure(clean, amb, s, seed, rng)

    return SynthCase(
        name=name or f"synth-{seed:04d}", cause=cause, seed=int(seed), parameters=params,
        settings=s, rod=rod, time_s=t, q_W_m2=q_rec, q_true_W_m2=q_true,
        ambient_true_C=amb, h_true_W_m2K=h_rec, clean_growth_um=clean,
        rod_growth_um=rod_growth, nominal_growth_um=nominal, growth_um=meas,
        ambient_C=amb_rec, temperatures=temps, outlier_rows=outl, empty_rows=empty,
        gaps=gaps, sensors=sensors, causes=causes, initial_known=not warm_s > 0,
        declared_rod=rod.with_(**s["declared_rod"]) if s["declared_rod"] else None)


def _with_warm_up(t, q_rec, warm_s: float, warm_q_W_m2: float):
    """The grid with a warm-up of ``warm_s`` [s] at ``warm_q_W_m2`` before the record
    (every 300 s; cut off again once simulated), and the number of rows it adds."""
    if not warm_s > 0:
        return t, q_rec, 0
    tp = np.arange(0.0, warm_s, 300.0)
    n_pre = tp.size
    t = np.concatenate([tp, warm_s + t])
    q_rec = np.concatenate([np.full(n_pre, warm_q_W_m2), q_rec])
    q_rec[0] = 0.0
    q_rec[n_pre] = q_rec[n_pre - 1]
    return t, q_rec, n_pre


def _settings(causes, cause: str, seed: int, rod: Rod, rng, overrides: dict) -> dict:
    """The record's settings: the common ones drawn from ``rng``, each cause's from its
    own stream of ``seed``, then the caller's ``overrides`` (an unknown one refused)."""
    s = _common_settings(rng)
    for c in causes:
        s.update(_cause_settings(c, np.random.default_rng([seed, 1 + CAUSES.index(c)]), rod))
    for k, v in overrides.items():
        if k not in s:
            raise InputError(f"unknown setting for cause {cause!r}; allowed: "
                             f"{', '.join(sorted(s))}", f"generate: {k}")
        s[k] = v
    if not (s["duration_h"] > 0 and s["interval_s"] >= 1):
        raise InputError("duration_h and interval_s must be positive", "generate")
    return s


def _true_inputs(causes, s: dict, t, q_rec, rod: Rod):
    """What the rod truly gets where the causes change it: heat flux [W/m²], ambient
    [°C] and h [W/(m²K)] per row, and the true parameters the diagnosis should find."""
    n = t.size
    q_true = q_rec.copy()
    amb = np.full(n, rod.ambient_C)
    h = np.full(n, rod.convection_W_m2K)
    params: dict = {}
    if "ambient_drift" in causes:
        tm = np.concatenate([[0.0], 0.5 * (t[1:] + t[:-1])])       # interval midpoints
        w = 2 * np.pi / (s["ambient_period_h"] * 3600.0)
        amb = (rod.ambient_C + s["ambient_amplitude_K"]
               * (np.sin(w * tm + s["ambient_phase_rad"]) - np.sin(s["ambient_phase_rad"]))
               + s["ambient_ramp_K_per_h"] * tm / 3600.0)
        params["ambient_gain_um_per_K"] = ambient_gain_um_per_K(rod)
    if "convection_mismatch" in causes:
        h[:] = float(s["h_W_m2K"])
        params["h_W_m2K"] = float(s["h_W_m2K"])
    if "speed_dependent_convection" in causes:
        h = np.where(q_rec > 0, float(s["h_running_W_m2K"]), float(s["h_stopped_W_m2K"]))
        params.update({"h_running_W_m2K": float(s["h_running_W_m2K"]),
                       "h_stopped_W_m2K": float(s["h_stopped_W_m2K"])})
    if "heat_input_scale" in causes:
        q_true = float(s["scale"]) * q_rec
        params["scale"] = float(s["scale"])
    if "sensor_drift" in causes:
        params["drift_um_per_h"] = float(s["drift_um_per_h"])
    if "nonlinear_convection" in causes:
        params["exponent"] = float(s["exponent"])
    return q_true, amb, h, params


def _rod_growth(model, causes, s: dict, t, q_true, amb, h):
    """The rod's true growth [µm] per row, and the h [W/(m²K)] to record (NaN where the
    convection is non-linear: no single h holds)."""
    if "nonlinear_convection" in causes:
        sched = Schedule(np.diff(t), q_true[1:])
        dt = float(s["nonlinear_dt_s"])
        src = _nonlinear_source(model, sched, dt, model.rod.convection_W_m2K,
                                float(s["exponent"]), float(s["delta_T_ref_K"]))
        res = solve_theta(model, sched, dt, source=src)
        nsteps = np.maximum(1, np.ceil(sched.durations_s / dt - 1e-9).astype(int))
        return res.growth_um[np.concatenate([[0], np.cumsum(nsteps)])], np.full(t.size, np.nan)
    return _modal_growth(model, t, q_true, amb, h).growth_um, h


def _frame(causes, s: dict, t, q_true, amb, model, rng, params: dict):
    """The machine frame: always present physically, heated by the rod only in
    frame_expansion. Its growth [µm] per row, the thermometers it adds and their
    descriptions; its true parameters go into ``params`` and its settings into ``s``."""
    rod, n = model.rod, t.size
    frame_growth = np.zeros(n)
    temps: dict = {}
    sensors = {"ambient_C": "ambient air temperature beside the machine"}
    framed = "frame_expansion" in causes
    if framed or s["frame_sensor"]:
        h0 = rod.convection_W_m2K
        tau_target = float(s.get("frame_time_constant_h", 4.0))
        fmodel, hf, tau = _frame_for_time_constant(tau_target, rod.ambient_C)
        frod = fmodel.rod
        beta = float(s.get("frame_heat_fraction", 0.0)) if framed else 0.0
        qf = beta * q_true * rod.area_m2 / frod.area_m2
        fres = _modal_growth(fmodel, t, qf, amb, np.full(n, hf))
        if framed:
            gr = _steady_growth_per_flux(model, h0)
            gf = _steady_growth_per_flux(fmodel, hf) * beta * rod.area_m2 / frod.area_m2
            k = float(s["frame_gain"]) * gr / gf
            frame_growth = k * fres.growth_um
            params.update({"frame_time_constant_h": tau, "frame_gain": float(s["frame_gain"])})
            s["frame_h_W_m2K"], s["frame_reading_gain"] = hf, k
        if s["frame_sensor"]:
            rhoc = frod.density_kg_m3 * frod.specific_heat_J_kgK
            mean_theta = fres.heat_J / (rhoc * fmodel.volume.sum())
            temps["T_frame_C"] = (rod.ambient_C + mean_theta
                                  + rng.normal(0, s["frame_noise_K"], n))
            sensors["T_frame_C"] = "machine frame, mid-length"
    return frame_growth, temps, sensors


def _measure(clean, amb, s: dict, seed: int, rng):
    """What the sensors record of the clean growth [µm] and the true ambient [°C]: white
    or coloured (AR(1), stationary σ = noise_um) noise, a slow wander, empty cells,
    outliers, quantisation and the unit; returns (growth, outlier rows, empty rows,
    ambient)."""
    n = clean.size
    white = rng.normal(0.0, s["noise_um"], n)
    rho = float(s["noise_ar1"])
    if rho:
        from scipy.signal import lfilter
        c = np.sqrt(1.0 - rho * rho)
        white = lfilter([c], [1.0, -rho], white, zi=[(1.0 - c) * white[0]])[0]
    meas = clean + white
    walk_um = float(s["noise_walk_um"])
    if walk_um > 0:          # slow wander of the sensor's electronics (own stream: the
        # other draws of the seed stay as they are)
        steps = np.random.default_rng([int(seed), 7]).normal(0.0, walk_um / np.sqrt(n), n)
        meas = meas + np.cumsum(steps) - steps[0]
    cand = np.flatnonzero((np.arange(n) >= 1) & (np.arange(n) < n - 1))
    # an empty growth cell may fall anywhere, also where the input switches: the loader
    # keeps the row's input and drops only the observation
    n_empty = int(math.floor(s["empty_fraction"] * n))
    empty = np.sort(rng.choice(cand, size=min(n_empty, cand.size), replace=False))
    rest = np.setdiff1d(cand, empty)
    outl = np.sort(rng.choice(rest, size=min(int(s["n_outliers"]), rest.size), replace=False))
    lo, hi = COMMON_RANGES["outlier_um"]
    meas[outl] += rng.uniform(lo, hi, outl.size) * rng.choice([-1.0, 1.0], outl.size)
    qs = float(s["quantum_um"])
    if qs > 0:
        meas = np.round(meas / qs) * qs
    meas[empty] = np.nan
    meas = meas * float(s["growth_unit_factor"])
    return meas, outl, empty, amb + rng.normal(0.0, s["ambient_noise_K"], n)


def random_case(seed: int, name: str | None = None) -> SynthCase:
    """A case with a cause drawn uniformly from :data:`CAUSES` (``none`` included).

    Examples
    --------
    >>> random_case(3).cause in CAUSES
    True
    """
    cause = CAUSES[int(np.random.default_rng([seed, 0]).integers(len(CAUSES)))]
    return generate(cause, seed, name=name)
