"""Small meshes with physical groups written in code (no gmsh needed), for the
geometry tests: a box of tetrahedra with named faces, as Gmsh 2.2 files via meshio (whose 4.1 writer needs entity tags; the 4.1 reader is exercised by the gmsh-made rod and spindle meshes)."""
from __future__ import annotations

import numpy as np
from skfem import MeshTet1


def box_meshio(n=(3, 2, 2), size=(0.3, 0.2, 0.2), groups=True, extra_cells=None,
               order=1):
    """A meshio.Mesh of the box [0, a]×[0, b]×[0, c] in tetrahedra with volume group
    ``body`` and surface groups ``left`` (x = 0), ``right`` (x = a), ``rest``."""
    import meshio
    m = MeshTet1.init_tensor(*(np.linspace(0, s, k + 1) for s, k in zip(size, n)))
    t = m.t.copy()
    p = m.p
    vol = np.einsum("ij,ij->j", p[:, t[1]] - p[:, t[0]],
                    np.cross(p[:, t[2]] - p[:, t[0]], p[:, t[3]] - p[:, t[0]], axis=0))
    t[[1, 2]] = np.where(vol < 0, t[[2, 1]], t[[1, 2]])   # Gmsh/VTK: positive volumes
    m = MeshTet1(p, t)
    bf = m.boundary_facets()
    mid = m.p[:, m.facets[:, bf]].mean(axis=1)
    left = bf[np.isclose(mid[0], 0.0)]
    right = bf[np.isclose(mid[0], size[0])]
    rest = np.setdiff1d(bf, np.concatenate([left, right]))
    tris = [m.facets[:, f].T for f in (left, right, rest)]
    cells = [("tetra", m.t.T.copy())] + [("triangle", t) for t in tris]
    tags = [np.full(m.nelements, 1)] + [np.full(len(t), k) for k, t in zip((2, 3, 4), tris)]
    if extra_cells is not None:
        cells.append(extra_cells)
        tags.append(np.full(len(extra_cells[1]), 1))
    kw = {}
    if groups:
        kw = dict(cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags},
                  field_data={"body": np.array([1, 3]), "left": np.array([2, 2]),
                              "right": np.array([3, 2]), "rest": np.array([4, 2])})
    return meshio.Mesh(m.p.T.copy(), cells, **kw)


def write_msh(mesh, path) -> str:
    import meshio
    meshio.write(str(path), mesh, file_format="gmsh22", binary=False)
    return str(path)


BOX_TOML = """
[scenario]
name = "box"
[geometry]
mesh = "box.msh"
unit = "m"
order = 1
[[material]]
group = "body"
conductivity_W_mK = 50.0
density_kg_m3 = 7850.0
specific_heat_J_kgK = 460.0
expansion_1_K = 12e-6
youngs_modulus_Pa = 206e9
poisson_ratio = 0.3
[cycle]
phases = [ { duration_h = 1.0, speed_rpm = 1000.0 }, { duration_h = 1.0 } ]
[[heat_source]]
name = "heater"
group = "left"
power_W = [50.0, 0.0]
[[convection]]
group = "right"
h_W_m2K = { a = 10.0, b = 0.01, m = 1.0 }
[support]
type = "clamped"
group = "left"
[[sensor]]
name = "tip_x"
point = [0.3, 0.1, 0.1]
direction = "x"
[[sensor]]
name = "mid"
point = [0.15, 0.1, 0.1]
quantity = "temperature"
[fem]
output_interval_s = 600.0
[outputs]
fields = false
picture = false
"""
