"""The diagnosis: what the nominal simulation gets wrong on a measured record, which cause
explains it, and how much the model extended by that cause gains on a hold-out.

Data flow: :class:`arfem.models.diagnosis.dataset.Dataset` → :func:`diagnose` → the one
typed :class:`~arfem.models.diagnosis.result.Diagnosis` of every plant (its ``evidence`` a
:class:`RodEvidence`) → ``diagnosis.json`` at the edge
(:func:`arfem.scenarios.diagnosis.document.document`) and the writers of
:mod:`arfem.scenarios.diagnosis.report`.

Selection rule (documented in every report; each rule has its one home in
:mod:`arfem.models.diagnosis.rules`, this module runs them):

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
   vocabulary; the report says so;
5. a fit outside the project's plausible ranges (``arfem.params.PLAUSIBLE_RANGES``: a
   heat scale outside 0.2-5, an h outside 1-2000 W/(m²K), ...) or stuck at the edge of
   its search range is refused as a cause; if the record's own magnitude is implausible
   against the nominal simulation (wrong units) no cause is named and a warning says
   what to check;
6. parsimony: where a cause with fewer parameters fits as well (the extra parameters'
   nested F test on N_eff has p >= ``PARSIMONY_P``) it is named, and the report gives the
   equivalent alternative;
7. a second cause is listed (contract v2) where the first leaves more than
   ``PAIR_MISFIT`` noise σ and the pair is significant against the first alone (F test
   on the pair's N_eff at ``ALPHA``/pairs, RMSE cut >= ``PAIR_MIN_GAIN``); parsimony
   applies within the pair. Where no single cause is named though the baseline is off by
   ``MISFIT_FACTOR`` σ, a pair that removes ``MISFIT_CUT`` of the misfit is named;
8. every named parameter has a 95 % interval from the joint fit
   (:func:`arfem.models.diagnosis.candidates.parameter_ci95`); on speed-only records from
   refits of the named candidate without each of several contiguous blocks
   (:func:`arfem.models.diagnosis.speed_intervals.jackknife_ci95`).

9. a cause named by rule 4 (the misfit rule) whose extended model is worse than the
   baseline on the hold-out is not named: it is reported as ``unconfirmed``;
10. a named cause (or pair) whose effect on the fit window -- the RMS of its prediction
    minus the baseline's -- is below ``EFFECT_FACTOR`` times the slow part of the noise
    it leaves (the RMS of the residual's 30-min means) is not named either
    (``unconfirmed``): slow sensor wander is fitted by a flexible cause but is not one.
    The second cause of a pair is held to the same rule with its own increment over
    the first (post hoc: added after the fresh batch 9000 was scored).

11. the verdict (:mod:`arfem.models.diagnosis.verdict`, :func:`add_verdict`): the cause
    named by rules 1-10 is *established* only if its 95 % intervals exclude no effect
    and stay inside the fit's range and the hold-out confirms it; otherwise it moves to
    ``best_candidate`` and the verdict is *unconfirmed* -- or *explained* where the
    baseline's residual is within the noise, *not_explained* where nothing was named
    and it is not.

Every N_eff (rules 2, 3, 6, 7 and the intervals) is the smaller of the lag-1 form and
the batch-means form, which sees slow sensor wander
(:func:`arfem.models.diagnosis.stats.noise_n_eff`).

Without ``--holdout-start`` the hold-out is the last third of the record if it holds a
change of the input, else it starts at the last such change
(:func:`arfem.models.diagnosis.holdout.default_holdout`, the mesh's too);
a hold-out whose growth varies by less than ``INFORMATIVE_NOISE_LEVELS`` noise σ gets a
warning.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Mapping, NamedTuple

import numpy as np

from arfem.models.diagnosis import stats as st
from arfem.models.diagnosis.candidates import (CAUSES, H_CAUSES, ArPhysics, CandidateFit,
                                               FemPhysics, fit_candidate, fit_rod_causes,
                                               parameter_ci95)
from arfem.models.diagnosis.rules import (
    ALPHA, EFFECT_FACTOR, MIN_GAIN, MISFIT_CUT, MISFIT_FACTOR, PAIR_MIN_GAIN,
    PAIR_MISFIT, PARSIMONY_P, _FEM_RULE, _SPEED_RULE, _effect_and_slow_noise,
    _implausible, _parsimony, _second_cause, _select, _select_cv, _unconfirmed,
    naming_test_text,
    _units_warning)
from arfem.models.diagnosis.speed_intervals import jackknife_ci95
from arfem.models.diagnosis.speed import (SPEED_CAUSES, fit_speed_candidate, mlr, paper_ar,
                                          speed_to_heat_map)
from arfem.models.diagnosis.speed_frame import SpeedFrameInputs, fit_frame_thermometers
from arfem.models.diagnosis.speed_select import cv_rmse, forward_folds, select_frame_structure
from arfem.params import InputError
from arfem.io import json_text
from arfem.models.diagnosis.blas import one_blas_thread
from arfem.models.diagnosis.holdout import default_holdout
from arfem.models.diagnosis.result import (ChannelEvidence, ChannelHoldout, Diagnosis, Holdout,
                                           NamedCause, frozen_mapping)

__all__ = ["Diagnosis", "RodEvidence", "typed_result", "diagnose", "observations", "ALPHA", "MIN_GAIN", "MISFIT_FACTOR", "EFFECT_FACTOR",
           "MISFIT_CUT", "CONTRACT_PARAMETERS", "PARSIMONY_P", "PAIR_MIN_GAIN", "PAIR_MISFIT",
           "INFORMATIVE_NOISE_LEVELS"]

#: a hold-out whose growth varies (std) by less than this many noise σ is not informative
INFORMATIVE_NOISE_LEVELS = 3.0
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


@dataclass(frozen=True)
class RodEvidence:
    """What only the rod's engine has, beside the shared
    :class:`~arfem.models.diagnosis.result.Diagnosis`.

    Attributes
    ----------
    document : mapping
        The rod's evidence as contract v2 lays it out (read-only): the residual analyses
        of the baseline and the extended model, every candidate's score and naming test,
        the selection, the AR forms, the MLR, the parsimony and second-cause records and
        the verdict's detail. :func:`arfem.scenarios.diagnosis.document.document` writes
        diagnosis.json from it; nothing changes it after :func:`diagnose` returns.
    notes : tuple of str
        What the speed-only branch calibrated (its speed-to-heat mapping, the paper
        AR(1)), in words, for report.md.
    extended : CandidateFit
        The fitted extended model (the baseline where nothing was named), for export as a
        compensator (:mod:`arfem.models.diagnosis.export`).
    physics : FemPhysics or None
        The FEM rod the fits ran on (``q_W_m2`` records).
    speed : SpeedFrameInputs or None
        What a speed record's thermometer frame fit ran on.
    """

    document: Mapping
    notes: tuple
    extended: CandidateFit
    physics: FemPhysics | None = None
    speed: SpeedFrameInputs | None = None


def _no_effect(names, nominal_h) -> dict:
    """The no-effect value of each of ``names`` that has one (:data:`verdict.NO_EFFECT`,
    the rod's nominal h for ``nominal_h``)."""
    from arfem.models.diagnosis.verdict import NO_EFFECT
    return {k: (nominal_h if NO_EFFECT[k] == "nominal_h" else NO_EFFECT[k])
            for k in names if k in NO_EFFECT}


def typed_result(summary: dict, series: dict, evidence_of, nominal_h) -> Diagnosis:
    """The shared typed result of a rod diagnosis from its contract-v2 ``summary`` (after
    the verdict), the figures' ``series`` and ``evidence_of(frozen document)`` → its
    :class:`RodEvidence`."""
    from arfem.models.diagnosis.verdict import selected_causes
    vdet = summary["verdict_detail"]
    wn = vdet["residual_within_noise"]
    causes = tuple(NamedCause(c["cause"], c["cause"], "", frozen_mapping(c["parameters"]),
                              frozen_mapping({k: tuple(v) for k, v in c["ci95"].items()}),
                              frozen_mapping(_no_effect(c["parameters"], nominal_h)),
                              tuple(c.get("ci95_model_choice", ())))
                   for c in selected_causes(summary))
    eq = summary.get("equivalent_alternative")
    h = summary["holdout"]
    mlr_h = (summary.get("mlr") or {}).get("holdout_rmse_um")
    holdout = Holdout(float(h["start_s"]), h["how_chosen"], int(h["n_samples"]),
                      float(h["gain_pct"]), None,
                      (ChannelHoldout("growth_um", "um", h["baseline_rmse_um"],
                                      h["extended_rmse_um"], mlr_h),))
    channel = ChannelEvidence("growth_um", "um",
                              float(summary["selection"].get("noise_sigma_um", np.nan)),
                              float(wn["ljung_box_p_neff"]),
                              tuple(wn["thermometers_beyond_bound"]))
    plant = "rod_fem" if summary["input_kind"] == "q_W_m2" else "rod_speed"
    return Diagnosis(
        dataset=summary["dataset"], plant=plant, verdict=summary["verdict"],
        text=vdet["text"], causes=causes, subject=vdet["subject"],
        failed=tuple(vdet["failed_checks"]),
        alternatives=(eq["cause"],) if eq and eq.get("excluded_by", "parsimony") is None else (),
        not_searched=tuple(summary["not_applicable"]), holdout=holdout, channels=(channel,),
        warnings=tuple(summary["warnings"]), below_resolution=bool(wn["below_resolution"]),
        beaten_by_regression=bool(vdet["best_candidate_beaten_by_mlr"]),
        series=frozen_mapping(series), evidence=evidence_of(frozen_mapping(summary)))


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


def _holdout_start(t, holdout_start_s, where, u=None):
    """The hold-out start [s] -- as given, or chosen by :func:`arfem.models.diagnosis.holdout.default_holdout` -- and
    how it was chosen.

    Fitting uses the samples with t < start and scoring those with t >= start, so the
    given value is kept as it is (not moved to the next sample time)."""
    if holdout_start_s is None:
        if u is None:
            hs = t[0] + (t[-1] - t[0]) * 2.0 / 3.0
            how = "not given: the last third of the record (from 2/3 of its duration)"
        else:
            hs, how = default_holdout(t, u)
    else:
        hs = float(holdout_start_s)
        how = "given by --holdout-start"
        if not np.isfinite(hs):
            raise InputError(f"must be finite, got {holdout_start_s!r}", "--holdout-start")
    n_before = int(np.sum(t < hs))
    n_after = int(np.sum(t >= hs))
    if n_before < 20 or n_after < 5:
        span = (f"{n_before} samples to fit and {n_after} to score (record {t[0]:g}..{t[-1]:g} s); "
                "need >= 20 to fit and >= 5 to score")
        if holdout_start_s is None:
            raise InputError(f"record too short: its hold-out from {hs:g} s leaves {span}",
                             where)
        raise InputError(f"{hs:g} s leaves {span}", f"--holdout-start (for {where})")
    return hs, how


def _holdout_warning(y, hold, noise_um):
    """A warning if the hold-out's growth varies by less than a few noise levels."""
    yh = np.asarray(y, float)[hold]
    yh = yh[np.isfinite(yh)]
    if yh.size < 2 or not np.isfinite(noise_um) or noise_um <= 0:
        return None
    sd = float(np.std(yh))
    if sd < INFORMATIVE_NOISE_LEVELS * noise_um:
        return (f"hold-out not informative: its growth varies by {sd:.3g} µm (std), less "
                f"than {INFORMATIVE_NOISE_LEVELS:g} noise levels (σ ≈ {noise_um:.3g} µm); "
                "the gain there says little -- choose a --holdout-start before a change of "
                "the input")
    return None


def _refuse_dead_sensor(ds):
    """One clear error for a growth column that never changes (a dead sensor)."""
    y = np.asarray(ds.growth_um, float)
    if y.size and float(np.ptp(y)) == 0.0:
        raise InputError(f"is {y[0]:g} µm on every row: a dead or disconnected sensor? "
                         "There is nothing to diagnose",
                         f"{ds.csv_path or ds.source}: column growth_um")


def observations(ds):
    """Time [s], growth [µm] (NaN where not observed), the observed and outlier masks and
    the inputs (a dict by column, None where not recorded) over every row the record has
    an input for: rows with an empty ``growth_um`` keep their input (dropping it would
    merge its interval into the next one's) -- see ``Dataset.unobserved``. Speed-only
    records use the observed rows only. The rod plant reads the same rows
    (:func:`arfem.models.diagnosis.rod_plant.rod_plant`)."""
    t = np.asarray(ds.time_s, float)
    y = np.asarray(ds.growth_um, float)
    un = getattr(ds, "unobserved", None)
    cols = {"q_W_m2": ds.q_W_m2, "speed_rpm": ds.speed_rpm, "ambient_C": ds.ambient_C,
            **ds.temperatures}
    cols = {k: None if v is None else np.asarray(v, float) for k, v in cols.items()}
    outl = np.asarray(ds.outliers, bool)
    if ds.input_kind != "q_W_m2" or not un or not np.size(un.get("time_s", [])):
        return t, y, np.ones(t.size, bool), outl, cols
    tu = np.asarray(un["time_s"], float)
    order = np.argsort(np.concatenate([t, tu]), kind="stable")
    t2 = np.concatenate([t, tu])[order]
    obs = np.concatenate([np.ones(t.size, bool), np.zeros(tu.size, bool)])[order]
    y2 = np.concatenate([y, np.full(tu.size, np.nan)])[order]
    out2 = np.concatenate([outl, np.zeros(tu.size, bool)])[order]
    if np.any(np.diff(t2) <= 0):         # an unobserved row repeats a time: leave them out
        return t, y, np.ones(t.size, bool), outl, cols
    cols2 = {}
    for k, v in cols.items():
        if v is None:
            cols2[k] = None
            continue
        w = un.get(k)
        w = np.full(tu.size, np.nan) if w is None else np.asarray(w, float)
        v2 = np.concatenate([v, w])[order]
        if k == "ambient_C" and np.isnan(v2).any():      # an ambient is needed on every interval
            ok = np.isfinite(v2)
            v2 = np.interp(t2, t2[ok], v2[ok])
        cols2[k] = v2
    return t2, y2, obs, out2, cols2


def _cause_entries(fit, causes, y, rows, ci=None):
    """``causes`` of diagnosis.json: each cause with its contract parameters and 95 %
    intervals from the (joint) fit (``ci``, if given: intervals computed otherwise)."""
    if ci is None:
        ci = parameter_ci95(fit, y, rows) if fit is not None else {}
    out = []
    for c in causes:
        names = CONTRACT_PARAMETERS[c]
        out.append({"cause": c,
                    "parameters": {k: fit.parameters[k] for k in names if k in fit.parameters},
                    "ci95": {k: ci[k] for k in names if k in ci}})
    return out


class ArForm(NamedTuple):
    """An AR-form realisation of the baseline and of the extended model, each scored on
    the hold-out beside the branch's own (``ar_form`` of diagnosis.json)."""

    baseline: CandidateFit | None
    extended: CandidateFit | None


@dataclass(frozen=True)
class BranchResult:
    """What a branch of the diagnosis (:func:`_diagnose_fem` for ``q_W_m2`` records,
    :func:`_diagnose_speed` for speed-only ones) found: the fits, the cause named and
    how, for :func:`diagnose` to score on the hold-out and write.

    Attributes
    ----------
    fits : dict of str to CandidateFit or None
        Every cause of :data:`CAUSES` fitted alone (None where it does not apply).
    cause : str
        The cause named (``none`` if none is).
    causes : tuple of str
        The causes named, the first one first (empty, one, or a pair).
    runner : str or None
        The best cause not named.
    scores : dict of str to float
        Each candidate's score, lower is better (``score_kind``).
    tests : dict of str to dict
        Each candidate's naming test (p-value, RMSE cut [%], ...), as diagnosis.json
        lists them.
    selection : dict
        What the selection rested on (N, ρ1, N_eff, noise σ [µm], ...), as diagnosis.json
        writes it under ``selection``.
    extended : CandidateFit
        The extended model: the named cause's (or pair's) fit, the baseline if none.
    baseline : CandidateFit
        The baseline (the nominal FEM, or the paper AR(1) calibrated by eq. 17).
    time_constant_s : float
        The baseline's slowest time constant [s] (the phases' cooling window).
    ar_forms : dict of str to ArForm
        The AR-form realisations, by the key diagnosis.json's ``ar_form`` gives them.
    baseline_model, score_kind, rule, ar_label : str
        Labels diagnosis.json writes: the baseline's model, what ``score`` is, the
        selection rule, how the AR form was made.
    refused : dict of str to str
        Causes refused as implausible and why (``q_W_m2`` records).
    equivalent : dict or None
        An alternative with fewer parameters that fits as well (rule 6).
    pairs_tried : tuple of dict
        The second-cause tests (rule 7).
    ci95 : dict or None
        Speed-only records: the named cause's 95 % intervals by the grouped jackknife
        [parameter units]; None where they come from the joint fit (``q_W_m2``).
    unconfirmed : dict or None
        Rule 10: the cause not named because its effect is within the slow noise.
    physics : FemPhysics or None
        The FEM rod the fits ran on (``q_W_m2`` records), for export.
    speed_inputs : SpeedFrameInputs or None
        The inputs of a named thermometer frame fit (speed records), for export.
    """

    fits: dict
    cause: str
    causes: tuple
    runner: str | None
    scores: dict
    tests: dict
    selection: dict
    extended: CandidateFit
    baseline: CandidateFit
    time_constant_s: float
    ar_forms: dict
    baseline_model: str
    score_kind: str
    rule: str
    ar_label: str
    refused: dict = field(default_factory=dict)
    equivalent: dict | None = None
    pairs_tried: tuple = ()
    ci95: dict | None = None
    unconfirmed: dict | None = None
    physics: FemPhysics | None = None
    speed_inputs: SpeedFrameInputs | None = None

    def copy_with(self, **changes) -> BranchResult:
        """A copy with the fields ``changes`` changed (the result itself is frozen)."""
        return type(self)(**{**{f.name: getattr(self, f.name) for f in fields(self)},
                             **changes})


def _diagnose_fem(ds, t, q, y, rows, amb_K, temps, warnings, progress) -> BranchResult:
    """q_W_m2 records: every cause fitted in the FEM, the refusals, the named cause(s)
    (selection rules, parsimony, a second cause) and the AR(1) realisation."""
    rod = ds.rod
    fem = FemPhysics(rod)
    args = (t, q, y, rows, ds.initial_known, amb_K, temps.get("T_frame_C"))
    fits = _fit_single_causes(fem, args, progress)
    # the noise scale of every rule: second differences, floored at the quantisation
    # noise of a quantised growth sensor (resolution/√12), which they under-read
    noise = max(st.noise_sigma(y[rows]), ds.noise_floor_um)
    refused = _refusals(fits, rod, noise, warnings)
    valid = {c: (None if c in refused else f) for c, f in fits.items()}
    cause, runner, scores, tests, neff = _select(
        valid, fits["none"], sum(f is not None for f in valid.values()) - 1, noise)
    cause, equivalent = _parsimony(cause, valid, tests, neff)
    if equivalent is not None:
        runner = equivalent["cause"]
    cause, pair, pairs_tried = _pair_search(cause, fits, fem, args, refused, scores, tests,
                                            neff, noise)
    cause, causes, pair = _second_cause_effect(cause, pair, fits, t, y, rows, warnings)
    ext = fits[cause] if pair is None else pair
    cause, causes, ext, unconfirmed = _effect_rule(cause, causes, ext, fits["none"], tests,
                                                   t, y, rows)
    ar = ArPhysics(rod)
    ar_base = fit_candidate("none", ar, *args)
    ar_ext = ar_base if cause == "none" else fit_rod_causes(tuple(causes), ar, *args)
    return BranchResult(
        fits=fits, cause=cause, causes=tuple(causes), runner=runner, scores=scores,
        tests=tests, selection=neff, extended=ext, baseline=fits["none"],
        time_constant_s=1.0 / fem.slowest_rate(), ar_forms={"ar": ArForm(ar_base, ar_ext)},
        baseline_model="fem", score_kind="bic_on_n_eff", rule=_FEM_RULE,
        ar_label="paper AR(1), coefficients from the [rod] values (eqs. 13-14)",
        refused=refused, equivalent=equivalent, pairs_tried=tuple(pairs_tried),
        unconfirmed=unconfirmed, physics=fem)


def _fit_single_causes(fem, args, progress) -> dict:
    """Every cause of :data:`CAUSES` fitted alone in the FEM (rule 1); the h models nest
    ``convection_mismatch`` and start from its optimum."""
    fits = {}
    for c in CAUSES:
        progress(f"FEM fit: {c}")
        h = fits.get("convection_mismatch")
        start = None if h is None or c not in ("speed_dependent_convection",
                                                "nonlinear_convection") else {
            "log_h_running": h.theta["log_h"], "log_h_stopped": h.theta["log_h"],
            "log_h_ref": h.theta["log_h"], "exponent": 0.0}
        fits[c] = fit_rod_causes(() if c == "none" else (c,), fem, *args, start=start)
    return fits


def _refusals(fits, rod, noise_um, warnings) -> dict:
    """Rule 5: the causes refused as implausible (or all of them where the record's
    magnitude is), and why; a warning where a refused fit would have been named."""
    refused = {c: why for c, f in fits.items()
               if c != "none" and f is not None and (why := _implausible(f))}
    unit_warning = _units_warning(fits, rod)
    if unit_warning:
        warnings.append(unit_warning)
        refused.update({c: "the record's magnitude is implausible (see warnings)"
                        for c, f in fits.items() if c != "none" and f is not None})
    n_tests = sum(f is not None for f in fits.values()) - 1
    if refused and not unit_warning:
        # a refusal is worth a warning where the refused fit would have been named
        would = _select(fits, fits["none"], n_tests, noise_um)[0]
        if would in refused:
            bound = fits[would].at_bound
            warnings.append(f"{would} fits best but is refused as a cause: {refused[would]}; "
                            + ("two causes at once, or one outside the vocabulary?" if bound
                               else "check the units of growth_um and the [rod] values"))
    return refused


def _pair_search(cause, fits, fem, args, refused, scores, tests, neff, noise_um):
    """Rule 7: a second cause beside the named one -- or, where nothing is named though
    the baseline is off by many noise σ, beside the best-scoring one (then named only if
    the pair removes ``MISFIT_CUT`` of the misfit). Returns (cause, the pair's fit or
    None, the pairs tried); ``tests`` records a cause so named."""
    pair, pairs_tried = None, []
    # the lead of a pair: the named cause; or, where nothing is named though the baseline
    # is off by many noise σ (rule 4 not met by any single cause), the best-scoring one
    lead = cause
    misfit = (neff.get("baseline_rmse_over_noise") or 0.0) > MISFIT_FACTOR
    if cause == "none" and misfit:
        lead = next((c for c in sorted(scores, key=scores.get) if c != "none"), "none")
    single_rmse = np.sqrt(fits[lead].rss / max(fits[lead].n, 1)) if lead != "none" else 0.0
    if not (lead != "none" and np.isfinite(noise_um) and single_rmse > PAIR_MISFIT * noise_um):
        return cause, pair, pairs_tried
    # the second-best single cause, and the best that does not change h, lead a
    # search too: a wrong lead (an h model standing in for a heat scale and a
    # drift) would hide the true pair
    ranked = [c for c in sorted(scores, key=scores.get)
              if c not in ("none", lead) and c not in refused]
    leads = [lead] + ranked[:1]
    leads += [c for c in ranked if c not in H_CAUSES and c not in leads][:1]
    for ld in leads:
        pr, tr = _second_cause(ld, fits, fem, args, refused)
        pairs_tried += tr
        if pr is not None and (pair is None or pr.rss < pair.rss):
            pair, lead = pr, ld
    base = fits["none"]
    if cause == "none" and pair is not None:
        cut = 1.0 - np.sqrt(pair.rss / base.rss) if base.rss > 0 else 0.0
        if cut < MISFIT_CUT:
            pair = None
        else:
            cause = lead
            tests.setdefault(lead, {})["named_by"] = "misfit, as one of two causes"
    return cause, pair, pairs_tried


def _second_cause_effect(cause, pair, fits, t, y, rows, warnings):
    """The causes named, the pair's first one first; rule 10 for the second cause of a
    pair: its own increment over the first must stand above the slow noise. Returns
    (cause, causes, pair or None)."""
    causes = [] if cause == "none" else ([cause] if pair is None else list(pair.causes))
    if pair is not None and causes[0] != cause:
        cause = causes[0]
    if pair is not None and fits.get(causes[0]) is not None:
        inc, slow = _effect_and_slow_noise(t, y, rows, pair, fits[causes[0]])
        if inc < EFFECT_FACTOR * slow:
            warnings.append(f"a second cause is listed only if it changes the fit window "
                            f"by at least {EFFECT_FACTOR:g} x the slow part of the noise "
                            f"({slow:.3g} µm) beyond the first; {causes[1]} beside "
                            f"{causes[0]} changes it by {inc:.3g} µm RMS: unconfirmed as a "
                            "second cause (post hoc rule, after the fresh batch 9000)")
            pair, causes, cause = None, [causes[0]], causes[0]
    return cause, causes, pair


def _effect_rule(cause, causes, ext, base, tests, t, y, rows):
    """Rule 10: a named cause whose effect on the fit window is within ``EFFECT_FACTOR``
    times the slow part of the noise is not named. Returns (cause, causes, extended
    fit, the unconfirmed record or None)."""
    if cause == "none":
        return cause, causes, ext, None
    effect, slow = _effect_and_slow_noise(t, y, rows, ext, base)
    if effect >= EFFECT_FACTOR * slow:
        return cause, causes, ext, None
    named = "+".join(causes)
    unconfirmed = {"cause": named, "parameters": ext.parameters,
                   "named_by": tests.get(cause, {}).get("named_by"),
                   "effect_rms_um": effect, "slow_noise_um": slow,
                   "why": (f"a cause is named only if it changes the fit window by at "
                           f"least {EFFECT_FACTOR:g} x the slow part of the noise "
                           f"({slow:.3g} µm, the residual's 30-min means); {named} changes "
                           f"it by {effect:.3g} µm RMS: unconfirmed, so no cause is named")}
    return "none", [], base, unconfirmed


#: what the baseline of a speed_rpm record is, fitted and run (diagnosis.json's
#: ``ar_form_description``): ``model.json`` is the same eq. 17 fit on every row before
#: the hold-out with C2 interpolated between the fitted speeds
#: (:func:`arfem.models.compensator.fit_speed_ar1_model`), so where the hold-out runs at
#: speeds not seen before it, ``arfem compensate`` scores it differently
SPEED_AR_LABEL = ("paper AR(1): C1 and one C2 per speed by eq. 17 (least squares on the "
                  "one-step pairs before the hold-out, outliers left out), run free from "
                  "the first row; a speed not seen before the hold-out gets its C2 by the "
                  "early-rise mapping of eqs. 20-21")


def _diagnose_speed(ds, t, sp, y, rows, amb_K, temps, frame_search, text, warnings,
                    progress, intervals=True, drift_last=False, on_fit=None) -> BranchResult:
    """speed_rpm records: the paper AR(1) calibrated by eq. 17 (the baseline), every
    speed-only cause fitted as an output-error AR(1) (the frame structure chosen by
    forward-chaining validation where there are thermometers), the cause named by
    validation, and its parameters' 95 % intervals by the grouped jackknife
    (:func:`arfem.models.diagnosis.speed_intervals.jackknife_ci95`; not computed, ``{}``,
    with ``intervals=False``); ``drift_last`` and ``on_fit`` as in :func:`diagnose`."""
    rod = ds.rod
    levels, seen, W, map_info = speed_to_heat_map(t, sp, temps, rows)
    rho_c_R = rod.density_kg_m3 * rod.specific_heat_J_kgK * rod.radius_m
    paper_pred, paper_info = paper_ar(t, y, sp, rows, W, seen)
    base_paper = CandidateFit("none", "ar", {}, paper_pred, 0)
    folds = forward_folds(t, sp, rows)
    fold_maps = [speed_to_heat_map(t, sp, temps, tr)[1:3] for tr, _ in folds]
    frame_struct, frame_table = None, {}
    if temps:
        progress(f"frame structure search ({frame_search})")
        frame_struct, frame_table = select_frame_structure(t, y, sp, temps, rows, folds,
                                                           fold_maps, frame_search)

    def fit_c(c, tr, seen_, W_):
        if c == "frame_expansion" and frame_struct is not None:
            f = fit_frame_thermometers(t, y, sp, tr, seen_, W_, temps, frame_struct)
        else:
            f = fit_speed_candidate(c, t, y, sp, tr, seen_, W_, amb_K, rho_c_R)
        if on_fit is not None:
            on_fit(c, tr, f)
        return f

    fits, cvs = _fit_and_validate(fit_c, rows, seen, W, y, folds, fold_maps, progress)
    cause, runner, scores, tests, neff = _select_cv(fits, cvs, folds, t,
                                                    robust=frame_search == "average",
                                                    drift_last=drift_last)
    if frame_struct is not None:
        neff["frame_structure"] = _frame_structure_record(frame_struct, frame_search,
                                                          frame_table)
    ci = {}
    if cause != "none" and intervals:
        progress(f"95 % intervals (block jackknife): {cause}")
        # each refit maps the speeds its rows do not hold as the procedure maps unseen
        # speeds (eqs. 20-21), as the validation folds do
        def refit(tr):
            return fit_c(cause, tr, *speed_to_heat_map(t, sp, temps, tr)[1:3])
        ci = _jackknife_intervals(refit, fits[cause], cause, y, rows, warnings)
    text.append(f"speed-to-heat mapping: {json_text(map_info)}")
    text.append(f"paper AR(1) calibration: {json_text(paper_info)}")
    ext = fits[cause] if cause != "none" else base_paper
    speed_inputs = SpeedFrameInputs(t, sp, rows, seen, W, temps, frame_struct) \
        if cause == "frame_expansion" and frame_struct is not None else None
    return BranchResult(
        fits=fits, cause=cause, causes=() if cause == "none" else (cause,), runner=runner,
        scores=scores, tests=tests, selection=neff, extended=ext, baseline=base_paper,
        time_constant_s=_time_constant_h(fits["none"]) * 3600.0,
        # output-error AR: the reference the candidates are tested against
        ar_forms={"ar_output_error": ArForm(fits["none"], ext)},
        baseline_model="ar", score_kind="validation_rmse_um", rule=_SPEED_RULE,
        ar_label=SPEED_AR_LABEL,
        ci95=ci, speed_inputs=speed_inputs)


def _time_constant_h(fit) -> float:
    """The AR(1) rod's time constant of a speed fit [h] (1 h where it has none)."""
    return 1.0 if fit.time_constant_h is None else fit.time_constant_h


def _fit_and_validate(fit_c, rows, seen, W, y, folds, fold_maps, progress):
    """Every speed-only cause fitted on the fit rows (``fit_c(cause, rows, seen, W)``)
    and its forward-chaining validation RMSE [µm] (:func:`cv_rmse`; each fold refitted
    with its own speed mapping). Returns (fits by cause, None where a cause does not
    apply; validation by cause)."""
    fits, cvs = {}, {}
    for c in SPEED_CAUSES:
        progress(f"AR fit and validation: {c}")
        f = fit_c(c, rows, seen, W)
        fits[c] = f
        if f is None:
            continue
        it = iter(fold_maps)

        def fitter(tr, c=c, it=it):
            g = fit_c(c, tr, *next(it))
            return None if g is None else g.prediction
        cvs[c] = cv_rmse(fitter, y, folds)
    for c in CAUSES:
        fits.setdefault(c, None)
    return fits, cvs


def _frame_structure_record(frame_struct, frame_search, frame_table) -> dict:
    """The chosen thermometer frame structure as diagnosis.json's ``selection`` gives it."""
    return {"components": frame_struct.components,
            "sensor_lag_h": frame_struct.sensor_lag_h,
            "heat_exponent": frame_struct.heat_exponent,
            "slow_response": frame_struct.slow_lag,
            "label": frame_struct.label,
            "search": frame_search,
            "validation_rmse_um": frame_table}


def _jackknife_intervals(refit, fit, cause, y, rows, warnings) -> dict:
    """The named speed cause's 95 % intervals by the grouped jackknife, with a warning for
    each parameter the data before the hold-out do not determine."""
    detail = {}
    ci = jackknife_ci95(refit, fit, y, rows, CONTRACT_PARAMETERS[cause], detail=detail)
    for k, why in detail.get("not_bounded", {}).items():
        warnings.append(f"{cause}: {k} = {fit.parameters[k]:.4g} is not "
                        f"determined by the data before the hold-out ({why}); its "
                        f"95 % interval is the range the fit can return, or none")
    return ci


def _residual_analysis(t, y, pred, mask, signals: dict, running, tau_s):
    r = (y - pred)
    rm = r[mask]
    n = int(mask.sum())
    rho = st.lag1(rm)
    n_eff = st.noise_n_eff(rm)
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
    out["cross_correlation_bound_white"] = st.corr_bound(n)
    out["cross_correlation_bound_neff"] = st.corr_bound(n_eff)
    out["n_eff"] = n_eff
    return out


def _signals(input_kind, cols, temps):
    """The recorded signals the residual is correlated with: the input, the ambient and
    every temperature sensor."""
    signals = {}
    if input_kind == "q_W_m2":
        signals["q_W_m2"] = cols["q_W_m2"]
    else:
        signals["speed_rpm"] = cols["speed_rpm"]
    if cols["ambient_C"] is not None:
        signals["ambient_C"] = cols["ambient_C"]
    signals.update(temps)
    return signals


def _unseen_speeds(r) -> dict:
    """The speeds [1/min] the hold-out runs at that no fit row holds, and on how many of
    its scored rows: where the paper AR(1) baseline (eqs. 20-21) and ``model.json``
    (C2 interpolated) differ."""
    u = np.asarray(r.u, float)
    unseen = sorted(set(np.unique(u[r.hold]).tolist()) - set(np.unique(u[r.rows]).tolist()))
    return {"speeds_not_seen_before_rpm": [float(v) for v in unseen],
            "n_samples_at_speeds_not_seen": int(np.isin(u[r.hold], unseen).sum())}


def _holdout_scores(y, base_pred, ext_pred, hold):
    """Hold-out RMSE of the baseline and the extended model [µm], and the gain [%]."""
    b_hold = st.rmse((y - base_pred)[hold])
    e_hold = st.rmse((y - ext_pred)[hold])
    return b_hold, e_hold, 100.0 * (1.0 - e_hold / b_hold) if b_hold > 0 else 0.0


def _runner_up(input_kind, cause, runner, fits, scores, tests, score_kind):
    """The best cause not named and why it lost -- the rule and its outcome -- or None."""
    if runner is None or fits.get(runner) is None:
        return None
    score, other = scores[runner], scores.get(cause, float("nan"))
    test = tests.get(runner)
    if input_kind == "q_W_m2":
        score_text = f"BIC {score:.1f}, {cause} {other:.1f}"
        least = "the least BIC on N_eff"
    else:
        score_text = f"validation RMSE {score:.3g} µm, {cause} {other:.3g} µm"
        least = "the least validation RMSE"
    if test is not None and not test.get("significant", False):
        why = f"{naming_test_text(test)} ({score_text})"
    elif cause == "none":          # passed its test, set behind by the post hoc drift rule
        why = (f"{runner} is named only if no cause driven by the recorded inputs passes "
               f"the naming test (--drift-last) ({score_text})")
    else:
        why = (f"the one with {least} among the candidates that pass the naming test is "
               f"named ({score_text})")
    return {"cause": runner, "score": scores[runner], "score_kind": score_kind,
            "parameters": fits[runner].parameters, "why_lost": why}


def _ar_form(ar_forms, y, hold):
    """Hold-out scores of the AR-form realisations of the baseline and extended model."""
    ar_out = {}
    for key, d in ar_forms.items():
        bb, ee = d.baseline, d.extended
        if bb is None or ee is None:
            continue
        bh = st.rmse((y - bb.prediction)[hold])
        eh = st.rmse((y - ee.prediction)[hold])
        ar_out[key] = {"baseline_model": bb.model, "extended_model": ee.model,
                       "baseline_holdout_rmse_um": bh, "extended_holdout_rmse_um": eh,
                       "gain_pct": 100.0 * (1.0 - eh / bh) if bh > 0 else 0.0,
                       "parameters": ee.parameters}
    return ar_out


def _add_mlr(summary, series, y, temps, rows, hold):
    """Paper eq. 18 on the recorded temperatures, as a reference on the hold-out."""
    if not temps:
        return
    pm, names = mlr(y, temps, rows)
    if pm is not None:
        summary["mlr"] = {"sensors": names, "holdout_rmse_um": st.rmse((y - pm)[hold]),
                          "note": "growth = β0 + Σ β_i T_i fitted before the hold-out "
                                  "(paper eq. 18)"}
        series["mlr_um"] = pm


def _add_version2(summary, branch: BranchResult, y, rows, hold, good, warnings,
                  noise_floor_um=0.0):
    """The contract's version-2 fields: ``causes`` (with 95 % intervals),
    ``parameters_ci95``, ``warnings``; and the parsimony / second-cause records."""
    ext = branch.extended
    # speed-only records bring their intervals (block jackknife); q_W_m2 ones get them
    # from the joint fit, and also record parsimony and the second-cause tests
    entries = _cause_entries(ext, branch.causes, y, rows, branch.ci95)
    if branch.ci95 is None:
        eq = ext.equivalent if len(entries) > 1 else branch.equivalent
        if eq is not None:
            summary["equivalent_alternative"] = eq
            _widen_for_model_choice(entries, eq)
        summary["second_cause_tests"] = list(branch.pairs_tried)
        summary["refused_candidates"] = [{"cause": c, "refused": why,
                                          "parameters": branch.fits[c].parameters}
                                         for c, why in branch.refused.items()]
    summary["contract_version"] = 2
    summary["causes"] = entries
    summary["parameters_ci95"] = entries[0]["ci95"] if entries else {}
    if len(entries) > 1:
        summary["extended"]["model"] = ext.model
    noise = max(st.noise_sigma(np.asarray(y, float)[good]), noise_floor_um)
    w = _holdout_warning(y, hold, noise)
    if w:
        warnings.append(w)
    warnings += _named_cause_warnings(summary, entries, noise)
    summary["warnings"] = list(warnings)


def _widen_for_model_choice(entries, eq) -> None:
    """Where an alternative explanation fits alike (``equivalent_alternative``), the model
    choice is uncertain: each interval of a parameter that the alternative also
    estimates is widened to hold the alternative's estimate, and ``ci95_model_choice``
    lists the parameters so widened (issue 24: intervals that account for model choice
    where it matters)."""
    alt = eq.get("parameters") or {}
    for e in entries:
        widened = []
        for k, ci in e["ci95"].items():
            v = alt.get(k)
            if ci is None or v is None or not np.isfinite(v):
                continue
            if v < ci[0] or v > ci[1]:
                e["ci95"][k] = [float(min(ci[0], v)), float(max(ci[1], v))]
                widened.append(k)
        if widened:
            e["ci95_model_choice"] = widened


#: parameters whose value 0 means "no effect": a named cause whose interval of one of
#: them holds 0 has not shown the size or sign of its effect
EFFECT_PARAMETERS = ("frame_gain", "drift_um_per_h", "ambient_gain_um_per_K")


def _named_cause_warnings(summary, entries, noise_um) -> list[str]:
    """What a reader of a named cause must not miss: an effect whose 95 % interval holds
    0, a hold-out the extended model makes worse, and an extended model that still
    leaves more than ``MISFIT_FACTOR`` noise σ (something outside the vocabulary, or a
    second cause not established)."""
    out = []
    for e in entries:
        for k, (lo, hi) in e["ci95"].items():
            if k in EFFECT_PARAMETERS and lo <= 0.0 <= hi:
                out.append(f"{e['cause']}: the 95 % interval of {k} ({lo:.3g} to {hi:.3g}) "
                           "holds 0: the data before the hold-out do not establish the size "
                           "or sign of this effect")
    gain = summary["holdout"]["gain_pct"]
    if entries and np.isfinite(gain) and gain < 0:
        out.append(f"the extended model is worse than the baseline on the hold-out (gain "
                   f"{gain:.1f} %): the named cause does not carry past the fit window; "
                   "treat it as unconfirmed")
    rmse = summary["extended"]["rmse_um"]
    if entries and np.isfinite(noise_um) and noise_um > 0 and rmse > MISFIT_FACTOR * noise_um:
        out.append(f"the extended model leaves "
                   f"{rmse / noise_um:.0f} noise σ (RMSE {rmse:.3g} µm, σ ≈ {noise_um:.3g} µm):"
                   " something the cause vocabulary does not hold remains, or a further "
                   "cause was not established")
    return out


def _summary(ds, branch: BranchResult, bres, eres, holdout):
    """diagnosis.json's main fields from the branch's result (:func:`_diagnose_fem` or
    :func:`_diagnose_speed`), the residual analyses and the hold-out scores."""
    fits, cause, scores, tests = branch.fits, branch.cause, branch.scores, branch.tests
    ext, base_model, score_kind = branch.extended, branch.baseline_model, branch.score_kind
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
        "holdout": holdout,
        "parameters": {k: v for k, v in ext.parameters.items()
                       if k in CONTRACT_PARAMETERS[cause]} if cause != "none" else {},
        "parameters_detail": {k: v for k, v in ext.parameters.items()
                              if k not in CONTRACT_PARAMETERS[cause]} if cause != "none" else {},
        # what "score" is (lower is better either way): a BIC for q_W_m2 records, a
        # forward-chaining validation RMSE [µm] for speed-only ones
        "candidates": [{"cause": c, "score": scores[c], "score_kind": score_kind,
                        **(tests[c] if c in tests else {}),
                        "parameters": fits[c].parameters,
                        "fit_rmse_um": float(np.sqrt(fits[c].rss / max(fits[c].n, 1)))}
                       for c in sorted(scores, key=scores.get)],
        "runner_up": None,
        "selection": {"rule": branch.rule, **branch.selection},
        "not_applicable": [c for c in CAUSES if fits.get(c) is None],
        "refused": dict(branch.refused),
        "input_kind": ds.input_kind,
        "data_notes": list(ds.notes),
    }
    summary["runner_up"] = _runner_up(ds.input_kind, cause, branch.runner, fits, scores,
                                      tests, score_kind)
    return summary


