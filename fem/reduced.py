"""Reduced-modal transient heat solve: a few slow modes exactly, the rest quasi-statically.

The semi-discrete problem M θ' + A θ = F u(t), A = K + hB, F = [f_q, f_b],
u = (q, h θ_amb), is linear and time-invariant between changes of h, and arfem's
inputs are piecewise constant. With M-orthonormal modes A φ_i = μ_i M φ_i the growth
is y = gᵀθ = Σ_i g_i c_i, c_i' = −μ_i c_i + F_iᵀu (g_i = gᵀφ_i, F_i = Φᵀ F); each
amplitude is advanced exactly by its exponential, so there is no time-step error.
:func:`solve_reduced` keeps a few modes, found in one of two ways after one symmetric
factorisation of A (:func:`arfem.fem.linsolve.factorize_spd`; PARDISO where the
optional ``fast`` extra is installed, since factoring is then the main cost).

``method="krylov"`` (default): Ritz modes of a block Krylov space
------------------------------------------------------------------
The space K_j(A⁻¹M; A⁻¹[f_q, f_b, g]) is grown one block (one solve with three
right-hand sides) at a time. The Ritz pairs of A in it are the modes. It starts from
what matters: the loads and the growth functional. On the paper's rod the axial modes
cos(nπx/L), n ≥ 1, integrate to zero and never reach the growth, and the azimuthal
modes are not excited. eigsh's slowest modes are mostly these, while the Krylov
space goes straight to the modes that carry heat into ∫θ.

Because A⁻¹F lies in the space, the Galerkin steady state is exact. The static
correction below vanishes to round-off.

Stopping rule and error statement: after each block the growth's step response to each
input, on a log grid from 0.01 s to 1000 slowest time constants, is compared with
the one before. The iteration stops when it moves by less than :data:`KRYLOV_TOL`
(1e-7) of the static gain. That last move per unit input, δ
(:attr:`ReducedModes.step_change`), is the error statement. Each jump Δu of the input
adds δ·|Δu| to :attr:`ReducedResult.error_estimate_m`, with no decay assumed. The
moves fall geometrically, by 10–100× per block on the paper's rod, so the last move
exceeds the error that remains. ``tests/test_fem_reduced.py`` checks this against the
exact solution of the same semi-discrete system (its dense eigensystem) on two meshes,
and against Crank–Nicolson with Δt → 0. A Ritz basis has no "first omitted mode", so
no rigorous bound is claimed: ``error_bound_m`` is NaN.

``method="eigsh"``: the k slowest modes and a static correction
-----------------------------------------------------------------
Shift-invert Lanczos (:func:`scipy.sparse.linalg.eigsh`) gives the k + 1 slowest
modes, whether they couple or not. The omitted modes are fast (time constants of
seconds to minutes on the paper's rod) and are taken quasi-statically,
c_i ≈ F_iᵀu/μ_i, which costs two solves with the factor already made:

    static correction   D = gᵀA⁻¹F − Σ_{i≤k} g_i F_iᵀ/μ_i        (growth per unit u)
    omitted field       X = A⁻¹F − Σ_{i≤k} φ_i F_iᵀ/μ_i          (θ per unit u)

so y(t) ≈ Σ_{i≤k} g_i c_i(t) + D u(t). This is exact in the steady state and exact at
every instant for the kept modes.

The only error is the lag of the omitted modes behind their quasi-static value.
After an input jump Δu at t_j it is e(t) = −Σ_{i>k} g_i F_iᵀΔu e^{−μ_i(t−t_j)}/μ_i.
At t_j⁺ it is exactly −DΔu, and every term decays at least as fast as the first
omitted mode, e^{−μ_{k+1}(t−t_j)}. :attr:`ReducedResult.error_estimate_m` sums
|D Δu_j| e^{−μ_{k+1}(t−t_j)} over the jumps before t (and the same for the initial
state and each change of h): the first omitted mode's rate applied to the omitted
modes' exact static size. It bounds the error whenever the omitted terms share a
sign.

A bound that needs no such assumption (Cauchy–Schwarz over the omitted modes,
|Σ g_i F_iᵀΔu/μ_i| ≤ √(gᵀA⁻¹g − Σ g_i²/μ_i) √(ΔuᵀGΔu)) is reported as
:attr:`ReducedResult.error_bound_m`. It is rigorous but loose: about 1e-3 of the peak
on the paper's rod, where the estimate is 3e-6 and the measured error 2e-6. The reason
is that the heated-face load excites many axial modes that the volume integral hardly
sees.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse.linalg import LinearOperator, eigsh

from arfem.fem.heat_problem import HeatFEM, HeatResult, initial_state_K, schedule_inputs, breakpoints
from arfem.fem.linsolve import default_method, factorize_spd
from arfem.params import InputError, Schedule

__all__ = ["ReducedModes", "ReducedResult", "reduced_modes", "solve_reduced",
           "DEFAULT_N_MODES", "m_orthonormal"]

#: Modes kept by default. On the paper's rod 6 already match Crank–Nicolson (Δt → 0)
#: to 2e-6 of the peak; 8 leaves a margin for other rods and meshes.
DEFAULT_N_MODES = 8


@dataclass(frozen=True)
class ReducedModes:
    """The k slowest modes of M θ' = −(K + hB)θ and the static correction of the rest.

    Attributes
    ----------
    h_W_m2K : float
        Lateral convection coefficient the modes belong to [W/(m²·K)].
    mu : ndarray, shape (k,)
        Kept decay rates μ_i [1/s], ascending.
    mu_next : float
        Decay rate of the first omitted mode μ_{k+1} [1/s].
    phi : ndarray, shape (ndofs, k)
        M-orthonormal modes (φᵀMφ = I, M in [J/K]).
    Fk : ndarray, shape (k, 2)
        Modal loads Φᵀ[f_q, f_b] per unit u = (q [W/m²], h θ_amb [W/m²]).
    gk, vk : ndarray, shape (k,)
        growthᵀΦ [m] and volumeᵀΦ [K·m³] per unit modal amplitude.
    Dg, Dv : ndarray, shape (2,)
        Static growth [m] and ∫θ dV [K·m³] of the omitted modes per unit u.
    X : ndarray, shape (ndofs, 2)
        Static field of the omitted modes per unit u [K per W/m²].
    g_rest : float
        gᵀA⁻¹g − Σ g_i²/μ_i ≥ 0, the omitted modes' share of the growth functional.
    G_rest : ndarray, shape (2, 2)
        FᵀA⁻¹F − Σ F_i F_iᵀ/μ_i, the omitted modes' share of the loads.
    method : str
        ``"krylov"`` (Ritz modes of a block Krylov space) or ``"eigsh"``.
    step_change : ndarray, shape (2,)
        ``"krylov"`` only: the largest change of the growth's step response per unit
        u that the last Krylov block made [m per W/m²] (NaN for ``"eigsh"``).
    n_blocks : int
        ``"krylov"`` only: block Krylov steps taken (0 for ``"eigsh"``).
    """

    h_W_m2K: float
    mu: np.ndarray
    mu_next: float
    phi: np.ndarray
    Fk: np.ndarray
    gk: np.ndarray
    vk: np.ndarray
    Dg: np.ndarray
    Dv: np.ndarray
    X: np.ndarray
    g_rest: float
    G_rest: np.ndarray
    method: str = "eigsh"
    step_change: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    n_blocks: int = 0

    @property
    def n_modes(self) -> int:
        return int(self.mu.size)


#: Relative change of the growth's step response below which the block Krylov
#: iteration stops: 1e-7 of the static gain, two decades below the 1e-5 of the peak
#: asked of the stated error, and two above the round-off floor of the comparison
#: (the response to the ambient input stalls near 1e-9 on the paper's rod).
KRYLOV_TOL = 1e-7

#: Reduction methods: ``"krylov"`` (default) and ``"eigsh"``.
METHODS = ("krylov", "eigsh")


def reduced_modes(model: HeatFEM, h_W_m2K: float, n_modes: int | None = None,
                  factor_method: str | None = None, method: str = "krylov",
                  tol: float = KRYLOV_TOL) -> ReducedModes:
    """Slow modes of M θ' = −(K + hB)θ coupling the loads to the growth, plus the rest.

    ``method="krylov"`` (default): Ritz modes of the block Krylov space
    K_j(A⁻¹M; A⁻¹[f_q, f_b, g]) -- the space that carries the loads to the growth --
    grown one block at a time until the growth's step response per unit input changes
    by less than ``tol`` of its static gain; the last change is kept as the error
    statement (module docstring). Since A⁻¹F lies in the space, the steady state is
    exact and the static correction vanishes to round-off.

    ``method="eigsh"``: the ``n_modes`` slowest modes by shift-invert Lanczos
    (:func:`scipy.sparse.linalg.eigsh`), whether they couple or not, plus the static
    correction of the rest and the first omitted mode for the error statement.

    Parameters
    ----------
    model : HeatFEM
    h_W_m2K : float
        Lateral convection coefficient h [W/(m²·K)].
    n_modes : int, optional
        ``"eigsh"``: modes kept, k ≥ 1 (one more is computed for the error estimate;
        default :data:`DEFAULT_N_MODES`). ``"krylov"``: the most Ritz modes the space
        may grow to (default min(ndofs − 2, 120)).
    factor_method : {"symmetric", "lu", "pardiso"}, optional
        Factorisation of K + hB (:func:`arfem.fem.linsolve.factorize_spd`); default
        :func:`arfem.fem.linsolve.default_method` for few solves.
    method : {"krylov", "eigsh"}
    tol : float
        ``"krylov"``: stopping tolerance, relative to the static gain [-].

    Returns
    -------
    ReducedModes

    Raises
    ------
    InputError
        If ``n_modes`` is not an integer in [1, ndofs − 2] or ``method`` is unknown.

    Examples
    --------
    >>> from arfem.params import Rod
    >>> from arfem.fem.heat import build_3d
    >>> m = build_3d(Rod(), order=1, n_core=2, n_ring=1, nz=6)
    >>> md = reduced_modes(m, 55.0, 4, method="eigsh")
    >>> md.n_modes, bool(md.mu_next >= md.mu[-1])
    (4, True)
    >>> mk = reduced_modes(m, 55.0)
    >>> bool(abs(mk.mu[0] / md.mu[0] - 1) < 1e-9), bool(mk.step_change.max() < 1e-9)
    (True, True)
    """
    n = model.ndofs
    _check_request(n, n_modes, method)
    A = model.operator(h_W_m2K)
    fac, F, AFg = _static_solves(model, A, factor_method)
    AF, Ag = AFg[:, :2], AFg[:, 2]
    extra = {}
    if method == "eigsh":
        k = DEFAULT_N_MODES if n_modes is None else int(n_modes)
        mu, phi, mu_next = _slowest_modes(model, A, fac, k)
    else:
        cap = min(n - 2, 120) if n_modes is None else int(n_modes)
        mu, phi, change, blocks = _krylov_ritz(model, A, fac, AFg, F, tol, cap)
        mu_next = float("nan")
        extra = dict(method="krylov", step_change=change, n_blocks=blocks)
    Fk = phi.T @ F
    gk, vk = model.growth @ phi, model.volume @ phi
    Fk_mu = Fk / mu[:, None]
    if method == "eigsh":
        g_rest = max(float(model.growth @ Ag - np.sum(gk ** 2 / mu)), 0.0)
        G_rest = F.T @ AF - Fk.T @ Fk_mu
    else:                                # no omitted-mode bound for a Ritz basis
        g_rest, G_rest = float("nan"), np.full((2, 2), np.nan)
    return ReducedModes(
        h_W_m2K=float(h_W_m2K), mu=mu, mu_next=mu_next, phi=phi, Fk=Fk, gk=gk, vk=vk,
        Dg=model.growth @ AF - gk @ Fk_mu, Dv=model.volume @ AF - vk @ Fk_mu,
        X=AF - phi @ Fk_mu, g_rest=g_rest, G_rest=G_rest, **extra)


def _static_solves(model: HeatFEM, A, factor_method):
    """The factorised operator A = K + hB, the loads F = [f_q, f_b] (ndofs, 2) and the
    static responses A⁻¹[f_q, f_b, g] (ndofs, 3)."""
    fac = factorize_spd(A, factor_method if factor_method is not None
                        else default_method(few_solves=True, n=model.ndofs))
    F = np.column_stack([model.f_q, model.f_b])
    return fac, F, fac.solve(np.column_stack([F, model.growth]))


def _check_request(n: int, n_modes, method: str) -> None:
    """``method`` one of :data:`METHODS`, ``n_modes`` None or an integer in [1, n − 2]
    (``n`` degrees of freedom); else an :class:`InputError` naming the argument."""
    if method not in METHODS:
        raise InputError(f"must be one of {', '.join(METHODS)}, got {method!r}", "method")
    if n_modes is not None and (not isinstance(n_modes, (int, np.integer))
                                or not 1 <= n_modes <= n - 2):
        raise InputError(f"must be an integer in [1, {n - 2}], got {n_modes!r}", "n_modes")


def _slowest_modes(model: HeatFEM, A, fac, k: int):
    """The ``k`` slowest modes of M θ' = −Aθ by shift-invert Lanczos, M-orthonormal and
    sorted: (μ [1/s], shape (k,); φ, shape (ndofs, k); the first omitted μ [1/s])."""
    n = model.ndofs
    op = LinearOperator((n, n), matvec=fac.solve, dtype=float)
    v0 = np.ones(n)                  # fixed start vector: the same modes every run
    mu, phi = eigsh(A, k=k + 1, M=model.M, sigma=0.0, which="LM", OPinv=op,
                    v0=v0, tol=1e-12)
    order = np.argsort(mu)
    mu, phi = mu[order], phi[:, order]
    phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, model.M @ phi))
    return mu[:-1], phi[:, :-1], float(mu[-1])


def m_orthonormal(M, V, W):
    """Columns spanning W − V Vᵀ M W, M-orthonormal (two passes of block Gram–Schmidt);
    directions that lost 6 digits of their M-norm to the projection are dropped as
    already in span V.

    Parameters
    ----------
    M : scipy.sparse matrix
        (n, n) symmetric positive definite (a capacity matrix).
    V : numpy.ndarray or None
        (n, k) M-orthonormal basis to project out, or None for none.
    W : numpy.ndarray
        (n, m) new directions.

    Returns
    -------
    numpy.ndarray
        (n, m') with m' ≤ m columns, M-orthonormal and M-orthogonal to ``V``.
    """
    scale = float(np.max(np.einsum("ij,ij->j", W, M @ W)))
    for _ in range(2):
        if V is not None:
            W = W - V @ (V.T @ (M @ W))
    w, U = np.linalg.eigh(W.T @ (M @ W))
    keep = w > 1e-12 * scale
    return (W @ U[:, keep]) / np.sqrt(w[keep])


def _krylov_ritz(model, A, fac, AFg, F, tol, cap):
    """Ritz pairs of A in the block Krylov space of A⁻¹M from A⁻¹[F, g].

    Grows the space one block (one multi-right-hand-side solve) at a time until the
    growth's step response per unit input, on a log grid from 0.01 s to 1000 slowest
    time constants, moves by less than ``tol`` of the static gain; returns (μ, Φ, the
    last move per input [m per W/m²], blocks).
    """
    M = model.M
    gain = model.growth @ AFg[:, :2]
    V = m_orthonormal(M, None, AFg)
    W = V
    t = change = prev = None
    blocks = 1
    while True:
        Ar = V.T @ (A @ V)
        mu, Y = np.linalg.eigh(0.5 * (Ar + Ar.T))
        phi = V @ Y
        coef = (model.growth @ phi)[:, None] * (phi.T @ F) / mu[:, None]     # (r, 2)
        if t is None:
            t = np.concatenate([[0.0], np.geomspace(1e-2, 1e3 / mu[0], 300)])
        step = gain - np.exp(-np.outer(t, mu)) @ coef                        # (t, 2)
        if prev is not None:
            change = np.max(np.abs(step - prev), axis=0)
            if np.all(change <= tol * np.abs(gain)):
                break
        prev = step
        if V.shape[1] + W.shape[1] > cap:
            break
        W = m_orthonormal(M, V, fac.solve(M @ W))
        if W.shape[1] == 0:              # an invariant subspace: the Ritz pairs are exact
            change = np.zeros(2)
            break
        V = np.hstack([V, W])
        blocks += 1
    if change is None:                   # capped before a second block could be compared
        change = np.abs(gain)
    return mu, phi, change, blocks


@dataclass(frozen=True)
class ReducedResult(HeatResult):
    """A :class:`arfem.fem.heat.HeatResult` with the reduced solve's error statement.

    Attributes
    ----------
    error_estimate_m : ndarray
        Estimated |growth error| at each output time [m] (module docstring).
    error_bound_m : ndarray
        Rigorous but loose bound on it [m] (``"eigsh"`` only); NaN for ``"krylov"``,
        and after a non-zero initial state or a change of h, where the reduced solve
        carries an approximate state.
    n_modes : int
        Modes kept (the most over the runs of constant h).
    """

    error_estimate_m: np.ndarray | None = None
    error_bound_m: np.ndarray | None = None
    n_modes: int = 0


def _runs_of_equal(values: np.ndarray):
    """(first, last) index of each run of equal consecutive ``values`` (e.g. the h of
    each interval: one modal basis per run).

    >>> list(_runs_of_equal(np.array([5.0, 5.0, 9.0, 5.0])))
    [(0, 1), (2, 2), (3, 3)]
    """
    k = 0
    while k < values.size:
        j = k
        while j + 1 < values.size and values[j + 1] == values[k]:
            j += 1
        yield k, j
        k = j + 1


def _modal_steps(md, U: np.ndarray, dt_s: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The kept modes' coordinates at the end of each interval (intervals × k), exact for
    inputs ``U`` held over intervals of ``dt_s`` [s] from the coordinates ``c``: each
    relaxes towards its steady value at its rate ``mu``."""
    css = U @ md.Fk.T / md.mu
    decay = np.exp(-np.outer(dt_s, md.mu))
    C = np.empty((dt_s.size, md.mu.size))
    for n in range(dt_s.size):
        c = css[n] + decay[n] * (c - css[n])
        C[n] = c
    return C


def _omitted_mode_events(md, U: np.ndarray, times_s: np.ndarray, e0: float,
                        u_prev) -> list:
    """The error events of the modes a run of one h leaves out: (time [s], size of the
    estimate [m], size of the bound [m], decay rate [1/s]) at the run's start (the
    mismatch ``e0`` [m] the state carries in, plus, for a Ritz basis, the step from the
    previous run's inputs ``u_prev``) and at every change of its inputs ``U``
    (intervals × 2: flux [W/m²], h × ambient [W/m²]). With eigenmodes each decays at
    the first omitted rate and has a bound; a Ritz (Krylov) basis has no first omitted
    mode: every input jump may leave the last block's change of the step response, which
    is not assumed to decay, and no bound is given (NaN)."""
    krylov = md.method == "krylov"
    if krylov:
        du0 = U[0] - (u_prev if u_prev is not None else 0.0)
        events = [(times_s[0], abs(e0) + float(md.step_change @ np.abs(du0)), np.nan, 0.0)]
    else:
        b0 = np.sqrt(md.g_rest * max(float(U[0] @ md.G_rest @ U[0]), 0.0))
        events = [(times_s[0], abs(e0), b0, md.mu_next)]
    for m_ in np.flatnonzero(np.any(np.diff(U, axis=0) != 0.0, axis=1)) + 1:
        du = U[m_] - U[m_ - 1]
        if krylov:
            events.append((times_s[m_], float(md.step_change @ np.abs(du)), np.nan, 0.0))
        else:
            events.append((times_s[m_], abs(float(md.Dg @ du)),
                           np.sqrt(md.g_rest * max(float(du @ md.G_rest @ du), 0.0)),
                           md.mu_next))
    return events


def _error_curves(events: list, times_s: np.ndarray):
    """The error estimate and bound [m] at ``times_s``: each event's size from its time
    on, decaying at its rate."""
    est, bound = np.zeros(times_s.size), np.zeros(times_s.size)
    for t_e, a_e, b_e, r_e in events:
        after = times_s > t_e
        w = np.exp(-r_e * (times_s[after] - t_e))
        est[after] += a_e * w
        bound[after] += b_e * w
    return est, bound


def _cached_modes(cache: dict, model: HeatFEM, h_W_m2K: float, n_modes, factor_method,
                  method: str) -> ReducedModes:
    """The reduced modes at ``h_W_m2K``, computed once per (h, n_modes, method) and kept
    in ``cache``."""
    key = (h_W_m2K, n_modes, method)
    if key not in cache:
        cache[key] = reduced_modes(model, h_W_m2K, n_modes, factor_method, method)
    return cache[key]


def _trajectory(model: HeatFEM, x: np.ndarray, n: int, store_fields: bool):
    """Growth [m] and heat content [m³·K] at ``n`` breakpoints (and the states θ [K],
    shape (n, ndofs), if ``store_fields``; else None), the first filled from ``x``."""
    growth, heat = np.empty(n), np.empty(n)
    states = np.empty((n, model.ndofs)) if store_fields else None
    growth[0], heat[0] = model.growth @ x, model.volume @ x
    if states is not None:
        states[0] = x
    return growth, heat, states


def _run_start(model: HeatFEM, md: ReducedModes, x: np.ndarray, u0: np.ndarray):
    """At the start of a run of equal h: the state ``x`` [K] in the kept modes, and the
    omitted modes' growth mismatch [m] (exact: the state is continuous)."""
    c = md.phi.T @ (model.M @ x)
    return c, float(model.growth @ x - md.gk @ c - md.Dg @ u0)


def solve_reduced(model: HeatFEM, schedule: Schedule, output_times_s=None,
                  store_fields: bool = False, theta0=None, n_modes: int | None = None,
                  mode_cache: dict | None = None,
                  factor_method: str | None = None,
                  method: str = "krylov") -> ReducedResult:
    """Growth (and fields) for piecewise-constant inputs by the reduced-modal method.

    Parameters
    ----------
    model : HeatFEM
    schedule : Schedule
    output_times_s : array_like, optional
        Times [s] within [0, schedule.total_s]; default t = 0 and every segment end.
        At a segment edge the value is the limit from the segment that ends there.
    store_fields : bool
        Keep θ [K] at every output time (kept modes + omitted static field).
    theta0 : array_like or float, optional
        Initial temperature rise [K]; default 0.
    n_modes : int, optional
        See :func:`reduced_modes`.
    mode_cache : dict, optional
        ``{(h, n_modes, method): ReducedModes}`` reused across calls with the same model.
    factor_method : {"symmetric", "lu", "pardiso"}, optional
        Factorisation used by the reduction and the static correction.
    method : {"krylov", "eigsh"}
        How the modes are found (:func:`reduced_modes`).

    Returns
    -------
    ReducedResult
        Growth, heat content and fields as :func:`arfem.fem.heat.solve_modal`, plus
        ``error_estimate_m`` and ``error_bound_m`` per output time.

    Examples
    --------
    >>> from arfem.params import Rod, paper_cycle
    >>> from arfem.fem.heat import build_3d
    >>> m = build_3d(Rod(), order=1, n_core=2, n_ring=1, nz=8)
    >>> r = solve_reduced(m, paper_cycle(2000.0))
    >>> bool(r.error_estimate_m.max() < 1e-4 * r.growth_m.max())
    True
    """
    q, h, amb = schedule_inputs(model, schedule)
    b = breakpoints(schedule, output_times_s)       # segment edges and output times
    bps, seg, d, out_t = b.times_s, b.segment, b.dt_s, b.output_times_s
    cache = {} if mode_cache is None else mode_cache
    x = initial_state_K(model, theta0)
    growth, heat, states = _trajectory(model, x, bps.size, store_fields)
    rigorous = not np.any(x)             # the bound needs a known (zero) omitted start
    events = []                          # (time, estimate size, bound size, decay rate)
    runs = n_kept = 0
    u_prev = None
    for k, j in _runs_of_equal(h[seg]):
        hk = float(h[seg[k]])
        md = _cached_modes(cache, model, hk, n_modes, factor_method, method)
        idx = np.arange(k, j + 1)
        U = np.column_stack([q[seg[idx]], hk * amb[seg[idx]]])        # (intervals, 2)
        c, e0 = _run_start(model, md, x, U[0])
        # a Ritz basis has no first omitted mode: nothing is assumed to decay, no bound
        rigorous = rigorous and md.method != "krylov"
        events += _omitted_mode_events(md, U, bps[k:j + 2], e0, u_prev)
        u_prev = U[-1]
        n_kept = max(n_kept, md.n_modes)
        C = _modal_steps(md, U, d[idx], c)                             # (intervals, k)
        c = C[-1]
        growth[k + 1:j + 2] = C @ md.gk + U @ md.Dg
        heat[k + 1:j + 2] = C @ md.vk + U @ md.Dv
        if store_fields:
            states[k + 1:j + 2] = C @ md.phi.T + U @ md.X.T
        x = md.phi @ c + md.X @ U[-1]     # nodal state carried into the next run of h
        runs += 1
    est, bound = _error_curves(events, bps)
    if not rigorous or runs > 1:
        bound[1:] = np.nan
    pick = b.pick
    rhoc = model.rod.density_kg_m3 * model.rod.specific_heat_J_kgK
    return ReducedResult(out_t.copy(), growth[pick], rhoc * heat[pick],
                         None if states is None else states[pick],
                         error_estimate_m=est[pick], error_bound_m=bound[pick],
                         n_modes=int(n_kept))
