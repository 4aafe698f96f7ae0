"""``arfem sweep``: grid expansion, the tidy table, bad input, resume after kill -9, Dask.

Sweeps here run on a coarse axisymmetric mesh (Q1, 2 x 6 elements) or the default
one with large Δτ so that the whole file stays well under a minute on 2 cores.
"""
from __future__ import annotations

import csv
import hashlib
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from arfem.params import InputError
from arfem.scenarios.cli import main
from arfem.scenarios.rod.scenario import scenario_from_dict
from arfem.scenarios.rod.evaluation import evaluate
from arfem.scenarios.sweep import (PointStore, TIMING_COLUMNS, biot_threshold, load_sweep,
                             point_key, run_sweep)

REPO = Path(__file__).resolve().parents[1]

PAPER_PHASES = """\
[cycle]
phases = [
  { duration_h = 4.0,  q_W_m2 = 2000.0 },
  { duration_h = 1.5,  q_W_m2 = 0.0 },
  { duration_h = 4.0,  q_W_m2 = 2000.0 },
  { duration_h = 14.5, q_W_m2 = 0.0 },
]
"""


def write_base(d: Path, mesh: str = "order = 1\n[fem.mesh]\nnr = 2\nnz = 6\n") -> Path:
    p = d / "base.toml"
    p.write_text('[scenario]\nname = "coarse"\n' + PAPER_PHASES +
                 "[ar]\ndtau_s = 600.0\n[fem]\nmodel = \"axisymmetric\"\n" + mesh)
    return p


def write_sweep(d: Path, grid: str, name: str = "small", base: str = "base.toml") -> Path:
    p = d / f"{name}.toml"
    p.write_text(f'[sweep]\nname = "{name}"\nbase = "{base}"\n[sweep.grid]\n{grid}')
    return p


SMALL_GRID = "dtau_s = [300, 600]\nh_W_m2K = [20, 55, 150]\nq_W_m2 = [2000, 3000]\n"


def cli(*argv) -> int:
    return main(["sweep", *map(str, argv), "--no-progress"])


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def snapshot(d: Path) -> dict:
    """Every file under ``d`` (relative path -> sha256 of its bytes)."""
    return {str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(d.rglob("*")) if p.is_file() and p.name != ".lock"}


@pytest.fixture(scope="module")
def small_store(tmp_path_factory):
    """A finished 12-point coarse sweep, computed in-process (workers=1)."""
    d = tmp_path_factory.mktemp("small")
    write_base(d)
    sw = write_sweep(d, SMALL_GRID)
    out = d / "out"
    assert cli(sw, "--out", out, "--workers", 1) == 0
    return sw, out


def test_shipped_sweep_is_valid_and_large_enough():
    """scenarios/data/sweep_dtau_h.toml loads (so every Δτ divides all phases of the paper's
    cycle, which load_sweep checks per point) and spans the promised grid: >= 6 Δτ from
    10 to 600 s, >= 8 h from 5 to 400 W/(m²K), q in {2000, 3000}, >= 96 points."""
    sweep = load_sweep(REPO / "scenarios" / "data" / "sweep_dtau_h.toml")
    g = sweep.grid
    assert len(g["dtau_s"]) >= 6 and (min(g["dtau_s"]), max(g["dtau_s"])) == (10, 600)
    assert len(g["h_W_m2K"]) >= 8 and (min(g["h_W_m2K"]), max(g["h_W_m2K"])) == (5, 400)
    assert sorted(g["q_W_m2"]) == [2000, 3000]
    assert len(sweep.points) >= 96 and len({p.key for p in sweep.points}) == len(sweep.points)
    for d in g["dtau_s"]:
        assert all(ph % d == 0 for ph in (14400, 5400, 52200)), d


def test_point_key_is_canonical():
    """The store key depends on the resolved inputs only: not on key order or 30 vs 30.0
    (so a resumed sweep finds its points), but on every value (so nothing is mixed up)."""
    a = {"rod": {"convection_W_m2K": 55, "radius_m": 0.1}, "ar": {"dtau_s": 30}}
    b = {"ar": {"dtau_s": 30.0}, "rod": {"radius_m": 0.1, "convection_W_m2K": 55.0}}
    c = {"ar": {"dtau_s": 30.0}, "rod": {"radius_m": 0.1, "convection_W_m2K": 55.000001}}
    assert point_key(a) == point_key(b)
    assert point_key(a) != point_key(c)


