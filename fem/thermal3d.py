"""Transient heat of a :class:`arfem.fem.body.ThermalBody`: θ-method and reduced-modal solve,
with many inputs and many outputs.

The semi-discrete system is M θ' + A(h) θ = F u(t), y = Gᵀθ, with A(h) = K + Σ_g h_g B_g,
u the sources' inputs and the convection groups' h θ_amb, and G one column per sensor
(temperature rows of the interpolation, displacement rows TᵀK⁻¹w of
:meth:`arfem.fem.body.ElasticBody.functional`). Inputs and h are piecewise constant on
an :class:`InputHistory`.

* :func:`solve_body_theta` -- the θ-method (Crank–Nicolson θ = ½, backward Euler θ = 1), each
  distinct (step, h) matrix M + θΔtA factored once (:func:`arfem.fem.linsolve.factorize_spd`),
  as :func:`arfem.fem.heat.solve_theta` does for the rod.
* :func:`solve_body_reduced` -- the block-Krylov reduced-modal solve of
  :mod:`arfem.fem.reduced` generalised to S + G inputs and r outputs: Ritz modes of
  A in K_j(A⁻¹M; A⁻¹[F, G]), grown until every output's step response to every
  input moves by less than ``tol`` of that output's largest static gain; the modal
  amplitudes are then advanced exactly (exponentials) between breakpoints. The
  steady state is exact (A⁻¹F is in the space); the last move is the error statement.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arfem.fem.linsolve import default_method, factorize_spd
from arfem.fem.reduced import m_orthonormal
from arfem.params import InputError

__all__ = ["InputHistory", "BodyResult", "BodyModes", "body_modes", "projected_modes",
           "solve_body_theta", "solve_body_reduced", "KRYLOV_TOL"]

#: Stopping tolerance of the Krylov growth, relative to each output's largest static gain:
#: 1e-5, since a point sensor (a thermometer beside a heated face) is a rough functional
#: whose response converges slowly in the Krylov space (1e-7, the rod's value, took the
#: spindle unit to the 400-vector cap).
KRYLOV_TOL = 1e-5

#: Most Ritz vectors of :func:`body_modes`.
KRYLOV_CAP = 400


@dataclass(frozen=True)
class InputHistory:
    """Piecewise-constant inputs of a body.

    Attributes
    ----------
    edges_s : ndarray, shape (n + 1,)
        Segment boundaries [s], from 0, increasing.
    u : ndarray, shape (n, p)
        Inputs on each segment: each source's power [W] or flux [W/m²], then h·θ_amb
        of each convection group [W/m²].
    h_W_m2K : ndarray, shape (n, G)
        Convection coefficient of each group on each segment [W/(m²·K)].
    """

    edges_s: np.ndarray
    u: np.ndarray
    h_W_m2K: np.ndarray

    @property
    def total_s(self) -> float:
        return float(self.edges_s[-1])

    @property
    def durations_s(self) -> np.ndarray:
        return np.diff(self.edges_s)

    def subdivided(self, dt_s: float) -> "InputHistory":
        """The same history with every segment split into steps of at most ``dt_s``."""
        edges, seg = [0.0], []
        for i, d in enumerate(self.durations_s):
            n = max(1, int(np.ceil(d / dt_s - 1e-9)))
            edges += list(self.edges_s[i] + d * np.arange(1, n + 1) / n)
            seg += [i] * n
        seg = np.asarray(seg)
        return InputHistory(np.asarray(edges), self.u[seg], self.h_W_m2K[seg])


@dataclass(frozen=True)
class BodyResult:
    """Outputs of a transient body solve.

    Attributes
    ----------
    times_s : ndarray, shape (nt,)
    outputs : ndarray, shape (nt, r)
        Each sensor's value [K or m] (θ = T − T_ref for temperatures).
    field_times_s : ndarray, shape (nf,)
    fields : ndarray or None, shape (nf, ndofs)
        θ [K] at ``field_times_s``.
    n_modes : int
        Modes kept (reduced solve; 0 for the θ-method).
    step_change : ndarray or None, shape (r,)
        The reduced solve's error statement: the last Krylov block's largest move of
        each output's step response per unit input [output unit per input unit].
    """

    times_s: np.ndarray
    outputs: np.ndarray
    field_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fields: np.ndarray | None = None
    n_modes: int = 0
    step_change: np.ndarray | None = None


def _check_times(hist: InputHistory, t, name: str) -> np.ndarray:
    t = np.asarray(t if t is not None else hist.edges_s, float)
    if t.ndim != 1 or np.any(~np.isfinite(t)) or np.any(np.diff(t) < 0):
        raise InputError("must be finite and non-decreasing", name)
    if t.size and (t[0] < -1e-9 or t[-1] > hist.total_s * (1 + 1e-12) + 1e-9):
        raise InputError(f"must lie within [0, {hist.total_s:g}] s", name)
    return np.clip(t, 0.0, hist.total_s)


def solve_body_theta(body, hist: InputHistory, G: np.ndarray, dt_s: float, theta: float = 0.5,
                field_times_s=None, factor_method: str | None = None) -> BodyResult:
    """θ-method; outputs at t = 0 and every step end, fields at the nearest step ends.

    Parameters
    ----------
    body : ThermalBody
    hist : InputHistory
    G : ndarray, shape (ndofs, r)
        Output functionals (y = Gᵀθ).
    dt_s : float
        Largest step [s]; each segment is split into equal steps.
    theta : float
        ½ Crank–Nicolson, 1 backward Euler.
    field_times_s : array_like, optional
        Times [s] whose fields to keep (the step end at or after each).
    """
    if not 0.5 <= theta <= 1.0:
        raise InputError(f"must lie in [0.5, 1], got {theta!r}", "theta")
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise InputError(f"must be > 0, got {dt_s!r}", "dt_s")
    fine = hist.subdivided(dt_s)
    ft = _check_times(hist, [] if field_times_s is None else field_times_s, "field_times_s")
    want = np.searchsorted(fine.edges_s, ft - 1e-6 * max(dt_s, 1.0))
    x = np.zeros(body.ndofs)
    M = body.M
    cache: dict = {}
    ys = [G.T @ x]
    keep = {}
    if np.any(want == 0):
        keep[0] = x.copy()
    for i, d in enumerate(fine.durations_s):
        key = (round(float(d), 9), tuple(fine.h_W_m2K[i]))
        if key not in cache:
            A = body.operator(fine.h_W_m2K[i])
            cache[key] = (factorize_spd((M + theta * d * A).tocsc(), factor_method),
                          (M - (1.0 - theta) * d * A).tocsr())
        lhs, rhs = cache[key]
        x = lhs.solve(rhs @ x + d * (body.F @ fine.u[i]))
        ys.append(G.T @ x)
        if np.any(want == i + 1):
            keep[i + 1] = x.copy()
    fields = np.array([keep[k] for k in want]) if ft.size else None
    return BodyResult(fine.edges_s.copy(), np.asarray(ys), fine.edges_s[want] if ft.size
                      else np.zeros(0), fields)


@dataclass(frozen=True)
class BodyModes:
    """Ritz modes of one A(h) in the Krylov space of the inputs and outputs.

    Attributes
    ----------
    h_W_m2K : tuple, the convection coefficients [W/(m²K)] these modes belong to
    mu : ndarray (k,), decay rates [1/s], ascending
    phi : ndarray (ndofs, k), M-orthonormal modes
    Fk : ndarray (k, p), modal loads per unit input
    Gk : ndarray (k, r), outputs per unit modal amplitude
    D : ndarray (r, p), static correction of the omitted modes (≈ 0)
    X : ndarray (ndofs, p), static field of the omitted modes per unit input
    step_change : ndarray (r,), last Krylov block's largest move of the step response
    n_blocks : int
    """

    h_W_m2K: tuple
    mu: np.ndarray
    phi: np.ndarray
    Fk: np.ndarray
    Gk: np.ndarray
    D: np.ndarray
    X: np.ndarray
    step_change: np.ndarray
    n_blocks: int

    @property
    def n_modes(self) -> int:
        return int(self.mu.size)


def body_modes(body, h_W_m2K, G: np.ndarray, tol: float = KRYLOV_TOL, cap: int = KRYLOV_CAP,
               factor_method: str | None = None, kinds=None,
               t_min_s: float = 1.0, other_h=()) -> BodyModes:
    """Ritz modes of A(h) in K_j(A⁻¹M; A⁻¹[F, G]) until the step responses settle.

    Parameters
    ----------
    body : ThermalBody
    h_W_m2K : array_like, shape (G,)
    G : ndarray, shape (ndofs, r)
    tol : float
        Stop when every output's step response per unit input moves by less than
        ``tol`` of that output's largest static gain [-].
    cap : int
        Most Ritz vectors.
    kinds : array_like of int, shape (r,), optional
        Output kinds (e.g. 0 temperature, 1 displacement) for the tolerance's floor.
    t_min_s : float
        Earliest time [s] after a step at which the step responses are compared: the
        shortest interval between two instants the solve reports or changes an input
        at (a response is never sampled sooner after a step than that).
    other_h : sequence of array_like, shape (G,) each
        Other convection coefficients whose modes :func:`projected_modes` will take
        from this space: their static fields A(h)⁻¹F join the space (by conjugate
        gradients preconditioned with this factor), so that the projection's steady
        state is exact for them too.
    """
    import scipy.linalg  # noqa: F401  (SciPy's OpenBLAS first, so that the limit reaches it)
    from threadpoolctl import threadpool_limits
    # one BLAS thread: the small dense products and eigenproblems here ran 10x slower
    # with threads contending on a busy 2-core machine (0.26 s CPU, 9.4 s wall at load 18)
    with threadpool_limits(limits=1):
        return _body_modes(body, h_W_m2K, G, tol, cap, factor_method, kinds, t_min_s,
                           other_h)


def _output_scale(gain: np.ndarray, kinds) -> np.ndarray:
    """Per output: its largest static gain, floored at 1e-3 of the largest gain of any
    output of the same kind, so that an output the loads hardly reach (the TCP across a
    plane of symmetry) is not asked for digits below round-off."""
    own = np.max(np.abs(gain), axis=1)
    kinds = np.zeros(gain.shape[0], int) if kinds is None else np.asarray(kinds)
    floor = np.array([own[kinds == k].max() for k in kinds])
    return np.maximum(np.maximum(own, 1e-3 * floor), 1e-300)


def _step_responses(t: np.ndarray, mu: np.ndarray, Gk: np.ndarray, Fk: np.ndarray,
                    gain: np.ndarray) -> np.ndarray:
    """Step response (nt, r, p) of every output to every input at times ``t`` [s]:
    gain − Σ_k Gk_ki Fk_kj e^{−μ_k t}/μ_k, as one matrix product."""
    k, r = Gk.shape
    p = Fk.shape[1]
    C = (Gk[:, :, None] * (Fk / mu[:, None])[:, None, :]).reshape(k, r * p)
    return gain[None] - (np.exp(-np.outer(t, mu)) @ C).reshape(t.size, r, p)


def _body_modes(body, h_W_m2K, G, tol, cap, factor_method, kinds, t_min_s,
                other_h) -> BodyModes:
    A = body.operator(h_W_m2K)
    M = body.M
    n = body.ndofs
    fac = factorize_spd(A.tocsc(), factor_method if factor_method is not None
                        else default_method(few_solves=True, n=n))
    F = body.F
    start = fac.solve(np.column_stack([F, G]))
    AF = start[:, :F.shape[1]]
    gain = G.T @ AF                                         # (r, p) static gains
    scale = _output_scale(gain, kinds)
    V = m_orthonormal(M, None, start)
    W = V
    Ar = V.T @ (A @ V)
    VF, VG = V.T @ F, V.T @ G       # grown with V: the Ritz vectors V Y (n × k each
    t = prev = change = None        # time) are formed once, after the loop
    blocks = 1
    while True:
        mu, Y = np.linalg.eigh(0.5 * (Ar + Ar.T))
        Fk, Gk = Y.T @ VF, Y.T @ VG
        if t is None:
            # from the first instant any output is sampled after a step (``t_min_s``): a
            # thermometer beside a heated face has millisecond dynamics that a Krylov
            # space resolves only with hundreds of vectors, and that no output sees
            t = np.concatenate([[0.0], np.geomspace(max(t_min_s, 1e-3),
                                                    max(1e3 / mu[0], 10 * t_min_s), 200)])
        step = _step_responses(t, mu, Gk, Fk, gain)
        if prev is not None:
            change = np.max(np.abs(step - prev), axis=(0, 2))
            if np.all(change <= tol * scale):
                break
        prev = step
        if V.shape[1] + W.shape[1] > cap:
            break
        W = m_orthonormal(M, V, fac.solve(M @ W))
        if W.shape[1] == 0:
            change = np.zeros(G.shape[1])
            break
        AW = A @ W                          # the projection grows by one block, not anew
        Ar = np.block([[Ar, V.T @ AW], [AW.T @ V, W.T @ AW]])
        V = np.hstack([V, W])
        VF, VG = np.vstack([VF, W.T @ F]), np.vstack([VG, W.T @ G])
        blocks += 1
    if change is None:
        change = scale
    if len(other_h):
        W = m_orthonormal(M, V, np.hstack([_static_fields(body, h, fac) for h in other_h]))
        if W.shape[1]:
            AW = A @ W
            Ar = np.block([[Ar, V.T @ AW], [AW.T @ V, W.T @ AW]])
            V = np.hstack([V, W])
            mu, Y = np.linalg.eigh(0.5 * (Ar + Ar.T))
    phi = V @ Y
    Fk, Gk = phi.T @ F, phi.T @ G
    Fk_mu = Fk / mu[:, None]
    return BodyModes(tuple(float(h) for h in np.atleast_1d(h_W_m2K)), mu, phi, Fk, Gk,
                     G.T @ AF - Gk.T @ Fk_mu, AF - phi @ Fk_mu, change, blocks)


def _static_fields(body, h_W_m2K, fac, rtol: float = 1e-10, maxiter: int = 200):
    """A(h)⁻¹F [K per unit input] by conjugate gradients, all columns at once,
    preconditioned by ``fac`` (the factor of A at another h: A(h) differs from it only
    by surface terms, so a few iterations suffice)."""
    A = body.operator(h_W_m2K)
    F = body.F
    X = fac.solve(F)
    nb = np.sqrt(np.abs(np.einsum("ij,ij->j", F, X)))       # preconditioned norms of F
    R = F - A @ X
    Z = fac.solve(R)
    P = Z.copy()
    rz = np.einsum("ij,ij->j", R, Z)
    for _ in range(maxiter):
        if np.all(np.sqrt(np.abs(rz)) <= rtol * nb):
            break
        AP = A @ P
        alpha = rz / np.where(rz == 0, 1.0, np.einsum("ij,ij->j", P, AP))
        X += P * alpha
        R -= AP * alpha
        Z = fac.solve(R)
        rz_new = np.einsum("ij,ij->j", R, Z)
        P = Z + P * (rz_new / np.where(rz == 0, 1.0, rz))
        rz = rz_new
    return X


def projected_modes(body, base: BodyModes, h_W_m2K, G: np.ndarray) -> BodyModes:
    """Modes of A(h) in the space of ``base`` (built for another h): Galerkin projection.

    A change of h (speed-dependent convection) alters A only by surface terms, so the
    Krylov space grown once (from the loads and the sensors) carries the other h's
    responses too; this costs one projection instead of a new factorisation and Krylov
    growth per speed. The steady state for the new h is exact when ``base`` was built
    with it among its ``other_h`` (its static fields are then in the space);
    ``benchmarks/bench_geometry.py`` measures the whole against Crank–Nicolson.
    """
    V = base.phi
    # V = Φ(h_b) diagonalises A(h_b) (VᵀA(h_b)V = diag μ_b), and A(h) − A(h_b) =
    # Σ_g (h_g − h_b,g) B_g lives on the convection surfaces: the projection needs only
    # V's rows there (n k² flops saved per speed)
    Ar = np.diag(base.mu)
    for dh, B in zip(np.atleast_1d(h_W_m2K) - np.asarray(base.h_W_m2K), body.B):
        if dh != 0.0:
            rows = np.unique(B.indices)
            Vs = V[rows]
            Ar = Ar + float(dh) * (Vs.T @ (B[rows][:, rows] @ Vs))
    mu, Y = np.linalg.eigh(0.5 * (Ar + Ar.T))
    phi = V @ Y
    p, r = body.F.shape[1], G.shape[1]
    return BodyModes(tuple(float(h) for h in np.atleast_1d(h_W_m2K)), mu, phi,
                     phi.T @ body.F, phi.T @ G, np.zeros((r, p)), np.zeros((body.ndofs, p)),
                     base.step_change, 0)


def solve_body_reduced(body, hist: InputHistory, G: np.ndarray, output_times_s=None,
                  field_times_s=None, tol: float = KRYLOV_TOL,
                  mode_cache: dict | None = None, kinds=None) -> BodyResult:
    """Outputs (and fields) for piecewise-constant inputs by the reduced-modal method.

    Exact in time for the kept modes; where h changes the state is carried across in
    nodal form. Parameters as :func:`solve_body_theta`; ``output_times_s`` default t = 0
    and every segment end; ``mode_cache`` ``{h tuple: BodyModes}`` reused across calls.
    """
    out_t = _check_times(hist, output_times_s, "output_times_s")
    ft = _check_times(hist, [] if field_times_s is None else field_times_s, "field_times_s")
    edges = hist.edges_s
    bps = np.union1d(edges, np.union1d(out_t, ft))
    seg = np.clip(np.searchsorted(edges, bps[1:], side="left") - 1, 0, len(edges) - 2)
    d = np.diff(bps)
    cache = {} if mode_cache is None else mode_cache
    # no response is sampled sooner after a step than the shortest interval between
    # breakpoints: the Krylov growth's stopping test starts there
    t_min = float(d[d > 0].min()) if np.any(d > 0) else 1.0
    r = G.shape[1]
    Y = np.zeros((bps.size, r))
    want_f = np.searchsorted(bps, ft)
    fields = np.zeros((ft.size, body.ndofs)) if ft.size else None
    x = np.zeros(body.ndofs)
    hkeys = [tuple(float(v) for v in row) for row in hist.h_W_m2K]
    k = 0
    nk, change = 0, np.zeros(r)
    while k < seg.size:
        j = k
        while j + 1 < seg.size and hkeys[seg[j + 1]] == hkeys[seg[k]]:
            j += 1
        hk = hkeys[seg[k]]
        if hk not in cache:
            base = next(iter(cache.values()), None)
            others = [np.array(h) for h in dict.fromkeys(hkeys) if h not in cache
                      and h != hk]
            cache[hk] = (body_modes(body, np.array(hk), G, tol, kinds=kinds, t_min_s=t_min,
                                    other_h=others)
                         if base is None
                         else projected_modes(body, base, np.array(hk), G))
        md = cache[hk]
        nk = max(nk, md.n_modes)
        change = np.maximum(change, md.step_change)
        c = md.phi.T @ (body.M @ x)
        U = hist.u[seg[k:j + 1]]                            # (m, p)
        css = (U @ md.Fk.T) / md.mu                         # (m, k)
        C = np.empty_like(css)
        for i in range(css.shape[0]):
            c = css[i] + np.exp(-md.mu * d[k + i]) * (c - css[i])
            C[i] = c
        Y[k + 1:j + 2] = C @ md.Gk + U @ md.D.T
        if fields is not None:
            for m_, b in enumerate(want_f):
                if k + 1 <= b <= j + 1:
                    fields[m_] = md.phi @ C[b - k - 1] + md.X @ U[b - k - 1]
        x = md.phi @ C[-1] + md.X @ U[-1]
        k = j + 1
    pick = np.searchsorted(bps, out_t)
    return BodyResult(out_t.copy(), Y[pick], ft.copy(), fields, nk, change)
