"""Bad input to the FEM is refused at construction with one clear InputError, before any solve."""
from __future__ import annotations

import math

import numpy as np
import pytest

from arfem.fem import heat as fem_heat
from arfem.fem.elastic import ThermoElastic
from arfem.fem.heat import build_3d, build_axisymmetric, solve_modal, solve_theta
from arfem.params import InputError, Rod, Schedule

POSITIVE = ["radius_m", "length_m", "conductivity_W_mK", "density_kg_m3",
            "specific_heat_J_kgK", "convection_W_m2K", "expansion_1_K", "youngs_modulus_Pa"]


def _one_line(err: InputError, name: str) -> None:
    msg = str(err)
    assert "\n" not in msg and name in msg, msg


@pytest.mark.parametrize("name", POSITIVE)
@pytest.mark.parametrize("value", [0.0, -1.0, math.nan, math.inf, "abc"])
def test_rod_refuses_non_physical(name, value):
    """R, L, λ, ρ, c, h, α, E ≤ 0, NaN, inf or non-numeric raise InputError naming the field.

    Property: a Rod cannot exist with a non-physical value, so no solver ever
    sees one. Exact check of the exception type and that the one-line message
    names the field.
    """
    with pytest.raises(InputError) as exc:
        Rod(**{name: value})
    _one_line(exc.value, name)


@pytest.mark.parametrize("value", [0.5, -0.2 - 1.0, math.nan])
def test_rod_refuses_bad_poisson(value):
    """ν outside (−1, 0.5) or NaN is refused (ν = 0.5 makes the elastic operator singular)."""
    with pytest.raises(InputError) as exc:
        Rod(poisson_ratio=value)
    _one_line(exc.value, "poisson_ratio")


@pytest.fixture
def no_assembly(monkeypatch):
    """Make any assembly or solve fail loudly, to prove refusal happens before them."""
    def boom(*a, **k):
        raise AssertionError("assembly/solve reached with bad input")
    monkeypatch.setattr(fem_heat.HeatFEM, "build", classmethod(boom))
    monkeypatch.setattr(fem_heat, "factorize_spd", boom)
    monkeypatch.setattr(fem_heat, "modes", boom)


@pytest.mark.parametrize("kw, name", [
    ({"nr": 0}, "nr"), ({"nz": -3}, "nz"), ({"nr": 2.5}, "nr"), ({"nz": True}, "nz"),
    ({"order": 3}, "order"), ({"ratio_z": 0.5}, "ratio"), ({"ratio_r": math.nan}, "ratio"),
])
def test_axisymmetric_mesh_refused_before_assembly(kw, name, no_assembly):
    """A mesh with < 1 element, a non-integer count, a bad order or grading is refused before assembly.

    Property: the error is an InputError naming the parameter, raised before
    HeatFEM.build runs (which is patched to fail the test if reached).
    """
    with pytest.raises(InputError) as exc:
        build_axisymmetric(Rod(), **kw)
    _one_line(exc.value, name)


@pytest.mark.parametrize("kw, name", [
    ({"n_core": 0}, "n_core"), ({"n_ring": -1}, "n_ring"), ({"nz": 0}, "nz"),
    ({"order": 5}, "order"),
])
def test_3d_mesh_refused_before_assembly(kw, name, no_assembly):
    """Same refusal for the 3D mesh parameters."""
    with pytest.raises(InputError) as exc:
        build_3d(Rod(), **kw)
    _one_line(exc.value, name)


@pytest.mark.parametrize("args, name", [
    (([3600, -1], [2000, 0]), "durations_s[1]"),
    (([3600, 0], [2000, 0]), "durations_s[1]"),
    (([math.nan], [2000]), "durations_s[0]"),
    (([3600], [math.nan]), "q_W_m2[0]"),
    (([3600], [-5.0]), "q_W_m2[0]"),
    (([], []), "durations_s"),
])
def test_schedule_refuses_bad_durations_and_nan(args, name):
    """Negative or zero durations, NaN values and an empty schedule are refused, naming the entry."""
    with pytest.raises(InputError) as exc:
        Schedule(*args)
    _one_line(exc.value, name)


def test_schedule_refuses_bad_h_and_ambient():
    """h ≤ 0 per segment and a NaN ambient are refused, naming the entry."""
    with pytest.raises(InputError) as exc:
        Schedule([10, 10], [0, 0], h_W_m2K=[55, 0])
    _one_line(exc.value, "h_W_m2K[1]")
    with pytest.raises(InputError) as exc:
        Schedule([10], [0], ambient_C=[math.nan])
    _one_line(exc.value, "ambient_C[0]")


@pytest.fixture(scope="module")
def small():
    return build_axisymmetric(Rod(), nr=1, nz=2)


@pytest.mark.parametrize("kw, name", [({"dt_s": 0.0}, "dt_s"), ({"dt_s": math.nan}, "dt_s"),
                                      ({"dt_s": 10.0, "theta": 0.3}, "theta"),
                                      ({"dt_s": 10.0, "theta0": [1.0, 2.0]}, "theta0")])
def test_solver_arguments_refused(small, kw, name):
    """Bad solver arguments (step ≤ 0 or NaN, unstable θ, wrong initial state) raise InputError."""
    with pytest.raises(InputError) as exc:
        solve_theta(small, Schedule([60.0], [100.0]), **kw)
    _one_line(exc.value, name)


def test_modal_output_times_refused(small):
    """Output times outside the schedule or decreasing are refused."""
    for t in ([0.0, 120.0], [30.0, 10.0], [math.nan]):
        with pytest.raises(InputError) as exc:
            solve_modal(small, Schedule([60.0], [100.0]), output_times_s=t)
        _one_line(exc.value, "output_times_s")


def test_elastic_refuses_wrong_inputs(small):
    """ThermoElastic refuses a non-HeatFEM and temperature fields of the wrong size or with NaN."""
    with pytest.raises(InputError) as exc:
        ThermoElastic.build("not a model")
    _one_line(exc.value, "heat")
    te = ThermoElastic.build(small)
    bad = np.ones(small.ndofs)
    bad[0] = np.nan
    for theta in (np.ones(small.ndofs + 1), bad):
        with pytest.raises(InputError) as exc:
            te.displacement(theta)
        _one_line(exc.value, "theta")
        with pytest.raises(InputError):
            te.growth(theta)
