"""A causal thermal-error compensator: a discrete-time state-space model and one cycle.

The seed paper's §3.3 writes its AR(1) into the controller's temperature compensation
every interval (Siemens: position-independent compensation ``SD43900``, enabled by
``MD32750``): the offset sent each interval is minus the predicted growth. This module
holds the model in a form a compensator can run and the one function every cycle
calls, in replay and in live operation alike:

    x_k = A x_{k−1} + B u_k,      ŷ_k = C x_k + D u_k + d0            (growth [µm])
    u_k = map(reading_k − reference)        (``input_offsets``, ``input_maps``; optional)
    offset_k = clamp(−ŷ_k, ±max_offset_um), rate-limited to ±max_step_um per cycle

``u_k`` are the inputs read at interval k (the heat flux over the interval that ends
there, temperatures, …), so the offset for interval k uses inputs up to k only. The
paper's AR(1) (eq. 12) is the one-state case A = C1, B = C2 per unit q (eq. 13–14),
C = 1. A missing, stale or non-finite input holds the last offset and raises an alarm;
the state then advances with the last good inputs, so that it stays on time.

A measured growth (a touch probe) corrects the state by a Kalman update whose noises
come from the fit: Q the one-step innovation variance, R the measurement noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from arfem.params import InputError

__all__ = ["MODEL_VERSION", "InputSpec", "StateSpaceModel", "Cycle", "Compensator",
           "ar1_model", "fit_speed_ar1_model", "fit_mlr_model"]

#: version of the ``model.json`` layout this module reads and writes
MODEL_VERSION = 1


@dataclass(frozen=True)
class InputSpec:
    """One input the model reads: its name as in the measured-data contract, and unit."""

    name: str
    unit: str


@dataclass(frozen=True)
class StateSpaceModel:
    """A discrete-time linear model of the growth at the record's Δτ.

    Attributes
    ----------
    kind : str
        What it is, e.g. ``"paper_ar1"`` or ``"corrected_ar1"``.
    dtau_s : float
        Interval Δτ [s] the matrices belong to.
    A, B, C, D : ndarray
        (n, n), (n, m), (1, n), (1, m): state update and output; growth in [µm].
    d0_um : float
        Constant output term [µm].
    inputs : tuple of InputSpec
        The m inputs, in the order of the columns of B and D.
    x0 : ndarray
        Initial state (n,) [µm].
    Q, R : float
        Innovation variance of the state [µm²] and measurement noise variance [µm²],
        for the probe update.
    description : str
        Where the model comes from (paper equations, fit window).
    arfem_version : str
        The arfem that wrote it.
    input_maps : dict
        Input name → (x, y): a piecewise-linear map of that input (e.g. speed → C2).
    input_offsets : dict
        Input name → reference subtracted from the reading (e.g. the nominal ambient).
    fit_window_s : tuple of float, optional
        (first, last) sample time [s] of the rows the model was fitted on; None for a
        model that is not fitted (the paper's eqs. 13-14 from the rod's values).
    """

    kind: str
    dtau_s: float
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    inputs: tuple
    x0: np.ndarray
    d0_um: float = 0.0
    Q: float = 0.0
    R: float = 0.0
    description: str = ""
    arfem_version: str = ""
    input_maps: dict = field(default_factory=dict)
    input_offsets: dict = field(default_factory=dict)
    fit_window_s: tuple | None = None

    @property
    def n_states(self) -> int:
        return int(self.A.shape[0])

    def mapped(self, name: str, value: float) -> tuple[float, bool]:
        """An input as the matrices take it: minus its reference where the model has one
        (e.g. the ambient minus the nominal ambient the model was linearised about), then
        through its piecewise-linear map where the model has one (e.g. spindle speed →
        C2 of the speed's level, paper eq. 17), with linear extrapolation beyond the
        fitted points; True where it extrapolated."""
        value = value - self.input_offsets.get(name, 0.0)
        m = self.input_maps.get(name)
        if m is None:
            return value, False
        x, y = m
        if x.size == 1:
            return float(y[0]), value != x[0]
        if value < x[0] or value > x[-1]:
            i = 0 if value < x[0] else -2
            slope = (y[i + 1] - y[i]) / (x[i + 1] - x[i])
            return float(y[i] + slope * (value - x[i])), True
        return float(np.interp(value, x, y)), False

    def to_dict(self) -> dict:
        """The ``model.json`` document (``docs/model-json.md``)."""
        return {"model_version": MODEL_VERSION, "kind": self.kind, "dtau_s": self.dtau_s,
                "inputs": [{"name": i.name, "unit": i.unit} for i in self.inputs],
                "output": {"name": "growth_um", "unit": "µm"},
                "A": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(),
                "D": self.D.tolist(), "d0_um": self.d0_um, "x0": self.x0.tolist(),
                "noise": {"Q_um2": self.Q, "R_um2": self.R},
                "input_maps": {k: {"x": x.tolist(), "y": y.tolist()}
                               for k, (x, y) in self.input_maps.items()},
                "description": self.description, "arfem_version": self.arfem_version,
                **({"input_offsets": dict(self.input_offsets)} if self.input_offsets else {}),
                **({"fit_window_s": [float(v) for v in self.fit_window_s]}
                   if self.fit_window_s is not None else {})}

    @classmethod
    def from_dict(cls, d: dict, where: str = "model") -> "StateSpaceModel":
        """Validate a ``model.json`` document; :class:`InputError` names the key.

        Examples
        --------
        >>> m = ar1_model(0.99, 1e-4, dtau_s=30.0)
        >>> StateSpaceModel.from_dict(m.to_dict()).A.tolist()
        [[0.99]]
        >>> StateSpaceModel.from_dict({**m.to_dict(), "model_version": 7})
        Traceback (most recent call last):
        ...
        arfem.params.InputError: model: model_version: is 7; this arfem reads version 1
        """
        if not isinstance(d, dict):
            raise InputError("must be a JSON object", where)
        known = {"model_version", "kind", "dtau_s", "inputs", "output", "A", "B", "C", "D",
                 "d0_um", "x0", "noise", "input_maps", "input_offsets", "fit_window_s",
                 "description", "arfem_version"}
        extra = sorted(set(d) - known)
        if extra:
            raise InputError(f"unknown key {extra[0]!r}", where)
        if d.get("model_version") != MODEL_VERSION:
            raise InputError(f"is {d.get('model_version')!r}; this arfem reads version "
                             f"{MODEL_VERSION}", f"{where}: model_version")

        def mat(key, shape=None):
            try:
                a = np.asarray(d[key], float)
            except KeyError:
                raise InputError("missing", f"{where}: {key}") from None
            except (TypeError, ValueError):
                raise InputError("must be numbers", f"{where}: {key}") from None
            if not np.all(np.isfinite(a)):
                raise InputError("must be finite", f"{where}: {key}")
            if a.size == 0 and (shape is None or 0 in shape):
                # a model without state (the MLR): JSON keeps [] and [[]] of (0, m) etc.
                a = a.reshape(shape if shape is not None else (0, 0))
            if shape is not None and a.shape != shape:
                raise InputError(f"has shape {a.shape}, needs {shape}", f"{where}: {key}")
            return a

        dtau = d.get("dtau_s")
        if not isinstance(dtau, (int, float)) or not math.isfinite(dtau) or dtau <= 0:
            raise InputError(f"must be a positive number of seconds, got {dtau!r}",
                             f"{where}: dtau_s")
        ins = d.get("inputs")
        if not isinstance(ins, list) or not all(isinstance(i, dict) and isinstance(
                i.get("name"), str) and isinstance(i.get("unit"), str) for i in ins):
            raise InputError("must be a list of {name, unit}", f"{where}: inputs")
        A = mat("A")
        if A.ndim != 2 or A.shape[0] != A.shape[1]:
            raise InputError(f"must be square, got shape {A.shape}", f"{where}: A")
        n, m = A.shape[0], len(ins)
        B, C, D = mat("B", (n, m)), mat("C", (1, n)), mat("D", (1, m))
        x0 = mat("x0", (n,))
        if n and np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
            raise InputError("has an eigenvalue on or outside the unit circle: the model "
                             "would not settle", f"{where}: A")
        maps = {}
        for name, mp in (d.get("input_maps") or {}).items():
            key = f"{where}: input_maps.{name}"
            if name not in {i["name"] for i in ins}:
                raise InputError("maps an input the model does not read", key)
            try:
                x, y = np.asarray(mp["x"], float), np.asarray(mp["y"], float)
            except (KeyError, TypeError, ValueError):
                raise InputError("needs numeric lists x and y", key) from None
            if x.ndim != 1 or x.shape != y.shape or x.size == 0 or np.any(np.diff(x) <= 0) \
                    or not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
                raise InputError("x must increase strictly and match y, all finite", key)
            maps[name] = (x, y)
        offsets = {}
        for name, v in (d.get("input_offsets") or {}).items():
            key = f"{where}: input_offsets.{name}"
            if name not in {i["name"] for i in ins}:
                raise InputError("offsets an input the model does not read", key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(f"must be a finite number, got {v!r}", key)
            offsets[name] = float(v)
        fw = d.get("fit_window_s")
        if fw is not None:
            if not (isinstance(fw, list) and len(fw) == 2 and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool)
                    and math.isfinite(v) for v in fw) and fw[0] <= fw[1]):
                raise InputError(f"must be [first, last] sample times in seconds, got {fw!r}",
                                 f"{where}: fit_window_s")
            fw = (float(fw[0]), float(fw[1]))
        noise = d.get("noise") or {}
        return cls(kind=str(d.get("kind", "")), dtau_s=float(dtau), A=A, B=B, C=C, D=D,
                   inputs=tuple(InputSpec(i["name"], i["unit"]) for i in ins), x0=x0,
                   d0_um=float(d.get("d0_um", 0.0)), Q=float(noise.get("Q_um2", 0.0)),
                   R=float(noise.get("R_um2", 0.0)),
                   description=str(d.get("description", "")),
                   arfem_version=str(d.get("arfem_version", "")), input_maps=maps,
                   input_offsets=offsets, fit_window_s=fw)


def ar1_model(c1: float, c2_um_per_W_m2: float, *, dtau_s: float, kind: str = "paper_ar1",
              Q_um2: float = 0.0, R_um2: float = 0.0, description: str = "",
              arfem_version: str = "") -> StateSpaceModel:
    r"""The paper's AR(1) as a one-state model that a :class:`Compensator` can run.

    The state is the growth: :math:`\Delta L_k = C_1 \Delta L_{k-1} + C_2 q_k` (paper
    equation 12).

    Parameters
    ----------
    c1 : float
        :math:`C_1 = e^{-b\Delta\tau}` (paper eq. 13) [-], in [0, 1).
    c2_um_per_W_m2 : float
        C2 per unit heat flux (paper eq. 14 is linear in q) [µm per W/m²].
    dtau_s : float
        Interval Δτ [s].

    Returns
    -------
    StateSpaceModel
        Input ``q_W_m2``; output growth [µm].

    Examples
    --------
    >>> m = ar1_model(0.9909, 0.1985 / 2000, dtau_s=30.0)
    >>> c = Compensator(m)
    >>> round(c.step({"q_W_m2": 2000.0}).predicted_growth_um, 4)
    0.1985
    """
    return StateSpaceModel(kind=kind, dtau_s=float(dtau_s), A=np.array([[float(c1)]]),
                           B=np.array([[float(c2_um_per_W_m2)]]), C=np.array([[1.0]]),
                           D=np.zeros((1, 1)), inputs=(InputSpec("q_W_m2", "W/m²"),),
                           x0=np.zeros(1), Q=float(Q_um2), R=float(R_um2),
                           description=description, arfem_version=arfem_version)


@dataclass(frozen=True)
class Cycle:
    """What one compensator cycle decided.

    Attributes
    ----------
    offset_um : float
        The correction to write [µm] (−predicted growth, clamped and rate-limited).
    predicted_growth_um : float
        The model's growth [µm] (NaN where the inputs were not usable).
    alarms : tuple of str
        ``missing:NAME``, ``nonfinite:NAME``, ``stale:NAME`` (from the transport): the
        offset is held; ``clamped``, ``rate_limited``, ``extrapolated:NAME`` (an input
        beyond its map's fitted points): informative.
    held : bool
        True when the last offset was kept because an input was not usable.
    """

    offset_um: float
    predicted_growth_um: float
    alarms: tuple = ()
    held: bool = False


@dataclass
class Compensator:
    """Runs a :class:`StateSpaceModel` cycle by cycle; the same object in replay and live.

    Parameters
    ----------
    model : StateSpaceModel
    max_offset_um : float
        Limit on the absolute offset [µm] (the controller's compensation range).
    max_step_um : float
        Largest change of the offset per cycle [µm] (large jumps spoil the surface).
    """

    model: StateSpaceModel
    max_offset_um: float = math.inf
    max_step_um: float = math.inf
    x: np.ndarray = field(init=False)
    P: np.ndarray = field(init=False)
    offset_um: float = field(init=False, default=0.0)
    _u_last: np.ndarray | None = field(init=False, default=None)

    def __post_init__(self):
        for name in ("max_offset_um", "max_step_um"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0):
                raise InputError(f"must be > 0, got {v!r}", name)
        self.x = self.model.x0.astype(float).copy()
        self.P = np.zeros((self.model.n_states,) * 2)

    def step(self, inputs: Mapping[str, float | None], alarms=(), advance: bool = True) -> Cycle:
        """One cycle: read the inputs of interval k, advance the state, set the offset.

        Parameters
        ----------
        inputs : mapping
            Input name → value in the unit of :attr:`StateSpaceModel.inputs`; ``None``
            for a value the transport could not read.
        alarms : iterable of str
            Alarms from the transport (e.g. ``"stale:speed_rpm"``); any holds the offset.
        advance : bool
            False for a reading the machine's clock says is not new (stale): the offset
            is held and the state is not advanced, as no interval has passed.
        """
        mdl = self.model
        alarms = list(alarms)
        u = np.empty(len(mdl.inputs))
        for j, spec in enumerate(mdl.inputs):
            v = inputs.get(spec.name)
            if v is None:
                alarms.append(f"missing:{spec.name}")
                u[j] = np.nan
            else:
                try:
                    u[j] = float(v)
                except (TypeError, ValueError):
                    u[j] = np.nan
                if not math.isfinite(u[j]):
                    alarms.append(f"nonfinite:{spec.name}")
        usable = not alarms and advance
        notes = []
        if usable:
            for j, spec in enumerate(mdl.inputs):
                u[j], extrapolated = mdl.mapped(spec.name, u[j])
                if extrapolated:
                    notes.append(f"extrapolated:{spec.name}")
        if usable:
            self._u_last = u
        u_run = u if usable else self._u_last
        if u_run is not None and advance:        # keep the state on time
            self.x = mdl.A @ self.x + mdl.B @ u_run
            self.P = mdl.A @ self.P @ mdl.A.T + mdl.Q * np.eye(mdl.n_states)
        if not usable:
            return Cycle(self.offset_um, float("nan"), tuple(alarms), True)
        alarms += notes                           # informative: the offset is not held
        y = float((mdl.C @ self.x + mdl.D @ u)[0] + mdl.d0_um)
        want = -y
        if abs(want) > self.max_offset_um:
            want = math.copysign(self.max_offset_um, want)
            alarms.append("clamped")
        if abs(want - self.offset_um) > self.max_step_um:
            want = self.offset_um + math.copysign(self.max_step_um, want - self.offset_um)
            alarms.append("rate_limited")
        self.offset_um = float(want)
        return Cycle(self.offset_um, y, tuple(alarms), False)

    def probe(self, measured_growth_um: float) -> float:
        """Kalman update of the state with a measured growth [µm]; returns the gain.

        The prediction error is weighted by P Cᵀ / (C P Cᵀ + R); with R = 0 the state
        jumps to the measurement, with Q = 0 (P = 0) the probe changes nothing.
        """
        mdl = self.model
        if mdl.n_states == 0 or not math.isfinite(measured_growth_um):
            return 0.0
        u = self._u_last if self._u_last is not None else np.zeros(len(mdl.inputs))
        y = float((mdl.C @ self.x + mdl.D @ u)[0] + mdl.d0_um)
        s = float((mdl.C @ self.P @ mdl.C.T)[0, 0] + mdl.R)
        if s <= 0:
            return 0.0
        K = (self.P @ mdl.C.T)[:, 0] / s
        self.x = self.x + K * (measured_growth_um - y)
        self.P = (np.eye(mdl.n_states) - np.outer(K, mdl.C[0])) @ self.P
        return float(K @ mdl.C[0])


def _noise_var(y) -> float:
    d2 = np.diff(np.asarray(y, float), 2)
    d2 = d2[np.isfinite(d2)]
    return float(np.mean(d2 ** 2) / 6.0) if d2.size >= 10 else 0.0


def fit_speed_ar1_model(growth_um, speed_rpm, *, dtau_s: float,
                        description: str = "", arfem_version: str = "") -> StateSpaceModel:
    """The paper's AR(1) calibrated on a speed record (paper eq. 17) as a model.

    C1 is shared, one C2 is fitted per spindle speed seen; the speed → C2 map is
    piecewise linear through the fitted levels (a speed between two levels gets the
    interpolated C2, one beyond them the extrapolated value, flagged). The state noise Q
    is the variance of the one-step residual of the fit, R that of the measurement
    (second differences), for the probe update.

    Parameters
    ----------
    growth_um : array_like
        ΔL_0 … ΔL_N [µm], every Δτ, over the fit window.
    speed_rpm : array_like
        Speed on each of the N steps [1/min] (the row's value: over the interval ending
        there).
    dtau_s : float
        Sampling interval Δτ [s].

    Returns
    -------
    StateSpaceModel
        Input ``speed_rpm``, mapped to C2 [µm]; A = C1, B = 1, C = 1.

    Raises
    ------
    InputError
        If the fitted C1 is not in [0, 1) (the model would not settle).

    Examples
    --------
    >>> from arfem.models.ar1 import ar1_simulate
    >>> sp = np.repeat([0.0, 3000.0, 0.0, 6000.0, 0.0], 200)
    >>> g = ar1_simulate(0.99, np.where(sp == 3000, 0.1, np.where(sp == 6000, 0.25, 0.0)))
    >>> m = fit_speed_ar1_model(g, sp, dtau_s=15.0)
    >>> round(float(m.A[0, 0]), 4), [round(float(v), 4) for v in m.input_maps["speed_rpm"][1]]
    (0.99, [0.0, 0.1, 0.25])
    """
    from arfem.models.ar1 import fit_ar1
    g = np.asarray(growth_um, float)
    sp = np.asarray(speed_rpm, float)
    fit = fit_ar1(g, sp)
    if not 0.0 <= fit.c1 < 1.0:
        raise InputError(f"eq. 17 gives C1 = {fit.c1:.6g}, not in [0, 1): this AR(1) would "
                         "not settle, so it cannot run as a compensator", "growth_um")
    levels = np.array(sorted(fit.c2))
    return StateSpaceModel(
        kind="paper_ar1_speed", dtau_s=float(dtau_s), A=np.array([[fit.c1]]),
        B=np.array([[1.0]]), C=np.array([[1.0]]), D=np.zeros((1, 1)),
        inputs=(InputSpec("speed_rpm", "1/min"),), x0=np.zeros(1),
        Q=fit.residual_rms ** 2, R=_noise_var(g), description=description,
        arfem_version=arfem_version,
        input_maps={"speed_rpm": (levels, np.array([fit.c2[v] for v in levels]))})


def fit_mlr_model(growth_um, temperatures: dict, *, dtau_s: float, description: str = "",
                  arfem_version: str = "") -> StateSpaceModel:
    """Multiple linear regression of the growth on temperatures (paper eq. 18) as a
    static model: ŷ = β0 + Σ β_i T_i (no state; probes cannot correct it).

    Parameters
    ----------
    growth_um : array_like
        Growth [µm] over the fit window.
    temperatures : dict
        ``T_<name>_C`` → series [°C] on the same rows; series with a non-finite value are
        left out.
    dtau_s : float
        Sampling interval Δτ [s].

    Examples
    --------
    >>> T = np.linspace(20, 30, 100)
    >>> m = fit_mlr_model(3.0 * (T - 20) + 1.0, {"T_a_C": T}, dtau_s=60.0)
    >>> round(float(m.D[0, 0]), 6), round(m.d0_um, 6)
    (3.0, -59.0)
    """
    g = np.asarray(growth_um, float)
    names = [k for k, v in temperatures.items() if np.all(np.isfinite(np.asarray(v, float)))]
    if not names:
        raise InputError("no complete temperature series to regress on", "temperatures")
    X = np.column_stack([np.ones_like(g)] + [np.asarray(temperatures[k], float) for k in names])
    coef, *_ = np.linalg.lstsq(X, g, rcond=None)
    return StateSpaceModel(
        kind="mlr", dtau_s=float(dtau_s), A=np.zeros((0, 0)), B=np.zeros((0, len(names))),
        C=np.zeros((1, 0)), D=coef[1:][None, :], inputs=tuple(InputSpec(k, "°C") for k in names),
        x0=np.zeros(0), d0_um=float(coef[0]), description=description,
        arfem_version=arfem_version)
