"""Losses: zero at their ideal, gradcheck in float64, batching, reductions, errors."""
import pytest
import torch

from symtorch.losses import (bijectivity_loss, fmap_loss, laplacian_commutativity_loss,
                             orientation_loss, orthogonality_loss, p2p_error, symmetric_fmap_loss,
                             symmetric_p2p_error, symmetry_equivariance_loss)

K = 5
F64 = torch.float64


def rand(*shape, seed=0):
    return torch.randn(*shape, generator=torch.Generator().manual_seed(seed), dtype=F64)


def orthogonal(*lead, n=K, seed=0):
    Q, _ = torch.linalg.qr(rand(*lead, n, n, seed=seed))
    return Q


def reflections(n=K, seed=0):
    """[2, n, n]: identity and a symmetric orthogonal involution with block structure diag(+-1)."""
    S = torch.diag(torch.tensor([1.0, -1.0, 1.0, -1.0, -1.0][:n], dtype=F64))
    return torch.stack([torch.eye(n, dtype=F64), S])


def commuting_map(S, seed=0):
    """A map C with C S = S C: block-diagonal on the +1 / -1 eigenspaces of S."""
    C = rand(K, K, seed=seed)
    plus = torch.diagonal(S) > 0
    return C * (plus[:, None] == plus[None, :])


def antisymmetric(*lead, n=K, seed=0):
    """Random antisymmetric matrices, like orientation operators."""
    A = rand(*lead, n, n, seed=seed)
    return A - A.mT


def test_zero_at_ideal():
    C = orthogonal(3)
    assert orthogonality_loss(C) < 1e-24
    assert bijectivity_loss(C, C.mT) < 1e-24
    evals = torch.tensor([0.0, 1.0, 1.0, 2.0, 3.0], dtype=F64)
    block = torch.eye(K, dtype=F64)
    block[1:3, 1:3] = orthogonal(n=2)  # mixes a repeated eigenvalue only
    assert laplacian_commutativity_loss(block, evals, evals) < 1e-24
    assert laplacian_commutativity_loss(block, evals, evals, normalize=False) < 1e-24
    O = antisymmetric(4)  # [D, K, K]
    Q = orthogonal(seed=7)
    assert orientation_loss(Q, O, Q @ O @ Q.mT) < 1e-24           # C O_x = O_y C
    assert orientation_loss(Q, O, -Q @ O @ Q.mT, reversing=True) < 1e-24
    assert orientation_loss(Q, O, -Q @ O @ Q.mT) > 1
    S = reflections()
    Cc = commuting_map(S[1])
    assert symmetry_equivariance_loss(Cc, S, S) < 1e-24
    assert symmetry_equivariance_loss(Cc, S.flip(0), S, match="best") < 1e-24
    Cgt = rand(2, K, K)
    assert fmap_loss(Cgt, Cgt) == 0
    assert symmetric_fmap_loss(S[1] @ Cgt, Cgt, S) < 1e-24  # the flipped truth is as good
    assert symmetric_fmap_loss(Cgt, Cgt, S) == 0
    assert fmap_loss(S[1] @ Cgt, Cgt) > 1


def test_gradcheck():
    C = rand(2, K, K, seed=1).requires_grad_()
    C2 = rand(2, K, K, seed=2).requires_grad_()
    evals_x = rand(2, K, seed=3).abs().cumsum(-1).requires_grad_()
    evals_y = rand(2, K, seed=4).abs().cumsum(-1).requires_grad_()
    S = reflections().requires_grad_()
    Cgt = rand(2, K, K, seed=5)
    mask = torch.tensor([[True, True], [True, False]])
    O = antisymmetric(2, 3, seed=6).requires_grad_()  # [B, D, K, K]
    checks = {
        "fmap": lambda c: fmap_loss(c, Cgt),
        "orthogonality": orthogonality_loss,
        "bijectivity": lambda c: bijectivity_loss(c, C2),
        "commutativity": lambda c: laplacian_commutativity_loss(c, evals_x, evals_y),
        "commutativity-raw": lambda c: laplacian_commutativity_loss(c, evals_x, evals_y, normalize=False),
        "orientation": lambda c: orientation_loss(c, O, O),
        "orientation-reversing": lambda c: orientation_loss(c, O, O, reversing=True),
        "equivariance": lambda c: symmetry_equivariance_loss(c, S, S),
        "equivariance-best": lambda c: symmetry_equivariance_loss(c, S, S.flip(0), mask_y=mask,
                                                                  match="best"),
        "symmetric": lambda c: symmetric_fmap_loss(c, Cgt, S, mask=mask),
    }
    for name, fn in checks.items():
        assert torch.autograd.gradcheck(fn, (C,)), name
    assert torch.autograd.gradcheck(lambda a, b: laplacian_commutativity_loss(C, a, b),
                                    (evals_x, evals_y))
    assert torch.autograd.gradcheck(lambda s: symmetry_equivariance_loss(C, s, s), (S,))
    O2 = antisymmetric(2, 3, seed=7).requires_grad_()
    assert torch.autograd.gradcheck(lambda a, b: orientation_loss(C, a, b), (O, O2))


