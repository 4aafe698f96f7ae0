"""
A CI gate for your own spindle
==============================

Describe your spindle in a scenario file and let ``arfem check`` fail your pipeline when
the AR(1) stops tracking the FEM (exit status 1). From Python the same check returns each
criterion with its value and limit.
"""
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import arfem

work = Path(tempfile.mkdtemp())
results = {}
for h in (55.0, 150.0):
    path = work / f"spindle_h{h:g}.toml"
    path.write_text(f"""
[scenario]
name = "my_spindle_h{h:g}"
[rod]
radius_m = 0.1
length_m = 0.8
convection_W_m2K = {h}
[cycle]
phases = [{{ duration_h = 4.0, q_W_m2 = 2000.0 }}, {{ duration_h = 4.0, q_W_m2 = 0.0 }}]
[ar]
dtau_s = 30.0
""")
    results[h] = arfem.check(path)
    for c in results[h].criteria:
        verdict = "PASS" if c.passed else "FAIL"         # short lines: none is cut
        unit = "" if c.unit == "-" else f" {c.unit}"
        print(f"h = {h:g}: {verdict}  {c.name} = {c.value:.4g}{unit}, "
              f"limit {c.limit:.4g}")

fig, ax = plt.subplots(figsize=(6, 3), layout="constrained")
vals = [results[h].criteria[0].value for h in results]
ax.bar([f"h = {h:g}" for h in results], vals,
       color=["tab:green" if results[h].passed else "tab:red" for h in results])
ax.axhline(results[55.0].criteria[0].limit, color="k", ls="--", label="limit")
ax.set_ylabel("max|AR − FEM| [% of peak]")
_ = ax.legend()
