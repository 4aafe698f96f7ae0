"""The elastic solves of the geometry path (issue 32, performance): the AMG-preconditioned
CG that replaces the factorisation above ``DIRECT_MAX_DOFS`` gives the factor's sensor
rows and displacements, and the memory estimate grows as the path it estimates."""
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


def test_amg_cg_gives_the_factors_sensor_rows_and_fields(rod, monkeypatch):
    """On the rod (P2, clamped far face), the AMG-CG path (forced by a threshold of 0)
    and the METIS + SuperLU factor give the same adjoint rows g = TᵀK⁻¹w for a point
    and a face-average sensor, and the same displacement fields, to 1e-8 of their
    largest entry (CG stops at a relative residual of 1e-10; the stiffness's condition
    number, ~1e6 here, loses up to the rest). Ten snapshots at once take the field path,
    which factors the stiffness after all: equal to the factor to round-off."""
    tb, sup = rod
    direct = ElasticBody.build(tb, sup)
    monkeypatch.setattr(body, "DIRECT_MAX_DOFS", 0)
    amg = ElasticBody.build(tb, sup)
    assert isinstance(amg.factor, body._AMGSolver) and not isinstance(direct.factor,
                                                                       body._AMGSolver)
    sensors = [SensorSpec("tip", "displacement", point=(0.0, 0.05, 0.0), direction=(1, 1, 0)),
               SensorSpec("face", "displacement", group="heated")]
    W = np.column_stack([direct.sensor_weight(s, s.name) for s in sensors])
    g_d, g_a = direct.functional(W), amg.functional(W)
    assert np.max(np.abs(g_a - g_d)) <= 1e-8 * np.max(np.abs(g_d))
    assert all(0 < it < 200 for it in amg.factor.iterations)
    rng = np.random.default_rng(3)
    theta = rng.uniform(0.0, 10.0, size=(10, tb.ndofs))
    u_d = direct.displacement(theta)
    u_a = amg.displacement(theta)                  # 10 solves: the factored path
    assert "factor" in amg._many
    assert np.max(np.abs(u_a - u_d)) <= 1e-10 * np.max(np.abs(u_d))
    u_1 = amg.displacement(theta[0])               # one solve: CG
    assert np.max(np.abs(u_1 - u_d[0])) <= 1e-8 * np.max(np.abs(u_d[0]))
    # a run that announces its field snapshots is factored from the start (no AMG set-up
    # and sensor CG solves wasted before the factor the snapshots need)
    many = ElasticBody.build(tb, sup, n_solves=body.FIELDS_FACTOR_MIN_SOLVES)
    assert not isinstance(many.factor, body._AMGSolver) and many.nnz_factor > 0


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
