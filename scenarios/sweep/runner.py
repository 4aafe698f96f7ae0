"""Running a sweep: open (or resume) the store, compute the missing points on an
executor, store each as it finishes, then write the outputs from the store."""
from __future__ import annotations

import errno
import functools
import math
import os
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from arfem.limits import Limits, resolve
from arfem.params import InputError
from arfem.io import write_json
from arfem.scenarios.sweep.executors import (WORKER_START_S, DaskExecutor, LocalExecutor,
                                            blas_threads, evaluate_point)
import arfem.scenarios.sweep.geometry_run as geometry_run
from arfem.scenarios.sweep.geometry import GeometrySweep, evaluate_geometry_point
from arfem.scenarios.sweep.report import write_outputs
from arfem.scenarios.sweep.points import STORE_VERSION, Point, Sweep, canonical
from arfem.scenarios.outdir import adopt_outputs
from arfem.scenarios.sweep.store import (STORE_MANIFEST, DirLock, PointStore,
                                         append_run_log, open_store)

__all__ = ["RunReport", "run_sweep", "stored_or_todo", "bad_points_line", "usable_cores", "check_wait", "check_workers",
           "n_local_workers", "MAX_WAIT_S", "MAX_CONNECT_S",
           "DEFAULT_WORKER_WAIT_S"]

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


#: Longest wait ``--worker-wait`` may ask for [s]; larger values are capped (with a note).
MAX_WAIT_S = 600.0
#: Longest wait ``--connect-timeout`` may ask for [s] (a scheduler answers in well under 1 s).
MAX_CONNECT_S = 60.0
#: How long a Dask cluster may have no worker (none yet, or all gone) before the sweep ends [s].
DEFAULT_WORKER_WAIT_S = 60.0


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity; ``os.cpu_count()`` elsewhere)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):                         # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def note(message: str) -> None:
    """One line on stderr: something arfem decided for the user (a cap, a default)."""
    print(f"arfem: note: {message}", file=sys.stderr, flush=True)


def check_wait(value, flag: str, warn: Callable = note, limit: float = MAX_WAIT_S) -> float:
    """A timeout flag [s]: a number > 0 (NaN refused), capped at ``limit``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value) \
            or value <= 0:
        raise InputError(f"must be a number of seconds > 0, got {value!r}", flag)
    if value > limit:
        warn(f"{flag} {value:g} s capped at {limit:g} s (the longest wait arfem allows)")
        return float(limit)
    return float(value)


def check_workers(workers) -> int | None:
    """``--workers``: None (all cores) or a whole number >= 1."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise InputError(f"must be a whole number >= 1, got {workers!r}", "--workers")
    return workers


def n_local_workers(workers: int | None, n_todo: int, warn: Callable = note) -> int:
    """Worker processes to start: the request (default: all cores), capped at the cores
    and at the points to compute; a cap of an explicit request is stated in one line."""
    cores = usable_cores()
    n = max(1, min(workers or cores, cores, n_todo))
    if workers is not None and workers > n and workers > cores:
        warn(f"--workers {workers} capped at {n} ({cores} cores, {n_todo} points to compute)")
    return n


def _mesh_sweeps_apart(run: Callable) -> Callable:
    """``run_sweep`` for a rod's sweep; a mesh scenario's sweep (``sweep.kind ==
    "geometry"``) goes to :func:`run_geometry_sweep`, the same store, executors and
    resume with its own outputs (:mod:`arfem.scenarios.sweep.geometry_run`)."""
    @functools.wraps(run)
    def dispatch(sweep, out, **kw):
        if getattr(sweep, "kind", None) == "geometry":
            return run_geometry_sweep(sweep, out, **kw)
        return run(sweep, out, **kw)
    return dispatch


