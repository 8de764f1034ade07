"""Tests for symtorch.sparse_solve: CHOLMOD and SuperLU give one answer; the fallbacks."""
from __future__ import annotations

import builtins

import numpy as np
import pytest
import scipy.sparse as sp

from symtorch.shapes import mirror_blob
from symtorch.sparse_solve import SPDFactor
from symtorch.spectrum import generalized_eigsh, laplacian_matrices


@pytest.fixture(scope="module")
def shifted_laplacian():
    W, mass = laplacian_matrices(*mirror_blob(3))  # 642 vertices
    mass = mass / mass.sum()
    return (W + 1e-3 * sp.diags(mass)).tocsc(), W, mass


def test_cholmod_and_superlu_solve_alike(shifted_laplacian):
    pytest.importorskip("cholespy")
    A = shifted_laplacian[0]
    chol, lu = SPDFactor(A), SPDFactor(A, prefer="superlu")
    assert (chol.backend, lu.backend) == ("cholmod", "superlu")
    rng = np.random.default_rng(0)
    for b in (rng.standard_normal(A.shape[0]), rng.standard_normal((A.shape[0], 3))):
        x, y = chol.solve(b), lu.solve(b)
        assert x.shape == b.shape and y.shape == b.shape
        assert np.linalg.norm(A @ x - b) <= 1e-9 * np.linalg.norm(A.data) * np.linalg.norm(x)
        assert np.abs(x - y).max() <= 1e-8 * np.abs(y).max()


def test_not_positive_definite_falls_back_to_superlu(shifted_laplacian):
    _, W, mass = shifted_laplacian
    A = (W - 50.0 * sp.diags(mass)).tocsc()  # indefinite (shift above the first eigenvalues), regular
    f = SPDFactor(A)
    assert f.backend == "superlu"
    b = np.ones(A.shape[0])
    assert np.allclose(A @ f.solve(b), b)


def test_without_cholespy_superlu_does_the_work(shifted_laplacian, monkeypatch):
    real_import = builtins.__import__

    def no_cholespy(name, *a, **kw):
        if name == "cholespy":
            raise ImportError("no cholespy here")
        return real_import(name, *a, **kw)

    monkeypatch.setattr(builtins, "__import__", no_cholespy)
    A = shifted_laplacian[0]
    f = SPDFactor(A)
    assert f.backend == "superlu"
    b = np.arange(f.n, dtype=float)
    x = f.solve(b)
    assert np.linalg.norm(A @ x - b) <= 1e-9 * np.linalg.norm(A.data) * np.linalg.norm(x)


def test_bad_preference_is_refused(shifted_laplacian):
    with pytest.raises(ValueError, match="prefer"):
        SPDFactor(shifted_laplacian[0], prefer="pardiso")


def test_spectrum_is_the_same_with_either_factorisation(shifted_laplacian):
    _, W, mass = shifted_laplacian
    ev1, phi1 = generalized_eigsh(W, mass, 20)
    ev2, phi2 = generalized_eigsh(W, mass, 20, solver="superlu")
    assert np.abs(ev1 - ev2).max() <= 1e-8 * ev1.max()
    # mirror_blob has a simple spectrum: each eigenvector agrees up to its sign (the sign rule, largest
    # entry positive, is a tie between mirror vertices for an antisymmetric eigenvector)
    sign = np.sign((phi1 * phi2).sum(0))
    assert np.abs(phi1 - phi2 * sign).max() < 1e-5


STRESS = """
import numpy as np, scipy.sparse as sp
from symtorch.sparse_solve import SPDFactor
from symtorch.spectrum import laplacian_matrices
from symtorch import shapes
cases = [laplacian_matrices(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]])),
         laplacian_matrices(*shapes.icosphere(0)), laplacian_matrices(*shapes.mirror_blob(1))]
for it in range(100):
    for W, mass in cases:
        F = SPDFactor(W + 1e-3 * sp.diags(mass / mass.sum()))
        for _ in range(10):
            F.solve(np.random.rand(F.n))
    junk = [np.random.rand(500) for _ in range(100)]
print(F.backend)
"""


@pytest.mark.multiprocess
def test_many_factorisations_leave_the_heap_intact():
    """cholespy 2.2's CSC input path freed memory it did not own: factorising small matrices of
    different sizes one after another corrupted the heap (glibc's checks abort the process)."""
    pytest.importorskip("cholespy")
    import os
    import subprocess
    import sys

    env = dict(os.environ, MALLOC_CHECK_="3")
    run = subprocess.run([sys.executable, "-c", STRESS], env=env, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr[-500:]
    assert run.stdout.strip() == "cholmod"
