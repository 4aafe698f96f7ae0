"""The diagnosis: what the nominal simulation gets wrong on a measured record, which cause
explains it, and how much the model extended by that cause gains on a hold-out.

Data flow: :class:`arfem.models.diagnosis.dataset.Dataset` → :func:`diagnose` → the one
typed :class:`~arfem.models.diagnosis.result.Diagnosis` of every plant (its ``evidence`` a
:class:`RodEvidence`) → ``diagnosis.json`` at the edge
(:func:`arfem.scenarios.diagnosis.document.document`) and the writers of
:mod:`arfem.scenarios.diagnosis.report`.

Selection (documented in every report):

* ``q_W_m2`` records are diagnosed by the **one pipeline** every plant shares
  (:func:`arfem.models.geodiagnosis.engine.diagnose_plant`, its module docstring gives
  the steps: every single cause screened by BIC on N_eff and a nested F test at
  ``ALPHA``/candidates, implausible magnitudes and a random walk in the noise ruled
  out, parsimony for a cause that nests another, a second cause, the alternatives that
  fit as well) on the rod plant (:mod:`arfem.models.diagnosis.rod_plant`: the paper's
  FEM rod, its causes named by the measured-data contract). :func:`_diagnose_fem`
  writes the pipeline's choice in the contract's names and adds rule 5's unit check;
* ``speed_rpm`` records (a machine whose geometry is unknown): every speed-only cause
  is fitted as an output-error AR(1) (:mod:`arfem.models.diagnosis.speed`) and scored
  by forward-chaining validation; the best is named only if it cuts the baseline's
  validation RMSE by at least ``MIN_GAIN`` and wins on a majority of the validation
  blocks (:func:`arfem.models.diagnosis.rules.select_by_validation`); its parameters'
  95 % intervals come from refits without each of several contiguous blocks
  (:func:`arfem.models.diagnosis.speed_intervals.jackknife_ci95`).

On both, rule 5: if the record's own magnitude is implausible against the nominal
model (wrong units: the heat scale that maps the nominal growth onto the record lies
outside ``arfem.params.PLAUSIBLE_RANGES`` and the spreads disagree), no cause is named
and a warning says what to check (:func:`arfem.models.diagnosis.rules.units_warning`).

The verdict (:mod:`arfem.models.diagnosis.verdict`, :func:`add_verdict`): the cause
named is *established* only if its 95 % intervals exclude no effect and stay inside the
fit's range, no alternative fits as well, the hold-out confirms it and the MLR of eq. 18
does not beat it; otherwise it moves to ``best_candidate`` and the verdict is
*unconfirmed* -- or *explained* where the baseline's residual is within the noise,
*not_explained* where nothing was named and it is not.

Without ``--holdout-start`` the hold-out is the last third of the record if it holds a
change of the input, else it starts at the last such change
(:func:`arfem.models.diagnosis.holdout.default_holdout`, the mesh's too);
a hold-out whose growth varies by less than ``INFORMATIVE_NOISE_LEVELS`` noise σ gets a
warning.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, NamedTuple

import numpy as np

from arfem.models.diagnosis import stats as st
from arfem.models.diagnosis.candidates import (CAUSES, ArPhysics, CandidateFit,
                                               FemPhysics, JointFit, fit_candidate,
                                               fit_rod_causes,
                                               parameter_ci95)
from arfem.models.diagnosis.rules import (
    ALPHA, FEM_RULE, MIN_GAIN, MISFIT_FACTOR, SPEED_RULE, naming_test_text,
    select_by_validation, units_warning)
from arfem.models.diagnosis.verdict import naming_level
from arfem.models.diagnosis.speed_intervals import jackknife_ci95
from arfem.models.diagnosis.speed import (SPEED_CAUSES, fit_speed_candidate, mlr, paper_ar,
                                          speed_to_heat_map)
from arfem.models.diagnosis.speed_frame import SpeedFrameInputs, fit_frame_thermometers
from arfem.models.diagnosis.speed_select import cv_rmse, forward_folds, select_frame_structure
from arfem.params import InputError
from arfem.io import json_text
from arfem.models.diagnosis.blas import one_blas_thread
from arfem.models.diagnosis.dataset import observations
from arfem.models.diagnosis.rod_plant import CONTRACT_NAME, contract_entries, rod_plant
from arfem.models.diagnosis.speed_plant import (FRAME_COMPONENTS, contract_names,
                                                speed_candidate_parameters,
                                                speed_contract_entries,
                                                speed_plant_from_dataset)
from arfem.models.geodiagnosis.engine import DELTA_BIC, diagnose_plant, named_causes
from arfem.models.diagnosis.holdout import default_holdout
from arfem.models.diagnosis.result import (ChannelEvidence, ChannelHoldout, Diagnosis, Holdout,
                                           NamedCause, frozen_mapping)

__all__ = ["Diagnosis", "RodEvidence", "typed_result", "diagnose", "ALPHA", "MIN_GAIN",
           "MISFIT_FACTOR", "CONTRACT_PARAMETERS", "SPEED_PLANT_CONTRACT_PARAMETERS",
           "INFORMATIVE_NOISE_LEVELS", "SPEED_ENGINES", "BRANCH_ONLY", "check_speed_engine"]

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
#: :data:`CONTRACT_PARAMETERS` of a speed record on the speed plant
#: (``speed_engine="pipeline"``), whose frame follows a thermometer, not the rod: its gain
#: ``frame_gain_um_per_K`` [µm per K of the thermometer's rise] or, on the leading
#: principal components of many thermometers, ``frame_gain_pc<j>_um`` [µm per unit
#: component]; ``frame_time_constant_h`` [h] where it lags (docs/measured-data.md)
SPEED_PLANT_CONTRACT_PARAMETERS = {
    **CONTRACT_PARAMETERS,
    "frame_expansion": ("frame_time_constant_h", "frame_gain_um_per_K")
    + tuple(f"frame_gain_pc{j}_um" for j in range(1, max(FRAME_COMPONENTS) + 1)),
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
    plant_fit : tuple or None
        A speed record diagnosed on the speed plant (``speed_engine="pipeline"``): (the
        :class:`~arfem.models.diagnosis.speed_plant.SpeedPlant`, the pipeline's named
        :class:`~arfem.models.geodiagnosis.fit.Fit`, its nominal fit where nothing was
        named), for export (:func:`arfem.models.diagnosis.export.speed_plant_state_space`).
    """

    document: Mapping
    notes: tuple
    extended: CandidateFit
    physics: FemPhysics | None = None
    speed: SpeedFrameInputs | None = None
    plant_fit: tuple | None = None


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


