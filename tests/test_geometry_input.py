"""Bad input for a geometry scenario (issue 32): one line naming the file and the key,
exit 2, nothing written; and what a good box scenario writes.

Each case changes one thing in a small box scenario that runs (``BOX_TOML``), so a
refusal can only come from that change.
"""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from arfem.params import InputError
from arfem.scenarios.geometry.scenario import (build_geometry_model, load_geometry_scenario,
                                               solve_geometry)
from geometry_meshes import BOX_TOML, box_meshio, write_msh


def _case(tmp_path, toml=BOX_TOML, mesh=None):
    write_msh(box_meshio() if mesh is None else mesh, tmp_path / "box.msh")
    (tmp_path / "s.toml").write_text(toml, encoding="utf-8")
    return tmp_path / "s.toml"


def _refusal(tmp_path, toml=BOX_TOML, mesh=None, env=None) -> str:
    path = _case(tmp_path, toml, mesh)
    with pytest.raises(InputError) as e:
        build_geometry_model(load_geometry_scenario(path))
    msg = str(e.value)
    assert "\n" not in msg and str(tmp_path) in msg      # one line, naming the file
    return msg


def test_good_box_runs_and_sensors_are_physical(tmp_path):
    """The unchanged box scenario solves: the heated box's tip moves +x (clamped at the
    heated face, it grows away from it) and the mid-point warms during the heating hour,
    then cools; a control for every refusal below."""
    run = solve_geometry(build_geometry_model(load_geometry_scenario(_case(tmp_path))))
    s = run.sensor_series()
    assert s["d_tip_x_um"].max() > 1.0
    T = s["T_mid_C"]
    k = int(np.argmax(T))
    assert T[0] == pytest.approx(20.0) and T[k] > 21.0 and T[-1] < T[k]


def test_no_physical_groups(tmp_path):
    msg = _refusal(tmp_path, mesh=box_meshio(groups=False))
    assert "no physical groups" in msg


def test_group_the_mesh_lacks_lists_the_groups(tmp_path):
    msg = _refusal(tmp_path, BOX_TOML.replace('group = "right"', 'group = "rigth"'))
    assert "'rigth'" in msg and "left, rest, right" in msg and "convection[0].group" in msg


def test_volume_group_without_material(tmp_path):
    msg = _refusal(tmp_path, BOX_TOML.replace('group = "body"', 'group = "body2"'))
    assert "no volume group 'body2'" in msg


def test_unsupported_and_mixed_cells(tmp_path):
    wedge = ("wedge", np.array([[0, 1, 2, 3, 4, 5]]))
    assert "wedge" in _refusal(tmp_path, mesh=box_meshio(extra_cells=wedge))
    hexa = ("hexahedron", np.array([[0, 1, 2, 3, 4, 5, 6, 7]]))
    assert "mixes hexahedron and tetra" in _refusal(tmp_path, mesh=box_meshio(extra_cells=hexa))


def test_inverted_and_zero_volume_elements(tmp_path):
    m = box_meshio()
    t = m.cells[0].data
    t[0, [1, 2]] = t[0, [2, 1]]
    assert "1 inverted elements" in _refusal(tmp_path, mesh=m)
    m = box_meshio()
    t = m.cells[0].data
    t[3, 3] = t[3, 0]                  # a repeated node: zero volume
    assert "zero volume" in _refusal(tmp_path, mesh=m)


def test_no_support(tmp_path):
    toml = BOX_TOML.replace('[support]\ntype = "clamped"\ngroup = "left"\n', "")
    path = _case(tmp_path, toml)
    with pytest.raises(InputError, match="no support"):
        load_geometry_scenario(path)


@pytest.mark.parametrize("size,unit,cause", [((300.0, 200.0, 200.0), "m", "likely in mm"),
                                             ((3e-4, 2e-4, 2e-4), "m", "likely in m,"),
                                             ((0.3, 0.2, 0.2), "mm", "likely in m,")])
def test_unit_sanity(tmp_path, size, unit, cause):
    """A box 0.36 m across declared in mm is 0.36 mm: refused as < 1 mm; 360 m: > 20 m."""
    msg = _refusal(tmp_path, BOX_TOML.replace('unit = "m"', f'unit = "{unit}"'),
                   mesh=box_meshio(size=size))
    assert cause in msg and "geometry.unit" in msg


