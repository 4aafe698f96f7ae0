"""A steady-state Kalman observer on a reduced thermal model: the thermometers correct it.

A compensator that runs its model open loop (:class:`arfem.models.compensator.Compensator`)
keeps every error of the model: a bearing that makes more heat than the model says, a
housing that loses heat faster, a machine that starts warm. The machine's thermometers
see these errors long before the tool does. This module corrects the model's state from
them, in the manner of a disturbance observer (Johnson 1971; the "augmented state" or
"random-walk disturbance" Kalman filter, Simon 2006, ch. 5 and 7):

    x_k = A x_{k−1} + B (u_k + E d_k) + v η_k          reduced thermal state
    d_k = ρ d_{k−1} + w_k                              disturbances (W, K)
    z_k = C_T x_k + D_T (u_k + E d_k) + z0 + ν_k       thermometers [°C]

* ``d`` holds one unknown heat per source (added to its input ``P_<source>_W``, [W]; or
  to a flux input ``q_<source>_W_m2`` [W/m²]) and an unknown ambient (added to
  ``ambient_C``, [K]); ``E`` (m × n_d) puts each into its input's column. Each is a
  random walk of strength σ_j per √h (``w_k`` ~ N(0, σ_j² Δτ/3600 s)) that slowly
  forgets (ρ = e^{−Δτ/τ_d}, τ_d = ``time_constant_h``, 100 h by default). The leak
  makes a combination the thermometers cannot see (four disturbances, three
  thermometers) decay to "no disturbance" instead of wandering: the augmented model is
  then detectable and the Riccati equation has its stabilising solution.
* ``v η_k`` is a random walk of the body's uniform temperature (``v`` the state of a
  uniform 1 K rise; σ_u per √h): what an initial state (a warm start) or any model error
  not in ``d`` looks like to the thermometers.
* ``ν_k`` ~ N(0, σ_T² I) is the thermometers' noise.

The gain is the steady-state Kalman gain K = P Hᵀ (H P Hᵀ + R)⁻¹ of the augmented
model, P the stabilising solution of the discrete algebraic Riccati equation
(:func:`dare_doubling`; Kalman 1960; Simon 2006, ch. 7). Each cycle,
after the compensator has advanced its state with the inputs it read,

    d⁻ = ρ d,    x⁻ = x_model + B E d⁻,    [x; d] = [x⁻; d⁻] + K (z − ẑ(x⁻, d⁻)),

and the output is computed from the corrected state with the inputs plus the estimated
disturbances. A thermometer that is missing, not finite or out of its plausible range
(the same check the inputs get, :func:`arfem.models.compensator.check_reading`) is
held: its innovation is taken as zero (its correction is not made) and its alarm is
raised. The offset itself still goes through the compensator's clamp and rate limit:
the observer changes what is predicted, never what may be sent.

With a speed-scheduled model (h depends on the speed) the gain is designed at each
tabulated speed and interpolated in the speed exactly as the matrices are
(:class:`arfem.models.compensator.SpeedSchedule`).

Pure: arrays in, dataclasses out; no file is read or written here.

References
----------
R. E. Kalman, "A new approach to linear filtering and prediction problems", J. Basic
Eng. 82 (1960) 35-45. D. Simon, *Optimal State Estimation*, Wiley 2006. C. D. Johnson,
"Accommodation of external disturbances in linear regulator and servomechanism
problems", IEEE TAC 16 (1971) 635-644. R. K. Mehra, "On the identification of variances
and adaptive Kalman filtering", IEEE TAC 15 (1970) 175-184 (the noise fitted by the
innovations' likelihood).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_discrete_are

from arfem.models.speed_table import at_speed

__all__ = ["ObserverNoise", "Disturbance", "Observer", "Correction", "ObserverRun",
           "augmented_matrices", "steady_state_gain", "design_observer",
           "disturbance_inputs", "fit_noise_scale", "noise_from_table", "NOISE_KEYS",
           "measurement_matrix", "dare_doubling"]


@dataclass(frozen=True)
class ObserverNoise:
    """The noise levels an observer is designed for (stated by the user or fitted).

    Attributes
    ----------
    thermometer_K : float
        Standard deviation of a thermometer's reading [K] (> 0).
    heat_per_sqrt_h : float
        Random-walk strength of each source's unknown heat, in its input's unit per √h
        ([W/√h] for a power ``P_<source>_W``).
    ambient_K_per_sqrt_h : float
        Random-walk strength of the unknown ambient [K/√h].
    uniform_K_per_sqrt_h : float
        Random-walk strength of the body's uniform temperature [K/√h] (initial state,
        errors not in the disturbances).
    time_constant_h : float
        τ_d: the disturbances forget with e^{−Δτ/τ_d} per interval [h].
    """

    thermometer_K: float = 0.05
    heat_per_sqrt_h: float = 2.0
    ambient_K_per_sqrt_h: float = 0.3
    uniform_K_per_sqrt_h: float = 0.1
    time_constant_h: float = 100.0

    def scaled(self, factor: float) -> "ObserverNoise":
        """The same with every process noise (not the thermometers') times ``factor``."""
        return ObserverNoise(self.thermometer_K, self.heat_per_sqrt_h * factor,
                             self.ambient_K_per_sqrt_h * factor,
                             self.uniform_K_per_sqrt_h * factor, self.time_constant_h)


#: keys of a scenario's ``[observer]`` table, each the :class:`ObserverNoise` field of
#: the same name
NOISE_KEYS = ("thermometer_K", "heat_per_sqrt_h", "ambient_K_per_sqrt_h",
              "uniform_K_per_sqrt_h", "time_constant_h")


def noise_from_table(table, where: str = "observer") -> ObserverNoise:
    """An ``[observer]`` table of noise levels (:data:`NOISE_KEYS`, each optional, each
    a number; ``thermometer_K`` and ``time_constant_h`` > 0, the others >= 0) as
    :class:`ObserverNoise`; :class:`arfem.params.InputError` names the key.

    >>> noise_from_table({"thermometer_K": 0.02}).thermometer_K
    0.02
    >>> noise_from_table({"thermometer_k": 1.0})
    Traceback (most recent call last):
    ...
    arfem.params.InputError: observer.thermometer_k: unknown key (did you mean 'thermometer_K'?)
    """
    from arfem.strict import check_keys, number
    if not isinstance(table, dict):
        from arfem.params import InputError
        raise InputError("must be a table of noise levels", where)
    check_keys(table, set(NOISE_KEYS), where)
    vals = {}
    for key in NOISE_KEYS:
        if key in table:
            strict = key in ("thermometer_K", "time_constant_h")
            vals[key] = number(table[key], f"{where}.{key}", positive=True,
                               allow_zero=not strict)
    return ObserverNoise(**vals)


@dataclass(frozen=True)
class Disturbance:
    """One disturbance state: the model input it adds to, its unit, its strength.

    Attributes
    ----------
    input : str
        The model input (``P_<source>_W``, ``q_<source>_W_m2`` or ``ambient_C``).
    unit : str
        The estimate's unit: ``"W"``, ``"W/m²"`` or ``"K"``.
    sigma_per_sqrt_h : float
        Its random walk's strength [unit/√h].
    """

    input: str
    unit: str
    sigma_per_sqrt_h: float


def disturbance_inputs(model, noise: ObserverNoise) -> tuple:
    """The default disturbances of ``model``: one unknown heat per source input, and the
    ambient where the model reads it (:class:`Disturbance` each, model order).

    >>> from types import SimpleNamespace as N
    >>> m = N(inputs=(N(name="P_a_W", unit="W"), N(name="ambient_C", unit="°C"),
    ...               N(name="speed_rpm", unit="1/min")))
    >>> [(d.input, d.unit) for d in disturbance_inputs(m, ObserverNoise())]
    [('P_a_W', 'W'), ('ambient_C', 'K')]
    """
    out = []
    for spec in model.inputs:
        if spec.name == "ambient_C":
            out.append(Disturbance(spec.name, "K", noise.ambient_K_per_sqrt_h))
        elif spec.name.startswith("P_") or spec.name.startswith("q_"):
            out.append(Disturbance(spec.name, spec.unit, noise.heat_per_sqrt_h))
    return tuple(out)


def augmented_matrices(A, B, columns, rho: float, uniform, sigmas, sigma_uniform: float,
                       dtau_s: float):
    """(F, Q): the augmented state matrix and process-noise covariance.

    Parameters
    ----------
    A : ndarray (n, n)
    B : ndarray (n, m)
    columns : sequence of int, length n_d
        The input column each disturbance adds to.
    rho : float
        e^{−Δτ/τ_d}, the disturbances' memory per interval [-].
    uniform : ndarray (n,)
        The state of a uniform 1 K rise [state per K].
    sigmas : sequence of float, length n_d
        Each disturbance's random-walk strength [unit/√h].
    sigma_uniform : float
        The uniform temperature's random-walk strength [K/√h].
    dtau_s : float
        Interval Δτ [s].

    Returns
    -------
    F : ndarray (n + n_d, n + n_d)
        [[A, ρ B E], [0, ρ I]].
    Q : ndarray (n + n_d, n + n_d)
        L Σ Lᵀ with L = [[B E, v], [I, 0]], Σ = diag(σ², σ_u²) Δτ/3600 s.

    Examples
    --------
    >>> F, Q = augmented_matrices([[0.9]], [[2.0]], [0], 0.5, [1.0], [1.0], 0.0, 3600.0)
    >>> F.tolist(), Q.tolist()
    ([[0.9, 1.0], [0.0, 0.5]], [[4.0, 2.0], [2.0, 1.0]])
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    n, nd = A.shape[0], len(columns)
    BE = B[:, list(columns)]
    F = np.zeros((n + nd, n + nd))
    F[:n, :n] = A
    F[:n, n:] = rho * BE
    F[n:, n:] = rho * np.eye(nd)
    L = np.zeros((n + nd, nd + 1))
    L[:n, :nd] = BE
    L[n:, :nd] = np.eye(nd)
    L[:n, nd] = np.asarray(uniform, float)
    var = np.concatenate([np.asarray(sigmas, float) ** 2, [sigma_uniform ** 2]]) \
        * (dtau_s / 3600.0)
    return F, (L * var) @ L.T


def measurement_matrix(C_T, D_T, columns) -> np.ndarray:
    """H = [C_T, D_T E] (q × (n + n_d)): the thermometers per augmented state [K]."""
    C_T, D_T = np.asarray(C_T, float), np.asarray(D_T, float)
    return np.hstack([C_T, D_T[:, list(columns)]])


def steady_state_gain(F, H, Q, R) -> tuple[np.ndarray, np.ndarray]:
    """The steady-state Kalman gain K and the a-priori covariance P of x_k = F x_{k−1} +
    w, z = H x + ν (Kalman 1960; Simon 2006, ch. 7, steady-state filtering): P the
    stabilising solution of P = F P Fᵀ − F P Hᵀ (H P Hᵀ + R)⁻¹ H P Fᵀ + Q,
    K = P Hᵀ (H P Hᵀ + R)⁻¹ (the measurement update x⁺ = x⁻ + K (z − H x⁻)).

    P is found by the doubling algorithm (:func:`dare_doubling`), a few n³ products
    per doubling, instead of the QZ decomposition of the 2n × 2n
    pencil (:func:`scipy.linalg.solve_discrete_are`: 12 s for a model of 404 states
    against 1.2 s, one BLAS thread; both give the same P, tested).

    Examples
    --------
    A random walk seen in noise of the same variance: P = φ (the golden ratio), K = 1/φ.

    >>> K, P = steady_state_gain([[1.0]], [[1.0]], [[1.0]], [[1.0]])
    >>> round(float(P[0, 0]), 6), round(float(K[0, 0]), 6)
    (1.618034, 0.618034)
    """
    F, H = np.asarray(F, float), np.asarray(H, float)
    Q, R = np.asarray(Q, float), np.asarray(R, float)
    P = dare_doubling(F, H, Q, R)
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    return K, P


def dare_doubling(F, H, Q, R, rtol: float = 1e-13, max_doublings: int = 64) -> np.ndarray:
    """The stabilising solution P of the filter Riccati equation
    P = F P Fᵀ − F P Hᵀ (H P Hᵀ + R)⁻¹ H P Fᵀ + Q by the doubling algorithm
    (Anderson, Int. J. Control 28 (1978) 295-306) in its structure-preserving form, on
    the control form A = Fᵀ, G = Hᵀ R⁻¹ H:
    with W = I + G_k P_k,

        A_{k+1} = A_k W⁻¹ A_k,   G_{k+1} = G_k + A_k W⁻¹ G_k A_kᵀ,
        P_{k+1} = P_k + A_kᵀ P_k W⁻¹ A_k,

    which converges quadratically (after k doublings the error is of the order of the
    closed loop's spectral radius to the power 2^k). Where it has not converged to
    ``rtol`` after ``max_doublings``, :func:`scipy.linalg.solve_discrete_are` is used.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> F = np.diag([0.99, 0.9, 0.5]); H = rng.normal(size=(1, 3)); Q = np.eye(3)
    >>> P = dare_doubling(F, H, Q, np.eye(1))
    >>> bool(np.allclose(P, solve_discrete_are(F.T, H.T, Q, np.eye(1)), rtol=1e-9))
    True
    """
    F, H = np.asarray(F, float), np.asarray(H, float)
    Q, R = np.asarray(Q, float), np.asarray(R, float)
    n = F.shape[0]
    A = F.T.copy()
    G = H.T @ np.linalg.solve(R, H)
    P = 0.5 * (Q + Q.T)
    eye = np.eye(n)
    for _ in range(max_doublings):
        W = eye + G @ P
        WA = np.linalg.solve(W, A)
        WG = np.linalg.solve(W, G)
        step = A.T @ P @ WA
        P = P + 0.5 * (step + step.T)
        G = G + A @ WG @ A.T
        G = 0.5 * (G + G.T)
        A = A @ WA
        if np.max(np.abs(step)) <= rtol * max(np.max(np.abs(P)), 1e-300):
            return P
    scale = max(float(np.max(np.abs(Q))), 1e-300)
    P = solve_discrete_are(F.T, H.T, Q / scale, R / scale) * scale
    return 0.5 * (P + P.T)


@dataclass(frozen=True)
class Observer:
    """The observer of a model (``model.json``'s ``observer`` block; module docstring).

    Attributes
    ----------
    thermometers : tuple of str
        The q thermometer columns it reads, ``T_<sensor>_C``.
    C_T : ndarray (q, n)
        Thermometer rows over the model's state [K per state unit].
    D_T : ndarray (q, m)
        Their direct terms over the model's inputs [K per input unit].
    z0_C : ndarray (q,)
        Their reading at rest [°C] (the reference temperature).
    disturbances : tuple of Disturbance
        The n_d disturbance states.
    columns : tuple of int
        The model input each disturbance adds to.
    uniform : ndarray (n,)
        The state of a uniform 1 K rise [state per K].
    noise : ObserverNoise
        The levels the gain was designed for (its ``heat_per_sqrt_h`` and
        ``ambient_K_per_sqrt_h`` are the defaults; each disturbance keeps its own).
    dtau_s : float
        Interval Δτ [s] (the model's).
    gains : ndarray (S, n + n_d, q)
        The steady-state gain at each tabulated speed of the model's schedule (S = 1
        without one).
    speeds_rpm : ndarray (S,) or None
        The schedule's speeds [1/min] (None without one).
    """

    thermometers: tuple
    C_T: np.ndarray
    D_T: np.ndarray
    z0_C: np.ndarray
    disturbances: tuple
    columns: tuple
    uniform: np.ndarray
    noise: ObserverNoise
    dtau_s: float
    gains: np.ndarray
    speeds_rpm: np.ndarray | None = None

    @property
    def rho(self) -> float:
        """e^{−Δτ/τ_d}: the disturbances' memory per interval [-]."""
        return math.exp(-self.dtau_s / (3600.0 * self.noise.time_constant_h))

    @property
    def n_disturbances(self) -> int:
        return len(self.disturbances)

    def gain(self, speed_rpm: float | None = None) -> np.ndarray:
        """The gain (n + n_d, q) at ``speed_rpm``: linear in the speed between two
        tabulated speeds, the end's outside them (the rule of
        :meth:`arfem.models.compensator.SpeedSchedule.at`); the one gain without a
        schedule or a known speed."""
        if self.speeds_rpm is None or speed_rpm is None:
            return self.gains[0]
        (g,), _ = at_speed(self.speeds_rpm, (self.gains,), speed_rpm)
        return g

    def estimate_sd(self, A, B) -> np.ndarray:
        """The steady-state standard deviation of each disturbance estimate (its unit)
        with the matrices ``A``, ``B`` (a schedule's at one speed): the square root of
        the disturbance block of the a-posteriori covariance P⁺ = P − K S Kᵀ, S = H P
        Hᵀ + R, of the noise levels the observer was designed for. A 95 % interval of an
        estimate is ± 1.96 of it.
        """
        K, P, H, R = self.riccati(A, B)
        post = P - K @ (H @ P @ H.T + R) @ K.T
        n = A.shape[0]
        return np.sqrt(np.maximum(np.diag(post)[n:], 0.0))

    def riccati(self, A, B) -> tuple:
        """(K, P, H, R): the steady-state gain and a-priori covariance of the augmented
        model with the matrices ``A``, ``B`` for this observer's noise levels, its
        measurement matrix and the thermometers' noise covariance [K²]."""
        F, Q = augmented_matrices(A, B, self.columns, self.rho, self.uniform,
                                  [d.sigma_per_sqrt_h for d in self.disturbances],
                                  self.noise.uniform_K_per_sqrt_h, self.dtau_s)
        H = measurement_matrix(self.C_T, self.D_T, self.columns)
        R = self.noise.thermometer_K ** 2 * np.eye(len(self.thermometers))
        K, P = steady_state_gain(F, H, Q, R)
        return K, P, H, R

    def closed_loop_radius(self, A, B, k: int = 0) -> float:
        """Spectral radius of the error dynamics (I − K H) F with the ``k``-th gain and
        the matrices ``A``, ``B`` of that speed: < 1 for an observer that settles."""
        F, _ = augmented_matrices(A, B, self.columns, self.rho, self.uniform,
                                  [0.0] * len(self.columns), 0.0, self.dtau_s)
        H = measurement_matrix(self.C_T, self.D_T, self.columns)
        M = (np.eye(F.shape[0]) - self.gains[k] @ H) @ F
        return float(np.max(np.abs(np.linalg.eigvals(M)))) if M.size else 0.0


def design_observer(model, thermometers, C_T, D_T, z0_C, uniform,
                    noise: ObserverNoise = ObserverNoise(), disturbances=None) -> Observer:
    """The steady-state observer of ``model`` (a version-2 ``StateSpaceModel``).

    Parameters
    ----------
    model : StateSpaceModel
        Its A, B (or, with a speed schedule, each tabulated speed's) and Δτ.
    thermometers : sequence of str
        The q thermometer columns ``T_<sensor>_C``.
    C_T : array_like (q, n)
    D_T : array_like (q, m)
        Thermometer rows over the state and the inputs [K per unit].
    z0_C : array_like (q,)
        The thermometers' reading at rest [°C].
    uniform : array_like (n,)
        The state of a uniform 1 K rise of the body.
    noise : ObserverNoise
    disturbances : sequence of Disturbance, optional
        Default :func:`disturbance_inputs`.

    Returns
    -------
    Observer

    Examples
    --------
    A one-mode body with one heater and one thermometer: the steady state seen
    exactly, the observer settles.

    >>> from arfem.models.modal_export import modal_state_space
    >>> m = modal_state_space([1e-4], [[1e-4]], [[2.0]], [[0.0]], dtau_s=60.0,
    ...                       input_map=[[1.0]], inputs=[("P_a_W", "W")],
    ...                       outputs=[("d_tcp_z_um", "Z")], output_scale=1.0)
    >>> ob = design_observer(m, ["T_a_C"], [[0.5]], [[0.0]], [20.0], [2.0])
    >>> ob.gains.shape, [d.input for d in ob.disturbances]
    ((1, 2, 1), ['P_a_W'])
    >>> ob.closed_loop_radius(m.A, m.B) < 1.0
    True
    """
    dist = tuple(disturbance_inputs(model, noise) if disturbances is None else disturbances)
    names = [i.name for i in model.inputs]
    columns = tuple(names.index(d.input) for d in dist)
    C_T, D_T = np.asarray(C_T, float), np.asarray(D_T, float)
    uniform = np.asarray(uniform, float)
    rho = math.exp(-model.dtau_s / (3600.0 * noise.time_constant_h))
    H = measurement_matrix(C_T, D_T, columns)
    R = noise.thermometer_K ** 2 * np.eye(len(thermometers))
    sched = model.schedule
    pairs = [(model.A, model.B)] if sched is None else list(zip(sched.A, sched.B))
    gains = []
    for A, B in pairs:
        F, Q = augmented_matrices(A, B, columns, rho, uniform,
                                  [d.sigma_per_sqrt_h for d in dist],
                                  noise.uniform_K_per_sqrt_h, model.dtau_s)
        gains.append(steady_state_gain(F, H, Q, R)[0])
    return Observer(tuple(thermometers), C_T, D_T, np.asarray(z0_C, float), dist, columns,
                    uniform, noise, float(model.dtau_s), np.array(gains),
                    None if sched is None else np.asarray(sched.speeds_rpm, float))


@dataclass(frozen=True)
class Correction:
    """What the observer did in one cycle.

    Attributes
    ----------
    disturbances : tuple
        ((input, unit, estimate), ...): each disturbance's estimate after the cycle
        [W, W/m² or K].
    innovations_K : tuple
        ((thermometer, measured − predicted [K]), ...); NaN for a held thermometer.
    held : tuple of str
        The thermometers held this cycle (missing, not finite, out of range).
    """

    disturbances: tuple
    innovations_K: tuple
    held: tuple = ()

    def estimates(self) -> dict:
        """``{"<input>": estimate}`` (JSON-ready)."""
        return {name: value for name, _, value in self.disturbances}


@dataclass
class ObserverRun:
    """An :class:`Observer` running: its disturbance estimates ``d``.

    Parameters
    ----------
    observer : Observer
    """

    observer: Observer
    d: np.ndarray = field(init=False)

    def __post_init__(self):
        self.d = np.zeros(self.observer.n_disturbances)

    def correct(self, x_model, u, B, speed_rpm, readings) -> tuple:
        """One measurement update (module docstring).

        Parameters
        ----------
        x_model : ndarray (n,)
            The state the compensator advanced with the inputs it read (no disturbance).
        u : ndarray (m,)
            The inputs of this interval as the matrices take them.
        B : ndarray (n, m)
            The interval's input matrix (a schedule's, at its speed).
        speed_rpm : float or None
            The interval's speed (selects the gain of a scheduled model).
        readings : sequence of float or None
            Each thermometer's reading [°C]; None for a held one.

        Returns
        -------
        (x, u_eff, Correction)
            The corrected state, the inputs plus the estimated disturbances (what the
            output and the next held cycles are computed with), and what was done.
        """
        ob = self.observer
        cols = list(ob.columns)
        d_prior = ob.rho * self.d
        x_prior = x_model + B[:, cols] @ d_prior
        u_prior = np.array(u, float)
        u_prior[cols] += d_prior
        z_hat = ob.C_T @ x_prior + ob.D_T @ u_prior + ob.z0_C
        innov = np.array([np.nan if r is None else float(r) - zh
                          for r, zh in zip(readings, z_hat)])
        held = np.isnan(innov)
        X = np.concatenate([x_prior, d_prior]) + ob.gain(speed_rpm) @ np.where(held, 0.0, innov)
        n = x_model.size
        self.d = X[n:]
        u_eff = np.array(u, float)
        u_eff[cols] += self.d
        corr = Correction(tuple((dd.input, dd.unit, float(v))
                                for dd, v in zip(ob.disturbances, self.d)),
                          tuple((t, float(v)) for t, v in zip(ob.thermometers, innov)),
                          tuple(t for t, h in zip(ob.thermometers, held) if h))
        return X[:n], u_eff, corr

    def state(self) -> list:
        """The disturbance estimates, JSON-ready (a warm start restores them)."""
        return self.d.tolist()

    def restore(self, d) -> None:
        """Set the estimates from :meth:`state`; :class:`ValueError` if they do not fit."""
        d = np.asarray(d, float).reshape(-1)
        if d.shape != self.d.shape or not np.all(np.isfinite(d)):
            raise ValueError("observer state does not fit the model")
        self.d = d


def fit_noise_scale(model, observer: Observer, inputs, readings,
                    factors=tuple(np.geomspace(0.1, 10.0, 11))) -> tuple[float, float]:
    """(factor, σ_T): the thermometers' noise and one common scale of the process noises
    fitted on a record's rows by the innovations' likelihood (Mehra 1970).

    σ_T [K] is the thermometers' white noise from their second differences (mean over
    channels of mean(Δ²z)²/6); then for each ``factor`` the observer is redesigned
    with every process noise times it and run over the rows; the factor of the largest
    Gaussian log-likelihood of the innovations, −½ Σ_k (log det S + νₖᵀ S⁻¹ νₖ), S = H P
    Hᵀ + R, is returned.

    Parameters
    ----------
    model : StateSpaceModel
    observer : Observer
        The observer to refit (its thermometer rows, disturbances' inputs and τ_d kept).
    inputs : ndarray (N, m)
        The model's inputs on the rows, as the matrices take them (mapped).
    readings : ndarray (N, q)
        The thermometers on the rows [°C] (finite).
    factors : sequence of float
        Scales tried.
    """
    z = np.asarray(readings, float)
    d2 = np.diff(z, 2, axis=0)
    sigma_T = float(np.sqrt(np.mean(d2 ** 2) / 6.0)) if d2.shape[0] >= 10 else \
        observer.noise.thermometer_K
    sigma_T = max(sigma_T, 1e-6)
    best = (-np.inf, 1.0)
    for f in factors:
        noise = _with_thermometer(observer.noise.scaled(f), sigma_T)
        dist = tuple(Disturbance(d.input, d.unit, d.sigma_per_sqrt_h * f)
                     for d in observer.disturbances)
        ob = design_observer(model, observer.thermometers, observer.C_T, observer.D_T,
                             observer.z0_C, observer.uniform, noise, dist)
        ll = _log_likelihood(model, ob, np.asarray(inputs, float), z)
        if ll > best[0]:
            best = (ll, float(f))
    return best[1], sigma_T


def _with_thermometer(noise: ObserverNoise, sigma_T: float) -> ObserverNoise:
    return ObserverNoise(sigma_T, noise.heat_per_sqrt_h, noise.ambient_K_per_sqrt_h,
                         noise.uniform_K_per_sqrt_h, noise.time_constant_h)


def _log_likelihood(model, ob: Observer, U: np.ndarray, Z: np.ndarray) -> float:
    """The innovations' Gaussian log-likelihood of ``ob`` run on rows ``U``, ``Z``
    (a time-invariant model, or a schedule's nominal matrices)."""
    A, B = model.A, model.B
    K, P, H, R = ob.riccati(A, B)
    S = H @ P @ H.T + R
    Si = np.linalg.inv(S)
    logdet = float(np.linalg.slogdet(S)[1])
    run = ObserverRun(ob)
    x = model.x0.astype(float).copy()
    ll = 0.0
    for k in range(U.shape[0]):
        x = A @ x + B @ U[k]
        x, _, c = run.correct(x, U[k], B, None, list(Z[k]))
        nu = np.array([v for _, v in c.innovations_K])
        ll -= 0.5 * (logdet + float(nu @ Si @ nu))
    return ll


#: the closed-loop error dynamics must settle by at least this margin below 1 (the
#: ``observer`` block of model.json is refused otherwise:
#: :mod:`arfem.scenarios.compensation.model_file`)
STABLE_RADIUS = 1.0 - 1e-12
