"""Reading an allocation scenario file (``arfem allocate``'s input), for the command, the
benchmarks and the tests alike."""
from __future__ import annotations

from pathlib import Path

from arfem.io import read_toml
from arfem.limits import Limits
from arfem.models.allocation.scenario import AllocationScenario, parse_scenario

__all__ = ["load_allocation_scenario"]


def load_allocation_scenario(path, limits: Limits | None = None) -> AllocationScenario:
    """Read and validate an allocation scenario file; :class:`InputError` names the file
    and key; ``limits`` (:class:`arfem.limits.Limits`) as the user allows."""
    p = Path(path)
    return parse_scenario(read_toml(p, limits), str(p))
