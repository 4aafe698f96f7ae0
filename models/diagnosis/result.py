"""One typed result of a diagnosis, for every plant (issue 41, stage 3).

The rod's engine (:func:`arfem.models.diagnosis.engine.diagnose`: the FEM rod of a
``q_W_m2`` record, the speed-only AR(1) frame model of a ``speed_rpm`` one) and the mesh
engine (:func:`arfem.models.geodiagnosis.engine.diagnose_geometry`) both return a
:class:`Diagnosis`: the verdict by the one set of rules of
:mod:`arfem.models.diagnosis.verdict`, the causes the selection rules named (each with its
parameters, their 95 % intervals and the value of each that means "no effect"), the
hold-out scores and how the hold-out was chosen, the alternatives that fit as well, what
went unsearched, the evidence per channel and the warnings. What only one plant has (the
rod's candidate table and AR forms, the mesh's ranking and fitted noise) is its
:attr:`Diagnosis.evidence`, a frozen record of that plant's engine.

``diagnosis.json`` is not this object: it is written from it at the edge
(:mod:`arfem.scenarios.diagnosis.document`), with the keys of ``docs/commands/diagnose.md``.

Pure: frozen dataclasses, no I/O.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

__all__ = ["NamedCause", "ChannelHoldout", "Holdout", "ChannelEvidence", "Diagnosis",
           "FrozenDict", "frozen_mapping", "unit_shown"]

#: a channel's unit (the record's ASCII name) as a reader is shown it
_UNIT_SHOWN = {"um": "µm", "urad": "µrad"}


def unit_shown(unit: str) -> str:
    """A channel's unit as texts show it: ``"um"`` → ``"µm"``, ``"urad"`` → ``"µrad"``,
    any other (``"K"``) as it is.

    >>> unit_shown("um"), unit_shown("K")
    ('µm', 'K')
    """
    return _UNIT_SHOWN.get(unit, unit)


class FrozenDict(dict):
    """A dict that refuses every change: a frozen result's mapping. It reads, pickles,
    copies and serialises (``json``) as a dict does.

    >>> m = FrozenDict({"a": 1})
    >>> m["a"], json_like(m)
    (1, True)
    >>> m["b"] = 2
    Traceback (most recent call last):
    TypeError: a diagnosis result is frozen: build a new one (dataclasses.replace)
    """

    def _refuse(self, *args, **kwargs):
        raise TypeError("a diagnosis result is frozen: build a new one (dataclasses.replace)")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _refuse
    __ior__ = _refuse

    def __reduce__(self):
        return (FrozenDict, (dict(self),))


def json_like(m) -> bool:
    """True when ``m`` serialises as a JSON object (for the doctest above)."""
    import json
    return json.dumps(m).startswith("{")


def frozen_mapping(d) -> FrozenDict:
    """A frozen copy of the mapping ``d`` (``{}`` for None): nested mappings frozen too,
    lists made tuples, arrays kept.

    >>> m = frozen_mapping({"a": {"b": [1, {"c": 2}]}})
    >>> m["a"]["b"][1]["c"], type(m["a"]).__name__, type(m["a"]["b"]).__name__
    (2, 'FrozenDict', 'tuple')
    """
    return FrozenDict({} if d is None else {k: _frozen(v) for k, v in d.items()})


def _frozen(v):
    if isinstance(v, Mapping):
        return frozen_mapping(v)
    if isinstance(v, (list, tuple)):
        return tuple(_frozen(x) for x in v)
    return v


@dataclass(frozen=True)
class NamedCause:
    """A cause the selection rules named, established or not.

    Attributes
    ----------
    cause : str
        Its kind in the plant's vocabulary (rod: ``convection_mismatch`` ...; mesh:
        ``missing_source``, ``contact_conductance`` ...).
    name : str
        As reported: the kind on the rod, ``<kind>:<target>`` on a mesh.
    target : str
        The group, source or channel it acts on (mesh); empty on the rod.
    parameters : mapping of str to float
        Its parameters, each named with its unit (``h_W_m2K``, ``power_W`` ...).
    ci95 : mapping of str to (float, float)
        Their 95 % intervals (low, high) [the parameter's unit]; a parameter without one
        is absent.
    no_effect : mapping of str to float or None
        For each effect parameter, the value that means "no effect"
        (:data:`arfem.models.diagnosis.verdict.NO_EFFECT`, the rod's nominal h resolved);
        None where the plant does not state it.
    model_choice : tuple of str
        The parameters whose interval was widened to hold an equivalent alternative's
        estimate (the rod's ``ci95_model_choice``).
    """

    cause: str
    name: str
    target: str
    parameters: Mapping[str, float]
    ci95: Mapping[str, tuple]
    no_effect: Mapping[str, Any] = field(default_factory=FrozenDict)
    model_choice: tuple = ()

    @property
    def established_effect(self) -> bool:
        """True when every effect parameter's interval excludes its no-effect value."""
        keys = [k for k, z in self.no_effect.items() if z is not None]
        return bool(keys) and all(k in self.ci95 and not (
            self.ci95[k][0] <= self.no_effect[k] <= self.ci95[k][1]) for k in keys)


@dataclass(frozen=True)
class ChannelHoldout:
    """One channel's error on the hold-out [its unit: µm, K, µrad]: the nominal model
    (the baseline), the extended model (the best candidate's, or the baseline where
    nothing was named) and the MLR of paper eq. 18 on the thermometers (None where it
    was not fitted)."""

    column: str
    unit: str
    baseline_rmse: float
    extended_rmse: float
    mlr_rmse: float | None


@dataclass(frozen=True)
class Holdout:
    """The hold-out and how both models score on it.

    Attributes
    ----------
    start_s : float
        Its start [s]; the fits saw only the rows before it.
    how_chosen : str
        In words: given, or by :func:`arfem.models.diagnosis.holdout.default_holdout`.
    n_samples : int
        Rows scored (every channel's valid rows on the mesh).
    gain_pct : float
        100 (1 − extended / baseline) of the hold-out error (the mesh: of the
        σ-weighted RMS over its channels).
    gain_whitened_pct : float or None
        The same of the errors whitened by each channel's fitted noise (the mesh's
        verdict uses it); None where the plant does not whiten.
    channels : tuple of ChannelHoldout
    """

    start_s: float
    how_chosen: str
    n_samples: int
    gain_pct: float
    gain_whitened_pct: float | None
    channels: tuple

    def channel(self, column: str) -> ChannelHoldout:
        """The scores of ``column``."""
        return next(c for c in self.channels if c.column == column)


@dataclass(frozen=True)
class ChannelEvidence:
    """What one channel says about the nominal model's residual.

    Attributes
    ----------
    column, unit : str
    noise_sigma : float
        The channel's noise σ [its unit].
    whiteness_p : float
        Ljung-Box p on N_eff of the nominal residual
        (:func:`arfem.models.diagnosis.verdict.whiteness_p`; on the mesh whitened by the
        channel's fitted noise); NaN where too short to test.
    thermometers_beyond : tuple of str
        The thermometers (and ambient) correlated with the residual beyond the bound on
        its N_eff (:func:`arfem.models.diagnosis.verdict.correlation_bound`).
    """

    column: str
    unit: str
    noise_sigma: float
    whiteness_p: float
    thermometers_beyond: tuple = ()


@dataclass(frozen=True)
class Diagnosis:
    """What a diagnosis found on one record, on any plant.

    Attributes
    ----------
    dataset : str
        The record's name.
    plant : str
        ``rod_fem`` (a ``q_W_m2`` record on the FEM rod), ``rod_speed`` (a speed-only
        record on the AR(1) frame model) or ``mesh`` (a contract-v3 record on a mesh).
    verdict : str
        ``established``, ``explained``, ``unconfirmed`` or ``not_explained``
        (:data:`arfem.models.diagnosis.verdict.VERDICTS`).
    text : str
        The verdict in words.
    causes : tuple of NamedCause
        The causes the selection rules named (empty if none); established only where
        :attr:`verdict` is ``established`` (:attr:`established`).
    subject : str or None
        What the verdict is about: the established cause or the best candidate ("a+b"
        for a pair on the rod, "a + b" on a mesh), None where there is none.
    failed : tuple of str
        The checks of "established" the named causes fail, in words.
    alternatives : tuple of str
        Causes that fit the data as well as the named ones and were not excluded.
    not_searched : tuple of str
        What the search left out: causes that do not apply to the record (rod), or that
        the scenario's ``[diagnosis]`` table left out (mesh).
    holdout : Holdout
    channels : tuple of ChannelEvidence
    warnings : tuple of str
        What a reader must not miss.
    below_resolution : bool
        The nominal residual stays below every channel's resolution (rule 0).
    beaten_by_regression : bool
        The verdict is ``not_explained`` because a regression on the thermometers beats
        the best candidate's extended model on the hold-out (rule 1d).
    series : mapping of str to ndarray
        The arrays behind the figures: time [s], measured and predicted (rod: growth
        [µm]; mesh: (N, C) in each channel's unit).
    evidence : object
        The plant engine's own frozen record (:class:`arfem.models.diagnosis.engine.RodEvidence`,
        :class:`arfem.models.geodiagnosis.engine.MeshEvidence`).
    """

    dataset: str
    plant: str
    verdict: str
    text: str
    causes: tuple
    subject: str | None
    failed: tuple
    alternatives: tuple
    not_searched: tuple
    holdout: Holdout
    channels: tuple
    warnings: tuple
    below_resolution: bool
    beaten_by_regression: bool
    series: Mapping[str, np.ndarray] = field(repr=False)
    evidence: Any = field(repr=False)

    @property
    def established(self) -> tuple:
        """The established causes (empty unless the verdict is ``established``)."""
        return self.causes if self.verdict == "established" else ()

    @property
    def cause(self) -> str:
        """The (first) established cause, ``none`` where none is (``cause`` of
        diagnosis.json)."""
        return self.established[0].name if self.established else "none"
