"""Padding collate: shapes, masks, pad values, nested pairs, and a DataLoader with workers."""
import pytest
import torch
from torch.utils.data import DataLoader

from symtorch.data import (Compose, ComputeDescriptors, ComputeSpectrum, MeshDataset, NormalizeArea,
                           PairDataset, RandomSymmetry, SetSymmetries, pad_collate, pad_stack)
from symtorch.io import write_mesh
from shapes import mirror_mesh

K = 6


def shape(subdivisions, with_mirror=True):
    verts, faces, mirror = mirror_mesh(subdivisions)
    V = verts.shape[0]
    p2p = torch.stack([torch.arange(V), mirror]) if with_mirror else torch.arange(V)[None]
    pre = Compose([NormalizeArea(), ComputeSpectrum(K), ComputeDescriptors(3, 0), SetSymmetries(p2p)])
    return pre({"name": f"s{subdivisions}", "verts": verts, "faces": faces,
                "corr": torch.arange(V)[:40]})


def test_pad_collate_samples_of_different_sizes():
    a, b = shape(1, with_mirror=False), shape(2)
    Va, Vb = a["verts"].shape[0], b["verts"].shape[0]
    batch = pad_collate([a, b])
    assert batch["name"] == ["s1", "s2"]
    assert batch["verts"].shape == (2, Vb, 3) and batch["evecs"].shape == (2, Vb, K)
    assert batch["mask"].tolist() == [[True] * Va + [False] * (Vb - Va), [True] * Vb]
    assert batch["mass"][0, Va:].abs().sum() == 0 and batch["evecs"][0, Va:].abs().sum() == 0
    assert (batch["faces"][0, a["faces"].shape[0]:] == -1).all()
    assert batch["faces_mask"].sum(1).tolist() == [a["faces"].shape[0], b["faces"].shape[0]]
    assert batch["sym_p2p"].shape == (2, 2, Vb) and batch["sym_mask"].tolist() == [[True, False],
                                                                                  [True, True]]
    assert batch["sym_fmap"][0, 1].abs().sum() == 0 and (batch["sym_p2p"][0, 1] == -1).all()
    # orientation flags pad with False, under the same group mask
    assert batch["sym_reverses"].tolist() == [[False, False], [False, True]]
    assert "sym_reverses_mask" not in batch
    assert batch["corr_mask"].all() and "hks_mask" not in batch and "evals_mask" not in batch
    # padded vertices carry no mass: spectral projections need no mask
    coefs = batch["evecs"].mT @ (batch["mass"][..., None] * batch["hks"])
    for i, s in enumerate((a, b)):
        torch.testing.assert_close(coefs[i], s["evecs"].mT @ (s["mass"][:, None] * s["hks"]))


def test_pad_collate_pairs_numbers_and_generic_keys():
    a, b = shape(1), shape(2)
    items = [{"x": a, "y": b, "p2p_yx": torch.arange(b["verts"].shape[0]), "w": 0.5},
             {"x": b, "y": a, "p2p_yx": torch.arange(a["verts"].shape[0]), "w": 1.5}]
    batch = pad_collate(items)
    assert batch["x"]["mask"].shape == (2, b["verts"].shape[0]) and batch["x"]["name"] == ["s1", "s2"]
    assert batch["p2p_yx_mask"].sum(1).tolist() == [b["verts"].shape[0], a["verts"].shape[0]]
    assert batch["w"].tolist() == [0.5, 1.5]


def test_pad_collate_errors():
    with pytest.raises(ValueError, match="empty batch"):
        pad_collate([])
    with pytest.raises(ValueError, match="samples have different keys"):
        pad_collate([{"a": torch.zeros(1)}, {"b": torch.zeros(1)}])
    with pytest.raises(ValueError, match="cannot stack tensors of ranks \\[1, 2\\]"):
        pad_stack([torch.zeros(2), torch.zeros(2, 2)])
    assert pad_stack([torch.ones(1, dtype=torch.bool), torch.ones(2, dtype=torch.bool)]).tolist() == \
        [[True, False], [True, True]]


@pytest.mark.multiprocess
def test_dataloader_with_two_workers(tmp_path):
    root = tmp_path / "meshes"
    root.mkdir()
    verts, faces, mirror = mirror_mesh(2)
    for i in range(3):
        write_mesh(root / f"m{i}.off", verts * (1 + 0.1 * i), faces)
    V = verts.shape[0]
    pre = Compose([NormalizeArea(), ComputeSpectrum(K), SetSymmetries(torch.stack([torch.arange(V),
                                                                                     mirror]))])
    ds = MeshDataset(root, pre, transform=RandomSymmetry(), processed_dir=tmp_path / "cache",
                     ground_truth="template")
    loader = DataLoader(PairDataset(ds), batch_size=2, num_workers=2, collate_fn=pad_collate)
    seen = 0
    for batch in loader:
        B = batch["fmap_xy"].shape[0]
        assert batch["x"]["evecs"].shape == (B, V, K) and batch["x"]["mask"].all()
        # each relabelled pair still has a valid ground truth, a vertex permutation
        for p in batch["p2p_yx"]:
            assert torch.equal(p.sort().values, torch.arange(V))
        seen += B
    assert seen == 6


def test_pad_collate_on_device(cuda_device):
    """Samples already on ``device`` (a GPU pre-transform) collate there, masks included."""
    device = cuda_device  # on CPU the comparison would be with itself
    a, b = shape(1, with_mirror=False), shape(2)
    move = (lambda s: {k: v.to(device) if torch.is_tensor(v) else v for k, v in s.items()})
    batch, ref = pad_collate([move(a), move(b)]), pad_collate([a, b])
    assert set(batch) == set(ref)
    for key, val in ref.items():
        if torch.is_tensor(val):
            assert batch[key].device == torch.device(device), key
            assert torch.equal(batch[key].cpu(), val), key


def test_pad_collate_confidence_and_uncertain_share_the_group_mask():
    a, b = shape(1, with_mirror=False), shape(2)
    a.update(sym_confidence=torch.tensor([1.0], dtype=torch.float64), sym_uncertain=torch.tensor([False]))
    b.update(sym_confidence=torch.tensor([1.0, 0.3], dtype=torch.float64), sym_uncertain=torch.tensor([False, True]))
    batch = pad_collate([a, b])
    assert batch["sym_confidence"].tolist() == [[1.0, 0.0], [1.0, 0.3]]
    assert batch["sym_uncertain"].tolist() == [[False, False], [False, True]]
    assert "sym_confidence_mask" not in batch and "sym_uncertain_mask" not in batch
