"""``arfem diagnose record.toml`` (or ``record.csv``) for a record whose TOML names a
mesh scenario (contract v3, :mod:`arfem.scenarios.records.georecord`): which part of the
user's model is wrong, on the geometry's own groups (issue 33).

Writes, atomically into ``--out``: ``diagnosis.json`` (verdict, causes with their
parameters and 95 % intervals, the hold-out scores per channel against the nominal
model and the MLR of paper eq. 18, the ranking of every candidate, the reduced model's
error statement), ``report.md`` and ``report.html`` opening with the verdict,
``geometry_named.png`` (the geometry with the named group highlighted), ``series.csv``
(measured, nominal and extended per channel) and ``channels.png``. Bad input: one
line, exit 2, ``--out`` untouched.
"""
from __future__ import annotations

import time

import numpy as np

from arfem.fem.body import SENSOR_QUANTITIES
from arfem.io import write_json
from arfem.models.geodiagnosis.engine import diagnose_geometry
from arfem.models.geodiagnosis.problem import GeoModel, GeoRecord, make_record, trial_for, Setting
from arfem.params import InputError
from arfem.scenarios.diagnosis.document import mesh_document
from arfem.scenarios.diagnosis.mesh_model import load_diagnosis_scenario, plant_of, reduced_model
from arfem.scenarios.diagnosis.terminal import diagnosis_terminal_line
from arfem.scenarios.records.georecord import (MeshRecord, is_mesh_record, read_mesh_record,
                                              refuse_unit_slip, sensor_columns)
from arfem.scenarios.outdir import prepare_out_dir, staged_out_dir

__all__ = ["WRITES", "is_mesh_record", "load_mesh_record", "run_geodiagnosis",
           "main_geodiagnose"]

#: Files a mesh diagnosis writes.
WRITES = ("diagnosis.json", "report.md", "report.html", "series.csv", "geometry_named.png",
          "channels.png", "model_extended.json", "model_nominal.json")

def _map_columns(cols: dict, sc, where: str):
    """(channel columns, source power columns, speed, ambient) of a v3 table; refusals
    name the column and what the scenario has (the one check,
    :func:`arfem.scenarios.records.georecord.sensor_columns`)."""
    chans, power = sensor_columns(cols, sc, where)
    return (chans, {s: cols[c] for s, c in power.items()}, cols.get("speed_rpm"),
            cols.get("ambient_C"))


def _speed_power(sc, src, speed, where: str) -> np.ndarray:
    """A source's power at each speed (its speed law, else linear between its
    scenario's (speed, power) pairs): :func:`arfem.scenarios.geometry.scenario.source_power_at_speed`."""
    from arfem.scenarios.geometry.scenario import source_power_at_speed
    return source_power_at_speed(sc, src, speed, where)


def load_mesh_record(path, progress=None, limits=None):
    """Read a v3 record (or take a :class:`~arfem.scenarios.records.georecord.MeshRecord` read
    once), its scenario, and build the reduced model.

    Returns (GeoRecord, GeoModel, Plant, scenario, timings {step: s}).
    """
    progress = progress or (lambda s: None)
    mr = path if isinstance(path, MeshRecord) else read_mesh_record(path, limits)
    files, tab = mr.files, mr.table
    where = str(files.csv)
    sc, spec = load_diagnosis_scenario(files.scenario, files.doc.scenario_toml)
    chans, power, speed, amb = _map_columns(tab.columns, sc, where)
    if speed is not None and (np.any(~np.isfinite(speed)) or np.any(speed < 0)):
        raise InputError("speed_rpm must be finite and >= 0", f"{where}: column speed_rpm")
    P = []
    for s in sc.sources:
        if s.spec.name in power:
            v = power[s.spec.name]
            if np.any(~np.isfinite(v)):
                raise InputError("empty or non-finite cells in an input column",
                                 f"{where}: column P_{s.spec.name}_W")
            P.append(v)
        elif speed is not None:
            P.append(_speed_power(sc, s, speed, where))
        else:
            raise InputError(f"no column P_{s.spec.name}_W and no speed_rpm: the input of heat "
                             f"source {s.spec.name!r} is unknown", where)
    tm = {}
    t0 = time.perf_counter()
    progress("assembling the scenario's model")
    plant, _ = plant_of(sc, progress)
    tm["assemble_s"] = time.perf_counter() - t0
    progress("growing the parametric reduced model")
    n_typ = float(np.median(speed[speed > 0])) if speed is not None and np.any(speed > 0) else 0.0
    model, tm["reduce_s"] = reduced_model(plant, sc, spec, n_typ)
    data = np.column_stack([tab.columns[c] for c in chans])
    rec = make_record(files.name, tab.columns["time_s"], data, chans, plant.names, plant.kinds,
                      np.column_stack(P) if P else np.zeros((data.shape[0], 0)), speed, amb,
                      sc.reference_C, files.displacement_zero)
    _check_units(model, rec, where)
    return rec, model, plant, sc, tm