def test_table_has_one_row_per_point_with_inputs_and_outputs(small_store):
    """results.csv is tidy: one row per grid point (full Cartesian product, 2 x 3 x 2),
    inputs under their unit-carrying names, closed-form C1 = exp(-bΔτ) (paper eq. 13,
    compared to 1e-12 relative: it is the same formula) and the % errors consistent
    with the µm errors and the FEM peak (1e-9: only rounding)."""
    sw, out = small_store
    rows = read_csv(out / "results.csv")
    assert len(rows) == 12
    combos = {(float(r["dtau_s"]), float(r["h_W_m2K"]), float(r["q_W_m2"])) for r in rows}
    assert combos == {(d, h, q) for d in (300, 600) for h in (20, 55, 150) for q in (2000, 3000)}
    for col in ("biot", "C1", "C2_um", "C1_fitted", "C2_fitted_um", "fem_peak_um",
                "max_abs_diff_um", "max_abs_diff_pct_of_peak", "rmse_um", "rmse_pct_of_peak",
                "corrected_max_abs_diff_um", "corrected_max_abs_diff_pct_of_peak",
                "corrected_rmse_um", "corrected_rmse_pct_of_peak", "run_time_s"):
        assert col in rows[0], col
    for r in rows:
        h, dtau = float(r["h_W_m2K"]), float(r["dtau_s"])
        b = 2 * h / (7850.0 * 460.0 * 0.1)
        assert math.isclose(float(r["C1"]), math.exp(-b * dtau), rel_tol=1e-12)
        assert math.isclose(float(r["biot"]), h * 0.1 / 50.0, rel_tol=1e-12)
        peak = float(r["fem_peak_um"])
        assert math.isclose(float(r["max_abs_diff_pct_of_peak"]),
                            100 * float(r["max_abs_diff_um"]) / peak, rel_tol=1e-9)
        assert math.isclose(float(r["rmse_pct_of_peak"]), 100 * float(r["rmse_um"]) / peak,
                            rel_tol=1e-9)
        assert float(r["run_time_s"]) > 0
    for name in ("error_vs_biot.png", "c1_vs_dtau.png", "error_heatmap.png",
                 "README.md", "summary.json"):
        assert (out / name).stat().st_size > 0, name


def test_row_equals_a_direct_evaluation(small_store):
    """A stored point is exactly what `evaluate` gives for that scenario (same code path,
    same machine: compared to 1e-9 relative, which only allows BLAS threading noise)."""
    sw, out = small_store
    sweep = load_sweep(sw)
    p = sweep.points[7]
    rec = PointStore(out).get(p.key)
    ev = evaluate(scenario_from_dict(p.data, "direct"))
    for k in ("fem_peak_um", "C1_fitted", "max_abs_diff_um", "corrected_rmse_um"):
        assert math.isclose(rec["metrics"][k], ev.metrics[k], rel_tol=1e-9), k
    assert ev.metrics["h_W_m2K"] == p.inputs["h_W_m2K"]
    assert ev.metrics["q_W_m2"] == p.inputs["q_W_m2"]


def test_other_keys_are_sweepable_under_their_dotted_names(tmp_path):
    """Any scenario key can be swept by its dotted path and appears as that column; the
    FEM really changes with it (dofs grow with fem.mesh.nz)."""
    write_base(tmp_path)
    sw = write_sweep(tmp_path, 'dtau_s = [600]\n"fem.mesh.nz" = [4, 8]\n', name="mesh")
    assert cli(sw, "--out", tmp_path / "o", "--workers", 1) == 0
    rows = read_csv(tmp_path / "o" / "results.csv")
    assert [r["fem.mesh.nz"] for r in rows] == ["4", "8"]
    assert int(rows[1]["fem_dofs"]) > int(rows[0]["fem_dofs"])
    assert rows[0]["h_W_m2K"] == rows[1]["h_W_m2K"] == "55.0"       # unswept core inputs too


def test_same_sweep_resumes_and_computes_nothing(small_store, tmp_path):
    """Re-running a finished sweep into its own --out is a resume (not refused): it computes
    no point, keeps every stored point file byte for byte, and rewrites the same table."""
    import shutil
    sw, out = small_store
    out2 = tmp_path / "copy"
    shutil.copytree(out, out2)
    before = snapshot(out2 / "points")
    table = (out2 / "results.csv").read_text()
    assert cli(sw, "--out", out2, "--workers", 1) == 0
    s = json.loads((out2 / "summary.json").read_text())
    assert (s["n_computed"], s["n_stored_before"], s["n_rows"]) == (0, 12, 12)
    assert snapshot(out2 / "points") == before
    strip = lambda t: [{k: v for k, v in r.items() if k not in TIMING_COLUMNS}
                       for r in csv.DictReader(t.splitlines())]
    assert strip((out2 / "results.csv").read_text()) == strip(table)


def test_different_sweep_is_refused_without_force(small_store, tmp_path, capsys):
    """A non-empty --out holding another sweep is refused (exit 2, one line, nothing
    touched); with --force it runs, and points with identical inputs are reused."""
    import shutil
    sw, out = small_store
    out2 = tmp_path / "copy"
    shutil.copytree(out, out2)
    before = snapshot(out2)
    other = write_sweep(sw.parent, "dtau_s = [600]\nh_W_m2K = [55, 77]\nq_W_m2 = [2000]\n",
                        name="other")
    capsys.readouterr()
    assert cli(other, "--out", out2, "--workers", 1) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("arfem: error:") and "different sweep" in err and "\n" not in err
    assert snapshot(out2) == before
    assert cli(other, "--out", out2, "--workers", 1, "--force") == 0
    s = json.loads((out2 / "summary.json").read_text())
    assert (s["n_points"], s["n_stored_before"], s["n_computed"]) == (2, 1, 1)


