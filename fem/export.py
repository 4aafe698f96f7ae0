"""Field output: an XDMF + HDF5 time series (ParaView) and a 3D picture of the rod.

Data flow: a :class:`arfem.fem.heat.HeatResult` with stored fields (and optionally a
:class:`arfem.fem.elastic.ThermoElastic` for the displacement) → files. No global
state; every file is written to a temporary name beside its target and renamed
into place, so a reader never sees a half-written file.

* :func:`node_grid` -- the mesh with *every* node of its elements, cells in VTK
  node order: Q1 → ``quad``, Q2 (9-node Lagrange) → ``quad9``
  (VTK_BIQUADRATIC_QUAD), Hex1 → ``hexahedron``, 20-node serendipity →
  ``hexahedron20`` (VTK_QUADRATIC_HEXAHEDRON), 27-node Lagrange →
  ``hexahedron27`` (VTK_TRIQUADRATIC_HEXAHEDRON). The 9-node quad keeps its
  centre node: scikit-fem's Q2 has an independent dof there, and dropping it (to an
  8-node serendipity quad) would make ParaView interpolate a different field from
  the one solved.
* :func:`write_fields` -- temperature ``T_C``, rise ``theta_K`` and the
  displacement vector ``displacement_m`` at every node, one XDMF 3 step per output
  time (``Time`` in seconds), heavy data in an HDF5 file beside it (gzip).
  Axisymmetric results are written in the plane y = 0 (x = r), displacement
  (u_r, 0, u_z). The series is named ``*.xdmf3``: ParaView opens it ("Xdmf3
  Reader"), as do ``meshio.xdmf.TimeSeriesReader``, VTK's XDMF reader and
  :func:`read_fields`, while ``meshio.read`` (single-grid files only; in meshio ≤ 5.3
  it ends the interpreter with ``sys.exit`` on any ``.xdmf`` time series) raises a
  normal ``ReadError`` on the extension. ``peak.xdmf`` (one grid, same HDF5 data) is
  the file for ``meshio.read``.
* :func:`render_png` -- an off-screen, orthographic pyvista rendering of the
  temperature on the rod deformed by an exaggerated displacement, annotated with
  matplotlib: a ruler along the axis in mm, the heated end, the undeformed and the
  grown far end, a colour bar in °C.
* :func:`write_scenario_fields` -- both at once into an output directory.
"""
from __future__ import annotations

from pathlib import Path

from dataclasses import dataclass

import numpy as np

from arfem.fem.heat import HeatFEM, HeatResult
from arfem.io import atomic_path, atomic_write_text
from arfem.params import InputError

__all__ = ["vertex_grid", "node_grid", "write_fields", "read_fields", "picture_figure",
           "render_png", "write_scenario_fields", "ParallelView", "draw_scale_bar",
           "draw_axis_triad"]


def vertex_grid(model: HeatFEM):
    """Linear cells of the model's mesh in 3D coordinates.

    Returns
    -------
    points : ndarray (n_vertices, 3)
        Vertex coordinates [m]; axisymmetric (r, z) is placed at (r, 0, z).
    cell_type : str
        meshio cell type (``"quad"`` or ``"hexahedron"``).
    cells : ndarray (n_cells, n_corners)
        Vertex indices in meshio/VTK order.
    theta_dofs : ndarray (n_vertices,)
        Index of each vertex's θ dof in the model's basis.

    Examples
    --------
    >>> from arfem.fem.heat import build_axisymmetric
    >>> from arfem.params import Rod
    >>> p, kind, c, d = vertex_grid(build_axisymmetric(Rod(), nr=2, nz=3))
    >>> p.shape, kind, c.shape
    ((12, 3), 'quad', (6, 4))
    """
    from skfem import MeshHex1, MeshQuad1
    from skfem.io.meshio import to_meshio
    mesh = model.basis.mesh
    nv = mesh.nvertices
    pv = mesh.p[:, :nv]
    lin = (MeshQuad1 if mesh.dim() == 2 else MeshHex1)(pv, mesh.t[: (4 if mesh.dim() == 2 else 8)])
    m = to_meshio(lin)
    block = m.cells[0]
    pts = np.asarray(m.points, float)
    if model.axisymmetric:
        pts = np.column_stack([pts[:, 0], np.zeros(len(pts)), pts[:, 1]])
    return pts, block.type, np.asarray(block.data), np.asarray(model.basis.nodal_dofs[0])


# VTK node order of the quadratic cells, as tuples of the corners whose mean is the node
# (VTK_BIQUADRATIC_QUAD, VTK_QUADRATIC_HEXAHEDRON, VTK_TRIQUADRATIC_HEXAHEDRON).
_Q_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0)]
_H_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
            (0, 4), (1, 5), (2, 6), (3, 7)]
