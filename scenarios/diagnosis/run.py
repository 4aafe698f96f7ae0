"""The work of ``arfem diagnose``, as a library: load a measured record, diagnose it, add
the verdict's stability, fit the compensators on the same window and write every output
(``diagnosis.json``, ``report.md``, ``series.csv``, figures, ``report.html``, ``model.json``,
``model_extended.json``, ``model_mlr.json``) atomically. The command module
(:mod:`arfem.scenarios.commands.diagnose`) only parses the command line and prints; report scripts,
benchmarks and tests call this module.
"""
from __future__ import annotations

from arfem.models.diagnosis.engine import BRANCH_ONLY, Diagnosis, check_speed_engine, diagnose
from arfem.params import InputError
from arfem.scenarios.diagnosis.document import document
from arfem.scenarios.records.dataset import RecordDoc, load_dataset, read_record_doc
from arfem.scenarios.records.georecord import refuse_mesh_channels, refuse_mesh_record
from arfem.scenarios.html_report import write_html_report
from arfem.scenarios.outdir import prepare_out_dir, staged_out_dir

__all__ = ["WRITES", "compensator_models", "diagnose_file", "add_stability",
           "run_diagnosis", "diagnose_and_write", "speed_options"]

#: The files ``write_all`` puts into --out (checked before the work: never an input or
#: a file arfem did not write; see arfem.scenarios.outdir).
WRITES = ("diagnosis.json", "report.md", "series.csv", "growth_residual.png",
          "correlations.png", "report.html", "model.json", "model_extended.json",
          "model_mlr.json")


def compensator_models(ds, fit_end_s: float, diag=None) -> dict:
    """The models ``arfem compensate`` can run, fitted on the rows before ``fit_end_s``
    (the diagnosis's hold-out start): ``{"model.json": …, "model_extended.json": …,
    "model_mlr.json": …}``.

    A ``q_W_m2`` record gets the paper's AR(1) of its ``[rod]`` (eqs. 12-14, nothing
    fitted) and, given the :class:`Diagnosis` ``diag`` with a named cause, the extended
    model (:func:`arfem.models.diagnosis.export.fem_state_space`); a ``speed_rpm``
    record the AR(1) calibrated by eq. 17 with its speed → C2 map and, given a named
    cause, the extended model of the engine that named it (the speed branch's thermometer
    frame, :func:`~arfem.models.diagnosis.export.speed_state_space`; the speed plant's,
    :func:`~arfem.models.diagnosis.export.speed_plant_state_space`); a record with complete
    temperatures also the MLR of eq. 18. A model that cannot run as a compensator (C1 >=
    1, a cause with no linear time-invariant form) is not exported; the list
    ``"not_exported"`` says why.
    """
    import dataclasses

    import numpy as np

    from arfem import __version__
    from arfem.models.ar1 import c1_paper, c2_paper
    from arfem.models.compensator import ar1_model, fit_mlr_model, fit_speed_ar1_model
    t = np.asarray(ds.time_s, float)
    dt = float(np.median(np.diff(t)))
    fit = t < fit_end_s
    span = f"fitted on {t[fit][0] / 3600:.2f}-{t[fit][-1] / 3600:.2f} h of {ds.name!r}"
    out, why = {}, []
    if ds.q_W_m2 is not None:
        out["model.json"] = ar1_model(
            c1_paper(ds.rod, dt), c2_paper(ds.rod, dt, 1.0) * 1e6, dtau_s=dt,
            arfem_version=__version__,
            description=f"paper eqs. 12-14 for the [rod] of {ds.name!r} (not fitted)")
    else:
        try:
            out["model.json"] = fit_speed_ar1_model(
                ds.growth_um[fit], ds.speed_rpm[fit][1:], dtau_s=dt,
                arfem_version=__version__,
                description=f"paper AR(1) calibrated by eq. 17 on every row, {span}; "
                            f"C2 of a speed off the fitted ones interpolated linearly "
                            f"(extrapolated beyond them; arfem diagnose's baseline maps "
                            f"a speed not seen before the hold-out by eqs. 20-21 instead)")
        except InputError as exc:          # e.g. C1 >= 1: no compensator to export
            why.append(f"model.json: {exc}")
    # the extended model of the cause the selection rules named, established or not
    # (an unconfirmed one is ``best_candidate`` in diagnosis.json; its file says so)
    if diag is not None and diag.causes:
        try:
            out["model_extended.json"] = _extended_model(ds, diag, dt, fit, span)
        except InputError as exc:
            why.append(f"model_extended.json: {exc}")
    temps = {k: np.asarray(v, float)[fit] for k, v in ds.temperatures.items()}
    if any(np.all(np.isfinite(v)) for v in temps.values()):
        out["model_mlr.json"] = fit_mlr_model(ds.growth_um[fit], temps, dtau_s=dt,
                                              arfem_version=__version__,
                                              description=f"MLR of eq. 18, {span}")
    window = (float(t[fit][0]), float(t[fit][-1]))
    for name, m in out.items():          # every model but the unfitted paper AR(1)
        if not (name == "model.json" and ds.q_W_m2 is not None):
            out[name] = dataclasses.replace(m, fit_window_s=window)
    if why:
        out["not_exported"] = why
    return out


