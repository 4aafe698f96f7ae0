"""Heat from the spindle speed: a bearing's friction power, and a power law.

A machine logs its spindle speed, not its bearings' watts. A heat source may therefore
give its power as a function of the speed n [rpm], in one of two ways:

* a power law, P = a + b·n^m [W] (:class:`PowerLaw`), the form convection's h already
  takes (``h_W_m2K = {a, b, m}``);
* Palmgren's friction moment of a rolling bearing (:class:`PalmgrenBearing`), as given
  by Harris & Kotzalas, *Rolling Bearing Analysis* (5th ed., 2007, vol. 1 ch. on
  friction; after Palmgren, *Ball and Roller Bearing Engineering*, 1959):

      M  = M0 + M1                                                   [N·mm]
      M0 = 1e-7 · f0 · (ν·n)^(2/3) · dm³       where ν·n ≥ 2000      (load-independent)
      M0 = 160e-7 · f0 · dm³                    where ν·n < 2000
      M1 = f1 · P1 · dm                                              (load-dependent)
      P  = M · ω = M [N·mm] · 1e-3 · 2π n / 60                       [W]

  with, in the units of the formula (its 1e-7 belongs to them):

  ========  =========================================================  ==========
  f0        lubrication factor: bearing type and lubrication method     [-]
  ν         kinematic viscosity of the lubricant (a grease's base oil)   mm²/s (cSt)
            at the operating temperature
  n         speed                                                        rpm
  dm        pitch diameter, (bore + outside diameter)/2                  mm
  f1        load factor; for ball bearings f1 = z·(P0/C0)^y, for         [-]
            angular-contact ball bearings z = 0.001, y = 0.33
            (P0 the static equivalent load, C0 the static rating)
  P1        the load that sets the load-dependent moment (for an         N
            angular-contact ball bearing 0.9·Fa·cot α − 0.1·Fr, not
            below Fr; for a preloaded spindle pair about the preload)
  ========  =========================================================  ==========

  f0 and f1 come from the bearing maker or from Palmgren's tables as reproduced by
  Harris & Kotzalas (f0 of the order of 1 to 4 for angular-contact ball bearings,
  larger for more rows and for oil bath than oil-air); the values in arfem's example
  scenarios are plausible assumptions, not a calibration. The formula is an
  empirical fit; the maker's own friction model (SKF's four-term model, for one) is
  better where given.

Only part of the friction power enters the structure (the rest leaves with the
lubricant and the cooling); a source's ``scale`` says which part.

Pure functions and frozen dataclasses, no I/O (layer ``models``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from arfem.params import InputError

__all__ = ["viscous_moment_Nmm", "load_moment_Nmm", "friction_power_W", "PowerLaw",
           "PalmgrenBearing", "RANGES", "check_range", "VISCOUS_BRANCH_NU_N"]

#: ν·n [mm²/s · rpm] below which Palmgren's load-independent moment no longer falls with
#: the speed (the film is then taken as fully formed at its low-speed value).
VISCOUS_BRANCH_NU_N = 2000.0

#: Ranges a scenario's speed-power data must lie in (closed), in the units of the names;
#: beyond them the value is almost certainly in other units (a pitch diameter in metres,
#: a viscosity in m²/s) or not a spindle bearing's.
RANGES = {
    "f0": (0.1, 20.0),
    "nu_mm2_s": (0.5, 5000.0),
    "dm_mm": (2.0, 2000.0),
    "f1": (0.0, 0.05),
    "P1_N": (0.0, 1e6),
    "count": (1, 16),
    "a": (0.0, 1e5),
    "b": (0.0, 1e5),
    "m": (0.05, 4.0),
}
_HINTS = {"dm_mm": " (in mm: a 7014's pitch diameter is 90 mm, not 0.09)",
          "nu_mm2_s": " (in mm²/s = cSt: ISO VG 22 oil is 22 mm²/s at 40 °C)"}


def check_range(name: str, value: float, where: str) -> float:
    """``value`` if it lies in :data:`RANGES` ``[name]``, else one line naming ``where``.

    >>> check_range("dm_mm", 90.0, "bearing.dm_mm")
    90.0
    """
    lo, hi = RANGES[name]
    if not lo <= value <= hi:
        raise InputError(f"{value:g} is outside [{lo:g}, {hi:g}]{_HINTS.get(name, '')}",
                         where)
    return value


def viscous_moment_Nmm(f0: float, nu_mm2_s: float, speed_rpm, dm_mm: float) -> np.ndarray:
    """Palmgren's load-independent friction moment M0 [N·mm] (module docstring).

    Parameters
    ----------
    f0 : float
        Lubrication factor [-].
    nu_mm2_s : float
        Kinematic viscosity [mm²/s].
    speed_rpm : array_like
        Speed n [rpm], >= 0.
    dm_mm : float
        Pitch diameter [mm].

    Returns
    -------
    ndarray
        M0 [N·mm]: 1e-7·f0·(νn)^(2/3)·dm³, or 160e-7·f0·dm³ where νn < 2000.

    Examples
    --------
    A 7014 (dm = 90 mm) in ISO VG 22 oil (22 mm²/s), f0 = 2, at 8000 rpm:

    >>> round(float(viscous_moment_Nmm(2.0, 22.0, 8000.0, 90.0)), 1)
    457.9
    >>> float(viscous_moment_Nmm(2.0, 22.0, 50.0, 90.0)) == 160e-7 * 2.0 * 90.0 ** 3
    True
    """
    n = np.asarray(speed_rpm, float)
    nu_n = nu_mm2_s * n
    high = 1e-7 * f0 * np.power(np.maximum(nu_n, 0.0), 2.0 / 3.0) * dm_mm ** 3
    return np.where(nu_n >= VISCOUS_BRANCH_NU_N, high, 160e-7 * f0 * dm_mm ** 3)


def load_moment_Nmm(f1: float, P1_N: float, dm_mm: float) -> float:
    """Palmgren's load-dependent friction moment M1 = f1·P1·dm [N·mm].

    >>> round(load_moment_Nmm(3.2e-4, 1000.0, 90.0), 2)
    28.8
    """
    return float(f1 * P1_N * dm_mm)


def friction_power_W(moment_Nmm, speed_rpm) -> np.ndarray:
    """Heat of a friction moment turning at n: P = M·ω [W], M [N·mm] × 1e-3 × 2πn/60.

    >>> round(float(friction_power_W(1000.0, 60.0 / (2 * math.pi))), 12)
    1.0
    """
    return np.asarray(moment_Nmm, float) * 1e-3 * 2.0 * math.pi * np.asarray(speed_rpm,
                                                                              float) / 60.0


@dataclass(frozen=True)
class PowerLaw:
    """P = a + b·n^m [W], n the speed [rpm] (at n = 0: a).

    Attributes
    ----------
    a : float, power at standstill [W]
    b : float, [W/rpm^m]
    m : float, exponent [-]

    Examples
    --------
    >>> PowerLaw(0.0, 0.003, 1.0).power_W([0.0, 4000.0, 12000.0]).tolist()
    [0.0, 12.0, 36.0]
    """

    a: float
    b: float
    m: float

    def power_W(self, speed_rpm) -> np.ndarray:
        n = np.maximum(np.asarray(speed_rpm, float), 0.0)
        return self.a + self.b * np.power(n, self.m)

    def describe(self) -> str:
        return f"P = {self.a:g} + {self.b:g}·n^{self.m:g} W"


@dataclass(frozen=True)
class PalmgrenBearing:
    """A bearing (or a set of ``count`` equal ones) whose friction heats the structure:
    P(n) = count · (M0(n) + M1)·ω (module docstring for the units and the source).

    Examples
    --------
    A preloaded pair of 7014 (dm = 90 mm), grease with a 22 mm²/s base oil, f0 = 2,
    f1 = 3.2e-4 under a 1 kN preload, at 8000 rpm: 2 × (457.9 + 28.8) N·mm × 837.8 rad/s = 815.5 W

    >>> b = PalmgrenBearing(f0=2.0, nu_mm2_s=22.0, dm_mm=90.0, f1=3.2e-4, P1_N=1000.0,
    ...                     count=2)
    >>> round(float(b.power_W(8000.0)), 1)
    815.5
    >>> float(b.power_W(0.0))
    0.0
    """

    f0: float
    nu_mm2_s: float
    dm_mm: float
    f1: float = 0.0
    P1_N: float = 0.0
    count: int = 1

    def moment_Nmm(self, speed_rpm) -> np.ndarray:
        """Friction moment of the set [N·mm]."""
        return self.count * (viscous_moment_Nmm(self.f0, self.nu_mm2_s, speed_rpm,
                                                self.dm_mm)
                             + load_moment_Nmm(self.f1, self.P1_N, self.dm_mm))

    def power_W(self, speed_rpm) -> np.ndarray:
        """Friction power of the set [W] at each speed [rpm]."""
        n = np.maximum(np.asarray(speed_rpm, float), 0.0)
        return friction_power_W(self.moment_Nmm(n), n)

    def describe(self) -> str:
        return (f"Palmgren: {self.count} × (1e-7·{self.f0:g}·({self.nu_mm2_s:g}·n)^(2/3)"
                f"·{self.dm_mm:g}³ + {self.f1:g}·{self.P1_N:g}·{self.dm_mm:g}) N·mm × ω")