def _check_units(model: GeoModel, rec: GeoRecord, where: str) -> None:
    """Refuse displacement channels whose spread is out of proportion to the nominal
    model's (the one rule, :func:`arfem.scenarios.records.georecord.refuse_unit_slip`)."""
    from arfem.models.geodiagnosis.problem import responses
    s = Setting(np.ones(len(model.convections)), np.ones(len(model.interfaces)))
    R, _ = responses(model, rec, s, np.zeros(rec.time_s.size))
    nom = R[:, :, :len(model.sources) + len(model.convections)].sum(axis=2)
    for j, c in enumerate(rec.channels):
        if c.kind == "displacement":
            refuse_unit_slip(c.column, rec.data[:, j], nom[:, j], where)


def _rom_statement(model: GeoModel, plant, rec: GeoRecord) -> dict:
    """The reduced model against the full solve (fresh Krylov basis at each h, the
    project's reduced-modal solver) on this record's nominal inputs: largest error per
    sensor, relative to the sensor's largest value."""
    from arfem.fem.thermal3d import InputHistory, solve_body_reduced
    from arfem.models.geodiagnosis.fit import make_context
    s = Setting(np.ones(len(model.convections)), np.ones(len(model.interfaces)))
    ctx = make_context(model, rec)
    tr = trial_for(model, rec, s, ctx.shape)
    t = np.concatenate([[0.0], np.cumsum(tr.durations_s)])
    S, G = len(model.sources), len(model.convections)
    hist = InputHistory(t, tr.inputs[:, :S + G], tr.h_W_m2K)
    t0 = time.perf_counter()
    full = solve_body_reduced(plant.body, hist, plant.G, t,
                         kinds=[SENSOR_QUANTITIES[k][4] for k in plant.kinds]).outputs
    t_full = time.perf_counter() - t0
    tr0 = type(tr)(tr.durations_s, tr.h_W_m2K, tr.kappa,
                   np.column_stack([tr.inputs[:, :S + G],
                                    np.zeros((tr.inputs.shape[0], len(model.candidates)))]))
    from arfem.models.geodiagnosis.rom import simulate
    red = simulate(model.rb, tr0, columns=False)
    err = np.max(np.abs(red - full), axis=0)
    scale = np.max(np.abs(full), axis=0)
    unit = [1.0 if k == "temperature" else 1e6 for k in plant.kinds]
    return {"basis_vectors": model.rb.k, "krylov_blocks": model.rb.n_blocks,
            "max_abs_error": {n: float(e * u) for n, e, u in zip(plant.names, err, unit)},
            "max_rel_error": {n: float(e / s) if s > 0 else 0.0
                              for n, e, s in zip(plant.names, err, scale)},
            "units": "µm for displacements, µrad for tilts, K for temperatures",
            "reference": "arfem.fem.thermal3d.solve_body_reduced at the nominal h (own basis)",
            "reference_solve_s": t_full}


