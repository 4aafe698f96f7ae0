"""The one strict reader of user tables (scenario, sweep, dataset and allocation TOML):
unknown keys are refused with a "did you mean" hint, values are checked for type, range
and finiteness, and every refusal is one :class:`~arfem.params.InputError` line naming
the key path.

>>> try:
...     check_keys({"convection_W_m2k": 55}, {"convection_W_m2K", "radius_m"}, "rod")
... except InputError as e:
...     print(e)
rod.convection_W_m2k: unknown key (did you mean 'convection_W_m2K'?)
"""
from __future__ import annotations

import difflib
from typing import Iterable

from arfem.params import InputError, check_finite

__all__ = ["check_keys", "join", "table", "number", "string", "boolean"]


def join(a: str, b: str) -> str:
    """Dotted key path ``a.b`` (``b`` alone at the top)."""
    return f"{a}.{b}" if a else b


def check_keys(keys: Iterable[str], allowed: Iterable[str], where: str) -> None:
    """Refuse the first key of ``keys`` not in ``allowed``, suggesting the closest one
    (or listing the allowed keys where none is close)."""
    allowed = sorted(allowed)
    for k in keys:
        if k not in allowed:
            close = difflib.get_close_matches(str(k), allowed, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else \
                f" (allowed: {', '.join(allowed)})"
            raise InputError(f"unknown key{hint}", join(where, str(k)))


def table(d: dict, key: str, where: str) -> dict:
    """``d[key]`` as a table (``{}`` when absent)."""
    v = d.get(key, {})
    if not isinstance(v, dict):
        raise InputError(f"must be a table, got {type(v).__name__}", join(where, key))
    return v


def number(v, where: str, *, positive=False, allow_zero=False, integer=False) -> float:
    """A finite number (a TOML boolean is not one); ``positive`` asks > 0 (or >= 0 with
    ``allow_zero``), ``integer`` a whole number."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"must be a number, got {type(v).__name__} {v!r}", where)
    if integer and not isinstance(v, int):
        raise InputError(f"must be a whole number, got {v!r}", where)
    f = check_finite(where, v)
    if positive and (f < 0 or (f == 0 and not allow_zero)):
        raise InputError(f"must be {'>= 0' if allow_zero else '> 0'}, got {v!r}", where)
    return f


def string(v, where: str, choices=None) -> str:
    """A string, one of ``choices`` if given."""
    if not isinstance(v, str):
        raise InputError(f"must be a string, got {type(v).__name__} {v!r}", where)
    if choices is not None and v not in choices:
        raise InputError(f"must be one of {', '.join(repr(c) for c in choices)}, got {v!r}",
                         where)
    return v


def boolean(v, where: str) -> bool:
    """``true`` or ``false``."""
    if not isinstance(v, bool):
        raise InputError(f"must be true or false, got {v!r}", where)
    return v
