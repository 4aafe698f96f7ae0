"""The rod's assembled heat problem, its inputs and its output instants: what every
transient solve of it shares (:mod:`arfem.fem.heat`'s exact modal and θ-method solves,
:mod:`arfem.fem.reduced`'s reduced-modal one), in a module of its own so that neither
solver module needs the other's.

The problem (θ = T − T_ref) is :mod:`arfem.fem.heat`'s: M θ' + (K + h B) θ = q f_q +
h θ_amb f_b, every input piecewise constant in time (a :class:`arfem.params.Schedule`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp
from skfem import (BilinearForm, ElementHex1, ElementHex2, ElementHexS2, ElementQuad1,
                   ElementQuad2, FacetBasis, LinearForm, Basis, Mesh)
from skfem.helpers import dot, grad

from arfem.params import InputError, Rod, Schedule

__all__ = ["HeatFEM", "HeatResult", "Breakpoints", "breakpoints", "ELEMENTS", "heat_forms",
           "schedule_inputs", "initial_state_K"]

ELEMENTS = {
    ("axisymmetric", 1): ElementQuad1,
    ("axisymmetric", 2): ElementQuad2,
    ("3d", 1): ElementHex1,
    ("3d", 2): ElementHexS2,      # 20-node serendipity brick, as in the paper
    ("3d", "2-lagrange"): ElementHex2,
}


def _radial_weight(axisymmetric: bool) -> Callable:
    if axisymmetric:
        return lambda x: 2.0 * np.pi * x[0]
    return lambda x: 1.0 + 0.0 * x[0]


def heat_forms(axisymmetric: bool):
    """Weak forms of the heat operator; axisymmetric ones carry the 2πr weight."""
    wr = _radial_weight(axisymmetric)

    @BilinearForm
    def mass(u, v, w):
        return u * v * wr(w.x)

    @BilinearForm
    def stiffness(u, v, w):
        return dot(grad(u), grad(v)) * wr(w.x)

    @LinearForm
    def unit_load(v, w):
        return v * wr(w.x)

    return mass, stiffness, unit_load


@dataclass(frozen=True)
class HeatFEM:
    """Assembled heat problem on one mesh and element (no state, no inputs).

    Attributes
    ----------
    rod : Rod
    basis : skfem.Basis
    axisymmetric : bool
    M : sparse, ρc-weighted mass [J/K per unit θ]
    K : sparse, conductance λ∫∇u·∇v [W/K]
    B : sparse, lateral-surface mass ∫uv dS [m²]
    f_q : ndarray, heated-face load ∫v dS [m²]
    f_b : ndarray, lateral-surface load ∫v dS [m²]
    volume : ndarray, ∫v dV [m³]; ``volume @ θ`` = ∫θ dV
    growth : ndarray, α ``volume`` / A_h [m/K]; ``growth @ θ`` = axial growth [m], A_h the
        discrete heated-face area ``f_q.sum()`` (πR² on the axisymmetric mesh)
    """

    rod: Rod
    basis: Basis
    axisymmetric: bool
    M: sp.csr_matrix
    K: sp.csr_matrix
    B: sp.csr_matrix
    f_q: np.ndarray
    f_b: np.ndarray
    volume: np.ndarray
    growth: np.ndarray = field(repr=False)

    @classmethod
    def build(cls, mesh: Mesh, element, rod: Rod, axisymmetric: bool,
              intorder: int | None = None) -> "HeatFEM":
        """Assemble M, K, B and the loads on ``mesh`` with ``element``.

        Parameters
        ----------
        mesh : skfem.Mesh
            Coordinates [m] ((r, z) if ``axisymmetric``), with boundaries tagged
            ``heated`` and ``lateral`` (and ``far`` for :mod:`arfem.fem.elastic`).
        element : skfem.Element
            Scalar element family (see :data:`ELEMENTS`).
        rod : Rod
            Supplies ρ [kg/m³], c [J/(kg·K)], λ [W/(m·K)] and α [1/K].
        axisymmetric : bool
            Weight every integral by 2πr, so that they are over the whole rod.
        intorder : int, optional
            Quadrature order; default: skfem's for ``element``.

        Returns
        -------
        HeatFEM
            M [J/K], K [W/K], B [m²], f_q, f_b [m²], volume [m³], growth [m/K].

        Raises
        ------
        InputError
            If ``mesh`` lacks the ``heated`` or ``lateral`` boundary.
        """
        for tag in ("heated", "lateral"):
            if mesh.boundaries is None or tag not in mesh.boundaries:
                raise InputError(f"mesh has no boundary tagged {tag!r}", "mesh")
        kw = {} if intorder is None else {"intorder": intorder}
        basis = Basis(mesh, element, **kw)
        fb_q = FacetBasis(mesh, element, facets=mesh.boundaries["heated"], **kw)
        fb_l = FacetBasis(mesh, element, facets=mesh.boundaries["lateral"], **kw)
        mass, stiffness, unit_load = heat_forms(axisymmetric)
        rhoc = rod.density_kg_m3 * rod.specific_heat_J_kgK
        M = (rhoc * mass.assemble(basis)).tocsr()
        K = (rod.conductivity_W_mK * stiffness.assemble(basis)).tocsr()
        B = mass.assemble(fb_l).tocsr()
        volume = unit_load.assemble(basis)
        f_q = unit_load.assemble(fb_q)
        # growth = α∫θ dV / A_h with A_h the discrete face area (= πR² to round-off
        # on the axisymmetric mesh); on the curved 3D mesh this keeps the growth equal
        # to the face-averaged far-end u_z (fem.elastic) instead of carrying the
        # O(h⁴) cross-section area error of the polygonal section.
        return cls(rod=rod, basis=basis, axisymmetric=axisymmetric, M=M, K=K, B=B,
                   f_q=f_q, f_b=unit_load.assemble(fb_l),
                   volume=volume, growth=rod.expansion_1_K * volume / float(f_q.sum()))

    @property
    def ndofs(self) -> int:
        return int(self.M.shape[0])

    def operator(self, h_W_m2K: float) -> sp.csr_matrix:
        """K + hB [W/K].

        Parameters
        ----------
        h_W_m2K : float
            Lateral convection coefficient h [W/(m²·K)].

        Returns
        -------
        scipy.sparse.csr_matrix
            Conductance plus lateral convection K + hB [W/K].
        """
        return (self.K + h_W_m2K * self.B).tocsr()

    def load(self, q_W_m2: float, h_W_m2K: float, theta_amb_K: float) -> np.ndarray:
        """q f_q + h θ_amb f_b [W].

        Parameters
        ----------
        q_W_m2 : float
            Heat flux into the heated end face [W/m²].
        h_W_m2K : float
            Lateral convection coefficient h [W/(m²·K)].
        theta_amb_K : float
            Ambient air temperature minus the rod's nominal ambient, θ_amb [K].

        Returns
        -------
        ndarray, shape (ndofs,)
            Nodal heat input [W].
        """
        return q_W_m2 * self.f_q + (h_W_m2K * theta_amb_K) * self.f_b

    def heat_content(self, theta: np.ndarray) -> np.ndarray:
        """ρc∫θ dV [J] of one state or a stack of states (last axis = dofs).

        Parameters
        ----------
        theta : ndarray, shape (..., ndofs)
            Temperature rise θ = T − T_ref [K].

        Returns
        -------
        float or ndarray, shape (...)
            Heat stored relative to the reference state θ = 0 [J].
        """
        rhoc = self.rod.density_kg_m3 * self.rod.specific_heat_J_kgK
        return rhoc * (np.asarray(theta) @ self.volume)

    def lateral_loss(self, theta: np.ndarray, h_W_m2K: float, theta_amb_K: float) -> np.ndarray:
        """Convective loss h∫(θ − θ_amb) dS [W] of one state or a stack of states.

        Parameters
        ----------
        theta : ndarray, shape (..., ndofs)
            Temperature rise θ = T − T_ref [K].
        h_W_m2K : float
            Lateral convection coefficient h [W/(m²·K)].
        theta_amb_K : float
            Ambient air temperature minus the rod's nominal ambient, θ_amb [K].

        Returns
        -------
        float or ndarray, shape (...)
            Heat flow from the lateral surface to the air [W] (> 0 = loss).
        """
        return h_W_m2K * (np.asarray(theta) @ self.f_b - theta_amb_K * self.f_b.sum())



@dataclass(frozen=True)
class HeatResult:
    """Output of a transient heat solve.

    Attributes
    ----------
    times_s : ndarray, output times [s] (starting with 0)
    growth_m : ndarray, α∫θ dV / A at each output time [m]
    fields : ndarray or None, θ [K] at each output time, shape (n_times, ndofs)
    heat_J : ndarray, ρc∫θ dV at each output time [J]
    """

    times_s: np.ndarray
    growth_m: np.ndarray
    heat_J: np.ndarray
    fields: np.ndarray | None = None

    @property
    def growth_um(self) -> np.ndarray:
        return self.growth_m * 1e6


def schedule_inputs(model: HeatFEM, schedule: Schedule):
    """The per-segment inputs of ``schedule`` on ``model``'s rod, as every time solver
    of the rod (:mod:`arfem.fem.heat`, :mod:`arfem.fem.reduced`) takes them.

    Parameters
    ----------
    model : HeatFEM
        Supplies the rod's nominal h [W/(m²·K)] and ambient [°C].
    schedule : Schedule
        The load history; h and ambient default to the rod's where not given.

    Returns
    -------
    q_W_m2, h_W_m2K, ambient_rise_K : numpy.ndarray
        Per segment: the end-face flux [W/m²], the lateral convection coefficient
        [W/(m²·K)] and the ambient's rise above the rod's nominal ambient [K].
    """
    q = np.asarray(schedule.q_W_m2, float)
    h = schedule.h_for(model.rod)
    amb = schedule.ambient_for(model.rod) - model.rod.ambient_C
    return q, h, amb


def _output_times(schedule: Schedule, output_times_s) -> np.ndarray:
    """Validated output times [s] (default: t = 0 and every segment end)."""
    edges = schedule.edges_s
    if output_times_s is None:
        return edges
    out_t = np.asarray(output_times_s, float)
    if out_t.ndim != 1 or np.any(~np.isfinite(out_t)) or np.any(np.diff(out_t) < 0):
        raise InputError("must be finite and non-decreasing", "output_times_s")
    if out_t.size and (out_t[0] < -1e-9 or out_t[-1] > edges[-1] * (1 + 1e-12) + 1e-9):
        raise InputError(f"must lie within [0, {edges[-1]:g}] s", "output_times_s")
    return out_t


@dataclass(frozen=True)
class Breakpoints:
    """The instants a modal solve steps between: every segment edge and output time.

    ``times_s`` (b,) [s], sorted, from 0; ``segment`` (b − 1,): the schedule segment of
    each step (times_s[i], times_s[i + 1]]; ``dt_s`` (b − 1,): its length [s];
    ``output_times_s`` (m,) [s] as asked; ``pick`` (m,): the index in ``times_s`` of each
    output time.
    """

    times_s: np.ndarray
    segment: np.ndarray
    dt_s: np.ndarray
    output_times_s: np.ndarray
    pick: np.ndarray


def breakpoints(schedule: Schedule, output_times_s=None) -> Breakpoints:
    """The :class:`Breakpoints` of ``schedule`` with the output times asked (default:
    t = 0 and every segment end), for :func:`solve_modal` and
    :func:`arfem.fem.reduced.solve_reduced`.

    >>> from arfem.params import Schedule
    >>> b = breakpoints(Schedule([3600.0, 3600.0], [1.0, 0.0]), [0.0, 1800.0, 7200.0])
    >>> b.times_s.tolist(), b.segment.tolist(), b.pick.tolist()
    ([0.0, 1800.0, 3600.0, 7200.0], [0, 0, 1], [0, 1, 3])
    """
    edges = schedule.edges_s
    out_t = _output_times(schedule, output_times_s)
    bps = np.union1d(edges, np.clip(out_t, 0.0, edges[-1]))
    seg = np.clip(np.searchsorted(edges, bps[1:], side="left") - 1, 0, schedule.n_segments - 1)
    pick = np.searchsorted(bps, np.clip(out_t, 0.0, edges[-1]))
    return Breakpoints(bps, seg, np.diff(bps), out_t, pick)


def initial_state_K(model: HeatFEM, theta0) -> np.ndarray:
    """The initial temperature rise θ₀ [K] at every degree of freedom of ``model``.

    Parameters
    ----------
    model : HeatFEM
        The discretised rod (its ``ndofs``).
    theta0 : array_like or float or None
        Initial temperature rise [K]: None for 0 (equilibrium with ambient), a scalar
        for a uniform rise, or one finite value per degree of freedom.

    Returns
    -------
    numpy.ndarray
        (ndofs,) [K], a copy.

    Raises
    ------
    InputError
        ``theta0`` has the wrong length or a non-finite value.
    """
    if theta0 is None:
        return np.zeros(model.ndofs)
    th = np.asarray(theta0, float)
    if th.ndim == 0:
        th = np.full(model.ndofs, float(th))
    if th.shape != (model.ndofs,) or not np.all(np.isfinite(th)):
        raise InputError(f"needs {model.ndofs} finite values", "theta0")
    return th.copy()


