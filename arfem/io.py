"""Ground-layer file plumbing: strict reading of a user's text files (one-line errors)
and atomic writes (a reader never sees a half-written file).

Everything in arfem reads and writes files through here; this module imports nothing of
arfem but :mod:`arfem.params` (for :class:`~arfem.params.InputError`).
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from arfem.limits import Limits, resolve
from arfem.params import InputError

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["sha256_file", "toml_has_table", "read_text_utf8", "read_toml", "json_text", "atomic_write_text",
           "atomic_write_bytes", "atomic_path", "write_json", "write_csv", "files_read",
           "MAX_TEXT_BYTES"]

#: Largest user text file (TOML, CSV) read whole [bytes]: 1 GiB would take minutes and
#: ~10x its size in memory to parse; far above any record here (lifted by --allow-large).
MAX_TEXT_BYTES = 256 * 1024 ** 2

#: Every user file read in this process (absolute paths): the inputs that
#: ``scenarios/outdir.py`` never lets an output replace.
_FILES_READ: set = set()


def files_read() -> frozenset:
    """Absolute paths of every file read through :func:`read_text_utf8` so far."""
    return frozenset(_FILES_READ)


def read_text_utf8(path: str | os.PathLike, missing: str = "file not found",
                   max_bytes: int | None = None, record: bool = True,
                   limits: Limits | None = None) -> str:
    """The text of a UTF-8 file (a leading BOM dropped).

    A missing file, a directory, an unreadable file, a file larger than ``max_bytes``
    [bytes] (default :data:`MAX_TEXT_BYTES`; unless ``limits.large``, see
    :class:`arfem.limits.Limits`), a NUL byte (checked in the first 64 KiB
    before the rest is read) or bytes that are not UTF-8 raise :class:`InputError`
    naming the file (and, for bad bytes, the line).

    With ``record`` (the default) the file counts as an input of this process: no
    output staged by ``scenarios/outdir.py`` may replace it (see :func:`files_read`).
    Pass ``record=False`` to read an earlier output only to compare it.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "x.csv"
    >>> _ = p.write_bytes(b"a,b\\n1,\\xe9\\n")
    >>> try:
    ...     read_text_utf8(p)
    ... except InputError as e:
    ...     print(str(e).replace(str(p), "x.csv"))
    x.csv: line 2: is not UTF-8 (byte 6 of the file)
    """
    p = Path(path)
    max_bytes = MAX_TEXT_BYTES if max_bytes is None else max_bytes
    NUL = b"\0"
    try:
        if not p.is_file():
            raise InputError(missing if not p.exists() else "is not a file", str(p))
        if record:
            _FILES_READ.add(os.path.abspath(p))
        size = p.stat().st_size
        if size > max_bytes and not resolve(limits).large:
            raise InputError(f"is {size / 1024 ** 2:.0f} MiB; arfem reads at most "
                             f"{max_bytes / 1024 ** 2:.0f} MiB (pass --allow-large to lift "
                             "the limit)", str(p))
        with open(p, "rb") as fh:
            head = fh.read(1 << 16)
            if b"\0" in head:
                raise InputError(f"holds a NUL byte (byte {head.index(NUL)} of the file): "
                                 "a binary file, not text", str(p))
            raw = head + fh.read()
    except OSError as e:
        raise InputError(f"cannot be read ({e.strerror or e})", str(p)) from None
    if b"\0" in raw:
        raise InputError(f"holds a NUL byte (byte {raw.index(NUL)} of the file): "
                         "a binary file, not text", str(p))
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise InputError(f"is not UTF-8 (byte {e.start} of the file)",
                         f"{p}: line {line}") from None


def read_toml(path: str | os.PathLike, limits: Limits | None = None) -> dict:
    """Parse a UTF-8 TOML file; anything wrong is one :class:`InputError` line."""
    text = read_text_utf8(path, limits=limits)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"malformed TOML: {str(e).splitlines()[0]}", str(path)) from None
    except RecursionError:
        raise InputError("malformed TOML: nested too deeply", str(path)) from None
    except ValueError as e:             # e.g. an integer of more than 4300 digits
        raise InputError(f"malformed TOML: {str(e).splitlines()[0]}", str(path)) from None


def toml_has_table(path: str | os.PathLike, table: str) -> bool:
    """True when ``path`` is a ``.toml`` file with a line opening ``[table]`` (a cheap
    text test that decides which reader a file goes to, before the strict one runs)."""
    p = Path(path)
    if p.suffix != ".toml" or not p.is_file():
        return False
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return False
    return any(line.strip().startswith(f"[{table}]") for line in text.splitlines())


def sha256_file(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _umask() -> int:
    m = os.umask(0o022)
    os.umask(m)
    return m


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        if os.path.exists(tmp):           # mkstemp's 0600 -> what open() would have made
            os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return [_jsonable(v) for v in o.tolist()]
    if isinstance(o, (np.floating, float)):
        f = float(o)
        return f if math.isfinite(f) else None
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.bool_,)):
        return bool(o)
    return o


def json_text(obj, indent: int | None = None) -> str:
    """JSON text of ``obj`` with numpy types converted and NaN/inf as null.

    >>> json_text({"ratio": np.float64(1.25), 3000.0: [np.int64(2), float("nan")]})
    '{"ratio": 1.25, "3000.0": [2, null]}'
    """
    return json.dumps(_jsonable(obj), indent=indent, allow_nan=False, ensure_ascii=False)


def write_json(path: str | os.PathLike, obj) -> None:
    """Atomic JSON (NaN/inf written as null, numpy types converted)."""
    atomic_write_text(path, json_text(obj, indent=2) + "\n")


def write_csv(path: str | os.PathLike, columns: dict[str, np.ndarray], fmt: str = "%.10g") -> None:
    """Atomic CSV from named equal-length columns (header = the names)."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    import io as _io
    buf = _io.StringIO()
    np.savetxt(buf, data, delimiter=",", header=",".join(names), comments="", fmt=fmt)
    atomic_write_text(path, buf.getvalue())