_H_FACES = [(0, 3, 7, 4), (1, 2, 6, 5), (0, 1, 5, 4), (3, 2, 6, 7), (0, 1, 2, 3), (4, 5, 6, 7)]
_NODE_LAYOUT = {
    # (mesh dim, nodes per element) -> (meshio type, XDMF topology, node definitions)
    (2, 4): ("quad", "Quadrilateral", [(i,) for i in range(4)]),
    (2, 9): ("quad9", "Quadrilateral_9", [(i,) for i in range(4)] + _Q_EDGES + [(0, 1, 2, 3)]),
    (3, 8): ("hexahedron", "Hexahedron", [(i,) for i in range(8)]),
    (3, 20): ("hexahedron20", "Hexahedron_20", [(i,) for i in range(8)] + _H_EDGES),
    (3, 27): ("hexahedron27", "Hexahedron_27",
              [(i,) for i in range(8)] + _H_EDGES + _H_FACES + [tuple(range(8))]),
}


def node_grid(model: HeatFEM):
    """Every node of the model's elements, cells in VTK node order.

    The nodes are the dof locations of the (Lagrange or serendipity) temperature
    basis, so point ``i`` carries dof ``i`` and a field needs no interpolation.
    Each element's dofs are put in VTK order by position: a VTK mid-side, mid-face
    or centre node is the dof nearest to the mean of the corners it lies between
    (on the curved elements at the circle it is off that mean by the sagitta, far
    less than the distance to any other node; checked).

    Returns
    -------
    points : ndarray (ndofs, 3)
        Node coordinates [m]; axisymmetric (r, z) is placed at (r, 0, z).
    cell_type : str
        meshio cell type: ``quad``, ``quad9``, ``hexahedron``, ``hexahedron20`` or
        ``hexahedron27``.
    xdmf_type : str
        The XDMF topology name of the same cell.
    cells : ndarray (n_cells, nodes_per_cell)
        Node indices.

    Examples
    --------
    >>> from arfem.fem.heat import build_axisymmetric
    >>> from arfem.params import Rod
    >>> p, kind, xkind, c = node_grid(build_axisymmetric(Rod(), order=2, nr=2, nz=3))
    >>> p.shape, kind, xkind, c.shape
    ((35, 3), 'quad9', 'Quadrilateral_9', (6, 9))
    """
    b = model.basis
    dim = b.mesh.dim()
    edofs = np.asarray(b.element_dofs)                       # (nloc, ne)
    key = (dim, edofs.shape[0])
    if key not in _NODE_LAYOUT:
        raise InputError(f"has no VTK cell for {type(b.elem).__name__}", "model")
    kind, xkind, nodes = _NODE_LAYOUT[key]
    _, _, corners, _ = vertex_grid(model)                    # VTK-ordered vertex ids
    X = np.asarray(b.doflocs)                                # (dim, ndofs)
    vx = X[:, np.asarray(b.nodal_dofs[0])]                   # vertex coordinates
    loc = X[:, edofs]                                        # (dim, nloc, ne)
    cells = np.empty((edofs.shape[1], len(nodes)), dtype=np.int64)
    cols = np.arange(edofs.shape[1])
    for j, cs in enumerate(nodes):
        target = vx[:, corners[:, list(cs)]].mean(axis=2)    # (dim, ne)
        dist = np.linalg.norm(loc - target[:, None, :], axis=0)
        order = np.argsort(dist, axis=0)
        # curved (isoparametric) elements: the node is off the chord by the sagitta, far
        # less than the distance to the next node
        if len(nodes) > 1 and np.any(dist[order[0], cols] > 0.5 * dist[order[1], cols]):
            raise InputError("has an element node that is not where VTK puts it", "model")
        cells[:, j] = edofs[order[0], cols]
    srt = np.sort(cells, axis=1)
    if np.any(srt[:, 1:] == srt[:, :-1]):
        raise InputError("has an element whose nodes cannot be put in VTK order", "model")
    pts = X.T.astype(float)
    if model.axisymmetric:
        pts = np.column_stack([pts[:, 0], np.zeros(len(pts)), pts[:, 1]])
    return pts, kind, xkind, cells


def _node_displacement(model: HeatFEM, elastic, theta: np.ndarray) -> np.ndarray:
    """(n_frames, ndofs, 3) displacement [m] at every node of :func:`node_grid`."""
    U = np.atleast_2d(elastic.displacement(theta))
    dim = model.basis.mesh.dim()
    comp = [U[:, c::dim] for c in range(dim)]                # ElementVector interleaves
    if model.axisymmetric:
        return np.stack([comp[0], np.zeros_like(comp[0]), comp[1]], axis=-1)
    return np.stack(comp, axis=-1)


def _vertex_displacement(model: HeatFEM, elastic, theta: np.ndarray) -> np.ndarray:
    """(n_frames, n_vertices, 3) displacement [m] at the vertices."""
    U = np.atleast_2d(elastic.displacement(theta))
    nd = elastic.basis.nodal_dofs
    if model.axisymmetric:
        return np.stack([U[:, nd[0]], np.zeros_like(U[:, nd[0]]), U[:, nd[1]]], axis=-1)
    return np.stack([U[:, nd[0]], U[:, nd[1]], U[:, nd[2]]], axis=-1)