def test_laplacian_commutativity_normalizes_eigenvalues_by_the_larger_maximum():
    C = rand(3, K, K, seed=8)
    ex, ey = rand(3, K, seed=9).abs().cumsum(-1), rand(3, K, seed=10).abs().cumsum(-1)
    top = torch.maximum(ex.amax(-1), ey.amax(-1))[:, None]  # per map, as GeomFmaps / ULRSSM
    per = laplacian_commutativity_loss(C, ex, ey, reduction="none")
    torch.testing.assert_close(per, laplacian_commutativity_loss(C, ex / top, ey / top,
                                                                 normalize=False, reduction="none"))
    # scale free: eigenvalues of a shape at another area (or at larger K) do not swamp the term
    torch.testing.assert_close(laplacian_commutativity_loss(C, 100 * ex, 100 * ey), per.mean())
    assert laplacian_commutativity_loss(C, 100 * ex, 100 * ey, normalize=False) > 1e3 * per.mean()
    zero = torch.zeros(K, dtype=F64)
    assert laplacian_commutativity_loss(C[0], zero, zero) == 0  # no NaN from an all-zero spectrum


def test_orientation_loss_batching_and_errors():
    C = rand(3, 4, K, seed=11)  # [B, K_y, K_x], K_y = 4
    Ox, Oy = antisymmetric(3, 2, seed=12), antisymmetric(3, 2, n=4, seed=13)  # [B, D, K, K]
    per = orientation_loss(C, Ox, Oy, reduction="none")
    assert per.shape == (3,) and per.dtype == F64
    want = ((C[1] @ Ox[1, 0] - Oy[1, 0] @ C[1]).square().sum()
            + (C[1] @ Ox[1, 1] - Oy[1, 1] @ C[1]).square().sum()) / 2  # mean over descriptors
    torch.testing.assert_close(per[1], want)
    torch.testing.assert_close(orientation_loss(C, Ox, Oy), per.mean())
    # padding: zero rows / columns of the map and the operators add nothing
    Cp, Oxp = torch.zeros(3, 4, K + 2, dtype=F64), torch.zeros(3, 2, K + 2, K + 2, dtype=F64)
    Cp[..., :K], Oxp[..., :K, :K] = C, Ox
    torch.testing.assert_close(orientation_loss(Cp, Oxp, Oy, reduction="none"), per)
    with pytest.raises(ValueError, match=r"needs O_x \[..., D, K_x, K_x\] and O_y \[..., D, K_y, K_y\]"):
        orientation_loss(C, Oy, Oy)
    with pytest.raises(ValueError, match=r"got \[3, 2, 5, 5\] and \[3, 1, 4, 4\]"):
        orientation_loss(C, Ox, Oy[:, :1])
    with pytest.raises(ValueError, match="reduction must be one of"):
        orientation_loss(C, Ox, Oy, reduction="max")


def test_batching_and_reductions():
    C = rand(3, 2, K, K)
    per = orthogonality_loss(C, reduction="none")
    assert per.shape == (3, 2)
    torch.testing.assert_close(orthogonality_loss(C), per.mean())
    torch.testing.assert_close(orthogonality_loss(C, reduction="sum"), per.sum())
    for i in range(3):
        torch.testing.assert_close(per[i, 1], orthogonality_loss(C[i, 1]))
    with pytest.raises(ValueError, match="reduction must be one of"):
        orthogonality_loss(C, reduction="max")


def test_dtype_and_shapes_follow_inputs():
    C = torch.randn(2, 4, 3, dtype=torch.float32)  # K_y = 4, K_x = 3
    Sx, Sy = torch.eye(3).expand(2, 1, 3, 3), torch.eye(4).expand(2, 1, 4, 4)
    for val in (orthogonality_loss(C), bijectivity_loss(C, C.mT),
                laplacian_commutativity_loss(C, torch.rand(3), torch.rand(4)),
                symmetry_equivariance_loss(C, Sx, Sy), symmetric_fmap_loss(C, C, Sy)):
        assert val.dtype == torch.float32 and val.dim() == 0
    with pytest.raises(ValueError, match="are not transposed shapes"):
        bijectivity_loss(C, C)
    with pytest.raises(ValueError, match="evals_x has 4"):
        laplacian_commutativity_loss(C, torch.rand(4), torch.rand(4))
    with pytest.raises(ValueError, match="match='index' needs groups of one order"):
        symmetry_equivariance_loss(C, Sx, torch.eye(4).expand(2, 2, 4, 4))
    with pytest.raises(ValueError, match="match must be 'index' or 'best'"):
        symmetry_equivariance_loss(C, Sx, Sy, match="all")
    with pytest.raises(ValueError, match="C is \\[2, 4, 3\\] but C_gt"):
        fmap_loss(C, C.mT)
    with pytest.raises(ValueError, match="C must be \\[..., K_y, K_x\\], got \\[3\\]"):
        orthogonality_loss(torch.zeros(3))
    with pytest.raises(ValueError, match="but sym_x is \\[2, 1, 4, 4\\]"):
        symmetry_equivariance_loss(C, Sy, Sy)
    with pytest.raises(ValueError, match="do not fit"):
        symmetric_fmap_loss(C, C, Sx)


