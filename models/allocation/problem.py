"""Precision allocation over a chain of meta-action units (after Zhou et al. 2020).

Two formulations, chosen by ``Settings.formula``:

``"screw"`` (default, the corrected model)
    The design variables are **tolerances** t_k >= 0 of the six error components of
    every unit (translations [mm], rotations [mrad] in scenario files; mm and rad
    inside). Each unit's error twist is mapped to the functional point (tool relative
    to workpiece, base-aligned axes) by a 6×6 map per pose of the travel: the adjoint
    Ad_{H⁻¹} of the screw chain (Zhou et al. eqs. 6-8 done with the nominal geometry),
    through a transmission where the chain has one (rack and pinion: Δθ = Δx / r).
    The stack-up m_E [mm] is the worst case over every sign of every error and every
    pose (exact zonotope maximum, :mod:`~arfem.models.allocation.tolerance`), or the
    RSS stack; a spindle's thermal growth, if the chain has one, adds along the spindle
    axis at every instant of its duty cycle. NSGA-II minimises (cost, m_E) subject to
    m_E <= ΔE, the cost a cost–tolerance law from the literature (:func:`tolerance_cost`).

``"paper_literal"``
    The equations as printed (:mod:`~arfem.models.allocation.paper`): minimise
    f_1 = Σ ω_j·v_j / |Σ ω_j| [mm] and Σ a·exp(−h_j / b), h_j = ω_j·v_j / |ω_j|,
    subject to |Σ ω_j| <= ΔE (eqs. 12-16). No geometry.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from arfem.models.allocation import paper, tolerance

__all__ = ["COMPONENTS", "TWIST_INDEX", "Unit", "Chain", "Thermal", "Settings", "Evaluation",
           "AllocationResult", "tolerance_cost", "unit_values", "evaluate_design", "allocate",
           "pick_index", "knee_index", "work_estimate", "MAX_EVALUATIONS", "FORMULAS",
           "CONSTRAINTS", "PICKS", "COST_MODELS", "with_settings",
           "worst_case_over_cycle"]

#: Error components of an MU pair, in scenario order (also the paper's x_1..x_6 order).
COMPONENTS = ("dx", "dy", "dz", "dalpha", "dbeta", "dgamma")
#: Position of each component in a twist [ω; v].
TWIST_INDEX = {"dalpha": 0, "dbeta": 1, "dgamma": 2, "dx": 3, "dy": 4, "dz": 5}
ROTATIONS = ("dalpha", "dbeta", "dgamma")
#: scenario unit of each component and the factor to the internal unit (mm, rad)
COMPONENT_UNIT = {c: ("mrad" if c in ROTATIONS else "mm") for c in COMPONENTS}
_TO_INTERNAL = np.array([1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3])
FORMULAS = ("screw", "paper_literal")
CONSTRAINTS = ("worst_case", "rss", "yield")
PICKS = ("knee", "min_cost", "min_stack", "compromise")
COST_MODELS = ("reciprocal_power", "exponential")
#: candidate evaluations (pop_size × n_gen) beyond which :func:`allocate` refuses unless
#: told otherwise: about 2 minutes on a shared 2-core machine
MAX_EVALUATIONS = 400_000


def tolerance_cost(t_um, model: str = "reciprocal_power", A: float = 0.0, B: float = 1.0,
                   k: float = 1.0, b_um: float = 1.0):
    """Relative cost of holding a tolerance ``t_um`` [µm] (cost–tolerance laws).

    ``"reciprocal_power"``: C = A + B / t^k (k = 1: the reciprocal law; k = 2: Spotts
    1973; general k: Sutherland & Roth 1975; all compared by Chase & Greenwood 1988).
    ``"exponential"``: C = A + B·exp(−t / b) (Speckhart 1972; Wilde & Prentice 1975,
    whose form Zhou et al. 2020 use in eq. 14).

    Parameters
    ----------
    t_um : float or array_like
        Tolerance [µm] (> 0).
    model : {"reciprocal_power", "exponential"}
    A, B : float
        Fixed cost and scale [relative units].
    k : float
        Exponent of the reciprocal-power law [-].
    b_um : float
        Decay length of the exponential law [µm].

    Returns
    -------
    float or ndarray
        Cost [relative units].

    Examples
    --------
    >>> float(tolerance_cost(2.0)), round(float(tolerance_cost(2.0, "exponential", b_um=2.0)), 6)
    (0.5, 0.367879)
    """
    t = np.asarray(t_um, float)
    if model == "reciprocal_power":
        return A + B / t ** k
    if model == "exponential":
        return A + B * np.exp(-t / b_um)
    raise ValueError(f"unknown cost model {model!r}")


@dataclass(frozen=True)
class Unit:
    """One meta-action unit: which components are designed, their bounds and fixed values.

    Attributes
    ----------
    name : str
    motion : str, ``"translation"``, ``"rotation"`` (descriptive)
    free : tuple of str, components that are design variables
    bounds : dict, component -> (low, high) in the scenario unit (mm or mrad)
    fixed : dict, component -> value in the scenario unit, for components not free
    costed : bool, whether its free components enter the cost
    branch : str, ``"tool"``, ``"workpiece"`` or ``"drive"`` (through a transmission)
    """

    name: str
    motion: str
    free: tuple = COMPONENTS
    bounds: dict = field(default_factory=dict)
    fixed: dict = field(default_factory=dict)
    costed: bool = True
    branch: str = "tool"


@dataclass(frozen=True)
class Thermal:
    """A spindle's axial growth over its duty cycle, as it enters the budget.

    Attributes
    ----------
    times_s : (m,) instants of the cycle [s]
    growth_mm : (m,) growth (or compensation residual) along the spindle axis [mm]
    direction : (P, 3) unit vector of the spindle axis at the functional point, per pose
    info : dict, how the series was made (model, noise, peaks), for the report
    """

    times_s: np.ndarray
    growth_mm: np.ndarray
    direction: np.ndarray
    info: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Chain:
    """Units, and the 6×6 map of each unit's error twist to the functional point per pose.

    ``maps[p, i]`` maps unit i's error twist [ω; v] (its own frame, rad and mm) to the
    twist of the functional point (tool relative to workpiece) in base-aligned axes at
    pose p of the travel. ``pose_labels[p]`` names the pose.
    """

    units: tuple
    maps: np.ndarray
    pose_labels: tuple = ("nominal",)
    thermal: Thermal | None = None
    geometry: dict = field(default_factory=dict)

    @property
    def names(self) -> list:
        return [u.name for u in self.units]

    @property
    def variables(self) -> list:
        """(unit index, component) of each design variable, in order."""
        return [(i, c) for i, u in enumerate(self.units) for c in COMPONENTS if c in u.free]

    def variable_names(self) -> list:
        return [f"{self.units[i].name}_{c}_{COMPONENT_UNIT[c]}" for i, c in self.variables]

    def component_names(self) -> list:
        """Every error component of the chain, unit after unit, in COMPONENTS order."""
        return [f"{u.name}.{c}" for u in self.units for c in COMPONENTS]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = [self.units[i].bounds[c][0] for i, c in self.variables]
        hi = [self.units[i].bounds[c][1] for i, c in self.variables]
        return np.array(lo, float), np.array(hi, float)

    def sensitivities(self) -> tuple[np.ndarray, np.ndarray]:
        """Jv, Jw of shape (P, 6·n_units, 3): displacement [mm] and rotation [rad] of the
        functional point per unit error (mm or rad) of every component, per pose."""
        cols = [TWIST_INDEX[c] for c in COMPONENTS]
        M = self.maps[:, :, :, cols]                      # (P, n, 6, 6) columns in COMPONENTS order
        P, n = M.shape[:2]
        Jw = M[:, :, :3, :].transpose(0, 1, 3, 2).reshape(P, 6 * n, 3)
        Jv = M[:, :, 3:, :].transpose(0, 1, 3, 2).reshape(P, 6 * n, 3)
        return Jv, Jw


@dataclass(frozen=True)
class Settings:
    """Tolerance, cost model, formula and optimiser settings of an allocation."""

    delta_E_mm: float = 0.005
    working_radius_mm: float = 0.0
    formula: str = "screw"              # "screw" | "paper_literal"
    constraint: str = "worst_case"      # "worst_case" | "rss" | "yield"   (screw formula)
    target_yield: float = 0.9973        # constraint "yield": P(m_E <= ΔE) >= this
    yield_dist: str = "normal"          # "normal" (t = 3σ) | "uniform"
    yield_draws: int = 10_000           # common random numbers, seeded by ``seed``
    cost_model: str = "reciprocal_power"
    cost_A: float = 0.0
    cost_B: float = 1.0
    cost_k: float = 1.0
    cost_b_um: float = 1.0
    angular_length_mm: float = 100.0    # a rotation tolerance θ costs like a length θ·L
    a: float = 1.2                      # paper eq. 14 (paper_literal)
    b_mm: float = 1.6
    pop_size: int = 200
    n_gen: int = 1000
    converge: bool = True               # stop early by pymoo's default MO termination
    crossover_prob: float = 0.9
    mutation_prob: float = 0.1          # per variable
    eta_crossover: float = 20.0
    eta_mutation: float = 20.0
    seed: int = 1
    pick: str = "knee"


def unit_values(chain: Chain, X) -> np.ndarray:
    """Every component's value for a batch of design vectors, in scenario units.

    Parameters
    ----------
    chain : Chain
    X : array_like, shape (n, n_variables)
        Free components in scenario units: translations [mm], rotations [mrad].

    Returns
    -------
    ndarray, shape (n, 6·n_units)
        Unit after unit, COMPONENTS order ([mm] ×3, [mrad] ×3); fixed ones filled in.
    """
    X = np.atleast_2d(np.asarray(X, float))
    V = np.zeros((X.shape[0], 6 * len(chain.units)))
    for i, u in enumerate(chain.units):
        for c, val in u.fixed.items():
            V[:, 6 * i + COMPONENTS.index(c)] = val
    for k, (i, c) in enumerate(chain.variables):
        V[:, 6 * i + COMPONENTS.index(c)] = X[:, k]
    return V


@dataclass(frozen=True)
class Evaluation:
    """Everything computed for a batch of candidates (one row per candidate).

    ``stack_mm`` is the constrained quantity (worst case or RSS, with the thermal term);
    ``unit_stack_mm`` each unit's own worst case at the functional point (screw), or
    h_j (paper_literal). Fields of the other formula are None.
    """

    formula: str
    cost: np.ndarray
    stack_mm: np.ndarray
    unit_stack_mm: np.ndarray
    worst_case_mm: np.ndarray | None = None
    rss_mm: np.ndarray | None = None
    kinematic_worst_case_mm: np.ndarray | None = None
    yield_: np.ndarray | None = None
    f1_mm: np.ndarray | None = None
    m_E: np.ndarray | None = None


def _costs(chain: Chain, V, st: Settings) -> np.ndarray:
    """Cost of every free, costed component [relative units], (n, K) with 0 elsewhere."""
    K = V.shape[1]
    mask = np.zeros(K, bool)
    for i, c in chain.variables:
        if chain.units[i].costed:
            mask[6 * i + COMPONENTS.index(c)] = True
    rot = np.tile(np.array([c in ROTATIONS for c in COMPONENTS]), len(chain.units))
    t_um = np.where(rot, V * 1e-3 * st.angular_length_mm * 1e3, V * 1e3)
    c = np.zeros_like(V)
    c[:, mask] = tolerance_cost(t_um[:, mask], st.cost_model, st.cost_A, st.cost_B, st.cost_k,
                                st.cost_b_um)
    return c


class _Kernel:
    """Precomputed sensitivities and zonotope sign vectors of a chain (per pose)."""

    def __init__(self, chain: Chain):
        self.Jv, self.Jw = chain.sensitivities()
        self.Sv = [tolerance.vertex_signs(J) for J in self.Jv]
        self.Sw = [tolerance.vertex_signs(J) for J in self.Jw]
        n = len(chain.units)
        self.unit_S = [[tolerance.vertex_signs(J[6 * i:6 * i + 6]) for i in range(n)]
                       for J in self.Jv]


_KERNELS: dict = {}


def _kernel(chain: Chain) -> _Kernel:
    key = id(chain)
    k = _KERNELS.get(key)
    if k is None or k.chain is not chain:
        k = _Kernel(chain)
        k.chain = chain
        _KERNELS.clear()
        _KERNELS[key] = k
    return k


def _yield_quantile(chain: Chain, T, st: Settings):
    """Monte Carlo with common random numbers (same draws for every candidate, so the
    optimiser compares designs, not noise): the ``target_yield`` quantile of the worst
    pose's |δp| [mm] (<= ΔE exactly when the yield >= target) and the yield itself."""
    kern = _kernel(chain)
    key = (st.yield_dist, st.yield_draws, st.seed)
    if getattr(kern, "mc_key", None) != key:
        rng = np.random.default_rng(st.seed)
        K = T.shape[1]
        if st.yield_dist == "uniform":
            U = rng.uniform(-1.0, 1.0, (st.yield_draws, K))
        else:
            U = rng.standard_normal((st.yield_draws, K)) / 3.0
        kern.mc_key, kern.mc_U = key, U
    U = kern.mc_U
    th = chain.thermal
    Js = kern.Jv
    offs = [np.zeros((len(Js), 3))]
    if th is not None:
        offs = [np.min(th.growth_mm) * th.direction, np.max(th.growth_mm) * th.direction]
    active = np.flatnonzero(np.any(np.abs(np.asarray(Js)) > 0, axis=(0, 2)))
    M = np.asarray(Js)[:, active, :].transpose(1, 0, 2).reshape(len(active), -1)   # (Ka, P*3)
    Ua = U[:, active].astype(np.float32)
    P = len(Js)
    q = np.empty(T.shape[0])
    y = np.empty(T.shape[0])
    step = 25                                   # candidates per block: bounds the memory
    for a in range(0, T.shape[0], step):
        Tb = T[a:a + step, active]
        B = (Tb[:, :, None] * M[None]).transpose(1, 0, 2).reshape(len(active), -1)
        D = (Ua @ B.astype(np.float32)).reshape(len(U), len(Tb), P, 3)
        w = None
        for o in offs:
            n = np.sqrt(np.sum((D + o[None, None].astype(np.float32)) ** 2, axis=3)).max(axis=2)
            w = n if w is None else np.maximum(w, n)
        q[a:a + step] = np.quantile(w, st.target_yield, axis=0)
        y[a:a + step] = np.mean(w <= st.delta_E_mm, axis=0)
    return q, y