def _frames(result: HeatResult, max_frames: int | None) -> np.ndarray:
    if result.fields is None:
        raise InputError("has no stored fields; solve with store_fields=True", "result")
    n = result.fields.shape[0]
    if max_frames is None or n <= max_frames:
        return np.arange(n)
    if max_frames < 2:
        raise InputError(f"must be >= 2, got {max_frames!r}", "max_frames")
    return np.unique(np.round(np.linspace(0, n - 1, max_frames)).astype(int))


def _xdmf_grid(parent, name: str, h5name: str, kind_x: str, shapes: dict, step: int | None,
               time_s: float | None, fields: list):
    """One XDMF ``Grid`` element whose heavy data are datasets of ``h5name``."""
    import xml.etree.ElementTree as ET
    g = ET.SubElement(parent, "Grid", Name=name, GridType="Uniform")
    if time_s is not None:
        ET.SubElement(g, "Time", Value=repr(float(time_s)))
    n_cells, n_nodes = shapes["cells"]
    topo = ET.SubElement(g, "Topology", TopologyType=kind_x, NumberOfElements=str(n_cells))
    ET.SubElement(topo, "DataItem", DataType="Int", Precision="8", Format="HDF",
                  Dimensions=f"{n_cells} {n_nodes}").text = f"{h5name}:/mesh/cells"
    geo = ET.SubElement(g, "Geometry", GeometryType="XYZ")
    ET.SubElement(geo, "DataItem", DataType="Float", Precision="8", Format="HDF",
                  Dimensions=f"{shapes['points'][0]} 3").text = f"{h5name}:/mesh/points"
    for fname in fields:
        shape = shapes[fname]
        a = ET.SubElement(g, "Attribute", Name=fname, Center="Node",
                          AttributeType="Vector" if len(shape) == 2 else "Scalar")
        ET.SubElement(a, "DataItem", DataType="Float", Precision="8", Format="HDF",
                      Dimensions=" ".join(map(str, shape))).text = \
            f"{h5name}:/{fname}/step_{step:05d}"
    return g


def _xdmf_text(root) -> str:
    import xml.etree.ElementTree as ET
    ET.indent(root)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def write_fields(model: HeatFEM, result: HeatResult, path, elastic=None,
                 max_frames: int | None = 200, peak_index: int | None = None) -> Path:
    """Write temperature (and displacement) as an XDMF time series with HDF5 data.

    Writes ``path`` (the XDMF 3 description, a temporal collection with one grid
    per output time) and ``path.with_suffix(".h5")`` (the heavy data: mesh once,
    one gzip-compressed dataset per field and step). Both are written to temporary
    names beside their targets and renamed into place, the HDF5 file first. Where
    ``peak_index`` is given, ``peak.xdmf`` beside them describes that one output
    time alone (a single grid on the same HDF5 data: the file ``meshio.read``
    can read).

    Parameters
    ----------
    model : HeatFEM
        The model that produced ``result``.
    result : HeatResult
        Must hold ``fields`` (solve with ``store_fields=True``).
    path : str or Path
        Target ``.xdmf3`` file (parent directories are created); ``.xdmf`` is
        accepted too, but ``meshio.read`` of an ``.xdmf`` time series exits the
        interpreter (meshio ≤ 5.3).
    elastic : ThermoElastic, optional
        If given, the vector ``displacement_m`` is written too.
    max_frames : int or None
        At most this many frames, evenly spread over the output times (always
        including the first and the last); None: every output time.
    peak_index : int, optional
        Index into ``result.times_s`` of the frame for ``peak.xdmf`` (it is kept
        among the frames).

    Returns
    -------
    Path
        ``path``.

    Examples
    --------
    >>> import tempfile, meshio
    >>> from arfem.fem.heat import build_axisymmetric, solve_modal
    >>> from arfem.params import Rod, paper_cycle
    >>> hm = build_axisymmetric(Rod(), nr=2, nz=4)
    >>> res = solve_modal(hm, paper_cycle(2000.0), store_fields=True)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = write_fields(hm, res, Path(d) / "fields.xdmf3")
    ...     with meshio.xdmf.TimeSeriesReader(p) as r:
    ...         pts, cells = r.read_points_cells()
    ...         t, pd, _ = r.read_data(r.num_steps - 1)
    ...         print(r.num_steps, t, sorted(pd), cells[0].type)
    5 86400.0 ['T_C', 'theta_K'] quad9
    """
    path = Path(path)
    if path.suffix.lower() not in (".xdmf3", ".xdmf"):
        raise InputError(f"must end in .xdmf3 (or .xdmf), got {path.name!r}", "path")
    pts, kind, kind_x, cells = node_grid(model)
    idx = _frames(result, max_frames)
    if peak_index is not None:
        idx = np.union1d(idx, [int(peak_index)])
    theta = np.asarray(result.fields)[idx]
    disp = _node_displacement(model, elastic, theta) if elastic is not None else None
    h5path = path.with_suffix(".h5")
    names = ["T_C", "theta_K"] + (["displacement_m"] if disp is not None else [])
    shapes = {"cells": cells.shape, "points": pts.shape, "T_C": (len(pts),),
              "theta_K": (len(pts),), "displacement_m": (len(pts), 3)}
    times_s = np.asarray(result.times_s, float)[idx]
    _write_h5(h5path, pts, cells, times_s, theta, model.rod.ambient_C, disp)
    peak = None if peak_index is None else int(np.searchsorted(idx, int(peak_index)))
    _write_xdmf(path, h5path.name, kind_x, shapes, times_s, names, peak)
    return path


