"""Output plumbing shared by every ``arfem`` command: safe output directories and
atomic writes (a reader never sees a half-written file; nothing the user owns is
overwritten without ``--force``)."""
from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from models.params import InputError

__all__ = ["prepare_out_dir", "atomic_write_text", "atomic_write_bytes", "atomic_path",
           "write_json", "write_csv", "staged_out_dir"]


def prepare_out_dir(out: str | os.PathLike, force: bool = False) -> Path:
    """Check ``out`` may be written: absent, empty, or ``force``. Creates nothing."""
    p = Path(out)
    if p.exists() and not p.is_dir():
        raise InputError("exists and is not a directory", str(p))
    if p.is_dir() and any(p.iterdir()) and not force:
        raise InputError("is not empty; choose another --out or pass --force to replace "
                         "the files arfem writes there", str(p))
    return p


@contextlib.contextmanager
def staged_out_dir(out: str | os.PathLike, force: bool = False):
    """Write a whole result set into a staging directory, then move it into ``out``.

    Yields the staging directory. On success each staged file replaces its
    namesake in ``out`` by an atomic rename (other files already in ``out`` are
    left alone); on any error ``out`` is untouched and the staging directory removed.
    """
    out = prepare_out_dir(out, force)
    parent = out.parent if str(out.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.staging-", dir=parent))
    try:
        yield stage
        out.mkdir(parents=True, exist_ok=True)
        for src in sorted(stage.rglob("*")):
            rel = src.relative_to(stage)
            dst = out / rel
            if src.is_dir():
                dst.mkdir(parents=True, exist_ok=True)
            else:
                dst.parent.mkdir(parents=True, exist_ok=True)
                os.replace(src, dst)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
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


def write_json(path: str | os.PathLike, obj) -> None:
    """Atomic JSON (NaN/inf written as null, numpy types converted)."""
    atomic_write_text(path, json.dumps(_jsonable(obj), indent=2, allow_nan=False) + "\n")


def write_csv(path: str | os.PathLike, columns: dict[str, np.ndarray], fmt: str = "%.10g") -> None:
    """Atomic CSV from named equal-length columns (header = the names)."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    import io as _io
    buf = _io.StringIO()
    np.savetxt(buf, data, delimiter=",", header=",".join(names), comments="", fmt=fmt)
    atomic_write_text(path, buf.getvalue())
