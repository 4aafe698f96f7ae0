"""The thermometer residual model of issue 43 (``arfem.models.residual``): it recovers a
known thermometer coefficient from generated data, declines to correct where the
residual has nothing to do with the thermometers, is causal (row k uses nothing after
k), and its ``model.json`` export -- alone and in parallel with a base model --
reproduces it exactly when stepped by the compensator, so the FL_THERMAL table
(``reports/fl_thermal/thermometers.md``) scores the model itself, not an export error."""
from __future__ import annotations

import numpy as np
import pytest

from arfem.models.compensator import Compensator, ar1_model
from arfem.models.residual import (fit_thermometer_residual, lag_features,
                                   parallel_state_space, residual_simulate,
                                   residual_state_space)
from arfem.params import InputError
from arfem.scenarios.compensation.model_file import model_from_doc, model_to_doc

DT = 60.0
N = 3000


def _thermometers(seed=0):
    """Two thermometers with warm-ups and cool-downs of different shapes, and a third
    that wanders (a random walk), from 22-23 °C at rest."""
    rng = np.random.default_rng(seed)
    k = np.arange(N)
    a = 22.0 + 3.0 * (np.sin(k / 140.0) ** 2) + 0.5 * np.sin(k / 37.0)
    b = 23.0 + 2.0 * (k % 700 < 350) * (1 - np.exp(-(k % 350) / 60.0))
    c = 22.5 + np.cumsum(rng.normal(0, 0.01, N))
    return {"T_a_C": a, "T_b_C": b, "T_c_C": c}


def _lagged(u, tau_s):
    return lag_features(u[:, None], [u[0]], [tau_s], DT)[:, 1]


def test_recovers_a_known_lag_gain_and_a_raw_gain():
    """r = 1.7 µm/K · L_2h(ΔT_a) + 0.4 µm/K · ΔT_b + 0.02 µm noise, with the 2 h lag in
    the only bank offered: the CV keeps the model, and the two coefficients come back
    within 2 % (noise 0.3 % of the residual's range); the wandering thermometer gets
    less than 0.02 µm/K."""
    T = _thermometers()
    ref = {k: float(v[0]) for k, v in T.items()}
    rng = np.random.default_rng(3)
    r = (1.7 * _lagged(T["T_a_C"], 7200.0) + 0.4 * (T["T_b_C"] - ref["T_b_C"])
         + rng.normal(0, 0.02, N))
    rows = np.arange(N) > 0
    f = fit_thermometer_residual(r, T, dtau_s=DT, fit_rows=rows, reference_C=ref,
                                 banks_h=((2.0,),))
    assert f.active and f.taus_s == (7200.0,)
    i = {nm: j for j, nm in enumerate(f.names)}
    assert f.lag_um_K[i["T_a_C"]][0] == pytest.approx(1.7, rel=0.02)
    assert f.raw_um_K[i["T_b_C"]] == pytest.approx(0.4, rel=0.02)
    assert abs(f.raw_um_K[i["T_c_C"]]) + abs(f.lag_um_K[i["T_c_C"]][0]) < 0.02


@pytest.mark.parametrize("forward", [False, True])
def test_default_banks_recover_the_steady_gain(forward):
    """The same residual with every bank and λ of the pre-registered grids and either
    CV: the steady-state gain of T_a (raw + lags, µm/K) within 3 % of 1.7, and the
    prediction within 0.1 µm RMS of the noise-free residual (a 1.6 µm RMS signal)."""
    T = _thermometers()
    ref = {k: float(v[0]) for k, v in T.items()}
    clean = 1.7 * _lagged(T["T_a_C"], 7200.0) + 0.4 * (T["T_b_C"] - ref["T_b_C"])
    r = clean + np.random.default_rng(4).normal(0, 0.02, N)
    f = fit_thermometer_residual(r, T, dtau_s=DT, fit_rows=np.arange(N) > 0,
                                 reference_C=ref, forward=forward)
    j = f.names.index("T_a_C")
    assert f.active
    assert f.raw_um_K[j] + sum(f.lag_um_K[j]) == pytest.approx(1.7, rel=0.03)
    assert np.sqrt(np.mean((residual_simulate(f, T) - clean) ** 2)) < 0.1


