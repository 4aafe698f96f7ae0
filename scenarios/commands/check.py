"""``arfem check``: "the AR(1) model tracks the FEM" as a gate for a user's CI.

The checks, their limits and reports are :mod:`arfem.scenarios.rod.checking`; this module
parses the command line, writes the reports asked for and prints one line. Exit status:
0 every criterion of every scenario holds, 1 at least one fails, 2 bad input.
"""
from __future__ import annotations

import time

from arfem.io import atomic_write_bytes, write_json
from arfem.scenarios.gate import check_report_path, json_report, junit_xml
from arfem.scenarios.rod.checking import run_checks
from arfem.scenarios.rod.scenario import CHECK_MODELS

__all__ = ["add_parser"]


# -- CLI -------------------------------------------------------------------------------------

def _main(args) -> int:
    junit = check_report_path(args.junit, "--junit") if args.junit else None
    jpath = check_report_path(args.json, "--json") if args.json else None
    t0 = time.perf_counter()
    results, skipped = run_checks(args.paths, args.max_abs_pct, args.max_c1_diff, args.model,
                                  limits=args.limits)
    wall = time.perf_counter() - t0
    n_ok = sum(r.passed for r in results)
    if junit is not None:
        atomic_write_bytes(junit, junit_xml(results, skipped, wall))
    if jpath is not None:
        write_json(jpath, json_report(results, skipped))
    print(f"{n_ok} passed, {len(results) - n_ok} failed"
          + (f", {len(skipped)} skipped" if skipped else "") + f" ({wall:.1f} s)")
    return 0 if n_ok == len(results) else 1


def add_parser(sub) -> None:
    p = sub.add_parser(
        "check", help="CI gate: does the AR(1) track the FEM? exit 0 pass, 1 fail, 2 bad input",
        description="Run each scenario (or every scenario file directly in a directory) and "
                    "hold the AR(1) model to the FEM: max|AR - FEM| in % of the FEM peak and "
                    "|C1 fitted to the FEM - C1 of the AR|. Limits: these flags, else the "
                    "scenario's [check] table, else 3 % and 5e-4. A mesh scenario "
                    "([geometry]) is held per displacement sensor: the slowest-mode AR(1) "
                    "(or --model paper: the lumped one), max|AR - FEM| in % of the largest "
                    "FEM drift, default 15 %. Exit status 0 when every "
                    "criterion holds, 1 when any fails, 2 on bad input.")
    p.add_argument("paths", nargs="+", metavar="SCENARIO_OR_DIR",
                   help="scenario TOML files or directories of them (or paper_fig2/3)")
    p.add_argument("--max-abs-pct", type=float, metavar="P", default=None,
                   help="limit on max|AR - FEM| [%% of the FEM peak growth] (default 3; on a "
                        "mesh scenario, of the largest FEM drift, default 15)")
    p.add_argument("--max-c1-diff", type=float, metavar="D", default=None,
                   help="limit on |C1 fitted - C1 of the AR| [-] (default 5e-4)")
    p.add_argument("--model", choices=CHECK_MODELS, default=None,
                   help="the AR(1) checked: paper (eqs. 12-14, default) or corrected "
                        "(radial-mode corrected); on a mesh scenario paper is the lumped "
                        "AR(1) and corrected (its default) the slowest-mode one")
    p.add_argument("--junit", metavar="FILE", help="write JUnit XML here (for CI services)")
    p.add_argument("--json", metavar="FILE", help="write the results as JSON here")
    p.set_defaults(func=_main)
