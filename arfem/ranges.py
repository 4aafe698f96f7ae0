"""The physical ranges of everything a user types or a machine records: one table.

Every reader checks its numbers against :data:`RANGES` and nothing else: the rod's and
the mesh's scenario readers (``scenarios/rod/scenario.py``, ``scenarios/geometry/scenario.py``)
for the quantities they share (λ, ρ, c, α, E, h, an ambient, a heat input, a speed), the
record reader of every contract version (``scenarios/records/dataset.py``) for each column,
and the live compensator for each reading (:func:`arfem.models.compensator.plausible_ranges`
narrows these by its model, never widens them). A value outside its range is in the
wrong unit or is no reading at all; the message names the unit expected.

A record's column or a live input is matched to its quantity by its name
(:func:`reading_quantity`): ``q_*`` a heat flux, ``P_*_W`` (or a unit in W) a power,
``*_rpm`` a speed, ``ambient*_C`` the ambient air, any other ``*_C`` a temperature
reading, ``growth_um`` and ``d_*_um`` a thermal displacement, ``tilt_*_urad`` a tilt.

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

from arfem.params import PLAUSIBLE_RANGES, InputError, check_plausible

__all__ = ["RANGES", "check_range", "reading_quantity", "reading_range", "first_outside"]

#: The one table of plausible ranges [lo, hi] with the unit expected: it lives in
#: :mod:`arfem.params` (the ground's validated inputs, which import nothing of arfem)
#: as ``PLAUSIBLE_RANGES``; this is the same object.
RANGES = PLAUSIBLE_RANGES

#: ``check_range(key, value, where)``: ``value`` if it lies in ``RANGES[key]``, else one
#: :class:`InputError` line naming the unit expected (:func:`arfem.params.check_plausible`).
check_range = check_plausible


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
    if name.startswith("tilt_") and name.endswith("_urad"):
        return "tilt_urad"
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
