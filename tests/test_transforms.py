"""Sample transforms: reprs, determinism under a generator, and the symmetry relabelling."""
import inspect

import pytest
import torch

from symtorch.data import (Compose, ComputeDescriptors, ComputeSpectrum, DetectSymmetries,
                           NormalizeArea, RandomBandRotation, RandomEigenSigns, RandomSymmetry,
                           SetSymmetries, apply_symmetry, bands_from_index, symmetry_fmaps)
from symtorch.spectrum import band_index, eigen_bands
from shapes import mirror_mesh

REL_GAP = inspect.signature(eigen_bands).parameters["rel_gap"].default


PRE = Compose([NormalizeArea(), ComputeSpectrum(k=12), ComputeDescriptors(n_hks=4, n_wks=4)])


@pytest.fixture(scope="module")
def sym_sample():
    verts, faces, mirror = mirror_mesh()
    V = verts.shape[0]
    sample = {"name": "mirror", "verts": verts, "faces": faces, "corr": torch.arange(V)}
    sample = SetSymmetries(torch.stack([torch.arange(V), mirror]))(PRE(sample))
    return sample, mirror


def test_reprs():
    assert repr(NormalizeArea()) == "NormalizeArea(center=True)"
    assert repr(NormalizeArea(center=False)) == "NormalizeArea(center=False)"
    assert repr(ComputeSpectrum(30)) == f"ComputeSpectrum(k=30, rel_gap={REL_GAP})"
    assert repr(ComputeSpectrum(30, rel_gap=0.2)) == "ComputeSpectrum(k=30, rel_gap=0.2)"
    assert repr(ComputeDescriptors(8, 0, normalize=False)) == \
        "ComputeDescriptors(n_hks=8, n_wks=0, normalize=False)"
    assert repr(DetectSymmetries()) == "DetectSymmetries(seed=0)"
    assert repr(DetectSymmetries(k_refine=40, k=20, mode="reflection")) == \
        "DetectSymmetries(seed=0, k=20, k_refine=40, mode='reflection')"
    p = torch.stack([torch.arange(4), torch.tensor([1, 0, 3, 2])])
    assert repr(SetSymmetries(p)).startswith("SetSymmetries(G=2, V=4, sha1=")
    assert repr(SetSymmetries(p)) == repr(SetSymmetries(p.clone()))
    assert repr(SetSymmetries(p)) != repr(SetSymmetries(p.flip(0)))
    g = torch.Generator().manual_seed(0)
    assert repr(RandomSymmetry(generator=g)) == "RandomSymmetry()"
    assert repr(RandomEigenSigns()) == "RandomEigenSigns()"
    assert repr(RandomBandRotation()) == "RandomBandRotation()"
    assert repr(Compose([NormalizeArea(), ComputeSpectrum(k=8)])) == \
        f"Compose([\n  NormalizeArea(center=True),\n  ComputeSpectrum(k=8, rel_gap={REL_GAP}),\n])"
    assert repr(Compose([])) == "Compose([])"


def test_transforms_do_not_mutate_their_input(sym_sample):
    sample, _ = sym_sample
    before = {k: v.clone() if isinstance(v, torch.Tensor) else v for k, v in sample.items()}
    for t in (NormalizeArea(), RandomSymmetry(), RandomEigenSigns(), RandomBandRotation()):
        t(sample)
    for key, value in before.items():
        assert key in sample
        if isinstance(value, torch.Tensor):
            assert torch.equal(sample[key], value), key


def test_normalize_area():
    verts, faces, _ = mirror_mesh()
    out = NormalizeArea()({"verts": verts * 3.0 + 1.0, "faces": faces})
    tri = out["verts"][faces]
    areas = 0.5 * torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).norm(dim=-1)
    torch.testing.assert_close(areas.sum(), torch.tensor(1.0, dtype=torch.float64))
    centroid = (areas[:, None] * tri.mean(1)).sum(0)
    torch.testing.assert_close(centroid, torch.zeros(3, dtype=torch.float64), atol=1e-12, rtol=0)
    # scale: lengths now / lengths before
    before = (verts[faces[0, 0]] - verts[faces[0, 1]]).norm() * 3.0
    after = (out["verts"][faces[0, 0]] - out["verts"][faces[0, 1]]).norm()
    torch.testing.assert_close(after / before, out["scale"])
    with pytest.raises(ValueError, match="needs sample keys \\['faces'\\]"):
        NormalizeArea()({"verts": verts})
    with pytest.raises(ValueError, match="mesh 'flat' has zero or non-finite area"):
        NormalizeArea()({"name": "flat", "verts": verts * 0, "faces": faces})


