"""A simulated spindle to test a compensator against: the FEM rod under a speed program,
with an effect the paper's AR(1) does not model hidden in it.

The rod is the axisymmetric FEM (Q2, finer than the diagnosis's reduced model, so that
the two discretisations differ), integrated by Crank–Nicolson one interval Δτ at a time
(:class:`arfem.fem.stepper.HeatStepper`). The spindle speed follows a repeating program;
the heat flux into the heated end is proportional to it. The hidden effect is the one
the seed paper names as its model's open limit: the ambient air temperature varies
(a daily sine), which heats and cools the rod through its lateral convection; the
paper's AR(1) (eqs. 12-14) sees only the heat input. The readings are those of a
machine: speed, heat flux, ambient and two rod temperatures, and the growth a
displacement sensor reads (the true growth plus white noise).

:class:`AxesTwin` is a machine with several compensation axes (issue 32 item 5): a
solved ``[geometry]`` scenario (the spindle unit's FEM, with its speed-dependent
convection, which the exported linear model only approximates) served interval by
interval: the inputs, the thermometers and each displacement sensor's reading (true
displacement plus white noise), and per axis the true drift of the tool centre point.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from arfem.params import InputError, Rod

__all__ = ["TwinProgram", "SpindleTwin", "TwinReading", "DEFAULT_PROGRAM", "AxesReading",
           "AxesTwin"]

#: (duration [h], speed [1/min]) segments of the default 20 h program, repeated
DEFAULT_PROGRAM = ((3.0, 3000.0), (1.0, 0.0), (4.0, 4500.0), (2.0, 0.0), (2.0, 6000.0),
                   (8.0, 0.0))


@dataclass(frozen=True)
class TwinProgram:
    """What the twin does and hides.

    Attributes
    ----------
    segments : tuple of (float, float)
        (duration [h], speed [1/min]) pairs, repeated.
    dtau_s : float
        Interval Δτ between readings [s].
    q_per_rpm_W_m2 : float
        Heat flux per unit speed [W/m² per 1/min] (3000 1/min → 2000 W/m², the paper's
        lower load).
    ambient_amplitude_K : float
        Amplitude of the daily ambient sine [K] (the hidden effect; 0 = none).
    ambient_peak_h : float
        Hour of the day at which the ambient peaks [h].
    growth_noise_um : float
        White noise σ of the growth sensor [µm].
    temperature_noise_K : float
        White noise σ of the temperature sensors [K].
    seed : int
        Seed of the sensor noise.
    nan_at_step : int
        Step at which the ``q_W_m2`` reading is NaN (a sensor fault to test alarms);
        −1 = never.
    """

    segments: tuple = DEFAULT_PROGRAM
    dtau_s: float = 60.0
    q_per_rpm_W_m2: float = 2000.0 / 3000.0
    ambient_amplitude_K: float = 2.0
    ambient_peak_h: float = 15.0
    growth_noise_um: float = 0.05
    temperature_noise_K: float = 0.02
    seed: int = 0
    nan_at_step: int = -1

    def __post_init__(self):
        if not self.segments or any(len(s) != 2 or not s[0] > 0 or s[1] < 0
                                    for s in self.segments):
            raise InputError("must be (hours > 0, speed >= 0) pairs", "segments")
        for name in ("dtau_s", "q_per_rpm_W_m2"):
            if not getattr(self, name) > 0:
                raise InputError(f"must be > 0, got {getattr(self, name)!r}", name)

    def speed_rpm(self, t_end_s: float) -> float:
        """Speed over the interval that ends at ``t_end_s`` [1/min] (its midpoint's)."""
        period = sum(h for h, _ in self.segments) * 3600.0
        tm = (t_end_s - 0.5 * self.dtau_s) % period
        edge = 0.0
        for hours, rpm in self.segments:
            edge += hours * 3600.0
            if tm < edge:
                return float(rpm)
        return float(self.segments[-1][1])

    def ambient_C(self, rod: Rod, t_end_s: float) -> float:
        """Ambient over the interval that ends at ``t_end_s`` [°C] (its midpoint's; the
        sine starts at the nominal ambient, so the rod starts in equilibrium)."""
        tm = t_end_s - 0.5 * self.dtau_s
        w = 2.0 * np.pi / 86400.0
        phase = w * (self.ambient_peak_h * 3600.0) - np.pi / 2
        return float(rod.ambient_C + self.ambient_amplitude_K
                     * (np.sin(w * tm - phase) - np.sin(-phase)))


@dataclass(frozen=True)
class TwinReading:
    """What the twin reads at the end of one Δτ (the inputs held over it).

    ``time_s`` [s], ``speed_rpm`` [1/min], ``q_W_m2`` [W/m²] (NaN at the program's
    ``nan_at_step``), ``ambient_C``, ``T_face_C`` (centre of the heated face) and
    ``T_mid_C`` (surface at mid-length) [°C], each with the program's temperature noise;
    ``true_growth_um`` (the FEM's) and ``growth_um`` (measured: plus the sensor noise) [µm].
    """

    time_s: float
    speed_rpm: float
    q_W_m2: float
    ambient_C: float
    T_face_C: float
    T_mid_C: float
    true_growth_um: float
    growth_um: float

    def as_dict(self) -> dict:
        """Reading name → value, in the order above (a record's columns)."""
        return asdict(self)


@dataclass
class SpindleTwin:
    """The FEM rod stepped through a :class:`TwinProgram`, one Δτ per :meth:`advance`.

    Examples
    --------
    >>> tw = SpindleTwin(TwinProgram(growth_noise_um=0.0), nr=2, nz=8)
    >>> r = [tw.advance() for _ in range(60)]
    >>> r[-1].time_s, r[-1].speed_rpm, round(r[-1].q_W_m2, 6)
    (3600.0, 3000.0, 2000.0)
    >>> 0 < r[0].growth_um < r[-1].growth_um
    True
    """

    program: TwinProgram = field(default_factory=TwinProgram)
    rod: Rod = field(default_factory=Rod)
    nr: int = 6
    nz: int = 32
    step_index: int = field(init=False, default=0)

    def __post_init__(self):
        from arfem.fem.heat import build_axisymmetric
        from arfem.fem.stepper import HeatStepper
        self._stepper = HeatStepper(build_axisymmetric(self.rod, order=2, nr=self.nr,
                                                       nz=self.nz), self.program.dtau_s)
        self._rng = np.random.default_rng(self.program.seed)
        R, L = self.rod.radius_m, self.rod.length_m
        self._points = {"T_face_C": (0.0, 0.0), "T_mid_C": (R, 0.5 * L)}

    def advance(self) -> TwinReading:
        """Step one Δτ; returns the readings at its end (inputs held over it)."""
        p, rod = self.program, self.rod
        self.step_index += 1
        t = self.step_index * p.dtau_s
        rpm = p.speed_rpm(t)
        q = rpm * p.q_per_rpm_W_m2
        amb = p.ambient_C(rod, t)
        g = self._stepper.step(q, rod.convection_W_m2K, amb - rod.ambient_C)
        noise = self._rng.standard_normal(4)
        temps = {name: float(self._stepper.temperature_C(pt)
                             + p.temperature_noise_K * noise[1 + j])
                 for j, (name, pt) in enumerate(self._points.items())}
        return TwinReading(
            time_s=float(t), speed_rpm=rpm,
            q_W_m2=float("nan") if self.step_index == p.nan_at_step else float(q),
            ambient_C=float(amb + p.temperature_noise_K * noise[0]), **temps,
            true_growth_um=g, growth_um=float(g + p.growth_noise_um * noise[3]))


@dataclass(frozen=True)
class AxesReading:
    """What an :class:`AxesTwin` reads at the end of one interval.

    ``time_s`` [s]; ``values``: reading name → value (the inputs over the interval,
    e.g. ``P_front_bearing_W`` [W], ``speed_rpm``, ``ambient_C``; the thermometers
    ``T_<name>_C`` [°C]; each displacement sensor ``d_<name>_um`` and ``growth_um`` (the
    Z axis's) as measured [µm]); ``true_um``: axis → the true displacement [µm].
    """

    time_s: float
    values: dict
    true_um: dict

    def as_dict(self) -> dict:
        """Reading name → value: the time, the readings, then ``true_<AXIS>_um``."""
        return {"time_s": self.time_s, **self.values,
                **{f"true_{ax}_um": v for ax, v in self.true_um.items()}}


@dataclass
class AxesTwin:
    """A machine with several axes that replays a solved run, one interval per
    :meth:`advance`.

    Parameters
    ----------
    time_s : ndarray (n,)
        Sample times [s], the first at 0 (the start, not served).
    readings : dict
        Reading name → (n,) values (each over the interval that ends at the sample).
    true_um : dict
        Axis → (n,) true displacement [µm].
    measured : dict
        Axis → the name of its displacement reading (``d_<sensor>_um``), which is served
        as true + noise.
    noise_um : float
        White noise σ of the displacement sensors [µm].
    seed : int
        Seed of the noise.

    Examples
    --------
    >>> t = np.arange(4) * 60.0
    >>> tw = AxesTwin(t, {"P_a_W": np.full(4, 5.0)}, {"Z": np.array([0, 1, 2, 3.0])},
    ...               {"Z": "d_tcp_z_um"})
    >>> r = tw.advance()
    >>> r.time_s, r.values["d_tcp_z_um"], r.true_um, tw.n_steps
    (60.0, 1.0, {'Z': 1.0}, 3)
    """

    time_s: np.ndarray
    readings: dict
    true_um: dict
    measured: dict
    noise_um: float = 0.0
    seed: int = 0
    step_index: int = field(init=False, default=0)

    def __post_init__(self):
        if not self.noise_um >= 0:
            raise InputError(f"must be >= 0, got {self.noise_um!r}", "noise_um")
        self._rng = np.random.default_rng(self.seed)

    @property
    def axes(self) -> tuple:
        return tuple(self.true_um)

    @property
    def names(self) -> tuple:
        """The readings' names, in the order :meth:`advance` gives them."""
        return tuple(self.readings) + tuple(self.measured.values()) + ("growth_um",)

    @property
    def n_steps(self) -> int:
        """Intervals the run holds (after the start)."""
        return int(np.asarray(self.time_s).size - 1)

    def advance(self) -> AxesReading:
        """The next interval's readings; :class:`IndexError` past the run's end."""
        if self.step_index >= self.n_steps:
            raise IndexError("the run has ended")
        self.step_index += 1
        k = self.step_index
        values = {nm: float(v[k]) for nm, v in self.readings.items()}
        true = {ax: float(v[k]) for ax, v in self.true_um.items()}
        noise = self._rng.standard_normal(len(self.axes))
        for j, ax in enumerate(self.axes):
            values[self.measured[ax]] = true[ax] + self.noise_um * float(noise[j])
        z = "Z" if "Z" in true else self.axes[0]
        values["growth_um"] = values[self.measured[z]]
        return AxesReading(float(self.time_s[k]), values, true)
