"""``arfem run`` and ``arfem reproduce``: one scenario, FEM against AR(1), all outputs.

Data flow: scenario file → :class:`~scenarios.config.Scenario` → :func:`evaluate`
(FEM, paper AR(1), corrected AR(1), least-squares fit) → :class:`Evaluation` →
writers (:func:`write_outputs`: CSV, JSON, PNG, Markdown, XDMF).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from arfem.fem.heat import HeatFEM, build_3d, build_axisymmetric, solve_modal, solve_theta
from arfem.models.ar1 import (ar1_on_schedule, c1_paper, c2_paper, corrected_coefficients, fit_ar1)
from arfem.params import InputError, Schedule
from arfem.scenarios.config import PAPER_SCENARIOS, Scenario, builtin_scenario_path, load_scenario
from arfem.io import atomic_write_text, read_text_utf8, sha256_file, write_csv, write_json
from arfem.scenarios.html_report import write_html_report
from arfem.scenarios.outdir import owned_files, prepare_out_dir, staged_out_dir
from arfem.scenarios import deterministic as det
from arfem.scenarios.progress import add_progress_flag, tagged

__all__ = ["Evaluation", "build_model", "evaluate", "write_outputs", "run_scenario",
           "reproduce", "growth_figure", "PAPER_VALUES"]

#: The files ``write_outputs`` puts into --out (checked before the work: never an input
#: or a file arfem did not write; see arfem.scenarios.outdir).
WRITES = ("timeseries.csv", "summary.json", "figure.png", "summary.md", "temperature_3d.png",
          "model.json", "model_corrected.json",
          "scenario.toml", "report.html", "fields/fields.xdmf3", "fields/fields.h5",
          "fields/peak.xdmf")

#: Values printed in the seed paper (Du et al. 2021, Sec. 2) at Δτ = 30 s.
PAPER_VALUES = {"C1": 0.9909, "C2_um": {2000.0: 0.1985, 3000.0: 0.2977}}


@dataclass(frozen=True)
class Evaluation:
    """Result of one scenario: time series on the AR grid and summary metrics."""

    scenario: Scenario
    times_s: np.ndarray
    q_W_m2: np.ndarray              # input on the interval ending at each sample
    fem_growth_um: np.ndarray
    ar_growth_um: np.ndarray
    ar_corrected_growth_um: np.ndarray
    metrics: dict
    model: HeatFEM | None = field(default=None, repr=False)


def build_model(scenario: Scenario, cache: dict | None = None) -> HeatFEM:
    """The scenario's FEM model (assembled once per rod/mesh when ``cache`` is given)."""
    f = scenario.fem
    key = (scenario.rod, f.model, f.order, tuple(sorted(f.mesh.items())))
    if cache is not None and key in cache:
        return cache[key]
    build = build_axisymmetric if f.model == "axisymmetric" else build_3d
    model = build(scenario.rod, order=f.order, **f.mesh)
    if cache is not None:
        cache[key] = model
    return model


def _fem_growth(scenario: Scenario, model: HeatFEM, cache: dict | None):
    """FEM growth [m] at the AR sample times 0, Δτ, 2Δτ, …"""
    fine = scenario.schedule.subdivided(scenario.dtau_s)
    if scenario.fem.theta is None:
        return fine, _modal_growth(scenario, model, fine, cache)
    res = solve_theta(model, fine, scenario.fem.dt_s, theta=scenario.fem.theta)
    k = int(round(scenario.dtau_s / scenario.fem.dt_s))
    return fine, res.growth_m[::k]


def _modal_growth(scenario: Scenario, model: HeatFEM, fine, cache: dict | None) -> np.ndarray:
    """Growth [m] of the exact modal solve on ``fine``, shared across a sweep's points.

    With the ambient at its nominal value the growth is linear in q, so it is computed
    for the flux pattern q / max|q| and scaled. Every run takes that path, cached or not,
    so a sweep's table is bit-identical however its points are spread over workers; in
    one worker the points that differ only in the flux level share one solve.
    """
    modes = None if cache is None else cache.setdefault(("modes", id(model)), {})
    sched = scenario.schedule
    q = np.asarray(sched.q_W_m2, float)
    qmax = float(np.max(np.abs(q)))
    amb = sched.ambient_for(model.rod) - model.rod.ambient_C
    if qmax == 0.0 or np.any(amb != 0.0):
        return solve_modal(model, fine, mode_cache=modes).growth_m
    key = ("unit_growth", id(model), scenario.dtau_s, tuple(sched.durations_s),
           tuple(q / qmax), tuple(sched.h_for(model.rod)))
    unit = None if cache is None else cache.get(key)
    if unit is None:
        unit_sched = Schedule(fine.durations_s, np.asarray(fine.q_W_m2) / qmax,
                              fine.ambient_C, fine.h_W_m2K)
        unit = solve_modal(model, unit_sched, mode_cache=modes).growth_m
        if cache is not None:
            cache[key] = unit
    return qmax * unit


