"""``arfem allocate SCENARIO --out DIR [--force]``: precision allocation over a motion chain.

The command's parser and printed line only; the allocation and its files are the library
:mod:`arfem.scenarios.allocation.run` (what it writes is listed there).
"""
from __future__ import annotations

from arfem.models.allocation.problem import MAX_EVALUATIONS
from arfem.scenarios.allocation.run import (WRITES, allocation_terminal_line, run_allocation,
                                           write_allocation)
from arfem.scenarios.outdir import prepare_out_dir, staged_out_dir


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "allocate", help="precision allocation over a chain of meta-action units (NSGA-II)",
        description="Allocate tolerances to the meta-action units of a motion chain "
                    "(after Zhou et al. 2020): min(cost, worst-case stack) s.t. stack <= "
                    "delta_E, or the paper's printed model (formula = \"paper_literal\").")
    p.add_argument("scenario", help="allocation scenario TOML (e.g. scenarios/data/pallet_changer.toml)")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--force", action="store_true", help="replace files in a non-empty --out")
    p.add_argument("--seeds", type=int, default=None,
                   help="seeds to run (default 3 for screw, 20 for paper_literal)")
    p.add_argument("--no-work-limit", action="store_true",
                   help=f"allow pop_size x n_gen above {MAX_EVALUATIONS:,} evaluations per run")
    p.set_defaults(func=main)


def main(args) -> int:
    out = prepare_out_dir(args.out, args.force, inputs=[args.scenario],
                          writes=WRITES)            # refuse early, before computing
    limit = None if getattr(args, "no_work_limit", False) else MAX_EVALUATIONS
    run = run_allocation(args.scenario, getattr(args, "seeds", None), limit,
                         getattr(args, "limits", None))
    command = f"arfem allocate {args.scenario} --out {args.out}" + (" --force" if args.force else "")
    with staged_out_dir(out, args.force) as stage:
        alloc = write_allocation(run, stage, command)
    print(allocation_terminal_line(run, alloc, out))
    return 0