def test_compute_spectrum_and_descriptors(sym_sample):
    sample, _ = sym_sample
    evecs, mass = sample["evecs"], sample["mass"]
    assert evecs.shape == (sample["verts"].shape[0], 12) and evecs.dtype == torch.float64
    torch.testing.assert_close(evecs.mT @ (mass[:, None] * evecs), torch.eye(12, dtype=torch.float64))
    assert torch.equal(sample["bands"], band_index(eigen_bands(sample["evals"]), 12))
    assert bands_from_index(sample["bands"]) == eigen_bands(sample["evals"])
    assert sample["hks"].shape == (evecs.shape[0], 4) and sample["wks"].shape == (evecs.shape[0], 4)
    torch.testing.assert_close(sample["hks"].mean(0), torch.ones(4, dtype=torch.float64))
    with pytest.raises(ValueError, match="k must be >= 2"):
        ComputeSpectrum(1)
    with pytest.raises(ValueError, match="run ComputeSpectrum first"):
        ComputeDescriptors()({"verts": sample["verts"]})


def test_float32_follows_verts():
    verts, faces, _ = mirror_mesh(dtype=torch.float32)
    out = PRE({"verts": verts, "faces": faces})
    assert out["evecs"].dtype == out["mass"].dtype == out["hks"].dtype == torch.float32


def test_set_symmetries(sym_sample):
    sample, mirror = sym_sample
    S = sample["sym_fmap"]
    assert S.shape == (2, 12, 12)
    torch.testing.assert_close(S[0], torch.eye(12, dtype=torch.float64), atol=1e-8, rtol=0)
    # an exact mirror: evecs[mirror] = evecs @ S, S orthogonal and involutive
    torch.testing.assert_close(sample["evecs"][mirror], sample["evecs"] @ S[1], atol=1e-6, rtol=0)
    torch.testing.assert_close(S[1] @ S[1], torch.eye(12, dtype=torch.float64), atol=1e-8, rtol=0)
    with pytest.raises(ValueError, match="sym_p2p has 5 vertices but sample"):
        SetSymmetries(torch.zeros(1, 5, dtype=torch.long))(sample)
    with pytest.raises(ValueError, match="sym_p2p must be \\[G, V\\] long"):
        SetSymmetries(torch.zeros(5))


def test_apply_symmetry_moves_points_with_their_images(sym_sample):
    sample, mirror = sym_sample
    out = apply_symmetry(sample, 1)
    # per-vertex fields are pulled back: x'[i] = x[g(i)]
    assert torch.equal(out["verts"], sample["verts"][mirror])
    assert torch.equal(out["hks"], sample["hks"][mirror])
    # ground truth still names the same points: x'[corr'[k]] = x[corr[k]]
    assert torch.equal(out["verts"][out["corr"]], sample["verts"][sample["corr"]])
    # the basis moves with the vertices: evecs' = evecs @ S ≈ evecs[g], exactly orthonormal
    torch.testing.assert_close(out["evecs"], sample["evecs"] @ sample["sym_fmap"][1])
    torch.testing.assert_close(out["evecs"], sample["evecs"][mirror], atol=1e-6, rtol=0)
    m = out["mass"]
    torch.testing.assert_close(out["evecs"].mT @ (m[:, None] * out["evecs"]),
                               torch.eye(12, dtype=torch.float64))
    # so a moved function keeps its coefficients, and the group's matrices are unchanged in it
    f = sample["verts"][:, 1:2]
    a = sample["evecs"].mT @ (sample["mass"][:, None] * f)
    a2 = out["evecs"].mT @ (m[:, None] * f[mirror])
    torch.testing.assert_close(a2, a, atol=1e-8, rtol=0)
    torch.testing.assert_close(out["sym_fmap"], sample["sym_fmap"])
    torch.testing.assert_close(symmetry_fmaps(out["sym_p2p"], out["evecs"], m), out["sym_fmap"],
                               atol=1e-6, rtol=0)
    # intrinsic keys stay, and the mirror applied twice is the identity
    for key in ("mass", "evals", "bands", "faces"):
        assert torch.equal(out[key], sample[key]), key
    twice = apply_symmetry(out, 1)
    for key in ("verts", "hks", "corr", "sym_p2p"):
        assert torch.equal(twice[key], sample[key]), key
    torch.testing.assert_close(twice["evecs"], sample["evecs"], atol=1e-8, rtol=0)
    same = apply_symmetry(sample, 0)
    for key in ("verts", "evecs", "corr", "sym_p2p"):
        torch.testing.assert_close(same[key], sample[key], atol=1e-10, rtol=0)


def test_apply_symmetry_approximate_map_uses_group_inverse(sym_sample):
    # a non-bijective map (one vertex's image changed): the inverse comes from the group's matrices
    sample, mirror = sym_sample
    rough = mirror.clone()
    rough[0] = rough[1]
    s = dict(sample, sym_p2p=torch.stack([torch.arange(len(mirror)), rough]))
    out = apply_symmetry(s, 1)
    assert torch.equal(out["corr"], rough[sample["corr"]])  # the reflection is its own inverse
    assert torch.equal(out["verts"], sample["verts"][rough])
    moved = out["verts"][out["corr"]] != sample["verts"][sample["corr"]]
    assert moved.any(-1).sum() <= 2  # only where the rough map is not a bijection


