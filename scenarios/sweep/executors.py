"""Where points are computed: one point (:func:`evaluate_point`), in this process, in
local worker processes, or on a Dask distributed cluster; BLAS held single-threaded
(:func:`blas_threads`, through threadpoolctl) so that every executor gives the same bits."""
from __future__ import annotations

import logging
import os
import socket
import threading
import time
import math
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

import numpy as np

from arfem.limits import Limits
from arfem.params import InputError
from arfem.scenarios.rod.scenario import scenario_from_dict
from arfem.scenarios.rod.deterministic import blas_threads

#: worker start-up [s] on a 2-core machine (spawning and importing numpy, scipy, arfem);
#: the shipped 156-point sweep computed in 2.5-3.1 s in-process against 3.9 s on the
#: default 2 workers (issue 30)
WORKER_START_S = 1.5

__all__ = ["evaluate_point", "blas_threads", "LocalExecutor", "DaskExecutor",
           "clear_worker_cache", "ClusterLost"]

# -- evaluating one point (runs in a worker) ----------------------------------------------

_WORKER_CACHE: dict = {}
#: entries kept per worker before the cache is cleared (all at once: entries refer to
#: their model by id). The shipped sweep needs 104 (13 h: model and modes, and one
#: unit-flux growth per Δτ); 24 cleared it every few points, 84 eigen-decompositions
#: for 13 distinct h. Entries are small (an axisymmetric model's dense modes ~3 MB).
_WORKER_CACHE_MAX = 128


