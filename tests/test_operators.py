"""ComputeOrientationOperators (symtorch.data.operators): repr, keys, and how orient_op follows the
other transforms (mirror, change of basis, relabelling by a symmetry)."""
import pytest
import torch

from symtorch.data import (Compose, ComputeDescriptors, ComputeOrientationOperators, ComputeSpectrum,
                           NormalizeArea, SetSymmetries, apply_symmetry, change_basis, mirror_shape,
                           pad_collate)
from symtorch.descriptors import default_energies, default_times, hks, wks
from symtorch.orientation import orientation_operators
from shapes import mirror_mesh


def rel(a, b):
    return float((a - b).norm() / b.norm())


@pytest.fixture(scope="module")
def sample():
    verts, faces, mirror = mirror_mesh(2)
    pre = Compose([NormalizeArea(), ComputeSpectrum(k=12), ComputeDescriptors(n_hks=4, n_wks=8),
                   SetSymmetries(torch.stack([torch.arange(len(verts)), mirror]))])
    return pre({"name": "mirror", "verts": verts, "faces": faces})


def test_repr_lists_every_argument():
    assert repr(ComputeOrientationOperators()) == \
        "ComputeOrientationOperators(n_descriptors=16, descriptor='wks', normalize=True)"
    assert repr(ComputeOrientationOperators(4, "hks", normalize=False)) == \
        "ComputeOrientationOperators(n_descriptors=4, descriptor='hks', normalize=False)"


def test_uses_the_samples_descriptors_or_computes_them(sample):
    out = ComputeOrientationOperators(n_descriptors=4)(sample)
    assert "orient_op" not in sample  # the input is not mutated
    O = out["orient_op"]
    assert O.shape == (4, 12, 12) and O.dtype == sample["evecs"].dtype
    cols = sample["wks"][:, [0, 2, 5, 7]]  # 4 evenly spaced of the sample's 8 columns
    args = (sample["verts"], sample["faces"], sample["evecs"], sample["mass"])
    torch.testing.assert_close(O, orientation_operators(*args, cols))
    bare = {k: v for k, v in sample.items() if k not in ("wks", "hks")}
    evals, evecs = sample["evals"], sample["evecs"]
    energies, sigma = default_energies(evals, 4)
    torch.testing.assert_close(ComputeOrientationOperators(4)(bare)["orient_op"],
                               orientation_operators(*args, wks(evals, evecs, energies, sigma)))
    torch.testing.assert_close(ComputeOrientationOperators(3, "hks")(bare)["orient_op"],
                               orientation_operators(*args, hks(evals, evecs, default_times(evals, 3))))
    batch = pad_collate([out, out])
    assert batch["orient_op"].shape == (2, 4, 12, 12)


def test_value_errors(sample):
    with pytest.raises(ValueError, match=r"descriptor must be one of \('wks', 'hks'\), got 'sihks'"):
        ComputeOrientationOperators(descriptor="sihks")
    with pytest.raises(ValueError, match="n_descriptors must be >= 1, got 0"):
        ComputeOrientationOperators(0)
    with pytest.raises(ValueError, match="n_descriptors=16 but the sample's 'hks' has 4 columns"):
        ComputeOrientationOperators(16, "hks")(sample)
    with pytest.raises(ValueError, match=r"needs sample keys \['evecs', 'evals', 'mass'\]"):
        ComputeOrientationOperators()({"verts": sample["verts"], "faces": sample["faces"]})


def test_mirror_negates_orient_op(sample):
    t = ComputeOrientationOperators(4)
    O = t(sample)["orient_op"]
    mirrored = dict(sample, verts=sample["verts"] * torch.tensor([-1.0, 1.0, 1.0]).to(sample["verts"]),
                    faces=sample["faces"].flip(1))  # same vertex order, basis and descriptors
    assert rel(t(mirrored)["orient_op"], -O) < 1e-5


def test_transforms_carry_orient_op_as_a_recomputation_would(sample):
    # the transports of the cached key agree with computing it afresh on the transformed sample
    t = ComputeOrientationOperators(4)
    s = t(sample)
    O = s["orient_op"]
    recomputed = t(mirror_shape(sample))["orient_op"]
    assert rel(mirror_shape(s)["orient_op"], recomputed) < 1e-5 and rel(recomputed, -O) < 1e-5
    signs = torch.diag(torch.tensor([1.0, -1.0] * 6)).to(O)
    assert rel(change_basis(s, signs)["orient_op"], t(change_basis(sample, signs))["orient_op"]) < 1e-5
    relabelled = apply_symmetry(s, 1)  # the reflection: ground truth moves, the mesh does not
    assert torch.equal(relabelled["orient_op"], O)
    assert rel(t(apply_symmetry(sample, 1))["orient_op"], O) < 1e-6
    # the reflection itself anti-commutes with the operators of its invariant descriptors
    S = s["sym_fmap"][1]
    assert rel(S @ O @ S.mT, -O) < 1e-5