@pytest.mark.parametrize("seed", [5, 8])
def test_declines_where_the_residual_is_not_in_the_thermometers(seed):
    """A residual of white noise (0.5 µm) that no thermometer explains: the
    forward-chaining CV either finds nothing better than "no correction" (the model
    is then exactly zero) or keeps only the most regularised fits, whose correction is
    under 5 % of the noise (RMS over every row)."""
    T = _thermometers()
    ref = {k: float(v.mean()) for k, v in T.items()}
    r = np.random.default_rng(seed).normal(0, 0.5, N)
    f = fit_thermometer_residual(r, T, dtau_s=DT, fit_rows=np.arange(N) > 0,
                                 reference_C=ref, forward=True)
    p = residual_simulate(f, T)
    if not f.active:
        assert f.cv_rms_um >= f.cv_zero_rms_um and np.all(p == 0.0)
    assert np.sqrt(np.mean(p ** 2)) < 0.025


def test_only_the_fit_rows_are_used():
    """Changing the residual outside ``fit_rows`` (the rows after an origin) changes
    nothing in the fit."""
    T = _thermometers()
    ref = {k: float(v[0]) for k, v in T.items()}
    r = 1.2 * (T["T_a_C"] - ref["T_a_C"]) + np.random.default_rng(6).normal(0, 0.05, N)
    rows = np.arange(N) < 2000
    rows[0] = False
    f1 = fit_thermometer_residual(r, T, dtau_s=DT, fit_rows=rows, reference_C=ref)
    r2 = r.copy()
    r2[2000:] = 1e3
    f2 = fit_thermometer_residual(r2, T, dtau_s=DT, fit_rows=rows, reference_C=ref)
    assert f1 == f2


def _fitted():
    T = _thermometers()
    ref = {k: float(v.mean()) for k, v in T.items()}
    r = (1.7 * _lagged(T["T_a_C"], 7200.0) - 0.6 * _lagged(T["T_b_C"], 1800.0)
         + np.random.default_rng(7).normal(0, 0.02, N))
    return T, fit_thermometer_residual(r, T, dtau_s=DT, fit_rows=np.arange(N) > 0,
                                       reference_C=ref)


def _stepped(model, inputs):
    """Compensator predictions for rows 1 … (row 0 is the rest replay starts from),
    through model.json and back."""
    c = Compensator(model_from_doc(model_to_doc(model)))
    n = len(next(iter(inputs.values())))
    return np.array([c.step({k: v[i] for k, v in inputs.items()}).predicted_growth_um
                     for i in range(1, n)])


def test_prediction_at_row_k_uses_nothing_after_k():
    """Causality: the thermometers after row k replaced by nonsense (+40 K) leave
    every prediction up to row k unchanged -- in the fitted model and in its export
    stepped by the compensator -- while row k + 1 does change (the test can fail)."""
    T, f = _fitted()
    k = 1700
    T2 = {nm: np.concatenate([v[:k + 1], v[k + 1:] + 40.0]) for nm, v in T.items()}
    p1, p2 = residual_simulate(f, T), residual_simulate(f, T2)
    assert np.array_equal(p1[:k + 1], p2[:k + 1]) and p1[k + 1] != p2[k + 1]
    first = {nm: float(v[0]) for nm, v in T.items()}
    m = residual_state_space(f, first)
    s1, s2 = _stepped(m, T), _stepped(m, T2)
    assert np.array_equal(s1[:k], s2[:k]) and s1[k] != s2[k]


def test_the_export_reproduces_the_fitted_model_exactly():
    """The state space (one state per thermometer and lag, raw through D), through
    model.json and stepped by the compensator from rest at row 0, equals the fitted
    model's prediction on rows 1 … to 1e-9 µm."""
    T, f = _fitted()
    assert f.active and len(f.taus_s) >= 1
    m = residual_state_space(f, {nm: float(v[0]) for nm, v in T.items()})
    assert m.n_states == len(f.names) * len(f.taus_s)
    np.testing.assert_allclose(_stepped(m, T), residual_simulate(f, T)[1:], atol=1e-9)


def test_parallel_sums_the_outputs_and_refuses_two_references():
    """Base (an AR(1) of a heat input) + residual model in parallel: the output is the
    sum of the two stepped apart, to 1e-9 µm; a thermometer read about two different
    references by the two models is refused (one line naming the input)."""
    T, f = _fitted()
    base = ar1_model(0.99, 2e-4, dtau_s=DT)
    q = np.where(np.arange(N) % 900 < 450, 2000.0, 0.0)
    res = residual_state_space(f, {nm: float(v[0]) for nm, v in T.items()})
    both = parallel_state_space(base, res)
    inputs = {"q_W_m2": q, **T}
    np.testing.assert_allclose(_stepped(both, inputs),
                               _stepped(base, {"q_W_m2": q}) + _stepped(res, T), atol=1e-9)
    import dataclasses
    other = dataclasses.replace(res, input_offsets={**res.input_offsets, "T_a_C": 0.0})
    with pytest.raises(InputError, match="T_a_C"):
        parallel_state_space(parallel_state_space(base, res), other)
