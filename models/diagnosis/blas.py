"""One BLAS thread for the diagnosis's many small dense solves.

The diagnosis solves thousands of small least-squares problems (an 11 000 × 6 matrix
per trial of a rate search on the real record). A multi-threaded BLAS splits each
into threads whose start-up and spin-waiting cost more than the work: on the 2-core
machine of issue 30, ``numpy.linalg.lstsq`` of an 8000 × 6 matrix took 5.0 ms of CPU
(25 ms wall at load 16) with OpenBLAS's 2 threads against 0.39 ms (1.3 ms wall) with
one -- the largest part of the 8-30× slowdown users measured on the real record.
The same holds for any parallelism over processes (``--jobs``): one thread each.

Single-threaded BLAS gives the same numbers here: the diagnosis of the real record
and of the generated batch was compared before and after (issue 30, report).
"""
from __future__ import annotations

import functools

__all__ = ["one_blas_thread"]


def one_blas_thread(fn):
    """Decorator: run ``fn`` with the BLAS/OpenMP thread pools limited to one thread
    (``threadpoolctl``), restoring the caller's limits afterwards.

    Examples
    --------
    >>> from threadpoolctl import threadpool_info
    >>> @one_blas_thread
    ... def threads():
    ...     return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}
    >>> threads() <= {1}
    True
    """
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from threadpoolctl import threadpool_limits
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)
    return wrapper
