"""The point store (``DIR/points/<key>.json``, one atomic file per finished point), the
manifest and run log beside it, and the lock that keeps two sweeps out of one folder."""
from __future__ import annotations

import json
import time
from pathlib import Path

from arfem.io import atomic_write_text, write_json
from arfem.params import InputError
from arfem.scenarios.outdir import check_out_path, check_replaceable, lock_out_dir

#: the report files a sweep writes into --out (its store, points/, sweep.json and
#: runs.jsonl, is checked above by its manifest)
SWEEP_WRITES = ("README.md", "results.csv", "summary.json", "report.html")

__all__ = ["PointStore", "open_store", "DirLock", "append_run_log", "read_runs"]

STORE_MANIFEST = "sweep.json"
_POINTS = "points"
_RUNS_LOG = "runs.jsonl"

class PointStore:
    """Finished points, one JSON file each, written atomically: ``DIR/points/<key>.json``.

    A file either exists complete or not at all (write to a temporary name, fsync,
    rename), so a sweep killed at any instant loses at most the points in flight.
    """

    def __init__(self, out: Path):
        self.dir = Path(out) / _POINTS

    def path(self, key: str) -> Path:
        return self.dir / f"{key}.json"

    def keys(self) -> set:
        if not self.dir.is_dir():
            return set()
        return {p.stem for p in self.dir.glob("*.json") if not p.name.startswith(".")}

    def get(self, key: str) -> dict | None:
        """The stored record of ``key``, or None (absent or unreadable → recompute)."""
        try:
            rec = json.loads(self.path(key).read_text("utf-8"))
        except (OSError, ValueError):
            return None
        if not isinstance(rec, dict) or rec.get("key") != key or "metrics" not in rec:
            return None
        return rec

    def put(self, record: dict) -> None:
        write_json(self.path(record["key"]), record)

    def remove_temporaries(self) -> int:
        """Delete half-written temporaries left by a killed run; return how many."""
        n = 0
        if self.dir.is_dir():
            for p in self.dir.glob(".*"):
                if p.is_file():
                    p.unlink(missing_ok=True)
                    n += 1
        for name in (STORE_MANIFEST, _RUNS_LOG):     # atomic writes beside the store
            for p in self.dir.parent.glob(f".{name}.*"):
                if p.is_file():
                    p.unlink(missing_ok=True)
                    n += 1
        return n


def open_store(out: Path, sweep, force: bool) -> str:
    """Check ``out`` for this sweep. Returns "new", "resume" or "force". Writes nothing.

    A directory holding the store of the same sweep is resumed; any other
    non-empty directory is refused unless ``force``.
    """
    check_out_path(out)
    if not out.is_dir() or not any(out.iterdir()):
        return "new"
    man = out / STORE_MANIFEST
    try:
        old = json.loads(man.read_text("utf-8"))
    except (OSError, ValueError):
        old = None
    if isinstance(old, dict) and old.get("sweep_id") == sweep.sweep_id:
        return "resume"
    if force:                 # --force never replaces a file arfem did not write: say so now
        check_replaceable(out, SWEEP_WRITES, force=True)
        return "force"
    if isinstance(old, dict):
        raise InputError(f"holds a different sweep ({old.get('name')!r}, "
                         f"{old.get('n_points')} points); choose another --out or pass "
                         "--force to run this one there (stored points with identical inputs "
                         "are reused)", str(out))
    raise InputError("is not empty and holds no sweep store; choose another --out or pass "
                     "--force", str(out))


class DirLock:
    """Exclusive advisory lock on the directory ``DIR`` itself for a sweep's whole run
    (:func:`arfem.scenarios.outdir.lock_out_dir`, not waiting): no lock file is left
    behind, and the OS releases it even on kill -9. A second sweep, or any other arfem
    command switching its results into ``DIR``, is kept out meanwhile."""

    def __init__(self, out: Path):
        self.dir = Path(out)
        self._cm = None

    def __enter__(self):
        self._cm = lock_out_dir(self.dir, wait=False, who="arfem command (a sweep?)")
        self._cm.__enter__()
        legacy = self.dir / ".lock"          # the lock file of arfem <= 0.1.0 (issue 16)
        if legacy.is_file() and legacy.stat().st_size == 0:
            legacy.unlink(missing_ok=True)
        return self

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)


def read_runs(out: Path) -> list[dict]:
    """The runs recorded in ``DIR/runs.jsonl``, oldest first (unreadable lines skipped)."""
    try:
        text = (Path(out) / _RUNS_LOG).read_text("utf-8")
    except (OSError, UnicodeDecodeError):
        return []
    runs = []
    for ln in text.splitlines():
        try:
            r = json.loads(ln)
        except ValueError:
            continue
        if isinstance(r, dict):
            runs.append(r)
    return runs


def append_run_log(out: Path, rep) -> list[dict]:
    """Add this run to ``DIR/runs.jsonl`` (rewritten atomically: never half a line);
    return every run recorded, this one last."""
    runs = read_runs(out) + [{
        "run_id": rep.run_id, "mode": rep.mode, "executor": rep.executor,
        "n_points": rep.n_points, "n_stored_before": rep.n_stored_before,
        "n_computed": rep.n_computed, "n_failed": rep.n_failed,
        "wall_s": round(rep.wall_s, 3),
        "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}]
    atomic_write_text(Path(out) / _RUNS_LOG,
                      "".join(json.dumps(r, ensure_ascii=False) + "\n" for r in runs))
    return runs
