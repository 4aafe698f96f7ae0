"""The speed-only path of the diagnosis (records with ``speed_rpm`` and no heat flux):
a frame with its own slow response and a non-linear speed-to-heat law are hidden in a
synthetic record with an unseen last speed; the diagnosis must find them from the files.

The record is made with :func:`first_order_lag` (the exact zero-order-hold solution on
the general uneven-step path), not with the fit's own column builder
(:func:`ar_columns`, an IIR filter on even steps).
"""
import json

import numpy as np
import pytest

from arfem.models.diagnosis.forward import ar_columns, ar_first_order, first_order_lag
from arfem.models.diagnosis.speed_frame import (FrameStructure, fit_frame_thermometers,
                                                frame_structures, heat_law)
from arfem.models.diagnosis.speed_select import forward_folds, select_frame_structure
from arfem.scenarios.cli import main as cli

ROD_TAU_H, FRAME_TAU_H, FRAME_GAIN, P_TRUE, K_ROD_UM = 1.0, 8.0, -0.4, 5.0 / 3.0, 20.0
ROOM_UM_PER_K = 1.5
PHASES = [(0, 1), (1000, 4), (0, 3), (2000, 4), (0, 3), (3000, 4), (0, 3), (4000, 4), (0, 4)]
HOLDOUT_S = 22 * 3600.0      # the 4000 rpm block: a speed the fit never sees
NOISE_UM = 0.1


def _record(seed=3, step_s=120.0, room_um_per_k=ROOM_UM_PER_K):
    rng = np.random.default_rng(seed)
    edges = np.cumsum([0] + [h * 3600.0 for _, h in PHASES])
    t = np.arange(1, int(edges[-1] / step_s) + 1) * step_s
    speed = np.array([PHASES[np.searchsorted(edges, x, side="left") - 1][0] for x in t], float)
    heat = heat_law(speed, P_TRUE, 4000.0)
    rod = K_ROD_UM * first_order_lag(t, heat, ROD_TAU_H * 3600.0)
    frame = FRAME_GAIN * K_ROD_UM * first_order_lag(t, heat, FRAME_TAU_H * 3600.0)
    room = 0.8 * np.sin(2 * np.pi * t / (26 * 3600.0)) + 0.3 * np.sin(t / 9000.0)
    y = rod + frame + room_um_per_k * room + rng.normal(0, NOISE_UM, t.size)
    temps = {"T_room_C": 21.0 + room + rng.normal(0, 0.02, t.size),
             "T_head_C": 22.0 + 3.0 * first_order_lag(t, heat, 1800.0)
             + rng.normal(0, 0.02, t.size)}
    return t, speed, y, temps


def test_ar_columns_equal_the_general_recursion_on_even_and_uneven_steps():
    """The IIR fast path of :func:`ar_columns` is the same exact recursion as the chunked
    one (uneven steps take the general path): agreement to 1e-12 of the response."""
    rng = np.random.default_rng(0)
    U = rng.uniform(0, 2, (800, 3))
    for t in (np.arange(1, 801) * 30.0, np.cumsum(rng.uniform(10, 50, 800))):
        X = ar_columns(t, U, 2e-4)
        for j in range(3):
            ref = ar_first_order(t, U[:, j], np.full(t.size, 2e-4), 1.0)  # array b: general path
            assert np.max(np.abs(X[:, j] - ref)) < 1e-12 * np.max(np.abs(ref))


