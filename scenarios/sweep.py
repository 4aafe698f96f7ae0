"""``arfem sweep``: one scenario evaluated over a grid of inputs, resumable, local or Dask.

A sweep file names a base scenario and the values to vary::

    [sweep]
    name = "dtau_h"
    base = "paper_fig2"            # a built-in scenario, or a path relative to this file
    description = "..."            # optional
    [sweep.grid]                   # full Cartesian product, in this key order
    dtau_s = [10, 30, 60]          # aliases: dtau_s, h_W_m2K, q_W_m2
    h_W_m2K = [5, 10, 55]
    q_W_m2 = [2000, 3000]
    "fem.mesh.nz" = [16, 32]       # any other scenario key, by its dotted path

Data flow: sweep file → :class:`Sweep` (every point resolved to a full scenario
dict and validated *before* anything is computed or written) → points evaluated
by :func:`evaluate_point` (worker processes, or a Dask cluster) → each finished
point stored at once in ``DIR/points/<key>.json`` (atomic write, fsync) →
``results.csv``, plots, ``summary.json`` and ``README.md`` written from the store.

On a Dask cluster (``--scheduler tcp://host:8786``) every worker must be able to
import arfem (``pip install -e .`` on each worker machine, or workers started in
the repository with it on ``PYTHONPATH``); the results are identical to a local
run (both use single-threaded BLAS, floats are stored with ``repr``).

The key of a point is the SHA-256 of the canonical JSON of its fully resolved
inputs (validated rod, cycle segments, Δτ, FEM settings; plus a store-format
version), so a sweep that was interrupted
(Ctrl-C, kill -9) and started again with the same ``--out`` computes only the
points that are missing: none lost, none computed twice.
"""
from __future__ import annotations

import argparse
import copy
import fcntl
import hashlib
import itertools
import json
import math
import os
import socket
import sys
import threading
import time
import uuid
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np

from arfem.params import InputError, check_finite
from arfem.scenarios.config import (ALIASES, apply_override, builtin_scenario_path,
                              scenario_from_dict)
from arfem.io import atomic_write_text, read_toml, write_json
from arfem.scenarios.outdir import check_out_path, staged_out_dir

__all__ = ["Sweep", "Point", "PointStore", "load_sweep", "sweep_from_dict", "point_key",
           "resolved_inputs",
           "evaluate_point", "run_sweep", "results_rows", "biot_threshold",
           "add_parser", "main", "STORE_VERSION", "METRIC_COLUMNS"]

#: Bumped when the stored record or the meaning of a metric changes; part of every key.
STORE_VERSION = 2   # 2: per-level metrics named *_by_q_W_m2

#: Column name of a grid key (the three usual inputs keep their short names).
_COLUMN = {"ar.dtau_s": "dtau_s", "rod.convection_W_m2K": "h_W_m2K", "cycle.q_W_m2": "q_W_m2"}
#: Input columns always present in ``results.csv`` (taken from the point's metrics if not swept).
CORE_INPUTS = ("dtau_s", "h_W_m2K", "q_W_m2")

#: Output columns of ``results.csv``, in order (units in the names; pct = % of FEM peak).
METRIC_COLUMNS = (
    "biot", "C1", "C2_um", "C1_fitted", "C2_fitted_um", "corrected_C1", "corrected_C2_um",
    "fem_peak_um", "fem_peak_time_h", "ar_peak_um",
    "max_abs_diff_um", "max_abs_diff_pct_of_peak", "rmse_um", "rmse_pct_of_peak",
    "corrected_max_abs_diff_um", "corrected_max_abs_diff_pct_of_peak",
    "corrected_rmse_um", "corrected_rmse_pct_of_peak",
    "fem_dofs", "n_samples", "run_time_s",
)
#: Columns that depend on the machine, not on the inputs (left out of reproducibility checks).
TIMING_COLUMNS = ("run_time_s",)

_SWEEP_KEYS = {"name", "base", "description", "grid"}
_STORE_MANIFEST = "sweep.json"
_POINTS = "points"
_RUNS_LOG = "runs.jsonl"
#: Files of ours allowed in a store directory that is resumed.
_OUR_FILES = {_STORE_MANIFEST, _POINTS, _RUNS_LOG, "results.csv", "summary.json", "README.md",
              ".lock"}


# -- the sweep definition ---------------------------------------------------------------

