"""Screw algebra of the allocation package: composition, pitch and magnitude."""
import numpy as np
import pytest

from arfem.models.allocation import screw


def _random_chain(rng, n=4):
    poses = [screw.pose(rng.uniform(-300, 300, 3), rng.uniform(-180, 180, 3)) for _ in range(n)]
    tool = screw.pose(rng.uniform(-500, 500, 3), rng.uniform(-180, 180, 3))
    return poses, tool


def _random_errors(rng, n, eps):
    """Errors of size eps: rotations eps [rad], translations eps * 100 mm (comparable motion)."""
    xi = rng.uniform(-1, 1, (n, 6))
    xi[:, :3] *= eps
    xi[:, 3:] *= eps * 100.0
    return xi


@pytest.mark.parametrize("seed", range(5))
def test_adjoint_composition_matches_transform_product_to_second_order(seed):
    """The adjoint-composed twist Σ Ad(H_i⁻¹) ξ_i equals log(g_nom⁻¹ g_act) of the direct
    4×4 products up to terms of second order in the error size: the discrepancy divided by
    ε² stays bounded and falls by ~4 when ε halves (ratio in [3, 5]; exactly 4 in the limit).
    The first-order sum without the adjoint (no lever arms) misses by O(ε), so it fails."""
    rng = np.random.default_rng(seed)
    poses, tool = _random_chain(rng)
    base = rng.uniform(-1, 1, (4, 6))
    d = []
    for eps in (1e-4, 5e-5):
        xi = base.copy()
        xi[:, :3] *= eps
        xi[:, 3:] *= eps * 100.0
        exact = screw.compose_exact(xi, poses, tool)
        adj = screw.compose_adjoint(xi, poses, tool)
        d.append(np.linalg.norm(exact - adj))
        scale = np.linalg.norm(exact)
        assert d[-1] < 1e-3 * scale          # first order is right
        naive = xi.sum(axis=0)               # no nominal geometry
        assert np.linalg.norm(exact - naive) > 1e-2 * scale
    assert 3.0 < d[0] / d[1] < 5.0


def test_compose_adjoint_batches():
    """A batch of candidates gives the same twists as one-by-one calls (einsum indices)."""
    rng = np.random.default_rng(7)
    poses, tool = _random_chain(rng, 3)
    xis = np.stack([_random_errors(rng, 3, 1e-5) for _ in range(5)])
    batch = screw.compose_adjoint(xis, poses, tool)
    one = np.array([screw.compose_adjoint(x, poses, tool) for x in xis])
    np.testing.assert_allclose(batch, one, rtol=0, atol=1e-15)


def test_adjoint_conjugation_identity():
    """g e^{ξ^} g⁻¹ = e^{(Ad_g ξ)^} for a finite (not small) twist: defines Ad for [ω; v]
    ordering (tolerance: round-off of expm on O(1) entries)."""
    rng = np.random.default_rng(3)
    g = screw.pose(rng.uniform(-2, 2, 3), rng.uniform(-180, 180, 3))
    xi = rng.uniform(-0.5, 0.5, 6)
    lhs = g @ screw.error_transform(xi) @ screw.inverse(g)
    rhs = screw.error_transform(screw.adjoint(g) @ xi)
    np.testing.assert_allclose(lhs, rhs, atol=1e-12)


def test_pitch_magnitude_known_answers():
    """Pure translation: infinite pitch, magnitude |v|. Pure rotation: pitch 0, magnitude |ω|.
    A rotation about z through a point off the origin (v = p × ω ⟂ ω) still has pitch 0.
    A screw along z with 0.5 mm per rad has pitch 0.5 (exact arithmetic, tolerance 1e-12)."""
    t = [0, 0, 0, 3e-3, 4e-3, 0]
    assert screw.pitch(t) == np.inf
    assert screw.screw_magnitude(t) == pytest.approx(5e-3, rel=1e-12)
    assert screw.point_displacement_bound(t) == pytest.approx(5e-3, rel=1e-12)
    r = [0, 0, 2e-6, 0, 0, 0]
    assert screw.pitch(r) == 0.0
    assert screw.screw_magnitude(r) == pytest.approx(2e-6, rel=1e-12)
    w = np.array([0, 0, 2e-6])
    off = np.concatenate([w, np.cross([100.0, 0, 0], w)])
    assert abs(screw.pitch(off)) < 1e-12
    assert screw.axial_translation(off) < 1e-15
    s = [0, 0, 2e-6, 0, 0, 1e-6]
    assert screw.pitch(s) == pytest.approx(0.5, rel=1e-12)
    assert screw.axial_translation(s) == pytest.approx(1e-6, rel=1e-12)
    # a screw with pitch h about an axis through p: v = p × ω + h ω
    h, p = 250.0, np.array([10.0, -20.0, 5.0])
    wg = np.array([1e-6, -2e-6, 3e-6])
    xi = np.concatenate([wg, np.cross(p, wg) + h * wg])
    assert screw.pitch(xi) == pytest.approx(h, rel=1e-10)


def test_pitch_is_invariant_under_change_of_frame():
    """Pitch is a property of the screw, not of the frame: h(Ad_g ξ) = h(ξ) (rel 1e-9)."""
    rng = np.random.default_rng(11)
    xi = _random_errors(rng, 1, 1e-5)[0]
    g = screw.pose(rng.uniform(-400, 400, 3), rng.uniform(-180, 180, 3))
    assert screw.pitch(screw.adjoint(g) @ xi) == pytest.approx(screw.pitch(xi), rel=1e-9)