def _write_h5(h5path: Path, pts, cells, times_s, theta, ambient_C: float, disp) -> None:
    """The heavy data of :func:`write_fields` (atomically): the mesh once, then per frame
    θ [K], T [°C] = θ + ``ambient_C`` and (``disp`` not None) the displacement [m], each
    a gzip-compressed dataset."""
    import h5py
    gz = {"compression": "gzip", "compression_opts": 4, "shuffle": True}
    with atomic_path(h5path) as tmp:
        # HDF5 1.10 object format: compact metadata (a third of the file with the 1.8 default)
        # and readable by every HDF5 from 1.10 on (Debian 12's ParaView links 1.10)
        with h5py.File(tmp, "w", libver=("v110", "v110")) as f:
            f.attrs["generator"] = "arfem"
            f.create_dataset("mesh/points", data=pts, **gz)
            f.create_dataset("mesh/cells", data=cells, **gz)
            f.create_dataset("time_s", data=times_s)
            for k in range(len(times_s)):
                f.create_dataset(f"theta_K/step_{k:05d}", data=theta[k], **gz)
                f.create_dataset(f"T_C/step_{k:05d}", data=theta[k] + ambient_C, **gz)
                if disp is not None:
                    f.create_dataset(f"displacement_m/step_{k:05d}", data=disp[k], **gz)


def _write_xdmf(path: Path, h5name: str, kind_x, shapes: dict, times_s, names: list,
                peak: int | None) -> None:
    """The XDMF 3 descriptions of :func:`write_fields` on the HDF5 file ``h5name``: a
    temporal collection with one grid per frame at ``path``, and (``peak`` not None)
    ``peak.xdmf`` beside it, the one grid of frame ``peak``."""
    import xml.etree.ElementTree as ET
    root = ET.Element("Xdmf", Version="3.0")
    coll = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="arfem_fields",
                         GridType="Collection", CollectionType="Temporal")
    for k, t in enumerate(times_s):
        _xdmf_grid(coll, f"t_{k:05d}", h5name, kind_x, shapes, k, float(t), names)
    atomic_write_text(path, _xdmf_text(root))
    if peak is not None:
        root = ET.Element("Xdmf", Version="3.0")
        _xdmf_grid(ET.SubElement(root, "Domain"), "peak", h5name, kind_x, shapes, peak,
                   None, names)
        atomic_write_text(path.with_name("peak.xdmf"), _xdmf_text(root))


def read_fields(path):
    """Read an arfem ``fields.xdmf3`` back: mesh and every step.

    A thin wrapper of ``meshio.xdmf.TimeSeriesReader`` (the reader for time series).

    Returns
    -------
    points : ndarray (n, 3)
        Node coordinates [m].
    cells : list of meshio.CellBlock
    steps : list of (time_s, point_data dict)
    """
    import meshio
    with meshio.xdmf.TimeSeriesReader(Path(path)) as r:
        pts, cells = r.read_points_cells()
        steps = [r.read_data(k)[:2] for k in range(r.num_steps)]
    return pts, cells, steps


def _revolve(pts: np.ndarray, cells: np.ndarray, n_phi: int = 36, sweep_deg: float = 270.0,
            start_deg: float = 0.0):
    """Revolve an (r, 0, z) quad section about the z axis into hexahedra."""
    phi = np.deg2rad(start_deg) + np.linspace(0.0, np.deg2rad(sweep_deg), n_phi + 1)
    r, z = pts[:, 0], pts[:, 2]
    n = len(pts)
    P = np.concatenate([np.column_stack([r * np.cos(f), r * np.sin(f), z]) for f in phi])
    hexes = [np.concatenate([cells + k * n, cells + (k + 1) * n], axis=1) for k in range(n_phi)]
    return P, np.concatenate(hexes), phi, n


def _nice_factor(x: float) -> float:
    """Largest 1, 2 or 5 × 10^k not above ``x`` (a readable exaggeration factor)."""
    if not np.isfinite(x) or x <= 0:
        return 1.0
    e = np.floor(np.log10(x))
    for m in (5.0, 2.0, 1.0):
        if m * 10 ** e <= x:
            return float(m * 10 ** e)
    return float(10 ** e)


