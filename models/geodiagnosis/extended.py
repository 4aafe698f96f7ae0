"""The extended model of a mesh diagnosis as a compensator (issue 33 item 4): the
parametric reduced model (:mod:`.rom`) with the established causes built in, exported
as a version-2 state-space model (one output per displacement channel, the layout of
``docs/model-json.md``).

In the coordinates z of the reduced basis V (VᵀMV = I) the reduced model at a setting
(h, κ) is z' = −A_r(h, κ) z + L u_body, y = Gᵀ V z, A_r = Vᵀ A(h, κ) V from the kept
small matrices (:meth:`.rom.ReducedBody.operator`: no re-meshing, no factorisation).
With A_r = Y diag(μ) Yᵀ and the body inputs held over each interval Δτ (the contract's
zero-order hold), its exact discretisation is

    z_k = Y diag(e^{−μΔτ}) Yᵀ z_{k−1} + Y diag((1 − e^{−μΔτ})/μ) Yᵀ L T u_k,
    y_k = 10⁶ Gᵀ z_k                                                  [µm],

with T the body inputs per model input (u_body = T u). How each cause enters:

==================== ===================================================================
cause                in the exported model
==================== ===================================================================
convection_scale     h of its group × ``h_scale`` in A_r and in T's ambient column
                     (re-assembled at the fitted setting, every tabulated speed)
contact_conductance  the interface group's conductivity × ``conductivity_scale`` in A_r
source_scale         the source's column of T × ``scale``
missing_source       a load column on its candidate group, tied to what the fit tied it
                     to: ``speed_rpm`` × power_W / n_max of the record, else the sum of
                     the recorded inputs × power_W / their largest sum
ambient_lag          one more state, the ambient through a first-order lag of ``lag_h``
                     (exact for a held ambient), starting at the record's first ambient
warm_start           the initial state x0 = ΔT · Vᵀ M 1 (the record's start; a later
                     start of the machine is its own)
sensor_drift         not built in: a sensor's offset or drift is an error of the
                     measurement, not a displacement of the machine, and compensating
                     it would move the tool (as the rod's extended model,
                     docs/commands/compensate.md); a drift in time could not be built
                     in anyway (a ramp needs a state that never settles, which
                     model.json refuses)
==================== ===================================================================

Where h depends on the speed (h = a + b·n^m) the matrices are tabulated over the
speed (``speed_schedule``), at the record's distinct speeds (at most
:data:`MAX_SPEEDS`, else that many evenly over their range), all in the same z.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arfem.models.compensator import InputSpec, OutputSpec, SpeedSchedule, StateSpaceModel

__all__ = ["ExtendedExport", "export_reduced", "how_entered", "is_scheduled", "reads_speed",
           "MAX_SPEEDS"]

#: most speeds a schedule tabulates (as ``arfem run``'s export)
MAX_SPEEDS = 8


@dataclass(frozen=True)
class ExtendedExport:
    """A reduced model exported with causes built in, or why it could not be.

    Attributes
    ----------
    model : StateSpaceModel or None
    entered : tuple of (cause name, how it enters, built in: bool)
    note : str, why there is no model ('' when there is)
    """

    model: StateSpaceModel | None
    entered: tuple = ()
    note: str = ""


def how_entered(cause, params: dict) -> tuple[str, bool]:
    """How one fitted cause enters the exported model (module table), and whether it
    is built in at all.

    >>> from types import SimpleNamespace as N
    >>> how_entered(N(kind="convection_scale", target="housing", name="c"), {"h_scale": 2.0})
    ('h of housing x 2 in the re-assembled reduced model', True)
    """
    k, t = cause.kind, cause.target
    if k == "convection_scale":
        return f"h of {t} x {params['h_scale']:.4g} in the re-assembled reduced model", True
    if k == "contact_conductance":
        return (f"conductivity of {t} x {params['conductivity_scale']:.4g} in the "
                "re-assembled reduced model", True)
    if k == "source_scale":
        return f"input of {t} x {params['scale']:.4g}", True
    if k == "missing_source":
        return (f"a source of {params['power_W']:.4g} W at the record's largest input on "
                f"{t}, tied to the same input as in the fit", True)
    if k == "ambient_lag":
        return f"the ambient through a first-order lag of {params['lag_h']:.4g} h (one state)", True
    if k == "warm_start":
        return (f"initial state {params['initial_offset_K']:.4g} K above the reference "
                "everywhere (this record's start)", True)
    if k == "sensor_drift":
        return (f"not built in: the offset and drift of {t} are errors of the "
                "measurement, not displacements of the machine; compensating them would "
                "move the tool", False)
    return "not built in: unknown cause", False


def _missing_row(power_W: float, rec, m_src: list, spd: int | None, m: int) -> np.ndarray:
    """The row of T for a missing source's load column: what the fit's schedule
    (:func:`arfem.models.geodiagnosis.fit.make_context`) is linear in.

    Parameters
    ----------
    power_W : float, the fitted power at the record's largest input [W]
    m_src : list of int, the model inputs of the sources (``P_<source>_W``)
    spd : int or None, the model input ``speed_rpm``
    m : int, number of model inputs
    """
    row = np.zeros(m)
    p = power_W
    if np.any(rec.speed_rpm > 0):
        row[spd] = p / float(np.max(rec.speed_rpm))
    else:
        tot = float(np.max(rec.power_W.sum(axis=1)))
        if tot > 0:
            row[m_src] = p / tot
    return row


def is_scheduled(model, rec) -> bool:
    """True where some h depends on the speed and the record's speed varies."""
    return bool(np.any(model.h_law[:, 1] != 0.0)) and float(np.ptp(rec.speed_rpm)) > 0


