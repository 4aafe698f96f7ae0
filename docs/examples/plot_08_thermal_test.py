"""
An ISO 230-3 thermal test of the spindle unit: five quantities, bearing heat from the speed
===========================================================================================

ISO 230-3 measures a spindle's thermal drift as a machine shop records it: the spindle
runs at a constant speed, then stands still, while five quantities are read at a test
mandrel, all zeroed at the start: the displacements X, Y and Z and the tilts A (about
X) and B (about Y), each tilt from two probes. This example runs that test on the
shipped spindle unit (``scenarios/data/iso230_3/iso230_3_spindle_unit.toml``): the bearings'
friction heat follows the speed through Palmgren's friction moment and is generated in
the rings' volumes, the motor's losses in the stator's volume. It ends with the
standard's figures: each quantity's drift over time and its maxima over the test.

From the command line, the same (with the shipped P2 elements; this page uses P1 on the
same mesh so that it builds in seconds)::

    arfem run scenarios/data/iso230_3/iso230_3_spindle_unit.toml --out out/iso
    python -m arfem.scenarios.geometry.thermal_test out/iso/record.toml --out out/iso_report

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
# The scenario file
# -----------------
# Four hours at 8000 rpm, then two hours stopped. The bearings' heat sits in the rings'
# volume groups and follows the speed; the five quantities are sensors of the scenario:
# X, Y and Z at the nose (z = −80 mm), A and B tilts from two points 60 mm apart on the
# shaft's free end (``quantity = "tilt"``, reported in µrad). The shipped file's
# sources and tilts:
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import arfem  # noqa: E402

# the ISO test ships beside the spindle unit it runs on
shipped = arfem.shipped_scenario("spindle_unit").parent / "iso230_3" / "iso230_3_spindle_unit.toml"
text = shipped.read_text(encoding="utf-8")
print(text[text.index("[[heat_source]]"):text.index("[[convection]]")].strip())
print("...")
print(text[text.index("# A, the tilt about X"):text.index('name = "front_bearing"\npoint')]
      .strip().removesuffix("[[sensor]]").strip())

# %%
# The test, run
# -------------
# A copy that names the shipped mesh by its full path and asks for P1 elements (the
# same geometry and loads with a seventh of the temperature unknowns, so that this page
# builds in seconds; the shipped P2 run is the one to trust), run as a user runs it:
# ``arfem run``, then the thermal-test report of the record it writes.
work = Path(tempfile.mkdtemp())
mesh = (shipped.parent.parent / "spindle_unit.msh").as_posix()
(work / "iso.toml").write_text(text.replace('mesh = "../spindle_unit.msh"', f'mesh = "{mesh}"')
                               .replace("order = 2", "order = 1")
                               .replace("picture = true", "picture = false"), encoding="utf-8")
for cmd in (["-m", "arfem", "run", str(work / "iso.toml"), "--out", str(work / "run"),
             "--no-progress"],
            ["-m", "arfem.scenarios.geometry.thermal_test", str(work / "run" / "record.toml"),
             "--out", str(work / "report")]):
    done = subprocess.run([sys.executable, *cmd], capture_output=True, text=True, check=True)
    print(done.stdout)

# %%
# The standard's figures
# ----------------------
# ``thermal_test.png``: every quantity as its drift from the start (the probes' zero),
# the speed below, the stop dashed. ``thermal_test.json`` (and the table of
# ``thermal_test.md`` and ``report.html``) gives each one's largest drift over the test,
# when, its range, and where it stood when the spindle stopped and at the end.
report = json.loads((work / "report" / "thermal_test.json").read_text(encoding="utf-8"))
print(f"{'quantity':<10}{'largest':>10}{'at [h]':>8}{'range':>9}{'at stop':>9}{'end':>8}")
for q in report["quantities"]:
    print(f"{q['name'] + ' [' + q['unit'] + ']':<10}{q['max_abs']:>10.2f}"
          f"{q['max_abs_time_h']:>8.2f}{q['range']:>9.2f}{q['at_stop']:>9.2f}{q['final']:>8.2f}")
fig, ax = plt.subplots(figsize=(9, 8), layout="constrained")
ax.imshow(plt.imread(work / "report" / "thermal_test.png"))
ax.set_axis_off()
