"""One reflection voted by a dataset's shapes through their correspondences (symtorch.data.consensus)."""
import pytest
import torch

from symtorch.data import ComputeSpectrum, NormalizeArea
from symtorch.data.consensus import template_reflection, with_template_reflection

from shapes import mirror_mesh


def _dataset(n_shapes: int = 5, seed: int = 0):
    """Copies of one mirror-symmetric mesh, each with its vertices shuffled (so that no two shapes
    share vertex ids), ``corr`` to the unshuffled template and the true reflection as the
    'detected' one: (samples, the template's mirror permutation)."""
    verts, faces, mirror = mirror_mesh(2)
    g = torch.Generator().manual_seed(seed)
    out = []
    for i in range(n_shapes):
        perm = torch.randperm(len(verts), generator=g)        # new vertex j is old vertex perm[j]
        inv = torch.argsort(perm)                              # old vertex k is new vertex inv[k]
        v = verts[perm] * (1.0 + 0.1 * i)                      # a different scale per shape
        f = inv[faces]
        R = inv[mirror[perm]]                                  # the reflection in the new ids
        s = {"name": f"s{i}", "verts": v, "faces": f, "corr": inv.clone(),
             "sym_p2p": torch.stack([torch.arange(len(v)), R]), "sym_reverses": torch.tensor([False, True]),
             "sym_confidence": torch.tensor([1.0, 1.0])}
        out.append(ComputeSpectrum(k=12)(NormalizeArea()(s)))
    return out, mirror


def _wrong(sample: dict) -> dict:
    """The sample with a wrong 'detected' reflection: the true one composed with a half turn of the
    shape's vertex labels (every vertex sent far from its mirror image)."""
    R = sample["sym_p2p"][1]
    shift = torch.roll(torch.arange(len(R)), len(R) // 2)
    return dict(sample, sym_p2p=torch.stack([sample["sym_p2p"][0], R[shift]]))


def test_the_vote_recovers_the_templates_reflection_and_outvotes_a_wrong_shape():
    samples, mirror = _dataset(5)
    samples[2] = _wrong(samples[2])
    tr = template_reflection(samples)
    assert tr.n_shapes == 5
    assert (tr.perm == mirror).double().mean() > 0.99
    assert float(tr.support.median()) == pytest.approx(0.8)  # four of five agree
    fixed = with_template_reflection(samples[2], tr)
    truth = _dataset(5)[0][2]["sym_p2p"][1]
    assert (fixed["sym_p2p"][1] == truth).double().mean() > 0.99
    assert fixed["sym_reverses"].tolist() == [False, True]
    assert fixed["sym_fmap"].shape == (2, 12, 12)
    assert "sym_confidence" not in fixed  # it described the detector's map, not this one


def test_shapes_without_a_reflection_or_correspondence_do_not_vote():
    samples, mirror = _dataset(3)
    samples[0] = {k: v for k, v in samples[0].items() if k not in ("sym_p2p", "sym_reverses")}
    samples[1] = dict(samples[1], corr=torch.full_like(samples[1]["corr"], -1))
    tr = template_reflection(samples)
    assert tr.n_shapes == 1
    assert bool((tr.perm == mirror).all())


def test_missing_template_points_stay_unknown_and_mismatched_templates_are_refused():
    samples, _ = _dataset(3)
    corr = samples[0]["corr"].clone()
    corr[:10] = -1
    samples = [dict(s, corr=corr if i == 0 else s["corr"]) for i, s in enumerate(samples)]
    tr = template_reflection(samples)
    assert bool((tr.perm >= 0).all())  # the other shapes still vote for those points
    with pytest.raises(ValueError, match="different lengths"):
        template_reflection([samples[0], dict(samples[1], corr=samples[1]["corr"][:-1])])
    with pytest.raises(ValueError, match="at least one"):
        template_reflection([])
    none = template_reflection([{k: v for k, v in samples[0].items() if k != "sym_p2p"}])
    assert none.n_shapes == 0 and bool((none.perm == -1).all())