def reads_speed(model, rec, fit) -> bool:
    """True where the exported model reads ``speed_rpm``: a schedule, or a missing
    source tied to the speed."""
    miss = any(c.kind == "missing_source" for c in (fit.causes if fit else ()))
    return is_scheduled(model, rec) or (miss and bool(np.any(rec.speed_rpm > 0)))


def _h_at(model, speed_rpm: float, h_scale) -> np.ndarray:
    a, b, mm = model.h_law.T
    return (a + b * np.power(max(speed_rpm, 0.0), mm)) * np.asarray(h_scale, float)


def _speeds(rec, scheduled: bool) -> np.ndarray:
    if not scheduled:
        return np.zeros(1)
    u = np.unique(np.maximum(rec.speed_rpm, 0.0))
    return u if u.size <= MAX_SPEEDS else np.linspace(u[0], u[-1], MAX_SPEEDS)


@dataclass(frozen=True)
class _Plan:
    """Everything of the export that does not depend on the speed."""

    T_fixed: np.ndarray        # (q, m): sources and candidates
    conv_col: int | None       # model input the convection ambient columns read
    follow: np.ndarray         # (G,) groups that follow the record's ambient
    out_idx: list
    d0: np.ndarray
    x0_z: np.ndarray
    lag_e: float | None        # e^{−Δτ/τ} of the ambient lag, None: no lag
    amb0: float


def _plan(model, rec, fit, dtau_s, out_idx, inputs_m: list):
    """(_Plan, entered) from the fitted causes; raises ValueError with the reason a
    cause cannot be expressed."""
    S, G = len(model.sources), len(model.convections)
    q = model.rb.L.shape[1]
    m = len(inputs_m)
    names = [n for n, _ in inputs_m]
    amb = names.index("ambient_C") if "ambient_C" in names else None
    spd = names.index("speed_rpm") if "speed_rpm" in names else None
    T = np.zeros((q, m))
    T[np.arange(S), np.arange(S)] = 1.0
    d0 = np.zeros(len(out_idx))
    x0 = np.zeros(model.rb.k)
    lag_e, entered = None, []
    for c, p in zip(fit.causes if fit else (), fit.params if fit else ()):
        how, built = how_entered(c, p)
        entered.append((c.name, how, built))
        if c.kind == "source_scale":
            j = model.sources.index(c.target)
            T[j, j] = p["scale"]
        elif c.kind == "missing_source":
            if np.any(rec.speed_rpm > 0) and spd is None:
                raise ValueError("the missing source follows speed_rpm, which the model "
                                 "does not read")
            T[S + G + model.candidates.index(c.target)] = _missing_row(
                p["power_W"], rec, list(range(S)), spd, m)
        elif c.kind == "ambient_lag":
            lag_e = float(np.exp(-dtau_s / (p["lag_h"] * 3600.0)))
        elif c.kind == "warm_start":
            x0 = p["initial_offset_K"] * np.asarray(model.rb.ones, float)
    own = np.asarray(model.convection_ambient_C, float)
    fixed = [g for g, o in zip(model.convection_groups, own)
             if np.isfinite(o) and o != model.reference_C]
    if fixed:
        raise ValueError(f"convection on {fixed[0]!r} has its own ambient, not the "
                         "reference; a constant forcing has no input of the model")
    amb0 = float(rec.ambient_C[0] - model.reference_C) if rec.ambient_C is not None else 0.0
    return _Plan(T, amb, np.isnan(own), list(out_idx), d0, x0, lag_e, amb0), entered


