"""A speed-only record (``speed_rpm``, no heat flux) as a :class:`~arfem.models.plant.Plant`
of the one diagnosis pipeline (issue 41, build item 1): the seed paper's AR(1) whose
heat is unknown per speed, with a frame that follows a thermometer.

Nominal model (paper eqs. 12-14 with the heat of a speed unknown), one of two
(:data:`HEAT_MODELS`, chosen by :func:`choose_heat_model`, below):

* ``"per_speed"`` -- one steady gain per speed (paper eqs. 12 and 17): the growth [µm]
  is Σ_s K_s · AR1_b[u_s] + c · exp(−b t), u_s the indicator of the non-zero speed s
  seen in the fit rows (before the hold-out) and K_s its steady growth [µm], each a
  nuisance column; at rest no heat. A speed first met after the fit window gets
  K(u) = ratio · K(s_ref) by the paper's eqs. 20-21 (the early temperature rise after
  a step to it against the nearest seen speed's, heat ∝ speed without a usable
  thermometer: :func:`arfem.models.diagnosis.speed.speed_to_heat_map`, the branch's and
  the reference model's own mapping; K(0) = 0, the plant's rest), folded into the
  columns (:func:`arfem.models.diagnosis.speed.level_inputs`), so an unseen speed's
  prediction stays linear in the fitted gains. τ [h] is the one nonlinear parameter.
* ``"law"`` -- the growth [µm] is
G · AR1_b[(n/n_max)^p] + c · exp(−b t): the unit-gain AR(1) (rate b = 1/τ) of the
speed-to-heat law (n/n_max)^p (heat ∝ n^p, zero at rest:
:func:`arfem.models.diagnosis.speed_frame.heat_law`'s family; p = 5/3 for viscous
bearing friction, Palmgren) times the steady growth at n_max, G [µm], and the free decay
of an unknown initial state, c [µm] -- both nuisance columns. τ [h] and p [-] are the
nominal model's own nonlinear parameters (``Plant.nominal_parameters``), searched in
every fit: τ within 1 min .. 200 h (the rod engine's range), p within 0.5 .. 3. One law
for every speed, so a speed first met in the hold-out is predicted (the rod engine maps
it by the paper's eqs. 20-21 instead). At rest no heat enters, so the growth returns to
the reference: the sensor's offset stays identifiable.

The choice (``heat_model="auto"``, the default; :func:`speed_plant`): where the fit rows
see a non-zero speed, both nominal models are fitted on them beside every linear
candidate cause at once (the largest model the pipeline fits its noise on: a cause left
out, a drift say, made the nominal fits' N_eff a handful and the choice the drift's),
GLS on one noise (:func:`~arfem.models.geodiagnosis.fit.with_noise` on the per-speed
plant), and the one of lower BIC on N_eff (the screen's criterion,
:func:`arfem.models.diagnosis.stats.bic`) is the plant's nominal; the per-speed gains
must beat the law by the screen's margin
(:data:`arfem.models.geodiagnosis.engine.DELTA_BIC`, 10: very strong evidence), else
the law (fewer unknowns). On the fit rows the
per-speed gains nest the law, so the law is kept where the heat follows one law --
always per speed, development synth seeds 1 and 5 (power law, M = 1) lost their
established drift, the gains absorbing part of the ramp before the drift-against-walk
test -- and the gains are taken where it does not (the real FL_THERMAL record,
README.posthoc.md 1.4). Where no non-zero speed is seen before the hold-out: the law.
The plant must be built with the diagnosis's hold-out start (``holdout_start_s``; None:
the default hold-out of :func:`arfem.models.diagnosis.holdout.default_holdout`, what
:func:`~arfem.models.geodiagnosis.engine.diagnose_plant` takes when given none): the
seen speeds and the fit rows of the choice are those before it.

Causes (the one vocabulary, :func:`arfem.models.plant.cause`), each exact for the model
it names (the truth of :mod:`arfem.models.diagnosis.synth_speed` is of this family):

* ``sensor_drift:growth_um``: an offset [µm] and a drift [µm/h];
* ``ambient_drift`` (where an ambient is recorded and varies): the rod's own AR(1) at
  its rate of the recorded ambient above the reference (the rod's nominal ambient,
  paper: 20 °C) with unit steady gain, times ``ambient_gain_um_per_K`` [µm/K];
* ``convection_scale:running`` (where the spindle both runs and rests): the rod's rate
  1/τ times ``h_scale`` [-] while the spindle turns (b = 2h/(ρcR), paper eq. 13, so a
  factor on b is one on h): contract ``speed_dependent_convection``, with
  h_running / h_stopped = h_scale and h_stopped = ρcR/(2τ);
* ``frame_expansion:<T column>``: the frame grows ``frame_gain_um_per_K`` × the rise of
  a recorded thermometer (°C above its first reading), no lag;
* ``frame_lag:<T column>``: the same through a first-order lag of
  ``frame_time_constant_h`` [h] (nonlinear, 2-200 h), its gain ``frame_gain_um_per_K``;
* above :data:`PER_THERMOMETER_FRAMES` thermometers, ``frame_expansion:pc1-3`` and
  ``frame_lag:pc1-3`` in their place: the frame follows the three leading principal
  components of the standardised thermometers
  (:func:`arfem.models.diagnosis.speed_frame.frame_components`, the speed branch's),
  one gain ``frame_gain_pc<j>_um`` [µm per unit component] each, without and with
  the lag. The components are taken over the whole record: the thermometers are
  inputs, no growth reading of the hold-out enters them.

Every thermometer is smoothed by a centred mean of ±:data:`THERMOMETER_SMOOTHING_S`
before it is a regressor (its noise is an error in the variable, which the fitted slow
noise turns into a gain drawn to zero).

Contract names: :func:`contract_causes`.

What this plant does not do (the rod engine's speed branch does): the choice of the
frame's structure among numbers of components and lags by forward-chaining validation
(README.posthoc.md 1.4.2: on FL_THERMAL a fixed three components lose to it), and a
frame without a thermometer (the frame's own lag of the rod's steady growth: its gain is
a product with the nominal model's unknown steady growth G, not a linear column).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from dataclasses import replace as with_fields

import numpy as np

from arfem.models.diagnosis.forward import ar_columns_rates, first_order_lag, intervals
from arfem.models.diagnosis.holdout import default_holdout
from arfem.models.diagnosis.rod_plant import ContractCause
from arfem.models.diagnosis.speed import level_inputs, paper_ar, speed_to_heat_map
from arfem.models.diagnosis.speed_frame import (centred_mean, frame_components,
                                                temperature_matrix)
from arfem.models.diagnosis.stats import bic
from arfem.models.geodiagnosis.engine import DELTA_BIC, named_causes, residual_n_eff
from arfem.models.geodiagnosis.fit import Z95, fit_mesh_causes, make_context, with_noise
from arfem.models.geodiagnosis.problem import Channel
from arfem.models.plant import Design, Parameter, SelectionRules, cause, components_target

__all__ = ["SpeedPlant", "SpeedSetting", "speed_plant", "speed_plant_from_dataset",
           "contract_causes", "TIME_CONSTANT", "HEAT_EXPONENT", "THERMOMETER_SMOOTHING_S",
           "PER_THERMOMETER_FRAMES", "FRAME_COMPONENTS", "PAPER_AR_LABEL", "contract_names",
           "speed_contract_entries", "speed_candidate_parameters", "convection_h_W_m2K",
           "convection_h_ci95", "HEAT_MODELS", "choose_heat_model", "HeatModel"]

#: how the verdict names the paper's AR(1), the speed plant's reference model
PAPER_AR_LABEL = "the paper AR(1) of eq. 17 (one C2 per speed, eqs. 20-21 for new speeds)"

#: The nominal model's time constant τ [h]: bounds 1 min .. 200 h, searched from 1 h
#: (no "no effect": not a cause).
TIME_CONSTANT = Parameter("time_constant_h", "h", float("nan"), linear=False,
                          bounds=(1.0 / 60.0, 200.0), start=1.0, probe=1.0)
#: The exponent p of the speed-to-heat law (n/n_max)^p [-]: bounds 0.5 .. 3, searched
#: from 5/3 (viscous bearing friction, Palmgren): from 1, a frame lag searched first
#: beside τ 1 h and p 1 settled at its 2 h bound with τ 8 h and a gain of −40 µm/K
#: (a frame lagging its thermometer by 3 h, gain 1.5: the lag test's record).
HEAT_EXPONENT = Parameter("heat_exponent", "-", float("nan"), linear=False,
                          bounds=(0.5, 3.0), start=5.0 / 3.0, probe=1.0)


#: Half-width [s] of the centred mean a thermometer is smoothed by before it is a
#: regressor (:func:`arfem.models.diagnosis.speed_frame.centred_mean`): ±6 min, ±3
#: samples of the synth's 2 min, ±24 of a 15 s record. Unsmoothed, a thermometer's
#: 0.01 K noise dominated its differenced rise under the fitted slow noise (AR(1) φ 0.99)
#: and drew the frame's gain to zero: synth_speed frame seeds 1-6 (AR noise) were
#: established 1 of 6 (seed 4: −0.50 µm/K [−1.00, −0.00] for −3.37); smoothed 6 of 6,
#: every interval holding the truth. The bias it adds at a kink of a first-order rise
#: of time constant τ is about w/(4τ) of the rise (1 % at the frame lag's 2 h bound).
THERMOMETER_SMOOTHING_S = 360.0
#: Up to this many thermometers each gets its own frame (with and without a lag);
#: above, the frame follows the leading principal components of them all
#: (:data:`FRAME_COMPONENTS`), as the rod engine's speed branch does.
PER_THERMOMETER_FRAMES = 3
#: The numbers of leading principal components a frame on many thermometers follows
#: (one cause each, with and without a lag). Three alone: on synth_speed's records of 8
#: thermometers (a frame on a mix of a fast and a slow one, room thermometers beside,
#: AR noise, seeds 1-6) the frame on 1, 2 or 3 components named three components on 5
#: of 6 and a pair of frames on 2 on the sixth ("explained"); three alone named and
#: established all 6, also with 16 thermometers, and halved the Bonferroni count. Two
#: alternatives were tried post hoc on FL_THERMAL (README.posthoc.md 1.4.2), where the
#: rod engine's speed branch chooses among 1-8 by validation and takes 6 or 8 on most
#: rolling origins: the branch's 1-8 all as candidates (synthetic frames at 8 and 16
#: thermometers established 1 of 6: the nested frames fit as well as each other), and
#: one number chosen on the fit rows by BIC on N_eff (FL_THERMAL: worse than three on
#: every channel's rolling median). Neither was kept.
FRAME_COMPONENTS = (3,)


#: the nominal models of the speed-to-heat relation: one law (n/n_max)^p, one gain per
#: speed (eqs. 20-21 for a speed first met in the hold-out), or the lower BIC on N_eff
#: of the two (module docstring)
HEAT_MODELS = ("law", "per_speed", "auto")


@dataclass(frozen=True)
class HeatModel:
    """The nominal model's heat, resolved for one fit window.

    Attributes
    ----------
    kind : str, ``"law"`` or ``"per_speed"``
    seen_rpm : tuple of float, the non-zero speeds seen in the fit rows, one gain each
        (``"per_speed"``; () for the law) [1/min]
    unseen_weights : dict, unseen speed [1/min] -> {seen speed [1/min]: weight [-]}
        (eqs. 20-21, :func:`arfem.models.diagnosis.speed.speed_to_heat_map`; a weight on
        speed 0 has no gain: K(0) = 0)
    inputs : ndarray (N, len(seen_rpm)), the unit heat input of each seen speed, the
        unseen ones folded in by their weights [-]
    why : str, the choice in words
    """

    kind: str
    seen_rpm: tuple = ()
    unseen_weights: dict = field(default_factory=dict)
    inputs: np.ndarray | None = None
    why: str = ""


def choose_heat_model(time_s, speed_rpm, temperatures: dict, rows,
                      heat_model: str = "auto") -> HeatModel:
    """The speed plant's nominal heat for the fit rows ``rows`` (module docstring):
    ``"law"``; ``"per_speed"`` or ``"auto"``: per speed when ``rows`` see a non-zero
    speed, else the law (``"auto"``'s choice by BIC between the two is
    :func:`speed_plant`'s).

    Parameters
    ----------
    time_s : (N,) sample times [s]
    speed_rpm : (N,) spindle speed [1/min]
    temperatures : dict, ``T_<name>_C`` -> (N,) [°C] (the eqs. 20-21 early rise)
    rows : (N,) bool, the fit rows (before the hold-out, a growth reading)
    heat_model : one of :data:`HEAT_MODELS`

    Examples
    --------
    >>> t = np.arange(1, 7) * 60.0
    >>> sp = np.array([0.0, 1000.0, 1000.0, 0.0, 2000.0, 2000.0])
    >>> hm = choose_heat_model(t, sp, {}, t < 250.0)
    >>> hm.kind, hm.seen_rpm, float(hm.unseen_weights[2000.0][1000.0])
    ('per_speed', (1000.0,), 2.0)
    >>> hm.inputs[:, 0].tolist()
    [0.0, 1.0, 1.0, 0.0, 2.0, 2.0]
    """
    if heat_model not in HEAT_MODELS:
        raise ValueError(f"heat_model must be one of {HEAT_MODELS}, not {heat_model!r}")
    sp = np.asarray(speed_rpm, float)
    rows = np.asarray(rows, bool)
    seen = tuple(float(v) for v in np.unique(sp[rows]) if v > 0)
    if heat_model == "law" or not seen:
        why = "asked for" if heat_model == "law" else \
            "no non-zero speed before the hold-out to take a gain from"
        return HeatModel("law", why=f"one law (n/n_max)^p: {why}")
    _, _, W, _ = speed_to_heat_map(time_s, sp, temperatures, rows)
    cols = level_inputs(sp, seen, W)
    unseen = sorted(W)
    return HeatModel("per_speed", seen, W, np.column_stack([cols[v] for v in seen]),
                     f"one gain per speed ({len(seen)} seen before the hold-out"
                     + (f"; {len(unseen)} first met after it, by eqs. 20-21)" if unseen
                        else ")"))


@dataclass(frozen=True)
class SpeedSetting:
    """The nominal model's parameters and the causes' nonlinear ones in one trial.

    Attributes
    ----------
    time_constant_h : float, τ = 1/b of the AR(1) (at rest where the rate is speed-
        dependent) [h]
    heat_exponent : float, p of the heat law (n/n_max)^p [-]
    running_rate_scale : float, factor on b while the spindle turns [-] (1: nominal)
    frame_time_constant_h : float, a thermometer frame's lag [h]
    """

    time_constant_h: float
    heat_exponent: float
    running_rate_scale: float = 1.0
    frame_time_constant_h: float = 4.0


#: the setting's field of each cause's nonlinear parameter (by cause kind)
_SETTING_OF = {"convection_scale": "running_rate_scale",
               "frame_lag": "frame_time_constant_h"}


@dataclass(frozen=True)
class SpeedPlant:
    """The AR(1) of a speed-only record (module docstring).

    Attributes
    ----------
    name : str
    time_s : ndarray (N,), sample times [s]
    data : ndarray (N, 1), measured growth [µm], NaN missing
    speed_rpm : ndarray (N,), spindle speed over the interval ending at each row [1/min]
    temperatures : dict, ``T_<name>_C`` -> (N,) [°C], the frame's candidate thermometers
    load_shape : ndarray (N,), n / n_max [-]
    ambient_C : ndarray (N,) or None, the recorded ambient [°C]
    reference_C : float, the rod's nominal ambient (= initial = reference) [°C]
    heat : HeatModel, the nominal model's heat (:func:`choose_heat_model`)
    """

    name: str
    time_s: np.ndarray
    data: np.ndarray
    speed_rpm: np.ndarray
    temperatures: dict
    load_shape: np.ndarray
    cache: dict = field(default_factory=dict, repr=False)
    kind: str = "speed"
    channels: tuple = (Channel("growth_um", "growth", "displacement", 0, 1.0, "um"),)
    ambient_C: np.ndarray | None = None
    reference_C: float = 20.0
    not_searched: tuple = ()
    nominal_parameters: tuple = (TIME_CONSTANT, HEAT_EXPONENT)
    regrows: bool = False
    rules: SelectionRules = SelectionRules()
    heat: HeatModel = HeatModel("law")

    def candidate_causes(self) -> tuple:
        """A sensor drift; an ambient drift where the ambient is recorded and varies; a
        running-only rate where the spindle both runs and rests; a frame following each
        thermometer, without and with a lag."""
        out = [cause("sensor_drift", "growth_um", "um")]
        amb = self.ambient_C
        if amb is not None and np.ptp(amb[np.isfinite(amb)]) > 0:
            out.append(cause("ambient_drift"))
        running = self.speed_rpm > 0
        if running.any() and not running.all():
            out.append(cause("convection_scale", "running"))
        names, _ = temperature_matrix(self.temperatures)
        targets = list(self.temperatures) if len(self.temperatures) <= PER_THERMOMETER_FRAMES \
            else [components_target(k) for k in FRAME_COMPONENTS if k <= len(names)]
        for k in targets:
            out += [cause("frame_expansion", k), cause("frame_lag", k)]
        return tuple(out)

    def setting(self, causes, values: dict) -> SpeedSetting:
        """τ and p from ``values`` (their starts where not given), and the nonlinear
        parameter of each cause in ``causes`` from ``values`` {cause name: value}."""
        kw = {_SETTING_OF[c.kind]: float(values[c.name]) for c in causes
              if c.kind in _SETTING_OF and c.name in values}
        return SpeedSetting(*(float(values.get(p.name, p.start))
                              for p in (TIME_CONSTANT, HEAT_EXPONENT)), **kw)

    def _rate_1_s(self, s: SpeedSetting) -> np.ndarray:
        """The rod's rate b on each interval [1/s]: 1/τ, times the running factor while
        the spindle turns."""
        b = 1.0 / (s.time_constant_h * 3600.0)
        return b * np.where(self.speed_rpm > 0, s.running_rate_scale, 1.0)

    def _cached(self, key: tuple, make):
        if key not in self.cache:
            if len(self.cache) > 400:
                self.cache.clear()
            self.cache[key] = make()
        return self.cache[key]

    def _nuisance(self, s: SpeedSetting) -> tuple:
        """The unit-gain AR(1) of the heat law (or of each seen speed's heat input, per
        speed: :attr:`heat`) and the initial state's decay."""
        per_speed = self.heat.kind == "per_speed"

        def make():
            t, b = self.time_s, self._rate_1_s(s)
            U = self.heat.inputs if per_speed else \
                (np.maximum(self.load_shape, 0.0) ** s.heat_exponent)[:, None]
            cols = list(ar_columns_rates(t, U, b).T) + [np.exp(-np.cumsum(b * intervals(t)))]
            return tuple(c[:, None] for c in cols)
        p = 0.0 if per_speed else round(s.heat_exponent, 10)
        return self._cached(("nuisance", round(s.time_constant_h, 10), p,
                             round(s.running_rate_scale, 10)), make)

    def _ambient(self, s: SpeedSetting) -> np.ndarray:
        """The unit-gain AR(1) at the rod's rate of the ambient above the reference [K]."""
        def make():
            amb = np.nan_to_num(np.asarray(self.ambient_C, float) - self.reference_C)
            return ar_columns_rates(self.time_s, amb[:, None], self._rate_1_s(s))
        return self._cached(("ambient", round(s.time_constant_h, 10),
                             round(s.running_rate_scale, 10)), make)

    def _smoothed_C(self, column: str) -> np.ndarray:
        """A thermometer smoothed by :data:`THERMOMETER_SMOOTHING_S` [°C] (NaN missing)."""
        return self._cached(("smoothed", column), lambda: np.where(
            np.isfinite(self.temperatures[column]),
            centred_mean(self.time_s, self.temperatures[column], THERMOMETER_SMOOTHING_S),
            np.nan))

    def smoothed_temperature_C(self, column: str) -> np.ndarray:
        """Thermometer ``column`` as every frame cause of this plant sees it: each
        reading the centred mean of the readings within ±:data:`THERMOMETER_SMOOTHING_S`
        of it (:func:`arfem.models.diagnosis.speed_frame.centred_mean`), NaN where the
        reading is missing. The frame's state-space export reads it
        (:func:`arfem.models.diagnosis.export.speed_plant_state_space`), so that the
        compensator starts from the same input as the fit.

        Parameters
        ----------
        column : str
            A thermometer of the record (a key of :attr:`temperatures`, ``T_<name>_C``).

        Returns
        -------
        ndarray (N,)
            The smoothed temperature [°C], read-only (the plant's cached array).
        """
        T = self._smoothed_C(column).view()
        T.flags.writeable = False
        return T

    def _rise_K(self, column: str) -> np.ndarray:
        """A thermometer's smoothed rise above its first reading [K] (0 where missing)."""
        T = self._smoothed_C(column)
        first = T[np.flatnonzero(np.isfinite(T))[0]]
        return np.where(np.isfinite(T), T - first, 0.0)

    def _frame_lag(self, column: str, tau_h: float) -> np.ndarray:
        """A thermometer's rise through a first-order lag of ``tau_h`` [h] [K]."""
        return self._cached(("frame", column, round(tau_h, 10)), lambda: first_order_lag(
            self.time_s, self._rise_K(column), tau_h * 3600.0)[:, None])

    def _components(self, k: int, tau_h: float) -> list:
        """The ``k`` leading principal components of the complete thermometers, each
        smoothed, standardised over the whole record (inputs only: no growth reading
        of the hold-out enters), through a first-order lag of ``tau_h`` [h] (0: none)
        (:func:`arfem.models.diagnosis.speed_frame.frame_components`) [-]."""
        def make():
            names, _ = temperature_matrix(self.temperatures)
            T = np.column_stack([self._smoothed_C(n) for n in names])
            return [p[:, None] for p in frame_components(
                self.time_s, T, np.ones(self.time_s.size, bool), k, tau_h)]
        return self._cached(("components", k, round(tau_h, 10)), make)

    def design(self, causes, setting: SpeedSetting) -> Design:
        """Zero base (every nominal part is a nuisance), the causes' columns (N, 1)."""
        th = self.time_s / 3600.0
        cols = []
        for c in causes:
            if c.kind == "sensor_drift":
                cols += [np.ones((th.size, 1)), th[:, None].copy()]
            elif c.kind == "ambient_drift":
                cols.append(self._ambient(setting))
            elif c.kind in ("frame_expansion", "frame_lag") and c.target.startswith("pc1-"):
                tau = setting.frame_time_constant_h if c.kind == "frame_lag" else 0.0
                cols += self._components(len(c.linear_parameters), tau)
            elif c.kind == "frame_expansion":
                cols.append(self._rise_K(c.target)[:, None])
            elif c.kind == "frame_lag":
                cols.append(self._frame_lag(c.target, setting.frame_time_constant_h))
        nuisance = self._nuisance(setting)
        kinds = {c.kind for c in causes}
        if kinds & {"frame_expansion", "frame_lag"} and "sensor_drift" not in kinds:
            # the frame's reading at the start is unknown (the rise is taken from the
            # first reading, a sample after it): an offset, the drift's own where it is
            # fitted beside
            nuisance = nuisance + (np.ones((th.size, 1)),)
        return Design(np.zeros((th.size, 1)), tuple(cols), setting, nuisance)

    def regrown(self, setting: SpeedSetting) -> "SpeedPlant":
        """The plant itself (nothing is reduced; never called)."""
        return self

    def reference_models(self, rows) -> tuple:
        """The seed paper's own model as a data baseline: its AR(1) calibrated by eq. 17
        on the one-step pairs of ``rows`` (C1 and one C2 per speed seen there; a speed
        first met later by the early-rise mapping of eqs. 20-21), run free from the
        first row -- what the rod engine's speed branch takes as its baseline
        (:func:`arfem.models.diagnosis.speed.paper_ar`, the same function). A cause the
        pipeline names must beat it too (:data:`PAPER_AR_LABEL`). Kept per ``rows``: the
        verdict and the diagnosis's document ask for the same one."""
        y = self.data[:, 0]
        ok = np.asarray(rows, bool) & np.isfinite(y)

        def make():
            _, seen, W, _ = speed_to_heat_map(self.time_s, self.speed_rpm,
                                              self.temperatures, ok)
            pred, _ = paper_ar(self.time_s, np.where(np.isfinite(y), y, 0.0),
                               self.speed_rpm, ok, W, seen)
            return ((PAPER_AR_LABEL, {self.channels[0].column: pred}),)
        return self._cached(("reference", ok.tobytes()), make)


def speed_plant(name: str, time_s, growth_um, speed_rpm, temperatures=None,
                ambient_C=None, reference_C: float = 20.0,
                holdout_start_s: float | None = None, heat_model: str = "auto") -> SpeedPlant:
    """The :class:`SpeedPlant` of a speed-only record: times [s], growth [µm], speed
    [1/min], thermometers {``T_<name>_C``: (N,) [°C]}, the recorded ambient [°C] (or
    None), the rod's nominal ambient ``reference_C`` [°C], the diagnosis's hold-out
    start [s] (None: the default hold-out, :func:`~arfem.models.diagnosis.holdout.default_holdout`)
    and the nominal heat (one of :data:`HEAT_MODELS`, :func:`choose_heat_model` on the
    rows before the hold-out with a growth reading)."""
    t = np.asarray(time_s, float)
    sp = np.asarray(speed_rpm, float)
    y = np.asarray(growth_um, float).reshape(-1, 1)
    shape = sp / float(np.max(sp)) if np.max(sp) > 0 else np.zeros_like(sp)
    amb = None if ambient_C is None else np.asarray(ambient_C, float)
    temps = dict(temperatures or {})
    h0 = default_holdout(t, shape)[0] if holdout_start_s is None else float(holdout_start_s)
    rows = (t < h0) & np.isfinite(y[:, 0])
    heat = choose_heat_model(t, sp, temps, rows, heat_model)
    nominal = (TIME_CONSTANT,) if heat.kind == "per_speed" else (TIME_CONSTANT, HEAT_EXPONENT)
    plant = SpeedPlant(name, t, y, sp, temps, shape, ambient_C=amb,
                       reference_C=float(reference_C), nominal_parameters=nominal, heat=heat)
    if heat_model == "auto" and heat.kind != "law":
        law = with_fields(plant, nominal_parameters=(TIME_CONSTANT, HEAT_EXPONENT), cache={},
                          heat=HeatModel("law"))
        plant = _lower_bic(law, plant, rows)
    return plant


def _lower_bic(law: SpeedPlant, per_speed: SpeedPlant, rows) -> SpeedPlant:
    """Of the two nominal models, the one of lower BIC on N_eff on ``rows`` (the law
    unless the per-speed gains beat it by the screen's ``DELTA_BIC``), each fitted
    beside every linear candidate cause by GLS on the noise the pipeline fits on the
    per-speed plant; its ``heat.why`` says the BICs."""
    ctx = with_noise(make_context(per_speed), rows)
    lin = tuple(c for c in per_speed.candidate_causes() if not c.nonlinear)
    out = {}
    for p in (law, per_speed):
        c = with_fields(ctx, plant=p, wcache={}, n_eff_full=None)
        f = fit_mesh_causes(c, lin, rows, intervals=False)
        N = int((c.valid & rows[:, None]).sum())
        ne = residual_n_eff(c, f.prediction, rows)
        out[p.heat.kind] = float(bic(f.sse_w, N, ne, f.n_params))
    pick = per_speed if out["per_speed"] < out["law"] - DELTA_BIC else law
    why = (f"BIC on N_eff {out['per_speed']:.1f} per speed against {out['law']:.1f} for "
           f"one law, the lower by more than {DELTA_BIC:g} chosen, else the law")
    first = ("one gain per speed" if pick is per_speed else "one law (n/n_max)^p") + ": "
    return with_fields(pick, heat=with_fields(pick.heat, why=first + why + (
        f"; {per_speed.heat.why}" if pick is per_speed else "")))


def speed_plant_from_dataset(ds, holdout_start_s: float | None = None,
                             heat_model: str = "auto") -> SpeedPlant:
    """The :class:`SpeedPlant` of a validated ``speed_rpm`` record
    (:class:`arfem.models.diagnosis.dataset.Dataset`): growth with its flagged outliers
    left out, the speed, the thermometers ``T_<name>_C`` and the ambient, the rod's
    nominal ambient its reference; ``holdout_start_s`` and ``heat_model`` as
    :func:`speed_plant`'s."""
    if ds.speed_rpm is None:
        raise ValueError(f"{ds.name}: the speed plant needs a speed_rpm record")
    y = np.array(ds.growth_um, float)
    y[np.asarray(ds.outliers, bool)] = np.nan
    return speed_plant(ds.name, ds.time_s, y, ds.speed_rpm, dict(ds.temperatures),
                       ds.ambient_C, ds.rod.ambient_C, holdout_start_s, heat_model)


#: the contract cause (docs/measured-data.md) of each kind of the plant
_CONTRACT = {"sensor_drift": "sensor_drift", "frame_expansion": "frame_expansion",
             "frame_lag": "frame_expansion", "ambient_drift": "ambient_drift",
             "convection_scale": "speed_dependent_convection"}


def contract_causes(causes) -> tuple:
    """The named causes of a speed diagnosis (:class:`~arfem.models.diagnosis.result.NamedCause`)
    as the measured-data contract names them: ((contract cause, {parameter: value},
    {parameter: (low, high)}), ...), strongest first.

    >>> from arfem.models.diagnosis.result import NamedCause
    >>> c = NamedCause("sensor_drift", "sensor_drift:growth_um", "growth_um",
    ...                {"offset_um": 0.1, "drift_um_per_h": 0.2}, {}, {})
    >>> contract_causes((c,))[0][:2]
    ('sensor_drift', {'offset_um': 0.1, 'drift_um_per_h': 0.2})
    """
    return tuple((_CONTRACT.get(c.cause, c.name), dict(c.parameters), dict(c.ci95))
                 for c in causes)


def contract_names(plant: SpeedPlant) -> dict:
    """{plant cause name (``kind:target``): contract cause} of every candidate cause of
    ``plant``, to write the pipeline's texts in the contract's names."""
    return {c.name: _CONTRACT.get(c.kind, c.kind) for c in plant.candidate_causes()}


def _h_stopped_W_m2K(rho_c_R_J_m2K: float, time_constant_h: float) -> float:
    """The h at rest of the lumped rod (paper eq. 13, b = 2h/(ρcR) = 1/τ):
    h = ρcR/(2τ) [W/(m²K)]."""
    return rho_c_R_J_m2K / (2.0 * time_constant_h * 3600.0)


def convection_h_W_m2K(h_scale: float, time_constant_h: float,
                       rho_c_R_J_m2K: float) -> dict:
    """The two h of a running-only rate (``convection_scale:running``) as the contract's
    ``speed_dependent_convection`` writes them: h_stopped = ρcR/(2τ) (paper eq. 13,
    b = 1/τ at rest) and h_running = h_scale · h_stopped [W/(m²K)].

    Parameters
    ----------
    h_scale : float, the factor on the rate while the spindle turns [-]
    time_constant_h : float, the plant's τ at rest [h]
    rho_c_R_J_m2K : float, ρ·c·R of the ``[rod]`` [J/(m²K)]

    Examples
    --------
    >>> h = convection_h_W_m2K(1.5, 0.5, 7850 * 460 * 0.1)
    >>> round(h["h_stopped_W_m2K"], 2), round(h["h_running_W_m2K"], 2)
    (100.31, 150.46)
    """
    h0 = _h_stopped_W_m2K(rho_c_R_J_m2K, time_constant_h)
    return {"h_running_W_m2K": float(h_scale) * h0, "h_stopped_W_m2K": h0}


def convection_h_ci95(h_scale: float, time_constant_h: float, rho_c_R_J_m2K: float,
                      var_scale: float, var_tau_h2: float, cov_scale_tau_h: float) -> dict:
    """95 % intervals of :func:`convection_h_W_m2K`'s two h by the delta method on the
    named fit's joint covariance of h_scale and τ (:attr:`arfem.models.geodiagnosis.fit.Fit.covariance`,
    Gauss–Newton on the whitened residual, as every interval of the pipeline):
    with h0 = ρcR/(2τ), var h_stopped = (h0/τ)² var τ and
    var h_running = h0² var s + (s·h0/τ)² var τ − 2 s h0²/τ cov(s, τ); each h ± 1.96 σ.

    Examples
    --------
    >>> ci = convection_h_ci95(1.5, 0.5, 7850 * 460 * 0.1, 0.0, 0.0, 0.0)
    >>> [round(v, 2) for v in ci["h_stopped_W_m2K"]]
    [100.31, 100.31]
    """
    h = convection_h_W_m2K(h_scale, time_constant_h, rho_c_R_J_m2K)
    h0, s, tau = h["h_stopped_W_m2K"], float(h_scale), float(time_constant_h)
    var_stop = (h0 / tau) ** 2 * var_tau_h2
    var_run = h0 * h0 * var_scale + (s * h0 / tau) ** 2 * var_tau_h2 \
        - 2.0 * s * h0 * h0 / tau * cov_scale_tau_h
    return {k: (float(h[k] - Z95 * np.sqrt(max(v, 0.0))), float(h[k] + Z95 * np.sqrt(max(v, 0.0))))
            for k, v in (("h_running_W_m2K", var_run), ("h_stopped_W_m2K", var_stop))}


def speed_candidate_parameters(one, nominal, rho_c_R_J_m2K: float) -> dict:
    """A screened single cause's parameters in the contract's names (no intervals: the
    screen computes none): a running-only rate as its two h at that fit's own τ
    (:func:`convection_h_W_m2K`), any other cause's the plant's own.

    ``one``: the cause (:class:`~arfem.models.diagnosis.result.NamedCause`);
    ``nominal``: its fit's nominal parameters {``time_constant_h``: τ [h], ...}
    (:attr:`arfem.models.geodiagnosis.engine.Ranked.nominal`); ``rho_c_R_J_m2K``:
    ρ·c·R of the ``[rod]`` [J/(m²K)].
    """
    if one.cause == "convection_scale" and TIME_CONSTANT.name in nominal:
        return convection_h_W_m2K(one.parameters["h_scale"], nominal[TIME_CONSTANT.name],
                                  rho_c_R_J_m2K)
    return dict(one.parameters)


def speed_contract_entries(fit, rho_c_R_J_m2K: float) -> tuple:
    """The named causes of a speed diagnosis as the measured-data contract writes them
    (:class:`arfem.models.diagnosis.rod_plant.ContractCause`, in the fit's order).

    ``fit``: the pipeline's named :class:`arfem.models.geodiagnosis.fit.Fit` (its τ in
    :attr:`~arfem.models.geodiagnosis.fit.Fit.nominal`, their joint covariance in
    :attr:`~arfem.models.geodiagnosis.fit.Fit.covariance`); ``rho_c_R_J_m2K``: ρ·c·R
    of the ``[rod]`` [J/(m²K)], which turns τ into the h at rest (paper eq. 13).
    ``speed_dependent_convection``: ``h_running_W_m2K`` and ``h_stopped_W_m2K``
    (:func:`convection_h_W_m2K`), their intervals by the delta method on the joint
    covariance of h_scale and τ (:func:`convection_h_ci95`). A frame keeps the plant's
    own parameters, which the contract names for speed records (docs/measured-data.md):
    ``frame_gain_um_per_K`` (per kelvin of its thermometer's rise),
    ``frame_gain_pc<j>_um`` (per unit principal component) and, lagged,
    ``frame_time_constant_h``.
    """
    tau = float(fit.nominal.get(TIME_CONSTANT.name, TIME_CONSTANT.start))
    cov = fit.covariance
    out = []
    for c, (name, p, ci) in zip(fit.causes, contract_causes(named_causes(fit))):
        if name == "speed_dependent_convection":
            s = p["h_scale"]
            p = convection_h_W_m2K(s, tau, rho_c_R_J_m2K)
            t, k = (None, TIME_CONSTANT.name), (c.name, "h_scale")
            ci = {} if cov is None or t not in cov.keys else convection_h_ci95(
                s, tau, rho_c_R_J_m2K, cov.of(k, k), cov.of(t, t), cov.of(k, t))
        out.append(ContractCause(name, p, {k: tuple(v) for k, v in ci.items()}))
    return tuple(out)
