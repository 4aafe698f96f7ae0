"""The sweep's default path (issue 30): points are first computed in this process, and
worker processes start only for what is left after ``IN_PROCESS_FIRST_S``; both parts
give the rows one path alone gives. No test here depends on how fast the machine is:
the budget is set to 'always enough' or 'never enough'."""
from __future__ import annotations

import csv
import os
from pathlib import Path

import pytest

from arfem.scenarios.sweep import TIMING_COLUMNS, load_sweep, run_sweep
from arfem.scenarios.sweep import runner

#: a coarse 12-point sweep of the paper's cycle (as tests/test_sweep.py's small one)
BASE = """[scenario]
name = "coarse"
[cycle]
phases = [
  { duration_h = 4.0,  q_W_m2 = 2000.0 },
  { duration_h = 14.5, q_W_m2 = 0.0 },
]
[ar]
dtau_s = 600.0
[fem]
model = "axisymmetric"
order = 1
[fem.mesh]
nr = 2
nz = 6
"""
SMALL_GRID = "dtau_s = [300, 600]\nh_W_m2K = [20, 55, 150]\nq_W_m2 = [2000, 3000]\n"


def write_sweep(d: Path) -> Path:
    (d / "base.toml").write_text(BASE)
    p = d / "small.toml"
    p.write_text(f'[sweep]\nname = "small"\nbase = "base.toml"\n[sweep.grid]\n{SMALL_GRID}')
    return p


def _rows(out: Path) -> list[dict]:
    with open(out / "results.csv", newline="") as fh:
        return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS}
                for r in csv.DictReader(fh)]


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    d = tmp_path_factory.mktemp("default_path")
    sweep = load_sweep(write_sweep(d))
    ref = d / "ref"
    run_sweep(sweep, ref, workers=1, progress=False)
    return sweep, d, _rows(ref)


def test_default_finishes_in_process_when_the_budget_suffices(small, monkeypatch):
    """A budget no sweep exhausts: every point is computed in this process (no worker
    is started), and the rows equal the in-process reference."""
    sweep, d, ref = small
    monkeypatch.setattr(runner, "IN_PROCESS_FIRST_S", 1e9)
    rep = run_sweep(sweep, d / "all_in", progress=False)
    assert rep.executor.startswith("local, in-process")
    assert rep.n_computed == len(ref)
    workers = {r["worker"] for r in csv.DictReader(open(d / "all_in" / "results.csv"))} \
        if "worker" in ref[0] else None
    assert _rows(d / "all_in") == ref
    if workers is not None:
        assert all(w.endswith(f":{os.getpid()}") for w in workers)


def test_default_hands_the_rest_to_workers_after_the_budget(small, monkeypatch):
    """A budget of 1 ns: the first point in-process, the rest on workers (where the
    machine has 2 cores); the rows are still those of the in-process reference."""
    sweep, d, ref = small
    monkeypatch.setattr(runner, "IN_PROCESS_FIRST_S", 1e-9)
    rep = run_sweep(sweep, d / "split", progress=False)
    assert rep.n_computed == len(ref)
    if runner.usable_cores() > 1:
        assert rep.executor.startswith("local, in-process for 1 point, then local, 2 worker")
    assert _rows(d / "split") == ref


def test_explicit_workers_skip_the_in_process_start(small, monkeypatch):
    """--workers given: the request is followed as it is (no in-process start)."""
    sweep, d, ref = small
    monkeypatch.setattr(runner, "IN_PROCESS_FIRST_S", 1e9)
    if runner.usable_cores() < 2:
        pytest.skip("one core: --workers 2 is capped to in-process")
    rep = run_sweep(sweep, d / "explicit", workers=2, progress=False)
    assert rep.executor.startswith("local, 2 worker")
    assert _rows(d / "explicit") == ref
