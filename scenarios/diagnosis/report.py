"""Writers for a :class:`arfem.models.diagnosis.engine.Diagnosis`: JSON, CSV, figures, Markdown.

All files go into a directory the caller stages (``arfem.io.staged_out_dir``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from arfem.models.diagnosis import stats as st
from arfem.models.diagnosis.rules import MIN_GAIN, blocks_needed
from arfem.models.diagnosis.speed_intervals import at_search_edge
from arfem.models.geodiagnosis.engine import NAMED_BY_SCREEN
from arfem.io import atomic_write_text, write_csv, write_json
from arfem.scenarios.diagnosis.document import document

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


def _figures(diag, j: dict, out: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    s = diag.series
    th = s["time_s"] / 3600.0
    good = s["outlier"] == 0
    hs = j["holdout"]["start_s"] / 3600.0
    fig, ax = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    ax[0].plot(th[good], s["growth_um"][good], ".", ms=2, color="0.5", label="measured")
    ax[0].plot(th, s["baseline_um"], label=f"baseline ({j['baseline']['model']})")
    est = j.get("verdict", "established") == "established"
    ext = "extended" if est else "best candidate, not established"
    # no candidate changed the model: the "extended" series is the baseline, not drawn
    same = bool(np.allclose(s["extended_um"], s["baseline_um"], equal_nan=True))
    if not same:
        ax[0].plot(th, s["extended_um"], label=f"{ext} ({j['extended']['model']})")
    if "mlr_um" in s:
        ax[0].plot(th, s["mlr_um"], lw=0.8, label="MLR on temperatures (eq. 18)")
    ax[0].axvline(hs, color="k", ls="--", lw=0.8, label="hold-out start")
    ax[0].set_ylabel("growth [µm]")
    ax[0].legend(fontsize=8)
    named = " + ".join(c["cause"] for c in j.get("causes", [])) or j["cause"]
    bc = (j.get("best_candidate") or {}).get("cause")
    ax[0].set_title(_plain(f"{j['dataset']}: verdict {j.get('verdict', '?')}, cause = {named}"
                           + (f" (best candidate {bc}, not established)" if bc else "")))
    ax[1].plot(th[good], (s["growth_um"] - s["baseline_um"])[good], lw=0.7, label="residual, baseline")
    if not same:
        ax[1].plot(th[good], (s["growth_um"] - s["extended_um"])[good], lw=0.7,
                   label=f"residual, {ext}")
    ax[1].axvline(hs, color="k", ls="--", lw=0.8)
    ax[1].set_xlabel("time [h]")
    ax[1].set_ylabel("residual = measured − model [µm]")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "growth_residual.png", dpi=110)
    plt.close(fig)

    _correlation_figure(plt, diag, j, out)


def _correlation_figure(plt, diag, j: dict, out: Path):
    """Residual diagnostics an engineer can read: left, the autocorrelation of each
    residual against lag [h] (how long a misfit persists); right, the cross-correlation
    of the baseline residual with each recorded input against lag [h] (what the misfit
    follows, and how late). Bands: the 95 % significance bound of a correlation on the
    effective number of independent samples (always <= 1)."""
    s = diag.series
    good = s["outlier"] == 0
    good = good & np.isfinite(s["growth_um"])
    t = s["time_s"][good]
    dt_h = float(np.median(np.diff(t))) / 3600.0 if t.size > 1 else 1.0
    max_lag = int(min(max(1, round(12.0 / dt_h)), max(t.size // 3, 1)))
    white = st.corr_bound(int(good.sum()))
    fig, ax = plt.subplots(1, 2, figsize=(11, 5.2))
    for key, lab, col in (("baseline_um", "baseline", "#0072B2"),
                          ("extended_um", "extended", "#D55E00")):
        r = (s["growth_um"] - s[key])[good]
        a = st.acf(r, max_lag)
        ax[0].plot(np.arange(a.size) * dt_h, a, color=col, label=f"residual, {lab}")
    ax[0].axhspan(-white, white, color="0.85", label=f"95 % band of a white residual (±{white:.2f})")
    ax[0].set_xlabel("lag [h]")
    ax[0].set_ylabel("autocorrelation [-]")
    ax[0].set_ylim(-1.05, 1.05)
    ax[0].set_title("residual = measured − model: how long a misfit lasts", fontsize=9)
    ax[0].legend(fontsize=8, loc="upper right")
    r = (s["growth_um"] - s["baseline_um"])[good]
    lags = np.arange(-max_lag, max_lag + 1) * dt_h
    colours = ["#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000"]
    shown = 0
    ar = st.acf(r, max_lag)
    curves = []
    for name in j["baseline"]["cross_correlation"]:
        if name == "time_s" or name not in s:
            continue
        x = np.asarray(s[name], float)[good]
        if not np.all(np.isfinite(x)) or np.std(x) == 0:
            continue
        c = st.ccf(r, x, max_lag)
        # Bartlett: both series autocorrelated -> var(ccf) ≈ (1 + 2 Σ ρ_r(k) ρ_x(k)) / N
        ax_ = st.acf(x, max_lag)
        m = min(ar.size, ax_.size)
        v = (1.0 + 2.0 * float(np.sum(ar[1:m] * ax_[1:m]))) / max(r.size, 1)
        b = min(1.96 * np.sqrt(max(v, 0.0)), 1.0)
        curves.append((name, c, b))
    # the input and the ambient always; of the other sensors the two that stand out most
    first = [cv for cv in curves if not cv[0].startswith("T_")]
    temps = sorted((cv for cv in curves if cv[0].startswith("T_")),
                   key=lambda cv: -np.max(np.abs(cv[1])) / max(cv[2], 1e-9))[:2]
    shown = 0
    for name, c, b in first + temps:
        col = colours[shown % len(colours)]
        ax[1].plot(lags, c, color=col, label=f"{_plain(name)} (95 % bound ±{b:.2f}, dashed)")
        ax[1].axhline(b, color=col, ls="--", lw=0.8)
        ax[1].axhline(-b, color=col, ls="--", lw=0.8)
        shown += 1
    if len(curves) > shown:
        ax[1].text(0.01, 0.02, f"{len(curves) - shown} more temperature sensors not drawn "
                   "(values in report.md)", transform=ax[1].transAxes, fontsize=7)
    if not shown:
        ax[1].text(0.5, 0.5, "no recorded input varies", ha="center", transform=ax[1].transAxes)
    ax[1].axvline(0.0, color="k", lw=0.6)
    ax[1].set_xlabel("lag [h] (> 0: the residual follows the signal)")
    ax[1].set_ylabel("cross-correlation with baseline residual [-]")
    ax[1].set_ylim(-1.05, 1.05)
    ax[1].set_title("what the baseline misfit follows", fontsize=9)
    ax[1].legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=1)
    ax[1].set_xlim(lags[0], lags[-1])
    fig.tight_layout()
    fig.savefig(out / "correlations.png", dpi=110)
    plt.close(fig)


def _words(v, depth: int = 0) -> str:
    """A JSON value as plain words: numbers rounded, lists and tables comma-separated.

    >>> _words({"500.0": {"ref_rpm": 1250.0, "how": "speed ratio"}, "x": []})
    '500.0 (ref rpm 1250, how speed ratio), x none'
    """
    if v is None or v == [] or v == {} or v == "":
        return "none"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return ", ".join(_words(x, depth + 1) for x in v)
    if isinstance(v, dict):
        inner = ", ".join(f"{str(k).replace('_', ' ')} {_words(x, depth + 1)}" for k, x in v.items())
        return f"({inner})" if depth else inner
    return str(v)


def _sentences(item: str) -> list[str]:
    """A data note as sentences: ``label: {json}`` becomes "label: key = value; ..."."""
    import json
    head, sep, rest = str(item).partition(": ")
    if sep and rest.lstrip().startswith("{"):
        try:
            d = json.loads(rest)
        except ValueError:
            d = None
        if isinstance(d, dict):
            parts = [f"{str(k).replace('_', ' ')} = {_words(v)}" for k, v in d.items()]
            return [f"{head[:1].upper()}{head[1:]}: " + "; ".join(parts) + "."]
    text = str(item).strip()
    return [text[:1].upper() + text[1:] + ("" if text.endswith(".") else ".")]


def _unbounded(name, ci) -> str:
    """A note when a 95 % interval reaches an end of the range the fit can return: the
    data do not bound the parameter there (e.g. a frame time constant 0.1-200 h); the
    one test of an end, :func:`arfem.models.diagnosis.speed_intervals.at_search_edge`."""
    return ("; reaches the end of the range the fit can return, so the data do not bound it"
            if at_search_edge(name, ci[0]) or at_search_edge(name, ci[1]) else "")


#: report.md's line on the engine that diagnosed a speed_rpm record
#: (diagnosis.json ``selection.speed_engine``; ``arfem diagnose --speed-engine``)
_SPEED_ENGINE_LINE = {
    "branch": "Speed engine: `branch`, the rod engine's speed branch (candidates chosen by "
              "forward-chaining validation; the published procedure).",
    "pipeline": "Speed engine: `pipeline`, the one diagnosis pipeline on the speed plant "
                "(candidates screened by BIC on N_eff; a prototype)."}


def verdict(j: dict) -> list[str]:
    """The report's opening: the verdict (``explained``, ``established``, ``unconfirmed``
    or ``not_explained``, chosen by the rules of :mod:`arfem.models.diagnosis.verdict`)
    in the same words diagnosis.json's ``verdict_detail.text`` and the terminal carry,
    then the key figure and the hold-out table, and for a speed record the engine that
    diagnosed it (everything else follows as evidence)."""
    b, e, h = j["baseline"], j["extended"], j["holdout"]
    base, ext = h["baseline_rmse_um"], h["extended_rmse_um"]
    mlr = (j.get("mlr") or {}).get("holdout_rmse_um")
    d = j.get("verdict_detail")
    if d is None:                 # a diagnosis.json written before verdicts (issue 30)
        d = {"verdict": "not given", "text": "this diagnosis.json predates verdicts; see "
                                             "the warnings and the residual analysis"}
    text = f"**Verdict: {d['verdict']}.** {d['text']}"
    ext_label = ("extended" if j.get("verdict") == "established" else
                 "best candidate, not established" if (j.get("best_candidate") or {}).get("causes")
                 else "extended")
    L = ["## Verdict", "", text, "",
         "![the record, the simulation as assumed and the extended model, with their "
         "residuals](growth_residual.png)", "",
         f"| model (fitted before t = {h['start_s'] / 3600:.2f} h) | hold-out RMSE [µm] |",
         "|---|---|",
         f"| simulation as assumed ({b['model']}) | {_fmt(base)} |",
         f"| {ext_label} ({e['model']}) | {_fmt(ext)} |"]
    if mlr is not None:
        L.append(f"| MLR on {len(j['mlr']['sensors'])} temperatures (eq. 18) | {_fmt(mlr)} |")
    engine = (j.get("selection") or {}).get("speed_engine")     # speed_rpm records
    if engine in _SPEED_ENGINE_LINE:
        L += ["", _SPEED_ENGINE_LINE[engine]]
    return L + ["", "## Warnings and the named cause in full", ""]


def _cause_lines(j: dict) -> list[str]:
    """The named cause(s) with their parameters and 95 % intervals, the best candidate
    not established, and an equivalent alternative."""
    L: list[str] = []
    causes = j.get("causes")
    if causes:
        for i, c in enumerate(causes):
            ci = c.get("ci95", {})
            widened = set(c.get("ci95_model_choice", []))
            L.append(f"**{'Cause' if i == 0 else 'Second cause'}: `{c['cause']}`** — " + ", ".join(
                f"`{k}` = {_fmt(v, 4)}" + (f" (95 % interval {_fmt(ci[k][0], 4)} to "
                                           f"{_fmt(ci[k][1], 4)}{_unbounded(k, ci[k])}"
                                           + (", widened to hold the equivalent "
                                              "alternative's estimate" if k in widened else "")
                                           + ")" if k in ci else "")
                for k, v in c["parameters"].items()))
            L.append("")
    else:
        L += [f"**Cause: `{j['cause']}`**" + (" — parameters: " + ", ".join(
            f"`{k}` = {_fmt(v, 4)}" for k, v in j["parameters"].items()) if j["parameters"] else ""), ""]
    bc = j.get("best_candidate")
    if bc:
        ci = bc.get("parameters_ci95") or {}
        L += [f"**Best candidate, not established: `{bc['cause']}`**" + (" — " + ", ".join(
            f"`{k}` = {_fmt(v, 4)}" + (f" (95 % interval {_fmt(ci[k][0], 4)} to "
                                       f"{_fmt(ci[k][1], 4)}{_unbounded(k, ci[k])})"
                                       if k in ci else "")
            for k, v in bc.get("parameters", {}).items()) if bc.get("parameters") else "")
            + ". Not established because: " + "; ".join(bc["not_established_because"]) + ".",
            ""]
    eq = j.get("equivalent_alternative")
    if eq:
        L += [f"Equivalent alternative: `{eq['cause']}` (" + ", ".join(
            f"`{k}` = {_fmt(v, 4)}" for k, v in eq["parameters"].items()) + f"). {eq['why']}.", ""]
    return L


def _residual_lines(j: dict) -> list[str]:
    """"What the nominal simulation gets wrong": baseline against extended, per phase,
    and the residual's cross-correlation with every recorded signal."""
    b, e = j["baseline"], j["extended"]
    L: list[str] = []
    L += ["## What the nominal simulation gets wrong", "",
         f"Baseline model: **{b['model']}** ({j['ar_form_description'] if b['model'] != 'fem' else 'FEM with the [rod] values, exact modal integration at the sample times'}).",
         "", "| measure | baseline | extended |", "|---|---|---|"]
    for k, lab in (("rmse_um", "RMSE [µm]"), ("max_abs_um", r"max \|error\| [µm]"),
                   ("fit_pct", "fit [%]"), ("ljung_box_p", "Ljung–Box p (eq. 19)")):
        f = st.format_p if k == "ljung_box_p" else _fmt
        L.append(f"| {lab} | {f(b.get(k))} | {f(e.get(k))} |")
    for p in ("heating", "cooling", "standing"):
        bp, ep = b["per_phase"].get(p), e["per_phase"].get(p)
        L.append(f"| RMSE {p} [µm] | {_fmt(bp and bp['rmse_um'])} | {_fmt(ep and ep['rmse_um'])} |")
    L += ["", "Phases: heating = input on; cooling = within 3 time constants after it stops; "
          "standing = otherwise. Outliers flagged by the loader are excluded everywhere. "
          "Residual = measured − model (positive: the rod grew more than the model says).", "",
          "Cross-correlation of the baseline residual with every recorded signal "
          f"(95 % significance bounds of a correlation: ±{b['cross_correlation_bound_white']:.3f} "
          f"for white noise, ±{b['cross_correlation_bound_neff']:.3f} on the effective sample "
          "size; lags in hours in `correlations.png`):", "",
          "| signal | xcorr | beyond N_eff bound |", "|---|---|---|"]
    for k, v in b["cross_correlation"].items():
        L.append(f"| {k} | {v:+.3f} | {'yes' if abs(v) > b['cross_correlation_bound_neff'] else 'no'} |")
    return L


