"""PROTOTYPE (branch speedswitch): a ``speed_rpm`` record diagnosed by the one pipeline on
the speed plant (``ARFEM_SPEED_ENGINE=plant`` / ``diagnose(..., speed_engine="plant")``).

* the default is still the rod engine's speed branch (nothing published moves);
* ``arfem diagnose`` with the variable set writes diagnosis.json and report.md for
  synth_speed's ``sensor_drift`` record of seed 1, names ``sensor_drift`` in the
  contract's name with a 95 % interval holding the truth (the interval is the
  tolerance), and ranks its candidates by the pipeline's BIC on N_eff;
* an unknown value of the variable is one line, exit 2, nothing written.
"""
from __future__ import annotations

import inspect
import json

import numpy as np

from arfem.models.diagnosis.engine import diagnose
from arfem.models.diagnosis.synth_speed import generate_speed
from arfem.scenarios.cli import main


def _write(tmp_path, case) -> str:
    cols = {"time_s": case.time_s, "speed_rpm": case.speed_rpm,
            "growth_um": case.growth_um, **case.temperatures}
    rows = np.column_stack(list(cols.values()))
    np.savetxt(tmp_path / "rec.csv", rows, delimiter=",", fmt="%.6f",
               header=",".join(cols), comments="")
    (tmp_path / "rec.toml").write_text('[dataset]\nname = "rec"\ncsv = "rec.csv"\n')
    return str(tmp_path / "rec.toml")


def test_the_default_speed_engine_is_the_published_branch():
    """The keyword's default selects the old branch: a published figure cannot move."""
    assert inspect.signature(diagnose).parameters["speed_engine"].default == "branch"


def test_arfem_diagnose_on_the_plant_names_the_drift_with_its_interval(tmp_path,
                                                                       monkeypatch):
    case = generate_speed("sensor_drift", 1)
    truth = case.truth["drift_um_per_h"]
    monkeypatch.setenv("ARFEM_SPEED_ENGINE", "plant")
    out = tmp_path / "out"
    rc = main(["diagnose", _write(tmp_path, case), "--out", str(out), "--no-progress",
               "--holdout-start", str(case.holdout_start_s)])
    assert rc == 0
    j = json.loads((out / "diagnosis.json").read_text())
    assert j["baseline"]["model"] == "ar_speed_plant"
    assert j["selection"]["rule"].startswith("the one pipeline")
    assert [c["cause"] for c in j["causes"]] == ["sensor_drift"]
    lo, hi = j["causes"][0]["ci95"]["drift_um_per_h"]
    assert lo <= truth <= hi, (lo, truth, hi)
    assert j["verdict"] == "established"
    assert all(c["score_kind"] == "bic_on_n_eff" for c in j["candidates"])
    assert "BIC score" in (out / "report.md").read_text()


def test_an_unknown_speed_engine_is_one_line_and_writes_nothing(tmp_path, monkeypatch,
                                                                capsys):
    case = generate_speed("sensor_drift", 1)
    monkeypatch.setenv("ARFEM_SPEED_ENGINE", "fast")
    out = tmp_path / "out"
    rc = main(["diagnose", _write(tmp_path, case), "--out", str(out), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "ARFEM_SPEED_ENGINE" in err[0], err
    assert not out.exists() or not any(out.iterdir())
