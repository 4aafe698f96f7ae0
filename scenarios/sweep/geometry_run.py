"""Running a mesh sweep (:mod:`arfem.scenarios.sweep.geometry`) with the rod sweep's
machinery: its store (one atomic file per point, resumed by key), its lock, its
executors (in-process, local workers, Dask) and run log; and what it writes: the tidy
``results.csv`` (inputs, then per sensor the peak, its time and the final value),
``summary.json``, ``README.md``, ``report.html`` and ``sensor_peaks.png``."""
from __future__ import annotations

import json
import math
from pathlib import Path

from arfem.fem.body import SENSOR_QUANTITIES      # each quantity's prefix and units
from arfem.io import atomic_write_text, write_json
import arfem.scenarios.sweep.executors as executors
from arfem.scenarios.sweep.geometry import GeometrySweep, metric_columns
from arfem.scenarios.sweep.points import canonical
from arfem.scenarios.sweep.store import PointStore, record_header_problem

__all__ = ["GeometryPointStore", "geometry_record_problem", "plan_tasks",
           "geometry_rows", "write_geometry_sweep_outputs", "FIGURE"]

FIGURE = "sensor_peaks.png"
_EXTRA = ("heat_dofs", "n_modes", "n_samples")


def geometry_record_problem(rec, key: str, inputs: dict | None, sensors) -> str | None:
    """Why a stored mesh-sweep point cannot be trusted, or None if it can: its layout,
    key, store version and inputs, every sensor column a finite number, each peak time
    within the cycle and each final value no farther from 0 (from the reference
    temperature) than the peak, which is the farthest value of the history.

    Examples
    --------
    >>> geometry_record_problem({"key": "k"}, "k", None, ())
    'store_version is None, not 2'
    """
    why = record_header_problem(rec, key, inputs)
    if why:
        return why
    m = rec["metrics"]
    for c in metric_columns(sensors) + list(_EXTRA) + ["reference_C", "total_h"]:
        v = m.get(c)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            return f"metrics.{c} is {v!r}"
    ref, total = m["reference_C"], m["total_h"]
    for name, q in sensors:                           # (a tilt's are tilt_ and urad)
        head, unit = SENSOR_QUANTITIES[q][:2]
        pre, zero = f"{head}_{name}", (ref if q == "temperature" else 0.0)
        if not 0.0 <= m[f"{pre}_peak_time_h"] <= total * (1 + 1e-12):
            return f"metrics.{pre}_peak_time_h is {m[f'{pre}_peak_time_h']!r}"
        if abs(m[f"{pre}_final_{unit}"] - zero) > abs(m[f"{pre}_peak_{unit}"] - zero) * \
                (1 + 1e-9) + 1e-12:
            return f"metrics.{pre}_final_{unit} is farther from {zero:g} than the peak"
    if m["heat_dofs"] < 1 or m["n_samples"] < 1:
        return "metrics.heat_dofs or n_samples is < 1"
    return None


class GeometryPointStore(PointStore):
    """The point store of a mesh sweep: the same files, its own record check."""

    def __init__(self, out: Path, sensors):
        super().__init__(out)
        self.sensors = tuple(sensors)

    def problem(self, rec, key: str, inputs: dict | None = None) -> str | None:
        """:func:`geometry_record_problem` for this store's sensors (the reading and the
        JSON parsing are :meth:`PointStore.check`'s)."""
        return geometry_record_problem(rec, key, inputs, self.sensors)


def _order(points) -> list:
    """Points that share a model and its h history next to each other (the modes of one
    are the next one's): sorted by every input but the sources' and the ambients'."""
    def share(p):
        return canonical({k: v for k, v in p.inputs.items()
                          if not k.startswith("heat_source.") and not k.endswith(".ambient_C")})
    return sorted(points, key=share)


def unique_in_order(todo) -> list:
    """Each point to compute once (identical inputs: one key), in :func:`_order`."""
    return _order({p.key: p for p in todo}.values())


