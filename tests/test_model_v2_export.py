"""The exported state-space model (model.json version 2) against the FEM at every sensor,
and its replay per axis (issue 32 item 5).

A box of tetrahedra (324 cells, P1) heated by two sources with their own schedules,
cooled on one face, clamped on another, with three displacement sensors along x, y, z
at its tip and one thermometer (written in code: tests/geometry_meshes.py).

What is verified and why:

* with speed-independent h, the exported model stepped by the compensator reproduces
  the run's reduced-modal solve at every displacement sensor to 1e-9 of the sensor's
  range: the model is the exact zero-order-hold discretisation of the same modes (the
  inputs are constant over each 60 s interval), so only round-off separates them
  (measured 2e-14); a wrong B/C scaling, a lost static term or a shifted input row
  would show at 1e-2 or more;
* against an independent FEM, Crank–Nicolson at Δt = 15 s on the same mesh, within
  1e-3 of each sensor's range (measured 2.7e-4 Y, 6.2e-4 Z, 1.3e-5 X: CN's own Δt
  error after each step of the sources and the reduced space's 1e-5 stopping test);
* with h = a + b·n (speed-dependent) the model is scheduled over the speed:
  tests/test_model_speed_schedule.py (the model of before, linearised at the mean h,
  missed by 0.9 % Y, 2.2 % Z, 1.5 % X of the range on this box);
* ``arfem run`` writes model.json (version 2, schema-valid), record.toml/csv, and
  ``arfem compensate`` replays it per axis: without limits every axis's residual RMS
  is below 1 % of its RMS (the CSV's 10 digits and nothing else separate model and
  record); with ``--axis-limits`` each axis keeps its own clamp and step limit on every
  row, and an axis that binds says so in its own counts.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from geometry_meshes import BOX_TOML, box_meshio, write_msh

EXTRA = '''[[heat_source]]
name = "side"
group = "rest"
phases = [ { duration_h = 0.5, power_W = 20.0 }, { duration_h = 1.5, power_W = 0.0 } ]
[[sensor]]
name = "tip_y"
point = [0.3, 0.1, 0.1]
direction = "y"
[[sensor]]
name = "tip_z"
point = [0.3, 0.1, 0.15]
direction = "z"
[[sensor]]
name = "tip_x"'''


def box_scenario(d: Path, b: float = 0.0, solver: str = "reduced") -> Path:
    """The box with two sources and three axes; h = 10 + b·n [W/m²K]; ambient steps."""
    write_msh(box_meshio(n=(6, 3, 3)), d / "box.msh")
    text = (BOX_TOML.replace("b = 0.01", f"b = {b}")
            .replace('[[sensor]]\nname = "tip_x"', EXTRA)
            .replace("output_interval_s = 600.0",
                     f'output_interval_s = 60.0\nsolver = "{solver}"\ndt_s = 15.0')
            .replace("{ duration_h = 1.0, speed_rpm = 1000.0 }, { duration_h = 1.0 }",
                     "{ duration_h = 1.0, speed_rpm = 1000.0, ambient_C = 21.0 }, "
                     "{ duration_h = 1.0, ambient_C = 19.0 }"))
    assert text.count("[[sensor]]") == 4 and "ambient_C = 19.0" in text
    (d / "box.toml").write_text(text)
    return d / "box.toml"


def simulate(model, cols) -> np.ndarray:
    """The model stepped by the compensator on the record's inputs: (n, p) [µm]."""
    from arfem.models.compensator import Compensator
    comp = Compensator(model)
    t = cols["time_s"]
    out = np.zeros((t.size, len(model.outputs)))
    for k in range(1, t.size):
        cyc = comp.step({i.name: cols[i.name][k] for i in model.inputs})
        out[k] = [a.predicted_um for a in cyc.axes]
    return out


def solved(d: Path, b: float, solver: str = "reduced"):
    from arfem.scenarios.geometry.export import export_state_space, record_columns
    from arfem.scenarios.geometry.scenario import (build_geometry_model,
                                                   load_geometry_scenario, solve_geometry)
    gm = build_geometry_model(load_geometry_scenario(box_scenario(d, b, solver)))
    run = solve_geometry(gm)
    ex = export_state_space(gm)
    return run, ex, record_columns(run, ex.model)


def rel_errors(model, cols, ref=None) -> dict:
    sim = simulate(model, cols)
    out = {}
    for j, o in enumerate(model.outputs):
        y = cols[o.name] if ref is None else ref[o.name]
        out[o.axis] = float(np.max(np.abs(sim[1:, j] - y[1:])) / np.ptp(y))
    return out


def test_exported_model_is_the_reduced_solve_at_every_sensor(tmp_path):
    run, ex, cols = solved(tmp_path, 0.0)
    m = ex.model
    assert m.version == 2 and [o.axis for o in m.outputs] == ["Y", "Z", "X"]
    assert [i.name for i in m.inputs] == ["P_heater_W", "P_side_W", "ambient_C"]
    assert m.input_offsets == {"ambient_C": 20.0} and ex.h_W_m2K == (10.0,)
    err = rel_errors(m, cols)
    assert max(err.values()) < 1e-9, err
    assert np.ptp(cols["ambient_C"]) == 2.0          # the ambient input is exercised


def test_exported_model_against_crank_nicolson(tmp_path):
    """The model (from the reduced modes) against the θ-method at Δt = 15 s."""
    (tmp_path / "r").mkdir()
    (tmp_path / "c").mkdir()
    _, ex, cols = solved(tmp_path / "r", 0.0)
    cn, _, _ = solved(tmp_path / "c", 0.0, "crank-nicolson")
    err = rel_errors(ex.model, cols, cn.sensor_series())
    assert max(err.values()) < 1e-3, err


