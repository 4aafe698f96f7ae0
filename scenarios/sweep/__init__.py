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

This package is a library (the API, the benchmarks and the tests import it); the
command's parser and printed lines live in :mod:`arfem.scenarios.commands.sweep`.
"""
from __future__ import annotations

from arfem.scenarios.sweep.executors import blas_threads, clear_worker_cache, evaluate_point
from arfem.scenarios.sweep.report import (biot_threshold, render_readme, results_rows,
                                          rows_to_csv, thresholds, write_outputs)
from arfem.scenarios.sweep.runner import (DEFAULT_WORKER_WAIT_S, MAX_CONNECT_S, MAX_WAIT_S,
                                          RunReport,
                                          run_sweep)
from arfem.scenarios.sweep.spec import (CORE_INPUTS, METRIC_COLUMNS, STORE_VERSION,
                                        TIMING_COLUMNS, Point, Sweep, load_sweep, point_key,
                                        resolved_inputs, sweep_from_dict, MAX_POINTS)
from arfem.scenarios.sweep.store import PointStore

__all__ = ["Sweep", "Point", "PointStore", "load_sweep", "sweep_from_dict", "point_key",
           "resolved_inputs", "evaluate_point", "blas_threads", "clear_worker_cache",
           "run_sweep", "RunReport", "results_rows", "rows_to_csv", "biot_threshold",
           "thresholds", "render_readme", "write_outputs",
           "STORE_VERSION", "METRIC_COLUMNS", "CORE_INPUTS", "TIMING_COLUMNS", "MAX_POINTS",
           "DEFAULT_WORKER_WAIT_S", "MAX_CONNECT_S", "MAX_WAIT_S"]