def test_frame_fit_recovers_slow_response_and_heat_law():
    """With the true structure (no room term, no thermometer components), the output-error
    fit on the first 22 h recovers the frame's time constant (30 %), its gain (0.05) and
    the rod's time constant (5 %). τ_f = 8 h is weakly identified by a 22 h window with a
    free offset and initial state: the RSS changes by < 0.5 % from 6 to 12 h, and three
    noise seeds give 7.3-9.9 h, hence 30 %. (With
    thermometers in the model, a head sensor that follows the heat can stand in for part
    of the slow response: the fit-window RSS is then flat to within the noise for τ_f
    from 8 to 30 h, so τ_f is checked here, not end to end.)"""
    t, speed, y, temps = _record(room_um_per_k=0.0)
    rows = t < HOLDOUT_S
    f = fit_frame_thermometers(t, y, speed, rows, None, None, temps,
                               FrameStructure(0, 0.0, P_TRUE, True))
    p = f.parameters
    assert abs(p["frame_time_constant_h"] / FRAME_TAU_H - 1) < 0.30
    assert abs(p["frame_gain"] - FRAME_GAIN) < 0.05
    assert abs(p["rod_time_constant_h"] / ROD_TAU_H - 1) < 0.05
    hold = ~rows
    rmse = float(np.sqrt(np.mean((y - f.prediction)[hold] ** 2)))
    assert rmse < 3 * NOISE_UM          # the unseen 4000 rpm block is predicted


def test_forward_chaining_selects_true_heat_law_and_slow_frame():
    """Selection uses only the fit window: each validation block opens with a speed its
    training part has not seen, so the heat exponent is tested by extrapolation. With
    the true law in the grid (5/3) and noise 0.1 µm, the neighbours (4/3, 2) miss the
    unseen speed by ~0.5-1 µm, far above the noise; the slow frame is required."""
    t, speed, y, temps = _record()
    rows = t < HOLDOUT_S
    folds = forward_folds(t, speed, rows)
    maps = [(np.unique(speed[tr]), {}) for tr, _ in folds]   # per-speed gains: no mapping
    st, table = select_frame_structure(t, y, speed, temps, rows, folds, maps, "wide")
    assert len(table) == len(frame_structures(2, "wide"))
    assert st.heat_exponent == pytest.approx(P_TRUE) and st.slow_lag
    assert st.components >= 1           # the room swing is in the reading


def _write(tmp_path, t, speed, y, temps):
    cols = {"time_s": t, "spindle(RPM)": speed, "growth_um": y, **temps}
    lines = [",".join(cols)] + [",".join(f"{v:.6g}" for v in row) for row in zip(*cols.values())]
    (tmp_path / "rec.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "rec.toml").write_text(
        '[dataset]\nname = "rec"\ncsv = "rec.csv"\n\n[columns]\nspeed_rpm = "spindle(RPM)"\n')
    return tmp_path / "rec.toml"


def test_diagnose_names_frame_and_gains_on_unseen_speed(tmp_path):
    """End to end from the files: the frame is named with a slow (>= 2 h) response, and the
    extended model beats the paper AR(1) (with the speed-proportional mapping for
    4000 rpm) on the hold-out by > 50 % (measured: 59 %, 1.08 -> 0.45 µm). The selected
    structure lets a lagged head thermometer stand in for part of the rod's own lag, so
    the physical parameters are checked in the thermometer-free fit above, not here."""
    t, speed, y, temps = _record()
    toml = _write(tmp_path, t, speed, y, temps)
    rc = cli(["diagnose", str(toml), "--out", str(tmp_path / "out"),
              "--holdout-start", str(HOLDOUT_S), "--frame-search", "wide"])
    assert rc == 0
    s = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    # named by the selection rules; whether it is *established* (issue 30) turns on its
    # intervals, which for the thermometer frame summarise the fit poorly (see above),
    # so the parameters are read from wherever the verdict put them
    from arfem.models.diagnosis.verdict import named_cause
    assert named_cause(s) == "frame_expansion"
    par = s["parameters"] if s["verdict"] == "established" else s["best_candidate"]["parameters"]
    assert s["verdict"] in ("established", "unconfirmed")
    assert not any("hold-out" in f for f in s["verdict_detail"]["failed_checks"])
    assert par["frame_time_constant_h"] >= 2.0
    assert s["holdout"]["gain_pct"] > 50