def _cause_entries(fit, causes, y, rows, ci=None, table=None):
    """``causes`` of diagnosis.json: each cause with its contract parameters (``table``,
    default :data:`CONTRACT_PARAMETERS`) and 95 % intervals from the (joint) fit (``ci``,
    if given: intervals computed otherwise)."""
    if ci is None:
        ci = parameter_ci95(fit, y, rows) if fit is not None else {}
    out = []
    for c in causes:
        names = (table or CONTRACT_PARAMETERS)[c]
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
        The alternatives that fit as well, which the verdict could not exclude
        (``q_W_m2`` records).
    ci95 : dict or None
        The named causes' 95 % intervals [parameter units]: ``q_W_m2`` records the
        pipeline's, speed-only records by the grouped jackknife; None: from the joint
        fit.
    physics : FemPhysics or None
        The FEM rod the fits ran on (``q_W_m2`` records), for export.
    not_applicable : tuple of str or None
        The contract causes the record cannot tell (None: those without a fit).
    candidate_parameters : dict of str to dict
        Each candidate's fitted parameters where ``fits`` does not hold its fit
        (``q_W_m2`` records: the pipeline's screen).
    contract_names : dict or None
        The pipeline plant's cause names -> the contract's, where the plant is not the
        rod (:func:`_diagnose_speed_plant`); None: the rod's :data:`CONTRACT_NAME`.
    contract_parameters : dict or None
        The contract's parameters by cause where they are not the rod's
        (:data:`SPEED_PLANT_CONTRACT_PARAMETERS`); None: :data:`CONTRACT_PARAMETERS`.
    screen_reasons : dict of str to str or None
        ``q_W_m2`` records: why the pipeline's screen did not name each single cause
        alone (:attr:`arfem.models.geodiagnosis.engine.Ranked.refused`, in the
        contract's names; None: the screen named it).
    pipeline : Diagnosis or None
        ``q_W_m2`` records: the one pipeline's diagnosis, whose verdict the document
        writes (:func:`_pipeline_verdict`); None where rule 5 refused every cause.
    speed_inputs : SpeedFrameInputs or None
        The inputs of a named thermometer frame fit (speed records), for export.
    plant_fit : tuple or None
        (speed plant, its named or nominal Fit) of :func:`_diagnose_speed_plant`, for
        export (:attr:`RodEvidence.plant_fit`).
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
    ci95: dict | None = None
    physics: FemPhysics | None = None
    speed_inputs: SpeedFrameInputs | None = None
    not_applicable: tuple | None = None
    candidate_parameters: dict = field(default_factory=dict)
    pipeline: Diagnosis | None = None
    screen_reasons: dict = field(default_factory=dict)
    contract_names: dict | None = None
    plant_fit: tuple | None = None
    contract_parameters: dict | None = None


def _diagnose_fem(ds, r, warnings, progress) -> BranchResult:
    """q_W_m2 records: the one pipeline names the causes
    (:func:`arfem.models.geodiagnosis.engine.diagnose_plant` on the rod plant,
    :mod:`arfem.models.diagnosis.rod_plant`), and this branch writes its choice as the
    measured-data contract lays it out: the named causes and their 95 % intervals by the
    contract's names (:func:`~arfem.models.diagnosis.rod_plant.contract_entries`), every
    single cause's BIC on N_eff and F test as the candidates, rule 5's unit check, and
    the AR(1) realisation of the named causes (paper eqs. 13-14)."""
    rod = ds.rod
    fem = FemPhysics(rod)
    t, q, y, rows = r.t, r.u, r.y, r.rows
    args = (t, q, y, rows, ds.initial_known, r.amb_K, r.temps.get("T_frame_C"))
    plant = rod_plant(ds, fem.m)
    d = diagnose_plant(plant, holdout_start_s=r.start_s, progress=progress)
    ev = d.evidence
    # the noise scale of the document's warnings: second differences, floored at the
    # quantisation noise of a quantised growth sensor (resolution/√12)
    noise = max(st.noise_sigma(y[rows]), ds.noise_floor_um)
    base = _pipeline_fit("none", "fem", {}, (), ev.baseline, y, rows)
    scores, tests, params, reasons = _screened(ev, rod.convection_W_m2K)
    # strongest first (contract v2): the cause that alone fits the record best, by the
    # screen's BIC on N_eff
    entries = sorted(contract_entries(named_causes(ev.named), rod.convection_W_m2K),
                     key=lambda e: scores.get(e.cause, np.inf))
    # rule 5's unit check: the heat scale that maps the nominal growth onto the record
    heat = fit_rod_causes(("heat_input_scale",), fem, *args)
    unit_warning = units_warning({"heat_input_scale": heat, "none": base}, rod)
    refused = {}
    if unit_warning:
        warnings.append(unit_warning)
        refused = {c: "the record's magnitude is implausible (see warnings)" for c in scores
                   if c != "none"}
        entries = ()
    causes = tuple(e.cause for e in entries)
    ext = base if not entries else _pipeline_fit(
        "+".join(causes), "fem+" + "+".join(causes),
        {k: v for e in entries for k, v in e.parameters.items()}, causes, ev.named, y, rows,
        _export_coordinates(ev.named, rod.convection_W_m2K))
    for c in causes[:1]:
        tests.setdefault(c, {})["named_by"] = "pipeline"
    runner = next((c for c in sorted(scores, key=scores.get)
                   if c not in causes and c != "none"), None)
    n_eff = float(st.noise_n_eff(ext.residual_um))
    alternatives = tuple(d.alternatives)
    equivalent = None if not alternatives or not entries else {
        "cause": " or ".join(_in_contract_names(a) for a in alternatives), "parameters": {},
        "excluded_by": None,
        "why": f"within ±{DELTA_BIC:g} of its BIC on N_eff, and the whitened hold-out does "
               "not tell them apart"}
    ar = ArPhysics(rod)
    ar_base = fit_candidate("none", ar, *args)
    ar_causes = tuple(c for c in causes if c in CAUSES)
    ar_ext = ar_base if not ar_causes else fit_rod_causes(ar_causes, ar, *args)
    return BranchResult(
        fits={"none": base, **({ext.cause: ext} if entries else {}),
              "heat_input_scale": heat},
        cause=causes[0] if causes else "none", causes=causes, runner=runner, scores=scores,
        tests=tests, selection={"n": base.n, "rho1": float(st.lag1(ext.residual_um)),
                                "n_eff": n_eff, "noise_sigma_um": noise,
                                "baseline_rmse_over_noise": (
                                    float(np.sqrt(base.rss / max(base.n, 1))) / noise
                                    if noise > 0 else None),
                                "pipeline_noise_sigma_um": float(ev.sigma.get("growth_um",
                                                                              np.nan))},
        extended=ext, baseline=base, time_constant_s=1.0 / fem.slowest_rate(),
        ar_forms={"ar": ArForm(ar_base, ar_ext)}, baseline_model="fem",
        score_kind="bic_on_n_eff", rule=FEM_RULE,
        ar_label="paper AR(1), coefficients from the [rod] values (eqs. 13-14)",
        refused=refused, equivalent=equivalent, physics=fem,
        ci95={k: list(v) for e in entries for k, v in e.ci95.items()},
        not_applicable=tuple(c for c in CAUSES if c not in scores),
        candidate_parameters=params, pipeline=None if unit_warning else d,
        screen_reasons=reasons)


#: what the baseline of a speed_rpm record is on the one pipeline
#: (:func:`_diagnose_speed_plant`)
SPEED_PLANT_LABEL = ("speed plant: one AR(1) driven by one steady gain per speed seen "
                     "before the hold-out (a speed first met after it by eqs. 20-21; one "
                     "law (n/n_max)^p where no speed is seen), its τ searched in every fit "
                     "(arfem.models.diagnosis.speed_plant); "
                     "beside it, the paper AR(1) of eq. 17 (one C2 per speed, eqs. 20-21 "
                     "for new speeds) is scored and held as a data baseline")


def _diagnose_speed_plant(ds, r, warnings, progress) -> BranchResult:
    """speed_rpm records on the one pipeline (``speed_engine="pipeline"``, not the default:
    it failed its pre-registered comparison on FL_THERMAL, reports/fl_thermal/switch.md):
    :func:`arfem.models.geodiagnosis.engine.diagnose_plant` on the speed plant
    (:func:`arfem.models.diagnosis.speed_plant.speed_plant_from_dataset`), written as
    :func:`_diagnose_fem` writes the rod's: the named causes and their 95 % intervals in
    the contract's names (:func:`~arfem.models.diagnosis.speed_plant.speed_contract_entries`),
    every single cause's BIC on N_eff and F test as the candidates, the pipeline's
    verdict; the paper AR(1) of eq. 17 (the plant's reference model, a data baseline of
    the verdict) is scored as ``ar_form["paper_ar"]``. No rule 5 unit check (no nominal
    magnitude); the plant and its fit kept for export (:attr:`BranchResult.plant_fit`)."""
    rod = ds.rod
    rho_c_R = rod.density_kg_m3 * rod.specific_heat_J_kgK * rod.radius_m
    y, rows = r.y, r.rows
    plant = speed_plant_from_dataset(ds, holdout_start_s=r.start_s)
    names = contract_names(plant)
    d = diagnose_plant(plant, holdout_start_s=r.start_s, progress=progress)
    ev = d.evidence
    noise = max(st.noise_sigma(y[rows]), ds.noise_floor_um)
    base = _pipeline_fit("none", "ar_speed_plant", {}, (), ev.baseline, y, rows)
    (_, ref), = plant.reference_models(rows)
    paper = CandidateFit("none", "ar", {}, ref[plant.channels[0].column], 0)
    tau_of = (lambda fit: float(getattr(fit.setting, "time_constant_h", 1.0)))
    scores, tests, params, reasons = _screened(
        ev, rod.convection_W_m2K, names,
        lambda one, rk: speed_candidate_parameters(one, rk.nominal, rho_c_R))
    named = ev.named
    entries = () if named is None else sorted(
        speed_contract_entries(named, rho_c_R), key=lambda e: scores.get(e.cause, np.inf))
    causes = tuple(e.cause for e in entries)
    ext = base if not entries else _pipeline_fit(
        "+".join(causes), "ar_speed_plant+" + "+".join(causes),
        {k: v for e in entries for k, v in e.parameters.items()}, causes, named, y, rows)
    for c in causes[:1]:
        tests.setdefault(c, {})["named_by"] = "pipeline"
    runner = next((c for c in sorted(scores, key=scores.get)
                   if c not in causes and c != "none"), None)
    alternatives = tuple(d.alternatives)
    equivalent = None if not alternatives or not entries else {
        "cause": " or ".join(_in_contract_names(a, names) for a in alternatives),
        "parameters": {}, "excluded_by": None,
        "why": f"within ±{DELTA_BIC:g} of its BIC on N_eff, and the whitened hold-out does "
               "not tell them apart"}
    return BranchResult(
        fits={"none": base, **({ext.cause: ext} if entries else {})},
        cause=causes[0] if causes else "none", causes=causes, runner=runner, scores=scores,
        tests=tests, selection={"n": base.n, "rho1": float(st.lag1(ext.residual_um)),
                                "n_eff": float(st.noise_n_eff(ext.residual_um)),
                                "noise_sigma_um": noise, "speed_plant_heat": plant.heat.kind,
                                "speed_plant_heat_why": plant.heat.why,
                                "pipeline_noise_sigma_um": float(ev.sigma.get("growth_um",
                                                                              np.nan))},
        extended=ext, baseline=base, time_constant_s=tau_of(ev.baseline) * 3600.0,
        ar_forms={"paper_ar": ArForm(paper, ext)}, baseline_model="ar_speed_plant",
        score_kind="bic_on_n_eff",
        rule=FEM_RULE, ar_label=SPEED_PLANT_LABEL, equivalent=equivalent,
        ci95={k: list(v) for e in entries for k, v in e.ci95.items()},
        not_applicable=tuple(c for c in CAUSES if c not in scores),
        candidate_parameters=params, pipeline=d, screen_reasons=reasons,
        contract_names=names, contract_parameters=SPEED_PLANT_CONTRACT_PARAMETERS,
        plant_fit=(plant, ev.baseline if named is None else named))


def _screened(ev, h0_W_m2K: float, names=None,
              entries_of=None) -> tuple[dict, dict, dict, dict]:
    """The pipeline's screen of every single cause (``ev``: its evidence) in the
    contract's names: ({cause: BIC on N_eff}, the nominal's under ``none``; {cause: its
    naming test}; {cause: its fitted parameters}; {cause: why the screen did not name it
    alone, None where it did}). A cause the contract writes once though the plant has
    two (a plain and a running-only h) keeps the better-ranked. ``names`` (plant cause
    name -> contract name, default the rod's :data:`CONTRACT_NAME`) and ``entries_of``
    (one :class:`NamedCause` and its :class:`~arfem.models.geodiagnosis.engine.Ranked`
    -> its contract parameters, default the rod's) serve
    another plant (:func:`_diagnose_speed_plant`)."""
    names = CONTRACT_NAME if names is None else names
    entries_of = entries_of or (
        lambda one, rk: dict(contract_entries((one,), h0_W_m2K)[0].parameters))
    level = naming_level(max(len(ev.ranking), 1))
    scores, tests, params, reasons = {}, {}, {}, {}
    for rk in ev.ranking:
        c = names.get(rk.cause, rk.cause)
        if c in scores:
            continue
        scores[c] = float(rk.bic)
        tests[c] = {"p_value": float(rk.f_test_p), "p_threshold": level,
                    "significant": bool(rk.f_test_p < level), "plant_cause": rk.cause}
        one = NamedCause(rk.cause.split(":")[0], rk.cause, "", rk.parameters, {}, {})
        params[c] = entries_of(one, rk)
        reasons[c] = None if rk.refused is None else _in_contract_names(rk.refused, names)
    scores["none"] = float(ev.baseline_bic)
    return scores, tests, params, reasons


def _pipeline_fit(cause, model, parameters, causes, fit, y, rows, coordinates=None):
    """The pipeline's :class:`~arfem.models.geodiagnosis.fit.Fit` of the growth channel as
    the document's :class:`CandidateFit` (the residual, RSS and rows on the fit window;
    ``coordinates``: the (θ, linear) :class:`JointFit` the export reads)."""
    pred = np.asarray(fit.prediction, float)[:, 0]
    res = (y - pred)[rows]
    return CandidateFit(cause=cause, model=model, parameters=dict(parameters),
                        prediction=pred, k=int(fit.n_params), rss=float(np.sum(res * res)),
                        n=int(rows.sum()), causes=tuple(causes), residual_um=res,
                        fit_rows=rows,
                        joint=None if coordinates is None else JointFit(*coordinates))


def _export_coordinates(fit, h0) -> tuple:
    """(θ, linear) of the pipeline's named rod fit as
    :func:`arfem.models.diagnosis.export.fem_state_space` reads them: ln h [W/(m²K)],
    ln τ_frame [h]; the heat scale, the ambient gain [µm/K] and the frame's raw gain
    on the nominal rod's steady growth."""
    theta, lin = {}, {}
    for c, p in zip(fit.causes, fit.params):
        if c.name == "convection_scale:lateral_surface":
            theta["log_h"] = float(np.log(p["h_scale"] * h0))
        elif c.kind == "frame_lag":
            theta["log_tau_h"] = float(np.log(p["frame_time_constant_h"]))
            lin["frame_gain"] = float(p["frame_gain"])
        elif c.kind == "source_scale":
            lin["scale"] = float(p["scale"])
        elif c.kind == "ambient_drift":
            lin["ambient_gain_um_per_K"] = float(p["ambient_gain_um_per_K"])
        elif c.kind == "sensor_drift":
            lin["drift_um_per_h"] = float(p["drift_um_per_h"])
    return theta, lin


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
    cause, runner, scores, tests, neff = select_by_validation(
        fits, cvs, folds, t, robust=frame_search == "average", drift_last=drift_last)
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
        baseline_model="ar", score_kind="validation_rmse_um", rule=SPEED_RULE,
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


def _runner_up(input_kind, cause, runner, fits, scores, tests, score_kind,
               candidate_parameters=None, branch: BranchResult | None = None):
    """The best cause not named and why it lost -- the rule and its outcome -- or None.
    ``q_W_m2`` records give the one pipeline's reason (``branch``:
    :func:`_pipeline_lost`); speed-only records the speed branch's rules."""
    if runner is None or runner not in scores:
        return None
    candidate_parameters = candidate_parameters or {}
    score, other = scores[runner], scores.get(cause, float("nan"))
    test = tests.get(runner)
    if score_kind == "bic_on_n_eff":
        why = f"{_pipeline_lost(runner, branch)} (BIC {score:.1f}, {cause} {other:.1f})"
    elif test is not None and not test.get("significant", False):
        why = (f"{naming_test_text(test)} (validation RMSE {score:.3g} µm, {cause} "
               f"{other:.3g} µm)")
    elif cause == "none":          # passed its test, set behind by the post hoc drift rule
        why = (f"{runner} is named only if no cause driven by the recorded inputs passes "
               f"the naming test (--drift-last) (validation RMSE {score:.3g} µm, {cause} "
               f"{other:.3g} µm)")
    else:
        why = (f"the one with the least validation RMSE among the candidates that pass the "
               f"naming test is named (validation RMSE {score:.3g} µm, {cause} "
               f"{other:.3g} µm)")
    return {"cause": runner, "score": scores[runner], "score_kind": score_kind,
            "parameters": (fits[runner].parameters if fits.get(runner) is not None
                           else candidate_parameters.get(runner, {})),
            "why_lost": why}


def _pipeline_lost(runner: str, branch: BranchResult | None) -> str:
    """Why the one pipeline did not name ``runner`` on a ``q_W_m2`` record: rule 5's unit
    check where it refused every cause, else the reason its screen of single causes
    recorded (:attr:`arfem.models.geodiagnosis.engine.Ranked.refused`); a cause the
    screen named alone lost in the pair search (step 4) that followed."""
    if branch is not None and runner in branch.refused:
        return branch.refused[runner]
    reason = None if branch is None else branch.screen_reasons.get(runner)
    if reason is not None:
        return f"fitted alone, {reason}"
    named = " and ".join(branch.causes) if branch is not None and branch.causes else "none"
    return (f"alone it is the screen's choice, but the pair search (step 4 of the "
            f"pipeline: a second cause beside it, each cause re-screened beside the other "
            f"and tested against it alone) ended with {named}")


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
    entries = _cause_entries(ext, branch.causes, y, rows, branch.ci95,
                             branch.contract_parameters)
    if branch.physics is not None or branch.score_kind == "bic_on_n_eff":
        eq = branch.equivalent
        if eq is not None:
            summary["equivalent_alternative"] = eq
            _widen_for_model_choice(entries, eq)
        summary["refused_candidates"] = [
            {"cause": c, "refused": why,
             "parameters": branch.fits[c].parameters if branch.fits.get(c) else {}}
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
    table = branch.contract_parameters or CONTRACT_PARAMETERS
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
                       if k in table[cause]} if cause != "none" else {},
        "parameters_detail": {k: v for k, v in ext.parameters.items()
                              if k not in table[cause]} if cause != "none" else {},
        # what "score" is (lower is better either way): a BIC for q_W_m2 records, a
        # forward-chaining validation RMSE [µm] for speed-only ones
        "candidates": [{"cause": c, "score": scores[c], "score_kind": score_kind,
                        **(tests[c] if c in tests else {}),
                        # the one pipeline's screen (q_W_m2 records): why not named alone
                        **({"not_named_alone_because": branch.screen_reasons[c]}
                           if c in branch.screen_reasons else {}),
                        **({"parameters": fits[c].parameters,
                            "fit_rmse_um": float(np.sqrt(fits[c].rss / max(fits[c].n, 1)))}
                           if fits.get(c) is not None and c not in branch.candidate_parameters
                           else {"parameters": branch.candidate_parameters.get(c, {})})}
                       for c in sorted(scores, key=scores.get)],
        "runner_up": None,
        "selection": {"rule": branch.rule, **branch.selection},
        "not_applicable": (list(branch.not_applicable) if branch.not_applicable is not None
                           else [c for c in CAUSES if fits.get(c) is None]),
        "refused": dict(branch.refused),
        "input_kind": ds.input_kind,
        "data_notes": list(ds.notes),
    }
    summary["runner_up"] = _runner_up(ds.input_kind, cause, branch.runner, fits, scores,
                                      tests, score_kind, branch.candidate_parameters, branch)
    return summary


def _in_contract_names(text: str, names=None) -> str:
    """``text`` with the plant's cause names (``names``: plant -> contract, default the
    rod plant's :data:`CONTRACT_NAME`) written as the contract's."""
    names = CONTRACT_NAME if names is None else names
    for plant, contract in sorted(names.items(), key=lambda kv: -len(kv[0])):
        text = contract.join(text.split(plant))
    return "+".join(text.split(" + "))


def _pipeline_verdict(summary: dict, d: Diagnosis, resolution_um: float = 0.0,
                      names=None) -> None:
    """The one pipeline's verdict on a ``q_W_m2`` record (its rules:
    :mod:`arfem.models.diagnosis.verdict`, the evidence of every plant: the residual
    whitened by the channel's fitted noise, the whitened hold-out) written into
    ``summary`` by :func:`arfem.models.diagnosis.verdict.apply`, in the contract's cause
    names; ``resolution_um`` the growth sensor's quantum [µm] (0: not quantised)."""
    from arfem.models.diagnosis import verdict as vd
    ch, ev = d.channels[0], d.evidence
    p = float(ch.whiteness_p)
    white = vd.channels_white([p])
    within = {"ljung_box_p_neff": p, "n_eff": float(ev.within_n_eff.get(ch.column, 0.0)),
              "white": white, "thermometers_beyond_bound": list(ch.thermometers_beyond),
              "better_baselines": (vd.better_baselines(summary) if ev.data_baseline_better
                                   else {}),
              "below_resolution": bool(d.below_resolution),
              "resolution": float(resolution_um or vd.DEFAULT_RESOLUTION), "whitened": True,
              "holds": bool(d.below_resolution or (white and not ch.thermometers_beyond
                                                  and not ev.data_baseline_better))}
    subject = None if d.subject is None else _in_contract_names(d.subject, names)
    if subject is None and d.verdict == "not_explained" and summary.get("runner_up"):
        subject = summary["runner_up"]["cause"]
    verdict, failed = d.verdict, tuple(_in_contract_names(f, names) for f in d.failed)
    # the contract's own rule for speed_dependent_convection (the two h's intervals do
    # not overlap), beside the pipeline's check of its plant parameter (h_scale excludes 1)
    two_h = [f for e in summary.get("causes") or ()
             if e["cause"] == "speed_dependent_convection" for f in vd.two_h_failures(e)]
    if verdict == "established" and two_h:
        verdict, failed = "unconfirmed", failed + tuple(two_h)
    vd.apply(summary, vd.Verdict(verdict, subject, failed, within))
    vdet = summary["verdict_detail"]
    vdet["best_candidate_beaten_by_mlr"] = bool(d.beaten_by_regression)
    vdet["text"] = vd.text(summary)


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


#: The engines a ``speed_rpm`` record can be diagnosed on (:func:`diagnose`'s
#: ``speed_engine``): the rod engine's speed branch (published) and the one pipeline.
SPEED_ENGINES = ("branch", "pipeline")

#: The speed branch's options, each with why it does not apply to the pipeline (one
#: wording, for :func:`diagnose`'s ValueError and for ``arfem diagnose``'s error line).
BRANCH_ONLY = {
    "frame_search": "the pipeline offers frames per thermometer (on 3 principal "
                    "components above 3 thermometers), not a search over frame structures",
    "intervals": "the pipeline always computes its intervals",
    "drift_last": "the pipeline has no drift-last rule (it names sensor_drift by the "
                  "same screen as every cause)",
    "on_fit": "the pipeline screens the candidates together and makes no per-candidate "
              "naming fit to report"}


def check_speed_engine(speed_engine) -> None:
    """The one range check of an engine's name: unless ``speed_engine`` is one of
    :data:`SPEED_ENGINES`, an :class:`arfem.params.InputError` (a ValueError) located at
    ``speed_engine``. A door that names the option otherwise relocates it
    (``arfem diagnose``: ``--speed-engine``,
    :func:`arfem.scenarios.diagnosis.run.speed_options`).

    >>> check_speed_engine("fast")
    Traceback (most recent call last):
    ...
    arfem.params.InputError: speed_engine: 'fast' is not 'branch' or 'pipeline'
    """
    if speed_engine not in SPEED_ENGINES:
        raise InputError(f"{speed_engine!r} is not {' or '.join(map(repr, SPEED_ENGINES))}",
                         "speed_engine")


def _check_speed_engine(speed_engine, frame_search, intervals, drift_last, on_fit) -> None:
    """ValueError for an unknown ``speed_engine`` (:func:`check_speed_engine`), or a
    speed-branch option (:data:`BRANCH_ONLY`) given with the pipeline."""
    check_speed_engine(speed_engine)
    given = {"frame_search": frame_search != "narrow", "intervals": not intervals,
             "drift_last": bool(drift_last), "on_fit": on_fit is not None}
    for key, on in given.items():
        if on and speed_engine == "pipeline":
            raise ValueError(f"{key}: applies to speed_engine='branch' only; "
                             f"{BRANCH_ONLY[key]}")


@one_blas_thread
def diagnose(ds, holdout_start_s=None, frame_search: str = "narrow",
             progress=None, intervals: bool = True, drift_last: bool = False,
             on_fit=None, speed_engine: str = "branch") -> Diagnosis:
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
    speed_engine : {"branch", "pipeline"}
        Speed-only records (written as ``selection["speed_engine"]``): the rod engine's
        speed branch (:func:`_diagnose_speed`, the default, the published procedure) or
        the one pipeline on the speed plant (:func:`_diagnose_speed_plant`, a prototype);
        ``frame_search``, ``intervals``, ``drift_last`` and ``on_fit`` are the branch's:
        given with ``"pipeline"`` they raise ValueError (:data:`BRANCH_ONLY`).
    """
    _check_speed_engine(speed_engine, frame_search, intervals, drift_last, on_fit)
    step = progress if progress is not None else (lambda name: None)
    _refuse_dead_sensor(ds)
    r = _prepare_record(ds, holdout_start_s)
    text, warnings = [], []
    if ds.input_kind == "q_W_m2":
        branch = _diagnose_fem(ds, r, warnings, step)
    elif speed_engine == "pipeline":
        branch = _diagnose_speed_plant(ds, r, warnings, step)
    else:
        branch = _diagnose_speed(ds, r.t, r.u, r.y, r.rows, r.amb_K, r.temps, frame_search, text,
                             warnings, step, intervals, drift_last, on_fit)
    step("residuals and hold-out")
    holdout = _score_holdout(branch, r)
    if ds.input_kind == "speed_rpm":
        holdout.update(_unseen_speeds(r))
    t, y, good, base, ext = r.t, r.y, r.good, branch.baseline, branch.extended
    running = r.u > 0
    bres = _residual_analysis(t, y, base.prediction, good, r.signals, running,
                              branch.time_constant_s)
    eres = _residual_analysis(t, y, ext.prediction, good, r.signals, running,
                              branch.time_constant_s)
    summary = _summary(ds, branch, bres, eres, holdout)
    if ds.input_kind == "speed_rpm":         # which engine ran: a reader must know
        summary["selection"]["speed_engine"] = speed_engine
    summary["ar_form"] = _ar_form(branch.ar_forms, y, r.hold)
    summary["ar_form_description"] = branch.ar_label
    _add_version2(summary, branch, y, r.rows, r.hold, good, warnings, ds.noise_floor_um)
    series = {"time_s": t, "growth_um": y, "baseline_um": base.prediction,
              "extended_um": ext.prediction, "outlier": (~good).astype(float)}
    if "paper_ar" in branch.ar_forms:           # the speed plant's reference model
        series["paper_ar_um"] = branch.ar_forms["paper_ar"].baseline.prediction
    series.update({k: v for k, v in r.signals.items() if k not in series})
    _add_mlr(summary, series, y, r.temps, r.rows, r.hold)
    if branch.pipeline is not None:
        _pipeline_verdict(summary, branch.pipeline,
                          getattr(ds, "growth_resolution_um", 0.0), branch.contract_names)
    else:
        add_verdict(summary, (y - base.prediction)[good], ds.rod.convection_W_m2K,
                    getattr(ds, "growth_resolution_um", 0.0))
    return typed_result(summary, series, lambda doc: RodEvidence(
        doc, tuple(text), ext, branch.physics, branch.speed_inputs, branch.plant_fit),
        ds.rod.convection_W_m2K)


class _Record(NamedTuple):
    """The record as the diagnosis reads it: every row with an input (rows without a
    growth reading keep theirs, see :func:`arfem.models.diagnosis.dataset.observations`) and the hold-out split.

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


def _score_holdout(branch: BranchResult, r: _Record) -> dict:
    """diagnosis.json's ``holdout``: the hold-out scores of the branch's baseline and
    extended model [µm] and the gain [%]."""
    b_hold, e_hold, gain = _holdout_scores(r.y, branch.baseline.prediction,
                                           branch.extended.prediction, r.hold)
    return {"start_s": r.start_s, "how_chosen": r.how_chosen, "baseline_rmse_um": b_hold,
            "extended_rmse_um": e_hold, "gain_pct": gain, "n_samples": int(r.hold.sum())}