def _extended_model(ds, diag, dt: float, fit, span: str):
    """The extended model of the causes ``diag`` named, as a compensator, by the engine
    that named them (``fit``: the fit rows; ``span``: the fit window in words);
    InputError where it has no such form."""
    import numpy as np

    from arfem import __version__
    from arfem.models.diagnosis import stats as st
    from arfem.models.diagnosis.export import (fem_state_space, speed_plant_state_space,
                                               speed_state_space)
    causes = " + ".join(c.name for c in diag.causes)
    verdict = diag.verdict
    label = ("" if verdict == "established" else
             f"; the best candidate, {verdict}: not established")
    kw = {"R_um2": max(st.noise_sigma(np.asarray(ds.growth_um)[fit]), ds.noise_floor_um) ** 2,
          "arfem_version": __version__}
    ev = diag.evidence
    if ev.physics is not None:
        return fem_state_space(ev.extended, ev.physics, dt,
                               description=f"FEM rod with {causes} (the diagnosis's extended "
                                           f"model{label}), {span}", **kw)
    if ev.speed is not None:
        return speed_state_space(ev.extended, ev.speed, dt,
                                 description=f"AR(1) of the speed + frame from thermometers "
                                             f"(the diagnosis's extended model{label}), "
                                             f"{span}", **kw)
    if ev.plant_fit is not None:
        plant, named = ev.plant_fit
        return speed_plant_state_space(
            named, plant, dt, Q_um2=ev.extended.rss / max(ev.extended.n, 1),
            description=f"speed plant: AR(1) of {plant.heat.why} with "
                        f"{causes} (the diagnosis's extended model{label}); thermometers "
                        f"read raw (the diagnosis smooths them by a centred mean), {span}",
            **kw)
    raise InputError(f"the extended model of this speed-only record ({causes}) is not "
                     f"exported yet")


