"""Fast forward models for the diagnosis: the FEM rod reduced exactly to its growth modes,
and the continuous-time AR(1) family a compensation controller would run.

Reduced FEM (:class:`RodModel`)
-------------------------------
On the structured axisymmetric mesh the matrices are tensor products in (r, z), and
with a lateral h that is uniform along the rod the axially uniform eigenvectors
φ = v(r) ⊗ 1(z) of (K + hB)φ = μMφ are exact. The growth functional α∫θdV/A is
orthogonal to every other mode, so the growth response to the end flux and to the
ambient lives *exactly* in the span of the axially uniform modes (2·nr + 1 of them for
Q2). :class:`RodModel` keeps those modes of the nominal h; a different h (or an h that
switches) is the small symmetric matrix
diag(μ0) + (h − h0) ΦᵀBΦ in that closed subspace -- no truncation error (an h that
varies along the surface couples the axial modes:
:mod:`arfem.models.diagnosis.local_convection`). A forward run
is then a handful of first-order recursions (paper eq. 12 per mode), milliseconds
for a 72 h record.

AR(1) family (:func:`ar_first_order`)
-------------------------------------
ΔL_n = C1_n ΔL_{n-1} + C2_n with C1_n = exp(−b Δτ_n) and C2_n = K u_n (1 − C1_n) --
paper eqs. 12-14 written for uneven steps Δτ_n, so gaps in the record are exact.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.signal import lfilter

from arfem.fem.heat import build_axisymmetric, modes
from arfem.params import Rod

__all__ = ["RodModel", "intervals", "first_order_lag", "ar_first_order", "ar_columns",
           "ar_columns_rates", "linear_recursion"]


def intervals(time_s) -> np.ndarray:
    """Length of the interval that ends at each sample [s] (the first starts at t = 0).

    Parameters
    ----------
    time_s : array_like
        Sample times [s], increasing, >= 0.

    Returns
    -------
    ndarray
        Δτ_n = t_n − t_{n−1} with t_{−1} = 0 [s] (zero for a first row at t = 0).

    Examples
    --------
    >>> intervals([0.0, 30.0, 90.0]).tolist()
    [0.0, 30.0, 60.0]
    """
    t = np.asarray(time_s, float)
    return np.diff(np.concatenate([[0.0], t]))


def linear_recursion(a: np.ndarray, b: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """x_n = a_n x_{n-1} + b_n for every column (mode); returns x after each step.

    Vectorised and exact for varying a_n in (0, 1]: within a chunk where the
    accumulated decay −Σ ln a stays below e^±500, x_n = P_n (x_s + Σ_k b_k / P_k) with
    P_n = Π a_j; every term P_n b_k / P_k = b_k Π_{j>k} a_j is bounded by |b_k|, so the
    rounding error stays at machine precision of max|b|. Columns whose every step
    decays by more than e^-36 keep two terms, x_n = b_n + a_n b_{n-1} (the rest is
    below double precision).

    Each column has its own chunks (:func:`_chunks`); the chunks of every column are
    run at once, grouped by length (:func:`_chunk_sums`), and only the carry from one
    chunk to the next is a loop (on scalars): the same floating-point operations per
    element as a loop over columns and chunks, so the same bits, at a fraction of the
    interpreter's overhead (the all-mode rod of :mod:`.local_convection` has ~440
    columns: 0.75 s per record as a loop over columns, issue 41's speed target).

    Parameters
    ----------
    a : numpy.ndarray
        (n, m) decay per step and column, in (0, 1] (dimensionless).
    b : numpy.ndarray
        (n, m) increment per step and column, in the unit of x.
    x0 : numpy.ndarray
        (m,) state before the first step, in the unit of x.

    Returns
    -------
    numpy.ndarray
        (n, m): x_1 … x_n, in the unit of x.
    """
    n, m = b.shape
    out = np.empty((n, m))
    if n == 0:
        return out
    with np.errstate(divide="ignore"):
        la = np.log(np.maximum(a, 1e-300))
    two = np.all(la < -36.0, axis=0)
    if two.any():
        k = np.flatnonzero(two)
        x = b[:, k].copy()
        x[0] += a[0, k] * x0[k]
        x[1:] += a[1:, k] * b[:-1, k]
        out[:, k] = x
    # columns whose every step either decays by more than e^-36 or is a zero-length
    # interval that adds nothing (a = 1, b = 0; e.g. a first row at t = 0): the chunks
    # are the single rows, i.e. the plain loop, computed as such (:func:`_plain_recursion`)
    plain = ~two & np.all((la < -36.0) | ((a == 1.0) & (b == 0.0)), axis=0)
    if plain.any():
        k = np.flatnonzero(plain)
        out[:, k] = _plain_recursion(a[:, k], b[:, k], x0[k])
    cols = np.flatnonzero(~two & ~plain)
    if cols.size == 0:
        return out
    # each column's rows contiguous, and one zero past the end for the padding
    step = np.append(-la[:, cols].T.ravel(), 0.0)
    bT = np.append(b[:, cols].T.ravel(), 0.0)
    col, s, e = _chunks(step[:-1].reshape(cols.size, n))
    groups, last = _chunk_sums(step, bT, col * n + s, e - s - 1)
    first = col * n + s
    xs = _chunk_carry(a[s, cols[col]], bT[first], last, col, x0[cols])
    flat = np.empty(cols.size * n + 1)
    flat[first] = xs
    for idx, j, P, S in groups:
        flat[idx] = P * (xs[j][:, None] + S)
    out[:, cols] = flat[:-1].reshape(cols.size, n).T
    return out


def _plain_recursion(a: np.ndarray, b: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """x_n = a_n x_{n-1} + b_n, the sequential loop's own operations (a product, then a
    sum) and so its bits, for columns whose decay a_n is either below e^-36 or a zero
    interval's 1 (with b_n = 0) on every row: where :func:`_chunks` makes every row a
    chunk of its own and :func:`_chunk_carry` runs the loop one row at a time (the fast
    modes of the all-mode rod of :mod:`.local_convection`: ~430 columns x ~3000 rows).

    Vectorised as a fixed point: one sweep x ← a · shift(x) + b over every row from
    x = b, then sweeps over the rows after those that changed, until none changes. A
    sequence that the loop's step leaves unchanged bit for bit is the loop's (by
    induction on the rows: each row is then the loop's product and sum of the previous
    row's loop value), and a row's value is final once its predecessor's is, so the
    sweeps end. A decay below e^-36 forgets a changed row within rounding, except where
    b = 0 (no input): there the state decays to exactly 0 within ~20 rows, and the
    sweeps after the first touch only those rows."""
    prev = np.empty_like(b)
    prev[0] = x0
    prev[1:] = b[:-1]
    x = a * prev + b
    return _sweep_to_fixed_point(x, np.flatnonzero(np.any(x != b, axis=1)) + 1,
                                 lambda rows: a[rows] * x[rows - 1] + b[rows])


def _sweep_to_fixed_point(x: np.ndarray, rows: np.ndarray, step, first=None) -> np.ndarray:
    """The sweeps that finish :func:`_plain_recursion` and :func:`_chunk_carry` after
    their first: x[r] ← ``step(r)`` over the rows ``rows`` (those after a row the first
    sweep changed), then over the rows after those that changed, until none changes;
    ``x`` is updated in place and returned. ``step(r)`` computes rows ``r`` from
    ``x[r - 1]`` (the loop's operations), so a row is final once its predecessor is.
    ``first`` (bool per row): rows that start a sequence of their own (a column's first
    chunk), never swept again. A row of a 2-D ``x`` changes where any column does."""
    n = x.shape[0]
    while True:
        rows = rows[rows < n]
        if first is not None:
            rows = rows[~first[rows]]
        if rows.size == 0:
            return x
        new = step(rows)
        changed = new != x[rows]
        if changed.ndim > 1:
            changed = np.any(changed, axis=1)
        x[rows] = new
        rows = rows[changed] + 1


def _chunks(step: np.ndarray) -> tuple:
    """The chunks of :func:`linear_recursion`, per row of ``step`` = −ln a (m, n)
    (a column's steps): (column, first row, end row) of every chunk, each column's in
    order. A chunk ends where the column's accumulated decay c (each step counted at
    most 36) first passes a multiple of 400 (the first row with c > 400 k, k >= 1,
    as ``np.searchsorted(c, 400 k, side="right")``), and before a step that decays by
    more than e^-36."""
    m, n = step.shape
    cum = np.cumsum(np.minimum(step, 36.0), axis=1)
    prev = cum[:, :-1]
    # the least multiple 400 k >= the previous row's c (k >= 1), exactly
    k = np.maximum(np.ceil(prev / 400.0), 1.0)
    k = np.where(400.0 * k < prev, k + 1.0, k)
    k = np.where((k > 1.0) & (400.0 * (k - 1.0) >= prev), k - 1.0, k)
    cut = np.zeros((m, n + 1), bool)
    cut[:, 1:n] = (400.0 * k < cum[:, 1:]) | (step[:, 1:] > 36.0)
    cut[:, 0] = cut[:, n] = True
    col, pos = np.nonzero(cut)
    ends = np.flatnonzero(pos != 0)          # every cut but a column's first opens a chunk
    return col[ends], pos[ends - 1], pos[ends]


def _chunk_sums(step: np.ndarray, b: np.ndarray, first: np.ndarray, rest: np.ndarray):
    """Within every chunk after its first element: P = exp(−c) and S = Σ b_k e^{c_k},
    c the chunk's accumulated decay (a cumulative sum along each chunk, as a 1-D
    ``np.cumsum`` of the chunk, so bit for bit). ``step`` and ``b`` are flat, each
    column's rows contiguous, with a trailing 0 that pads; a chunk starts at flat index
    ``first`` and has ``rest`` more elements. Chunks are stacked in groups of lengths
    up to a power of two. Returns ([(flat indices (the pad's where past the chunk),
    chunk index, P, S) per group], (P, S) at each chunk's last element (NaN for a
    one-element chunk))."""
    pad = step.size - 1
    last = np.full((2, first.size), np.nan)
    groups = []
    width = np.where(rest > 0, 2 ** np.ceil(np.log2(np.maximum(rest, 1))), 0).astype(int)
    for w in np.unique(width[width > 0]):
        j = np.flatnonzero(width == w)
        off = np.arange(1, w + 1)
        idx = np.where(off[None, :] <= rest[j, None], first[j, None] + off[None, :], pad)
        c = np.cumsum(step[idx], axis=1)
        P = np.exp(-c)
        S = np.cumsum(b[idx] * np.exp(c), axis=1)
        i = np.arange(j.size)
        last[0, j], last[1, j] = P[i, rest[j] - 1], S[i, rest[j] - 1]
        groups.append((idx, j, P, S))
    return groups, last


def _chunk_carry(a_first, b_first, last, col, x0) -> np.ndarray:
    """Each chunk's first value x_s = a_s x_prev + b_s, x_prev the previous chunk's
    last value (P (x_s + S) at its last row; x0 before a column's first chunk): the
    one sequential part of :func:`linear_recursion` (chunks in column order, each
    column's in row order). With few chunks per column, a loop over the chunks on
    Python floats (IEEE doubles, the loop's operations; the growth modes of
    :class:`RodModel`: ~6000 chunks, 190 in the fastest column); with many, the loop
    vectorised as a fixed point (:func:`_plain_recursion`'s argument): one sweep over
    every chunk from x_s = b_s, then sweeps over the chunks after those that changed,
    until none changes. A chunk's value is the loop's once its predecessor's is, and
    the step from one chunk to the next decays by more than e^-36 (a chunk ends where
    its decay passes 400 or before a step past e^-36), so the later sweeps touch only
    the few chunks after the input-free stretches (the ~280 mid-speed modes of the
    all-mode rod: ~90 000 chunks, where a loop over the chunks' ordinal ran ~3000
    vectorised steps)."""
    n_chunks = col.size
    start = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])      # each column's first
    count = np.diff(np.r_[start, n_chunks])
    if n_chunks < 30 * count.max():
        return _chunk_carry_loop(a_first, b_first, last, col, x0)
    first = np.zeros(n_chunks, bool)
    first[start] = True
    one = np.isnan(last[0])

    def carried(p):
        """The value that chunk p hands to the next (its last row's)."""
        return np.where(one[p], xs[p], last[0, p] * (xs[p] + last[1, p]))
    xs = b_first.copy()
    prev = np.asarray(x0, float)[col]
    k = np.flatnonzero(~first)
    prev[k] = carried(k - 1)
    new = a_first * prev + b_first
    rows = np.flatnonzero(new != xs) + 1
    xs = new
    return _sweep_to_fixed_point(xs, rows,
                                 lambda r: a_first[r] * carried(r - 1) + b_first[r], first)


def _chunk_carry_loop(a_first, b_first, last, col, x0) -> np.ndarray:
    """:func:`_chunk_carry` as a loop over the chunks, on Python floats."""
    a_l, b_l = a_first.tolist(), b_first.tolist()
    P_l, S_l = last[0].tolist(), last[1].tolist()
    x0_l, col_l = np.asarray(x0, float).tolist(), col.tolist()
    xs = [0.0] * len(a_l)
    prev_col, x_prev = -1, 0.0
    for i, k in enumerate(col_l):
        if k != prev_col:
            x_prev, prev_col = x0_l[k], k
        x = a_l[i] * x_prev + b_l[i]
        xs[i] = x
        x_prev = x if P_l[i] != P_l[i] else P_l[i] * (x + S_l[i])
    return np.array(xs)


def _shared_recursion(a: np.ndarray, b: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """:func:`linear_recursion` for columns that share one decay a_n (shape (n,)):
    every column in one pass, with the same chunks and the same floating-point
    operations per element, so each column equals its own :func:`linear_recursion`
    bit for bit (the steady-gain columns of a speed-only fit all decay at one rate;
    issue 30: one recursion per column was a third of a real record's diagnosis)."""
    n, m = b.shape
    out = np.empty((n, m))
    if n == 0:
        return out
    with np.errstate(divide="ignore"):
        la = np.log(np.maximum(a, 1e-300))
    if np.all(la < -36.0):
        x = b.copy()
        x[0] += a[0] * x0
        x[1:] += a[1:, None] * b[:-1]
        return x
    step = -la
    cum = np.cumsum(np.minimum(step, 36.0))
    cuts = set(np.searchsorted(cum, np.arange(400.0, cum[-1], 400.0), side="right").tolist())
    cuts |= set((np.flatnonzero(step > 36.0)).tolist())
    bounds = sorted({0, n} | {c for c in cuts if 0 < c < n})
    x_prev = np.asarray(x0, float)
    for s, e in zip(bounds[:-1], bounds[1:]):
        xs = a[s] * x_prev + b[s]
        out[s] = xs
        if e - s > 1:
            c = np.cumsum(step[s + 1:e])
            P = np.exp(-c)
            S = np.cumsum(b[s + 1:e] * np.exp(c)[:, None], axis=0)
            out[s + 1:e] = P[:, None] * (xs + S)
        x_prev = out[e - 1].copy()
    return out


def ar_columns_rates(time_s, U, b_1_s) -> np.ndarray:
    """Unit-gain AR(1) responses of several inputs at one rate b_n per interval (which
    may switch), in one call: column j equals ``ar_first_order(time_s, U[:, j], b_1_s,
    1.0)`` for an array ``b_1_s``, bit for bit.

    Parameters
    ----------
    time_s : array_like
        Sample times [s].
    U : array_like, shape (n, m)
        m inputs held over the interval ending at each sample.
    b_1_s : array_like, shape (n,)
        Rate b on each interval [1/s].

    Returns
    -------
    ndarray, shape (n, m)
        Responses from 0 at t = 0.

    Examples
    --------
    >>> t = np.arange(1, 7) * 60.0
    >>> b = np.array([1e-3, 1e-3, 5e-4, 5e-4, 1e-3, 1e-3])
    >>> U = np.column_stack([np.ones(6), np.arange(6.0)])
    >>> X = ar_columns_rates(t, U, b)
    >>> bool(np.array_equal(X[:, 1], ar_first_order(t, U[:, 1], b, 1.0)))
    True
    """
    d = intervals(time_s)
    U = np.asarray(U, float)
    a = np.exp(-np.asarray(b_1_s, float) * d)
    return _shared_recursion(a, U * (1.0 - a)[:, None], np.zeros(U.shape[1]))


def first_order_lag(time_s, u, tau_s: float, y0: float = 0.0) -> np.ndarray:
    """First-order lag τ y' = u − y of a zero-order-hold input, exact for uneven steps.

    Parameters
    ----------
    time_s : array_like
        Sample times [s] (the first interval starts at t = 0).
    u : array_like
        Input held over the interval ending at each sample [any unit].
    tau_s : float
        Time constant τ [s], > 0.
    y0 : float
        y at t = 0.

    Returns
    -------
    ndarray
        y at each sample, in the unit of ``u``.

    Examples
    --------
    >>> y = first_order_lag([3600.0, 7200.0], [1.0, 1.0], 3600.0)
    >>> np.round(y, 4).tolist()     # 1 - e^-1, 1 - e^-2
    [0.6321, 0.8647]
    """
    d = intervals(time_s)
    a = np.exp(-d / float(tau_s))[:, None]
    b = ((1.0 - a[:, 0]) * np.asarray(u, float))[:, None]
    return linear_recursion(a, b, np.array([y0]))[:, 0]


def ar_first_order(time_s, u, b_1_s, gain, x0: float = 0.0) -> np.ndarray:
    """AR(1) of paper eq. 12 with C1 = e^{−bΔτ}, C2 = gain·u·(1 − C1) (eqs. 13-14).

    Parameters
    ----------
    time_s : array_like
        Sample times [s].
    u : array_like
        Input on the interval ending at each sample (e.g. q [W/m²]).
    b_1_s : float or array_like
        Rate b [1/s] (scalar, or per interval for a switching C1).
    gain : float
        Steady growth per unit input [µm per unit of ``u``] (qαa/(λb) per q in eq. 14).
    x0 : float
        ΔL at t = 0 [µm].

    Returns
    -------
    ndarray
        ΔL at each sample [µm].

    Examples
    --------
    >>> from arfem.models.ar1 import c1_paper, c2_paper, steady_growth_m
    >>> rod = Rod()
    >>> g = ar_first_order([30.0, 60.0], [2000.0, 2000.0], rod.fin_rate_1_s,
    ...                    steady_growth_m(rod, 1.0) * 1e6)
    >>> bool(abs(g[0] - c2_paper(rod, 30.0, 2000.0) * 1e6) < 1e-12)
    True
    """
    if np.ndim(b_1_s) == 0:
        return ar_columns(time_s, float(gain) * np.asarray(u, float)[:, None], float(b_1_s),
                          [x0])[:, 0]
    d = intervals(time_s)
    a = np.exp(-np.asarray(b_1_s, float) * d)[:, None]
    c2 = (float(gain) * np.asarray(u, float) * (1.0 - a[:, 0]))[:, None]
    return linear_recursion(a, c2, np.array([x0]))[:, 0]


def ar_columns(time_s, U, b_1_s: float, x0=None) -> np.ndarray:
    """Unit-gain AR(1) responses (:func:`ar_first_order`) of several inputs at one rate, in
    one call -- the columns a least-squares fit of the steady gains needs. With even steps
    (after the first) the recursion runs as one IIR filter; otherwise exactly as
    :func:`linear_recursion`.

    Parameters
    ----------
    time_s : array_like
        Sample times [s].
    U : array_like, shape (n, m)
        m inputs held over the interval ending at each sample.
    b_1_s : float
        Rate b [1/s], > 0.
    x0 : array_like, shape (m,), optional
        Responses at t = 0 (default 0).

    Returns
    -------
    ndarray, shape (n, m)

    Examples
    --------
    >>> t = np.arange(1, 6) * 60.0
    >>> U = np.column_stack([np.ones(5), np.arange(5.0)])
    >>> X = ar_columns(t, U, 1e-3)
    >>> bool(np.allclose(X[:, 1], ar_first_order(t, U[:, 1], 1e-3, 1.0), atol=1e-15))
    True
    """
    d = intervals(time_s)
    U = np.asarray(U, float)
    x0 = np.zeros(U.shape[1]) if x0 is None else np.asarray(x0, float)
    a = np.exp(-float(b_1_s) * d)
    C = U * (1.0 - a)[:, None]
    if d.size > 2 and np.all(d[2:] == d[1]) and 0 < a[1] < 1:
        X = np.empty_like(C)
        X[0] = a[0] * x0 + C[0]
        X[1:], _ = lfilter([1.0], [1.0, -a[1]], C[1:], axis=0, zi=a[1] * X[:1])
        return X
    return linear_recursion(np.repeat(a[:, None], U.shape[1], axis=1), C, x0)


@dataclass(frozen=True)
class _Eig:
    lam: np.ndarray      # decay rates [1/s]
    V: np.ndarray        # eigenvectors in the reduced basis
    fq: np.ndarray       # load per unit q [W per W/m²] in eigen-coordinates
    fb: np.ndarray       # lateral load per unit (h·θ_amb) in eigen-coordinates
    g: np.ndarray        # growth per unit coordinate [µm]
    s: np.ndarray        # lateral-surface mean temperature per unit coordinate [K]


class RodModel:
    """The FEM rod reduced exactly to the modes that carry axial growth.

    Parameters
    ----------
    rod : Rod
        Geometry, material, nominal h [W/(m²·K)] and nominal ambient [°C].
    order, nr, nz : int
        Axisymmetric mesh of :func:`arfem.fem.heat.build_axisymmetric` (Q2, 4 x 24 default:
        the growth modes are radial, so nz barely matters).

    Examples
    --------
    >>> m = RodModel(Rod())
    >>> t = np.arange(1, 2881) * 30.0          # 24 h every 30 s
    >>> g = m.simulate(t, np.full(t.size, 2000.0))
    >>> round(float(g[-1]), 2)                 # steady 3D growth (1D fin theory: 21.8 µm)
    22.42
    """

    def __init__(self, rod: Rod, order: int = 2, nr: int = 4, nz: int = 24):
        self.rod = rod
        self.fem = build_axisymmetric(rod, order=order, nr=nr, nz=nz)
        h0 = rod.convection_W_m2K
        md = modes(self.fem, h0)
        self.all_modes = md          # every mode at h0 (for models that need axial ones)
        g = md.g
        keep = np.abs(g) > 1e-9 * np.max(np.abs(g))
        phi = md.phi[:, keep]
        self.h0 = h0
        self.mu0 = md.mu[keep]
        self.Bm = phi.T @ (self.fem.B @ phi)
        self.Bm = 0.5 * (self.Bm + self.Bm.T)
        self.fq = md.fq[keep]
        self.fb = md.fb[keep]
        self.g = md.g[keep] * 1e6
        self.lateral_area_m2 = float(self.fem.f_b.sum())
        self.s = self.fb / self.lateral_area_m2
        self.n_modes = int(keep.sum())
        self._cache: dict[float, _Eig] = {}

    def eig(self, h_W_m2K: float) -> _Eig:
        """Eigen-decomposition of the reduced operator at convection h [W/(m²·K)] (cached).

        The reduced operator is diag(μ0) + (h − h0) ΦᵀBΦ in the nominal growth modes.

        Parameters
        ----------
        h_W_m2K : float
            Lateral convection coefficient h [W/(m²·K)].

        Returns
        -------
        _Eig
            ``lam``: decay rates [1/s], ascending; ``V``: eigenvectors in the reduced
            basis; ``fq``: modal load per unit q [W per W/m²]; ``fb``: modal lateral
            load per unit h·θ_amb [W per W/m²]; ``g``: growth per unit coordinate
            [µm]; ``s``: lateral-surface mean temperature rise per unit coordinate [K].
        """
        h = float(h_W_m2K)
        e = self._cache.get(h)
        if e is None:
            A = np.diag(self.mu0) + (h - self.h0) * self.Bm
            lam, V = scipy.linalg.eigh(A)
            e = _Eig(lam, V, V.T @ self.fq, V.T @ self.fb, self.g @ V, self.s @ V)
            if len(self._cache) > 4096:
                self._cache.clear()
            self._cache[h] = e
        return e

    def steady_growth_um(self, q_W_m2: float = 1.0, h_W_m2K: float | None = None) -> float:
        """Steady growth [µm] under constant flux q [W/m²] at convection h.

        Parameters
        ----------
        q_W_m2 : float
            Heat flux into the heated end [W/m²]; default 1 (the steady gain).
        h_W_m2K : float, optional
            Lateral convection coefficient [W/(m²·K)]; default the rod's nominal.

        Returns
        -------
        float
            Steady axial growth at the nominal ambient [µm].
        """
        e = self.eig(self.h0 if h_W_m2K is None else h_W_m2K)
        return float(e.g @ (q_W_m2 * e.fq / e.lam))

    def slowest_rate_1_s(self, h_W_m2K: float | None = None) -> float:
        """Decay rate of the slowest growth mode [1/s] (1/time constant).

        Parameters
        ----------
        h_W_m2K : float, optional
            Lateral convection coefficient [W/(m²·K)]; default the rod's nominal.

        Returns
        -------
        float
            Smallest eigenvalue of the reduced operator [1/s].
        """
        return float(self.eig(self.h0 if h_W_m2K is None else h_W_m2K).lam[0])

    def simulate(self, time_s, q_W_m2, ambient_K=None, h_W_m2K=None, c0=None,
                 return_surface: bool = False):
        """Growth [µm] at the sample times for zero-order-hold inputs.

        Parameters
        ----------
        time_s : array_like
            Sample times [s] (the first interval starts at t = 0).
        q_W_m2 : array_like
            Heat flux on each interval [W/m²].
        ambient_K : array_like, optional
            Ambient minus the nominal ambient on each interval [K]; default 0.
        h_W_m2K : float or array_like, optional
            Convection on each interval [W/(m²·K)]; default the rod's nominal.
        c0 : array_like, optional
            Initial state in the nominal reduced basis (default 0 = equilibrium).
        return_surface : bool
            Also return the lateral-surface mean temperature rise [K].
        """
        t = np.asarray(time_s, float)
        d = intervals(t)
        q = np.asarray(q_W_m2, float)
        amb = np.zeros(t.size) if ambient_K is None else np.asarray(ambient_K, float)
        h = np.broadcast_to(np.asarray(self.h0 if h_W_m2K is None else h_W_m2K, float), t.shape)
        c = np.zeros(self.n_modes) if c0 is None else np.asarray(c0, float).copy()
        growth = np.empty(t.size)
        surf = np.empty(t.size) if return_surface else None
        change = np.flatnonzero(h[1:] != h[:-1]) + 1
        starts = np.concatenate([[0], change])
        ends = np.concatenate([change, [t.size]])
        for s, e_ in zip(starts, ends):
            hk = float(h[s])
            E = self.eig(hk)
            z = E.V.T @ c
            a = np.exp(-np.outer(d[s:e_], E.lam))
            forcing = (np.outer(q[s:e_], E.fq) + np.outer(hk * amb[s:e_], E.fb)) / E.lam
            Z = linear_recursion(a, (1.0 - a) * forcing, z)
            growth[s:e_] = Z @ E.g
            if return_surface:
                surf[s:e_] = Z @ E.s
            c = E.V @ Z[-1]
        if return_surface:
            return growth, surf
        return growth
