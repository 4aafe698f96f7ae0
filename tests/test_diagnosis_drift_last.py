"""The post hoc ``drift_last`` naming rule of the speed-only diagnosis
(``arfem diagnose --drift-last``; reports/fl_thermal/README.md, 1.3.1): a linear drift in
time (``sensor_drift``) is named only where no cause driven by the recorded inputs passes
its naming test. Checked on the naming step itself with fabricated validation scores (the
rule is a pure function of them), and that the CLI flag reaches the engine."""
import numpy as np
import pytest

from arfem.models.diagnosis.candidates import CandidateFit
from arfem.models.diagnosis.rules import select_by_validation
from arfem.scenarios.cli import main as cli


def _case(frame_blocks):
    """Fits and per-block validation RMSEs [µm]: the drift cuts the baseline's error most
    on every block (ratio 0.5), the frame by the given per-block errors (baseline 2 µm)."""
    t = np.arange(100) * 60.0
    res = np.random.default_rng(0).normal(0, 1, 60)
    fits = {c: CandidateFit(c, "ar", {}, np.zeros(t.size), 1, 1.0, 60, residual_um=res)
            for c in ("none", "sensor_drift", "frame_expansion")}
    folds = [(t < a, (t >= a) & (t < a + 1200)) for a in (1800.0, 3000.0, 4200.0)]
    per = {"none": [2.0, 2.0, 2.0], "sensor_drift": [1.0, 1.0, 1.0],
           "frame_expansion": list(frame_blocks)}
    cvs = {c: (float(np.sqrt(np.mean(np.square(v)))), v) for c, v in per.items()}
    return fits, cvs, folds, t


@pytest.mark.parametrize("robust", [False, True])
def test_drift_is_named_only_if_no_input_driven_cause_passes(robust):
    """Both naming tests (pooled cut + majority of blocks; median block ratio): the drift,
    best on validation, is named without the rule; with it, the frame that also passes
    (ratio 0.7 on every block) is named instead, the drift stays a candidate; and where
    the frame fails its test (worse than the baseline on every block) the drift is still
    named -- the rule reorders, it never removes a cause."""
    fits, cvs, folds, t = _case([1.4, 1.4, 1.4])
    assert select_by_validation(fits, cvs, folds, t, robust=robust)[0] == "sensor_drift"
    cause, runner, _, tests, info = select_by_validation(fits, cvs, folds, t, robust=robust,
                                               drift_last=True)
    assert cause == "frame_expansion"
    assert tests["sensor_drift"]["significant"] and tests["frame_expansion"]["significant"]
    assert "drift_rule" in info
    fits, cvs, folds, t = _case([2.5, 2.5, 2.5])
    assert select_by_validation(fits, cvs, folds, t, robust=robust, drift_last=True)[0] == "sensor_drift"


def test_drift_last_flag_reaches_the_engine(tmp_path, monkeypatch):
    """``arfem diagnose --drift-last`` passes drift_last=True to the engine (and the
    default passes False), ``--speed-engine`` its engine (default the speed branch): the
    engine is replaced by a recorder that stops the run."""
    from types import SimpleNamespace

    import arfem.scenarios.diagnosis.run as d
    seen = []

    class Stop(Exception):
        pass

    def fake(ds, hs, search, progress, drift_last=False, speed_engine="branch"):
        seen.append((search, drift_last, speed_engine))
        raise Stop
    monkeypatch.setattr(d, "load_dataset",
                        lambda path, limits=None: SimpleNamespace(input_kind="speed_rpm",
                                                                  source=path))
    monkeypatch.setattr(d, "diagnose", fake)
    (tmp_path / "x.toml").write_text("")
    for extra, want in (([], ("narrow", False, "branch")),
                        (["--frame-search", "average", "--drift-last"],
                         ("average", True, "branch")),
                        (["--speed-engine", "pipeline"], ("narrow", False, "pipeline"))):
        with pytest.raises(Stop):
            cli(["diagnose", str(tmp_path / "x.toml"), "--out", str(tmp_path / "o"),
                 "--no-progress", *extra])
        assert seen[-1] == want


def test_speed_only_options_on_a_heat_flux_record_are_reported_as_ignored(tmp_path,
                                                                          monkeypatch,
                                                                          capsys):
    """--drift-last and --frame-search act on speed_rpm records only; on a q_W_m2 record
    the command must say they were not used instead of ignoring them silently (an audit
    found the output identical with and without them), and say nothing without them
    (the diagnosis itself is replaced by a fixed summary: only the command's lines are
    under test)."""
    import arfem.scenarios.diagnosis.run as d
    summary = {"dataset": "x", "cause": "none", "causes": [], "input_kind": "q_W_m2",
               "warnings": [], "holdout": {"baseline_rmse_um": 1.0, "extended_rmse_um": 1.0,
                                           "gain_pct": 0.0, "start_s": 0.0,
                                           "how_chosen": "given"}}
    from types import SimpleNamespace

    from arfem.models.diagnosis.result import ChannelHoldout, Diagnosis, Holdout
    diag = Diagnosis("x", "rod_fem", "explained", "text", (), None, (), (), (),
                     Holdout(0.0, "given", 10, 0.0, None,
                             (ChannelHoldout("growth_um", "um", 1.0, 1.0, None),)),
                     (), (), False, False, {}, SimpleNamespace(document=summary))
    monkeypatch.setattr(d, "diagnose_and_write", lambda *a, **k: diag)
    monkeypatch.chdir(tmp_path)          # the command reads the record's TOML first
    (tmp_path / "x.toml").write_text("")
    for extra, note in (([], None), (["--drift-last"], "--drift-last apply"),
                        (["--frame-search", "wide", "--drift-last"],
                         "--frame-search and --drift-last apply")):
        assert cli(["diagnose", "x.toml", "--out", str(tmp_path / "o"), "--no-progress",
                    *extra]) == 0
        out = capsys.readouterr().out
        assert (note in out) if note else ("note:" not in out), out
