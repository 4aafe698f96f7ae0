"""The reduced modal model of a body as a discrete-time state-space model (issue 32 item 5).

:func:`arfem.fem.thermal3d.body_modes` gives, for one set of convection coefficients h,
the M-orthonormal Ritz modes of M θ' + A(h) θ = F u with decay rates μ_i, the modal
loads F_k = Φᵀ F, the outputs per modal amplitude G_k = Φᵀ G and the static correction
D of the omitted modes. In modal amplitudes c the model is diagonal,

    c' = −diag(μ) c + F_k u,        y = G_kᵀ c + D u,

and with u held over each interval Δτ (zero-order hold, as the measured-data contract
reads a row's input: over the interval that ends at the row) its exact discretisation is

    c_k = e^{−μΔτ} c_{k−1} + (1 − e^{−μΔτ})/μ · F_k u_k,     y_k = G_kᵀ c_k + D u_k,

which is what :func:`arfem.fem.thermal3d.solve_body_reduced` advances between breakpoints:
for inputs constant over each interval and the same h, the two give the same outputs
to round-off. The model's inputs u_model map to the body's inputs by a matrix
(u = T u_model): each source's power or flux is one body input, and the ambient drives
every convection group that follows the cycle's ambient through h_g (θ_amb,g = T_amb −
T_ref), so its column of T is h_g on those groups.
"""
from __future__ import annotations

import numpy as np

from arfem.models.compensator import InputSpec, OutputSpec, SpeedSchedule, StateSpaceModel

__all__ = ["modal_state_space", "galerkin_modes", "speed_scheduled_state_space"]


def modal_state_space(mu, Fk, Gk, D_static, *, dtau_s: float, input_map, inputs,
                      outputs, output_scale: float = 1e6, input_offsets=None,
                      kind: str = "fem_modal", description: str = "",
                      arfem_version: str = "") -> StateSpaceModel:
    """The exact zero-order-hold discretisation of a diagonal modal model.

    Parameters
    ----------
    mu : array_like, shape (k,)
        Decay rates of the kept modes [1/s], > 0.
    Fk : array_like, shape (k, p_body)
        Modal load per unit body input [modal amplitude/s per input unit].
    Gk : array_like, shape (k, r)
        Output per unit modal amplitude of each of the r outputs [output unit].
    D_static : array_like, shape (r, p_body)
        Static correction of the omitted modes [output unit per input unit].
    dtau_s : float
        Interval Δτ [s].
    input_map : array_like, shape (p_body, m)
        Body inputs per model input (u_body = input_map @ u_model).
    inputs : sequence of (name, unit)
        The m model inputs.
    outputs : sequence of (name, axis)
        The r outputs (µm after ``output_scale``), each with its controller axis.
    output_scale : float
        Factor from the body's output unit to µm (1e6 for metres).
    input_offsets : dict, optional
        Input name → the reading's reference (e.g. ``ambient_C`` → the reference
        temperature the body's θ is counted from [°C]).

    Returns
    -------
    StateSpaceModel
        Version 2 (several outputs); A = diag(e^{−μΔτ}), x0 = 0 (the body starts at the
        reference temperature).

    Examples
    --------
    One mode, one input, one output: a first-order lag of gain 2 and rate 1e-3 /s.

    >>> m = modal_state_space([1e-3], [[1e-3]], [[2.0]], [[0.0]], dtau_s=60.0,
    ...                       input_map=[[1.0]], inputs=[("P_a_W", "W")],
    ...                       outputs=[("d_tcp_z_um", "Z")], output_scale=1.0)
    >>> round(float(m.A[0, 0]), 6), round(float(m.B[0, 0] * m.C[0, 0]), 6)
    (0.941765, 0.116471)
    >>> x = 0.0
    >>> for _ in range(10000):
    ...     x = m.A[0, 0] * x + m.B[0, 0] * 1.0
    >>> round(float(m.C[0, 0] * x), 9)        # the steady state: the static gain 2
    2.0
    """
    mu = np.asarray(mu, float)
    T = np.asarray(input_map, float)
    e = np.exp(-mu * float(dtau_s))
    gain = -np.expm1(-mu * float(dtau_s)) / mu              # (1 − e^{−μΔτ})/μ, exact
    B = (gain[:, None] * np.asarray(Fk, float)) @ T
    C = output_scale * np.asarray(Gk, float).T
    D = output_scale * np.asarray(D_static, float) @ T
    return StateSpaceModel(
        kind=kind, dtau_s=float(dtau_s), A=np.diag(e), B=B, C=C, D=D,
        inputs=tuple(InputSpec(n, u) for n, u in inputs), x0=np.zeros(mu.size),
        d0_um=tuple(0.0 for _ in outputs), description=description,
        arfem_version=arfem_version, input_offsets=dict(input_offsets or {}),
        outputs=tuple(OutputSpec(n, "µm", a) for n, a in outputs))


