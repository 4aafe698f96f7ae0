"""No function of the package grows past 80 lines, and the long ones left only shrink.

Why: a function over 80 lines mixes ideas that a reader, a test and a reviewer want to
take one at a time (issue 31); split it where the split names an idea. The functions
still longer are listed below with their length today; the test fails when a function
not listed passes 80 lines, when a listed one grows, and when a listed one has been
split (so that its entry is removed and the list only shrinks). Lines are counted from
the ``def`` to the last line of the body, docstring included (:mod:`ast`).
"""
from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FOLDERS = ("arfem", "fem", "models", "scenarios")
MAX_LINES = 80

#: "file::Class.function" -> its length today [lines]; to be split, never to grow. Empty
#: since 2026-11-25 (issue 31): a new entry needs a reason a reviewer accepts (a data table)
LONG_FUNCTIONS: dict[str, int] = {}


def long_functions(source: str, limit: int = MAX_LINES) -> dict[str, int]:
    """Qualified name -> length [lines] of every function in ``source`` longer than
    ``limit`` (methods as ``Class.method``, nested functions as ``outer.inner``)."""
    out = {}

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    n = child.end_lineno - child.lineno + 1
                    if n > limit:
                        out[name] = n
                visit(child, name + ".")
            else:
                visit(child, prefix)
    visit(ast.parse(source), "")
    return out


def package_long_functions() -> dict[str, int]:
    found = {}
    for folder in FOLDERS:
        for p in sorted((REPO / folder).rglob("*.py")):
            rel = p.relative_to(REPO).as_posix()
            for name, n in long_functions(p.read_text(encoding="utf-8")).items():
                found[f"{rel}::{name}"] = n
    return found


def test_the_counter_measures_functions_methods_and_nested_ones():
    """The counter itself: a 3-line function is under a limit of 3 lines, a 4-line one
    over; methods and nested functions are named by their owner."""
    src = ("def a():\n    x = 1\n    return x\n\n"
           "class K:\n    def m(self):\n        x = 1\n        y = 2\n        return x + y\n\n"
           "def outer():\n    def inner():\n        x = 1\n        y = 2\n        return x + y\n"
           "    return inner\n")
    assert long_functions(src, limit=3) == {"K.m": 4, "outer": 6, "outer.inner": 4}
    assert long_functions(src, limit=6) == {}


def test_no_function_grows_past_80_lines():
    """Every function over 80 lines is listed, none is longer than its entry, and every
    entry is still over 80 lines (a split function leaves the list)."""
    found = package_long_functions()
    new = sorted(f"{k}: {n} lines" for k, n in found.items() if k not in LONG_FUNCTIONS)
    assert new == [], "split it where the split names an idea"
    grown = sorted(f"{k}: {found[k]} lines (listed {n})" for k, n in LONG_FUNCTIONS.items()
                   if k in found and found[k] > n)
    assert grown == [], "a listed long function may only get shorter"
    done = sorted(k for k in LONG_FUNCTIONS if k not in found)
    assert done == [], "now at most 80 lines (or gone): remove from LONG_FUNCTIONS"
