"""Issue 33 targets for the mesh diagnosis, printed (never asserted).

PRE-REGISTERED PROCEDURE (fixed on 2026-11-25 before the fresh batch was scored; the
engine is ``arfem.models.geodiagnosis.engine`` at the commit that adds this file;
anything changed after the first score is labelled post hoc in the commit and here):

* Plant: the spindle unit on the coarse mesh of the tests (tests/data/geodiag, 48 mm
  P1, for CPU on a shared 2-core machine), candidate groups spindle_bore and
  housing_outer, interface groups front_bearing and rear_bearing.
* Fresh batch: seeds 50000 + i (the tests use 1000-1099). For each noise kind (white
  0.3 µm / 0.03 K; random walk (0.05 σ per sample) on top of it; white quantised at
  4 σ) one record per single cause kind (convection_scale, source_scale, missing_source,
  contact_conductance, ambient_lag, sensor_drift, warm_start) with target and magnitude
  drawn at random (ranges in ``_draw``), one pair of two different kinds, and two clean
  records. 24 h at 2 min, the random duty cycle of ``synth.duty_cycle``. Full-order
  generation (a fresh Krylov basis at the changed operator).
* Scores: a record with hidden causes is right when the ESTABLISHED causes equal the
  hidden ones (kind and target); a clean record is right when nothing is established.
  Coverage: for every established hidden cause, whether the 95 % interval of its effect
  parameter (h_scale, scale, power_W, conductivity_scale, lag_h, drift_<u>_per_h,
  initial_offset_K) holds the true value. Compensation: on the hold-out, the RMS over
  the displacement channels of the extended model (where something is named, else the
  nominal) against the uncalibrated nominal model and against the MLR of paper eq. 18
  on the thermometers and the ambient, both fitted on the same window.
* Speed: a 48 h record at 1 min on the SHIPPED spindle unit (P2) with a hidden
  convection_scale, diagnosed by ``run_geodiagnosis`` end to end (reading, assembly,
  reduced model, diagnosis, error statement, writing); CPU (user + sys) and wall.

Targets (issue 33): >= 95 % right, 0 causes on clean records, coverage 92-98 %, 48 h in
<= 60 s, extended residual <= 25 % of the uncalibrated and below the MLR.

Usage: python benchmarks/bench_geodiagnosis.py [--batch] [--speed] [--n-noise K] [--seed0 S]

FIRST SCORING (2026-11-25, 21:05-21:24 UTC, load average 12-14 on the shared 2-core
machine; the engine at commit "a fit that is not physical is not a cause", which was
made on dev seed 2 before any fresh record was scored; nothing changed since):

* fresh batch, 30 records: causes named right on 15/24 records with causes (62 %;
  target >= 95 %: MISSED) -- white noise 8/8, random walk 1/8, quantised 6/8; by kind
  convection_scale 3/3, source_scale 2/3, missing_source 1/3, contact_conductance 2/3,
  ambient_lag 2/3, sensor_drift 2/3, warm_start 2/3. Under the random walk most records
  end "unconfirmed" (the walk-noise covariance widens the intervals to hold "no
  effect"), and two name a wrong cause (source_scale:motor for rear_bearing; an extra
  source_scale beside a warm start).
* clean records with a cause established: 1/6 (target 0: MISSED): a quantised record
  (quantum 1.2 µm) got sensor_drift on d_tcp_x_um, a channel the model holds near 0.
* 95 % interval coverage: 18/18 (100 %; target 92-98 %: above, i.e. conservative).
* extended / uncalibrated hold-out RMS over the displacement channels, median over the
  24 records with causes: 0.861 (target <= 0.25: MISSED; where a cause is small against
  0.3 µm noise both are near the noise floor), extended below the MLR of eq. 18 on 18/24.
* 48 h at 1 min on the shipped unit: CPU 74.4 s (user + sys), wall 227 s at load ~13
  (target <= 60 s: MISSED by CPU); assembly 55.6 s wall (elastic factorisation), reduced
  model 7.9 s, diagnosis 88.0 s wall; the reduced model's largest error against the
  full solve 0.0019 µm (TCP), 0.003 K (thermometers).
  Rerun at 21:37 UTC at load 1.1-3.2: CPU 68.3 s, wall 80.8 s (MISSED): assembly 17.6 s,
  reduced model 2.3 s, the diagnosis itself 27.8 s, the rest (~30 s) the error
  statement's full reference solve, the pictures and writing.

SECOND PRE-REGISTRATION (committed 2026-11-25 23:49:36 UTC, before any record of it was
generated or scored): after the first scoring the engine's procedure was changed on
development data only (seeds 1000-1099 and the spent 50000-50029): a noise model of
white noise plus a random walk fitted by REML and GLS on it, a practical-size floor on
quantised channels, the whiteness test's thinning, the hold-out choice only within
ΔBIC 10, the basis regrown before a second cause (engine commit fea7cce, "Mesh
diagnosis: clean records stay clean ..."; procedure in the docstring of
``arfem.models.geodiagnosis.engine``). The second batch:

* Fresh seeds 70000 + i, i = 0..29, never used before by any test, benchmark or
  development run; the same composition, drawing, plant and scores as the first
  (3 noise kinds × (7 single causes + 1 pair + 2 clean)), nothing else changed.
* Command: ``nice -n 10 python benchmarks/bench_geodiagnosis.py --batch --seed0 70000``
  run ONCE; the speed case separately with ``--speed``. Anything changed after it is
  labelled post hoc here and in the commit.

SECOND SCORING (2026-11-25, 23:49:38-00:01:35 UTC, load average 7.5 at the start, 5.7
at the end, on the shared 2-core machine; engine fea7cce, benchmark df229a1; command
``nice -n 10 /usr/bin/time -v python benchmarks/bench_geodiagnosis.py --batch --seed0
70000``, run once; 298 s CPU for the 30 records, 11:56 wall, 275 MB):

* causes named right on 21/24 records with causes (88 %; target >= 95 %: MISSED) --
  white noise 8/8, random walk 6/8 (first scoring 1/8), quantised 7/8; by kind
  convection_scale 3/3, source_scale 3/3, missing_source 3/3, contact_conductance 3/3,
  ambient_lag 3/3, sensor_drift 2/3, warm_start 2/3. The misses: 70015 (walk) named a
  sensor drift of d_tcp_z_um right but added convection_scale:shaft_exposed; 70016
  (walk) warm start 1.47 K "unconfirmed"; 70027 (quantised pair contact + warm start)
  "unconfirmed".
* clean records with a cause established: 1/6 (target 0: MISSED): 70019, a clean
  random-walk record, got sensor_drift on T_housing_C (a thermometer's walk taken for
  a drift). The quantised clean records are now "explained" (2/2), the white ones too.
* 95 % interval coverage: 22/24 (92 %; target 92-98 %: met at its lower edge; first
  scoring 18/18, conservative); the two misses are the pair of 70007 (white,
  convection_scale:shaft_exposed + contact_conductance:rear_bearing, both right, both
  intervals missing the truth).
* extended / uncalibrated hold-out RMS over the displacement channels, median over the
  24 records with causes: 0.287 (target <= 0.25: MISSED; first scoring 0.861); the
  extended model below the MLR of eq. 18 on 22/24. The extended model's hold-out RMS
  is at the noise floor (median 1.01 × the clean records' RMS of the same noise kind:
  0.293 µm white, 0.410 µm walk, 0.443 µm quantised), so the ratio cannot fall below
  floor/uncalibrated: on 11 of the 24 records the uncalibrated error is under 4 × the
  noise floor (causes drawn small against 0.3 µm noise: e.g. a warm start's
  0.33-0.46 µm, a front contact's 0.47-0.80 µm) and 0.25 is out of reach of any model;
  on the other 13 the median ratio is 0.135.

SPEED, today (``nice -n 10 /usr/bin/time -v python benchmarks/bench_geodiagnosis.py
--speed``, CPU of ``run_geodiagnosis`` alone as printed): at engine fea7cce 62.8 s CPU,
128 s wall (00:02 UTC, load 5.7) and 68.1 s CPU, 123 s wall (00:09 UTC, load 5.3):
MISSED; after e5dafa5 (post hoc, speed only: the modal amplitudes advanced by one
vectorised update per step instead of one lfilter call per mode, outputs equal to
1e-14) 50.1 s CPU, 79 s wall (00:13 UTC, load 5.2; target <= 60 s: met at this load)
-- wall steps: assembly 30.5 s, reduced model 3.8 s, diagnosis 29.9 s, the error
statement's reference solve ~12.5 s, writing ~2.4 s. The process's peak RSS is 4.9 GB
(the benchmark also generates the 48 h record with the full-order model). The error
statement's full reference solve was left as it is (scenarios/diagnosis/mesh.py); the
reduced model's largest error against it is 0.0019 µm (TCP), 0.003 K.

THIRD PRE-REGISTRATION (committed 2026-11-26 00:20 UTC, before any record of it was
generated): a replication of the second scoring's procedure, unchanged (engine fea7cce
plus only the speed change e5dafa5, equal to round-off): fresh seeds 80000 + i,
i = 0..29, never used before; same composition and scores; command ``nice -n 10
python benchmarks/bench_geodiagnosis.py --batch --seed0 80000``, run once.

THIRD SCORING (2026-11-26, 00:20:15-00:22:50 UTC, load average 2.1 at the start, 1.4
at the end; engine fea7cce + e5dafa5, benchmark e67aedd; ``nice -n 10 /usr/bin/time
-v python benchmarks/bench_geodiagnosis.py --batch --seed0 80000``, run once; 157 s
CPU for the 30 records, 2:35 wall, 279 MB):

* causes named right on 23/24 records with causes (96 %; target >= 95 %: met on this
  batch) -- white 8/8, random walk 7/8, quantised 8/8; every kind 3/3 as a single
  cause. The miss: 80017 (walk pair contact_conductance:front_bearing +
  missing_source:spindle_bore) named the contact right and source_scale:front_bearing
  for the missing source (and its contact interval missed the truth).
* clean records with a cause established: 0/6 (target 0: met on this batch); one
  clean quantised record (80028) is "not_explained", no cause named.
* 95 % interval coverage: 25/26 (96 %; target 92-98 %: met).
* extended / uncalibrated hold-out RMS median 0.226 (target <= 0.25: met on this
  batch, where fewer causes were small against the noise); extended below the MLR of
  eq. 18 on 21/24.
* Second and third scorings together (the same procedure, 60 fresh records): causes
  named right 44/48 (92 %: below the 95 % target), clean records with a cause 1/12
  (target 0: missed once), coverage 47/50 (94 %: within 92-98 %).

ANALYSIS OF THE TWO MISSES OF THE SECOND AND THIRD SCORINGS (2026-11-26, on them as
development data, reproduced through this file's own generation):

* 70019 (clean, walk): the thermometers' walk-to-white ratio, fitted by REML on the
  largest model, came out 0 (the displacements' 0.056, the truth 0.05): every
  thermometer's own offset and drift columns and the causes' smooth temperature columns
  absorb a weak walk (σ_w √480 ≈ σ_e over the fit window), and the restricted
  likelihood then has little left to see it. On that noise the F test of
  sensor_drift:T_housing_C gave p = 1e-27 for 0.0018 K/h, i.e. 0.028 K over 16 h, less
  than the walk's own excursion. On the channel alone, with the walk's strength
  profiled under each hypothesis, offset + drift against the walk alone gives p = 0.011
  (χ² on 2 df) -- no evidence at the naming level 0.01/19 = 5.3e-4. Flaw: a drift was tested
  against a walk strength fitted elsewhere, never against what the channel's own walk
  produces. Fix: ``engine.walk_explains`` (noise.drift_vs_walk_p) as a further
  condition on a sensor drift in the single and the pair screen, at the same level.
  Not fixed: the thermometers' ratio itself (0 on that record), so other causes' F
  tests there are still too sharp; 70019 now ends "unconfirmed" (a source scale of
  1.005 + an h of 1.01 named, refused by the hold-out gain), not "explained".
* 80017 (walk pair, front contact κ 0.22 + missing source 16.4 W in the spindle
  bore): forward selection named source_scale:front_bearing first (BIC 380 against
  932 for the contact alone: more heat at the front bearing stands in for the sum) and
  never revisited it; the right pair has BIC 1.4 against the named pair's 260 and a
  lower whitened hold-out error (1.010 against 1.087). Flaw: no backward step. Fix:
  ``engine._swap``: with the second cause kept, every other cause is screened as its
  partner by the pair screen's rules (the second's nonlinear parameter NOT held at its
  single fit: alone the contact fits at 0.51, beside the source at 0.22) and the best
  replaces the pair when its BIC is lower (hold-out within ΔBIC 10).
* Checked on development data after the fix (engine 75dd6b9, the same command with
  --seed0 70000 and 80000, 00:38-00:44 UTC, load ~3.3): 70000-: 21/24 right (the same
  three misses 70015, 70016, 70027 as in the second scoring; 70017 still right), clean
  with a cause 0/6 (was 1/6), coverage 22/24; 80000-: 24/24 right (was 23/24), clean
  0/6, coverage 27/27 (was 25/26); 192 s and 177 s CPU (was 298 s under more load and
  157 s). The spent 50000- batch was rerun alongside (below, after the scoring). A
  bug of the first version (the drift check also applied to the lead drift against
  its own fit, so 70017's contact was never added) was found on 70017 and fixed
  before this check.

FOURTH PRE-REGISTRATION (committed before any record of it was generated): the engine
at commit 75dd6b9 (the two fixes above, on development data only); fresh seeds
90000 + i, i = 0..29, never used before by any test, benchmark or development run;
the same composition, drawing, plant and scores as the first three; command ``nice -n
10 /usr/bin/time -v python benchmarks/bench_geodiagnosis.py --batch --seed0 90000``,
run ONCE. Anything changed after it is post hoc.

FOURTH SCORING (2026-11-26, 00:44:06-00:47:22 UTC, load average 2.7 at the start, 2.9
at the end (the spent 50000- batch and tests/test_geodiagnosis.py ran alongside at
lower priority); engine 75dd6b9, benchmark fc50bbc; ``nice -n 10 /usr/bin/time -v
python benchmarks/bench_geodiagnosis.py --batch --seed0 90000``, run once; 174.3 s CPU
(user + sys) for the 30 records, 3:16 wall, 311 MB):

* causes named right on 22/24 records with causes (92 %; target >= 95 %: MISSED) --
  white 8/8, random walk 8/8, quantised 6/8; every single kind 3/3 but
  contact_conductance 2/3. The misses, both quantised: 90023 (contact rear_bearing
  κ 0.41, uncalibrated hold-out RMS 0.442 µm, i.e. at the quantised noise floor
  ~0.44 µm: "not_explained", no cause named); 90027 (pair contact front_bearing κ 0.45
  + missing_source housing_outer 16.9 W) named convection_scale:column_faces +
  missing_source:spindle_bore, both wrong (not analysed: anything on it is post hoc).
* clean records with a cause established: 0/6 (target 0: met on this batch); 90019
  (walk) and 90029 (quantised) are "not_explained", no cause named.
* 95 % interval coverage: 23/24 (96 %; target 92-98 %: met); the miss 90010's h_scale.
* extended / uncalibrated hold-out RMS median 0.232 (target <= 0.25: met on this
  batch); extended below the MLR of eq. 18 on 22/24.
* Pooled over the second, third and fourth scorings (the second and third on engine
  fea7cce, the fourth on 75dd6b9: not one procedure): causes right 66/72 (92 %),
  clean records with a cause 1/18, coverage 70/74 (95 %).

After the scoring (development data now; no engine change): the spent 50000- batch on
engine 75dd6b9 (same command, --seed0 50000, 00:40-00:44 UTC, load ~3.3, 167.6 s CPU):
23/24 right (miss 50017, walk pair contact rear_bearing + ambient_lag named
ambient_lag alone), clean 0/6, coverage 26/26, ratio median 0.412, below the MLR 22/24.

ANALYSIS OF THE FOURTH SCORING'S TWO MISSES (2026-11-26, 00:50-00:56 UTC, on them as
development data, reproduced through this file's own generation: ``_draw``, the seed's
plan, ``duty_cycle``, ``generate``; both quantised at q = 1.2 µm / 0.12 K):

* 90023 (rear contact κ 0.41): the single screen ranked contact_conductance:rear_bearing
  first by far (BIC 13.3 against 86.9 for the next, F test p = 7e-62, fitted κ 0.398),
  and ``below_floor`` refused it: its effect stayed within half a quantum (0.6 µm,
  0.06 K) on every channel. Flaw: the floor was the half quantum whatever the noise
  ahead of the quantiser, while its own docstring gives the quantiser's slow bias for
  Gaussian noise σ as ~(q/π) exp(−2π²σ²/q²), 0.11 µm at σ = 0.3 µm: five times too
  high. Fix: ``engine.quantiser_bias`` (the bound Σ_k (q/πk) exp(−2π²k²σ²/q²), at most
  q/2), σ ahead of the quantiser = the channel's fitted white σ with the rounding's
  q²/12 taken out; the floor is that bias. The effect was NOT at the noise floor: the
  record shows it clearly once the floor is the quantiser's real bias. The noise
  variance itself did not ignore q²/12 (REML fits the total, 0.35-0.44 µm against the
  truth √(0.3² + 1.2²/12) = 0.46 µm; the q/√12 is a floor only).
* 90027 (front contact κ 0.45 + missing source 16.9 W in the housing): the best single
  was missing_source:spindle_bore (BIC 908; the true housing source second, 1024), its
  partner convection_scale:column_faces; ``_swap`` held that second and re-screened
  the first once, so neither true cause was ever a lead: the right pair (BIC 28,
  fitted 0.452 and 16.86 W) against the named 615. Flaw: a forward search from one
  lead, a backward step on one side only. Fix: ``engine._best_pair`` (when the named
  first has a partner, the same pair screen beside each other passing single of step
  3, at most three, the lowest BIC kept) and ``_swap`` revisiting both causes until
  nothing changes. A first version also paired the weaker leads when the first had no
  partner; on development records 90000, 70000, 80000 (single convections) it named
  pairs that ended unconfirmed, and it was withdrawn before any check was scored.
* Both fixes on development data only (engine 86999fd); tests
  ``test_quantiser_bias_bounds_the_mean_reading_error``,
  ``test_quantised_contact_at_its_true_size_is_named``,
  ``test_pair_out_of_reach_of_the_best_single_is_found``.
* Checked on development data (engine 86999fd, 00:56-01:07 UTC, the four batches at
  once, load 4.5-5.3; ``nice -n 10 /usr/bin/time -v python
  benchmarks/bench_geodiagnosis.py --batch --seed0 S``): 90000-: 24/24 right (was
  22/24), clean 0/6, coverage 26/27, 208.8 s CPU; 70000-: 22/24 (was 21/24: 70027, a
  quantised contact + warm start, now right; 70015 and 70016, both walk, still
  missed), clean 0/6, coverage 24/26, 256.4 s CPU; 80000-: 24/24, clean 0/6,
  coverage 27/27, 210.5 s CPU; 50000-: 23/24 (50017 still missed), clean 0/6,
  coverage 26/26, 197.2 s CPU. No record right before is wrong now.

FIFTH PRE-REGISTRATION (committed 2026-11-26 ~01:08 UTC, before any record of it was
generated): the engine at commit 86999fd (the two fixes above, on development data
only); fresh seeds 100000 + i, i = 0..29, never used before by any test, benchmark or
development run; the same composition, drawing, plant and scores as the first four;
command ``nice -n 10 /usr/bin/time -v python benchmarks/bench_geodiagnosis.py --batch
--seed0 100000``, run ONCE. Anything changed after it is post hoc.

FIFTH SCORING (2026-11-26, 01:07:47-01:11:18 UTC, load average 1.8 at the start, 2.8
at the end (tests/test_geodiagnosis.py ran alongside at lower priority); engine
86999fd, benchmark 2645dbe; ``nice -n 10 /usr/bin/time -v python
benchmarks/bench_geodiagnosis.py --batch --seed0 100000``, run once; 185.1 s CPU (user
+ sys) for the 30 records, 3:31 wall, 310 MB):

* causes named right on 22/24 records with causes (92 %; target >= 95 %: MISSED) --
  white 8/8, random walk 7/8, quantised 7/8; every single kind 3/3 but warm_start
  2/3. The misses: 100016 (walk, warm start 2.11 K: "unconfirmed", nothing
  established, as 70016 on development data); 100027 (quantised pair missing_source
  spindle_bore 10.2 W + warm start 1.69 K) named missing_source:housing_outer alone
  (not analysed: anything on it is post hoc).
* clean records with a cause established: 0/6 (target 0: met); 100028 (quantised)
  "not_explained", no cause named.
* 95 % interval coverage: 22/24 (92 %; target 92-98 %: met at its lower edge); the
  misses 100012's power_W (walk) and 100026's initial_offset_K (quantised).
* extended / uncalibrated hold-out RMS median 0.282 (target <= 0.25: MISSED); extended
  below the MLR of eq. 18 on 22/24.

ANALYSIS OF THE REMAINING MISSES (2026-11-26, 01:55-02:40 UTC, every batch above now
development data; reproduced through this file's own generation). Four flaws of the
procedure, each fixed as a procedure (no threshold moved, no seed special-cased):

* 100016 and 70016 (walk, warm starts 2.11 K and 1.47 K, both named at the truth with
  tight intervals, left "unconfirmed"): the verdict's hold-out check used the raw
  weighted RMS, which under a random walk is mostly the walk's level on the hold-out
  (100016: -10.8 % on it, from T_housing_C 0.032 -> 0.057 K) while the whitened
  one-step error, step 3's own score, fell (0.981 -> 0.975). Fix: the check is on the
  whitened hold-out (``Diagnosis.holdout.gain_whitened_pct``); the raw gain is still
  reported.
* 100027 (quantised pair missing source spindle_bore + warm start, named a housing
  source alone): beside the housing source the lowest-BIC partner (a bore convection,
  BIC 553) failed the hold-out and ``_second`` returned nothing; the warm start (BIC
  700, whitened hold-out 1.35 against the single's 4.88) was never tried. Fix: the
  passing partners are tried in BIC order, the first whose pair lowers the whitened
  hold-out kept. The beam then reaches the true pair (BIC 3.3).
* 70015 (walk, sensor drift d_tcp_z 0.13 µm/h, named with an extra shaft convection
  h 0.94): the thermometers' walk ratio, fitted once on the largest model, came out a
  tenth of the truth, and the convection (the best single by the hold-out within
  ΔBIC 10) stood in for the drift on the thermometers' wander; no step ever dropped a
  cause. A per-channel median ratio without the sensors' own columns was tried and
  withdrawn (it lost the drift itself: the displacements' ratio swelled to 4x the
  truth). Fix: a partner must also pass a likelihood-ratio test with each sensor
  kind's walk ratio re-fitted under both models (``engine.walk_profiled_p``), and at
  the end each cause of a pair is tested against the other alone by the F test and
  that test, the weaker dropped when it fails either (``engine._prune``, the backward
  step of stepwise selection).
* 70007 (white pair shaft convection 0.44 + rear contact 0.27, both intervals missing
  the truth): two coordinate sweeps stopped short in the correlated valley (weighted
  SSE 2879.8 at 0.458 / 0.311, 2870.7 at the truth). Fix: the named fit of two
  nonlinear parameters is polished jointly (Nelder-Mead on their logarithms).

Not fixed: 50017 (walk pair rear contact κ 0.36 + ambient lag 3.8 h named the lag
alone): beside the lag the contact's F test gives p = 0.044 on the fit window, no
evidence at the naming level; its noise-free residual after the lag is 0.084 µm against
the walk's 0.41 µm floor.

The benchmark now also prints the residuals against the noise-free readings
(``synth.signal``; ``generate`` is ``add_noise`` of it, its random draws unchanged):
what the compensation leaves on the machine. The measured ratio above cannot fall below
the probes' noise over the uncalibrated error; the noise-free one can. It counts a
sensor's drift as what that sensor reads.

Checked on development data, engine at the commit that adds this paragraph (the
whitened verdict and the partner order at 346d695, the polish at e39e8f5, the profiled
test and the prune after; ``nice -n 5 python benchmarks/bench_geodiagnosis.py --batch
--seed0 S``, 02:18-02:40 UTC, two at a time): 50000- 23/24 (50017), 70000- 24/24,
80000- 24/24, 90000- 24/24, 100000- 24/24; clean records with a cause 0/30;
coverage 26/26, 27/27, 27/27, 26/27, 25/27 (131/134, 98 %).

SIXTH PRE-REGISTRATION (committed before any record of it was generated): the engine at
the commit that adds this paragraph; THREE fresh batches, seeds 110000 + i, 110030 + i
and 110060 + i, i = 0..29 (90 records: 72 with causes, 18 clean), never used before by
any test, benchmark or development run; the same composition, drawing, plant and scores
as the first five, plus the noise-free residual ratio (median over the records with a
cause, target <= 0.25) and the extended model below the MLR against the noise-free
readings. Commands, each run ONCE: ``nice -n 5 /usr/bin/time -v python
benchmarks/bench_geodiagnosis.py --batch --seed0 S`` for S = 110000, 110030, 110060
(two at a time on the 2-core machine). The score is the three pooled; each batch is
reported too. Anything changed after it is post hoc.

SIXTH SCORING (2026-11-26, 02:34:58-02:42:02 UTC, load average 0.9 at the start, 3.0
at its peak; engine 5c6242a; the three commands above, each run once, 110000- and
110030- together, then 110060-; 199.5 s, 192.9 s and 187.4 s user CPU, 3:30, 3:23 and
3:04 wall, 303-305 MB each):

* causes named right on 70/72 records with causes (97 %; target >= 95 %: MET) --
  per batch 24/24, 23/24, 23/24; white 24/24, random walk 22/24, quantised 24/24;
  every single kind 9/9 but sensor_drift 8/9. The misses, both random walk: 110045
  (a drift of 0.100 µm/h on d_tcp_z, the smallest the benchmark draws: "explained",
  nothing named) and 110077 (pair rear-bearing source × 0.53 + a missing source of
  11.9 W in the spindle bore, named source_scale:front_bearing alone). Not analysed
  beyond these lines: anything on them is post hoc.
* clean records with a cause established: 0/18 (target 0: MET).
* 95 % interval coverage: 73/78 (94 %; target 92-98 %: MET) -- per batch 24/27 (89 %),
  26/26, 23/25; four of the five misses are random-walk records (110010 h_scale,
  110013 conductivity_scale, 110016 and 110076 initial_offset_K), one quantised
  (110080 h_scale).
* extended / uncalibrated hold-out RMS against the record, median over the 72: 0.345
  (per batch 0.313, 0.423, 0.412; target <= 0.25: MISSED as measured against the
  noisy record); at most 0.25 on 30/72; on the 31 records whose uncalibrated error is
  at least 4x the clean records' noise floor of its kind (0.29 / 0.41 / 0.44 µm) the
  median is 0.121. Against the noise-free readings (the residual left on the machine)
  the median is 0.0033 (per batch 0.004, 0.002, 0.006; target <= 0.25: MET), at most
  0.25 on 70/72 (the two misses, where nothing or the wrong cause was named).
* extended below the MLR of eq. 18: 63/72 against the record, 71/72 against the
  noise-free readings (110045, where nothing was named).
* 48 h at 1 min on the shipped unit, the same engine (``/usr/bin/time -v python
  benchmarks/bench_geodiagnosis.py --speed``, 02:42:42 UTC, load 0.5): 45.0 s CPU,
  44.0 s wall for ``run_geodiagnosis`` (target <= 60 s: MET): assembly 13.8 s,
  reduced model 2.3 s, diagnosis 19.6 s, export and replay 2.5 s; the process's peak
  RSS 4.86 GB (the benchmark also generates the record with the full-order model).
  The command itself on that record (``farm-bench -n 3 -- sh -c 'rm -rf OUT; exec
  arfem diagnose rec48.toml --out OUT'``, 02:50 UTC, load < 1): median 44.5 s CPU,
  43.4 s wall, 2.61 GB peak.

After the sixth scoring (post hoc; neither changes a score, which counts established
causes only): the verdict's text prints parameters and intervals to 4 significant
digits instead of 3 (commit b6270e6); and a channel whose whitened nominal residual has
fewer than 10 effective samples is no longer skipped by the "within the noise" test of
``explained`` (p = 0 instead of NaN: found by an audit, a thermometer 30 σ off counted
as within the noise), so such a record reads ``not_explained``, not ``explained``.

The sixth batch re-run on the engine of 2026-11-28 (one verdict module for every plant,
the whole model searched by default unless ``[diagnosis]`` narrows it, equal
alternatives, the pipeline over a plant and its thermometer check with the walk in both
hypotheses; DEVELOPMENT data now, so post hoc; the three commands above, 02:09-02:21 UTC,
each once): the same scores as the sixth scoring -- 70/72 right (24/24, 23/24, 23/24;
the same two misses, 110045 and 110077), 0/18 clean records with a cause, coverage
73/78; residual ratio against the record, per batch 0.313, 0.423, 0.412 (was pooled
0.345), against the noise-free readings 0.004, 0.002, 0.006. Clean records' verdicts:
16 explained, 2 not_explained (one walk, one quantised), none with a cause.
"""
from __future__ import annotations