def _levels_metrics(prefix: str, by_q: dict) -> dict:
    return {f"{prefix}_by_q_W_m2": {f"{q:g}": v for q, v in by_q.items()},
            prefix: by_q[max(by_q)] if by_q else 0.0}


def evaluate(scenario: Scenario, cache: dict | None = None, progress=None) -> Evaluation:
    """Run the FEM and both AR(1) models on the scenario's cycle; compare them.

    Parameters
    ----------
    scenario : Scenario
    cache : dict, optional
        Reuse assembled models and eigen-decompositions across calls (sweeps).
    progress : callable, optional
        Called with the name of each slow step as it starts
        (:class:`arfem.scenarios.progress.Progress`).
    """
    progress = progress or _no_progress
    progress("FEM solve")
    t0 = time.perf_counter()
    rod, dtau = scenario.rod, scenario.dtau_s
    model = build_model(scenario, cache)
    fine, fem_m = _fem_growth(scenario, model, cache)
    t_fem = time.perf_counter() - t0
    progress("AR(1) models and fit")
    times, ar_m = ar1_on_schedule(rod, scenario.schedule, dtau)
    _, arc_m = ar1_on_schedule(rod, scenario.schedule, dtau, corrected=True)
    q = np.concatenate([[fine.q_W_m2[0]], fine.q_W_m2])
    fem, ar, arc = fem_m * 1e6, ar_m * 1e6, arc_m * 1e6
    fit = fit_ar1(fem, fine.q_W_m2)
    levels = scenario.q_levels
    peak = float(np.max(np.abs(fem)))
    d, dc = ar - fem, arc - fem
    c1c = corrected_coefficients(rod, dtau, 1.0)[0]
    m = {
        "scenario": scenario.name,
        "dtau_s": dtau,
        "h_W_m2K": rod.convection_W_m2K,
        "q_W_m2": max(levels) if levels else 0.0,
        "biot": rod.biot,
        "fem_model": scenario.fem.model,
        "fem_order": scenario.fem.order,
        "fem_solver": scenario.fem.solver,
        "fem_dofs": model.ndofs,
        "n_samples": int(times.size),
        "C1": c1_paper(rod, dtau),
        **_levels_metrics("C2_um", {q_: c2_paper(rod, dtau, q_) * 1e6 for q_ in levels}),
        "C1_fitted": fit.c1,
        **_levels_metrics("C2_fitted_um", {q_: fit.c2.get(q_, float("nan")) for q_ in levels}),
        "C2_fitted_um_at_q0": fit.c2.get(0.0, 0.0),
        "corrected_C1": c1c,
        **_levels_metrics("corrected_C2_um",
                          {q_: corrected_coefficients(rod, dtau, q_)[1] * 1e6 for q_ in levels}),
        "fem_peak_um": peak,
        "fem_peak_time_h": float(times[np.argmax(np.abs(fem))] / 3600.0),
        "ar_peak_um": float(np.max(np.abs(ar))),
        "ar_corrected_peak_um": float(np.max(np.abs(arc))),
        "max_abs_diff_um": float(np.max(np.abs(d))),
        "max_abs_diff_pct_of_peak": float(100 * np.max(np.abs(d)) / peak) if peak else 0.0,
        "rmse_um": float(np.sqrt(np.mean(d ** 2))),
        "corrected_max_abs_diff_um": float(np.max(np.abs(dc))),
        "corrected_max_abs_diff_pct_of_peak": float(100 * np.max(np.abs(dc)) / peak) if peak else 0.0,
        "corrected_rmse_um": float(np.sqrt(np.mean(dc ** 2))),
        "corrected_peak_diff_pct": float(100 * (np.max(np.abs(arc)) - peak) / peak) if peak else 0.0,
        "fem_wall_s": t_fem,
        "wall_s": time.perf_counter() - t0,
    }
    return Evaluation(scenario, times, q, fem, ar, arc, m, model)


