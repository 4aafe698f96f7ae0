"""The scenarios shipped with arfem (``scenarios/data/``, installed as package data) and
the one rule by which a bare name (``paper_fig2``, ``spindle_unit``, a shipped sweep)
is taken for one of them: the CLI, the check, the sweeps and the Python API
(:func:`arfem.shipped_scenario`) all call it, for the rod and a mesh alike."""
from __future__ import annotations

from importlib import resources
from pathlib import Path

from arfem.params import InputError

__all__ = ["shipped_dir", "builtin_scenario_path", "shipped_names", "scenario_file"]


def shipped_dir():
    """The folder of the scenarios shipped with arfem (``scenarios/data/``, installed as
    package data), as an importlib resource."""
    return resources.files("arfem.scenarios").joinpath("data")


def builtin_scenario_path(name: str) -> Path:
    """Path of a scenario file shipped with arfem (``paper_fig2``, ``spindle_unit`` …;
    ``.toml`` may be given or left out): the one rule by which the CLI, the sweeps, the
    check and the Python API (:func:`arfem.shipped_scenario`) map a name to a file."""
    stem = name[:-5] if name.endswith(".toml") else name
    p = shipped_dir().joinpath(f"{stem}.toml")
    if not p.is_file():
        raise InputError(f"no such shipped scenario (there are: {shipped_names()})", name)
    return Path(str(p))


def shipped_names() -> str:
    """The names of the scenarios shipped with arfem, for a message."""
    here = shipped_dir()
    return ", ".join(sorted(q.name[:-5] for q in here.iterdir() if q.name.endswith(".toml")))


def scenario_file(path) -> Path:
    """The file of scenario ``path``: itself, or, for a bare name that is no file here
    (no folder, no suffix), the shipped scenario of that name
    (:func:`builtin_scenario_path`)."""
    p = Path(path)
    if not p.exists() and not p.suffix and len(p.parts) == 1:
        if not shipped_dir().joinpath(f"{p.name}.toml").is_file():
            raise InputError(f"is no file here, nor a shipped scenario (there are: "
                             f"{shipped_names()})", str(path))
        p = builtin_scenario_path(p.name)
    return p
