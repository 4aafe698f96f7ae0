"""Precision allocation over a chain of meta-action units (Zhou et al. 2020, eqs. 14-16).

Design variables are the six small errors of every unit pair that the scenario
marks free (translations [mm], rotations [mrad] as given in scenario files,
rad inside the screw algebra). For each candidate:

* the chain error screw ξ_E in the frame of the functional point
  (:func:`arfem.models.allocation.screw.compose_adjoint`, or the paper's form
  :func:`~arfem.models.allocation.screw.compose_paper`), eqs. 6-8;
* its pitch h_E [mm/rad] and the displacement bound m_E [mm] (eqs. 10-13);
* each unit's accuracy x_i [mm] = |v_i| + r·|ω_i| of its own error screw mapped to
  the functional point (what that unit alone moves a point within the working
  radius r), and the cost Σ_i a·e^{−x_i/b} (eq. 14) over the units that are
  designed (a spindle's thermal growth is fixed and costs nothing here).

NSGA-II (pymoo) minimises (|h_E|, cost) subject to m_E ≤ ΔE (eq. 16).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arfem.models.allocation import screw

__all__ = ["COMPONENTS", "TWIST_INDEX", "Unit", "Chain", "Settings", "Evaluation",
           "AllocationResult", "cost_model", "unit_twists", "evaluate", "allocate",
           "pick_index"]

#: Error components of an MU pair, in scenario order.
COMPONENTS = ("dx", "dy", "dz", "dalpha", "dbeta", "dgamma")
#: Position of each component in a twist [ω; v].
TWIST_INDEX = {"dalpha": 0, "dbeta": 1, "dgamma": 2, "dx": 3, "dy": 4, "dz": 5}
ROTATIONS = ("dalpha", "dbeta", "dgamma")
#: scenario unit of each component and the factor to the internal unit (mm, rad)
COMPONENT_UNIT = {c: ("mrad" if c in ROTATIONS else "mm") for c in COMPONENTS}
_TO_INTERNAL = {"mm": 1.0, "mrad": 1e-3}
_BIG_PITCH = 1e12


def cost_model(x_mm, a: float = 1.2, b_mm: float = 1.6):
    """Relative manufacturing cost of holding accuracy ``x_mm``: a·e^{−x/b} (paper eq. 14).

    Parameters
    ----------
    x_mm : float or array_like
        Accuracy (allowed error) of a unit [mm]; tighter (smaller) costs more.
    a : float
        Cost scale [-] (paper: 1.2).
    b_mm : float
        Accuracy scale [mm] (paper: 1.6).

    Returns
    -------
    float or ndarray
        Cost [-] (relative units).

    Examples
    --------
    >>> round(float(cost_model(0.0)), 6), round(float(cost_model(0.005)), 6)
    (1.2, 1.196256)
    """
    return a * np.exp(-np.asarray(x_mm, float) / b_mm)


@dataclass(frozen=True)
class Unit:
    """One meta-action unit of the chain (validated by the scenario reader).

    Attributes
    ----------
    name : str
    motion : str, ``"translation"`` or ``"rotation"`` (descriptive; the nominal
        joint position is already folded into ``pose``)
    pose : (4, 4) ndarray, nominal pose in the frame of the previous unit [mm]
    free : tuple of str, components that are design variables
    bounds : dict, component -> (low, high) in the scenario unit (mm or mrad)
    fixed : dict, component -> value in the scenario unit, for components not free
    costed : bool, whether its accuracy enters the cost (False for a spindle)
    """

    name: str
    motion: str
    pose: np.ndarray
    free: tuple = COMPONENTS
    bounds: dict = field(default_factory=dict)
    fixed: dict = field(default_factory=dict)
    costed: bool = True


@dataclass(frozen=True)
class Chain:
    """Units in chain order and the functional point's pose in the last unit's frame."""

    units: tuple
    tool: np.ndarray

    @property
    def names(self) -> list:
        return [u.name for u in self.units]

    @property
    def variables(self) -> list:
        """(unit index, component) of each design variable, in order."""
        return [(i, c) for i, u in enumerate(self.units) for c in COMPONENTS if c in u.free]

    def variable_names(self) -> list:
        return [f"{self.units[i].name}_{c}_{COMPONENT_UNIT[c]}" for i, c in self.variables]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = [self.units[i].bounds[c][0] for i, c in self.variables]
        hi = [self.units[i].bounds[c][1] for i, c in self.variables]
        return np.array(lo, float), np.array(hi, float)

    def adjoints(self) -> np.ndarray:
        return screw.chain_adjoints([u.pose for u in self.units], self.tool)


@dataclass(frozen=True)
class Settings:
    """Tolerance, cost constants, formula and NSGA-II settings of an allocation."""

    delta_E_mm: float = 0.005
    working_radius_mm: float = 0.0
    a: float = 1.2
    b_mm: float = 1.6
    formula: str = "screw"          # "screw" | "paper"
    constraint: str = "composed"    # "composed" | "worst_case"
    pop_size: int = 16
    n_gen: int = 30
    crossover_prob: float = 0.9
    mutation_prob: float = 0.1      # per variable
    eta_crossover: float = 20.0
    eta_mutation: float = 20.0
    seed: int = 1
    pick: str = "compromise"        # "compromise" | "min_cost" | "min_pitch"


def unit_twists(chain: Chain, X) -> np.ndarray:
    """Error twist of every unit for a batch of design vectors.

    Parameters
    ----------
    chain : Chain
    X : array_like, shape (n_candidates, n_variables)
        Free components in scenario units: translations [mm], rotations [mrad].

    Returns
    -------
    ndarray, shape (n_candidates, n_units, 6)
        [ω; v] per unit in its own frame ([rad], [mm]).
    """
    X = np.atleast_2d(np.asarray(X, float))
    xis = np.zeros((X.shape[0], len(chain.units), 6))
    for i, u in enumerate(chain.units):
        for c, val in u.fixed.items():
            xis[:, i, TWIST_INDEX[c]] = val * _TO_INTERNAL[COMPONENT_UNIT[c]]
    for k, (i, c) in enumerate(chain.variables):
        xis[:, i, TWIST_INDEX[c]] = X[:, k] * _TO_INTERNAL[COMPONENT_UNIT[c]]
    return xis


@dataclass(frozen=True)
class Evaluation:
    """Everything computed for a batch of candidates (one row per candidate)."""

    xi_E: np.ndarray           # (n, 6) chain error screw [rad, mm]
    h_E_mm_per_rad: np.ndarray
    m_E_mm: np.ndarray
    m_E_worst_case_mm: np.ndarray
    screw_magnitude: np.ndarray   # |ω_E| [rad] (|v_E| [mm] if ω_E = 0)
    axial_translation_mm: np.ndarray
    unit_accuracy_mm: np.ndarray  # (n, n_units)
    cost: np.ndarray


def evaluate(chain: Chain, X, settings: Settings, formula: str | None = None) -> Evaluation:
    """Chain error screw, pitch, m_E, unit accuracies and cost for candidates ``X``.

    Parameters
    ----------
    chain : Chain
    X : array_like, shape (n, n_variables)
        Free components in scenario units: translations [mm], rotations [mrad].
    settings : Settings
    formula : {"screw", "paper"}, optional
        Overrides ``settings.formula``. ``"screw"``: ξ_E = Σ Ad_{H_i⁻¹} ξ_i;
        ``"paper"``: product of the raw pair error matrices, no nominal poses.

    Returns
    -------
    Evaluation
    """
    formula = formula or settings.formula
    r = settings.working_radius_mm
    xis = unit_twists(chain, X)
    if formula == "screw":
        A = chain.adjoints()
        eta = np.einsum("nij,knj->kni", A, xis)            # each unit's screw at the tool
        xi_E = eta.sum(axis=1)
        # worst case over error signs: Σ_j |ξ_j| (|A_v[:, j]| + r |A_ω[:, j]|)
        wcol = np.linalg.norm(A[:, 3:, :], axis=1) + r * np.linalg.norm(A[:, :3, :], axis=1)
    elif formula == "paper":
        eta = xis
        xi_E = screw.compose_paper(xis)
        wcol = np.broadcast_to(np.array([r, r, r, 1.0, 1.0, 1.0]), xis.shape[1:])
    else:
        raise ValueError(f"unknown formula {formula!r}")
    acc = screw.point_displacement_bound(eta, r)
    worst = np.einsum("knj,nj->k", np.abs(xis), wcol)
    costed = np.array([u.costed for u in chain.units], bool)
    cost = cost_model(acc[:, costed], settings.a, settings.b_mm).sum(axis=1)
    return Evaluation(xi_E, screw.pitch(xi_E), screw.point_displacement_bound(xi_E, r), worst,
                      screw.screw_magnitude(xi_E), screw.axial_translation(xi_E), acc, cost)


def _objectives(ev: Evaluation, settings: Settings):
    h = np.abs(ev.h_E_mm_per_rad)
    h = np.where(np.isfinite(h), h, _BIG_PITCH)
    m = ev.m_E_worst_case_mm if settings.constraint == "worst_case" else ev.m_E_mm
    return np.column_stack([h, ev.cost]), (m / settings.delta_E_mm - 1.0)[:, None]


def pick_index(F, rule: str = "compromise") -> int:
    """Index of the front member to report.

    ``"compromise"``: least Euclidean distance to the ideal point after scaling
    each objective to [0, 1] over the front; ``"min_cost"`` / ``"min_pitch"``:
    the extreme ends.

    Examples
    --------
    >>> pick_index([[0.0, 1.0], [0.4, 0.4], [1.0, 0.0]])
    1
    """
    F = np.asarray(F, float)
    if rule == "min_pitch":
        return int(np.argmin(F[:, 0]))
    if rule == "min_cost":
        return int(np.argmin(F[:, 1]))
    span = np.ptp(F, axis=0)
    span = np.where(span > 0, span, 1.0)
    z = (F - F.min(axis=0)) / span
    return int(np.argmin(np.linalg.norm(z, axis=1)))


@dataclass(frozen=True)
class AllocationResult:
    """Pareto front of an allocation and the member picked for reporting.

    ``front_X`` rows are sorted by |h_E|; ``feasible`` is False when no candidate
    met m_E ≤ ΔE, in which case the front holds the least-violating candidate.
    """

    chain: Chain
    settings: Settings
    front_X: np.ndarray
    front: Evaluation
    chosen: int
    feasible: bool
    n_evaluations: int


def _problem(chain: Chain, settings: Settings):
    from pymoo.core.problem import Problem

    lo, hi = chain.bounds()

    class _Alloc(Problem):
        def __init__(self):
            super().__init__(n_var=lo.size, n_obj=2, n_ieq_constr=1, xl=lo, xu=hi)

        def _evaluate(self, x, out, *args, **kwargs):
            F, G = _objectives(evaluate(chain, x, settings), settings)
            out["F"], out["G"] = F, G

    return _Alloc()


def allocate(chain: Chain, settings: Settings) -> AllocationResult:
    """Solve min(|h_E|, cost) s.t. m_E ≤ ΔE with pymoo's NSGA-II (paper eq. 16), seeded.

    SBX crossover (probability ``crossover_prob``, index ``eta_crossover``) and
    polynomial mutation (per-variable probability ``mutation_prob``, index
    ``eta_mutation``); duplicates eliminated. The same chain, settings and seed
    give the identical front.

    Returns
    -------
    AllocationResult
    """
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.operators.crossover.sbx import SBX
    from pymoo.operators.mutation.pm import PM
    from pymoo.optimize import minimize

    if not chain.variables:
        raise ValueError("the chain has no design variables")
    algo = NSGA2(pop_size=settings.pop_size,
                 crossover=SBX(prob=settings.crossover_prob, eta=settings.eta_crossover),
                 mutation=PM(prob=1.0, prob_var=settings.mutation_prob, eta=settings.eta_mutation),
                 eliminate_duplicates=True)
    res = minimize(_problem(chain, settings), algo, ("n_gen", settings.n_gen),
                   seed=int(settings.seed), verbose=False, save_history=False)
    if res.X is not None:
        X = np.atleast_2d(res.X)
        feasible = True
    else:  # nothing feasible: keep the least-violating candidate
        pop = res.pop
        cv = pop.get("CV").ravel()
        X = np.atleast_2d(pop.get("X")[int(np.argmin(cv))])
        feasible = False
    ev = evaluate(chain, X, settings)
    F, _ = _objectives(ev, settings)
    order = np.lexsort((F[:, 1], F[:, 0]))
    X = X[order]
    ev = evaluate(chain, X, settings)
    F, _ = _objectives(ev, settings)
    return AllocationResult(chain, settings, X, ev, pick_index(F, settings.pick), feasible,
                            int(res.algorithm.evaluator.n_eval))