def plan_tasks(points: list, first: dict | None, n_workers: int,
               start_s: float | None = None) -> list | None:
    """How the points after the first go to ``n_workers`` workers: ``n`` runs of
    adjacent points (each worker then builds the model once and reuses it, and the modes
    where h repeats, across its run), or None to compute them in this process.

    ``first``: the first point's result, computed in this process (None when the
    workers were asked for: always the workers). Its ``model_s`` (building the model:
    mesh, assembly, elasticity) and the rest of its ``run_time_s`` (the solve) give the
    two costs: the rest here takes n·solve (the model is held), on w workers
    start + model + ⌈n/w⌉·solve, with ``start_s`` a worker's start-up
    (:data:`arfem.scenarios.sweep.executors.WORKER_START_S`). The workers get the points
    only when they finish sooner.

    Examples
    --------
    >>> plan_tasks(list("ab"), {"run_time_s": 11.0, "model_s": 6.0}, 2) is None
    True
    >>> plan_tasks(list("abcdefg"), {"run_time_s": 11.0, "model_s": 6.0}, 2)
    [['a', 'b', 'c', 'd'], ['e', 'f', 'g']]
    >>> plan_tasks(list("abc"), None, 2)
    [['a', 'b'], ['c']]
    """
    n = len(points)
    w = max(1, min(n_workers, n))
    if first is not None:
        start = executors.WORKER_START_S if start_s is None else start_s
        build = float(first.get("model_s", 0.0))
        solve = max(float(first["run_time_s"]) - build, 0.0)
        if n * solve <= start + build + math.ceil(n / w) * solve:
            return None
    size, extra = divmod(n, w)
    out, i = [], 0
    for k in range(w):
        j = i + size + (k < extra)
        out.append(list(points[i:j]))
        i = j
    return out


def ready_store(out: Path, sweep: GeometrySweep, mode: str) -> "GeometryPointStore":
    """The mesh sweep's point store in ``out``, ready as the rod's is
    (:func:`arfem.scenarios.sweep.runner.ready_store`): folder made, temporaries removed,
    manifest written (kept on a resume), the folder adopted as arfem's."""
    from arfem.scenarios.outdir import adopt_outputs
    from arfem.scenarios.sweep.store import STORE_MANIFEST
    store = GeometryPointStore(out, sweep.sensors)
    store.dir.mkdir(parents=True, exist_ok=True)
    store.remove_temporaries()
    if mode != "resume" or not (out / STORE_MANIFEST).is_file():
        write_json(out / STORE_MANIFEST, sweep.manifest())
    adopt_outputs(out, [STORE_MANIFEST])
    return store


# -- outputs ------------------------------------------------------------------------------

def geometry_rows(sweep: GeometrySweep, store) -> list:
    """One row per stored point, in grid order: the swept keys, then per sensor its
    peak, peak time and final value, then the model's size and the point's run time."""
    cols = metric_columns(sweep.sensors)
    rows = []
    for p in sweep.points:
        rec = store.get(p.key, p.inputs)
        if rec is None:
            continue
        m = rec["metrics"]
        row = dict(p.inputs)
        row.update({c: m.get(c) for c in cols + list(_EXTRA)})
        row["run_time_s"] = rec.get("run_time_s")
        row["reused"] = m.get("reused", "")
        row["point_key"] = p.key
        rows.append(row)
    return rows


def _numeric(vals) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals)


def _short(inputs: dict) -> str:
    """``convection.housing.h_W_m2K=8`` as ``housing.h_W_m2K=8`` (legend labels)."""
    return ", ".join(f"{'.'.join(k.split('.')[-2:])}={v}" for k, v in inputs.items())


def _figure(sweep: GeometrySweep, rows: list, path: Path) -> None:
    """Peak (solid) and final (dashed) of every sensor against the first swept key: one
    colour per sensor, one marker per combination of the other keys; displacements
    above, then tilts, then temperatures, the legends beside the panels."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    key = next(iter(sweep.grid))
    xs = sweep.grid[key]
    num = _numeric(xs)
    others = [k for k in sweep.grid if k != key]
    combos = sorted({canonical({k: r[k] for k in others}) for r in rows})
    kinds = [(q, [n for n, qq in sweep.sensors if qq == q])
             for q in ("displacement", "tilt", "temperature")]
    kinds = [(q, ns) for q, ns in kinds if ns]
    fig, axes = plt.subplots(len(kinds), 1, figsize=(11, 3.8 * len(kinds)), squeeze=False)
    colours = plt.get_cmap("tab10")
    markers = "o^sDv<>pP*"
    for ax, (q, names) in zip(axes[:, 0], kinds):
        pre, unit, _, shown = SENSOR_QUANTITIES[q][:4]
        for i, name in enumerate(names):
            for j, combo in enumerate(combos):
                rs = sorted((r for r in rows if canonical({k: r[k] for k in others}) == combo),
                            key=lambda r: xs.index(r[key]))
                x = [r[key] if num else xs.index(r[key]) for r in rs]
                tag = name + (f" ({_short(json.loads(combo))})" if others else "")
                kw = dict(color=colours(i % 10), marker=markers[j % len(markers)])
                ax.plot(x, [r[f"{pre}_{name}_peak_{unit}"] for r in rs], "-", label=f"{tag}: peak",
                        **kw)
                ax.plot(x, [r[f"{pre}_{name}_final_{unit}"] for r in rs], "--", alpha=0.6,
                        mfc="none", label=f"{tag}: final", **kw)
        ax.set_ylabel(f"{q} [{shown}]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
        if not num:
            ax.set_xticks(range(len(xs)), [str(v) for v in xs])
    axes[-1, 0].set_xlabel(key)
    axes[0, 0].set_title(f"sweep {sweep.name}: each sensor's peak (solid) and final value "
                         "(dashed)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "–" if v is None else str(v)


def _range_lines(sweep: GeometrySweep, rows: list) -> list:
    """Per sensor: its peak's range over the points and the inputs at either end."""
    L = []
    for name, q in sweep.sensors:
        head, short, _, unit = SENSOR_QUANTITIES[q][:4]
        col = f"{head}_{name}_peak_{short}"
        lo = min(rows, key=lambda r: r[col])
        hi = max(rows, key=lambda r: r[col])
        where = lambda r: ", ".join(f"`{k}` = {_fmt(r[k])}" for k in sweep.grid)
        L.append(f"- `{name}` ({q}): peak from {lo[col]:.4g} {unit} ({where(lo)}) to "
                 f"{hi[col]:.4g} {unit} ({where(hi)})")
    return L


