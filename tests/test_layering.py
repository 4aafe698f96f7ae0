"""Imports run one way: ground (``arfem.params``, ``arfem.io``) -> ``arfem.fem`` ->
``arfem.models`` -> ``arfem.scenarios``; ``models`` touches no file; everything imports as
``arfem.…`` and nothing edits ``sys.path``.

Why these checks: a module that imports a layer above it drags user files, CLI or
plotting into code meant to be pure and reusable (and re-creates import cycles); a
top-level ``fem``/``models``/``scenarios`` import breaks arfem in any working directory
that holds a ``models.py`` (issue 11). The checker reads source with :mod:`ast`, so it
sees imports inside functions too, and it is itself tested on a synthetic upward import.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

REPO = Path(__file__).resolve().parents[1]

#: source folder -> import name, as pyproject's package-dir maps them
FOLDERS = {"arfem": "arfem", "fem": "arfem.fem", "models": "arfem.models",
           "scenarios": "arfem.scenarios"}
#: rank of each layer; a module may import its own rank or lower
RANKS = {"ground": 0, "arfem.fem": 1, "arfem.models": 2, "arfem.scenarios": 3,
         "arfem.api": 4}
#: the one upward import allowed: the package root re-exports the API lazily (PEP 562
#: ``__getattr__``), so ``import arfem`` loads nothing of the layers above
FRONT_DOOR = {("arfem", "arfem.api")}
#: ``python -m arfem`` sits above everything (the root ``arfem`` itself is ground: its version)
ENTRY = {"arfem.__main__"}
#: calls that read or write files; none may appear under models/
FILE_CALLS = {"open", "read_text", "write_text", "read_bytes", "write_bytes", "savetxt",
              "loadtxt", "savefig", "mkdir", "unlink", "replace", "rename", "genfromtxt"}


def layer(module: str) -> str | None:
    """The layer of an ``arfem`` module name (None for anything outside arfem)."""
    if module in ENTRY:
        return "entry"
    for pkg in ("arfem.fem", "arfem.models", "arfem.scenarios", "arfem.api"):
        if module == pkg or module.startswith(pkg + "."):
            return pkg
    if module == "arfem" or module.startswith("arfem."):
        return "ground"
    return None


def module_name(path: Path) -> str:
    rel = path.relative_to(REPO)
    parts = [FOLDERS[rel.parts[0]], *rel.parts[1:]]
    parts[-1] = parts[-1][:-3]
    name = ".".join(parts)
    return name[: -len(".__init__")] if name.endswith(".__init__") else name


def imported_modules(source: str, module: str) -> list[tuple[int, str]]:
    """Absolute names of every module ``source`` imports (relative ones resolved)."""
    out = []
    pkg = module if module.count(".") == 0 else module.rsplit(".", 1)[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.rsplit(".", node.level - 1)[0] if node.level > 1 else pkg
                name = f"{base}.{node.module}" if node.module else base
            else:
                name = node.module
            out.append((node.lineno, name))
            out += [(node.lineno, f"{name}.{a.name}") for a in node.names
                    if layer(f"{name}.{a.name}") not in (None, layer(name))]
    return out


def violations(source: str, module: str) -> list[str]:
    """Every import in ``source`` that runs against the layering, one line each."""
    mine = layer(module)
    bad = []
    for line, name in imported_modules(source, module):
        top = name.split(".")[0]
        if top in ("fem", "models", "scenarios"):
            bad.append(f"{module}:{line} imports {name!r}: everything imports as arfem.…")
            continue
        theirs = layer(name)
        if theirs is None or mine == "entry" or (module, name) in FRONT_DOOR:
            continue
        if theirs == "entry":
            bad.append(f"{module}:{line} imports the entry point {name!r}")
        elif RANKS[theirs] > RANKS[mine]:
            bad.append(f"{module}:{line} ({mine}) imports {name!r} ({theirs}), a layer above")
        elif mine == "ground" and module == "arfem.params" and theirs == "ground":
            bad.append(f"{module}:{line} imports {name!r}: arfem.params imports nothing of arfem")
    return bad


def file_calls(source: str) -> list[str]:
    """Calls in ``source`` that read or write files (by the called name)."""
    hits = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) \
                else None
            if name in FILE_CALLS:
                hits.append(f"line {node.lineno}: {name}(…)")
    return hits


def package_modules():
    for folder in FOLDERS:
        for p in sorted((REPO / folder).rglob("*.py")):
            yield p, module_name(p)


def test_the_checker_flags_an_upward_import():
    """The checker itself: an upward import, a bare top-level import and a relative
    upward import are each caught; downward ones are not (so a green run means something)."""
    assert violations("from arfem.scenarios.io import x\n", "arfem.models.ar1")
    assert violations("def f():\n    from arfem.models import ar1\n", "arfem.fem.heat")
    assert violations("from arfem.fem import heat\n", "arfem.params")
    assert violations("from models.ar1 import x\n", "arfem.scenarios.commands.run")
    assert violations("from ...scenarios import cli\n", "arfem.models.diagnosis.engine")
    assert violations("from arfem.models import diagnosis\n", "arfem.io") != []
    assert violations("from arfem.fem.heat import x\nfrom arfem.params import Rod\n",
                      "arfem.models.ar1") == []
    assert violations("from arfem.models.ar1 import x\n", "arfem.scenarios.commands.run") == []
    assert file_calls("def f(p):\n    return open(p).read()\n")
    # the API sits above everything; only the package root may reach it (lazily)
    assert violations("from arfem import api\n", "arfem.scenarios.commands.run")
    assert violations("from arfem import api\n", "arfem.params")
    assert violations("from arfem import api\n", "arfem") == []
    assert violations("from arfem.scenarios.commands.run import evaluate\n", "arfem.api") == []


@pytest.mark.parametrize("path, module", list(package_modules()),
                         ids=lambda v: v if isinstance(v, str) else "")
def test_imports_run_one_way(path, module):
    """No module imports a layer above its own, nor a bare fem/models/scenarios."""
    assert violations(path.read_text(encoding="utf-8"), module) == []


@pytest.mark.parametrize("path", sorted((REPO / "models").rglob("*.py")), ids=str)
def test_models_touch_no_file(path):
    """models/ is pure: arrays and dataclasses in, results out; no file read or written."""
    assert file_calls(path.read_text(encoding="utf-8")) == []


def test_no_script_edits_sys_path():
    """Benchmarks, report scripts and tests import the installed arfem; none puts the
    repository on sys.path by hand."""
    offenders = [str(p.relative_to(REPO)) for p in REPO.rglob("*.py")
                 if ".venv" not in p.parts and p != Path(__file__).resolve()
                 and "sys.path" in p.read_text(encoding="utf-8", errors="replace")]
    assert offenders == []


def test_only_arfem_is_installed():
    """pyproject installs every package under the one name arfem (no top-level fem,
    models or scenarios in site-packages)."""
    cfg = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    st = cfg["tool"]["setuptools"]
    assert all(p == "arfem" or p.startswith("arfem.") for p in st["packages"])
    assert set(st["package-dir"]) == set(FOLDERS.values())
    assert cfg["project"]["scripts"]["arfem"].startswith("arfem.")


# -- command modules are entry points only --------------------------------------------
#
# A command module (one that defines ``add_parser``, which scenarios/cli.py registers) is
# the CLI's: what another module, a report script, a benchmark or a test needs from it
# lives in a library module (issue 31). The list of exceptions below is empty; an entry
# that no longer occurs fails too, so that the list may only shrink.

#: the one module that may import a command module
CLI = "arfem.scenarios.cli"
#: (importing file, command module) -> why it is still allowed (none left: keep it empty;
#: a new entry needs a reason that a reviewer accepts)
KNOWN_COMMAND_IMPORTS: dict[tuple[str, str], str] = {}
#: folders of scripts that are checked besides the package (a test of a command module
#: runs it through arfem.scenarios.cli.main)
SCRIPT_FOLDERS = ("benchmarks", "reports", "tests")


def defines_command(source: str) -> bool:
    """True for a command module: it defines ``add_parser`` at its top level."""
    return any(isinstance(n, ast.FunctionDef) and n.name == "add_parser"
               for n in ast.parse(source).body)


def imported_names(source: str, module: str) -> list[tuple[int, str]]:
    """Every module name ``source`` imports, with each ``from X import y`` also as X.y."""
    out = []
    pkg = module if module.count(".") == 0 else module.rsplit(".", 1)[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.rsplit(".", node.level - 1)[0] if node.level > 1 else pkg
                name = f"{base}.{node.module}" if node.module else base
            else:
                name = node.module or ""
            out.append((node.lineno, name))
            out += [(node.lineno, f"{name}.{a.name}") for a in node.names]
    return out


def command_imports(source: str, module: str, commands: set[str]) -> list[tuple[int, str]]:
    """(line, command module) for every command module ``source`` imports, unless it is
    the CLI or the command module itself."""
    if module == CLI:
        return []
    return sorted({(line, name) for line, name in imported_names(source, module)
                   if name in commands and name != module})


def command_module_names() -> set[str]:
    return {name for path, name in package_modules()
            if defines_command(path.read_text(encoding="utf-8"))}


def checked_files():
    """(path relative to the repository, module name) of every file the rule covers."""
    for path, name in package_modules():
        yield path.relative_to(REPO).as_posix(), name, path
    for folder in SCRIPT_FOLDERS:
        for path in sorted((REPO / folder).rglob("*.py")):
            yield path.relative_to(REPO).as_posix(), "script", path


def test_the_command_checker_flags_a_command_import():
    """The checker itself: importing a command module from a library module, a script or
    through ``from package import command`` is caught; the CLI, the command's own module
    and a library module beside it are not (so a green run means something)."""
    cmds = {"arfem.scenarios.commands.run", "arfem.scenarios.commands.compensate"}
    src = "from arfem.scenarios.commands.run import evaluate\n"
    assert command_imports(src, "arfem.scenarios.commands.check", cmds) == [(1, "arfem.scenarios.commands.run")]
    assert command_imports(src, "script", cmds) == [(1, "arfem.scenarios.commands.run")]
    assert command_imports("def f():\n    from arfem.scenarios.commands import compensate\n",
                           "arfem.api", cmds) == [(2, "arfem.scenarios.commands.compensate")]
    assert command_imports("import arfem.scenarios.commands.run as r\n", "script", cmds)
    assert command_imports("from .run import evaluate\n", "arfem.scenarios.commands.check", cmds)
    assert command_imports(src, CLI, cmds) == []
    assert command_imports(src, "arfem.scenarios.commands.run", cmds) == []
    assert command_imports("from arfem.scenarios.rod.evaluation import evaluate\n"
                           "from arfem.scenarios.compensation.replay import replay\n", "script", cmds) == []
    assert defines_command("def add_parser(sub):\n    pass\n")
    assert not defines_command("def f():\n    def add_parser(sub):\n        pass\n")


def test_command_modules_are_imported_by_the_cli_only():
    """No module, report script, benchmark or test imports a command module (``run``,
    ``compensate``, ``diagnose``, ``check``, ``sweep``, ``allocate``, ``twin``,
    ``report``…) but scenarios/cli.py, except the pairs of KNOWN_COMMAND_IMPORTS; and
    every one of those still occurs (the list only shrinks)."""
    cmds = command_module_names()
    assert {"arfem.scenarios.commands.run", "arfem.scenarios.commands.compensate"} <= cmds
    found = {}
    for rel, name, path in checked_files():
        for line, cmd in command_imports(path.read_text(encoding="utf-8"), name, cmds):
            found.setdefault((rel, cmd), line)
    new = sorted(f"{rel}:{line} imports the command module {cmd}"
                 for (rel, cmd), line in found.items() if (rel, cmd) not in KNOWN_COMMAND_IMPORTS)
    assert new == [], "move what it needs into a library module"
    stale = sorted(set(KNOWN_COMMAND_IMPORTS) - set(found))
    assert stale == [], "remove these from KNOWN_COMMAND_IMPORTS: they no longer occur"


def import_graph(sources: dict) -> dict:
    """module -> the arfem modules it imports, anywhere in its source (a function's body
    included): ``sources`` maps module names to their text. A name is resolved to the
    module it lies in; the package root ``arfem`` is left out (it loads the API lazily,
    PEP 562, so importing it runs nothing of the layers)."""
    mods = set(sources)

    def owner(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None
    graph = {}
    for mod, text in sources.items():
        deps = {owner(n) for _, n in imported_modules(text, mod)}
        graph[mod] = {d for d in deps if d not in (None, mod, "arfem")}
    return graph


def cycles(graph: dict) -> list:
    """The import cycles of ``graph``: each strongly connected component of two or more
    modules (Tarjan's algorithm), sorted."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(out)


def test_the_cycle_finder_sees_a_cycle_hidden_in_a_function():
    """The check below is itself checked: an import inside a function closes a cycle
    as surely as one at the top (it only delays it to the call)."""
    src = {"arfem.scenarios.a": "import arfem.scenarios.b\n",
           "arfem.scenarios.b": "def f():\n    from arfem.scenarios.a import g\n",
           "arfem.scenarios.c": "from arfem.scenarios.a import h\n"}
    assert cycles(import_graph(src)) == [["arfem.scenarios.a", "arfem.scenarios.b"]]
    src["arfem.scenarios.b"] = "def f():\n    from arfem.scenarios.d import g\n"
    src["arfem.scenarios.d"] = "import arfem\n"            # the lazy root: no edge
    assert cycles(import_graph(src)) == []
    src["arfem.scenarios.d"] = "def f():\n    import arfem.scenarios.c\n"
    assert cycles(import_graph(src)) == [["arfem.scenarios.a", "arfem.scenarios.b",
                                          "arfem.scenarios.c", "arfem.scenarios.d"]]


def test_no_import_cycle_even_inside_functions():
    """Issue 41: six import cycles were hidden by imports inside functions (heat and
    reduced, the mesh's scenario and export, the rod's check and the mesh's, the sweep's
    spec and runner with their mesh twins, the two live transports, the compensator and
    its observer). A module whose import would run into its own importer is a design
    knot: what both need goes below both, what uses both goes above. Imports inside
    functions stay allowed for start-up time, never to hide a cycle."""
    sources = {module: path.read_text(encoding="utf-8") for path, module in package_modules()}
    assert cycles(import_graph(sources)) == []


#: public function names a module of any room may define: the entry point of a command
#: module or of a ``python -m`` module (the CLI calls each by its module)
PROTOCOL_NAMES = {"main"}
#: the names that once collided across the rod's and the mesh's worlds (issue 41 item 6);
#: never allowed twice, whatever the allow-list below says
ONCE_COLLIDED = {"terminal_line", "solve_theta", "solve_reduced", "fit_causes"}
#: public top-level functions defined in modules of different rooms, each with exactly
#: the modules that define it and why it may stay so. The test fails when a name gains
#: or loses a module: a new collision must be resolved or argued here, and an entry
#: whose collision is gone must be deleted.
SHARED_NAMES = {
    # the Python front door names what a user calls; each body calls the one below it
    "diagnose": ({"arfem.api", "arfem.models.diagnosis.engine"}, "front door"),
    "load_scenario": ({"arfem.api", "arfem.scenarios.rod.scenario"}, "front door"),
    "read_model": ({"arfem.api", "arfem.scenarios.compensation.model_file"}, "front door"),
    # the two engines' doubles, merged by issue 41 item 1 (the one diagnosis pipeline)
    "establishment_failures": ({"arfem.models.diagnosis.verdict",
                                "arfem.models.geodiagnosis.engine"}, "issue 41 item 1"),
    "generate": ({"arfem.models.diagnosis.synth", "arfem.models.geodiagnosis.synth"},
                 "issue 41 item 1"),
    # different things under one verb; not yet renamed (issue 41 item 6)
    "check_size": ({"arfem.scenarios.rod.scenario", "arfem.scenarios.sweep.spec"},
                   "a scenario's cost vs a sweep grid's size"),
    "record_columns": ({"arfem.scenarios.compensation.replay",
                        "arfem.scenarios.geometry.export"},
                       "a model's columns read from a record vs a run written as one"),
    "verdict": ({"arfem.scenarios.allocation.run", "arfem.scenarios.diagnosis.report"},
                "each report's opening section"),
    "write_outputs": ({"arfem.scenarios.rod.outputs", "arfem.scenarios.sweep.report"},
                      "a rod run's files vs a sweep's"),
    "write_record": ({"arfem.scenarios.live.twin_record", "arfem.scenarios.records.georecord"},
                     "the twin's history vs a v3 record from columns"),
}


def public_functions(source: str) -> set[str]:
    """The public (no leading underscore) functions ``source`` defines at its top level."""
    return {n.name for n in ast.parse(source).body
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
            and not n.name.startswith("_")}


def shared_names(sources: dict) -> dict:
    """{name: set of modules} for every public top-level function name that modules of
    two or more rooms (a room: the package a module sits in) define, but
    :data:`PROTOCOL_NAMES`."""
    where: dict = {}
    for module, src in sources.items():
        for name in public_functions(src) - PROTOCOL_NAMES:
            where.setdefault(name, set()).add(module)
    return {n: ms for n, ms in where.items()
            if len({m.rsplit(".", 1)[0] for m in ms}) > 1}


def test_the_name_checker_sees_a_name_in_two_rooms():
    """The check below is itself checked: one name in two rooms is seen, two modules of
    one room (the commands' ``add_parser``), a private name and ``main`` are not."""
    src = {"arfem.scenarios.diagnosis.run": "def terminal_line(s):\n    pass\n",
           "arfem.scenarios.compensation.report": "def terminal_line(r, o):\n    pass\n",
           "arfem.scenarios.commands.run": "def add_parser(p):\n    pass\ndef main(a):\n    pass\n",
           "arfem.scenarios.commands.check": "def add_parser(p):\n    pass\ndef main(a):\n    pass\n",
           "arfem.scenarios.cli": "def main(a):\n    pass\ndef _helper():\n    pass\n",
           "arfem.fem.heat": "def _helper():\n    pass\n"}
    assert shared_names(src) == {"terminal_line": {"arfem.scenarios.diagnosis.run",
                                                   "arfem.scenarios.compensation.report"}}


def test_no_function_name_is_defined_in_two_rooms():
    """Issue 41 item 6: the rod's and the mesh's worlds grew functions of one name
    (``solve_theta``, ``solve_reduced``, ``fit_causes``, four ``terminal_line``): a
    traceback, a grep or an import could not tell which was meant, and two of them were
    a rule written twice. A public top-level function name is defined in one room only,
    but the entries of :data:`SHARED_NAMES`, each with its modules and why."""
    assert not ONCE_COLLIDED & set(SHARED_NAMES)
    sources = {module: path.read_text(encoding="utf-8") for path, module in package_modules()}
    found = shared_names(sources)
    allowed = {n: ms for n, (ms, _) in SHARED_NAMES.items()}
    new = {n: sorted(ms) for n, ms in found.items() if allowed.get(n) != ms}
    gone = sorted(n for n in allowed if n not in found)
    assert not new, f"defined in modules of two rooms (rename, or argue it in SHARED_NAMES): {new}"
    assert not gone, f"no longer shared: delete from SHARED_NAMES: {gone}"
