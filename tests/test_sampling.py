"""Tests for symtorch.sampling: farthest point sampling and mesh-graph local maxima."""
from __future__ import annotations

import numpy as np
import torch

from symtorch.sampling import farthest_point_sampling


def _reference_fps(x: np.ndarray, n: int, start: int = 0) -> np.ndarray:
    """Plain greedy FPS: each next point maximises the distance to those already taken."""
    out = [start]
    d = np.linalg.norm(x - x[start], axis=1)
    for _ in range(n - 1):
        nxt = int(d.argmax())
        out.append(nxt)
        d = np.minimum(d, np.linalg.norm(x - x[nxt], axis=1))
    return np.array(out)


def test_fps_matches_the_greedy_definition_in_3d_and_in_high_dimension():
    rng = np.random.default_rng(0)
    for dim in (3, 20):  # the coordinate-row path (D <= 8) and the [V, D] path
        x = rng.standard_normal((700, dim))
        got = farthest_point_sampling(torch.as_tensor(x), 60, start=5).numpy()
        assert np.array_equal(got, _reference_fps(x, 60, start=5))
        assert len(set(got.tolist())) == 60


def test_fps_prefix_is_spread_and_n_is_clamped():
    x = torch.as_tensor(np.random.default_rng(1).random((400, 3)))
    s = farthest_point_sampling(x, 1000)
    assert s.shape == (400,) and len(set(s.tolist())) == 400
    # the first samples are far apart: their closest pair beats the closest pair overall
    head = x[s[:10]]
    d = torch.cdist(head, head) + torch.eye(10) * 1e9
    dall = torch.cdist(x, x) + torch.eye(400) * 1e9
    assert float(d.min()) > 10 * float(dall.min())


def test_local_maxima_match_the_ring_definition():
    import trimesh
    from scipy.sparse.csgraph import shortest_path

    from symtorch.sampling import local_maxima, vertex_adjacency

    m = trimesh.creation.icosphere(subdivisions=2)
    V = len(m.vertices)
    A = vertex_adjacency(m.faces, V)
    hops = shortest_path(A, unweighted=True)  # [V, V] edge rings
    rng = np.random.default_rng(2)
    for values in (rng.random(V), np.round(m.vertices[:, 0], 1)):  # the second has many ties
        rank = np.empty(V)
        rank[np.lexsort((np.arange(V), values))] = np.arange(V)  # ties: the larger index wins
        for rings in (1, 2, 3):
            want = [v for v in range(V) if rank[v] >= rank[hops[v] <= rings].max()]
            got = local_maxima(values, A, rings=rings)
            assert sorted(got.tolist()) == sorted(want)
            assert np.all(np.diff(values[got]) <= 0)  # by decreasing value


def test_count_components_ignores_unreferenced_vertices():
    import trimesh

    from symtorch.sampling import count_components

    m = trimesh.creation.icosphere(subdivisions=1)
    V = len(m.vertices)
    faces = np.concatenate([m.faces, m.faces + V])
    assert count_components(m.faces, V) == 1
    assert count_components(faces, 2 * V) == 2
    assert count_components(m.faces, V + 7) == 1  # 7 vertices no face references


def test_knn_adjacency_is_the_symmetric_pattern_of_the_k_nearest():
    from scipy.spatial import cKDTree
    from symtorch.sampling import knn_adjacency

    v = np.random.default_rng(0).random((300, 3))
    A = knn_adjacency(v, k=5)
    assert (A != A.T).nnz == 0 and set(np.unique(A.data)) == {1.0} and A.diagonal().sum() == 0
    nn = cKDTree(v).query(v, k=6)[1][:, 1:]
    assert all(A[i, j] == 1.0 for i in range(300) for j in nn[i])
    assert (np.diff(A.indptr) >= 5).all()