import argparse
import resource
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from arfem.models.geodiagnosis.engine import diagnose_geometry, mlr_holdout
from arfem.models.geodiagnosis.problem import make_record
from arfem.models.geodiagnosis.synth import (NOISE_KINDS, Hidden, add_noise, covers,
                                             duty_cycle, generate, signal)
from arfem.scenarios.diagnosis.mesh_model import load_diagnosis_scenario, plant_of, reduced_model

ROOT = Path(__file__).resolve().parents[1]
COARSE = ROOT / "tests" / "data" / "geodiag" / "spindle_coarse.toml"
KINDS = ("convection_scale", "source_scale", "missing_source", "contact_conductance",
         "ambient_lag", "sensor_drift", "warm_start")


def _draw(rng, kind, plant, model) -> Hidden:
    if kind == "convection_scale":
        return Hidden(kind, str(rng.choice(plant.convections)),
                      float(rng.choice([rng.uniform(0.4, 0.65), rng.uniform(1.6, 2.5)])))
    if kind == "source_scale":
        return Hidden(kind, str(rng.choice(plant.sources)),
                      float(rng.choice([rng.uniform(0.5, 0.7), rng.uniform(1.4, 1.8)])))
    if kind == "missing_source":
        return Hidden(kind, str(rng.choice(model.candidates)), float(rng.uniform(8.0, 20.0)))
    if kind == "contact_conductance":
        return Hidden(kind, str(rng.choice(model.interfaces)), float(rng.uniform(0.2, 0.5)))
    if kind == "ambient_lag":
        return Hidden(kind, "", float(rng.uniform(1.0, 4.0)))
    if kind == "sensor_drift":
        return Hidden(kind, "d_tcp_z_um", float(rng.choice([-1, 1]) * rng.uniform(0.1, 0.3)))
    return Hidden(kind, "", float(rng.uniform(1.0, 3.0)))


