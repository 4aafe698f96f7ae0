"""One place that chooses how arfem factors its symmetric positive definite matrices.

Every matrix arfem factors -- the θ-method's M + θΔt(K + hB), the conductance
K + hB of the reduced-modal solve, the elastic stiffness -- is symmetric positive
definite. SuperLU (SciPy's :func:`scipy.sparse.linalg.splu`) treats them as general
matrices by default: a column ordering for A (COLAMD) and partial pivoting, so its
L and U do not mirror each other and the fill is larger than a symmetric ordering
would give. For an SPD matrix no pivoting is needed, so arfem

1. orders the unknowns by METIS nested dissection of the matrix graph
   (:func:`pymetis.nested_dissection`), a symmetric fill-reducing ordering, and
2. factors the permuted matrix with SuperLU keeping the natural order and the
   diagonal pivots (``permc_spec="NATURAL"``, ``diag_pivot_thresh=0``,
   ``SymmetricMode``). With diagonal pivots, A = L D Lᵀ and U = D Lᵀ: the
   factorisation *is* a Cholesky (LDLᵀ) one, stored by SuperLU's supernodal kernels.

scikit-sparse/CHOLMOD was the first choice, but PyPI has no wheel of it for any
platform (it builds from source against SuiteSparse); `qdldl` has wheels but its
triangular solves ran 1.5× slower than SuperLU's on arfem's matrices. pymetis ships
wheels for Linux and macOS; where it is absent (Windows), arfem falls back to
SuperLU's own COLAMD ordering with partial pivoting -- the general LU arfem used
before, slower but identical to round-off.

Measured on the 9948-dof 20-node CN matrix of the paper cycle (one BLAS thread,
``benchmarks/bench_fem.py --cases 3d-theta-10k``): nnz(L+U) 6.30 M → 4.89 M and one
solve 6.8 ms → 4.4 ms, i.e. the 2880-step Crank–Nicolson solve 1.55× faster.

Where a matrix is factored for a handful of solves only (the reduced-modal solve's
conductance), the factorisation is the cost. There, when the optional ``fast`` extra
is installed (``pypardiso``, Intel MKL's PARDISO: wheels for Linux and Windows on
x86-64), :func:`default_method` with ``few_solves=True`` picks a true sparse Cholesky
for matrices of at least :data:`PARDISO_MIN_DOFS` unknowns:
at 38 545 dofs (20-node bricks, one thread) PARDISO factors in 1.0–1.4 s where METIS +
SuperLU take 3.0 s. Its triangular solves are slower than SuperLU's (34 ms against
28 ms there), so the θ-method, which solves 2880 times, keeps SuperLU.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["SPDFactor", "factorize_spd", "default_method", "METHODS"]

#: ``"symmetric"``: METIS nested dissection + diagonal pivots (needs pymetis);
#: ``"lu"``: SuperLU's COLAMD + partial pivoting (always available);
#: ``"pardiso"``: MKL PARDISO's sparse Cholesky (needs the optional pypardiso).
METHODS = ("symmetric", "lu", "pardiso")


def _metis():
    try:
        import pymetis  # noqa: F401
    except ImportError:          # pragma: no cover - exercised where pymetis is absent
        return None
    return pymetis


def _pardiso():
    try:
        import pypardiso
    except ImportError:          # pragma: no cover - the default install has no MKL
        return None
    return pypardiso


#: Smallest order at which PARDISO is chosen for few solves: below it MKL's start-up
#: (about 0.3 s) outweighs the faster factorisation (at 9948 dofs the reduced solve
#: took 0.66 s with PARDISO and 0.44 s with SuperLU; at 38 545, 1.95 s and 3.58 s).
PARDISO_MIN_DOFS = 20_000


def default_method(few_solves: bool = False, n: int | None = None) -> str:
    """The factorisation arfem uses: the one place where it is chosen.

    Parameters
    ----------
    few_solves : bool
        The factor serves a handful of solves, so factoring dominates: PARDISO where
        the optional pypardiso is importable and the order ``n`` is at least
        :data:`PARDISO_MIN_DOFS`. Otherwise, and for many solves, ``"symmetric"``
        where pymetis is importable, else ``"lu"``.
    n : int, optional
        Order of the matrix (default: large).

    >>> default_method() in METHODS and default_method(few_solves=True) in METHODS
    True
    >>> default_method(few_solves=True, n=500) == default_method()
    True
    """
    if few_solves and (n is None or n >= PARDISO_MIN_DOFS) and _pardiso() is not None:
        return "pardiso"
    return "symmetric" if _metis() is not None else "lu"


def nested_dissection(A: sp.spmatrix) -> np.ndarray:
    """METIS nested-dissection ordering of the graph of the symmetric matrix ``A``.

    Parameters
    ----------
    A : scipy.sparse matrix, shape (n, n)
        Symmetric sparsity pattern (values are ignored).

    Returns
    -------
    ndarray of int, shape (n,)
        ``perm``: row/column ``perm[i]`` of ``A`` becomes row/column ``i``.
    """
    import warnings

    pymetis = _metis()
    S = sp.csr_matrix(A, copy=True)
    S.setdiag(0.0)
    S.eliminate_zeros()
    xadj = S.indptr.astype(np.int64)
    adjncy = S.indices.astype(np.int64)
    with warnings.catch_warnings():          # pymetis 2025 prefers a CSRAdjacency object;
        warnings.simplefilter("ignore")      # the xadj/adjncy form works on every release
        if hasattr(pymetis, "CSRAdjacency"):
            perm, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(xadj, adjncy))
        else:                                # pragma: no cover - older pymetis
            perm, _ = pymetis.nested_dissection(xadj=xadj, adjncy=adjncy)
    return np.asarray(perm, dtype=np.int64)


@dataclass(frozen=True)
class SPDFactor:
    """A factored SPD matrix: ``solve(b)`` returns A⁻¹b.

    Attributes
    ----------
    method : str
        ``"symmetric"`` or ``"lu"`` (see :data:`METHODS`).
    n : int
        Order of the matrix.
    nnz : int
        Stored entries of the factors, nnz(L) + nnz(U).
    """

    method: str
    n: int
    nnz: int
    _lu: object
    _perm: np.ndarray | None
    _iperm: np.ndarray | None

    def solve(self, b: np.ndarray) -> np.ndarray:
        """A⁻¹b for one right-hand side (n,) or several (n, k)."""
        if self._perm is None:
            return self._lu.solve(b)
        return self._lu.solve(b[self._perm])[self._iperm]


def factorize_spd(A: sp.spmatrix, method: str | None = None) -> SPDFactor:
    """Factor the symmetric positive definite sparse matrix ``A`` once.

    Parameters
    ----------
    A : scipy.sparse matrix, shape (n, n)
        Symmetric positive definite (not checked; a matrix that is not SPD may
        meet a zero pivot on the ``"symmetric"`` path).
    method : {"symmetric", "lu", "pardiso"}, optional
        Default :func:`default_method` (for many solves).

    Returns
    -------
    SPDFactor

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> A = sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(50, 50)).tocsc()
    >>> b = np.arange(50.0)
    >>> x_sym = factorize_spd(A, "symmetric").solve(b)
    >>> x_lu = factorize_spd(A, "lu").solve(b)
    >>> bool(np.allclose(x_sym, x_lu, rtol=1e-13, atol=0))
    True
    """
    method = default_method() if method is None else method
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if method == "pardiso" and _pardiso() is None:
        raise ValueError("method 'pardiso' needs the optional pypardiso "
                         "(pip install 'arfem[fast]')")
    A = sp.csc_matrix(A)
    n = A.shape[0]
    if method == "pardiso" and n >= 3:
        fac = _PardisoCholesky(A)
        return SPDFactor("pardiso", n, fac.nnz, fac, None, None)
    if method == "lu" or n < 3:
        lu = splu(A)
        return SPDFactor("lu", n, int(lu.L.nnz + lu.U.nnz), lu, None, None)
    perm = nested_dissection(A)
    iperm = np.empty_like(perm)
    iperm[perm] = np.arange(n)
    lu = splu(A[perm][:, perm].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
              options={"SymmetricMode": True})
    return SPDFactor("symmetric", n, int(lu.L.nnz + lu.U.nnz), lu, perm, iperm)


class _PardisoCholesky:
    """MKL PARDISO's sparse Cholesky (mtype 2, real SPD) of one matrix, by pypardiso.

    PARDISO reads the upper triangle in CSR form; its memory is released when this
    object is collected.
    """

    def __init__(self, A: sp.spmatrix):
        import weakref

        pypardiso = _pardiso()
        self._U = sp.triu(A, format="csr")
        self._U.sort_indices()
        self._solver = pypardiso.PyPardisoSolver(mtype=2)
        self._solver.factorize(self._U)
        self.nnz = int(self._solver.iparm[17])     # iparm(18): non-zeros in the factor
        weakref.finalize(self, self._solver.free_memory, True)

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._solver.solve(self._U, np.asarray(b, dtype=float))
