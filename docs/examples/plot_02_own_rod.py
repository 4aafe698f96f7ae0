"""
The FEM and the AR(1) on your own rod
=====================================

Change the rod and the duty cycle, run the FEM and the AR(1) in a few lines, and see
where the paper's 1D assumption (a thin rod, Biot number hR/λ ≪ 1) stops holding.
"""
import matplotlib.pyplot as plt

import arfem

cycle = arfem.Schedule([2 * 3600.0, 2 * 3600.0, 4 * 3600.0], [3000.0, 0.0, 1500.0])
fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
for radius_m in (0.05, 0.1, 0.2):
    rod = arfem.Rod(radius_m=radius_m, convection_W_m2K=80.0)
    fem = arfem.solve_fem(rod, cycle, dtau_s=60.0)
    ar = arfem.ar1(rod, cycle, dtau_s=60.0)
    line, = ax.plot(fem.times_s / 3600, fem.growth_um, lw=2,
                    label=f"FEM, R = {radius_m} m (Bi = {rod.biot:.2f})")
    ax.plot(ar.times_s / 3600, ar.growth_um, "--", color=line.get_color(), label="AR(1)")
ax.set_xlabel("time [h]")
ax.set_ylabel("axial growth [µm]")
_ = ax.legend(fontsize=8)