def add_verdict(summary: dict, baseline_residual, nominal_h_W_m2K=None,
                resolution_um: float = 0.0) -> None:
    """The verdict (:mod:`arfem.models.diagnosis.verdict`) written into ``summary``:
    ``verdict``, ``verdict_detail`` and, for a cause that is not established,
    ``best_candidate`` in place of ``cause``/``causes``/``parameters``.
    ``resolution_um``: the growth sensor's quantum [µm], 0 where the record is not
    quantised (the verdict's default resolution then)."""
    from arfem.models.diagnosis import verdict as vd
    vd.apply(summary, vd.decide(summary, baseline_residual, nominal_h_W_m2K,
                                resolution_um or vd.DEFAULT_RESOLUTION))


@one_blas_thread
def diagnose(ds, holdout_start_s=None, frame_search: str = "narrow",
             progress=None, intervals: bool = True, drift_last: bool = False,
             on_fit=None) -> Diagnosis:
    """Diagnose a loaded :class:`~arfem.models.diagnosis.dataset.Dataset`.

    Parameters
    ----------
    ds : Dataset
        The record (``q_W_m2`` → FEM baseline; ``speed_rpm`` → calibrated AR(1) baseline).
    holdout_start_s : float, optional
        Start of the hold-out [s]; default the last third of the record.
    frame_search : {"narrow", "wide", "average"}
        Speed-only records: the frame structures compared by forward-chaining
        validation (:func:`arfem.models.diagnosis.speed_frame.frame_structures`).
    progress : callable, optional
        Called with a step's name as each slow step starts (the command shows it).
    intervals : bool
        Speed-only records: compute the named cause's 95 % intervals (B refits, up to
        twice the run's time with ``frame_search="average"``); False leaves ``ci95``
        empty, for callers that need only the predictions (a rolling-origin evaluation).
    drift_last : bool
        Speed-only records (post hoc option): name ``sensor_drift`` only if no
        input-driven cause passes the naming test
        (:func:`arfem.models.diagnosis.speed_select.drift_last`).
    on_fit : callable, optional
        Speed-only records: called as ``on_fit(cause, rows, fit)`` after each candidate
        cause is fitted for naming (``rows``: the boolean fit rows; ``fit``: its
        :class:`~arfem.models.diagnosis.candidates.CandidateFit`, or None where it failed),
        for exploratory scripts that study every candidate, not only the one named.
    """
    step = progress if progress is not None else (lambda name: None)
    _refuse_dead_sensor(ds)
    r = _prepare_record(ds, holdout_start_s)
    text, warnings = [], []
    if ds.input_kind == "q_W_m2":
        branch = _diagnose_fem(ds, r.t, r.u, r.y, r.rows, r.amb_K, r.temps, warnings, step)
    else:
        branch = _diagnose_speed(ds, r.t, r.u, r.y, r.rows, r.amb_K, r.temps, frame_search, text,
                             warnings, step, intervals, drift_last, on_fit)
    step("residuals and hold-out")
    branch, holdout = _score_holdout(branch, r, warnings)
    if ds.input_kind == "speed_rpm":
        holdout.update(_unseen_speeds(r))
    t, y, good, base, ext = r.t, r.y, r.good, branch.baseline, branch.extended
    running = r.u > 0
    bres = _residual_analysis(t, y, base.prediction, good, r.signals, running,
                              branch.time_constant_s)
    eres = _residual_analysis(t, y, ext.prediction, good, r.signals, running,
                              branch.time_constant_s)
    summary = _summary(ds, branch, bres, eres, holdout)
    if branch.unconfirmed is not None:
        summary["unconfirmed"] = branch.unconfirmed
    summary["ar_form"] = _ar_form(branch.ar_forms, y, r.hold)
    summary["ar_form_description"] = branch.ar_label
    _add_version2(summary, branch, y, r.rows, r.hold, good, warnings, ds.noise_floor_um)
    series = {"time_s": t, "growth_um": y, "baseline_um": base.prediction,
              "extended_um": ext.prediction, "outlier": (~good).astype(float)}
    series.update({k: v for k, v in r.signals.items() if k not in series})
    _add_mlr(summary, series, y, r.temps, r.rows, r.hold)
    add_verdict(summary, (y - base.prediction)[good], ds.rod.convection_W_m2K,
                getattr(ds, "growth_resolution_um", 0.0))
    return typed_result(summary, series, lambda doc: RodEvidence(
        doc, tuple(text), ext, branch.physics, branch.speed_inputs), ds.rod.convection_W_m2K)


