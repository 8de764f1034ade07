"""Sample transforms: reprs, determinism under a generator, and symmetry augmentation."""
import inspect

import pytest
import torch

from symtorch.data import (Compose, ComputeDescriptors, ComputeSpectrum, DetectSymmetries,
                           NormalizeArea, RandomBandRotation, RandomEigenSigns, RandomSymmetry,
                           SetSymmetries, SymmetryFromCorrespondence, apply_symmetry,
                           bands_from_index, mirror_shape, symmetry_fmaps)
from symtorch.detect.config import DETECTOR_REVISION
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


def test_reprs(monkeypatch):
    assert repr(NormalizeArea()) == "NormalizeArea(center=True)"
    assert repr(NormalizeArea(center=False)) == "NormalizeArea(center=False)"
    assert repr(ComputeSpectrum(30)) == f"ComputeSpectrum(k=30, rel_gap={REL_GAP})"
    assert repr(ComputeSpectrum(30, rel_gap=0.2)) == "ComputeSpectrum(k=30, rel_gap=0.2)"
    assert repr(ComputeDescriptors(8, 0, normalize=False)) == \
        "ComputeDescriptors(n_hks=8, n_wks=0, normalize=False)"
    rev = f"revision={DETECTOR_REVISION}"
    assert repr(DetectSymmetries()) == f"DetectSymmetries(seed=0, {rev})"
    assert repr(DetectSymmetries(k_refine=40, k=20, mode="reflection")) == \
        f"DetectSymmetries(seed=0, {rev}, k=20, k_refine=40, mode='reflection')"
    p = torch.stack([torch.arange(4), torch.tensor([1, 0, 3, 2])])
    assert repr(SetSymmetries(p)).startswith("SetSymmetries(G=2, V=4, sha1=")
    assert repr(SetSymmetries(p)) == repr(SetSymmetries(p.clone()))
    assert repr(SetSymmetries(p)) != repr(SetSymmetries(p.flip(0)))
    assert repr(SetSymmetries(p)).endswith(", reverses=None)")
    assert repr(SetSymmetries(p, reverses=[False, True])).endswith(", reverses=[False, True])")
    g = torch.Generator().manual_seed(0)
    assert repr(RandomSymmetry(generator=g)) == "RandomSymmetry(mode='relabel', axis=0)"
    assert repr(RandomSymmetry(mode="mirror", axis=2)) == "RandomSymmetry(mode='mirror', axis=2)"
    assert repr(SymmetryFromCorrespondence()) == "SymmetryFromCorrespondence(method='local')"
    assert repr(RandomEigenSigns()) == "RandomEigenSigns()"
    assert repr(RandomBandRotation()) == "RandomBandRotation()"
    assert repr(Compose([NormalizeArea(), ComputeSpectrum(k=8)])) == \
        f"Compose([\n  NormalizeArea(center=True),\n  ComputeSpectrum(k=8, rel_gap={REL_GAP}),\n])"
    assert repr(Compose([])) == "Compose([])"
    # the detector's revision is part of the cache key: a detector whose results differ recomputes
    import symtorch.detect.config as config
    monkeypatch.setattr(config, "DETECTOR_REVISION", DETECTOR_REVISION + 1)
    assert repr(DetectSymmetries()) == f"DetectSymmetries(seed=0, revision={DETECTOR_REVISION + 1})"


def test_transforms_do_not_mutate_their_input(sym_sample):
    sample, _ = sym_sample
    before = {k: v.clone() if isinstance(v, torch.Tensor) else v for k, v in sample.items()}
    mirror_all = RandomSymmetry(mode="mirror", generator=torch.Generator().manual_seed(0))
    for t in (NormalizeArea(), RandomSymmetry(), RandomEigenSigns(), RandomBandRotation(),
              *[mirror_all] * 4):
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
    # orientation: voted on the faces when not given (the mirror reverses it), or taken as given
    assert sample["sym_reverses"].tolist() == [False, True]
    given = SetSymmetries(sample["sym_p2p"], reverses=torch.tensor([False, False]))(sample)
    assert given["sym_reverses"].tolist() == [False, False]
    cloud = {k: v for k, v in sample.items() if k != "faces"}
    assert "sym_reverses" not in SetSymmetries(sample["sym_p2p"])(
        {k: v for k, v in cloud.items() if k != "sym_reverses"})
    with pytest.raises(ValueError, match="reverses must be \\[G\\] = \\[2\\] bools"):
        SetSymmetries(sample["sym_p2p"], reverses=[True])
    with pytest.raises(ValueError, match="sym_p2p has 5 vertices but sample"):
        SetSymmetries(torch.zeros(1, 5, dtype=torch.long))(sample)
    with pytest.raises(ValueError, match="sym_p2p must be \\[G, V\\] long"):
        SetSymmetries(torch.zeros(5))