#: colour map of the temperature pictures: perceptually uniform, readable in grey and by
#: colour-blind readers
CMAP = "viridis"
#: direction from the rod to the camera: perpendicular to the axis z, which runs to the right
_VIEW = (0.55, 1.0, 0.0)


def _render(grid, undeformed, clim, window_size):
    """Orthographic off-screen rendering; returns (image, world→pixel function)."""
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger
    verbosity = vtkLogger.GetCurrentVerbosityCutoff()
    # a headless machine has no X server; VTK falls back to off-screen rendering but logs a
    # warning on stderr first, which reads like a failure of a run that succeeded
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    try:
        pl.set_background("white")
        pl.add_mesh(grid, scalars="T_C", cmap=CMAP, clim=clim, show_edges=True,
                    edge_color="#555555", line_width=0.4, show_scalar_bar=False,
                    # mostly ambient light: the colours stay those of the colour bar
                    ambient=0.55, diffuse=0.45, specular=0.0)
        try:                              # pyvista >= 0.47 warns unless the algorithm is named
            surface = undeformed.extract_surface(algorithm=None)
        except TypeError:                 # older pyvista has no such keyword
            surface = undeformed.extract_surface()
        edges = surface.extract_feature_edges(
            feature_angle=40, boundary_edges=False, non_manifold_edges=False,
            manifold_edges=False)
        pl.add_mesh(edges, color="black", line_width=1.5, opacity=0.6)
        # the rod's axis (z) horizontal; the view direction is perpendicular to z, so with a
        # parallel projection every length along z is drawn to one scale
        pl.view_vector(_VIEW, viewup=(1.0, 0.0, 0.0))
        pl.enable_parallel_projection()
        pl.reset_camera()
        pl.camera.zoom(1.25)
        img = pl.screenshot(return_img=True)
        ren = pl.renderer
        h = img.shape[0]

        def to_px(p):
            ren.SetWorldPoint(float(p[0]), float(p[1]), float(p[2]), 1.0)
            ren.WorldToDisplay()
            x, y, _ = ren.GetDisplayPoint()
            return np.array([x, h - 1 - y])
        # evaluate the projections while the renderer is alive
        return img, to_px, pl
    except Exception:
        pl.close()
        raise
    finally:
        vtkLogger.SetStderrVerbosity(verbosity)


def _scene(model: HeatFEM, theta: np.ndarray, elastic, exaggeration):
    """The rod as pyvista grids for :func:`picture_figure`: (deformed grid, undeformed
    grid, colour limits [°C], growth ΔL [m] or None, displacement scale factor [-]); an
    axisymmetric section revolved through 270° with the missing quarter facing the
    camera."""
    import pyvista as pv
    rod = model.rod
    L = rod.length_m
    pts, kind, cells, tdofs = vertex_grid(model)
    T = theta[tdofs] + rod.ambient_C
    disp = _vertex_displacement(model, elastic, theta)[0] if elastic is not None else None
    growth = None
    if elastic is not None:
        growth = float(np.atleast_1d(elastic.growth(theta)[0])[0])
    if model.axisymmetric:
        # the missing quarter faces the camera, so the two cut planes show the core
        P, hexes, phi, n = _revolve(pts, cells, start_deg=np.rad2deg(np.arctan2(_VIEW[1],
                                                                                  _VIEW[0])) + 45)
        T = np.tile(T, phi.size)
        if disp is not None:
            ur, uz = disp[:, 0], disp[:, 2]
            disp = np.concatenate([np.column_stack([ur * np.cos(f), ur * np.sin(f), uz])
                                   for f in phi])
        pts, cells = P, hexes
    grid = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: cells}, pts)
    grid.point_data["T_C"] = T
    undeformed = grid.copy()
    scale = 0.0
    if disp is not None:
        umax = float(np.max(np.linalg.norm(disp, axis=1)))
        scale = (_nice_factor(0.08 * L / umax) if umax > 0 else 1.0) \
            if exaggeration is None else float(exaggeration)
        grid.point_data["displacement_m"] = disp
        grid = grid.warp_by_vector("displacement_m", factor=scale)
    clim = [float(T.min()), float(T.max())]
    if clim[1] - clim[0] < 1e-9:
        clim[1] = clim[0] + 1.0
    return grid, undeformed, clim, growth, scale


def _crop(img: np.ndarray, pad: int, heat_c, z0, far_x: float):
    """Crop the empty margins of the rendering, keeping room for the arrows left of the
    heated end (``heat_c`` [px]), the ruler below ``z0`` [px] and the grown end at
    ``far_x`` [px]; returns the image and the (column, row) offset of its corner."""
    content = np.argwhere(np.any(img[..., :3] < 250, axis=-1))
    r0, c0 = content.min(axis=0)
    r1, c1 = content.max(axis=0)
    c0 = max(0, min(c0, int(heat_c[0]) - 9 * pad) - pad)
    c1 = min(img.shape[1], max(c1, int(far_x)) + 9 * pad)
    r0 = max(0, r0 - pad)
    r1 = min(img.shape[0], max(r1, int(z0[1])) + 3 * pad)
    return img[r0:r1, c0:c1], np.array([c0, r0])