class _Record(NamedTuple):
    """The record as the diagnosis reads it: every row with an input (rows without a
    growth reading keep theirs, see :func:`observations`) and the hold-out split.

    Attributes: ``t`` sample times [s], ``y`` growth [µm] (NaN where not observed),
    ``good`` observed and not an outlier, ``u`` the input (``q_W_m2`` [W/m²] or
    ``speed_rpm`` [1/min]), ``rows`` / ``hold`` the good rows before / from the
    hold-out start ``start_s`` [s] (``how_chosen`` says how), ``amb_K`` the recorded
    ambient minus the nominal [K] or None, ``temps`` the temperatures [°C] by column,
    ``signals`` the recorded signals the residual is correlated with; arrays of
    shape (N,).
    """

    t: np.ndarray
    y: np.ndarray
    good: np.ndarray
    u: np.ndarray
    rows: np.ndarray
    hold: np.ndarray
    start_s: float
    how_chosen: str
    amb_K: np.ndarray | None
    temps: dict
    signals: dict


def _prepare_record(ds, holdout_start_s) -> _Record:
    """The rows, the input, the hold-out split and the signals of a record."""
    t, y, observed, outl, cols = observations(ds)
    good = observed & ~outl
    u = cols["q_W_m2"] if ds.input_kind == "q_W_m2" else cols["speed_rpm"]
    hs, how = _holdout_start(t, holdout_start_s, str(ds.source), u)
    amb_K = None if cols["ambient_C"] is None else cols["ambient_C"] - ds.rod.ambient_C
    temps = {k: cols[k] for k in ds.temperatures}
    return _Record(t, y, good, u, good & (t < hs), good & (t >= hs), hs, how, amb_K, temps,
                   _signals(ds.input_kind, cols, temps))