@pytest.mark.parametrize("grid, needle", [
    ("dtau_s = []\nh_W_m2K = [55]\n", "sweep.grid.dtau_s: is empty"),
    ("dtau_s = [300, 7]\n", "sweep.grid.dtau_s[1]: 7 is refused"),
    ("dtau_s = [300]\nrod.colour = [1]\n", "sweep.grid.rod.colour: is not a scenario key"),
    ("dtau_s = [300]\n\"rod.colour\" = [1]\n", "sweep.grid.rod.colour: is not a scenario key"),
    ("dtau_s = [300]\nh_W_m2K = [55, -4]\n", "sweep.grid.h_W_m2K[1]"),
])
def test_bad_sweep_file_is_one_line_exit_2_and_store_intact(small_store, tmp_path, capsys,
                                                             grid, needle):
    """Bad input (empty grid, Δτ not dividing the phases, unknown key, non-physical h):
    one `arfem: error:` line naming the file and key, exit 2, and the existing store in
    --out unchanged byte for byte."""
    import shutil
    sw, out = small_store
    out2 = tmp_path / "copy"
    shutil.copytree(out, out2)
    before = snapshot(out2)
    write_base(tmp_path)
    bad = write_sweep(tmp_path, grid, name="bad")
    capsys.readouterr()
    assert cli(bad, "--out", out2) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("arfem: error:"), err
    assert "bad.toml" in err and needle in err, err
    if "7 is refused" in needle:
        assert "does not divide" in err
    assert snapshot(out2) == before


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.xdist_group("tcp_ports")   # takes a TCP port: see conftest.py
def test_unreachable_scheduler_is_one_line_exit_2_and_store_intact(small_store, tmp_path,
                                                                  capsys):
    """--scheduler at an address where nothing listens: one line, exit 2, the store
    untouched even though the same sweep would otherwise be resumed. (It returns within
    the connect timeout plus Dask's own retries; that is not asserted by the clock, which
    a loaded machine would make a flake: a hang would stop CI's run instead.)"""
    import shutil
    sw, out = small_store
    out2 = tmp_path / "copy"
    shutil.copytree(out, out2)
    before = snapshot(out2)
    capsys.readouterr()
    rc = cli(sw, "--out", out2, "--scheduler", f"tcp://127.0.0.1:{_free_port()}",
             "--connect-timeout", 1.5)
    assert rc == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--scheduler" in err and "cannot reach" in err, err
    assert snapshot(out2) == before


def test_bad_worker_count_is_exit_2(small_store, tmp_path, capsys):
    """--workers 0 is bad input: one line naming --workers, exit 2, nothing written."""
    sw, _ = small_store
    capsys.readouterr()
    assert cli(sw, "--out", tmp_path / "o", "--workers", 0) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--workers" in err
    assert not (tmp_path / "o").exists()


def test_key_ignores_names_and_stated_defaults_but_not_physics(tmp_path):
    """Points are keyed by their resolved physical inputs: a base that differs only in
    its name, its output options or by stating a default explicitly gives the same keys
    (so such a sweep reuses the store), a different rod radius gives new keys."""
    write_base(tmp_path)
    ref = {p.key for p in load_sweep(write_sweep(tmp_path, SMALL_GRID)).points}
    text = (tmp_path / "base.toml").read_text()
    (tmp_path / "b2.toml").write_text(text.replace('name = "coarse"', 'name = "other"') +
                                      "[rod]\nradius_m = 0.1\n[outputs]\npicture = false\n")
    same = load_sweep(write_sweep(tmp_path, SMALL_GRID, name="s2", base="b2.toml"))
    assert {p.key for p in same.points} == ref
    (tmp_path / "b3.toml").write_text(text + "[rod]\nradius_m = 0.11\n")
    other = load_sweep(write_sweep(tmp_path, SMALL_GRID, name="s3", base="b3.toml"))
    assert not ({p.key for p in other.points} & ref)


def test_biot_threshold_interpolates_and_reports_unreached():
    """The threshold is the first crossing, linearly interpolated between grid points;
    nan when the level is never reached (so the report can say so)."""
    assert biot_threshold([0.4, 0.1, 0.2], [6.0, 1.0, 2.0], 3.0) == pytest.approx(0.25)
    assert biot_threshold([0.1, 0.2], [4.0, 5.0], 3.0) == 0.1
    assert math.isnan(biot_threshold([0.1, 0.2], [1.0, 2.0], 3.0))


def _flaky_point(data, source, limits=None):
    """Stand-in for evaluate_point: fails for h = 55, else returns h as its 'metric'."""
    h = data["rod"]["convection_W_m2K"]
    if h == 55:
        raise RuntimeError("solver blew up")
    return {"metrics": valid_metrics(h), "run_time_s": 0.0}