def _draw_ruler(ax, a, b, L: float, R: float, px_per_m: float, pad: int) -> None:
    """The ruler along z from ``a`` to ``b`` [px] in mm (the picture's axis and scale)
    and a 100 mm bar across the axis (screen-up is perpendicular to the view: to scale)."""
    ink = dict(color="black", fontsize=8)
    # ruler along z: the axes of the picture and its scale bar
    ax.plot([a[0], b[0]], [a[1], b[1]], color="black", lw=1.2)
    step = 0.1 if L >= 0.3 else 0.05 if L >= 0.1 else 0.01
    for zt in np.arange(0.0, L + 1e-12, step):
        x = a[0] + zt * px_per_m
        ax.plot([x, x], [a[1], a[1] + 8], color="black", lw=1)
        ax.text(x, a[1] + 12, f"{zt * 1e3:.0f}", ha="center", va="top", **ink)
    ax.text((a[0] + b[0]) / 2, a[1] + 45, "axial position z [mm] (undeformed; drawn to scale)",
            ha="center", va="top", **ink)
    # a 100 mm scale bar across the axis (screen-up is perpendicular to the view: to scale)
    bar = 0.1 if R >= 0.05 else 0.01
    x = a[0] - 2 * pad
    ax.plot([x, x], [a[1], a[1] - bar * px_per_m], color="black", lw=2.5, solid_capstyle="butt")
    ax.text(x - 6, a[1] - bar * px_per_m / 2, f"{bar * 1e3:.0f} mm", ha="right", va="center",
            rotation=90, **ink)


def _landmarks(to_px, L: float, R: float):
    """Where the annotations go on the rendering [px]: the ruler's ends under the rod
    (z = 0 and L), the heated end's centre and top, the far end's top and bottom."""
    v = np.array(_VIEW) / np.linalg.norm(_VIEW)
    up = np.array([1.0, 0.0, 0.0]) - v[0] * v
    up /= np.linalg.norm(up)                                     # screen-up direction
    below = -1.8 * R * up                                        # ruler line, under the rod
    z0, zL = to_px(below), to_px(below + [0, 0, L])
    heat_c, heat_top = to_px((0, 0, 0)), to_px(R * up)
    far_top, far_bot = to_px(1.15 * R * up + [0, 0, L]), to_px(-1.15 * R * up + [0, 0, L])
    return z0, zL, heat_c, heat_top, far_top, far_bot


def _draw_ends(ax, hc, ht, ft, fb, growth, scale: float, px_per_m: float, pad: int,
               heat_flux_W_m2) -> None:
    """The heated end (centre ``hc``, top ``ht`` [px]) with its flux arrows, and the far
    end (top ``ft``, bottom ``fb`` [px]): undeformed (dashed) and grown by ``growth``
    [m] drawn × ``scale`` (solid), with ΔL written beside it."""
    ink = dict(color="black", fontsize=8)
    # heated end
    qtxt = f"q = {heat_flux_W_m2:g} W/m²" if heat_flux_W_m2 is not None else "heat flux q"
    for f in (-0.5, 0.0, 0.5) if heat_flux_W_m2 is None or heat_flux_W_m2 > 0 else ():
        y = hc[1] + f * (hc[1] - ht[1])
        ax.annotate("", xy=(hc[0] - 4, y), xytext=(hc[0] - 4 * pad, y),
                    arrowprops=dict(arrowstyle="-|>", color="#b2182b", lw=1.6))
    ax.text(hc[0] - 4.5 * pad, hc[1], f"heated end\nz = 0\n{qtxt}", ha="right", va="center",
            color="#b2182b", fontsize=8)
    # far end: undeformed position and the grown end
    ax.plot([ft[0], fb[0]], [ft[1], fb[1]], ls="--", color="black", lw=1)
    if growth is not None:
        xg = ft[0] + growth * scale * px_per_m
        ax.plot([xg, xg], [ft[1], fb[1]], ls="-", color="#2166ac", lw=1.4)
        ax.annotate("", xy=(xg, fb[1] - 6), xytext=(ft[0], fb[1] - 6),
                    arrowprops=dict(arrowstyle="-|>", color="#2166ac", lw=1.2))
        ax.text(xg + 10, (ft[1] + fb[1]) / 2, f"grown end\nΔL = {growth * 1e6:.2f} µm\n"
                f"(displacement\ndrawn × {scale:g})", ha="left", va="center",
                color="#2166ac", fontsize=8)
        ax.text(ft[0], ft[1] - 4, "undeformed end", ha="center", va="bottom", **ink)