def galerkin_modes(V, A_h) -> tuple:
    """(μ, Y): the eigenpairs of the Galerkin projection Vᵀ A(h) V, ascending.

    Parameters
    ----------
    V : ndarray, shape (ndofs, k)
        M-orthonormal basis (the modes of another h) [-].
    A_h : sparse or ndarray, shape (ndofs, ndofs)
        Conductance operator at the new h [W/K per unit of the M-normalisation].

    Returns
    -------
    mu : ndarray (k,), decay rates [1/s]; Y : ndarray (k, k), orthonormal, the new modes
    are V Y. The same operations as :func:`arfem.fem.thermal3d.projected_modes`, so the
    same floats.
    """
    Ar = V.T @ (A_h @ V)
    return np.linalg.eigh(0.5 * (Ar + Ar.T))


def _discretised(mu, Y, Fr, D_static, T, dtau_s: float, scale: float) -> tuple:
    """(A, B, D) of one h in the shared coordinates z (see the module's docstring);
    Y None: the basis's own modes (A diagonal, exactly as :func:`modal_state_space`)."""
    mu = np.asarray(mu, float)
    e = np.exp(-mu * dtau_s)
    gain = -np.expm1(-mu * dtau_s) / mu
    T = np.asarray(T, float)
    if Y is None:
        A = np.diag(e)
        B = (gain[:, None] * Fr) @ T
    else:
        A = (Y * e) @ Y.T
        B = (Y @ (gain[:, None] * (Y.T @ Fr))) @ T
    return A, B, scale * np.asarray(D_static, float) @ T


def speed_scheduled_state_space(speeds_rpm, tables, nominal, Fr, Gr, *, dtau_s: float,
                                inputs, outputs, speed_input: str = "speed_rpm",
                                output_scale: float = 1e6, input_offsets=None,
                                kind: str = "fem_modal_speed", description: str = "",
                                arfem_version: str = "") -> StateSpaceModel:
    """A version-2 model whose A, B, D are tabulated over the spindle speed.

    Parameters
    ----------
    speeds_rpm : array_like, shape (K,)
        The tabulated speeds [1/min], strictly increasing.
    tables : sequence of (mu, Y, D_static, input_map), one per speed
        mu (k,) decay rates [1/s] and Y (k, k) the Galerkin eigenvectors in the shared
        basis (:func:`galerkin_modes`; Y None for the basis's own h), D_static (r,
        p_body) the static correction [output unit per input unit] and input_map
        (p_body, m) at that speed's h.
    nominal : (mu, Y, D_static, input_map)
        The same at the h the model's own A, B, D are given for (the plausible ranges'
        model, e.g. the time-weighted mean h).
    Fr : array_like, shape (k, p_body)
        Vᵀ F: the basis's loads per unit body input.
    Gr : array_like, shape (k, r)
        Vᵀ G: the outputs per unit amplitude of the basis.
    dtau_s, inputs, outputs, output_scale, input_offsets
        As :func:`modal_state_space`; ``inputs`` includes ``speed_input``, whose
        column of every input_map is zero (the speed acts through the matrices).

    Returns
    -------
    StateSpaceModel
        With :class:`SpeedSchedule` ``schedule``; x0 = 0.

    Examples
    --------
    One mode whose rate doubles from 0 to 1000 rpm; a speed between gets the matrices
    interpolated linearly in the speed.

    >>> one = lambda mu: ([mu], None, [[0.0]], [[1.0, 0.0]])
    >>> m = speed_scheduled_state_space([0.0, 1000.0], [one(1e-3), one(2e-3)], one(1e-3),
    ...         [[1e-3]], [[2.0]], dtau_s=60.0, inputs=[("P_a_W", "W"),
    ...         ("speed_rpm", "1/min")], outputs=[("d_tcp_z_um", "Z")], output_scale=1.0)
    >>> [round(float(a[0, 0]), 6) for a in m.schedule.A]
    [0.941765, 0.88692]
    >>> round(float(m.matrices(500.0)[0][0, 0]), 6)
    0.914342
    """
    Fr = np.asarray(Fr, float)
    dt = float(dtau_s)
    mats = [_discretised(mu, Y, Fr, Ds, T, dt, output_scale) for mu, Y, Ds, T in tables]
    A0, B0, D0 = _discretised(*nominal[:2], Fr, *nominal[2:], dt, output_scale)
    schedule = SpeedSchedule(speed_input, np.asarray(speeds_rpm, float),
                             *(np.array([m[i] for m in mats]) for i in range(3)))
    return StateSpaceModel(
        kind=kind, dtau_s=dt, A=A0, B=B0, C=output_scale * np.asarray(Gr, float).T, D=D0,
        inputs=tuple(InputSpec(n, u) for n, u in inputs), x0=np.zeros(Fr.shape[0]),
        d0_um=tuple(0.0 for _ in outputs), description=description,
        arfem_version=arfem_version, input_offsets=dict(input_offsets or {}),
        outputs=tuple(OutputSpec(n, "µm", a) for n, a in outputs), schedule=schedule)
