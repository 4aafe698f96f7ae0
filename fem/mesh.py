"""Meshes of the spindle rod, generated in code (no external mesher).

Two meshes, both with boundaries tagged ``heated`` (z = 0, where the flux
enters), ``far`` (z = L, adiabatic) and ``lateral`` (r = R, convection):

* :func:`axisymmetric_mesh` -- a structured (r, z) quadrilateral mesh of the
  half-section, graded toward the heated end and toward the lateral surface.
  Coordinates: ``x[0] = r``, ``x[1] = z``. An extra tag ``axis`` marks r = 0.
* :func:`cylinder_mesh` -- a 3D hexahedral "butterfly" (O-grid) mesh of the
  cylinder: a square core and a ring of blocks blended onto the circle. The mesh
  geometry is quadratic (:class:`skfem.MeshHex2`, 27-node isoparametric map)
  with every geometry node placed on the true circle, so the cross-section is
  represented to third order in the element size. Coordinates: x, y in the
  section, z along the axis.

Element choice is left to the caller (``ElementQuad1/2`` or ``ElementHex1``,
``ElementHexS2`` -- the paper's 20-node brick -- and ``ElementHex2``).
"""
from __future__ import annotations

import logging

import numpy as np
from skfem import MeshHex1, MeshHex2, MeshQuad1

from arfem.params import InputError, Rod

__all__ = ["graded", "axisymmetric_mesh", "cylinder_mesh", "disk_map"]


def _check_count(name: str, n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"needs at least 1 element, got {n!r}", name)
    return int(n)


def graded(n: int, length: float, ratio: float = 1.0, toward: str = "start") -> np.ndarray:
    """Nodes of a 1D interval [0, length] with ``n`` elements in geometric progression.

    Parameters
    ----------
    n : int
        Number of elements (>= 1).
    length : float
        Interval length [m].
    ratio : float
        Size of the largest element over the smallest [-] (1 = uniform).
    toward : {"start", "end"}
        Where the small elements are.

    Examples
    --------
    >>> graded(2, 1.0).tolist()
    [0.0, 0.5, 1.0]
    >>> x = graded(4, 1.0, ratio=8.0)
    >>> bool(np.isclose((x[-1] - x[-2]) / (x[1] - x[0]), 8.0))
    True
    """
    n = _check_count("n", n)
    if not (ratio >= 1.0 and np.isfinite(ratio)):
        raise InputError(f"must be >= 1, got {ratio!r}", "ratio")
    if n == 1 or ratio == 1.0:
        x = np.linspace(0.0, length, n + 1)
    else:
        g = ratio ** (1.0 / (n - 1))
        h = g ** np.arange(n)
        x = np.concatenate([[0.0], np.cumsum(h)]) / h.sum() * length
    if toward == "end":
        x = length - x[::-1]
    elif toward != "start":
        raise InputError(f"must be 'start' or 'end', got {toward!r}", "toward")
    x[0], x[-1] = 0.0, length
    return x


def axisymmetric_mesh(rod: Rod, nr: int = 6, nz: int = 24, ratio_r: float = 3.0,
                      ratio_z: float = 6.0) -> MeshQuad1:
    """Structured quadrilateral mesh of the rod's (r, z) half-section.

    Parameters
    ----------
    rod : Rod
        Geometry source (``radius_m``, ``length_m``).
    nr, nz : int
        Elements across the radius and along the length (>= 1).
    ratio_r : float
        Largest/smallest radial element; small ones at the lateral surface [-].
    ratio_z : float
        Largest/smallest axial element; small ones at the heated end [-].

    Returns
    -------
    skfem.MeshQuad1
        With boundaries ``heated``, ``far``, ``lateral``, ``axis``.

    Examples
    --------
    >>> m = axisymmetric_mesh(Rod(), nr=2, nz=4)
    >>> m.nelements, sorted(m.boundaries)
    (8, ['axis', 'far', 'heated', 'lateral'])
    """
    nr, nz = _check_count("nr", nr), _check_count("nz", nz)
    r = graded(nr, rod.radius_m, ratio_r, toward="end")
    z = graded(nz, rod.length_m, ratio_z, toward="start")
    m = MeshQuad1.init_tensor(r, z)
    R, L = rod.radius_m, rod.length_m
    tol = 1e-9 * max(R, L)
    return m.with_boundaries({
        "heated": lambda x: np.abs(x[1]) < tol,
        "far": lambda x: np.abs(x[1] - L) < tol,
        "lateral": lambda x: np.abs(x[0] - R) < tol,
        "axis": lambda x: np.abs(x[0]) < tol,
    })


