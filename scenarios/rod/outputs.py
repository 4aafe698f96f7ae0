"""The files of one scenario run and of the paper's reproduction: the writers of
``arfem run`` and ``arfem reproduce`` (CSV, JSON, PNG, Markdown, XDMF, report.html), and
``reproduce --check``.

Data flow: scenario file → :class:`~arfem.scenarios.rod.scenario.Scenario` →
:func:`arfem.scenarios.rod.evaluation.evaluate` → :class:`~arfem.scenarios.rod.evaluation.Evaluation`
→ :func:`write_outputs`. The command (:mod:`arfem.scenarios.commands.run`) only parses and prints;
tests, benchmarks and the API call these functions.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from arfem.fem.heat import solve_modal, solve_theta
from arfem.models.ar1 import c1_paper, c2_paper, corrected_coefficients
from arfem.params import InputError
from arfem.scenarios.rod.scenario import PAPER_SCENARIOS, Scenario, load_scenario
from arfem.scenarios.shipped import builtin_scenario_path
from arfem.scenarios.rod.evaluation import Evaluation, evaluate, no_progress
from arfem.io import atomic_write_text, read_text_utf8, sha256_file, write_csv, write_json
from arfem.scenarios.html_report import write_html_report
from arfem.scenarios.outdir import owned_files, prepare_out_dir, staged_out_dir
from arfem.scenarios.rod import deterministic as det
from arfem.scenarios.progress import tagged

__all__ = ["write_outputs", "run_scenario", "reproduce", "check_reproduction",
           "growth_figure", "PAPER_VALUES", "WRITES", "AR_TOLERANCE_PCT",
           "keep_committed_pictures"]

#: The files ``write_outputs`` puts into --out (checked before the work: never an input
#: or a file arfem did not write; see arfem.scenarios.outdir).
WRITES = ("timeseries.csv", "summary.json", "figure.png", "summary.md", "temperature_3d.png",
          "model.json", "model_corrected.json",
          "scenario.toml", "report.html", "fields/fields.xdmf3", "fields/fields.h5",
          "fields/peak.xdmf")

#: Values printed in the seed paper (Du et al. 2021, Sec. 2) at Δτ = 30 s.
PAPER_VALUES = {"C1": 0.9909, "C2_um": {2000.0: 0.1985, 3000.0: 0.2977}}


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
    th = ev.times_s / 3600.0
    fig = Figure(figsize=(8.0, 8.6), dpi=150, layout="constrained")
    ax, bx, cx = fig.subplots(3, 1, sharex=True, gridspec_kw={"height_ratios": [2.2, 1, 1]})
    edges = ev.scenario.schedule.edges_s / 3600.0
    levels = sorted({float(q) for q in ev.scenario.schedule.q_W_m2 if q > 0})
    for i, qv in enumerate(ev.scenario.schedule.q_W_m2):
        if qv > 0:
            for a in (ax, bx, cx):
                a.axvspan(edges[i], edges[i + 1], color=_C_HEAT, alpha=0.15, lw=0)
    _growth_panel(ax, ev, th, levels)
    _ar_error_panel(bx, ev, th)
    _corrected_error_panel(cx, ev)
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


def _growth_panel(ax, ev: Evaluation, th, levels: list) -> None:
    """Panel (a) of :func:`growth_figure`: the growth [µm] of the FEM, the paper's AR(1)
    and the corrected AR(1) against time ``th`` [h], the heat-flux ``levels`` [W/m²] in
    the legend."""
    from matplotlib.patches import Patch
    m = ev.metrics
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


def _ar_error_panel(bx, ev: Evaluation, th) -> None:
    """Panel (b) of :func:`growth_figure`: paper AR(1) − FEM [µm] with the CI tolerance
    (± AR_TOLERANCE_PCT % of the FEM peak) as labelled lines."""
    m = ev.metrics
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


def _corrected_error_panel(cx, ev: Evaluation) -> None:
    """Panel (c) of :func:`growth_figure`: corrected AR(1) − FEM [nm]."""
    m = ev.metrics
    th = ev.times_s / 3600.0
    dc = (ev.ar_corrected_growth_um - ev.fem_growth_um) * 1e3
    cx.plot(th, dc, ":", color=_C_ARC, lw=1.8)
    cx.axhline(0, color="0.5", lw=0.6)
    amp = float(np.max(np.abs(dc))) or 1.0
    cx.set_ylim(-1.6 * amp, 1.9 * amp)
    cx.set_ylabel("corrected AR(1) − FEM\n[nm]")
    cx.text(0.005, 0.96, f"(c) max |corrected AR − FEM| = {m['corrected_max_abs_diff_um'] * 1e3:.3g}"
            f" nm ({m['corrected_max_abs_diff_pct_of_peak']:.2g} % of peak)",
            transform=cx.transAxes, va="top", fontsize=8)


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
    from arfem.scenarios.compensation.model_file import write_model
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
    :mod:`arfem.scenarios.rod.deterministic` and no wall times, so that a rerun writes the
    same bytes.
    """
    progress = progress or no_progress
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


