"""CI check: the paper's AR(1) tracks the FEM on the paper duty cycle (issue 3).

The FEM is the axisymmetric Q2 model on the default mesh of
:func:`arfem.fem.heat.build_axisymmetric`, integrated exactly in time by
:func:`arfem.fem.heat.solve_modal` on the paper cycle subdivided into Δτ = 30 s steps.
The criterion itself is :func:`arfem.models.checks.check_ar_tracks_fem`; here it is
shown to pass for the paper AR(1) and to fail for deliberately broken ones.

Measured (python -m pytest tests/test_ar_tracks_fem.py, default mesh nr=4, nz=24):

===========================  ==========  ==========
quantity                     q = 2000    q = 3000
===========================  ==========  ==========
FEM peak [µm]                22.1666     33.2500
paper AR max|AR−FEM| / peak  2.566 %     2.566 %
corrected AR, same           0.00033 %   0.00033 %
C1 fitted to FEM             0.9911473   0.9911473
C1 paper (eq. 13)            0.9909029   0.9909029
|ΔC1|                        2.44e-4     2.44e-4
broken h=80: max dev         32.4 %      32.4 %
broken α=13e-6: max dev      5.65 %      5.65 %
===========================  ==========  ==========
"""
from __future__ import annotations

import numpy as np
import pytest

from arfem.fem.heat import build_axisymmetric, solve_modal
from arfem.models.ar1 import ar1_on_schedule, c1_paper, corrected_coefficients, fit_ar1
from arfem.models.checks import check_ar_tracks_fem
from arfem.params import Rod, paper_cycle

ROD = Rod()
DTAU = 30.0


@pytest.fixture(scope="module")
def fem_model():
    return build_axisymmetric(ROD)


@pytest.fixture(scope="module", params=[2000.0, 3000.0], ids=["q2000", "q3000"])
def case(request, fem_model):
    """FEM growth on the Δτ grid, the fitted C1 and the schedule, per flux level."""
    q = request.param
    fine = paper_cycle(q).subdivided(DTAU)
    fem = solve_modal(fem_model, fine).growth_m
    fit = fit_ar1(fem, fine.q_W_m2)          # levels = q on each step
    return q, fine, fem, fit


def test_paper_ar_tracks_fem(case):
    """Paper AR(1) within 3 % of the FEM peak, fitted C1 within 5e-4 of eq. 13.

    Tolerances are the issue's acceptance limits; measured 2.566 % and 2.44e-4,
    the residual being the O(Bi) radial-conduction effect the 1D theory omits
    (Bi = 0.11; see models.ar1.corrected_coefficients).
    """
    q, fine, fem, fit = case
    t, ar = ar1_on_schedule(ROD, paper_cycle(q), DTAU)
    assert np.array_equal(t, fine.edges_s)
    failures = check_ar_tracks_fem(fem, ar, fit.c1, c1_paper(ROD, DTAU))
    assert failures == []
    # the margin is real but finite: the paper AR is neither exact nor far off
    dev = np.max(np.abs(ar - fem)) / np.max(fem)
    assert 0.02 < dev < 0.03
    assert np.max(fem) * 1e6 == pytest.approx(22.1666 * q / 2000.0, abs=1e-3)


@pytest.mark.parametrize("broken", [
    {"convection_W_m2K": 80.0},          # wrong h: both C1 and C2 wrong
    {"expansion_1_K": 13e-6},            # wrong α: only C2 wrong (8 % amplitude)
    {"convection_W_m2K": 80.0, "expansion_1_K": 13e-6},
], ids=["h80", "alpha13e-6", "both"])
def test_check_bites_on_broken_ar(case, broken):
    """The same check FAILS for an AR built from wrong physics, so it can detect errors.

    h = 80 instead of 55 W/(m²K): max dev 32 % and |ΔC1| = 4.4e-3 (both flagged).
    α = 13e-6 instead of 12e-6 1/K: max dev 5.6 % (amplitude flagged; C1 unaffected).
    """
    q, fine, fem, fit = case
    bad = ROD.with_(**broken)
    _, ar_bad = ar1_on_schedule(bad, paper_cycle(q), DTAU)
    failures = check_ar_tracks_fem(fem, ar_bad, fit.c1, c1_paper(bad, DTAU))
    assert any("max|AR - FEM|" in f for f in failures), failures
    if "convection_W_m2K" in broken:
        assert any("C1_fitted" in f for f in failures), failures
    else:
        assert not any("C1_fitted" in f for f in failures), failures


def test_corrected_ar_matches_fem_within_target(case):
    """Mode-1 corrected AR(1) within 0.1 % of the FEM peak (issue target).

    Measured 0.00033 % (the FEM's own mesh error and the O(Bi²) higher radial
    modes). Its C1 also equals the C1 fitted to the FEM to 1e-6 (measured 7e-8),
    the evidence that the correction is the physics and not a fit.
    """
    q, fine, fem, fit = case
    _, ar = ar1_on_schedule(ROD, paper_cycle(q), DTAU, corrected=True)
    assert np.max(np.abs(ar - fem)) <= 1e-3 * np.max(fem)
    c1c, c2c = corrected_coefficients(ROD, DTAU, q)
    assert abs(fit.c1 - c1c) <= 1e-6
    assert fit.c2[q] == pytest.approx(c2c, rel=1e-3)
    assert check_ar_tracks_fem(fem, ar, fit.c1, c1c) == []
