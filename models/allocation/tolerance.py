"""Tolerance stack-up of a chain of error screws: worst case, RSS, Monte Carlo yield.

A tolerance t_k >= 0 allows the error component e_k anywhere in [-t_k, t_k] (its sign
is not known when the part is made). The small displacement of the functional point is
linear in the errors, δp = Σ_k e_k J_k, with J_k [mm per mm, or mm per rad] the
translational part of the unit's adjoint column (:func:`arfem.models.allocation.screw.chain_adjoints`).
Over every sign combination δp fills the zonotope Σ_k [-t_k, t_k] J_k, so

* worst case  m_wc = max over the zonotope of |δp| = max over its vertices (|·| is convex);
* RSS         m_rss = sqrt(Σ_k t_k² |J_k|²), the classical root-sum-square stack
  (= 3·sqrt(E|δp|²) when every e_k is normal with t_k = 3σ_k);
* yield       P(|δp| <= ΔE) by Monte Carlo, errors uniform in ±t_k or normal (t_k = 3σ_k).

The vertices of a 3-D zonotope are the sign vectors s = sign(J u) of the cells of the
great-circle arrangement {u : u·J_k = 0} on the unit sphere. Every cell has a corner
u0 = ±(J_d × J_e)/|J_d × J_e|, so walking round every corner (one small step into each
sector between the circles through it) visits every cell: O(K²) candidate sign
vectors, exact, instead of 2^K.
"""
from __future__ import annotations

import numpy as np

__all__ = ["vertex_signs", "worst_case", "rss", "monte_carlo", "sensitivity"]

_TOL = 1e-10


def _unit(v):
    return v / np.linalg.norm(v)


def vertex_signs(J) -> np.ndarray:
    """Sign vectors of every vertex of the zonotope Σ_k [-1, 1] J_k (one of each ± pair).

    Parameters
    ----------
    J : array_like, shape (K, 3)
        Generator directions (any unit; only directions matter). Zero rows are allowed
        (their sign is returned as +1).

    Returns
    -------
    ndarray, shape (M, K)
        Entries ±1. For any t >= 0, max_s |Σ_k s_k t_k J_k| over these rows is the
        largest norm of the zonotope Σ [-t_k, t_k] J_k.

    Examples
    --------
    Two orthogonal generators: the square's vertices (±1, ±1), one of each ± pair:

    >>> vertex_signs([[1.0, 0, 0], [0, 1.0, 0]]).shape
    (2, 2)
    """
    J = np.asarray(J, float)
    K = J.shape[0]
    norms = np.linalg.norm(J, axis=1)
    scale = norms.max() if K else 0.0
    act = np.flatnonzero(norms > _TOL * max(scale, 1e-300))
    out = np.ones((1, K))
    if act.size == 0:
        return out
    D = J[act] / norms[act, None]
    corners = []
    for a in range(len(D)):
        c = np.cross(D[a], D[a + 1:])
        n = np.linalg.norm(c, axis=1)
        corners.extend(c[n > 1e-9] / n[n > 1e-9, None])
    if not corners:                       # all generators parallel: one vertex
        s = np.sign(D @ D[0])
        out[0, act] = s
        return out
    corners = np.unique(np.round(np.array(corners), 12), axis=0)
    rows = []
    for u0 in corners:
        u0 = _unit(u0)
        d = D @ u0
        zero = np.abs(d) < 1e-9
        base = np.sign(d)
        a = _unit(np.cross(u0, [1.0, 0, 0]) if abs(u0[0]) < 0.9 else np.cross(u0, [0, 1.0, 0]))
        b = np.cross(u0, a)
        nz = np.column_stack([D[zero] @ a, D[zero] @ b])       # normals of the circles in the tangent plane
        ang = np.mod(np.arctan2(nz[:, 1], nz[:, 0]) + np.pi / 2, np.pi)   # line directions
        ang = np.unique(np.round(ang, 12))
        edges = np.sort(np.concatenate([ang, ang + np.pi]))
        mids = 0.5 * (edges + np.roll(edges, -1))
        mids[-1] = 0.5 * (edges[-1] + edges[0] + 2 * np.pi)
        for m in mids:
            w = np.cos(m) * nz[:, 0] + np.sin(m) * nz[:, 1]
            s = base.copy()
            s[zero] = np.sign(w)
            rows.append(s)
    S = np.array(rows)
    S = S * np.where(S[:, :1] < 0, -1.0, 1.0)          # canonical member of each ± pair
    S = np.unique(S, axis=0)
    out = np.ones((S.shape[0], K))
    out[:, act] = S
    return out


def worst_case(T, J, signs=None) -> np.ndarray:
    """Worst-case |δp| [mm] over every sign of the errors, for a batch of tolerance sets.

    Parameters
    ----------
    T : array_like, shape (n, K)
        Tolerances (internal units: mm for translations, rad for rotations).
    J : array_like, shape (K, 3)
        Displacement of the functional point per unit error [mm/mm, mm/rad].
    signs : ndarray, optional
        :func:`vertex_signs` of ``J`` (pass it to avoid recomputing).

    Returns
    -------
    ndarray, shape (n,)
        max over sign combinations of |Σ s_k t_k J_k| [mm] (exact).

    Examples
    --------
    Three orthogonal 1 µm tolerances: the cube's corner, √3 µm:

    >>> round(float(worst_case([[1e-3] * 3], np.eye(3))[0] * 1e3), 6)
    1.732051
    """
    T = np.atleast_2d(np.asarray(T, float))
    J = np.asarray(J, float)
    S = vertex_signs(J) if signs is None else signs
    sq = np.zeros((T.shape[0], S.shape[0]))
    for j in range(3):
        sq += (T @ (S * J[:, j]).T) ** 2
    return np.sqrt(sq.max(axis=1))


