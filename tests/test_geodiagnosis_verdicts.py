"""Issue 41 item 2: verdicts no bigger than the data, on the mesh plant.

Each finding of the issue replayed on the coarse spindle unit (tests/data/geodiag, 48 mm
elements) with records of the full-order model (models/geodiagnosis/synth.py), 12 h at
300 s so that each diagnosis takes seconds:

* a run's own noise-free record is "explained" (the practical floor: a residual below
  the instruments' resolution claims nothing);
* without a ``[diagnosis]`` table every surface group without a source is searched for
  a missing source and every thin layer for a contact: a 10 W source missing near the
  motor is found on its group; a narrowed search says what it left out;
* two causes that fit the data alike are reported together and neither is
  established;
* an error outside the vocabulary (the housing expanding at 11.5e-6 where the model
  says 10.5e-6) that a regression on the thermometers explains far better than any
  cause is "not explained".

A run's own `arfem run` record goes through the commands on the coarse unit in CI and
on the shipped unit in one slow test.
"""
from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arfem.models.geodiagnosis.engine import diagnose_geometry
from arfem.models.geodiagnosis.problem import make_record
from arfem.models.geodiagnosis.synth import Hidden, covers, duty_cycle, generate, signal
from arfem.scenarios.diagnosis.mesh_model import (DiagnosisSpec, load_diagnosis_scenario,
                                               plant_of, reduced_model)

DATA = Path(__file__).parent / "data" / "geodiag"
SCENARIO = DATA / "spindle_coarse.toml"
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def coarse():
    """The coarse unit's plant and its model searched as a scenario without a
    ``[diagnosis]`` table would be (the default search)."""
    sc, _ = load_diagnosis_scenario(SCENARIO)
    plant, _ = plant_of(sc)
    model, _ = reduced_model(plant, sc, DiagnosisSpec(), 8000.0)
    return sc, plant, model


def _record(plant, hidden, seed, noise=True, truth=None):
    """A 12 h record at 300 s; ``noise=False``: the noise-free readings at 10
    significant digits (as ``arfem run`` writes record.csv); ``truth``: the plant that
    generates it (default ``plant``)."""
    rng = np.random.default_rng(seed)
    t, speed, power, amb = duty_cycle(rng, 12.0, 300.0, plant.sources)
    src = truth or plant
    if noise:
        y = generate(src, hidden, t, speed, power, amb, rng)
    else:
        y = np.array([[float(f"{v:.10g}") for v in row]
                      for row in signal(src, hidden, t, speed, power, amb)])
    return make_record(f"seed{seed}", t, y, plant.columns, plant.names, plant.kinds, power,
                       speed, amb, plant.reference_C)


def test_default_search_is_every_sourceless_surface_and_every_thin_layer(coarse):
    """Without the table: the five surface groups that carry no source are candidates
    for a missing source (the three bearing/motor faces carry the sources), the two
    bearing rings (thin layers between shaft and housing) are interfaces, the housing
    (between stator and column, not thin) and the shaft are not; nothing is left
    unsearched. A table that narrows the search lists what it left out."""
    sc, plant, model = coarse
    assert model.candidates == ("column_faces", "column_foot", "housing_outer",
                                "shaft_exposed", "spindle_bore")
    assert model.interfaces == ("front_bearing", "rear_bearing")
    assert model.unsearched == ()
    narrow, _ = reduced_model(plant, sc, DiagnosisSpec(("housing_outer",), ()), 8000.0)
    assert narrow.candidates == ("housing_outer",) and narrow.interfaces == ()
    assert narrow.unsearched == (
        "missing_source:column_faces", "missing_source:column_foot",
        "missing_source:shaft_exposed", "missing_source:spindle_bore",
        "contact_conductance:front_bearing", "contact_conductance:rear_bearing")


def test_noise_free_record_is_explained(coarse):
    """The route docs/geometry.md suggests: a record of the model itself, without
    noise. Its residual is the reduced model's own error (~1e-4 µm), far below any
    sensor's resolution: "explained" (it had been "established: warm_start" and "not
    explained" on two meshes), nothing established."""
    sc, plant, model = coarse
    d = diagnose_geometry(model, _record(plant, [], 1101, noise=False))
    assert d.verdict == "explained", d.text
    assert d.below_resolution and d.established == ()
    assert "resolution" in d.text


def test_missing_source_near_the_motor_is_found_without_a_table(coarse):
    """A 10 W source missing in the spindle bore (by the motor): with the default
    search it is established on its group, its interval holding 10 W (on the shipped
    unit without the table it had come out established as the wrong pair, front bearing
    × 1.114 and motor × 1.113)."""
    sc, plant, model = coarse
    hidden = Hidden("missing_source", "spindle_bore", 10.0)
    d = diagnose_geometry(model, _record(plant, [hidden], 1102))
    assert d.verdict == "established", d.text
    assert [c.name for c in d.evidence.named.causes] == ["missing_source:spindle_bore"], d.text
    assert covers(d.causes, hidden), d.evidence.named.ci95


