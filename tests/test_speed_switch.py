"""How a user selects the engine that diagnoses a ``speed_rpm`` record: ``arfem diagnose
--speed-engine {branch,pipeline}`` and ``diagnose(..., speed_engine=...)`` (no environment
variable: a setting outside the command line must not change a result).

* the default is the rod engine's speed branch (what every published figure ran), and
  diagnosis.json (``selection.speed_engine``) and report.md say which engine ran;
* ``--speed-engine pipeline`` (the one pipeline on the speed plant, a prototype) names
  synth_speed's ``sensor_drift`` of seed 1 in the contract's name with a 95 % interval
  holding the truth (the interval is the tolerance), ranks its candidates by the
  pipeline's BIC on N_eff, and its --stability reruns run on the same engine;
* what does not apply is refused in one line, exit 2, nothing written: an unknown engine,
  the branch's --frame-search / --drift-last with the pipeline, ``branch`` on a record
  that is always on the pipeline (q_W_m2, mesh); in Python a ValueError.

Synthetic records only: the real FL_THERMAL record must not meet the pipeline before the
pre-registered comparison (reports/fl_thermal/PREREGISTRATION.md, last section).
"""
from __future__ import annotations

import inspect
import json

import numpy as np
import pytest

import arfem
from arfem.models.diagnosis.engine import BRANCH_ONLY, diagnose
from arfem.models.diagnosis.synth_speed import generate_speed
from arfem.params import InputError
from arfem.scenarios.cli import main
from arfem.scenarios.diagnosis import run as run_mod
from arfem.scenarios.diagnosis.run import speed_options
from arfem.scenarios.records.dataset import load_dataset


def _columns(case) -> dict:
    return {"time_s": case.time_s, "speed_rpm": case.speed_rpm,
            "growth_um": case.growth_um, **case.temperatures}


def _write(tmp_path, case) -> str:
    cols = _columns(case)
    rows = np.column_stack(list(cols.values()))
    np.savetxt(tmp_path / "rec.csv", rows, delimiter=",", fmt="%.6f",
               header=",".join(cols), comments="")
    (tmp_path / "rec.toml").write_text('[dataset]\nname = "rec"\ncsv = "rec.csv"\n')
    return str(tmp_path / "rec.toml")


def _refused(capsys, argv, out, *words):
    """``arfem`` with ``argv``: exit 2, one ``arfem: error:`` line holding ``words``,
    nothing in ``out`` (argparse's own refusals end by SystemExit)."""
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("arfem: error: "), err
    assert all(w in err[0] for w in words), err
    assert not out.exists() or not any(out.iterdir())
    return err[0]


def test_the_default_speed_engine_is_the_published_branch():
    """Every door defaults to the old branch (a published figure cannot move): the
    engine's keyword, arfem.diagnose's keyword and the command (not given = branch)."""
    assert inspect.signature(diagnose).parameters["speed_engine"].default == "branch"
    assert inspect.signature(arfem.diagnose).parameters["speed_engine"].default == "branch"
    assert speed_options("speed_rpm") == ("branch", "narrow")


def test_arfem_diagnose_records_the_branch_it_ran_by_default(tmp_path):
    """Without --speed-engine a speed record runs the branch, and both outputs say so."""
    case = generate_speed("sensor_drift", 1, step_s=600.0)     # 180 rows: a short run
    out = tmp_path / "out"
    assert main(["diagnose", _write(tmp_path, case), "--out", str(out),
                 "--no-progress"]) == 0
    j = json.loads((out / "diagnosis.json").read_text())
    assert j["selection"]["speed_engine"] == "branch"
    assert "validation_blocks_s" in j["selection"]          # the branch's own selection
    assert "Speed engine: `branch`" in (out / "report.md").read_text()


def test_arfem_diagnose_on_the_pipeline_names_the_drift_with_its_interval(tmp_path,
                                                                          monkeypatch):
    """--speed-engine pipeline: the drift named with an interval holding the truth, the
    engine written in both outputs, and the --stability reruns on the pipeline too (the
    reruns are served the first result: only the engine they ask for is under test)."""
    case = generate_speed("sensor_drift", 1)
    truth = case.truth["drift_um_per_h"]
    asked, first, real = [], [], run_mod.diagnose

    def recorder(*a, **k):
        asked.append(k)
        if not first:
            first.append(real(*a, **k))
        return first[0]
    monkeypatch.setattr(run_mod, "diagnose", recorder)
    out = tmp_path / "out"
    rc = main(["diagnose", _write(tmp_path, case), "--out", str(out), "--no-progress",
               "--holdout-start", str(case.holdout_start_s), "--speed-engine", "pipeline",
               "--stability", "2"])
    assert rc == 0
    assert len(asked) >= 2 and {c["speed_engine"] for c in asked} == {"pipeline"}
    assert all(c.get("intervals", True) for c in asked)   # the pipeline cannot skip them
    j = json.loads((out / "diagnosis.json").read_text())
    assert j["selection"]["speed_engine"] == "pipeline"
    assert j["baseline"]["model"] == "ar_speed_plant"
    assert j["selection"]["rule"].startswith("the one pipeline")
    assert [c["cause"] for c in j["causes"]] == ["sensor_drift"]
    lo, hi = j["causes"][0]["ci95"]["drift_um_per_h"]
    assert lo <= truth <= hi, (lo, truth, hi)
    assert j["verdict"] == "established"
    assert all(c["score_kind"] == "bic_on_n_eff" for c in j["candidates"])
    report = (out / "report.md").read_text()
    assert "BIC score" in report and "Speed engine: `pipeline`" in report


