"""The shipped spindle unit (issue 32): its scenario validates, its committed mesh carries
every group the scenario names, and every sensor point lies in the mesh -- without
solving (the solve is benchmarks/bench_geometry.py's job)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from arfem.fem.body import locate
from arfem.fem.gmsh_io import read_grouped_mesh
from arfem.scenarios.geometry.scenario import input_history, load_geometry_scenario

SCEN = Path(__file__).resolve().parents[1] / "scenarios" / "data" / "spindle_unit.toml"


@pytest.fixture(scope="module")
def unit():
    sc = load_geometry_scenario(SCEN)
    return sc, read_grouped_mesh(sc.mesh_path, sc.unit)


def test_groups_of_the_scenario_are_in_the_mesh(unit):
    """Each material, source, convection and support group exists with the right
    dimension; every volume group has a material (else arfem run would refuse)."""
    sc, gm = unit
    assert set(sc.materials) == set(gm.volumes)
    for s in sc.sources:
        assert gm.surfaces[s.spec.group].size > 0
    for c in sc.convections:
        assert gm.surfaces[c.spec.group].size > 0
    assert gm.surfaces[sc.support.group].size > 0
    # the mesh is in mm: a spindle unit half a metre across, not 500 m
    span = np.ptp(gm.mesh.p, axis=1)
    assert 0.3 < span.max() < 1.0


def test_sensor_points_lie_in_the_mesh(unit):
    sc, gm = unit
    from skfem import Basis, ElementTetP1
    b = Basis(gm.mesh, ElementTetP1())
    for s in sc.sensors:
        cell, vals = locate(b, s.point, s.name)
        assert vals.sum() == pytest.approx(1.0)


def test_history_puts_each_source_on_its_own_schedule(unit):
    """The motor's own phases (3 h, 1 h, 5 h, 15 h) and the cycle's five phases merge
    into one piecewise-constant history; powers and h = a + b·n^m follow the speed."""
    sc, _ = unit
    h = input_history(sc)
    assert h.total_s == pytest.approx(24 * 3600)
    names = [s.spec.name for s in sc.sources]

    def at(hours):                     # the segment holding this time
        return int(np.searchsorted(h.edges_s, hours * 3600, side="right") - 1)
    motor = h.u[:, names.index("motor")]
    front = h.u[:, names.index("front_bearing")]
    assert motor[at(8.0)] == 50.0 and front[at(8.0)] == 36.0
    assert motor[at(5.0)] == 50.0 and front[at(5.0)] == 24.0
    k_bore = [c.spec.group for c in sc.convections].index("spindle_bore")
    hb = h.h_W_m2K[:, k_bore]
    assert hb[at(8.0)] == pytest.approx(5.0 + 0.08 * 12000 ** 0.6)
    assert hb[at(20.0)] == pytest.approx(5.0)