def _worst_with_offset(T, J, S, offsets) -> np.ndarray:
    """max over vertices s (both signs) and offsets d of |x_s + d| [mm]; T (n, K)."""
    X = np.stack([T @ (S * J[:, j]).T for j in range(3)], axis=-1)     # (n, M, 3)
    best = np.zeros(T.shape[0])
    for d in offsets:
        for sg in (1.0, -1.0):
            best = np.maximum(best, np.linalg.norm(sg * X + d, axis=2).max(axis=1))
    return best


def evaluate_design(chain: Chain, X, settings: Settings) -> Evaluation:
    """Stack-up, per-unit accuracy and cost of candidates ``X`` (see the module docstring).

    Parameters
    ----------
    chain : Chain
    X : array_like, shape (n, n_variables)
        Free components in scenario units (translations [mm], rotations [mrad]): the
        tolerances (``screw``) or the paper's x_i (``paper_literal``).
    settings : Settings

    Returns
    -------
    Evaluation
    """
    st = settings
    V = unit_values(chain, X)
    if st.formula == "paper_literal":
        o = paper.objectives(V, st.a, st.b_mm)
        costed = np.array([u.costed for u in chain.units], bool)
        cost = np.sum(st.a * np.exp(-o["h_mm"][:, costed] / st.b_mm), axis=1)
        return Evaluation("paper_literal", cost, o["m_E"], o["h_mm"], f1_mm=o["f1_mm"],
                          m_E=o["m_E"])
    if st.formula != "screw":
        raise ValueError(f"unknown formula {st.formula!r}")
    T = V * np.tile(_TO_INTERNAL, len(chain.units))
    kern = _kernel(chain)
    r = st.working_radius_mm
    n = T.shape[0]
    wc_kin = np.zeros(n)
    wc = np.zeros(n)
    rs = np.zeros(n)
    unit = np.zeros((n, len(chain.units)))
    th = chain.thermal
    for p in range(len(kern.Jv)):
        Jv, Jw = kern.Jv[p], kern.Jw[p]
        rot_wc = tolerance.worst_case(T, Jw, kern.Sw[p]) if r > 0 else 0.0
        kin = tolerance.worst_case(T, Jv, kern.Sv[p]) + r * rot_wc
        wc_kin = np.maximum(wc_kin, kin)
        if th is None:
            full = kin
            dmax = 0.0
        else:
            # |x + d(t) a| is convex in d: its maximum over the cycle is at min d or max d
            a = th.direction[p]
            offs = [np.min(th.growth_mm) * a, np.max(th.growth_mm) * a]
            full = _worst_with_offset(T, Jv, kern.Sv[p], offs) + r * rot_wc
            dmax = float(np.max(np.abs(th.growth_mm)))
        wc = np.maximum(wc, full)
        rs = np.maximum(rs, tolerance.rss(T, Jv) + r * tolerance.rss(T, Jw) + dmax)
        for i in range(len(chain.units)):
            sl = slice(6 * i, 6 * i + 6)
            unit[:, i] = np.maximum(unit[:, i], tolerance.worst_case(T[:, sl], Jv[sl],
                                                                     kern.unit_S[p][i]))
    cost = _costs(chain, V, st).sum(axis=1)
    yl = None
    if st.constraint == "yield":
        stack, yl = _yield_quantile(chain, T, st)
    else:
        stack = wc if st.constraint == "worst_case" else rs
    return Evaluation("screw", cost, stack, unit, worst_case_mm=wc, rss_mm=rs,
                      kinematic_worst_case_mm=wc_kin, yield_=yl)


