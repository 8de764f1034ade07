"""Tests for symtorch.maps: p2p <-> fmap round trips and the composition conventions of ALGORITHM §2.

Composition is pinned on an exactly D_5h-symmetric prism (:func:`symtorch.shapes.polar_prism`),
where a rotation and a mirror do not commute, so the order of the matrix product is observable.
"""
from __future__ import annotations

import pytest
import torch

from shapes import mirror_mesh
from symtorch.groups import compose_fmap, compose_p2p, inverse_fmap
from symtorch.geodesics import voronoi_cells
from symtorch.maps import (TwoLevelSearch, fmap_to_p2p, least_squares, nearest_neighbors,
                           nearest_neighbors_among, p2p_to_fmap)
from symtorch.sampling import farthest_point_sampling
from symtorch.shapes import polar_prism, polar_prism_symmetries, symmetry_maps
from symtorch.spectrum import band_boundary, eigen_bands, laplacian_spectrum


@pytest.fixture(scope="module")
def mirror():
    verts, faces, perm = mirror_mesh(2)
    s = laplacian_spectrum(verts, faces, k=30)
    K = band_boundary(eigen_bands(s.evals), 20)
    return s, K, perm


@pytest.fixture(scope="module")
def d5h():
    """Spectrum cut at an exact eigenspace boundary, and the 20 exact symmetries as p2p [20, V]."""
    verts, faces = polar_prism(5, height=0.94)
    s = laplacian_spectrum(verts, faces, k=30)
    lam = s.evals.numpy()
    ends = [i + 1 for i in range(len(lam) - 1) if lam[i + 1] - lam[i] > 1e-7 * lam[-1]]
    K = min(ends, key=lambda e: abs(e - 20))
    p2p = torch.as_tensor(symmetry_maps(verts, polar_prism_symmetries(5)))
    return s, K, p2p


def test_mirror_round_trip_is_exact(mirror):
    s, K, perm = mirror
    E = s.evecs[:, :K]
    C = p2p_to_fmap(perm, E, s.mass)
    assert C.shape == (K, K)
    torch.testing.assert_close(C.mT @ C, torch.eye(K, dtype=C.dtype), atol=1e-8, rtol=0)
    # rows of the embedding move as evecs[p2p] = evecs @ C
    torch.testing.assert_close(E[perm], E @ C, atol=1e-8, rtol=0)
    # an involution: C @ C = I, and C is diagonal +-1 (simple eigenvalues)
    torch.testing.assert_close(C @ C, torch.eye(K, dtype=C.dtype), atol=1e-8, rtol=0)
    assert torch.equal(fmap_to_p2p(C, E), perm)
    assert torch.equal(fmap_to_p2p(torch.eye(K, dtype=C.dtype), E), torch.arange(len(perm)))


def test_round_trip_float32_and_batched(mirror):
    s, K, perm = mirror
    E = s.evecs[:, :K]
    C = p2p_to_fmap(torch.stack([perm, torch.arange(len(perm))]), E, s.mass)  # [2, K, K]
    assert C.shape == (2, K, K)
    out = fmap_to_p2p(C.float(), E.float())
    assert out.shape == (2, len(perm)) and torch.equal(out[0], perm) and torch.equal(out[1].sort().values, out[1])