@_mesh_sweeps_apart
def run_sweep(sweep: Sweep, out, *, workers: int | None = None, scheduler: str | None = None,
              force: bool = False, progress: bool = True, timeout_s: float = 5.0,
              worker_wait_s: float = DEFAULT_WORKER_WAIT_S, point_fn: Callable = evaluate_point,
              warn: Callable = note, limits: Limits | None = None) -> RunReport:
    """Compute every point of ``sweep`` missing from the store in ``out``; write the results.

    Parameters
    ----------
    sweep : Sweep
    out : path
        Store and output directory (resumed if it holds the same sweep).
    workers : int, optional
        Local worker processes (default: all cores; capped at the cores and at the
        points to compute). 1 = in this process.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``); overrides ``workers``.
    force : bool
        Allow a non-empty ``out`` that holds something else.
    progress : bool
        tqdm progress bar with ETA on stderr.
    timeout_s : float
        Connection timeout for ``scheduler`` [s] (at most :data:`MAX_CONNECT_S`).
    worker_wait_s : float
        How long the Dask cluster may have no worker before the sweep ends [s] (at most
        :data:`MAX_WAIT_S`); the points stored so far are kept.
    point_fn : callable
        ``point_fn(data, source, limits=...) -> {"metrics": ..., "run_time_s": ...}``
        (picklable).
    warn : callable
        Receives one-line notes (caps applied to the flags).
    limits : arfem.limits.Limits, optional
        What the user allows past the size limits; passed to every point (each worker
        validates its point again). Default: :meth:`Limits.from_environment`.
    """
    return run_in_store(sweep, out, ready_store=_ready_store, order=_in_cache_order,
                        write=write_outputs, workers=workers, scheduler=scheduler,
                        force=force, progress=progress, timeout_s=timeout_s,
                        worker_wait_s=worker_wait_s, point_fn=point_fn, warn=warn,
                        limits=limits)


def run_in_store(sweep, out, *, ready_store: Callable, order: Callable, write: Callable,
                 workers: int | None, scheduler: str | None, force: bool, progress: bool,
                 timeout_s: float, worker_wait_s: float, point_fn: Callable,
                 warn: Callable, limits: Limits | None,
                 plan: Callable | None = None) -> RunReport:
    """The one loop of a sweep over its store, shared by the rod's and the mesh's sweep:
    open (or resume) the store under its lock, compute the points it lacks (in process,
    on local workers or on Dask), log the run and write the outputs.

    ``ready_store(out, sweep, mode)`` gives the store ready to take points,
    ``order(todo)`` the points to compute in the order that shares the most work, and
    ``write(sweep, out, store, report, runs)`` the outputs (see :func:`run_sweep` for
    the other parameters). ``plan(points, first, n_workers)``, where points share work
    that only the process holding it can reuse (a mesh sweep's model), splits the
    points into runs of adjacent points, each sent to a worker as one task, or returns
    None to compute them in this process; ``first`` is the result of the point computed
    in this process to measure the costs (None when the workers were asked for)."""
    out = Path(out)
    mode = open_store(out, sweep, force)
    timeout_s = check_wait(timeout_s, "--connect-timeout", warn, MAX_CONNECT_S)
    worker_wait_s = check_wait(worker_wait_s, "--worker-wait", warn)
    workers = check_workers(workers)
    executor = None
    if scheduler is not None:
        executor = DaskExecutor(scheduler, timeout_s, worker_wait_s).connect()  # fail first
    t0 = time.perf_counter()
    run_id = time.strftime("%Y%m%dT%H%M%S") + "-" + uuid.uuid4().hex[:8]
    try:
        with DirLock(out):
            store = ready_store(out, sweep, mode)
            todo, bad = stored_or_todo(sweep, store)
            if bad:
                warn(bad_points_line(bad))
            unique = order(todo)
            rep = RunReport(run_id, len(sweep.points), len(sweep.points) - len(todo), mode=mode)
            if unique:
                if executor is None:
                    n = n_local_workers(workers, len(unique), warn)
                    executor = LocalExecutor(n) if n > 1 else None
                rep.executor = executor.label if executor else "local, in-process"
                fn = functools.partial(point_fn, limits=resolve(limits))
                # by default, start workers only for what the first seconds in-process
                # did not finish (issue 30: the shipped sweep was slower on 2 workers)
                first_s = IN_PROCESS_FIRST_S if workers is None and scheduler is None else 0.0
                _compute(sweep, unique, store, executor, fn, rep, run_id, progress, first_s,
                         plan)
            else:
                rep.executor = "nothing to compute"
                if executor is not None:
                    executor.close()
            rep.wall_s = time.perf_counter() - t0
            runs = append_run_log(out, rep)
            write(sweep, out, store, rep, runs)
    except OSError as exc:
        if exc.errno in _DISK_ERRNOS:
            raise InputError(f"cannot be written ({exc.strerror}); every point stored so far "
                             "is kept, and the same command resumes once there is room",
                             str(out)) from None
        raise
    finally:
        if isinstance(executor, DaskExecutor):
            executor.close()
    return rep