def _score_holdout(branch: BranchResult, r: _Record,
                   warnings) -> tuple[BranchResult, dict]:
    """The hold-out scores of the branch's baseline and extended model, and rule 9: a
    cause named by the misfit rule that makes the hold-out worse is not named (the
    branch result is returned without it). Returns (branch result, diagnosis.json's
    ``holdout``)."""
    base = branch.baseline
    b_hold, e_hold, gain = _holdout_scores(r.y, base.prediction, branch.extended.prediction,
                                           r.hold)
    if branch.unconfirmed is not None:        # rule 10 (in the branch)
        warnings.append(branch.unconfirmed["why"])
    elif (unconfirmed := _unconfirmed(branch.cause, branch.causes, branch.tests,
                                      branch.extended.parameters, gain)) is not None:   # rule 9
        ar_forms = dict(branch.ar_forms)
        if "ar" in ar_forms:
            ar_forms["ar"] = ArForm(ar_forms["ar"].baseline, ar_forms["ar"].baseline)
        branch = branch.copy_with(cause="none", causes=(), extended=base, unconfirmed=unconfirmed,
                          ar_forms=ar_forms)
        warnings.append(unconfirmed["why"])
        e_hold, gain = b_hold, 0.0
    return branch, {"start_s": r.start_s, "how_chosen": r.how_chosen, "baseline_rmse_um": b_hold,
                "extended_rmse_um": e_hold, "gain_pct": gain, "n_samples": int(r.hold.sum())}
