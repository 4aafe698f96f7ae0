"""Writers for a :class:`arfem.models.diagnosis.engine.Diagnosis`: JSON, CSV, figures, Markdown.

All files go into a directory the caller stages (``arfem.io.staged_out_dir``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from arfem.models.diagnosis import stats as st
from arfem.io import atomic_write_text, write_csv, write_json

__all__ = ["write_all"]


def _fmt(v, nd=3):
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.{nd}g}" if abs(v) < 1e-3 or abs(v) >= 1e4 else f"{v:.{nd}f}"
    return str(v)


def _plain(text: str) -> str:
    """``text`` as matplotlib shows it literally: a user's ``$`` is not mathtext.

    >>> print(_plain("run $x^{$ 17"))
    run \\$x^{\\$ 17
    """
    return str(text).replace("$", r"\$")


def _figures(diag, out: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    s = diag.series
    j = diag.summary
    th = s["time_s"] / 3600.0
    good = s["outlier"] == 0
    hs = j["holdout"]["start_s"] / 3600.0
    fig, ax = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    ax[0].plot(th[good], s["growth_um"][good], ".", ms=2, color="0.5", label="measured")
    ax[0].plot(th, s["baseline_um"], label=f"baseline ({j['baseline']['model']})")
    ax[0].plot(th, s["extended_um"], label=f"extended ({j['extended']['model']})")
    if "mlr_um" in s:
        ax[0].plot(th, s["mlr_um"], lw=0.8, label="MLR on temperatures (eq. 18)")
    ax[0].axvline(hs, color="k", ls="--", lw=0.8, label="hold-out start")
    ax[0].set_ylabel("growth [µm]")
    ax[0].legend(fontsize=8)
    ax[0].set_title(_plain(f"{j['dataset']}: cause = {j['cause']}"))
    ax[1].plot(th[good], (s["growth_um"] - s["baseline_um"])[good], lw=0.7, label="residual, baseline")
    ax[1].plot(th[good], (s["growth_um"] - s["extended_um"])[good], lw=0.7, label="residual, extended")
    ax[1].axvline(hs, color="k", ls="--", lw=0.8)
    ax[1].set_xlabel("time [h]")
    ax[1].set_ylabel("residual [µm]")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "growth_residual.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for key, lab in (("baseline_um", "baseline"), ("extended_um", "extended")):
        r = (s["growth_um"] - s[key])[good]
        a = st.acf(r, min(200, r.size - 1))
        ax[0].plot(np.arange(a.size), a, label=lab)
    n = int(good.sum())
    ax[0].axhline(1.96 / np.sqrt(n), color="k", ls=":", lw=0.8)
    ax[0].axhline(-1.96 / np.sqrt(n), color="k", ls=":", lw=0.8, label="±1.96/√N")
    ax[0].set_xlabel("lag [samples]")
    ax[0].set_ylabel("autocorrelation of residual")
    ax[0].legend(fontsize=8)
    xc = j["baseline"]["cross_correlation"]
    names = list(xc)
    ax[1].bar(range(len(names)), [xc[k] for k in names])
    for b, ls in ((j["baseline"]["cross_correlation_bound_white"], ":"),
                  (j["baseline"]["cross_correlation_bound_neff"], "--")):
        ax[1].axhline(b, color="k", ls=ls, lw=0.8)
        ax[1].axhline(-b, color="k", ls=ls, lw=0.8)
    ax[1].set_xticks(range(len(names)))
    ax[1].set_xticklabels([_plain(k) for k in names], rotation=70, fontsize=7)
    ax[1].set_ylabel("xcorr(baseline residual, signal)")
    ax[1].set_title("bounds: ±1.96/√N (dotted), ±1.96/√N_eff (dashed)", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "correlations.png", dpi=110)
    plt.close(fig)


def _markdown(diag) -> str:
    j = diag.summary
    b, e, h = j["baseline"], j["extended"], j["holdout"]
    L = [f"# Diagnosis of `{j['dataset']}`", "",
         f"**Cause: `{j['cause']}`**" + (f" — parameters: " + ", ".join(
             f"`{k}` = {_fmt(v, 4)}" for k, v in j["parameters"].items()) if j["parameters"] else ""),
         "", "## What the nominal simulation gets wrong", "",
         f"Baseline model: **{b['model']}** ({j['ar_form_description'] if b['model'] == 'ar' else 'FEM with the [rod] values, exact modal integration at the sample times'}).",
         "", "| measure | baseline | extended |", "|---|---|---|"]
    for k, lab in (("rmse_um", "RMSE [µm]"), ("max_abs_um", "max |error| [µm]"),
                   ("fit_pct", "fit [%]"), ("ljung_box_p", "Ljung–Box p (eq. 19)")):
        L.append(f"| {lab} | {_fmt(b.get(k))} | {_fmt(e.get(k))} |")
    for p in ("heating", "cooling", "standing"):
        bp, ep = b["per_phase"].get(p), e["per_phase"].get(p)
        L.append(f"| RMSE {p} [µm] | {_fmt(bp and bp['rmse_um'])} | {_fmt(ep and ep['rmse_um'])} |")
    L += ["", "Phases: heating = input on; cooling = within 3 time constants after it stops; "
          "standing = otherwise. Outliers flagged by the loader are excluded everywhere.", "",
          "Cross-correlation of the baseline residual with every recorded signal "
          f"(bounds ±{b['cross_correlation_bound_white']:.3f} for white noise, "
          f"±{b['cross_correlation_bound_neff']:.3f} with the effective sample size):", "",
          "| signal | xcorr | beyond N_eff bound |", "|---|---|---|"]
    for k, v in b["cross_correlation"].items():
        L.append(f"| {k} | {v:+.3f} | {'yes' if abs(v) > b['cross_correlation_bound_neff'] else 'no'} |")
    sel = j["selection"]
    L += ["", "## Naming the cause", "", f"Rule: {sel['rule']}. "
          f"N = {sel['n']}, lag-1 autocorrelation {sel['rho1']:.3f}, "
          f"N_eff = {sel['n_eff']:.1f}.", ""]
    if j["input_kind"] == "q_W_m2":
        L += ["| candidate | BIC score | F-test p | fit-RMSE cut [%] | parameters |",
              "|---|---|---|---|---|"]
        for c in j["candidates"]:
            L.append(f"| {c['cause']} | {c['score']:.1f} | {_fmt(c.get('p_value'))} | "
                     f"{_fmt(c.get('rmse_cut_pct'))} | " + ", ".join(
                         f"{k}={_fmt(v, 4)}" for k, v in c["parameters"].items()) + " |")
    else:
        blocks = ", ".join(f"{a / 3600:.2f}-{b / 3600:.2f} h" for a, b in sel["validation_blocks_s"])
        L += [f"Validation blocks (each fitted on everything before it): {blocks}. Baseline "
              f"(AR(1) output error) validation RMSE per block: "
              + ", ".join(_fmt(v) for v in sel["baseline_cv_per_block_um"]) + " µm.", ""]
        if "frame_structure" in sel:
            fs = sel["frame_structure"]
            L += [(f"Thermometer frame structure chosen by the same validation: "
                   f"{fs['components']} principal components, sensor lag {fs['sensor_lag_h']:g} h "
                   "(validation RMSE of every structure tried, µm: " + ", ".join(
                       f"{k}: {_fmt(v)}" for k, v in fs["validation_rmse_um"].items()) + ").")
                  if isinstance(fs["components"], int) else       # FrameEnsemble: no choice
                  f"Thermometer frame: no structure chosen, the {fs['label']} structures.", ""]
        L += ["| candidate | validation RMSE [µm] | per block [µm] | cut [%] | blocks won | parameters |",
              "|---|---|---|---|---|---|"]
        for c in j["candidates"]:
            per = ", ".join(_fmt(v) for v in c.get("cv_per_block_um", []))
            L.append(f"| {c['cause']} | {_fmt(c['score'])} | {per} | {_fmt(c.get('rmse_cut_pct'))} | "
                     f"{c.get('blocks_won', '')} | " + ", ".join(
                         f"{k}={_fmt(v, 4)}" for k, v in c["parameters"].items()) + " |")
    if j["not_applicable"]:
        L.append("")
        L.append("Not applicable to this record: " + ", ".join(j["not_applicable"]) +
                 (" (for speed-only records the calibrated C1 and C2 already absorb a "
                  "different h and a heat scale; nonlinear convection needs a temperature "
                  "scale the record lacks; ambient drift needs `ambient_C`)."
                  if j["input_kind"] == "speed_rpm" else " (missing input column)."))
    named = next((c for c in j["candidates"] if c["cause"] == j["cause"]), {})
    if named.get("named_by") == "misfit":
        L += ["", f"**Named by misfit, not by the F test.** The baseline is off by "
              f"{sel['baseline_rmse_over_noise']:.0f} noise σ (σ ≈ {sel['noise_sigma_um']:.3g} µm "
              f"from second differences), so `none` cannot hold; `{j['cause']}` removes "
              f"{named['rmse_cut_pct']:.0f} % of it, but what it leaves is so correlated "
              f"(N_eff = {sel['n_eff']:.1f}) that the F test is not significant (p = "
              f"{named['p_value']:.3g}). More than one cause, or one outside the vocabulary, "
              "is likely; treat the named one as the largest part."]
    if j.get("runner_up"):
        r = j["runner_up"]
        L += ["", f"Runner-up: `{r['cause']}` — lost because {r['why_lost']}."]
    L += ["", "## Extended model on the hold-out", "",
          f"Hold-out from t = {h['start_s']:g} s ({h['start_s'] / 3600:.2f} h); {h['how_chosen']}. "
          f"All fits use only the data before it.", "",
          "| model | hold-out RMSE [µm] |", "|---|---|",
          f"| baseline ({b['model']}) | {_fmt(h['baseline_rmse_um'])} |",
          f"| extended ({e['model']}) | {_fmt(h['extended_rmse_um'])} |"]
    for key, a in j.get("ar_form", {}).items():
        L.append(f"| {key}: {a['baseline_model']} | {_fmt(a['baseline_holdout_rmse_um'])} |")
        L.append(f"| {key}: {a['extended_model']} | {_fmt(a['extended_holdout_rmse_um'])} |")
    if "mlr" in j:
        L.append(f"| MLR on {len(j['mlr']['sensors'])} temperatures (eq. 18) | "
                 f"{_fmt(j['mlr']['holdout_rmse_um'])} |")
    L += ["", f"**gain_pct = {h['gain_pct']:.1f} %** (100·(1 − extended/baseline) on the hold-out)."]
    for key, a in j.get("ar_form", {}).items():
        L.append(f"AR form ({key}): gain {a['gain_pct']:.1f} %.")
    L += ["", "## Data notes", ""] + [f"- {n}" for n in j["data_notes"]] + \
         [f"- {t}" for t in diag.text] + ["", "Figures: `growth_residual.png`, `correlations.png`."]
    return "\n".join(L) + "\n"


def write_all(diag, out) -> None:
    """Write diagnosis.json, series.csv, report.md and the figures into ``out``."""
    out = Path(out)
    write_json(out / "diagnosis.json", diag.summary)
    cols = {k: v for k, v in diag.series.items()}
    write_csv(out / "series.csv", cols)
    atomic_write_text(out / "report.md", _markdown(diag))
    _figures(diag, out)