def _heat_flux_candidates(j: dict) -> list[str]:
    """The candidates of a q_W_m2 record: BIC score, F test, fit-RMSE cut (refused
    ones with their reason)."""
    L: list[str] = []
    # the one pipeline's screen says why it did not name each cause alone
    why = any("not_named_alone_because" in c for c in j["candidates"])
    L += ["| candidate | BIC score | F-test p | fit-RMSE cut [%] | parameters |"
          + (" alone, not named because |" if why else ""),
          "|---|---|---|---|---|" + ("---|" if why else "")]
    for c in j["candidates"] + j.get("refused_candidates", []):
        if "refused" in c:
            L.append(f"| {c['cause']} | refused: {c['refused']} | – | – | " + ", ".join(
                f"{k}={_fmt(v, 4)}" for k, v in c["parameters"].items()) + " |"
                + (" – |" if why else ""))
            continue
        reason = " " + (c.get("not_named_alone_because") or (
            NAMED_BY_SCREEN if "not_named_alone_because" in c else "–")) + " |"
        L.append(f"| {c['cause']} | {c['score']:.1f} | {st.format_p(c.get('p_value'))} | "
                 f"{_fmt(c.get('rmse_cut_pct'))} | " + ", ".join(
                     f"{k}={_fmt(v, 4)}" for k, v in c["parameters"].items()) + " |"
                 + (reason if why else ""))
    return L


