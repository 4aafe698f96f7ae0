"""Heat from the speed (issue 42 item 4): a source's power as a power law of the speed
or as a bearing's Palmgren friction power (:mod:`arfem.models.bearing`), and a record
of the speed alone driving every source.

Verified: the formula against a hand computation in its own units and at its branch
point; the scenario's source per phase equals the law at the phase's speed times its
``scale``; the diagnosis's reader and the compensator's replay of a record without
``P`` columns take the law's power at the recorded speed (not the linear interpolation
between the phases' pairs, which would differ between the tabulated speeds); every new
key range-checked in one line, exit 2.
"""
from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from arfem.models.bearing import (PalmgrenBearing, PowerLaw, friction_power_W,
                                  viscous_moment_Nmm)

from geometry_meshes import BOX_TOML, box_meshio, write_msh

BEARING = ('bearing = { f0 = 2.0, nu_mm2_s = 22.0, dm_mm = 90.0, f1 = 3.2e-4, '
           'P1_N = 1000.0, count = 2 }\nscale = 0.01')


def test_palmgren_moment_by_hand_and_at_its_branch():
    """M0 = 1e-7·f0·(νn)^(2/3)·dm³ [N·mm] with ν in mm²/s, n in rpm, dm in mm: at
    f0 = 1.5, ν = 10, n = 12 000, dm = 62.5: (1.2e5)^(2/3) = 2432.9, dm³ = 244 140.6,
    M0 = 89.1 N·mm; P = M·ω = 0.0891 N·m × 1256.6 rad/s = 112.0 W. At νn = 2000 the two
    branches meet within 1 % (160 against 2000^(2/3) = 158.7: Palmgren's constant)."""
    m0 = float(viscous_moment_Nmm(1.5, 10.0, 12000.0, 62.5))
    assert m0 == pytest.approx(1e-7 * 1.5 * 120000.0 ** (2 / 3) * 62.5 ** 3, rel=1e-12)
    assert m0 == pytest.approx(89.10, abs=0.01)
    assert float(friction_power_W(m0, 12000.0)) == pytest.approx(
        m0 * 1e-3 * 2 * math.pi * 200.0, rel=1e-12)
    lo = float(viscous_moment_Nmm(1.0, 1.0, 1999.999, 100.0))
    hi = float(viscous_moment_Nmm(1.0, 1.0, 2000.0, 100.0))
    assert abs(hi - lo) / lo < 0.01 and lo == pytest.approx(160e-7 * 1e6)
    b = PalmgrenBearing(1.5, 10.0, 62.5)
    assert float(b.power_W(0.0)) == 0.0 and float(b.power_W(-5.0)) == 0.0


def _scenario(tmp_path: Path, source: str, **kw) -> Path:
    write_msh(box_meshio(n=(6, 3, 3)), tmp_path / "box.msh")
    text = (BOX_TOML.replace('power_W = [50.0, 0.0]', source)
            .replace("{ duration_h = 1.0, speed_rpm = 1000.0 }, { duration_h = 1.0 }",
                     "{ duration_h = 1.0, speed_rpm = 4000.0 }, "
                     "{ duration_h = 1.0, speed_rpm = 12000.0 }, { duration_h = 1.0 }"))
    (tmp_path / "box.toml").write_text(text)
    return tmp_path / "box.toml"


def test_scenario_source_is_the_law_at_each_phase_speed(tmp_path):
    """The bearing source's values per phase are scale × the pair's power at 4000,
    12 000 and 0 rpm; a power law's likewise."""
    from arfem.scenarios.geometry.scenario import load_geometry_scenario
    sc = load_geometry_scenario(_scenario(tmp_path, BEARING))
    src = sc.sources[0]
    b = PalmgrenBearing(2.0, 22.0, 90.0, 3.2e-4, 1000.0, 2)
    np.testing.assert_allclose(src.values, 0.01 * b.power_W([4000.0, 12000.0, 0.0]),
                               rtol=1e-14)
    assert src.values[2] == 0.0 and 2.0 < src.values[0] < src.values[1] < 20.0
    sc = load_geometry_scenario(_scenario(tmp_path, "power_W = { a = 1.0, b = 0.003, m = 1.0 }"))
    np.testing.assert_allclose(sc.sources[0].values, [13.0, 37.0, 1.0])
    assert sc.sources[0].law == PowerLaw(1.0, 0.003, 1.0)


