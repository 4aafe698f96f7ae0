"""The ISO 230-3 worked example (issue 42 item 5): the shipped scenario, its record and
the report of the standard's figures.

Verified, and why:

* the scenario holds the standard's five quantities (X, Y, Z, and the tilts A about +X
  and B about +Y by their ``about`` vectors) and its heat in volumes from the speed;
* the shipped record is the scenario's: the scenario solved with P1 elements on the
  same mesh reproduces each quantity's largest drift within 3 % (P1 against the
  record's P2: the gallery's 0.5 % on Z, 2.5 % on A when written), and the replay
  of the record's speed alone through the sources' laws is checked in
  tests/test_bearing_heat.py;
* the report's figures are the record's own (the largest |drift|, its time, the range,
  the value at the stop), recomputed here from the CSV;
* a record with nothing to report is one line, exit 2, nothing written.
"""
from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
ISO = ROOT / "scenarios" / "data" / "iso230_3"


def _csv(path: Path) -> dict:
    rows = list(csv.DictReader(open(path, newline="")))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_scenario_holds_the_five_quantities_and_volume_heat_from_the_speed():
    from arfem.models.bearing import PalmgrenBearing, PowerLaw
    from arfem.scenarios.geometry.scenario import load_geometry_scenario
    sc = load_geometry_scenario(ISO / "iso230_3_spindle_unit.toml")
    q = {s.name: s for s in sc.sensors}
    assert [q[n].direction for n in "XYZ"] == [(1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0)]
    np.testing.assert_allclose(q["A"].about, [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(q["B"].about, [0.0, 1.0, 0.0], atol=1e-15)
    assert q["A"].base_m == pytest.approx(0.06)
    laws = {s.spec.name: (s.spec.group, type(s.law)) for s in sc.sources}
    assert laws == {"front_bearing": ("front_bearing", PalmgrenBearing),
                    "rear_bearing": ("rear_bearing", PalmgrenBearing),
                    "motor": ("stator", PowerLaw)}
    assert list(sc.cycle.speed_rpm) == [8000.0, 0.0]


def test_shipped_record_is_the_scenarios_test():
    from arfem.models.thermal_test import thermal_test
    from arfem.scenarios.records.georecord import read_record_files
    from arfem.scenarios.geometry.scenario import (build_geometry_model,
                                                   load_geometry_scenario, solve_geometry)
    files = read_record_files(ISO / "record.toml")
    assert files.displacement_zero == "first_row"
    rec = _csv(ISO / "record.csv")
    assert not any(k.startswith("P_") for k in rec)        # the speed drives the sources
    sc = load_geometry_scenario(ISO / "iso230_3_spindle_unit.toml")
    sc = type(sc)(**{**sc.__dict__, "order": 1, "picture": False, "fields": False})
    run = solve_geometry(build_geometry_model(sc))
    sim = thermal_test(run.result.times_s, run.sensor_series())
    shipped = thermal_test(rec["time_s"], rec)
    assert [q.name for q in shipped.quantities] == ["X", "Y", "Z", "A", "B"]
    for a, b in zip(sim.quantities, shipped.quantities):
        if b.name in "XB":                 # ~0 by the unit's symmetry: absolute, not relative
            assert abs(a.max_abs - b.max_abs) < 0.1, (a, b)
        else:
            assert a.max_abs == pytest.approx(b.max_abs, rel=0.03), (a, b)


def test_report_figures_are_the_records(tmp_path):
    from arfem.scenarios.geometry.thermal_test import main
    assert main([str(ISO / "record.toml"), "--out", str(tmp_path / "r")]) == 0
    js = json.loads((tmp_path / "r" / "thermal_test.json").read_text("utf-8"))
    rec = _csv(ISO / "record.csv")
    stop = int(np.flatnonzero(rec["speed_rpm"] > 0)[-1])
    assert js["stop_h"] == pytest.approx(4.0)
    for q in js["quantities"]:
        d = rec[q["column"]] - rec[q["column"]][0]
        k = int(np.argmax(np.abs(d)))
        assert q["max_abs"] == d[k] and q["max_abs_time_h"] == rec["time_s"][k] / 3600
        assert q["range"] == pytest.approx(np.ptp(d)) and q["at_stop"] == d[stop]
    md = (tmp_path / "r" / "thermal_test.md").read_text("utf-8")
    assert "| Z [µm] |" in md and "| A [µrad] |" in md
    assert (tmp_path / "r" / "thermal_test.png").stat().st_size > 20_000


def test_record_without_quantities_is_one_line(tmp_path):
    (tmp_path / "r.csv").write_text("time_s,speed_rpm,T_housing_C\n0,0,20\n60,0,20\n")
    (tmp_path / "r.toml").write_text('[dataset]\ncsv = "r.csv"\n[model]\nscenario = '
                                     f'"{(ISO / "iso230_3_spindle_unit.toml").as_posix()}"\n')
    r = subprocess.run([sys.executable, "-m", "arfem.scenarios.geometry.thermal_test",
                        str(tmp_path / "r.toml"), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(err) == 1, r.stderr
    assert "r.csv" in err[0] and "no displacement" in err[0]
    assert not (tmp_path / "o").exists()


def _cut_record(tmp_path: Path, n_rows: int) -> Path:
    """The shipped record cut to its first ``n_rows`` readings, beside its scenario."""
    lines = (ISO / "record.csv").read_text("utf-8").splitlines()[:n_rows + 1]
    (tmp_path / "record.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    toml = (ISO / "record.toml").read_text("utf-8").replace(
        'scenario = "iso230_3_spindle_unit.toml"',
        f'scenario = "{(ISO / "iso230_3_spindle_unit.toml").as_posix()}"')
    (tmp_path / "record.toml").write_text(toml, encoding="utf-8")
    return tmp_path / "record.toml"


def test_a_test_cut_while_the_spindle_runs_has_no_stop(tmp_path):
    """A record that ends while the spindle still runs (every row at 8000 rpm) has no
    stop: the report said 'the spindle stopped at 3.30 h', the last reading's time, and
    gave an 'at the stop' column equal to the end's."""
    from arfem.scenarios.geometry.thermal_test import main
    rec = _cut_record(tmp_path, 199)                  # 0 ... 3.30 h, all at 8000 rpm
    assert main([str(rec), "--out", str(tmp_path / "r")]) == 0
    js = json.loads((tmp_path / "r" / "thermal_test.json").read_text("utf-8"))
    assert js["stop_h"] is None
    assert all(q["at_stop"] is None for q in js["quantities"])
    md = (tmp_path / "r" / "thermal_test.md").read_text("utf-8")
    assert "stopped at" not in md and "still runs at the end" in md
    assert "| Z [µm] | -17.46 | 3.30 | 17.46 | — | -17.46 |" in md


def test_report_names_its_record_and_writes_a_page(tmp_path):
    """The report says which record it comes from and how its probes were zeroed, by a
    link relative to the folder (a committed report names no machine's folders), and
    writes report.html with that record as its input and its title once (it was written
    only by a separate ``arfem report``, titled by the folder's name, 'No input file is
    recorded')."""
    from arfem.scenarios.geometry.thermal_test import main
    out = tmp_path / "deep" / "r"
    assert main([str(ISO / "record.toml"), "--out", str(out)]) == 0
    js = json.loads((out / "thermal_test.json").read_text("utf-8"))
    assert js["displacement_zero"] == "first_row"
    assert not Path(js["record_toml"]).is_absolute()
    assert (out / js["record_toml"]).resolve() == (ISO / "record.toml").resolve()
    md = (out / "thermal_test.md").read_text("utf-8")
    assert f"]({js['record_toml']})" in md and 'displacement_zero = "first_row"' in md
    page = (out / "report.html").read_text("utf-8")
    assert page.count("Thermal test of iso230_3_spindle_unit (ISO 230-3)") == 2  # <title>, <h1>
    assert "No input file is recorded" not in page
    assert 'href="' + js["record_toml"] + '"' in page
    manifest = json.loads((out / ".arfem-outputs.json").read_text("utf-8"))
    assert "report.html" in manifest["files"]         # arfem's: a --force rerun replaces it
    assert main([str(ISO / "record.toml"), "--out", str(out), "--force"]) == 0


def test_the_gallery_example_runs_the_commands_not_the_internals():
    """docs/examples/plot_08_thermal_test.py shows what a user does (the scenario file,
    arfem run, the report command, the files they write): it imported the scenario
    reader, the solver and the report's figure function from arfem.scenarios.*, and
    copied the scenario dataclass through its __dict__."""
    import ast
    src = (ROOT / "docs" / "examples" / "plot_08_thermal_test.py").read_text("utf-8")
    mods = set()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.ImportFrom):
            mods.add(node.module)
        elif isinstance(node, ast.Import):
            mods.update(a.name for a in node.names)
    arfem_mods = {m for m in mods if m and m.startswith("arfem")}
    assert arfem_mods <= {"arfem", "arfem.models.bearing"}, arfem_mods
    assert "__dict__" not in src
    assert '"arfem", "run"' in src and '"arfem.scenarios.geometry.thermal_test"' in src


def test_the_check_gate_fails_this_test_as_the_page_says(tmp_path, capsys):
    """docs/thermal-test.md says that arfem check fails the ISO scenario (Z beyond the
    15 % gate, A's tilt missed by most of its peak, X and Y within): the short test's
    drift is mostly the fast share one time constant per input cannot follow. Held with
    P1 elements on the same mesh (P2 in the file: 20.2 % on Z; P1 19.3 %, both > 15 %)."""
    import re
    from arfem.scenarios.cli import main
    text = (ISO / "iso230_3_spindle_unit.toml").read_text("utf-8")
    (tmp_path / "iso.toml").write_text(
        text.replace('mesh = "../spindle_unit.msh"',
                     f'mesh = "{(ISO.parent / "spindle_unit.msh").as_posix()}"')
        .replace("order = 2", "order = 1").replace("picture = true", "picture = false"),
        encoding="utf-8")
    assert main(["check", str(tmp_path / "iso.toml")]) == 1
    out = capsys.readouterr().out
    pct = {m[0]: float(m[1]) for m in
           re.findall(r"(?:FAILED )?([XYZAB]): max\|slowest-mode AR - FEM\| = [^=]+= ([\d.]+) %",
                      out)}
    assert pct["Z"] > 15.0 and pct["Y"] < 15.0 and pct["X"] < 15.0, pct
    assert pct["A"] > 50.0, pct
    assert "FAILED Z" in out and "tilts (reported, not gated" in out
