"""A multi-material body on a user's mesh: heat and thermo-elastic operators.

The problem on a :class:`arfem.fem.gmsh_io.GroupedMesh` (θ = T − T_ref, T_ref the
uniform start and stress-free temperature):

    ρc ∂θ/∂t − ∇·(λ∇θ) = Σ_v P_v(t)/V_v · 1_v       in each volume group (own ρ, c, λ)
    λ ∂θ/∂n = q_s(t)                                 on each heat-source surface group s
    λ ∂θ/∂n = −h_g(t) (θ − θ_amb,g(t))               on each convection group g
    ∂θ/∂n = 0                                        elsewhere

semi-discretised as M θ' + (K + Σ_g h_g B_g) θ = F u(t) with the input vector
u = (q_1 … q_S, h_1θ_amb,1 … h_Gθ_amb,G): a source given as a total power P [W] has
the column ∫v dS / A_s on a surface group, or ∫_{Ω_v} v dΩ / V_v on a volume group
(the power spread uniformly over the group's volume, a heat generation P/V [W/m³]:
a motor's losses in its stator, a bearing's friction in its rings), so that its input
is P itself (:func:`power_column`).

Quasi-static thermo-elasticity (small strain, isotropic per group):

    ∇·σ = 0,  σ = C(E, ν) : (ε(u) − αθ I),   held by a clamped face group or by a
    statically determinate 3-2-1 support (six point constraints; free expansion).

A displacement sensor s(u) = wᵀu is a linear functional of θ through the factored
stiffness: s = wᵀK⁻¹Tθ = (TᵀK⁻¹w)ᵀθ, one solve per sensor (adjoint, as in
:mod:`arfem.fem.elastic`). Every sensor, temperature or displacement, is therefore a
row gᵀ over the temperature unknowns, and the transient solves of
:mod:`arfem.fem.thermal3d` need only G = [g_1 … g_r].

The weak forms are the small decorated functions below; material data enter as
element-wise constants.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from skfem import (Basis, BilinearForm, ElementHex1, ElementHexS2, ElementTetP1,
                   ElementTetP2, ElementVector, FacetBasis, Functional, LinearForm)
from skfem.helpers import dot, grad

from arfem.fem.gmsh_io import ELASTIC_DIRECT_MAX_DOFS, ELASTIC_FACTOR_MAX_DOFS, GroupedMesh
from arfem.fem.linsolve import factorize_spd
from arfem.params import InputError

__all__ = ["Material", "SourceSpec", "ConvectionSpec", "Support", "SensorSpec", "SENSOR_QUANTITIES",
           "ThermalBody", "ElasticBody", "element_for", "conduction", "capacity",
           "surface_mass", "unit_load", "elastic_stiffness", "thermal_coupling",
           "LumpedGeometry", "group_volumes_m3", "lumped_geometry", "assemble_elastic_stiffness",
           "assemble_thermal_coupling", "power_column", "is_volume_source",
           "per_element", "material_arrays"]


# -- weak forms -------------------------------------------------------------------------------

@BilinearForm
def conduction(u, v, w):
    """∫ λ ∇u·∇v dV [W/K]; ``w.k`` is λ [W/(m·K)] per element."""
    return w.k * dot(grad(u), grad(v))


@BilinearForm
def capacity(u, v, w):
    """∫ ρc u v dV [J/K]; ``w.rhoc`` is ρc [J/(m³·K)] per element."""
    return w.rhoc * u * v


@BilinearForm
def surface_mass(u, v, w):
    """∫ u v dS [m²] on a facet group (times h: convective conductance)."""
    return u * v


@LinearForm
def unit_load(v, w):
    """∫ v dS or ∫ v dV [m² or m³]."""
    return v


@BilinearForm
def elastic_stiffness(u, v, w):
    """∫ σ(u):ε(v) dV [N/m], σ = λ_L tr ε I + 2μ ε; ``w.lam``, ``w.mu`` [Pa] per element."""
    gu, gv = u.grad, v.grad
    tu = gu[0][0] + gu[1][1] + gu[2][2]
    tv = gv[0][0] + gv[1][1] + gv[2][2]
    normal = gu[0][0] * gv[0][0] + gu[1][1] * gv[1][1] + gu[2][2] * gv[2][2]
    shear = ((gu[0][1] + gu[1][0]) * (gv[0][1] + gv[1][0])
             + (gu[0][2] + gu[2][0]) * (gv[0][2] + gv[2][0])
             + (gu[1][2] + gu[2][1]) * (gv[1][2] + gv[2][1]))
    # 2μ ε(u):ε(v) = 2μ Σ ε_ii ε_ii + μ Σ_{i<j} γ_ij γ_ij, γ = 2ε (components, not
    # skfem.helpers.sym_grad, which is 10x slower here)
    return w.lam * tu * tv + w.mu * (2.0 * normal + shear)


@BilinearForm
def thermal_coupling(theta, v, w):
    """∫ (3λ_L + 2μ) α θ tr ε(v) dV [N/K]; ``w.beta`` = (3λ_L + 2μ)α [Pa/K] per element."""
    g = v.grad
    return w.beta * theta * (g[0][0] + g[1][1] + g[2][2])


# -- vectorised element kernels (the same forms, without skfem's per-basis-pair loop) -----------

#: Elements per block of the vectorised kernels: bounds their temporaries (a block of
#: 8192 P2 tetrahedra holds 8192 × 30 × 30 doubles = 59 MB of element matrices).
KERNEL_BLOCK_ELEMENTS = 8192


def _scalar_pattern(sb: Basis):
    """The sparsity pattern of the scalar matrices on ``sb`` and where each element's
    (a, b) entry goes in it: (indptr, indices, pos) with ``pos`` of shape (nel, nloc, nloc)
    indexing the CSR entries (rows and columns sorted)."""
    edofs = np.asarray(sb.element_dofs, np.int64)
    N = int(sb.N)
    keys = (edofs.T[:, :, None] * N + edofs.T[:, None, :])          # (nel, nloc, nloc)
    uniq, pos = np.unique(keys.ravel(), return_inverse=True)
    rows = uniq // N
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=N))])
    return indptr, (uniq % N).astype(np.int32), pos.reshape(keys.shape)


def _scalar_gradients_block(sb: Basis, e: slice) -> np.ndarray:
    """∇N_a of the elements ``e``: shape (ne, nloc, 3, nqp) [1/m]."""
    return np.stack([np.asarray(b[0].grad)[:, e] for b in sb.basis], axis=0).transpose(
        2, 0, 1, 3)


def assemble_elastic_stiffness(sb: Basis, lam_el: np.ndarray, mu_el: np.ndarray,
                               pattern=None) -> sp.csr_matrix:
    """The stiffness of :func:`elastic_stiffness` on the vector basis of ``sb``, vectorised.

    K[(a,i),(b,j)] = Σ_q dx_q [λ_L ∂_iN_a ∂_jN_b + μ (δ_ij ∇N_a·∇N_b + ∂_jN_a ∂_iN_b)]
    (σ(u):ε(v) with u = N_b e_j, v = N_a e_i), computed for all elements at once as a
    batched product of the scalar basis gradients, and summed into the 3 × 3 blocks of
    the scalar matrices' pattern, instead of skfem's loop over the 30 × 30 basis pairs of
    ``ElementVector(ElementTetP2)``; equal to ``elastic_stiffness.assemble`` to round-off
    (tests/test_geometry_verification.py).

    Parameters
    ----------
    sb : skfem.Basis
        Scalar basis (its element and quadrature are used); the displacement dof of
        scalar dof s and component c is 3s + c, as skfem's ``ElementVector`` numbers them.
    lam_el, mu_el : ndarray, shape (nel,)
        Lamé's λ_L and the shear modulus μ [Pa] per element.
    pattern : tuple, optional
        ``_scalar_pattern(sb)``, when the caller has it already (computed otherwise).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (3 N, 3 N)
        K [N/m].
    """
    indptr, indices, pos = _scalar_pattern(sb) if pattern is None else pattern
    nnz, nel = indices.size, pos.shape[0]
    data = np.zeros((nnz, 3, 3))
    lam_el, mu_el = np.asarray(lam_el, float), np.asarray(mu_el, float)
    for s in range(0, nel, KERNEL_BLOCK_ELEMENTS):
        e = slice(s, min(s + KERNEL_BLOCK_ELEMENTS, nel))
        G = _scalar_gradients_block(sb, e)                                 # (ne, nloc, 3, q)
        ne, nloc, q = G.shape[0], G.shape[1], G.shape[-1]
        Gf = G.reshape(ne, 3 * nloc, q)
        P = np.matmul(Gf * np.asarray(sb.dx)[e][:, None, :], Gf.transpose(0, 2, 1))
        P = P.reshape(ne, nloc, 3, nloc, 3)                                # Σ dx ∂iNa ∂jNb
        lap = mu_el[e][:, None, None] * np.einsum("eakbk->eab", P)
        lam, mu = lam_el[e][:, None, None], mu_el[e][:, None, None]
        p = pos[e].ravel()
        for i in range(3):
            for j in range(3):
                blk = lam * P[:, :, i, :, j] + mu * P[:, :, j, :, i]
                if i == j:
                    blk = blk + lap
                data[:, i, j] += np.bincount(p, weights=blk.ravel(), minlength=nnz)
    N = int(sb.N)
    return sp.bsr_matrix((data, indices, indptr), shape=(3 * N, 3 * N)).tocsr()


def assemble_thermal_coupling(sb: Basis, beta_el: np.ndarray, pattern=None) -> sp.csr_matrix:
    """The coupling of :func:`thermal_coupling` (temperature → displacement), vectorised.

    T[(a,i), b] = Σ_q dx_q β ∂_iN_a N_b with β = (3λ_L + 2μ)α [Pa/K] per element; equal
    to ``thermal_coupling.assemble(sb, ElementVector basis)`` to round-off.

    Parameters
    ----------
    sb : skfem.Basis
        Scalar basis (temperature; also the scalar factor of the displacement basis).
    beta_el : ndarray, shape (nel,)
        (3λ_L + 2μ)α [Pa/K] per element.
    pattern : tuple, optional
        ``_scalar_pattern(sb)``, when the caller has it already (computed otherwise).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (3 N, N)
        T [N/K]: ``T @ θ`` is the thermal load [N] of θ [K].
    """
    indptr, indices, pos = _scalar_pattern(sb) if pattern is None else pattern
    nnz, nel = indices.size, pos.shape[0]
    data = np.zeros((nnz, 3, 1))
    beta_el = np.asarray(beta_el, float)
    for s in range(0, nel, KERNEL_BLOCK_ELEMENTS):
        e = slice(s, min(s + KERNEL_BLOCK_ELEMENTS, nel))
        G = _scalar_gradients_block(sb, e)                                  # (ne, nloc, 3, q)
        ne, nloc = G.shape[0], G.shape[1]
        Nv = np.stack([np.asarray(b[0].value)[e] for b in sb.basis], axis=1)  # (ne, nloc, q)
        w = np.asarray(sb.dx)[e] * beta_el[e][:, None]
        Te = np.matmul(G.reshape(ne, 3 * nloc, -1) * w[:, None, :], Nv.transpose(0, 2, 1))
        Te = Te.reshape(ne, nloc, 3, nloc)
        p = pos[e].ravel()
        for i in range(3):
            data[:, i, 0] += np.bincount(p, weights=Te[:, :, i, :].ravel(), minlength=nnz)
    N = int(sb.N)
    return sp.bsr_matrix((data, indices, indptr), shape=(3 * N, N)).tocsr()


# -- specifications -----------------------------------------------------------------------------

@dataclass(frozen=True)
class Material:
    """An isotropic material on one volume group (all SI)."""

    group: str
    conductivity_W_mK: float
    density_kg_m3: float
    specific_heat_J_kgK: float
    expansion_1_K: float
    youngs_modulus_Pa: float
    poisson_ratio: float

    @property
    def lame(self) -> tuple[float, float]:
        """(λ_L, μ) [Pa]."""
        E, nu = self.youngs_modulus_Pa, self.poisson_ratio
        return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


@dataclass(frozen=True)
class SourceSpec:
    """A heat source on a surface group (its input a flux [W/m²] or a power [W]) or on
    a volume group (its input a power [W], spread uniformly over the group's volume).
    A name that is both a surface and a volume group of the mesh means the surface."""

    name: str
    group: str
    kind: str = "power"          # "power" (input in W) or "flux" (input in W/m²)


@dataclass(frozen=True)
class ConvectionSpec:
    """Convection on a surface group (its h and ambient come with the schedule)."""

    name: str
    group: str


@dataclass(frozen=True)
class Support:
    """How the body is held: ``kind="clamped"`` on ``group``, or ``kind="3-2-1"`` on
    three points (coordinates [m]): ``points[0]`` fixed in x, y, z; ``points[1]`` in the
    two directions across the line 0→1; ``points[2]`` normal to the plane 0-1-2."""

    kind: str
    group: str | None = None
    points: tuple = ()


#: Per sensor quantity: (column prefix, column unit suffix, output → record unit factor,
#: unit shown, kind index for the Krylov tolerance's per-kind floor).
SENSOR_QUANTITIES = {
    "temperature": ("T", "C", 1.0, "°C", 0),
    "displacement": ("d", "um", 1e6, "µm", 1),
    "tilt": ("tilt", "urad", 1e6, "µrad", 2),
}


@dataclass(frozen=True)
class SensorSpec:
    """A named sensor: a temperature at a point; a displacement along ``direction``
    (a unit vector) at a point or averaged over a surface group; or a tilt [rad]: the
    difference of the displacements along ``direction`` at the two ``points`` over
    their distance, (d(p₂) − d(p₁))/|p₂ − p₁| (two probes on a test mandrel, ISO 230-3's
    A and B). A rigid rotation ω gives the tilt ω·(t × e), t the unit vector p₁→p₂ and
    e the direction: the rotation about :attr:`about`."""

    name: str
    quantity: str                # "temperature" | "displacement" | "tilt"
    point: tuple | None = None   # [m]
    group: str | None = None     # displacement averaged over this surface group
    direction: tuple = (0.0, 0.0, 1.0)
    points: tuple = ()           # a tilt's two points ((x, y, z), (x, y, z)) [m]

    @property
    def elastic(self) -> bool:
        """True when the sensor reads the displacement field (an elastic adjoint)."""
        return self.quantity != "temperature"

    @property
    def column(self) -> str:
        """Its record column: ``T_<name>_C``, ``d_<name>_um`` or ``tilt_<name>_urad``."""
        pre, unit = SENSOR_QUANTITIES[self.quantity][:2]
        return f"{pre}_{self.name}_{unit}"

    @property
    def record_scale(self) -> float:
        """Model output (K above reference, m, rad) → record unit (°C offset, µm, µrad)."""
        return SENSOR_QUANTITIES[self.quantity][2]

    @property
    def unit(self) -> str:
        return SENSOR_QUANTITIES[self.quantity][3]

    @property
    def kind_index(self) -> int:
        """0 temperature, 1 displacement, 2 tilt (the reduced solve's per-kind floor)."""
        return SENSOR_QUANTITIES[self.quantity][4]

    @property
    def about(self) -> tuple | None:
        """A tilt's rotation axis t × e (unit vector), None for other sensors."""
        if self.quantity != "tilt":
            return None
        t = np.subtract(self.points[1], self.points[0])
        a = np.cross(t / np.linalg.norm(t), np.asarray(self.direction, float))
        return tuple(float(v) for v in a / np.linalg.norm(a))

    @property
    def base_m(self) -> float | None:
        """A tilt's base |p₂ − p₁| [m], None for other sensors."""
        if self.quantity != "tilt":
            return None
        return float(np.linalg.norm(np.subtract(self.points[1], self.points[0])))


def element_for(gmesh: GroupedMesh, order: int):
    """The scalar element of ``order`` (1 or 2) on ``gmesh``'s cells."""
    if order not in (1, 2):
        raise InputError(f"must be 1 or 2, got {order!r}", "geometry.order")
    if gmesh.cell_type == "hexahedron":
        return ElementHex1() if order == 1 else ElementHexS2()
    return ElementTetP1() if order == 1 else ElementTetP2()


def per_element(basis: Basis, values_el: np.ndarray) -> np.ndarray:
    """An element-wise constant as skfem expects it: shape (nelems, nqp).

    Parameters
    ----------
    basis : skfem.Basis
        Gives the quadrature points per element (nqp).
    values_el : array_like
        (nelems,) one value per element, in its own unit (kept).

    Returns
    -------
    numpy.ndarray
        (nelems, nqp), each element's value repeated at its quadrature points.
    """
    return np.repeat(np.asarray(values_el, float)[:, None], basis.X.shape[1], axis=1)


def material_arrays(gmesh: GroupedMesh, materials: dict) -> dict:
    """Per-element property arrays from {group: Material}; every element needs one.

    Parameters
    ----------
    gmesh : GroupedMesh
        The mesh and its volume groups.
    materials : dict
        {group: :class:`Material`}.

    Returns
    -------
    dict
        (nelems,) arrays: ``"k"`` conductivity [W/(m·K)], ``"rhoc"`` ρc [J/(m³·K)],
        ``"alpha"`` expansion [1/K], ``"lam"`` and ``"mu"`` Lamé parameters [Pa],
        ``"beta"`` = (3λ + 2μ)α [Pa/K], ``"which"`` the index of each element's
        material in ``materials``.

    Raises
    ------
    InputError
        A volume group has no material, or an element belongs to none.
    """
    ne = gmesh.mesh.nelements
    which = -np.ones(ne, int)
    mats = list(materials.values())
    for i, mat in enumerate(mats):
        el = gmesh.volume_group(mat.group, f"material[{i}].group")
        which[el] = i
    missing = [g for g in gmesh.volumes if g not in materials]
    if missing:
        raise InputError(f"volume group {missing[0]!r} of the mesh has no [[material]] "
                         f"(groups without one: {', '.join(sorted(missing))})", "material")
    if np.any(which < 0):
        raise InputError(f"{int(np.sum(which < 0))} elements belong to no volume group with "
                         "a material", "material")

    def arr(f):
        return np.array([f(m) for m in mats])[which]
    lam = arr(lambda m: m.lame[0])
    mu = arr(lambda m: m.lame[1])
    return {"k": arr(lambda m: m.conductivity_W_mK),
            "rhoc": arr(lambda m: m.density_kg_m3 * m.specific_heat_J_kgK),
            "alpha": arr(lambda m: m.expansion_1_K), "lam": lam, "mu": mu,
            "beta": (3 * lam + 2 * mu) * arr(lambda m: m.expansion_1_K),
            "which": which}


@dataclass(frozen=True)
class ThermalBody:
    """Assembled heat operators of a multi-material body (no inputs, no state).

    Attributes
    ----------
    gmesh : GroupedMesh
    basis : skfem.Basis
        Scalar basis (temperature).
    M : sparse, capacity ∫ρc u v dV [J/K]
    K : sparse, conductance ∫λ∇u·∇v dV [W/K]
    B : tuple of sparse
        Per convection group, ∫u v dS [m²] (times h [W/(m²K)] gives W/K).
    F : ndarray, shape (ndofs, S + G)
        Input matrix: M θ' + A θ = F u with u = (source inputs [W or W/m²],
        h θ_amb per convection group [W/m²]).
    sources, convections : tuple of SourceSpec / ConvectionSpec
    areas_m2 : dict
        Discrete area [m²] of every surface group used.
    volume : ndarray, ∫v dV [m³]
    props : dict
        Element-wise material arrays (``k``, ``rhoc``, ``alpha``, ``lam``, ``mu``, ``beta``).
    source_volumes_m3 : dict
        Discrete volume [m³] of every volume group a source heats.
    """

    gmesh: GroupedMesh
    basis: Basis
    M: sp.csr_matrix = field(repr=False)
    K: sp.csr_matrix = field(repr=False)
    B: tuple = field(repr=False)
    F: np.ndarray = field(repr=False)
    sources: tuple
    convections: tuple
    areas_m2: dict
    volume: np.ndarray = field(repr=False)
    props: dict = field(repr=False)
    order: int = 2
    source_volumes_m3: dict = field(default_factory=dict)

    @property
    def ndofs(self) -> int:
        return int(self.basis.N)

    @property
    def n_inputs(self) -> int:
        return int(self.F.shape[1])

    def operator(self, h_W_m2K) -> sp.csr_matrix:
        """K + Σ_g h_g B_g [W/K] for the convection coefficients ``h_W_m2K`` (one per group)."""
        A = self.K.copy()
        for h, B in zip(np.atleast_1d(h_W_m2K), self.B):
            A = A + float(h) * B
        return A.tocsr()

    @classmethod
    def build(cls, gmesh: GroupedMesh, materials: dict, sources=(), convections=(),
              order: int = 2, intorder: int | None = None) -> "ThermalBody":
        """Assemble M, K, the convection matrices and the input matrix on ``gmesh``.

        Parameters
        ----------
        gmesh : GroupedMesh
        materials : dict
            {volume group: Material}; every volume group needs one.
        sources : sequence of SourceSpec
        convections : sequence of ConvectionSpec
        order : {1, 2}
            Element order (P1/P2 tetrahedra, 8/20-node bricks).
        intorder : int, optional
            Quadrature order (default: 2·order, exact for the mass on straight cells).
        """
        mesh = gmesh.mesh
        elem = element_for(gmesh, order)
        io = intorder if intorder is not None else 2 * order + (1 if mesh.__class__.__name__
                                                                 .endswith("2") else 0)
        basis = Basis(mesh, elem, intorder=io)
        props = material_arrays(gmesh, materials)
        M = capacity.assemble(basis, rhoc=per_element(basis, props["rhoc"])).tocsr()
        K = conduction.assemble(basis, k=per_element(basis, props["k"])).tocsr()
        volume = unit_load.assemble(basis)
        areas, cols, Bs, vols = {}, [], [], {}
        for i, s in enumerate(sources):
            f, measure, in_volume = _unit_source(gmesh, basis, s.group, io,
                                                 f"heat_source[{i}].group")
            if in_volume and s.kind != "power":
                raise InputError(f"{s.group!r} is a volume group: a volume source takes "
                                 "power_W [W] (spread over its volume), not flux_W_m2",
                                 f"heat_source[{i}]")
            (vols if in_volume else areas)[s.group] = measure
            cols.append(f / measure if s.kind == "power" else f)
        for i, c in enumerate(convections):
            fac = gmesh.surface_group(c.group, f"convection[{i}].group")
            fb = FacetBasis(mesh, elem, facets=fac, intorder=io)
            f = unit_load.assemble(fb)
            areas[c.group] = float(f.sum())
            cols.append(f)
            Bs.append(surface_mass.assemble(fb).tocsr())
        F = np.column_stack(cols) if cols else np.zeros((basis.N, 0))
        return cls(gmesh=gmesh, basis=basis, M=M, K=K, B=tuple(Bs), F=F,
                   sources=tuple(sources), convections=tuple(convections), areas_m2=areas,
                   volume=volume, props=props, order=order, source_volumes_m3=vols)

    def probe(self, points_m: np.ndarray, names) -> sp.csr_matrix:
        """Interpolation rows (npoints, ndofs) at ``points_m`` (3, npoints) [m], each in
        the element that holds it (:func:`locate`); a point outside the mesh is refused
        by name."""
        rows = []
        for j, name in enumerate(names):
            cell, vals = locate(self.basis, points_m[:, j], f"sensor {name!r}.point",
                                self.gmesh.source)
            dofs = self.basis.element_dofs[:, cell]
            rows.append(sp.csr_matrix((vals, (np.zeros(dofs.size, int), dofs)),
                                      shape=(1, self.basis.N)))
        return sp.vstack(rows).tocsr()


def is_volume_source(gmesh: GroupedMesh, group: str) -> bool:
    """True when a source on ``group`` heats a volume: the name is a volume group and
    not also a surface group (a name that is both means the surface, as before volume
    sources existed)."""
    return group in gmesh.volumes and group not in gmesh.surfaces


def _unit_source(gmesh: GroupedMesh, basis: Basis, group: str, intorder: int,
                 where: str) -> tuple:
    """(∫v over the group [m² or m³ per dof], the group's area [m²] or volume [m³],
    whether it is a volume): the load of a unit flux on a surface group, or of a unit
    heat generation [W/m³] on a volume group's cells."""
    if is_volume_source(gmesh, group):
        vb = Basis(gmesh.mesh, basis.elem, elements=gmesh.volume_group(group, where),
                   intorder=intorder)
        f = unit_load.assemble(vb)
        return f, float(f.sum()), True
    if group not in gmesh.surfaces:
        raise InputError(f"the mesh has no surface or volume group {group!r} (it has "
                         f"{gmesh.describe_groups()})", where)
    fb = FacetBasis(gmesh.mesh, basis.elem, facets=gmesh.surfaces[group], intorder=intorder)
    f = unit_load.assemble(fb)
    return f, float(f.sum()), False


def power_column(thermal: "ThermalBody", group: str, where: str) -> np.ndarray:
    """The load column of 1 W spread evenly over a surface group (per area) or a volume
    group (per volume, ∫_{Ω_g} v dΩ / V_g) of ``thermal``'s mesh [W per W].

    Its entries sum to 1 (all of the watt enters the body), whichever the group.
    """
    io = _intorder(thermal)
    f, measure, _ = _unit_source(thermal.gmesh, thermal.basis, group, io, where)
    return f / measure


def _intorder(thermal: "ThermalBody") -> int:
    """The quadrature order the body was assembled with (2·order, + 1 on curved cells)."""
    return 2 * thermal.order + (1 if thermal.gmesh.mesh.__class__.__name__.endswith("2")
                                else 0)


def _inverse_map(mapping, x: np.ndarray, e: int, tet: bool):
    """Reference coordinates (3, 1) of ``x`` in element ``e`` by Newton's method on the
    element's own map (skfem's ``invF`` raises as soon as it meets a point just outside a
    curved element); None if it does not converge."""
    X = np.full((3, 1), 0.25 if tet else 0.5)
    tind = np.array([e])
    for _ in range(30):
        F = mapping.F(X, tind=tind)[:, 0, :]            # (3, 1)
        J = mapping.DF(X, tind=tind)[:, :, 0, 0]        # (3, 3)
        try:
            dX = np.linalg.solve(J, x - F[:, 0])
        except np.linalg.LinAlgError:
            return None
        X = X + dX[:, None]
        if np.max(np.abs(dX)) < 1e-12:
            return X
        if np.max(np.abs(X)) > 10.0:
            return None
    return None


def locate(basis: Basis, point_m, where: str, source: str = "the mesh"):
    """The element holding ``point_m`` (3,) [m] and the element's basis values there.

    Candidates are the elements whose node bounding box holds the point; the reference
    coordinates are found by the element's own (isoparametric) inverse map, so a point
    near a curved boundary lands in the curved element. skfem's ``probes`` tries Newton
    on its nearest candidates and stops at the first that does not converge; this tries
    each candidate in turn.

    Returns
    -------
    cell : int
    values : ndarray, shape (n_local_dofs,)
        Basis function values at the point (sum to 1 for Lagrange elements).
    """
    mesh = basis.mesh
    x = np.asarray(point_m, float).reshape(3)
    loc = mesh.doflocs[:, mesh.t] if mesh.doflocs.shape[1] == mesh.p.shape[1] else None
    if not hasattr(basis, "_arfem_boxes"):
        nodes = mesh.doflocs[:, basis.mesh.dofs.element_dofs] if loc is None else loc
        object.__setattr__(basis, "_arfem_boxes", (nodes.min(axis=1), nodes.max(axis=1)))
    lo, hi = basis._arfem_boxes
    tol = 1e-3 * np.max(hi - lo, axis=0)          # 0.1 % of each element's size
    cand = np.flatnonzero(np.all((lo - tol <= x[:, None]) & (x[:, None] <= hi + tol), axis=0))
    tet = mesh.t.shape[0] == 4
    best = None
    for e in cand:
        X = _inverse_map(basis.mapping, x, int(e), tet)
        if X is None:
            continue
        Xr = X[:, 0]
        out = (max(-Xr.min(), Xr.sum() - 1.0) if tet
               else max(-Xr.min(), (Xr - 1.0).max()))
        if best is None or out < best[0]:
            best = (out, e, X)
        if out <= 1e-9:
            break
    # a point on a curved face may lie a hair (O(h³)) outside the quadratic surface:
    # accepted within 0.1 % of the element (reference coordinates), i.e. on the surface
    if best is None or best[0] > 1e-3:
        raise InputError(f"point ({x[0]:.6g}, {x[1]:.6g}, {x[2]:.6g}) m is outside the mesh "
                         f"({source})", where)
    _, e, X = best
    el = basis.elem
    vals = np.array([float(np.ravel(el.lbasis(X, i)[0])[0]) for i in range(el.doflocs.shape[0])])
    return int(e), vals


def _nearest_vertex(mesh, point, where: str) -> int:
    nv = int(mesh.t.max()) + 1
    d = np.linalg.norm(mesh.p[:, :nv] - np.asarray(point, float)[:, None], axis=0)
    k = int(np.argmin(d))
    size = float(np.linalg.norm(mesh.p[:, :nv].max(axis=1) - mesh.p[:, :nv].min(axis=1)))
    if d[k] > 0.05 * size:
        p = np.asarray(point, float)
        raise InputError(f"point ({p[0]:.6g}, {p[1]:.6g}, {p[2]:.6g}) m is {d[k] * 1e3:.3g} mm "
                         "from the nearest mesh vertex; a 3-2-1 support point must lie on the "
                         "mesh (it is held at the nearest vertex)", where)
    return k


#: Above this many free displacement unknowns the elastic solves use conjugate gradients
#: (preconditioned by the P2/P1 p-multigrid :class:`_PMGSolver` for second-order
#: elements, by smoothed-aggregation AMG :class:`_AMGSolver` for first-order ones)
#: instead of a sparse factorisation: the factor of P2-tetrahedron elasticity fills in
#: badly (nnz(L+U) = 75.2 M for 73 k free unknowns of the 25k-dof spindle unit: 13.5 s
#: CPU in SuperLU and 1.8 GB), while the geometry path needs only a handful of solves (one
#: per displacement sensor); the p-multigrid CG took 0.4 s to set up and about 1 s CPU
#: per solve there, in a tenth of the memory.
DIRECT_MAX_DOFS = ELASTIC_DIRECT_MAX_DOFS

#: Fields (many displacement solves) factor the stiffness after all, up to this many
#: free unknowns (the factor that :data:`DIRECT_MAX_DOFS` avoids for the sensors'
#: few solves: 1.8 GB at 73k unknowns), from this many solves at once.
FIELDS_DIRECT_MAX_DOFS = ELASTIC_FACTOR_MAX_DOFS
FIELDS_FACTOR_MIN_SOLVES = 8

#: Relative residual at which the AMG-preconditioned CG stops.
CG_RTOL = 1e-10

#: pyamg's smoothed aggregation for P2 elasticity, chosen on the 25k-dof spindle unit's
#: stiffness (73k free unknowns, 2026-11-25): default settings took 44 CG iterations to
#: 1e-8 (0.07 s CPU each; its dense coarse pseudo-inverse alone 2.8 s); Jacobi smoothing
#: 92; energy-minimising prolongation with a sparse-LU coarse solve, 30.
AMG_OPTIONS = dict(strength=("symmetric", {"theta": 0.0}), smooth=("energy", {"degree": 1}),
                   presmoother=("gauss_seidel", {"sweep": "symmetric"}),
                   postsmoother=("gauss_seidel", {"sweep": "symmetric"}),
                   max_coarse=3000, coarse_solver="splu")


class _IterativeSolver:
    """Conjugate gradients on the free stiffness ``K`` with a preconditioner ``M`` (set by
    the subclass), to the relative residual :data:`CG_RTOL`; ``solve(b)`` like
    :class:`arfem.fem.linsolve.SPDFactor`, the iterations of every solve in
    ``iterations``."""

    K: sp.csr_matrix
    M: object
    nnz = 0

    def solve(self, b: np.ndarray) -> np.ndarray:
        from scipy.sparse.linalg import cg
        b = np.asarray(b, float)
        cols = b.reshape(b.shape[0], -1)
        out = np.zeros_like(cols)
        for j in range(cols.shape[1]):
            nb = np.linalg.norm(cols[:, j])
            if nb == 0.0:
                continue
            it = [0]

            def count(_):
                it[0] += 1
            xj, info = cg(self.K, cols[:, j], rtol=CG_RTOL, maxiter=2000, M=self.M,
                          callback=count)
            if info != 0:
                raise RuntimeError(f"CG did not converge ({info})")
            self.iterations.append(it[0])
            out[:, j] = xj
        return out.reshape(b.shape)


class _AMGSolver(_IterativeSolver):
    """CG with a smoothed-aggregation AMG preconditioner built on the rigid-body modes
    (pyamg, :data:`AMG_OPTIONS`): the elastic solves of first-order elements."""

    def __init__(self, K, coords: np.ndarray, comp: np.ndarray):
        import pyamg
        n = K.shape[0]
        x, y, z = coords
        B = np.zeros((n, 6))
        for c in range(3):
            B[comp == c, c] = 1.0
        # rotations: (−y, x, 0), (0, −z, y), (z, 0, −x)
        B[comp == 0, 3], B[comp == 1, 3] = -y[comp == 0], x[comp == 1]
        B[comp == 1, 4], B[comp == 2, 4] = -z[comp == 1], y[comp == 2]
        B[comp == 2, 5], B[comp == 0, 5] = -x[comp == 2], z[comp == 0]
        self.K = K
        self.ml = pyamg.smoothed_aggregation_solver(K, B=B, **AMG_OPTIONS)
        self.M = self.ml.aspreconditioner(cycle="V")
        self.iterations: list = []


def has_vertex_edge_dofs(elem) -> bool:
    """True for the second-order elements whose dofs are the values at the vertices and
    at one node per edge (10-node tetrahedron, 20-node serendipity brick): their space
    holds the first-order one, whose values at an edge node are the mean of the edge's
    two vertex values (the edge node sits at the reference edge's midpoint)."""
    return (getattr(elem, "nodal_dofs", 0) == 1 and getattr(elem, "edge_dofs", 0) == 1
            and getattr(elem, "facet_dofs", 0) == 0 and getattr(elem, "interior_dofs", 0) == 0)


def p1_prolongation(sb: Basis, free: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """The interpolation of first-order displacements into ``sb``'s second-order ones.

    Vertex dofs are copied, an edge node gets the mean of its edge's two vertices (exact:
    the first-order space is a subspace of the second-order one), per component.
    Restricted to the ``free`` displacement dofs and to the vertex dofs that are free,
    so that a coarse function vanishes wherever the fine one is held.

    Parameters
    ----------
    sb : skfem.Basis
        Scalar second-order basis with :func:`has_vertex_edge_dofs`.
    free : ndarray of int
        Free displacement dofs (3 s + c numbering).

    Returns
    -------
    P : scipy.sparse.csr_matrix, shape (free.size, n_coarse)
    coarse_free : ndarray of int
        The free vertex displacement dofs (3 k + c, k the mesh vertex) P's columns are.
    """
    nod, edg = np.asarray(sb.nodal_dofs[0]), np.asarray(sb.edge_dofs[0])
    edges = np.asarray(sb.mesh.edges)
    nv = nod.size
    rows = np.concatenate([nod, edg, edg])
    cols = np.concatenate([np.arange(nv), edges[0], edges[1]])
    vals = np.concatenate([np.ones(nv), np.full(2 * edg.size, 0.5)])
    Ps = sp.csr_matrix((vals, (rows, cols)), shape=(int(sb.N), nv))
    P = sp.kron(Ps, sp.identity(3), format="csr")
    is_free = np.zeros(3 * int(sb.N), bool)
    is_free[free] = True
    coarse_free = np.flatnonzero(is_free[(3 * nod[:, None] + np.arange(3)).ravel()])
    return P[free][:, coarse_free].tocsr(), coarse_free


class _PMGSolver(_IterativeSolver):
    """CG preconditioned by a two-level p-multigrid: one symmetric Gauss–Seidel sweep
    on the second-order stiffness, an exact correction in the first-order (vertex) space
    (Galerkin Pᵀ K P by :func:`p1_prolongation`, factored once), one symmetric sweep back;
    a symmetric preconditioner, so CG applies.

    On the 25k-dof spindle unit (72 942 free unknowns, 2026-11-25, one BLAS thread) it
    set up in 0.4 s CPU (coarse order 10 365, factor 4.1 M entries) and solved the three
    adjoints in 17–18 iterations, 3.1 s CPU, where pyamg's energy-minimising smoothed
    aggregation (:class:`_AMGSolver`) took 3.5 s to set up and 7.6 s for 38–40
    iterations; the two solutions agree to 5e-12 of their largest entry.
    """

    def __init__(self, K, sb: Basis, free: np.ndarray):
        self.K = K
        self.P, _ = p1_prolongation(sb, free)
        self.coarse = factorize_spd((self.P.T @ K @ self.P).tocsr())
        self.nnz = 0                    # the coarse factor is small; not the stiffness's
        self.nnz_coarse = self.coarse.nnz
        self.iterations: list = []
        from scipy.sparse.linalg import LinearOperator
        self.M = LinearOperator(K.shape, matvec=self._cycle, dtype=float)

    def _cycle(self, b: np.ndarray) -> np.ndarray:
        from pyamg.relaxation.relaxation import gauss_seidel
        b = np.asarray(b, float).ravel()
        x = np.zeros_like(b)
        gauss_seidel(self.K, x, b, iterations=1, sweep="symmetric")
        x += self.P @ self.coarse.solve(self.P.T @ (b - self.K @ x))
        gauss_seidel(self.K, x, b, iterations=1, sweep="symmetric")
        return x


@dataclass(frozen=True)
class ElasticBody:
    """Factored thermo-elastic operator of a :class:`ThermalBody` and its support.

    Attributes
    ----------
    thermal : ThermalBody
    basis : skfem.Basis
        Vector basis (displacement, interleaved components).
    T : sparse, thermal load [N] = ``T @ θ`` (θ [K]).
    free : ndarray, unconstrained displacement dofs.
    """

    thermal: ThermalBody
    basis: Basis
    T: sp.csr_matrix = field(repr=False)
    free: np.ndarray = field(repr=False)
    factor: object = field(repr=False)
    nnz_factor: int = 0
    _many: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def build(cls, thermal: ThermalBody, support: Support,
              factor_method: str | None = None, n_solves: int = 0) -> "ElasticBody":
        """Assemble and factor the stiffness with ``support``'s constraints.

        ``n_solves``: the solves expected (sensors and field snapshots); from
        :data:`FIELDS_FACTOR_MIN_SOLVES` on, the stiffness is factored up to
        :data:`FIELDS_DIRECT_MAX_DOFS` free unknowns instead of set up for AMG-CG.
        """
        gm = thermal.gmesh
        mesh = gm.mesh
        sb = thermal.basis
        vb = sb.with_element(ElementVector(sb.elem))
        pr = thermal.props
        pattern = _scalar_pattern(sb)
        K = assemble_elastic_stiffness(sb, pr["lam"], pr["mu"], pattern)
        T = assemble_thermal_coupling(sb, pr["beta"], pattern)
        if support.kind == "clamped":
            fac = gm.surface_group(support.group, "support.group")
            D = vb.get_dofs(facets=fac).flatten()
        elif support.kind == "3-2-1":
            if len(support.points) != 3:
                raise InputError("a 3-2-1 support needs three points", "support.points")
            P = [np.asarray(p, float) for p in support.points]
            v = [_nearest_vertex(mesh, p, f"support.points[{i}]") for i, p in enumerate(P)]
            if len(set(v)) < 3:
                raise InputError("the three points fall on fewer than three mesh vertices",
                                 "support.points")
            ab = P[1] - P[0]
            nrm = np.cross(ab, P[2] - P[0])
            if np.linalg.norm(nrm) < 1e-9 * np.linalg.norm(ab) ** 2:
                raise InputError("the three points are on one line; a 3-2-1 support needs "
                                 "a triangle", "support.points")
            along = int(np.argmax(np.abs(ab)))
            normal = int(np.argmax(np.abs(nrm)))
            nd = vb.nodal_dofs
            D = np.concatenate([nd[:, v[0]], nd[[c for c in range(3) if c != along], v[1]],
                                nd[[normal], v[2]]])
        else:
            raise InputError(f"must be 'clamped' or '3-2-1', got {support.kind!r}",
                             "support.type")
        free = np.setdiff1d(np.arange(vb.N), D)
        K = K[free]                      # rows, then columns: two copies at a time, not
        Kf = K[:, free].tocsr()          # three (the 100k unit's stiffness is 0.4 GB each)
        del K
        many = n_solves >= FIELDS_FACTOR_MIN_SOLVES and free.size <= FIELDS_DIRECT_MAX_DOFS
        if factor_method is None and free.size > DIRECT_MAX_DOFS and not many:
            lu = (_PMGSolver(Kf, sb, free) if has_vertex_edge_dofs(sb.elem)
                  else _AMGSolver(Kf, vb.doflocs[:, free], free % 3))
        else:
            try:
                lu = factorize_spd(Kf, factor_method)
            except RuntimeError as exc:
                raise InputError(f"the support does not hold the body ({exc})",
                                 "support") from None
        return cls(thermal=thermal, basis=vb, T=T, free=free, factor=lu,
                   nnz_factor=int(getattr(lu, "nnz", 0)))

    @property
    def ndofs(self) -> int:
        return int(self.basis.N)

    def displacement(self, theta: np.ndarray) -> np.ndarray:
        """Displacement dofs [m] for θ of shape (ndofs_heat,) or (n, ndofs_heat) [K]."""
        th = np.atleast_2d(np.asarray(theta, float))
        F = np.asarray(self.T @ th.T)
        U = np.zeros((self.ndofs, th.shape[0]))
        U[self.free] = self._solver(th.shape[0]).solve(np.ascontiguousarray(F[self.free]))
        return U[:, 0] if np.ndim(theta) == 1 else U.T

    def _solver(self, n_solves: int):
        """The AMG-CG of ``build`` for a few solves; for many (field snapshots) a factor
        of the stiffness, made once, while it fits (:data:`FIELDS_DIRECT_MAX_DOFS`):
        on the 25k-dof spindle unit 25 hourly snapshots took 25 CG solves of about
        2 s CPU each against one factorisation of 15 s and solves of 0.1 s."""
        if (n_solves < FIELDS_FACTOR_MIN_SOLVES or not isinstance(self.factor, _IterativeSolver)
                or self.free.size > FIELDS_DIRECT_MAX_DOFS):
            return self.factor
        if "factor" not in self._many:
            self._many["factor"] = factorize_spd(self.factor.K)
        return self._many["factor"]

    def functional(self, w: np.ndarray) -> np.ndarray:
        """The row g over θ with wᵀu(θ) = gᵀθ: g = TᵀK⁻¹w (one solve per column of w)."""
        W = np.atleast_2d(np.asarray(w, float).T).T if np.ndim(w) == 1 else np.asarray(w)
        W = W.reshape(self.ndofs, -1)
        Y = np.zeros_like(W)
        Y[self.free] = self.factor.solve(np.ascontiguousarray(W[self.free]))
        G = np.asarray(self.T.T @ Y)
        return G[:, 0] if np.ndim(w) == 1 else G

    def sensor_weight(self, sensor: SensorSpec, where: str) -> np.ndarray:
        """w with wᵀu = the sensor's displacement [m] (point value or group average), or
        its tilt [rad]: (w(p₂) − w(p₁))/|p₂ − p₁| of the point displacements."""
        if sensor.quantity == "tilt":
            w1, w2 = (self.sensor_weight(replace(sensor, quantity="displacement", point=p,
                                                 points=()), f"{where}.points[{k}]")
                      for k, p in enumerate(sensor.points))
            return (w2 - w1) / sensor.base_m
        d = np.asarray(sensor.direction, float)
        d = d / np.linalg.norm(d)
        gm = self.thermal.gmesh
        if sensor.group is not None:
            fac = gm.surface_group(sensor.group, f"{where}.group")
            fb = FacetBasis(gm.mesh, self.basis.elem, facets=fac,
                            intorder=self.thermal.basis.quadrature[0].shape[0] + 2)

            @LinearForm
            def along(v, w_):
                return d[0] * v.value[0] + d[1] * v.value[1] + d[2] * v.value[2]

            @Functional
            def area(w_):
                return 1.0 + 0.0 * w_.x[0]
            return along.assemble(fb) / float(area.assemble(fb))
        cell, vals = locate(self.thermal.basis, sensor.point, f"{where}.point", gm.source)
        sdofs = self.thermal.basis.element_dofs[:, cell]
        w = np.zeros(self.ndofs)
        for c in range(3):           # ElementVector numbers component c of node s as 3s + c
            w[3 * sdofs + c] += d[c] * vals
        return w


# -- lumped quantities (issue 32 item 4: the paper's AR(1) generalised to any geometry) ----------

@Functional
def _one(w):
    """∫ 1 dV per element [m³]."""
    return 1.0 + 0.0 * w.x[0]


@dataclass(frozen=True)
class LumpedGeometry:
    """What the lumped (one-temperature) model of a body needs from its mesh.

    Attributes
    ----------
    volumes_m3 : dict
        Volume [m³] of each volume group (element quadrature, exact on straight cells).
    heat_capacity_J_K : dict
        ρcV [J/K] of each volume group (its material's ρ·c times its volume).
    areas_m2 : dict
        Area [m²] of each heat-source and convection group (:attr:`ThermalBody.areas_m2`).
    input_power_W : ndarray, shape (S + G,)
        Heat into the body per unit of each input [W per input unit]: 1 for a source
        given as a power, its area for a flux [W/m²], the group's area for a convection
        group's h·θ_amb [W/m²]. It is 1ᵀF, the column sums of the input matrix.
    uniform_gain : ndarray, shape (r,)
        Each sensor's output for a uniform temperature rise of 1 K [m/K or K/K]: gᵀ1,
        the free (or restrained, as supported) thermal expansion at a displacement
        sensor; 1 at a thermometer.
    """

    volumes_m3: dict
    heat_capacity_J_K: dict
    areas_m2: dict
    input_power_W: np.ndarray
    uniform_gain: np.ndarray

    @property
    def total_heat_capacity_J_K(self) -> float:
        """Σ ρ_i c_i V_i over the volume groups [J/K]."""
        return float(sum(self.heat_capacity_J_K.values()))


def group_volumes_m3(thermal: "ThermalBody") -> dict:
    """Volume [m³] of each volume group of ``thermal``'s mesh."""
    vol_el = _one.elemental(thermal.basis)
    return {g: float(vol_el[el].sum()) for g, el in thermal.gmesh.volumes.items()}


def lumped_geometry(thermal: "ThermalBody", G: np.ndarray) -> LumpedGeometry:
    """Volumes, heat capacities, areas, input powers and uniform-rise gains of a body.

    Parameters
    ----------
    thermal : ThermalBody
    G : ndarray, shape (ndofs, r)
        Sensor functionals over the temperature unknowns (y = Gᵀθ).
    """
    vol_el = _one.elemental(thermal.basis)
    rhoc = np.asarray(thermal.props["rhoc"])
    vols = {g: float(vol_el[el].sum()) for g, el in thermal.gmesh.volumes.items()}
    caps = {g: float((rhoc[el] * vol_el[el]).sum()) for g, el in thermal.gmesh.volumes.items()}
    ones = np.ones(thermal.ndofs)
    return LumpedGeometry(vols, caps, dict(thermal.areas_m2),
                          np.asarray(thermal.F.sum(axis=0), float).ravel(),
                          np.asarray(G.T @ ones, float).ravel())