def test_apply_symmetry_errors(sym_sample):
    sample, _ = sym_sample
    with pytest.raises(ValueError, match="index must be in \\[0, 1\\], got 2"):
        apply_symmetry(sample, 2)
    no_sym = {k: v for k, v in sample.items() if not k.startswith("sym_")}
    with pytest.raises(ValueError, match="run DetectSymmetries or SetSymmetries"):
        RandomSymmetry()(no_sym)
    with pytest.raises(ValueError, match="needs sample keys \\['sym_fmap'\\]"):
        apply_symmetry({k: v for k, v in sample.items() if k != "sym_fmap"}, 1)


@pytest.mark.parametrize("cls", [RandomSymmetry, RandomEigenSigns, RandomBandRotation])
def test_random_transforms_are_deterministic_under_a_generator(sym_sample, cls):
    sample, _ = sym_sample
    runs = []
    for _ in range(2):
        t = cls(generator=torch.Generator().manual_seed(3))
        runs.append([t(sample) for _ in range(6)])
    for a, b in zip(*runs):
        assert torch.equal(a["evecs"], b["evecs"]) and torch.equal(a["verts"], b["verts"]), cls
    # and they do draw: six calls are not all alike
    assert len({tuple(o["evecs"][0].tolist()) for o in runs[0]}) > 1, cls


def test_random_symmetry_draws_each_element(sym_sample):
    sample, mirror = sym_sample
    t = RandomSymmetry(generator=torch.Generator().manual_seed(0))
    moved = [bool(torch.equal(t(sample)["verts"], sample["verts"][mirror])) for _ in range(20)]
    assert 0 < sum(moved) < 20, moved


@pytest.mark.parametrize("cls", [RandomEigenSigns, RandomBandRotation])
def test_basis_changes_keep_the_eigenspaces(sym_sample, cls):
    sample, _ = sym_sample
    out = cls(generator=torch.Generator().manual_seed(1))(sample)
    E, E2, m = sample["evecs"], out["evecs"], sample["mass"]
    torch.testing.assert_close(E2.mT @ (m[:, None] * E2), torch.eye(12, dtype=torch.float64))
    for b in bands_from_index(sample["bands"]):  # same projector on every band
        P, P2 = E[:, b] @ E[:, b].mT, E2[:, b] @ E2[:, b].mT
        torch.testing.assert_close(P2, P, atol=1e-10, rtol=0, msg=f"{cls.__name__} band {b}")
    assert torch.equal(out["verts"], sample["verts"])
    torch.testing.assert_close(symmetry_fmaps(out["sym_p2p"], E2, m, bands_from_index(out["bands"])),
                               out["sym_fmap"], atol=1e-8, rtol=0)


def test_detect_symmetries_transform():
    try:
        from symtorch.detect import detect_symmetries  # noqa: F401
    except ImportError:
        pytest.skip("symtorch.detect_symmetries is not available yet")
    verts, faces, mirror = mirror_mesh(subdivisions=3)
    sample = Compose([NormalizeArea(), ComputeSpectrum(k=40)])({"verts": verts, "faces": faces})
    out = DetectSymmetries(k=12, k_refine=24, n_samples=300)(sample)
    G, V = out["sym_p2p"].shape
    assert V == verts.shape[0] and out["sym_score"].shape == (G,)
    assert out["sym_fmap"].shape == (G, 40, 40)
    assert torch.equal(out["sym_p2p"][0], torch.arange(V))
    assert G == 2, f"the mirror was not found: scores {out['sym_score'].tolist()}"
    assert (out["sym_p2p"][1] == mirror).double().mean() > 0.9


@pytest.mark.parametrize("cls", [RandomSymmetry, RandomEigenSigns, RandomBandRotation])
def test_augmentations_on_device(sym_sample, cls, cuda_device):
    """A sample whose tensors live on ``device`` stays there, with the values the CPU gives."""
    device = cuda_device  # on CPU the comparison would be with itself
    sample, _ = sym_sample
    on_dev = {k: v.to(device) if torch.is_tensor(v) else v for k, v in sample.items()}
    for seed in range(3):  # both elements of the group are drawn among the seeds
        out = cls(generator=torch.Generator().manual_seed(seed))(on_dev)
        ref = cls(generator=torch.Generator().manual_seed(seed))(sample)
        for key, val in ref.items():
            if torch.is_tensor(val):
                assert out[key].device == torch.device(device), (cls.__name__, key)
                torch.testing.assert_close(out[key].cpu(), val, msg=f"{cls.__name__} {key}")
    # the group inverse (used for a map that is not a bijection) on the device too
    rough = on_dev["sym_p2p"].clone()
    rough[1, 0] = rough[1, 1]
    out = apply_symmetry(dict(on_dev, sym_p2p=rough), 1)
    assert out["corr"].device == torch.device(device)
    assert torch.equal(out["corr"].cpu(), rough[1].cpu()[sample["corr"]])
