"""What a sweep is made of, whatever the plant: its points, their keys in the store, and
the normalisation of grid values. The rod's sweep file (:mod:`arfem.scenarios.sweep.spec`)
and the mesh's (:mod:`arfem.scenarios.sweep.geometry`) both build on it; it needs
neither."""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field

import numpy as np

from arfem.params import InputError, check_finite

__all__ = ["Point", "Sweep", "canonical", "point_key", "distinct_values", "STORE_VERSION",
           "MAX_POINTS", "flatten_keys", "normalise", "sha256_key"]

#: Bumped when the stored record or the meaning of a metric changes; part of every key.
STORE_VERSION = 2   # 2: per-level metrics named *_by_q_W_m2

#: Largest grid accepted without ``--max-points`` (the shipped sweep has 156 points; each
#: point is resolved and validated up front, about 2 ms each, i.e. 40 s for 20000 points on a
#: loaded 2-core machine, then computed, 0.02-2 s each).
MAX_POINTS = 20000


# -- the sweep definition ---------------------------------------------------------------

@dataclass(frozen=True)
class Point:
    """One grid point: its inputs (column → value), full scenario dict and key."""

    index: int
    inputs: dict
    data: dict = field(repr=False)
    key: str = ""


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: base scenario, grid and every resolved point."""

    name: str
    description: str
    source: str
    base: str
    grid: dict               # column name -> list of values, in file order
    paths: dict              # column name -> dotted scenario path (or alias) it sets
    points: tuple

    @property
    def sweep_id(self) -> str:
        """SHA-256 of the name and the ordered point keys: equal iff the same sweep."""
        return sha256_key({"name": self.name, "points": [p.key for p in self.points]})

    def manifest(self) -> dict:
        return {"store_version": STORE_VERSION, "sweep_id": self.sweep_id, "name": self.name,
                "description": self.description, "source": self.source, "base": self.base,
                "grid": self.grid, "n_points": len(self.points)}


def canonical(obj) -> str:
    """Canonical JSON text of ``obj`` (sorted keys, no spaces, ASCII): the key of a point
    and of a sweep in the store."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False)


def sha256_key(obj) -> str:
    """SHA-256 of ``obj``'s :func:`canonical` JSON: the store's key of anything keyed
    (a point, a sweep, a geometry point).

    Parameters
    ----------
    obj : JSON-like
        Already :func:`normalise`-d where numbers must compare by value.

    Returns
    -------
    str
        64 hex digits.

    >>> sha256_key({"b": 1, "a": 2}) == sha256_key({"a": 2, "b": 1})
    True
    """
    return hashlib.sha256(canonical(obj).encode("ascii")).hexdigest()


def point_key(data: dict) -> str:
    """Key of a point: SHA-256 of its fully resolved inputs, canonical JSON.

    Numbers are normalised (``30`` and ``30.0`` give the same key) and the
    store format version is part of the hash.

    Parameters
    ----------
    data : dict
        Resolved inputs (:func:`resolved_inputs`), or any JSON-like dict.

    Returns
    -------
    str
        64 hex digits.

    Examples
    --------
    >>> point_key({"ar": {"dtau_s": 30}}) == point_key({"ar": {"dtau_s": 30.0}})
    True
    >>> point_key({"ar": {"dtau_s": 30}}) == point_key({"ar": {"dtau_s": 60}})
    False
    """
    return sha256_key({"store_version": STORE_VERSION, "scenario": normalise(data)})


def normalise(o):
    """``o`` with every number a float (``30`` and ``30.0`` alike; non-finite refused),
    keys strings, tuples lists, dates ISO text and anything else its ``str``: the form
    a key is hashed in.

    Parameters
    ----------
    o : JSON-like or TOML value
        Any nesting of dicts, lists, tuples, numbers, strings, booleans and dates.

    Returns
    -------
    JSON-like
        The normalised copy (units unchanged).

    Raises
    ------
    InputError
        A number is not finite.

    >>> normalise({"ar": {"dtau_s": 30}, "q": (1, 2.5)})
    {'ar': {'dtau_s': 30.0}, 'q': [1.0, 2.5]}
    """
    if isinstance(o, dict):
        return {str(k): normalise(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [normalise(v) for v in o]
    if isinstance(o, bool) or o is None or isinstance(o, str):
        return o
    if isinstance(o, (int, float, np.integer, np.floating)):
        return check_finite(None, o)
    if hasattr(o, "isoformat"):          # TOML dates and times
        return o.isoformat()
    return str(o)



def distinct_values(values: list, where: str) -> list:
    """The grid values of one key, normalised (:func:`normalise`); one line naming
    ``where`` for a value that is not a number or string, or one given twice."""
    try:
        norm = [normalise(v) for v in values]
    except InputError as e:
        raise e.at(where) from None
    dup = [v for i, v in enumerate(norm) if v in norm[:i]]
    if dup:
        raise InputError(f"lists the value {dup[0]!r} twice", where)
    return norm


def flatten_keys(d: dict, prefix: str = "") -> dict:
    """``{"fem": {"mesh": {"nz": [..]}}}`` → ``{"fem.mesh.nz": [..]}`` (unquoted dotted
    TOML keys): a sweep's ``[grid]`` table as one value list per dotted key.

    Parameters
    ----------
    d : dict
        Nested tables.
    prefix : str
        Prepended to every key (used by the recursion).

    Returns
    -------
    dict
        {dotted key: leaf value}.

    >>> flatten_keys({"fem": {"mesh": {"nz": [40, 80]}}, "ar": {"dtau_s": [30]}})
    {'fem.mesh.nz': [40, 80], 'ar.dtau_s': [30]}
    """
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten_keys(v, key + "."))
        else:
            out[key] = v
    return out