def valid_metrics(h: float, peak_um: float = 10.0) -> dict:
    """Metrics a stored point must hold to be trusted on resume (physical ranges and the
    identities between them, ``sweep.store.record_problem``), with h as the marker."""
    return {"dtau_s": 300.0, "h_W_m2K": h, "q_W_m2": 2000.0, "biot": 0.1, "C1": 0.99,
            "C1_fitted": 0.99, "corrected_C1": 0.99, "fem_peak_um": peak_um,
            "ar_peak_um": peak_um + 0.1, "fem_peak_time_h": 4.0, "max_abs_diff_um": 0.2,
            "max_abs_diff_pct_of_peak": 100 * 0.2 / peak_um, "rmse_um": 0.1,
            "corrected_max_abs_diff_um": 0.02,
            "corrected_max_abs_diff_pct_of_peak": 100 * 0.02 / peak_um,
            "corrected_rmse_um": 0.01, "fem_dofs": 100, "n_samples": 50}


def test_failed_points_are_not_stored_and_are_retried(tmp_path):
    """A point whose evaluation raises is reported (exit status 1 from the CLI path,
    n_failed here), not stored; the others are stored; the next run computes only it."""
    write_base(tmp_path)
    sweep = load_sweep(write_sweep(tmp_path, "h_W_m2K = [20, 55, 150]\n"))
    out = tmp_path / "o"
    rep = run_sweep(sweep, out, workers=1, progress=False, point_fn=_flaky_point)
    assert (rep.n_computed, rep.n_failed) == (2, 1)
    assert "solver blew up" in rep.failures[0]["error"]
    assert len(PointStore(out).keys()) == 2
    rep2 = run_sweep(sweep, out, workers=1, progress=False, point_fn=_flaky_point)
    assert (rep2.n_stored_before, rep2.n_computed, rep2.n_failed) == (2, 0, 1)


def _children(pid: int) -> list[int]:
    kids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                kids.append(int(d.name))
    return kids


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


#: a point function for the interrupt test: each call takes a unique ticket (an O_EXCL
#: file, atomic across processes); tickets below GATE_OPEN compute the point as the sweep
#: does, the others wait for a file that never appears until the sweep is stopped. So an
#: interrupted run has stored exactly GATE_OPEN points, whatever the load and whichever
#: worker runs first -- no sleep decides what the test sees.
_GATED_POINT = """\
import os, time
from pathlib import Path
from arfem.scenarios.sweep.executors import evaluate_point

def point(data, source="<sweep point>", limits=None):
    d = Path(os.environ["ARFEM_TEST_GATE_DIR"])
    i = 0
    while True:
        try:
            os.close(os.open(d / f"ticket_{i}", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            break
        except FileExistsError:
            i += 1
    if i >= int(os.environ["ARFEM_TEST_GATE_OPEN"]):
        while not (d / "never").exists():    # held until the sweep is stopped
            time.sleep(0.05)
    return evaluate_point(data, source, limits)
"""

#: a generous bound on waiting for an event, only so that a broken sweep fails the test
#: instead of hanging it; no assertion depends on how long anything took
_SAFETY_S = 600.0


def _wait_for(what: str, condition, proc=None) -> None:
    """Poll ``condition`` (an observable event: files in the store, /proc entries) until
    it holds; fail naming ``what`` if ``proc`` exits first or after :data:`_SAFETY_S`."""
    end = time.monotonic() + _SAFETY_S
    while not condition():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"sweep exited ({proc.returncode}) before {what}: "
                                 f"{proc.stderr.read().decode()}")
        assert time.monotonic() < end, f"no {what} after {_SAFETY_S:g} s"
        time.sleep(0.02)


def _launch_and_interrupt(cmd, store: PointStore, stored: int, sig, whole_group: bool,
                          gate_dir: Path):
    """Start the sweep in its own session with its points gated (:data:`_GATED_POINT`:
    it computes just enough points to make ``stored`` in the store, the rest wait), send
    ``sig`` once the store holds them; return (exit status, stderr, pids of the
    workers)."""
    gate_dir.mkdir()
    new = stored - len(store.keys())                   # points this run may compute
    # the gated point's module (beside the sweep, written by the test) is found by the
    # sweep and by its spawned workers through PYTHONPATH
    path = os.pathsep.join(filter(None, [str(gate_dir.parent), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "PYTHONPATH": path, "ARFEM_TEST_GATE_DIR": str(gate_dir),
           "ARFEM_TEST_GATE_OPEN": str(new)}
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, env=env)
    try:
        _wait_for(f"{stored} stored points", lambda: len(store.keys()) >= stored, proc)
        # a worker holds a ticket past the gate: the sweep is held there, not finishing
        _wait_for("a waiting worker", lambda: len(list(gate_dir.glob("ticket_*"))) > new,
                  proc)
        workers = set(_children(proc.pid))
        if whole_group:
            os.killpg(proc.pid, sig)                   # Ctrl-C in a terminal hits the group
        else:
            os.kill(proc.pid, sig)                     # kill -9 <pid of the sweep>
        _, err = proc.communicate(timeout=_SAFETY_S)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)        # our own session, in case of failure
        except ProcessLookupError:
            pass
    return proc.returncode, err.decode(), workers