def disk_map(x: np.ndarray, y: np.ndarray, core: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Map the square [-1, 1]² onto the unit disk, O-grid style.

    Points with max(|x|, |y|) <= ``core`` stay where they are (the square core).
    Outside, each point is blended linearly, along its ray through the core square,
    between the core boundary and the circle. The map is smooth inside each
    ring block and continuous across blocks, and sends the square's boundary
    exactly onto the unit circle.

    Examples
    --------
    >>> X, Y = disk_map(np.array([1.0, 1.0, 0.25]), np.array([0.0, 1.0, 0.25]))
    >>> np.round(np.hypot(X, Y), 12).tolist()
    [1.0, 1.0, 0.353553390593]
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    s = np.maximum(np.abs(x), np.abs(y))
    X, Y = x.copy(), y.copy()
    o = s > core * (1 + 1e-12)
    sx, sy = x[o] / s[o], y[o] / s[o]          # on the square's boundary
    # equal-angle placement on the circle: a side coordinate u in [-1, 1]
    # covers a 90 degree arc uniformly, so quadratic arcs are symmetric.
    phi = np.arctan2(sy, sx)
    centre = np.round(phi / (np.pi / 2)) * (np.pi / 2)
    delta = np.angle(np.exp(1j * (phi - centre)))
    phi_eq = centre + (np.pi / 4) * np.tan(delta)
    t = (s[o] - core) / (1.0 - core)
    X[o] = core * sx + t * (np.cos(phi_eq) - core * sx)
    Y[o] = core * sy + t * (np.sin(phi_eq) - core * sy)
    return X, Y


def cylinder_mesh(rod: Rod, n_core: int = 2, n_ring: int = 2, nz: int = 16,
                  core: float = 0.5, ratio_ring: float = 2.0, ratio_z: float = 6.0) -> MeshHex2:
    """Hexahedral mesh of the cylinder with quadratic (curved) geometry.

    Parameters
    ----------
    rod : Rod
        Geometry source.
    n_core : int
        Elements along each side of the square core (>= 1); there are
        ``4 * n_core`` elements around the circumference.
    n_ring : int
        Element layers from the core to the circle (>= 1).
    nz : int
        Elements along the axis (>= 1), graded toward the heated end.
    core : float
        Half-side of the core square as a fraction of R, in (0, 1).
    ratio_ring, ratio_z : float
        Grading ratios toward the lateral surface and the heated end [-].

    Returns
    -------
    skfem.MeshHex2
        With boundaries ``heated``, ``far``, ``lateral``.

    Examples
    --------
    >>> m = cylinder_mesh(Rod(), n_core=2, n_ring=1, nz=2)
    >>> m.nelements, sorted(m.boundaries)
    (24, ['far', 'heated', 'lateral'])
    """
    n_core, n_ring, nz = (_check_count("n_core", n_core), _check_count("n_ring", n_ring),
                          _check_count("nz", nz))
    if not 0.0 < core < 1.0:
        raise InputError(f"must lie in (0, 1), got {core!r}", "core")
    # Butterfly topology in reference coordinates [-1, 1]^2: a core square and
    # four trapezoidal ring blocks whose nodes lie on rays through the origin,
    # so that disk_map is smooth inside every block.
    z = graded(nz, rod.length_m, ratio_z, toward="start")
    xi = np.linspace(-1.0, 1.0, n_core + 1)
    ring = core + graded(n_ring, 1.0 - core, ratio_ring, toward="end")
    box = MeshHex1.init_tensor(core * xi, core * xi, z)
    # skfem's mesh join leaves its arrays in Fortran order and logs a warning as it
    # copies them ("Transforming over 1000 vertices ..."): noise for arfem's users
    join_log = logging.getLogger("skfem.mesh.mesh")
    level = join_log.level
    join_log.setLevel(logging.ERROR)
    try:
        box = _join_quarters(box, xi, ring, z)
    finally:
        join_log.setLevel(level)
    m2 = MeshHex2.from_mesh(box)
    d = m2.doflocs.copy()
    X, Y = disk_map(d[0], d[1], core)
    d[0], d[1] = X * rod.radius_m, Y * rod.radius_m
    m = MeshHex2(d, m2.t)
    L = rod.length_m
    tol = 1e-9 * max(rod.radius_m, L)
    mid = m.p[:, m.facets].mean(axis=1)
    bnd = m.boundary_facets()
    heated = bnd[np.abs(mid[2, bnd]) < tol]
    far = bnd[np.abs(mid[2, bnd] - L) < tol]
    lateral = np.setdiff1d(bnd, np.concatenate([heated, far]))
    return MeshHex2(d, m2.t, _boundaries={"heated": heated, "far": far, "lateral": lateral})


def _join_quarters(box, xi, ring, z):
    """The core box plus four ring blocks, one per quarter, their nodes on rays."""
    for quarter in range(4):
        blk = MeshHex1.init_tensor(xi, ring, z)
        p = blk.p.copy()
        p[0] = p[0] * p[1]                    # x = xi * y: nodes on rays
        c, s_ = np.cos(quarter * np.pi / 2), np.sin(quarter * np.pi / 2)
        p[0], p[1] = c * p[0] - s_ * p[1], s_ * p[0] + c * p[1]
        box = box + MeshHex1(p, blk.t)
    return box
