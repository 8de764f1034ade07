"""Tests for symtorch.detect.candidates: invariant points, source tuples, pruned target tuples."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from symtorch import shapes
from symtorch.units import EPS_KLC
from symtorch.detect.candidates import (candidate_tuples, descriptor_ratios, invariant_points, partner_mask,
                                       source_tuples)
from symtorch.spectrum import laplacian_spectrum


def test_candidate_tuples_keep_distance_preserving_targets():
    # four corners of a unit square plus its centre: the 8 symmetries of the square move a source
    # tuple (corner, corner, centre) to exactly 8 targets
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], dtype=np.float64)
    dist = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    allowed = np.ones((5, 5), dtype=bool)
    q, total = candidate_tuples([0, 1, 4], dist, allowed, delta=0.9, slack=0.0)
    assert total == 5 * 4 * 3
    assert len(q) == 8, q
    assert (q[:, 2] == 4).all()  # the centre maps to itself
    allowed[4, 4] = False  # descriptors forbid the centre from staying: nothing survives
    q, _ = candidate_tuples([0, 1, 4], dist, allowed, delta=0.9, slack=0.0)
    assert len(q) == 0


def test_invariant_points_are_mapped_onto_themselves_by_the_symmetries():
    """P is a union of orbits: every true symmetry sends each point of P near a point of P."""
    v, f = shapes.star_prism(subdivisions=3)
    spec = laplacian_spectrum(v, f, k=40)
    unit = v * spec.scale
    pts = invariant_points(spec.evals, spec.evecs, f, unit, n_max=40)
    assert 10 <= len(pts) <= 40 and len(set(pts.tolist())) == len(pts)
    tree = cKDTree(unit[pts])
    for g in shapes.symmetry_maps(v, shapes.true_symmetries("star_prism")):
        d, _ = tree.query(unit[g[pts]])
        # the mesh is only approximately symmetric (the true maps are nearest vertices of a rigid
        # motion, an edge off): within the KLC tolerance, while points of P are >= 1 eps apart
        assert d.max() < EPS_KLC and d.mean() < 0.5 * EPS_KLC, d


def test_the_suppression_keeps_an_orbit_whose_members_straddle_its_radius():
    """A square antiprism's corners lie 0.92 and 1.02 suppression radii from the coarsest scale's
    maxima, by the triangulation of its caps (split along one diagonal); the suppression must keep
    all eight or none, so the set stays a union of D4d orbits (``border=0``: half the corners)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from shapes import antiprism, convex_solid

    v, f, mats = convex_solid(antiprism(4, 0.6))
    spec = laplacian_spectrum(v, f, k=60)
    unit = np.asarray(v) * spec.scale
    corners = [int(np.linalg.norm(v - c, axis=1).argmin()) for c in antiprism(4, 0.6)]

    def missed(**kw):
        pts = invariant_points(spec.evals, spec.evecs, f, unit, n_max=40, **kw)
        tree = cKDTree(unit[pts])
        worst = max(tree.query(unit[g[pts]])[0].max() for g in shapes.symmetry_maps(v, mats))
        return worst, sum(tree.query(unit[c])[0] > 0.5 * EPS_KLC for c in corners)

    worst, corners_missed = missed()
    assert worst < 0.5 * EPS_KLC and corners_missed == 0, (worst / EPS_KLC, corners_missed)
    assert missed(border=0.0)[1] == 4


def test_source_tuples_are_spread_distinct_and_prefer_usable_points():
    rng = np.random.default_rng(0)
    x = rng.random((12, 3))
    dist = np.linalg.norm(x[:, None] - x[None], axis=-1)
    out = source_tuples(dist, 4, 3)
    assert len(out) == 3 and all(len(t) == 4 and len(set(t)) == 4 for t in out)
    assert len({tuple(sorted(t)) for t in out}) == 3
    first = out[0]
    assert first[0] == int(np.argmax(dist.sum(1)))  # the most eccentric point starts
    assert first[1] == int(np.argmax(dist[first[0]]))  # then the farthest from it
    usable = np.zeros(12, dtype=bool)
    usable[[1, 3, 5, 7, 9]] = True
    assert all(set(t) <= {1, 3, 5, 7, 9} for t in source_tuples(dist, 4, 3, usable))


def test_descriptor_ratios_are_shares_of_the_median_pair_and_gate_the_partners():
    import torch

    g = np.random.default_rng(0)
    base = np.exp(g.normal(size=(4, 6)))
    # points 0/1 and 2/3 are partners (equal descriptors); 4 and 5 stand apart
    desc = torch.as_tensor(np.concatenate([base[[0, 0, 1, 1]], base[2:4]]))
    r = descriptor_ratios(desc)
    n = len(desc)
    assert r.shape == (n, n) and np.allclose(r, r.T) and np.allclose(np.diag(r), 0)
    assert np.isclose(np.median(r[~np.eye(n, dtype=bool)]), 1.0)
    assert r[0, 1] < 1e-9 and r[2, 3] < 1e-9 and r[0, 2] > 0.1
    dist = np.ones((n, n)) - np.eye(n)  # every point the same distance profile
    allowed = partner_mask(desc, dist, 0.6)
    assert allowed[0, 1] and allowed[2, 3] and not allowed[0, 2]
    assert (allowed == (r <= 0.6)).all()
    # identical descriptors everywhere: the median is 0 and only exact matches pass
    same = descriptor_ratios(torch.ones(3, 4))
    assert (same == 0).all()


