"""
Compensate a recording with the paper's AR(1)
=============================================

The seed paper's §3.3 sends −(predicted growth) to the controller every interval. Here
the paper's AR(1) for the nominal rod compensates a record whose rod loses heat faster
than assumed (h = 70 instead of 55 W/(m²K)); the residual is the error that is left (the
paper's Fig. 8). ``arfem compensate MODEL.json RECORD.toml --out DIR`` does the same from
files, with clamps, a rate limit and probe updates.
"""
import matplotlib.pyplot as plt
import numpy as np

import arfem

rod = arfem.Rod()
model = arfem.ar1_model(arfem.ar1(rod, arfem.paper_cycle(2000.0), dtau_s=60.0).C1,
                        arfem.ar1(rod, arfem.paper_cycle(2000.0), dtau_s=60.0).C2_um_per_W_m2,
                        dtau_s=60.0)
cycle = arfem.Schedule([3 * 3600.0, 2 * 3600.0, 4 * 3600.0, 7 * 3600.0],
                       [3000.0, 0.0, 2000.0, 0.0])
truth = arfem.solve_fem(arfem.Rod(convection_W_m2K=70.0), cycle, dtau_s=60.0)
q = cycle.subdivided(60.0).q_W_m2

comp = arfem.Compensator(model, max_offset_um=40.0, max_step_um=0.5)
offset = np.r_[0.0, [comp.step({"q_W_m2": qk}).offset_um for qk in q]]
residual = truth.growth_um + offset
print(f"RMS error {np.sqrt(np.mean(truth.growth_um ** 2)):.2f} µm without compensation, "
      f"{np.sqrt(np.mean(residual ** 2)):.2f} µm with it")

fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
ax.plot(truth.times_s / 3600, truth.growth_um, label="without compensation")
ax.plot(truth.times_s / 3600, residual, label="with the paper's AR(1) (h = 55 assumed)")
ax.axhline(0.0, color="0.5", lw=0.8)
ax.set_xlabel("time [h]")
ax.set_ylabel("thermal error [µm]")
_ = ax.legend()
