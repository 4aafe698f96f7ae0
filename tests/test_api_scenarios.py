"""One Python API for the rod and a mesh (issue 41 item 5): ``arfem.load_scenario``,
``solve``, ``run``, ``compare``, ``check`` and ``sweep`` take the paper's rod and a
user's mesh alike and give one result type each.

What is verified and why:
* each function on a rod scenario (a coarse one: Δτ = 60 s, a 2 × 8 mesh) and on a
  small box mesh (tests/geometry_meshes.py, P1, 2 h; a displacement, a thermometer and
  a tilt) returns the one result type, with ``kind`` saying which (the box's tilt found
  that a mesh sweep over a scenario with a tilt ended in a KeyError: its stored points
  were checked, and its README written, under the displacement's ``d_`` names);
* the numbers are the CLI's: the same scenario through ``arfem run``, ``arfem check
  --json`` and ``arfem sweep`` (in process, :func:`arfem.scenarios.cli.main`) writes the
  arrays and figures the API returns (``timeseries.csv``, ``sensors.csv``, the check's
  JSON entry, ``results.csv``). Tolerances: the run's CSVs hold 10 significant digits
  (``%.10g``), so 1e-9 relative (the rounding, and the rod's API solve taking the modal
  solve directly where the run scales one solve by q: the growth is linear in q); the
  JSON documents and ``results.csv`` hold ``repr`` floats: equal to the last bit;
* bad input is :class:`arfem.InputError` whose message is the CLI's one line (file and
  key), for the rod and the mesh, before anything is computed.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import arfem
from arfem.scenarios.cli import main

from geometry_meshes import BOX_TOML, box_meshio, write_msh

ROD_TOML = """
[scenario]
name = "small_rod"
[cycle]
phases = [ { duration_h = 2.0, q_W_m2 = 2000.0 }, { duration_h = 2.0, q_W_m2 = 0.0 } ]
[ar]
dtau_s = 60.0
[fem.mesh]
nr = 2
nz = 8
[outputs]
fields = false
picture = false
"""


#: A tilt on the box's free face, from two x probes 0.1 m apart along y [µrad].
TILT = """
[[sensor]]
name = "yaw"
quantity = "tilt"
points = [[0.3, 0.05, 0.1], [0.3, 0.15, 0.1]]
direction = "x"
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict:
    """The rod's and the box's scenario files, and a sweep over each."""
    d = tmp_path_factory.mktemp("api")
    write_msh(box_meshio(), d / "box.msh")
    (d / "box.toml").write_text(BOX_TOML + TILT, encoding="utf-8")
    (d / "rod.toml").write_text(ROD_TOML, encoding="utf-8")
    (d / "sweep_box.toml").write_text('[sweep]\nname = "box_h"\nbase = "box.toml"\n'
                                      '[sweep.grid]\n"convection.right.h_W_m2K" = [5.0, 20.0]\n',
                                      encoding="utf-8")
    (d / "sweep_rod.toml").write_text('[sweep]\nname = "rod_h"\nbase = "rod.toml"\n'
                                      '[sweep.grid]\nh_W_m2K = [35.0, 55.0]\n', encoding="utf-8")
    return {k: d / f"{k}.toml" for k in ("box", "rod", "sweep_box", "sweep_rod")}


@pytest.fixture(scope="module")
def cli_runs(files, tmp_path_factory) -> dict:
    """``arfem run`` of both scenarios and ``arfem check --json`` of both: the files the
    API's results are held to."""
    d = tmp_path_factory.mktemp("cli")
    for k in ("box", "rod"):
        assert main(["run", str(files[k]), "--out", str(d / k), "--no-progress"]) == 0
        assert main(["check", str(files[k]), "--json", str(d / f"{k}.json")]) in (0, 1)
    return {k: d / k for k in ("box", "rod")} | {
        f"{k}_check": json.loads((d / f"{k}.json").read_text("utf-8"))["scenarios"][0]
        for k in ("box", "rod")}


# -- load_scenario ---------------------------------------------------------------------------

def test_load_scenario_reads_the_rod_and_a_mesh_with_their_kind(files):
    rod, box = arfem.load_scenario(files["rod"]), arfem.load_scenario(files["box"])
    assert (rod.kind, rod.name, rod.dtau_s) == ("rod", "small_rod", 60.0)
    assert (box.kind, box.name, box.source) == ("mesh", "box", str(files["box"]))
    assert [s.name for s in box.scenario.sensors] == ["tip_x", "mid", "yaw"]
    assert box.max_abs_diff_pct_of_peak is None          # the file has no [check]


