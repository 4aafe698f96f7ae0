"""Write a generated case (:func:`arfem.models.diagnosis.synth.generate`) as a measured
dataset, ``<name>.csv`` + ``<name>.toml``, exactly per the measured-data contract
(``docs/measured-data.md``) and with no hint of the injected cause."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from arfem.io import atomic_write_text
from arfem.models.diagnosis.synth import SynthCase

__all__ = ["write_case"]


# -- writing --------------------------------------------------------------------------

def _fmt(values, decimals: int) -> list[str]:
    return ["" if not np.isfinite(v) else f"{v:.{decimals}f}" for v in np.asarray(values, float)]


def write_case(case: SynthCase, directory) -> Path:
    """Write ``<name>.csv`` and ``<name>.toml`` per the measured-data contract.

    Parameters
    ----------
    case : SynthCase
    directory : str or path-like
        Created if absent; files are written atomically.

    Returns
    -------
    Path
        The TOML file.
    """
    directory = Path(directory)
    factor = float(case.settings.get("growth_unit_factor", 1.0))
    digits = 3 + max(0, int(np.ceil(-np.log10(factor)))) if factor > 0 else 3
    cols = {"time_s": _fmt(case.time_s, 0), "growth_um": _fmt(case.growth_um, digits),
            "q_W_m2": _fmt(case.q_W_m2, 1), "ambient_C": _fmt(case.ambient_C, 3)}
    for k, v in case.temperatures.items():
        cols[k] = _fmt(v, 3)
    lines = [",".join(cols)] + [",".join(row) for row in zip(*cols.values())]
    atomic_write_text(directory / f"{case.name}.csv", "\n".join(lines) + "\n")
    r = case.declared_rod or case.rod
    toml = [
        "[dataset]",
        f'name = "{case.name}"',
        f'csv = "{case.name}.csv"',
        *([] if case.initial_known else ['initial = "unknown"']),
        "",
        "[rod]",
        *(f"{k} = {getattr(r, k)!r}" for k in (
            "radius_m", "length_m", "conductivity_W_mK", "density_kg_m3",
            "specific_heat_J_kgK", "expansion_1_K", "convection_W_m2K", "ambient_C")),
    ]
    for key, desc in case.sensors.items():
        toml += ["", f"[sensors.{key}]", f'description = "{desc}"']
    path = directory / f"{case.name}.toml"
    atomic_write_text(path, "\n".join(toml) + "\n")
    return path
