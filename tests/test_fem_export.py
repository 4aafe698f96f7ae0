"""Field export: the XDMF/HDF5 time series holds the solved values on the quadratic cells,
VTK (what ParaView uses) reads it back, and the 3D picture is drawn with its annotations."""
from __future__ import annotations

import meshio
import numpy as np
import pytest

from arfem.fem.elastic import ThermoElastic
from arfem.fem.export import (node_grid, picture_figure, read_fields, render_png, write_fields,
                              write_scenario_fields)
from arfem.fem.heat import build_3d, build_axisymmetric, solve_modal, solve_theta
from arfem.params import InputError, Rod, paper_cycle

ROD = Rod()
TIMES = np.array([0.0, 4 * 3600.0, 9.5 * 3600.0, 24 * 3600.0])
#: meshio cell type and VTK cell id of each model's elements
CELLS = {"axi": ("quad9", 28), "3d": ("hexahedron20", 25)}   # VTK_BIQUADRATIC_QUAD, VTK_QUADRATIC_HEXAHEDRON


@pytest.fixture(scope="module", params=["axi", "3d"])
def case(request):
    model = (build_axisymmetric(ROD, order=2, nr=2, nz=8) if request.param == "axi"
             else build_3d(ROD, order=2, n_core=2, n_ring=1, nz=4))
    res = solve_modal(model, paper_cycle(2000.0), output_times_s=TIMES, store_fields=True)
    return request.param, model, res, ThermoElastic.build(model)


def test_xdmf_round_trip(case, tmp_path):
    """What meshio's time-series reader reads back equals the solution at every node.

    Property: the quadratic cells are written as quadratic (every dof is a node,
    9-node quads / 20-node bricks), the times are the output times in seconds,
    T = θ + ambient and the displacement vector at every node survive the write
    exactly (HDF5 float64, so 1e-12 relative), and only fields.xdmf3 + fields.h5
    remain (the temporary names were renamed).
    """
    kind, model, res, te = case
    path = write_fields(model, res, tmp_path / "fields.xdmf3", elastic=te)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fields.h5", "fields.xdmf3"]
    pts, cells, steps = read_fields(path)
    assert pts.shape == (model.ndofs, 3)
    assert cells[0].type == CELLS[kind][0]
    assert len(steps) == TIMES.size
    dim = model.basis.mesh.dim()
    for k, (t, pd) in enumerate(steps):
        assert t == pytest.approx(TIMES[k])
        assert np.allclose(pd["T_C"], res.fields[k] + ROD.ambient_C, rtol=1e-12, atol=1e-12)
        U = te.displacement(res.fields[k])
        assert pd["displacement_m"].shape == (model.ndofs, 3)
        assert np.allclose(pd["displacement_m"][:, 2], U[dim - 1::dim], rtol=1e-12, atol=1e-18)
    # the peak frame is really heated and really grown
    pd = steps[2][1]
    assert pd["T_C"].max() > ROD.ambient_C + 5
    far = np.isclose(pts[:, 2], ROD.length_m)
    assert pd["displacement_m"][far, 2].mean() == pytest.approx(res.growth_m[2], rel=0.02)


def test_vtk_reads_the_quadratic_cells(case, tmp_path):
    """VTK's XDMF reader (ParaView's) gets the time steps, the quadratic cell types and,
    through VTK's own quadratic interpolation, the finite-element field itself.

    Property: probing the VTK grid at points inside elements gives the value of
    scikit-fem's interpolant there. Two mid-side nodes swapped in every cell move
    the probed values by ~6 K (measured on this 3D mesh). Axisymmetric: the same
    bilinear geometry map on both sides, so to round-off (1e-8 K). 3D: scikit-fem
    maps the bricks with 27 geometry nodes and VTK with the 20 written ones, which
    moves a point's reference coordinates slightly: 2.8e-4 K measured, 2e-3 K
    allowed, still 3000 times below the swapped-node error.
    """
    pv = pytest.importorskip("pyvista")
    kind, model, res, te = case
    path = write_fields(model, res, tmp_path / "fields.xdmf3", elastic=te)
    r = pv.XdmfReader(str(path))
    assert r.time_values == pytest.approx(list(TIMES))
    r.set_active_time_value(TIMES[2])
    grid = r.read()
    assert set(np.unique(grid.celltypes)) == {CELLS[kind][1]}
    assert grid.point_data["displacement_m"].shape == (model.ndofs, 3)
    rng = np.random.default_rng(3)
    z = rng.uniform(0.02, 0.78, 12)
    r_ = rng.uniform(0.0, 0.06, 12)
    if model.axisymmetric:
        xq = np.vstack([r_, z])
        probe = np.column_stack([r_, np.zeros_like(r_), z])
    else:
        xq = np.vstack([r_ / 3, r_ / 4, z])
        probe = xq.T
    ref = model.basis.probes(xq) @ res.fields[2] + ROD.ambient_C
    got = pv.PolyData(probe).sample(grid).point_data["T_C"]
    assert np.allclose(got, ref, rtol=0, atol=1e-8 if model.axisymmetric else 2e-3)


def test_peak_file_is_what_meshio_read_reads(case, tmp_path):
    """peak.xdmf (one grid, same HDF5 data) is readable by ``meshio.read`` and holds the
    peak frame; ``meshio.read`` cannot read any XDMF time series (meshio issue 461), so
    the single-grid file is the one to give it."""
    kind, model, res, te = case
    write_fields(model, res, tmp_path / "fields.xdmf3", elastic=te, peak_index=2)
    m = meshio.read(tmp_path / "peak.xdmf")
    assert m.cells[0].type == CELLS[kind][0]
    assert np.allclose(m.point_data["theta_K"], res.fields[2], rtol=1e-12, atol=1e-12)