def worst_case_over_cycle(chain: Chain, X) -> np.ndarray:
    """Worst-case stack [mm] of one design at every instant of the thermal series.

    Parameters
    ----------
    chain : Chain
        With a :class:`Thermal` term.
    X : array_like, shape (1, n_variables)
        Tolerances in scenario units ([mm], [mrad]).

    Returns
    -------
    ndarray, shape (m,)
        max over poses and error signs of |δp_kinematic + d(t)·a| [mm] (plus r·worst |ω|).
    """
    th = chain.thermal
    T = unit_values(chain, X)[:1] * np.tile(_TO_INTERNAL, len(chain.units))
    kern = _kernel(chain)
    out = np.zeros(len(th.times_s))
    for p in range(len(kern.Jv)):
        S, J = kern.Sv[p], kern.Jv[p]
        V = np.stack([(T @ (S * J[:, j]).T)[0] for j in range(3)], axis=-1)      # (M, 3)
        V = np.concatenate([V, -V])
        D = th.growth_mm[:, None] * th.direction[p][None, :]                     # (m, 3)
        w = np.sqrt(np.max(np.sum(V ** 2, 1)[None, :] + 2 * D @ V.T
                           + np.sum(D ** 2, 1)[:, None], axis=1))
        out = np.maximum(out, w)
    return out


