"""Issue 43 item 2: the extended model with its thermometers used online, on FL_THERMAL.

PRE-REGISTRATION, PART 1 (development protocol), committed before any development run
and before any score of the new model on the 50 scored (channel, origin) pairs.

What is scored (fixed by peers.py, not by this script): the 10 rolling origins of
rolling.md (speed steps from 16.13 h on: 16.13, 20.13, 24.13, 28.13, 32.13, 36.13,
40.13, 42.13, 44.13, 45.13 h) × 5 channels = 50 pairs; each model fitted on the rows
before the origin (``regenerate.origin_dataset``: the growth from the origin on hidden),
replayed by the causal ``replay`` of ``arfem compensate`` from t = 0, RMS of measured
growth + offset over the block to the next origin. The peers' and the extended model's
scores on these pairs are already published in peers.md (known when this was written);
the new model's are not computed before PART 2 is committed.

Development data (never scored): everything before 16.13 h. Two development origins,
the speed steps at 8.13 h (fit on t < 8.13 h, judged on 8.13-12.13 h, 2500 1/min, a
speed the fit has not seen) and 12.13 h (fit on t < 12.13 h, judged on 12.13-16.13 h,
the cooling after 2500 1/min), × 5 channels = 10 development pairs; plus time-blocked
cross-validation inside each fit window. Every design choice (the residual model's
inputs, its filter bank, its regularisation rule, its fallback) is made on these and
written into PART 2 (below, replacing this paragraph's "to be fixed") before the
scoring run. The scoring run is done once; anything changed after it is labelled post
hoc with the pre/post comparison in thermometers.md.

Observer or residual model: the extended model the diagnosis exports for this record
(``speed_state_space``: a speed AR(1) state plus lagged principal components of the 16
thermometers) reads the thermometers as inputs and has one output, the growth; it has
no output equation for any thermometer, so there is nothing for an observer to compare
a thermometer with. The thermometers are therefore used as inputs of a residual model
(PART 2: to be fixed on the development data).
"""
