import pytest
import torch

from symtorch.fmap_solve import regularized_fmap, resolvent_mask


def test_mask_vanishes_on_equal_eigenvalues_and_grows_away():
    ev = torch.linspace(0, 5, 10, dtype=torch.float64)
    M = resolvent_mask(ev, ev)
    assert torch.allclose(torch.diagonal(M), torch.zeros(10, dtype=torch.float64))
    assert (M[0, 1:] > 0).all() and M[0, -1] > M[0, 1]


def test_recovers_the_map_that_carries_descriptors():
    g = torch.Generator().manual_seed(0)
    K, D = 12, 40
    evals = torch.sort(torch.rand(K, generator=g, dtype=torch.float64) * 10).values
    A_x = torch.randn(K, D, generator=g, dtype=torch.float64)
    signs = torch.diag(torch.tensor([1.0, -1.0] * (K // 2), dtype=torch.float64))
    C_true = signs  # diagonal: commutes with the Laplacian, so the mask does not pull it away
    C = regularized_fmap(A_x, C_true @ A_x, evals, evals, lam=10.0)
    assert torch.allclose(C, C_true, atol=1e-8)


def test_batched_and_differentiable():
    g = torch.Generator().manual_seed(1)
    A_x = torch.randn(3, 6, 20, generator=g, dtype=torch.float64, requires_grad=True)
    A_y = torch.randn(3, 5, 20, generator=g, dtype=torch.float64)
    ex = torch.sort(torch.rand(3, 6, generator=g, dtype=torch.float64), -1).values
    ey = torch.sort(torch.rand(3, 5, generator=g, dtype=torch.float64), -1).values
    C = regularized_fmap(A_x, A_y, ex, ey)
    assert C.shape == (3, 5, 6)
    one = regularized_fmap(A_x[1], A_y[1], ex[1], ey[1])
    assert torch.allclose(C[1], one)
    assert torch.autograd.gradcheck(lambda a: regularized_fmap(a, A_y, ex, ey, lam=3.0), (A_x,))


def test_shape_mismatch_is_one_line_error():
    with pytest.raises(ValueError, match="descriptors"):
        regularized_fmap(torch.zeros(4, 3), torch.zeros(4, 2), torch.zeros(4), torch.zeros(4))
