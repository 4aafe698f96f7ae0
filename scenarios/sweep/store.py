"""The point store (``DIR/points/<key>.json``, one atomic file per finished point), the
manifest and run log beside it, and the lock that keeps two sweeps out of one folder."""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

from arfem.io import atomic_write_text, write_json
from arfem.params import InputError
from arfem.scenarios.outdir import check_out_path, check_replaceable, lock_out_dir
from arfem.scenarios.sweep.points import STORE_VERSION

#: the report files a sweep writes into --out (its store, points/, sweep.json and
#: runs.jsonl, is checked above by its manifest)
SWEEP_WRITES = ("README.md", "results.csv", "summary.json", "report.html")

__all__ = ["PointStore", "record_header_problem", "open_store", "DirLock", "append_run_log", "read_runs",
           "record_problem", "PEAK_RANGE_UM"]

STORE_MANIFEST = "sweep.json"
_POINTS = "points"
_RUNS_LOG = "runs.jsonl"

#: A growth peak outside this range [µm] is not a rod's (a picometre's thousandth to a
#: kilometre): a stored point claiming one is corrupt and recomputed.
PEAK_RANGE_UM = (1e-9, 1e9)
#: Relative tolerance of the identities between stored metrics (each is written from the
#: same float64 numbers; a corrupted value breaks them by far more).
_REL = 1e-9

# (metric, lowest, lowest allowed itself?) of the metrics every stored point must hold;
# the upper bound of every one is "finite"
_REQUIRED = (("dtau_s", 0.0, False), ("h_W_m2K", 0.0, False), ("q_W_m2", 0.0, True),
             ("biot", 0.0, False), ("C1", 0.0, False), ("C1_fitted", -math.inf, False),
             ("corrected_C1", 0.0, False),
             ("fem_peak_um", PEAK_RANGE_UM[0], True), ("ar_peak_um", PEAK_RANGE_UM[0], True),
             ("fem_peak_time_h", 0.0, True),
             ("max_abs_diff_um", 0.0, True), ("max_abs_diff_pct_of_peak", 0.0, True),
             ("rmse_um", 0.0, True), ("corrected_max_abs_diff_um", 0.0, True),
             ("corrected_max_abs_diff_pct_of_peak", 0.0, True),
             ("corrected_rmse_um", 0.0, True), ("fem_dofs", 1, True), ("n_samples", 1, True))
# metrics that may be absent or null (non-finite values are stored as null), else numbers
_OPTIONAL = ("C2_um", "C2_fitted_um", "corrected_C2_um", "ar_corrected_peak_um",
             "C2_fitted_um_at_q0", "corrected_peak_diff_pct", "fem_wall_s", "wall_s")


def _num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def record_header_problem(rec, key: str, inputs=None) -> str | None:
    """What is wrong with a stored point's envelope (object, key, store version,
    inputs, a ``metrics`` object), or None: the checks every sweep's store makes
    before its own metrics' (:func:`record_problem`, the mesh sweep's)."""
    if not isinstance(rec, dict):
        return "not a JSON object"
    if rec.get("key") != key:
        return f"key is {rec.get('key')!r}, not the file's name"
    if rec.get("store_version") != STORE_VERSION or isinstance(rec.get("store_version"), bool):
        return f"store_version is {rec.get('store_version')!r}, not {STORE_VERSION}"
    if inputs is not None and rec.get("inputs") != inputs:
        return "inputs are not this point's"
    if not isinstance(rec.get("metrics"), dict):
        return "metrics is not a JSON object"
    return None


def record_problem(rec, key: str, inputs: dict | None = None) -> str | None:
    """Why a stored point record cannot be trusted, or None if it can.

    Checked: the layout (an object with this ``key``, the store version, an object of
    metrics), the point's inputs (``inputs``: the sweep's, when given), every metric the
    tables and thresholds read is a finite number (not a string, not a boolean) in its
    physical range (Δτ, h, Biot > 0; 0 < C1 < 1; peaks in :data:`PEAK_RANGE_UM`; errors
    and counts >= 0), and the identities between them (the % errors are
    100·error/peak; an RMS is at most the max; the AR peak is within the max error of
    the FEM peak), so that a corrupted value (a negative error, a peak of 1e-320) is
    caught, not only a malformed one.

    Examples
    --------
    >>> record_problem({"key": "k"}, "k")
    'store_version is None, not 2'
    """
    why = record_header_problem(rec, key, inputs)
    if why:
        return why
    m = rec["metrics"]
    for name, low, closed in _REQUIRED:
        v = m.get(name)
        if not _num(v) or v < low or (v == low and not closed):
            return f"metrics.{name} is {v!r}"
    if not m["C1"] < 1.0 or not m["corrected_C1"] < 1.0:
        return f"metrics.C1 is {m['C1']!r} (must be < 1)"
    for name in ("fem_peak_um", "ar_peak_um"):
        if m[name] > PEAK_RANGE_UM[1]:
            return f"metrics.{name} is {m[name]!r}"
    for name in _OPTIONAL:
        if m.get(name) is not None and not _num(m[name]):
            return f"metrics.{name} is {m[name]!r}"
    peak = m["fem_peak_um"]
    for pre in ("", "corrected_"):
        err, pct, rms = (m[f"{pre}max_abs_diff_um"], m[f"{pre}max_abs_diff_pct_of_peak"],
                         m[f"{pre}rmse_um"])
        if not math.isclose(pct, 100.0 * err / peak, rel_tol=_REL, abs_tol=1e-300):
            return (f"metrics.{pre}max_abs_diff_pct_of_peak ({pct!r}) is not "
                    f"100·{pre}max_abs_diff_um/fem_peak_um")
        if rms > err * (1 + _REL):
            return f"metrics.{pre}rmse_um ({rms!r}) exceeds {pre}max_abs_diff_um"
    if abs(m["ar_peak_um"] - peak) > m["max_abs_diff_um"] * (1 + _REL) + 1e-12 * peak:
        return "metrics.ar_peak_um differs from fem_peak_um by more than max_abs_diff_um"
    rt = rec.get("run_time_s")
    if rt is not None and (not _num(rt) or rt < 0):
        return f"run_time_s is {rt!r}"
    return None


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

    def get(self, key: str, inputs: dict | None = None) -> dict | None:
        """The stored record of ``key``, or None (absent, unreadable or not valid:
        :func:`record_problem` → recompute)."""
        return self.check(key, inputs)[0]

    def check(self, key: str, inputs: dict | None = None) -> tuple[dict | None, str | None]:
        """(record, None) for a valid stored point; (None, why) for a file that cannot
        be trusted; (None, None) when there is no file."""
        try:
            text = self.path(key).read_text("utf-8")
        except FileNotFoundError:
            return None, None
        except (OSError, UnicodeDecodeError) as exc:
            return None, f"cannot be read ({getattr(exc, 'strerror', None) or exc})"
        try:
            rec = json.loads(text, parse_constant=lambda t: float(t))
        except (ValueError, RecursionError):
            return None, "is not JSON"
        why = self.problem(rec, key, inputs)
        return (None, why) if why else (rec, None)

    def problem(self, rec, key: str, inputs: dict | None = None) -> str | None:
        """What makes a parsed stored point untrustworthy, or None (:func:`record_problem`;
        a store of another kind of point overrides this, not :meth:`check`)."""
        return record_problem(rec, key, inputs)

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