def _no_progress(step: str) -> None:
    """The default progress hook: nothing."""


# -- writers -----------------------------------------------------------------------------

#: tolerance of the CI check "AR tracks FEM" (tests/test_ar_tracks_fem.py) [% of FEM peak]
AR_TOLERANCE_PCT = 3.0
#: colour-blind-safe colours (Okabe & Ito), each series also with its own line style
_C_FEM, _C_AR, _C_ARC, _C_HEAT = "black", "#0072B2", "#D55E00", "#E69F00"


def growth_figure(ev: Evaluation):
    """The paper's Fig. 2/3 and its errors as one figure (returned, not saved).

    Three panels on one time axis, each on its own scale: (a) axial growth of the
    FEM, the paper's AR(1) and the corrected AR(1) with the heating phases shaded;
    (b) paper AR(1) − FEM [µm] with the CI tolerance (± 3 % of the FEM peak) as
    labelled lines; (c) corrected AR(1) − FEM [nm]. Colours are colour-blind safe
    and every series has its own line style, so it reads in grey too.

    Parameters
    ----------
    ev : Evaluation

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch
    th = ev.times_s / 3600.0
    m = ev.metrics
    fig = Figure(figsize=(8.0, 8.6), dpi=150, layout="constrained")
    ax, bx, cx = fig.subplots(3, 1, sharex=True, gridspec_kw={"height_ratios": [2.2, 1, 1]})
    edges = ev.scenario.schedule.edges_s / 3600.0
    levels = sorted({float(q) for q in ev.scenario.schedule.q_W_m2 if q > 0})
    for i, qv in enumerate(ev.scenario.schedule.q_W_m2):
        if qv > 0:
            for a in (ax, bx, cx):
                a.axvspan(edges[i], edges[i + 1], color=_C_HEAT, alpha=0.15, lw=0)
    ax.plot(th, ev.fem_growth_um, "-", color=_C_FEM, lw=2.4, label="FEM (scikit-fem)")
    ax.plot(th, ev.ar_growth_um, "--", color=_C_AR, lw=1.6, label="AR(1), paper eqs. 12–14")
    ax.plot(th, ev.ar_corrected_growth_um, ":", color=_C_ARC, lw=2.0,
            label="AR(1), radial-mode corrected")
    qtxt = ", ".join(f"{q:g}" for q in levels) if levels else "none"
    handles, labels = ax.get_legend_handles_labels()
    if levels:
        handles.append(Patch(color=_C_HEAT, alpha=0.3, lw=0))
        labels.append(f"heat flux on: q = {qtxt} W/m²")
    lo = min(0.0, float(np.min(ev.fem_growth_um)), float(np.min(ev.ar_growth_um)))
    hi = max(float(np.max(ev.fem_growth_um)), float(np.max(ev.ar_growth_um)),
             float(np.max(ev.ar_corrected_growth_um)))
    span = (hi - lo) or 1.0
    ax.set_ylim(lo - 0.03 * span, hi + 0.45 * span)       # the legend's room above the data
    ax.legend(handles, labels, loc="upper center", ncol=2, fontsize=8, frameon=False)
    ax.set_ylabel("axial growth ΔL [µm]")
    ax.set_title(f"{ev.scenario.name}: h = {m['h_W_m2K']:g} W/(m²K), Bi = {m['biot']:.3f}, "
                 f"Δτ = {ev.scenario.dtau_s:g} s, FEM {m['fem_model']} order {m['fem_order']}",
                 fontsize=9)
    ax.text(0.005, 0.98, "(a)", transform=ax.transAxes, va="top", fontsize=9)

    d = ev.ar_growth_um - ev.fem_growth_um
    thr = AR_TOLERANCE_PCT / 100.0 * m["fem_peak_um"]
    bx.plot(th, d, "--", color=_C_AR, lw=1.4)
    bx.axhline(0, color="0.5", lw=0.6)
    if thr > 0:
        for sgn, va in ((1, "bottom"), (-1, "top")):
            bx.axhline(sgn * thr, color="0.25", lw=0.9, ls="-.")
            bx.text(th[-1], sgn * thr, f"{'+' if sgn > 0 else '−'}{AR_TOLERANCE_PCT:g} % of FEM "
                    "peak (CI tolerance) ", ha="right", va=va, fontsize=7, color="0.25",
                    bbox=dict(facecolor="white", edgecolor="none", pad=0.5, alpha=0.85))
    # room above the data and the tolerance lines for the panel's heading, below for a label
    top = max(thr, float(np.max(d)))
    bot = min(-thr, float(np.min(d)))
    span = (top - bot) or 1.0
    bx.set_ylim(bot - 0.15 * span, top + 0.3 * span)
    bx.set_ylabel("paper AR(1) − FEM\n[µm]")
    bx.text(0.005, 0.96, f"(b) max |AR − FEM| = {m['max_abs_diff_um']:.3f} µm "
            f"({m['max_abs_diff_pct_of_peak']:.2f} % of peak)", transform=bx.transAxes,
            va="top", fontsize=8)

    dc = (ev.ar_corrected_growth_um - ev.fem_growth_um) * 1e3
    cx.plot(th, dc, ":", color=_C_ARC, lw=1.8)
    cx.axhline(0, color="0.5", lw=0.6)
    amp = float(np.max(np.abs(dc))) or 1.0
    cx.set_ylim(-1.6 * amp, 1.9 * amp)
    cx.set_ylabel("corrected AR(1) − FEM\n[nm]")
    cx.text(0.005, 0.96, f"(c) max |corrected AR − FEM| = {m['corrected_max_abs_diff_um'] * 1e3:.3g}"
            f" nm ({m['corrected_max_abs_diff_pct_of_peak']:.2g} % of peak)",
            transform=cx.transAxes, va="top", fontsize=8)
    cx.set_xlabel("time t [h]")
    cx.set_xlim(th[0], th[-1])
    if th[-1] - th[0] <= 48:
        from matplotlib.ticker import MultipleLocator
        cx.xaxis.set_major_locator(MultipleLocator(2 if th[-1] - th[0] > 6 else 0.5))
    for a in (ax, bx, cx):
        a.grid(alpha=0.3)
        a.tick_params(labelsize=8)
    fig.align_ylabels([ax, bx, cx])
    return fig


def _figure(ev: Evaluation, path: Path) -> None:
    from arfem.io import atomic_path
    fig = growth_figure(ev)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")


def _summary_md(ev: Evaluation) -> str:
    m = ev.metrics
    sc = ev.scenario
    ok = m["max_abs_diff_pct_of_peak"] <= AR_TOLERANCE_PCT
    verdict = (
        f"The paper's AR(1) {'tracks' if ok else 'does not track'} the FEM on this scenario: "
        f"its largest deviation is {m['max_abs_diff_pct_of_peak']:.2f} % of the FEM peak "
        f"({m['max_abs_diff_um']:.3f} of {m['fem_peak_um']:.3f} µm; the CI check allows "
        f"{AR_TOLERANCE_PCT:g} %). The corrected AR(1) deviates by "
        f"{m['corrected_max_abs_diff_pct_of_peak']:.4f} %"
        + ("." if ok else "; use it (`arfem check --model corrected`), or shorten Δτ / "
           "reduce the Biot number hR/λ, where the paper's 1D model holds."))
    lines = [
        f"# {sc.name}",
        "",
        "## Verdict",
        "",
        verdict,
        "",
        "![growth of the FEM, the paper's AR(1) and the corrected AR(1), and their "
        "differences](figure.png)",
        "",
        "## The scenario",
        "",
        sc.description,
        "",
        f"FEM: {m['fem_model']}, order {m['fem_order']}, {m['fem_dofs']} dofs, solver "
        f"{m['fem_solver']}; AR(1) step Δτ = {sc.dtau_s:g} s; Biot number hR/λ = {m['biot']:.4f}.",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| C1 (closed form, eq. 13) | {m['C1']:.6f} |",
    ]
    for q, v in m["C2_um_by_q_W_m2"].items():
        lines.append(f"| C2 at q = {q} W/m² (closed form, eq. 14) [µm] | {v:.6f} |")
    lines.append(f"| C1 fitted to the FEM (eq. 17) | {m['C1_fitted']:.6f} |")
    for q, v in m["C2_fitted_um_by_q_W_m2"].items():
        lines.append(f"| C2 fitted to the FEM at q = {q} W/m² [µm] | {v:.6f} |")
    lines += [
        f"| C1 of the corrected AR(1) | {m['corrected_C1']:.6f} |",
        f"| FEM peak growth [µm] | {m['fem_peak_um']:.4f} (at {m['fem_peak_time_h']:.2f} h) |",
        f"| AR(1) peak growth [µm] | {m['ar_peak_um']:.4f} |",
        f"| max abs(AR − FEM) [µm] | {m['max_abs_diff_um']:.4f} "
        f"({m['max_abs_diff_pct_of_peak']:.3f} % of peak) |",
        f"| RMSE AR − FEM [µm] | {m['rmse_um']:.4f} |",
        f"| max abs(corrected AR − FEM) [µm] | {m['corrected_max_abs_diff_um']:.5f} "
        f"({m['corrected_max_abs_diff_pct_of_peak']:.4f} % of peak) |",
        f"| RMSE corrected AR − FEM [µm] | {m['corrected_rmse_um']:.5f} |",
        "",
        "Files: `timeseries.csv` (growth at every Δτ), `summary.json` (these numbers), "
        "`figure.png` (in the manner of the paper's Fig. 2/3), and the FEM fields where "
        "requested (`fields/`, `temperature_3d.png`).",
        "",
    ]
    return "\n".join(lines)


def _timeseries_columns(ev: Evaluation) -> dict:
    return {
        "time_s": ev.times_s, "time_h": ev.times_s / 3600.0, "q_W_m2": ev.q_W_m2,
        "fem_growth_um": ev.fem_growth_um, "ar_growth_um": ev.ar_growth_um,
        "ar_corrected_growth_um": ev.ar_corrected_growth_um,
        "ar_minus_fem_um": ev.ar_growth_um - ev.fem_growth_um,
        "ar_corrected_minus_fem_um": ev.ar_corrected_growth_um - ev.fem_growth_um,
    }


def _write_models(ev: Evaluation, out_dir: Path) -> list[str]:
    """``model.json`` (the paper's AR(1), eqs. 12-14) and ``model_corrected.json`` (the
    radial-mode corrected AR(1)) at the scenario's Δτ, for ``arfem compensate``."""
    from arfem import __version__
    from arfem.models.compensator import ar1_model
    from arfem.scenarios.model_file import write_model
    rod, dt = ev.scenario.rod, ev.scenario.dtau_s
    out = []
    for name, kind in (("model.json", "paper_ar1"), ("model_corrected.json", "corrected_ar1")):
        if kind == "paper_ar1":
            c1, c2 = c1_paper(rod, dt), c2_paper(rod, dt, 1.0)
            how = "paper eqs. 12-14 (C1 = exp(-b dtau), C2 per unit q)"
        else:
            c1, c2 = corrected_coefficients(rod, dt, 1.0)
            how = "arfem's radial-mode corrected AR(1) (slowest axially uniform mode)"
        write_model(out_dir / name, ar1_model(
            c1, c2 * 1e6, dtau_s=dt, kind=kind, arfem_version=__version__,
            description=f"{how}, for the rod of scenario {ev.scenario.name!r}"))
        out.append(name)
    return out