def speed_options(input_kind: str, speed_engine: str | None = None,
                  frame_search: str | None = None, drift_last: bool = False,
                  source=None) -> tuple[str, str]:
    """``(speed_engine, frame_search)`` for :func:`arfem.models.diagnosis.engine.diagnose`
    from ``arfem diagnose``'s options as the user gave them (None: not given; then the
    speed branch, ``"branch"``, and ``"narrow"``).

    ``input_kind``: the record's (``"speed_rpm"``, ``"q_W_m2"``) or ``"mesh"`` for a
    contract-v3 record. A ``q_W_m2`` or mesh record is always diagnosed by the one
    pipeline, so an explicit ``branch`` is refused there; ``--frame-search`` and
    ``--drift-last`` belong to the branch
    (:data:`arfem.models.diagnosis.engine.BRANCH_ONLY`) and are refused with
    ``pipeline``. Each refusal is an InputError (one line, exit 2), raised before
    anything is written; ``source`` (the record's file) locates the one that is about
    the record. An unknown engine is the engine's own check
    (:func:`arfem.models.diagnosis.engine.check_speed_engine`), located at the option.
    """
    if speed_engine is not None:
        try:
            check_speed_engine(speed_engine)
        except InputError as exc:
            raise InputError(exc.message, "--speed-engine") from None
    if speed_engine == "branch" and input_kind != "speed_rpm":
        what = "mesh record (contract v3)" if input_kind == "mesh" else f"{input_kind} record"
        raise InputError(f"applies to speed_rpm records on the rod only; this {what} is "
                         f"always diagnosed by the one pipeline (leave the option out)",
                         "--speed-engine branch" if source is None
                         else f"{source}: --speed-engine branch")
    if speed_engine == "pipeline":
        for key, flag, given in (("frame_search", "--frame-search", frame_search is not None),
                                 ("drift_last", "--drift-last", drift_last)):
            if given:
                raise InputError(f"does not apply with --speed-engine pipeline: "
                                 f"{BRANCH_ONLY[key]}", flag)
    return speed_engine or "branch", frame_search or "narrow"


def _rod_dataset(toml_path, limits):
    """The record read for the rod's diagnosis (``toml_path``, or its TOML as read: a
    :class:`arfem.scenarios.records.dataset.RecordDoc`); a mesh model's record (contract v3, or
    its displacement channels without the ``[model]`` table) is refused in one line."""
    doc = toml_path if isinstance(toml_path, RecordDoc) else read_record_doc(toml_path, limits)
    refuse_mesh_record(doc)
    ds = load_dataset(doc, limits)
    refuse_mesh_channels(ds)
    return ds


def diagnose_file(toml_path, holdout_start_s=None, frame_search: str | None = None,
                  progress=None, drift_last: bool = False, limits=None,
                  stability: int = 0, speed_engine: str | None = None) -> Diagnosis:
    """Load a contract dataset (TOML + CSV) and diagnose it; ``progress`` and
    ``drift_last`` as in :func:`arfem.models.diagnosis.engine.diagnose`, ``limits``
    (:class:`arfem.limits.Limits`) as :func:`arfem.scenarios.records.dataset.load_dataset`,
    ``stability`` as in :func:`add_stability`; ``speed_engine`` and ``frame_search`` as
    the user gave them (None: not given), checked by :func:`speed_options`."""
    if progress is not None:
        progress("reading the dataset")
    ds = _rod_dataset(toml_path, limits)
    return _diagnose_checked(ds, holdout_start_s, frame_search, progress, drift_last,
                             stability, speed_engine)


def _diagnose_checked(ds, holdout_start_s, frame_search, progress, drift_last, stability,
                      speed_engine) -> Diagnosis:
    """``ds`` diagnosed with the options as the user gave them (:func:`speed_options`
    checks them first) and the verdict's stability added (:func:`add_stability`)."""
    engine, frame_search = speed_options(ds.input_kind, speed_engine, frame_search,
                                         drift_last, ds.source)
    diag = diagnose(ds, holdout_start_s, frame_search, progress, drift_last=drift_last,
                    speed_engine=engine)
    return add_stability(diag, ds, stability, frame_search, drift_last, progress,
                         speed_engine=engine)


