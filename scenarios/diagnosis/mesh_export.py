"""The compensators of a mesh diagnosis (issue 33 item 4): ``model_extended.json`` (the
parametric reduced model with the established causes built in,
:mod:`arfem.models.geodiagnosis.extended`) and ``model_nominal.json`` (the same reduced
model at the scenario's nominal parameters, same basis, same discretisation), both
version 2 (one output per displacement channel), and their causal replay on the record
(:func:`arfem.scenarios.compensation.replay.replay`, the replay ``arfem compensate`` runs),
scored from the hold-out's start.

With no established cause, or none that can be built into the machine's model (a
sensor's drift alone), no ``model_extended.json`` is written (the verdict never claims
more than the data show): ``diagnosis.json``'s ``extended_model`` says why, and
``model_nominal.json`` is still written, flagged as the nominal model in its ``kind``
(``fem_reduced_nominal``) and description.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arfem.models.geodiagnosis.extended import export_reduced, reads_speed
from arfem.params import InputError

__all__ = ["DiagnosisModels", "diagnosis_models", "replay_table", "MODEL_FILES"]

#: the compensator files a mesh diagnosis may write
MODEL_FILES = ("model_extended.json", "model_nominal.json")


@dataclass(frozen=True)
class DiagnosisModels:
    """The nominal and (if any) extended model of a diagnosis.

    Attributes
    ----------
    nominal, extended : StateSpaceModel or None
    statement : dict, ``diagnosis.json``'s ``extended_model`` (written or why not,
        record, scenario, causes with intervals and how each enters)
    """

    nominal: object
    extended: object
    statement: dict


def _outputs(rec, sc) -> list:
    """(sensor output index, column, axis) of each displacement channel, in the
    scenario's sensor order; axes as ``arfem run``'s model.json (X/Y/Z by direction)."""
    from arfem.scenarios.geometry.export import sensor_axes
    axis = {s.name: ax for s, ax in sensor_axes(sc.sensors)}
    chans = sorted((c for c in rec.channels if c.kind == "displacement"),
                   key=lambda c: c.output)
    return [(c.output, c.column, axis[c.sensor]) for c in chans]


def _inputs(model, rec, sc, fit, columns) -> tuple[list, str]:
    """The model's inputs (name, unit) and '' or why the record cannot drive it."""
    ins = []
    for s in sc.sources:
        name = f"P_{s.spec.name}_W"
        if name not in columns:
            return [], (f"the record gives source {s.spec.name!r} through speed_rpm; a "
                        f"state-space model reads its input: add the column {name}")
        ins.append((name, "W" if s.spec.kind == "power" else "W/m²"))
    if rec.ambient_C is not None:
        ins.append(("ambient_C", "°C"))
    if reads_speed(model, rec, fit):
        ins.append(("speed_rpm", "1/min"))
    return ins, ""


def _provenance(d, files, rec, what: str) -> str:
    parts = [f"{what} of {files.scenario.name} fitted by arfem diagnose on record "
             f"{rec.name!r} ({files.toml.name}), fit window {rec.time_s[0]:g}-"
             f"{float(rec.time_s[rec.time_s < d.holdout.start_s][-1]):g} s, hold-out from "
             f"{d.holdout.start_s:g} s (verdict {d.verdict})"]
    for c in d.established:
        parts.append(c.name + ": " + ", ".join(
            f"{k} = {v:.4g} [{c.ci95[k][0]:.4g}, {c.ci95[k][1]:.4g}]"
            for k, v in c.parameters.items()))
    return "; ".join(parts)


