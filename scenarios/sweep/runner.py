"""Running a sweep: open (or resume) the store, compute the missing points on an
executor, store each as it finishes, then write the outputs from the store."""
from __future__ import annotations

import math
import os
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from arfem.params import InputError
from arfem.io import write_json
from arfem.scenarios.sweep.executors import (DaskExecutor, LocalExecutor, blas_threads,
                                            evaluate_point)
from arfem.scenarios.sweep.report import write_outputs
from arfem.scenarios.sweep.spec import STORE_VERSION, Point, Sweep, _canonical
from arfem.scenarios.sweep.store import (_STORE_MANIFEST, DirLock, PointStore,
                                         append_run_log, open_store)

__all__ = ["RunReport", "run_sweep"]

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
    mode = open_store(out, sweep, force)
    if not (math.isfinite(timeout_s) and timeout_s > 0):
        raise InputError(f"must be a finite number of seconds > 0, got {timeout_s!r}",
                         "--connect-timeout")
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise InputError(f"must be a whole number >= 1, got {workers!r}", "--workers")
    executor = None
    if scheduler is not None:
        executor = DaskExecutor(scheduler, timeout_s).connect()   # fail before writing
    t0 = time.perf_counter()
    run_id = time.strftime("%Y%m%dT%H%M%S") + "-" + uuid.uuid4().hex[:8]
    try:
        with DirLock(out):
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
                    executor = LocalExecutor(n) if n > 1 else None
                rep.executor = executor.label if executor else "local, in-process"
                _compute(sweep, unique, store, executor, point_fn, rep, run_id, progress)
            else:
                rep.executor = "nothing to compute"
                if executor is not None:
                    executor.client.close()
            rep.wall_s = time.perf_counter() - t0
            append_run_log(out, rep)
            write_outputs(sweep, out, store, rep)
    except BaseException:
        if isinstance(executor, DaskExecutor) and executor.client is not None:
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
            with blas_threads(1):
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
