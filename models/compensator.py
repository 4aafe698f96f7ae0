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

``model_version`` 2 (issue 32) has several outputs, one per controller axis (the tool
centre point's drift in X, Y, Z of a spindle unit from a mesh): C is p × n, D p × m,
d0 a p-vector, and each output carries the axis its offset is written to. The cycle is
the same, per axis: offset_j = clamp(−ŷ_j, ±max_offset_j), rate-limited to
±max_step_j; an unusable input holds every axis (they share the inputs), a clamp or a
rate limit is that axis's alarm (``clamped@X``). A version-1 model is one axis: the
same per-axis clamp and rate limit run it (the same floats as before), its alarms
untagged.

What the controller holds (issue 40): the rate limit of each axis counts from the value
that axis of the controller holds, given by a transport to
:meth:`Compensator.resume_axis`, the one rule every transport calls: a value inside
the axis's clamp is adopted; one beyond it, or not a finite number, is not -- the axis
is held (``held_beyond_clamp`` / ``held_nonfinite``, offset NaN: not to be written) until
the controller is seen holding a value inside; a read-back that differs from what was
last set is ``external_change`` and the ramp starts from it. No offset beyond the clamp
is ever produced, nor one more than a step from a value the controller was seen holding.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from dataclasses import replace as _with_fields
from typing import Mapping

import numpy as np

from arfem.models.observer import ObserverRun
from arfem.models.speed_table import at_speed
from arfem.params import InputError
from arfem.strict import is_json_number
from arfem.ranges import RANGES, reading_quantity, reading_range

__all__ = ["InputSpec", "OutputSpec", "GROWTH_AXIS",
           "StateSpaceModel", "SpeedSchedule", "AxisCycle", "Cycle", "Compensator", "ar1_model",
           "fit_speed_ar1_model", "fit_mlr_model", "noise_var_um2",
           "plausible_ranges", "propagate", "INFORMATIVE", "alarm_kind", "check_reading"]

@dataclass(frozen=True)
class InputSpec:
    """One input the model reads: its name as in the measured-data contract, and unit."""

    name: str
    unit: str


@dataclass(frozen=True)
class OutputSpec:
    """One output of a version-2 model: its name (the record's column, ``d_<sensor>_um``),
    unit (µm) and the controller axis its offset is written to (``"X"``, ``"Y"``,
    ``"Z"``, or any other axis name)."""

    name: str
    unit: str
    axis: str


#: The one axis of a version-1 model: its output ``growth_um`` [µm], the axis named after
#: it (``growth``); a replay, a report and a live loop treat it as any other axis.
GROWTH_AXIS = OutputSpec("growth_um", "µm", "growth")


@dataclass(frozen=True)
class SpeedSchedule:
    """A version-2 model's matrices tabulated over the spindle speed (issue 32).

    Where a convection coefficient depends on the speed (h = a + b·n^m) the model is
    not time-invariant: ``A``, ``B`` and ``D`` are tabulated at the speeds ``speeds_rpm``
    in ONE set of state coordinates (C is shared), so the state carries over when the
    speed changes. Between two tabulated speeds each matrix is interpolated linearly in
    the speed (each tabulated A of an exported modal model is symmetric with eigenvalues
    in (0, 1), and so is every convex combination of them: the interpolated model
    settles); outside them the end's matrices are used and :meth:`at` says so (the
    compensator's ``outside_schedule:<input>`` alarm): never extrapolated.

    Attributes
    ----------
    input : str
        The model input whose raw reading selects the matrices (``speed_rpm`` [1/min]).
    speeds_rpm : ndarray, shape (K,)
        Tabulated speeds [1/min], strictly increasing, K >= 2.
    A : ndarray, shape (K, n, n)
    B : ndarray, shape (K, n, m)
    D : ndarray, shape (K, p, m)
        The matrices at each speed (as the model's A, B, D).
    """

    input: str
    speeds_rpm: np.ndarray
    A: np.ndarray
    B: np.ndarray
    D: np.ndarray

    def at(self, speed_rpm: float) -> tuple:
        """(A, B, D, outside): the matrices at ``speed_rpm``, linear in the speed
        between two tabulated speeds, the end's beyond them (``outside`` True).

        Examples
        --------
        >>> s = SpeedSchedule("speed_rpm", np.array([0.0, 1000.0]),
        ...                   np.array([[[0.5]], [[0.9]]]), np.ones((2, 1, 1)),
        ...                   np.zeros((2, 1, 1)))
        >>> float(s.at(250.0)[0][0, 0]), s.at(250.0)[3]
        (0.6, False)
        >>> float(s.at(2000.0)[0][0, 0]), s.at(2000.0)[3]
        (0.9, True)
        """
        (A, B, D), outside = at_speed(self.speeds_rpm, (self.A, self.B, self.D), speed_rpm)
        return A, B, D, outside


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
        (n, n), (n, m), (p, n), (p, m): state update and output; growth in [µm]; p = 1
        for version 1, the number of ``outputs`` for version 2.
    d0_um : float or tuple of float
        Constant output term [µm]: a float (version 1) or one per output (version 2).
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
    outputs : tuple of OutputSpec
        Version 2: the p outputs, in the order of the rows of C and D, each with its
        axis; empty for version 1 (the one output ``growth_um``).
    schedule : SpeedSchedule, optional
        Version 2: A, B, D tabulated over the speed (:class:`SpeedSchedule`); the
        compensator then steps the matrices of each interval's speed, and A, B, D above
        are the nominal ones (for the plausible ranges; the export's: at the
        time-weighted mean h). None: time-invariant.
    observer : Observer, optional
        Version 2: the thermometers' observer (:mod:`arfem.models.observer`, issue 43):
        the compensator corrects the state from the ``T_<sensor>_C`` readings each
        cycle. None: open loop.
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
    outputs: tuple = ()
    schedule: SpeedSchedule | None = None
    observer: object = None

    def matrices(self, speed_rpm: float | None = None) -> tuple:
        """(A, B, D, outside): the matrices of an interval at ``speed_rpm`` (the raw
        reading of the schedule's input); the model's own where it has no schedule or
        no speed is known."""
        if self.schedule is None or speed_rpm is None:
            return self.A, self.B, self.D, False
        return self.schedule.at(speed_rpm)

    @property
    def n_states(self) -> int:
        return int(self.A.shape[0])

    @property
    def version(self) -> int:
        """``model_version``: 2 for a model with named outputs, else 1."""
        return 2 if self.outputs else 1

    @property
    def axes(self) -> tuple:
        """The axis of each output (version 2); () for version 1."""
        return tuple(o.axis for o in self.outputs)

    @property
    def axis_outputs(self) -> tuple:
        """Every axis the model compensates, as :class:`OutputSpec`: a version-2 model's
        ``outputs``; a version-1 model's one axis, named after its output ``growth_um``
        (:data:`GROWTH_AXIS`)."""
        return self.outputs or (GROWTH_AXIS,)

    def d0_vector(self) -> np.ndarray:
        """The constant output term as a (p,) array [µm]."""
        return np.atleast_1d(np.asarray(self.d0_um, float))

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


#: alarm kinds that do not hold the offset (the part before ``:``); every other alarm is
#: a fault the operator must see
INFORMATIVE = frozenset({"clamped", "rate_limited", "extrapolated", "outside_schedule"})

#: a value read back from the controller that differs from the one this compensator
#: last set by more than this, relative to max(1 µm, |value|), is an external change (a
#: Float node rounds a Double to about 6e-8 relative; anything more was done by someone)
READBACK_TOLERANCE = 1e-6

#: no spindle's thermal growth reaches 1 mm: an input whose steady-state share of the
#: predicted growth would exceed this is not a reading [µm] (the growth's range in the
#: one table of ranges, :data:`arfem.ranges.RANGES`)
PLAUSIBLE_GROWTH_UM = RANGES["growth_um"][1]

#: missed intervals up to this many are stepped one by one (the same floats as a replay
#: that saw them); more are stepped in closed form (:func:`propagate`)
EXACT_STEPS = 64


def propagate(A: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A^k, Σ_{j<k} A^j and Σ_{j<k} A^j (A^j)ᵀ by binary doubling: O(log k) products.

    Advancing ``x ← A x + B u`` k times with a constant ``u`` gives
    ``A^k x + (Σ A^j) B u``; the covariance ``P ← A P Aᵀ + Q I`` gives
    ``A^k P (A^k)ᵀ + Q Σ A^j (A^j)ᵀ``. Used for a machine clock that jumped (issue 28):
    a jump of 1e15 s costs about 50 products, not one loop turn per interval.

    Parameters
    ----------
    A : ndarray (n, n)
        State matrix (spectral radius < 1 for a model that settles).
    k : int
        Number of intervals, >= 0.

    Examples
    --------
    >>> Ak, G, S = propagate(np.array([[0.5]]), 3)
    >>> float(Ak[0, 0]), float(G[0, 0]), float(S[0, 0])
    (0.125, 1.75, 1.3125)
    """
    n = A.shape[0]
    eye = np.eye(n)
    rp, rg, rs = eye, np.zeros((n, n)), np.zeros((n, n))     # k = 0
    bp, bg, bs = A.astype(float), eye, eye                   # k = 1
    k = int(k)
    while k > 0:
        if k & 1:                                            # r ∘ b: r's steps, then b's
            rp, rg, rs = bp @ rp, rg + rp @ bg, rs + rp @ bs @ rp.T
        k >>= 1
        if k:
            bp, bg, bs = bp @ bp, bg + bp @ bg, bs + bp @ bs @ bp.T
    return rp, rg, rs


def check_reading(name: str, v, ranges: Mapping | None) -> tuple[float, str | None]:
    """A raw reading as a float and what is wrong with it: ``missing:NAME`` (None),
    ``nonfinite:NAME`` (not a finite number), ``out_of_range:NAME`` (outside
    ``ranges[name]``, where ``ranges`` has it), or None. The one check of every
    reading the compensator takes: the model's inputs and the observer's thermometers.

    >>> check_reading("T_a_C", 200.0, {"T_a_C": (-10.0, 150.0)})
    (200.0, 'out_of_range:T_a_C')
    >>> check_reading("P_a_W", None, None)
    (nan, 'missing:P_a_W')
    """
    if v is None:
        return math.nan, f"missing:{name}"
    try:
        x = float(v)
    except (TypeError, ValueError):
        x = math.nan
    if not math.isfinite(x):
        return x, f"nonfinite:{name}"
    if ranges is not None and name in ranges:
        lo, hi = ranges[name]
        if not lo <= x <= hi:
            return x, f"out_of_range:{name}"
    return x, None


def plausible_ranges(model: "StateSpaceModel", overrides: Mapping | None = None) -> dict:
    """The range [lo, hi] each input's raw reading must lie in to be fed to the state.

    A reading outside is a bad reading (``out_of_range:NAME``: the offset is held, the
    state never sees it; issue 28). The ranges are the one table's
    (:func:`arfem.ranges.reading_range`, which the record reader applies to every
    record replayed or diagnosed), narrowed by the model:

    * a heat input (``q_*`` or a unit in W/m²: 0 to 1e7 W/m²; ``P_*_W`` or a unit in
      W: 0 to 1 MW);
    * a speed (``*_rpm``): 0 to twice the fastest speed of its map or speed schedule (or
      the table's 100 000 /min);
    * an ambient temperature (``ambient*``): -10 to 50 °C; any other ``*_C``: -10 to
      150 °C;
    * every other input whose share of the steady-state growth, C (I − A)⁻¹ B + D per
      unit, is known: no more than :data:`PLAUSIBLE_GROWTH_UM` (1 mm) of growth.

    ``overrides`` maps an input name to ``(lo, hi)`` (the config's ``[live.ranges]``).

    Examples
    --------
    >>> m = ar1_model(0.99, 1e-4, dtau_s=60.0)
    >>> lo, hi = plausible_ranges(m)["q_W_m2"]
    >>> lo, round(hi)
    (0.0, 100000)
    """
    n = model.n_states
    if n:
        dc = model.C @ np.linalg.solve(np.eye(n) - model.A, model.B) + model.D
    else:
        dc = model.D
    # one output: its row; several: each input's largest share over the outputs
    dc = dc[0] if not model.outputs else np.max(np.abs(dc), axis=0)
    out = {}
    # the observer's thermometers (issue 43) by the same rules (no growth share)
    therm = [InputSpec(t, "°C") for t in (model.observer.thermometers
                                          if model.observer is not None else ())]
    dc = np.concatenate([np.asarray(dc, float), np.zeros(len(therm))])
    for j, spec in enumerate(tuple(model.inputs) + tuple(therm)):
        nm, unit = spec.name, spec.unit
        kind = reading_quantity(nm, unit)
        lo, hi = reading_range(nm, unit)
        if kind == "speed_rpm":
            m = model.input_maps.get(nm)
            if m is None and model.schedule is not None and model.schedule.input == nm:
                m = (model.schedule.speeds_rpm,)        # its tabulated speeds
            if m is not None:
                hi = 2.0 * max(float(m[0][-1]), 1.0)
        elif kind not in ("ambient_C", "temperature_C") and nm not in model.input_maps \
                and abs(dc[j]) > 0:
            ref = model.input_offsets.get(nm, 0.0)
            half = PLAUSIBLE_GROWTH_UM / abs(float(dc[j]))
            lo, hi = max(lo, ref - half), min(hi, ref + half)
        out[nm] = (float(lo), float(hi))
    for nm, (lo, hi) in (overrides or {}).items():
        out[nm] = (float(lo), float(hi))
    return out


@dataclass(frozen=True)
class AxisCycle:
    """What one cycle decided for one axis of a version-2 model.

    Attributes
    ----------
    axis : str
        The controller axis (``"X"``, ``"Y"``, ``"Z"``).
    output : str
        The model's output it compensates (``d_tcp_x_um``).
    offset_um : float
        The correction to write on this axis [µm] (−predicted, clamped and
        rate-limited by this axis's limits; held where the inputs were not usable).
    predicted_um : float
        The model's output [µm] (NaN where the inputs were not usable).
    alarms : tuple of str
        This axis's own alarms: ``clamped``, ``rate_limited`` (informative),
        ``held_beyond_clamp`` / ``held_nonfinite`` (the controller holds a value this
        compensator does not adopt: the axis is not written), ``external_change`` (a
        read-back differed from what this compensator last set), and any a transport adds
        for it (``write_refused:STATUS``).
    held : bool
        True when this axis is not to be written this cycle: its ``offset_um`` is then
        what it holds (an input fault, every axis), or NaN where the controller holds a
        value beyond the clamp or not a number (:meth:`Compensator.resume_axis`).
    """

    axis: str
    output: str
    offset_um: float
    predicted_um: float
    alarms: tuple = ()
    held: bool = False


@dataclass(frozen=True)
class Cycle:
    """What one compensator cycle decided.

    Attributes
    ----------
    offset_um : float
        The correction to write [µm] (−predicted growth, clamped and rate-limited).
        NaN for a version-2 model (its offsets are per axis, in ``axes``), and where the
        controller holds a value beyond the clamp or not a number (nothing is written).
    predicted_growth_um : float
        The model's growth [µm] (NaN where the inputs were not usable, and for a
        version-2 model).
    alarms : tuple of str
        ``missing:NAME``, ``nonfinite:NAME``, ``out_of_range:NAME``, ``stale:NAME`` and
        any other alarm from the transport: the offset is held; ``clamped``,
        ``rate_limited``, ``extrapolated:NAME`` (an input beyond its map's fitted points):
        informative (:data:`INFORMATIVE`). A version-2 model's axis alarms appear here
        too, tagged with their axis (``clamped@X``, ``write_refused@Y:BadNotWritable``).
    held : bool
        True when the last offset was kept because an input was not usable (every axis
        is held: they share the inputs); for a version-1 model also while the controller
        holds a value beyond the clamp or not a number (``offset_um`` NaN: nothing to
        write). A version-2 model's axis held alone says so in its :class:`AxisCycle`.
    axes : tuple of AxisCycle
        Version 2: one per output, in the model's order; () for version 1.
    observer : Correction, optional
        What the thermometers' observer corrected this cycle (the disturbance estimates
        in W and K, the innovations; :class:`arfem.models.observer.Correction`); None
        without an observer or in a held cycle.
    """

    offset_um: float
    predicted_growth_um: float
    alarms: tuple = ()
    held: bool = False
    axes: tuple = ()
    observer: object = None

    def per_axis(self) -> tuple:
        """Every axis of the cycle, each with ``axis``, ``output``, ``offset_um``,
        ``predicted_um``, ``alarms`` and ``held`` (:class:`AxisCycle`): ``axes``, or a
        version-1 model's one axis (:data:`GROWTH_AXIS`), which is the cycle itself, so
        that one loop serves one axis and several."""
        return self.axes or (self,)

    @property
    def axis(self) -> str:
        """A version-1 cycle as its one axis: the axis's name (:data:`GROWTH_AXIS`)."""
        return GROWTH_AXIS.axis

    @property
    def output(self) -> str:
        """A version-1 cycle as its one axis: its output, ``growth_um``."""
        return GROWTH_AXIS.name

    @property
    def predicted_um(self) -> float:
        """A version-1 cycle as its one axis: the predicted growth [µm]."""
        return self.predicted_growth_um

    def axis_alarms(self, axis: str) -> tuple:
        """The alarms that concern ``axis``: every alarm not tagged with an axis (the
        inputs', the transport's) and this axis's own, untagged."""
        own = next((a.alarms for a in self.axes if a.axis == axis), ())
        return tuple(a for a in self.alarms if "@" not in a.split(":")[0]) + own

    def with_axis_alarm(self, axis: str, alarm: str) -> "Cycle":
        """This cycle with ``alarm`` added to ``axis`` (and to :attr:`alarms`, tagged)."""
        axes = tuple(_with_fields(a, alarms=a.alarms + (alarm,)) if a.axis == axis else a
                     for a in self.axes)
        kind, _, rest = alarm.partition(":")
        tagged = f"{kind}@{axis}" + (f":{rest}" if rest else "")
        return _with_fields(self, alarms=self.alarms + (tagged,), axes=axes)


def alarm_kind(alarm: str) -> str:
    """An alarm's kind: the part before ``:`` and before an axis tag ``@``.

    >>> alarm_kind("clamped@X"), alarm_kind("missing:q_W_m2"), alarm_kind("clamped")
    ('clamped', 'missing', 'clamped')
    """
    return alarm.split(":")[0].split("@")[0]


@dataclass
class Compensator:
    """Runs a :class:`StateSpaceModel` cycle by cycle; the same object in replay and live.

    Parameters
    ----------
    model : StateSpaceModel
    max_offset_um : float or tuple of float
        Limit on the absolute offset [µm] (the controller's compensation range); for a
        version-2 model one per axis (in the order of its outputs) or one for all.
    max_step_um : float or tuple of float
        Largest change of the offset per cycle [µm] (large jumps spoil the surface); per
        axis as ``max_offset_um``.
    ranges : mapping, optional
        Input name → (lo, hi): the plausible range of its raw reading
        (:func:`plausible_ranges`); a reading outside is ``out_of_range:NAME``, held and
        never fed to the state. None (replay's default): no range check.
    use_observer : bool
        Run the model's thermometer observer (``model.observer``, issue 43) where it has
        one (default); False runs it open loop, exactly as a model without one.

    Notes
    -----
    A version-1 model is one axis: both versions go through the same clamp and rate
    limit (:meth:`_axis_offset`), per axis. :attr:`offsets_um` holds, per axis, the
    offset the controller holds -- the rate limit counts from it -- and
    :attr:`offset_um` is the one axis of a version-1 model. A transport that reads the
    controller's value back (on start, on reconnect, every cycle, after a refused write)
    or is told it (a JSON line, the log's warm start) passes it to :meth:`resume_axis`
    (:meth:`resume` for every axis), the one rule for adopting it: a value inside the
    axis's clamp is adopted and the next offset is at most the axis's step from it; a
    value beyond the clamp or not a finite number is NOT adopted: the axis raises
    ``held_beyond_clamp`` or ``held_nonfinite`` and is not written (its offset is NaN)
    until the controller is seen holding a value inside the clamp (the operator brings it
    there; ``docs/safety.md``). No offset beyond the clamp is ever produced, and none more
    than a step from a value the controller was seen holding.
    """

    model: StateSpaceModel
    max_offset_um: float | tuple = math.inf
    max_step_um: float | tuple = math.inf
    ranges: Mapping | None = None
    use_observer: bool = True
    x: np.ndarray = field(init=False)
    P: np.ndarray = field(init=False)
    offsets_um: np.ndarray = field(init=False)
    _u_last: np.ndarray | None = field(init=False, default=None)
    _speed_last: float | None = field(init=False, default=None)
    _held: list = field(init=False)             # per axis: None, or why it is not written
    _events: list = field(init=False)           # per axis: alarms for the next cycle
    _known: list = field(init=False)            # per axis: its value set or adopted
    _d0: np.ndarray = field(init=False)
    _lims: tuple = field(init=False)
    _observer: object = field(init=False, default=None)

    def __post_init__(self):
        p = len(self.model.outputs)
        for name in ("max_offset_um", "max_step_um"):
            v = getattr(self, name)
            vals = v if (p and isinstance(v, (tuple, list))) else (v,)
            if p and len(vals) not in (1, p):
                raise InputError(f"needs one value per axis ({p}), got {len(vals)}", name)
            for x in vals:
                if not (isinstance(x, (int, float)) and x > 0):
                    raise InputError(f"must be > 0, got {x!r}", name)
        self.x = self.model.x0.astype(float).copy()
        self.P = np.zeros((self.model.n_states,) * 2)
        n_axes = max(p, 1)                          # version 1: one axis
        self._d0 = self.model.d0_vector()           # (the model is frozen)
        self._lims = (None, [])                     # (limits' fields, per axis), cached
        self.offsets_um = np.zeros(n_axes)
        self._held = [None] * n_axes
        self._events = [[] for _ in range(n_axes)]
        self._known = [False] * n_axes              # (0 at a cold start is assumed)
        if self.use_observer and self.model.observer is not None:
            self._observer = ObserverRun(self.model.observer)

    @property
    def offset_um(self) -> float:
        """The offset the controller holds [µm], of a version-1 model's one axis (NaN
        while it holds a value that is not adopted)."""
        return float(self.offsets_um[0])

    def held_reason(self, j: int) -> str | None:
        """Why axis ``j`` is not written (``held_beyond_clamp``, ``held_nonfinite``:
        the controller holds a value :meth:`resume_axis` did not adopt), or None."""
        return self._held[j]

    def limits(self, j: int) -> tuple[float, float]:
        """(max_offset_um, max_step_um) of axis ``j`` [µm] (0 for a version-1 model)."""
        key = (self.max_offset_um, self.max_step_um)
        if self._lims[0] != key:                    # computed once per value of the fields
            per = []
            for v in key:
                vals = v if isinstance(v, (tuple, list)) else (v,)
                per.append([float(vals[i] if len(vals) > 1 else vals[0])
                            for i in range(len(self.offsets_um))])
            self._lims = (key, list(zip(*per)))
        return self._lims[1][j]

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
            u[j], bad = check_reading(spec.name, inputs.get(spec.name), self.ranges)
            if bad:
                alarms.append(bad)
        usable = not alarms and advance
        notes = []
        if usable:
            if mdl.schedule is not None:             # the raw speed selects the matrices
                self._speed_last = float(u[self._schedule_column()])
            for j, spec in enumerate(mdl.inputs):
                u[j], extrapolated = mdl.mapped(spec.name, u[j])
                if extrapolated:
                    notes.append(f"extrapolated:{spec.name}")
        if usable:
            self._u_last = u
        u_run = u if usable else self._u_last
        # a speed schedule: the matrices of this interval's speed (the last good one
        # where the inputs are not usable), the end's beyond the tabulated speeds
        A, B, D, outside = mdl.matrices(self._speed_last)
        if outside and usable:
            notes.append(f"outside_schedule:{mdl.schedule.input}")
        if u_run is not None and advance:        # keep the state on time
            self.x = A @ self.x + B @ u_run
            if mdl.Q or self.P.any():             # P = 0 stays 0 with Q = 0 (exactly):
                self.P = A @ self.P @ A.T + mdl.Q * np.eye(mdl.n_states)  # skip n³ work
        if not usable:
            return self._axes_cycle(None, alarms)
        if self._observer is not None:          # the thermometers correct the state
            return self._observed(inputs, u, B, D, alarms + notes)   # first (issue 43)
        return self._axes_cycle(u, alarms + notes, D)   # notes: informative, not held

    def _observed(self, inputs: Mapping, u: np.ndarray, B: np.ndarray, D: np.ndarray,
                  alarms: list) -> "Cycle":
        """A version-2 cycle with the observer's measurement update first
        (:meth:`ObserverRun.correct <arfem.models.observer.ObserverRun.correct>`): each
        thermometer is checked as an input is (:func:`check_reading`; a bad one is held
        -- its correction not made -- and its alarm raised, the offset not held), the
        state corrected, and the outputs computed with the inputs plus the estimated
        disturbances (which held cycles and unseen intervals after it also use)."""
        ob = self._observer.observer
        readings = []
        for name in ob.thermometers:
            v, bad = check_reading(name, inputs.get(name), self.ranges)
            readings.append(None if bad else v)
            if bad:
                alarms.append(bad)
        self.x, u_eff, corr = self._observer.correct(self.x, u, B, self._speed_last,
                                                     readings)
        self._u_last = u_eff
        return _with_fields(self._axes_cycle(u_eff, alarms, D), observer=corr)

    def _schedule_column(self) -> int:
        """The column of the speed schedule's input among the model's inputs."""
        return [i.name for i in self.model.inputs].index(self.model.schedule.input)

    def _axes_cycle(self, u, alarms: list, D=None) -> Cycle:
        """A cycle: each axis's offset from its output (:meth:`_axis_offset`), counted
        from what that axis holds; ``u`` None: every axis held. A version-1 model is one
        axis whose alarms are not tagged and whose offset is the cycle's; a version-2
        model tags each axis's alarms (``clamped@X``). ``D``: the interval's (a speed
        schedule's), else the model's."""
        mdl = self.model
        y = None
        if u is not None:
            y = mdl.C @ self.x + (mdl.D if D is None else D) @ u + self._d0
        if not mdl.outputs:                         # version 1: the cycle is the axis
            off, own = self._axis_result(0, None if y is None else -float(y[0]))
            return Cycle(off, math.nan if y is None else float(y[0]),
                         tuple(alarms + own) if own else tuple(alarms),
                         y is None or math.isnan(off))
        axes = []
        for j, o in enumerate(mdl.outputs):
            off, own = self._axis_result(j, None if y is None else -float(y[j]))
            alarms += [f"{a.split(':')[0]}@{o.axis}" + (":" + a.split(":", 1)[1]
                                                         if ":" in a else "") for a in own]
            axes.append(AxisCycle(o.axis, o.name, off, math.nan if y is None else float(y[j]),
                                  tuple(own), y is None or math.isnan(off)))
        return Cycle(math.nan, math.nan, tuple(alarms), y is None, tuple(axes))

    def _axis_result(self, j: int, want: float | None) -> tuple[float, list]:
        """Axis ``j``'s offset and own alarms this cycle: :meth:`_axis_offset` of the
        wanted correction, or (``want`` None: the inputs were not usable) what it holds,
        with its hold's alarm; then the events seen since the last cycle
        (``external_change``)."""
        if want is not None:
            off, own = self._axis_offset(j, want)
        else:
            off, own = float(self.offsets_um[j]), ([] if self._held[j] is None
                                                   else [self._held[j]])
        if self._events[j]:
            own += self._events[j]
            self._events[j] = []
        return off, own

    def _axis_offset(self, j: int, want: float) -> tuple[float, list]:
        """Axis ``j``'s offset for the wanted correction ``want`` [µm] and its own
        alarms: clamped to ±max_offset_um (``clamped``), then limited to ±max_step_um
        from what the axis holds (``rate_limited``). The one clamp and rate limit of
        every model, transport and replay. An axis whose controller holds a value not
        adopted (:meth:`resume_axis`) is not written: NaN and its alarm; so is a
        prediction that is not finite (``nonfinite:prediction``, the held value kept)."""
        if self._held[j] is not None:
            return float("nan"), [self._held[j]]
        held = float(self.offsets_um[j])
        if not math.isfinite(want):
            return held, ["nonfinite:prediction"]
        lim, step = self.limits(j)
        own = []
        if abs(want) > lim:
            want = math.copysign(lim, want)
            own.append("clamped")
        if abs(want - held) > step:
            want = held + math.copysign(step, want - held)
            own.append("rate_limited")
        self.offsets_um[j] = want
        self._known[j] = True
        return float(want), own

    def resume_axis(self, j: int, offset_um, readback: bool = False) -> str | None:
        """Take ``offset_um`` [µm] as the value axis ``j`` of the controller holds (read
        back on start, on reconnect or each cycle; a JSON line's; the log's warm start;
        the last accepted value after a refused write). The one rule for every transport:

        * inside the axis's clamp (|v| <= max_offset_um): adopted; the next offset is at
          most the axis's step from it. With ``readback`` (a value read again while
          running), a value that differs from what this compensator last set or took
          (by more than :data:`READBACK_TOLERANCE` relative; not the 0 a cold start
          assumes) raises ``external_change`` on the next cycle: someone else changed
          it; the ramp starts from it;
        * beyond the clamp, or not a finite number (None, NaN, ±inf, not a number):
          NOT adopted; the axis raises ``held_beyond_clamp`` or ``held_nonfinite`` on
          every cycle and is not written (NaN) until a value inside the clamp is taken.

        Returns the alarm kind raised (``held_beyond_clamp``, ``held_nonfinite``,
        ``external_change``) or None.

        Examples
        --------
        >>> c = Compensator(ar1_model(0.9, 1e-3, dtau_s=60.0), max_offset_um=3.0,
        ...                 max_step_um=0.1)
        >>> c.resume_axis(0, 50.0), c.step({"q_W_m2": 100.0}).offset_um
        ('held_beyond_clamp', nan)
        >>> c.resume_axis(0, 2.5), c.step({"q_W_m2": 100.0}).offset_um
        (None, 2.4)
        """
        try:
            v = float(offset_um) if is_json_number(offset_um) else math.nan
        except OverflowError:                       # an int beyond the float range
            v = math.inf
        lim, _ = self.limits(j)
        kind = ("held_nonfinite" if not math.isfinite(v) else
                "held_beyond_clamp" if abs(v) > lim else None)
        if kind is not None:
            self._held[j] = kind
            self.offsets_um[j] = math.nan
            return kind
        known = float(self.offsets_um[j])
        changed = (readback and self._known[j] and self._held[j] is None
                   and abs(v - known) > READBACK_TOLERANCE * max(1.0, abs(known)))
        self._held[j], self._known[j] = None, True
        self.offsets_um[j] = float(v)
        if changed:
            self._events[j].append("external_change")
            return "external_change"
        return None

    def advance_idle(self, k: int) -> None:
        """Advance the state through ``k`` intervals not seen, with the last good inputs
        (the offset is held: nothing was sent). Up to :data:`EXACT_STEPS` one by one --
        the floats of a replay that stepped them -- beyond that in closed form
        (:func:`propagate`), so that any jump costs O(log k). Nothing moves before a
        first good reading."""
        mdl = self.model
        k = int(k)
        if k <= 0 or self._u_last is None or mdl.n_states == 0:
            return
        A, B, _, _ = mdl.matrices(self._speed_last)    # the last good speed's
        bu = B @ self._u_last
        if k <= EXACT_STEPS:
            for _ in range(k):
                self.x = A @ self.x + bu
                if mdl.Q or self.P.any():
                    self.P = A @ self.P @ A.T + mdl.Q * np.eye(mdl.n_states)
            return
        Ak, G, S = propagate(A, k)
        self.x = Ak @ self.x + G @ bu
        self.P = Ak @ self.P @ Ak.T + mdl.Q * S

    def reinitialise(self) -> None:
        """Forget the state (back to the model's ``x0``, no last inputs); the offset the
        controller holds is kept, so the next offsets ramp from it."""
        self.x = self.model.x0.astype(float).copy()
        self.P = np.zeros((self.model.n_states,) * 2)
        self._u_last = None
        self._speed_last = None
        if self._observer is not None:
            self._observer.d[:] = 0.0

    def resume(self, offset_um) -> tuple:
        """:meth:`resume_axis` for every axis: ``offset_um`` one value per axis (a
        sequence, version 2) or one for all; returns each axis's alarm kind or None."""
        vals = offset_um if isinstance(offset_um, (tuple, list, np.ndarray)) else \
            [offset_um] * len(self.offsets_um)
        if len(vals) != len(self.offsets_um):
            raise ValueError(f"needs one value per axis ({len(self.offsets_um)})")
        return tuple(self.resume_axis(j, v) for j, v in enumerate(vals))

    def state(self) -> dict:
        """The state to log (a warm start restores it): ``x`` [µm], ``P`` [µm²] and the
        last good inputs ``u`` (as the matrices take them; with an observer, plus its
        estimated disturbances), with a speed schedule the last good speed ``speed_rpm``
        (its matrices), and with an observer its ``disturbances`` (W, K), JSON-ready."""
        return {"x": self.x.tolist(), "P": self.P.tolist(),
                "u": None if self._u_last is None else self._u_last.tolist(),
                **({"speed_rpm": self._speed_last} if self.model.schedule is not None
                   else {}),
                **({"disturbances": self._observer.state()} if self._observer is not None
                   else {})}

    def restore(self, state: Mapping) -> None:
        """Set the state from :meth:`state`'s document; :class:`ValueError` if it does not
        fit this model (shape, finiteness)."""
        n, m = self.model.n_states, len(self.model.inputs)
        x = np.asarray(state["x"], float).reshape(-1)
        P = np.asarray(state["P"], float)
        u = None if state.get("u") is None else np.asarray(state["u"], float).reshape(-1)
        if x.shape != (n,) or P.shape != (n, n) or (u is not None and u.shape != (m,)):
            raise ValueError("state does not fit the model")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))
                and (u is None or np.all(np.isfinite(u)))):
            raise ValueError("state is not finite")
        speed = state.get("speed_rpm")
        if speed is not None and not (isinstance(speed, (int, float))
                                      and math.isfinite(speed)):
            raise ValueError("state's speed is not finite")
        if self._observer is not None and state.get("disturbances") is not None:
            self._observer.restore(state["disturbances"])   # ValueError if it does not fit
        self.x, self.P, self._u_last = x, P, u
        self._speed_last = (None if self.model.schedule is None or speed is None
                            else float(speed))

    def probe(self, measured_growth_um: float) -> float:
        """Kalman update of the state with a measured growth [µm]; returns the gain.

        The prediction error is weighted by P Cᵀ / (C P Cᵀ + R); with R = 0 the state
        jumps to the measurement, with Q = 0 (P = 0) the probe changes nothing.
        """
        mdl = self.model
        if mdl.outputs:
            raise ValueError("a probe update needs a one-output (version 1) model")
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


def noise_var_um2(growth_um) -> float:
    """Measurement noise variance [µm²] of a growth record from its second differences
    (the R of every model's probe update).

    For white noise of variance σ² on a smooth signal, the second difference has
    variance 6σ²; the estimate assumes the signal's own curvature is small against the
    noise at the sampling interval.

    Parameters
    ----------
    growth_um : array_like
        Growth samples [µm] at equal intervals; non-finite differences are skipped.

    Returns
    -------
    float
        σ² [µm²]; 0.0 when fewer than 10 finite second differences remain.

    >>> round(noise_var_um2([0.0, 1.0] * 10), 6)
    0.666667
    """
    d2 = np.diff(np.asarray(growth_um, float), 2)
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
        Q=fit.residual_rms ** 2, R=noise_var_um2(g), description=description,
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