def _readme(sweep: GeometrySweep, rows: list, summary: dict) -> str:
    cols = list(sweep.grid) + [c for c in metric_columns(sweep.sensors)
                               if not c.endswith("_time_h")]
    L = [f"# Sweep `{sweep.name}` of the mesh scenario `{sweep.base}`", ""]
    if sweep.description:
        L += [sweep.description, ""]
    L += [f"{len(sweep.points)} points (full Cartesian product of "
          + ", ".join(f"`{k}` = {', '.join(_fmt(v) for v in vs)}" for k, vs in sweep.grid.items())
          + f"); {len(rows)} in the table.", ""]
    if rows:
        L += ["## Each sensor over the sweep", "", *_range_lines(sweep, rows), "",
              f"![peak and final value of each sensor]({FIGURE})", "",
              "## The points", "", "Peak = the value farthest from 0 µm (from the reference "
              "temperature), over the whole cycle; final = at its end.", "",
              "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        L += ["| " + " | ".join(_fmt(r[c]) for c in cols) + " |" for r in rows]
        L += ["", "## What was reused between points", "",
              "Per point, as its process found it (`reused` in `results.csv`; "
              "`docs/commands/sweep.md` says why each reuse gives the numbers of a run "
              "alone):", ""]
        L += [f"- {n} point(s): {w}" for w, n in summary["reused"].items()] + [""]
    L += [f"Runs: {len(summary['runs'])}; this one computed {summary['n_computed']} point(s), "
          f"took {summary['n_stored_before']} from the store, {summary['n_failed']} failed "
          f"({summary['executor']}, {summary['wall_s']:.1f} s).", "",
          "Files: `results.csv` (one row per point: the swept keys, then per sensor "
          "`*_peak_*`, `*_peak_time_h`, `*_final_*`, units in the names), `summary.json` "
          f"(the same rows and this page's figures), `{FIGURE}`, `report.html`; the store "
          "`sweep.json`, `points/`, `runs.jsonl`.", "",
          f"Reproduce: `arfem sweep {sweep.source} --out DIR` (an interrupted run resumes).",
          ""]
    return "\n".join(L)


def write_geometry_sweep_outputs(sweep: GeometrySweep, out: Path, store, rep,
                                 runs=None) -> dict:
    """(Re)write ``results.csv``, ``summary.json``, ``README.md``, ``report.html`` and
    the figure from the store."""
    from arfem.scenarios.html_report import write_html_report
    from arfem.scenarios.outdir import staged_out_dir
    from arfem.scenarios.sweep.report import rows_to_csv
    rows = geometry_rows(sweep, store)
    reused: dict = {}
    for r in rows:
        reused[r["reused"]] = reused.get(r["reused"], 0) + 1
    summary = {
        "sweep": sweep.name, "kind": "geometry", "sweep_id": sweep.sweep_id,
        "base": sweep.base, "grid": sweep.grid, "sensors": [list(s) for s in sweep.sensors],
        "run_id": rep.run_id, "n_points": rep.n_points, "n_rows": len(rows),
        "n_stored_before": rep.n_stored_before, "n_computed": rep.n_computed,
        "n_failed": rep.n_failed, "failures": rep.failures, "executor": rep.executor,
        "wall_s": rep.wall_s,
        "sum_point_run_time_s": float(sum(r["run_time_s"] or 0.0 for r in rows)),
        "reused": reused, "runs": list(runs or []), "rows": rows,
        "plots": [FIGURE] if rows else []}
    with staged_out_dir(out, force=True, out_locked=True) as stage:
        atomic_write_text(stage / "results.csv", rows_to_csv(rows))
        if rows:
            _figure(sweep, rows, stage / FIGURE)
        write_json(stage / "summary.json", summary)
        atomic_write_text(stage / "README.md", _readme(sweep, rows, summary))
        write_html_report(stage)
    return summary