def _ready_store(out: Path, sweep: Sweep, mode: str) -> PointStore:
    """The point store in ``out``, ready to take points: its folder made, temporaries of
    an interrupted run removed, the sweep's manifest written (kept on a resume), and
    the folder adopted as arfem's."""
    store = PointStore(out)
    store.dir.mkdir(parents=True, exist_ok=True)
    store.remove_temporaries()
    man = out / STORE_MANIFEST
    if mode != "resume" or not man.is_file():
        write_json(man, sweep.manifest())
    # the folder is arfem's from its first file on (``arfem report`` writes only
    # into a folder whose ownership manifest says so, and lists its page there)
    adopt_outputs(out, [STORE_MANIFEST])
    return store


def _in_cache_order(todo: list) -> list:
    """The points to compute, each key once (identical inputs: compute once), those that
    share everything but Δτ and q side by side: they share the FEM model and its
    eigen-decomposition, so submitted together the worker caches hit."""
    seen, unique = set(), []
    for p in todo:
        if p.key not in seen:
            seen.add(p.key)
            unique.append(p)
    unique.sort(key=lambda p: canonical({k: v for k, v in p.inputs.items()
                                          if k not in ("dtau_s", "q_W_m2")}))
    return unique


def stored_or_todo(sweep: Sweep, store: PointStore) -> tuple[list, list]:
    """The points of ``sweep`` to compute (absent, or stored but not valid), and
    [(point, why)] for the stored files that failed validation
    (:func:`arfem.scenarios.sweep.store.record_problem`): they are recomputed, never
    trusted."""
    todo, bad = [], []
    for p in sweep.points:
        rec, why = store.check(p.key, p.inputs)
        if rec is None:
            todo.append(p)
            if why is not None:
                bad.append((p, why))
    return todo, bad


def bad_points_line(bad: list) -> str:
    """One line for the stored points that are recomputed because they were not valid."""
    p, why = bad[0]
    more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
    return (f"{len(bad)} stored point(s) not valid, recomputed: points/{p.key}.json: "
            f"{why}{more}")


#: Write errors that are the disk's, not arfem's: no space, quota, read-only, I/O.
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EFBIG}


#: with the default ``workers``, points are first computed in this process for this long
#: [s]; workers start only for what is left. A sweep done by then costs no start-up;
#: one that is not would gain at most this from workers started at once (two workers
#: halve the compute of the rest, and their start-up is ``WORKER_START_S``)
IN_PROCESS_FIRST_S = 2.0 * WORKER_START_S


class PointFailed(Exception):
    """A point that failed inside a task of several points (its message as the worker
    wrote it: ``Type: message``)."""


def evaluate_points(point_fn: Callable, items: list) -> list:
    """Evaluate ``[(data, source), ...]`` one after the other in one process (a worker
    task of a planned sweep, whose points share what the process caches); per point
    ``(True, result)`` or ``(False, "Type: message")``: one failure does not lose the
    task's other points."""
    out = []
    for data, source in items:
        try:
            out.append((True, point_fn(data, source)))
        except Exception as exc:                        # reported per point, as alone
            out.append((False, f"{type(exc).__name__}: {' '.join(str(exc).split())}"))
    return out


def _n_workers(executor) -> int:
    if isinstance(executor, LocalExecutor):
        return executor.workers
    return max(1, executor.n_workers())


