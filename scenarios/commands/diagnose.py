"""``arfem diagnose CASE.toml --out DIR``: what the nominal simulation gets wrong on a
measured record, the physical cause, and the hold-out gain of the extended model.

Writes ``diagnosis.json`` (the measured-data contract's keys and more), ``report.md``,
``series.csv``, figures, ``report.html`` and the compensator models fitted on the same
window (``model.json``: the paper's AR(1); ``model_mlr.json``: eq. 18 where the record has
temperatures; see ``arfem compensate``), atomically. Bad input: one line, exit 2, ``--out`` untouched.
"""
from __future__ import annotations

from arfem.models.diagnosis.engine import SPEED_ENGINES
from arfem.scenarios.diagnosis import run as diagnosis_run
from arfem.scenarios.diagnosis.document import document
from arfem.scenarios.diagnosis.terminal import diagnosis_terminal_line
from arfem.scenarios.progress import Progress, add_progress_flag

__all__ = ["add_parser", "main"]


def add_parser(subparsers):
    p = subparsers.add_parser(
        "diagnose", help="diagnose a measured record (contract TOML + CSV)",
        description="Compare a measured record with the nominal simulation, name the cause "
                    "of the difference, and score the extended model on a hold-out. A "
                    "record whose TOML has a [model] table (contract v3, e.g. the "
                    "record.toml of a mesh run) is checked against that mesh scenario, "
                    "with causes on its own groups, always by the one pipeline; "
                    "--frame-search, --drift-last and --stability apply to records on "
                    "the rod only, --speed-engine to its speed_rpm records.")
    p.add_argument("case", help="dataset TOML (measured-data contract; a contract-v3 "
                                "record also by its CSV)")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--holdout-start", type=float, default=None, metavar="SECONDS",
                   help="start of the hold-out [s]; default: the last third of the record "
                        "if it holds a change of the input, else from the last such change")
    p.add_argument("--speed-engine", choices=SPEED_ENGINES, default=None,
                   help="speed_rpm records: which engine diagnoses them -- the rod "
                        "engine's speed branch, candidates chosen by forward-chaining "
                        "validation, the published procedure (branch, default), or the one "
                        "diagnosis pipeline on the speed plant, candidates screened by BIC "
                        "on N_eff with frames per thermometer (pipeline; --frame-search and "
                        "--drift-last do not apply to it). q_W_m2 and mesh records always "
                        "run the pipeline. The default stays branch: the pipeline failed "
                        "its pre-registered comparison on the real record "
                        "(reports/fl_thermal/switch.md)")
    p.add_argument("--frame-search", choices=("narrow", "wide", "average"), default=None,
                   help="speed-only records on the speed branch: frame structures compared "
                        "by validation -- "
                        "thermometer components only (narrow, default) or also speed-to-heat "
                        "laws n^p and a slow frame response (wide, ~5x slower), or no choice: "
                        "the average of every narrow structure (average)")
    p.add_argument("--drift-last", action="store_true",
                   help="speed-only records on the speed branch (post hoc, not the "
                        "default): name sensor_drift "
                        "(a linear drift in time) only if no cause driven by the recorded "
                        "inputs passes the naming test (its rolling-origin evaluation on the "
                        "real record: reports/fl_thermal/README.md)")
    p.add_argument("--stability", type=int, nargs="?", const=10, default=0, metavar="N",
                   help="also say how stable the verdict is across hold-out splits: rerun "
                        "the diagnosis (without intervals) with its hold-out from each of up "
                        "to N rolling origins (input changes in the last 60 %% of the "
                        "record; N = 10 if not given); off by default, as it costs about N "
                        "diagnoses")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out")
    add_progress_flag(p)
    p.set_defaults(func=main)
    return p


def main(args) -> int:
    from arfem.scenarios.records.dataset import read_record_doc
    from arfem.scenarios.diagnosis.mesh import main_geodiagnose
    doc = read_record_doc(args.case, args.limits)    # the record's TOML, read once
    if doc.is_mesh:                      # contract v3: the record names a mesh scenario
        diagnosis_run.speed_options("mesh", args.speed_engine, args.frame_search,
                                    args.drift_last, args.case)   # before any work
        rc = main_geodiagnose(args, doc)
        rod_only = [f for f, on in (("--frame-search", args.frame_search not in (None, "narrow")),
                                    ("--drift-last", args.drift_last),
                                    ("--stability", args.stability)) if on]
        if rod_only:
            one = len(rod_only) == 1
            print(f"note: {' and '.join(rod_only)} appl{'ies' if one else 'y'} to records on "
                  f"the rod only; this mesh record (contract v3) was diagnosed without "
                  f"{'it' if one else 'them'}")
        return rc
    with Progress(12 + max(args.stability, 0), "arfem diagnose",
                  enabled=not args.no_progress) as progress:
        d = diagnosis_run.diagnose_and_write(doc, args.out, args.holdout_start, args.force,
                                             args.frame_search, progress, args.drift_last,
                                             args.limits, args.stability,
                                             args.speed_engine)
    s = document(d)
    print(diagnosis_terminal_line(d) + f"; wrote {args.out}")
    if s.get("verdict_detail"):
        print(f"verdict ({s['verdict']}): {s['verdict_detail']['text']}")
    h = s["holdout"]
    print(f"hold-out: from {h['start_s']:g} s; {h['how_chosen']}")
    for w in s.get("warnings", []):
        print(f"warning: {w}")
    ignored = [f for f, on in (("--frame-search", args.frame_search not in (None, "narrow")),
                               ("--drift-last", args.drift_last)) if on]
    if ignored and s.get("input_kind") != "speed_rpm":
        print(f"note: {' and '.join(ignored)} apply to speed_rpm records only; this "
              f"{s.get('input_kind')} record was diagnosed without them")
    return 0