def _objectives(ev: Evaluation, settings: Settings):
    G = (ev.stack_mm / settings.delta_E_mm - 1.0)[:, None]
    if ev.formula == "paper_literal":
        return np.column_stack([ev.f1_mm, ev.cost]), G
    return np.column_stack([ev.cost, ev.stack_mm]), G


def knee_index(F) -> int:
    """Knee of a 2-objective front: the member farthest from the line through its two
    extremes, after scaling both objectives to [0, 1] (Das 1999, "On characterizing the
    'knee' of the Pareto curve", Struct. Optim. 18:107).

    Examples
    --------
    >>> knee_index([[0.0, 1.0], [0.1, 0.2], [0.5, 0.1], [1.0, 0.0]])
    1
    """
    F = np.asarray(F, float)
    if len(F) < 3:
        return 0
    span = np.ptp(F, axis=0)
    span = np.where(span > 0, span, 1.0)
    z = (F - F.min(axis=0)) / span
    a, b = z[np.argmin(z[:, 0])], z[np.argmin(z[:, 1])]
    d = b - a
    nd = np.linalg.norm(d)
    if nd == 0:
        return 0
    side = (z[:, 0] - a[0]) * d[1] - (z[:, 1] - a[1]) * d[0]
    ideal = -a[0] * d[1] + a[1] * d[0]          # the same expression at the ideal point (0, 0)
    dist = side * np.sign(ideal) / nd           # > 0 on the ideal side of the line
    return int(np.argmax(dist))