def picture_figure(model: HeatFEM, theta: np.ndarray, elastic=None,
                   exaggeration: float | None = None, title: str | None = None,
                   heat_flux_W_m2: float | None = None, window_size=(1800, 900)):
    """Annotated 3D picture of the temperature on the deformed rod (a matplotlib Figure).

    An orthographic pyvista rendering (an axisymmetric section revolved through
    270°, so the cut shows the core) with, drawn by matplotlib on top: a ruler
    along the axis in mm (the scale bar), a 100 mm bar across it, arrows at the
    heated end z = 0, the undeformed (dashed) and grown (solid) far end with the
    growth ΔL and the exaggeration factor, and a colour bar T [°C].

    Parameters
    ----------
    model : HeatFEM
    theta : ndarray (ndofs,)
        Temperature rise [K] of one state.
    elastic : ThermoElastic, optional
        If given, the rod is drawn displaced by ``exaggeration`` × u.
    exaggeration : float, optional
        Displacement scale factor [-]; default: a round number (1, 2 or 5 × 10^k) that
        draws the largest displacement as at most 8 % of the rod length.
    title : str, optional
        Figure title.
    heat_flux_W_m2 : float, optional
        Flux into the heated end at this instant [W/m²], written at the arrows.
    window_size : (int, int)
        Size of the 3D rendering [px].

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure
    from matplotlib import cm, colors
    theta = np.asarray(theta, float)
    if theta.shape != (model.ndofs,):
        raise InputError(f"needs {model.ndofs} values", "theta")
    L, R = model.rod.length_m, model.rod.radius_m
    grid, undeformed, clim, growth, scale = _scene(model, theta, elastic, exaggeration)
    img, to_px, pl = _render(grid, undeformed, clim, window_size)
    try:
        z0, zL, heat_c, heat_top, far_top, far_bot = _landmarks(to_px, L, R)
    finally:
        pl.close()
    px_per_m = (zL[0] - z0[0]) / L
    pad = int(0.02 * img.shape[1])
    img, off = _crop(img, pad, heat_c, z0, zL[0] + (growth or 0) * scale * px_per_m)
    sh = lambda p: p - off                                           # noqa: E731

    fig = Figure(figsize=(10, 10 * img.shape[0] / img.shape[1] + 0.9), dpi=150,
                 layout="constrained")
    ax = fig.add_subplot()
    ax.imshow(img, interpolation="lanczos")
    ax.set_axis_off()
    ax.set_xlim(0, img.shape[1])
    ax.set_ylim(img.shape[0], -0.02 * img.shape[0])
    a, b = sh(z0), sh(zL)
    _draw_ruler(ax, a, b, L, R, px_per_m, pad)
    _draw_ends(ax, sh(heat_c), sh(heat_top), sh(far_top), sh(far_bot), growth, scale,
               px_per_m, pad, heat_flux_W_m2)
    norm = colors.Normalize(*clim)
    cb = fig.colorbar(cm.ScalarMappable(norm=norm, cmap=CMAP), ax=ax, orientation="horizontal",
                      fraction=0.05, shrink=0.5, pad=0.01, aspect=40)
    cb.set_label("temperature T [°C]", fontsize=8)
    cb.ax.tick_params(labelsize=8)
    if title:
        ax.set_title(title, fontsize=9)
    fig.arfem_exaggeration = scale
    return fig


def render_png(model: HeatFEM, theta: np.ndarray, path, elastic=None,
               exaggeration: float | None = None, title: str | None = None,
               heat_flux_W_m2: float | None = None, window_size=(1800, 900)) -> Path:
    """Save :func:`picture_figure` as a PNG (atomically).

    Parameters
    ----------
    model, theta, elastic, exaggeration, title, heat_flux_W_m2, window_size
        See :func:`picture_figure`.
    path : str or Path
        Target ``.png`` file.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise InputError(f"must end in .png, got {path.name!r}", "path")
    fig = picture_figure(model, theta, elastic=elastic, exaggeration=exaggeration, title=title,
                         heat_flux_W_m2=heat_flux_W_m2, window_size=window_size)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return path


