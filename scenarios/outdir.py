"""Output directories for every ``arfem`` command: refuse an ``--out`` that cannot be
written before any work, stage a whole result set, then switch it into place all or
nothing, and never replace a file that arfem did not write.

The rules (they hold for ``run``, ``reproduce``, ``sweep``, ``diagnose``, ``allocate``):

* **Ownership.** Every result set moved into ``--out`` also updates ``--out``'s
  ownership manifest :data:`OWNERSHIP_MANIFEST` (``.arfem-outputs.json``: the SHA-256
  of each file arfem wrote there). A file that exists in ``--out`` and is not in that
  manifest was not written by arfem and is never replaced, ``--force`` or not.
  ``--force`` only lets arfem replace its own files (also when changed since).
* **Inputs.** A file read as an input of the same run (every file read through
  :func:`arfem.io.read_text_utf8`, plus any the caller names) is never replaced.
* **All or nothing.** A new ``--out`` appears by one ``rename`` of the staged
  directory. In an existing ``--out`` the files are switched one by one under a journal
  written before the first rename; the switch commits by one more rename of that
  journal. A run killed at any point (kill -9, power cut after the journal is on disk)
  is rolled back to the old files by the next arfem command that uses the same
  ``--out`` (:func:`recover_out_dir`), so ``--out`` is always the old or the new set.
* **Liveness by lock, not by PID.** Each staging directory holds a lock file locked
  (``fcntl.flock``) for the run's whole life; a staging directory whose lock can be
  taken belongs to a dead run (in any PID namespace) and is recovered or removed.
* **One writer at a time.** The switch into an existing ``--out`` holds an exclusive
  ``flock`` on the directory itself (:func:`lock_out_dir`; no lock file is left, and the
  OS drops it on kill -9), so two commands finishing at once switch one after the
  other instead of interleaving their files and manifests; the later one waits, saying
  so. ``arfem sweep`` holds the same lock for its whole run.
"""
from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

from arfem import io as _io
from arfem.params import InputError

__all__ = ["check_out_path", "prepare_out_dir", "staged_out_dir", "check_replaceable",
           "recover_out_dir", "owned_files", "adopt_outputs", "lock_out_dir",
           "arfem_wrote", "replace_owned_file",
           "OWNERSHIP_MANIFEST", "final_out_dir"]

#: The ownership manifest arfem keeps in every ``--out`` it writes: {file: sha256}.
OWNERSHIP_MANIFEST = ".arfem-outputs.json"
_STAGE = ".arfem-staging-"          # staging directories (inside --out, or beside a new one)
_LOCK, _JOURNAL, _COMMITTED, _NEW, _OLD = "lock", "journal.json", "committed.json", "new", "old"
#: A staging directory without its lock file is a run killed between mkdir and lock
#: (microseconds); it is removed once it is older than this [s].
_UNLOCKED_GRACE_S = 60.0
#: Older arfem (before the ownership manifest): ``arfem reproduce``'s MANIFEST.json.
_LEGACY_MANIFEST = "MANIFEST.json"


def _rename(src, dst) -> None:
    """The one rename primitive of the switch (tests inject kills here)."""
    os.replace(src, dst)


def _oserror(e: OSError, where) -> InputError:
    return InputError(f"cannot be written ({e.strerror or e})", str(where))


