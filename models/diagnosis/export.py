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

import numpy as np

from arfem.models.compensator import InputSpec, StateSpaceModel
from arfem.params import InputError

__all__ = ["fem_state_space", "speed_state_space", "NOT_LTI"]

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
                         "not a linear time-invariant model, so it is not exported",
                         "model_extended.json")
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
    A, B, C, x0 = [[a]], [[1.0 - a]], [1.0], [float(decay)]
    D = [0.0]
    offsets = {}
    k = int(gamma.size)
    if k:
        names, T, mu, W = _component_weights(info, k)
        inputs += [InputSpec(nm, "°C") for nm in names]
        offsets = {nm: float(m) for nm, m in zip(names, mu)}
        m = len(names)
        if st.sensor_lag_h > 0:
            al = float(np.exp(-dtau_s / (st.sensor_lag_h * 3600.0)))
            n = 1 + k
            A = np.diag([a] + [al] * k)
            B = np.zeros((n, 1 + m))
            B[0, 0] = 1.0 - a
            B[1:, 1:] = (1.0 - al) * W.T
            C = np.concatenate([[1.0], gamma])
            x0 = np.concatenate([[decay], (T[0] - mu) @ W])
            D = np.zeros(1 + m)
        else:
            A, B = np.array([[a]]), np.concatenate([[1.0 - a], np.zeros(m)])[None, :]
            D = np.concatenate([[0.0], W @ gamma])
    A, B = np.atleast_2d(np.asarray(A, float)), np.atleast_2d(np.asarray(B, float))
    return StateSpaceModel(
        kind="extended:frame_expansion(thermometers)", dtau_s=float(dtau_s), A=A, B=B,
        C=np.atleast_2d(np.asarray(C, float)), D=np.atleast_2d(np.asarray(D, float)),
        inputs=tuple(inputs), x0=np.asarray(x0, float), d0_um=float(c),
        Q=float(fit.rss / max(fit.n, 1)), R=float(R_um2), description=description,
        arfem_version=arfem_version, input_maps=maps, input_offsets=offsets)


def _speed_gain_table(seen, gains, W):
    """(speeds [1/min], steady gains [µm]) sorted by speed: the fitted gain of each seen
    speed and the mapped gain of each unseen one (weights ``W`` of eqs. 20-21)."""
    level_gain = {sv: g for sv, g in zip(seen, gains)}
    for lv, w in W.items():
        level_gain[float(lv)] = float(sum(wt * level_gain[float(sv)] for sv, wt in w.items()))
    xs = np.array(sorted(level_gain))
    return xs, np.array([level_gain[v] for v in xs])


def _component_weights(info, k):
    """The leading ``k`` principal components of the standardised temperatures as
    weights on the raw ones: (names, T (N, m) [°C], fit-window means μ (m,) [°C],
    W (m, k) [1/°C]) with component_j = Σ_i (T_i − μ_i) W_ij, as
    :func:`arfem.models.diagnosis.speed_frame.frame_components` makes them."""
    rows = np.asarray(info.rows, bool)
    names = [nm for nm, v in info.temps.items() if np.all(np.isfinite(np.asarray(v, float)))]
    T = np.column_stack([np.asarray(info.temps[nm], float) for nm in names])
    mu, sd = T[rows].mean(0), T[rows].std(0)
    sd[sd == 0] = 1.0
    Z = (T - mu) / sd
    lam, V = np.linalg.eigh(Z[rows].T @ Z[rows])
    lam, V = lam[::-1], V[:, ::-1]
    scale = np.array([max(np.sqrt(max(lam[j], 0.0) / rows.sum()), 1e-12) for j in range(k)])
    return names, T, mu, V[:, :k] / sd[:, None] / scale[None, :]