def test_interrupt_and_kill_9_then_resume_lose_nothing_and_recompute_nothing(tmp_path):
    """Ctrl-C (SIGINT to the process group) a running sweep with 2 worker processes, run it
    again and kill -9 it, run it a third time: every point is in results.csv exactly once,
    the points stored by the interrupted runs are kept byte for byte, and the last run
    computed exactly the missing ones (its summary and runs.jsonl say so). Ctrl-C exits
    130 with one line; the workers orphaned by kill -9 exit by themselves.

    Deterministic at any load: the interrupted runs compute exactly 4 points each and
    their other points wait on a file (:data:`_GATED_POINT`), so the signal always finds
    the same store and two busy workers; every wait is for an observable event (points
    in the store, tickets, /proc), never a fixed sleep."""
    write_base(tmp_path, mesh="[fem.mesh]\nnr = 3\nnz = 10\n")      # Q2, 147 dofs
    sw = write_sweep(tmp_path, "dtau_s = [60, 120, 300]\n"
                               "h_W_m2K = [5, 10, 20, 35, 55, 100, 150, 250]\n"
                               "q_W_m2 = [2000, 3000]\n", name="long")
    n = 48
    out = tmp_path / "out"
    store = PointStore(out)
    (tmp_path / "gated_point.py").write_text(_GATED_POINT)
    # SIGINT handled as in a terminal even where the test runs in the background (a
    # shell starts background jobs with SIGINT ignored, and Python then never raises
    # KeyboardInterrupt)
    cmd = [sys.executable, "-c",
           "import signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
           "import sys, gated_point; "
           "from arfem.scenarios.sweep import runner; "
           "run = runner.run_in_store; runner.run_in_store = lambda *a, **k: "
           "run(*a, **{**k, 'point_fn': gated_point.point}); "
           "from arfem.scenarios.cli import main; sys.exit(main(sys.argv[1:]))",
           "sweep", str(sw), "--out", str(out), "--workers", "2",
           "--no-progress"]

    rc, err, _ = _launch_and_interrupt(cmd, store, 4, signal.SIGINT, True, tmp_path / "g1")
    assert rc == 130 and err.strip().splitlines()[-1] == "arfem: interrupted", err
    assert len(store.keys()) == 4            # exactly the points let through, none lost

    rc, _, workers = _launch_and_interrupt(cmd, store, 8, signal.SIGKILL, False,
                                           tmp_path / "g2")
    assert rc == -signal.SIGKILL
    assert workers
    _wait_for("exit of the workers orphaned by kill -9",     # each watches its parent
              lambda: not [w for w in workers if _alive(w)])
    stored = {k: store.path(k).read_bytes() for k in store.keys()}
    assert len(stored) == 8, len(stored)

    assert cli(sw, "--out", out, "--workers", 1) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["n_stored_before"] == len(stored)
    assert s["n_computed"] == n - len(stored)
    log = [json.loads(x) for x in (out / "runs.jsonl").read_text().splitlines()]
    assert [r["n_computed"] for r in log] == [n - len(stored)]   # interrupted runs log nothing
    rows = read_csv(out / "results.csv")
    keys = [r["point_key"] for r in rows]
    assert len(keys) == n and len(set(keys)) == n
    assert set(keys) == {p.key for p in load_sweep(sw).points}
    for k, data in stored.items():
        assert store.path(k).read_bytes() == data
    assert sorted(p.name for p in store.dir.iterdir()) == sorted(f"{k}.json" for k in keys)


@pytest.mark.xdist_group("tcp_ports")   # takes a TCP port: see conftest.py
def test_dask_cluster_gives_the_same_table_as_local_processes(small_store, tmp_path):
    """The same sweep on a Dask LocalCluster (2 worker processes) and by the local
    executor gives identical rows: every non-timing column equal as text (floats are
    written with repr, so this is bit-for-bit; both run single-threaded BLAS)."""
    from dask.distributed import LocalCluster
    sw, local = small_store                          # computed by the local executor
    t0 = time.perf_counter()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        t1 = time.perf_counter()
        assert cli(sw, "--out", tmp_path / "dask", "--scheduler", cluster.scheduler_address) == 0
        t2 = time.perf_counter()
    print(f"cluster start {t1 - t0:.1f} s, sweep {t2 - t1:.1f} s, close {time.perf_counter() - t2:.1f} s")
    a = read_csv(local / "results.csv")
    b = read_csv(tmp_path / "dask" / "results.csv")
    assert len(a) == len(b) == 12
    s = json.loads((tmp_path / "dask" / "summary.json").read_text())
    assert s["executor"].startswith("dask") and s["n_computed"] == 12
    for ra, rb in zip(a, b):
        for col in ra:
            if col not in TIMING_COLUMNS:
                assert ra[col] == rb[col], (col, ra[col], rb[col])