def test_meshio_read_of_the_series_raises_and_never_exits(tmp_path):
    """Issue 15: ``meshio.read`` of the written time series must raise a normal exception
    (or read it), never end the interpreter. meshio <= 5.3 calls ``sys.exit`` on an
    ``.xdmf`` it cannot read, so the series is ``.xdmf3``, an extension meshio does not
    guess. Run in a subprocess so that an exit would show as a failed child, not kill
    pytest; the child must print the exception's name and exit 0."""
    import subprocess
    import sys

    from arfem.fem.heat import build_axisymmetric, solve_modal
    from arfem.params import Rod, paper_cycle
    hm = build_axisymmetric(Rod(), nr=2, nz=4)
    path = write_fields(hm, solve_modal(hm, paper_cycle(2000.0), store_fields=True),
                        tmp_path / "fields.xdmf3")
    code = ("import meshio, sys\n"
            "try:\n    meshio.read(sys.argv[1])\n    print('read')\n"
            "except Exception as e:\n    print('raised', type(e).__name__)\n")
    r = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.split()[0] in ("raised", "read")
    with meshio.xdmf.TimeSeriesReader(path) as rd:       # the series itself still reads
        assert rd.num_steps == 5


def test_max_frames_thins_evenly(tmp_path):
    """``max_frames`` keeps first and last output times and at most that many frames."""
    model = build_axisymmetric(ROD, order=1, nr=1, nz=4)
    res = solve_theta(model, paper_cycle(2000.0), 3600.0, store_fields=True)   # 25 frames
    path = write_fields(model, res, tmp_path / "f.xdmf", max_frames=5)
    _, cells, steps = read_fields(path)
    ts = [t for t, _ in steps]
    assert cells[0].type == "quad"
    assert len(ts) == 5 and ts[0] == 0.0 and ts[-1] == pytest.approx(24 * 3600.0)


def test_failed_write_leaves_nothing(case, tmp_path, monkeypatch):
    """A write that fails half-way leaves neither fields.h5 nor fields.xdmf3 nor a temp file."""
    import h5py
    kind, model, res, te = case

    def boom(*a, **k):
        raise OSError("disk full")
    monkeypatch.setattr(h5py.Group, "create_dataset", boom)
    with pytest.raises(OSError):
        write_fields(model, res, tmp_path / "fields.xdmf3", elastic=te)
    assert list(tmp_path.iterdir()) == []


def test_node_grid_orders_cells_like_vtk():
    """Each quadratic cell's mid-side nodes lie between the corners VTK says they do.

    Property (axisymmetric, straight edges): node 4 of a VTK biquadratic quad is
    the midpoint of corners 0-1, ..., node 8 the centre; to round-off.
    """
    p, kind, xkind, c = node_grid(build_axisymmetric(ROD, order=2, nr=2, nz=3))
    assert (kind, xkind) == ("quad9", "Quadrilateral_9")
    P = p[c]                                            # (cells, 9, 3)
    for j, (a, b) in enumerate([(0, 1), (1, 2), (2, 3), (3, 0)]):
        assert np.allclose(P[:, 4 + j], (P[:, a] + P[:, b]) / 2, atol=1e-14)
    assert np.allclose(P[:, 8], P[:, :4].mean(axis=1), atol=1e-14)


def test_picture_is_drawn(case, tmp_path):
    """The 3D picture is a real PNG with the annotations an engineer needs, written atomically.

    Property: the figure carries the title with the time, a colour bar in °C, the
    ruler in mm, the heated end, and the growth with its exaggeration factor;
    the PNG is non-blank (pixel variance) and no temporary file is left.
    """
    import matplotlib.image as mpimg
    kind, model, res, te = case
    out = write_scenario_fields(model, res, tmp_path / "out", elastic=te, title="test",
                                heat_flux_W_m2=2000.0)
    png = out["picture_png"]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(png)
    assert img.shape[0] > 300 and img.shape[1] > 1000 and img[..., :3].std() > 0.05
    assert out["picture_time_s"] == pytest.approx(9.5 * 3600.0)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "fields.h5", "fields.xdmf3", "peak.xdmf", "temperature_3d.png"]
    fig = picture_figure(model, res.fields[2], elastic=te, title="t = 9.50 h",
                         heat_flux_W_m2=2000.0)
    texts = " ".join(t.get_text() for ax in fig.axes for t in ax.texts)
    labels = " ".join(ax.get_xlabel() for ax in fig.axes)
    assert "[°C]" in labels and "z [mm]" in texts and "heated end" in texts
    assert "2000 W/m²" in texts and f"× {fig.arfem_exaggeration:g}" in texts
    assert "9.50 h" in fig.axes[0].get_title()


def test_export_refuses_bad_requests(case, tmp_path):
    """No stored fields, a wrong suffix or a wrong field size raise InputError; nothing is written."""
    kind, model, res, te = case
    bare = solve_modal(model, paper_cycle(2000.0), output_times_s=TIMES)
    with pytest.raises(InputError):
        write_fields(model, bare, tmp_path / "a.xdmf")
    with pytest.raises(InputError):
        write_fields(model, res, tmp_path / "a.vtu")
    with pytest.raises(InputError):
        render_png(model, np.zeros(model.ndofs + 1), tmp_path / "a.png")
    with pytest.raises(InputError):
        render_png(model, res.fields[1], tmp_path / "a.jpg")
    assert list(tmp_path.iterdir()) == []