def write_outputs(ev: Evaluation, out_dir: Path, fixed_precision: bool = False,
                  progress=None) -> list[str]:
    """Write every output of one evaluation into ``out_dir`` (a staging directory);
    ``progress`` as in :func:`evaluate`.

    ``fixed_precision`` (``arfem reproduce``): numbers with the fixed decimals of
    :mod:`arfem.scenarios.deterministic` and no wall times, so that a rerun writes the
    same bytes.
    """
    progress = progress or _no_progress
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cols = _timeseries_columns(ev)
    if fixed_precision:
        write_csv(out_dir / "timeseries.csv", det.fixed_columns(cols), fmt=det.csv_formats(cols))
    else:
        write_csv(out_dir / "timeseries.csv", cols)
    written = ["timeseries.csv"]
    extra = _write_fields(ev, out_dir, progress)
    summary = {**ev.metrics, **extra}
    write_json(out_dir / "summary.json", det.fixed_metrics(summary) if fixed_precision
               else summary)
    written += _write_models(ev, out_dir)
    progress("figure")
    _figure(ev, out_dir / "figure.png")
    atomic_write_text(out_dir / "summary.md", _summary_md(ev))
    written += ["summary.json", "figure.png", "summary.md"]
    src = Path(ev.scenario.source)
    if src.suffix == ".toml" and src.is_file():     # the input, for report.html and reruns
        atomic_write_text(out_dir / "scenario.toml", read_text_utf8(src))
        written.append("scenario.toml")
    return written


