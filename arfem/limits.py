"""The user's permissions to go past arfem's limits, as one explicit value.

``--allow-large`` lifts the size limits (mesh, time steps, samples, memory estimate,
text and CSV size, CSV rows); ``--allow-csv-outside`` lets a dataset TOML name a CSV
outside its folder. The CLI builds a :class:`Limits` from its flags and passes it to the
readers and to the sweep's workers (local processes or Dask) as an argument; nothing is
passed through ``os.environ``. A caller of the library that passes no ``Limits`` gets
:meth:`Limits.from_environment`: the strict limits, unless the user set
``ARFEM_ALLOW_LARGE=1`` or ``ARFEM_ALLOW_CSV_OUTSIDE=1`` in the environment (docs/safety.md).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

__all__ = ["Limits", "STRICT", "resolve"]


def _on(value: str | None) -> bool:
    return value not in (None, "", "0")


@dataclass(frozen=True)
class Limits:
    """What the user allows past arfem's default limits.

    Parameters
    ----------
    large : bool
        Lift the size limits (``--allow-large``).
    csv_outside : bool
        Read a dataset CSV outside its TOML's folder (``--allow-csv-outside``); its cells
        are then never shown in error messages.

    Examples
    --------
    >>> Limits.from_environment({"ARFEM_ALLOW_LARGE": "1"})
    Limits(large=True, csv_outside=False)
    >>> Limits(large=True) | Limits(csv_outside=True)
    Limits(large=True, csv_outside=True)
    """

    large: bool = False
    csv_outside: bool = False

    @classmethod
    def from_environment(cls, environ=None) -> "Limits":
        """The limits the user set in the environment (read, never written)."""
        env = os.environ if environ is None else environ
        return cls(large=_on(env.get("ARFEM_ALLOW_LARGE")),
                   csv_outside=_on(env.get("ARFEM_ALLOW_CSV_OUTSIDE")))

    def __or__(self, other: "Limits") -> "Limits":
        """Each permission granted by either."""
        return Limits(self.large or other.large, self.csv_outside or other.csv_outside)


#: arfem's default: every limit in force
STRICT = Limits()


def resolve(limits: Limits | None) -> Limits:
    """``limits``, or the environment's when None (a library call that passes none)."""
    return Limits.from_environment() if limits is None else limits