def _score(d, hidden, rec, truth=None) -> dict:
    """One record's scores; ``truth`` (N, r), the noise-free readings, adds the
    residuals against it (``*_true``): what the compensation leaves on the machine,
    the probes' noise taken out."""
    est = {(c.cause, c.target) for c in d.established}
    truth_set = {(h.kind, h.target) for h in hidden}
    cover = []
    if d.verdict == "established":
        cover = [c for c in (covers(d.causes, h) for h in hidden) if c is not None]
    train = rec.time_s < d.holdout.start_s
    hold = ~train
    mlr = mlr_holdout(rec, train)
    disp = [j for j, c in enumerate(rec.channels) if c.kind == "displacement"]
    ext = d.series["extended"] if d.established else d.series["baseline"]

    def rms(P, Y=rec.data):
        return float(np.sqrt(np.mean((Y[hold][:, disp] - P[hold][:, disp]) ** 2)))
    m = np.column_stack([mlr[rec.channels[j].column] for j in disp]) if mlr else None
    mp = np.zeros_like(rec.data)
    if m is not None:
        mp[:, disp] = m
    out = {"right": est == truth_set, "established": sorted(est), "verdict": d.verdict,
           "cover": cover, "base": rms(d.evidence.baseline.prediction), "ext": rms(ext),
           "mlr": rms(mp) if m is not None else float("nan")}
    if truth is not None:
        out.update(base_true=rms(d.evidence.baseline.prediction, truth), ext_true=rms(ext, truth),
                   mlr_true=rms(mp, truth) if m is not None else float("nan"))
    return out


