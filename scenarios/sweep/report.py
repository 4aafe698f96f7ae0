"""What a sweep writes from its store: the tidy ``results.csv``, the Biot thresholds and
conclusion, the figures, ``summary.json`` and ``README.md``."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from arfem.io import atomic_write_text, write_json
from arfem.scenarios.html_report import write_html_report
from arfem.scenarios.outdir import staged_out_dir
from arfem.scenarios.sweep.figures import write_figures
from arfem.scenarios.sweep.points import Sweep, canonical
from arfem.scenarios.sweep.spec import CORE_INPUTS, METRIC_COLUMNS

__all__ = ["results_rows", "rows_to_csv", "biot_threshold", "thresholds", "render_readme",
           "write_outputs"]

# -- the tidy table -----------------------------------------------------------------------

def results_rows(sweep: Sweep, store) -> list[dict]:
    """One row per stored point of ``sweep``, in grid order: inputs, then metrics."""
    rows = []
    for p in sweep.points:
        rec = store.get(p.key, p.inputs)          # validated: never a corrupt point
        if rec is None:
            continue
        m = dict(rec["metrics"])
        peak = m.get("fem_peak_um") or float("nan")
        for pre in ("", "corrected_"):
            if f"{pre}rmse_pct_of_peak" not in m and f"{pre}rmse_um" in m:
                m[f"{pre}rmse_pct_of_peak"] = 100.0 * m[f"{pre}rmse_um"] / peak
        m["run_time_s"] = rec.get("run_time_s")
        row = {c: m.get(c) for c in CORE_INPUTS}
        row.update(p.inputs)
        for c in METRIC_COLUMNS:
            row[c] = m.get(c)
        row["point_key"] = p.key
        rows.append(row)
    return rows


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ""
    s = str(v)
    if any(ch in s for ch in ',"\n'):
        s = '"' + s.replace('"', '""') + '"'
    return s


def rows_to_csv(rows: list[dict]) -> str:
    """Tidy CSV text; floats written with ``repr`` (round-trips exactly)."""
    if not rows:
        return ""
    cols = list(rows[0])
    lines = [",".join(cols)] + [",".join(_cell(r.get(c)) for c in cols) for r in rows]
    return "\n".join(lines) + "\n"


# -- analysis -----------------------------------------------------------------------------

def biot_threshold(biot, error, level: float) -> float:
    """Smallest Biot number at which ``error`` reaches ``level``, linearly interpolated.

    Parameters
    ----------
    biot : array_like
        Biot numbers hR/λ [-] (any order).
    error : array_like
        Error at each Biot number [% of peak].
    level : float
        Threshold [% of peak].

    Returns
    -------
    float
        The crossing [-]; ``nan`` if the error never reaches ``level``, the
        smallest Biot number if it is reached already there.

    Examples
    --------
    >>> biot_threshold([0.1, 0.2, 0.4], [1.0, 2.0, 6.0], 3.0)
    0.25
    >>> biot_threshold([0.1, 0.2], [1.0, 2.0], 3.0)
    nan
    """
    b = np.asarray(biot, float)
    e = np.asarray(error, float)
    o = np.argsort(b)
    b, e = b[o], e[o]
    above = np.nonzero(e >= level)[0]
    if above.size == 0:
        return float("nan")
    i = int(above[0])
    if i == 0:
        return float(b[0])
    return float(b[i - 1] + (level - e[i - 1]) * (b[i] - b[i - 1]) / (e[i] - e[i - 1]))


def _slice_rows(sweep: Sweep, rows: list[dict]) -> tuple[list[dict], dict]:
    """Rows at the largest q and the first value of every other non-core swept key."""
    fixed = {c: v[0] for c, v in sweep.grid.items() if c not in CORE_INPUTS}
    if "q_W_m2" in sweep.grid:
        fixed["q_W_m2"] = max(v for v in sweep.grid["q_W_m2"])
    sel = [r for r in rows if all(r.get(c) == v for c, v in fixed.items())]
    return sel, fixed


def thresholds(sweep: Sweep, rows: list[dict], levels=(3.0, 5.0)) -> list[dict]:
    """Per Δτ: the Biot number above which each AR's max error exceeds each level."""
    sel, _ = _slice_rows(sweep, rows)
    out = []
    for dtau in sorted({r["dtau_s"] for r in sel}):
        rs = [r for r in sel if r["dtau_s"] == dtau]
        b = [r["biot"] for r in rs]
        item = {"dtau_s": dtau, "biot_min": min(b), "biot_max": max(b)}
        for pre, name in (("", "paper"), ("corrected_", "corrected")):
            e = [r[f"{pre}max_abs_diff_pct_of_peak"] for r in rs]
            item[f"{name}_max_error_pct"] = max(e)
            for lv in levels:
                item[f"{name}_biot_at_{lv:g}pct"] = biot_threshold(b, e, lv)
        out.append(item)
    return out