def write_scenario_fields(model: HeatFEM, result: HeatResult, out_dir, elastic=None,
                          max_frames: int | None = 200, title: str | None = None,
                          heat_flux_W_m2: float | None = None,
                          fields_xdmf: str | None = "fields.xdmf3",
                          picture_png: str | None = "temperature_3d.png",
                          progress=None) -> dict:
    """Field outputs of one scenario: ``fields.xdmf3`` + ``fields.h5`` (+ ``peak.xdmf``)
    and ``temperature_3d.png`` (what ``arfem run`` writes, where the scenario asks).

    The picture shows the stored field with the largest growth (the peak).

    Parameters
    ----------
    model : HeatFEM
    result : HeatResult
        With stored fields.
    out_dir : str or Path
        Directory (created if needed); typically a staging directory of
        :func:`arfem.io.staged_out_dir`.
    elastic : ThermoElastic, optional
        Adds the displacement to both outputs; built from ``model`` if None.
    max_frames : int or None
        See :func:`write_fields`.
    title : str, optional
        Picture caption (the time of the frame is appended).
    heat_flux_W_m2 : float, optional
        Flux at the heated end at the peak instant [W/m²], for the picture.
    fields_xdmf, picture_png : str or None
        Where each goes, relative to ``out_dir``; None: not written.
    progress : callable, optional
        Called with the name of each of the two slow steps as it starts.

    Returns
    -------
    dict
        ``{"fields_xdmf": Path or None, "picture_png": Path or None,
        "picture_time_s": float}``.
    """
    from arfem.fem.elastic import ThermoElastic
    out = Path(out_dir)
    if result.fields is None:
        raise InputError("has no stored fields; solve with store_fields=True", "result")
    el = elastic if elastic is not None else ThermoElastic.build(model)
    k = int(np.argmax(result.growth_m))
    xdmf = png = None
    progress = progress or (lambda step: None)
    if fields_xdmf is not None:
        progress("fields.xdmf3 + fields.h5")
        xdmf = write_fields(model, result, out / fields_xdmf, elastic=el,
                            max_frames=max_frames, peak_index=k)
    t = float(result.times_s[k])
    cap = f"{title + ': ' if title else ''}temperature at peak growth, t = {t / 3600:.2f} h"
    if picture_png is not None:
        progress("3D picture")
        png = render_png(model, np.asarray(result.fields[k]), out / picture_png,
                         elastic=el, title=cap, heat_flux_W_m2=heat_flux_W_m2)
    return {"fields_xdmf": xdmf, "picture_png": png, "picture_time_s": t}


# -- annotations of an orthographic 3D picture (the geometry picture of a mesh scenario) ----

@dataclass(frozen=True)
class ParallelView:
    """An orthographic camera as the picture sees it: the screen's right and up
    directions in the model's axes (unit vectors) and the scale [px per m]."""

    right: tuple
    up: tuple
    px_per_m: float

    @classmethod
    def of(cls, position, focal_point, view_up, parallel_scale_m: float,
           height_px: int) -> "ParallelView":
        """From a VTK camera: ``parallel_scale_m`` is half the viewport's height [m]."""
        d = np.asarray(focal_point, float) - np.asarray(position, float)
        d /= np.linalg.norm(d)
        right = np.cross(d, np.asarray(view_up, float))
        right /= np.linalg.norm(right)
        up = np.cross(right, d)
        return cls(tuple(right), tuple(up), height_px / (2.0 * parallel_scale_m))


def draw_scale_bar(ax, view: ParallelView, shape: tuple) -> float:
    """A scale bar of a round length (1, 2 or 5 × 10^k mm, at most 20 % of the image's
    width) in the bottom right corner of an image of ``shape`` shown in ``ax`` (pixel
    coordinates). Returns its length [m]. True at every depth: the view is orthographic.
    """
    L = _nice_factor(0.2 * shape[1] / view.px_per_m * 1e3) * 1e-3
    w = L * view.px_per_m
    x1, y = shape[1] * 0.97, shape[0] * 0.96
    tick = 0.012 * shape[0]
    ax.plot([x1 - w, x1], [y, y], color="black", lw=4, solid_capstyle="butt")
    for x in (x1 - w, x1):
        ax.plot([x, x], [y - tick, y + tick], color="black", lw=2)
    ax.text(x1 - w / 2, y - 1.6 * tick, f"{L * 1e3:g} mm", ha="center", va="bottom",
            fontsize=13, color="black")
    return L


def draw_axis_triad(ax, view: ParallelView, origin_px: tuple, length_px: float) -> None:
    """The model's x, y and z axes as arrows from ``origin_px`` (image pixels), each as
    long as it appears in the view (foreshortened), with large labels."""
    colours = {"x": "#d62728", "y": "#2ca02c", "z": "#1f77b4"}
    for k, name in enumerate("xyz"):
        e = np.eye(3)[k]
        dx, dy = float(e @ view.right), -float(e @ view.up)     # image y runs down
        if np.hypot(dx, dy) < 0.15:                               # along the view: a dot
            ax.plot(*origin_px, "o", color=colours[name], ms=8)
            ax.text(origin_px[0] + 0.1 * length_px, origin_px[1] - 0.1 * length_px, name,
                    color=colours[name],
                    fontsize=15, fontweight="bold")
            continue
        tip = (origin_px[0] + length_px * dx, origin_px[1] + length_px * dy)
        ax.annotate("", xy=tip, xytext=origin_px,
                    arrowprops=dict(arrowstyle="-|>", color=colours[name], lw=2.5,
                                    mutation_scale=18))
        pad = 0.2 * length_px / np.hypot(dx, dy)
        ax.text(tip[0] + pad * dx, tip[1] + pad * dy,
                name, color=colours[name], fontsize=15, fontweight="bold", ha="center",
                va="center")