def _signed_volume(verts, faces):
    tri = verts[faces]
    return torch.linalg.det(tri).sum() / 6


def test_apply_symmetry_relabel_moves_only_the_ground_truth(sym_sample):
    sample, mirror = sym_sample
    s = dict(sample, corr_sym=mirror[sample["corr"]])
    s["corr"] = torch.where(torch.arange(len(mirror)) % 9 == 0, -1, s["corr"])  # -1: missing
    out = apply_symmetry(s, 1)
    # the template point k is now at the image of its old vertex; -1 stays -1
    ok = s["corr"] >= 0
    assert torch.equal(out["corr"][ok], mirror[s["corr"][ok]])
    assert (out["corr"][~ok] == -1).all()
    assert torch.equal(out["corr_sym"], mirror[s["corr_sym"]])
    # exact reflection: corr' is the old corr_sym, corr_sym' the old corr
    assert torch.equal(out["corr"][ok], s["corr_sym"][ok]) and torch.equal(out["corr_sym"],
                                                                           sample["corr"])
    # nothing geometric, spectral or group-theoretic moves
    for key in ("verts", "faces", "mass", "evals", "evecs", "bands", "hks", "wks", "sym_p2p",
                "sym_fmap", "sym_reverses"):
        assert torch.equal(out[key], s[key]), key
    assert torch.equal(apply_symmetry(out, 1)["corr"], s["corr"])  # an involution
    assert torch.equal(apply_symmetry(s, 0)["corr"], s["corr"])  # the identity


def test_apply_symmetry_mirror_keeps_an_outward_mesh(sym_sample):
    sample, mirror = sym_sample
    D, K = 3, sample["evecs"].shape[1]
    s = dict(sample, corr_sym=mirror[sample["corr"]],
             normals=torch.nn.functional.normalize(sample["verts"], dim=-1),
             orient_op=torch.randn(D, K, K, generator=torch.Generator().manual_seed(0),
                                   dtype=torch.float64))
    for axis in (0, 1, 2):
        out = apply_symmetry(s, 1, mode="mirror", axis=axis)
        M = torch.ones(3, dtype=torch.float64)
        M[axis] = -1
        assert torch.equal(out["verts"], s["verts"] * M), axis
        assert torch.equal(out["normals"], s["normals"] * M), axis
        assert torch.equal(out["faces"], s["faces"][:, [0, 2, 1]]), axis
        assert torch.equal(out["orient_op"], -s["orient_op"]), axis
        # still outward: same signed volume, face normals are the mirrored ones
        torch.testing.assert_close(_signed_volume(out["verts"], out["faces"]),
                                   _signed_volume(s["verts"], s["faces"]))
        assert _signed_volume(out["verts"], out["faces"]) > 0
        n0 = torch.linalg.cross(*(s["verts"][s["faces"][:, i]] - s["verts"][s["faces"][:, 0]]
                                  for i in (1, 2)))
        n1 = torch.linalg.cross(*(out["verts"][out["faces"][:, i]]
                                  - out["verts"][out["faces"][:, 0]] for i in (2, 1)))
        torch.testing.assert_close(-n1, n0 * M, msg=f"axis={axis}")
        # the ground truth is composed with the reflection, the intrinsic fields stay
        assert torch.equal(out["corr"], mirror[s["corr"]]) and torch.equal(out["corr"],
                                                                           s["corr_sym"])
        for key in ("mass", "evals", "evecs", "hks", "sym_p2p", "sym_fmap", "sym_reverses"):
            assert torch.equal(out[key], s[key]), (axis, key)
    twice = apply_symmetry(apply_symmetry(s, 1, mode="mirror"), 1, mode="mirror")
    for key in ("verts", "faces", "normals", "orient_op", "corr", "corr_sym"):
        assert torch.equal(twice[key], s[key]), key
    # mirror_shape alone touches only the extrinsic fields
    alone = mirror_shape(s)
    assert torch.equal(alone["corr"], s["corr"]) and torch.equal(alone["evecs"], s["evecs"])