def test_an_unknown_speed_engine_is_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    path = _write(tmp_path, generate_speed("sensor_drift", 1))
    for bad in ("fast", "plant"):                  # "plant": the prototype's old name
        _refused(capsys, ["diagnose", path, "--out", str(out), "--no-progress",
                          "--speed-engine", bad], out, "--speed-engine", bad)


def test_an_engine_name_has_one_range_check(monkeypatch):
    """The engine's check is the one rule: the command's choices are its tuple,
    speed_options refuses what the engine refuses (relocated at --speed-engine, the
    engine's own wording) and accepts what it accepts -- a name the engine is made to
    know passes speed_options too, which a second list in run.py would refuse."""
    from arfem.models.diagnosis import engine
    from arfem.scenarios.cli import build_parser
    sub = build_parser("diagnose")._subparsers._group_actions[0].choices["diagnose"]
    (action,) = [a for a in sub._actions if "--speed-engine" in a.option_strings]
    assert action.choices is engine.SPEED_ENGINES
    with pytest.raises(InputError) as refused:
        speed_options("speed_rpm", "fast")
    with pytest.raises(InputError) as own:
        engine.check_speed_engine("fast")
    assert refused.value.where == "--speed-engine" and own.value.where == "speed_engine"
    assert refused.value.message == own.value.message == "'fast' is not 'branch' or 'pipeline'"
    monkeypatch.setattr(engine, "SPEED_ENGINES", (*engine.SPEED_ENGINES, "fast"))
    assert speed_options("speed_rpm", "fast") == ("fast", "narrow")


@pytest.mark.parametrize("extra,flag", [(["--frame-search", "narrow"], "--frame-search"),
                                        (["--frame-search", "wide"], "--frame-search"),
                                        (["--drift-last"], "--drift-last")])
def test_branch_options_with_the_pipeline_are_refused(tmp_path, capsys, extra, flag):
    """Given explicitly (even the branch's default ``narrow``) with the pipeline: one line
    saying why, before any work."""
    out = tmp_path / "out"
    path = _write(tmp_path, generate_speed("sensor_drift", 1))
    line = _refused(capsys, ["diagnose", path, "--out", str(out), "--no-progress",
                             "--speed-engine", "pipeline", *extra], out, flag,
                    "--speed-engine pipeline")
    assert BRANCH_ONLY[flag[2:].replace("-", "_")] in line


def test_branch_on_a_heat_flux_record_is_refused(tmp_path, capsys):
    """A q_W_m2 record is always on the pipeline: an explicit ``branch`` would be a
    choice the command cannot honour, so it is refused (named with the record), not
    ignored; ``pipeline`` there is what runs anyway."""
    from arfem.models.diagnosis.synth import generate
    from arfem.scenarios.records.synth_files import write_case
    toml = write_case(generate("convection_mismatch", 1), tmp_path / "d")
    out = tmp_path / "out"
    _refused(capsys, ["diagnose", str(toml), "--out", str(out), "--no-progress",
                      "--speed-engine", "branch"], out, "--speed-engine branch",
             "q_W_m2 record")
    assert speed_options("q_W_m2", "pipeline") == ("pipeline", "narrow")
    with pytest.raises(InputError, match="mesh record"):
        speed_options("mesh", "branch")


@pytest.mark.parametrize("kw", [{"intervals": False}, {"on_fit": lambda *a: None},
                                {"drift_last": True}, {"frame_search": "average"}])
def test_python_branch_options_with_the_pipeline_raise(tmp_path, kw):
    """engine.diagnose: a branch-only keyword with speed_engine="pipeline" is a
    ValueError naming it and why (it would otherwise be silently ignored)."""
    ds = load_dataset(_write(tmp_path, generate_speed("sensor_drift", 1)))
    (key,) = kw
    with pytest.raises(ValueError, match=f"^{key}: applies to speed_engine='branch' only"):
        diagnose(ds, speed_engine="pipeline", **kw)
    with pytest.raises(ValueError, match="'plant' is not 'branch' or 'pipeline'"):
        diagnose(ds, speed_engine="plant")


def test_arfem_diagnose_passes_its_engine_and_refuses_what_does_not_apply(tmp_path):
    """The public API: a bad engine and the frame search with the pipeline are
    ValueErrors; the pipeline runs on a DataFrame-like dict of samples and says so."""
    case = generate_speed("sensor_drift", 1)
    cols = _columns(case)
    with pytest.raises(ValueError, match="speed_engine"):
        arfem.diagnose(cols, speed_engine="fast")
    with pytest.raises(ValueError, match="^frame_search: applies to speed_engine='branch'"):
        arfem.diagnose(cols, speed_engine="pipeline", frame_search="wide")
    d = arfem.diagnose(cols, speed_engine="pipeline", holdout_start_s=case.holdout_start_s)
    assert d.summary["selection"]["speed_engine"] == "pipeline"
    assert [c.cause for c in d.causes] == ["sensor_drift"]
