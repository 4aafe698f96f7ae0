"""Thermal growth of a machine-tool spindle: simulate it, check it, diagnose it, compensate it.

arfem checks a finite-element (FEM) thermo-elastic simulation of a machine-tool spindle
against the closed-form first-order autoregressive (AR(1)) thermal-growth model of
Du et al. (2021), diagnoses measured records (what the simulation gets wrong, why, and
how much an extended model gains), and compensates the thermal error on a machine.

Start here::

    import arfem
    rod = arfem.Rod(radius_m=0.05, length_m=0.5)          # SI units, unit in each name
    cycle = arfem.paper_cycle(2000.0)                      # the paper's 24 h duty cycle
    fem = arfem.solve_fem(rod, cycle, dtau_s=30.0)         # the FEM's axial growth [µm]
    ar = arfem.ar1(rod, cycle, dtau_s=30.0)                # the paper's AR(1)
    record = arfem.read_record("my_record.toml")           # a measured record
    diagnosis = arfem.diagnose(record)                     # what the simulation gets wrong
    unit = arfem.load_scenario("spindle_unit")             # a spindle unit on a Gmsh mesh
    drift = arfem.solve(unit)                              # its TCP drift [µm] per sensor

What else there is: run (every file arfem run writes), compare, check and sweep (the FEM
against the AR(1) on a scenario file, the rod's or a mesh's), read_model and Compensator
(run a compensator), and the result classes; dir(arfem)
lists them, and help(arfem.diagnose) and the others give each one's units and an
example. The same work from the shell: arfem --help. The documentation (command pages,
file formats, the physics) is in the repository's docs/ folder.

import arfem is fast: the FEM, the diagnosis engine and matplotlib load when a function
first needs them.

Subpackages: arfem.fem (meshes, heat, thermo-elasticity, reduced models), arfem.models
(plants, AR(1) and its extensions, the diagnosis, the compensator: pure functions) and
arfem.scenarios (files, the commands, the writers).
"""
from importlib import metadata as _metadata
from pathlib import Path as _Path

# In a source checkout, python started from the repository's root finds this folder
# (arfem/) before the installed package, and the subpackages arfem.fem, arfem.models and
# arfem.scenarios sit beside it (fem/, models/, scenarios/; pyproject's package-dir), not
# inside it: so that the README's example runs from the root after `pip install .` too,
# those three folders (and only they: not the root, whose conftest.py and arfem/ would
# then be listed by help(arfem) as modules of the package) are found there.
_ROOT = _Path(__file__).resolve().parent.parent
if (_ROOT / "models" / "compensator.py").is_file():
    import sys as _sys
    from importlib.machinery import PathFinder as _PathFinder

    class _CheckoutSubpackages:
        """Finds arfem.fem, arfem.models and arfem.scenarios in the checkout's root."""

        names = {f"arfem.{n}" for n in ("fem", "models", "scenarios")}

        @classmethod
        def find_spec(cls, fullname, path=None, target=None):
            if fullname not in cls.names:
                return None
            return _PathFinder.find_spec(fullname, [str(_ROOT)], target)

    if not any(getattr(f, "names", None) == _CheckoutSubpackages.names
               for f in _sys.meta_path):
        _sys.meta_path.append(_CheckoutSubpackages)
    del _sys
del _Path

try:
    __version__ = _metadata.version("arfem")
except _metadata.PackageNotFoundError:  # pragma: no cover - running from an uninstalled tree
    __version__ = "0+unknown"

#: The promised API (:mod:`arfem.api`), loaded on first use so that ``import arfem`` stays
#: fast (the FEM, the diagnosis engine and matplotlib load only when a function runs).
_API = ("Rod", "Schedule", "paper_cycle", "load_scenario", "shipped_scenario", "solve", "run",
        "solve_fem", "FemResult", "ar1", "AR1Result", "compare", "Comparison", "check",
        "CheckResult", "sweep", "SweepResult", "diagnose", "DiagnosisResult", "diagnose_mesh",
        "NamedCause", "Holdout", "read_record", "Record", "Compensator", "StateSpaceModel",
        "ar1_model", "read_model", "InputError")

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    """``arfem.<name>`` for the names of :mod:`arfem.api` (PEP 562 lazy attribute)."""
    if name in _API:
        from arfem import api          # the one upward import: the package front door
        return getattr(api, name)
    raise AttributeError(f"module 'arfem' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The promised names only (``dir(arfem)``), not the module's internals."""
    return sorted(__all__)