def pick_index(F, rule: str = "knee") -> int:
    """Index of the front member to report.

    ``"knee"``: :func:`knee_index`; ``"compromise"``: least distance to the ideal point
    after scaling each objective to [0, 1]; ``"min_cost"`` / ``"min_stack"``: the ends
    (objective 0 is the cost for the screw formula, f_1 for paper_literal: the rule
    names refer to the screw formula's objectives).

    Examples
    --------
    >>> pick_index([[0.0, 1.0], [0.4, 0.4], [1.0, 0.0]], "compromise")
    1
    """
    F = np.asarray(F, float)
    if rule == "min_cost":
        return int(np.argmin(F[:, 0]))
    if rule == "min_stack":
        return int(np.argmin(F[:, 1]))
    if rule == "knee":
        return knee_index(F)
    span = np.ptp(F, axis=0)
    span = np.where(span > 0, span, 1.0)
    z = (F - F.min(axis=0)) / span
    return int(np.argmin(np.linalg.norm(z, axis=1)))


@dataclass(frozen=True)
class AllocationResult:
    """Pareto front of an allocation, the picked member and how the run converged.

    ``front_X`` rows are sorted by objective 0; ``feasible`` is False when no candidate
    met the constraint (the front then holds the least-violating candidate).
    ``history`` has per generation: ``n_eval``, ``hv`` (hypervolume of the feasible
    front against ``hv_ref``, objectives scaled by it), ``n_front``.
    """

    chain: Chain
    settings: Settings
    front_X: np.ndarray
    front: Evaluation
    chosen: int
    feasible: bool
    n_evaluations: int
    n_generations: int = 0
    converged: bool = False
    history: dict = field(default_factory=dict)
    hv_ref: tuple = ()


