"""The speed-only plant's frame on thermometers (issue 41): a thermometer smoothed before
it is a regressor, and a frame on the principal components of many thermometers.

* :func:`arfem.models.diagnosis.speed_frame.centred_mean` adds no lag (a ramp comes out
  as itself away from the ends) and cuts the noise of a differenced white series by the
  window's sample count: the property the errors-in-variables fix rests on;
* on synth_speed's frame record of seed 4 with its own AR(1) noise the frame's gain per
  kelvin is named and its interval holds the truth (before the smoothing: −0.50 µm/K
  [−1.00, −0.00] for −3.37, the thermometer's noise drawing the gain to zero);
* a record of more than :data:`~arfem.models.diagnosis.speed_plant.PER_THERMOMETER_FRAMES`
  thermometers offers one frame on their leading components (with and without a lag),
  not one per thermometer, and a frame growing as a mix of two of eight thermometers
  is named on them and established;
* synth_speed's records of one thermometer are unchanged by the option of several.
"""
from __future__ import annotations

import numpy as np

from arfem.models.diagnosis.speed_frame import centred_mean
from arfem.models.diagnosis.speed_plant import (FRAME_COMPONENTS, PER_THERMOMETER_FRAMES,
                                                speed_plant)
from arfem.models.diagnosis.synth_speed import generate_speed
from arfem.models.geodiagnosis.engine import diagnose_plant
from arfem.models.plant import components_target


def test_centred_mean_adds_no_lag_and_cuts_the_differenced_noise():
    """A ramp is returned exactly where the window is whole (a centred mean of a linear
    series is its middle value: no lag, to rounding); a white series differenced after
    a mean over 7 samples has its σ cut about 7-fold (the differenced mean is
    (x_{k+4} − x_{k−3})/7: σ √2/7 against σ √2; tolerance ±15 % on 20 000 samples)."""
    t = np.arange(20000) * 120.0
    ramp = 0.3 * t / 3600.0
    out = centred_mean(t, ramp, 360.0)
    assert np.allclose(out[3:-3], ramp[3:-3], rtol=0, atol=1e-9)
    x = np.random.default_rng(0).normal(0.0, 1.0, t.size)
    ratio = np.std(np.diff(x)) / np.std(np.diff(centred_mean(t, x, 360.0)))
    assert 7.0 / 1.15 < ratio < 7.0 * 1.15, ratio


def _plant(case, y=None):
    amb = None if case.ambient_K is None else 20.0 + case.ambient_K
    return speed_plant("r", case.time_s, case.growth_um if y is None else y,
                       case.speed_rpm, case.temperatures, amb)


def test_a_frame_under_ar_noise_keeps_its_gain_per_kelvin():
    """synth_speed frame seed 4 (its AR(1) noise, ρ 0.80, σ 0.14 µm; the frame's gain
    per kelvin of T_frame_C −3.37 µm/K) is established as the lag-free frame on its
    thermometer, the GLS 95 % interval holding the truth (the interval is the
    tolerance)."""
    from arfem.models.diagnosis.forward import first_order_lag
    case = generate_speed("frame_expansion", 4)
    s, tr = case.settings, case.truth
    frame = first_order_lag(case.time_s, (case.speed_rpm / s["n_max_rpm"]) ** (5.0 / 3.0),
                            tr["frame_time_constant_h"] * 3600.0)
    per_unit = np.linalg.lstsq(frame[:, None], case.temperatures["T_frame_C"] - 20.0,
                               rcond=None)[0][0]
    truth = tr["frame_gain"] * s["steady_growth_um"] / per_unit
    d = diagnose_plant(_plant(case), case.holdout_start_s)
    assert d.verdict == "established", d.text
    assert [c.name for c in d.causes] == ["frame_expansion:T_frame_C"], d.text
    lo, hi = d.causes[0].ci95["frame_gain_um_per_K"]
    assert lo <= truth <= hi, (d.causes[0].parameters, truth)


def test_many_thermometers_offer_one_frame_on_their_components():
    """Eight thermometers: a frame on their leading components with and without a lag,
    one gain per component; three or fewer: one frame per thermometer as before."""
    case = generate_speed("sensor_drift", 1, thermometers=8)
    names = [c.name for c in _plant(case).candidate_causes()]
    k = max(FRAME_COMPONENTS)
    assert [n for n in names if n.startswith("frame")] == \
        [f"{kind}:{components_target(j)}" for j in FRAME_COMPONENTS
         for kind in ("frame_expansion", "frame_lag")]
    lag = next(c for c in _plant(case).candidate_causes() if c.kind == "frame_lag")
    assert [p.name for p in lag.linear_parameters] == \
        [f"frame_gain_pc{j}_um" for j in range(1, k + 1)]
    few = generate_speed("sensor_drift", 1, thermometers=PER_THERMOMETER_FRAMES)
    assert sum(n.startswith("frame") for n in
               (c.name for c in _plant(few).candidate_causes())) == 2 * PER_THERMOMETER_FRAMES


def test_a_frame_on_a_mix_of_two_of_eight_thermometers_is_named_on_their_components():
    """synth_speed frame seed 1 with eight thermometers (two on the machine's heat, fast
    and slow, two more mixes, four of the room; the frame a mix of the first two, its
    AR(1) noise): the frame on the components is established, and its prediction of
    the hold-out is within 3 noise σ of the noise-free growth (the frame part is a
    sixth of the growth there)."""
    case = generate_speed("frame_expansion", 1, thermometers=8)
    d = diagnose_plant(_plant(case), case.holdout_start_s)
    assert d.verdict == "established", d.text
    on = components_target(max(FRAME_COMPONENTS))
    assert [c.name for c in d.causes] == [f"frame_expansion:{on}"], d.text
    clean = generate_speed("frame_expansion", 1, noise_um=0.0, thermometers=8).growth_um
    hold = case.time_s >= case.holdout_start_s
    err = d.series["extended"][hold, 0] - clean[hold]
    assert np.sqrt(np.mean(err ** 2)) < 3.0 * case.settings["noise_sigma_um"], err


def test_synth_records_of_one_thermometer_are_unchanged_by_the_option_of_several():
    """thermometers=1 is the record as before (same growth, same one thermometer);
    thermometers=8 leaves a drift record's growth as it was and adds T_t1_C..T_t8_C."""
    a, b = generate_speed("frame_expansion", 3), generate_speed("frame_expansion", 3,
                                                                 thermometers=1)
    assert np.array_equal(a.growth_um, b.growth_um) and list(b.temperatures) == ["T_frame_C"]
    c = generate_speed("sensor_drift", 3, thermometers=8)
    assert np.array_equal(c.growth_um, generate_speed("sensor_drift", 3).growth_um)
    assert list(c.temperatures) == [f"T_t{j}_C" for j in range(1, 9)]