@dataclass(frozen=True)
class Point:
    """One grid point: its inputs (column → value), full scenario dict and key."""

    index: int
    inputs: dict
    data: dict = field(repr=False)
    key: str = ""


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: base scenario, grid and every resolved point."""

    name: str
    description: str
    source: str
    base: str
    grid: dict               # column name -> list of values, in file order
    paths: dict              # column name -> dotted scenario path (or alias) it sets
    points: tuple

    @property
    def sweep_id(self) -> str:
        """SHA-256 of the name and the ordered point keys: equal iff the same sweep."""
        return _sha256({"name": self.name, "points": [p.key for p in self.points]})

    def manifest(self) -> dict:
        return {"store_version": STORE_VERSION, "sweep_id": self.sweep_id, "name": self.name,
                "description": self.description, "source": self.source, "base": self.base,
                "grid": self.grid, "n_points": len(self.points)}


def _canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False)


def _sha256(obj) -> str:
    return hashlib.sha256(_canonical(obj).encode("ascii")).hexdigest()


def point_key(data: dict) -> str:
    """Key of a point: SHA-256 of its fully resolved inputs, canonical JSON.

    Numbers are normalised (``30`` and ``30.0`` give the same key) and the
    store format version is part of the hash.

    Parameters
    ----------
    data : dict
        Resolved inputs (:func:`resolved_inputs`), or any JSON-like dict.

    Returns
    -------
    str
        64 hex digits.

    Examples
    --------
    >>> point_key({"ar": {"dtau_s": 30}}) == point_key({"ar": {"dtau_s": 30.0}})
    True
    >>> point_key({"ar": {"dtau_s": 30}}) == point_key({"ar": {"dtau_s": 60}})
    False
    """
    return _sha256({"store_version": STORE_VERSION, "scenario": _normalise(data)})


def resolved_inputs(scenario) -> dict:
    """Everything a point's results depend on, with defaults filled in.

    The validated rod (every field), the cycle as segments (durations, q, ambient,
    h), Δτ and the FEM settings. Names, descriptions and output options are left
    out: they do not change a number in ``results.csv``.

    Examples
    --------
    >>> from arfem.scenarios.config import scenario_from_dict
    >>> cyc = {"phases": [{"duration_h": 1.0, "q_W_m2": 2000.0}]}
    >>> a = scenario_from_dict({"cycle": cyc, "scenario": {"name": "a"}})
    >>> b = scenario_from_dict({"cycle": cyc, "rod": {"radius_m": 0.1}, "ar": {"dtau_s": 30}})
    >>> point_key(resolved_inputs(a)) == point_key(resolved_inputs(b))
    True
    """
    from dataclasses import asdict, fields as dc_fields
    sch = scenario.schedule
    arr = lambda a: None if a is None else [float(x) for x in np.asarray(a)]
    return {
        "rod": {f.name: getattr(scenario.rod, f.name) for f in dc_fields(scenario.rod)},
        "schedule": {"durations_s": arr(sch.durations_s), "q_W_m2": arr(sch.q_W_m2),
                     "ambient_C": arr(sch.ambient_C), "h_W_m2K": arr(sch.h_W_m2K)},
        "dtau_s": scenario.dtau_s,
        "fem": asdict(scenario.fem),
    }


def _normalise(o):
    if isinstance(o, dict):
        return {str(k): _normalise(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_normalise(v) for v in o]
    if isinstance(o, bool) or o is None or isinstance(o, str):
        return o
    if isinstance(o, (int, float, np.integer, np.floating)):
        return check_finite(None, o)
    if hasattr(o, "isoformat"):          # TOML dates and times
        return o.isoformat()
    return str(o)


def _resolve_base(base: str, sweep_path: Path) -> tuple[Path, str]:
    """A path relative to the sweep file, or a built-in scenario name."""
    p = Path(base)
    cand = p if p.is_absolute() else sweep_path.parent / p
    if cand.is_file():
        return cand, str(cand)
    if p.suffix in ("", ".toml") and len(p.parts) == 1:
        try:
            b = builtin_scenario_path(p.name)
            return b, p.stem
        except InputError:
            pass
    raise InputError(f"no scenario file {str(cand)!r} and no built-in scenario {base!r}",
                     "sweep.base")


def load_sweep(path) -> Sweep:
    """Read and validate a sweep file; every point is resolved and checked up front.

    Errors are one line naming the file, the key (``sweep.grid.dtau_s[2]``) and what
    is wrong, e.g. a Δτ that does not divide the phases.
    """
    p = Path(path)
    data = read_toml(p)
    return sweep_from_dict(data, str(p))


def sweep_from_dict(data: dict, source: str = "<sweep>", base_data: dict | None = None) -> Sweep:
    """Validate a sweep given as a dict (as read from TOML).

    ``base_data`` may be given to use a scenario dict instead of reading
    ``sweep.base`` (tests, programmatic sweeps).
    """
    try:
        return _sweep_from_dict(data, source, base_data)
    except InputError as exc:
        if exc.where and exc.where.startswith(source):
            raise
        raise exc.at(source) from None


def _sweep_from_dict(data: dict, source: str, base_data: dict | None) -> Sweep:
    if not isinstance(data, dict) or set(data) != {"sweep"}:
        extra = sorted(set(data) - {"sweep"}) if isinstance(data, dict) else []
        raise InputError(f"unknown top-level key {extra[0]!r}; a sweep file holds one [sweep] "
                         "table" if extra else "needs a [sweep] table", extra[0] if extra else None)
    sw = data["sweep"]
    if not isinstance(sw, dict):
        raise InputError("must be a table", "sweep")
    for k in sw:
        if k not in _SWEEP_KEYS:
            raise InputError(f"unknown key (allowed: {', '.join(sorted(_SWEEP_KEYS))})",
                             f"sweep.{k}")
    name = sw.get("name", Path(source).stem)
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"must be a non-empty string, got {name!r}", "sweep.name")
    description = sw.get("description", "")
    if not isinstance(description, str):
        raise InputError(f"must be a string, got {description!r}", "sweep.description")
    if base_data is None:
        if "base" not in sw:
            raise InputError("missing: name the base scenario (a built-in such as "
                             "'paper_fig2', or a .toml path relative to the sweep file)",
                             "sweep.base")
        if not isinstance(sw["base"], str):
            raise InputError(f"must be a string, got {sw['base']!r}", "sweep.base")
        base_path, base_name = _resolve_base(sw["base"], Path(source))
        base_data = read_toml(base_path)
        base_source = str(base_path)
    else:
        base_name, base_source = str(sw.get("base", "<base>")), "<base>"
    scenario_from_dict(base_data, base_source)            # the base itself must be valid

    grid_d = sw.get("grid")
    if not isinstance(grid_d, dict) or not grid_d:
        raise InputError("must be a non-empty table of key = [values, ...]", "sweep.grid")
    grid, paths = {}, {}
    for key, values in _flatten(grid_d).items():
        where = f"sweep.grid.{key}"
        if not isinstance(values, list):
            raise InputError(f"must be a list of values, got {type(values).__name__} "
                             f"{values!r}", where)
        if not values:
            raise InputError("is empty; give at least one value", where)
        path = ALIASES.get(key, key)
        col = _COLUMN.get(path, key)
        if col in grid:
            raise InputError(f"sets the same input as sweep.grid.{paths[col]}", where)
        try:
            norm = [_normalise(v) for v in values]
        except InputError as e:
            raise e.at(where) from None
        dup = [v for i, v in enumerate(norm) if v in norm[:i]]
        if dup:
            raise InputError(f"lists the value {dup[0]!r} twice", where)
        try:
            apply_override(base_data, key, values[0])
        except InputError as exc:            # unknown key
            raise InputError(exc.message, where) from None
        for i, v in enumerate(values):        # each value alone on the base: names the culprit
            try:
                scenario_from_dict(apply_override(base_data, key, v), base_source)
            except InputError as exc:
                raise InputError(f"{v!r} is refused: {exc}", f"{where}[{i}]") from None
        grid[col], paths[col] = list(values), key

    points = []
    cols = list(grid)
    for i, combo in enumerate(itertools.product(*(grid[c] for c in cols))):
        d = base_data
        for c, v in zip(cols, combo):
            d = apply_override(d, paths[c], v)
        inputs = dict(zip(cols, combo))
        try:
            sc = scenario_from_dict(d, base_source)
        except InputError as exc:
            raise InputError(f"point {inputs} is refused: {exc}", "sweep.grid") from None
        points.append(Point(i, inputs, d, point_key(resolved_inputs(sc))))
    return Sweep(name=name, description=description, source=source, base=base_name,
                 grid=grid, paths=paths, points=tuple(points))


def _flatten(d: dict, prefix: str = "") -> dict:
    """``{"fem": {"mesh": {"nz": [..]}}}`` → ``{"fem.mesh.nz": [..]}`` (unquoted dotted TOML keys)."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