def batch(n_noise: int, seed0: int = 70000) -> None:
    sc, spec = load_diagnosis_scenario(COARSE)
    plant, _ = plant_of(sc)
    model, _ = reduced_model(plant, sc, spec, 8000.0)
    rows, seed = [], seed0
    for noise in NOISE_KINDS[:n_noise]:
        plans = [[k] for k in KINDS] + [["pair"], [], []]
        for plan in plans:
            rng = np.random.default_rng(seed)
            if plan == ["pair"]:
                a, b = rng.choice(len(KINDS), 2, replace=False)
                hidden = [_draw(rng, KINDS[a], plant, model), _draw(rng, KINDS[b], plant, model)]
            else:
                hidden = [_draw(rng, k, plant, model) for k in plan]
            t, speed, power, amb = duty_cycle(rng, 24.0, 120.0, plant.sources)
            clean = signal(plant, hidden, t, speed, power, amb)
            y = add_noise(plant, clean, rng, noise)
            rec = make_record(f"s{seed}", t, y, plant.columns, plant.names, plant.kinds, power,
                              speed, amb, plant.reference_C)
            c0 = time.process_time()
            d = diagnose_geometry(model, rec)
            s = _score(d, hidden, rec, clean)
            s.update(seed=seed, noise=noise, hidden=[(h.kind, h.target, round(h.value, 3))
                                                   for h in hidden],
                     cpu_s=time.process_time() - c0)
            rows.append(s)
            print(f"{seed} {noise:9s} hidden={s['hidden']} -> {s['verdict']} "
                  f"{s['established']} right={s['right']} cover={s['cover']} "
                  f"rms base/ext/mlr {s['base']:.3f}/{s['ext']:.3f}/{s['mlr']:.3f} µm "
                  f"(noise-free {s['base_true']:.3f}/{s['ext_true']:.3f}/{s['mlr_true']:.3f}) "
                  f"cpu {s['cpu_s']:.1f} s", flush=True)
            seed += 1
    caused = [r for r in rows if r["hidden"]]
    clean = [r for r in rows if not r["hidden"]]
    cov = [c for r in rows for c in r["cover"]]
    print(f"\nrecords with causes named right: {sum(r['right'] for r in caused)}/{len(caused)} "
          f"({100 * np.mean([r['right'] for r in caused]):.0f} %; target >= 95 %)")
    print(f"clean records with a cause established: "
          f"{sum(bool(r['established']) for r in clean)}/{len(clean)} (target 0)")
    if cov:
        print(f"95 % interval coverage: {sum(cov)}/{len(cov)} ({100 * np.mean(cov):.0f} %; "
              "target 92-98 %)")
    ratio = [r["ext"] / r["base"] for r in caused if r["base"] > 0]
    below = [r["ext"] < r["mlr"] for r in caused if np.isfinite(r["mlr"])]
    print(f"extended / uncalibrated hold-out RMS (displacements), median over records with a "
          f"cause: {np.median(ratio):.3f} (target <= 0.25); extended below the MLR on "
          f"{sum(below)}/{len(below)}")
    ratio_t = [r["ext_true"] / r["base_true"] for r in caused if r["base_true"] > 0]
    below_t = [r["ext_true"] < r["mlr_true"] for r in caused if np.isfinite(r["mlr_true"])]
    print(f"the same against the noise-free readings (the residual the compensation leaves on "
          f"the machine): median {np.median(ratio_t):.3f} (target <= 0.25), at most 0.25 on "
          f"{sum(x <= 0.25 for x in ratio_t)}/{len(ratio_t)}; extended below the MLR on "
          f"{sum(below_t)}/{len(below_t)}")
    print("by cause kind (right/records):")
    for k in KINDS:
        rk = [r for r in caused if len(r["hidden"]) == 1 and r["hidden"][0][0] == k]
        print(f"  {k:20s} {sum(r['right'] for r in rk)}/{len(rk)}")