def add_stability(diag: Diagnosis, ds, n_origins: int, frame_search: str = "narrow",
                  drift_last: bool = False, progress=None, mapper=map,
                  speed_engine: str = "branch") -> Diagnosis:
    """``diag`` with the verdict's stability across hold-out splits (in its document's
    ``verdict_detail.stability`` and the verdict's text): the diagnosis rerun with its
    hold-out from each of up to ``n_origins`` rolling origins
    (:func:`arfem.models.diagnosis.rolling.stability_origins`), on the same
    ``speed_engine`` as ``diag``, without intervals where the engine can leave them out
    (the speed branch; the pipeline always computes them)
    (:func:`arfem.models.diagnosis.rolling.verdict_stability`). ``n_origins`` 0: ``diag``
    as it is. Each rerun costs about one diagnosis without intervals."""
    if not n_origins:
        return diag
    import dataclasses

    from arfem.models.diagnosis import verdict as vd
    from arfem.models.diagnosis.engine import typed_result
    from arfem.models.diagnosis.rolling import stability_origins, verdict_stability
    u = ds.q_W_m2 if ds.input_kind == "q_W_m2" else ds.speed_rpm
    origins = stability_origins(ds.time_s, u, n_origins)
    s = document(diag)

    def at(origin_s):
        if progress is not None:
            progress(f"stability: hold-out from {origin_s / 3600:.2f} h")
        return diagnose(ds, origin_s, frame_search, None,
                        intervals=speed_engine == "pipeline", drift_last=drift_last,
                        speed_engine=speed_engine).evidence.document

    subject = s["verdict_detail"]["subject"] if s["verdict"] != "not_explained" else None
    if s["verdict"] == "explained" and not s.get("causes"):
        subject = None
    if s["verdict"] == "not_explained" and s["verdict_detail"].get("best_candidate_beaten_by_mlr"):
        # named by the selection rules, not explained only because a regression beats it
        # (issue 41): its stability is still that of the cause the rules named
        subject = vd.named_cause(s)
    st = verdict_stability(at, origins, subject, mapper)
    s["verdict_detail"]["stability"] = st
    s["verdict_detail"]["text"] = vd.text(s)
    return typed_result(s, diag.series,
                        lambda doc: dataclasses.replace(diag.evidence, document=doc),
                        ds.rod.convection_W_m2K)


def run_diagnosis(case, out, holdout_start_s=None, force=False, frame_search=None,
                  progress=None, drift_last=False, limits=None, stability=0,
                  speed_engine=None) -> dict:
    """Diagnose ``case`` (TOML path) and write every output, with ``report.html``, into
    ``out``; returns the summary (diagnosis.json's content). ``progress``,
    ``frame_search`` and ``speed_engine`` as in :func:`diagnose_file`; the typed result:
    :func:`diagnose_and_write`."""
    return document(diagnose_and_write(case, out, holdout_start_s, force, frame_search,
                                       progress, drift_last, limits, stability,
                                       speed_engine))


def diagnose_and_write(case, out, holdout_start_s=None, force=False, frame_search=None,
                       progress=None, drift_last=False, limits=None,
                       stability=0, speed_engine=None) -> Diagnosis:
    """:func:`run_diagnosis`, returning the typed result (what ``arfem diagnose`` prints
    from, :func:`arfem.scenarios.diagnosis.terminal.diagnosis_terminal_line`)."""
    from arfem.scenarios.diagnosis.report import write_all
    from arfem.scenarios.compensation.model_file import write_model
    doc = case if isinstance(case, RecordDoc) else read_record_doc(case, limits)
    refuse_mesh_record(doc)          # a v3 record goes to the mesh diagnosis, not here
    prepare_out_dir(out, force, inputs=[doc.path], writes=WRITES)   # refuse early, before any work
    if progress is not None:
        progress("reading the dataset")
    ds = _rod_dataset(doc, limits)
    diag = _diagnose_checked(ds, holdout_start_s, frame_search, progress, drift_last,
                             stability, speed_engine)
    if progress is not None:
        progress("writing outputs")
    models = compensator_models(ds, diag.holdout.start_s, diag)
    for why in models.pop("not_exported", []):
        print(f"note: {why}")
    with staged_out_dir(out, force) as stage:
        write_all(diag, stage)
        for name, m in models.items():
            write_model(stage / name, m)
        write_html_report(stage)
    return diag