@pytest.mark.parametrize("source, says", [
    (BEARING.replace("dm_mm = 90.0", "dm_mm = 0.09"), "bearing.dm_mm: 0.09 is outside"),
    (BEARING.replace("f0 = 2.0, ", ""), "missing f0"),
    (BEARING.replace("nu_mm2_s = 22.0", "nu_mm2_s = 2.2e-5"), "bearing.nu_mm2_s"),
    (BEARING.replace("count = 2", "count = 2.5"), "bearing.count: must be a whole"),
    (BEARING.replace("f1 = 3.2e-4", "f1 = 0.3"), "bearing.f1: 0.3 is outside"),
    (BEARING.replace("P1_N", "P1_kN"), "bearing"),
    (BEARING + "\npower_W = 3.0", "gives both bearing and power_W"),
    ("power_W = { a = 0.0, b = 0.003, m = 9.0 }", "power_W.m: 9 is outside"),
    ("power_W = { a = -1.0 }", "power_W.a: -1 is outside"),
])
def test_bad_speed_power_data_is_one_line(tmp_path, source, says):
    toml = _scenario(tmp_path, source)
    r = subprocess.run([sys.executable, "-m", "arfem.scenarios.cli", "run", str(toml),
                        "--out", str(tmp_path / "o")], capture_output=True, text=True)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(err) == 1, r.stderr
    assert "box.toml" in err[0] and "heat_source[0]" in err[0] and says in err[0], err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("source, h_law, key", [
    ("power_W = { a = 1.0, b = 0.003 }", None, "heat_source[0].power_W"),
    ("power_W = 5.0", "h_W_m2K = { a = 10.0, b = 0.01 }", "convection[0].h_W_m2K"),
])
def test_a_speed_law_without_its_exponent_is_refused(tmp_path, source, h_law, key):
    """A speed term b·n^m without m: the exponent sets how the heat (or h) grows with
    the speed, so the reader refuses it in one line naming the file and the key rather
    than take m = 1 (a new user's audit found it taken silently); a law without a
    speed term (b absent or 0) needs no m."""
    toml = _scenario(tmp_path, source)
    if h_law is not None:
        toml.write_text(toml.read_text().replace("h_W_m2K = { a = 10.0, b = 0.01, m = 1.0 }",
                                                 h_law))
    r = subprocess.run([sys.executable, "-m", "arfem.scenarios.cli", "run", str(toml),
                        "--out", str(tmp_path / "o")], capture_output=True, text=True)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(err) == 1, r.stderr
    assert err[0].startswith(f"arfem: error: {toml}: {key}: b is given but not m"), err
    assert not (tmp_path / "o").exists()
    from arfem.scenarios.geometry.scenario import load_geometry_scenario
    toml = _scenario(tmp_path, "power_W = { a = 1.0, b = 0.0 }")
    assert load_geometry_scenario(toml).sources[0].law == PowerLaw(1.0, 0.0, 1.0)


@pytest.fixture(scope="module")
def speed_run(tmp_path_factory):
    """The box with a bearing source run once; its record rewritten without the P column
    and with speeds between the phases' (so that the law and the interpolation
    between the (speed, power) pairs differ)."""
    from arfem.scenarios.cli import main
    d = tmp_path_factory.mktemp("speed")
    toml = _scenario(d, BEARING)
    assert main(["run", str(toml), "--out", str(d / "run"), "--no-progress"]) == 0
    return d


def test_record_of_the_speed_alone_drives_the_source(speed_run):
    """A record with speed_rpm and no P_heater_W: the diagnosis's reader and the
    compensator's reader give the heater the law's power at each recorded speed (to
    1e-12), where the linear interpolation between the phases' pairs is off by more
    than 1 % at 8000 rpm; the replay of the run's own record without its P column
    equals the replay with it (same residual per axis to 1e-9 µm)."""
    from arfem.scenarios.records.axes_record import load_axes_record
    from arfem.scenarios.cli import main
    from arfem.scenarios.geometry.scenario import load_geometry_scenario, source_power_at_speed
    d = speed_run
    rows = list(csv.DictReader(open(d / "run" / "record.csv", newline="")))
    keep = [k for k in rows[0] if k != "P_heater_W"]
    with open(d / "run" / "nop.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    (d / "run" / "nop.toml").write_text('[dataset]\nname = "nop"\ncsv = "nop.csv"\n'
                                         '[model]\nscenario = "scenario.toml"\n')
    rec = load_axes_record(d / "run" / "nop.toml")
    speed = rec.speed_rpm
    sc = load_geometry_scenario(d / "run" / "scenario.toml")
    law = 0.01 * PalmgrenBearing(2.0, 22.0, 90.0, 3.2e-4, 1000.0, 2).power_W(speed)
    got = np.array([float(c) for c in rec.extra_columns["P_heater_W"]])
    np.testing.assert_allclose(got, law, rtol=1e-12)
    orig = np.array([float(r["P_heater_W"]) for r in rows])
    np.testing.assert_allclose(got[1:], orig[1:], rtol=1e-9)
    mid = source_power_at_speed(sc, sc.sources[0], np.array([8000.0]), "x")
    lin = 0.5 * (sc.sources[0].values[0] + sc.sources[0].values[1])
    assert abs(mid[0] - lin) > 0.01 * mid[0]
    for name, rec_toml in (("a", "record.toml"), ("b", "nop.toml")):
        assert main(["compensate", str(d / "run" / "model.json"), str(d / "run" / rec_toml),
                     "--out", str(d / name)]) == 0
    sa, sb = (json.loads((d / n / "summary.json").read_text("utf-8")) for n in "ab")
    for a, b in zip(sa["axes"], sb["axes"]):
        assert b["rms_after_um"] == pytest.approx(a["rms_after_um"], abs=1e-9)


def test_diagnosis_reader_takes_the_law(speed_run):
    """``load_mesh_record``'s power for a source without a column is the law's."""
    from arfem.scenarios.diagnosis.mesh import _speed_power
    from arfem.scenarios.geometry.scenario import load_geometry_scenario
    sc = load_geometry_scenario(speed_run / "run" / "scenario.toml")
    n = np.array([0.0, 3000.0, 8000.0, 15000.0])
    np.testing.assert_allclose(_speed_power(sc, sc.sources[0], n, "x"),
                               0.01 * PalmgrenBearing(2.0, 22.0, 90.0, 3.2e-4, 1000.0,
                                                      2).power_W(n), rtol=1e-14)
    assert tomllib.loads((speed_run / "run" / "scenario.toml").read_text())[
        "heat_source"][0]["bearing"]["count"] == 2