# -- writing the results ------------------------------------------------------------------

def _fmt(x, nd=3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:.{nd}g}" if isinstance(x, float) else str(x)


def _verdict_lines(sweep: Sweep, rows: list[dict], summary: dict) -> list[str]:
    """The page's opening: the answer of the sweep in a sentence, its key figure and its
    one table (the thresholds), before the grid, the runs and the files."""
    th = summary.get("thresholds") or []
    concl = summary.get("conclusion") or {}
    done = [r for r in rows if isinstance(r.get("max_abs_diff_pct_of_peak"), (int, float))]
    if not done:
        return ["## Verdict", "", "No point has been computed yet.", "", "## The sweep", ""]
    worst = max(done, key=lambda r: r["max_abs_diff_pct_of_peak"])
    best = min(done, key=lambda r: r["max_abs_diff_pct_of_peak"])
    text = concl.get("text") or (
        f"The paper's AR(1) deviates from the FEM by {best['max_abs_diff_pct_of_peak']:.3g} "
        f"to {worst['max_abs_diff_pct_of_peak']:.3g} % of the peak over these "
        f"{len(done)} points" + (f" ({len(rows) - len(done)} failed)" if len(done) < len(rows)
                                 else "") + ".")
    act = ("Use the paper's AR(1) only below those Biot numbers hR/λ; above, use the "
           "corrected AR(1) (`--model corrected` in `arfem check`)."
           if concl.get("paper_biot_at_3pct_range") else "")
    L = ["## Verdict", "", text + (" " + act if act else ""), ""]
    plots = summary.get("plots") or []
    fig = "error_vs_biot.png" if "error_vs_biot.png" in plots else (plots[0] if plots else None)
    if fig:
        L += [f"![max |AR − FEM| against the Biot number, per Δτ]({fig})", ""]
    if th:
        L += ["| Δτ [s] | paper AR max error [%] | Bi at 3 % | corrected AR max error [%] |",
              "|---|---|---|---|"]
        L += [f"| {t['dtau_s']:g} | {t['paper_max_error_pct']:.3g} | "
              f"{_fmt(t['paper_biot_at_3pct'])} | {t['corrected_max_error_pct']:.2g} |"
              for t in th]
        L.append("")
    return L + ["## The sweep", ""]


def render_readme(sweep: Sweep, rows: list[dict], summary: dict) -> str:
    """Markdown report of a sweep; every number in it is computed from ``rows``."""
    L = [f"# Sweep `{sweep.name}`", ""] + _verdict_lines(sweep, rows, summary)
    if sweep.description:
        L += [sweep.description, ""]
    L += [f"Base scenario `{sweep.base}`; grid (full Cartesian product, "
          f"{len(sweep.points)} points):", ""]
    for c, v in sweep.grid.items():
        L.append(f"- `{c}` = {', '.join(_fmt(x, 6) if isinstance(x, float) else str(x) for x in v)}")
    L += ["", f"Points in the table: {summary['n_rows']} of {summary['n_points']}. "
          f"Sum of per-point run times {summary['sum_point_run_time_s']:.1f} s.", "",
          *_runs_lines(summary.get("runs") or []),
          _files_line(summary), "",
          f"Reproduce: `arfem sweep {sweep.source} --out DIR` (add `--scheduler ADDRESS` "
          "for a Dask cluster; an interrupted run resumes where it stopped).", ""]
    th = summary.get("thresholds") or []
    if th and len({r["biot"] for r in rows}) > 1:
        sel, fixed = _slice_rows(sweep, rows)
        tag = ", ".join(f"{k} = {_fmt(v, 6)}" for k, v in fixed.items())
        L += ["## When does the paper's AR(1) stop tracking the FEM?", "",
              f"Max |AR − FEM| over the cycle in % of the FEM peak, against the Biot "
              f"number hR/λ ({tag}{_q_note(sweep, rows)}). Thresholds are interpolated linearly in Biot "
              "between grid points by `arfem.scenarios.sweep.biot_threshold`; `–` = not reached "
              "in the grid.", "",
              "| Δτ [s] | Biot range | paper AR max error [%] | Bi at 3 % | Bi at 5 % | "
              "corrected AR max error [%] | corrected: Bi at 3 % | corrected: Bi at 5 % |",
              "|---|---|---|---|---|---|---|---|"]
        for t in th:
            L.append(f"| {t['dtau_s']:g} | {t['biot_min']:.3g}–{t['biot_max']:.3g} | "
                     f"{t['paper_max_error_pct']:.3g} | {_fmt(t['paper_biot_at_3pct'])} | "
                     f"{_fmt(t['paper_biot_at_5pct'])} | {t['corrected_max_error_pct']:.2g} | "
                     f"{_fmt(t['corrected_biot_at_3pct'])} | {_fmt(t['corrected_biot_at_5pct'])} |")
        s = summary["conclusion"]
        L += ["", "**From the data:** " + s["text"], ""]
        L += _by_h_table(sel)
    return "\n".join(L) + "\n"


