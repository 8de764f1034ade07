import pytest
import torch

pytest.importorskip("geomfum", reason="DiffusionNet comes from geomfum (pip install symtorch[train])")

from symtorch import shapes  # noqa: E402
from symtorch.backbone import (ComputeGradientOperator, DiffusionNetFeatures,  # noqa: E402
                               gradient_operator, sparse_gradient)
from symtorch.data import Compose, ComputeSpectrum, NormalizeArea  # noqa: E402


def _blob():
    verts, faces = shapes.mirror_blob(subdivisions=3)
    return torch.as_tensor(verts, dtype=torch.float64), torch.as_tensor(faces, dtype=torch.long)


def _complex(idx, val, V):
    return torch.sparse_coo_tensor(idx, torch.complex(val[:, 0], val[:, 1]), (V, V)).to_dense()


def test_gradient_of_a_linear_function_is_its_tangent_projection():
    verts, faces = _blob()
    idx, val = gradient_operator(verts, faces)
    G = _complex(idx, val, verts.shape[0])
    for axis in range(3):
        g = G @ verts[:, axis].to(G.dtype)
        # |tangential gradient| of a coordinate function is at most 1, and about 1 on average
        assert float(g.abs().max()) < 1.5
        assert 0.3 < float(g.abs().mean()) <= 1.05


def test_mirror_image_conjugates_the_gradient_features():
    # DiffusionNet's gradient features use Re(conj(G u) * (G v)) (a dot product, mirror invariant)
    # and Im(conj(G u) * (G v)) (a cross product n . (grad u x grad v), which flips sign)
    verts, faces = _blob()
    V = verts.shape[0]
    mirror = verts * torch.tensor([-1.0, 1.0, 1.0], dtype=verts.dtype)
    G = _complex(*gradient_operator(verts, faces), V)
    Gm = _complex(*gradient_operator(mirror, faces.flip(-1)), V)
    gen = torch.Generator().manual_seed(0)
    u, v = (torch.randn(V, generator=gen, dtype=torch.float64).to(G.dtype) for _ in range(2))
    a, b = torch.conj(G @ u) * (G @ v), torch.conj(Gm @ u) * (Gm @ v)
    assert torch.allclose(a.real, b.real, atol=1e-8 * float(a.abs().max()))
    assert torch.allclose(a.imag, -b.imag, atol=1e-8 * float(a.abs().max()))


def test_features_run_on_a_sample_and_backpropagate():
    verts, faces = _blob()
    s = Compose([NormalizeArea(), ComputeSpectrum(k=20), ComputeGradientOperator()])(
        {"verts": verts.float(), "faces": faces})
    gx, gy = sparse_gradient(s)
    assert gx.shape == gy.shape == (verts.shape[0],) * 2
    net = DiffusionNetFeatures(3, 8, hidden_channels=16, n_block=2, k_eig=16)
    f = net(s, s["verts"].float())
    assert f.shape == (verts.shape[0], 8)
    f.square().mean().backward()
    assert all(p.grad is not None for p in net.parameters() if p.requires_grad)
    with pytest.raises(ValueError, match="grad_idx"):
        net({k: v for k, v in s.items() if k != "grad_idx"}, s["verts"].float())
