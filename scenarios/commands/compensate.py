"""``arfem compensate MODEL.json RECORD.toml --out DIR``: replay a compensator on a record.

Strictly causal (:func:`arfem.scenarios.compensation.replay.replay`, the one replay of a
version-1 model's one axis and a version-2 model's several): the record is stepped
through row by row, and each axis's offset for interval k is computed from the inputs of
rows up to k only (the same call a live loop makes). What is left after the offset is
applied -- the residual the seed paper's Fig. 8 shows -- is measured + offset.

Writes (:mod:`arfem.scenarios.compensation.report`) ``compensated.csv`` (per row: inputs,
per axis the measured and predicted displacement, offset, residual), ``summary.json``,
``summary.md`` (the verdict first), ``figure.png`` (in the manner of the paper's Fig. 8:
uncompensated against compensated error per axis, the inputs below) and
``report.html``.

``--probe-every DURATION`` (e.g. ``1h``, ``4h``, ``900s``): a measured growth is used
only at those instants, to correct the model's state by a Kalman update.
"""
from __future__ import annotations

import math
import re

from arfem.params import InputError
from arfem.scenarios.compensation.model_file import read_model
from arfem.scenarios.compensation.replay import axis_limits, replay
from arfem.scenarios.compensation.report import replay_terminal_line, write_replay
from arfem.scenarios.html_report import write_html_report
from arfem.scenarios.outdir import prepare_out_dir, staged_out_dir

__all__ = ["parse_duration_s", "axis_limits", "add_parser", "main", "WRITES"]

WRITES = ("compensated.csv", "summary.json", "summary.md", "figure.png", "report.html")


def parse_duration_s(text: str, where: str = "--probe-every") -> float:
    """``"4h"``, ``"30min"``, ``"900s"`` or ``"900"`` (seconds) → seconds.

    >>> parse_duration_s("4h"), parse_duration_s("30min"), parse_duration_s("900")
    (14400.0, 1800.0, 900.0)
    """
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*(h|min|s)?\s*", str(text))
    if not m:
        raise InputError(f"must be a duration such as 1h, 30min or 900s, got {text!r}", where)
    v = float(m.group(1)) * {"h": 3600.0, "min": 60.0, "s": 1.0, None: 1.0}[m.group(2)]
    if v <= 0:
        raise InputError(f"must be > 0, got {text!r}", where)
    return v


def add_parser(sub) -> None:
    p = sub.add_parser(
        "compensate", help="replay a compensator (model.json) on a measured record",
        description="Step a state-space model (model.json, written by arfem run or arfem "
                    "diagnose) through a "
                    "measured record strictly causally, apply the offset each interval, and "
                    "report the error that is left (the seed paper's Fig. 8).")
    p.add_argument("model", help="model.json (written by arfem run or arfem diagnose)")
    p.add_argument("record", nargs="?", help="dataset TOML (measured-data contract); "
                   "not with --live")
    p.add_argument("--out", help="output directory (replay)")
    p.add_argument("--live", metavar="CONFIG.toml",
                   help="run live instead of replaying, with the transport the config "
                        "names: an OPC UA client (reads the input nodes, writes the offset "
                        "node every period_s) or JSON lines on stdin/stdout "
                        "(docs: arfem compensate)")
    p.add_argument("--max-offset-um", type=float, default=math.inf, metavar="UM",
                   help="largest |offset| written [µm] (default: no limit; with --live "
                        "the config's, and a value given here may only tighten it: a "
                        "larger one is refused)")
    p.add_argument("--max-step-um", type=float, default=math.inf, metavar="UM",
                   help="largest change of the offset per cycle [µm] (default: no limit; "
                        "with --live as --max-offset-um)")
    p.add_argument("--axis-limits", action="append", default=None,
                   metavar="AXIS=OFFSET:STEP",
                   help="a version-2 model's clamp and step limit of one axis [µm], e.g. "
                        "X=20:0.5 (repeat per axis); axes not named take --max-offset-um "
                        "and --max-step-um; with --live each may only tighten the "
                        "config's limit of that axis (a larger one is refused)")
    p.add_argument("--probe-every", default=None, metavar="DURATION",
                   help="use the measured growth only every DURATION (1h, 30min, 900s) to "
                        "correct the model's state (Kalman update); default: never "
                        "(replay only: refused with --live)")
    p.add_argument("--score-from", type=float, default=None, metavar="SECONDS",
                   help="measure the error from this time on [s]; default: after the "
                        "model's fit window (fit_window_s in model.json), or every row for "
                        "a model without one; 0 scores every row. The replay itself "
                        "always starts at the first row (replay only: refused with --live)")
    p.add_argument("--no-observer", action="store_true",
                   help="run the model open loop: do not correct its state from the "
                        "thermometers even where model.json has an observer (by default "
                        "it is used when the record or stream has its thermometers)")
    p.add_argument("--force", action="store_true", help="write into a non-empty --out "
                   "(replay only: refused with --live)")
    p.set_defaults(func=main)


