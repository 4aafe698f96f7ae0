"""
Diagnose a recording held in a DataFrame
========================================

A record whose rod loses heat faster than the simulation assumes (h = 80 instead of
55 W/(m²K)), with sensor noise: ``arfem.diagnose`` names the cause, estimates h with a
95 % interval, and scores the extended model on the hold-out against the baseline and
the multiple linear regression of the paper's eq. 18.
"""
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import arfem

cycle = arfem.Schedule([4 * 3600.0] * 6, [2000.0, 0.0] * 3)
truth = arfem.solve_fem(arfem.Rod(convection_W_m2K=80.0), cycle, dtau_s=300.0)
noise = np.random.default_rng(1).normal(0.0, 0.02, truth.times_s.size)
df = pd.DataFrame({"time_s": truth.times_s,
                   "q_W_m2": np.r_[0.0, cycle.subdivided(300.0).q_W_m2],
                   "growth_um": truth.growth_um + noise})
result = arfem.diagnose(df, initial="equilibrium")   # the rod starts at the ambient
cause = result.summary["causes"][0]
print("named cause:", result.cause)
for key, value in cause["parameters"].items():        # one line each, so none is cut
    low, high = cause["ci95"].get(key, (float("nan"), float("nan")))
    print(f"  {key} = {value:.4g}, 95 % interval [{low:.4g}, {high:.4g}]")

s = result.to_dataframe()
fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
ax.plot(s.time_s / 3600, s.growth_um, ".", ms=3, color="0.5", label="measured")
ax.plot(s.time_s / 3600, s.baseline_um, "--", label="simulation as assumed (h = 55)")
ax.plot(s.time_s / 3600, s.extended_um, "-", label=f"extended: {result.cause}")
ax.set_xlabel("time [h]")
ax.set_ylabel("axial growth [µm]")
_ = fig.legend(loc="outside lower center", ncol=3, fontsize=8, frameon=False)  # off the traces
