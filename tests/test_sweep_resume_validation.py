"""A sweep store's points are validated on resume (issue 29).

Properties verified:

* each corruption the reliability test of issue 29 made (a metric stored as a string,
  which crashed the thresholds; ``ar_peak_um = -inf``, ``fem_peak_um = 1e-320``, a
  negative error, which were resumed as "nothing to compute") makes that point
  recomputed, never trusted and never crashed on;
* the resume says so in ONE line naming the point's file and what is wrong;
* the results (``results.csv``, ``summary.json``) then hold only the recomputed, valid
  numbers; the valid points are not recomputed.
"""
from __future__ import annotations

import csv
import json
import math
from unittest import mock

import pytest
from sweep_fakes import fake_point, valid_metrics, write_small_sweep

from arfem.scenarios.sweep import PointStore, load_sweep, run_sweep
from arfem.scenarios.sweep.store import record_problem


def _rec(key="k", **metrics):
    from arfem.scenarios.sweep.spec import STORE_VERSION
    return {"key": key, "store_version": STORE_VERSION, "inputs": {"h_W_m2K": 20},
            "metrics": {**valid_metrics(20), **metrics}, "run_time_s": 0.1}


CORRUPT = [
    ("ar_peak_um", -math.inf), ("ar_peak_um", None), ("fem_peak_um", 1e-320),
    ("fem_peak_um", -3.0), ("max_abs_diff_um", -0.2), ("rmse_um", -1e-9),
    ("max_abs_diff_pct_of_peak", "2.0"), ("biot", True), ("C1", 1.5), ("n_samples", -1),
    ("corrected_rmse_um", math.nan), ("fem_peak_um", 1e300),
    ("max_abs_diff_pct_of_peak", 50.0),          # not 100 · max_abs_diff_um / fem_peak_um
    ("rmse_um", 5.0),                            # an RMS above the max error
    ("ar_peak_um", 30.0),                        # AR peak 20 µm off, max error 0.2 µm
]


def test_a_valid_record_is_trusted():
    assert record_problem(_rec(), "k", {"h_W_m2K": 20}) is None


@pytest.mark.parametrize("name,value", CORRUPT, ids=[f"{n}={v!r}" for n, v in CORRUPT])
def test_each_corruption_is_caught_and_named(name, value):
    why = record_problem(_rec(**{name: value}), "k")
    assert why is not None and why.count("\n") == 0
    assert name in why or "max_abs_diff" in why or "fem_peak_um" in why, why


@pytest.mark.parametrize("change,expect", [
    ({"key": "other"}, "key"), ({"store_version": 1}, "store_version"),
    ({"metrics": [1]}, "metrics"), ({"run_time_s": -1.0}, "run_time_s"),
    ({"inputs": {"h_W_m2K": 55}}, "inputs")])
def test_layout_and_inputs_are_checked(change, expect):
    assert expect in record_problem({**_rec(), **change}, "k", {"h_W_m2K": 20})


def _corrupt(store: PointStore, key: str, name: str, value) -> None:
    p = store.path(key)
    rec = json.loads(p.read_text("utf-8"))
    rec["metrics"][name] = value
    p.write_text(json.dumps(rec, allow_nan=True), "utf-8")   # -Infinity as Python writes it


@pytest.mark.parametrize("name,value", [("ar_peak_um", -math.inf), ("fem_peak_um", 1e-320),
                                        ("max_abs_diff_um", -0.5),
                                        ("max_abs_diff_pct_of_peak", "x")])
def test_a_corrupt_point_is_recomputed_on_resume_and_reported(tmp_path, name, value):
    sweep = load_sweep(write_small_sweep(tmp_path))
    out = tmp_path / "o"
    notes = []
    with mock.patch("arfem.scenarios.sweep.report.write_figures", lambda *a: []):
        run_sweep(sweep, out, workers=1, progress=False, point_fn=fake_point)
        store = PointStore(out)
        bad = sweep.points[1]
        _corrupt(store, bad.key, name, value)
        rep = run_sweep(sweep, out, workers=1, progress=False, point_fn=fake_point,
                        warn=notes.append)
    assert (rep.n_stored_before, rep.n_computed, rep.n_failed) == (2, 1, 0)
    assert len(notes) == 1 and f"points/{bad.key}.json" in notes[0] and name in notes[0]
    assert store.get(bad.key, bad.inputs)["metrics"] == valid_metrics(55)
    rows = list(csv.DictReader((out / "results.csv").open(encoding="utf-8")))
    assert len(rows) == 3
    for r in rows:
        assert float(r["ar_peak_um"]) == pytest.approx(10.1)
        assert float(r["max_abs_diff_um"]) == pytest.approx(0.2)
    # and a third run trusts everything: nothing to compute, nothing said
    notes.clear()
    with mock.patch("arfem.scenarios.sweep.report.write_figures", lambda *a: []):
        rep = run_sweep(sweep, out, workers=1, progress=False, point_fn=fake_point,
                        warn=notes.append)
    assert rep.n_computed == 0 and notes == []


def test_the_cli_resume_over_a_string_metric_exits_0_with_one_note(tmp_path, capsys):
    """The crash of issue 29 (a string metric reached the thresholds: TypeError, exit 1),
    through the whole command (real points of a coarse rod): exit 0, one note line, the
    point recomputed."""
    from arfem.scenarios.cli import main
    sw = write_small_sweep(tmp_path, "h_W_m2K = [20, 55]\n")
    out = tmp_path / "o"
    with mock.patch("arfem.scenarios.sweep.report.write_figures", lambda *a: []):
        assert main(["sweep", str(sw), "--out", str(out), "--workers", "1",
                     "--no-progress"]) == 0
        key = load_sweep(sw).points[0].key
        _corrupt(PointStore(out), key, "max_abs_diff_pct_of_peak", "2.0")
        capsys.readouterr()
        assert main(["sweep", str(sw), "--out", str(out), "--workers", "1",
                     "--no-progress"]) == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if "not valid" in ln]
    assert len(err) == 1 and key in err[0]