def work_estimate(settings: Settings) -> int:
    """Candidate evaluations an allocation will do at most: pop_size × n_gen.

    Examples
    --------
    >>> work_estimate(Settings(pop_size=200, n_gen=1000))
    200000
    """
    return int(settings.pop_size) * int(settings.n_gen)


def _hv_reference(chain: Chain, st: Settings) -> np.ndarray:
    """A fixed hypervolume reference point: the worst value each objective can take
    on a feasible candidate (cost at the lower bounds, resp. the constraint ΔE)."""
    lo, hi = chain.bounds()
    if st.formula == "paper_literal":
        n = sum(u.costed for u in chain.units)
        return np.array([float(np.sqrt(3.0) * hi.max()), st.a * n])
    c = evaluate_design(chain, lo[None], st).cost[0]
    return np.array([float(c), st.delta_E_mm])


def _loosen_idle(chain: Chain, X, hi) -> np.ndarray:
    """Set every free tolerance that moves the functional point at no pose (zero gain in
    translation and rotation) to its upper bound: the stack cannot change, the cost can
    only fall, so the member stays on the front. NSGA-II leaves such variables wherever
    its tolerance stopped it."""
    Jv, Jw = chain.sensitivities()
    gain = np.linalg.norm(Jv, axis=2).max(axis=0) + np.linalg.norm(Jw, axis=2).max(axis=0)
    X = np.array(X, float)
    for k, (i, c) in enumerate(chain.variables):
        if gain[6 * i + COMPONENTS.index(c)] == 0.0:
            X[:, k] = hi[k]
    return X


def _refuse_oversize(chain: Chain, st: Settings, max_evaluations: int | None) -> None:
    """A ValueError before any work when the chain has nothing to allocate or the run
    would take more than ``max_evaluations`` evaluations (None: no limit)."""
    if not chain.variables:
        raise ValueError("the chain has no design variables")
    work = work_estimate(st)
    if max_evaluations is not None and work > max_evaluations:
        raise ValueError(f"pop_size × n_gen = {st.pop_size} × {st.n_gen} = {work:,} evaluations "
                         f"exceeds the limit of {max_evaluations:,} (about 2 min here); lower "
                         f"them or lift the limit (--no-work-limit)")