def test_sensor_outside_the_mesh(tmp_path):
    msg = _refusal(tmp_path, BOX_TOML.replace("point = [0.3, 0.1, 0.1]",
                                              "point = [0.31, 0.1, 0.1]"))
    assert "sensor 'tip_x'.point" in msg and "outside the mesh" in msg


def test_memory_estimate_refused_before_assembly(tmp_path, monkeypatch):
    """The estimate is made from the mesh's size before anything is assembled and named
    in the message; ARFEM_MEMORY_LIMIT_BYTES stands in for a small machine."""
    monkeypatch.setenv("ARFEM_MEMORY_LIMIT_BYTES", "1e6")
    msg = _refusal(tmp_path)
    assert "need an estimated" in msg and "GB" in msg and "available" in msg


def test_cli_exit_2_one_line_nothing_written(tmp_path):
    path = _case(tmp_path, BOX_TOML.replace('group = "right"', 'group = "nope"'))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "arfem", "run", str(path), "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "nope" in r.stderr
    assert r.stdout == ""        # meshio's Gmsh reader printed a bare newline before it
    assert not out.exists()


def test_hexahedral_mesh_is_read_with_its_volume_and_groups(tmp_path):
    """An 8-node hexahedron mesh (VTK/Gmsh node order) becomes skfem's MeshHex1 with
    positive element volumes summing to the box's, and its faces are found as facets;
    one hex with two corner layers swapped is refused as inverted."""
    import meshio
    from skfem import Basis, ElementHex1, MeshHex1

    from arfem.fem.gmsh_io import VTK_TO_SKFEM_HEX, read_grouped_mesh
    m = MeshHex1.init_tensor(np.linspace(0, 0.3, 4), np.linspace(0, 0.2, 3),
                             np.linspace(0, 0.1, 2))
    t_vtk = m.t[np.argsort(VTK_TO_SKFEM_HEX)].T.copy()
    left = m.facets[:, m.boundary_facets()[np.isclose(
        m.p[0, m.facets[:, m.boundary_facets()]].mean(axis=0), 0.0)]]
    quads = []
    for f in left.T:                   # skfem facet nodes -> a quad in cyclic order
        P = m.p[1:, f]
        c = P.mean(axis=1)
        quads.append(f[np.argsort(np.arctan2(P[1] - c[1], P[0] - c[0]))])
    mm = meshio.Mesh(m.p.T, [("hexahedron", t_vtk), ("quad", np.array(quads))],
                     cell_data={"gmsh:physical": [np.full(len(t_vtk), 1),
                                                  np.full(len(quads), 2)],
                                "gmsh:geometrical": [np.full(len(t_vtk), 1),
                                                     np.full(len(quads), 2)]},
                     field_data={"body": np.array([1, 3]), "left": np.array([2, 2])})
    write_msh(mm, tmp_path / "hex.msh")
    gm = read_grouped_mesh(tmp_path / "hex.msh", "m")
    assert gm.cell_type == "hexahedron" and gm.surfaces["left"].size == 2
    vol = Basis(gm.mesh, ElementHex1()).dx.sum()
    assert vol == pytest.approx(0.3 * 0.2 * 0.1, rel=1e-12)
    bad = t_vtk.copy()
    bad[0] = bad[0][[4, 5, 6, 7, 0, 1, 2, 3]]
    mm.cells[0] = meshio.CellBlock("hexahedron", bad)
    write_msh(mm, tmp_path / "bad.msh")
    with pytest.raises(InputError, match="inverted"):
        read_grouped_mesh(tmp_path / "bad.msh", "m")


def test_a_thermometer_named_like_its_column_is_refused(tmp_path):
    """A temperature sensor's output column is T_<name>_C (the measured-data contract),
    so a sensor named "T_mid" would become the column T_T_mid_C (a new user's spindle
    scenario shipped so); the name is refused with the column it would give."""
    msg = _refusal(tmp_path, BOX_TOML.replace('name = "mid"', 'name = "T_mid"'))
    assert "sensor[1].name" in msg and "T_<name>_C" in msg and "'mid'" in msg