def test_load_scenario_knows_the_shipped_ones_by_name():
    fig2, unit = arfem.load_scenario("paper_fig2"), arfem.load_scenario("spindle_unit")
    assert fig2.kind == "rod" and fig2.q_levels == [2000.0]
    assert unit.kind == "mesh" and unit.scenario.order == 2
    assert unit.scenario.mesh_path == arfem.shipped_scenario("spindle_unit").with_suffix(".msh")
    assert arfem.load_scenario("spindle_unit", order=1).scenario.order == 1
    assert arfem.load_scenario("paper_fig2", order=1).fem.order == 1


def test_order_is_validated_as_the_files_value(files):
    with pytest.raises(arfem.InputError, match=r"box\.toml: geometry\.order"):
        arfem.load_scenario(files["box"], order=3)
    with pytest.raises(arfem.InputError, match=r"rod\.toml: fem\.order: must be 1 or 2"):
        arfem.load_scenario(files["rod"], order=3)


def test_an_unknown_shipped_name_lists_the_shipped_ones():
    with pytest.raises(arfem.InputError) as exc:
        arfem.shipped_scenario("spindle_unti")
    assert str(exc.value).startswith("spindle_unti: no such shipped scenario")
    assert "paper_fig2" in str(exc.value) and "spindle_unit" in str(exc.value)
    with pytest.raises(arfem.InputError, match="is no file here, nor a shipped scenario"):
        arfem.load_scenario("spindle_unti")


@pytest.mark.parametrize("kind, old, new, key", [
    ("rod", "nz = 8", "nz = 8\nnq = 3", "fem.mesh"),
    ("rod", "dtau_s = 60.0", "dtau_s = -60.0", "ar.dtau_s"),
    ("box", "conductivity_W_mK = 50.0", "conductivity_W_m = 50.0", "material"),
    ("box", 'direction = "x"', 'direction = "w"', "sensor"),
])
def test_bad_input_is_the_clis_one_line(files, tmp_path, capsys, kind, old, new, key):
    """The API's InputError is the line ``arfem check`` prints (after ``arfem: error:``):
    the file, the key and what is wrong."""
    bad = tmp_path / f"bad_{kind}.toml"
    text = files[kind].read_text("utf-8")
    assert old in text
    bad.write_text(text.replace(old, new).replace('"box.msh"', json.dumps(
        str(files["box"].with_suffix(".msh")))), encoding="utf-8")
    with pytest.raises(arfem.InputError) as exc:
        arfem.load_scenario(bad)
    msg = str(exc.value)
    assert msg.startswith(f"{bad}: {key}") and "\n" not in msg
    assert main(["check", str(bad)]) == 2
    assert capsys.readouterr().err.strip() == f"arfem: error: {msg}"
    for fn in (arfem.solve, arfem.compare, arfem.check):      # the same, before any work
        with pytest.raises(arfem.InputError, match=key):
            fn(bad)


def test_a_scenario_argument_of_another_type_is_refused():
    with pytest.raises(arfem.InputError, match="scenario: must be a scenario from"):
        arfem.solve(42)
    with pytest.raises(arfem.InputError, match="scenario: give the scenario's file"):
        arfem.run(arfem.load_scenario("paper_fig2"), "out")


# -- solve and run ---------------------------------------------------------------------------