# -- issue 16 / 17: bounded whatever the flags, one line for what goes wrong -----------------

def test_workers_are_capped_at_cores_and_points_with_one_note():
    """--workers 100000 must not start 100000 processes (issue 16: load > 60): the count
    is capped at the usable cores and the points to compute, and the cap is said once."""
    from arfem.scenarios.sweep.runner import n_local_workers, usable_cores
    notes = []
    n = n_local_workers(100000, 156, notes.append)
    assert n == min(usable_cores(), 156) and len(notes) == 1 and "capped" in notes[0]
    assert n_local_workers(100000, 1, notes.append) == 1
    notes.clear()
    assert n_local_workers(None, 3, notes.append) == min(usable_cores(), 3) and not notes


@pytest.mark.parametrize("value, expect", [(1e308, "cap"), (float("inf"), "cap"),
                                           (float("nan"), "refuse"), (0.0, "refuse"),
                                           (-1.0, "refuse"), (2.5, 2.5)])
def test_timeouts_are_capped_at_the_documented_maximum(value, expect):
    """--connect-timeout 1e308 hung the command (issue 16): any wait above its documented
    maximum (MAX_CONNECT_S) is capped there, with a note; NaN and non-positive waits are
    bad input."""
    from arfem.scenarios.sweep.runner import MAX_CONNECT_S as MAX_WAIT_S, check_wait
    notes = []
    if expect == "refuse":
        with pytest.raises(InputError, match="--connect-timeout"):
            check_wait(value, "--connect-timeout", notes.append)
    elif expect == "cap":
        assert check_wait(value, "--connect-timeout", notes.append, MAX_WAIT_S) == MAX_WAIT_S
        assert len(notes) == 1 and f"{MAX_WAIT_S:g}" in notes[0]
    else:
        assert check_wait(value, "--connect-timeout", notes.append) == expect and not notes


def test_rerun_keeps_first_timing_and_folder_holds_only_listed_files(small_store, tmp_path):
    """Issue 16: a finished sweep left a .lock file, and a re-run with nothing to compute
    wrote a wall time of 0.0 s over the real one. Now the folder holds only what its
    README lists, and a re-run adds its own run to runs.jsonl and the README."""
    import shutil
    sw, out = small_store
    out2 = tmp_path / "copy"
    shutil.copytree(out, out2)
    first = [json.loads(x) for x in (out2 / "runs.jsonl").read_text().splitlines()]
    assert len(first) == 1 and first[0]["n_computed"] == 12 and first[0]["wall_s"] > 0
    assert cli(sw, "--out", out2, "--workers", 1) == 0
    runs = [json.loads(x) for x in (out2 / "runs.jsonl").read_text().splitlines()]
    assert runs[0] == first[0] and runs[1]["n_computed"] == 0 and len(runs) == 2
    s = json.loads((out2 / "summary.json").read_text())
    assert [r["run_id"] for r in s["runs"]] == [r["run_id"] for r in runs]
    readme = (out2 / "README.md").read_text()
    assert f"wall time {first[0]['wall_s']:.1f} s" in readme
    listed = set(__import__("re").findall(r"`([^`/ ]+/?)`", readme))
    present = {p.name + ("/" if p.is_dir() else "") for p in out2.iterdir()}
    assert present <= listed, present - listed
    assert not (out2 / ".lock").exists()


@pytest.mark.xdist_group("tcp_ports")   # takes a TCP port: see conftest.py
def test_cluster_without_workers_ends_with_one_line_and_keeps_the_store(small_store,
                                                                       tmp_path, capsys):
    """Issue 16: a Dask scheduler with no worker sat at 0/N forever. With --worker-wait 1
    it ends: exit 2, one line naming --worker-wait, the stored points untouched."""
    import shutil
    from dask.distributed import LocalCluster
    sw, out = small_store
    out2 = tmp_path / "copy"
    shutil.copytree(out, out2)
    for p in sorted((out2 / "points").glob("*.json"))[:2]:
        p.unlink()
    before = snapshot(out2 / "points")
    capsys.readouterr()
    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        rc = cli(sw, "--out", out2, "--scheduler", cluster.scheduler_address,
                 "--worker-wait", 1)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "no worker" in err and "--worker-wait" in err
    assert snapshot(out2 / "points") == before


def test_inproc_address_of_no_scheduler_is_one_line(small_store, tmp_path, capsys):
    """Issue 17: --scheduler inproc://x printed an extra 'Exception ignored' traceback
    (a half-made Client collected later). Now: one line, exit 2, nothing else."""
    import gc
    sw, _ = small_store
    capsys.readouterr()
    assert cli(sw, "--out", tmp_path / "o", "--scheduler", "inproc://x") == 2
    gc.collect()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("arfem: error: --scheduler"), err
    assert not (tmp_path / "o").exists()


