"""Mirror test-time averaging (symtorch.tta)."""
import torch

from symtorch.tta import mirror_averaged_fmap, mirror_pair
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