def run_geodiagnosis(case, out, holdout_start_s=None, force=False, progress=None,
                     limits=None) -> dict:
    """Diagnose a v3 record (its path, or a :class:`~arfem.scenarios.records.georecord.MeshRecord`
    read once) and write every output into ``out``; returns the summary (diagnosis.json's
    content)."""
    return _diagnose_and_write(case, out, holdout_start_s, force, progress, limits)[1]


def _diagnose_and_write(case, out, holdout_start_s, force, progress, limits):
    """:func:`run_geodiagnosis`'s work: (the typed result, diagnosis.json's content)."""
    from arfem.scenarios.diagnosis.mesh_report import write_report
    progress = progress or (lambda s: None)
    progress("reading the record")
    t0 = time.perf_counter()
    case = case if isinstance(case, MeshRecord) else read_mesh_record(case, limits)
    prepare_out_dir(out, force, inputs=[case.files.toml], writes=WRITES)
    rec, model, plant, sc, tm = load_mesh_record(case, progress)
    if holdout_start_s is not None and not rec.time_s[0] < holdout_start_s < rec.time_s[-1]:
        raise InputError(f"{holdout_start_s:g} s is outside the record "
                         f"({rec.time_s[0]:g}-{rec.time_s[-1]:g} s)", "--holdout-start")
    t1 = time.perf_counter()
    d = diagnose_geometry(model, rec, holdout_start_s, progress)
    tm["diagnose_s"] = time.perf_counter() - t1
    progress("stating the reduced model's error")
    rom = _rom_statement(model, plant, rec)
    s = mesh_document(d, rom)
    progress("exporting the compensators")
    t2 = time.perf_counter()
    models = _export_models(case, d, model, rec, sc, progress)
    tm["export_and_replay_s"] = time.perf_counter() - t2
    s["extended_model"] = models.statement
    tm["total_s"] = time.perf_counter() - t0
    s["timings_s"] = tm
    progress("writing outputs")
    with staged_out_dir(out, force) as stage:
        write_json(stage / "diagnosis.json", s)
        write_report(stage, s, d, rec, model, plant, sc)
        from arfem.scenarios.compensation.model_file import write_model
        if models.nominal is not None:
            write_model(stage / "model_nominal.json", models.nominal)
        if models.extended is not None:
            write_model(stage / "model_extended.json", models.extended)
    return d, s


def _export_models(case, d, model, rec, sc, progress):
    """model_extended.json / model_nominal.json and their replay on the record
    (:mod:`arfem.scenarios.diagnosis.mesh_export`); ``case`` the record read once."""
    from arfem import __version__
    from arfem.scenarios.records.axes_record import load_axes_record
    from arfem.scenarios.diagnosis.mesh_export import diagnosis_models, replay_table
    ds = load_axes_record(case)             # the record as read, not read again
    models = diagnosis_models(d, model, rec, sc, case.files, set(ds.extra_columns),
                              __version__, progress)
    models.statement["replay"] = replay_table(models, ds, d.holdout.start_s,
                                              str(case.files.toml))
    return models


def main_geodiagnose(args, record=None) -> int:
    """The ``arfem diagnose`` command for a mesh record (parsed ``args`` of
    :mod:`arfem.scenarios.commands.diagnose`; ``record`` its TOML as read, or None)."""
    from arfem.scenarios.progress import Progress
    limits = getattr(args, "limits", None)
    with Progress(10, "arfem diagnose", enabled=not args.no_progress) as progress:
        case = args.case if record is None else read_mesh_record(args.case, limits, record)
        d, _ = _diagnose_and_write(case, args.out, args.holdout_start, args.force,
                                   progress, limits)
    print(diagnosis_terminal_line(d) + f"; wrote {args.out}")
    print(f"verdict ({d.verdict}): {d.text}")
    for n in (case.table.notes if isinstance(case, MeshRecord) else ()):
        print(f"note: {n}")               # what the record reader did (e.g. filled cells)
    return 0