def diagnosis_models(d, model, rec, sc, files, columns, arfem_version: str = "",
                     progress=None) -> DiagnosisModels:
    """Export the nominal and the extended model of diagnosis ``d``.

    Parameters
    ----------
    d : Diagnosis, a mesh diagnosis (its ``evidence`` the engine's
        :class:`~arfem.models.geodiagnosis.engine.MeshEvidence`)
    model : GeoModel, the nominal parametric reduced model of the diagnosis
    rec : GeoRecord
    sc : GeometryScenario
    files : RecordFiles, the record's files (provenance)
    columns : collection of str, the record's column names
    """
    progress = progress or (lambda s: None)
    dt = np.diff(rec.time_s)
    dtau = float(np.median(dt))
    train_end = float(rec.time_s[rec.time_s < d.holdout.start_s][-1])
    named = d.evidence.named
    est = bool(d.established)
    outs = _outputs(rec, sc)
    st = {"written": False, "file": None, "nominal_file": None, "kind": None,
          "record": files.toml.name, "scenario": files.scenario.name,
          "dtau_s": dtau, "fit_window_s": [float(rec.time_s[0]), train_end],
          "causes": [], "why_not": ""}
    ins, why = _inputs(model, rec, sc, named if est else None, columns)
    if why:
        st["why_not"] = why
        return DiagnosisModels(None, None, st)
    nom = export_reduced(model, rec, None, dtau_s=dtau, outputs=outs, inputs=ins,
                         kind="fem_reduced_nominal",
                         description="NOMINAL (no cause built in): reduced model at the "
                         "scenario's own parameters; " + _provenance(d, files, rec,
                                                                     "reduced model"),
                         arfem_version=arfem_version)
    if nom.model is None:
        st["why_not"] = nom.note
        return DiagnosisModels(None, None, st)
    st["nominal_file"] = "model_nominal.json"
    if not est:
        st["why_not"] = (f"verdict {d.verdict}: no cause established, so no extended "
                         "model (model_nominal.json is the scenario's model as it is)")
        return DiagnosisModels(nom.model, None, st)
    used = model
    s = named.setting
    if model.regrow is not None and any(c.nonlinear for c in named.causes):
        progress("regrowing the reduced basis at the named setting for the export")
        from arfem.models.geodiagnosis.problem import GeoModel
        used = GeoModel(**{**vars(model), "rb": model.regrow(s.h_scale, s.kappa)})
    kind = "extended:" + "+".join(c.name for c in d.causes)
    ext = export_reduced(used, rec, named, dtau_s=dtau, outputs=outs, inputs=ins, kind=kind,
                         description=_provenance(d, files, rec, "extended reduced model"),
                         arfem_version=arfem_version,
                         fit_window_s=(float(rec.time_s[0]), train_end))
    st["causes"] = [{"cause": c.name, "parameters": dict(c.parameters),
                     "ci95": {k: list(v) for k, v in c.ci95.items()}} for c in d.causes]
    for e, (nm, how, built) in zip(st["causes"], ext.entered):
        e["enters_as"], e["built_in"] = how, built
    if ext.model is None:
        st["why_not"] = ext.note
        return DiagnosisModels(nom.model, None, st)
    if not any(built for _, _, built in ext.entered):
        # e.g. a sensor's drift alone: the machine's model is the nominal one, and a file
        # named "extended" that is the nominal would claim a correction it does not make
        st["why_not"] = ("no established cause can be built into the machine's model ("
                         + "; ".join(f"{nm}: {how}" for nm, how, _ in ext.entered)
                         + "), so the machine's model is model_nominal.json")
        return DiagnosisModels(nom.model, None, st)
    st.update(written=True, file="model_extended.json", kind=kind)
    return DiagnosisModels(nom.model, ext.model, st)


def replay_table(models: DiagnosisModels, ds, score_from_s: float, where: str) -> dict:
    """Each model replayed causally on the record ``ds`` (an
    :class:`arfem.scenarios.records.axes_record.AxesRecord`, read once by the caller), scored
    from ``score_from_s``:
    {axis: {output, rms_before_um, nominal_rms_after_um, extended_rms_after_um}}."""
    from arfem.scenarios.compensation.replay import replay
    if models.nominal is None:
        return {}
    try:
        rn = replay(models.nominal, ds, score_from_s=score_from_s, where=where)
        re_ = (replay(models.extended, ds, score_from_s=score_from_s, where=where)
               if models.extended is not None else None)
    except InputError as exc:           # e.g. a record not sampled at one interval
        return {"not_replayed": str(exc)}
    out = {}
    for j, a in enumerate(rn.summary.axes):
        out[a.axis] = {"output": a.output, "rms_before_um": a.rms_before_um,
                       "nominal_rms_after_um": a.rms_after_um,
                       "extended_rms_after_um": (re_.summary.axes[j].rms_after_um
                                                 if re_ is not None else None)}
    return out
