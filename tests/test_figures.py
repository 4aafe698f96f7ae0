"""Every figure of `arfem run` / `arfem reproduce`, checked for what a reviewer can check
from the objects behind it: labelled axes with units, a legend inside its axes that covers
no data, and a PNG of a sensible size. (How it looks is judged by looking at it.)"""
from __future__ import annotations

import re

import numpy as np
import pytest

from arfem.scenarios.rod.scenario import scenario_from_dict
from arfem.scenarios.rod.evaluation import evaluate
from arfem.scenarios.rod.outputs import growth_figure, write_outputs

UNIT = re.compile(r"\[[^\]]+\]")          # "[µm]", "[h]", "[°C]"

SMALL = {
    "scenario": {"name": "small"},
    "cycle": {"phases": [{"duration_h": 1.0, "q_W_m2": 2000.0},
                         {"duration_h": 1.0, "q_W_m2": 0.0}]},
    "ar": {"dtau_s": 60.0},
    "fem": {"mesh": {"nr": 2, "nz": 8}},
    "outputs": {"fields": True, "picture": True, "field_interval_s": 1800.0},
}


@pytest.fixture(scope="module")
def ev():
    return evaluate(scenario_from_dict(SMALL))


def assert_readable(fig):
    """Labelled axes with units; every legend inside its axes and over no data point."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    axes = [a for a in fig.axes if a.get_visible() and a.get_label() != "<colorbar>"]
    assert axes
    for ax in axes:
        assert UNIT.search(ax.get_ylabel()), f"y label without unit: {ax.get_ylabel()!r}"
        legend = ax.get_legend()
        if legend is None:
            continue
        box = legend.get_window_extent(renderer)
        frame = ax.get_window_extent(renderer)
        assert (box.x0 >= frame.x0 - 1 and box.x1 <= frame.x1 + 1
                and box.y0 >= frame.y0 - 1 and box.y1 <= frame.y1 + 1), "legend outside its axes"
        for line in ax.get_lines():
            xy = ax.transData.transform(np.column_stack(line.get_data()))
            inside = ((xy[:, 0] > box.x0) & (xy[:, 0] < box.x1)
                      & (xy[:, 1] > box.y0) & (xy[:, 1] < box.y1))
            assert not inside.any(), f"legend covers {line.get_label()!r}"
    bottom = min(axes, key=lambda a: a.get_position().y0)
    assert UNIT.search(bottom.get_xlabel()), "x axis without unit"


def test_growth_figure_is_readable(ev):
    """The FEM-vs-AR figure: three panels, units on every axis, the legend in free space,
    the CI tolerance lines labelled, the three series in distinct line styles."""
    fig = growth_figure(ev)
    assert_readable(fig)
    ax, bx, cx = fig.axes
    assert ax.get_legend() is not None
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("FEM" in t for t in labels) and any("corrected" in t for t in labels)
    assert any("W/m²" in t for t in labels)                    # the heating phases named
    assert len({ln.get_linestyle() for ln in ax.get_lines()}) == 3  # readable in grey
    assert any("CI tolerance" in t.get_text() for t in bx.texts)
    assert "[µm]" in bx.get_ylabel() and "[nm]" in cx.get_ylabel()


def test_written_figures_exist_with_sensible_size(ev, tmp_path):
    """write_outputs writes figure.png and temperature_3d.png as real PNGs of a size a
    report can print (≥ 1000 px wide, 20 kB–3 MB)."""
    import matplotlib.image as mpimg
    write_outputs(ev, tmp_path)
    for name in ("figure.png", "temperature_3d.png"):
        p = tmp_path / name
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert 20_000 < p.stat().st_size < 3_000_000, (name, p.stat().st_size)
        img = mpimg.imread(p)
        assert img.shape[1] >= 1000 and img[..., :3].std() > 0.05, name


def test_3d_picture_figure_is_readable(ev):
    """The 3D picture's colour bar carries its unit, and its title names the instant."""
    from arfem.fem.elastic import ThermoElastic
    from arfem.fem.export import picture_figure
    from arfem.fem.heat import solve_modal
    model = ev.model
    res = solve_modal(model, ev.scenario.schedule, output_times_s=[0.0, 3600.0],
                      store_fields=True)
    fig = picture_figure(model, res.fields[1], elastic=ThermoElastic.build(model),
                         title="small: t = 1.00 h")
    cbar = [a for a in fig.axes if a is not fig.axes[0]]
    assert cbar and UNIT.search(cbar[0].get_xlabel())
    assert "1.00 h" in fig.axes[0].get_title()