def test_solve_a_mesh_gives_sensors_csv(files, cli_runs):
    """Every channel of solve() is the column arfem run wrote, to its 10 digits (the same
    build and solve; the API leaves out the fields, which only files hold)."""
    r = arfem.solve(arfem.load_scenario(files["box"]))
    csv = pd.read_csv(cli_runs["box"] / "sensors.csv")
    df = r.to_dataframe()
    assert (r.kind, r.scenario, r.model, r.solver) == ("mesh", "box", "mesh", "reduced")
    assert list(df.columns) == ["time_s", "d_tip_x_um", "T_mid_C", "tilt_yaw_urad"]
    assert [c.quantity for c in r.channels] == ["displacement", "temperature", "tilt"]
    assert [c.unit for c in r.channels] == ["µm", "°C", "µrad"]
    assert set(r.displacement_um) == {"tip_x"} and set(r.temperature_C) == {"mid"}
    assert set(r.tilt_urad) == {"yaw"} and r.heat_J is None
    assert np.abs(r.tilt_urad["yaw"]).max() > 0.0
    for col in df.columns:
        np.testing.assert_allclose(df[col].to_numpy(), csv[col].to_numpy(), rtol=1e-9)
    assert r.displacement_um["tip_x"].max() > 1.0        # the heater moves the tip [µm]
    doc = json.loads(r.to_json())
    assert [c["column"] for c in doc["channels"]] == ["d_tip_x_um", "T_mid_C",
                                                      "tilt_yaw_urad"]
    assert doc["channels"][0]["values"] == df["d_tip_x_um"].tolist()
    with pytest.raises(AttributeError, match="tip_x"):
        r.growth_um


def test_a_mesh_scenario_object_is_taken_as_loaded(files):
    """A validated GeometryScenario (the library's) solves as its file does."""
    case = arfem.load_scenario(files["box"])
    a, b = arfem.solve(case.scenario), arfem.solve(files["box"])
    np.testing.assert_array_equal(a.temperature_C["mid"], b.temperature_C["mid"])


def test_solve_the_rod_gives_timeseries_csv(files, cli_runs):
    r = arfem.solve(files["rod"])
    ts = pd.read_csv(cli_runs["rod"] / "timeseries.csv")
    assert (r.kind, r.scenario, r.model, r.solver) == ("rod", "small_rod", "axisymmetric",
                                                       "modal")
    np.testing.assert_array_equal(r.times_s, ts["time_s"].to_numpy())
    np.testing.assert_allclose(r.growth_um, ts["fem_growth_um"].to_numpy(), rtol=1e-9,
                               atol=1e-12)
    assert list(r.to_dataframe().columns) == ["time_s", "growth_um", "heat_J"]
    assert r.displacement_um["growth"] is r.growth_um and r.heat_J[-1] > 0


