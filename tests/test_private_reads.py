"""No module reads another module's private member: a name with a leading underscore
(``plant._smoothed_C``, ``verdict._better_baselines``) is read only in the module that
defines it, and what another module needs is public and documented
(:meth:`arfem.models.diagnosis.speed_plant.SpeedPlant.smoothed_temperature_C`,
:func:`arfem.models.diagnosis.verdict.better_baselines`).

Checked statically on the package's sources (ground, fem, models, scenarios): every
attribute ``x._name`` read on anything but ``self``/``cls`` must name something its own
module defines (a function, class, assignment, attribute set, argument or string: an
attribute it sets on an object by name). Allowed beside them: the named tuple's public
API (``_asdict``, ...) and the two standard-library names listed in :data:`STDLIB`.
Private names are not imported either: no ``from arfem.x import _y`` (nor from a private
module, ``from x._y import z``), wherever the import stands (module level, inside a
function, in a parenthesised multi-line import). A name another module needs is part
of its defining module's interface: public, documented and in its ``__all__``. The
standard-library exceptions, if ever needed, go in :data:`STDLIB_IMPORTS` with a reason.
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the package's rooms: ground, fem, models, scenarios
ROOMS = ["arfem", "fem", "models", "scenarios"]
#: the named tuple's API: public, with an underscore against field-name clashes
NAMED_TUPLE = {"_asdict", "_replace", "_fields", "_make", "_field_defaults"}
#: standard-library members read where no public way exists: (file, expression)
STDLIB = {("scenarios/cli.py", "sp._actions"),             # argparse's sub-parsers
          ("scenarios/sweep/executors.py", "os._exit")}    # a documented os function
#: standard-library private names imported where no public way exists:
#: {(file, "module._name"): reason}; empty, none is needed today
STDLIB_IMPORTS: dict = {}


def _defined(tree) -> set:
    """Every name the module defines or sets itself (and every string it holds)."""
    out = set()
    for n in ast.walk(tree):
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(n.name)
        elif isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store):
            out.add(n.id)
        elif isinstance(n, ast.Attribute) and isinstance(n.ctx, ast.Store):
            out.add(n.attr)
        elif isinstance(n, ast.Constant) and isinstance(n.value, str):
            out.add(n.value)
        elif isinstance(n, ast.arg):
            out.add(n.arg)
    return out


def foreign_private_reads(source: str, rel: str) -> list:
    """``["<rel>:<line>: <expression>", ...]``: reads of a private attribute that the
    module ``rel`` (its ``source``) does not define."""
    tree = ast.parse(source)
    mine = _defined(tree)
    out = []
    for n in ast.walk(tree):
        if not (isinstance(n, ast.Attribute) and n.attr.startswith("_")
                and not n.attr.startswith("__")):
            continue
        if isinstance(n.value, ast.Name) and n.value.id in ("self", "cls"):
            continue
        if n.attr in NAMED_TUPLE or n.attr in mine or (rel, ast.unparse(n)) in STDLIB:
            continue
        out.append(f"{rel}:{n.lineno}: {ast.unparse(n)}")
    return out


def test_the_check_sees_a_foreign_private_read():
    """The check itself: a plant's private method read from outside is caught, the
    module's own private names, ``self``'s and a named tuple's ``_asdict`` are not."""
    src = ("def f(plant, row):\n    return plant._smoothed_C('T_C'), row._asdict()\n"
           "def _own():\n    pass\nclass A:\n    def g(self, m):\n"
           "        return self._x, m._own\n")
    assert foreign_private_reads(src, "m.py") == ["m.py:2: plant._smoothed_C"]


def _scan(room: str, check) -> list:
    """``check(source, rel)``'s findings over every module of the package room ``room``."""
    found = []
    for path in sorted((ROOT / room).rglob("*.py")):
        found += check(path.read_text(encoding="utf-8"), path.relative_to(ROOT).as_posix())
    return found


@pytest.mark.parametrize("room", ROOMS)
def test_no_module_reads_another_modules_private_member(room):
    assert _scan(room, foreign_private_reads) == []


def _private(name: str) -> bool:
    """A single leading underscore: private by Python's convention (dunders are not)."""
    return name.startswith("_") and not name.startswith("__")


def foreign_private_imports(source: str, rel: str) -> list:
    """``["<rel>:<line>: from <module> import <name>", ...]``: every import in module
    ``rel`` (its ``source``) of a private name, or of anything from a private module,
    at any depth of the tree (function-level imports included), less
    :data:`STDLIB_IMPORTS`."""
    out = []
    for n in ast.walk(ast.parse(source)):
        if isinstance(n, ast.ImportFrom):
            mod = "." * n.level + (n.module or "")
            in_private = any(_private(part) for part in (n.module or "").split("."))
            for a in n.names:
                if (in_private or _private(a.name)) and \
                        (rel, f"{mod}.{a.name}") not in STDLIB_IMPORTS:
                    out.append(f"{rel}:{n.lineno}: from {mod} import {a.name}")
        elif isinstance(n, ast.Import):
            for a in n.names:
                if any(_private(part) for part in a.name.split(".")) and \
                        (rel, a.name) not in STDLIB_IMPORTS:
                    out.append(f"{rel}:{n.lineno}: import {a.name}")
    return sorted(out, key=lambda s: int(s.split(":")[1]))


def test_the_check_sees_a_private_import():
    """The check itself: a private name in a one-line import, in a parenthesised
    multi-line import, under ``as``, in a function-level import and from a private
    module is caught; public names, ``__future__`` and dunders are not."""
    src = ("from __future__ import annotations\n"
           "from arfem.a import _one, public\n"
           "from arfem.b import (Public,\n"
           "                     _two as two)\n"
           "from . import __version__\n"
           "def f():\n"
           "    from .c import _three\n"
           "    import arfem._hidden\n"
           "    from arfem._d import four\n"
           "    return _three\n")
    assert foreign_private_imports(src, "m.py") == [
        "m.py:2: from arfem.a import _one", "m.py:3: from arfem.b import _two",
        "m.py:7: from .c import _three", "m.py:8: import arfem._hidden",
        "m.py:9: from arfem._d import four"]


@pytest.mark.parametrize("room", ROOMS)
def test_no_module_imports_another_modules_private_name(room):
    assert _scan(room, foreign_private_imports) == []