def _write_fields(ev: Evaluation, out_dir: Path, progress=_no_progress) -> dict:
    """FEM field time series and 3D picture (:mod:`arfem.fem.export`), where the scenario asks.

    The fields are solved again, with stored states, at every
    ``outputs.field_interval_s`` (and at the growth peak), and the thermo-elastic
    displacement is computed at those times only. Returns extra summary entries:
    the elastic growth at the peak (face-averaged and on the axis) and its relative
    difference from α∫θ dV / A (reciprocity).
    """
    sc = ev.scenario
    if not (sc.outputs.fields or sc.outputs.picture or sc.fem.elastic):
        return {}
    from arfem.fem import export
    from arfem.fem.elastic import ThermoElastic

    total = sc.schedule.total_s
    times = np.arange(0.0, total + 1e-9, sc.outputs.field_interval_s)
    peak_t = ev.metrics["fem_peak_time_h"] * 3600.0
    times = np.union1d(np.append(times, total), [peak_t])
    model = ev.model
    progress("FEM fields and displacement")
    if sc.fem.theta is None:
        res = solve_modal(model, sc.schedule, output_times_s=times, store_fields=True)
    else:
        full = solve_theta(model, sc.schedule.subdivided(sc.fem.dt_s), sc.fem.dt_s,
                           theta=sc.fem.theta, store_fields=True)
        pick = np.searchsorted(full.times_s, times - 1e-6)
        res = type(full)(full.times_s[pick], full.growth_m[pick], full.heat_J[pick],
                         full.fields[pick])
    extra: dict = {}
    el = ThermoElastic.build(model) if (sc.fem.elastic or sc.outputs.fields
                                        or sc.outputs.picture) else None
    if el is not None:
        k = int(np.argmax(res.growth_m))
        face, axis = el.growth(res.fields[k])
        vol = float(res.growth_m[k])
        extra.update({
            "elastic_growth_face_um_at_peak": float(face) * 1e6,
            "elastic_growth_axis_um_at_peak": float(axis) * 1e6,
            "reciprocity_rel_diff": abs(float(face) - vol) / abs(vol) if vol else 0.0,
        })
    k = int(np.argmax(res.growth_m))
    if sc.outputs.fields:
        progress("fields.xdmf3 + fields.h5")
        export.write_fields(model, res, out_dir / "fields" / "fields.xdmf3", elastic=el,
                            peak_index=k)
    if sc.outputs.picture:
        progress("3D picture")
        # the flux on the AR interval that ends at the FEM peak: the heating that made it
        q_peak = float(ev.q_W_m2[int(np.argmax(np.abs(ev.fem_growth_um)))])
        export.render_png(model, np.asarray(res.fields[k]), out_dir / "temperature_3d.png",
                          elastic=el, heat_flux_W_m2=q_peak,
                          title=f"{sc.name}: temperature at peak growth, "
                                f"t = {res.times_s[k] / 3600:.2f} h")
    return extra


