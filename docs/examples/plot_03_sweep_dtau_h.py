"""
A Δτ × h sweep
==============

How far does the paper's AR(1) drift from the FEM as the AR step Δτ and the convection
coefficient h grow? ``arfem sweep`` runs such a grid on local processes or a Dask
cluster and writes tables, figures and a report; here a small grid in-process.
"""
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import arfem

work = Path(tempfile.mkdtemp())
(work / "sweep.toml").write_text("""
[sweep]
name = "gallery"
base = "paper_fig2"
[sweep.grid]
dtau_s = [30, 120, 600]
h_W_m2K = [10, 35, 55, 90, 150, 250]
""")
report = arfem.sweep(work / "sweep.toml", work / "out", workers=1)
table = pd.read_csv(work / "out" / "results.csv")
grid = table.pivot_table(index="dtau_s", columns="h_W_m2K", values="max_abs_diff_pct_of_peak")
fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
im = ax.imshow(grid.values, cmap="viridis", aspect="auto", origin="lower")
ax.set_xticks(range(grid.shape[1]), [f"{h:g}" for h in grid.columns])
ax.set_yticks(range(grid.shape[0]), [f"{d:g}" for d in grid.index])
for (i, j), v in np.ndenumerate(grid.values):
    ax.text(j, i, f"{v:.1f}", ha="center", va="center", color="w" if v < grid.values.max() / 2 else "k")
ax.set_xlabel("h [W/(m²K)]")
ax.set_ylabel("Δτ [s]")
fig.colorbar(im, label="max|AR − FEM| [% of FEM peak]")
print(f"{report.n_computed} points computed in {report.wall_s:.1f} s")