def _runs_lines(runs: list[dict]) -> list[str]:
    """One line per run of the sweep (a re-run adds its own timing, never replaces one)."""
    if not runs:
        return []
    L = ["Runs of this sweep into this folder (from `runs.jsonl`):", ""]
    for i, r in enumerate(runs, 1):
        L.append(f"{i}. {r.get('finished_at', r.get('run_id', ''))}: "
                 f"{r.get('n_computed', 0)} computed, {r.get('n_stored_before', 0)} taken from "
                 f"the store, {r.get('n_failed', 0)} failed, wall time "
                 f"{float(r.get('wall_s') or 0.0):.1f} s ({r.get('executor', '')}).")
    return L + [""]


def _files_line(summary: dict) -> str:
    """The files of the sweep folder, by the names actually written."""
    figs = ", ".join(f"`{f}`" for f in summary.get("plots") or [])
    return ("Files: `README.md` (this page), `report.html` (this page with the figures and "
            "the numbers of `summary.json`, one self-contained file), "
            "`results.csv` (one row per point; inputs then "
            "outputs, units in the column names, `pct` = % of the FEM peak growth), "
            "`summary.json` (the figures of this page, machine-readable)"
            + (f", the figures {figs}" if figs else "") +
            "; the store: `sweep.json` (what was swept), `points/` (one JSON file per "
            "finished point; re-running the same command resumes it) and `runs.jsonl` "
            "(one line per run); `.arfem-outputs.json` lists the files arfem wrote here, with "
            "their SHA-256 (`--force` replaces only those).")


def _q_note(sweep: Sweep, rows: list[dict]) -> str:
    """How much the % errors differ between q levels at equal other inputs (from the data)."""
    qs = sweep.grid.get("q_W_m2", [])
    if len(qs) < 2:
        return ""
    groups: dict = {}
    for r in rows:
        k = canonical({c: r[c] for c in sweep.grid if c != "q_W_m2"})
        groups.setdefault(k, []).append(r)
    d = max(((max(r[c] for r in g) - min(r[c] for r in g))
             for g in groups.values() if len(g) > 1
             for c in ("max_abs_diff_pct_of_peak", "corrected_max_abs_diff_pct_of_peak")),
            default=float("nan"))
    if not math.isfinite(d):
        return ""
    return (f"; the other q levels give the same % errors to within {d:.1g} percentage points, "
            "as the FEM and both ARs are linear in q, so the figures show one q level")


def _by_h_table(sel: list[dict]) -> list[str]:
    """Per h: errors (max over Δτ, and their spread over Δτ) and the fitted decay rate."""
    dts = sorted({r["dtau_s"] for r in sel})
    L = ["Per h (same slice; \"spread\" = max − min over the Δτ values, showing how little "
         "the error depends on Δτ; the last column compares the FEM's fitted per-step decay "
         "1 − C1_fitted with the paper's 1 − C1 = 1 − exp(−bΔτ) at the smallest Δτ):", "",
         "| h [W/(m²·K)] | Bi [-] | paper AR max error [%] | spread over Δτ [% points] | "
         "corrected AR max error [%] | (1 − C1_fitted)/(1 − C1) at "
         f"Δτ = {dts[0]:g} s |", "|---|---|---|---|---|---|"]
    for h in sorted({r["h_W_m2K"] for r in sel}):
        rs = [r for r in sel if r["h_W_m2K"] == h]
        e = [r["max_abs_diff_pct_of_peak"] for r in rs]
        ec = [r["corrected_max_abs_diff_pct_of_peak"] for r in rs]
        r0 = min(rs, key=lambda r: r["dtau_s"])
        ratio = (1 - r0["C1_fitted"]) / (1 - r0["C1"])
        L.append(f"| {h:g} | {r0['biot']:.3g} | {max(e):.3g} | {max(e) - min(e):.2g} | "
                 f"{max(ec):.2g} | {ratio:.4f} |")
    return L + [""]


