"""``arfem compensate`` checks a contract-v3 record as ``arfem diagnose`` does, and its
report says what the record's zero and its other channels mean (issue 41, a new user's
audit of compensate with a v3 record); and there is one replay, not two.

A box of tetrahedra (tests/geometry_meshes.py) with one displacement sensor (X), a
thermometer and a tilt, heated by a source whose power follows the cycle's speed, h
depending on the speed (so model.json reads the speed), is run once; its record is
rewritten with one fault each.

What is verified and why:

* a column naming no sensor of the scenario (``tilt_tiltC_urad``, ``d_tiltA_um``) is
  refused by compensate in one line, exit 2, nothing written -- and the line is the one
  diagnose gives for the same record, word for word (one check, shared:
  :func:`arfem.scenarios.records.georecord.sensor_columns`);
* a record in mm labelled µm (the displacement divided by 1000) is refused in one line
  by diagnose's units rule (:func:`arfem.scenarios.records.georecord.refuse_unit_slip`),
  where it was replayed with exit 0;
* without the speed (and without the power it gives), the line says the model reads
  ``speed_rpm`` and that the scenario gives the power from it, instead of listing the
  power as needed too;
* a record whose probes were zeroed at the first row, and one with a tilt column: the
  summary (json and md) says that the residual is counted from the first row and which
  channels are not compensated;
* one replay: ``scenarios/compensation`` holds one replay module and one summary and
  series type, and only the replay and the live loop build a Compensator.
"""
from __future__ import annotations

import ast
import csv
import json
from pathlib import Path

import pytest

from geometry_meshes import BOX_TOML, box_meshio, write_msh

REPO = Path(__file__).resolve().parents[1]

TILT = '''[[sensor]]
name = "tiltA"
quantity = "tilt"
points = [[0.2, 0.1, 0.1], [0.3, 0.1, 0.1]]
direction = "z"
[fem]'''


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    from arfem.scenarios.cli import main
    d = tmp_path_factory.mktemp("checks")
    write_msh(box_meshio(n=(6, 3, 3)), d / "box.msh")
    (d / "box.toml").write_text(
        BOX_TOML.replace("output_interval_s = 600.0",
                         'output_interval_s = 60.0\nsolver = "reduced"\ndt_s = 15.0')
        .replace("[fem]", TILT))
    assert main(["run", str(d / "box.toml"), "--out", str(d / "run"), "--no-progress"]) == 0
    return d