def test_apply_symmetry_with_a_rough_map_keeps_the_mesh(sym_sample):
    # a non-bijective map (as detected or remeshed maps are): faces never degenerate
    sample, mirror = sym_sample
    rough = mirror.clone()
    rough[0] = rough[1]
    s = dict(sample, sym_p2p=torch.stack([torch.arange(len(mirror)), rough]))
    for mode in ("relabel", "mirror"):
        out = apply_symmetry(s, 1, mode=mode)
        assert torch.equal(out["corr"], rough[sample["corr"]]), mode
        f = out["faces"]
        assert ((f != f.roll(1, -1)).all(-1)).all(), mode
        assert torch.equal(f.sort(-1).values, sample["faces"].sort(-1).values), mode


def test_apply_symmetry_errors(sym_sample):
    sample, _ = sym_sample
    with pytest.raises(ValueError, match="index must be in \\[0, 1\\], got 2"):
        apply_symmetry(sample, 2)
    with pytest.raises(ValueError, match="mode must be one of \\('relabel', 'mirror'\\), got 'move'"):
        apply_symmetry(sample, 1, mode="move")
    with pytest.raises(ValueError, match="mode must be one of"):
        RandomSymmetry(mode="flip")
    with pytest.raises(ValueError, match="axis must be 0, 1 or 2"):
        apply_symmetry(sample, 1, mode="mirror", axis=3)
    with pytest.raises(ValueError, match="element 0 preserves orientation"):
        apply_symmetry(sample, 0, mode="mirror")
    no_rev = {k: v for k, v in sample.items() if k != "sym_reverses"}
    with pytest.raises(ValueError, match="needs sample keys \\['sym_reverses'\\]"):
        apply_symmetry(no_rev, 1, mode="mirror")
    with pytest.raises(ValueError, match="needs sample keys \\['sym_reverses'\\]"):
        RandomSymmetry(mode="mirror")(no_rev)
    apply_symmetry(no_rev, 1)  # relabelling does not need it
    no_sym = {k: v for k, v in sample.items() if not k.startswith("sym_")}
    with pytest.raises(ValueError, match="run DetectSymmetries, SetSymmetries or "
                                         "SymmetryFromCorrespondence"):
        RandomSymmetry()(no_sym)


def test_random_symmetry_mirror_mode_mirrors_only_reversing_elements(sym_sample):
    sample, mirror = sym_sample
    t = RandomSymmetry(mode="mirror", generator=torch.Generator().manual_seed(0))
    outs = [t(sample) for _ in range(30)]
    flipped = [bool(torch.equal(o["corr"], mirror[sample["corr"]])) for o in outs]
    assert 0 < sum(flipped) < 30, flipped
    for o, f in zip(outs, flipped):  # mirrored exactly when the reflection was drawn
        assert torch.equal(o["faces"], sample["faces"][:, [0, 2, 1]] if f else sample["faces"])
    # a rotation (here: the reflection's flag cleared) is relabelled, never mirrored
    rot = dict(sample, sym_reverses=torch.tensor([False, False]))
    for _ in range(10):
        assert torch.equal(t(rot)["faces"], sample["faces"])


@pytest.mark.parametrize("cls", [RandomSymmetry, RandomEigenSigns, RandomBandRotation])
def test_random_transforms_are_deterministic_under_a_generator(sym_sample, cls):
    sample, _ = sym_sample
    key = "corr" if cls is RandomSymmetry else "evecs"  # what each one draws
    runs = []
    for _ in range(2):
        t = cls(generator=torch.Generator().manual_seed(3))
        runs.append([t(sample) for _ in range(6)])
    for a, b in zip(*runs):
        assert torch.equal(a["evecs"], b["evecs"]) and torch.equal(a["corr"], b["corr"]), cls
    # and they do draw: six calls are not all alike
    assert len({tuple(o[key][:4].flatten().tolist()) for o in runs[0]}) > 1, cls


