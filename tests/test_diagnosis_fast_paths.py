"""The fast paths of issue 30 (the real record diagnosed in seconds) compute the same
numbers as the forms they replace: the diagnosis must not change beyond round-off."""
import numpy as np
import pytest

from arfem.models.diagnosis import stats as st
from arfem.models.diagnosis.blas import one_blas_thread
from arfem.models.diagnosis.forward import ar_columns_rates, ar_first_order


def _series(seed, n):
    rng = np.random.default_rng(seed)
    return (np.cumsum(rng.normal(size=n)) * 0.1 + 5.0,
            np.cumsum(rng.normal(size=n)) + 30.0)


@pytest.mark.parametrize("seed,n,lag", [(0, 3000, 720), (1, 500, 166), (2, 40, 39)])
def test_ccf_equals_lag_by_lag(seed, n, lag):
    """FFT + prefix sums against one xcorr per lag; 1e-12 absolute: the FFT's round-off
    on correlations bounded by 1 (measured ~1e-15)."""
    r, x = _series(seed, n)
    assert np.allclose(st.ccf(r, x, lag), st._ccf_loop(r, x, lag), rtol=0, atol=1e-12)


def test_ccf_with_gaps_uses_the_overlap_of_finite_samples():
    """A series with empty cells takes the lag-by-lag form: the same values exactly."""
    r, x = _series(3, 400)
    x[[5, 100, 250]] = np.nan
    assert np.array_equal(st.ccf(r, x, 50), st._ccf_loop(r, x, 50))


def test_acf_equals_lag_by_lag():
    """FFT autocorrelation against one dot product per lag, 1e-12 absolute (round-off)."""
    r, _ = _series(4, 5000)
    assert np.allclose(st.acf(r, 1200), st._acf_direct(r, 1200), rtol=0, atol=1e-12)


@pytest.mark.parametrize("rate_1_s", [1 / 3600.0, 1 / 60.0, 2.0, 1e-7])
def test_shared_rate_columns_are_bit_identical(rate_1_s):
    """Every column of ar_columns_rates equals its own ar_first_order exactly (not to a
    tolerance): the rate searches compare objective values, and a changed last bit
    could move a Nelder-Mead path. Rates from a 2 s to a 100-day time constant cover
    the two-term branch, several chunks and one chunk; the rate switches like a
    running/stopped spindle's."""
    rng = np.random.default_rng(5)
    n = 4000
    t = np.cumsum(rng.choice([15.0, 15.0, 30.0], n))
    b = np.repeat(np.where(rng.random(n // 100 + 1) < 0.5, rate_1_s, 0.3 * rate_1_s), 100)[:n]
    U = rng.random((n, 4))
    X = ar_columns_rates(t, U, b)
    for j in range(U.shape[1]):
        assert np.array_equal(X[:, j], ar_first_order(t, U[:, j], b, 1.0))


def test_one_blas_thread_limits_and_restores():
    """Inside: at most one BLAS thread; after: the caller's limits again."""
    from threadpoolctl import threadpool_info

    def blas_threads():
        return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]
    before = blas_threads()
    inside = one_blas_thread(blas_threads)()
    assert all(n == 1 for n in inside)
    assert blas_threads() == before


def test_api_diagnose_reports_progress_to_a_callable():
    """arfem.diagnose(..., progress=callable) hears each slow step as it starts, in order
    (issue 30: a real record's diagnosis ran for minutes with nothing shown)."""
    import pandas as pd
    import arfem
    from arfem.models.diagnosis.synth import generate
    case = generate("sensor_drift", 11)
    df = pd.DataFrame({"time_s": case.time_s, "q_W_m2": case.q_W_m2,
                       "growth_um": case.growth_um})
    steps = []
    arfem.diagnose(df, progress=steps.append)
    assert steps[0] == "reading the dataset"
    assert any(s.startswith("fitting") and "single causes" in s for s in steps)
    assert steps.index("residuals and hold-out") > max(
        i for i, s in enumerate(steps) if s.startswith("fitting"))