def _table(model, plan: _Plan, setting, speed_rpm: float, dtau_s: float):
    """(A, B) at one speed in the coordinates z (plus the lag state, if any)."""
    rb = model.rb
    S = len(model.sources)
    h = _h_at(model, speed_rpm, setting.h_scale)
    mu, Y = np.linalg.eigh(rb.operator(h, setting.kappa))
    mu = np.maximum(mu, 1e-300)
    e = np.exp(-mu * dtau_s)
    gain = -np.expm1(-mu * dtau_s) / mu
    Az = (Y * e) @ Y.T
    Bb = (Y * gain) @ (Y.T @ rb.L)                              # (k, q)
    T = plan.T_fixed.copy()
    hcol = np.where(plan.follow, h, 0.0)
    if plan.lag_e is None:
        if plan.conv_col is not None:
            T[S:S + len(h), plan.conv_col] = hcol
        return Az, Bb @ T
    b_amb = Bb[:, S:S + len(h)] @ hcol                          # (k,) per lagged kelvin
    el = plan.lag_e
    k = Az.shape[0]
    A = np.zeros((k + 1, k + 1))
    A[:k, :k], A[:k, k], A[k, k] = Az, el * b_amb, el
    B = np.vstack([Bb @ T, np.zeros((1, T.shape[1]))])
    B[:k, plan.conv_col] += (1.0 - el) * b_amb
    B[k, plan.conv_col] = 1.0 - el
    return A, B


def export_reduced(model, rec, fit, *, dtau_s: float, outputs, inputs, kind: str,
                   description: str, arfem_version: str = "",
                   fit_window_s=None) -> ExtendedExport:
    """The reduced model at ``fit``'s setting with its causes built in (module table).

    Parameters
    ----------
    model : GeoModel
        The parametric reduced model (the basis the fit ended on).
    rec : GeoRecord
        The record the causes were fitted on (its speeds tabulate a schedule; its first
        ambient starts a lag; a missing source's tie takes its largest input).
    fit : Fit or None
        The fitted causes (None: the nominal model in the same basis).
    dtau_s : float
        The interval [s] (the record's).
    outputs : sequence of (sensor output index, name, axis)
        The displacement outputs (``d_<sensor>_um``, axis X/Y/Z or a name).
    inputs : sequence of (name, unit)
        The model's inputs: one per source (``P_<source>_W``, in the model's source
        order), then ``ambient_C`` if the record has one, then ``speed_rpm`` where h
        depends on the speed or a missing source follows it.
    fit_window_s : (first, last) or None
        The rows the causes were fitted on [s].

    Returns
    -------
    ExtendedExport
        No model (and why) where a cause or the scenario cannot be expressed.
    """
    from arfem.models.geodiagnosis.problem import Setting
    out_idx = [o[0] for o in outputs]
    setting = fit.setting if fit is not None else Setting(np.ones(len(model.convections)),
                                                          np.ones(len(model.interfaces)))
    scheduled = is_scheduled(model, rec)
    try:
        plan, entered = _plan(model, rec, fit, dtau_s, out_idx, list(inputs))
    except ValueError as exc:
        return ExtendedExport(None, (), str(exc))
    C = 1e6 * np.asarray(model.rb.G, float)[:, out_idx].T
    x0 = plan.x0_z
    if plan.lag_e is not None:
        C = np.column_stack([C, np.zeros(len(out_idx))])
        x0 = np.concatenate([x0, [plan.amb0]])
    speeds = _speeds(rec, scheduled)
    tabs = [_table(model, plan, setting, float(n), dtau_s) for n in speeds]
    n_mean = float(np.mean(np.maximum(rec.speed_rpm, 0.0)))     # one speed: at it
    A0, B0 = _table(model, plan, setting, n_mean, dtau_s)
    p, m = len(out_idx), len(inputs)
    names = [n for n, _ in inputs]
    sched = None
    if scheduled:
        sched = SpeedSchedule("speed_rpm", np.asarray(speeds, float),
                              np.array([t[0] for t in tabs]), np.array([t[1] for t in tabs]),
                              np.zeros((len(speeds), p, m)))
    offsets = {"ambient_C": float(model.reference_C)} if "ambient_C" in names else {}
    sm = StateSpaceModel(
        kind=kind, dtau_s=float(dtau_s), A=A0, B=B0, C=C, D=np.zeros((p, m)),
        inputs=tuple(InputSpec(n, u) for n, u in inputs), x0=x0,
        d0_um=tuple(float(v) for v in plan.d0), description=description,
        arfem_version=arfem_version, input_offsets=offsets,
        outputs=tuple(OutputSpec(nm, "µm", ax) for _, nm, ax in outputs), schedule=sched,
        fit_window_s=None if fit_window_s is None else tuple(float(v) for v in fit_window_s))
    return ExtendedExport(sm, tuple(entered), "")
