"""The verdict of a diagnosis: four outcomes chosen by stated rules, so that what
``diagnosis.json``, the terminal line and ``report.md`` say never claims more than the
data show (issue 30).

The rules, in the order they are applied (:func:`decide`):

1. **established** -- a cause (or pair) is named by the selection rules
   (:mod:`arfem.models.diagnosis.rules`) *and* for each named cause

   a. the 95 % interval of its effect parameter excludes "no effect" (:data:`NO_EFFECT`:
      ``frame_gain`` 0, ``drift_um_per_h`` 0, ``ambient_gain_um_per_K`` 0, ``scale`` 1,
      ``h_W_m2K`` the ``[rod]``'s nominal h, ``exponent`` 0; for
      ``speed_dependent_convection`` the intervals of ``h_running_W_m2K`` and
      ``h_stopped_W_m2K`` do not overlap), and an interval was computed at all;
   b. no interval of its parameters reaches an end of the range the fit can return
      (``frame_time_constant_h`` 0.1-200 h, :data:`arfem.models.diagnosis.speed_intervals.SEARCH_RANGES`);

   and c. the extended model beats the baseline on the hold-out (``gain_pct`` > 0).
2. **explained** -- otherwise, if the residual of the simulation as configured (the
   baseline) is within the noise: white by Ljung-Box on the effective sample size
   (:func:`ljung_box_p_neff`, p >= :data:`WHITE_P`), no thermometer (``T_*``,
   ``ambient_C``) correlated with it beyond the 95 % bound on N_eff, and no baseline
   model -- the MLR of paper eq. 18, the paper AR(1) (:data:`BETTER_CUT`) -- better on
   the hold-out.
3. **unconfirmed** -- otherwise, if the selection rules named a cause (the *best
   candidate*) that fails 1a-1c or was withdrawn by rule 9 or 10: the failed checks are
   listed.
4. **not_explained** -- otherwise: what is left, how big, the best-scoring candidate and
   why it was not named, and that the vocabulary of causes may lack the cause.

Only an established cause keeps the machine-readable ``cause``/``causes``/``parameters``;
an unconfirmed one moves to ``best_candidate`` (:func:`apply`). Advice ("what to do") is
given only for an established cause (:func:`text`).

Pure: dicts and arrays in, a :class:`Verdict` and text out.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arfem.models.diagnosis import stats as st
from arfem.models.diagnosis.speed_intervals import EDGE_TOL, SEARCH_RANGES

__all__ = ["VERDICTS", "Verdict", "decide", "apply", "text", "ljung_box_p_neff",
           "NO_EFFECT", "WHITE_P", "BETTER_CUT", "ACTIONS", "named_cause"]

#: the four outcomes, as written to ``diagnosis.json``'s ``verdict``
VERDICTS = ("explained", "established", "unconfirmed", "not_explained")

#: Ljung-Box p-value at or above which a residual counts as white
WHITE_P = 0.05

#: a baseline model (MLR, paper AR(1)) is "better on the hold-out" if its RMSE is below
#: the simulation's by at least this fraction (the selection rules' MIN_GAIN): a smaller
#: difference is within what one hold-out can tell
BETTER_CUT = 0.05

#: the value of each effect parameter that means "no effect"; ``"nominal_h"`` is the
#: record's ``[rod]`` convection_W_m2K
NO_EFFECT = {"frame_gain": 0.0, "drift_um_per_h": 0.0, "ambient_gain_um_per_K": 0.0,
             "scale": 1.0, "h_W_m2K": "nominal_h", "exponent": 0.0}

#: what an engineer can do about each established cause (the verdict's last sentence)
ACTIONS = {
    "ambient_drift": "give the model the ambient air temperature as an input (a recorded "
                     "`ambient_C`); the seed paper names a varying ambient as its AR(1)'s "
                     "open limit",
    "convection_mismatch": "set the simulation's lateral h to the fitted value",
    "speed_dependent_convection": "use one h while the spindle runs and another while it "
                                  "stands",
    "heat_input_scale": "rescale the heat input (the speed-to-heat map of eqs. 20-21)",
    "frame_expansion": "add the machine frame's slow expansion (a first-order term driven "
                       "by the same input) to the compensation model",
    "sensor_drift": "check the displacement sensor's zero before changing the thermal model",
    "nonlinear_convection": "use a natural-convection h(ΔT) instead of a constant h",
}


@dataclass(frozen=True)
class Verdict:
    """The outcome of :func:`decide`.

    Attributes
    ----------
    verdict : str
        One of :data:`VERDICTS`.
    subject : str or None
        The established cause, or the best candidate ("a+b" for a pair); None where
        there is none.
    failed : tuple of str
        Unconfirmed: the establishment checks the best candidate failed, in words.
    within_noise : dict
        The three checks of "explained" on the baseline residual: ``ljung_box_p_neff``,
        ``n_eff``, ``thermometers_beyond_bound`` (names), ``better_baselines``
        ({model: hold-out RMSE [µm]}), ``white``, ``holds``.
    """

    verdict: str
    subject: str | None
    failed: tuple = ()
    within_noise: dict = field(default_factory=dict)


def ljung_box_p_neff(r, lags: int = 20) -> float:
    """Ljung-Box p-value of a residual on its effective sample size [-]: the residual
    is sampled every ⌈N/N_eff⌉ rows (N_eff of :func:`arfem.models.diagnosis.stats.noise_n_eff`)
    and the test (paper eq. 19) run on those N_eff samples, with ``lags`` lags (at most
    a fifth of them). A slow wander that N_eff already accounts for is then not taken
    for structure; a misfit that persists across independent samples still is.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> ljung_box_p_neff(rng.normal(size=2000)) > 0.05
    True
    >>> ljung_box_p_neff(np.sin(np.arange(4000) / 300) + 0.01 * rng.normal(size=4000)) < 0.05
    True
    """
    r = np.asarray(r, float)
    r = r[np.isfinite(r)]
    if r.size < 10:
        return float("nan")
    n_eff = max(st.noise_n_eff(r), 1.0)
    stride = max(int(np.ceil(r.size / n_eff)), 1)
    thin = r[::stride]
    if thin.size < 10:            # too few independent samples to test anything
        return float("nan")
    return st.ljung_box_p(thin, lags)


def _thermometers_beyond(summary) -> list[str]:
    b = summary["baseline"]
    bound = b.get("cross_correlation_bound_neff")
    if bound is None:
        return []
    return [k for k, v in b.get("cross_correlation", {}).items()
            if (k.startswith("T_") or k == "ambient_C") and v is not None and abs(v) > bound]


def _better_baselines(summary) -> dict:
    """Baseline models better than the simulation as configured on the hold-out by at
    least BETTER_CUT: ``{label: hold-out RMSE [µm]}``."""
    ref = summary["holdout"]["baseline_rmse_um"]
    models = {}
    if summary.get("mlr"):
        models["MLR of eq. 18"] = summary["mlr"]["holdout_rmse_um"]
    for key, a in (summary.get("ar_form") or {}).items():
        if a.get("baseline_model") != summary["baseline"]["model"]:
            models[f"{a['baseline_model']} ({key})"] = a["baseline_holdout_rmse_um"]
        elif key == "ar_output_error":
            models["AR(1) output-error"] = a["baseline_holdout_rmse_um"]
    return {k: float(v) for k, v in models.items()
            if v is not None and np.isfinite(v) and np.isfinite(ref)
            and v < (1.0 - BETTER_CUT) * ref}


def within_noise(summary, baseline_residual) -> dict:
    """The three checks of "explained" on the baseline residual (every scored row)."""
    r = np.asarray(baseline_residual, float)
    r = r[np.isfinite(r)]
    p = ljung_box_p_neff(r)
    beyond = _thermometers_beyond(summary)
    better = _better_baselines(summary)
    white = bool(np.isfinite(p) and p >= WHITE_P)
    return {"ljung_box_p_neff": p, "n_eff": float(st.noise_n_eff(r)) if r.size else 0.0,
            "white": white, "thermometers_beyond_bound": beyond,
            "better_baselines": better, "holds": bool(white and not beyond and not better)}


def _edge(name, ci) -> bool:
    lo, hi = SEARCH_RANGES.get(name, (None, None))
    return any(e is not None and abs(v - e) <= EDGE_TOL * e for e, v in ((lo, ci[0]), (hi, ci[1])))


def _range(name) -> str:
    """`` (0.1 to 200)``: the range the fit can return for ``name``, where it is known."""
    lo, hi = SEARCH_RANGES.get(name, (None, None))
    return f" ({lo:g} to {hi:g})" if lo is not None and hi is not None else ""


def establishment_failures(entries, gain_pct, nominal_h=None) -> list[str]:
    """Why the named causes ``entries`` (diagnosis.json's ``causes``) are not established,
    in words; empty if they are (rules 1a-1c of the module docstring).

    Examples
    --------
    >>> e = [{"cause": "sensor_drift", "parameters": {"drift_um_per_h": 0.5},
    ...       "ci95": {"drift_um_per_h": [0.4, 0.6]}}]
    >>> establishment_failures(e, 30.0)
    []
    >>> establishment_failures(e, -3.0)
    ['established only if the hold-out confirms it (the extended model beats the baseline there: gain > 0); its gain is -3.0 %']
    """
    out = []
    for e in entries:
        c, ci = e["cause"], e.get("ci95") or {}
        if c == "speed_dependent_convection":
            a, b = ci.get("h_running_W_m2K"), ci.get("h_stopped_W_m2K")
            if a is None or b is None:
                out.append(f"{c}: established only with 95 % intervals of its h values; "
                           "none was computed")
            elif a[0] <= b[1] and b[0] <= a[1]:
                out.append(f"{c}: established only if the 95 % intervals of h_running_W_m2K "
                           "and h_stopped_W_m2K do not overlap (else one h for both is not "
                           f"excluded); they are {a[0]:.3g} to {a[1]:.3g} and {b[0]:.3g} to "
                           f"{b[1]:.3g}")
        else:
            keys = [k for k in e.get("parameters", {}) if k in NO_EFFECT]
            if not keys:
                out.append(f"{c}: established only with an effect parameter to test; it "
                           "has none")
            for k in keys:
                zero = NO_EFFECT[k]
                if zero == "nominal_h":
                    zero = nominal_h
                iv = ci.get(k)
                if iv is None:
                    out.append(f"{c}: established only with a 95 % interval of {k}; none "
                               "was computed")
                elif zero is not None and iv[0] <= zero <= iv[1]:
                    out.append(f"{c}: established only if the 95 % interval of {k} excludes "
                               f"{zero:g} (no effect); it is {iv[0]:.3g} to {iv[1]:.3g}")
        for k, iv in ci.items():
            if iv is not None and _edge(k, iv):
                out.append(f"{c}: established only if the 95 % interval of {k} stays off "
                           f"the ends of the range the fit can return{_range(k)}; it is "
                           f"{iv[0]:.3g} to {iv[1]:.3g}")
    if not (gain_pct is not None and np.isfinite(gain_pct) and gain_pct > 0):
        out.append(f"established only if the hold-out confirms it (the extended model beats "
                   f"the baseline there: gain > 0); its gain is {gain_pct:.1f} %")
    return out


def decide(summary, baseline_residual, nominal_h=None) -> Verdict:
    """The verdict of a diagnosis (rules 1-4 of the module docstring).

    Parameters
    ----------
    summary : dict
        ``diagnosis.json`` as the engine builds it, before :func:`apply`: ``cause``,
        ``causes`` (with ``ci95``), ``holdout``, ``baseline``, ``mlr``, ``ar_form``,
        ``unconfirmed``, ``runner_up``.
    baseline_residual : array_like
        measured − baseline [µm] on every scored (observed, not outlier) row.
    nominal_h : float, optional
        The ``[rod]``'s convection_W_m2K [W/(m²K)]: "no effect" for ``h_W_m2K``.
    """
    noise = within_noise(summary, baseline_residual)
    entries = summary.get("causes") or []
    if summary.get("cause", "none") != "none" and entries:
        subject = "+".join(e["cause"] for e in entries)
        failed = establishment_failures(entries, summary["holdout"]["gain_pct"], nominal_h)
        if not failed:
            return Verdict("established", subject, (), noise)
        if noise["holds"]:
            return Verdict("explained", subject, tuple(failed), noise)
        return Verdict("unconfirmed", subject, tuple(failed), noise)
    u = summary.get("unconfirmed")
    subject = u["cause"] if u else None
    failed = (u["why"],) if u else ()
    if noise["holds"]:
        return Verdict("explained", subject, failed, noise)
    if u:
        return Verdict("unconfirmed", subject, failed, noise)
    r = summary.get("runner_up")
    return Verdict("not_explained", r["cause"] if r else None, (), noise)


def apply(summary, v: Verdict) -> None:
    """Write ``v`` into ``summary`` (in place): ``verdict``, ``verdict_detail`` and, where
    the named cause is not established, ``best_candidate`` -- the named cause(s) with
    their parameters and intervals, moved there from ``cause``/``causes``/``parameters``/
    ``parameters_ci95``/``parameters_detail`` (which then read ``none`` and empty, as for
    a record with no cause). ``extended`` and ``holdout`` keep scoring the best
    candidate's extended model."""
    summary["verdict"] = v.verdict
    named = summary.get("cause", "none") != "none" and summary.get("causes")
    if v.verdict != "established" and named:
        summary["best_candidate"] = {
            "cause": v.subject, "causes": summary["causes"],
            "parameters": summary.get("parameters", {}),
            "parameters_ci95": summary.get("parameters_ci95", {}),
            "parameters_detail": summary.get("parameters_detail", {}),
            "named_by_selection_rules": True, "not_established_because": list(v.failed)}
        summary.update(cause="none", causes=[], parameters={}, parameters_ci95={},
                       parameters_detail={})
    elif v.verdict != "established" and summary.get("unconfirmed"):
        u = summary["unconfirmed"]
        summary["best_candidate"] = {"cause": u["cause"], "causes": [],
                                     "parameters": u.get("parameters", {}),
                                     "named_by_selection_rules": True,
                                     "not_established_because": [u["why"] + (
                                         "; that looks like slow sensor wander, not a cause"
                                         if "effect_rms_um" in u else "")]}
    elif v.verdict == "not_explained" and summary.get("runner_up"):
        r = summary["runner_up"]
        summary["best_candidate"] = {"cause": r["cause"], "causes": [],
                                     "parameters": r.get("parameters", {}),
                                     "named_by_selection_rules": False,
                                     "not_established_because": [
                                         f"not named by the selection rules: {r['why_lost']}"]}
    wn = v.within_noise
    summary["verdict_detail"] = {
        "verdict": v.verdict, "subject": v.subject, "failed_checks": list(v.failed),
        "residual_within_noise": {
            "holds": wn["holds"], "ljung_box_p_neff": wn["ljung_box_p_neff"],
            "n_eff": wn["n_eff"], "white": wn["white"],
            "thermometers_beyond_bound": wn["thermometers_beyond_bound"],
            "better_baselines_holdout_rmse_um": wn["better_baselines"]},
        "rules": RULES_TEXT, "stability": summary.get("verdict_detail", {}).get("stability")}
    summary["verdict_detail"]["text"] = text(summary)


RULES_TEXT = (
    "established: a named cause whose 95 % intervals exclude no effect and do not reach "
    "the end of the fit's range, confirmed on the hold-out (gain > 0); explained: "
    f"otherwise, the baseline residual is white by Ljung-Box on N_eff (p >= {WHITE_P:g}), "
    "no thermometer correlates with it beyond the N_eff bound and no baseline model (MLR "
    f"of eq. 18, paper AR(1)) is better on the hold-out by >= {100 * BETTER_CUT:g} %; "
    "unconfirmed: otherwise, a cause named by the selection rules that fails a check of "
    "'established'; not_explained: otherwise")


def _f(v, nd=3) -> str:
    if v is None or not np.isfinite(v):
        return "–"
    return f"{v:.{nd}g}"


def _what_is_left(summary) -> str:
    wn = summary["verdict_detail"]["residual_within_noise"]
    h, b = summary["holdout"], summary["baseline"]
    parts = [f"the simulation as configured leaves {_f(h['baseline_rmse_um'])} µm RMSE on "
             f"the hold-out (RMSE {_f(b['rmse_um'])} µm over the whole record, largest "
             f"error {_f(b.get('max_abs_um'))} µm)"]
    why = []
    if not wn["white"] and not np.isfinite(wn["ljung_box_p_neff"]):
        why.append(f"its whiteness cannot be tested (N_eff = {wn['n_eff']:.0f}: fewer than "
                   "10 independent samples), so it is not shown to be within the noise")
    elif not wn["white"]:
        why.append(f"its residual is not white (Ljung-Box on N_eff = {wn['n_eff']:.0f}: "
                   f"{st.p_text(wn['ljung_box_p_neff'])})")
    if wn["thermometers_beyond_bound"]:
        n = len(wn["thermometers_beyond_bound"])
        why.append(f"{n} thermometer{'s' if n > 1 else ''} correlate{'' if n > 1 else 's'} "
                   f"with it beyond the N_eff bound ({', '.join(wn['thermometers_beyond_bound'][:4])}"
                   + (", …" if n > 4 else "") + ")")
    for k, v in wn["better_baselines_holdout_rmse_um"].items():
        why.append(f"the {k} does better on the hold-out ({_f(v)} against "
                   f"{_f(h['baseline_rmse_um'])} µm)")
    return parts[0] + (": " + "; ".join(why) if why else "")


#: said where the stability across hold-out splits was not computed (issue 30: one
#: split's luck must not pass for the answer)
ONE_SPLIT = (" This verdict rests on one hold-out split; `arfem diagnose --stability N` "
             "says how often it holds at N rolling origins.")


def _stability_sentence(summary) -> str:
    s = (summary.get("verdict_detail") or {}).get("stability")
    if not s:
        return ONE_SPLIT
    return f" Stability: {s['text']}" if s.get("text") else ""


def _params(c: dict) -> str:
    ci = c.get("ci95") or {}
    return ", ".join(f"{k} = {_f(v, 4)}" + (f" [{_f(ci[k][0])}, {_f(ci[k][1])}]" if k in ci else "")
                     for k, v in c.get("parameters", {}).items())


def text(summary) -> str:
    """The verdict in words, without its label (report.md opens with "**Verdict: <verdict>.**"
    and this text, the terminal prints "verdict (<verdict>): " and this text); advice only
    for an established cause."""
    d = summary["verdict_detail"]
    v, h = d["verdict"], summary["holdout"]
    mlr = (summary.get("mlr") or {}).get("holdout_rmse_um")
    stab = _stability_sentence(summary)
    if v == "established":
        causes = summary.get("causes") or []
        acts = "; ".join(ACTIONS[c["cause"]] for c in causes if c["cause"] in ACTIONS)
        return (f"The simulation misses "
                + " and ".join(f"`{c['cause']}` ({_params(c)})" for c in causes)
                + f", with 95 % intervals in brackets; adding it cuts the hold-out error from "
                f"{_f(h['baseline_rmse_um'])} to {_f(h['extended_rmse_um'])} µm RMSE "
                f"({h['gain_pct']:.0f} %)"
                + (f"; the MLR of eq. 18 scores {_f(mlr)} µm" if mlr is not None else "")
                + "." + stab + (f" What to do: {acts}." if acts else ""))
    bc = summary.get("best_candidate")
    if v == "explained":
        wn = d["residual_within_noise"]
        s = (f"The simulation as configured explains this record to within the "
             f"noise: its residual is white by Ljung-Box on N_eff = {wn['n_eff']:.0f} "
             f"({st.p_text(wn['ljung_box_p_neff'])}), no thermometer correlates with it beyond "
             f"its bound, and no baseline model does better on the hold-out "
             f"({_f(h['baseline_rmse_um'])} µm RMSE"
             + (f"; MLR of eq. 18 {_f(mlr)} µm" if mlr is not None else "") + ").")
        if bc and bc.get("named_by_selection_rules"):
            s += (f" A `{bc['cause']}` fits the data before the hold-out but is not "
                  f"established ({'; '.join(bc['not_established_because'])}).")
        return s + stab
    if v == "unconfirmed":
        c = {"parameters": bc.get("parameters", {}),
             "ci95": bc.get("parameters_ci95", {})} if bc else {}
        return (f"`{d['subject']}` is the best candidate"
                + (f" ({_params(c)})" if c.get("parameters") else "")
                + f" but is not established: {'; '.join(d['failed_checks'])}. No cause is "
                f"named. Not explained either: {_what_is_left(summary)}." + stab)
    s = f"No cause is established, and {_what_is_left(summary)}."
    if bc:
        s += (f" The best candidate, `{bc['cause']}`, was not accepted: "
              f"{'; '.join(bc['not_established_because'])}.")
    return s + (" arfem's vocabulary of causes may lack what is left (or it is two causes "
                "at once, or slow sensor wander)." + stab)


def selected_causes(summary) -> list:
    """The cause records (``causes``-style dicts) the selection rules named, established
    or not: ``causes`` where the cause is established, else the ``best_candidate``'s
    where the rules named it; ``[]`` if nothing was named. The benchmarks of issue 24
    measure the selection rules by these.

    >>> [c["cause"] for c in selected_causes({"cause": "none", "causes": [],
    ...     "best_candidate": {"causes": [{"cause": "frame_expansion"}],
    ...                        "named_by_selection_rules": True}})]
    ['frame_expansion']
    """
    if summary.get("causes"):
        return list(summary["causes"])
    bc = summary.get("best_candidate") or {}
    return list(bc.get("causes", [])) if bc.get("named_by_selection_rules") else []


def named_cause(summary) -> str:
    """The cause the selection rules named, established or not ("a+b" for a pair;
    ``none`` if nothing was named or it was withdrawn by rule 9 or 10): ``cause`` where
    it is established, else ``best_candidate`` where the selection rules named it.

    >>> named_cause({"cause": "none", "causes": [], "best_candidate": {
    ...     "cause": "frame_expansion", "causes": [{"cause": "frame_expansion"}],
    ...     "named_by_selection_rules": True}})
    'frame_expansion'
    """
    if summary.get("causes"):
        return "+".join(c["cause"] for c in summary["causes"])
    bc = summary.get("best_candidate") or {}
    if bc.get("named_by_selection_rules") and bc.get("causes"):
        return "+".join(c["cause"] for c in bc["causes"])
    return summary.get("cause", "none")