def test_random_symmetry_draws_each_element(sym_sample):
    sample, mirror = sym_sample
    t = RandomSymmetry(generator=torch.Generator().manual_seed(0))
    moved = [bool(torch.equal(t(sample)["corr"], mirror[sample["corr"]])) for _ in range(20)]
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
    verts, faces, mirror = mirror_mesh(subdivisions=3)
    sample = Compose([NormalizeArea(), ComputeSpectrum(k=40)])({"verts": verts, "faces": faces})
    out = DetectSymmetries(k=12, k_refine=24, n_samples=300)(sample)
    G, V = out["sym_p2p"].shape
    assert V == verts.shape[0] and out["sym_score"].shape == (G,)
    assert out["sym_fmap"].shape == (G, 40, 40)
    assert torch.equal(out["sym_p2p"][0], torch.arange(V))
    assert G == 2, f"the mirror was not found: scores {out['sym_score'].tolist()}"
    assert out["sym_reverses"].tolist() == [False, True]
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
    # a map that is not a bijection, mirrored, on the device too
    rough = on_dev["sym_p2p"].clone()
    rough[1, 0] = rough[1, 1]
    out = apply_symmetry(dict(on_dev, sym_p2p=rough), 1, mode="mirror")
    assert out["corr"].device == out["faces"].device == torch.device(device)
    assert torch.equal(out["corr"].cpu(), rough[1].cpu()[sample["corr"]])


@pytest.fixture(scope="module")
def mirror_spectrum_sample():
    verts, faces, mirror = mirror_mesh(subdivisions=3)
    return Compose([NormalizeArea(), ComputeSpectrum(k=40)])({"verts": verts, "faces": faces}), mirror


DETECT_SMALL = dict(k=12, k_refine=24, n_samples=300)


@pytest.mark.parametrize("on_uncertain", ["keep", "flag", "drop"])
@pytest.mark.parametrize("min_confidence", [0.0, 1.5])  # nothing, everything below it
def test_detect_symmetries_on_uncertain(mirror_spectrum_sample, on_uncertain, min_confidence):
    sample, mirror = mirror_spectrum_sample
    out = DetectSymmetries(on_uncertain=on_uncertain, min_confidence=min_confidence,
                           **DETECT_SMALL)(sample)
    msg = f"on_uncertain={on_uncertain}, min_confidence={min_confidence}"
    dropped = on_uncertain == "drop" and min_confidence > 1
    G = out["sym_p2p"].shape[0]
    assert G == (1 if dropped else 2), msg
    for key in ("sym_score", "sym_confidence", "sym_reverses"):
        assert out[key].shape == (G,), f"{key}: {msg}"
    assert out["sym_fmap"].shape[0] == G
    conf = out["sym_confidence"]
    assert ((conf >= 0) & (conf <= 1)).all() and conf[0] == 1, f"{conf.tolist()}: {msg}"
    assert torch.equal(out["sym_p2p"][0], torch.arange(sample["verts"].shape[0]))
    if not dropped:
        assert (out["sym_p2p"][1] == mirror).double().mean() > 0.9, msg
    if on_uncertain == "flag":
        assert out["sym_uncertain"].tolist() == [False, min_confidence > 1], msg
    else:
        assert "sym_uncertain" not in out, msg


def test_detect_symmetries_on_uncertain_is_checked_and_in_the_repr():
    with pytest.raises(ValueError, match="on_uncertain must be one of 'keep', 'flag', 'drop', got 'skip'"):
        DetectSymmetries(on_uncertain="skip")
    assert repr(DetectSymmetries(on_uncertain="keep")) == f"DetectSymmetries(seed=0, revision={DETECTOR_REVISION})"
    assert repr(DetectSymmetries(on_uncertain="drop", min_confidence=0.6)) == \
        f"DetectSymmetries(seed=0, revision={DETECTOR_REVISION}, on_uncertain='drop', min_confidence=0.6)"