def rss(T, J) -> np.ndarray:
    """Root-sum-square stack sqrt(Σ_k t_k² |J_k|²) [mm].

    Parameters
    ----------
    T : array_like, shape (n, K)
        Tolerances [mm, rad].
    J : array_like, shape (K, 3)
        Sensitivities [mm/mm, mm/rad].

    Returns
    -------
    ndarray, shape (n,)

    Examples
    --------
    >>> round(float(rss([[3e-3, 4e-3]], [[1, 0, 0], [0, 1, 0]])[0]), 9)
    0.005
    """
    T = np.atleast_2d(np.asarray(T, float))
    return np.sqrt((T ** 2) @ np.sum(np.asarray(J, float) ** 2, axis=1))


def monte_carlo(t, Js, delta_E_mm, n_draws=100_000, dist="uniform", seed=0,
                offsets_mm=None, chunk=50_000) -> dict:
    """Monte Carlo yield P(max over poses |δp| <= ΔE) of one tolerance set.

    Parameters
    ----------
    t : array_like, shape (K,)
        Tolerances [mm, rad].
    Js : array_like, shape (P, K, 3)
        Sensitivities at each of P poses (a part passes only if it is within ΔE at all).
    delta_E_mm : float
        Allowed displacement [mm].
    n_draws : int
        Number of simulated assemblies.
    dist : {"uniform", "normal"}
        Errors uniform in [-t_k, t_k], or normal with σ_k = t_k / 3.
    seed : int
        Seed of :func:`numpy.random.default_rng`.
    offsets_mm : array_like, shape (P, 3), optional
        A known displacement added at each pose (e.g. a thermal term) [mm].
    chunk : int
        Draws per vectorised block (bounds the memory to chunk·K floats).

    Returns
    -------
    dict
        ``yield`` [-], ``n_draws``, ``dist``, ``p99_mm`` (99th percentile of the worst
        pose's |δp|), ``max_mm``.

    Examples
    --------
    One generator of tolerance 2 µm, ΔE 1 µm, uniform: half the parts pass.

    >>> r = monte_carlo([2e-3], [[[1.0, 0, 0]]], 1e-3, n_draws=20000, seed=1)
    >>> abs(r["yield"] - 0.5) < 0.02
    True
    """
    t = np.asarray(t, float)
    Js = np.asarray(Js, float)
    if Js.ndim == 2:
        Js = Js[None]
    rng = np.random.default_rng(seed)
    off = np.zeros((Js.shape[0], 3)) if offsets_mm is None else np.asarray(offsets_mm, float)
    worst = np.empty(n_draws)
    M = Js.transpose(1, 0, 2).reshape(len(t), -1)          # (K, P*3)
    for a in range(0, n_draws, chunk):
        m = min(chunk, n_draws - a)
        if dist == "uniform":
            E = rng.uniform(-1.0, 1.0, (m, len(t))) * t
        elif dist == "normal":
            E = rng.standard_normal((m, len(t))) * (t / 3.0)
        else:
            raise ValueError(f"unknown distribution {dist!r}")
        d = (E @ M).reshape(m, Js.shape[0], 3) + off
        worst[a:a + m] = np.linalg.norm(d, axis=2).max(axis=1)
    return {"yield": float(np.mean(worst <= delta_E_mm)), "n_draws": int(n_draws), "dist": dist,
            "p99_mm": float(np.quantile(worst, 0.99)), "max_mm": float(worst.max())}


def sensitivity(t, Js) -> dict:
    """Per-component sensitivity |J_k| and share of the RSS variance, worst pose.

    Parameters
    ----------
    t : array_like, shape (K,)
        Tolerances [mm, rad].
    Js : array_like, shape (P, K, 3)
        Sensitivities at each pose [mm/mm, mm/rad].

    Returns
    -------
    dict
        ``gain`` (K,) max over poses of |J_k| [mm/mm or mm/rad]; ``contribution_mm`` (K,)
        t_k·gain_k; ``variance_share`` (K,) t_k²·gain_k² / Σ (sums to 1).

    Examples
    --------
    >>> s = sensitivity([1e-3, 1e-6], [[[1, 0, 0], [0, 500, 0]]])
    >>> s["gain"].tolist(), [round(float(v), 3) for v in s["variance_share"]]
    ([1.0, 500.0], [0.8, 0.2])
    """
    t = np.asarray(t, float)
    Js = np.asarray(Js, float)
    if Js.ndim == 2:
        Js = Js[None]
    gain = np.linalg.norm(Js, axis=2).max(axis=0)
    c = t * gain
    tot = np.sum(c ** 2)
    share = c ** 2 / tot if tot > 0 else np.zeros_like(c)
    return {"gain": gain, "contribution_mm": c, "variance_share": share}