def _speed_candidates(j: dict, sel: dict) -> list[str]:
    """The candidates of a speed_rpm record, chosen by blocked validation: the blocks,
    the thermometer frame structure, and each candidate's validation RMSE."""
    L: list[str] = []
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
              f"Thermometer frame: no structure chosen, the {fs['label']} structures. "
              "Its `frame_time_constant_h` is the members' median; members with a "
              "sensor lag add that lag to it, so where the thermometers follow the "
              "frame without lag it runs long, and its 95 % interval (noise only) "
              "held the truth in 2 of 8 generated cases "
              "(`benchmarks/bench_speed_intervals.py --kinds frame_average`).", ""]
    if "drift_rule" in sel:                # --drift-last (post hoc option)
        L += [f"Naming: {sel['drift_rule']}.", ""]
    nb = len(sel["validation_blocks_s"])
    if "naming" not in sel:                # the rule of the default search (not average)
        L += [f"Naming test: a cause is named only if it cuts the baseline's validation "
              f"RMSE by at least {100 * MIN_GAIN:g} % and wins on at least "
              f"{blocks_needed(nb)} of the {nb} blocks.", ""]
    L += [f"| candidate | validation RMSE [µm] | per block [µm] | cut [%] | blocks won (of "
          f"{nb}) | parameters |",
          "|---|---|---|---|---|---|"]
    for c in j["candidates"]:
        per = ", ".join(_fmt(v) for v in c.get("cv_per_block_um", []))
        L.append(f"| {c['cause']} | {_fmt(c['score'])} | {per} | {_fmt(c.get('rmse_cut_pct'))} | "
                 f"{c.get('blocks_won', '')} | " + ", ".join(
                     f"{k}={_fmt(v, 4)}" for k, v in c["parameters"].items()) + " |")
    return L


