"""Field output: an XDMF time series (ParaView) and a 3D picture of the rod.

Data flow: a :class:`arfem.fem.heat.HeatResult` with stored fields (and optionally a
:class:`arfem.fem.elastic.ThermoElastic` for the displacement) → files. No global
state; every file is written to a temporary name beside its target and renamed
into place, so a reader never sees a half-written file.

* :func:`write_fields` -- temperature ``T_C``, rise ``theta_K`` and displacement
  ``displacement_m`` at the mesh vertices, one frame per output time, on the
  *linear* cells of the mesh (quadratic elements contribute their vertex values),
  as XDMF 3 with inline XML data (no HDF5 dependency; ParaView opens it).
  Axisymmetric results are written in the plane y = 0 (x = r), displacement
  (u_r, 0, u_z).
* :func:`render_png` -- an off-screen pyvista picture of the temperature on the
  displaced (exaggerated) rod; an axisymmetric section is revolved through 270°.
* :func:`write_scenario_fields` -- both at once into an output directory; what
  the scenario runner calls.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from arfem.fem.heat import HeatFEM, HeatResult
from arfem.io import atomic_path
from arfem.params import InputError

__all__ = ["vertex_grid", "write_fields", "render_png", "write_scenario_fields"]


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


def write_fields(model: HeatFEM, result: HeatResult, path, elastic=None,
                 max_frames: int | None = 200) -> Path:
    """Write temperature (and displacement) as an XDMF time series.

    Parameters
    ----------
    model : HeatFEM
        The model that produced ``result``.
    result : HeatResult
        Must hold ``fields`` (solve with ``store_fields=True``).
    path : str or Path
        Target ``.xdmf`` file (parent directories are created).
    elastic : ThermoElastic, optional
        If given, ``displacement_m`` is written too.
    max_frames : int or None
        At most this many frames, evenly spread over the output times (always
        including the first and the last); None: every output time.

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
    ...     p = write_fields(hm, res, Path(d) / "fields.xdmf")
    ...     with meshio.xdmf.TimeSeriesReader(p) as r:
    ...         pts, cells = r.read_points_cells()
    ...         t, pd, _ = r.read_data(r.num_steps - 1)
    ...         print(r.num_steps, t, sorted(pd))
    5 86400.0 ['T_C', 'theta_K']
    """
    import meshio
    path = Path(path)
    if path.suffix.lower() != ".xdmf":
        raise InputError(f"must end in .xdmf, got {path.name!r}", "path")
    pts, kind, cells, tdofs = vertex_grid(model)
    idx = _frames(result, max_frames)
    theta = np.asarray(result.fields)[idx]
    disp = _vertex_displacement(model, elastic, theta) if elastic is not None else None
    # inline XML: one self-contained file, renamed atomically into place
    with atomic_path(path) as tmp:
        with meshio.xdmf.TimeSeriesWriter(tmp, data_format="XML") as w:
            w.write_points_cells(pts, [(kind, cells)])
            for k, i in enumerate(idx):
                th = theta[k][tdofs]
                pd = {"theta_K": th, "T_C": th + model.rod.ambient_C}
                if disp is not None:
                    pd["displacement_m"] = disp[k]
                w.write_data(float(result.times_s[i]), point_data=pd)
    return path


def _revolve(pts: np.ndarray, cells: np.ndarray, n_phi: int = 36, sweep_deg: float = 270.0):
    """Revolve an (r, 0, z) quad section about the z axis into hexahedra."""
    phi = np.linspace(0.0, np.deg2rad(sweep_deg), n_phi + 1)
    r, z = pts[:, 0], pts[:, 2]
    n = len(pts)
    P = np.concatenate([np.column_stack([r * np.cos(f), r * np.sin(f), z]) for f in phi])
    hexes = [np.concatenate([cells + k * n, cells + (k + 1) * n], axis=1) for k in range(n_phi)]
    return P, np.concatenate(hexes), phi, n


def render_png(model: HeatFEM, theta: np.ndarray, path, elastic=None,
               exaggeration: float | None = None, title: str | None = None,
               window_size=(1400, 700)) -> Path:
    """Off-screen picture of the temperature on the (exaggerated) displaced rod.

    Parameters
    ----------
    model : HeatFEM
    theta : ndarray (ndofs,)
        Temperature rise [K] of one state.
    path : str or Path
        Target ``.png`` file.
    elastic : ThermoElastic, optional
        If given, the rod is drawn displaced by ``exaggeration`` × u.
    exaggeration : float, optional
        Displacement scale factor [-]; default: the largest displacement is drawn
        as 5 % of the rod length.
    title : str, optional
        Text drawn in the upper-left corner.
    window_size : (int, int)
        Image size [px].

    Returns
    -------
    Path
        ``path``.
    """
    import pyvista as pv
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise InputError(f"must end in .png, got {path.name!r}", "path")
    theta = np.asarray(theta, float)
    if theta.shape != (model.ndofs,):
        raise InputError(f"needs {model.ndofs} values", "theta")
    pts, kind, cells, tdofs = vertex_grid(model)
    T = theta[tdofs] + model.rod.ambient_C
    disp = _vertex_displacement(model, elastic, theta)[0] if elastic is not None else None
    if model.axisymmetric:
        P, hexes, phi, n = _revolve(pts, cells)
        T = np.tile(T, phi.size)
        if disp is not None:
            ur, uz = disp[:, 0], disp[:, 2]
            disp = np.concatenate([np.column_stack([ur * np.cos(f), ur * np.sin(f), uz])
                                   for f in phi])
        pts, cells = P, hexes
    grid = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: cells}, pts)
    grid.point_data["T_C"] = T
    scale = 0.0
    if disp is not None:
        umax = float(np.max(np.linalg.norm(disp, axis=1)))
        scale = (0.05 * model.rod.length_m / umax if umax > 0 else 0.0) \
            if exaggeration is None else float(exaggeration)
        grid.point_data["displacement_m"] = disp
        grid = grid.warp_by_vector("displacement_m", factor=scale)
    from vtkmodules.vtkCommonCore import vtkLogger
    verbosity = vtkLogger.GetCurrentVerbosityCutoff()
    # a headless machine has no X server; VTK falls back to off-screen rendering but logs a
    # warning on stderr first, which reads like a failure of a run that succeeded
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    try:
        pl.add_mesh(grid, scalars="T_C", cmap="inferno", show_edges=True, edge_color="grey",
                    line_width=0.5, scalar_bar_args={"title": "T [°C]"})
        label = title or ""
        if disp is not None:
            label += f"{chr(10) if label else ''}displacement × {scale:.3g}"
        if label:
            pl.add_text(label, position="upper_left", font_size=10)
        # rod lying horizontally (z to the right), seen slightly from above
        pl.view_vector((0.6, -1.0, 0.0), viewup=(1.0, 0.0, 0.0))
        pl.reset_camera()
        pl.camera.zoom(1.4)
        with atomic_path(path) as tmp:
            pl.screenshot(str(tmp))
    finally:
        pl.close()
        vtkLogger.SetStderrVerbosity(verbosity)
    return path


def write_scenario_fields(model: HeatFEM, result: HeatResult, out_dir, elastic=None,
                          max_frames: int | None = 200, title: str | None = None) -> dict:
    """Field outputs of one scenario: ``fields.xdmf`` and ``temperature_3d.png``.

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

    Returns
    -------
    dict
        ``{"fields_xdmf": Path, "picture_png": Path, "picture_time_s": float}``.
    """
    from arfem.fem.elastic import ThermoElastic
    out = Path(out_dir)
    if result.fields is None:
        raise InputError("has no stored fields; solve with store_fields=True", "result")
    el = elastic if elastic is not None else ThermoElastic.build(model)
    xdmf = write_fields(model, result, out / "fields.xdmf", elastic=el, max_frames=max_frames)
    k = int(np.argmax(result.growth_m))
    t = float(result.times_s[k])
    cap = f"{title + ', ' if title else ''}t = {t / 3600:.2f} h (peak growth)"
    png = render_png(model, np.asarray(result.fields[k]), out / "temperature_3d.png",
                     elastic=el, title=cap)
    return {"fields_xdmf": xdmf, "picture_png": png, "picture_time_s": t}
