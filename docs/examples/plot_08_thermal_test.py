"""
An ISO 230-3 thermal test of the spindle unit: five quantities, bearing heat from the speed
===========================================================================================

ISO 230-3 measures a spindle's thermal drift as a machine shop records it: the spindle
runs at a constant speed, then stands still, while five quantities are read at a test
mandrel, all zeroed at the start: the displacements X, Y and Z and the tilts A (about
X) and B (about Y), each tilt from two probes. This example runs that test on the
shipped spindle unit (``scenarios/iso230_3/iso230_3_spindle_unit.toml``): the bearings'
friction heat follows the speed through Palmgren's friction moment and is generated in
the rings' volumes, the motor's losses in the stator's volume. It ends with the
standard's figures: each quantity's drift over time and its maxima over the test.

From the command line, the same (with the shipped P2 elements; this page uses P1 on the
same mesh so that it builds in seconds)::

    arfem run scenarios/iso230_3/iso230_3_spindle_unit.toml --out out/iso
    python -m arfem.scenarios.thermal_test out/iso/record.toml --out out/iso_report

:doc:`../thermal-test` explains every key.
"""
# %%
# Heat from the speed: the bearing model
# --------------------------------------
# The front bearing set is a preloaded pair of 7014 (pitch diameter 90 mm) under
# oil-air. Palmgren's friction moment M = 1e-7·f0·(ν·n)^(2/3)·dm³ + f1·P1·dm [N·mm]
# (ν in mm²/s, n in rpm, dm in mm) turns at ω = 2πn/60 into P = M·ω; the scenario lets
# 10 % of it into the structure (``scale = 0.1``), the rest leaving with the air-oil and
# the cooling jacket. The values of f0, f1 and the preload are assumptions.
import matplotlib.pyplot as plt
import numpy as np

from arfem.models.bearing import PalmgrenBearing
from arfem.models.thermal_test import thermal_test
from arfem.scenarios.config import builtin_scenario_path
from arfem.scenarios.geometry_scenario import load_geometry_scenario, solve_geometry
from arfem.scenarios.geometry_scenario import build_geometry_model
from arfem.scenarios.thermal_test import thermal_test_figure

front = PalmgrenBearing(f0=1.0, nu_mm2_s=10.0, dm_mm=90.0, f1=3.2e-4, P1_N=1000.0, count=2)
n = np.linspace(0.0, 15000.0, 151)
fig, ax = plt.subplots(figsize=(6.5, 3.2), layout="constrained")
ax.plot(n, front.power_W(n), label="friction of the pair")
ax.plot(n, 0.1 * front.power_W(n), label="into the structure (scale 0.1)")
ax.set_xlabel("spindle speed [rpm]")
ax.set_ylabel("power [W]")
ax.legend()
ax.grid(alpha=0.3)
print(f"front pair at 8000 rpm: M = {float(front.moment_Nmm(8000.0)):.0f} N·mm, "
      f"P = {float(front.power_W(8000.0)):.0f} W")

# %%
# The test, solved
# ----------------
# Four hours at 8000 rpm, then two hours stopped. The five quantities are sensors of the
# scenario: X, Y and Z at the nose (z = −80 mm), A and B tilts from two points 60 mm
# apart on the shaft's free end (``quantity = "tilt"``, reported in µrad). P1 elements
# here (the file says P2).
path = builtin_scenario_path("spindle_unit").parent / "iso230_3" / "iso230_3_spindle_unit.toml"
sc = load_geometry_scenario(path)
sc = type(sc)(**{**sc.__dict__, "order": 1, "picture": False})
for s in sc.sources:
    law = s.law.describe() if s.law is not None else "schedule"
    print(f"{s.spec.name:<14} in {s.spec.group:<14} {law}, × {s.scale:g}")
for s in sc.sensors:
    if s.quantity == "tilt":
        print(f"tilt {s.name}: about {np.round(s.about, 3) + 0.0} over {s.base_m * 1e3:.0f} mm")
run = solve_geometry(build_geometry_model(sc))
series = run.sensor_series()

# %%
# The standard's figures
# ----------------------
# Every quantity as its drift from the start (the probes' zero), the speed below; the
# table gives each one's largest drift over the test, when, its range, and where it
# stood when the spindle stopped and at the end.
tt = thermal_test(run.result.times_s, series,
                  speed_rpm=np.where(run.result.times_s <= sc.cycle.edges_s[1], 8000.0, 0.0))
print(f"{'quantity':<10}{'largest':>10}{'at [h]':>8}{'range':>9}{'at stop':>9}{'end':>8}")
for q in tt.quantities:
    print(f"{q.name + ' [' + q.unit + ']':<10}{q.max_abs:>10.2f}{q.max_abs_time_h:>8.2f}"
          f"{q.range:>9.2f}{q.at_stop:>9.2f}{q.final:>8.2f}")
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

png = Path(tempfile.mkdtemp()) / "thermal_test.png"
thermal_test_figure(tt, png, "spindle unit (P1): ISO 230-3 thermal test")
fig, ax = plt.subplots(figsize=(9, 8), layout="constrained")
ax.imshow(plt.imread(png))
ax.set_axis_off()