def test_a_narrowed_search_says_what_went_unsearched(coarse, tmp_path):
    """The same record against a table that lists only the housing: the verdict text
    and diagnosis.json name every cause left out, the true one among them, and no
    missing source is claimed on the group actually searched."""
    from arfem.scenarios.diagnosis.document import mesh_document
    sc, plant, _ = coarse
    narrow, _ = reduced_model(plant, sc, DiagnosisSpec(("housing_outer",), ()), 8000.0)
    d = diagnose_geometry(narrow, _record(plant, [Hidden("missing_source", "spindle_bore",
                                                         10.0)], 1102))
    assert "Not searched" in d.text and "missing_source:spindle_bore" in d.text, d.text
    assert "missing_source:housing_outer" not in [c.name for c in d.established]
    s = mesh_document(d, {})
    assert "missing_source:spindle_bore" in s["not_searched"]
    assert json.loads(json.dumps(s["not_searched"])) == list(narrow.unsearched)


def test_causes_that_fit_alike_are_reported_together_and_not_established(coarse):
    """Two candidate groups whose load columns are identical (a mesh cannot tell them
    apart: the spindle bore and its twin) and a source missing on one: both fit the
    record alike, so both are reported (the named one and its alternative) and neither
    is established."""
    sc, plant, _ = coarse
    narrow, _ = reduced_model(plant, sc, DiagnosisSpec(("spindle_bore",), ()), 8000.0)
    i = len(narrow.sources) + len(narrow.convections)
    rb = dataclasses.replace(narrow.rb, L=np.column_stack([narrow.rb.L, narrow.rb.L[:, i]]))
    twin = dataclasses.replace(narrow, rb=rb, regrow=None,
                               candidates=("spindle_bore", "spindle_bore_twin"))
    d = diagnose_geometry(twin, _record(plant, [Hidden("missing_source", "spindle_bore",
                                                       10.0)], 1102))
    names = {c.name for c in d.evidence.named.causes} | set(d.alternatives)
    assert names == {"missing_source:spindle_bore", "missing_source:spindle_bore_twin"}, \
        (d.text, d.alternatives)
    assert d.verdict != "established" and d.established == ()
    assert "fits the data as well" in d.text


@pytest.mark.parametrize("seed", [1105, 1005])
def test_an_error_outside_the_vocabulary_that_a_regression_explains_is_not_explained(
        coarse, tmp_path, seed):
    """The housing expands at 11.5e-6 1/K where the model says 10.5e-6: no cause of the
    vocabulary is that. The nominal residual follows the temperatures, and the nominal
    model with its residual regressed on the thermometers does far better on the
    hold-out than the best candidate's extended model (0.35 against 0.79 µm on d_tcp_z
    for seed 1005): "not explained", neither "unconfirmed" (as on the shipped unit)
    nor "explained" (as the whitening alone had it: the fitted walk absorbed the
    misfit), and no cause established."""
    sc, plant, _ = coarse
    text = SCENARIO.read_text(encoding="utf-8")
    i = text.index('group = "housing"')
    j = text.index("expansion_1_K", i)
    k = text.index("\n", j)
    shutil.copy(DATA / "spindle_coarse.msh", tmp_path / "spindle_coarse.msh")
    (tmp_path / "truth.toml").write_text(text[:j] + "expansion_1_K = 11.5e-6" + text[k:],
                                         encoding="utf-8")
    sct, _ = load_diagnosis_scenario(tmp_path / "truth.toml")
    truth, _ = plant_of(sct)
    model, _ = reduced_model(plant, sc, DiagnosisSpec(), 8000.0)
    d = diagnose_geometry(model, _record(plant, [], seed, truth=truth))
    assert d.verdict == "not_explained", d.text
    assert d.established == ()
    assert "temperatures" in d.text or "regression" in d.text, d.text
    if d.evidence.named is not None:      # a best candidate: the regression beats its extended model
        assert d.beaten_by_regression and "regression on the thermometers" in d.text, d.text


@pytest.mark.parametrize("unit", [
    DATA / "spindle_coarse.toml",
    # the shipped P2 mesh: about 2 min of assembly and solves, too long for CI
    pytest.param(ROOT / "scenarios" / "data" / "spindle_unit.toml", marks=pytest.mark.slow),
], ids=["coarse", "shipped"])
def test_a_units_own_run_record_is_explained(tmp_path, unit):
    """`arfem run <unit>.toml` then `arfem diagnose` of its record.toml, end to end:
    "explained" below the instruments' resolution, no cause (on the shipped unit it had
    been "established: warm_start" for -2.7e-5 K). The coarse unit takes about 20 s,
    in CI. Guards the practical floor: with ``verdict.below_resolution`` reverted to
    never true in the engine, the coarse run's record comes out "not_explained"
    (checked 2026-11-28). No tolerance: the run's
    record is its model's own noise-free readings; the residual is the reduced model's
    error and the record's 10 significant digits, orders below the resolution."""
    run = tmp_path / "run"
    for args in (["run", str(unit), "--out", str(run)],
                 ["diagnose", str(run / "record.toml"), "--out", str(tmp_path / "diag"),
                  "--no-progress"]):
        r = subprocess.run([sys.executable, "-m", "arfem", *args], capture_output=True,
                           text=True, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "diag" / "diagnosis.json").read_text(encoding="utf-8"))
    assert s["verdict"] == "explained", s["verdict_text"]
    assert s["below_resolution"] and s["cause"] == "none"