def test_frame_ensemble_is_the_equal_weight_mean_of_its_members():
    """--frame-search average (post hoc): no structure is chosen; the candidate's
    prediction is exactly the mean of the "narrow" structures' predictions (1e-9 of the
    growth range: the members are the same deterministic fits), its contract parameters
    the members' medians, and select_frame_structure returns it with no table."""
    from arfem.models.diagnosis.speed_frame import FrameEnsemble
    t, speed, y, temps = _record()
    rows = t < HOLDOUT_S
    folds = forward_folds(t, speed, rows)
    maps = [(np.unique(speed[tr]), {}) for tr, _ in folds]
    ens, table = select_frame_structure(t, y, speed, temps, rows, folds, maps, "average")
    assert isinstance(ens, FrameEnsemble) and table == {}
    assert list(ens.members) == frame_structures(2, "narrow")
    seen = np.unique(speed[rows])
    W = {4000.0: {3000.0: 4 / 3, 0.0: -1 / 3}}
    f = fit_frame_thermometers(t, y, speed, rows, seen, W, temps, ens)
    fits = [fit_frame_thermometers(t, y, speed, rows, seen, W, temps, m) for m in ens.members]
    mean = np.mean([g.prediction for g in fits], axis=0)
    assert np.max(np.abs(f.prediction - mean)) <= 1e-9 * np.ptp(y)
    assert f.parameters["frame_gain"] == pytest.approx(
        np.median([g.parameters["frame_gain"] for g in fits]), rel=1e-12)
    assert f.parameters["frame_members"] == len(ens.members)


def test_average_search_end_to_end_uses_the_median_block_ratio_rule(tmp_path):
    """From the files with --frame-search average: the run completes (report included),
    the frame structure is reported as the average, and every candidate is named
    'significant' exactly when its median per-block validation RMSE ratio to the
    baseline is <= 1 - MIN_GAIN -- the post hoc naming rule of that search; the named
    cause has the least ratio among the significant ones."""
    from arfem.models.diagnosis.engine import MIN_GAIN
    t, speed, y, temps = _record()
    toml = _write(tmp_path, t, speed, y, temps)
    rc = cli(["diagnose", str(toml), "--out", str(tmp_path / "out"),
              "--holdout-start", str(HOLDOUT_S), "--frame-search", "average"])
    assert rc == 0
    s = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert s["selection"]["frame_structure"]["label"].startswith("average of 6")
    assert "no structure chosen" in (tmp_path / "out" / "report.md").read_text()
    tests = [c for c in s["candidates"] if "median_block_ratio" in c]
    assert tests
    for c in tests:
        assert c["significant"] == (c["median_block_ratio"] <= 1 - MIN_GAIN)
    sig = [c for c in tests if c["significant"]]
    from arfem.models.diagnosis.verdict import named_cause     # established or not
    if sig:
        assert named_cause(s) == min(sig, key=lambda c: c["median_block_ratio"])["cause"]
    else:
        assert named_cause(s) == "none"


def test_on_fit_reports_every_candidate_without_changing_the_diagnosis(tmp_path):
    """The engine's on_fit hook (issue 31: explore_candidates.py studies every candidate
    through it instead of replacing engine functions) is called with each speed cause's
    fit on its boolean rows, and the diagnosis it watches is the same, to the bit, as
    one without it (the hook only observes)."""
    from arfem.models.diagnosis.engine import diagnose
    from arfem.models.diagnosis.speed import SPEED_CAUSES
    from arfem.scenarios.records.dataset import load_dataset
    t, speed, y, temps = _record()
    ds = load_dataset(_write(tmp_path, t, speed, y, temps))
    seen = []
    watched = diagnose(ds, HOLDOUT_S, intervals=False,
                       on_fit=lambda c, rows, f: seen.append((c, rows.dtype, f)))
    plain = diagnose(ds, HOLDOUT_S, intervals=False)
    assert set(SPEED_CAUSES) <= {c for c, _, _ in seen}
    assert all(dt == bool for _, dt, _ in seen)
    assert watched.cause == plain.cause
    assert np.array_equal(watched.series["extended_um"], plain.series["extended_um"],
                          equal_nan=True)
