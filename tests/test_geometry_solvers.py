"""The elastic solves of the geometry path (issue 32, performance): the preconditioned CG
(P2/P1 p-multigrid, or AMG for first-order elements) that replaces the factorisation above
``DIRECT_MAX_DOFS`` gives the factor's sensor rows and displacements, and the memory
estimate grows as the path it estimates."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import arfem.fem.body as body
from arfem.fem.body import (ConvectionSpec, ElasticBody, Material, SensorSpec, SourceSpec,
                            Support, ThermalBody)
from arfem.fem.gmsh_io import (ELASTIC_FACTOR_MAX_DOFS, estimate_memory_bytes,
                               read_grouped_mesh)
from arfem.params import Rod

DATA = Path(__file__).parent / "data"
ROD = Rod()
STEEL = Material("rod", ROD.conductivity_W_mK, ROD.density_kg_m3, ROD.specific_heat_J_kgK,
                 ROD.expansion_1_K, ROD.youngs_modulus_Pa, ROD.poisson_ratio)


@pytest.fixture(scope="module")
def rod():
    gm = read_grouped_mesh(DATA / "rod_tet10.msh", "m")
    tb = ThermalBody.build(gm, {"rod": STEEL}, [SourceSpec("q", "heated", "flux")],
                           [ConvectionSpec("h", "lateral")], order=2)
    return tb, Support("clamped", group="far")


@pytest.mark.parametrize("preconditioner", ["p-multigrid", "AMG"])
def test_iterative_path_gives_the_factors_sensor_rows_and_fields(rod, monkeypatch,
                                                                 preconditioner):
    """On the rod (P2, clamped far face), the CG path (forced by a threshold of 0; with
    the P2/P1 p-multigrid that second-order elements get, or with the smoothed-aggregation
    AMG that first-order ones get) and the METIS + SuperLU factor give the same adjoint
    rows g = TᵀK⁻¹w for a point and a face-average sensor, and the same displacement
    fields, to 1e-8 of their largest entry (CG stops at a relative residual of 1e-10;
    the stiffness's condition number, ~1e6 here, loses up to the rest). Ten snapshots at
    once take the field path, which factors the stiffness after all: equal to the
    factor to round-off."""
    tb, sup = rod
    direct = ElasticBody.build(tb, sup)
    monkeypatch.setattr(body, "DIRECT_MAX_DOFS", 0)
    if preconditioner == "AMG":
        monkeypatch.setattr(body, "has_vertex_edge_dofs", lambda elem: False)
    it = ElasticBody.build(tb, sup)
    kind = body._PMGSolver if preconditioner == "p-multigrid" else body._AMGSolver
    assert isinstance(it.factor, kind) and not isinstance(direct.factor,
                                                          body._IterativeSolver)
    sensors = [SensorSpec("tip", "displacement", point=(0.0, 0.05, 0.0), direction=(1, 1, 0)),
               SensorSpec("face", "displacement", group="heated")]
    W = np.column_stack([direct.sensor_weight(s, s.name) for s in sensors])
    g_d, g_a = direct.functional(W), it.functional(W)
    assert np.max(np.abs(g_a - g_d)) <= 1e-8 * np.max(np.abs(g_d))
    assert all(0 < n < 200 for n in it.factor.iterations)
    rng = np.random.default_rng(3)
    theta = rng.uniform(0.0, 10.0, size=(10, tb.ndofs))
    u_d = direct.displacement(theta)
    u_a = it.displacement(theta)                   # 10 solves: the factored path
    assert "factor" in it._many
    assert np.max(np.abs(u_a - u_d)) <= 1e-10 * np.max(np.abs(u_d))
    u_1 = it.displacement(theta[0])                # one solve: CG
    assert np.max(np.abs(u_1 - u_d[0])) <= 1e-8 * np.max(np.abs(u_d[0]))
    # a run that announces its field snapshots is factored from the start (no set-up
    # and sensor CG solves wasted before the factor the snapshots need)
    many = ElasticBody.build(tb, sup, n_solves=body.FIELDS_FACTOR_MIN_SOLVES)
    assert not isinstance(many.factor, body._IterativeSolver) and many.nnz_factor > 0


def test_p1_prolongation_interpolates_first_order_fields_exactly(rod):
    """p1_prolongation (the p-multigrid's coarse space) maps the vertex values of a
    linear displacement field to the P2 nodal values of the same field, at every free
    dof, to round-off: the edge nodes of the rod's tetra10 mesh lie at its edges'
    midpoints up to the curved boundary's offset, which a linear field sees as its mean
    of the two vertex values only where the edge is straight, so the check is on the
    mesh's straight interior edges (relative 1e-12)."""
    tb, _ = rod
    sb = tb.basis
    free = np.arange(3 * sb.N)
    P, coarse = body.p1_prolongation(sb, free)
    m = sb.mesh
    nod, edg = np.asarray(sb.nodal_dofs[0]), np.asarray(sb.edge_dofs[0])
    A = np.array([[1.0, 2.0, -0.5], [0.3, -1.0, 0.7], [0.2, 0.1, 1.5]])
    b = np.array([0.1, -0.2, 0.3])
    vert = m.p[:, :nod.size]
    u_c = (A @ vert + b[:, None]).T.ravel()[coarse]          # 3k + c, all free
    u_f = (P @ u_c).reshape(-1, 3)
    x = sb.doflocs
    mid = 0.5 * (vert[:, m.edges[0]] + vert[:, m.edges[1]])
    straight = np.linalg.norm(x[:, edg] - mid, axis=0) <= 1e-12 * np.ptp(vert)
    exact = (A @ x + b[:, None]).T
    assert straight.sum() > 0.5 * edg.size
    for dofs in (nod, edg[straight]):
        assert np.max(np.abs(u_f[dofs] - exact[dofs])) <= 1e-12 * np.max(np.abs(exact))
    assert P.shape == (free.size, 3 * nod.size)


def test_memory_estimate_grows_with_size_and_drops_at_the_amg_switch():
    """The estimate grows with n on each path, and past the largest factored elastic
    stiffness (3n > ELASTIC_FACTOR_MAX_DOFS) the AMG path's linear memory replaces the
    factor's n^{4/3}: the estimate just above the switch is below the one just under."""
    n_switch = ELASTIC_FACTOR_MAX_DOFS // 3
    under, over = estimate_memory_bytes(n_switch), estimate_memory_bytes(n_switch + 1)
    assert over < under
    sizes = [25_000, 100_000, 500_000]
    est = [estimate_memory_bytes(n) for n in sizes]
    assert est == sorted(est)