def test_run_writes_what_arfem_run_writes_and_returns_it(files, cli_runs, tmp_path):
    """arfem.run: the same files as the command (by name), and the result is what they
    hold."""
    for k, table in (("box", "sensors.csv"), ("rod", "timeseries.csv")):
        out = tmp_path / k
        r = arfem.run(files[k], out)
        assert sorted(p.name for p in out.iterdir()) == sorted(
            p.name for p in cli_runs[k].iterdir())
        csv = pd.read_csv(out / table)
        got, want = ((r.displacement_um["tip_x"], csv["d_tip_x_um"]) if k == "box" else
                     (r.growth_um, csv["fem_growth_um"]))
        np.testing.assert_allclose(got, want.to_numpy(), rtol=1e-9)
    with pytest.raises(arfem.InputError, match="mine: is not empty"):
        (tmp_path / "mine").mkdir()
        (tmp_path / "mine" / "notes.txt").write_text("mine")
        arfem.run(files["rod"], tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "mine"


# -- compare and check -----------------------------------------------------------------------

def test_compare_the_rod_gives_timeseries_csv_columns(files, cli_runs):
    c = arfem.compare(files["rod"])
    ts = pd.read_csv(cli_runs["rod"] / "timeseries.csv")
    df = c.to_dataframe()
    assert c.kind == "rod" and list(c.fem_um) == ["growth"]
    for col in ("fem_growth_um", "ar_growth_um", "ar_corrected_growth_um"):
        np.testing.assert_allclose(df[col].to_numpy(), ts[col].to_numpy(), rtol=1e-9)
    summary = json.loads((cli_runs["rod"] / "summary.json").read_text("utf-8"))
    assert json.loads(c.to_json())["max_abs_diff_um"] == summary["max_abs_diff_um"]


def test_compare_a_mesh_measures_what_check_gates(files, cli_runs):
    """compare() on the box: the FEM and both AR(1)s per displacement sensor; its
    corrected (slowest-mode) error in % of the largest drift is the value arfem check
    gates, its paper (lumped) error the one check reports in its notes."""
    c = arfem.compare(files["box"])
    assert c.kind == "mesh" and list(c.fem_um) == ["tip_x"]   # no thermometer, no tilt
    assert list(c.to_dataframe().columns) == ["time_s", "fem_tip_x_um", "ar_tip_x_um",
                                              "ar_corrected_tip_x_um"]
    case = arfem.load_scenario(files["box"])             # the check's Δτ: no [check]
    assert c.times_s[1] == c.metrics["dtau_s"] == case.scenario.output_interval_s  # dtau_s
    m = c.metrics["sensors"]["tip_x"]
    gated = cli_runs["box_check"]["criteria"][0]
    assert gated["name"] == "max_abs_diff_pct_of_peak[tip_x]"
    assert m["corrected_max_abs_diff_pct_of_peak"] == pytest.approx(gated["value"], rel=1e-12)
    assert f"tip_x {m['max_abs_diff_um']:.3g} µm" in cli_runs["box_check"]["notes"][0]
    fem = c.fem_um["tip_x"]
    assert m["fem_peak_um"] == pytest.approx(np.abs(fem).max(), rel=1e-12)
    assert np.abs(c.ar_corrected_um["tip_x"] - fem).max() == pytest.approx(
        m["corrected_max_abs_diff_um"], rel=1e-12)
    lo, hi = c.metrics["corrected_C1"]
    assert 0.0 < lo <= hi < 1.0


@pytest.mark.parametrize("kind", ["rod", "box"])
def test_check_is_arfem_check_json(files, cli_runs, kind):
    """check(): the entry arfem check --json writes for the same file (wall time aside)."""
    r = arfem.check(arfem.load_scenario(files[kind]))
    assert r.kind == ("rod" if kind == "rod" else "mesh")
    assert json.loads(r.to_json()) == cli_runs[f"{kind}_check"]
    df = r.to_dataframe()
    assert list(df["name"]) == [c.name for c in r.criteria]
    assert list(df["passed"]) == [c.passed for c in r.criteria] and r.passed == all(df["passed"])


def test_check_limits_and_model_are_validated(files):
    with pytest.raises(arfem.InputError, match="model: must be one of"):
        arfem.check(files["box"], model="lumped")
    r = arfem.check(files["box"], model="paper", max_abs_pct=1e-3, max_c1_diff=1e-3)
    assert r.model == "lumped" and not r.passed
    assert r.notes[-1] == "--max-c1-diff applies to rod scenarios only"


# -- sweep -----------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["rod", "box"])
def test_sweep_of_the_rod_and_a_mesh_gives_results_csv(files, tmp_path, kind):
    rep = arfem.sweep(files[f"sweep_{kind}"], tmp_path / "out", workers=1)
    assert rep.kind == ("rod" if kind == "rod" else "mesh")
    assert (rep.n_points, rep.n_computed, rep.n_failed, rep.failures) == (2, 2, 0, ())
    csv = pd.read_csv(tmp_path / "out" / "results.csv")
    df = rep.to_dataframe()
    assert list(df.columns) == list(csv.columns) and len(df) == 2
    num = [c for c in csv.columns if pd.api.types.is_float_dtype(csv[c])
           and c != "run_time_s"]
    assert num
    np.testing.assert_array_equal(df[num].to_numpy(float), csv[num].to_numpy(float))
    again = arfem.sweep(files[f"sweep_{kind}"], tmp_path / "out", workers=1)
    assert (again.n_stored_before, again.n_computed) == (2, 0) and again.rows == rep.rows
    assert json.loads(rep.to_json())["rows"][0]["point_key"] == rep.rows[0]["point_key"]


def test_the_spindle_gallery_example_uses_the_public_api_only():
    """docs/examples/plot_07_spindle_unit.py runs the shipped unit through arfem.run and
    arfem.shipped_scenario: no subprocess, no module under arfem imported (it used
    ``python -m arfem run`` and ``arfem.scenarios.__file__``: no public function ran a
    mesh scenario)."""
    import ast
    src = (Path(__file__).resolve().parents[1] / "docs" / "examples"
           / "plot_07_spindle_unit.py").read_text("utf-8")
    tree = ast.parse(src)
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert "arfem" in imported and "subprocess" not in imported
    assert not [m for m in imported if m and m.startswith("arfem.")]
    used = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)
            and isinstance(n.value, ast.Name) and n.value.id == "arfem"}
    assert {"run", "shipped_scenario"} <= used and used <= set(arfem.__all__)
