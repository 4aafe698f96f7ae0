"""Quasi-static linear thermo-elasticity of the rod: axial growth from a temperature field.

The problem (small strain, isotropic, θ = T − T_ref):

    ∇·σ = 0,   σ = C : (ε(u) − αθ I),   ε(u) = ½(∇u + ∇uᵀ)     in the rod
    σ·n = 0                                                     on ``lateral`` and ``far``
    u_z = 0,  (σ·n)_tangential = 0                              on ``heated`` (axial roller)

plus the few point constraints that remove the remaining rigid-body motion
(none of which load the rod, because the thermal load is self-equilibrated).

Two geometries, both on the mesh and the element family of a :class:`arfem.fem.heat.HeatFEM`:

* axisymmetric, coordinates (r, z), displacement (u_r, u_z), hoop strain
  ε_θθ = u_r / r, volume weight 2πr; u_r = 0 on the axis;
* 3D, displacement (u_x, u_y, u_z) on the curved-hex mesh of
  :func:`arfem.fem.mesh.cylinder_mesh`; u_x = u_y = 0 at the heated-face vertex nearest
  the axis and the in-row component at a second vertex of the same row, which
  fixes the in-plane translations and the rotation about z.

The stiffness is assembled and factored once (:func:`arfem.fem.linsolve.factorize_spd`);
the thermal load is a fixed coupling matrix ``T`` applied to θ, so the
displacement of any number of temperature fields costs one triangular solve each.

Reciprocity (Maxwell–Betti with the uniform-tension field σ* = e_z ⊗ e_z, whose
displacement is linear and therefore in the FE space): the far-face integral of
u_z equals α∫θ dV, exactly in the discrete problem too. Hence the face-averaged
far-end growth equals :attr:`arfem.fem.heat.HeatFEM.growth` ``@ θ`` (up to the ratio of
the discrete to the exact face area) -- the identity the AR(1) comparison rests on.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from skfem import Basis, BilinearForm, ElementVector, FacetBasis, LinearForm

from arfem.fem.heat import HeatFEM
from arfem.fem.linsolve import factorize_spd
from arfem.params import InputError, Rod

__all__ = ["lame_parameters", "ThermoElastic", "elastic_forms"]


def lame_parameters(youngs_modulus_Pa: float, poisson_ratio: float) -> tuple[float, float]:
    """Lamé parameters (λ_L, μ) [Pa, Pa] of an isotropic solid.

    λ_L = Eν / ((1 + ν)(1 − 2ν)),  μ = E / (2(1 + ν)).

    Parameters
    ----------
    youngs_modulus_Pa : float
        Young's modulus E [Pa].
    poisson_ratio : float
        Poisson's ratio ν [-].

    Returns
    -------
    tuple of float
        (λ_L, μ) [Pa].

    Examples
    --------
    >>> lam, mu = lame_parameters(206e9, 0.3)
    >>> round(lam / 1e9, 2), round(mu / 1e9, 2)
    (118.85, 79.23)
    >>> round((3 * lam + 2 * mu) * (1 - 2 * 0.3) / 206e9, 12)   # 3K(1 − 2ν) = E
    1.0
    """
    E, nu = float(youngs_modulus_Pa), float(poisson_ratio)
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def _strain(u, w, axisymmetric: bool):
    """Strain components as a list of (component, multiplicity) pairs."""
    g = u.grad
    if axisymmetric:
        r = w.x[0]
        err, ezz, ett = g[0][0], g[1][1], u.value[0] / r
        erz = 0.5 * (g[0][1] + g[1][0])
        return (err, ezz, ett), (erz,)
    exx, eyy, ezz = g[0][0], g[1][1], g[2][2]
    return (exx, eyy, ezz), (0.5 * (g[0][1] + g[1][0]), 0.5 * (g[0][2] + g[2][0]),
                             0.5 * (g[1][2] + g[2][1]))


def elastic_forms(axisymmetric: bool, lam: float, mu: float, alpha: float):
    """Weak forms: stiffness ∫σ(u):ε(v) dV and thermal coupling ∫(3λ_L+2μ)αθ tr ε(v) dV.

    ``coupling`` is a mixed form with the scalar temperature as trial function and
    the displacement as test function. Axisymmetric forms carry the 2πr weight.

    Parameters
    ----------
    axisymmetric : bool
        True: (r, z) coordinates [m] with hoop strain u_r / r and weight 2πr;
        False: 3D (x, y, z) [m].
    lam : float
        Lamé's first parameter λ_L [Pa] (see :func:`lame_parameters`).
    mu : float
        Shear modulus μ [Pa].
    alpha : float
        Linear thermal expansion coefficient α [1/K].

    Returns
    -------
    stiffness : skfem.BilinearForm
        Assembles K [N/m]: ``K @ u`` is the elastic force [N] of displacement dofs u [m].
    coupling : skfem.BilinearForm
        Assembles T [N/K] (temperature basis → vector basis): ``T @ θ`` is the
        thermal load [N] of a temperature rise θ [K].
    """
    wr = (lambda x: 2.0 * np.pi * x[0]) if axisymmetric else (lambda x: 1.0 + 0.0 * x[0])

    @BilinearForm
    def stiffness(u, v, w):
        du, su = _strain(u, w, axisymmetric)
        dv, sv = _strain(v, w, axisymmetric)
        tru, trv = sum(du), sum(dv)
        energy = lam * tru * trv + 2.0 * mu * sum(a * b for a, b in zip(du, dv))
        energy = energy + 4.0 * mu * sum(a * b for a, b in zip(su, sv))
        return energy * wr(w.x)

    @BilinearForm
    def coupling(theta, v, w):
        dv, _ = _strain(v, w, axisymmetric)
        return (3.0 * lam + 2.0 * mu) * alpha * theta * sum(dv) * wr(w.x)

    return stiffness, coupling


def _fixed_dofs(mesh, vb, rod: Rod, axi: bool) -> np.ndarray:
    """The displacement dofs held fixed: u_z on the heated face, and what removes the
    rigid-body motions left (u_r on the axis; in 3D both lateral components at the
    heated face's centre vertex and one at a second vertex in its row, which stops the
    rotation about z). Sorted, unique."""
    zc = mesh.dim() - 1
    fixed = [vb.get_dofs("heated").all(f"u^{zc + 1}")]
    nv = mesh.nvertices if hasattr(mesh, "nvertices") else mesh.p.shape[1]
    pv = mesh.p[:, :nv]
    tol = 1e-9 * max(rod.radius_m, rod.length_m)
    if axi:
        if "axis" not in mesh.boundaries:
            raise InputError("axisymmetric mesh has no boundary tagged 'axis'", "mesh")
        fixed += [vb.get_dofs("axis").all("u^1")]
    else:
        heated_v = np.unique(mesh.facets[:, mesh.boundaries["heated"]])
        heated_v = heated_v[heated_v < nv]
        rad = np.hypot(pv[0, heated_v], pv[1, heated_v])
        a = heated_v[np.argmin(rad)]
        row = heated_v[np.abs(pv[1, heated_v] - pv[1, a]) < tol]
        row = row[row != a]
        if row.size == 0:
            raise InputError("no second heated-face vertex in the row of the centre one; "
                             "cannot fix the rotation about z", "mesh")
        b = row[np.argmax(np.abs(pv[0, row] - pv[0, a]))]
        fixed += [vb.nodal_dofs[:2, a], vb.nodal_dofs[1:2, b]]
    return np.unique(np.concatenate([np.asarray(f, int).ravel() for f in fixed]))


def _far_face_weights(mesh, vb, axi: bool, intorder: int | None):
    """Weights w with wᵀu = the face-averaged u_z [m] over the far face (∫ v_z dA / ∫ dA),
    and the face's area A_far [m²]."""
    zc = mesh.dim() - 1
    fb = FacetBasis(mesh, vb.elem, facets=mesh.boundaries["far"], intorder=intorder or 6)
    wr = (lambda x: 2.0 * np.pi * x[0]) if axi else (lambda x: 1.0 + 0.0 * x[0])

    @LinearForm
    def face_uz(v, w):
        return v.value[zc] * wr(w.x)

    fw = face_uz.assemble(fb)
    area = float(np.sum(fw))      # ∫ v_z dA with v_z ≡ 1 on every u_z dof = A_far
    # (u_z dofs carry a partition of unity, so summing the weights gives the area)
    return fw / area, area


