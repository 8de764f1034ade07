"""Point selection on meshes: adjacency, local extrema, farthest point sampling."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import torch
from torch import Tensor

from ._checks import to_numpy


def vertex_adjacency(faces, n_verts: int) -> sp.csr_matrix:
    """[V, V] symmetric 0/1 adjacency of the mesh edges (no self loops)."""
    f = to_numpy(faces, np.int64)
    i = np.concatenate([f[:, 0], f[:, 1], f[:, 2], f[:, 1], f[:, 2], f[:, 0]])
    j = np.concatenate([f[:, 1], f[:, 2], f[:, 0], f[:, 0], f[:, 1], f[:, 2]])
    A = sp.coo_matrix((np.ones_like(i, dtype=np.float64), (i, j)), shape=(n_verts, n_verts)).tocsr()
    A.data[:] = 1.0
    return A


def count_components(faces, n_verts: int) -> int:
    """Connected components of the vertices the faces reference (unreferenced vertices are ignored)."""
    from scipy.sparse.csgraph import connected_components

    f = to_numpy(faces, np.int64)
    _, labels = connected_components(vertex_adjacency(f, n_verts), directed=False)
    return int(np.unique(labels[np.unique(f)]).size)


def knn_adjacency(verts, k: int = 8) -> sp.csr_matrix:
    """[V, V] symmetric k-nearest-neighbour adjacency (0/1) of a point cloud: the pattern of
    :func:`symtorch.point_cloud.knn_graph`."""
    from .point_cloud import knn_graph

    A = knn_graph(to_numpy(verts, np.float64), k)
    A.data[:] = 1.0
    return A


def local_maxima(values, adjacency: sp.csr_matrix, rings: int = 2) -> np.ndarray:
    """Vertices whose value is the largest within ``rings`` edge rings (ties broken by index).

    Args:
        values: [V] function on the vertices.
        adjacency: [V, V] from ``vertex_adjacency`` or ``knn_adjacency``.

    Returns:
        [N] vertex ids, by decreasing value.
    """
    f = to_numpy(values, np.float64).reshape(-1)
    V = f.shape[0]
    # Rank-based comparison makes ties strict: each vertex has a distinct rank.
    rank = np.empty(V, dtype=np.float64)
    rank[np.lexsort((np.arange(V), f))] = np.arange(V)
    # max of rank over the ``rings``-ring neighbourhood: the 1-ring max applied ``rings`` times
    # (O(rings * E); no sparse matrix powers)
    A = sp.csr_matrix(adjacency)
    has = np.diff(A.indptr) > 0
    starts = A.indptr[:-1][has]
    neigh_max = rank.copy()
    for _ in range(rings):
        ring = neigh_max.copy()
        if A.nnz:
            ring[has] = np.maximum(ring[has], np.maximum.reduceat(neigh_max[A.indices], starts))
        neigh_max = ring
    ids = np.flatnonzero(rank >= neigh_max)
    return ids[np.argsort(-f[ids])]


def farthest_point_sampling(points: Tensor, n: int, start: int = 0) -> Tensor:
    """Greedy farthest point sampling in Euclidean space.

    Args:
        points: [V, D] (3D positions or a spectral embedding).
        n: number of samples (clamped to V).
        start: first sample.

    Returns:
        [n] long vertex ids.
    """
    V = points.shape[0]
    n = min(n, V)
    # the loop is sequential by nature: numpy on the host is ~5x faster than small torch ops
    x = points.detach().cpu().numpy().astype(np.float64)
    out = np.empty(n, dtype=np.int64)
    dist = np.full(V, np.inf)
    d = np.empty(V)
    cur = start
    if x.shape[1] <= 8:
        # few coordinates: one contiguous row per coordinate and in-place ufuncs, no [V, D]
        # temporary per step (3D, 12.5K points, 2000 samples: 0.03 s instead of 0.19 s)
        xt = np.ascontiguousarray(x.T)
        tmp = np.empty(V)
        for i in range(n):
            out[i] = cur
            np.subtract(xt[0], xt[0, cur], out=d)
            np.multiply(d, d, out=d)
            for row in xt[1:]:
                np.subtract(row, row[cur], out=tmp)
                np.multiply(tmp, tmp, out=tmp)
                np.add(d, tmp, out=d)
            np.minimum(dist, d, out=dist)
            cur = int(dist.argmax())
    else:
        x = np.ascontiguousarray(x)
        for i in range(n):
            out[i] = cur
            diff = x - x[cur]
            np.einsum("ij,ij->i", diff, diff, out=d)
            np.minimum(dist, d, out=dist)
            cur = int(dist.argmax())
    return torch.as_tensor(out, device=points.device)
