"""Small-displacement screws of meta-action units (MUs) and their composition.

Conventions (used throughout :mod:`arfem.models.allocation`)
-----------------------------------------------------
* A twist is ξ = [ω; v] (6-vector): ω = (Δα, Δβ, Δγ) [rad] small rotations about
  x, y, z; v = (Δx, Δy, Δz) [mm] small translations. Lengths are in mm everywhere
  in this package, angles in rad (scenario files give angles in mrad).
* A pose is a 4×4 homogeneous transform g = [[R, p], [0, 1]] with p in mm.
* The error of an MU pair is applied in the frame of the downstream unit, after
  its nominal pose: actual = G_1 e^{ξ_1^} G_2 e^{ξ_2^} … G_n e^{ξ_n^} G_tool.
* Ad_g = [[R, 0], [p̂R, R]] maps a twist given in the frame of g into the
  reference frame of g (g e^{ξ^} g⁻¹ = e^{(Ad_g ξ)^}).

The error of the chain seen in the frame of the functional point ("tool") is
δg = g_nom⁻¹ g_act = Π_i e^{η_i^} exactly, with η_i = Ad_{H_i⁻¹} ξ_i and
H_i = G_{i+1} … G_n G_tool (frame i → tool). The composed error screw of
Zhou et al. (2020, eqs. 6-8), done with the nominal geometry, is therefore
ξ_E = Σ_i η_i, exact in the geometry and first order in the error size (the
neglected terms are the ½[η_i, η_j] Lie brackets, second order); :func:`compose_exact`
gives log δg. The paper's printed form, which has no geometry, is in
:mod:`arfem.models.allocation.paper`.

References
----------
.. [1] Zhou et al., "Kinematic accuracy mapping of NC machine tools based on
   meta-action units", J. Harbin Inst. Technol. 52(1), 2020.
.. [2] Murray, Li, Sastry, "A Mathematical Introduction to Robotic
   Manipulation", CRC 1994, ch. 2 (twists, adjoint, pitch, magnitude).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

__all__ = ["hat3", "vee3", "hat", "vee", "pose", "adjoint", "inverse", "error_twist",
           "error_transform", "chain_adjoints", "compose_adjoint", "compose_exact",
           "pitch", "screw_magnitude",
           "point_displacement_bound", "axial_translation"]

_EPS_OMEGA = 1e-300


def hat3(w) -> np.ndarray:
    """Skew matrix ŵ with ŵ x = w × x.

    Examples
    --------
    >>> hat3([1, 2, 3]) @ np.array([0, 0, 1.0])
    array([ 2., -1.,  0.])
    """
    w = np.asarray(w, float)
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def vee3(m) -> np.ndarray:
    """Inverse of :func:`hat3` (skew part of ``m``).

    Examples
    --------
    >>> vee3(hat3([1, 2, 3])).tolist()
    [1.0, 2.0, 3.0]
    """
    m = np.asarray(m, float)
    s = 0.5 * (m - m.T)
    return np.array([s[2, 1], s[0, 2], s[1, 0]])


def hat(xi) -> np.ndarray:
    """4×4 twist matrix ξ^ = [[ω̂, v], [0, 0]] of ξ = [ω; v] ([rad], [mm]).

    Parameters
    ----------
    xi : array_like, shape (6,)
        Twist [ω; v]: small rotations [rad], then small translations [mm].

    Returns
    -------
    ndarray, shape (4, 4)
        ξ^: rotation block ω̂ [rad], translation column v [mm].

    Examples
    --------
    >>> hat([0, 0, 0, 1, 2, 3])[:3, 3].tolist()
    [1.0, 2.0, 3.0]
    """
    xi = np.asarray(xi, float)
    m = np.zeros((4, 4))
    m[:3, :3] = hat3(xi[:3])
    m[:3, 3] = xi[3:]
    return m


def vee(m) -> np.ndarray:
    """Inverse of :func:`hat`: [ω; v] from a 4×4 twist matrix.

    Examples
    --------
    >>> vee(hat([1, 2, 3, 4, 5, 6])).tolist()
    [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    """
    m = np.asarray(m, float)
    return np.concatenate([vee3(m[:3, :3]), m[:3, 3]])


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def pose(offset_mm=(0.0, 0.0, 0.0), rpy_deg=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Homogeneous transform from a translation [mm] and roll-pitch-yaw angles [deg].

    R = Rz(yaw) Ry(pitch) Rx(roll); the translation is applied in the parent frame.

    Parameters
    ----------
    offset_mm : sequence of 3 float
        Origin of the child frame in the parent frame [mm].
    rpy_deg : sequence of 3 float
        Roll, pitch, yaw about x, y, z [deg].

    Returns
    -------
    ndarray, shape (4, 4)

    Examples
    --------
    >>> g = pose([10, 0, 0], [0, 0, 90])
    >>> np.round(g @ [1, 0, 0, 1], 12).tolist()
    [10.0, 1.0, 0.0, 1.0]
    """
    r, p, y = np.radians(np.asarray(rpy_deg, float))
    g = np.eye(4)
    g[:3, :3] = _rot(2, y) @ _rot(1, p) @ _rot(0, r)
    g[:3, 3] = np.asarray(offset_mm, float)
    return g


def inverse(g) -> np.ndarray:
    """Inverse of a rigid transform, [[Rᵀ, −Rᵀp], [0, 1]].

    Parameters
    ----------
    g : array_like, shape (4, 4)
        Rigid transform, p in [mm].

    Returns
    -------
    ndarray, shape (4, 4)
        g⁻¹, translation −Rᵀp [mm].

    Examples
    --------
    >>> g = pose([1, 2, 3], [10, 20, 30])
    >>> bool(np.allclose(inverse(g) @ g, np.eye(4)))
    True
    """
    g = np.asarray(g, float)
    out = np.eye(4)
    out[:3, :3] = g[:3, :3].T
    out[:3, 3] = -g[:3, :3].T @ g[:3, 3]
    return out


def adjoint(g) -> np.ndarray:
    """6×6 adjoint Ad_g = [[R, 0], [p̂R, R]] for twists ordered [ω; v].

    Parameters
    ----------
    g : array_like, shape (4, 4)
        Rigid transform, p in [mm].

    Returns
    -------
    ndarray, shape (6, 6)
        Maps a twist given in the frame of ``g`` to the frame ``g`` is expressed in
        (ω [rad] unchanged in size, v [mm] picks up the lever arm p × Rω).

    Examples
    --------
    A rotation of 1e-6 rad about z at a point 500 mm along x moves the parent
    origin by 5e-4 mm along -y:

    >>> (adjoint(pose([500, 0, 0])) @ [0, 0, 1e-6, 0, 0, 0]).round(9).tolist()
    [0.0, 0.0, 1e-06, 0.0, -0.0005, 0.0]
    """
    g = np.asarray(g, float)
    R, p = g[:3, :3], g[:3, 3]
    A = np.zeros((6, 6))
    A[:3, :3] = R
    A[3:, 3:] = R
    A[3:, :3] = hat3(p) @ R
    return A


def error_twist(dx_mm=0.0, dy_mm=0.0, dz_mm=0.0, dalpha_rad=0.0, dbeta_rad=0.0,
                dgamma_rad=0.0) -> np.ndarray:
    """Error twist of one MU pair from its six small errors (cf. paper eqs. 5-6).

    Parameters
    ----------
    dx_mm, dy_mm, dz_mm : float
        Small translations Δx, Δy, Δz [mm].
    dalpha_rad, dbeta_rad, dgamma_rad : float
        Small rotations Δα, Δβ, Δγ about x, y, z [rad].

    Returns
    -------
    ndarray, shape (6,)
        ξ = [Δα, Δβ, Δγ, Δx, Δy, Δz] ([rad], [mm]).

    Examples
    --------
    >>> error_twist(dz_mm=0.002, dgamma_rad=1e-6).tolist()
    [0.0, 0.0, 1e-06, 0.0, 0.0, 0.002]
    """
    return np.array([dalpha_rad, dbeta_rad, dgamma_rad, dx_mm, dy_mm, dz_mm], float)


def error_transform(xi) -> np.ndarray:
    """Exact rigid error transform e^{ξ^} of a twist [rad, mm] (matrix exponential).

    Its first-order part is I + ξ^.

    Parameters
    ----------
    xi : array_like, shape (6,)
        Error twist [ω; v] ([rad], [mm]).

    Returns
    -------
    ndarray, shape (4, 4)
        Rigid transform, translation p [mm].

    Examples
    --------
    >>> g = error_transform([0, 0, np.pi / 2, 0, 0, 0])
    >>> np.round(g[:2, :2], 12).tolist()
    [[0.0, -1.0], [1.0, 0.0]]
    """
    return scipy.linalg.expm(hat(xi))


def chain_adjoints(poses, tool=None) -> np.ndarray:
    """Ad_{H_i⁻¹} for every unit, H_i = G_{i+1} … G_n G_tool (frame i → functional point).

    Parameters
    ----------
    poses : sequence of (4, 4) arrays
        Nominal pose G_i of unit i in the frame of unit i−1 [mm].
    tool : (4, 4) array, optional
        Pose of the functional point in the frame of the last unit, translation
        [mm] (default identity).

    Returns
    -------
    ndarray, shape (n, 6, 6)

    Examples
    --------
    >>> A = chain_adjoints([np.eye(4), pose([0, 0, 100])], tool=pose([500, 0, 0]))
    >>> A.shape
    (2, 6, 6)
    """
    poses = [np.asarray(g, float) for g in poses]
    H = np.eye(4) if tool is None else np.asarray(tool, float)
    out = np.empty((len(poses), 6, 6))
    for i in range(len(poses) - 1, -1, -1):
        out[i] = adjoint(inverse(H))
        H = poses[i] @ H
    return out


def compose_adjoint(xis, poses, tool=None) -> np.ndarray:
    """Whole-chain error screw ξ_E = Σ_i Ad_{H_i⁻¹} ξ_i in the tool frame (paper eqs. 6-8).

    Exact in the nominal geometry, first order in the error size.

    Parameters
    ----------
    xis : array_like, shape (..., n, 6)
        Error twist of each unit [rad, mm] (leading axes: batch of candidates).
    poses : sequence of n (4, 4) arrays
        Nominal poses (see :func:`chain_adjoints`).
    tool : (4, 4) array, optional
        Pose of the functional point in the frame of the last unit, translation
        [mm] (default identity).

    Returns
    -------
    ndarray, shape (..., 6)

    Examples
    --------
    A 1e-6 rad error of a carrier about z seen at a pallet 500 mm away:

    >>> xi = np.array([[0, 0, 1e-6, 0, 0, 0]])
    >>> compose_adjoint(xi, [np.eye(4)], tool=pose([500, 0, 0])).round(9).tolist()
    [0.0, 0.0, 1e-06, 0.0, 0.0005, 0.0]
    """
    A = chain_adjoints(poses, tool)
    return np.einsum("nij,...nj->...i", A, np.asarray(xis, float))


def compose_exact(xis, poses, tool=None) -> np.ndarray:
    """log(g_nom⁻¹ g_act) for one candidate: the exact error twist of the chain.

    Parameters
    ----------
    xis : array_like, shape (n, 6)
        Error twist of each unit [rad, mm].
    poses, tool : see :func:`chain_adjoints`.

    Returns
    -------
    ndarray, shape (6,)
        Twist whose exponential is the exact error transform [rad, mm].

    Examples
    --------
    >>> xi = np.array([[1e-6, 0, 0, 1e-3, 0, 0], [0, 2e-6, 0, 0, 0, 1e-3]])
    >>> g = [pose([0, 0, 100]), pose([0, 50, 0], [0, 0, 30])]
    >>> t = pose([400, 0, 0])
    >>> bool(np.allclose(compose_exact(xi, g, t), compose_adjoint(xi, g, t), atol=1e-9))
    True
    """
    xis = np.asarray(xis, float)
    g_nom = np.eye(4)
    g_act = np.eye(4)
    for g, xi in zip(poses, xis):
        g_nom = g_nom @ g
        g_act = g_act @ g @ error_transform(xi)
    t = np.eye(4) if tool is None else np.asarray(tool, float)
    g_nom, g_act = g_nom @ t, g_act @ t
    d = inverse(g_nom) @ g_act
    return vee(np.real(scipy.linalg.logm(d)))


def pitch(xi) -> np.ndarray:
    """Pitch h = ω·v / |ω|² [mm/rad] of a twist (paper eq. 10).

    Translation along the screw axis per radian of rotation about it. A pure
    translation (ω = 0) has infinite pitch (returned as ``inf``).

    Parameters
    ----------
    xi : array_like, shape (..., 6)
        Twist [ω; v] ([rad], [mm]).

    Returns
    -------
    ndarray or float
        h [mm/rad] (signed: right-handed screw > 0).

    Examples
    --------
    >>> round(float(pitch([0, 0, 2e-6, 0, 0, 4e-3])), 6)   # 4 µm along z per 2 µrad about z
    2000.0
    >>> float(pitch([1e-6, 0, 0, 0, 1e-3, 0]))        # translation ⟂ axis: pure rotation
    0.0
    >>> float(pitch([0, 0, 0, 1e-3, 0, 0]))
    inf
    """
    xi = np.asarray(xi, float)
    w, v = xi[..., :3], xi[..., 3:]
    ww = np.sum(w * w, axis=-1)
    wv = np.sum(w * v, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(ww > _EPS_OMEGA, wv / np.where(ww > _EPS_OMEGA, ww, 1.0), np.inf)
    return h[()] if h.ndim == 0 else h


def screw_magnitude(xi) -> np.ndarray:
    """Screw-theory magnitude M: |ω| [rad] if ω ≠ 0, else |v| [mm] (paper eq. 11).

    Parameters
    ----------
    xi : array_like, shape (..., 6)
        Twist [ω; v] ([rad], [mm]).

    Returns
    -------
    ndarray or float
        M: |ω| [rad], or |v| [mm] for a pure translation (ω = 0).

    References
    ----------
    Zhou et al., J. Harbin Inst. Technol. 52(1), 2020, eq. 11; Murray, Li, Sastry
    (1994), ch. 2.

    Examples
    --------
    >>> float(screw_magnitude([0, 0, 3e-6, 0, 4e-3, 0]))
    3e-06
    >>> float(screw_magnitude([0, 0, 0, 3e-3, 4e-3, 0]))
    0.005
    """
    xi = np.asarray(xi, float)
    nw = np.linalg.norm(xi[..., :3], axis=-1)
    nv = np.linalg.norm(xi[..., 3:], axis=-1)
    m = np.where(nw ** 2 > _EPS_OMEGA, nw, nv)
    return m[()] if m.ndim == 0 else m


def point_displacement_bound(xi, radius_mm: float = 0.0) -> np.ndarray:
    """m_E [mm]: largest displacement of a point within ``radius_mm`` of the tool origin.

    The small motion of a point at r is v + ω × r, so |δr| ≤ |v| + |ω|·|r|;
    m_E = |v| + radius·|ω| is what the paper's constraint m_E ≤ ΔE (eq. 16)
    compares with the tolerance ΔE [mm]. With radius 0 it is the displacement
    of the functional point itself.

    Parameters
    ----------
    xi : array_like, shape (..., 6)
        Twist in the tool frame [rad, mm].
    radius_mm : float
        Working radius around the functional point [mm], ≥ 0.

    Returns
    -------
    ndarray or float
        m_E [mm].

    Examples
    --------
    >>> float(point_displacement_bound([0, 0, 0, 3e-3, 4e-3, 0]))
    0.005
    >>> round(float(point_displacement_bound([0, 0, 1e-6, 0, 0, 0], radius_mm=100.0)), 9)
    0.0001
    """
    xi = np.asarray(xi, float)
    m = np.linalg.norm(xi[..., 3:], axis=-1) + radius_mm * np.linalg.norm(xi[..., :3], axis=-1)
    return m[()] if m.ndim == 0 else m


def axial_translation(xi) -> np.ndarray:
    """Translation along the screw axis, |ω·v| / |ω| [mm].

    Equals |h|·|ω| (h the pitch, :func:`pitch`): the least displacement of any
    point; |v| for a pure translation.

    Parameters
    ----------
    xi : array_like, shape (..., 6)
        Twist [ω; v] ([rad], [mm]).

    Returns
    -------
    ndarray or float
        Axial translation [mm], >= 0.

    Examples
    --------
    >>> float(axial_translation([0, 0, 2e-6, 3e-3, 0, 4e-3]))
    0.004
    """
    xi = np.asarray(xi, float)
    w, v = xi[..., :3], xi[..., 3:]
    nw = np.linalg.norm(w, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(nw ** 2 > _EPS_OMEGA, np.abs(np.sum(w * v, -1)) / np.where(nw > 0, nw, 1.0),
                     np.linalg.norm(v, axis=-1))
    return t[()] if t.ndim == 0 else t