# -- evaluating one point (runs in a worker) ----------------------------------------------

_WORKER_CACHE: dict = {}
_WORKER_CACHE_MAX = 24            # assembled models + eigen-decompositions kept per worker


def evaluate_point(data: dict, source: str = "<sweep point>") -> dict:
    """Evaluate one resolved scenario dict; return its JSON-able metrics and run time.

    Runs in a worker process (local pool or Dask worker). Assembled models and
    eigen-decompositions are cached per worker (one per rod, i.e. per h), so
    points that share h only redo the cheap modal time stepping.

    Parameters
    ----------
    data : dict
        Fully resolved scenario dict.
    source : str
        Name used in error messages.

    Returns
    -------
    dict
        ``{"metrics": {...}, "run_time_s": float, "worker": "host:pid"}``.
    """
    from arfem.scenarios.run import evaluate
    t0 = time.perf_counter()
    scenario = scenario_from_dict(data, source)
    if len(_WORKER_CACHE) > _WORKER_CACHE_MAX:
        _WORKER_CACHE.clear()
    ev = evaluate(scenario, cache=_WORKER_CACHE)
    metrics = _plain(ev.metrics)
    return {"metrics": metrics, "run_time_s": time.perf_counter() - t0,
            "worker": f"{socket.gethostname()}:{os.getpid()}"}


def _plain(o):
    """JSON-able copy: numpy scalars to Python, non-finite floats to None."""
    if isinstance(o, dict):
        return {str(k): _plain(v) for k, v in o.items()}
    if isinstance(o, (list, tuple, np.ndarray)):
        return [_plain(v) for v in (o.tolist() if isinstance(o, np.ndarray) else o)]
    if isinstance(o, (bool, np.bool_)):
        return bool(o)
    if isinstance(o, (int, np.integer)):
        return int(o)
    if isinstance(o, (float, np.floating)):
        f = float(o)
        return f if math.isfinite(f) else None
    return o


# -- the store ----------------------------------------------------------------------------

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
        return n


def _open_store(out: Path, sweep: Sweep, force: bool) -> str:
    """Check ``out`` for this sweep. Returns "new", "resume" or "force". Writes nothing.

    A directory holding the store of the same sweep is resumed; any other
    non-empty directory is refused unless ``force``.
    """
    check_out_path(out)
    if not out.is_dir() or not any(out.iterdir()):
        return "new"
    man = out / _STORE_MANIFEST
    try:
        old = json.loads(man.read_text("utf-8"))
    except (OSError, ValueError):
        old = None
    if isinstance(old, dict) and old.get("sweep_id") == sweep.sweep_id:
        return "resume"
    if force:
        return "force"
    if isinstance(old, dict):
        raise InputError(f"holds a different sweep ({old.get('name')!r}, "
                         f"{old.get('n_points')} points); choose another --out or pass "
                         "--force to run this one there (stored points with identical inputs "
                         "are reused)", str(out))
    raise InputError("is not empty and holds no sweep store; choose another --out or pass "
                     "--force", str(out))


class _DirLock:
    """Exclusive advisory lock on ``DIR/.lock`` (released by the OS even on kill -9)."""

    def __init__(self, out: Path):
        self.path = out / ".lock"
        self.fh = None

    def __enter__(self):
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fh = open(self.path, "a+")
        try:
            fcntl.flock(self.fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self.fh.close()
            raise InputError("another arfem sweep is writing to this directory", str(
                self.path.parent)) from None
        return self

    def __exit__(self, *exc):
        fcntl.flock(self.fh, fcntl.LOCK_UN)
        self.fh.close()


# -- executors ----------------------------------------------------------------------------

#: Same single-threaded BLAS as a Dask nanny worker, so local and Dask runs agree bit for bit.
_WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}

_OPENBLAS_SET = ("scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads",
                 "openblas_set_num_threads64_", "openblas_set_num_threads")
_OPENBLAS_GET = ("scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads",
                 "openblas_get_num_threads64_", "openblas_get_num_threads")


def _openblas_libs() -> list:
    """(set, get) thread-count functions of every OpenBLAS loaded in this process."""
    import ctypes
    import scipy.linalg  # noqa: F401  (loads SciPy's own OpenBLAS, used by eigh)
    try:
        with open("/proc/self/maps") as fh:
            paths = sorted({ln.split()[-1] for ln in fh if "openblas" in ln.lower()
                            and ln.split()[-1].startswith("/")})
    except OSError:                                             # pragma: no cover - not Linux
        return []
    out = []
    for p in paths:
        try:
            lib = ctypes.CDLL(p)
        except OSError:                                         # pragma: no cover
            continue
        set_ = next((getattr(lib, n) for n in _OPENBLAS_SET if hasattr(lib, n)), None)
        get_ = next((getattr(lib, n) for n in _OPENBLAS_GET if hasattr(lib, n)), None)
        if set_ is not None and get_ is not None:
            out.append((set_, get_))
    return out


class _BlasThreads:
    """Set the OpenBLAS thread count of this process for a while (restored on exit).

    Small dense eigen-decompositions are much faster on one thread, and far
    slower on several when the machine is loaded; workers run single-threaded.
    """

    def __init__(self, n: int = 1):
        self.n = n
        self.saved = []

    def __enter__(self):
        for set_, get_ in _openblas_libs():
            self.saved.append((set_, int(get_())))
            set_(self.n)
        return self

    def __exit__(self, *exc):
        for set_, old in self.saved:
            set_(old)


