"""The scenario copy of a mesh run's output folder, re-runnable from anywhere.

``arfem run SCENARIO.toml --out DIR`` on a ``[geometry]`` scenario copies the scenario
into ``DIR/scenario.toml`` (for ``report.html``, for ``arfem diagnose DIR/record.toml``,
whose ``[model]`` table names it, and for a rerun). The scenario names its mesh, and
possibly a cycle CSV, relative to itself; a verbatim copy would name files that are not
beside it. So the files it names are copied beside it too, and the copy's keys
``geometry.mesh`` and ``cycle.csv`` are rewritten to the copies' names: ``arfem run
DIR/scenario.toml --out DIR2`` then works from any working directory, and the folder can
be moved or archived whole. An XDMF mesh, whose data live in companion files, is not
copied: the copy names it by absolute path (re-runnable from anywhere on this machine).

The rewrite edits only the value of those keys in the text (comments and layout kept),
and is checked by parsing the result: it must equal the original document with those
keys changed. Where the text is written in a way the line edit does not handle (e.g. an
inline table ``geometry = {mesh = ...}``), the copy keeps the original text and names
the files by absolute path in a comment (:attr:`ScenarioCopy.self_contained` is False).
"""
from __future__ import annotations

import json
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ScenarioCopy", "plan_copy", "plan_scenario_copy", "write_copy",
           "rewrite_values", "COPY_NAME"]

#: the name of the copy in the output folder
COPY_NAME = "scenario.toml"
#: (table, key) of every file a geometry scenario names relative to itself
_FILE_KEYS = (("geometry", "mesh"), ("cycle", "csv"))
#: mesh formats whose data live in companion files (XDMF: heavy data in .h5): named by
#: absolute path instead of copied
_LINKED = (".xdmf", ".xmf", ".xdmf3")
_HEADER = re.compile(r"^\s*\[\[?\s*([A-Za-z0-9_.\-\"' ]+?)\s*\]\]?\s*(#.*)?$")
_VALUE = r"""("(?:[^"\\]|\\.)*"|'[^']*')"""


@dataclass(frozen=True)
class ScenarioCopy:
    """What goes into the output folder beside the scenario's copy.

    Attributes
    ----------
    files : tuple of (Path, str)
        Each input file the scenario names (resolved) and its name in the folder.
    values : dict
        ``{(table, key): name in the folder}``: the copy's new values.
    originals : dict
        ``{(table, key): Path}``: the file each key names, resolved.
    """

    source: Path
    files: tuple
    values: dict
    originals: dict

    @property
    def names(self) -> tuple:
        """The names this copy writes into the folder (the scenario's and its files')."""
        return (COPY_NAME, *(n for _, n in self.files))


def plan_copy(source, doc: dict, taken=()) -> ScenarioCopy:
    """Which files the scenario ``source`` (parsed as ``doc``) names and under which
    name each is copied: its own base name, or ``input_<name>`` where that is one of
    the folder's other outputs (``taken``) or an earlier copy's name.

    >>> c = plan_copy(Path("/a/s.toml"), {"geometry": {"mesh": "m/u.msh"},
    ...               "cycle": {"csv": "record.csv"}}, taken=("record.csv",))
    >>> [n for _, n in c.files], c.values[("cycle", "csv")]
    (['u.msh', 'input_record.csv'], 'input_record.csv')
    """
    source = Path(source)
    used = {COPY_NAME, *taken}
    files, values, originals = [], {}, {}
    for table, key in _FILE_KEYS:
        v = doc.get(table, {}).get(key) if isinstance(doc.get(table), dict) else None
        if not isinstance(v, str):
            continue
        path = (source.parent / v).resolve()
        originals[(table, key)] = path
        if path.suffix.lower() in _LINKED:      # its data sit in other files: not copied,
            values[(table, key)] = path.as_posix()     # named by its absolute path
            continue
        name = path.name
        while name in used:
            name = f"input_{name}"
        used.add(name)
        files.append((path, name))
        values[(table, key)] = name
    return ScenarioCopy(source, tuple(files), values, originals)


def plan_scenario_copy(source, taken=(), text: str | None = None) -> tuple:
    """(:class:`ScenarioCopy`, text) of the scenario file ``source`` (read as an input
    of this run; ``text``: its text already read, not read again), or (None, '') where
    it is not a file (a scenario built in memory)."""
    from arfem.io import read_text_utf8
    source = Path(source)
    if not source.is_file():
        return None, ""
    text = read_text_utf8(source) if text is None else text
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        doc = {}
    return plan_copy(source, doc, taken), text


def _set(doc: dict, values: dict) -> dict:
    new = {k: (dict(v) if isinstance(v, dict) else v) for k, v in doc.items()}
    for (table, key), v in values.items():
        new[table][key] = v
    return new


def rewrite_values(text: str, values: dict) -> str | None:
    """``text`` (a TOML document) with the string value of each ``(table, key)`` of
    ``values`` replaced, comments and layout kept; None where a key is not written as
    ``key = "..."`` on its own line under ``[table]`` or the result does not parse to
    the original document with those values.

    >>> rewrite_values('[geometry]\\nmesh = "../m.msh"  # the mesh\\n',
    ...                {("geometry", "mesh"): "m.msh"})
    '[geometry]\\nmesh = "m.msh"  # the mesh\\n'
    """
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return None
    lines, table, done = text.splitlines(keepends=True), None, set()
    for i, line in enumerate(lines):
        h = _HEADER.match(line)
        if h:
            table = h.group(1).strip().strip("\"'")
            continue
        for (t, key), v in values.items():
            m = re.match(rf"^(\s*{re.escape(key)}\s*=\s*){_VALUE}(.*)$", line, re.S)
            if t == table and m and (t, key) not in done:
                lines[i] = m.group(1) + json.dumps(v, ensure_ascii=False) + m.group(3)
                done.add((t, key))
    out = "".join(lines)
    try:
        ok = done == set(values) and tomllib.loads(out) == _set(doc, values)
    except tomllib.TOMLDecodeError:
        ok = False
    return out if ok else None


def write_copy(copy: ScenarioCopy, text: str, out_dir: Path) -> bool:
    """Write the scenario's copy (``text`` rewritten by :func:`rewrite_values`) and
    the files it names into ``out_dir`` (a staging directory); True when the folder is
    self-contained, False when the copy kept its original text and names the files in a
    comment (see the module)."""
    import shutil

    from arfem.io import atomic_write_text
    new = rewrite_values(text, copy.values) if copy.values else text
    head = f"# copied by arfem run from {copy.source.resolve()}"
    contained = new is not None
    if not contained:
        where = ", ".join(f"{t}.{k} = {str(p)!r}" for (t, k), p in copy.originals.items())
        new = (f"{head}; its files are beside that original, not here (the copy could "
               f"not rewrite its paths): {where}\n{text}")
    else:
        new = (f"{head}" + (f"; {', '.join(n for _, n in copy.files)} copied beside it"
                            if copy.files else "") + f"\n{new}")
        for path, name in copy.files:
            shutil.copyfile(path, out_dir / name)
    atomic_write_text(out_dir / COPY_NAME, new)
    return contained