def _conclusion(th: list[dict]) -> dict:
    def rng(key):
        v = [t[key] for t in th if math.isfinite(t[key])]
        return (min(v), max(v), len(v)) if v else None

    parts = []
    out = {}
    for lv in (3, 5):
        r = rng(f"paper_biot_at_{lv}pct")
        out[f"paper_biot_at_{lv}pct_range"] = None if r is None else [r[0], r[1]]
        if r is None:
            parts.append(f"the paper's AR never exceeds {lv} % of peak in this grid")
        elif f"{r[0]:.3g}" == f"{r[1]:.3g}":
            parts.append(f"the paper's AR exceeds {lv} % of peak above Bi ≈ {r[0]:.3g}, the "
                         f"same to 3 digits for all {r[2]} of {len(th)} Δτ values that reach it")
        else:
            parts.append(f"the paper's AR exceeds {lv} % of peak above Bi ≈ {r[0]:.3g}–"
                         f"{r[1]:.3g} depending on Δτ ({r[2]} of {len(th)} Δτ values reach it)")
    cmax = max(t["corrected_max_error_pct"] for t in th)
    out["corrected_max_error_pct"] = cmax
    out["corrected_exceeds_3pct"] = bool(cmax >= 3.0)
    out["corrected_exceeds_5pct"] = bool(cmax >= 5.0)
    parts.append(("the corrected AR stays below 3 % everywhere in the grid" if cmax < 3 else
                  "the corrected AR also exceeds 3 % somewhere in the grid")
                 + f" (its largest error is {cmax:.3g} % of peak)")
    out["text"] = "; ".join(parts) + "."
    out["text"] = out["text"][0].upper() + out["text"][1:]
    return out


def write_outputs(sweep: Sweep, out: Path, store, rep, runs: list | None = None) -> dict:
    """(Re)write ``results.csv``, plots, ``summary.json`` and ``README.md`` from the store."""
    rows = results_rows(sweep, store)
    summary = {
        "sweep": sweep.name, "sweep_id": sweep.sweep_id, "run_id": rep.run_id,
        "n_points": rep.n_points, "n_rows": len(rows), "n_stored_before": rep.n_stored_before,
        "n_computed": rep.n_computed, "n_failed": rep.n_failed, "failures": rep.failures,
        "executor": rep.executor, "wall_s": rep.wall_s,
        "points_per_s": rep.n_computed / rep.wall_s if rep.wall_s > 0 else None,
        "sum_point_run_time_s": float(sum(r["run_time_s"] or 0.0 for r in rows)),
        "runs": list(runs or []),
    }
    has_core = rows and all(r.get(c) is not None for r in rows for c in
                            ("dtau_s", "h_W_m2K", "biot", "max_abs_diff_pct_of_peak"))
    if has_core:
        th = thresholds(sweep, rows)
        summary["thresholds"] = th
        summary["conclusion"] = _conclusion(th)
    try:                                  # figures of an earlier run, by the names it wrote
        old_plots = set(json.loads((out / "summary.json").read_text("utf-8")).get("plots")
                        or [])
    except (OSError, ValueError, AttributeError):
        old_plots = set()
    with staged_out_dir(out, force=True, out_locked=True) as stage:   # DirLock held
        atomic_write_text(stage / "results.csv", rows_to_csv(rows))
        summary["plots"] = write_figures(sweep, rows, stage) if has_core else []
        write_json(stage / "summary.json", summary)
        atomic_write_text(stage / "README.md", render_readme(sweep, rows, summary))
        write_html_report(stage)
    for name in old_plots - set(summary["plots"]):   # the README lists only what is there
        if isinstance(name, str) and name.endswith(".png") and "/" not in name:
            (out / name).unlink(missing_ok=True)
    return summary