def speed() -> None:
    """48 h at 1 min on the shipped spindle unit, end to end through the command's
    library function."""
    from arfem.scenarios.diagnosis.mesh import run_geodiagnosis
    from arfem.scenarios.records.georecord import write_record
    tmp = Path(tempfile.mkdtemp(prefix="bench_geodiag_"))
    try:
        shutil.copy(ROOT / "scenarios" / "data" / "spindle_unit.msh", tmp)
        text = (ROOT / "scenarios" / "data" / "spindle_unit.toml").read_text()
        (tmp / "spindle_unit.toml").write_text(
            text + '\n[diagnosis]\ncandidate_groups = ["spindle_bore", "housing_outer"]\n'
                   'interface_groups = ["front_bearing", "rear_bearing"]\n')
        sc, spec = load_diagnosis_scenario(tmp / "spindle_unit.toml")
        plant, _ = plant_of(sc)
        rng = np.random.default_rng(60000)
        t, sp, power, amb = duty_cycle(rng, 48.0, 60.0, plant.sources)
        y = generate(plant, [Hidden("convection_scale", "housing_outer", 1.8)], t, sp, power,
                     amb, rng, "white")
        cols = {"time_s": t, "speed_rpm": sp, "ambient_C": amb}
        cols.update({c: y[:, j] for j, c in enumerate(plant.columns)})
        cols.update({f"P_{s}_W": power[:, j] for j, s in enumerate(plant.sources)})
        toml = write_record(tmp / "rec48.toml", "spindle_unit.toml", cols)
        r0 = resource.getrusage(resource.RUSAGE_SELF)
        w0 = time.perf_counter()
        s = run_geodiagnosis(toml, tmp / "out")
        wall = time.perf_counter() - w0
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
        print(f"48 h at 1 min ({t.size} rows, 6 channels) on the shipped spindle unit "
              f"({plant.body.ndofs} heat dofs, P2): verdict {s['verdict']}, cause "
              f"{s['cause']}; CPU {cpu:.1f} s, wall {wall:.1f} s (target <= 60 s); "
              f"steps {({k: round(v, 1) for k, v in s['timings_s'].items()})}")
        print(f"reduced model: {s['reduced_model']['basis_vectors']} vectors; largest error "
              f"vs the full solve: {s['reduced_model']['max_abs_error']} (µm / K)")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--batch", action="store_true")
    ap.add_argument("--speed", action="store_true")
    ap.add_argument("--n-noise", type=int, default=3)
    ap.add_argument("--seed0", type=int, default=70000,
                    help="first seed of the batch (50000: the first scoring's, now spent)")
    a = ap.parse_args()
    if a.speed or not a.batch:
        speed()
    if a.batch or not a.speed:
        batch(a.n_noise, a.seed0)