def test_equivariance_loss_masks_padded_elements():
    S = reflections()
    C = rand(K, K)
    padded = torch.stack([S[0], torch.zeros(K, K, dtype=F64)])
    mask = torch.tensor([True, False])
    full = symmetry_equivariance_loss(C, S[:1], S[:1])
    torch.testing.assert_close(symmetry_equivariance_loss(C, padded, padded, mask_x=mask, mask_y=mask),
                               full)
    torch.testing.assert_close(symmetry_equivariance_loss(C, padded, padded, mask_x=mask, mask_y=mask,
                                                          match="best"), full)


def test_p2p_errors():
    # 6 points on a line, mirror i -> 5 - i; distances |i - j|
    pos = torch.arange(6, dtype=F64)
    dist = (pos[:, None] - pos[None, :]).abs()
    sym = torch.stack([torch.arange(6), torch.arange(6).flip(0)])
    gt = torch.tensor([0, 1, 2, 3, -1])  # 5 points of y, the last unknown
    assert p2p_error(gt.clamp_min(0), gt, dist) == 0
    flipped = sym[1][gt.clamp_min(0)]
    assert p2p_error(flipped, gt, dist) == pytest.approx((5 + 3 + 1 + 1) / 4)
    err, elem = symmetric_p2p_error(flipped, gt, sym, dist)
    assert err == 0 and elem == 1
    err, elem = symmetric_p2p_error(gt.clamp_min(0), gt, sym, dist)
    assert err == 0 and elem == 0
    # batched, with a callable distance and masks
    p = torch.stack([gt.clamp_min(0), flipped])
    g = torch.stack([gt, gt])
    err, elem = symmetric_p2p_error(p, g, sym.expand(2, 2, 6),
                                    lambda a, b: (pos[a] - pos[b]).abs(),
                                    sym_mask=torch.tensor([[True, True], [True, False]]))
    assert elem.tolist() == [0, 0] and err[0] == 0 and err[1] == pytest.approx(2.5)
    mask = torch.tensor([True, False, False, False, True])
    assert p2p_error(flipped, gt, dist, mask=mask) == 5
    assert p2p_error(flipped[None], gt[None], dist[None]).shape == (1,)


def test_losses_on_device(device):
    """Every loss on ``device``: its value there equals the CPU value, and it back-propagates."""
    C = rand(2, K, K, seed=1)
    C2, Cgt = rand(2, K, K, seed=2), rand(2, K, K, seed=5)
    evals = rand(2, K, seed=3).abs().cumsum(-1)
    S = reflections()
    mask = torch.tensor([[True, True], [True, False]])
    pos = torch.arange(6, dtype=F64)
    dist = (pos[:, None] - pos[None, :]).abs()
    sym = torch.stack([torch.arange(6), torch.arange(6).flip(0)])
    gt = torch.tensor([0, 1, 2, 3, 4])
    losses = {
        "fmap": lambda c, d: fmap_loss(c, d(Cgt)),
        "orthogonality": lambda c, d: orthogonality_loss(c),
        "bijectivity": lambda c, d: bijectivity_loss(c, d(C2).mT),
        "commutativity": lambda c, d: laplacian_commutativity_loss(c, d(evals), d(evals)),
        "orientation": lambda c, d: orientation_loss(c, d(antisymmetric(2, 3)), d(antisymmetric(2, 3, seed=1))),
        "equivariance": lambda c, d: symmetry_equivariance_loss(c, d(S), d(S), mask_y=d(mask), match="best"),
        "symmetric": lambda c, d: symmetric_fmap_loss(c, d(Cgt), d(S), mask=d(mask)),
    }
    for name, fn in losses.items():
        c = C.to(device).requires_grad_()
        val = fn(c, lambda t: t.to(device))
        assert val.device == c.device, name
        torch.testing.assert_close(val.cpu(), fn(C, lambda t: t), msg=name)
        val.backward()
        assert c.grad is not None and c.grad.device == c.device and torch.isfinite(c.grad).all(), name
    err, elem = symmetric_p2p_error(sym[1][gt].to(device), gt.to(device), sym.to(device), dist.to(device))
    assert err.device == torch.device(device) and float(err) == 0 and int(elem) == 1
    assert float(p2p_error(sym[1][gt].to(device), gt.to(device), dist.to(device))) == pytest.approx((5 + 3 + 1 + 1 + 3) / 5)