#: options of a replay that a live run has no use for: refused with --live, one line
LIVE_REFUSES = (("record", "RECORD", "a live run reads its inputs from the config's "
                 "transport, not from a record"),
                ("out", "--out", "a live run writes stdout (JSON lines) and the config's "
                 "log, not a folder"),
                ("probe_every", "--probe-every", "a live run reads no measured growth to "
                 "correct its state with"),
                ("score_from", "--score-from", "a live run scores nothing (it has no "
                 "measured growth)"),
                ("force", "--force", "a live run writes no --out (its log is appended "
                 "to, never replaced)"))


def _refuse_replay_options(args) -> None:
    """One line naming the first option of a replay given with ``--live``."""
    for attr, opt, why in LIVE_REFUSES:
        v = getattr(args, attr, None)
        if v is not None and v is not False:        # (not `in`: --score-from 0 == False)
            raise InputError(f"is for a replay, not with --live: {why}", opt)


def main(args) -> int:
    """``arfem compensate``: the replay or the live loop on one BLAS thread. A version-2
    model's step is a few 400 x 400 products; with OpenBLAS's threads contending on a
    busy 2-core machine the spindle unit's replay took 51 s of CPU instead of 10 s
    (2026-11-25, load ~3), and live and replay then run the same single-thread
    arithmetic."""
    from arfem.scenarios.rod.deterministic import blas_threads
    with blas_threads(1):
        return _main(args)


def _load_record(args, model):
    """The record: contract v3 (a ``[model]`` table, ``d_<sensor>_um`` channels, read by
    :mod:`arfem.scenarios.records.axes_record`, for a version-2 model only) or the contract's
    version 1/2 (``growth_um``)."""
    from arfem.scenarios.records.dataset import load_dataset, read_record_doc
    doc = read_record_doc(args.record, args.limits)      # the one reader: TOML once
    if doc.is_mesh:
        from arfem.scenarios.records.axes_record import load_axes_record, require_axes_model
        from arfem.scenarios.records.georecord import read_mesh_record
        ds = load_axes_record(read_mesh_record(args.record, args.limits, doc))
        require_axes_model(model, ds, str(args.record))
        return ds
    return load_dataset(doc, args.limits)


def _main(args) -> int:
    for name in ("max_offset_um", "max_step_um"):
        v = getattr(args, name)
        if not (v > 0):
            raise InputError(f"must be > 0, got {v!r}", "--" + name.replace("_", "-"))
    if args.live is not None:
        _refuse_replay_options(args)
        from arfem.scenarios.live.jsonl import run_live
        return run_live(args)
    if args.record is None or args.out is None:
        raise InputError("a replay needs MODEL.json RECORD.toml --out DIR (or --live "
                         "CONFIG.toml)", "arfem compensate")
    probe = None if args.probe_every is None else parse_duration_s(args.probe_every)
    prepare_out_dir(args.out, args.force, inputs=[args.model, args.record], writes=WRITES)
    model = read_model(args.model, args.limits)
    ds = _load_record(args, model)
    if args.score_from is not None and not math.isfinite(args.score_from):
        raise InputError(f"must be a finite number of seconds, got {args.score_from!r}",
                         "--score-from")
    off, step = axis_limits(model, args.axis_limits, args.max_offset_um, args.max_step_um)
    res = replay(model, ds, max_offset_um=off, max_step_um=step, probe_every_s=probe,
                 score_from_s=args.score_from, where=str(args.record),
                 use_observer=not getattr(args, "no_observer", False))
    with staged_out_dir(args.out, args.force) as stage:
        write_replay(res, stage, args.model, args.record)
        write_html_report(stage)
    print(replay_terminal_line(res, args.out))
    return 0
