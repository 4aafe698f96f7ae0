"""The one strict reader of user tables (scenario, sweep, dataset and allocation TOML)
and JSON documents (``model.json``): unknown keys are refused with a "did you mean" hint
(a JSON object: the unknown key named), values are checked for type, range and
finiteness, and every refusal is one :class:`~arfem.params.InputError` line naming the
key path.

A JSON document's numbers are JSON numbers (not booleans), finite and of magnitude at
most a bound the format states (:func:`json_number`, :func:`number_array`); its arrays
have the shapes the format asks (:func:`shaped`).

>>> try:
...     check_keys({"convection_W_m2k": 55}, {"convection_W_m2K", "radius_m"}, "rod")
... except InputError as e:
...     print(e)
rod.convection_W_m2k: unknown key (did you mean 'convection_W_m2K'?)
"""
from __future__ import annotations

import difflib
import math
from typing import Iterable

import numpy as np

from arfem.params import InputError, check_finite

__all__ = ["check_keys", "join", "table", "number", "string", "boolean", "short_repr",
           "is_json_number", "json_number", "json_string", "json_object", "number_array",
           "shaped"]


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


# -- JSON documents ---------------------------------------------------------------------

def short_repr(v, n: int = 60) -> str:
    """``repr(v)``, cut to ``n`` characters (``...`` at the end) for a one-line message."""
    r = repr(v)
    return r if len(r) <= n else r[:n - 3] + "..."


def is_json_number(v) -> bool:
    """A JSON number: int or float, not a bool."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def json_number(v, where: str, what: str = "a finite number", *, bound: float = math.inf,
                low: float | None = None, low_open: bool = False) -> float:
    """``v`` as a float if it is a JSON number, finite, in [low, bound] (``low``
    default -bound; ``low_open``: > low); else one :class:`InputError` at ``where``:
    ``must be <what>, got <v>``.

    >>> json_number(True, "m: d0_um", "a finite number of µm")
    Traceback (most recent call last):
    ...
    arfem.params.InputError: m: d0_um: must be a finite number of µm, got True
    """
    low = -bound if low is None else low
    ok = is_json_number(v) and (math.isfinite(v) if isinstance(v, float) else True)
    if ok:
        ok = (v > low if low_open else v >= low) and v <= bound
    if not ok:
        raise InputError(f"must be {what}, got {short_repr(v)}", where)
    return float(v)


def json_string(v, where: str) -> str:
    """``v`` if it is a JSON string."""
    if not isinstance(v, str):
        raise InputError(f"must be a string, got {short_repr(v)}", where)
    return v


def json_object(v, where: str, allowed=None, required=()) -> dict:
    """``v`` if it is a JSON object with string keys, only ``allowed`` ones (if given:
    ``unknown key 'k'`` at ``where``) and every ``required`` one (``missing`` at
    ``where.k``)."""
    if not isinstance(v, dict) or not all(isinstance(k, str) for k in v):
        raise InputError(f"must be a JSON object, got {short_repr(v)}", where)
    if allowed is not None:
        extra = sorted(set(v) - set(allowed))
        if extra:
            raise InputError(f"unknown key {extra[0]!r}", where)
    for k in required:
        if k not in v:
            raise InputError("missing", f"{where}.{k}")
    return v


def number_array(v, where: str, ndim: int, min_len: int = 0, *,
                 bound: float = math.inf) -> np.ndarray:
    """A list (``ndim`` 1) or list of equally long lists (``ndim`` 2) of JSON numbers,
    each finite and of magnitude at most ``bound`` (:func:`json_number`, naming the
    entry ``where[i][j]``), as a float array; ``[]`` as 2-D is shape (0, 0).

    >>> number_array([[1, 2.5]], "m: B", 2).tolist()
    [[1.0, 2.5]]
    >>> number_array([1, None], "m: x0", 1)
    Traceback (most recent call last):
    ...
    arfem.params.InputError: m: x0[1]: must be a finite number, got None
    """
    what = "a list of numbers" if ndim == 1 else "a list of lists of numbers"
    if not isinstance(v, list) or len(v) < min_len:
        raise InputError(f"must be {what}" + (f" (at least {min_len})" if min_len else "")
                         + f", got {short_repr(v)}", where)
    rows = v if ndim == 2 else [v]
    for i, row in enumerate(rows):
        if not isinstance(row, list):
            raise InputError(f"must be {what}, got {short_repr(row)} in row {i}", where)
        for j, x in enumerate(row):
            json_number(x, f"{where}[{i}][{j}]" if ndim == 2 else f"{where}[{j}]",
                        bound=bound)
    if ndim == 2 and len({len(r) for r in rows}) > 1:
        raise InputError("rows must have the same length", where)
    a = np.array(v, dtype=float)
    if ndim == 2 and a.ndim == 1:                   # [] → shape (0,): no rows
        a = a.reshape(0, 0)
    return a


def shaped(a: np.ndarray, shape: tuple, where: str) -> np.ndarray:
    """``a`` in ``shape`` (``has shape …, needs …``); an empty array takes any empty
    shape (a model without state keeps ``[]`` and ``[[]]``)."""
    if a.size == 0 and 0 in shape:
        return a.reshape(shape)
    if a.shape != shape:
        raise InputError(f"has shape {a.shape}, needs {shape}", where)
    return a
