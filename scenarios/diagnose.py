"""``arfem diagnose CASE.toml --out DIR``: what the nominal simulation gets wrong on a
measured record, the physical cause, and the hold-out gain of the extended model.

Writes ``diagnosis.json`` (the measured-data contract's keys and more), ``report.md``,
``series.csv`` and figures, atomically. Bad input: one line, exit 2, ``--out`` untouched.
"""
from __future__ import annotations

from arfem.models.diagnosis.engine import Diagnosis, diagnose
from arfem.scenarios.dataset import load_dataset
from arfem.scenarios.outdir import prepare_out_dir, staged_out_dir

__all__ = ["add_parser", "main", "run_diagnosis", "diagnose_file"]

#: The files ``write_all`` puts into --out (checked before the work: never an input or
#: a file arfem did not write; see arfem.scenarios.outdir).
WRITES = ("diagnosis.json", "report.md", "series.csv", "growth_residual.png",
          "correlations.png")


def diagnose_file(toml_path, holdout_start_s=None, frame_search: str = "narrow") -> Diagnosis:
    """Load a contract dataset (TOML + CSV) and diagnose it."""
    return diagnose(load_dataset(toml_path), holdout_start_s, frame_search)


def add_parser(subparsers):
    p = subparsers.add_parser(
        "diagnose", help="diagnose a measured record (contract TOML + CSV)",
        description="Compare a measured record with the nominal simulation, name the cause "
                    "of the difference, and score the extended model on a hold-out.")
    p.add_argument("case", help="dataset TOML (measured-data contract)")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--holdout-start", type=float, default=None, metavar="SECONDS",
                   help="start of the hold-out [s]; default: the last third of the record")
    p.add_argument("--frame-search", choices=("narrow", "wide"), default="narrow",
                   help="speed-only records: frame structures compared by validation -- "
                        "thermometer components only (narrow, default) or also speed-to-heat "
                        "laws n^p and a slow frame response (wide, ~5x slower)")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    p.set_defaults(func=main)
    return p


def run_diagnosis(case, out, holdout_start_s=None, force=False, frame_search="narrow"):
    """Diagnose ``case`` (TOML path) and write every output into ``out``; returns the summary."""
    from arfem.scenarios.diagnosis_report import write_all
    prepare_out_dir(out, force, inputs=[case], writes=WRITES)   # refuse early, before any work
    diag = diagnose_file(case, holdout_start_s, frame_search)
    with staged_out_dir(out, force) as stage:
        write_all(diag, stage)
    return diag.summary


def main(args) -> int:
    s = run_diagnosis(args.case, args.out, args.holdout_start, args.force, args.frame_search)
    h = s["holdout"]
    print(f"{s['dataset']}: cause = {s['cause']}; hold-out RMSE {h['baseline_rmse_um']:.3g} -> "
          f"{h['extended_rmse_um']:.3g} µm (gain {h['gain_pct']:.1f} %); wrote {args.out}")
    return 0
