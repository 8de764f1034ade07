"""Correspondence evaluation with the field's protocol, on small meshes whose truth is known."""
import math

import pytest
import scipy.io
import torch

from symtorch.eval import (CorrespondenceEvaluator, CorrespondenceScore, PairScore, ShapeDistances,
                           pair_score, summarize_pairs)
from symtorch.geodesics import graph_distances
from shapes import mirror_mesh


@pytest.fixture(scope="module")
def pair():
    """x: the mirror blob; y: the same template stretched (same vertex order): the truth is the
    identity, the symmetric truth the mirror permutation."""
    verts, faces, mirror = mirror_mesh(1)
    V = verts.shape[0]
    y = verts * torch.tensor([1.0, 1.3, 0.8], dtype=verts.dtype)
    corr = torch.arange(V)
    return verts, y, faces, mirror, corr


def test_identity_and_mirror_maps(pair):
    x, _, faces, mirror, corr = pair
    dist_x = ShapeDistances(x, faces)
    good = pair_score(corr, corr, corr, dist_x, corr_sym_x=mirror)
    assert isinstance(good, PairScore) and good.points.shape == corr.shape
    assert good.mean == 0 and good.mean_sym > 0.1 and not good.flipped
    assert good.mean_up_to_symmetry == 0
    flip = pair_score(mirror, corr, corr, dist_x, corr_sym_x=mirror)
    assert flip.flipped and flip.mean_sym == 0 and flip.mean_up_to_symmetry == 0
    assert math.isclose(flip.mean, good.mean_sym, rel_tol=0.05)  # d(g(p), p), both directions
    plain = pair_score(mirror, corr, corr, dist_x)
    assert plain.errors_sym is None and math.isnan(plain.mean_sym) and not plain.flipped
    assert plain.mean_up_to_symmetry == plain.mean


def test_errors_follow_the_formula_with_a_geodesic_matrix(pair):
    x, _, faces, mirror, corr = pair
    V = x.shape[0]
    D = graph_distances(x, faces, torch.arange(V))
    dist_x = ShapeDistances(x, faces, dist=D)
    g = torch.Generator().manual_seed(0)
    p2p = torch.randint(V, (V,), generator=g)
    corr_y = torch.randperm(V, generator=g)  # y's vertex of template point k
    corr_x = torch.randperm(V, generator=g)
    s = pair_score(p2p, corr_x, corr_y, dist_x, corr_sym_x=mirror[corr_x])
    area = 0.5 * torch.linalg.cross(x[faces[:, 1]] - x[faces[:, 0]],
                                    x[faces[:, 2]] - x[faces[:, 0]]).norm(dim=-1).sum()
    ref = D[corr_x, p2p[corr_y]] / area.sqrt()
    torch.testing.assert_close(s.errors, ref)
    torch.testing.assert_close(s.errors_sym, D[mirror[corr_x], p2p[corr_y]] / area.sqrt())
    assert math.isclose(s.mean, float(ref.mean()))


def test_subsets_missing_points_and_scale(pair):
    x, _, faces, mirror, corr = pair
    V = x.shape[0]
    dist_x = ShapeDistances(x, faces)
    sub = pair_score(mirror, corr, corr, dist_x, corr_sym_x=mirror, n_points=10)
    assert sub.points.shape == (10,) and sub.points[0] == 0 and sub.points[-1] == V - 1
    some = pair_score(mirror, corr, corr, dist_x, points=torch.tensor([3, 5, 7]))
    assert some.points.tolist() == [3, 5, 7]
    holes = torch.where(corr % 4 == 0, -1, corr)
    h = pair_score(mirror, holes, corr, dist_x)
    assert (h.points % 4 != 0).all() and h.points.numel() == V - (V + 3) // 4
    # scale free: the same map on x scaled by 3 has the same normalised errors
    big = pair_score(mirror, corr, corr, ShapeDistances(3 * x, faces), corr_sym_x=mirror)
    full = pair_score(mirror, corr, corr, dist_x, corr_sym_x=mirror)
    torch.testing.assert_close(big.errors, full.errors, rtol=1e-6, atol=1e-9)


def test_pair_score_errors(pair):
    x, _, faces, mirror, corr = pair
    dist_x = ShapeDistances(x, faces)
    with pytest.raises(ValueError, match="corr_x and corr_y must name the same template points"):
        pair_score(corr, corr, corr[:5], dist_x)
    with pytest.raises(ValueError, match="p2p_yx must map into \\[0, 41\\]"):
        pair_score(corr + 100, corr, corr, dist_x)
    with pytest.raises(ValueError, match="corr_sym_x has 5 template points"):
        pair_score(corr, corr, corr, dist_x, corr_sym_x=corr[:5])
    with pytest.raises(ValueError, match="no template point is present on both shapes"):
        pair_score(corr, torch.full_like(corr, -1), corr, dist_x)
    with pytest.raises(ValueError, match="p2p_yx must be a 1-D tensor of vertex ids"):
        pair_score(corr.double(), corr, corr, dist_x)
    with pytest.raises(ValueError, match="dist must be \\[V, V\\] = \\[42, 42\\]"):
        ShapeDistances(x, faces, dist=torch.zeros(3, 3))
    with pytest.raises(ValueError, match="summarize_pairs got no pair scores"):
        summarize_pairs([])


def test_evaluator_over_pairs_with_dist_files(pair, tmp_path):
    x, y, faces, mirror, corr = pair
    V = x.shape[0]
    D = graph_distances(x, faces, torch.arange(V))
    scipy.io.savemat(tmp_path / "x.mat", {"dist": D.numpy()})
    # the sample is at half the file's scale (NormalizeArea's ``scale``): the file's distances follow
    sx = {"name": "x", "verts": 0.5 * x, "faces": faces, "corr": corr, "corr_sym": mirror,
          "scale": torch.tensor(0.5, dtype=torch.float64), "dist_path": str(tmp_path / "x.mat")}
    sy = {"name": "y", "verts": y, "faces": faces, "corr": corr, "corr_sym": mirror}
    ev = CorrespondenceEvaluator()
    assert ev.distances(sx) is ev.distances(sx)  # cached per shape
    assert ev.distances(sx).dist is not None and ev.distances(sy).dist is None
    ref = pair_score(mirror, corr, corr, ShapeDistances(x, faces, D), corr_sym_x=mirror)
    got = ev.score(mirror, sx, sy)
    torch.testing.assert_close(got.errors, ref.errors)
    summary = ev.evaluate([(corr, sx, sy), (mirror, sx, sy), (corr, sy, sx)])
    assert isinstance(summary, CorrespondenceScore) and len(summary.pairs) == 3
    assert math.isclose(summary.flipped_share, 1 / 3)
    assert math.isclose(summary.mean, sum(p.mean for p in summary.pairs) / 3)
    assert summary.mean_up_to_symmetry == 0
    heat = CorrespondenceEvaluator(n_points=8, use_dist_files=False)
    assert heat.distances(sx).dist is None and heat.score(corr, sx, sy).points.numel() == 8
    with pytest.raises(ValueError, match="sample y \\('y'\\) has no corr ground truth"):
        ev.score(corr, sx, {k: v for k, v in sy.items() if k != "corr"})