def _name_max(d: Path) -> int:
    try:
        return os.pathconf(d, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def _sibling_prefix(out: Path) -> str:
    """Prefix of staging directories beside a new ``out``: fixed length, whatever the
    length of ``out``'s name (a 250-character name still fits)."""
    return f"{_STAGE}{hashlib.sha1(os.fsencode(out.name)).hexdigest()[:12]}-"


def check_out_path(out: str | os.PathLike) -> Path:
    """Refuse an output path that cannot become a writable directory; recover a switch
    interrupted in it (see :func:`recover_out_dir`). Creates nothing.

    Catches, before any work is done: an existing file or a broken symbolic link at
    ``out``, a file where one of its parent directories should be, a name longer than
    the file system allows, a directory that cannot be read or written, and the same
    for the staging directory arfem will create.
    """
    p = Path(out)
    limit = _name_max(Path(p.anchor or "."))
    for part in p.parts:
        if len(os.fsencode(part)) > limit:
            raise InputError(f"a name in it is {len(os.fsencode(part))} bytes long; the "
                             f"file system allows at most {limit}", _short(p))
    try:
        if p.is_symlink() and not p.exists():
            raise InputError("is a broken symbolic link", str(p))
        if p.exists() and not p.is_dir():
            raise InputError("exists and is not a directory", str(p))
        anc = p.parent                        # Path("out").parent is Path(".")
        while not anc.exists() and anc != anc.parent:
            anc = anc.parent
        if not anc.is_dir():
            raise InputError(f"cannot be created: {anc} is not a directory", str(p))
        if p.is_dir() or p.parent.is_dir():
            recover_out_dir(p)
        probe = [(p, _STAGE)] if p.is_dir() else [(anc, _sibling_prefix(p))]
        for d, prefix in probe:
            tempfile.TemporaryDirectory(prefix=prefix, dir=d).cleanup()
    except InputError:
        raise
    except OSError as e:
        raise InputError(f"cannot be used ({e.strerror or e})", _short(p)) from None
    return p


def _short(p) -> str:
    s = str(p)
    return s if len(s) <= 120 else s[:60] + "…" + s[-40:]


def prepare_out_dir(out: str | os.PathLike, force: bool = False, inputs=(),
                    writes=()) -> Path:
    """Check ``out`` may be written: absent, empty, or ``force``. Creates nothing.

    ``writes`` (names relative to ``out`` that the command will write, as far as it
    knows them before the work) and ``inputs`` (paths the command reads) let the
    ownership and input rules refuse at once instead of after the work; the full check
    is repeated on the actual files when they are moved (:func:`staged_out_dir`).
    """
    p = check_out_path(out)
    if p.is_dir() and not force and _user_entries(p):
        raise InputError("is not empty; choose another --out or pass --force to replace "
                         "the files arfem wrote there", str(p))
    check_replaceable(p, writes, inputs, force)
    return p


def _user_entries(out: Path) -> list[str]:
    try:
        return [e.name for e in out.iterdir()
                if not e.name.startswith(_STAGE) and e.name != OWNERSHIP_MANIFEST]
    except OSError as e:
        raise InputError(f"cannot be read ({e.strerror or e})", str(out)) from None


def owned_files(out: str | os.PathLike) -> dict:
    """{relative posix path: sha256 or None} of the files arfem wrote into ``out``.

    Read from ``out``'s ownership manifest; an older ``arfem reproduce`` result (its
    ``MANIFEST.json``) counts too. Unreadable or foreign manifests own nothing.
    """
    out = Path(out)
    own: dict = {}
    for name in (_LEGACY_MANIFEST, OWNERSHIP_MANIFEST):
        try:
            with open(out / name, encoding="utf-8") as fh:   # not an input: not via arfem.io
                man = json.load(fh)
        except (OSError, ValueError):
            continue
        if not isinstance(man, dict):
            continue
        if name == _LEGACY_MANIFEST and man.get("generator") != "arfem reproduce":
            continue
        files = man.get("files")
        if isinstance(files, dict):
            own.update({str(k): (v if isinstance(v, str) else None) for k, v in files.items()})
        elif isinstance(files, list) and name == _LEGACY_MANIFEST:
            own.update({str(k): None for k in files})
        if name == _LEGACY_MANIFEST and isinstance(man.get("not_committed"), list):
            own.update({str(k): None for k in man["not_committed"]})   # reproduce's fields/
        own[name] = None
    return own


def _inputs_set(inputs) -> set:
    """(st_dev, st_ino) of every input: the caller's and every file arfem read."""
    ids = set()
    for f in list(inputs) + list(_io.files_read()):
        with contextlib.suppress(OSError):
            st = os.stat(f)
            ids.add((st.st_dev, st.st_ino))
    return ids


def _refusal(rel: str, dst: Path, own: dict, force: bool, inputs: set,
             out) -> InputError | None:
    """Why the existing ``dst`` may not be replaced, or None if it may."""
    with contextlib.suppress(OSError):
        st = os.stat(dst)
        if (st.st_dev, st.st_ino) in inputs:
            return InputError(f"{rel} is an input of this run; arfem never writes over "
                              "its inputs, --force or not: choose another --out", str(out))
    if rel in own:
        if force or own[rel] is None:
            return None
        with contextlib.suppress(OSError):
            if _io.sha256_file(dst) == own[rel]:
                return None
    if rel in own:
        return InputError(f"{rel} was changed since arfem wrote it; pass --force to "
                          "replace it", str(out))
    return InputError(f"{rel} was not written by arfem (it is not in {OWNERSHIP_MANIFEST}); "
                      "arfem never replaces such a file, --force or not: move it away or "
                      "choose another --out", str(out))


def check_replaceable(out: str | os.PathLike, names, inputs=(), force: bool = True) -> None:
    """Refuse (InputError) if writing ``names`` (relative to ``out``) would replace an
    input or a file arfem did not write; nothing is changed. Call it before the work
    with the names a command will write (e.g. a sweep's ``README.md``)."""
    out = Path(out)
    names = [str(n) for n in names]
    if not names or not out.is_dir():
        return
    own, ids = owned_files(out), _inputs_set(inputs)
    for rel in names:
        dst = out / rel
        if dst.is_dir() and not dst.is_symlink():
            raise InputError(f"{rel} is a directory here, where arfem writes a file; "
                             "move it away", str(out))
        if dst.is_file() or dst.is_symlink():
            why = _refusal(Path(rel).as_posix(), dst, own, force, ids, out)
            if why is not None:
                raise why


def adopt_outputs(out: str | os.PathLike, names) -> None:
    """Record existing files of ``out`` (relative ``names``) as arfem's in its ownership
    manifest, e.g. results written by an arfem older than the manifest. Only for files
    you know arfem wrote: from then on ``--force`` may replace them."""
    out = Path(out)
    own = {k: v for k, v in owned_files(out).items() if k != OWNERSHIP_MANIFEST}
    for rel in names:
        f = out / rel
        if not f.is_file():
            raise InputError("is not a file", str(f))
        own[Path(rel).as_posix()] = _io.sha256_file(f)
    _io.atomic_write_text(out / OWNERSHIP_MANIFEST, _manifest_text(own))


def _manifest_text(files: dict) -> str:
    return _io.json_text({"generator": "arfem", "note": "files arfem wrote here (SHA-256); "
                          "arfem replaces no other file", "files": dict(sorted(files.items()))},
                         indent=2) + "\n"


# -- recovery ------------------------------------------------------------------------

def _try_lock(txn: Path):
    """An open, exclusively locked fd of ``txn``'s lock file, or None if a live run holds
    it. A lock file that does not exist yields None unless the directory is old."""
    try:
        fd = os.open(txn / _LOCK, os.O_RDWR)
    except FileNotFoundError:
        with contextlib.suppress(OSError):
            if time.time() - txn.stat().st_mtime > _UNLOCKED_GRACE_S:
                return os.open(txn, os.O_RDONLY)      # nothing to lock: stale
        return None
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def _rollback(txn: Path, out: Path) -> None:
    """Undo an uncommitted switch of ``txn`` into ``out`` (see :func:`_switch`)."""
    with open(txn / _JOURNAL, encoding="utf-8") as fh:
        j = json.load(fh)
    new, old = txn / _NEW, txn / _OLD
    for rel, had_old in reversed(j["files"]):
        dst, bak, src = out / rel, old / rel, new / rel
        if bak.exists() or bak.is_symlink():
            _rename(bak, dst)                              # the old file back
        elif not had_old and not (src.exists() or src.is_symlink()):
            with contextlib.suppress(FileNotFoundError):   # the new file had been moved in
                dst.unlink()
    for rel in reversed(j["dirs"]):
        with contextlib.suppress(OSError):
            (out / rel).rmdir()


def recover_out_dir(out: str | os.PathLike, _skip=None) -> list[str]:
    """Finish what a killed arfem run left in ``out``; returns what was done.

    A committed switch has its backups deleted; an uncommitted one is rolled back (each
    old file renamed back, each new one removed), so ``out`` holds the old result set;
    a staging directory of a run killed while computing is removed. Directories of
    live runs (their lock is held) are left alone.
    """
    out = Path(out)
    done: list[str] = []
    cands = []
    if out.is_dir():
        cands += [(d, out) for d in out.glob(_STAGE + "*") if d.is_dir() and d != _skip]
    if out.parent.is_dir():
        mine = _sibling_prefix(out)
        # beside out: this out's staging directories (their switch, if any, went into
        # out), and any other staging directory of a killed run there (of another --out
        # in the same folder, or of the folder itself): removed when dead and holding no
        # switch journal, i.e. nothing of it was ever moved anywhere
        cands += [(d, out if d.name.startswith(mine) else None)
                  for d in out.parent.glob(_STAGE + "*") if d.is_dir() and d != _skip]
    if not cands:
        return done
    for txn, target in cands:      # each one's own lock: one recoverer, never a live run
        fd = _try_lock(txn)
        if fd is None:
            continue
        try:
            journal = (txn / _JOURNAL).exists() and not (txn / _COMMITTED).exists()
            if journal and target is None:
                continue               # another folder's switch: recovered from there
            if journal:
                _rollback(txn, target)
                done.append(f"rolled back an interrupted switch into {target}")
            else:
                done.append(f"removed {txn.name}")
            shutil.rmtree(txn, ignore_errors=True)
        finally:
            os.close(fd)
    return done


def arfem_wrote(out: str | os.PathLike) -> bool:
    """True when ``out``'s ownership manifest (or an older ``arfem reproduce``
    ``MANIFEST.json``) shows that arfem wrote this folder: it is arfem's and lists at
    least one file that is there."""
    out = Path(out)
    own = owned_files(out)
    return any((out / rel).is_file() for rel in own
               if rel not in (OWNERSHIP_MANIFEST, _LEGACY_MANIFEST))


def replace_owned_file(out: str | os.PathLike, rel: str, write, force: bool = False,
                       who: str = "arfem report") -> Path:
    """Write ``out/rel`` (by ``write(path)``, which must write it atomically) into a
    folder arfem wrote, and record its SHA-256 in the ownership manifest.

    Refused (:class:`InputError`, nothing written): ``out`` is not a directory; its
    manifest does not show arfem wrote it (:func:`arfem_wrote`); ``out/rel`` exists and
    is not arfem's (not in the manifest), is a directory, or (without ``force``) was
    changed since arfem wrote it; another arfem command is writing there (its lock is
    held: a running sweep). A run killed there before is recovered first
    (:func:`recover_out_dir`). The manifest lists ``rel`` before the file is replaced
    and with the new file's hash after, so a kill at any instant leaves the file
    arfem's in the manifest (the next command may replace it; a resumed sweep does).
    """
    out = Path(out)
    if not out.is_dir():
        raise InputError("is not a directory", str(out))
    rel = Path(rel).as_posix()
    with lock_out_dir(out, wait=False, who="arfem command"):
        recover_out_dir(out)
        if not arfem_wrote(out):
            raise InputError(f"arfem did not write this folder (no {OWNERSHIP_MANIFEST} "
                             f"listing its files); {who} writes only into a folder arfem "
                             "wrote, and never replaces a file arfem did not write",
                             str(out))
        check_replaceable(out, [rel], force=force)
        own = {k: v for k, v in owned_files(out).items() if k != OWNERSHIP_MANIFEST}
        dst = out / rel
        if dst.exists() or dst.is_symlink() or rel not in own:
            own[rel] = None          # arfem's from now on, whatever a kill leaves there
            _io.atomic_write_text(out / OWNERSHIP_MANIFEST, _manifest_text(own))
        write(dst)
        own[rel] = _io.sha256_file(dst)
        _io.atomic_write_text(out / OWNERSHIP_MANIFEST, _manifest_text(own))
    return dst


# -- staging and the switch ----------------------------------------------------------

@contextlib.contextmanager
def lock_out_dir(out: str | os.PathLike, wait: bool = True, who: str = "arfem command"):
    """Hold an exclusive advisory lock (``flock``) on the directory ``out`` itself.

    No lock file is written and the OS releases the lock when the process dies, kill -9
    included. With ``wait`` a busy directory is waited for (one line on stderr says
    so); without, it is one :class:`InputError`. The lock is per open directory, so a
    process must not take it twice on the same ``out`` (it would wait for itself):
    a caller that already holds it passes ``out_locked=True`` to :func:`staged_out_dir`.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if not wait:
                raise InputError(f"another {who} is writing to this directory; wait for it "
                                 "to finish", str(out)) from None
            print(f"arfem: note: {_short(out)}: another arfem command is writing there; "
                  "waiting for it to finish", file=sys.stderr, flush=True)
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield out
    finally:
        os.close(fd)                                 # releases the lock


@contextlib.contextmanager
def staged_out_dir(out: str | os.PathLike, force: bool = False, update: bool = False,
                   inputs=(), out_locked: bool = False):
    """Write a whole result set into a staging directory, then switch it into ``out``.

    Yields the staging directory. On success each staged file replaces its namesake
    in ``out`` (other files already in ``out`` are left alone) and ``out``'s ownership
    manifest records the SHA-256 of every file arfem wrote. Refused before the first
    rename (``out`` unchanged): a clash (a directory where a file goes, or the reverse),
    replacing an input (``inputs`` or any file arfem read in this process), replacing a
    file arfem did not write (``--force`` or not), or, without ``force``, one changed
    since arfem wrote it, or any file at all in an ``out`` that was absent or empty when
    the command started (another command wrote there meanwhile). The switch is all or
    nothing, also across a kill -9 (the next run rolls it back), and holds
    :func:`lock_out_dir` on an existing ``out`` (``out_locked``: the caller holds it
    already, as ``arfem sweep`` does). On any error ``out`` is as it was and the staging
    directory is removed; an error writing into the stage (e.g. disk full) is one
    :class:`InputError`.

    ``update``: ``out`` may hold this command's earlier results, so it may be non-empty
    without ``force``; the rules above still hold (only arfem's own files, unchanged
    since, are replaced; never an input).
    """
    out = prepare_out_dir(out, force or update)
    inside = out.is_dir()
    try:
        if inside:
            txn = Path(tempfile.mkdtemp(prefix=_STAGE, dir=out))
        else:
            out.parent.mkdir(parents=True, exist_ok=True)
            txn = Path(tempfile.mkdtemp(prefix=_sibling_prefix(out), dir=out.parent))
        lock = os.open(txn / _LOCK, os.O_RDWR | os.O_CREAT, 0o600)
        fcntl.flock(lock, fcntl.LOCK_EX)
        stage = txn / _NEW
        stage.mkdir()
    except OSError as e:
        raise _oserror(e, out) from None
    try:
        try:
            yield stage
        except OSError as e:                       # disk full, quota, ... while writing
            if e.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS,
                           errno.EACCES, errno.EPERM, errno.ENAMETOOLONG, errno.EIO):
                raise InputError(f"cannot write the results ({e.strerror or e}); left as "
                                 "it was", str(out)) from None
            raise
        try:
            _switch(txn, out, force, inputs, out_locked, nonempty_ok=force or update)
        except InputError:
            raise
        except OSError as e:
            raise InputError(f"cannot be written ({e.strerror or e}); left as it was",
                             str(out)) from None
    finally:
        if not (txn / _JOURNAL).exists():          # else a failed rollback: keep it
            shutil.rmtree(txn, ignore_errors=True)   # for the next run to recover
        os.close(lock)


def _write_manifest(stage: Path, out: Path, own: dict, files: list) -> None:
    """Stage the updated ownership manifest: old entries whose file is still there,
    plus every staged file with its SHA-256."""
    keep = {k: v for k, v in own.items() if k != OWNERSHIP_MANIFEST
            and ((out / k).is_file() or (out / k).is_symlink())}
    for src in files:
        keep[src.relative_to(stage).as_posix()] = _io.sha256_file(src)
    (stage / OWNERSHIP_MANIFEST).write_text(_manifest_text(keep), encoding="utf-8")


def _switch(txn: Path, out: Path, force: bool, inputs, out_locked: bool = False,
            nonempty_ok: bool = True) -> None:
    stage = txn / _NEW
    if (stage / OWNERSHIP_MANIFEST).exists():
        raise InputError(f"{OWNERSHIP_MANIFEST} is arfem's own bookkeeping file; a command "
                         "may not write it", str(out))
    entries = sorted(stage.rglob("*"))
    files = [s for s in entries if not s.is_dir()]
    if not out.is_dir():                                  # a new --out: one rename
        _write_manifest(stage, out, {}, files)
        try:
            _rename(stage, out)
            return
        except OSError as e:
            if e.errno not in (errno.ENOTEMPTY, errno.EEXIST) or not out.is_dir():
                raise
            # someone created out meanwhile: switch file by file below
            (stage / OWNERSHIP_MANIFEST).unlink()
    with (contextlib.nullcontext() if out_locked else lock_out_dir(out)):
        # checked again under the lock: a command that found --out absent or empty must
        # not fill it with its files after another one wrote there meanwhile
        if not nonempty_ok and _user_entries(out):
            raise InputError("is not empty: another command wrote there while this one "
                             "ran, and nothing of this run was moved in; choose another "
                             "--out or pass --force", str(out))
        _switch_into(txn, stage, out, force, inputs, entries, files)


def _switch_into(txn, stage, out, force, inputs, entries, files) -> None:
    """The file-by-file switch into an existing ``out`` (its lock held)."""
    recover_out_dir(out, _skip=txn)                   # killed runs, never live ones
    own, ids = owned_files(out), _inputs_set(inputs)
    for src in entries:                               # every refusal before any move
        rel = src.relative_to(stage)
        dst = out / rel
        if src.is_dir() and (dst.exists() or dst.is_symlink()) and not dst.is_dir():
            raise InputError(f"{rel} is a file here, where arfem writes a directory; "
                             "move it away", str(out))
        if not src.is_dir() and dst.is_dir():
            raise InputError(f"{rel} is a directory here, where arfem writes a file; "
                             "move it away", str(out))
        if not src.is_dir() and (dst.exists() or dst.is_symlink()):
            why = _refusal(rel.as_posix(), dst, own, force, ids, out)
            if why is not None:
                raise why
    _write_manifest(stage, out, own, files)
    files.append(stage / OWNERSHIP_MANIFEST)          # moved last
    dirs = [s.relative_to(stage).as_posix() for s in entries if s.is_dir()
            and not (out / s.relative_to(stage)).is_dir()]
    plan = [(s.relative_to(stage).as_posix(),
             (out / s.relative_to(stage)).exists()
             or (out / s.relative_to(stage)).is_symlink()) for s in files]
    _io.atomic_write_text(txn / _JOURNAL, json.dumps({"files": plan, "dirs": dirs}))
    old = txn / _OLD
    try:
        for rel in dirs:
            (out / rel).mkdir()
        for rel, had_old in plan:
            if had_old:
                (old / rel).parent.mkdir(parents=True, exist_ok=True)
                _rename(out / rel, old / rel)
            _rename(stage / rel, out / rel)
        _rename(txn / _JOURNAL, txn / _COMMITTED)     # the commit point
    except BaseException:
        _rollback(txn, out)           # if this fails too, the next run finishes it
        (txn / _JOURNAL).unlink()
        raise


def final_out_dir(root: Path) -> Path:
    """Where the folder ``root`` will be read: ``root`` itself, or, when it is a staging
    directory of :func:`staged_out_dir` (``<out>/.arfem-staging-.../new`` inside an
    existing ``--out``, ``<parent>/.arfem-staging-<hash>-.../new`` beside a new one), a
    folder at the depth of ``--out``, for links to files outside it (the HTML report's
    relative links, :mod:`arfem.scenarios.html_report`).

    >>> final_out_dir(Path("/a/out/.arfem-staging-k2j4_x9q/new")).as_posix()
    '/a/out'
    >>> final_out_dir(Path("/a/.arfem-staging-0123456789ab-k2j4_x9q/new")).parent.as_posix()
    '/a'
    """
    root = Path(root).resolve()
    txn = root.parent
    if root.name != _NEW or not txn.name.startswith(_STAGE):
        return root
    if re.match(re.escape(_STAGE) + r"[0-9a-f]{12}-", txn.name):   # beside a new --out
        return txn.parent / "out"
    return txn.parent
