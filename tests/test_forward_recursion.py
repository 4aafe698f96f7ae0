"""The exact modal recursion of the reduced rod (:func:`arfem.models.diagnosis.forward.linear_recursion`).

Properties verified: it is the recursion x_n = a_n x_{n-1} + b_n (against the plain
sequential loop, to 1e-12 of max|b|: its chunked closed form is exact up to rounding),
and running the columns together changes no bit of any column (the all-mode rod runs
~440 columns at once; each column's answer must not depend on its neighbours).
"""
import numpy as np

from arfem.models.diagnosis.forward import linear_recursion


def _sequential(a, b, x0):
    out = np.empty_like(b)
    x = np.array(x0, float)
    for i in range(b.shape[0]):
        x = a[i] * x + b[i]
        out[i] = x
    return out


def _record(seed):
    """Uneven steps with long gaps, decay rates from 1e-6 to 50 1/s, and a step that
    decays to exactly 0: every chunking path (long, cut, two-term, zero)."""
    rng = np.random.default_rng(seed)
    d = rng.choice([1.0, 30.0, 60.0, 3000.0, 20000.0], size=1500, p=[.1, .6, .2, .08, .02])
    lam = np.array([1e-6, 1e-4, 3e-3, 0.02, 0.3, 1.5, 50.0])
    a = np.exp(-np.outer(d, lam))
    a[700, 2] = 0.0
    return a, rng.normal(size=a.shape), rng.normal(size=lam.size)


def test_recursion_matches_the_sequential_loop():
    for seed in (1, 2):
        a, b, x0 = _record(seed)
        got = linear_recursion(a, b, x0)
        ref = _sequential(a, b, x0)
        assert np.max(np.abs(got - ref)) <= 1e-12 * np.max(np.abs(b)) * 10


def test_each_column_alone_gives_the_same_bits():
    a, b, x0 = _record(3)
    together = linear_recursion(a, b, x0)
    for k in range(b.shape[1]):
        alone = linear_recursion(a[:, k:k + 1], b[:, k:k + 1], x0[k:k + 1])
        assert np.array_equal(alone[:, 0], together[:, k])


def test_fast_columns_after_a_zero_first_interval_are_the_loop_bit_for_bit():
    """A record whose first row is at t = 0 (a zero interval: a = 1, b = 0) and whose
    fast modes decay past e^-36 on every later step, with the input off for long
    stretches (b = 0: the state decays to exactly 0 through subnormal numbers): those
    columns are the plain loop (:func:`_plain_recursion`), so they must equal it in
    every bit, not only to rounding."""
    rng = np.random.default_rng(7)
    d = rng.choice([0.0, 30.0, 40.0], size=1200, p=[.05, .6, .35])
    d[:2] = 0.0
    lam = np.array([0.95, 3.5, 50.0, 1e3])         # λ·Δτ 28.5-38 (mixed), then > 36
    a = np.exp(-np.outer(d, lam))
    f = rng.normal(size=a.shape)
    f[300:700] = 0.0
    f[rng.random(d.size) < 0.3] = 0.0
    b = (1.0 - a) * f
    x0 = rng.normal(size=lam.size)
    got, ref = linear_recursion(a, b, x0), _sequential(a, b, x0)
    assert np.array_equal(got[:, 1:], ref[:, 1:])
    assert np.max(np.abs(got[:, 0] - ref[:, 0])) <= 1e-12 * np.max(np.abs(b))


def test_chunk_carry_fixed_point_is_the_loop_bit_for_bit():
    """Many chunks per column (the all-mode rod's mid-speed modes): the carry runs as a
    fixed point over the chunks (:func:`_chunk_carry`), which must give the loop over
    the chunks (:func:`_chunk_carry_loop`) in every bit, input-free stretches (b = 0,
    S = 0: a value carried on through tiny decays) and one-row chunks (NaN P) included."""
    from arfem.models.diagnosis.forward import _chunk_carry, _chunk_carry_loop
    rng = np.random.default_rng(11)
    count = rng.integers(1, 120, size=200)
    col = np.repeat(np.arange(count.size), count)
    n = col.size
    a_first = np.exp(-rng.uniform(0.0, 60.0, n))
    b_first = rng.normal(size=n)
    P = np.exp(-rng.uniform(5.0, 400.0, n))
    S = rng.normal(size=n)
    off = rng.random(n) < 0.4
    b_first[off], S[off] = 0.0, 0.0
    P[rng.random(n) < 0.3] = np.nan                  # one-row chunks
    x0 = rng.normal(size=count.size)
    assert n >= 30 * count.max()                     # the fixed-point path
    got = _chunk_carry(a_first, b_first, np.array([P, S]), col, x0)
    ref = _chunk_carry_loop(a_first, b_first, np.array([P, S]), col, x0)
    assert np.array_equal(got, ref)
