"""The diagnosis: what the nominal simulation gets wrong on a measured record, which cause
explains it, and how much the model extended by that cause gains on a hold-out.

Data flow: :class:`arfem.models.diagnosis.dataset.Dataset` → :func:`diagnose` → :class:`Diagnosis`
(the contract's ``diagnosis.json`` content plus the series for figures) → writers in
:mod:`arfem.models.diagnosis.report`.

Selection rule (documented in every report):

1. every applicable cause is fitted on the rows before the hold-out that the loader
   did not flag as outliers (:mod:`arfem.models.diagnosis.candidates`);
2. each is scored by BIC on *effective* samples, N_eff ln(RSS/N) + k ln N_eff, with
   N_eff = N(1 − ρ1)/(1 + ρ1) from the lag-1 autocorrelation ρ1 of the best candidate's
   residual (one N_eff for all, so the scores are comparable);
3. the best-scoring cause is named only if it beats the baseline in a nested F test
   on N_eff samples at p < ``ALPHA`` (Bonferroni over the candidates) *and* cuts the
   fit-window RMSE by at least ``MIN_GAIN`` -- otherwise the cause is ``none``;
4. except where ``none`` would contradict its own definition ("the nominal simulation
   explains the data to within measurement noise"): if the baseline's fit-window RMSE
   exceeds ``MISFIT_FACTOR`` times the noise (estimated from the data's second
   differences) and the best cause removes at least ``MISFIT_CUT`` of it, that cause is
   named though the F test is not significant (``named_by = "misfit"``). This happens
   when one cause explains most of a large misfit but leaves a correlated residual that
   shrinks N_eff to a handful -- typically two causes at once, or one outside the
   vocabulary; the report says so.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arfem.models.diagnosis import stats as st
from arfem.models.diagnosis.candidates import (CAUSES, ArPhysics, CandidateFit, FemPhysics,
                                         fit_candidate)
from arfem.models.diagnosis.speed import (SPEED_CAUSES, cv_rmse, fit_frame_thermometers,
                                    fit_speed_candidate, median_block_ratio,
                                    forward_folds, mlr, paper_ar, select_frame_structure,
                                    speed_to_heat_map)
from arfem.params import InputError
from arfem.io import json_text

__all__ = ["Diagnosis", "diagnose", "ALPHA", "MIN_GAIN", "MISFIT_FACTOR",
           "MISFIT_CUT", "CONTRACT_PARAMETERS"]

#: family-wise significance level of the test against the baseline
ALPHA = 1e-3
#: minimum relative cut of the fit-window RMSE for a cause to be named
MIN_GAIN = 0.05
#: rule 4: a baseline off by more than this many noise standard deviations ...
MISFIT_FACTOR = 10.0
#: ... whose best cause removes at least this fraction of its fit-window RMSE
MISFIT_CUT = 0.5
#: the ``parameters`` of diagnosis.json, by cause, exactly as the measured-data contract
#: names them; anything else a fit reports goes under ``parameters_detail``
CONTRACT_PARAMETERS = {
    "none": (),
    "ambient_drift": ("ambient_gain_um_per_K",),
    "convection_mismatch": ("h_W_m2K",),
    "speed_dependent_convection": ("h_running_W_m2K", "h_stopped_W_m2K"),
    "heat_input_scale": ("scale",),
    "frame_expansion": ("frame_time_constant_h", "frame_gain"),
    "sensor_drift": ("drift_um_per_h",),
    "nonlinear_convection": ("exponent",),
}


@dataclass
class Diagnosis:
    """Result: ``summary`` is the JSON document; ``series`` the arrays for figures/CSV."""

    summary: dict
    series: dict
    text: list = field(default_factory=list)


def _phases(t, running, tau_s):
    """'heating' while the input is on; 'cooling' within 3τ after it stops; else 'standing'."""
    lab = np.where(running, "heating", "standing").astype(object)
    last_on = -np.inf
    for i in range(t.size):
        if running[i]:
            last_on = t[i]
        elif t[i] - last_on < 3.0 * tau_s:
            lab[i] = "cooling"
    return lab


def _metrics(y, pred, mask):
    r = (y - pred)[mask]
    return {"rmse_um": st.rmse(r), "max_abs_um": float(np.max(np.abs(r))) if r.size else None,
            "fit_pct": st.fit_percent(y[mask], pred[mask])}


def _holdout_start(t, holdout_start_s, where):
    """The hold-out start [s] -- as given, or 2/3 of the record -- and how it was chosen.

    Fitting uses the samples with t < start and scoring those with t >= start, so the
    given value is kept as it is (not moved to the next sample time)."""
    if holdout_start_s is None:
        hs = t[0] + (t[-1] - t[0]) * 2.0 / 3.0
        how = "not given: the last third of the record (from 2/3 of its duration)"
    else:
        hs = float(holdout_start_s)
        how = "given by --holdout-start"
        if not np.isfinite(hs):
            raise InputError(f"must be finite, got {holdout_start_s!r}", "--holdout-start")
    n_before = int(np.sum(t < hs))
    n_after = int(np.sum(t >= hs))
    if n_before < 20 or n_after < 5:
        span = (f"{n_before} samples to fit and {n_after} to score (record {t[0]:g}..{t[-1]:g} s); "
                "need >= 20 and >= 5")
        if holdout_start_s is None:
            raise InputError(f"record too short: its last third from {hs:g} s leaves {span}",
                             where)
        raise InputError(f"{hs:g} s leaves {span}", f"--holdout-start (for {where})")
    return hs, how


def _select(fits: dict, base: CandidateFit, n_tests: int, noise_um: float):
    """Scores, the named cause and the runner-up (see module docstring)."""
    valid = {c: f for c, f in fits.items() if f is not None}
    best_rss = min(f.rss for f in valid.values())
    best_fit = min(valid.values(), key=lambda f: f.rss)
    r_best = best_fit.extra.get("_res")
    n = base.n
    rho = st.lag1(r_best) if r_best is not None else 0.0
    n_eff = st.effective_n(n, rho)
    scores = {c: st.bic(f.rss, n, n_eff, f.k) for c, f in valid.items()}
    order = sorted(scores, key=scores.get)
    named = [c for c in order if c != "none"]
    top = named[0] if named else "none"
    tests = {}
    for c in named:
        f = valid[c]
        p = st.f_test_p(base.rss, f.rss, f.k, n_eff)
        cut = 1.0 - np.sqrt(f.rss / base.rss) if base.rss > 0 else 0.0
        tests[c] = {"p_value": p, "rmse_cut_pct": 100 * cut,
                    "significant": bool(p < ALPHA / max(n_tests, 1) and cut >= MIN_GAIN)}
    cause = top if top != "none" and tests[top]["significant"] else "none"
    base_rmse = float(np.sqrt(base.rss / max(n, 1)))
    misfit = bool(np.isfinite(noise_um) and base_rmse > MISFIT_FACTOR * noise_um)
    if top != "none":
        tests[top]["named_by"] = "f_test" if cause == top else None
        if (cause == "none" and misfit and tests[top]["rmse_cut_pct"] >= 100 * MISFIT_CUT):
            cause = top
            tests[top]["named_by"] = "misfit"
    runner = None
    for c in order:
        if c != cause:
            runner = c
            break
    return cause, runner, scores, tests, {"n": n, "rho1": rho, "n_eff": n_eff,
                                          "noise_sigma_um": noise_um,
                                          "baseline_rmse_over_noise": (
                                              base_rmse / noise_um if noise_um > 0 else None)}


def _select_cv(fits: dict, cvs: dict, folds, t, robust: bool = False):
    """Speed-only records: the cause with the least forward-chaining validation RMSE on
    the fit window is named only if it cuts the baseline's by >= ``MIN_GAIN`` *and* wins
    on a majority of the validation blocks (see :func:`arfem.models.diagnosis.speed.forward_folds`);
    otherwise ``none``. Residuals of thermal models are so autocorrelated that the
    effective sample size of the fit window is a few dozen, so out-of-sample error on
    later blocks -- each opening, like the hold-out, with a speed the training part has
    not seen -- is the comparison used instead of an F test."""
    base_cv, base_per = cvs["none"]
    scores = {c: v[0] for c, v in cvs.items() if np.isfinite(v[0])}
    order = sorted(scores, key=scores.get)
    tests = {}
    for c in order:
        if c == "none":
            continue
        cv, per = cvs[c]
        won = int(sum(a < b for a, b in zip(per, base_per)))
        cut = 1.0 - cv / base_cv if base_cv > 0 else 0.0
        tests[c] = {"cv_rmse_um": cv, "cv_per_block_um": per, "blocks_won": won,
                    "rmse_cut_pct": 100 * cut,
                    "significant": bool(cut >= MIN_GAIN and won > len(per) / 2)}
    named = [c for c in order if c != "none"]
    if robust:    # frame_search "average" (post hoc): speed.median_block_ratio decides
        for c in named:
            r = median_block_ratio(tests[c]["cv_per_block_um"], base_per)
            tests[c].update(median_block_ratio=r, significant=bool(r <= 1.0 - MIN_GAIN))
        named.sort(key=lambda c: tests[c]["median_block_ratio"])
    top = named[0] if named else "none"
    cause = top if top != "none" and tests[top]["significant"] else "none"
    runner = next((c for c in order if c != cause), None)
    blocks = [[float(t[v][0]), float(t[v][-1])] for _, v in folds]
    n = fits["none"].n
    rho = st.lag1(fits["none"].extra["_res"])
    return cause, runner, scores, tests, {
        "n": n, "rho1": rho, "n_eff": st.effective_n(n, rho),
        "validation_blocks_s": blocks, "baseline_cv_rmse_um": base_cv,
        "baseline_cv_per_block_um": base_per,
        **({"naming": f"post hoc rule of --frame-search average: the cause with the least "
                      f"median per-block RMSE ratio to the baseline, named if that is <= "
                      f"{1 - MIN_GAIN:g}"} if robust else {})}


def _residual_analysis(t, y, pred, mask, signals: dict, running, tau_s):
    r = (y - pred)
    rm = r[mask]
    n = int(mask.sum())
    rho = st.lag1(rm)
    n_eff = st.effective_n(n, rho)
    out = _metrics(y, pred, mask)
    out["ljung_box_p"] = st.ljung_box_p(rm)
    out["lag1_autocorrelation"] = rho
    ph = _phases(t, running, tau_s)
    out["per_phase"] = {p: ({"rmse_um": st.rmse(r[mask & (ph == p)]),
                             "n": int(np.sum(mask & (ph == p)))}
                            if np.any(mask & (ph == p)) else None)
                        for p in ("heating", "cooling", "standing")}
    xc = {}
    for name, x in {**signals, "time_s": t}.items():
        x = np.asarray(x, float)
        ok = mask & np.isfinite(x)
        if ok.sum() < 5 or np.std(x[ok]) == 0:
            continue
        xc[name] = st.xcorr(r[ok], x[ok])
    out["cross_correlation"] = xc
    out["cross_correlation_bound_white"] = 1.96 / np.sqrt(n)
    out["cross_correlation_bound_neff"] = 1.96 / np.sqrt(n_eff)
    return out


def diagnose(ds, holdout_start_s=None, frame_search: str = "narrow") -> Diagnosis:
    """Diagnose a loaded :class:`~arfem.models.diagnosis.dataset.Dataset`.

    Parameters
    ----------
    ds : Dataset
        The record (``q_W_m2`` → FEM baseline; ``speed_rpm`` → calibrated AR(1) baseline).
    holdout_start_s : float, optional
        Start of the hold-out [s]; default the last third of the record.
    frame_search : {"narrow", "wide"}
        Speed-only records: the frame structures compared by forward-chaining
        validation (:func:`arfem.models.diagnosis.speed.frame_structures`).
    """
    t = np.asarray(ds.time_s, float)
    y = np.asarray(ds.growth_um, float)
    good = ~np.asarray(ds.outliers, bool)
    hs, how = _holdout_start(t, holdout_start_s, str(ds.source))
    rows = good & (t < hs)
    hold = good & (t >= hs)
    rod = ds.rod
    amb_K = None if ds.ambient_C is None else np.asarray(ds.ambient_C, float) - rod.ambient_C
    temps = {k: np.asarray(v, float) for k, v in ds.temperatures.items()}
    signals = {}
    if ds.input_kind == "q_W_m2":
        signals["q_W_m2"] = np.asarray(ds.q_W_m2, float)
    else:
        signals["speed_rpm"] = np.asarray(ds.speed_rpm, float)
    if ds.ambient_C is not None:
        signals["ambient_C"] = np.asarray(ds.ambient_C, float)
    signals.update(temps)
    text = []
    extra_models = {}

    if ds.input_kind == "q_W_m2":
        q = np.asarray(ds.q_W_m2, float)
        running = q > 0
        fem = FemPhysics(rod)
        tau_s = 1.0 / fem.slowest_rate()
        frame = temps.get("T_frame_C")
        fits = {}
        for c in CAUSES:
            f = fit_candidate(c, fem, t, q, y, rows, ds.initial_known, amb_K, frame)
            if f is not None:
                f.extra["_res"] = (y - f.prediction)[rows]
            fits[c] = f
        base = fits["none"]
        cause, runner, scores, tests, neff = _select(
            fits, base, sum(f is not None for f in fits.values()) - 1, st.noise_sigma(y[rows]))
        ext = fits[cause]
        ar = ArPhysics(rod)
        ar_base = fit_candidate("none", ar, t, q, y, rows, ds.initial_known, amb_K, frame)
        ar_ext = ar_base if cause == "none" else fit_candidate(cause, ar, t, q, y, rows,
                                                               ds.initial_known, amb_K, frame)
        base_model = "fem"
        ar_label = "paper AR(1), coefficients from the [rod] values (eqs. 13-14)"
        extra_models["ar"] = {"baseline": ar_base, "extended": ar_ext}
    else:
        sp = np.asarray(ds.speed_rpm, float)
        running = sp > 0
        levels, seen, W, map_info = speed_to_heat_map(t, sp, temps, rows)
        rho_c_R = rod.density_kg_m3 * rod.specific_heat_J_kgK * rod.radius_m
        paper_pred, paper_info = paper_ar(t, y, sp, rows, W, seen)
        base_paper = CandidateFit("none", "ar", {}, paper_pred, 0)
        folds = forward_folds(t, sp, rows)
        fold_maps = [speed_to_heat_map(t, sp, temps, tr)[1:3] for tr, _ in folds]
        frame_struct, frame_table = None, {}
        if temps:
            frame_struct, frame_table = select_frame_structure(t, y, sp, temps, rows, folds,
                                                               fold_maps, frame_search)

        def fit_c(c, tr, seen_, W_):
            if c == "frame_expansion" and frame_struct is not None:
                return fit_frame_thermometers(t, y, sp, tr, seen_, W_, temps, frame_struct)
            return fit_speed_candidate(c, t, y, sp, tr, seen_, W_, amb_K, rho_c_R)

        fits, cvs = {}, {}
        for c in SPEED_CAUSES:
            f = fit_c(c, rows, seen, W)
            fits[c] = f
            if f is None:
                continue
            f.extra["_res"] = (y - f.prediction)[rows]
            it = iter(fold_maps)

            def fitter(tr, c=c, it=it):
                g = fit_c(c, tr, *next(it))
                return None if g is None else g.prediction
            cvs[c] = cv_rmse(fitter, y, folds)
        for c in CAUSES:
            fits.setdefault(c, None)
        base = fits["none"]   # output-error AR: the reference the candidates are tested against
        cause, runner, scores, tests, neff = _select_cv(fits, cvs, folds, t,
                                                        robust=frame_search == "average")
        if frame_struct is not None:
            neff["frame_structure"] = {"components": frame_struct.components,
                                       "sensor_lag_h": frame_struct.sensor_lag_h,
                                       "heat_exponent": frame_struct.heat_exponent,
                                       "slow_response": frame_struct.slow_lag,
                                       "label": frame_struct.label,
                                       "search": frame_search,
                                       "validation_rmse_um": frame_table}
        ext = fits[cause] if cause != "none" else base_paper
        tau_s = base.extra.get("time_constant_h", 1.0) * 3600.0
        base = base_paper
        base_model = "ar"
        ar_label = "paper AR(1) calibrated by eq. 17 before the hold-out"
        extra_models["ar_output_error"] = {"baseline": fits["none"], "extended": ext}
        text.append(f"speed-to-heat mapping: {json_text(map_info)}")
        text.append(f"paper AR(1) calibration: {json_text(paper_info)}")

    bres = _residual_analysis(t, y, base.prediction, good, signals, running, tau_s)
    eres = _residual_analysis(t, y, ext.prediction, good, signals, running, tau_s)
    b_hold = st.rmse((y - base.prediction)[hold])
    e_hold = st.rmse((y - ext.prediction)[hold])
    gain = 100.0 * (1.0 - e_hold / b_hold) if b_hold > 0 else 0.0

    # what "score" is (lower is better either way): a BIC for q_W_m2 records, a
    # forward-chaining validation RMSE [µm] for speed-only ones
    score_kind = "bic_on_n_eff" if ds.input_kind == "q_W_m2" else "validation_rmse_um"
    summary = {
        "dataset": ds.name,
        "cause": cause,
        "baseline": {"model": base_model, "rmse_um": bres["rmse_um"],
                     "max_abs_um": bres["max_abs_um"], "ljung_box_p": bres["ljung_box_p"],
                     "fit_pct": bres["fit_pct"], "per_phase": bres["per_phase"],
                     "lag1_autocorrelation": bres["lag1_autocorrelation"],
                     "cross_correlation": bres["cross_correlation"],
                     "cross_correlation_bound_white": bres["cross_correlation_bound_white"],
                     "cross_correlation_bound_neff": bres["cross_correlation_bound_neff"]},
        "extended": {"model": ext.model if cause != "none" else base_model,
                     "rmse_um": eres["rmse_um"], "max_abs_um": eres["max_abs_um"],
                     "ljung_box_p": eres["ljung_box_p"], "fit_pct": eres["fit_pct"],
                     "per_phase": eres["per_phase"]},
        "holdout": {"start_s": hs, "how_chosen": how, "baseline_rmse_um": b_hold,
                    "extended_rmse_um": e_hold, "gain_pct": gain,
                    "n_samples": int(hold.sum())},
        "parameters": {k: v for k, v in ext.parameters.items()
                       if k in CONTRACT_PARAMETERS[cause]} if cause != "none" else {},
        "parameters_detail": {k: v for k, v in ext.parameters.items()
                              if k not in CONTRACT_PARAMETERS[cause]} if cause != "none" else {},
        "candidates": [{"cause": c, "score": scores[c], "score_kind": score_kind,
                        **(tests[c] if c in tests else {}),
                        "parameters": fits[c].parameters,
                        "fit_rmse_um": float(np.sqrt(fits[c].rss / max(fits[c].n, 1)))}
                       for c in sorted(scores, key=scores.get)],
        "runner_up": None,
        "selection": {"rule": (f"BIC on N_eff samples; named only if nested F test p < "
                               f"{ALPHA:g}/candidates and fit-window RMSE cut >= "
                               f"{100 * MIN_GAIN:g} %, or, where the baseline is off by more "
                               f"than {MISFIT_FACTOR:g} noise σ, if it removes >= "
                               f"{100 * MISFIT_CUT:g} % of that misfit")
                      if ds.input_kind == "q_W_m2" else
                              (f"score = forward-chaining validation RMSE [µm] on the fit "
                               f"window; the best cause is named only if it cuts the "
                               f"baseline's by >= {100 * MIN_GAIN:g} % and wins on a majority "
                               f"of the validation blocks"),
                      **neff},
        "not_applicable": [c for c in CAUSES if fits.get(c) is None],
        "input_kind": ds.input_kind,
        "data_notes": list(ds.notes),
    }
    if runner is not None and fits.get(runner) is not None:
        if ds.input_kind == "q_W_m2":
            why = (f"BIC {scores[runner]:.1f} vs {scores.get(cause, float('nan')):.1f}"
                   + (f"; F-test p = {tests[runner]['p_value']:.3g}, fit-RMSE cut "
                      f"{tests[runner]['rmse_cut_pct']:.1f} %" if runner in tests else ""))
        else:
            why = (f"validation RMSE {scores[runner]:.3g} vs {scores.get(cause, float('nan')):.3g} µm"
                   + (f"; cut {tests[runner]['rmse_cut_pct']:.1f} % of the baseline's, "
                      f"{tests[runner]['blocks_won']}/{len(tests[runner]['cv_per_block_um'])} "
                      f"blocks won" if runner in tests else ""))
        summary["runner_up"] = {"cause": runner, "score": scores[runner], "score_kind": score_kind,
                                "parameters": fits[runner].parameters, "why_lost": why}
    # AR-form results
    ar_out = {}
    for key, d in extra_models.items():
        bb, ee = d["baseline"], d["extended"]
        if bb is None or ee is None:
            continue
        bh = st.rmse((y - bb.prediction)[hold])
        eh = st.rmse((y - ee.prediction)[hold])
        ar_out[key] = {"baseline_model": bb.model, "extended_model": ee.model,
                       "baseline_holdout_rmse_um": bh, "extended_holdout_rmse_um": eh,
                       "gain_pct": 100.0 * (1.0 - eh / bh) if bh > 0 else 0.0,
                       "parameters": ee.parameters}
    summary["ar_form"] = ar_out
    summary["ar_form_description"] = ar_label
    series = {"time_s": t, "growth_um": y, "baseline_um": base.prediction,
              "extended_um": ext.prediction, "outlier": (~good).astype(float)}
    if temps:
        pm, names = mlr(y, temps, rows)
        if pm is not None:
            summary["mlr"] = {"sensors": names, "holdout_rmse_um": st.rmse((y - pm)[hold]),
                              "note": "growth = β0 + Σ β_i T_i fitted before the hold-out "
                                      "(paper eq. 18)"}
            series["mlr_um"] = pm
    return Diagnosis(summary, series, text)
