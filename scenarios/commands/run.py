"""``arfem run`` and ``arfem reproduce``: one scenario, FEM against AR(1), all outputs.

The command only parses and prints: the computation is
:func:`arfem.scenarios.rod.evaluation.evaluate`, the files are written by
:mod:`arfem.scenarios.rod.outputs`.
"""
from __future__ import annotations

import time
from pathlib import Path

from arfem.scenarios.rod.scenario import PAPER_SCENARIOS
from arfem.scenarios.rod.evaluation import Evaluation
from arfem.scenarios.progress import add_progress_flag
from arfem.scenarios.rod.outputs import check_reproduction, reproduce, run_scenario

__all__ = ["add_parser"]


# -- CLI -----------------------------------------------------------------------------------

def _print_summary(ev: Evaluation, out) -> None:
    m = ev.metrics
    print(f"{ev.scenario.name}: FEM peak {m['fem_peak_um']:.3f} µm, AR peak {m['ar_peak_um']:.3f} µm, "
          f"max|AR-FEM| {m['max_abs_diff_um']:.3f} µm ({m['max_abs_diff_pct_of_peak']:.2f} % of "
          f"peak), corrected {m['corrected_max_abs_diff_pct_of_peak']:.4f} %; "
          f"C1 {m['C1']:.5f} (fitted {m['C1_fitted']:.5f}) -> {out}")


def _main_run(args) -> int:
    from arfem.io import read_toml_file
    from arfem.scenarios.geometry import scenario as geo     # a [geometry] scenario (issue 32)
    from arfem.scenarios.rod.scenario import load_scenario
    from arfem.scenarios.shipped import scenario_file
    path = scenario_file(args.scenario)
    toml = read_toml_file(path, args.limits)          # the scenario, read once
    if toml.has_table("geometry"):
        return geo.main_run_geometry(args, toml, path)
    from arfem.scenarios.progress import Progress
    with Progress(7, "arfem run", enabled=not args.no_progress) as progress:
        ev = run_scenario(load_scenario(path, args.limits, toml), args.out, args.force,
                          progress=progress, limits=args.limits)
    _print_summary(ev, args.out)
    return 0


def _main_reproduce(args) -> int:
    from arfem.scenarios.progress import Progress
    t0 = time.perf_counter()
    if args.check:
        drifts = check_reproduction(args.out)
        for d in drifts:
            print(f"DRIFT {d}")
        print(f"reproduce --check: {len(PAPER_SCENARIOS)} scenarios recomputed against "
              f"{args.out}: " + (f"{len(drifts)} drifts" if drifts else
                                 "every number within tolerance")
              + f" ({time.perf_counter() - t0:.1f} s)")
        return 1 if drifts else 0
    with Progress(7 * len(PAPER_SCENARIOS) + 1, "arfem reproduce",
                  enabled=not args.no_progress) as progress:
        evs = reproduce(args.out, args.force, progress=progress)
    for ev in evs:
        _print_summary(ev, Path(args.out) / ev.scenario.name)
    print(f"reproduced {len(evs)} paper scenarios into {args.out} in "
          f"{time.perf_counter() - t0:.1f} s")
    return 0


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run one scenario: FEM vs AR(1), all outputs",
                       description="Run one scenario file into --out. The paper's rod "
                                   "([rod]): the FEM against the paper's AR(1) and the "
                                   "corrected AR(1); writes timeseries.csv, summary.json, "
                                   "summary.md, figure.png, model.json, "
                                   "model_corrected.json, scenario.toml, report.html and, "
                                   "as [outputs] asks, temperature_3d.png and the fields "
                                   "(fields/fields.xdmf3, fields/fields.h5, "
                                   "fields/peak.xdmf). A mesh scenario ([geometry], e.g. "
                                   "scenarios/data/spindle_unit.toml): each sensor's history; "
                                   "writes sensors.csv, sensors.json, summary.json, "
                                   "summary.md, sensors.png, model.json (version 2), "
                                   "record.toml + record.csv (the run as a contract-v3 "
                                   "record, for arfem compensate and arfem diagnose), "
                                   "scenario.toml with a copy of its mesh (re-runnable from "
                                   "any directory), report.html and, as [outputs] asks, "
                                   "geometry.png (on by default) and the fields "
                                   "(fields/fields.xdmf3, fields/fields.h5; off by "
                                   "default).")
    p.add_argument("scenario", help="scenario TOML file (or a built-in name: paper_fig2, paper_fig3)")
    p.add_argument("--out", required=True, help="output directory (must be new or empty)")
    p.add_argument("--force", action="store_true", help="replace files in a non-empty --out")
    add_progress_flag(p)
    p.set_defaults(func=_main_run)
    r = sub.add_parser("reproduce", help="regenerate the paper's Fig. 2 and 3 into reports/paper/",
                       description="Run every paper scenario into reports/paper/ with a README "
                                   "that sets arfem's numbers beside the paper's.")
    r.add_argument("--out", default="reports/paper", help="output directory (default: reports/paper)")
    r.add_argument("--force", action="store_true", help="replace a non-empty --out that is not "
                                                        "an earlier reproduce result")
    r.add_argument("--check", action="store_true",
                   help="write nothing: recompute the numbers and compare them with the "
                        "committed summary.json and timeseries.csv files in --out; exit 1 "
                        "on a drift beyond 2 units in the last written decimal")
    add_progress_flag(r)
    r.set_defaults(func=_main_reproduce)
