"""The report of an ISO 230-3 spindle thermal test from a record (contract v3).

    python -m arfem.scenarios.geometry.thermal_test RECORD.toml --out DIR [--force]

reads a record (a machine's, or ``arfem run``'s own ``record.toml``; its displacement
columns ``d_<sensor>_um`` and tilts ``tilt_<sensor>_urad``, ``speed_rpm`` where given)
and writes, atomically into ``DIR``:

* ``thermal_test.png``: each quantity's drift from the start against time, the
  displacements (µm) and the tilts (µrad) in their own panels, the spindle speed
  below, the stop marked: the standard's graph;
* ``thermal_test.md`` and ``thermal_test.json``: the record they come from (linked,
  and how its probes were zeroed), then per quantity the largest drift over the test
  and when, its range, its drift when the spindle stopped and at the end
  (:func:`arfem.models.thermal_test.thermal_test`);
* ``report.html``: all of it on one page, the record listed as its input.

Bad input: one line ``arfem: error: <file>: <key or column>: <what>``, exit 2, ``DIR``
untouched. docs/thermal-test.md is the user's page.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from arfem.io import atomic_write_text, write_json
from arfem.models.thermal_test import ThermalTest, quantity_columns, thermal_test
from arfem.params import InputError, one_line

__all__ = ["WRITES", "ThermalTestRecord", "read_thermal_test", "thermal_test_figure", "thermal_test_markdown",
           "write_thermal_test", "main"]

#: Files the report writes.
WRITES = ("thermal_test.png", "thermal_test.md", "thermal_test.json", "report.html")


@dataclass(frozen=True)
class ThermalTestRecord:
    """Where a thermal test's figures come from: the record's name, its TOML as the user
    gave it and how its displacement and tilt channels were zeroed."""

    name: str
    toml: Path
    displacement_zero: str


def read_thermal_test(record) -> tuple[ThermalTest, ThermalTestRecord]:
    """(ThermalTest, its record) of a v3 record; refuses one without a displacement or
    tilt column."""
    from arfem.scenarios.records.georecord import read_record_files, read_table
    files = read_record_files(record)
    tab = read_table(files)
    if not quantity_columns(tab.columns):
        raise InputError("has no displacement (d_<sensor>_um) or tilt (tilt_<sensor>_urad) "
                         "column to report", str(files.csv))
    return (thermal_test(tab.columns["time_s"], tab.columns, tab.columns.get("speed_rpm")),
            ThermalTestRecord(files.name, Path(files.toml), files.displacement_zero))


def thermal_test_figure(tt: ThermalTest, path, title: str = "") -> None:
    """The standard's graph: drifts against time (µm; µrad), the speed below."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t_h = tt.time_s / 3600.0
    groups = [(u, [q for q in tt.quantities if q.unit == u]) for u in ("µm", "µrad")]
    groups = [(u, qs) for u, qs in groups if qs]
    speed = tt.speed_rpm is not None
    heights = [3.0] * len(groups) + ([1.2] if speed else [])
    fig, axes = plt.subplots(len(heights), 1, figsize=(9, sum(heights) + 0.8), sharex=True,
                             squeeze=False, gridspec_kw={"height_ratios": heights})
    for ax, (unit, qs) in zip(axes[:, 0], groups):
        for q in qs:
            ax.plot(t_h, tt.drift[q.column], label=f"{q.name} (max {q.max_abs:.2f} {unit}"
                                                    f" at {q.max_abs_time_h:.2f} h)")
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_ylabel(f"{'displacement' if unit == 'µm' else 'tilt'} drift [{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    if speed:
        ax = axes[-1, 0]
        ax.step(t_h, tt.speed_rpm, where="pre", color="k", lw=1.0)
        ax.set_ylabel("speed [rpm]")
        ax.grid(alpha=0.3)
    if tt.stop_s is not None:
        for ax in axes[:, 0]:
            ax.axvline(tt.stop_s / 3600.0, color="0.4", ls="--", lw=0.8)
    axes[-1, 0].set_xlabel("time from the start of the test [h]")
    axes[0, 0].set_title(title or "ISO 230-3 thermal test: drift from the start")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _zero_text(zero: str) -> str:
    if zero == "first_row":
        return ("its probes zeroed at the start (`displacement_zero = \"first_row\"`), as "
                "ISO 230-3 does")
    return ("its displacements read from the stress-free state (`displacement_zero = "
            "\"reference\"`), here counted from its first row as a zeroed probe would read")


def _stop_text(tt: ThermalTest) -> str:
    if tt.stop_s is not None:
        return f"; the spindle stopped at {tt.stop_s / 3600:.2f} h"
    if tt.speed_rpm is None:
        return " (no `speed_rpm` column: no stop to report)"
    if np.any(tt.speed_rpm > 0):
        return "; the spindle still runs at the end (no stop in the record)"
    return "; the spindle never runs"


def thermal_test_markdown(tt: ThermalTest, record: ThermalTestRecord,
                          link: str | None = None) -> str:
    """The figures as a Markdown table, opening with the record (``link``: its path as
    the Markdown links it, default the TOML's absolute path) and what was measured."""
    from urllib.parse import quote
    link = record.toml.resolve().as_posix() if link is None else link
    dur = tt.time_s[-1] / 3600.0
    lines = [f"# Thermal test of {record.name} (ISO 230-3)", "",
             f"Record [`{record.toml.name}`]({quote(link)}) (`{record.name}`), "
             f"{_zero_text(record.displacement_zero)}: "
             f"{len(tt.time_s)} readings over {dur:.2f} h{_stop_text(tt)}. Drift of each "
             "quantity from its reading at the start (the probes' zero).", "",
             "| quantity | largest drift | at [h] | range | at the stop | at the end |",
             "|---|---|---|---|---|---|"]
    for q in tt.quantities:
        s = "—" if q.at_stop is None else f"{q.at_stop:.2f}"
        lines.append(f"| {q.name} [{q.unit}] | {q.max_abs:.2f} | {q.max_abs_time_h:.2f} | "
                     f"{q.range:.2f} | {s} | {q.final:.2f} |")
    lines += ["", "![drift over the test](thermal_test.png)", ""]
    return "\n".join(lines)


def _link_from(out: Path, toml: Path) -> str:
    """The record's path relative to the output folder (a report that moves with the
    record stays linked; a committed report names no machine's folders), else absolute."""
    import os
    try:
        return Path(os.path.relpath(toml.resolve(), out.resolve())).as_posix()
    except ValueError:                                  # another drive (Windows)
        return toml.resolve().as_posix()


def write_thermal_test(record, out, force: bool = False) -> ThermalTest:
    """Read ``record`` and write :data:`WRITES` into ``out``: the figures atomically, then
    ``report.html`` from them (as ``arfem report`` does, so that the record's relative
    link resolves from ``out`` itself)."""
    from arfem.scenarios.html_report import REPORT_NAME, write_html_report
    from arfem.scenarios.outdir import prepare_out_dir, replace_owned_file, staged_out_dir
    tt, rec = read_thermal_test(record)
    prepare_out_dir(out, force, writes=WRITES)
    link = _link_from(Path(out), rec.toml)
    title = f"Thermal test of {rec.name} (ISO 230-3)"
    with staged_out_dir(out, force) as stage:
        thermal_test_figure(tt, stage / "thermal_test.png",
                            f"{rec.name}: ISO 230-3 thermal test, drift from the start")
        atomic_write_text(stage / "thermal_test.md", thermal_test_markdown(tt, rec, link))
        write_json(stage / "thermal_test.json", {
            "record": rec.name, "record_toml": link,
            "displacement_zero": rec.displacement_zero,
            "duration_h": float(tt.time_s[-1] / 3600.0),
            "stop_h": None if tt.stop_s is None else tt.stop_s / 3600.0,
            "quantities": [asdict(q) for q in tt.quantities]})
    replace_owned_file(out, REPORT_NAME, lambda dst: write_html_report(dst.parent, title),
                       force=force, who="python -m arfem.scenarios.geometry.thermal_test")
    return tt


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m arfem.scenarios.geometry.thermal_test",
                                description="ISO 230-3 thermal-test report of a record "
                                            "(contract v3): drift of each quantity over "
                                            "time and its maxima.")
    p.add_argument("record", help="the record's TOML (or its CSV)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--force", action="store_true", help="replace arfem's files in --out")
    args = p.parse_args(argv)
    try:
        tt = write_thermal_test(args.record, args.out, args.force)
    except InputError as exc:
        print(f"arfem: error: {one_line(str(exc))}", file=sys.stderr)
        return 2
    for q in tt.quantities:
        print(f"{q.name}: largest drift {q.max_abs:.2f} {q.unit} at {q.max_abs_time_h:.2f} h, "
              f"range {q.range:.2f} {q.unit}")
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
