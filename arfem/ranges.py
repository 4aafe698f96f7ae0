"""The physical ranges of everything a user types or a machine records: one table.

Every reader checks its numbers against :data:`RANGES` and nothing else: the rod's and
the mesh's scenario readers (``scenarios/config.py``, ``scenarios/geometry_scenario.py``)
for the quantities they share (λ, ρ, c, α, E, h, an ambient, a heat input, a speed), the
record reader of every contract version (``scenarios/dataset.py``) for each column,
and the live compensator for each reading (:func:`arfem.models.compensator.plausible_ranges`
narrows these by its model, never widens them). A value outside its range is in the
wrong unit or is no reading at all; the message names the unit expected.

A record's column or a live input is matched to its quantity by its name
(:func:`reading_quantity`): ``q_*`` a heat flux, ``P_*_W`` (or a unit in W) a power,
``*_rpm`` a speed, ``ambient*_C`` the ambient air, any other ``*_C`` a temperature
reading, ``growth_um`` and ``d_*_um`` a thermal displacement.

Examples
--------
>>> check_range("specific_heat_J_kgK", 460.0, "m.toml: material[0].specific_heat_J_kgK")
460.0
>>> try:
...     check_range("specific_heat_J_kgK", 1e308, "m.toml: material[0].specific_heat_J_kgK")
... except InputError as e:
...     print(e)
m.toml: material[0].specific_heat_J_kgK: 1e+308 is outside the plausible range [10, 20000] for a value in J/(kg·K) (a value in kJ/(kg·K)?)
>>> reading_quantity("T_front_bearing_C"), reading_quantity("P_motor_W"), reading_quantity("d_tcp_z_um")
('temperature_C', 'power_W', 'growth_um')
"""
from __future__ import annotations

import math

from arfem.params import InputError

__all__ = ["RANGES", "check_range", "reading_quantity", "reading_range", "first_outside"]

#: Plausible ranges [lo, hi] of the quantities a user types or records, with the unit
#: they must be in: a value outside is almost certainly in the wrong unit, or no reading.
#: The readings' ranges (ambient, temperature, speed, heat, growth) are the live
#: compensator's: a record is judged as the machine's readings are judged live.
RANGES = {
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
    "coordinate_m": (-100.0, 100.0, "metres of the declared unit (the unit wrong?)"),
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
}


def check_range(key: str, value: float, where: str) -> float:
    """``value`` if it is finite and lies in ``RANGES[key]`` (or ``key`` has no range),
    else one :class:`InputError` line at ``where`` naming the unit expected.

    Examples
    --------
    >>> check_range("ambient_C", 21.5, "case.toml: rod.ambient_C")
    21.5
    >>> try:
    ...     check_range("ambient_C", 293.15, "case.toml: rod.ambient_C")
    ... except InputError as e:
    ...     print(e)
    case.toml: rod.ambient_C: 293.15 is outside the plausible range [-10, 50] for a value in °C (a temperature in K?)
    """
    if key in RANGES:
        lo, hi, unit = RANGES[key]
        if not lo <= value <= hi:             # NaN fails too
            shown = f"{value:g}" if math.isfinite(value) else repr(value)
            if lo == 0.0 and value < 0:
                raise InputError(f"{shown} is negative; a value in {unit} is >= 0 (the "
                                 f"plausible range is [0, {hi:g}])", where)
            raise InputError(f"{shown} is outside the plausible range [{lo:g}, {hi:g}] "
                             f"for a value in {unit}", where)
    return value


def reading_quantity(name: str, unit: str = "") -> str | None:
    """The :data:`RANGES` key of a record's column or a live input, by its name (and
    unit, where given): None for a column with no physical range (``time_s``, a column
    the contract does not know)."""
    if name.startswith("q_") or unit in ("W/m²", "W/m2"):
        return "q_W_m2"
    if name.endswith("_rpm"):
        return "speed_rpm"
    if (name.startswith("P_") and name.endswith("_W")) or unit == "W":
        return "power_W"
    if name.endswith("_C") or unit in ("°C", "degC", "C"):
        return "ambient_C" if "ambient" in name else "temperature_C"
    if name == "growth_um" or (name.startswith("d_") and name.endswith("_um")):
        return "growth_um"
    return None


def reading_range(name: str, unit: str = "") -> tuple[float, float]:
    """(lo, hi) a reading named ``name`` must lie in; (-inf, inf) where it has no range.

    >>> reading_range("ambient_C"), reading_range("speed_rpm")
    ((-10.0, 50.0), (0.0, 100000.0))
    """
    key = reading_quantity(name, unit)
    if key is None:
        return (-math.inf, math.inf)
    lo, hi, _ = RANGES[key]
    return (lo, hi)


def first_outside(name: str, values) -> int | None:
    """Index of the first finite value of column ``name`` outside its reading range (an
    empty cell, NaN, is not judged here), or None.

    >>> first_outside("ambient_C", [20.0, float("nan"), -1e300, 21.0])
    2
    """
    import numpy as np
    lo, hi = reading_range(name)
    v = np.asarray(values, dtype=float)
    bad = np.flatnonzero(~np.isnan(v) & ~((v >= lo) & (v <= hi)))
    return int(bad[0]) if bad.size else None
