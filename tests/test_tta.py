"""Mirror test-time averaging (symtorch.tta)."""
import pytest
import torch

from symtorch.data import mirror_shape
from symtorch.tta import mirror_averaged_fmap, mirror_pair, reflection_index, symmetrized_features
from shapes import mirror_mesh


def _sample(verts, faces):
    return {"verts": verts, "faces": faces, "orient_op": torch.ones(2, 3, 3)}


def test_mirror_pair_reflects_both_and_keeps_vertex_ids():
    verts, faces, _ = mirror_mesh(2)
    x, y = _sample(verts, faces), _sample(2 * verts, faces)
    xm, ym = mirror_pair(x, y, axis=1)
    for s, m in ((x, xm), (y, ym)):
        assert torch.equal(m["verts"][:, 1], -s["verts"][:, 1])
        assert torch.equal(m["verts"][:, [0, 2]], s["verts"][:, [0, 2]])
        assert torch.equal(m["faces"], s["faces"][:, [0, 2, 1]])
        assert torch.equal(m["orient_op"], -s["orient_op"])
    back = mirror_pair(xm, ym, axis=1)
    assert torch.equal(back[0]["verts"], x["verts"]) and torch.equal(back[0]["faces"], x["faces"])


def test_the_average_is_over_the_pair_and_its_mirror_image():
    verts, faces, _ = mirror_mesh(2)
    x, y = _sample(verts, faces), _sample(verts + 1.0, faces)

    def fmap_fn(a, b):  # depends on the side: the mean x coordinate of both shapes
        return torch.full((4, 4), float(a["verts"][:, 0].mean() + b["verts"][:, 0].mean()))

    C = mirror_averaged_fmap(fmap_fn, x, y)
    expected = 0.5 * (fmap_fn(x, y) + fmap_fn(*mirror_pair(x, y)))
    assert torch.allclose(C, expected) and not torch.allclose(C, fmap_fn(x, y))


def _with_reflection(verts, faces, mirror):
    s = _sample(verts, faces)
    s["sym_p2p"] = torch.stack([torch.arange(len(verts)), mirror])
    s["sym_reverses"] = torch.tensor([False, True])
    return s


def test_symmetrized_features_are_mirror_equivariant():
    verts, faces, mirror = mirror_mesh(2)
    x = _with_reflection(verts, faces, mirror)

    def fn(s):  # orientation-aware "network": position and an orientation operator's sign
        wind = float(s["orient_op"].sum())  # mirror_shape negates orientation operators
        return torch.cat([s["verts"], torch.full((len(verts), 1), wind, dtype=verts.dtype)], 1)

    F = symmetrized_features(fn, x)
    # the mirror image read through the exact reflection is the shape itself: f(x')[R] = f(x) in xyz
    assert torch.allclose(F[:, :3], verts, atol=1e-12)
    # the orientation term is negated in the mirror image and averages out
    assert torch.allclose(F[:, 3], torch.zeros(len(verts), dtype=verts.dtype), atol=1e-12)
    # equivariance: the features of the mirror image are those of the shape read through R
    Fm = symmetrized_features(fn, mirror_shape(x))
    assert torch.allclose(Fm, F[mirror], atol=1e-12)


def test_symmetrized_features_without_a_reflection_are_the_network_s():
    verts, faces, mirror = mirror_mesh(2)
    x = _with_reflection(verts, faces, mirror)
    x["sym_reverses"] = torch.tensor([False, False])
    assert reflection_index(x) is None
    F = symmetrized_features(lambda s: s["verts"][:, :2] * 2, x)
    assert torch.equal(F, verts[:, :2] * 2)
    x["sym_reverses"] = torch.tensor([False, True])
    x["sym_p2p"] = x["sym_p2p"][:, :5]
    with pytest.raises(ValueError, match="sym_p2p"):
        symmetrized_features(lambda s: s["verts"], x)


def test_the_spectral_average_is_the_vertex_average_read_in_the_reduced_basis():
    from symtorch.data import ComputeSpectrum, SetSymmetries
    from symtorch.tta import reflection_average, spectral_reflection_average

    verts, faces, mirror = mirror_mesh(2)
    s = ComputeSpectrum(k=16)({"verts": verts, "faces": faces})
    s = SetSymmetries(torch.stack([torch.arange(len(verts)), mirror]), reverses=[False, True])(s)
    k = 10
    Phi, M = s["evecs"][:, :k], s["mass"][:, None]
    g = torch.Generator().manual_seed(0)
    F = Phi @ torch.randn(k, 3, generator=g, dtype=Phi.dtype)      # band-limited features
    F_m = Phi @ torch.randn(k, 3, generator=g, dtype=Phi.dtype)
    A, A_m = Phi.mT @ (M * F), Phi.mT @ (M * F_m)
    got = spectral_reflection_average(A, A_m, s)
    want = Phi.mT @ (M * reflection_average(F, F_m, s))              # the vertex-level average
    assert torch.allclose(got, want, atol=1e-6)
    assert not torch.allclose(got, 0.5 * (A + A_m), atol=1e-3)      # the reflection does act
    no = dict(s, sym_reverses=torch.tensor([False, False]))
    assert torch.equal(spectral_reflection_average(A, A_m, no), A)
    with pytest.raises(ValueError, match="smaller"):
        spectral_reflection_average(torch.zeros(20, 3, dtype=A.dtype), torch.zeros(20, 3, dtype=A.dtype), s)


def test_the_reflection_residual_is_zero_for_the_true_reflection_and_large_for_a_wrong_one():
    import math

    from symtorch.tta import reflection_residual

    verts, faces, mirror = mirror_mesh(2)
    x = _with_reflection(verts, faces, mirror)
    F = verts.clone()                      # features of the shape: its coordinates
    F_m = verts.clone()
    F_m[:, 0] = -F_m[:, 0]                 # of the mirror image x' (x negated), same vertex ids
    assert reflection_residual(F, F_m, x) < 1e-12
    wrong = dict(x, sym_p2p=torch.stack([x["sym_p2p"][0], torch.roll(mirror, len(mirror) // 2)]))
    assert reflection_residual(F, F_m, wrong) > 0.5
    assert math.isnan(reflection_residual(F, F_m, dict(x, sym_reverses=torch.tensor([False, False]))))