def _worker_init(ppid: int) -> None:        # pragma: no cover - runs in worker processes
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # Ctrl-C is the parent's to handle
    _BlasThreads(1).__enter__()
    _watch_parent(ppid)


def _watch_parent(ppid: int) -> None:       # pragma: no cover - runs in worker processes
    def loop():
        while True:
            time.sleep(1.0)
            if os.getppid() != ppid:
                os._exit(1)
    threading.Thread(target=loop, daemon=True).start()


class _LocalExecutor:
    """Worker processes on this machine (spawned, single-threaded BLAS)."""

    def __init__(self, workers: int):
        self.workers = workers
        self.pool = None
        self.label = f"local, {workers} worker process{'es' if workers > 1 else ''}"

    def __enter__(self):
        import multiprocessing as mp
        saved = {k: os.environ.get(k) for k in _WORKER_ENV}
        os.environ.update(_WORKER_ENV)
        try:
            self.pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                            initializer=_worker_init, initargs=(os.getpid(),))
            # start the workers now, while the environment is set
            list(self.pool.map(abs, range(self.workers)))
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
        return self

    def submit(self, fn, *args):
        return self.pool.submit(fn, *args)

    def as_completed(self, futures):
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            yield from done

    def __exit__(self, exc_type, *exc):
        if exc_type is None:
            self.pool.shutdown(wait=True)
        else:   # interrupted: drop queued work, do not wait for points in flight
            procs = list((getattr(self.pool, "_processes", None) or {}).values())
            self.pool.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                p.terminate()


_LIMITED = []


def _probe_scheduler(address: str, timeout_s: float) -> None:
    """Raise unless a Dask scheduler answers an ``identity`` request at ``address``."""
    import asyncio
    from distributed.comm import connect
    from distributed.comm.addressing import parse_address
    from distributed.comm.registry import get_backend

    scheme, loc = parse_address(address)
    get_backend(scheme)                              # ValueError: unknown scheme
    if scheme == "inproc":
        return

    async def probe():
        comm = await connect(address, timeout=timeout_s)
        try:
            await comm.write({"op": "identity", "reply": True})
            reply = await comm.read()
        finally:
            comm.abort()
        if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
            raise ConnectionError(f"not a Dask scheduler (identity: {str(reply)[:60]})")

    async def bounded():
        return await asyncio.wait_for(probe(), timeout_s)

    try:
        asyncio.run(bounded())
    except asyncio.TimeoutError:
        raise TimeoutError(f"no answer after {timeout_s:g} s") from None
    except MemoryError:
        raise ConnectionError("something answered, but not in the Dask protocol") from None


def _single_threaded_call(fn, *args):
    """Run ``fn`` with single-threaded BLAS (set once per process: Dask workers)."""
    if not _LIMITED:
        _LIMITED.append(_BlasThreads(1).__enter__())
    return fn(*args)


class _DaskExecutor:
    """The same tasks on a Dask distributed cluster."""

    def __init__(self, address: str, timeout_s: float = 5.0):
        self.address = address
        self.timeout_s = timeout_s
        self.client = None
        self.submitted = []
        self.label = f"dask scheduler {address}"

    def connect(self):
        try:
            from dask.distributed import Client
        except ImportError:                                     # pragma: no cover
            raise InputError("dask.distributed is not installed", "--scheduler") from None
        def fail(exc):
            msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            return InputError(f"cannot reach the Dask scheduler at {self.address!r} within "
                              f"{self.timeout_s:g} s ({msg})", "--scheduler")

        try:        # a bare probe first: a failed Client() leaves a noisy half-made object
            _probe_scheduler(self.address, self.timeout_s)
        except Exception as exc:      # OSError, TimeoutError, ValueError for a bad address
            raise fail(exc) from None
        try:
            self.client = Client(self.address, timeout=self.timeout_s, set_as_default=False)
        except Exception as exc:                                # pragma: no cover - races
            raise fail(exc) from None
        n = len(self.client.scheduler_info().get("workers", {}))
        self.label = f"dask scheduler {self.address} ({n} workers)"
        return self

    def __enter__(self):
        if self.client is None:
            self.connect()
        return self

    def submit(self, fn, *args):
        fut = self.client.submit(_single_threaded_call, fn, *args, pure=False)
        self.submitted.append(fut)
        return fut

    def as_completed(self, futures):
        from dask.distributed import as_completed
        yield from as_completed(futures, loop=self.client.loop)

    def __exit__(self, exc_type, *exc):
        if exc_type is not None:
            try:
                self.client.cancel(self.submitted)
            except Exception:                                   # pragma: no cover
                pass
        self.client.close()


# -- running ------------------------------------------------------------------------------

@dataclass
class RunReport:
    """What one invocation did."""

    run_id: str
    n_points: int
    n_stored_before: int
    n_computed: int = 0
    n_failed: int = 0
    failures: list = field(default_factory=list)
    wall_s: float = 0.0
    executor: str = ""
    mode: str = "new"


