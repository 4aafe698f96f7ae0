"""geometry.png (issue 32): every surface group in its own colour with a legend entry
naming its role, and every sensor point labelled with its name."""
from __future__ import annotations

import numpy as np

from arfem.fem.body import SensorSpec
from arfem.fem.gmsh_io import read_grouped_mesh
from arfem.scenarios.geometry.scenario import (_GROUP_COLOURS, _sensor_labels, geometry_picture,
                                               group_roles, load_geometry_scenario)
from geometry_meshes import BOX_TOML, box_meshio, write_msh


def test_sensors_at_one_point_share_a_label_and_thermometers_say_so():
    """Three axes of one TCP make one label (three would print on top of each other);
    a thermometer's label carries its unit; a group-averaged sensor has no point."""
    s = [SensorSpec("tcp_x", "displacement", (0.0, 0.0, 1.0), None, (1, 0, 0)),
         SensorSpec("tcp_z", "displacement", (0.0, 0.0, 1.0), None, (0, 0, 1)),
         SensorSpec("bearing", "temperature", (0.1, 0.0, 0.0)),
         SensorSpec("face", "displacement", None, "right")]
    labels = [t for _, t in _sensor_labels(s)]
    assert labels == ["tcp_x, tcp_z", "bearing (°C)"]


def test_roles_and_picture_of_the_box(tmp_path):
    """The box's groups get their roles (the clamped face that is also heated gets both)
    and the picture is written with every group's colour in it: distinct saturated
    colours, not tab20's pale halves."""
    write_msh(box_meshio(), tmp_path / "box.msh")
    (tmp_path / "s.toml").write_text(BOX_TOML, encoding="utf-8")
    sc = load_geometry_scenario(tmp_path / "s.toml")
    roles = group_roles(sc)
    assert roles["left"] == "heat source heater; support (clamped)"
    assert roles["right"].startswith("convection h = 10 + 0.01·n^1")
    assert len(set(_GROUP_COLOURS)) == len(_GROUP_COLOURS)
    gm = read_grouped_mesh(sc.mesh_path, sc.unit)
    out = tmp_path / "geometry.png"
    geometry_picture(gm, out, sc.sensors, title="box", roles=roles)
    import matplotlib.image as mpimg
    img = (mpimg.imread(out)[..., :3] * 255).round().astype(int)
    colours = {tuple(int(c[i:i + 2], 16) for i in (1, 3, 5))
               for c in _GROUP_COLOURS[:len(gm.surfaces)]}
    for c in colours:       # each group's colour appears (its legend patch at least)
        assert np.any(np.all(np.abs(img - np.array(c)) <= 2, axis=-1)), c


def test_the_scale_bar_is_true_in_the_orthographic_view():
    """The scale bar of the geometry picture: a round length (1, 2 or 5 × 10^k mm) drawn
    over exactly length × pixels per metre of the view, at most a fifth of the image;
    the view's right and up are orthonormal and perpendicular to the line of sight."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from arfem.fem.export import ParallelView, draw_scale_bar
    v = ParallelView.of((1.2, -2.0, -0.6), (0, 0, 0), (0, 0, 1), 0.35, 860)
    r, u = np.array(v.right), np.array(v.up)
    d = -np.array([1.2, -2.0, -0.6]) / np.linalg.norm([1.2, -2.0, -0.6])
    assert abs(r @ u) < 1e-12 and abs(r @ d) < 1e-12 and abs(u @ d) < 1e-12
    assert v.px_per_m == 860 / 0.7
    fig, ax = plt.subplots()
    L = draw_scale_bar(ax, v, (860, 1000, 3))
    bar = ax.lines[0].get_xdata()
    plt.close(fig)
    assert round(L * 1e3) in (100, 200, 50) and L * v.px_per_m <= 200
    assert abs(bar[1] - bar[0] - L * v.px_per_m) < 1e-9
