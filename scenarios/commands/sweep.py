"""``arfem sweep SWEEP.toml --out DIR``: the command's parser and printed lines only; the
sweep itself is the library :mod:`arfem.scenarios.sweep` (load_sweep, run_sweep)."""
from __future__ import annotations

import sys
from pathlib import Path

from arfem.params import InputError
from arfem.scenarios.sweep.runner import (DEFAULT_WORKER_WAIT_S, MAX_CONNECT_S, MAX_WAIT_S,
                                          run_sweep)
from arfem.scenarios.sweep.spec import MAX_POINTS, load_sweep


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
                   help="local worker processes (default: all cores; capped at the cores "
                        "and at the points to compute, with a note; 1 = in-process)")
    p.add_argument("--connect-timeout", type=float, default=5.0, metavar="S",
                   help=f"seconds to wait for the Dask scheduler (default 5, at most "
                        f"{MAX_CONNECT_S:g})")
    p.add_argument("--worker-wait", type=float, default=DEFAULT_WORKER_WAIT_S, metavar="S",
                   help=f"end the sweep (exit 2, stored points kept) once the Dask cluster "
                        f"has had no worker for S seconds (default {DEFAULT_WORKER_WAIT_S:g}, "
                        f"at most {MAX_WAIT_S:g})")
    p.add_argument("--max-points", type=int, default=None, metavar="N",
                   help=f"accept a grid of up to N points (default {MAX_POINTS}; the size is "
                        "checked from the grid before anything is resolved)")
    p.add_argument("--force", action="store_true",
                   help="run in a non-empty --out that holds something else")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=main)


def main(args) -> int:
    if args.max_points is not None and args.max_points < 1:
        raise InputError(f"must be a whole number >= 1, got {args.max_points}", "--max-points")
    sweep = load_sweep(args.sweep_file, max_points=args.max_points, limits=args.limits)
    rep = run_sweep(sweep, args.out, workers=args.workers, scheduler=args.scheduler,
                    force=args.force, progress=not args.no_progress,
                    timeout_s=args.connect_timeout, worker_wait_s=args.worker_wait,
                    limits=args.limits)
    print(f"sweep {sweep.name!r}: {rep.n_points} points ({rep.n_stored_before} already "
          f"stored, {rep.n_computed} computed, {rep.n_failed} failed) in {rep.wall_s:.1f} s "
          f"[{rep.executor}] -> {Path(args.out) / 'results.csv'}")
    if rep.failures:                    # one line, however many points and kinds of error
        kinds: dict = {}
        for f in rep.failures:
            kinds.setdefault(f["error"].split(":", 1)[0], []).append(f)
        first = max(kinds.values(), key=len)[0]
        more = f" ({len(kinds)} kinds of error)" if len(kinds) > 1 else ""
        print(f"arfem: {rep.n_failed} point(s) failed{more}, e.g. {first['inputs']}: "
              f"{first['error'][:300]}; each is listed in {Path(args.out) / 'summary.json'} "
              "and is computed again by the same command", file=sys.stderr)
    return 1 if rep.n_failed else 0