def run_sweep(sweep: Sweep, out, *, workers: int | None = None, scheduler: str | None = None,
              force: bool = False, progress: bool = True, timeout_s: float = 5.0,
              point_fn: Callable = evaluate_point) -> RunReport:
    """Compute every point of ``sweep`` missing from the store in ``out``; write the results.

    Parameters
    ----------
    sweep : Sweep
    out : path
        Store and output directory (resumed if it holds the same sweep).
    workers : int, optional
        Local worker processes (default: all cores). 1 = in this process.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``); overrides ``workers``.
    force : bool
        Allow a non-empty ``out`` that holds something else.
    progress : bool
        tqdm progress bar with ETA on stderr.
    timeout_s : float
        Connection timeout for ``scheduler`` [s].
    point_fn : callable
        ``point_fn(data, source) -> {"metrics": ..., "run_time_s": ...}`` (picklable).
    """
    out = Path(out)
    mode = _open_store(out, sweep, force)
    if not (math.isfinite(timeout_s) and timeout_s > 0):
        raise InputError(f"must be a finite number of seconds > 0, got {timeout_s!r}",
                         "--connect-timeout")
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise InputError(f"must be a whole number >= 1, got {workers!r}", "--workers")
    executor = None
    if scheduler is not None:
        executor = _DaskExecutor(scheduler, timeout_s).connect()   # fail before writing
    t0 = time.perf_counter()
    run_id = time.strftime("%Y%m%dT%H%M%S") + "-" + uuid.uuid4().hex[:8]
    try:
        with _DirLock(out):
            store = PointStore(out)
            store.dir.mkdir(parents=True, exist_ok=True)
            store.remove_temporaries()
            man = out / _STORE_MANIFEST
            if mode != "resume" or not man.is_file():
                write_json(man, sweep.manifest())
            stored = store.keys()
            todo = [p for p in sweep.points if p.key not in stored or store.get(p.key) is None]
            seen, unique = set(), []
            for p in todo:                                  # identical inputs: compute once
                if p.key not in seen:
                    seen.add(p.key)
                    unique.append(p)
            # points that share everything but Δτ and q share the FEM model and its
            # eigen-decomposition: submit them together so worker caches hit
            unique.sort(key=lambda p: _canonical({k: v for k, v in p.inputs.items()
                                                  if k not in ("dtau_s", "q_W_m2")}))
            rep = RunReport(run_id, len(sweep.points), len(sweep.points) - len(todo), mode=mode)
            if unique:
                if executor is None:
                    n = min(workers or os.cpu_count() or 1, len(unique))
                    executor = _LocalExecutor(n) if n > 1 else None
                rep.executor = executor.label if executor else "local, in-process"
                _compute(sweep, unique, store, executor, point_fn, rep, run_id, progress)
            else:
                rep.executor = "nothing to compute"
                if executor is not None:
                    executor.client.close()
            rep.wall_s = time.perf_counter() - t0
            _append_run_log(out, rep)
            write_outputs(sweep, out, store, rep)
    except BaseException:
        if isinstance(executor, _DaskExecutor) and executor.client is not None:
            executor.client.close()
        raise
    return rep


