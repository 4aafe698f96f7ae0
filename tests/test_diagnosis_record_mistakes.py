"""Contract version 2 of the diagnosis (docs/measured-data.md, "Version 2 additions"), and
what a user's records did wrong, each turned into a test: growth in mm, a [rod] value in
kW, a dead sensor, a hold-out of pure standstill, a constant h named as a two-parameter
cause, and empty growth cells at input switches."""
import json

import numpy as np
import pytest

from arfem.models.diagnosis.holdout import default_holdout as _default_holdout
from arfem.models.diagnosis.synth import generate
from arfem.scenarios.cli import main as cli
from arfem.scenarios.records.dataset import load_dataset
from arfem.scenarios.diagnosis.run import run_diagnosis
from arfem.scenarios.records.synth_files import write_case


def _diag(case, tmp_path, *extra):
    toml = write_case(case, tmp_path / "data")
    out = tmp_path / "out"
    rc = cli(["diagnose", str(toml), "--out", str(out), *extra])
    return rc, toml, out


def test_growth_in_mm_gives_a_units_warning_and_no_cause(tmp_path, capsys):
    """Growth written in mm (1000x too small) once read as heat_input_scale = 0.00078: the
    heat-input scale of the record is outside the plausible 0.2-5, so no cause is named,
    and one warning line (CLI and diagnosis.json) says growth_um may be in mm."""
    case = generate("heat_input_scale", 15, duration_h=24.0, growth_unit_factor=1e-3)
    rc, _, out = _diag(case, tmp_path)
    assert rc == 0
    got = json.loads((out / "diagnosis.json").read_text())
    assert got["cause"] == "none" and got["causes"] == [] and got["parameters"] == {}
    assert any("mm" in w for w in got["warnings"]), got["warnings"]
    printed = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("warning:")]
    assert any("growth_um" in ln and "mm" in ln for ln in printed)
    assert got["contract_version"] == 2


def test_rod_convection_in_kw_is_refused_in_one_line(tmp_path, capsys):
    """[rod] convection_W_m2K = 0.055 (kW/(m²K) by mistake) once gave a 0.0437 heat scale
    and a 188 µm hold-out RMSE without a word: it is outside the key's plausible range
    (1-2000 W/(m²K)), so the record is refused with one line naming the key, exit 2."""
    case = generate("none", 11, duration_h=24.0, declared_rod={"convection_W_m2K": 0.055})
    rc, _, out = _diag(case, tmp_path)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "rod.convection_W_m2K" in err[0] and "kW" in err[0]
    assert not out.exists()