def test_relative_gate_admits_a_distinctive_point_s_nearest_partners():
    import torch

    g = np.random.default_rng(2)
    base = np.exp(g.normal(size=(8, 6)))
    # points 0-5 alike, 6 and 7 a distinctive pair (two arm tips a bend pulled apart): far from the
    # rest, nearer each other than anything else, but beyond the global tolerance
    far = np.exp(5.0) * base[[6]]
    desc = torch.as_tensor(np.concatenate([base[:6], far, far * 3.0]))
    r = descriptor_ratios(desc)
    n = len(desc)
    dist = np.ones((n, n)) - np.eye(n)
    assert r[6, 7] > 0.6 and r[6, 7] < 0.5 * min(np.median(r[6, :6]), np.median(r[7, :6]))
    plain = partner_mask(desc, dist, 0.6)
    relative = partner_mask(desc, dist, 0.6, relative_tol=0.5)
    assert not plain[6, 7] and relative[6, 7] and relative[7, 6]
    assert not relative[6, :6].any() and (relative >= plain).all()


def test_descriptor_ratios_look_around_a_point_displaced_along_its_ridge():
    import torch

    g = np.random.default_rng(1)
    base = np.exp(g.normal(size=(5, 6)))
    # vertices 0..4 are the points; point 1 is the partner of point 0 but sits one vertex off the
    # spot that matches it (vertex 5, next to 1, carries point 0's descriptors)
    desc_all = torch.as_tensor(np.concatenate([base[[0]], base[[1]] * 3.0, base[2:5], base[[0]]]))
    P = np.arange(5)
    mask = torch.zeros(5, 6, dtype=torch.bool)
    mask[P, P] = True
    plain = descriptor_ratios(desc_all[P])
    assert np.allclose(descriptor_ratios(desc_all[P], (desc_all, mask)), plain)  # only themselves
    mask[1, 5] = True
    near = descriptor_ratios(desc_all[P], (desc_all, mask))
    assert plain[0, 1] > 0.5 and near[0, 1] < 1e-9 and near[1, 0] < 1e-9  # symmetric
    rest = [0, 2, 3, 4]  # pairs without point 1 do not look at vertex 5
    assert (near <= plain + 1e-12).all() and np.allclose(near[np.ix_(rest, rest)], plain[np.ix_(rest, rest)])
    dist = np.ones((5, 5)) - np.eye(5)
    assert partner_mask(desc_all[P], dist, 0.3, (desc_all, mask))[0, 1]
    assert not partner_mask(desc_all[P], dist, 0.3)[0, 1]


def test_top_of_hill_tells_a_peak_from_a_ripple():
    """0-dimensional persistence in a ball: on a grid, a tall bump's top stands a tenth of the range
    above every path to a higher vertex; a ripple on its flank (a hundredth high) does not, nor
    does a vertex on the slope; the ripple tops a hill of its own, under a thousandth high."""
    import scipy.sparse as sp

    from symtorch.detect.candidates import _top_of_hill

    n = 41
    xy = np.stack(np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n)), -1).reshape(-1, 2)
    idx = np.arange(n * n).reshape(n, n)
    rows = np.concatenate([idx[:, :-1].ravel(), idx[:-1].ravel()])
    cols = np.concatenate([idx[:, 1:].ravel(), idx[1:].ravel()])
    adj = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n * n, n * n))
    adj = (adj + adj.T).tocsr()
    f = np.exp(-((xy ** 2).sum(1)) / 0.1)  # the peak at the centre, range ~1
    f = f + 0.01 * np.exp(-((xy - xy[idx[20, 36]]) ** 2).sum(1) / 0.01)  # on the foot of the peak
    ripple = int(idx[20, 36])
    ball = np.ones(n * n, dtype=bool)
    peak = int(f.argmax())
    assert peak == idx[20, 20]
    assert _top_of_hill(f, adj, ball, peak, 0.1)
    assert not _top_of_hill(f, adj, ball, ripple, 0.1) and _top_of_hill(f, adj, ball, ripple, 1e-4)
    assert not _top_of_hill(f, adj, ball, idx[20, 26], 0.05)


def test_candidate_tuples_may_leave_a_source_point_without_target():
    """``max_missing``: a source point no point of the set can be the image of (a bend moved its
    partner's extremum away) leaves -1 in its place instead of emptying every tuple through it."""
    x = np.array([0.0, 1.0, 2.5, 4.5])
    dist = np.abs(x[:, None] - x[None])
    allowed = np.ones((4, 4), dtype=bool)
    allowed[1] = False  # point 1 has no partner
    q, _ = candidate_tuples([0, 1, 2], dist, allowed, delta=0.9, slack=0.0)
    assert len(q) == 0
    q, _ = candidate_tuples([0, 1, 2], dist, allowed, delta=0.9, slack=0.0, max_missing=1)
    assert len(q) and (q[:, 1] == -1).all()
    assert [0, -1, 2] in q.tolist() and [2, -1, 0] in q.tolist()  # the identity and the flip keep d(0, 2)
    assert all(abs(dist[a, b] - dist[0, 2]) <= 0.1 * max(dist[a, b], dist[0, 2]) for a, _, b in q.tolist())