@dataclass(frozen=True)
class ThermoElastic:
    """Factored thermo-elastic operator on the mesh of a :class:`HeatFEM`.

    Build with :meth:`build`; then :meth:`displacement` (one or many θ) and
    :meth:`growth`. Holds no state beyond the assembled, factored operator.

    Attributes
    ----------
    heat : HeatFEM
        The heat model whose mesh, element family and θ dofs are used.
    basis : skfem.Basis
        Vector basis (same mesh and quadrature as ``heat.basis``).
    T : sparse
        Coupling: thermal load [N] = ``T @ θ`` (θ in K).
    far_weight : ndarray
        ``far_weight @ u`` = ∫_far u_z dA / A_far, the face-averaged u_z [m].
    axis_weight : ndarray
        ``axis_weight @ u`` = u_z at the point on the axis at the far end [m]
        (FE interpolation; equals a nodal value when a node lies there).
    growth_face, growth_axis : ndarray
        Adjoint vectors over the θ dofs: ``growth_face @ θ`` and ``growth_axis @ θ``
        are the two growths [m] (one solve each at build time).
    """

    heat: HeatFEM
    basis: Basis
    T: sp.csr_matrix = field(repr=False)
    free: np.ndarray = field(repr=False)
    far_weight: np.ndarray = field(repr=False)
    far_area_m2: float
    axis_weight: np.ndarray = field(repr=False)
    growth_face: np.ndarray = field(repr=False)
    growth_axis: np.ndarray = field(repr=False)
    _lu: object = field(repr=False)

    @classmethod
    def build(cls, heat: HeatFEM, intorder: int | None = None) -> "ThermoElastic":
        """Assemble and factor the elastic stiffness on ``heat``'s mesh.

        Parameters
        ----------
        heat : HeatFEM
            Supplies the mesh, the element family and the θ dof numbering.
        intorder : int, optional
            Quadrature order; default: the quadrature of ``heat.basis``. A higher
            order makes the discrete reciprocity identity exact on curved 3D
            elements (see the module notes).

        Examples
        --------
        >>> from arfem.fem.heat import build_axisymmetric
        >>> hm = build_axisymmetric(Rod(), order=2, nr=2, nz=4)
        >>> te = ThermoElastic.build(hm)
        >>> g_face, g_axis = te.growth(np.ones(hm.ndofs))   # uniform 1 K rise
        >>> round(float(g_face) * 1e6, 6), round(float(g_axis) * 1e6, 6)  # α L = 9.6 µm
        (9.6, 9.6)
        """
        if not isinstance(heat, HeatFEM):
            raise InputError(f"needs a fem.heat.HeatFEM, got {type(heat).__name__}", "heat")
        rod: Rod = heat.rod
        mesh = heat.basis.mesh
        if "far" not in mesh.boundaries:
            raise InputError("mesh has no boundary tagged 'far'", "mesh")
        axi = heat.axisymmetric
        dim = mesh.dim()
        sb = heat.basis if intorder is None else Basis(mesh, heat.basis.elem, intorder=intorder)
        vb = sb.with_element(ElementVector(heat.basis.elem))
        lam, mu = lame_parameters(rod.youngs_modulus_Pa, rod.poisson_ratio)
        stiffness, coupling = elastic_forms(axi, lam, mu, rod.expansion_1_K)
        K = stiffness.assemble(vb).tocsr()
        T = coupling.assemble(sb, vb).tocsr()

        zc = dim - 1                                     # index of the axial component
        free = np.setdiff1d(np.arange(vb.N), _fixed_dofs(mesh, vb, rod, axi))
        lu = factorize_spd(K[free][:, free])
        far_weight, area = _far_face_weights(mesh, vb, axi, intorder)

        # u_z on the axis at the far end, interpolated (no node needs to lie there)
        target = np.zeros((dim, 1))
        target[zc, 0] = rod.length_m
        axis_weight = np.asarray(vb.probes(target).toarray()[zc]).ravel()

        def adjoint(weight):
            # growth = weightᵀ K⁻¹ T θ = (Tᵀ K⁻¹ weight)ᵀ θ  (K symmetric): one solve
            # turns the growth into a dot product with θ (discrete reciprocity).
            y = np.zeros(vb.N)
            y[free] = lu.solve(np.ascontiguousarray(weight[free]))
            return np.asarray(T.T @ y).ravel()

        return cls(heat=heat, basis=vb, T=T, free=free, far_weight=far_weight,
                   far_area_m2=area, axis_weight=axis_weight, growth_face=adjoint(far_weight),
                   growth_axis=adjoint(axis_weight), _lu=lu)

    @property
    def ndofs(self) -> int:
        return int(self.basis.N)

    def displacement(self, theta: np.ndarray) -> np.ndarray:
        """Displacement dofs [m] for one θ (ndofs_heat,) or a stack (n, ndofs_heat) [K].

        Parameters
        ----------
        theta : ndarray, shape (ndofs_heat,) or (n, ndofs_heat)
            Temperature rise θ = T − T_ref on the dofs of :attr:`heat` [K], finite.

        Returns
        -------
        ndarray, shape (ndofs,) or (n, ndofs)
            Displacement dofs [m] in the basis ordering of :attr:`basis` (component
            dofs interleaved, as skfem's ``ElementVector``).

        Raises
        ------
        InputError
            If a field has the wrong length or a non-finite value.
        """
        th = np.asarray(theta, float)
        one = th.ndim == 1
        th2 = np.atleast_2d(th)
        if th2.shape[1] != self.heat.ndofs or not np.all(np.isfinite(th2)):
            raise InputError(f"needs {self.heat.ndofs} finite values per field", "theta")
        F = self.T @ th2.T                                   # (ndofs, n)
        U = np.zeros((self.ndofs, th2.shape[0]))
        U[self.free] = self._lu.solve(np.ascontiguousarray(F[self.free]))
        return U[:, 0] if one else U.T

    def growth(self, theta: np.ndarray) -> tuple:
        """Axial growth of the far end [m]: (face-averaged u_z, u_z on the axis).

        For a stack of fields (n, ndofs_heat) returns two arrays. Computed with the
        adjoint vectors :attr:`growth_face` / :attr:`growth_axis` (one solve at
        build time), so it costs a dot product per field; identical to reading
        the same quantities off :meth:`displacement` up to round-off.

        Parameters
        ----------
        theta : ndarray, shape (ndofs_heat,) or (n, ndofs_heat)
            Temperature rise θ = T − T_ref on the dofs of :attr:`heat` [K], finite.

        Returns
        -------
        face : float or ndarray, shape (n,)
            Face-averaged axial displacement of the far face, ∫_far u_z dA / A_far [m].
        axis : float or ndarray, shape (n,)
            Axial displacement on the axis at the far end [m].

        Raises
        ------
        InputError
            If a field has the wrong length or a non-finite value.
        """
        th = np.asarray(theta, float)
        if th.shape[-1] != self.heat.ndofs or not np.all(np.isfinite(th)):
            raise InputError(f"needs {self.heat.ndofs} finite values per field", "theta")
        face = th @ self.growth_face
        return face, th @ self.growth_axis