def evaluate_point(data: dict, source: str = "<sweep point>",
                   limits: Limits | None = None) -> dict:
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
    limits : arfem.limits.Limits, optional
        What the user allows past the size limits, passed from the parent (a worker
        process or a Dask worker sees no flag of the command that started it).

    Returns
    -------
    dict
        ``{"metrics": {...}, "run_time_s": float, "worker": "host:pid"}``.
    """
    from arfem.scenarios.rod.evaluation import evaluate
    t0 = time.perf_counter()
    scenario = scenario_from_dict(data, source, limits)
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



# -- executors ----------------------------------------------------------------------------

#: BLAS limits kept for the life of a worker process: the same single-threaded BLAS as a
#: Dask nanny worker, so local and Dask runs agree bit for bit (threadpoolctl, set by the
#: worker's initializer, after SciPy's own OpenBLAS is loaded; no environment is written).
_LIMITED = []


def clear_worker_cache() -> None:
    """Forget the models and eigen-decompositions cached in this process (benchmarks)."""
    _WORKER_CACHE.clear()


def _worker_init(ppid: int) -> None:        # pragma: no cover - runs in worker processes
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # Ctrl-C is the parent's to handle
    _LIMITED.append(blas_threads(1))
    _watch_parent(ppid)


def _watch_parent(ppid: int) -> None:       # pragma: no cover - runs in worker processes
    def loop():
        while True:
            time.sleep(1.0)
            if os.getppid() != ppid:
                os._exit(1)
    threading.Thread(target=loop, daemon=True).start()


class LocalExecutor:
    """Worker processes on this machine (spawned, single-threaded BLAS)."""

    def __init__(self, workers: int):
        self.workers = workers
        self.pool = None
        self.label = f"local, {workers} worker process{'es' if workers > 1 else ''}"

    def __enter__(self):
        import multiprocessing as mp
        self.pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                        initializer=_worker_init, initargs=(os.getpid(),))
        list(self.pool.map(abs, range(self.workers)))       # start the workers now
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



def _probe_scheduler(address: str, timeout_s: float) -> None:
    """Raise unless a Dask scheduler answers an ``identity`` request at ``address``."""
    import asyncio
    from distributed.comm import connect
    from distributed.comm.addressing import parse_address
    from distributed.comm.registry import get_backend

    scheme, loc = parse_address(address)
    get_backend(scheme)                              # ValueError: unknown scheme
    if scheme == "inproc":       # only a scheduler started in this very process answers
        from distributed.comm.inproc import global_manager
        if global_manager.get_listener_for(loc) is None:
            raise ConnectionError("no scheduler in this process listens there (an inproc:// "
                                  "address is only reachable from the process that made it)")
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
        _LIMITED.append(blas_threads(1))
    return fn(*args)


class ClusterLost(InputError):
    """The Dask cluster cannot finish the sweep (no worker, or the scheduler gone)."""


_NOISY_LOGGERS = ("distributed", "tornado", "asyncio")


def _silence_distributed() -> dict:
    """distributed logs (and prints tracebacks for) every lost connection; the sweep says
    what happened in one line of its own instead. Returns the levels to restore."""
    names = set(_NOISY_LOGGERS) | {n for n in logging.Logger.manager.loggerDict
                                   if n.split(".")[0] in _NOISY_LOGGERS}
    saved = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL + 1)
    return saved


def _restore_logging(saved: dict) -> None:
    for n, lv in saved.items():
        logging.getLogger(n).setLevel(lv)


class DaskExecutor:
    """The same tasks on a Dask distributed cluster.

    While the tasks run it watches the cluster once a second: if the scheduler stops
    answering, or no worker is connected for ``worker_wait_s`` seconds in a row (none
    ever came, or all died), it raises :class:`ClusterLost` (one line); the points
    already stored are kept and the same command resumes them.
    """

    def __init__(self, address: str, timeout_s: float = 5.0, worker_wait_s: float = 60.0):
        self.address = address
        self.timeout_s = timeout_s
        self.worker_wait_s = worker_wait_s
        self.client = None
        self.submitted = []
        self.label = f"dask scheduler {address}"
        self._saved_levels = None

    def connect(self):
        try:
            from dask.distributed import Client
        except ImportError:                                     # pragma: no cover
            raise InputError("dask.distributed is not installed", "--scheduler") from None
        def fail(exc):
            msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            return InputError(f"cannot reach the Dask scheduler at {self.address!r} within "
                              f"{self.timeout_s:g} s ({msg})", "--scheduler")

        self._saved_levels = _silence_distributed()
        try:        # a bare probe first: a failed Client() leaves a noisy half-made object
            _probe_scheduler(self.address, self.timeout_s)
        except Exception as exc:      # OSError, TimeoutError, ValueError for a bad address
            self.close()
            raise fail(exc) from None
        try:
            self.client = Client(self.address, timeout=self.timeout_s, set_as_default=False)
        except Exception as exc:                                # pragma: no cover - races
            self.close()
            raise fail(exc) from None
        n = self.n_workers()
        self.label = f"dask scheduler {self.address} ({n} workers at the start)"
        return self

    def n_workers(self) -> int:
        """Workers connected to the scheduler now (asks the scheduler, bounded wait)."""
        try:
            return len(self.client.sync(self.client.scheduler.ncores,
                                        callback_timeout=min(self.timeout_s, 10.0)))
        except Exception:
            return -1                       # no answer: the scheduler is gone or stuck

    def __enter__(self):
        if self.client is None:
            self.connect()
        return self

    def submit(self, fn, *args):
        fut = self.client.submit(_single_threaded_call, fn, *args, pure=False)
        self.submitted.append(fut)
        return fut

    def _lost(self, what: str) -> ClusterLost:
        return ClusterLost(f"{what}; the points finished so far are stored and the same "
                           "command resumes the rest", "--scheduler")

    def as_completed(self, futures):
        """Yield futures as they finish; raise :class:`ClusterLost` if the cluster dies."""
        from distributed import as_completed
        ac = as_completed(futures, loop=self.client.loop)
        idle_since, checked = None, time.monotonic()
        left = len(futures)
        while left:
            try:
                done = ac.next_batch(block=False)
            except Exception:
                raise self._lost(f"the Dask scheduler at {self.address} stopped answering") \
                    from None
            for fut in done:
                if fut.status == "cancelled":          # the client lost its scheduler
                    raise self._lost(f"the Dask scheduler at {self.address} stopped "
                                     "answering (its tasks were cancelled)")
                left -= 1
                yield fut
            if not left:
                break
            if done or time.monotonic() - checked < 1.0:
                time.sleep(0.05)
                continue
            checked = time.monotonic()
            if self.client.status not in ("running", "newly-created"):
                raise self._lost(f"the Dask scheduler at {self.address} stopped answering")
            n = self.n_workers()
            if n < 0:
                raise self._lost(f"the Dask scheduler at {self.address} stopped answering")
            if n > 0:
                idle_since = None
                continue
            now = time.monotonic()
            idle_since = now if idle_since is None else idle_since
            if now - idle_since >= self.worker_wait_s:
                raise self._lost(f"the Dask cluster at {self.address} has had no worker for "
                                 f"{self.worker_wait_s:g} s (--worker-wait), with "
                                 f"{left} points left to compute")

    def close(self) -> None:
        """Cancel what is queued, disconnect (bounded), let distributed talk again."""
        client, self.client = self.client, None
        if client is not None:
            try:
                if self.submitted:
                    client.cancel(self.submitted, force=True)
            except Exception:
                pass
            try:
                client.close(timeout=min(self.timeout_s, 5.0))
            except Exception:
                pass
        self.submitted = []
        if self._saved_levels is not None:
            _restore_logging(self._saved_levels)
            self._saved_levels = None

    def __exit__(self, exc_type, *exc):
        self.close()
