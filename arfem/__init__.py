"""arfem: checks a finite-element thermo-elastic simulation of a machine-tool spindle
against the first-order autoregressive (AR(1)) thermal-growth model of Du et al. (2021),
and diagnoses measured records.

Layers, imported in one direction only (``tests/test_layering.py`` enforces it):

* ground -- :mod:`arfem.params` (physical inputs ``Rod``/``Schedule``, ``InputError``
  and the checks) and :mod:`arfem.io` (reading user files, atomic writes);
* :mod:`arfem.fem` -- meshes, transient heat, thermo-elasticity, field export;
* :mod:`arfem.models` -- pure models: arrays and dataclasses in, results out, no files;
* :mod:`arfem.scenarios` -- user files, the ``arfem`` command, runners and writers;
* :mod:`arfem.api` -- the promised Python API, above everything, re-exported here lazily.

The source folders ``fem/``, ``models/`` and ``scenarios/`` sit at the top of the
repository and are installed under this package (setuptools ``package-dir``).
"""
from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("arfem")
except PackageNotFoundError:  # pragma: no cover - running from an uninstalled tree
    __version__ = "0+unknown"

#: The promised API (:mod:`arfem.api`), loaded on first use so that ``import arfem`` stays
#: fast (the FEM, the diagnosis engine and matplotlib load only when a function runs).
_API = ("Rod", "Schedule", "paper_cycle", "load_scenario", "solve_fem", "FemResult", "ar1",
        "AR1Result", "compare", "Comparison", "check", "CheckResult", "sweep", "diagnose",
        "DiagnosisResult", "Compensator", "StateSpaceModel", "ar1_model", "read_model",
        "InputError")

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    """``arfem.<name>`` for the names of :mod:`arfem.api` (PEP 562 lazy attribute)."""
    if name in _API:
        from arfem import api          # the one upward import: the package front door
        return getattr(api, name)
    raise AttributeError(f"module 'arfem' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_API))