def test_a_rod_value_the_rod_refuses_is_named_as_its_key(tmp_path, capsys):
    """A [rod] value that passes the reader's number check but not the rod's own
    (a negative radius) is named ``rod.radius_m`` as every other key is (a new user's
    audit: it read ``rod: radius_m``)."""
    toml = write_case(generate("none", 11, duration_h=3.0), tmp_path / "data")
    toml.write_text(toml.read_text().replace("radius_m = 0.1", "radius_m = -0.1"))
    rc = cli(["diagnose", str(toml), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith(f"arfem: error: {toml}: rod.radius_m: must be > 0"), err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", ["0.000", "12.500"])
def test_dead_growth_sensor_is_one_clear_line(tmp_path, capsys, value):
    """A constant or all-zero growth_um (a dead sensor) once raised a TypeError traceback
    after a minute of fitting: it is refused before any fit, one line, exit 2."""
    rows = ["time_s,growth_um,q_W_m2"] + [f"{30 * i},{value},{2000 if i % 200 < 100 else 0}"
                                          for i in range(600)]
    (tmp_path / "d.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "d.toml").write_text('[dataset]\nname = "d"\ncsv = "d.csv"\n')
    rc = cli(["diagnose", str(tmp_path / "d.toml"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "growth_um" in err[0] and "dead" in err[0]


def test_default_holdout_contains_a_change_of_input():
    """A 24 h cycle whose last third is standstill once gave "gain 0.8 %" on pure noise:
    the default hold-out must start at (just before) the last change of the input when
    the last third holds none, and keep >= 40 % of the record to fit."""
    t = np.arange(0, 24 * 3600 + 1, 60.0)
    q = np.where((t > 3600) & (t <= 11 * 3600), 2000.0, 0.0)
    hs, how = _default_holdout(t, q)
    assert 0.4 * t[-1] <= hs <= 11 * 3600 and "cooling" in how
    # a last third with a change is kept as it is
    q2 = np.where((t > 17 * 3600) & (t <= 20 * 3600), 2000.0, 0.0)
    hs2, how2 = _default_holdout(t, q2)
    assert hs2 == pytest.approx(16 * 3600) and "last third" in how2


def test_standstill_holdout_warns_not_informative(tmp_path):
    """With --holdout-start in a long standstill the hold-out is noise: the output warns
    that the gain there is not informative; without it the default moves to the last
    change (cooling) and the warning is gone."""
    phases = [(0.3, 0.0), (4.0, 2500.0), (2.0, 0.0), (4.7, 3000.0), (13.0, 0.0)]
    case = generate("convection_mismatch", 13, duration_h=24.0, phases=phases, h_W_m2K=80.0)
    toml = write_case(case, tmp_path / "data")
    given = run_diagnosis(toml, tmp_path / "o1", holdout_start_s=20 * 3600.0)
    assert any("not informative" in w for w in given["warnings"]), given["warnings"]
    default = run_diagnosis(toml, tmp_path / "o2")
    assert default["holdout"]["start_s"] <= 11.0 * 3600 and "cooling" in default["holdout"]["how_chosen"]
    assert not any("not informative" in w for w in default["warnings"])
    assert default["cause"] == "convection_mismatch" and default["holdout"]["gain_pct"] > 50


def test_constant_h70_is_convection_mismatch_with_interval(tmp_path):
    """End to end: a constant h = 70 with 30 empty growth cells (once flipped to
    nonlinear_convection, exponent -0.014) is convection_mismatch, one cause, and its 95 %
    interval holds 70 (v2 fields: causes, ci95, parameters_ci95)."""
    case = generate("convection_mismatch", 31, duration_h=24.0, h_W_m2K=70.0,
                    empty_fraction=30.5 / 1700)
    assert case.empty_rows.size >= 30
    out = tmp_path / "out"
    got = run_diagnosis(write_case(case, tmp_path / "data"), out)
    assert got["cause"] == "convection_mismatch" and len(got["causes"]) == 1, got["candidates"][:3]
    lo, hi = got["parameters_ci95"]["h_W_m2K"]
    assert lo < 70.0 < hi and hi - lo < 5.0
    assert got["causes"][0]["ci95"] == got["parameters_ci95"]


def test_empty_growth_keeps_its_input(tmp_path):
    """A row with an empty growth_um keeps its input (only the observation is dropped):
    the loader reports it in ``unobserved``, and on a clean record whose empty cells sit
    exactly where the input switches the diagnosis still finds nothing (dropping the
    inputs would hold the next row's flux over those intervals and misfit)."""
    case = generate("none", 5, duration_h=24.0, n_outliers=0)
    toml = write_case(case, tmp_path / "data")
    csv = toml.with_suffix(".csv")
    lines = csv.read_text().splitlines()
    sw = np.flatnonzero(np.diff(case.q_W_m2) != 0) + 1
    for i in sw:                               # empty the growth cell of every switch row
        f = lines[i + 1].split(",")
        f[1] = ""
        lines[i + 1] = ",".join(f)
    csv.write_text("\n".join(lines) + "\n")
    ds = load_dataset(toml)
    assert ds.unobserved["time_s"].size >= sw.size
    assert set(case.time_s[sw]) <= set(ds.unobserved["time_s"].tolist())
    got = run_diagnosis(toml, tmp_path / "out")
    assert got["cause"] == "none" and got["causes"] == [], got["candidates"][:3]


def test_named_cause_warnings_say_what_a_reader_must_not_miss():
    """Three facts about a named cause go to ``warnings`` (an audit found each silent on
    the real record or a generated one): its effect's interval holds 0; the extended
    model is worse on the hold-out; it still leaves > MISFIT_FACTOR noise σ. A cause
    whose effect is established, that gains, and fits to noise gets none of them."""
    from arfem.models.diagnosis.engine import MISFIT_FACTOR, _named_cause_warnings

    def summary(gain, rmse):
        return {"holdout": {"gain_pct": gain}, "extended": {"rmse_um": rmse}}
    good = [{"cause": "frame_expansion", "ci95": {"frame_time_constant_h": [3.0, 9.0],
                                                   "frame_gain": [0.4, 0.6]}}]
    assert _named_cause_warnings(summary(40.0, 1.0), good, 0.5) == []
    bad = [{"cause": "frame_expansion", "ci95": {"frame_time_constant_h": [0.1, 200.0],
                                                  "frame_gain": [-44.0, 47.0]}}]
    w = _named_cause_warnings(summary(-5.0, 2.6), bad, 2.6 / (MISFIT_FACTOR + 1))
    assert len(w) == 3
    assert "frame_gain" in w[0] and "holds 0" in w[0]
    assert "worse than the baseline" in w[1] and "leaves 11 noise σ" in w[2]
    assert _named_cause_warnings(summary(-5.0, 50.0), [], 0.1) == []   # no cause: none