def _write_fields(ev: Evaluation, out_dir: Path, progress=no_progress) -> dict:
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
    if sc.outputs.fields or sc.outputs.picture:
        # the flux on the AR interval that ends at the FEM peak: the heating that made it
        q_peak = float(ev.q_W_m2[int(np.argmax(np.abs(ev.fem_growth_um)))])
        export.write_scenario_fields(
            model, res, out_dir, elastic=el, title=sc.name, heat_flux_W_m2=q_peak,
            fields_xdmf="fields/fields.xdmf3" if sc.outputs.fields else None,
            picture_png="temperature_3d.png" if sc.outputs.picture else None,
            progress=progress)
    return extra


def run_scenario(path, out, force: bool = False, progress=None, limits=None) -> Evaluation:
    """Load (``path``, or a :class:`Scenario` read already), evaluate and write one
    scenario into ``out`` (atomically); ``progress`` as in
    :func:`evaluate`, ``limits`` (:class:`arfem.limits.Limits`) as the user allows."""
    progress = progress or no_progress
    scenario = path if isinstance(path, Scenario) else load_scenario(path, limits)
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


def keep_committed_pictures(stage: Path, out: Path) -> list[str]:
    """Put back the bytes of every PNG of an earlier reproduce result in ``out`` (listed
    in its manifest and unchanged since) whose regenerated namesake in ``stage``
    matches it within one grey level (:func:`arfem.scenarios.rod.deterministic.same_picture`):
    a fresh clone stays clean where the renderer moved an edge pixel by one level.
    Returns the files kept (relative paths)."""
    own = owned_files(out)
    kept = []
    for new in sorted(stage.rglob("*.png")):
        rel = new.relative_to(stage).as_posix()
        old = out / rel
        if own.get(rel) is None or not old.is_file() or sha256_file(old) != own[rel]:
            continue
        if new.read_bytes() != old.read_bytes() and det.same_picture(new, old):
            new.write_bytes(old.read_bytes())
            kept.append(rel)
    return kept


def reproduce(out="reports/paper", force: bool = False, progress=None) -> list[Evaluation]:
    """Run every paper scenario into ``out``/<name>/ plus a README comparing with the paper.

    ``out`` may be updated without ``--force`` only if it holds an earlier
    ``arfem reproduce`` result (its ``MANIFEST.json``), and then only the files that
    result wrote and nobody has changed since (their SHA-256 is in the manifest).
    The files are deterministic (:mod:`arfem.scenarios.rod.deterministic`): a rerun writes
    the same bytes.
    """
    out = Path(out)
    earlier = MANIFEST in owned_files(out)          # an earlier reproduce result
    prepare_out_dir(out, force or earlier)
    progress = progress or no_progress
    with det.blas_threads():
        evs = [evaluate(load_scenario(builtin_scenario_path(n)), progress=tagged(progress, n))
               for n in PAPER_SCENARIOS]
        with staged_out_dir(out, force, update=earlier) as stage:
            for ev in evs:
                write_outputs(ev, stage / ev.scenario.name, fixed_precision=True,
                              progress=tagged(progress, ev.scenario.name))
            if earlier:
                keep_committed_pictures(stage, out)
            atomic_write_text(stage / "README.md", _paper_readme(evs))
            progress("report.html")
            write_html_report(stage, file_sizes=False,      # byte-identical on a rerun
                              versions=False)                # and on other packages
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
    :data:`arfem.scenarios.rod.deterministic.TOLERANCE_UNITS` units in the last written
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