def test_huge_grid_is_refused_from_its_shape_before_any_point(tmp_path, capsys):
    """Issue 17: a 100³ grid was still validating at 180 s. Its size is known from the list
    lengths: refused in one line that gives the points and the estimated time steps and
    names --max-points; check_size accepts it when the limit is lifted."""
    from arfem.scenarios.rod.scenario import load_scenario
    from arfem.scenarios.sweep.spec import MAX_POINTS, check_size
    write_base(tmp_path)
    vals = lambda a: "[" + ", ".join(str(a + i) for i in range(100)) + "]"
    grid = f"h_W_m2K = {vals(5)}\nq_W_m2 = {vals(1000)}\n\"fem.mesh.nz\" = {vals(4)}\n"
    sw = write_sweep(tmp_path, grid, name="huge")
    capsys.readouterr()
    assert cli(sw, "--out", tmp_path / "o") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "1000000 points" in err and "--max-points" in err, err
    assert f"limit of {MAX_POINTS} points" in err and "time steps" in err
    base = load_scenario(tmp_path / "base.toml")
    n, steps = check_size({"h_W_m2K": list(range(100)), "q_W_m2": list(range(100)),
                           "fem.mesh.nz": list(range(100))}, base, max_points=10**6)
    assert n == 10**6 and steps == pytest.approx(10**6 * 86400 / 600)


def test_disk_full_is_one_line_and_leaves_the_store_intact(tmp_path, capsys, monkeypatch):
    """Issue 17: Errno 28 in `sweep` gave a traceback. Simulated at the third point file:
    one line naming --out's folder and the cause, exit 2; the two points stored before
    parse and no half-written file is left; the same command then finishes the sweep."""
    import errno as _errno
    import arfem.scenarios.sweep.store as store_mod
    write_base(tmp_path)
    sw = write_sweep(tmp_path, "h_W_m2K = [20, 55, 150, 250]\n", name="full")
    out = tmp_path / "o"
    real, calls = store_mod.write_json, []

    def full(path, obj):
        calls.append(path)
        if len(calls) == 3:               # points 1 and 2 stored, then no room
            raise OSError(_errno.ENOSPC, "No space left on device")
        real(path, obj)

    monkeypatch.setattr(store_mod, "write_json", full)
    capsys.readouterr()
    assert cli(sw, "--out", out, "--workers", 1) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No space left" in err and str(out) in err, err
    files = sorted(p.name for p in (out / "points").iterdir())
    assert len(files) == 2 and all(not f.startswith(".") for f in files)
    for f in files:
        assert json.loads((out / "points" / f).read_text())["metrics"]
    monkeypatch.setattr(store_mod, "write_json", real)
    assert cli(sw, "--out", out, "--workers", 1) == 0
    s = json.loads((out / "summary.json").read_text())
    assert (s["n_stored_before"], s["n_computed"]) == (2, 2)