def record(d: Path, name: str, drop=(), change=None, add=None, zero=None) -> Path:
    """The run's record as a v3 record ``name``/r.toml without ``growth_um`` and
    ``drop``, a column changed (``change``: {column: f(value)}) or added (``add``:
    {column: source column}); ``zero``: its ``displacement_zero``."""
    with open(d / "run" / "record.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    keep = [k for k in rows[0] if k not in ("growth_um", *drop)]
    out = d / name
    out.mkdir()
    with open(out / "r.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(keep + list(add or {}))
        for r in rows:
            vals = [str((change or {}).get(k, float)(float(r[k]))) for k in keep]
            w.writerow(vals + [r[src] for src in (add or {}).values()])
    (out / "r.toml").write_text(
        f'[dataset]\nname = "{name}"\ncsv = "r.csv"\n'
        + (f'displacement_zero = "{zero}"\n' if zero else "")
        + '[model]\nscenario = "../run/scenario.toml"\n')
    return out / "r.toml"


def _refused(capsys, argv, out: Path) -> str:
    from arfem.scenarios.cli import main
    capsys.readouterr()
    rc = main(argv)
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1, err
    assert not out.exists()
    return err[0]


@pytest.mark.parametrize("column, source, words", [
    ("tilt_tiltC_urad", "tilt_tiltA_urad", "names no tilt sensor"),
    ("d_tiltA_um", "d_tip_x_um", "names no displacement sensor")])
def test_a_column_naming_no_sensor_is_refused_as_diagnose_refuses_it(box, capsys, column,
                                                                      source, words):
    rec = record(box, f"no_{column}", add={column: source})
    model = box / "run" / "model.json"
    comp = _refused(capsys, ["compensate", str(model), str(rec), "--out",
                             str(box / f"c_{column}")], box / f"c_{column}")
    assert words in comp and f"column {column}" in comp, comp
    diag = _refused(capsys, ["diagnose", str(rec), "--out", str(box / f"d_{column}"),
                             "--no-progress"], box / f"d_{column}")
    assert comp == diag


def test_a_record_in_mm_labelled_um_is_refused(box, capsys):
    rec = record(box, "mm", change={"d_tip_x_um": lambda v: v / 1000.0})
    line = _refused(capsys, ["compensate", str(box / "run" / "model.json"), str(rec),
                             "--out", str(box / "c_mm")], box / "c_mm")
    assert "column d_tip_x_um" in line and "displacements in mm declared as µm?" in line


def test_without_the_speed_the_line_asks_for_the_speed_alone(box, capsys):
    """The model reads P_heater_W, ambient_C and speed_rpm; the record has neither the
    speed nor the power, which the scenario gives from the speed: only the speed is
    asked for."""
    assert [i["name"] for i in json.loads((box / "run" / "model.json").read_text())[
        "inputs"]] == ["P_heater_W", "ambient_C", "speed_rpm"]
    rec = record(box, "nospeed", drop=("speed_rpm", "P_heater_W"))
    line = _refused(capsys, ["compensate", str(box / "run" / "model.json"), str(rec),
                             "--out", str(box / "c_nospeed")], box / "c_nospeed")
    assert "the model reads speed_rpm, which this record does not have" in line, line
    assert "its scenario gives P_heater_W too" in line, line


def test_the_report_says_the_records_zero_and_what_is_not_compensated(box, capsys):
    from arfem.scenarios.cli import main
    rec = record(box, "zeroed", zero="first_row")
    out = box / "c_zeroed"
    assert main(["compensate", str(box / "run" / "model.json"), str(rec), "--out",
                 str(out)]) == 0
    s = json.loads((out / "summary.json").read_text("utf-8"))
    assert s["displacement_zero"] == "first_row"
    assert s["not_compensated"] == ["tilt_tiltA_urad"]
    md = (out / "summary.md").read_text("utf-8")
    assert 'displacement_zero = "first_row"' in md and "counted from the first row" in md
    assert "Not compensated" in md and "`tilt_tiltA_urad`" in md
    plain = box / "c_plain"
    assert main(["compensate", str(box / "run" / "model.json"),
                 str(box / "run" / "record.toml"), "--out", str(plain)]) == 0
    s = json.loads((plain / "summary.json").read_text("utf-8"))
    assert s["displacement_zero"] == "reference"
    assert "first row" not in (plain / "summary.md").read_text("utf-8")


def _defs(folder: Path, kind) -> dict:
    """{name: module} of every top-level ``kind`` (ast.ClassDef, ast.FunctionDef)."""
    out = {}
    for p in sorted(folder.rglob("*.py")):
        for node in ast.parse(p.read_text("utf-8")).body:
            if isinstance(node, kind):
                out[node.name] = p.relative_to(REPO).as_posix()
    return out


def test_there_is_one_replay():
    """One replay module, one summary and one series type (per axis inside them), one
    writer; a second replay beside it (a module, a *Summary or *Series type, or a
    Compensator built elsewhere than the replay and the live loop) fails here."""
    comp = REPO / "scenarios" / "compensation"
    assert sorted(p.name for p in comp.glob("*.py")) == [
        "__init__.py", "model_file.py", "replay.py", "report.py"]
    classes = _defs(REPO / "scenarios", ast.ClassDef)
    assert sorted(c for c in classes if c.endswith(("Summary", "Series", "Replay"))) == [
        "AxisSeries", "AxisSummary", "ObserverSummary", "Replay", "ReplaySeries",
        "ReplaySummary"]
    funcs = _defs(comp, ast.FunctionDef)
    assert sorted(f for f in funcs if f.startswith("replay") or "replay" in f) == [
        "replay", "replay_figure", "replay_markdown", "replay_terminal_line",
        "write_replay"]
    builders = set()
    for p in sorted((REPO / "scenarios").rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text("utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "Compensator":
                builders.add(p.relative_to(REPO).as_posix())
    assert builders == {"scenarios/compensation/replay.py", "scenarios/live/config.py"}