def _second_cause_lines(j: dict) -> list[str]:
    """Each partner fitted together with the first cause, and whether it is
    significant."""
    L: list[str] = []
    pairs = j.get("second_cause_tests") or []
    if pairs:
        L += ["", "Second cause: each partner fitted together with the first cause "
              "(significant = F test against the first alone at the rule's level, RMSE cut "
              "large enough, and plausible):", "",
              "| pair | F-test p | fit-RMSE cut [%] | N_eff | significant | parameters |",
              "|---|---|---|---|---|---|"]
        for t in pairs:
            L.append(f"| {' + '.join(t['causes'])} | {st.format_p(t['p_value'])} | "
                     f"{_fmt(t['rmse_cut_pct'])} | {t['n_eff']:.1f} | "
                     f"{'yes' if t['significant'] else 'no' + (' (refused)' if 'refused' in t else '')} | "
                     + ", ".join(f"{k}={_fmt(v, 4)}" for k, v in t["parameters"].items()) + " |")
    return L


def _naming_lines(j: dict) -> list[str]:
    """"Naming the cause": the rule, the candidates, a second cause, what does not
    apply, a cause named by misfit and the runner-up."""
    sel = j["selection"]
    L = ["", "## Naming the cause", "", f"Rule: {sel['rule']}. "
          f"N = {sel['n']}, lag-1 autocorrelation {sel['rho1']:.3f}, "
          f"N_eff = {sel['n_eff']:.1f}.", ""]
    # by how they were chosen: a speed record on the one pipeline (the speed plant,
    # prototype) has BIC-screened candidates as a q_W_m2 record has
    L += _speed_candidates(j, sel) if "validation_blocks_s" in sel else _heat_flux_candidates(j)
    L += _second_cause_lines(j)
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
              f"(N_eff = {sel['n_eff']:.1f}) that the F test is not significant "
              f"({st.p_text(named['p_value'])}). More than one cause, or one outside the "
              "vocabulary, "
              "is likely; treat the named one as the largest part."]
    if j.get("runner_up"):
        r = j["runner_up"]
        L += ["", f"Runner-up: `{r['cause']}` — lost because {r['why_lost']}."]
    return L


