"""Tests for symtorch.procrustes: batched band-by-band Procrustes (ALGORITHM §3)."""
from __future__ import annotations

import pytest
import torch

from symtorch.procrustes import (block_mask, block_procrustes, block_project, nearest_orthogonal,
                                 procrustes_rotation)
from symtorch.spectrum import bands_from_sizes
from conftest import DEVICES  # CPU, and CUDA where present

DTYPES = [torch.float32, torch.float64]
TOL = {torch.float32: dict(atol=2e-4, rtol=0), torch.float64: dict(atol=1e-10, rtol=0)}

# band sizes of a realistic K = 20 basis (the constant mode, then 1-, 2- and 3-dim eigenspaces)
SIZES = [1, 1, 2, 1, 3, 1, 2, 2, 1, 1, 2, 3]


make_bands = bands_from_sizes


def random_orthogonal(*shape_n, generator) -> torch.Tensor:
    """[..., n, n] Haar-random orthogonal matrices (det +-1), float64."""
    *batch, n = shape_n
    Q, R = torch.linalg.qr(torch.randn(*batch, n, n, generator=generator, dtype=torch.float64))
    return Q * torch.sign(torch.diagonal(R, dim1=-2, dim2=-1))[..., None, :]


def random_block_orthogonal(B, bands, generator, fixed_first=True) -> torch.Tensor:
    K = bands[-1].stop
    C = torch.zeros(B, K, K, dtype=torch.float64)
    for b in bands:
        C[:, b.start:b.stop, b.start:b.stop] = random_orthogonal(B, len(b), generator=generator)
    if fixed_first:
        C[:, 0, 0] = 1.0
    return C


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("dtype", DTYPES)
def test_recovers_known_block_orthogonal_matrices_batched(device, dtype):
    g = torch.Generator().manual_seed(0)
    bands = make_bands(SIZES)
    K, J, B = bands[-1].stop, 24, 500
    C = random_block_orthogonal(B, bands, g)  # one different true matrix per candidate
    A = torch.randn(B, K, J, generator=g, dtype=torch.float64)
    Bm = C @ A  # exact constraints: C A = B
    est = block_procrustes(A.to(device, dtype), Bm.to(device, dtype), bands)
    assert est.shape == (B, K, K) and est.dtype == dtype and est.device.type == device
    torch.testing.assert_close(est.cpu().double(), C, **TOL[dtype],
                               msg=f"dtype={dtype}, device={device}")
    eye = torch.eye(K, dtype=dtype, device=device)
    torch.testing.assert_close(est.mT @ est, eye.expand(B, K, K), **TOL[dtype])
    mask = block_mask(bands, device=device)
    assert (est[:, ~mask] == 0).all(), "entries outside the bands must be exactly zero"


@pytest.mark.parametrize("device", DEVICES)
def test_leading_batch_dims_and_weights(device):
    g = torch.Generator().manual_seed(1)
    bands = make_bands([1, 2, 3, 1, 2])
    K, J = bands[-1].stop, 12
    C = random_block_orthogonal(12, bands, g).view(3, 4, K, K)
    A = torch.randn(3, 4, K, J, generator=g, dtype=torch.float64)
    w = torch.rand(3, 4, J, generator=g, dtype=torch.float64) + 0.1
    est = block_procrustes(A.to(device), (C @ A).to(device), bands, weights=w.to(device))
    assert est.shape == (3, 4, K, K)
    torch.testing.assert_close(est.cpu(), C, **TOL[torch.float64])
    # the result equals a per-candidate loop
    for i in range(3):
        for j in range(4):
            one = block_procrustes(A[i, j], C[i, j] @ A[i, j], bands, weights=w[i, j])
            torch.testing.assert_close(est[i, j].cpu(), one, **TOL[torch.float64])


def test_noisy_constraints_give_least_squares_blocks():
    """With noise, each block is the orthogonal Procrustes solution of its own rows."""
    g = torch.Generator().manual_seed(2)
    bands = make_bands([1, 2, 3])
    A = torch.randn(6, 40, generator=g, dtype=torch.float64)
    Bm = random_block_orthogonal(1, bands, g)[0] @ A + 0.3 * torch.randn(6, 40, generator=g,
                                                                      dtype=torch.float64)
    est = block_procrustes(A, Bm, bands)
    for b in bands[1:]:
        sl = slice(b.start, b.stop)
        D = est[sl, sl]
        best = torch.linalg.norm(D @ A[sl] - Bm[sl])
        for _ in range(50):  # no random orthogonal block does better
            Q = random_orthogonal(len(b), generator=g)
            assert torch.linalg.norm(Q @ A[sl] - Bm[sl]) >= best - 1e-9
        torch.testing.assert_close(D, procrustes_rotation(A[sl], Bm[sl]))


def test_fixed_first_keeps_constant_mode():
    g = torch.Generator().manual_seed(3)
    bands = make_bands([1, 2, 2])
    A = torch.randn(5, 8, generator=g, dtype=torch.float64)
    C = random_block_orthogonal(1, bands, g)[0]
    C[0, 0] = -1.0  # a sign the fixed block must override
    est = block_procrustes(A, C @ A, bands, fixed_first=True)
    assert est[0, 0] == 1 and (est[0, 1:] == 0).all() and (est[1:, 0] == 0).all()
    free = block_procrustes(A, C @ A, bands, fixed_first=False)
    torch.testing.assert_close(free, C)


@pytest.mark.parametrize("dtype", DTYPES)
def test_nearest_orthogonal_and_block_project(dtype):
    g = torch.Generator().manual_seed(4)
    bands = make_bands(SIZES)
    K = bands[-1].stop
    C = random_block_orthogonal(8, bands, g).to(dtype)
    torch.testing.assert_close(nearest_orthogonal(C), C, **TOL[dtype])
    torch.testing.assert_close(block_project(C, bands), C, **TOL[dtype])
    noisy = C + 0.01 * torch.randn(8, K, K, generator=g, dtype=torch.float64).to(dtype)
    P = block_project(noisy, bands)
    torch.testing.assert_close(block_project(P, bands), P, **TOL[dtype])  # idempotent
    assert (P - C).abs().max() < 0.05
    eye = torch.eye(K, dtype=dtype)
    torch.testing.assert_close(P.mT @ P, eye.expand_as(P), **TOL[dtype])


def test_block_mask():
    m = block_mask(make_bands([1, 2, 3]))
    assert m.shape == (6, 6) and m.sum() == 1 + 4 + 9
    assert m[1, 2] and not m[0, 1] and not m[2, 3]
    assert block_mask(make_bands([1, 2, 3]), K=4).shape == (4, 4)


def test_value_errors():
    A = torch.zeros(2, 5, 7)
    with pytest.raises(ValueError, match=r"A and B must have the same shape, got \[2, 5, 7\] and \[2, 5, 6\]"):
        block_procrustes(A, torch.zeros(2, 5, 6), make_bands([1, 2, 2]))
    with pytest.raises(ValueError, match="bands must cover 0..4"):
        block_procrustes(A, A, make_bands([1, 2]))
    with pytest.raises(ValueError, match="bands must cover 0..4"):
        block_procrustes(A, A, [])
    with pytest.raises(ValueError, match="bands must cover 0..4"):
        block_procrustes(A, A, [range(1, 5)])
