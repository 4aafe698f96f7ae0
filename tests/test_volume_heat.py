"""Heat generated in a volume group (issue 42 item 1) against closed forms.

A ``[[heat_source]]`` on a volume group spreads its power over the group's volume: the
load is ∫_{Ω_g} v dΩ · P/V_g. Verified here:

* an insulated body under uniform volume heat warms uniformly at dT/dt = P/(ρcV);
* with the heat in one of two materials, the stored energy Σ∫ρcθ equals P·t (nothing
  leaves an insulated body; the discrete 1ᵀF = 1 and 1ᵀK = 0);
* a slab with volume heat, insulated at x = 0 and cooled at x = L, against its steady
  profile θ(x) = q(L² − x²)/(2λ) + qL/h (q = P/V [W/m³]): P2 holds the parabola exactly,
  P1 converges at its observed L2 order 2;
* the scenario, its model and the diagnosis's candidate column carry it.
"""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from skfem import Functional, MeshTet1

from arfem.fem.body import (ConvectionSpec, Material, SourceSpec, ThermalBody, lumped_geometry,
                            power_column)
from arfem.fem.gmsh_io import GroupedMesh
from arfem.fem.thermal3d import InputHistory, solve_body_reduced, solve_body_theta

STEEL = dict(conductivity_W_mK=50.0, density_kg_m3=7850.0, specific_heat_J_kgK=460.0,
             expansion_1_K=12e-6, youngs_modulus_Pa=206e9, poisson_ratio=0.3)
ALU = dict(conductivity_W_mK=200.0, density_kg_m3=2700.0, specific_heat_J_kgK=900.0,
           expansion_1_K=23e-6, youngs_modulus_Pa=70e9, poisson_ratio=0.33)


def _box(n=(4, 2, 2), size=(0.2, 0.1, 0.1), split: bool = False) -> GroupedMesh:
    """A box of tetrahedra: volume ``body`` (or ``core`` x < a/2 and ``rest``), surface
    ``cooled`` (x = a)."""
    m = MeshTet1.init_tensor(*(np.linspace(0, s, k + 1) for s, k in zip(size, n)))
    mid = m.p[:, m.t].mean(axis=1)
    vols = ({"core": np.flatnonzero(mid[0] < size[0] / 2),
             "rest": np.flatnonzero(mid[0] >= size[0] / 2)} if split
            else {"body": np.arange(m.nelements)})
    bf = m.boundary_facets()
    fx = m.p[0, m.facets[:, bf]].mean(axis=0)
    return GroupedMesh(m, "tetra", vols, {"cooled": bf[np.isclose(fx, size[0])]})


