"""Field export: the XDMF time series holds the solved values, and the picture is drawn."""
from __future__ import annotations

import meshio
import numpy as np
import pytest

from arfem.fem.elastic import ThermoElastic
from arfem.fem.export import render_png, write_fields, write_scenario_fields
from arfem.fem.heat import build_3d, build_axisymmetric, solve_modal, solve_theta
from arfem.params import InputError, Rod, paper_cycle

ROD = Rod()
TIMES = np.array([0.0, 4 * 3600.0, 9.5 * 3600.0, 24 * 3600.0])


@pytest.fixture(scope="module", params=["axi", "3d"])
def case(request):
    model = (build_axisymmetric(ROD, nr=2, nz=8) if request.param == "axi"
             else build_3d(ROD, n_core=2, n_ring=1, nz=4))
    res = solve_modal(model, paper_cycle(2000.0), output_times_s=TIMES, store_fields=True)
    return model, res, ThermoElastic.build(model)


def test_xdmf_round_trip(case, tmp_path):
    """What ParaView would read back equals the solution at the vertices, frame by frame.

    Property: times, T = θ + ambient at every vertex and the displacement at
    every vertex survive the write exactly (values are written as text with
    full precision, so the tolerance is 1e-12 relative). Only the target file
    remains in the directory (the temporary one was renamed).
    """
    model, res, te = case
    path = write_fields(model, res, tmp_path / "fields.xdmf", elastic=te)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fields.xdmf"]
    vdofs = model.basis.nodal_dofs[0]
    with meshio.xdmf.TimeSeriesReader(path) as r:
        pts, cells = r.read_points_cells()
        assert r.num_steps == TIMES.size
        assert pts.shape == (model.basis.mesh.nvertices, 3)
        assert cells[0].type == ("quad" if model.axisymmetric else "hexahedron")
        for k in range(r.num_steps):
            t, pd, _ = r.read_data(k)
            assert t == pytest.approx(TIMES[k])
            T = res.fields[k][vdofs] + ROD.ambient_C
            assert np.allclose(pd["T_C"], T, rtol=1e-12, atol=1e-12)
            U = te.displacement(res.fields[k])
            uz = U[te.basis.nodal_dofs[model.basis.mesh.dim() - 1]]
            assert np.allclose(pd["displacement_m"][:, 2], uz, rtol=1e-12, atol=1e-18)
    # the peak frame is really heated and really grown
    assert pd is not None
    with meshio.xdmf.TimeSeriesReader(path) as r:
        r.read_points_cells()
        _, pd, _ = r.read_data(2)
    assert pd["T_C"].max() > ROD.ambient_C + 5
    far = np.isclose(pts[:, 2], ROD.length_m)
    assert pd["displacement_m"][far, 2].mean() == pytest.approx(res.growth_m[2], rel=0.02)


def test_max_frames_thins_evenly(tmp_path):
    """``max_frames`` keeps first and last output times and at most that many frames."""
    model = build_axisymmetric(ROD, nr=1, nz=4)
    res = solve_theta(model, paper_cycle(2000.0), 3600.0, store_fields=True)   # 25 frames
    path = write_fields(model, res, tmp_path / "f.xdmf", max_frames=5)
    with meshio.xdmf.TimeSeriesReader(path) as r:
        r.read_points_cells()
        ts = [r.read_data(k)[0] for k in range(r.num_steps)]
    assert len(ts) == 5 and ts[0] == 0.0 and ts[-1] == pytest.approx(24 * 3600.0)


def test_picture_is_drawn(case, tmp_path):
    """The off-screen picture is a real PNG with a temperature colour range, written atomically.

    Property: the rendering pipeline (revolved section for the axisymmetric
    model) produces a non-blank image; checked by the PNG signature, size and
    pixel variance, and that no temporary file is left.
    """
    import matplotlib.image as mpimg
    model, res, te = case
    out = write_scenario_fields(model, res, tmp_path / "out", elastic=te, title="test")
    png = out["picture_png"]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(png)
    assert img.shape[0] > 300 and img[..., :3].std() > 0.05
    assert out["picture_time_s"] == pytest.approx(9.5 * 3600.0)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["fields.xdmf",
                                                                    "temperature_3d.png"]


def test_export_refuses_bad_requests(case, tmp_path):
    """No stored fields, a wrong suffix or a wrong field size raise InputError; nothing is written."""
    model, res, te = case
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
