"""
A spindle unit from a Gmsh mesh: the tool-centre point's drift in X, Y and Z
============================================================================

The rod of the seed paper is not your machine. This example runs the spindle unit
shipped with arfem (``scenarios/data/spindle_unit.toml`` and its mesh) as a user does: the
scenario file, :func:`arfem.run` (``arfem run`` from Python), its result and the files
it writes. The unit is a steel shaft in two
bearing sets and a built-in motor, in a cast-iron housing on a column stub clamped at
its foot, run for 24 h of speed steps. What a compensation engineer wants from it: the
drift of the tool-centre point (TCP) along X, Y and Z, the temperatures the sensors
would read, and the fields.

From the command line, the same in one go (with the shipped P2 elements; this page uses
P1 on the same mesh so that it builds in seconds)::

    arfem run scenarios/data/spindle_unit.toml --out out/spindle
"""
# %%
# The scenario file
# -----------------
# A scenario with ``[geometry]`` names a mesh and ties its physical groups to
# materials, heat sources, convection, a support and sensors, every key with its unit
# (:doc:`../geometry` explains each table). This is the shipped file:
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import arfem

shipped = arfem.shipped_scenario("spindle_unit")      # the installed file
text = shipped.read_text(encoding="utf-8")
print(text[text.index("[geometry]"):text.index("[[material]]")])
print("...")
print(text[text.index("[[heat_source]]"):text.index("[[convection]]")])

# %%
# Run it
# ------
# A copy that names the shipped mesh by its full path and asks for P1 elements (the
# same geometry, groups and loads with a seventh of the temperature unknowns; the
# shipped P2 run is the one to trust, and the P1 peaks lie within 0.6 % of it) and for
# the fields, which are off by default. :func:`arfem.run` writes what ``arfem run``
# writes and returns the sensors' histories (:class:`arfem.FemResult`);
# :func:`arfem.solve` would return them without writing a file.
work = Path(tempfile.mkdtemp())
copy = (text.replace('mesh = "spindle_unit.msh"',
                     f'mesh = "{shipped.with_suffix(".msh").as_posix()}"')
        .replace("order = 2", "order = 1")
        .replace("fields = false", "fields = true")
        .replace("field_interval_s = 3600.0", "field_interval_s = 1800.0"))
(work / "unit.toml").write_text(copy, encoding="utf-8")
out = work / "out"
unit = arfem.run(work / "unit.toml", out)
print(f"{unit.scenario}: {unit.ndofs} temperature unknowns, solver {unit.solver}")
print("wrote:", ", ".join(sorted(p.name for p in out.iterdir() if not p.name.startswith("."))))

# %%
# The mesh's groups
# -----------------
# ``geometry.png``: volume groups carry the materials, surface groups the heat sources,
# the convection and the support. Every surface group has its colour, the outer faces
# are translucent so that the bearing seats and the motor's air gap inside show, and
# every sensor point is labelled; the scale bar holds at every depth (the view is
# orthographic).
fig, ax = plt.subplots(figsize=(10, 6), layout="constrained")
ax.imshow(plt.imread(out / "geometry.png"))
ax.set_axis_off()

# %%
# The TCP's drift along X, Y and Z, and the temperatures
# -------------------------------------------------------
# The result holds each sensor by its name, in its unit: ``displacement_um``,
# ``temperature_C`` (and ``tilt_urad``); ``unit.to_dataframe()`` gives the columns of
# ``sensors.csv``. Z is the spindle axis: the shaft and the housing grow, and the nose
# (at z = −80 mm, below the housing) moves down, −Z. The column stub is clamped at its
# back face (y = 300 mm); everything in front of it expands away from that face, so the
# nose also moves −Y. X stays near zero: the unit is symmetric about the plane x = 0.
# These three curves are what a compensation writes into the controller's offsets.
t_h = unit.times_s / 3600.0
table = unit.to_dataframe()
for c in unit.channels:
    v = table[c.column].to_numpy()
    j = int(np.argmax(np.abs(v - (20.0 if c.quantity == "temperature" else 0.0))))
    print(f"{c.column:<20} peak {v[j]:8.2f} {c.unit:<2} at {t_h[j]:5.2f} h, final {v[-1]:8.2f}")
fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True, layout="constrained")
for axis in "xyz":
    ax1.plot(t_h, unit.displacement_um[f"tcp_{axis}"], label=f"TCP {axis.upper()}")
ax1.axhline(0.0, color="0.6", lw=0.8)
ax1.set_ylabel("TCP drift [µm]")
ax1.legend(ncol=3)
for name in ("front_bearing", "housing", "column"):
    ax2.plot(t_h, unit.temperature_C[name], label=name)
ax2.set_ylabel("temperature [°C]")
ax2.set_xlabel("time [h]")
_ = ax2.legend(ncol=3, loc="upper right")

# %%
# The fields
# ----------
# ``fields/fields.xdmf3`` holds the temperature and the displacement at the mesh's
# vertices every ``field_interval_s`` (ParaView opens it). Here, read with meshio, the
# hottest moment (9 h, the end of the high-speed phase), cut along the plane of
# symmetry: the temperature on the shape deformed 1000 times, seen from +X onto the cut.
import meshio  # noqa: E402
import pyvista as pv  # noqa: E402

with meshio.xdmf.TimeSeriesReader(str(out / "fields" / "fields.xdmf3")) as r:
    points, cells = r.read_points_cells()
    frames = [r.read_data(k) for k in range(r.num_steps)]
t_s, data, _ = min(frames, key=lambda f: abs(f[0] - 9 * 3600.0))
grid = pv.UnstructuredGrid({pv.CellType.TETRA: cells[0].data}, points)
grid.point_data["temperature [°C]"] = data["temperature_C"]
warped = grid.copy()
warped.points = points + 1000.0 * data["displacement_m"]
pv.OFF_SCREEN = True
pl = pv.Plotter(off_screen=True, window_size=(900, 800))
pl.add_mesh(warped.clip(normal="x", origin=(0.0, 0.0, 0.0)), scalars="temperature [°C]",
            cmap="inferno", scalar_bar_args={"title": "temperature [°C]", "vertical": False,
                                             "position_x": 0.25, "position_y": 0.04,
                                             "width": 0.5})
c = np.asarray(grid.center)
r = float(np.linalg.norm(np.ptp(points, axis=0)))
pl.camera_position = [tuple(c + r * np.array([2.2, -0.4, -0.3])), tuple(c), (0, 0, 1)]
img = pl.screenshot(None, return_img=True)
pl.close()
fig, ax = plt.subplots(figsize=(8, 7), layout="constrained")
ax.imshow(img)
ax.set_axis_off()
_ = ax.set_title(f"t = {t_s / 3600:g} h: temperature on the half x < 0, deformed ×1000")

# %%
# Next steps
# ----------
# * ``arfem run scenarios/data/spindle_unit.toml --out out/spindle``: the shipped P2 run,
#   with ``report.html`` and ``model.json``.
# * ``arfem sweep scenarios/data/sweep_spindle_unit.toml --out out/sweep``: the TCP drift per
#   axis for other housing h and motor losses
#   (:doc:`../commands/sweep`, "Sweeping a mesh scenario").
# * Replace the mesh by your own: name its groups in Gmsh, keep the units declared.