@pytest.mark.parametrize("order", [1, 2])
def test_insulated_body_warms_at_p_over_rho_c_v(order):
    """P = 100 W in a steel box of V = 2e-3 m³, no convection, Crank–Nicolson over 1 h
    in 60 s steps: every node at P t/(ρcV) = 49.85 K after an hour, to 1e-10 of it.
    The uniform rise is in the space and linear in time, and the load ∫v dΩ/V is M·1/(ρcV)
    exactly, so nothing but round-off is left (hence the tight tolerance)."""
    gm = _box()
    body = ThermalBody.build(gm, {"body": Material("body", **STEEL)},
                             [SourceSpec("heater", "body")], order=order)
    assert body.source_volumes_m3 == pytest.approx({"body": 2e-3}, rel=1e-12)
    assert body.areas_m2 == {}
    assert float(body.volume.sum()) == pytest.approx(2e-3, rel=1e-12)   # ∫v dV kept
    P, rhoc = 100.0, 7850.0 * 460.0
    hist = InputHistory(np.array([0.0, 3600.0]), np.array([[P]]), np.zeros((1, 0)))
    G = np.eye(body.ndofs)[:, :: max(1, body.ndofs // 7)]
    res = solve_body_theta(body, hist, G, 60.0, 0.5)
    expect = P * res.times_s / (rhoc * 2e-3)
    assert expect[-1] == pytest.approx(49.8477, rel=1e-5)
    assert np.max(np.abs(res.outputs - expect[:, None])) <= 1e-10 * expect[-1]


def test_heat_in_one_material_is_all_stored():
    """P = 50 W in the steel half of a steel/aluminium box, insulated: the stored energy
    Σ∫ρcθ dΩ = 1ᵀMθ equals P·t at every step to 1e-10 (the column sums to one watt;
    conduction moves heat, never creates it), while the temperature is not uniform
    (the heated half is warmer: the source stays in its group)."""
    gm = _box(split=True)
    mats = {"core": Material("core", **STEEL), "rest": Material("rest", **ALU)}
    body = ThermalBody.build(gm, mats, [SourceSpec("heater", "core")], order=2)
    assert float(body.F[:, 0].sum()) == pytest.approx(1.0, abs=1e-13)
    hist = InputHistory(np.array([0.0, 600.0]), np.array([[50.0]]), np.zeros((1, 0)))
    ones = np.asarray(body.M @ np.ones(body.ndofs))
    res = solve_body_theta(body, hist, np.column_stack([ones]), 30.0, 1.0,
                      field_times_s=[600.0])
    np.testing.assert_allclose(res.outputs[:, 0], 50.0 * res.times_s, rtol=1e-10, atol=1e-9)
    x = body.basis.doflocs[0]
    th = res.fields[-1]
    assert th[x < 0.05].mean() > th[x > 0.15].mean() + 1e-3


def _slab_error(n: int, order: int) -> tuple:
    """(L2 error [K·m^1.5], nodal max error [K], body, θ, exact) of the slab's steady
    profile on cubes of side 0.02/n (5n along L = 0.1 m)."""
    L, lam, h, P = 0.1, 50.0, 200.0, 40.0
    gm = _box(n=(5 * n, n, n), size=(L, 0.02, 0.02))     # cubes of side 0.02/n
    mat = dict(STEEL, conductivity_W_mK=lam)
    body = ThermalBody.build(gm, {"body": Material("body", **mat)},
                             [SourceSpec("heater", "body")], [ConvectionSpec("c", "cooled")],
                             order=order)
    q = P / (L * 0.02 * 0.02)
    A = body.operator([h])
    from scipy.sparse.linalg import spsolve
    th = spsolve(A.tocsc(), body.F @ np.array([P, 0.0]))

    def exact(x):
        return q * (L ** 2 - x ** 2) / (2 * lam) + q * L / h

    @Functional
    def err2(w):
        return (w["t"] - exact(w.x[0])) ** 2
    from skfem import Basis
    fine = Basis(gm.mesh, body.basis.elem, intorder=6)       # the error's own quadrature
    e = float(np.sqrt(err2.assemble(fine, t=fine.interpolate(th))))
    return e, float(np.max(np.abs(th - exact(body.basis.doflocs[0])))), body, th, exact


def test_slab_with_volume_heat_and_convection_steady_profile():
    """Slab L = 0.1 m, λ = 50, q = 1e6 W/m³ (40 W in 4e-5 m³), h = 200 at x = L:
    θ(0) = qL²/(2λ) + qL/h = 600 K. P2 holds the parabola: every node exact to 1e-9 of
    θ(0) (round-off of the sparse solve). P1 on cubes of side 0.02/n split into six
    tetrahedra, n = 1, 2, 4, 8: the L2 error's observed order (1.91, 1.96, 1.98 when
    written) approaches 2, the order of linear elements; the last halving's within 0.05
    of 2 and every one within 0.15 (the first mesh has one cube across the slab)."""
    e2, n2, _, _, exact = _slab_error(1, 2)
    assert exact(0.0) == pytest.approx(600.0)
    assert n2 <= 1e-9 * 600.0
    errs = [_slab_error(n, 1)[0] for n in (1, 2, 4, 8)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert abs(orders[-1] - 2.0) <= 0.05 and np.all(np.abs(orders - 2.0) <= 0.15), orders


def test_reduced_solve_reaches_the_slab_steady_state():
    """The reduced-modal solve (the run's default) with the volume source reaches the
    same steady profile: θ(0) after 200 h (τ = ρcL/h ≈ 5 h) within 1e-6 of 600 K (its
    steady state is exact, A⁻¹F is in its space; the decay left is e^{−40})."""
    _, _, body, th, exact = _slab_error(1, 2)
    x = body.basis.doflocs[0]
    G = np.eye(body.ndofs)[:, [int(np.argmin(x))]]
    hist = InputHistory(np.array([0.0, 200 * 3600.0]), np.array([[40.0, 0.0]]),
                        np.array([[200.0]]))
    res = solve_body_reduced(body, hist, G, [0.0, 200 * 3600.0])
    assert res.outputs[-1, 0] == pytest.approx(600.0, rel=1e-6)


def test_lumped_geometry_and_candidate_column_of_a_volume_source():
    """The lumped AR(1)'s heat per unit input of a volume source is 1 W/W (1ᵀF), and the
    diagnosis's missing-source column (:func:`power_column`) on a volume group is the
    source's own column."""
    gm = _box(split=True)
    mats = {"core": Material("core", **STEEL), "rest": Material("rest", **ALU)}
    body = ThermalBody.build(gm, mats, [SourceSpec("heater", "core")],
                             [ConvectionSpec("c", "cooled")], order=2)
    lg = lumped_geometry(body, np.ones((body.ndofs, 1)))
    assert lg.input_power_W[0] == pytest.approx(1.0, abs=1e-13)
    np.testing.assert_allclose(power_column(body, "core", "x"), body.F[:, 0], atol=1e-15)
    assert power_column(body, "cooled", "x").sum() == pytest.approx(1.0)
    from arfem.models.geodiagnosis.rom import surface_power_column
    np.testing.assert_allclose(surface_power_column(body, "core", "x"), body.F[:, 0])


def test_flux_on_a_volume_group_is_refused(tmp_path):
    """flux_W_m2 on a volume group: one line naming the file and the source, exit 2."""
    from geometry_meshes import BOX_TOML, box_meshio, write_msh
    write_msh(box_meshio(), tmp_path / "box.msh")
    toml = BOX_TOML.replace('group = "left"\npower_W = [50.0, 0.0]',
                            'group = "body"\nflux_W_m2 = [50.0, 0.0]')
    (tmp_path / "s.toml").write_text(toml)
    r = subprocess.run([sys.executable, "-m", "arfem.scenarios.cli", "run", "s.toml", "--out",
                        "o"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert "s.toml" in r.stderr and "heat_source[0]" in r.stderr and "power_W" in r.stderr
    assert not (tmp_path / "o").exists()


def test_volume_source_runs_through_a_scenario(tmp_path):
    """A box scenario with its heater in the volume: the model's input matrix column is
    the volume's, the run's record carries P_heater_W, the lumped AR(1) sees 1 W/W."""
    from geometry_meshes import BOX_TOML, box_meshio, write_msh

    from arfem.scenarios.geometry.scenario import (build_geometry_model,
                                                   geometry_scenario_from_dict,
                                                   solve_geometry)
    import tomllib
    write_msh(box_meshio(), tmp_path / "box.msh")
    toml = BOX_TOML.replace('group = "left"\npower_W', 'group = "body"\npower_W')
    sc = geometry_scenario_from_dict(tomllib.loads(toml), "s.toml", tmp_path)
    sc = type(sc)(**{**sc.__dict__, "fields": False, "picture": False})
    model = build_geometry_model(sc)
    assert model.thermal.source_volumes_m3 == pytest.approx({"body": 0.3 * 0.2 * 0.2})
    run = solve_geometry(model)
    T = run.sensor_series()["T_mid_C"]
    assert T.max() > 20.0 + 1e-3
