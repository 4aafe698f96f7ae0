"""Why ``arfem diagnose`` and ``arfem compensate`` can give different paper-AR(1)
hold-out errors on the same speed record (FL_THERMAL ch2: 5.36 against 5.06 µm), and
that the eq. 17 fit behind both is one implementation.

Both fit C1 and one C2 per speed by the least squares of paper eq. 17
(:func:`arfem.models.ar1.eq17_least_squares`) on the rows before the hold-out, and both
run the recursion from the first row. They differ in one rule: a speed the fit never
saw gets its C2 by the early-rise mapping of eqs. 20-21 in the diagnosis's baseline
(:func:`arfem.models.diagnosis.speed.paper_ar`) and by linear interpolation between the
fitted speeds in model.json (:func:`arfem.models.compensator.fit_speed_ar1_model`).
(The diagnosis also leaves the loader's outliers out of its fit and its score; the
records here have none.)
"""
from __future__ import annotations

import dataclasses

import numpy as np

from arfem.models.ar1 import ar1_simulate, fit_ar1
from arfem.models.compensator import Compensator, fit_speed_ar1_model
from arfem.models.diagnosis.speed import paper_ar, speed_to_heat_map
from arfem.scenarios.diagnosis.report import _unseen_note

DT = 15.0
C1 = 0.995
C2 = {0.0: 0.0, 2000.0: 0.02, 3000.0: 0.035, 4000.0: 0.05}


def _record(hold_speeds):
    """2 h blocks of speed, the last three the hold-out; growth by the AR(1) with a
    little noise (so the fit is not exact), from 0 at t = 0."""
    speeds = [0.0, 2000.0, 0.0, 4000.0, 0.0, 2000.0, 4000.0, 0.0] + list(hold_speeds)
    sp = np.repeat(speeds, int(7200 / DT))
    sp = np.r_[0.0, sp]
    g = ar1_simulate(C1, [C2[s] for s in sp[1:]])          # g[0] = 0
    g = g + np.random.default_rng(3).normal(0.0, 0.005, g.size)
    g[0] = 0.0
    t = DT * np.arange(sp.size)
    return t, g, sp, t >= 8 * 7200.0


def _replay(model, sp):
    comp = Compensator(model)
    return np.r_[np.nan, [comp.step({"speed_rpm": v}).predicted_growth_um for v in sp[1:]]]


def _both(hold_speeds):
    t, g, sp, hold = _record(hold_speeds)
    rows = ~hold
    _, seen, W, _ = speed_to_heat_map(t, sp, {}, rows)
    diag, info = paper_ar(t, g, sp, rows, W, seen)
    model = fit_speed_ar1_model(g[rows], sp[rows][1:], dtau_s=DT)
    return t, g, sp, hold, diag, info, model


def test_one_eq17_fit_gives_the_same_coefficients_to_both():
    """The diagnosis's baseline and model.json carry the same C1 and C2 (to 1e-12: one
    least-squares implementation on the same pairs; the diagnosis only clips C1 into
    (0, 1), which this record does not reach)."""
    t, g, sp, hold, _, info, model = _both([2000.0, 0.0, 4000.0])
    fit = fit_ar1(g[~hold], sp[~hold][1:])
    assert abs(info["C1"] - fit.c1) < 1e-12 and abs(model.A[0, 0] - fit.c1) < 1e-12
    levels, values = model.input_maps["speed_rpm"]
    for s, c in zip(levels, values):
        assert abs(info["C2_um"][float(s)] - c) < 1e-12 and abs(fit.c2[float(s)] - c) < 1e-12
    assert abs(fit.c1 - C1) < 2e-3          # and it recovers the record's C1


def test_same_prediction_on_a_hold_out_at_seen_speeds():
    """Every hold-out speed seen before it: diagnose's baseline and compensate's replay
    of model.json predict the same growth on every hold-out row (1e-9 µm: the same
    recursion from the same start), so they score the same."""
    _, _, sp, hold, diag, _, model = _both([2000.0, 0.0, 4000.0])
    comp = _replay(model, sp)
    assert np.max(np.abs(diag[hold] - comp[hold])) < 1e-9


def test_unseen_speeds_are_the_whole_difference():
    """A hold-out at 3000 rpm, a speed the fit never saw: the two predictions differ
    (eqs. 20-21 against interpolation), and giving model.json the diagnosis's mapped C2
    at 3000 rpm makes them agree again to 1e-9 µm -- nothing else differs."""
    _, _, sp, hold, diag, info, model = _both([3000.0, 0.0, 3000.0])
    comp = _replay(model, sp)
    assert np.max(np.abs(diag[hold] - comp[hold])) > 0.05
    levels, values = model.input_maps["speed_rpm"]
    mapped = info["C2_mapped_um"][3000.0]
    i = int(np.searchsorted(levels, 3000.0))
    same = dataclasses.replace(model, input_maps={"speed_rpm": (
        np.insert(levels, i, 3000.0), np.insert(values, i, mapped))})
    assert np.max(np.abs(diag[hold] - _replay(same, sp)[hold])) < 1e-9


def test_outputs_say_where_the_two_numbers_part():
    """The report's hold-out section names the hold-out's scored rows and the speeds not
    seen before it, and says that compensate scores model.json differently there; with
    none, it says nothing of it (the terminal line's:
    tests/test_diagnosis_terminal_line.py)."""
    h = {"baseline_rmse_um": 5.36, "extended_rmse_um": 5.36, "gain_pct": 0.0,
         "start_s": 111140.0, "n_samples": 3701,
         "speeds_not_seen_before_rpm": [500.0, 1500.0, 3500.0, 4500.0],
         "n_samples_at_speeds_not_seen": 2157}
    note = _unseen_note(h)
    assert "2157 of them (58 %) run at speeds not seen before it" in note
    assert "`arfem compensate` scores it differently" in note
    assert _unseen_note(dict(h, speeds_not_seen_before_rpm=[])) == ""