def _markdown(diag, j: dict) -> str:
    L = [f"# Diagnosis of `{j['dataset']}`", ""] + verdict(j)
    for w in j.get("warnings", []):
        L += [f"> **Warning:** {w}", ""]
    L += _cause_lines(j) + _residual_lines(j) + _naming_lines(j)
    L += _holdout_section(j)
    L += ["", "## Data notes", ""] + [f"- {x}" for n in j["data_notes"] for x in _sentences(n)] + \
         [f"- {x}" for t in diag.evidence.notes for x in _sentences(t)] + \
         ["", "Figures: `growth_residual.png` (the record, both models, and their residuals), "
          "`correlations.png` (residual autocorrelation, and cross-correlation with each "
          "input, against lag in hours)."]
    return "\n".join(L) + "\n"


def write_all(diag, out) -> None:
    """Write diagnosis.json (:func:`arfem.scenarios.diagnosis.document.document`), series.csv,
    report.md and the figures of the rod's diagnosis ``diag`` into ``out``."""
    out = Path(out)
    j = document(diag)
    write_json(out / "diagnosis.json", j)
    cols = {k: v for k, v in diag.series.items()}
    write_csv(out / "series.csv", cols)
    atomic_write_text(out / "report.md", _markdown(diag, j))
    _figures(diag, j, out)