def run_scenario(path, out, force: bool = False, progress=None) -> Evaluation:
    """Load, evaluate and write one scenario into ``out`` (atomically); ``progress`` as in
    :func:`evaluate`."""
    progress = progress or _no_progress
    scenario = load_scenario(path)
    prepare_out_dir(out, force, writes=WRITES)
    ev = evaluate(scenario, progress=progress)
    with staged_out_dir(out, force) as stage:
        write_outputs(ev, stage, progress=progress)
        progress("report.html")
        write_html_report(stage)
    return ev


def _paper_readme(evs: list[Evaluation]) -> str:
    rows = []
    for ev in evs:
        m = ev.metrics
        q = m["q_W_m2"]
        rows.append((ev.scenario.name, q, m))
    lines = [
        "# The paper's Fig. 2 and 3, reproduced",
        "",
        "Generated by `arfem reproduce` (do not edit by hand). Seed paper: Du et al., "
        "\"First-order autoregressive modeling method for axial thermal error of machine tool "
        "spindle\", J. Harbin Inst. Technol. 53(7), 2021.",
        "",
        "## Closed-form AR(1) coefficients at Δτ = 30 s",
        "",
        "| quantity | paper | arfem |",
        "|---|---|---|",
        f"| C1 (eq. 13) | {PAPER_VALUES['C1']} | {rows[0][2]['C1']:.4f} |",
    ]
    for name, q, m in rows:
        pv = PAPER_VALUES["C2_um"].get(q)
        lines.append(f"| C2 at q = {q:g} W/m² (eq. 14) [µm] | {pv if pv is not None else '–'} | "
                     f"{m['C2_um']:.4f} |")
    lines += [
        "",
        "## FEM against AR(1) over the 24 h duty cycle",
        "",
        "| scenario | q [W/m²] | FEM peak [µm] | AR peak [µm] | max abs(AR−FEM) [µm] | "
        "% of peak | C1 fitted to FEM | C2 fitted [µm] | corrected AR max diff [% of peak] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, q, m in rows:
        lines.append(
            f"| [{name}]({name}/figure.png) | {q:g} | {m['fem_peak_um']:.3f} | "
            f"{m['ar_peak_um']:.3f} | {m['max_abs_diff_um']:.3f} | "
            f"{m['max_abs_diff_pct_of_peak']:.2f} | {m['C1_fitted']:.5f} | "
            f"{m['C2_fitted_um']:.4f} | {m['corrected_max_abs_diff_pct_of_peak']:.4f} |")
    lines += [
        "",
        "The closed-form coefficients agree with the paper's to the digits it prints. The "
        "paper's AR(1) falls short of the FEM by a few percent at the peaks because the 1D "
        "theory assumes a uniform cross-section temperature: with Biot number hR/λ = "
        f"{rows[0][2]['biot']:.2f} the surface runs cooler than the core, so the rod loses "
        "less heat and cools more slowly than eq. 13 assumes. The corrected AR(1) takes C1 "
        "and C2 from the slowest axially uniform mode J0(μ1 r/R) of the convectively cooled "
        "cylinder (μ J1(μ) = Bi J0(μ)); it is derived, not fitted, and tracks the FEM to the "
        "figure in the last column.",
        "",
        "## How these files are written",
        "",
        "Rerunning `arfem reproduce` writes the same bytes, so `git diff --exit-code "
        "reports/` can gate a change: the computation runs on one BLAS thread (its round-off "
        "then does not depend on the core count), numbers are written with fixed decimals "
        "(growths and differences in µm: 5 in timeseries.csv, 6 in summary.json, as are % of "
        "peak and hours; C1, C2, the Biot number and relative differences: 9; time_s and "
        "q_W_m2: 3), and wall times are printed, not written. `MANIFEST.json` holds the SHA-256 of every committed file. The FEM field "
        "time series (`*/fields/`: XDMF + HDF5) are regenerated but not committed (git "
        "ignores them): their float64 values change in the last digits on a CPU whose BLAS "
        "kernels round differently.",
        "",
        "`arfem reproduce --check` recomputes the numbers and compares them with these files "
        "instead of writing: it exits 1 and names the file, the key or column and the size "
        "of the drift when a number moves by more than 2 units in its last written decimal "
        "(plus 1e-9 relative). The pictures and this README are not compared by it.",
        "",
    ]
    return "\n".join(lines)


MANIFEST = "MANIFEST.json"


#: Subdirectories reproduce writes but does not list for version control (see the README
#: it writes): the field values (XDMF + HDF5, float64) differ in their last digits between CPUs.
UNCOMMITTED_DIRS = ("fields",)


def _committed(rel: str) -> bool:
    return not any(part in UNCOMMITTED_DIRS for part in rel.split("/")[:-1])


def reproduce(out="reports/paper", force: bool = False, progress=None) -> list[Evaluation]:
    """Run every paper scenario into ``out``/<name>/ plus a README comparing with the paper.

    ``out`` may be updated without ``--force`` only if it holds an earlier
    ``arfem reproduce`` result (its ``MANIFEST.json``), and then only the files that
    result wrote and nobody has changed since (their SHA-256 is in the manifest).
    The files are deterministic (:mod:`arfem.scenarios.deterministic`): a rerun writes
    the same bytes.
    """
    out = Path(out)
    earlier = MANIFEST in owned_files(out)          # an earlier reproduce result
    prepare_out_dir(out, force or earlier)
    progress = progress or _no_progress
    with det.blas_threads():
        evs = [evaluate(load_scenario(builtin_scenario_path(n)), progress=tagged(progress, n))
               for n in PAPER_SCENARIOS]
        with staged_out_dir(out, force, update=earlier) as stage:
            for ev in evs:
                write_outputs(ev, stage / ev.scenario.name, fixed_precision=True,
                              progress=tagged(progress, ev.scenario.name))
            atomic_write_text(stage / "README.md", _paper_readme(evs))
            progress("report.html")
            write_html_report(stage, file_sizes=False)      # byte-identical on a rerun
            rels = [p.relative_to(stage).as_posix() for p in sorted(stage.rglob("*"))
                    if p.is_file()]
            write_json(stage / MANIFEST, {
                "generator": "arfem reproduce",
                "scenarios": list(PAPER_SCENARIOS),
                "files": {r: sha256_file(stage / r) for r in rels if _committed(r)},
                "not_committed": [r for r in rels if not _committed(r)]})
    return evs


def check_reproduction(out="reports/paper") -> list[str]:
    """``arfem reproduce --check``: recompute the paper scenarios' numbers and compare them
    with the ``summary.json`` and ``timeseries.csv`` files in ``out``, writing nothing.

    Returns one line per drift (file, key or column, committed and recomputed values, the
    drift and its tolerance); empty when everything agrees within
    :data:`arfem.scenarios.deterministic.TOLERANCE_UNITS` units in the last written
    decimal. The FEM fields and the pictures are not solved or drawn; the elastic growth
    at the peak is (it is in summary.json).
    """
    import dataclasses
    import tempfile

    out = Path(out)
    if MANIFEST not in owned_files(out):
        raise InputError("holds no arfem reproduce output (its MANIFEST.json) to check "
                         "against; run arfem reproduce first", str(out))
    drifts = []
    with det.blas_threads(), tempfile.TemporaryDirectory() as tmp:
        for name in PAPER_SCENARIOS:
            sc = load_scenario(builtin_scenario_path(name))
            sc = dataclasses.replace(sc, outputs=dataclasses.replace(
                sc.outputs, fields=False, picture=False))
            ev = evaluate(sc)
            extra = _write_fields(ev, Path(tmp))       # fields and picture off: no file
            expected = det.fixed_metrics({**ev.metrics, **extra})
            drifts += det.compare_summary(str(out / name / "summary.json"),
                                          out / name / "summary.json", expected)
            drifts += det.compare_timeseries(str(out / name / "timeseries.csv"),
                                             out / name / "timeseries.csv",
                                             _timeseries_columns(ev))
    return drifts


# -- CLI -----------------------------------------------------------------------------------

def _print_summary(ev: Evaluation, out) -> None:
    m = ev.metrics
    print(f"{ev.scenario.name}: FEM peak {m['fem_peak_um']:.3f} µm, AR peak {m['ar_peak_um']:.3f} µm, "
          f"max|AR-FEM| {m['max_abs_diff_um']:.3f} µm ({m['max_abs_diff_pct_of_peak']:.2f} % of "
          f"peak), corrected {m['corrected_max_abs_diff_pct_of_peak']:.4f} %; "
          f"C1 {m['C1']:.5f} (fitted {m['C1_fitted']:.5f}) -> {out}")


def _main_run(args) -> int:
    from arfem.scenarios import geometry_scenario as geo     # a [geometry] scenario (issue 32)
    if geo.is_geometry_scenario(args.scenario):
        return geo.main_run_geometry(args)
    from arfem.scenarios.progress import Progress
    with Progress(7, "arfem run", enabled=not args.no_progress) as progress:
        ev = run_scenario(args.scenario, args.out, args.force, progress=progress)
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
                       description="Run one scenario file: FEM against the paper's AR(1) and "
                                   "the corrected AR(1); writes timeseries.csv, summary.json, "
                                   "figure.png, summary.md and FEM fields into --out.")
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