def _compute(sweep, points, store, executor, point_fn, rep, run_id, progress,
             in_process_first_s: float = 0.0, plan: Callable | None = None):
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
        if isinstance(exc, PointFailed):
            rep.failures.append({"inputs": p.inputs, "error": str(exc)})
            return
        msg = " ".join(str(exc).split())
        if "deserializ" in msg:
            msg += (" [the Dask scheduler and every worker must be able to import arfem: "
                    "pip install -e <repo> there, or start them with PYTHONPATH=<repo>]")
        rep.failures.append({"inputs": p.inputs, "error": f"{type(exc).__name__}: {msg}"})

    def settle(p: Point, get_result) -> dict | None:
        """Store one finished point as soon as it completes, or record its failure."""
        res = None
        try:
            res = get_result()
        except Exception as exc:
            failed(p, exc)
        else:
            store.put(record(p, res))
            rep.n_computed += 1
        bar.update(1)
        return res

    try:
        if executor is None:
            with blas_threads(1):
                _serial(sweep, points, point_fn, settle)
            return
        if plan is not None:
            _planned(sweep, points, executor, point_fn, rep, settle, plan,
                     in_process_first_s > 0 and isinstance(executor, LocalExecutor))
            return
        if in_process_first_s > 0 and isinstance(executor, LocalExecutor):
            t0 = time.perf_counter()
            with blas_threads(1):
                while points:                     # at least one point, then while in budget
                    _serial(sweep, points[:1], point_fn, settle)
                    points = points[1:]
                    if time.perf_counter() - t0 >= in_process_first_s:
                        break
            done = rep.n_computed + rep.n_failed
            if not points:
                rep.executor = "local, in-process (done before workers were worth starting)"
                return
            rep.executor = f"local, in-process for {done} point{'' if done == 1 else 's'}, then {executor.label}"
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


def _raise(exc: BaseException):
    raise exc


def _planned(sweep, points, executor, point_fn, rep, settle, plan, measure_first: bool):
    """A planned sweep (see :func:`run_in_store`): with the default workers, the first
    point in this process and then ``plan`` on its costs; the runs of points it makes go
    to the workers one task each, so that each worker builds what they share once."""
    first = None
    if measure_first:
        p = points[0]
        with blas_threads(1):
            first = settle(p, lambda: point_fn(p.data, f"{sweep.source} point {p.index}"))
        points = points[1:]
        if not points:
            rep.executor = "local, in-process (one point)"
            return
    chunks = plan(points, first, _n_workers(executor))
    if chunks is None:                 # cheaper here, where the first point left its model
        with blas_threads(1):
            _serial(sweep, points, point_fn, settle)
        rep.executor = ("local, in-process (the points share a model this process holds; "
                        "workers would not finish sooner)")
        return
    if measure_first:
        rep.executor = f"local, in-process for 1 point, then {executor.label}"
    rep.executor += (f", {len(chunks)} task{'s' if len(chunks) > 1 else ''} of adjacent "
                     "points (each worker reuses its model across its task)")
    with executor:
        futs = {executor.submit(evaluate_points, point_fn,
                                [(p.data, f"{sweep.source} point {p.index}") for p in c]): c
                for c in chunks}
        for fut in executor.as_completed(list(futs)):
            try:
                results = fut.result()
            except Exception as exc:              # the whole task: each of its points failed
                results = [(False, exc)] * len(futs[fut])
            for p, (ok, res) in zip(futs[fut], results):
                if ok:
                    settle(p, lambda res=res: res)
                else:
                    err = res if isinstance(res, BaseException) else PointFailed(res)
                    settle(p, lambda err=err: _raise(err))


def run_geometry_sweep(sweep: GeometrySweep, out, *, workers=None, scheduler=None,
                       force: bool = False, progress: bool = True, timeout_s: float = 5.0,
                       worker_wait_s: float = 60.0, point_fn=evaluate_geometry_point,
                       warn=None, limits=None):
    """:func:`run_sweep` for a mesh sweep (:mod:`arfem.scenarios.sweep.geometry_run`): the same store,
    resume, lock, executors and run log; its own record check and outputs."""
    return run_in_store(sweep, out, ready_store=geometry_run.ready_store, order=geometry_run.unique_in_order,
                        write=geometry_run.write_geometry_sweep_outputs, workers=workers,
                        scheduler=scheduler, force=force, progress=progress,
                        timeout_s=timeout_s, worker_wait_s=worker_wait_s, point_fn=point_fn,
                        warn=warn or note, limits=limits, plan=geometry_run.plan_tasks)