def _unseen_note(h: dict) -> str:
    """What the hold-out's speeds not seen before it do to the paper AR(1) baseline, and
    why ``arfem compensate`` scores ``model.json`` differently there ('' if none)."""
    unseen = h.get("speeds_not_seen_before_rpm")
    if not unseen:
        return ""
    share = h["n_samples_at_speeds_not_seen"] / max(h["n_samples"], 1)
    return (f" {h['n_samples_at_speeds_not_seen']} of them ({100 * share:.0f} %) run at "
            f"speeds not seen before it ({', '.join(f'{v:g}' for v in unseen)} rpm), whose C2 "
            "the baseline (paper AR(1)) takes from the early-rise mapping of eqs. 20-21; "
            "`model.json` is the same eq. 17 fit on every row before the hold-out with C2 "
            "interpolated linearly between the fitted speeds (extrapolated beyond them), "
            "so `arfem compensate` scores it "
            "differently on this hold-out (docs/measured-data.md, \"Two paper AR(1) "
            "numbers\").")


def _holdout_section(j: dict) -> list[str]:
    """The "Extended model on the hold-out" section: every model's hold-out RMSE, an
    unestablished candidate called so, and no "extended" row where the extended model
    is the baseline itself."""
    b, e, h = j["baseline"], j["extended"], j["holdout"]
    L = ["", "## Extended model on the hold-out", "",
         f"Hold-out from t = {h['start_s']:g} s ({h['start_s'] / 3600:.2f} h); {h['how_chosen']}. "
         f"All fits use only the data before it. Scored on its {h['n_samples']} rows with a "
         "growth reading (outliers left out)." + _unseen_note(h), "",
         "| model | hold-out RMSE [µm] |", "|---|---|",
         f"| baseline ({b['model']}) | {_fmt(h['baseline_rmse_um'])} |"]
    ext = ("extended" if j.get("verdict", "established") == "established"
           else "best candidate, not established")
    if (e["model"], h["extended_rmse_um"]) != (b["model"], h["baseline_rmse_um"]):
        L.append(f"| {ext} ({e['model']}) | {_fmt(h['extended_rmse_um'])} |")
    for key, a in j.get("ar_form", {}).items():
        L.append(f"| {key}, baseline ({a['baseline_model']}) | "
                 f"{_fmt(a['baseline_holdout_rmse_um'])} |")
        L.append(f"| {key}, {ext} ({a['extended_model']}) | "
                 f"{_fmt(a['extended_holdout_rmse_um'])} |")
    if "mlr" in j:
        L.append(f"| MLR on {len(j['mlr']['sensors'])} temperatures (eq. 18) | "
                 f"{_fmt(j['mlr']['holdout_rmse_um'])} |")
    L += ["", f"**gain_pct = {h['gain_pct']:.1f} %** (100·(1 − extended/baseline) on the hold-out)."]
    for key, a in j.get("ar_form", {}).items():
        L.append(f"AR form ({key}): gain {a['gain_pct']:.1f} %.")
    return L
