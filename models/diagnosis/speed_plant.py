"""A speed-only record (``speed_rpm``, no heat flux) as a :class:`~arfem.models.plant.Plant`
of the one diagnosis pipeline (issue 41, build item 1): the seed paper's AR(1) whose
heat is unknown per speed, with a frame that follows a thermometer.

Nominal model (paper eqs. 12-14 with the heat of a speed unknown): the growth [µm] is
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

Causes (the one vocabulary, :func:`arfem.models.plant.cause`):

* ``sensor_drift:growth_um``: an offset [µm] and a drift [µm/h];
* ``frame_expansion:<T column>``: the frame grows ``frame_gain_um_per_K`` × the rise
  of a recorded thermometer (°C above its first reading) -- the simplest structure of
  :mod:`arfem.models.diagnosis.speed_frame` (one thermometer, no lag, no principal
  components).

What this plant does not do (the rod engine's speed branch does): one gain per speed
with the paper's eqs. 20-21 mapping, the frame's lagged principal components and the
choice of structure, ambient drift, and a speed-dependent rate.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arfem.models.diagnosis.forward import ar_columns_rates, intervals
from arfem.models.geodiagnosis.problem import Channel
from arfem.models.plant import Design, Parameter, cause

__all__ = ["SpeedPlant", "SpeedSetting", "speed_plant", "TIME_CONSTANT", "HEAT_EXPONENT"]

#: The nominal model's time constant τ [h]: bounds 1 min .. 200 h, searched from 1 h
#: (no "no effect": not a cause).
TIME_CONSTANT = Parameter("time_constant_h", "h", float("nan"), linear=False,
                          bounds=(1.0 / 60.0, 200.0), start=1.0, probe=1.0)
#: The exponent p of the speed-to-heat law (n/n_max)^p [-]: bounds 0.5 .. 3, from 1.
HEAT_EXPONENT = Parameter("heat_exponent", "-", float("nan"), linear=False,
                          bounds=(0.5, 3.0), start=1.0, probe=1.0)


@dataclass(frozen=True)
class SpeedSetting:
    """The nominal model's parameters in one trial.

    Attributes
    ----------
    time_constant_h : float, τ = 1/b of the AR(1) [h]
    heat_exponent : float, p of the heat law (n/n_max)^p [-]
    """

    time_constant_h: float
    heat_exponent: float


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
    not_searched: tuple = ()
    nominal_parameters: tuple = (TIME_CONSTANT, HEAT_EXPONENT)
    regrows: bool = False

    def candidate_causes(self) -> tuple:
        """A sensor drift, and a frame following each thermometer."""
        return (cause("sensor_drift", "growth_um", "um"),) + tuple(
            cause("frame_expansion", k) for k in self.temperatures)

    def setting(self, causes, values: dict) -> SpeedSetting:
        """τ and p from ``values`` (their starts where not given)."""
        return SpeedSetting(*(float(values.get(p.name, p.start))
                              for p in (TIME_CONSTANT, HEAT_EXPONENT)))

    def _nuisance(self, s: SpeedSetting) -> tuple:
        """The unit-gain AR(1) of the heat law and the initial state's decay."""
        key = (round(s.time_constant_h, 10), round(s.heat_exponent, 10))
        if key not in self.cache:
            if len(self.cache) > 400:
                self.cache.clear()
            t = self.time_s
            b = np.full(t.size, 1.0 / (s.time_constant_h * 3600.0))
            heat = np.maximum(self.load_shape, 0.0) ** s.heat_exponent
            cols = [ar_columns_rates(t, heat[:, None], b)[:, 0],
                    np.exp(-np.cumsum(b * intervals(t)))]
            self.cache[key] = tuple(c[:, None] for c in cols)
        return self.cache[key]

    def design(self, causes, setting: SpeedSetting) -> Design:
        """Zero base (every nominal part is a nuisance), the causes' columns (N, 1)."""
        th = self.time_s / 3600.0
        cols = []
        for c in causes:
            if c.kind == "sensor_drift":
                cols += [np.ones((th.size, 1)), th[:, None].copy()]
            elif c.kind == "frame_expansion":
                T = np.asarray(self.temperatures[c.target], float)
                first = T[np.flatnonzero(np.isfinite(T))[0]]
                cols.append(np.where(np.isfinite(T), T - first, 0.0)[:, None])
        return Design(np.zeros((th.size, 1)), tuple(cols), setting, self._nuisance(setting))

    def regrown(self, setting: SpeedSetting) -> "SpeedPlant":
        """The plant itself (nothing is reduced; never called)."""
        return self


def speed_plant(name: str, time_s, growth_um, speed_rpm, temperatures=None) -> SpeedPlant:
    """The :class:`SpeedPlant` of a speed-only record: times [s], growth [µm], speed
    [1/min] and thermometers {``T_<name>_C``: (N,) [°C]}."""
    t = np.asarray(time_s, float)
    sp = np.asarray(speed_rpm, float)
    shape = sp / float(np.max(sp)) if np.max(sp) > 0 else np.zeros_like(sp)
    return SpeedPlant(name, t, np.asarray(growth_um, float).reshape(-1, 1), sp,
                      dict(temperatures or {}), shape)
