"""A plant: what the one diagnosis pipeline needs of a model checked against a record
(issue 41, build item 1).

The pipeline (:mod:`arfem.models.geodiagnosis.fit` for the fits and intervals,
:mod:`arfem.models.geodiagnosis.engine` for the selection and the verdict) talks to
its model only through :class:`Plant`: a model bound to one measured record. A plant
gives

* its **channels** (each with a ``column`` name, a ``kind``: ``"displacement"``,
  ``"temperature"`` or ``"tilt"``, and a ``unit``: ``"um"``, ``"K"``, ``"urad"``) and
  their readings per row, ``data`` (N, C) in those units (NaN: no reading);
* its **inputs per row**: ``time_s``, the recorded ``ambient_C`` (or None), and
  ``load_shape``, the schedule of its heat input (1 at its largest), from which the
  default hold-out is chosen and a missing source follows;
* its **candidate causes** (:class:`CandidateCause`): each a part of the model that
  may be wrong, with its parameters (:class:`Parameter`: name with its unit, the value
  that means "no effect", the range a fit can return, the plausible range, linear or
  nonlinear);
* its **responses at a setting**: :meth:`Plant.setting` turns the causes' nonlinear
  values into the plant's own setting, and :meth:`Plant.design` gives at that setting
  the nominal prediction (N, C) and one column (N, C) per linear parameter (the
  response to a unit change of it), so that the linear parameters are a least-squares
  fit: prediction = base + Σ_k β_k column_k, parameter = no-effect + β (and, where
  the nominal model has unknowns of its own, its nuisance columns, fitted alike, and
  its ``nominal_parameters``, searched alike).

Two plants implement it: the user's mesh (:class:`arfem.models.geodiagnosis.plant.MeshPlant`,
the parametric reduced model of a Gmsh unit) and the seed paper's rod
(:class:`arfem.models.diagnosis.rod_plant.RodPlant`, the reduced FEM rod of Du et al.
2021). Everything here is pure: no files, no state beyond the caches a plant keeps.

The causes come from one vocabulary (:func:`cause`), whatever the plant:

==================== ================== ===================================== ===========
kind                 target             parameters [unit]                     no effect
==================== ================== ===================================== ===========
convection_scale     convection group   ``h_scale`` [-], nonlinear            1
source_scale         heat source        ``scale`` [-]                         1
missing_source       candidate group    ``power_W`` [W]                       0
contact_conductance  interface group    ``conductivity_scale`` [-],           1
                                        nonlinear
ambient_lag          (all surfaces)     ``lag_h`` [h], nonlinear              0
sensor_drift         a channel          ``offset_<u>``, ``drift_<u>_per_h``   0, 0
warm_start           (whole body)       ``initial_offset_K`` [K]              0
frame_expansion      a thermometer      ``frame_gain_um_per_K`` [µm/K]        0
frame_lag            (the frame)        ``frame_time_constant_h`` [h],        --, 0
                                        nonlinear; ``frame_gain`` [-]
frame_lag            a thermometer      ``frame_time_constant_h`` [h],        --, 0
                                        nonlinear; ``frame_gain_um_per_K``
                                        [µm/K]
frame_expansion      ``pc1-<k>``        ``frame_gain_pc<j>_um`` [µm], j=1..k  0
frame_lag            ``pc1-<k>``        ``frame_time_constant_h`` [h],        --, 0
                                        nonlinear; ``frame_gain_pc<j>_um``
natural_convection   convection group   ``h_scale`` [-] (h at 10 K) and       1, 0
                                        ``exponent`` [-], both nonlinear
ambient_drift        (the ambient)      ``ambient_gain_um_per_K`` [µm/K]      0
==================== ================== ===================================== ===========

``frame_lag``, ``natural_convection`` and ``ambient_drift`` are the seed paper's
rod's (:class:`arfem.models.diagnosis.rod_plant.RodPlant`): a frame heated by the same
source with its own time constant, a natural-convection h ∝ ΔT^exponent, and a
recorded ambient that the paper's nominal model (a constant ambient) leaves out. On a
thermometer (a ``T_<name>_C`` target, the speed-only plant's
:class:`arfem.models.diagnosis.speed_plant.SpeedPlant`) a frame lag follows that
thermometer's rise through its time constant, its gain in µm/K as ``frame_expansion``'s;
on a ``pc1-<k>`` target (:func:`components_target`) a frame follows the ``k`` leading
principal components of the record's standardised thermometers, one gain each (a
record of many thermometers: one cause for them all).

The no-effect values are the verdict's (:data:`arfem.models.diagnosis.verdict.NO_EFFECT`,
one table).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from arfem.models.diagnosis.verdict import NO_EFFECT
from arfem.params import PLAUSIBLE_RANGES

__all__ = ["Parameter", "CandidateCause", "Design", "Plant", "SelectionRules", "linear_value", "cause",
           "components_target",
           "BOUNDS", "PLAUSIBLE"]


@dataclass(frozen=True)
class Parameter:
    """One parameter of a cause.

    Attributes
    ----------
    name : str
        Its name with its unit, as reported (``h_scale`` [-], ``power_W`` [W],
        ``lag_h`` [h], ``drift_um_per_h`` [µm/h], ``initial_offset_K`` [K]).
    unit : str
        Its unit alone (``"-"`` for a factor).
    no_effect : float
        The value at which the cause changes nothing (1 for a factor, 0 for an added
        quantity); a cause is established only when its 95 % interval excludes it.
        NaN for a parameter that only shapes an effect another parameter of the cause
        carries (a frame's time constant beside its gain).
    linear : bool
        True: the prediction is linear in it (fitted by least squares, value =
        ``no_effect`` + β). False: searched on a log scale within ``bounds``.
    bounds : (float, float) or None
        The range a nonlinear fit can return, in the parameter's unit; an interval
        reaching an end of it is not a cause. None for a linear parameter.
    plausible : (float, float) or None
        The physically plausible range; a fit outside is a sign of wrong units or of
        another cause. None: any value.
    start : float or None
        A nonlinear parameter's value while another is searched first (its no-effect
        value, or a point inside ``bounds`` where that lies outside them).
    probe : float or None
        A nonlinear parameter's secant point for the largest model of the noise fit
        (:func:`arfem.models.geodiagnosis.fit.with_noise`).
    log_scale : bool
        A nonlinear parameter is searched on a log scale (a factor, a time; its
        bounds positive), or on a linear one where False (an exponent, whose
        no-effect value 0 lies inside its bounds).
    """

    name: str
    unit: str
    no_effect: float
    linear: bool = True
    bounds: tuple | None = None
    plausible: tuple | None = None
    start: float | None = None
    probe: float | None = None
    log_scale: bool = True


@dataclass(frozen=True)
class CandidateCause:
    """One cause a plant can tell: a ``kind`` on a ``target`` (a group, source or
    channel name; empty for a whole-body cause) with its :class:`Parameter` s.

    A cause has at most two nonlinear parameters (the pipeline searches them, each under
    :meth:`key`); the others are linear. Two causes are the same when kind, target and
    parameters agree.

    >>> c = CandidateCause("convection_scale", "housing", (
    ...     Parameter("h_scale", "-", 1.0, linear=False, bounds=(0.1, 10.0), start=1.0,
    ...               probe=1.5),))
    >>> c.name, c.nonlinear, c.linear_parameters
    ('convection_scale:housing', 'h_scale', ())
    """

    kind: str
    target: str = ""
    parameters: tuple = ()

    @property
    def name(self) -> str:
        """``kind:target`` (``kind`` alone for a whole-body cause)."""
        return f"{self.kind}:{self.target}" if self.target else self.kind

    @property
    def nonlinear(self) -> str | None:
        """The name of the nonlinear parameter, or None."""
        return next((p.name for p in self.parameters if not p.linear), None)

    @property
    def nonlinear_parameter(self) -> Parameter | None:
        """The (first) nonlinear :class:`Parameter`, or None."""
        return next((p for p in self.parameters if not p.linear), None)

    @property
    def nonlinear_parameters(self) -> tuple:
        """Every nonlinear :class:`Parameter`, in order (at most two: a natural
        convection's exponent and the h it scales)."""
        return tuple(p for p in self.parameters if not p.linear)

    def key(self, p: Parameter) -> str:
        """The key of nonlinear parameter ``p`` in a fit's values (what
        :meth:`Plant.setting` reads): the cause's name for its first, ``name/param``
        for a second.

        >>> c = cause("natural_convection", "outer")
        >>> [c.key(p) for p in c.nonlinear_parameters]
        ['natural_convection:outer', 'natural_convection:outer/exponent']
        """
        return self.name if p == self.nonlinear_parameter else f"{self.name}/{p.name}"

    @property
    def linear_parameters(self) -> tuple:
        """The linear :class:`Parameter` s, in the order of the plant's columns."""
        return tuple(p for p in self.parameters if p.linear)

    def parameter(self, name: str) -> Parameter | None:
        """The parameter called ``name``, or None."""
        return next((p for p in self.parameters if p.name == name), None)


@dataclass(frozen=True)
class Design:
    """A plant's responses at one setting.

    Attributes
    ----------
    base : ndarray (N, C)
        The prediction with every linear parameter at its no-effect value [channel units].
    columns : tuple of ndarray (N, C)
        One per linear parameter of the causes, in cause order then parameter order:
        the change of the prediction per unit of the parameter.
    setting : object
        The plant's own setting (what its nonlinear values mean to it).
    nuisance : tuple of ndarray (N, C)
        Columns of the nominal model's own unknowns (e.g. the free response of an
        unknown initial state), fitted by least squares in every fit, the nominal's
        included, and never reported as a cause; () for a plant whose nominal model is
        fully given.
    """

    base: np.ndarray
    columns: tuple
    setting: Any
    nuisance: tuple = ()


def linear_value(p: Parameter, beta: float) -> float:
    """A linear parameter's value from its least-squares coefficient β: no-effect + β.

    >>> linear_value(Parameter("scale", "-", 1.0), 0.25)
    1.25
    """
    return float(beta) + float(p.no_effect)


#: Ranges the fit can return (natural units); an interval reaching one is not a cause.
#: A frame lag's time constant starts at 2 h, the rod engine's: a frame as quick as the
#: seed paper's rod (τ ≈ 0.9 h) is a heat scale in disguise -- with 0.1 h (the speed
#: fits' range) development seed 1051 (heat × 0.70 and a frame at τ 2.0 h) came out a
#: frame alone at τ 1.1 h, gain −0.42, its intervals missing the truth.
BOUNDS = {"h_scale": (0.1, 10.0), "conductivity_scale": (0.01, 100.0),
          "lag_h": (0.02, 48.0), "frame_time_constant_h": (2.0, 200.0),
          "exponent": (-0.5, 1.5)}


def _plausible(key: str, signed: bool = False) -> tuple:
    """(low, high) of the project's one table of plausible magnitudes
    (:data:`arfem.params.PLAUSIBLE_RANGES`, the rod engine's and the live loop's too);
    ``signed``: ±high (a gain or a drift of either sign, bounded in size)."""
    lo, hi, _ = PLAUSIBLE_RANGES[key]
    return (-hi, hi) if signed else (lo, hi)


#: Plausible ranges of the linear magnitudes, by parameter; a fit outside is a sign of
#: wrong units, not a cause. Read from the one table, never written beside it.
PLAUSIBLE = {"scale": _plausible("heat_input_scale"), "power_W": _plausible("power_W"),
             "ambient_gain_um_per_K": _plausible("ambient_gain_um_per_K", signed=True),
             "drift_um_per_h": _plausible("drift_um_per_h")}
#: Where a nonlinear parameter is held while another is searched (a lag of 0 h lies
#: outside its log-scale range: 1 h) and its secant point for the noise fit's largest
#: model (h × 1.5, κ × 0.5, a lag of 1 h).
_START = {"h_scale": 1.0, "conductivity_scale": 1.0, "lag_h": 1.0,
          "frame_time_constant_h": 4.0, "exponent": 0.0}
_PROBE = {"h_scale": 1.5, "conductivity_scale": 0.5, "lag_h": 1.0,
          "frame_time_constant_h": 4.0, "exponent": 0.25}
#: nonlinear parameters without a no-effect value (NaN): a frame's time constant shapes
#: its effect, which its gain carries (the verdict tests the gain against 0)
_NO_EFFECT_NONLINEAR = {"frame_time_constant_h": float("nan")}
_NONLINEAR = {"convection_scale": ("h_scale", "-"),
              "contact_conductance": ("conductivity_scale", "-"), "ambient_lag": ("lag_h", "h"),
              "frame_lag": ("frame_time_constant_h", "h")}
#: causes of two nonlinear parameters: natural convection, h = h_scale h0 (ΔT/10 K)^exponent
#: (h first: the coordinate sweep starts from the plain h scale's optimum)
_NONLINEAR2 = {"natural_convection": (("h_scale", "-"), ("exponent", "-"))}
_LINEAR = {"source_scale": (("scale", "-"),), "missing_source": (("power_W", "W"),),
           "warm_start": (("initial_offset_K", "K"),),
           "frame_expansion": (("frame_gain_um_per_K", "um/K"),),
           "frame_lag": (("frame_gain", "-"),),
           "ambient_drift": (("ambient_gain_um_per_K", "um/K"),)}
#: the linear parameters of a kind on a thermometer (a ``T_<name>_C`` target), where
#: they differ: a frame lag's gain is then per kelvin of that thermometer
_LINEAR_ON_THERMOMETER = {"frame_lag": (("frame_gain_um_per_K", "um/K"),)}


def _nonlinear(name: str, unit: str) -> Parameter:
    lo = BOUNDS[name][0]
    no_effect = NO_EFFECT.get(name, _NO_EFFECT_NONLINEAR.get(name))
    return Parameter(name, unit, float(no_effect), linear=False, bounds=BOUNDS[name],
                     start=_START[name], probe=_PROBE[name], log_scale=lo > 0)


def _column_unit(column: str) -> str:
    """A record column's unit, from its name (``d_*_um``, ``tilt_*_urad``, ``T_*_C``)."""
    if column.endswith("_um"):
        return "um"
    return "urad" if column.endswith("_urad") else "K"


def components_target(k: int) -> str:
    """The target of a frame on the thermometers' ``k`` leading principal components:
    ``pc1-<k>``.

    >>> components_target(3), _components("pc1-3"), _components("T_frame_C")
    ('pc1-3', 3, 0)
    """
    return f"pc1-{int(k)}"


def _components(target: str) -> int:
    """The number of principal components a ``pc1-<k>`` target names (0: another)."""
    m = re.fullmatch(r"pc1-([1-9][0-9]*)", target)
    return int(m.group(1)) if m else 0


def cause(kind: str, target: str = "", unit: str | None = None) -> CandidateCause:
    """The cause ``kind`` on ``target`` with its parameters (module table), the same for
    every plant; ``unit`` is a sensor drift's channel unit (from its column name when
    not given).

    >>> [p.name for p in cause("sensor_drift", "d_tcp_z_um").parameters]
    ['offset_um', 'drift_um_per_h']
    >>> cause("source_scale", "motor").parameters[0].plausible
    (0.2, 5.0)
    >>> [p.name for p in cause("frame_lag", "T_frame_C").parameters]
    ['frame_time_constant_h', 'frame_gain_um_per_K']
    >>> [p.name for p in cause("frame_expansion", "pc1-2").parameters]
    ['frame_gain_pc1_um', 'frame_gain_pc2_um']
    """
    if kind in ("frame_expansion", "frame_lag") and _components(target):
        # a frame on the thermometers' leading principal components: one gain [µm per
        # unit component] each (the components are standardised, unit-free)
        params = ((_nonlinear(*_NONLINEAR[kind]),) if kind in _NONLINEAR else ()) + tuple(
            Parameter(f"frame_gain_pc{j}_um", "um", 0.0)
            for j in range(1, _components(target) + 1))
        return CandidateCause(kind, target, params)
    if kind == "sensor_drift":
        u = unit or _column_unit(target)
        params = (Parameter(f"offset_{u}", u, 0.0),
                  Parameter(f"drift_{u}_per_h", f"{u}/h", 0.0,
                            plausible=PLAUSIBLE.get(f"drift_{u}_per_h")))
    elif kind in _NONLINEAR2:
        params = tuple(_nonlinear(n, u) for n, u in _NONLINEAR2[kind])
    elif kind in _NONLINEAR or kind in _LINEAR:
        thermometer = target.startswith("T_") and target.endswith("_C")
        linear = (_LINEAR_ON_THERMOMETER if thermometer and kind in _LINEAR_ON_THERMOMETER
                  else _LINEAR).get(kind, ())
        params = ((_nonlinear(*_NONLINEAR[kind]),) if kind in _NONLINEAR else ()) + tuple(
            Parameter(n, u, float(NO_EFFECT[n]), plausible=PLAUSIBLE.get(n))
            for n, u in linear)
    else:
        raise ValueError(f"unknown cause {kind!r}")
    return CandidateCause(kind, target, params)


@dataclass(frozen=True)
class SelectionRules:
    """Where a plant needs the one pipeline's selection to read its record otherwise
    (issue 41: "where the rod needs to differ, that is a named property of its plant,
    documented"). The defaults are the mesh's, as pre-registered and scored by
    ``benchmarks/bench_geodiagnosis.py``; a plant that sets one says why at the plant.

    Attributes
    ----------
    shared_n_eff : bool
        Every F test and BIC on ONE effective sample size, that of the largest model's
        whitened residual (every candidate at once, the model the noise is fitted on,
        :func:`arfem.models.geodiagnosis.fit.with_noise`), as an F test takes its error
        variance from its full model; False: each candidate's own residual's N_eff.
    nested_in_pair : bool
        A cause of a named pair that nests a simpler single cause (a natural convection
        holds a plain h) is replaced by it where its extra parameters fail the nested F
        test beside the other cause (parsimony within a pair).
    pair_misfit_sigma : float
        A second cause is searched only where the first leaves more than this many noise
        σ on some channel (RMS of its residual on the fit window over the channel's
        second-difference σ); 0: always.
    """

    shared_n_eff: bool = False
    nested_in_pair: bool = False
    pair_misfit_sigma: float = 0.0


@runtime_checkable
class Plant(Protocol):
    """A model bound to one measured record: what the diagnosis pipeline calls.

    Attributes
    ----------
    kind : str
        ``"mesh"`` or ``"rod"`` (``Diagnosis.plant``).
    name : str
        The record's name.
    time_s : ndarray (N,)
        Sample times [s], increasing.
    data : ndarray (N, C)
        Each channel's readings [channel unit] (thermometers as θ = T − reference [K]),
        NaN where missing.
    channels : tuple
        One per column of ``data``, each with ``column`` (str), ``kind`` (str) and
        ``unit`` (str).
    ambient_C : ndarray (N,) or None
        The recorded ambient air [°C], an input and a data baseline's regressor.
    load_shape : ndarray (N,)
        The heat input's schedule, 1 at its largest [-]; zeros when nothing heats.
    not_searched : tuple of str
        Causes left out of the search by the user (said in the verdict).
    nominal_parameters : tuple of Parameter
        Nonlinear unknowns of the nominal model itself (e.g. a speed-only record's
        time constant), searched within their bounds in every fit, the nominal's
        included, and never reported as a cause; () for a plant whose nominal model
        is fully given.
    regrows : bool
        True when the plant's reduced model is rebuilt at a named nonlinear setting
        (:meth:`regrown`) to remove its reduction bias there; False when the reduction
        is exact at every setting.
    rules : SelectionRules
        Where the plant's selection differs from the mesh's (:class:`SelectionRules`).
    """

    kind: str
    name: str
    time_s: np.ndarray
    data: np.ndarray
    channels: tuple
    ambient_C: np.ndarray | None
    load_shape: np.ndarray
    not_searched: tuple
    nominal_parameters: tuple
    regrows: bool
    rules: SelectionRules

    def candidate_causes(self) -> tuple:
        """Every single :class:`CandidateCause` this record and model can tell."""

    def setting(self, causes, values: dict) -> Any:
        """The plant's setting for ``causes`` with their nonlinear parameters at
        ``values`` {cause name: value}; every other part nominal."""

    def design(self, causes, setting) -> Design:
        """The :class:`Design` of ``causes`` at ``setting``."""

    def regrown(self, setting) -> "Plant":
        """The same plant with its reduced model rebuilt at ``setting`` (its reduction
        bias there removed); called only when ``regrows``."""

    def reference_models(self, rows) -> tuple:
        """The data-driven models this plant's users already trust beside the MLR of
        eq. 18 (every plant's), fitted on ``rows`` (bool (N,)) and run over the record:
        ((label, {column: prediction (N,)}), ...); () where there is none. The verdict
        holds each as a data baseline (a named property of the plant)."""