@pytest.mark.xdist_group("tcp_ports")   # takes a TCP port: see conftest.py
@pytest.mark.slow
def test_scheduler_killed_mid_sweep_is_one_line_and_keeps_points(tmp_path):
    """Issue 17: the Dask scheduler killed mid-sweep gave distributed's tracebacks and five
    failure lines. Now: exit 2, one line on stderr, the points finished before are kept."""
    port = _free_port()
    env = dict(os.environ)
    sched = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                              "--port", str(port), "--no-dashboard"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    work = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker",
                             f"tcp://127.0.0.1:{port}", "--nthreads", "1", "--no-dashboard"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    out = tmp_path / "o"
    try:
        time.sleep(5)
        proc = subprocess.Popen([sys.executable, "-m", "arfem", "sweep",
                                 str(REPO / "scenarios" / "data" / "sweep_dtau_h.toml"), "--out",
                                 str(out), "--scheduler", f"tcp://127.0.0.1:{port}",
                                 "--no-progress"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, cwd=tmp_path)
        store = PointStore(out)
        t_end = time.time() + 120
        while len(store.keys()) < 3 and time.time() < t_end and proc.poll() is None:
            time.sleep(0.1)
        sched.kill()
        _, err = proc.communicate(timeout=120)
    finally:
        for p in (sched, work):
            p.kill()
            p.wait()
    err = err.decode()
    assert proc.returncode == 2 and err.count("\n") == 1 and "stopped answering" in err, err
    assert len(store.keys()) >= 3


# -- figures (issue 15) -----------------------------------------------------------------------

def _figure_rows(small_store):
    from arfem.scenarios.sweep import results_rows
    sw, out = small_store
    sweep = load_sweep(sw)
    return sweep, results_rows(sweep, PointStore(out))


def _check_figure(fig):
    """Sensible size; every data axes labelled (units in brackets), every colour bar
    labelled; every legend inside its axes and over none of the plotted points."""
    fig.canvas.draw()
    w, h = fig.get_size_inches()
    assert 5 <= w <= 16 and 3 <= h <= 14, (w, h)
    r = fig.canvas.get_renderer()
    n_data = 0
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        if ax.get_label() == "<colorbar>":
            assert ax.get_ylabel().strip(), "colour bar without a label"
            continue
        n_data += 1
        for lab in (ax.get_xlabel(), ax.get_ylabel()):
            assert lab.strip() and "[" in lab and "]" in lab, lab
        leg = ax.get_legend()
        if leg is None:
            continue
        lb, ab = leg.get_window_extent(r), ax.get_window_extent(r)
        assert ab.x0 - 1 <= lb.x0 and lb.x1 <= ab.x1 + 1 and ab.y0 - 1 <= lb.y0 \
            and lb.y1 <= ab.y1 + 1, "legend outside its axes"
        for line in ax.lines:
            xy = line.get_xydata()
            if len(xy) == 0 or line.get_label().startswith("_"):
                continue
            pts = ax.transData.transform(xy)
            inside = ((pts[:, 0] > lb.x0) & (pts[:, 0] < lb.x1) & (pts[:, 1] > lb.y0)
                      & (pts[:, 1] < lb.y1))
            assert not inside.any(), f"legend covers data of {line.get_label()!r}"
    assert n_data >= 1


@pytest.mark.parametrize("name", ["fig_error_vs_biot", "fig_c1_vs_dtau", "fig_error_heatmap"])
def test_each_figure_is_labelled_and_its_legend_covers_no_data(small_store, name):
    """Issue 15 (journal standard): each figure function returns a Figure of a sensible
    size with units on every axis, labelled colour bars and legends inside the axes that
    cover none of the plotted points."""
    import arfem.scenarios.sweep.figures as F
    sweep, rows = _figure_rows(small_store)
    _check_figure(getattr(F, name)(sweep, rows))


def test_one_heatmap_when_the_error_does_not_depend_on_q(small_store):
    """The % errors are the same at q = 2000 and 3000 W/m² (FEM and ARs are linear in q):
    decided from the data (differences < 1e-6 % points), one heat map is written and its
    title says so; the folder holds exactly the figures summary.json names."""
    import arfem.scenarios.sweep.figures as F
    sweep, rows = _figure_rows(small_store)
    assert F.q_dependence(sweep, rows) < F.Q_SAME_PP
    fig = F.fig_error_heatmap(sweep, rows)
    assert "identical for q = 2000, 3000" in fig._suptitle.get_text()
    assert len([a for a in fig.axes if a.get_label() != "<colorbar>" and a.images]) == 2
    sw, out = small_store
    pngs = {p.name for p in out.glob("*.png")}
    assert pngs == set(json.loads((out / "summary.json").read_text())["plots"])
    assert not any("_q" in p for p in pngs)


def test_heatmap_labels_contrast_with_their_cells(small_store):
    """White labels on pale yellow could not be read (issue 15): the label colour is chosen
    from the cell's luminance, so every label has a WCAG contrast ratio >= 4.5 with its
    cell (the level at which text counts as readable)."""
    import arfem.scenarios.sweep.figures as F
    from matplotlib.colors import to_rgba
    sweep, rows = _figure_rows(small_store)
    fig = F.fig_error_heatmap(sweep, rows)
    n = 0
    for ax in fig.axes:
        if not ax.images:
            continue
        im = ax.images[0]
        Z = im.get_array()
        for t in ax.texts:
            j, i = (int(round(v)) for v in t.get_position())
            if not (0 <= i < Z.shape[0] and 0 <= j < Z.shape[1]) or np.ma.is_masked(Z[i, j]):
                continue
            lc = F._luminance(im.cmap(im.norm(Z[i, j])))
            lt = F._luminance(to_rgba(t.get_color()))
            ratio = (max(lc, lt) + 0.05) / (min(lc, lt) + 0.05)
            assert ratio >= 4.5, (t.get_text(), ratio)
            n += 1
    assert n >= 12


def test_third_swept_variable_is_stated_on_the_figures(tmp_path):
    """A custom sweep's figures held a third swept variable at a value chosen silently:
    now the value is stated in each figure's title (Δτ × h × fem.mesh.nz, no core q)."""
    import arfem.scenarios.sweep.figures as F
    write_base(tmp_path)
    sweep = load_sweep(write_sweep(tmp_path, 'h_W_m2K = [20, 150]\n"fem.mesh.nz" = [4, 6]\n',
                                   name="third"))
    rows = [{"dtau_s": 600.0, "h_W_m2K": h, "q_W_m2": 2000.0, "fem.mesh.nz": nz,
             "biot": h / 500, "C1": 0.9, "C1_fitted": 0.91, "corrected_C1": 0.91,
             "max_abs_diff_pct_of_peak": h / 30, "corrected_max_abs_diff_pct_of_peak": h / 3e3}
            for h in (20, 150) for nz in (4, 6)]
    for make in (F.fig_error_vs_biot, F.fig_c1_vs_dtau, F.fig_error_heatmap):
        fig = make(sweep, rows)
        assert "fem.mesh.nz = 4 (first of 2 values)" in fig._suptitle.get_text().replace("\n", " ")
        _check_figure(fig)