def _nsga2(st: Settings):
    """pymoo's NSGA-II with the settings' SBX crossover and polynomial mutation, and its
    termination: pymoo's default criteria or ``n_gen`` with ``st.converge``, else
    exactly ``n_gen`` generations."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.operators.crossover.sbx import SBX
    from pymoo.operators.mutation.pm import PM
    from pymoo.termination.default import DefaultMultiObjectiveTermination
    from pymoo.termination.max_gen import MaximumGenerationTermination
    algo = NSGA2(pop_size=st.pop_size,
                 crossover=SBX(prob=st.crossover_prob, eta=st.eta_crossover),
                 mutation=PM(prob=1.0, prob_var=st.mutation_prob, eta=st.eta_mutation),
                 eliminate_duplicates=True)
    term = (DefaultMultiObjectiveTermination(n_max_gen=st.n_gen,
                                             n_max_evals=st.pop_size * (st.n_gen + 1))
            if st.converge
            else MaximumGenerationTermination(st.n_gen))
    return algo, term


def _sorted_front(chain: Chain, st: Settings, res, hi: np.ndarray):
    """The final front of a pymoo result (or, if nothing is feasible, the least-violating
    member), idle tolerances loosened to ``hi`` (screw formula), sorted by cost then
    stack: (X, its evaluation, its objectives, feasible)."""
    if res.X is not None:
        X = np.atleast_2d(res.X)
        feasible = True
    else:  # nothing feasible: keep the least-violating candidate
        pop = res.pop
        X = np.atleast_2d(pop.get("X")[int(np.argmin(pop.get("CV").ravel()))])
        feasible = False
    if st.formula == "screw":
        X = _loosen_idle(chain, X, hi)
    F, _ = _objectives(evaluate_design(chain, X, st), st)
    X = X[np.lexsort((F[:, 1], F[:, 0]))]
    ev = evaluate_design(chain, X, st)
    F, _ = _objectives(ev, st)
    return X, ev, F, feasible


def allocate(chain: Chain, settings: Settings, max_evaluations: int | None = MAX_EVALUATIONS,
             record_history: bool = True) -> AllocationResult:
    """Solve the allocation with pymoo's NSGA-II, seeded (same inputs, same front).

    SBX crossover and polynomial mutation (per-variable probability), duplicates
    eliminated. Tolerances with no effect at any pose are set to their upper bound in
    the returned front (same stack, lower cost). With ``settings.converge`` the run stops by pymoo's default
    multi-objective termination (design-space, constraint and objective-space
    tolerances over a sliding window) or at ``n_gen``, whichever is first.

    Parameters
    ----------
    chain : Chain
    settings : Settings
    max_evaluations : int or None
        Refuse (ValueError) before starting when pop_size × n_gen exceeds it; None lifts it.
    record_history : bool
        Record the hypervolume of every generation (cheap in 2-D).

    Returns
    -------
    AllocationResult
    """
    from pymoo.core.callback import Callback
    from pymoo.core.problem import Problem
    from pymoo.indicators.hv import HV
    from pymoo.optimize import minimize
    from threadpoolctl import threadpool_limits

    st = settings
    _refuse_oversize(chain, st, max_evaluations)
    lo, hi = chain.bounds()
    ref = _hv_reference(chain, st)
    hv = HV(ref_point=np.ones(2))
    hist = {"n_gen": [], "n_eval": [], "hv": [], "n_front": []}

    class _Alloc(Problem):
        def __init__(self):
            super().__init__(n_var=lo.size, n_obj=2, n_ieq_constr=1, xl=lo, xu=hi)

        def _evaluate(self, x, out, *args, **kwargs):
            F, G = _objectives(evaluate_design(chain, x, st), st)
            out["F"], out["G"] = F, G

    class _Record(Callback):
        def notify(self, algorithm):
            opt = algorithm.opt
            F = opt.get("F")
            ok = opt.get("CV").ravel() <= 0
            val = float(hv(F[ok] / ref)) if ok.any() else 0.0
            hist["n_gen"].append(int(algorithm.n_gen))
            hist["n_eval"].append(int(algorithm.evaluator.n_eval))
            hist["hv"].append(val)
            hist["n_front"].append(int(ok.sum()))

    algo, term = _nsga2(st)
    with threadpool_limits(1):          # small matrices: BLAS threads only contend
        res = minimize(_Alloc(), algo, term, seed=int(st.seed), verbose=False,
                       save_history=False, callback=_Record() if record_history else None)
        n_gen = len(hist["hv"]) if record_history else int(res.algorithm.n_gen) - 1
        X, ev, F, feasible = _sorted_front(chain, st, res, hi)
    return AllocationResult(chain, st, X, ev, pick_index(F, st.pick), feasible,
                            int(res.algorithm.evaluator.n_eval), n_gen,
                            bool(st.converge and n_gen < st.n_gen),
                            {k: np.array(v) for k, v in hist.items()}, tuple(ref.tolist()))


def with_settings(settings: Settings, **changes) -> Settings:
    """A copy of ``settings`` with ``changes``.

    Examples
    --------
    >>> with_settings(Settings(), seed=7).seed
    7
    """
    return Settings(**{**dataclasses.asdict(settings), **changes})
