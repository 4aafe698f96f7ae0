"""``arfem sweep`` on a mesh scenario (issue 32 item 6), on the small box of
``geometry_meshes`` (36 temperature unknowns: each point takes milliseconds).

Properties verified: the physics of an h sweep (more h on the cooled face, less growth
and lower temperatures), that a point computed with reused parts (assembly, factored
stiffness, modes, rebuilt K or T) equals a run of that scenario on its own, resume,
the in-process and worker-process paths giving the same table, and the bad keys
(one line naming the key and what exists, exit 2, nothing written).
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from arfem.scenarios.cli import main
from arfem.scenarios.geometry.scenario import (build_geometry_model, geometry_scenario_from_dict,
                                               solve_geometry)
from arfem.scenarios.sweep.runner import run_sweep
from arfem.scenarios.sweep.spec import load_sweep
from arfem.scenarios.sweep.geometry import (clear_geometry_cache, evaluate_geometry_point,
                                            geometry_override, sensor_metrics)
from arfem.io import read_toml
from geometry_meshes import BOX_TOML, box_meshio, write_msh


def _files(d: Path, grid: str) -> Path:
    write_msh(box_meshio(), d / "box.msh")
    (d / "box.toml").write_text(BOX_TOML, encoding="utf-8")
    (d / "sw.toml").write_text(f'[sweep]\nname = "box"\nbase = "box.toml"\n[sweep.grid]\n{grid}',
                               encoding="utf-8")
    return d / "sw.toml"


def _rows(out: Path) -> list:
    with open(out / "results.csv", newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _alone(d: Path, key: str, value) -> dict:
    """The metrics of the box with ``key`` = ``value``, built and solved on its own."""
    data = geometry_override(read_toml(d / "box.toml"), key, value)
    sc = geometry_scenario_from_dict(data, "alone", d)
    return sensor_metrics(solve_geometry(build_geometry_model(sc)))


def test_more_h_less_growth_and_cooler(tmp_path):
    """Raising h on the cooled face lowers the tip's peak growth and the mid-point's peak
    temperature at every step (strictly: 4x steps of h change both by far more than
    round-off), and every sensor has its peak, its time and its final value."""
    sw = _files(tmp_path, '"convection.right.h_W_m2K.a" = [2.0, 8.0, 32.0, 128.0]\n')
    assert main(["sweep", str(sw), "--out", str(tmp_path / "out"), "--no-progress",
                 "--workers", "1"]) == 0
    rows = sorted(_rows(tmp_path / "out"), key=lambda r: float(r["convection.right.h_W_m2K.a"]))
    d = [float(r["d_tip_x_peak_um"]) for r in rows]
    T = [float(r["T_mid_peak_C"]) for r in rows]
    assert all(a > b for a, b in zip(d, d[1:])), d
    assert all(a > b for a, b in zip(T, T[1:])), T
    assert d[-1] > 0 and T[-1] > 20.0
    for c in ("d_tip_x_peak_time_h", "d_tip_x_final_um", "T_mid_final_C"):
        assert all(r[c] != "" for r in rows)
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["kind"] == "geometry" and len(s["rows"]) == 4 and s["plots"] == ["sensor_peaks.png"]
    assert (tmp_path / "out" / "sensor_peaks.png").stat().st_size > 10_000
    assert "tip_x" in (tmp_path / "out" / "README.md").read_text()


@pytest.mark.parametrize("key, values", [
    ("convection.right.h_W_m2K.a", [5.0, 40.0]),                 # same model, new h
    ("heat_source.heater.scale", [1.0, 3.0]),                    # same modes
    ("material.body.expansion_1_K", [12e-6, 20e-6]),             # T and G rebuilt
    ("material.body.conductivity_W_mK", [50.0, 15.0]),           # K rebuilt
    ("material.body.poisson_ratio", [0.3, 0.1]),                 # built anew
])
def test_a_point_with_reused_parts_equals_its_scenario_run_alone(tmp_path, key, values):
    """The second point is computed from what the first left in the cache (the reuse
    each parameter names); its sensors equal a fresh build and solve of the same
    scenario to 1e-9 relative (the same operations on the same numbers; the margin is
    for summation order only)."""
    _files(tmp_path, "")
    clear_geometry_cache()
    base = read_toml(tmp_path / "box.toml")
    base["geometry"]["mesh"] = str(tmp_path / "box.msh")
    res = [evaluate_geometry_point(geometry_override(base, key, v), "p") for v in values]
    assert res[0]["metrics"]["reused"].startswith("nothing")
    assert not res[1]["metrics"]["reused"].startswith("nothing (first")
    alone = _alone(tmp_path, key, values[1])
    for c, v in alone.items():
        assert res[1]["metrics"][c] == pytest.approx(v, rel=1e-9, abs=1e-12), c
    if "poisson" in key:
        assert res[1]["metrics"]["reused"].startswith("nothing (Young")
    # and the change is real: the two points differ at the tip
    assert res[0]["metrics"]["d_tip_x_peak_um"] != pytest.approx(
        res[1]["metrics"]["d_tip_x_peak_um"], rel=1e-6)


def test_youngs_modulus_of_the_one_material_leaves_the_growth_alone(tmp_path):
    """Physics check of the rebuilt elasticity: in a body of one material the thermal
    load (3λ+2μ)α and the stiffness both scale with E, so halving E leaves every
    displacement as it was (to 1e-9 relative: the same field, another factorisation)."""
    _files(tmp_path, "")
    clear_geometry_cache()
    base = read_toml(tmp_path / "box.toml")
    base["geometry"]["mesh"] = str(tmp_path / "box.msh")
    a, b = (evaluate_geometry_point(geometry_override(base, "material.body.youngs_modulus_Pa",
                                                      E), "p")["metrics"]
            for E in (206e9, 103e9))
    assert b["reused"].startswith("nothing (Young")
    assert b["d_tip_x_peak_um"] == pytest.approx(a["d_tip_x_peak_um"], rel=1e-9)


def test_resume_computes_nothing_and_workers_give_the_same_table(tmp_path):
    """A second run into the same folder computes no point (the store is keyed by the
    resolved scenario); two worker processes give the same table bit for bit (floats
    written with repr), apart from the timing and reuse columns."""
    sw = _files(tmp_path, '"heat_source.heater.power_W" = [[20.0, 0.0], [60.0, 0.0]]\n'
                          '"fem.solver" = ["reduced", "crank-nicolson"]\n')
    sweep = load_sweep(sw)
    a = run_sweep(sweep, tmp_path / "a", workers=1, progress=False)
    assert a.n_computed == 4 and a.n_failed == 0
    again = run_sweep(sweep, tmp_path / "a", workers=1, progress=False)
    assert again.n_computed == 0 and again.n_stored_before == 4
    b = run_sweep(sweep, tmp_path / "b", workers=2, progress=False)
    assert b.n_computed == 4 and "worker" in b.executor
    skip = {"run_time_s", "reused"}
    ra, rb = _rows(tmp_path / "a"), _rows(tmp_path / "b")
    assert [{k: v for k, v in r.items() if k not in skip} for r in ra] == \
        [{k: v for k, v in r.items() if k not in skip} for r in rb]


def test_a_corrupt_stored_point_is_recomputed(tmp_path):
    """A stored point whose final value lies beyond its peak (impossible: the peak is
    the farthest value) is not trusted: the next run computes it again."""
    sw = _files(tmp_path, '"convection.right.h_W_m2K.a" = [5.0, 10.0]\n')
    sweep = load_sweep(sw)
    run_sweep(sweep, tmp_path / "o", workers=1, progress=False)
    p = tmp_path / "o" / "points" / f"{sweep.points[0].key}.json"
    rec = json.loads(p.read_text())
    rec["metrics"]["d_tip_x_final_um"] = 10 * rec["metrics"]["d_tip_x_peak_um"]
    p.write_text(json.dumps(rec))
    rep = run_sweep(sweep, tmp_path / "o", workers=1, progress=False, warn=lambda m: None)
    assert rep.n_computed == 1


@pytest.mark.parametrize("key, says", [
    ("convection.lefty.h_W_m2K", "(it has: right)"),
    ("material.steel.expansion_1_K", "(it has: body)"),
    ("heat_source.motor.power_W", "(it has: heater)"),
    ("foo.bar", "convection.<group>.h_W_m2K"),
    ("material.body.colour", "conductivity_W_mK"),
    ("heat_source.heater.flux_W_m2", "gives power_W"),
])
def test_a_bad_key_is_one_line_naming_it_exit_2_nothing_written(tmp_path, capsys, key, says):
    """An unknown key, group or field: one line naming the sweep file and the key and
    listing what the base has, exit 2, no output folder."""
    sw = _files(tmp_path, f'"{key}" = [1.0, 2.0]\n')
    assert main(["sweep", str(sw), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"sweep.grid.{key}" in err and says in err, err
    assert str(sw) in err and not (tmp_path / "out").exists()


def test_a_refused_value_names_its_index(tmp_path, capsys):
    """A value the scenario refuses (a negative h) names the key and its index."""
    sw = _files(tmp_path, '"convection.right.h_W_m2K" = [10.0, -1.0]\n')
    assert main(["sweep", str(sw), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "sweep.grid.convection.right.h_W_m2K[1]" in err and err.count("\n") == 1


@pytest.mark.xdist_group("tcp_ports")   # takes a TCP port: see conftest.py
def test_a_dask_cluster_gives_the_in_process_table(tmp_path):
    """The mesh sweep on a Dask cluster (one in-process worker: the same submit, gather
    and store path as a remote one) gives the in-process table, apart from timing and
    reuse."""
    from dask.distributed import LocalCluster
    sw = _files(tmp_path, '"material.body.expansion_1_K" = [10e-6, 14e-6]\n'
                          '"convection.right.ambient_C" = [18.0, 22.0]\n')
    sweep = load_sweep(sw)
    run_sweep(sweep, tmp_path / "local", workers=1, progress=False)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:
        rep = run_sweep(sweep, tmp_path / "dask", scheduler=cluster.scheduler_address,
                        progress=False)
    assert rep.n_computed == 4 and rep.executor.startswith("dask")
    skip = {"run_time_s", "reused"}
    ra, rb = _rows(tmp_path / "local"), _rows(tmp_path / "dask")
    assert [{k: v for k, v in r.items() if k not in skip} for r in ra] == \
        [{k: v for k, v in r.items() if k not in skip} for r in rb]


def test_on_workers_each_task_builds_its_model_once(tmp_path):
    """A 3-point sweep on 2 workers: two tasks of adjacent points, so one point reuses
    the model its worker built for the point before it (it used to be three builds:
    nothing reused); the table equals the in-process one apart from timing and reuse.
    Which process takes which task is the pool's choice: one process may run both
    tasks and reuse its model across them (seen under a second test process), so the
    builds are asserted at most one per task and at least one, not exactly two."""
    sw = _files(tmp_path, '"convection.right.h_W_m2K.a" = [5.0, 10.0, 20.0]\n')
    sweep = load_sweep(sw)
    run_sweep(sweep, tmp_path / "one", workers=1, progress=False)
    rep = run_sweep(sweep, tmp_path / "two", workers=2, progress=False)
    assert rep.n_computed == 3 and rep.n_failed == 0
    assert "2 tasks of adjacent points" in rep.executor, rep.executor
    reused = [r["reused"] for r in _rows(tmp_path / "two")]
    built = sum(r.startswith("nothing (first point") for r in reused)
    again = sum(r.startswith("mesh, heat and elasticity assembly") for r in reused)
    assert 1 <= built <= 2 and built + again == 3, reused
    skip = {"run_time_s", "reused"}
    assert [{k: v for k, v in r.items() if k not in skip} for r in _rows(tmp_path / "one")] \
        == [{k: v for k, v in r.items() if k not in skip} for r in _rows(tmp_path / "two")]


def test_by_default_the_rest_stays_where_the_model_is_when_workers_cost_more(
        tmp_path, monkeypatch):
    """The default path: the first point in this process, then the plan on its costs. A
    worker start-up that never pays (monkeypatched, so no timing decides) keeps every
    point here, each after the first reusing the model this process built."""
    from arfem.scenarios.sweep import executors, runner
    monkeypatch.setattr(executors, "WORKER_START_S", 1e9)
    monkeypatch.setattr(runner, "usable_cores", lambda: 2)
    clear_geometry_cache()
    sw = _files(tmp_path, '"heat_source.heater.scale" = [1.0, 2.0, 3.0]\n')
    rep = run_sweep(load_sweep(sw), tmp_path / "o", progress=False)
    assert rep.executor.startswith("local, in-process (the points share a model"), rep.executor
    reused = [r["reused"] for r in _rows(tmp_path / "o")]
    assert sum(r.startswith("nothing") for r in reused) == 1, reused
    assert sum("reduced modes" in r for r in reused) == 2
