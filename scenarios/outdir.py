"""Output directories for every ``arfem`` command: refuse an ``--out`` that cannot be
written before any work, stage a whole result set, then move it into place all or
nothing (nothing the user owns is overwritten without ``--force``)."""
from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from arfem.params import InputError

__all__ = ["check_out_path", "prepare_out_dir", "staged_out_dir"]


def check_out_path(out: str | os.PathLike) -> Path:
    """Refuse an output path that cannot become a writable directory. Creates nothing.

    Catches, before any work is done: an existing file or a broken symbolic link at
    ``out``, a file where one of its parent directories should be, and a directory
    (``out`` or its nearest existing parent) that cannot be written.
    """
    p = Path(out)
    if p.is_symlink() and not p.exists():
        raise InputError("is a broken symbolic link", str(p))
    if p.exists() and not p.is_dir():
        raise InputError("exists and is not a directory", str(p))
    anc = p.parent                        # Path("out").parent is Path(".")
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        raise InputError(f"cannot be created: {anc} is not a directory", str(p))
    for d in ([p] if p.is_dir() else []) + [anc]:
        try:
            tempfile.TemporaryDirectory(prefix=".arfem-probe-", dir=d).cleanup()
        except OSError as e:
            raise InputError(f"cannot be written ({e.strerror or e})",
                             str(p) if d is p else f"{p} (in {d})") from None
    return p


def prepare_out_dir(out: str | os.PathLike, force: bool = False) -> Path:
    """Check ``out`` may be written: absent, empty, or ``force``. Creates nothing."""
    p = check_out_path(out)
    if p.is_dir() and any(p.iterdir()) and not force:
        raise InputError("is not empty; choose another --out or pass --force to replace "
                         "the files arfem writes there", str(p))
    return p


def _stale_stages(out: Path):
    """Staging directories of ``out`` left by an arfem process that no longer runs."""
    for d in out.parent.glob(f".{out.name}.staging-*-*"):
        try:
            pid = int(d.name[len(f".{out.name}.staging-"):].split("-", 1)[0])
            os.kill(pid, 0)
        except ProcessLookupError:
            yield d
        except (ValueError, PermissionError, OSError):
            continue


@contextlib.contextmanager
def staged_out_dir(out: str | os.PathLike, force: bool = False, may_replace=None):
    """Write a whole result set into a staging directory, then move it into ``out``.

    Yields the staging directory. On success each staged file replaces its namesake
    in ``out`` by an atomic rename (other files already in ``out`` are left alone).
    The move is all or nothing: every clash (a directory where a file goes, or the
    reverse) is refused before the first rename, and if a rename still fails, the
    files already moved are put back as they were. On any error ``out`` is as it was
    and the staging directory is removed; one left by a killed run is removed by the
    next run into the same ``out``.

    ``may_replace(rel, path)``, if given, lets ``out`` be non-empty and is asked before
    each existing file is replaced (unless ``force``); a False refuses the whole set.
    """
    out = prepare_out_dir(out, force or may_replace is not None)
    for d in _stale_stages(out):
        shutil.rmtree(d, ignore_errors=True)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.staging-{os.getpid()}-",
                                      dir=out.parent))
    except OSError as e:
        raise InputError(f"cannot be written ({e.strerror or e})", str(out)) from None
    try:
        yield stage
        _move_all(stage, out, force, may_replace)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _move_all(stage: Path, out: Path, force: bool, may_replace) -> None:
    entries = sorted(stage.rglob("*"))
    files = [s for s in entries if not s.is_dir()]
    for src in entries:                                   # every clash, before any move
        rel = src.relative_to(stage)
        dst = out / rel
        if src.is_dir() and (dst.exists() or dst.is_symlink()) and not dst.is_dir():
            raise InputError(f"{rel} is a file here, where arfem writes a directory; "
                             "move it away", str(out))
        if not src.is_dir() and dst.is_dir():
            raise InputError(f"{rel} is a directory here, where arfem writes a file; "
                             "move it away", str(out))
        if (not src.is_dir() and not force and may_replace is not None and dst.exists()
                and not may_replace(rel, dst)):
            raise InputError(f"{rel} was not written by arfem (or was changed since); "
                             "pass --force to replace it", str(out))
    backup = stage.with_name(stage.name + ".old")
    done, made = [], []
    try:
        for d in [out] + [out / s.relative_to(stage) for s in entries if s.is_dir()]:
            if not d.is_dir():
                d.mkdir(parents=True)
                made.append(d)
        for src in files:
            rel = src.relative_to(stage)
            dst = out / rel
            bak = None
            if dst.exists() or dst.is_symlink():
                bak = backup / rel
                bak.parent.mkdir(parents=True, exist_ok=True)
                os.replace(dst, bak)
            done.append((dst, bak))
            os.replace(src, dst)
    except OSError as e:
        for dst, bak in reversed(done):                   # put everything back
            with contextlib.suppress(OSError):
                if bak is not None and bak.exists():
                    os.replace(bak, dst)
                elif dst.exists():
                    dst.unlink()
        for d in reversed(made):
            with contextlib.suppress(OSError):
                d.rmdir()
        raise InputError(f"cannot be written ({e.strerror or e}); left as it was",
                         str(out)) from None
    finally:
        shutil.rmtree(backup, ignore_errors=True)