def _compute(sweep, points, store, executor, point_fn, rep, run_id, progress):
    from tqdm import tqdm
    bar = tqdm(total=rep.n_points, initial=rep.n_points - len(points), desc=f"sweep {sweep.name}",
               unit="pt", file=sys.stderr, disable=not progress, dynamic_ncols=True,
               mininterval=0.5)

    def record(p: Point, res: dict) -> dict:
        return {"key": p.key, "store_version": STORE_VERSION, "sweep": sweep.name,
                "inputs": p.inputs, "scenario": p.data, "metrics": res["metrics"],
                "run_time_s": res["run_time_s"], "worker": res.get("worker", ""),
                "run_id": run_id, "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}

    def failed(p: Point, exc: BaseException):
        rep.n_failed += 1
        msg = " ".join(str(exc).split())
        if "deserializ" in msg:
            msg += (" [the Dask scheduler and every worker must be able to import arfem: "
                    "pip install -e <repo> there, or start them with PYTHONPATH=<repo>]")
        rep.failures.append({"inputs": p.inputs, "error": f"{type(exc).__name__}: {msg}"})

    def settle(p: Point, get_result) -> None:
        """Store one finished point as soon as it completes, or record its failure."""
        try:
            res = get_result()
        except Exception as exc:
            failed(p, exc)
        else:
            store.put(record(p, res))
            rep.n_computed += 1
        bar.update(1)

    try:
        if executor is None:
            with _BlasThreads(1):
                _serial(sweep, points, point_fn, settle)
            return
        with executor:
            futs = {executor.submit(point_fn, p.data, f"{sweep.source} point {p.index}"): p
                    for p in points}
            for fut in executor.as_completed(list(futs)):
                settle(futs[fut], fut.result)
    finally:
        bar.close()


def _serial(sweep, points, point_fn, settle):
    for p in points:
        settle(p, lambda p=p: point_fn(p.data, f"{sweep.source} point {p.index}"))


def _append_run_log(out: Path, rep: RunReport) -> None:
    line = json.dumps({"run_id": rep.run_id, "mode": rep.mode, "executor": rep.executor,
                       "n_points": rep.n_points, "n_stored_before": rep.n_stored_before,
                       "n_computed": rep.n_computed, "n_failed": rep.n_failed,
                       "wall_s": round(rep.wall_s, 3)})
    with open(out / _RUNS_LOG, "a", encoding="utf-8") as fh:
        fh.write(line + "\n")
        fh.flush()
        os.fsync(fh.fileno())


# -- the tidy table -----------------------------------------------------------------------

def results_rows(sweep: Sweep, store: PointStore) -> list[dict]:
    """One row per stored point of ``sweep``, in grid order: inputs, then metrics."""
    rows = []
    for p in sweep.points:
        rec = store.get(p.key)
        if rec is None:
            continue
        m = dict(rec["metrics"])
        peak = m.get("fem_peak_um") or float("nan")
        for pre in ("", "corrected_"):
            if f"{pre}rmse_pct_of_peak" not in m and f"{pre}rmse_um" in m:
                m[f"{pre}rmse_pct_of_peak"] = 100.0 * m[f"{pre}rmse_um"] / peak
        m["run_time_s"] = rec.get("run_time_s")
        row = {c: m.get(c) for c in CORE_INPUTS}
        row.update(p.inputs)
        for c in METRIC_COLUMNS:
            row[c] = m.get(c)
        row["point_key"] = p.key
        rows.append(row)
    return rows


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ""
    s = str(v)
    if any(ch in s for ch in ',"\n'):
        s = '"' + s.replace('"', '""') + '"'
    return s


def rows_to_csv(rows: list[dict]) -> str:
    """Tidy CSV text; floats written with ``repr`` (round-trips exactly)."""
    if not rows:
        return ""
    cols = list(rows[0])
    lines = [",".join(cols)] + [",".join(_cell(r.get(c)) for c in cols) for r in rows]
    return "\n".join(lines) + "\n"


# -- analysis -----------------------------------------------------------------------------

def biot_threshold(biot, error, level: float) -> float:
    """Smallest Biot number at which ``error`` reaches ``level``, linearly interpolated.

    Parameters
    ----------
    biot : array_like
        Biot numbers hR/λ [-] (any order).
    error : array_like
        Error at each Biot number [% of peak].
    level : float
        Threshold [% of peak].

    Returns
    -------
    float
        The crossing [-]; ``nan`` if the error never reaches ``level``, the
        smallest Biot number if it is reached already there.

    Examples
    --------
    >>> biot_threshold([0.1, 0.2, 0.4], [1.0, 2.0, 6.0], 3.0)
    0.25
    >>> biot_threshold([0.1, 0.2], [1.0, 2.0], 3.0)
    nan
    """
    b = np.asarray(biot, float)
    e = np.asarray(error, float)
    o = np.argsort(b)
    b, e = b[o], e[o]
    above = np.nonzero(e >= level)[0]
    if above.size == 0:
        return float("nan")
    i = int(above[0])
    if i == 0:
        return float(b[0])
    return float(b[i - 1] + (level - e[i - 1]) * (b[i] - b[i - 1]) / (e[i] - e[i - 1]))


def _slice_rows(sweep: Sweep, rows: list[dict]) -> tuple[list[dict], dict]:
    """Rows at the largest q and the first value of every other non-core swept key."""
    fixed = {c: v[0] for c, v in sweep.grid.items() if c not in CORE_INPUTS}
    if "q_W_m2" in sweep.grid:
        fixed["q_W_m2"] = max(v for v in sweep.grid["q_W_m2"])
    sel = [r for r in rows if all(r.get(c) == v for c, v in fixed.items())]
    return sel, fixed


def thresholds(sweep: Sweep, rows: list[dict], levels=(3.0, 5.0)) -> list[dict]:
    """Per Δτ: the Biot number above which each AR's max error exceeds each level."""
    sel, _ = _slice_rows(sweep, rows)
    out = []
    for dtau in sorted({r["dtau_s"] for r in sel}):
        rs = [r for r in sel if r["dtau_s"] == dtau]
        b = [r["biot"] for r in rs]
        item = {"dtau_s": dtau, "biot_min": min(b), "biot_max": max(b)}
        for pre, name in (("", "paper"), ("corrected_", "corrected")):
            e = [r[f"{pre}max_abs_diff_pct_of_peak"] for r in rs]
            item[f"{name}_max_error_pct"] = max(e)
            for lv in levels:
                item[f"{name}_biot_at_{lv:g}pct"] = biot_threshold(b, e, lv)
        out.append(item)
    return out


# -- plots --------------------------------------------------------------------------------

def _plots(sweep: Sweep, rows: list[dict], stage: Path) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    sel, fixed = _slice_rows(sweep, rows)
    if not sel:
        return written
    tag = ", ".join(f"{k} = {v:g}" if isinstance(v, (int, float)) else f"{k} = {v}"
                    for k, v in fixed.items())
    dtaus = sorted({r["dtau_s"] for r in sel})
    hs = sorted({r["h_W_m2K"] for r in sel})
    cmap = plt.get_cmap("viridis")

    # 1. error against Biot, one line per Δτ, paper and corrected AR
    fig, ax = plt.subplots(figsize=(7.5, 5))
    for i, dt in enumerate(dtaus):
        rs = sorted((r for r in sel if r["dtau_s"] == dt), key=lambda r: r["biot"])
        col = cmap(i / max(1, len(dtaus) - 1))
        b = [r["biot"] for r in rs]
        ax.plot(b, [r["max_abs_diff_pct_of_peak"] for r in rs], "o-", color=col,
                label=f"paper AR, Δτ = {dt:g} s")
        ax.plot(b, [max(r["corrected_max_abs_diff_pct_of_peak"], 1e-6) for r in rs], "x--",
                color=col, label=f"corrected AR, Δτ = {dt:g} s")
    for lv in (3.0, 5.0):
        ax.axhline(lv, color="0.5", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("Biot number hR/λ [-]")
    ax.set_ylabel("max |AR − FEM| [% of FEM peak]")
    ax.set_title(f"AR(1) error against Biot number ({tag})" if tag else "AR(1) error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(stage / "error_vs_biot.png", dpi=120)
    plt.close(fig)
    written.append("error_vs_biot.png")

    # 2. C1 against Δτ: closed form (line), fitted to the FEM (markers), corrected (dotted)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.5))
    for j, h in enumerate(hs):
        rs = sorted((r for r in sel if r["h_W_m2K"] == h), key=lambda r: r["dtau_s"])
        col = cmap(j / max(1, len(hs) - 1))
        d = [r["dtau_s"] for r in rs]
        for ax, f in ((a1, lambda c: c), (a2, lambda c: 1.0 - c)):
            ax.plot(d, [f(r["C1"]) for r in rs], "-", color=col, label=f"h = {h:g} closed form")
            ax.plot(d, [f(r["C1_fitted"]) for r in rs], "o", color=col, mfc="none",
                    label=f"h = {h:g} fitted to FEM")
            ax.plot(d, [f(r["corrected_C1"]) for r in rs], ":", color=col)
    a1.set_xlabel("Δτ [s]")
    a1.set_ylabel("C1 [-]")
    a1.set_title("C1: paper eq. 13 (line), fitted (o), corrected (dotted)")
    a2.set_xscale("log")
    a2.set_yscale("log")
    a2.set_xlabel("Δτ [s]")
    a2.set_ylabel("1 − C1 [-]")
    a2.set_title("1 − C1 (log-log)")
    for ax in (a1, a2):
        ax.grid(True, which="both", alpha=0.3)
    a1.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(stage / "c1_vs_dtau.png", dpi=120)
    plt.close(fig)
    written.append("c1_vs_dtau.png")

    # 3. heat maps of the error over (Δτ, h), one per q
    qs = sorted({r["q_W_m2"] for r in rows}) if "q_W_m2" in sweep.grid else [fixed.get("q_W_m2")]
    other = {k: v for k, v in fixed.items() if k != "q_W_m2"}
    for q in qs:
        rs = [r for r in rows if all(r.get(c) == v for c, v in other.items())
              and (q is None or r["q_W_m2"] == q)]
        fig, axs = plt.subplots(1, 2, figsize=(12, 4.8))
        for ax, pre, title in ((axs[0], "", "paper AR"), (axs[1], "corrected_", "corrected AR")):
            Z = np.full((len(dtaus), len(hs)), np.nan)
            for r in rs:
                Z[dtaus.index(r["dtau_s"]), hs.index(r["h_W_m2K"])] = \
                    r[f"{pre}max_abs_diff_pct_of_peak"]
            from matplotlib.colors import LogNorm
            pos = Z[np.isfinite(Z) & (Z > 0)]
            norm = LogNorm(pos.min(), pos.max()) if pos.size and pos.max() > pos.min() else None
            im = ax.imshow(Z, origin="lower", aspect="auto", cmap="magma_r", norm=norm)
            ax.set_xticks(range(len(hs)), [f"{h:g}" for h in hs])
            ax.set_yticks(range(len(dtaus)), [f"{d:g}" for d in dtaus])
            ax.set_xlabel("h [W/(m²·K)]")
            ax.set_ylabel("Δτ [s]")
            ax.set_title(f"{title}: max |AR − FEM| [% of peak]" +
                         (f", q = {q:g} W/m²" if q is not None else ""), fontsize=9)
            for (i, j), z in np.ndenumerate(Z):
                if np.isfinite(z):
                    ax.text(j, i, f"{z:.2g}", ha="center", va="center", fontsize=6,
                            color="w" if z > np.nanmax(Z) * 0.3 else "k")
            fig.colorbar(im, ax=ax)
        fig.tight_layout()
        name = f"error_heatmap_q{q:g}.png" if q is not None else "error_heatmap.png"
        fig.savefig(stage / name, dpi=120)
        plt.close(fig)
        written.append(name)
    return written


# -- writing the results ------------------------------------------------------------------

def _fmt(x, nd=3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.{nd}g}" if isinstance(x, float) else str(x)


def render_readme(sweep: Sweep, rows: list[dict], summary: dict) -> str:
    """Markdown report of a sweep; every number in it is computed from ``rows``."""
    L = [f"# Sweep `{sweep.name}`", ""]
    if sweep.description:
        L += [sweep.description, ""]
    L += [f"Base scenario `{sweep.base}`; grid (full Cartesian product, "
          f"{len(sweep.points)} points):", ""]
    for c, v in sweep.grid.items():
        L.append(f"- `{c}` = {', '.join(_fmt(x, 6) if isinstance(x, float) else str(x) for x in v)}")
    L += ["", f"Points in the table: {summary['n_rows']} of {summary['n_points']}. "
          f"This run: {summary['n_computed']} computed, {summary['n_stored_before']} taken "
          f"from the store, {summary['n_failed']} failed, wall time {summary['wall_s']:.1f} s "
          f"({summary['executor']}). Sum of per-point run times "
          f"{summary['sum_point_run_time_s']:.1f} s.", "",
          "Files: `results.csv` (one row per point; inputs then outputs, units in the "
          "column names, `pct` = % of the FEM peak growth), `summary.json`, "
          "`error_vs_biot.png`, `c1_vs_dtau.png`, `error_heatmap_q*.png`; the per-point "
          "store is `points/` (re-running the same command resumes it).", "",
          f"Reproduce: `arfem sweep {sweep.source} --out DIR` (add `--scheduler ADDRESS` "
          "for a Dask cluster; an interrupted run resumes where it stopped).", ""]
    th = summary.get("thresholds") or []
    if th and len({r["biot"] for r in rows}) > 1:
        sel, fixed = _slice_rows(sweep, rows)
        tag = ", ".join(f"{k} = {_fmt(v, 6)}" for k, v in fixed.items())
        L += ["## When does the paper's AR(1) stop tracking the FEM?", "",
              f"Max |AR − FEM| over the cycle in % of the FEM peak, against the Biot "
              f"number hR/λ ({tag}{_q_note(sweep, rows)}). Thresholds are interpolated linearly in Biot "
              "between grid points by `scenarios.sweep.biot_threshold`; `–` = not reached "
              "in the grid.", "",
              "| Δτ [s] | Biot range | paper AR max error [%] | Bi at 3 % | Bi at 5 % | "
              "corrected AR max error [%] | corrected: Bi at 3 % | corrected: Bi at 5 % |",
              "|---|---|---|---|---|---|---|---|"]
        for t in th:
            L.append(f"| {t['dtau_s']:g} | {t['biot_min']:.3g}–{t['biot_max']:.3g} | "
                     f"{t['paper_max_error_pct']:.3g} | {_fmt(t['paper_biot_at_3pct'])} | "
                     f"{_fmt(t['paper_biot_at_5pct'])} | {t['corrected_max_error_pct']:.2g} | "
                     f"{_fmt(t['corrected_biot_at_3pct'])} | {_fmt(t['corrected_biot_at_5pct'])} |")
        s = summary["conclusion"]
        L += ["", "**From the data:** " + s["text"], ""]
        L += _by_h_table(sel)
    return "\n".join(L) + "\n"


def _q_note(sweep: Sweep, rows: list[dict]) -> str:
    """How much the % errors differ between q levels at equal other inputs (from the data)."""
    qs = sweep.grid.get("q_W_m2", [])
    if len(qs) < 2:
        return ""
    groups: dict = {}
    for r in rows:
        k = _canonical({c: r[c] for c in sweep.grid if c != "q_W_m2"})
        groups.setdefault(k, []).append(r)
    d = max(((max(r[c] for r in g) - min(r[c] for r in g))
             for g in groups.values() if len(g) > 1
             for c in ("max_abs_diff_pct_of_peak", "corrected_max_abs_diff_pct_of_peak")),
            default=float("nan"))
    if not math.isfinite(d):
        return ""
    return (f"; the other q levels give the same % errors to within {d:.1g} percentage points, "
            "as the FEM and both ARs are linear in q")


def _by_h_table(sel: list[dict]) -> list[str]:
    """Per h: errors (max over Δτ, and their spread over Δτ) and the fitted decay rate."""
    dts = sorted({r["dtau_s"] for r in sel})
    L = ["Per h (same slice; \"spread\" = max − min over the Δτ values, showing how little "
         "the error depends on Δτ; the last column compares the FEM's fitted per-step decay "
         "1 − C1_fitted with the paper's 1 − C1 = 1 − exp(−bΔτ) at the smallest Δτ):", "",
         "| h [W/(m²·K)] | Bi [-] | paper AR max error [%] | spread over Δτ [% points] | "
         "corrected AR max error [%] | (1 − C1_fitted)/(1 − C1) at "
         f"Δτ = {dts[0]:g} s |", "|---|---|---|---|---|---|"]
    for h in sorted({r["h_W_m2K"] for r in sel}):
        rs = [r for r in sel if r["h_W_m2K"] == h]
        e = [r["max_abs_diff_pct_of_peak"] for r in rs]
        ec = [r["corrected_max_abs_diff_pct_of_peak"] for r in rs]
        r0 = min(rs, key=lambda r: r["dtau_s"])
        ratio = (1 - r0["C1_fitted"]) / (1 - r0["C1"])
        L.append(f"| {h:g} | {r0['biot']:.3g} | {max(e):.3g} | {max(e) - min(e):.2g} | "
                 f"{max(ec):.2g} | {ratio:.4f} |")
    return L + [""]


def _conclusion(th: list[dict]) -> dict:
    def rng(key):
        v = [t[key] for t in th if math.isfinite(t[key])]
        return (min(v), max(v), len(v)) if v else None

    parts = []
    out = {}
    for lv in (3, 5):
        r = rng(f"paper_biot_at_{lv}pct")
        out[f"paper_biot_at_{lv}pct_range"] = None if r is None else [r[0], r[1]]
        if r is None:
            parts.append(f"the paper's AR never exceeds {lv} % of peak in this grid")
        elif f"{r[0]:.3g}" == f"{r[1]:.3g}":
            parts.append(f"the paper's AR exceeds {lv} % of peak above Bi ≈ {r[0]:.3g}, the "
                         f"same to 3 digits for all {r[2]} of {len(th)} Δτ values that reach it")
        else:
            parts.append(f"the paper's AR exceeds {lv} % of peak above Bi ≈ {r[0]:.3g}–"
                         f"{r[1]:.3g} depending on Δτ ({r[2]} of {len(th)} Δτ values reach it)")
    cmax = max(t["corrected_max_error_pct"] for t in th)
    out["corrected_max_error_pct"] = cmax
    out["corrected_exceeds_3pct"] = bool(cmax >= 3.0)
    out["corrected_exceeds_5pct"] = bool(cmax >= 5.0)
    parts.append(("the corrected AR stays below 3 % everywhere in the grid" if cmax < 3 else
                  "the corrected AR also exceeds 3 % somewhere in the grid")
                 + f" (its largest error is {cmax:.3g} % of peak)")
    out["text"] = "; ".join(parts) + "."
    out["text"] = out["text"][0].upper() + out["text"][1:]
    return out


def write_outputs(sweep: Sweep, out: Path, store: PointStore, rep: RunReport) -> dict:
    """(Re)write ``results.csv``, plots, ``summary.json`` and ``README.md`` from the store."""
    rows = results_rows(sweep, store)
    summary = {
        "sweep": sweep.name, "sweep_id": sweep.sweep_id, "run_id": rep.run_id,
        "n_points": rep.n_points, "n_rows": len(rows), "n_stored_before": rep.n_stored_before,
        "n_computed": rep.n_computed, "n_failed": rep.n_failed, "failures": rep.failures[:20],
        "executor": rep.executor, "wall_s": rep.wall_s,
        "points_per_s": rep.n_computed / rep.wall_s if rep.wall_s > 0 else None,
        "sum_point_run_time_s": float(sum(r["run_time_s"] or 0.0 for r in rows)),
    }
    has_core = rows and all(r.get(c) is not None for r in rows for c in
                            ("dtau_s", "h_W_m2K", "biot", "max_abs_diff_pct_of_peak"))
    if has_core:
        th = thresholds(sweep, rows)
        summary["thresholds"] = th
        summary["conclusion"] = _conclusion(th)
    with staged_out_dir(out, force=True) as stage:
        atomic_write_text(stage / "results.csv", rows_to_csv(rows))
        summary["plots"] = _plots(sweep, rows, stage) if has_core else []
        write_json(stage / "summary.json", summary)
        atomic_write_text(stage / "README.md", render_readme(sweep, rows, summary))
    return summary


# -- command line -------------------------------------------------------------------------

def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "sweep", help="evaluate a scenario over a grid of inputs (resumable; local or Dask)",
        description="Evaluate the base scenario of SWEEP.toml at every point of its grid: "
                    "closed-form and fitted AR(1) coefficients, FEM peak, AR-FEM errors. "
                    "Each finished point is stored at once in DIR/points/; re-running the "
                    "same command with the same --out computes only the missing points.")
    p.add_argument("sweep_file", metavar="SWEEP.toml")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="store and output directory (resumed if it holds this sweep)")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="run on a Dask distributed cluster, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes (default: all cores; 1 = in-process)")
    p.add_argument("--connect-timeout", type=float, default=5.0, metavar="S",
                   help="seconds to wait for the Dask scheduler (default 5)")
    p.add_argument("--force", action="store_true",
                   help="run in a non-empty --out that holds something else")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=main)


def main(args) -> int:
    sweep = load_sweep(args.sweep_file)
    rep = run_sweep(sweep, args.out, workers=args.workers, scheduler=args.scheduler,
                    force=args.force, progress=not args.no_progress,
                    timeout_s=args.connect_timeout)
    print(f"sweep {sweep.name!r}: {rep.n_points} points ({rep.n_stored_before} already "
          f"stored, {rep.n_computed} computed, {rep.n_failed} failed) in {rep.wall_s:.1f} s "
          f"[{rep.executor}] -> {Path(args.out) / 'results.csv'}")
    errors: dict = {}
    for f in rep.failures:
        errors.setdefault(f["error"], []).append(f["inputs"])
    for err, inputs in list(errors.items())[:5]:
        print(f"arfem: {len(inputs)} point(s) failed, e.g. {inputs[0]}: {err}", file=sys.stderr)
    return 1 if rep.n_failed else 0