def test_run_writes_model_and_record_and_compensate_replays_each_axis(tmp_path, capsys):
    import jsonschema

    from arfem.scenarios.cli import main
    toml = box_scenario(tmp_path, 0.0)
    assert main(["run", str(toml), "--out", str(tmp_path / "run")]) == 0
    doc = json.loads((tmp_path / "run" / "model.json").read_text("utf-8"))
    schema = json.loads((Path(__file__).resolve().parents[1] / "docs" /
                         "model.schema.json").read_text("utf-8"))
    jsonschema.validate(doc, schema)
    assert doc["model_version"] == 2 and len(doc["C"]) == 3
    rec = tmp_path / "run" / "record.toml"
    # the record carries the thermometer as the run computed it (evidence for a diagnosis
    # against the mesh), and compensate below still replays it (extra columns ignored)
    with open(tmp_path / "run" / "record.csv", newline="") as f:
        rec_rows = list(csv.DictReader(f))
    with open(tmp_path / "run" / "sensors.csv", newline="") as f:
        sen_rows = list(csv.DictReader(f))
    assert len(rec_rows) == len(sen_rows) and "T_mid_C" in rec_rows[0]
    assert [float(r["T_mid_C"]) for r in rec_rows] == pytest.approx(
        [float(r["T_mid_C"]) for r in sen_rows], rel=1e-9, abs=1e-9)
    assert main(["compensate", str(tmp_path / "run" / "model.json"), str(rec), "--out",
                 str(tmp_path / "free")]) == 0
    s = json.loads((tmp_path / "free" / "summary.json").read_text("utf-8"))
    assert [a["axis"] for a in s["axes"]] == ["Y", "Z", "X"]
    for a in s["axes"]:
        assert a["rms_after_um"] < 0.01 * a["rms_before_um"], a
    assert main(["compensate", str(tmp_path / "run" / "model.json"), str(rec), "--out",
                 str(tmp_path / "lim"), "--axis-limits", "X=15:0.3",
                 "--axis-limits", "Y=2:0.2"]) == 0
    s = json.loads((tmp_path / "lim" / "summary.json").read_text("utf-8"))
    by = {a["axis"]: a for a in s["axes"]}
    assert by["X"]["cycles_clamped"] > 0 and by["X"]["cycles_rate_limited"] > 0
    assert by["Y"]["cycles_clamped"] > 0 and by["Z"]["cycles_clamped"] == 0
    with open(tmp_path / "lim" / "compensated.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    for ax, clamp, step in (("X", 15.0, 0.3), ("Y", 2.0, 0.2)):
        off = np.array([float(r[f"offset_{ax}_um"]) for r in rows])
        assert np.max(np.abs(off)) <= clamp + 1e-9
        assert np.max(np.abs(np.diff(off))) <= step + 1e-9
    assert (tmp_path / "lim" / "figure.png").stat().st_size > 10_000


def test_axis_limits_refusals(tmp_path, capsys):
    from arfem.scenarios.cli import main
    toml = box_scenario(tmp_path, 0.0)
    assert main(["run", str(toml), "--out", str(tmp_path / "run")]) == 0
    for bad in ("W=1:1", "X=1", "X=-1:1", "X=1:nan"):
        capsys.readouterr()
        rc = main(["compensate", str(tmp_path / "run" / "model.json"),
                   str(tmp_path / "run" / "record.toml"), "--out", str(tmp_path / "o"),
                   "--axis-limits", bad])
        err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
        assert rc == 2 and len(err) == 1 and "--axis-limits" in err[0], err
        assert not (tmp_path / "o").exists()


def test_axis_limits_refuses_an_axis_given_twice(tmp_path, capsys):
    """Two --axis-limits for one axis are refused (one line, exit 2, nothing written), not
    resolved silently by the last one winning: the limits guard the machine, so an
    ambiguous one is not guessed."""
    from arfem.scenarios.cli import main
    toml = box_scenario(tmp_path, 0.0)
    assert main(["run", str(toml), "--out", str(tmp_path / "run")]) == 0
    capsys.readouterr()
    rc = main(["compensate", str(tmp_path / "run" / "model.json"),
               str(tmp_path / "run" / "record.toml"), "--out", str(tmp_path / "o"),
               "--axis-limits", "X=20:0.5", "--axis-limits", "X=10:1"])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1 and "axis X is given more than once" in err[0], err
    assert not (tmp_path / "o").exists()


def test_a_record_without_an_axis_or_with_a_bad_cell_is_one_line(tmp_path, capsys):
    """The replay of a version-2 model refuses a record that lacks an output's column or
    holds a cell that is not a number in one, naming the column (and the CSV's line)."""
    from arfem.scenarios.cli import main
    toml = box_scenario(tmp_path, 0.0)
    assert main(["run", str(toml), "--out", str(tmp_path / "run")]) == 0
    text = (tmp_path / "run" / "record.csv").read_text().splitlines()
    header = text[0].split(",")
    j = header.index("d_tip_x_um")
    drop = [",".join(c for i, c in enumerate(ln.split(",")) if i != j) for ln in text]
    bad = text[:5] + [",".join("abc" if i == j else c for i, c in enumerate(
        text[5].split(",")))] + text[6:]
    for rows, words in ((drop, "d_tip_x_um"), (bad, "line 6")):
        (tmp_path / "run" / "record.csv").write_text("\n".join(rows) + "\n")
        capsys.readouterr()
        rc = main(["compensate", str(tmp_path / "run" / "model.json"),
                   str(tmp_path / "run" / "record.toml"), "--out", str(tmp_path / "o")])
        err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
        assert rc == 2 and len(err) == 1 and words in err[0], err
        assert not (tmp_path / "o").exists()
