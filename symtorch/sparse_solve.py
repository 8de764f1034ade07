"""Factor once, solve many times: the sparse symmetric positive-definite systems of the spectrum.

The shift-invert Lanczos of :func:`symtorch.spectrum.generalized_eigsh` applies ``(W - sigma M)^-1``
about 280 times for 110 eigenpairs. CHOLMOD's supernodal Cholesky (through ``cholespy``, which ships
it) solves in a third to a quarter of the time of scipy's SuperLU: 0.27 against 0.79 ms a solve on a
12.5K-vertex SCAPE mesh, 2.1 against 8.6 ms on a 52K-vertex TOSCA mesh, with the same accuracy
(``python scripts/bench_spectrum.py``). SuperLU remains the fallback: where ``cholespy`` is not
installed, and where CHOLMOD finds the matrix not positive definite (CHOLMOD then prints a warning
line on stderr itself; the spectrum's shifted Laplacians never met that on the benchmarks or the
malformed-input corpus of ``tests/test_hardening.py``).
"""
from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

log = logging.getLogger(__name__)

__all__ = ["SPDFactor"]


class SPDFactor:
    """A factorisation of a sparse symmetric positive-definite matrix ``A [n, n]``.

    ``backend`` is ``"cholmod"`` or ``"superlu"`` (also for ``prefer="superlu"``). ``solve(b)``
    takes ``b [n]`` or ``[n, m]`` and returns ``A^-1 b`` of the same shape, float64.

    Raises:
        RuntimeError: SuperLU finds the matrix exactly singular (the caller may shift it and retry).
    """

    def __init__(self, A: sp.spmatrix, prefer: str = "cholmod"):
        if prefer not in ("cholmod", "superlu"):
            raise ValueError(f"prefer must be 'cholmod' or 'superlu', got {prefer!r}")
        A = sp.csc_matrix(A, dtype=np.float64)  # SuperLU's format
        self.n = A.shape[0]
        self._chol = None
        self._lu = None
        if prefer == "cholmod" and max(A.nnz, self.n) < 2 ** 31:  # cholespy takes int32 indices
            # CSR, not CSC: cholespy 2.2's CSC input path corrupts the heap once its arrays are
            # freed (a crash within a few hundred small solves, tests/test_sparse_solve.py); its
            # CSR path copies them. They are kept alive with the factor all the same.
            R = A.tocsr()
            self._csr = (R.indptr.astype(np.int32), R.indices.astype(np.int32), np.ascontiguousarray(R.data))
            self._chol = _cholmod(self.n, *self._csr)
        if self._chol is None:
            self._lu = sla.splu(A, permc_spec="COLAMD")
        self.backend = "cholmod" if self._chol is not None else "superlu"

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        if self._lu is not None:
            return self._lu.solve(b)
        shape = b.shape
        rhs = np.ascontiguousarray(b.reshape(self.n, -1) if b.ndim > 1 else b.reshape(self.n))
        x = np.empty_like(rhs)
        self._chol.solve(rhs, x)
        return x.reshape(shape)


def _cholmod(n: int, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray):
    """cholespy's CHOLMOD solver for the CSR matrix, or None (not installed, or not positive
    definite). The caller keeps the three arrays alive while the solver lives."""
    try:
        from cholespy import CholeskySolverD, MatrixType
    except ImportError:
        return None
    try:
        return CholeskySolverD(n, indptr, indices, data, MatrixType.CSR)
    except (ValueError, RuntimeError) as err:
        log.debug("CHOLMOD refused the matrix (%s); using SuperLU", err)
        return None
