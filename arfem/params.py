"""Validated physical inputs shared by the FEM and the closed-form models.

Everything a solver or model needs is held in two small immutable objects:

* :class:`Rod` -- geometry, material and the nominal boundary conditions of the
  spindle rod of Du et al. (2021), Sec. 1. Defaults are the paper's values.
* :class:`Schedule` -- piecewise-constant inputs in time: heat flux into the
  heated end face, ambient air temperature and convection coefficient, each
  constant on a segment.

Both refuse non-physical values at construction, before any solve, by raising
:class:`InputError` with a one-line message naming the offending field.

References
----------
.. [1] Du L., et al., "First-order autoregressive modeling method for axial
   thermal error of machine tool spindle", J. Harbin Inst. Technol. 53(7), 2021.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Iterable

import numpy as np

__all__ = [
    "InputError",
    "one_line",
    "PLAUSIBLE_RANGES",
    "check_plausible",
    "Rod",
    "Schedule",
    "paper_cycle",
    "PAPER_PHASES_S",
]


_LINE_BREAKING = {c: f"\\x{c:02x}" for c in list(range(0x20)) + [0x7f]} | {
    ord("\n"): "\\n", ord("\r"): "\\r", ord("\t"): " ", 0x85: "\\x85",
    0x2028: "\\u2028", 0x2029: "\\u2029"}


def one_line(text) -> str:
    """``text`` with every control character (a newline or NUL in a file name, say)
    shown as an escape, so that an error message stays one line.

    >>> print(one_line("a\\nb.toml\\x00"))
    a\\nb.toml\\x00
    """
    return str(text).translate(_LINE_BREAKING)


class InputError(ValueError):
    """Bad user input. ``str(err)`` is one line naming where and what.

    Parameters
    ----------
    message : str
        What is wrong, e.g. ``"must be > 0, got -1"``.
    where : str, optional
        Where it is wrong: a file, a key path, a row (``"case.toml: rod.radius_m"``).
    """

    def __init__(self, message: str, where: str | None = None):
        self.where = one_line(where) if where is not None else None
        self.message = one_line(message)
        super().__init__(f"{self.where}: {self.message}" if self.where else self.message)

    def at(self, where: str) -> "InputError":
        """Return a copy located at ``where`` (prefixing any existing location)."""
        loc = f"{where}: {self.where}" if self.where else where
        return InputError(self.message, loc)

    def in_table(self, table: str) -> "InputError":
        """Return a copy located at the key ``<table>.<where>`` (a field of a table, e.g.
        :class:`Rod`'s ``poisson_ratio`` read from ``[rod]``), as every other key is
        named; ``table`` itself where it has no location.

        >>> str(InputError("must lie in (-1, 0.5), got 0.6", "poisson_ratio").in_table("rod"))
        'rod.poisson_ratio: must lie in (-1, 0.5), got 0.6'
        """
        return InputError(self.message, f"{table}.{self.where}" if self.where else table)


#: Plausible ranges [lo, hi] of the quantities a user types or records, with the unit
#: they must be in: a value outside is almost certainly in the wrong unit, or no reading.
#: The readings' ranges (ambient, temperature, speed, heat, growth) are the live
#: compensator's: a record is judged as the machine's readings are judged live.
PLAUSIBLE_RANGES = {
    "radius_m": (1e-4, 5.0, "metres (a radius in mm?)"),
    "length_m": (1e-3, 50.0, "metres (a length in mm?)"),
    "conductivity_W_mK": (1e-3, 2000.0, "W/(m·K)"),
    "density_kg_m3": (10.0, 30000.0, "kg/m³ (a density in g/cm³?)"),
    "specific_heat_J_kgK": (10.0, 20000.0, "J/(kg·K) (a value in kJ/(kg·K)?)"),
    "expansion_1_K": (1e-8, 1e-3, "1/K (a value in µm/(m·K) or ppm/K?)"),
    "youngs_modulus_Pa": (1e6, 2e12, "Pa (a modulus in GPa?)"),
    "convection_W_m2K": (1.0, 2000.0, "W/(m²·K) (a value in kW/(m²·K)?)"),
    # the air around a machine tool (also a scenario's reference temperature); the live
    # loop's range for an ambient reading
    "ambient_C": (-10.0, 50.0, "°C (a temperature in K?)"),
    # any other temperature a machine's thermometer reads (a bearing, a motor, a frame)
    "temperature_C": (-10.0, 150.0, "°C (a temperature in K?)"),
    "q_W_m2": (0.0, 1e7, "W/m²"),
    # the heat a source puts into a machine-tool structure (a bearing set, a motor's
    # losses): well under a megawatt
    "power_W": (0.0, 1e6, "W (a power in mW?)"),
    "h_W_m2K": (0.01, 1e5, "W/(m²·K)"),
    "speed_rpm": (0.0, 1e5, "1/min (a speed in rad/s or Hz?)"),
    # a scenario's cycle, a phase of it [s]: a century at most (a duration in ms?)
    "duration_s": (0.0, 3.2e9, "s (a duration in ms?)"),
    # a coordinate of a mesh or a sensor, in metres once the declared unit is applied
    # (the unit's tell-tale sizes are judged by the mesh's bounding box, fem/gmsh_io.py)
    "coordinate_m": (-1e6, 1e6, "metres (no machine part lies this far)"),
    # fitted magnitudes of the diagnosis (arfem.models.diagnosis): outside these the fit
    # points at wrong units or a wrong [rod], not at a physical cause
    "heat_input_scale": (0.2, 5.0, "times the nominal heat input (growth_um in mm, or a "
                                   "[rod] value in the wrong unit?)"),
    "fitted_h_W_m2K": (1.0, 2000.0, "W/(m²·K) (a [rod] value in the wrong unit?)"),
    "ambient_gain_um_per_K": (0.05, 500.0, "µm/K (growth_um in mm?)"),
    "drift_um_per_h": (-100.0, 100.0, "µm/h (growth_um in nm?)"),
    # measured thermal growth of a spindle: tens of µm, never 1 mm (the live loop's
    # bound on an input's share of the growth); 5 mm would be a value in nm or a broken
    # sensor, and 1e300 ends in inf/nan scores
    "growth_um": (-1000.0, 1000.0, "µm (a growth in nm?)"),
    # a spindle's thermal tilt (ISO 230-3's A, B): tens of µrad; 10 mrad is a tilt in
    # nrad or a broken probe
    "tilt_urad": (-1e4, 1e4, "µrad (a tilt in nrad?)"),
}


def check_plausible(key: str, value: float, where: str) -> float:
    """``value`` if it is finite and lies in ``PLAUSIBLE_RANGES[key]`` (or ``key`` has no range),
    else one :class:`InputError` line at ``where`` naming the unit expected.

    Examples
    --------
    >>> check_plausible("ambient_C", 21.5, "case.toml: rod.ambient_C")
    21.5
    >>> try:
    ...     check_plausible("ambient_C", 293.15, "case.toml: rod.ambient_C")
    ... except InputError as e:
    ...     print(e)
    case.toml: rod.ambient_C: 293.15 is outside the plausible range [-10, 50] for a value in °C (a temperature in K?)
    """
    if key in PLAUSIBLE_RANGES:
        lo, hi, unit = PLAUSIBLE_RANGES[key]
        if not lo <= value <= hi:             # NaN fails too
            shown = f"{value:g}" if math.isfinite(value) else repr(value)
            if lo == 0.0 and value < 0:
                raise InputError(f"{shown} is negative; a value in {unit} is >= 0 (the "
                                 f"plausible range is [0, {hi:g}])", where)
            raise InputError(f"{shown} is outside the plausible range [{lo:g}, {hi:g}] "
                             f"for a value in {unit}", where)
    return value


def check_finite(name: str, value) -> float:
    """``float(value)``, or an :class:`InputError` at ``name`` if it is not a finite number."""
    try:
        v = float(value)
    except OverflowError:
        raise InputError(f"is too large for a number ({len(str(value))} digits)", name) from None
    except (TypeError, ValueError):
        raise InputError(f"must be a number, got {value!r}", name) from None
    if not math.isfinite(v):
        raise InputError(f"must be finite, got {value!r}", name)
    return v


def check_positive(name: str, value, allow_zero: bool = False) -> float:
    """Like :func:`check_finite`, and > 0 (or >= 0 with ``allow_zero``)."""
    v = check_finite(name, value)
    if v < 0 or (v == 0 and not allow_zero):
        raise InputError(f"must be {'>= 0' if allow_zero else '> 0'}, got {value!r}", name)
    return v




@dataclass(frozen=True)
class Rod:
    """Spindle rod: geometry, material and nominal boundary conditions.

    Field names carry their SI unit; defaults are the seed paper's values (Du et al. 2021, §2).

    Parameters
    ----------
    radius_m : float
        Rod radius R [m].
    length_m : float
        Rod length L [m]. Heat enters the end face z = 0; z = L is adiabatic.
    conductivity_W_mK : float
        Thermal conductivity λ [W/(m·K)].
    density_kg_m3 : float
        Density ρ [kg/m³].
    specific_heat_J_kgK : float
        Specific heat capacity c [J/(kg·K)].
    expansion_1_K : float
        Linear thermal expansion coefficient α [1/K].
    youngs_modulus_Pa : float
        Young's modulus E [Pa].
    poisson_ratio : float
        Poisson's ratio ν [-], in (-1, 0.5).
    convection_W_m2K : float
        Convection coefficient h on the lateral surface [W/(m²·K)].
    ambient_C : float
        Nominal ambient air temperature [°C]; also the initial and the
        stress-free reference temperature.

    Examples
    --------
    >>> rod = Rod()
    >>> round(rod.biot, 3)
    0.11
    >>> Rod(radius_m=-1)
    Traceback (most recent call last):
    ...
    arfem.params.InputError: radius_m: must be > 0, got -1
    """

    radius_m: float = 0.1
    length_m: float = 0.8
    conductivity_W_mK: float = 50.0
    density_kg_m3: float = 7850.0
    specific_heat_J_kgK: float = 460.0
    expansion_1_K: float = 12e-6
    youngs_modulus_Pa: float = 206e9
    poisson_ratio: float = 0.3
    convection_W_m2K: float = 55.0
    ambient_C: float = 20.0

    def __post_init__(self):
        for f in fields(self):
            name = f.name
            value = getattr(self, name)
            if name == "poisson_ratio":
                v = check_finite(name, value)
                if not -1.0 < v < 0.5:
                    raise InputError(f"must lie in (-1, 0.5), got {value!r}", name)
            elif name == "ambient_C":
                v = check_finite(name, value)
                if v < -273.15:
                    raise InputError(f"is below absolute zero, got {value!r}", name)
            else:
                v = check_positive(name, value)
            object.__setattr__(self, name, v)

    # -- derived quantities of the 1D theory (paper eqs. 1-4) ------------------
    @property
    def diffusivity_m2_s(self) -> float:
        """a = λ/(ρc) [m²/s]."""
        return self.conductivity_W_mK / (self.density_kg_m3 * self.specific_heat_J_kgK)

    @property
    def fin_rate_1_s(self) -> float:
        """b = 2h/(ρcR) [1/s], the lateral-loss rate of the 1D fin equation."""
        return 2.0 * self.convection_W_m2K / (
            self.density_kg_m3 * self.specific_heat_J_kgK * self.radius_m)

    @property
    def biot(self) -> float:
        """Biot number hR/λ [-]."""
        return self.convection_W_m2K * self.radius_m / self.conductivity_W_mK

    @property
    def area_m2(self) -> float:
        """Cross-section area πR² [m²]."""
        return math.pi * self.radius_m ** 2

    def with_(self, **changes) -> "Rod":
        """Return a copy with some fields changed (validated again)."""
        return replace(self, **changes)


@dataclass(frozen=True)
class Schedule:
    """Piecewise-constant inputs: one value per segment, segments back to back from t = 0.

    Parameters
    ----------
    durations_s : array_like
        Length of each segment [s], all > 0.
    q_W_m2 : array_like
        Heat flux into the heated end face on each segment [W/m²], >= 0.
    ambient_C : array_like or None
        Ambient air temperature on each segment [°C]. ``None``: the rod's nominal
        ambient throughout.
    h_W_m2K : array_like or None
        Lateral convection coefficient on each segment [W/(m²·K)], > 0. ``None``:
        the rod's nominal h throughout.

    Examples
    --------
    >>> s = Schedule([3600, 1800], [2000, 0])
    >>> s.edges_s.tolist()
    [0.0, 3600.0, 5400.0]
    >>> Schedule([3600, -1], [2000, 0])
    Traceback (most recent call last):
    ...
    arfem.params.InputError: durations_s[1]: must be > 0, got -1.0
    """

    durations_s: np.ndarray
    q_W_m2: np.ndarray
    ambient_C: np.ndarray | None = None
    h_W_m2K: np.ndarray | None = None

    def __post_init__(self):
        d = np.atleast_1d(np.asarray(self.durations_s, dtype=float))
        if d.ndim != 1 or d.size == 0:
            raise InputError("needs at least one segment", "durations_s")
        n = d.size

        def arr(name, value, positive, allow_zero):
            a = np.atleast_1d(np.asarray(value, dtype=float))
            if a.size == 1 and n > 1:
                a = np.full(n, a.item())
            if a.shape != (n,):
                raise InputError(f"has {a.size} values for {n} segments", name)
            # one vectorised test (a sweep point's subdivided schedule has ~10⁴ segments);
            # the first offending value is then named as before
            bad = ~np.isfinite(a)
            if positive:
                bad |= (a < 0) | ((a == 0) & (not allow_zero))
            if bad.any():
                i = int(np.argmax(bad))
                v = a.tolist()[i]
                if not math.isfinite(v):
                    raise InputError(f"must be finite, got {v!r}", f"{name}[{i}]")
                raise InputError(f"must be {'>= 0' if allow_zero else '> 0'}, got {v!r}",
                                 f"{name}[{i}]")
            a.setflags(write=False)
            return a

        object.__setattr__(self, "durations_s", arr("durations_s", d, True, False))
        object.__setattr__(self, "q_W_m2", arr("q_W_m2", self.q_W_m2, True, True))
        if self.ambient_C is not None:
            object.__setattr__(self, "ambient_C", arr("ambient_C", self.ambient_C, False, False))
        if self.h_W_m2K is not None:
            object.__setattr__(self, "h_W_m2K", arr("h_W_m2K", self.h_W_m2K, True, False))

    @property
    def n_segments(self) -> int:
        return int(self.durations_s.size)

    @property
    def edges_s(self) -> np.ndarray:
        """Segment boundaries [s], length ``n_segments + 1``, starting at 0."""
        return np.concatenate([[0.0], np.cumsum(self.durations_s)])

    @property
    def total_s(self) -> float:
        return float(self.durations_s.sum())

    def ambient_for(self, rod: Rod) -> np.ndarray:
        """Ambient per segment [°C], the rod's nominal value where not given.

        Parameters
        ----------
        rod : Rod
            Supplies the nominal ambient ``ambient_C`` [°C].

        Returns
        -------
        ndarray, shape (n_segments,)
            Ambient air temperature on each segment [°C].
        """
        if self.ambient_C is None:
            return np.full(self.n_segments, rod.ambient_C)
        return np.asarray(self.ambient_C)

    def h_for(self, rod: Rod) -> np.ndarray:
        """Convection coefficient per segment [W/(m²·K)], the rod's nominal where not given.

        Parameters
        ----------
        rod : Rod
            Supplies the nominal h ``convection_W_m2K`` [W/(m²·K)].

        Returns
        -------
        ndarray, shape (n_segments,)
            Lateral convection coefficient on each segment [W/(m²·K)].
        """
        if self.h_W_m2K is None:
            return np.full(self.n_segments, rod.convection_W_m2K)
        return np.asarray(self.h_W_m2K)

    def subdivided(self, dt_s: float) -> "Schedule":
        """Split every segment into pieces of exactly ``dt_s``.

        Raises :class:`InputError` if ``dt_s`` does not divide a segment.

        Parameters
        ----------
        dt_s : float
            Piece length [s], > 0; must divide every segment duration.

        Returns
        -------
        Schedule
            Same inputs (flux [W/m²], ambient [°C], h [W/(m²·K)]) on segments of
            ``dt_s`` [s] each.
        """
        dt = check_positive("dt_s", dt_s)
        counts = steps_per_segment(self.durations_s, dt)
        rep = np.repeat(np.arange(self.n_segments), counts)
        pick = lambda a: None if a is None else np.asarray(a)[rep]
        return Schedule(np.full(rep.size, dt), pick(self.q_W_m2), pick(self.ambient_C),
                        pick(self.h_W_m2K))


def _gcd_all(durations: Iterable[float]) -> float:
    ints = [int(round(d)) for d in durations]
    if all(abs(a - b) < 1e-9 for a, b in zip(ints, durations)):
        g = 0
        for i in ints:
            g = math.gcd(g, i)
        return float(g)
    return float(min(durations))


def _divisor_examples(g: float) -> str:
    cands = [d for d in (1, 2, 5, 10, 15, 20, 30, 60, 90, 120, 180, 300, 600, 900, 1800, 3600)
             if g > 0 and abs(g / d - round(g / d)) < 1e-9]
    return ", ".join(f"{d:g}" for d in cands[-6:]) if cands else f"{g:g}"


def steps_per_segment(durations_s, step_s, where: str = "dt_s", what: str = "segment") -> list[int]:
    """How many steps of ``step_s`` fit each duration; every one must divide exactly.

    Parameters
    ----------
    durations_s : array_like
        Segment (phase) durations [s].
    step_s : float
        Time step [s], > 0.
    where : str
        Location named in the error (e.g. ``"ar.dtau_s"``).
    what : str
        What a duration is called in the error (``"segment"``, ``"phase"``).

    Examples
    --------
    >>> steps_per_segment([14400, 5400], 1800)
    [8, 3]
    >>> steps_per_segment([14400, 5400], 7, where="ar.dtau_s", what="phase")
    Traceback (most recent call last):
    ...
    arfem.params.InputError: ar.dtau_s: 7 s does not divide phase 0 (14400 s); choose a step that divides every phase, e.g. 120, 180, 300, 600, 900, 1800 s
    """
    step = check_positive(where, step_s)
    durations = [float(d) for d in np.atleast_1d(durations_s)]
    counts = []
    for i, d in enumerate(durations):
        k = d / step
        if abs(k - round(k)) > 1e-9 * max(1.0, k) or round(k) < 1:
            raise InputError(f"{step:g} s does not divide {what} {i} ({d:g} s); choose a step "
                             f"that divides every {what}, e.g. "
                             f"{_divisor_examples(_gcd_all(durations))} s", where)
        counts.append(int(round(k)))
    return counts


#: The paper's duty cycle: 4 h on, 1.5 h off, 4 h on, 14.5 h off [s] (Du et al. 2021, Sec. 2).
PAPER_PHASES_S: tuple[tuple[float, bool], ...] = (
    (4.0 * 3600, True), (1.5 * 3600, False), (4.0 * 3600, True), (14.5 * 3600, False))


def paper_cycle(q_W_m2: float) -> Schedule:
    """The seed paper's 24 h duty cycle at heat flux ``q_W_m2`` [W/m²].

    4 h on, 1.5 h off, 4 h on, 14.5 h off (:data:`PAPER_PHASES_S`).

    Parameters
    ----------
    q_W_m2 : float
        Heat flux into the heated end during the on-phases [W/m²], >= 0.

    Returns
    -------
    Schedule
        Four segments [s] with flux ``q_W_m2`` or 0 [W/m²]; nominal ambient and h.

    References
    ----------
    Du et al., J. Harbin Inst. Technol. 53(7), 2021, Sec. 2.

    Examples
    --------
    >>> s = paper_cycle(2000.0)
    >>> s.total_s / 3600, s.q_W_m2.tolist()
    (24.0, [2000.0, 0.0, 2000.0, 0.0])
    """
    return Schedule([d for d, _ in PAPER_PHASES_S], [q_W_m2 if on else 0.0 for _, on in PAPER_PHASES_S])
