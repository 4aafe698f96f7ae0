"""The diagnosis's extended model as a compensator (:class:`StateSpaceModel`).

For a ``q_W_m2`` record the extended model is the FEM rod reduced exactly to its growth
modes (:class:`arfem.models.diagnosis.forward.RodModel`) with the named causes. Its
forward run is a set of first-order recursions with exact zero-order-hold steps, so at
a fixed interval Δτ it *is* a discrete-time state-space model:

    z_k = diag(e^{−λΔτ}) z_{k−1} + diag((1 − e^{−λΔτ})/λ) (f_q q_k + h f_b θ_amb,k)
    growth_k = gᵀ z_k  [+ frame gain · x_frame,k]

(paper eq. 12 per mode). The causes enter as follows:

* ``convection_mismatch``: the modes of the fitted h;
* ``heat_input_scale``: f_q times the fitted scale;
* ``ambient_drift``: a second input ``ambient_C`` (minus the nominal ambient, the
  ``input_offsets`` of the model), its load scaled by the fitted gain over the
  physical one;
* ``frame_expansion``: one more state, the first-order lag (time constant τ) of the
  rod's steady growth target q·(steady gain), times the fitted frame gain.

Not exported: ``sensor_drift`` (a drifting sensor is not growth of the machine:
compensating it would move the tool by the drift; it is left out and said so),
``speed_dependent_convection`` and ``nonlinear_convection`` (the modes change with the
speed or the temperature: not a linear time-invariant model). The initial-state
nuisance terms of a record with ``initial = "unknown"`` describe that record's start;
the compensator starts from equilibrium (``x0 = 0``).

For a ``speed_rpm`` record the extended model the diagnosis names from thermometers
(``frame_expansion``, :func:`arfem.models.diagnosis.speed_frame.fit_frame_thermometers`, the
"narrow" structures: per-speed gains, no slow response) is an output-error AR(1) plus a
linear function of lagged principal components of the temperatures, also linear and
time-invariant (:func:`speed_state_space`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arfem.models.compensator import InputSpec, StateSpaceModel
from arfem.params import InputError

__all__ = ["fem_state_space", "speed_state_space", "speed_plant_state_space",
           "NOT_LTI", "SPEED_MAP_POINTS"]

#: causes whose model is not linear time-invariant at a fixed interval
NOT_LTI = ("speed_dependent_convection", "nonlinear_convection")


def fem_state_space(fit, phys, dtau_s: float, *, R_um2: float = 0.0, description: str = "",
                    arfem_version: str = "") -> StateSpaceModel:
    """The fitted causes ``fit`` on the FEM rod ``phys`` as a model at interval Δτ.

    Parameters
    ----------
    fit : CandidateFit
        A fit of :func:`arfem.models.diagnosis.candidates.fit_rod_causes` on
        :class:`~arfem.models.diagnosis.candidates.FemPhysics` (its ``causes`` and
        ``joint``: θ and the linear coefficients).
    phys : FemPhysics
        The physics the fit ran on.
    dtau_s : float
        Interval Δτ [s] of the model (the record's).
    R_um2 : float
        Measurement noise variance of the growth sensor [µm²], for the probe update (the
        state noise Q is the fit's residual variance).

    Returns
    -------
    StateSpaceModel
        Inputs ``q_W_m2`` [W/m²] (and ``ambient_C`` [°C] with ``ambient_drift``);
        output growth [µm]; ``kind`` = ``"extended:<causes>"``.

    Raises
    ------
    InputError
        If a cause has no linear time-invariant form (:data:`NOT_LTI`).

    Examples
    --------
    >>> from arfem.models.diagnosis.candidates import FemPhysics, fit_rod_causes
    >>> from arfem.models.diagnosis.forward import RodModel
    >>> from arfem.params import Rod
    >>> phys = FemPhysics(Rod(), RodModel(Rod(), nr=2, nz=8))
    >>> t = np.arange(1, 601) * 60.0
    >>> q = np.where((t % 36000) < 18000, 2000.0, 0.0)
    >>> y = 1.2 * phys.response(t, q)
    >>> f = fit_rod_causes(("heat_input_scale",), phys, t, q, y, np.ones(t.size, bool))
    >>> m = fem_state_space(f, phys, 60.0)
    >>> from arfem.models.compensator import Compensator
    >>> c = Compensator(m)
    >>> pred = [c.step({"q_W_m2": v}).predicted_growth_um for v in q]
    >>> bool(np.max(np.abs(np.array(pred) - y)) < 1e-9 * np.max(y))
    True
    """
    causes = tuple(fit.causes)
    bad = [c for c in causes if c in NOT_LTI]
    if bad:
        raise InputError(f"{bad[0]} changes the rod's modes with the input or the state: "
                         "not a linear time-invariant model, so it is not exported")
    theta, lin = fit.theta, (fit.joint.linear if fit.joint is not None else {})
    rod, m = phys.rod, phys.m
    h = float(np.exp(theta["log_h"])) if "convection_mismatch" in causes \
        else rod.convection_W_m2K
    E = m.eig(h)
    a = np.exp(-E.lam * dtau_s)
    w = (1.0 - a) / E.lam
    scale = float(lin.get("scale", 1.0)) if "heat_input_scale" in causes else 1.0
    cols = [scale * w * E.fq]
    inputs = [InputSpec("q_W_m2", "W/m²")]
    offsets = {}
    notes = []
    if "ambient_drift" in causes:
        k = float(lin["ambient_gain_um_per_K"]) / phys.ambient_gain_um_per_K()
        cols.append(k * w * h * E.fb)
        inputs.append(InputSpec("ambient_C", "°C"))
        offsets["ambient_C"] = float(rod.ambient_C)
    A, B, C = np.diag(a), np.column_stack(cols), np.array(E.g, float)
    if "frame_expansion" in causes:
        A, B, C = _with_frame_state(A, B, C, theta, lin, phys, dtau_s)
    notes += _left_out(causes, lin)
    desc = "; ".join([description] + notes) if description or notes else ""
    return StateSpaceModel(
        kind="extended:" + "+".join(causes) if causes else "fem", dtau_s=float(dtau_s),
        A=A, B=B, C=C[None, :], D=np.zeros((1, B.shape[1])), inputs=tuple(inputs),
        x0=np.zeros(A.shape[0]), Q=float(fit.rss / max(fit.n, 1)), R=float(R_um2),
        description=desc, arfem_version=arfem_version, input_offsets=offsets)


def _with_frame_state(A, B, C, theta, lin, phys, dtau_s):
    """``frame_expansion`` as one more state: the first-order lag (τ = e^θ [h]) of the
    rod's steady growth target (the flux [W/m²] times the rod's steady gain), seen
    through the fitted frame gain [-]."""
    n = A.shape[0]
    af = float(np.exp(-dtau_s / (np.exp(theta["log_tau_h"]) * 3600.0)))
    A = np.block([[A, np.zeros((n, 1))], [np.zeros((1, n)), np.array([[af]])]])
    row = np.zeros((1, B.shape[1]))
    row[0, 0] = (1.0 - af) * phys.steady_gain_um_per_W_m2()
    return A, np.vstack([B, row]), np.concatenate([C, [float(lin["frame_gain"])]])


def _left_out(causes, lin) -> list[str]:
    """What the exported model leaves out of the fit, said in its description."""
    notes = []
    if "sensor_drift" in causes:
        notes.append("sensor_drift left out: a sensor's drift is not growth of the machine")
    if any(k.startswith("_initial") for k in lin):
        notes.append("the record's unknown initial state is not carried: the compensator "
                     "starts at equilibrium")
    return notes


def speed_state_space(fit, info, dtau_s: float, *, R_um2: float = 0.0,
                      description: str = "", arfem_version: str = "") -> StateSpaceModel:
    """The thermometer frame model of a speed record as a model at interval Δτ.

    The fit's prediction is (:func:`~arfem.models.diagnosis.speed_frame.fit_frame_thermometers`)

        ŷ = Σ_s G_s X_s + d·e^{−bt} + c + Σ_j γ_j P_j

    with X_s the unit AR(1) responses (rate b) of the speed levels, P_j the leading
    principal components of the standardised temperatures (from the fit rows), lagged
    by τ_l. As a state-space model: one rod state (A = e^{−bΔτ}, input the speed mapped
    to its level's gain G, initial value d), one state per lagged component (A =
    e^{−Δτ/τ_l}, inputs the temperatures about their fit-window means, initial value the
    component's first sample) -- or, without lag, the components straight through D --
    and d0 = c. A speed between the levels of the record gets the interpolated gain
    (the diagnosis has no gain for it).

    Parameters
    ----------
    fit : CandidateFit
        The ``frame_expansion`` fit (its ``frame.coefficients`` and ``time_constant_h``).
    info : SpeedFrameInputs
        What the fit ran on (what :func:`arfem.models.diagnosis.engine.diagnose` keeps in
        ``Diagnosis.evidence.speed``).
    dtau_s : float
        Interval Δτ [s] (the record's).
    R_um2 : float
        Growth sensor noise variance [µm²] for the probe update.

    Raises
    ------
    InputError
        For a structure with a heat law, a slow frame response or an average of
        structures (not exported).
    """
    from arfem.models.diagnosis.speed_frame import FrameEnsemble
    st = info.structure
    where = "model_extended.json"
    if isinstance(st, FrameEnsemble) or st.slow_lag or st.heat_exponent is not None:
        raise InputError(f"the frame structure {getattr(st, 'label', st)} (a heat law, a "
                         "slow response or an average of structures) is not exported yet",
                         where)
    coef = np.asarray(fit.frame.coefficients, float)
    seen = [float(v) for v in info.seen]
    nl = len(seen)
    gains, decay, c, gamma = coef[:nl], coef[nl], coef[nl + 1], coef[nl + 2:]
    b = 1.0 / (fit.time_constant_h * 3600.0)
    maps = {"speed_rpm": _speed_gain_table(seen, gains, info.W)}
    a = float(np.exp(-b * dtau_s))
    inputs = [InputSpec("speed_rpm", "1/min")]
    offsets, frames = {}, []
    k = int(gamma.size)
    if k:
        rows = np.asarray(info.rows, bool)
        names = [nm for nm, v in info.temps.items()
                 if np.all(np.isfinite(np.asarray(v, float)))]
        T = np.column_stack([np.asarray(info.temps[nm], float) for nm in names])
        mu, W = _component_weights(T, rows, k)
        inputs += [InputSpec(nm, "°C") for nm in names]
        offsets = {nm: float(m) for nm, m in zip(names, mu)}
        al = (float(np.exp(-dtau_s / (st.sensor_lag_h * 3600.0))) if st.sensor_lag_h > 0
              else None)
        frames.append(_Frame(np.vstack([np.zeros((1, k)), W]), gamma, al, (T[0] - mu) @ W))
    b_rod = np.zeros(len(inputs))
    b_rod[0] = 1.0 - a
    A, B, C, D, x0 = _ar1_with_frames(a, b_rod, float(decay), frames)
    return StateSpaceModel(
        kind="extended:frame_expansion(thermometers)", dtau_s=float(dtau_s), A=A, B=B,
        C=C, D=D, inputs=tuple(inputs), x0=x0, d0_um=float(c),
        Q=float(fit.rss / max(fit.n, 1)), R=float(R_um2), description=description,
        arfem_version=arfem_version, input_maps=maps, input_offsets=offsets)


def speed_plant_state_space(fit, plant, dtau_s: float, *, Q_um2: float = 0.0,
                            R_um2: float = 0.0, description: str = "",
                            arfem_version: str = "") -> StateSpaceModel:
    """A fit of the speed plant (:mod:`arfem.models.diagnosis.speed_plant`) as a model at
    interval Δτ.

    The plant's prediction is G·AR1_b[(n/n_max)^p] + c·e^{−bt} [+ o] (per speed:
    Σ_s K_s·AR1_b[u_s] + c·e^{−bt} [+ o], its ``input_maps`` the gain of each speed of
    the record, 0 at rest, an unseen one's by eqs. 20-21 as in the fit) plus its causes'
    columns, each AR(1) an exact zero-order-hold recursion at the step factor
    a = e^{−Δτ/τ} (paper eqs. 12-13). As a state-space model (:func:`_ar1_with_frames`):

    * one rod state, initial value c, input ``speed_rpm`` mapped to G·(n/n_max)^p
      (``input_maps``: tabulated at the record's speeds and on a grid of
      :data:`SPEED_MAP_POINTS` speeds from 0 to n_max; between two points linear, so a
      speed of the record is exact and an unseen one within [0, n_max] follows the
      fitted law to within the grid's linear interpolation (largest error, as a
      fraction of G, on 65 points: 1.8e-4 at p = 5/3 or 3, 6.1e-5 at 2, 0 at 1, 3.1e-2
      at p = 0.5, near rest where the law is steepest); a speed above n_max is
      extrapolated linearly along the last segment and flagged ``extrapolated:speed_rpm``
      by the compensator, below the law for p > 1);
    * ``ambient_drift``: a second input of the rod state, ``ambient_C`` minus the
      plant's reference, times the fitted ``ambient_gain_um_per_K``;
    * ``frame_expansion:<T>`` / ``frame_lag:<T>``: the thermometer's reading minus its
      first (smoothed) reading, times ``frame_gain_um_per_K``, straight through D or
      through one lag state (from 0); on ``pc1-k``, the components as linear weights on
      the thermometers (:func:`_component_weights` over every row), lagged from their
      first value;
    * the frame's unknown offset o: ``d0_um``.

    The diagnosis smooths each thermometer by a centred mean
    (:data:`~arfem.models.diagnosis.speed_plant.THERMOMETER_SMOOTHING_S`, ±6 min) before
    it is a regressor; a compensator cannot read ahead, so the model reads the raw
    thermometer and differs from the diagnosis's prediction by the frame's gain times
    the thermometer's noise (exactly: the model run on the smoothed thermometers is
    the prediction). Left out (said in ``description``): ``sensor_drift`` (its offset
    and ramp are the sensor's, not the machine's growth).

    Parameters
    ----------
    fit : Fit
        The plant's fit (:class:`arfem.models.geodiagnosis.fit.Fit`: causes, setting and
        prediction; its linear coefficients are solved back from the prediction on the
        plant's own design, exact to round-off).
    plant : SpeedPlant
        The plant the fit ran on.
    dtau_s : float
        Interval Δτ [s] (the record's).
    Q_um2, R_um2 : float
        State noise and growth sensor noise variances [µm²].

    Raises
    ------
    InputError
        For a running-only rate (``convection_scale:running``; the contract's
        ``speed_dependent_convection``): the rate depends on the speed, not a
        time-invariant model.
    """
    causes = tuple(fit.causes)
    kinds = tuple(c.kind for c in causes)
    if "convection_scale" in kinds:
        raise InputError("speed_dependent_convection changes the rod's rate with the speed: "
                         "not a linear time-invariant model, so it is not exported")
    s = fit.setting
    beta, nuisance = _plant_coefficients(fit, plant)
    speed_map, nuisance = _plant_speed_map(plant, nuisance, s.heat_exponent)
    a = float(np.exp(-dtau_s / (s.time_constant_h * 3600.0)))
    inputs, offsets, b_rod, frames = _plant_inputs(fit, plant, beta, a, dtau_s)
    A, B, C, D, x0 = _ar1_with_frames(a, b_rod, nuisance[1], frames)
    desc = "; ".join(x for x in [description] + _left_out(kinds, {}) if x)
    return StateSpaceModel(
        kind="extended:" + "+".join(c.name for c in causes) if causes else "speed_plant",
        dtau_s=float(dtau_s), A=A, B=B, C=C, D=D, inputs=tuple(inputs), x0=x0,
        d0_um=float(nuisance[2]) if len(nuisance) > 2 else 0.0, Q=float(Q_um2),
        R=float(R_um2), description=desc, arfem_version=arfem_version,
        input_maps={"speed_rpm": speed_map},
        input_offsets=offsets)


#: Speeds from 0 to the record's fastest at which the speed plant's law (n/n_max)^p is
#: tabulated for :func:`speed_plant_state_space` (beside the record's own speeds)
SPEED_MAP_POINTS = 65


def _plant_speed_map(plant, nuisance: tuple, p: float) -> tuple:
    """(the speed plant's ``input_maps["speed_rpm"]``, its nuisance coefficients with
    the heat's reduced to one (G, c[, o])): the law's table (:func:`_speed_law_table`),
    or per speed the fitted gain of each seen speed, 0 at rest and the eqs. 20-21 gain
    of each unseen one (:func:`_speed_gain_table`)."""
    heat = plant.heat
    if heat.kind == "law":
        return _speed_law_table(plant, nuisance[0], p), nuisance
    k = len(heat.seen_rpm)
    return (_speed_gain_table((0.0,) + heat.seen_rpm, (0.0,) + nuisance[:k],
                              heat.unseen_weights), nuisance[k - 1:])


def _speed_law_table(plant, gain_um: float, p: float) -> tuple:
    """(speeds [1/min], G·(n/n_max)^p [µm]): the speed plant's heat law at the record's
    speeds and at :data:`SPEED_MAP_POINTS` speeds from 0 to n_max."""
    sp = np.asarray(plant.speed_rpm, float)
    n_max = float(np.max(sp))
    xs = np.unique(np.concatenate([np.linspace(0.0, n_max, SPEED_MAP_POINTS),
                                   sp[np.isfinite(sp) & (sp >= 0)]]))
    return xs, gain_um * (xs / n_max) ** p


def _plant_inputs(fit, plant, beta, a: float, dtau_s: float) -> tuple:
    """(inputs, input_offsets, the rod state's input row, :class:`_Frame` s) of a speed
    plant fit at the rod's step factor ``a``: ``speed_rpm``, ``ambient_C`` with an
    ambient drift, then the frames' thermometers."""
    kinds = tuple(c.kind for c in fit.causes)
    inputs, offsets, frames = [InputSpec("speed_rpm", "1/min")], {}, []
    rod = {"speed_rpm": 1.0 - a}
    if "ambient_drift" in kinds:
        inputs.append(InputSpec("ambient_C", "°C"))
        offsets["ambient_C"] = float(plant.reference_C)
        rod["ambient_C"] = (1.0 - a) * beta[kinds.index("ambient_drift")][0]
    for c, b in zip(fit.causes, beta):
        if c.kind in ("frame_expansion", "frame_lag"):
            frames.append(_plant_frame(c, b, plant, fit.setting, dtau_s, inputs, offsets))
    names = [i.name for i in inputs]
    frames = [_Frame(np.vstack([w.get(nm, np.zeros(g.size)) for nm in names]), g, al, x0)
              for w, g, al, x0 in frames]
    return inputs, offsets, np.array([rod.get(nm, 0.0) for nm in names]), frames


def _plant_coefficients(fit, plant) -> tuple:
    """(per cause its linear coefficients, the nuisance coefficients (G, c[, o])) of a
    speed plant fit: least squares of its prediction on its own design at its setting,
    which reproduces it to round-off (refused otherwise: the fit is not this plant's)."""
    d = plant.design(fit.causes, fit.setting)
    cols = [np.asarray(c, float)[:, 0] for c in tuple(d.columns) + tuple(d.nuisance)]
    target = np.asarray(fit.prediction, float)[:, 0] - np.asarray(d.base, float)[:, 0]
    X = np.column_stack(cols)
    beta, *_ = np.linalg.lstsq(X, target, rcond=None)
    if np.max(np.abs(X @ beta - target)) > 1e-9 * max(1.0, float(np.max(np.abs(target)))):
        raise ValueError("the fit's prediction is not on its plant's design")
    out, j = [], 0
    for c in fit.causes:
        k = len(c.linear_parameters)
        out.append(tuple(float(v) for v in beta[j:j + k]))
        j += k
    return out, tuple(float(v) for v in beta[j:])


def _plant_frame(c, beta, plant, s, dtau_s, inputs, offsets) -> tuple:
    """A speed plant's frame cause ``c`` as ({input: weights (k,)}, γ (k,), lag step
    factor or None, initial lag states (k,)); its thermometers are appended to
    ``inputs`` and their references to ``offsets``."""
    from arfem.models.diagnosis.speed_frame import temperature_matrix
    lag = c.kind == "frame_lag"
    al = float(np.exp(-dtau_s / (s.frame_time_constant_h * 3600.0))) if lag else None
    gamma = np.asarray(beta, float)
    if c.target.startswith("pc1-"):
        names, _ = temperature_matrix(plant.temperatures)
        T = np.column_stack([plant.smoothed_temperature_C(nm) for nm in names])
        mu, W = _component_weights(T, np.ones(T.shape[0], bool), gamma.size)
        weights = {nm: W[i] for i, nm in enumerate(names)}
        refs = dict(zip(names, mu))
        x0 = (T[0] - mu) @ W
    else:
        T = plant.smoothed_temperature_C(c.target)
        first = float(T[np.flatnonzero(np.isfinite(T))[0]])
        weights, refs, x0 = {c.target: np.ones(1)}, {c.target: first}, np.zeros(1)
    for nm, ref in refs.items():
        if nm not in offsets:
            inputs.append(InputSpec(nm, "°C"))
            offsets[nm] = float(ref)
    return weights, gamma, al, x0


def _speed_gain_table(seen, gains, W):
    """(speeds [1/min], steady gains [µm]) sorted by speed: the fitted gain of each seen
    speed and the mapped gain of each unseen one (weights ``W`` of eqs. 20-21)."""
    level_gain = {sv: g for sv, g in zip(seen, gains)}
    for lv, w in W.items():
        level_gain[float(lv)] = float(sum(wt * level_gain[float(sv)] for sv, wt in w.items()))
    xs = np.array(sorted(level_gain))
    return xs, np.array([level_gain[v] for v in xs])


def _component_weights(T, rows, k):
    """The leading ``k`` principal components of the standardised temperatures ``T``
    (N, m) [°C] as weights on the raw ones: (μ (m,) [°C], W (m, k) [1/°C]) with
    component_j = Σ_i (T_i − μ_i) W_ij, the standardisation and components from the
    rows ``rows`` (N,) bool, as
    :func:`arfem.models.diagnosis.speed_frame.frame_components` makes them."""
    rows = np.asarray(rows, bool)
    mu, sd = T[rows].mean(0), T[rows].std(0)
    sd[sd == 0] = 1.0
    Z = (T - mu) / sd
    lam, V = np.linalg.eigh(Z[rows].T @ Z[rows])
    lam, V = lam[::-1], V[:, ::-1]
    scale = np.array([max(np.sqrt(max(lam[j], 0.0) / rows.sum()), 1e-12) for j in range(k)])
    return mu, V[:, :k] / sd[:, None] / scale[None, :]


@dataclass(frozen=True)
class _Frame:
    """A frame that follows a linear combination of the model's inputs: components
    c_j = Σ_i u_i W_ij (W (m, k), over every input, zero rows for the inputs it does not
    read), through a first-order lag of step factor ``lag_a`` (one state each, initial
    values ``x0`` (k,)) or, for ``lag_a`` None, straight through D; growth Σ_j γ_j c_j
    (``gamma`` (k,) [µm per unit component])."""

    W: np.ndarray
    gamma: np.ndarray
    lag_a: float | None
    x0: np.ndarray


def _ar1_with_frames(a: float, b_rod: np.ndarray, x0_rod: float, frames) -> tuple:
    """(A, B, C, D, x0) of one AR(1) rod state (step factor ``a`` = e^{−Δτ/τ}, input row
    ``b_rod`` (m,), initial value ``x0_rod`` [µm], output gain 1) beside the
    :class:`_Frame` s ``frames``: the one state-space layout of a speed record's extended
    model (:func:`speed_state_space`, :func:`speed_plant_state_space`)."""
    b_rod = np.asarray(b_rod, float)
    Ad, Brows, C, x0 = [a], [b_rod], [1.0], [x0_rod]
    D = np.zeros(b_rod.size)
    for f in frames:
        gamma = np.asarray(f.gamma, float)
        if f.lag_a is None:
            D = D + np.asarray(f.W, float) @ gamma
            continue
        Ad += [f.lag_a] * gamma.size
        Brows += list((1.0 - f.lag_a) * np.asarray(f.W, float).T)
        C += list(gamma)
        x0 += list(np.asarray(f.x0, float))
    return (np.diag(np.asarray(Ad, float)), np.vstack(Brows), np.asarray(C, float)[None, :],
            D[None, :], np.asarray(x0, float))
