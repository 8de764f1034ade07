"""Point clouds: input checks, consistently oriented normals, local triangle fans and a triangulation.

A point cloud has no faces, but the detectors need three things faces give a mesh: a neighbourhood
graph (local maxima, graph distances, Voronoi cells), an orientation of the surface (the
orientation vote of a map: does it keep or flip the winding?) and small triangles to take gradients
on (the orientation guide). :func:`local_triangulation` gives all three at once: the union of every
point's tangent-plane Delaunay fan (``potpourri3d.PointCloudLocalTriangulation``, the fans
``robust_laplacian.point_cloud_laplacian`` builds its Laplacian from), each triangle once, wound
counter-clockwise about the normals of :func:`oriented_normals`. It is a triangle soup, not a
manifold mesh: good for everything local. The Laplacian and the heat method run on the fans
themselves, :func:`local_triangles`, with their repeats (robust-laplacian's construction: the
tufted cover of the soup is what :func:`fan_spectrum` and ``geodesics.GeodesicSolver`` build from
them), without the triangles that bridge two sheets of the surface; or on the point cloud as it is
(``spectrum.laplacian_matrices(verts, None)``, ``GeodesicSolver(verts, None)``).

Normals: PCA of each point's nearest neighbours, made to agree along a minimum spanning tree of the
neighbour graph (Hoppe et al., "Surface reconstruction from unorganized points", SIGGRAPH 1992). The
tree's edge cost ``1 - |n_i . n_j|`` is raised by how far each edge leaves the two tangent planes,
so that the propagation does not jump between two sheets that touch (an arm resting on a torso:
close points, antiparallel normals). Each connected part is then turned outward (normals pointing
away from its centroid on average; only the agreement matters to the detectors).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ._checks import check_verts

__all__ = ["MIN_POINTS", "check_point_cloud", "pca_normals", "oriented_normals", "local_triangles",
           "fan_spectrum", "local_triangulation", "knn_graph"]

#: fewest points a detection accepts: the point-cloud Laplacian needs neighbourhoods (30 points)
#: and the detectors a few dozen eigenpairs
MIN_POINTS = 100


def check_point_cloud(points, min_points: int = MIN_POINTS, name: str = "points") -> np.ndarray:
    """Validate a point cloud: [N, 3] finite floats, at least ``min_points`` of them, spanning a surface.

    Returns:
        [N, 3] float64 numpy array.

    Raises:
        ValueError: wrong shape, NaN or inf coordinates, too few points, all points coincident or on
            a line.
    """
    v = check_verts(points, name)
    if v.shape[0] < min_points:
        raise ValueError(f"{name}: a point cloud needs at least {min_points} points for symmetry "
                         f"detection, got {v.shape[0]}")
    s = np.linalg.svd(v - v.mean(axis=0), compute_uv=False)
    if s[0] == 0 or s[1] <= 1e-8 * s[0]:
        raise ValueError(f"{name}: point cloud has zero area (its {v.shape[0]} points are "
                         "coincident or collinear)")
    distinct = np.unique(v, axis=0).shape[0]
    if distinct < v.shape[0]:
        raise ValueError(f"{name}: point cloud has {v.shape[0] - distinct} duplicated points (identical "
                         "coordinates); remove them first (symmetry maps are reported per point)")
    return v


def _neighbors(v: np.ndarray, k: int) -> np.ndarray:
    """[N, k] the k nearest other points of each point."""
    from scipy.spatial import cKDTree

    k = min(k, v.shape[0] - 1)
    return cKDTree(v).query(v, k=k + 1)[1][:, 1:]


def pca_normals(points, k: int = 12) -> np.ndarray:
    """[N, 3] unit normals (sign arbitrary): the least-variance direction of each point's ``k`` nearest
    neighbours and itself."""
    v = np.asarray(points, dtype=np.float64)
    nn = np.concatenate([np.arange(len(v))[:, None], _neighbors(v, k)], axis=1)  # [N, k+1]
    x = v[nn] - v[nn].mean(axis=1, keepdims=True)                                # [N, k+1, 3]
    _, vecs = np.linalg.eigh(x.transpose(0, 2, 1) @ x)                           # ascending
    return vecs[:, :, 0]


def oriented_normals(points, k: int = 12) -> np.ndarray:
    """[N, 3] unit normals that agree across the surface, outward on each closed part (module docstring).

    Args:
        points: [N, 3] positions.
        k: neighbours of the PCA fit and of the propagation graph.
    """
    from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree

    v = np.asarray(points, dtype=np.float64)
    n = pca_normals(v, k)
    N = len(v)
    nn = _neighbors(v, k)
    i, j = np.repeat(np.arange(N), nn.shape[1]), nn.reshape(-1)
    e = v[j] - v[i]
    e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-300)
    # cost: normals that disagree, and edges that leave the tangent planes (two touching sheets)
    cost = 1.0 - np.abs((n[i] * n[j]).sum(1)) + np.abs((n[i] * e).sum(1)) + np.abs((n[j] * e).sum(1))
    G = sp.coo_matrix((cost + 1e-9, (i, j)), shape=(N, N)).tocsr()  # 1e-9: a zero would be no edge
    G = G.maximum(G.T)
    T = minimum_spanning_tree(G)
    T = T + T.T
    n_parts, labels = connected_components(T, directed=False)
    sign = np.zeros(N)
    for part in range(n_parts):
        members = np.flatnonzero(labels == part)
        root = int(members[0])
        order, pred = breadth_first_order(T, root, directed=False, return_predecessors=True)
        sign[root] = 1.0
        # parents come before their children in breadth-first order
        agree = np.sign((n[order[1:]] * n[pred[order[1:]]]).sum(1))
        for node, parent, a in zip(order[1:].tolist(), pred[order[1:]].tolist(), agree.tolist()):
            sign[node] = sign[parent] * (a if a != 0 else 1.0)
        outward = float((sign[members, None] * n[members] * (v[members] - v[members].mean(0))).sum())
        if outward < 0:
            sign[members] *= -1.0
    return n * sign[:, None]


def local_triangles(points, normals: np.ndarray | None = None, min_cos: float | None = 0.0) -> np.ndarray:
    """[T, 3] int64: every point's tangent-plane Delaunay fan, one triangle per fan it is in.

    The fans of ``potpourri3d.PointCloudLocalTriangulation``, the construction
    ``robust_laplacian.point_cloud_laplacian`` sums (its Laplacian is that of this soup, divided by
    three). Where two sheets of the surface come within a point spacing of each other (a hand on a
    thigh), fans bridge them and the Laplacian and the heat method take the short cut; a bridging
    triangle has corners whose normals face each other. With ``min_cos``, triangles whose corner
    normals (``normals``, default :func:`oriented_normals`) disagree, some pair's cosine below it, are
    dropped, as long as the soup stays one connected piece: the triangles of a point cut off that
    way are kept.

    Args:
        points: [N, 3].
        normals: [N, 3] consistently oriented; only with ``min_cos``.
        min_cos: cosine threshold, or None to keep every fan whole.

    Returns:
        [T, 3] triangles with repeats (a triangle in three fans is there three times), first corner
        the centre of the fan, winding arbitrary.
    """
    import potpourri3d as pp3d
    from scipy.sparse.csgraph import connected_components

    v = np.asarray(points, dtype=np.float64)
    tri = pp3d.PointCloudLocalTriangulation(v).get_local_triangulation().reshape(-1, 3)
    tri = tri[(tri >= 0).all(axis=1)].astype(np.int64)
    if min_cos is None:
        return tri
    n = oriented_normals(v) if normals is None else np.asarray(normals, dtype=np.float64)
    cos = np.minimum.reduce([(n[tri[:, a]] * n[tri[:, b]]).sum(1) for a, b in ((0, 1), (1, 2), (0, 2))])
    keep = cos >= min_cos
    N = len(v)
    for _ in range(N):  # each round restores the fans of the points outside the largest piece
        k = tri[keep]
        A = sp.coo_matrix((np.ones(3 * len(k)), (k.ravel(), k[:, [1, 2, 0]].ravel())), shape=(N, N))
        n_parts, labels = connected_components(A, directed=False)
        main = np.bincount(labels).argmax()
        cut = labels[tri[:, 0]] != main
        if n_parts == 1 or (keep | cut).sum() == keep.sum():
            break
        keep |= cut
    return tri[keep]


def fan_spectrum(points, fans: np.ndarray, k: int, **kw):
    """``spectrum.laplacian_spectrum`` of the fans, as robust-laplacian counts them.

    Each fan triangle is in the fans of its (up to) three corners, so the soup's stiffness and mass
    are three times the surface's; ``robust_laplacian.point_cloud_laplacian`` divides both by three.
    Solved on the soup as a mesh, the unit-area scaling would take the tripled area: the eigenvalues
    would come out three times too large and ``scale`` ``sqrt(3)`` times too small. Corrected here.

    Args:
        points: [N, 3]; fans: [T, 3] from :func:`local_triangles`; k: eigenpairs.
        **kw: ``laplacian_spectrum`` keywords (``dtype``, ``device``).

    Returns:
        Spectrum(evals [k], evecs [N, k], mass [N] summing to 1, scale) of the unit-area surface.
    """
    from .spectrum import Spectrum, laplacian_spectrum

    spec = laplacian_spectrum(points, fans, k=k, **kw)
    return Spectrum(spec.evals / 3.0, spec.evecs, spec.mass, spec.scale * 3.0 ** 0.5)


def local_triangulation(points, normals: np.ndarray | None = None,
                        triangles: np.ndarray | None = None) -> np.ndarray:
    """[F, 3] int64 triangles: the union of the fans (``triangles``, default :func:`local_triangles`),
    each triangle once, wound counter-clockwise about ``normals`` (default :func:`oriented_normals`).

    Zero-area triangles are left out. Every point is a corner of its own fan, so every point is
    referenced (unless its whole neighbourhood is degenerate).
    """
    v = np.asarray(points, dtype=np.float64)
    n = oriented_normals(v) if normals is None else np.asarray(normals, dtype=np.float64)
    tri = local_triangles(v, n) if triangles is None else np.asarray(triangles, dtype=np.int64)
    _, first = np.unique(np.sort(tri, axis=1), axis=0, return_index=True)
    tri = tri[np.sort(first)]
    fn = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])  # [F, 3], twice the area
    area2 = np.linalg.norm(fn, axis=1)
    keep = area2 > 1e-12 * max(float(area2.max(initial=0.0)), 1e-300)
    tri, fn = tri[keep], fn[keep]
    flip = (fn * n[tri].sum(axis=1)).sum(axis=1) < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return tri


def knn_graph(points, k: int = 8) -> sp.csr_matrix:
    """[N, N] symmetric sparse matrix of Euclidean distances to the ``k`` nearest neighbours (a
    point-cloud stand-in for a mesh's edge graph)."""
    v = np.asarray(points, dtype=np.float64)
    nn = _neighbors(v, k)
    i, j = np.repeat(np.arange(len(v)), nn.shape[1]), nn.reshape(-1)
    w = np.maximum(np.linalg.norm(v[i] - v[j], axis=1), 1e-300)  # a zero would be no edge
    G = sp.coo_matrix((w, (i, j)), shape=(len(v),) * 2).tocsr()
    return G.maximum(G.T).tocsr()