def test_pullback_acts_on_coefficients(mirror):
    """If f = evecs @ a then f o g = evecs @ (C @ a) (ALGORITHM §2)."""
    s, K, perm = mirror
    E = s.evecs[:, :K]
    C = p2p_to_fmap(perm, E, s.mass)
    a = torch.randn(K, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    f = E @ a
    torch.testing.assert_close(f[perm], E @ (C @ a), atol=1e-8, rtol=0)


def test_symmetries_round_trip_on_prism(d5h):
    s, K, p2p = d5h
    E = s.evecs[:, :K]
    C = p2p_to_fmap(p2p, E, s.mass)  # [20, K, K]
    eye = torch.eye(K, dtype=C.dtype)
    torch.testing.assert_close(C.mT @ C, eye.expand_as(C), atol=1e-8, rtol=0)
    # the 20 maps come back exactly, 2-D eigenspaces included
    assert torch.equal(fmap_to_p2p(C, E), p2p)


def test_composition_order(d5h):
    s, K, p2p = d5h
    E = s.evecs[:, :K]
    g, h = p2p[1], p2p[5]  # the rotation by 2 pi / 5 and a vertical mirror: they do not commute
    assert not torch.equal(g[h], h[g])
    C_g, C_h = p2p_to_fmap(g, E, s.mass), p2p_to_fmap(h, E, s.mass)
    gh = compose_p2p(g, h)  # "apply h, then g"
    assert torch.equal(gh, g[h])
    C_gh = p2p_to_fmap(gh, E, s.mass)
    torch.testing.assert_close(C_gh, C_h @ C_g, atol=1e-8, rtol=0)
    torch.testing.assert_close(compose_fmap(C_g, C_h), C_h @ C_g)
    assert (C_gh - C_g @ C_h).abs().max() > 0.1, "the other order must differ on D5h"


def test_inverse_is_transpose(d5h):
    s, K, p2p = d5h
    E = s.evecs[:, :K]
    g = p2p[1]
    g_inv = torch.empty_like(g)
    g_inv[g] = torch.arange(len(g))
    C_g = p2p_to_fmap(g, E, s.mass)
    torch.testing.assert_close(p2p_to_fmap(g_inv, E, s.mass), C_g.mT, atol=1e-8, rtol=0)
    torch.testing.assert_close(inverse_fmap(C_g), C_g.mT)
    # order 5: C^5 = I and no smaller power is
    P = torch.eye(K, dtype=C_g.dtype)
    for n in range(1, 6):
        P = P @ C_g
        assert ((P - torch.eye(K, dtype=P.dtype)).abs().max() < 1e-7) == (n == 5), n


def test_nearest_neighbors_kdtree_and_blocked_agree():
    g = torch.Generator().manual_seed(0)
    pts = torch.randn(300, 8, generator=g, dtype=torch.float64)
    q = pts[torch.randperm(300, generator=g)] + 1e-6 * torch.randn(300, 8, generator=g, dtype=torch.float64)
    tree = nearest_neighbors(q, pts)
    wide = torch.cat([pts, torch.zeros(300, 50, dtype=torch.float64)], 1)  # D > 48: blocked cdist
    qw = torch.cat([q, torch.zeros(300, 50, dtype=torch.float64)], 1)
    blocked = nearest_neighbors(qw, wide, chunk=64)
    assert torch.equal(tree, blocked)
    assert torch.equal(pts[tree], pts[(q[:, None] - pts[None]).norm(dim=-1).argmin(1)])


def test_value_errors(mirror):
    s, K, perm = mirror
    E = s.evecs[:, :K]
    with pytest.raises(ValueError, match="p2p has 161 entries but the domain has 162 vertices"):
        p2p_to_fmap(perm[:-1], E, s.mass)
    with pytest.raises(ValueError, match=rf"C must be \[{K}, {K}\], got \[{K}, {K - 1}\]"):
        fmap_to_p2p(torch.zeros(K, K - 1, dtype=torch.float64), E)


def test_nearest_neighbors_among_is_the_best_candidate():
    g = torch.Generator().manual_seed(0)
    points = torch.randn(500, 8, generator=g, dtype=torch.float64)
    queries = torch.randn(300, 8, generator=g, dtype=torch.float64)
    # every candidate set holds all points: the same answer as the full search
    full = torch.arange(500).expand(4, 500)
    groups = torch.randint(0, 4, (300,), generator=g)
    assert torch.equal(nearest_neighbors_among(queries, points, full, groups, chunk=64),
                       nearest_neighbors(queries, points))
    # restricted sets: the answer is in the query's set and no other member of it is nearer
    cand = torch.stack([torch.randperm(500, generator=g)[:20] for _ in range(4)])
    got = nearest_neighbors_among(queries, points, cand, groups)
    for q in range(300):
        c = cand[groups[q]]
        assert int(got[q]) in c.tolist()
        assert int(got[q]) == int(c[(points[c] - queries[q]).norm(dim=1).argmin()])
    # uneven groups (one holds most queries, several none) cut into many tiles and blocks
    cand = torch.stack([torch.randperm(500, generator=g)[:30] for _ in range(40)])
    groups = torch.where(torch.rand(300, generator=g) < 0.7, 3, torch.randint(0, 20, (300,), generator=g))
    got = nearest_neighbors_among(queries, points, cand, groups, chunk=2)
    d = (points[cand[groups]] - queries[:, None]).norm(dim=-1)  # [300, 30]
    assert torch.equal(got, cand[groups].gather(1, d.argmin(1, keepdim=True))[:, 0])
    assert nearest_neighbors_among(queries[:0], points, cand, groups[:0]).shape == (0,)
    with pytest.raises(ValueError, match="groups has 299 entries for 300 queries"):
        nearest_neighbors_among(queries, points, cand, groups[:299])


def test_two_level_search_agrees_with_the_full_search(mirror):
    s, K, perm = mirror
    verts, faces, _ = mirror_mesh(2)
    vu = torch.as_tensor(verts) * s.scale
    C = p2p_to_fmap(perm, s.evecs[:, :K], s.mass)  # the true mirror's matrix, truncated
    full = fmap_to_p2p(C, s.evecs[:, :K])
    samples = farthest_point_sampling(vu, 150)
    cells = voronoi_cells(vu, faces, samples)
    local = TwoLevelSearch(vu, s.evecs, samples, cells, 24)(C)
    assert float((local == full).double().mean()) > 0.97
    assert float((local == perm).double().mean()) >= float((full == perm).double().mean()) - 0.01
    at = torch.arange(0, len(vu), 7)
    assert torch.equal(TwoLevelSearch(vu, s.evecs, samples, cells, 24)(C, at), local[at])
    # no local search: a cell without a sample, or n_local 0
    no_cell = torch.full_like(cells, -1)
    assert torch.equal(TwoLevelSearch(vu, s.evecs, samples, no_cell, 24)(C), full)
    assert torch.equal(TwoLevelSearch(vu, s.evecs, samples, cells, 0)(C), full)


def test_maps_on_device(mirror, device):
    """Round trips and nearest-neighbour searches on ``device``: the same answers as on CPU."""
    s, K, perm = mirror
    E, m = s.evecs[:, :K].to(device), s.mass.to(device)
    C = p2p_to_fmap(perm.to(device), E, m)
    assert C.device == E.device
    torch.testing.assert_close(C.cpu(), p2p_to_fmap(perm, s.evecs[:, :K], s.mass))
    assert torch.equal(fmap_to_p2p(C, E).cpu(), perm)
    g = torch.Generator().manual_seed(0)
    points = torch.randn(500, 8, generator=g, dtype=torch.float64)
    queries = torch.randn(300, 8, generator=g, dtype=torch.float64)
    cand = torch.stack([torch.randperm(500, generator=g)[:20] for _ in range(4)])
    groups = torch.randint(0, 4, (300,), generator=g)
    nn = nearest_neighbors(queries.to(device), points.to(device))
    assert nn.device == torch.device(device) and torch.equal(nn.cpu(), nearest_neighbors(queries, points))
    among = nearest_neighbors_among(queries.to(device), points.to(device), cand.to(device), groups.to(device))
    assert torch.equal(among.cpu(), nearest_neighbors_among(queries, points, cand, groups))


def _at_offset(t: torch.Tensor, offset: int) -> torch.Tensor:
    """A copy of ``t`` whose storage starts ``offset`` elements into a fresh buffer."""
    buf = torch.empty(t.numel() + offset, dtype=t.dtype)
    out = buf[offset:].view_as(t)
    out.copy_(t)
    return out


def test_least_squares_is_bitwise_reproducible():
    # torch's CPU default (pivoted QR, gelsy) changes its last bits with the inputs' memory
    # alignment, which made two trainings from one seed drift apart; least_squares must not.
    g = torch.Generator().manual_seed(0)
    A = torch.randn(3000, 30, generator=g, dtype=torch.float64)
    B = torch.randn(3000, 30, generator=g, dtype=torch.float64)
    ref = least_squares(A, B)
    assert torch.allclose(ref, torch.linalg.pinv(A) @ B, atol=1e-10)
    for offset in range(1, 9):
        assert torch.equal(least_squares(_at_offset(A, offset), _at_offset(B, offset)), ref)
    assert least_squares(A.float(), B.float()).dtype == torch.float32
