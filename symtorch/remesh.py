"""Independent remeshing of a shape and closest-point transfer of vertex data onto the remesh.

The correspondence datasets the field trains on (FAUST_r, SCAPE_r; Ren et al. 2018) remesh every shape
on its own, so that no two shapes share connectivity, and carry the ground truth over by closest
vertices. This module holds the reusable half of ``scripts/build_scape_r.py``:

- :func:`remesh_acvd` remeshes a surface to about ``n_verts`` vertices by approximated centroidal
  Voronoi clustering (ACVD; Valette, Chassery & Prost 2008) through the optional ``pyacvd`` package.
  The input is shuffled with a seeded permutation first, because the clustering is seeded in vertex
  order: shapes that share one template numbering would otherwise start from the same clusters.
  :func:`clean_remesh` drops what clustering can leave behind.
- :func:`closest_points` finds the exact closest point of a triangle mesh to each query point.
- Query points to vertex ids: :func:`nearest_vertices` (Euclidean, what FAUST_r / SCAPE_r do),
  :func:`projected_vertices` (through the closest surface point), :func:`geodesic_nearest_vertices`
  (along the source surface) and :func:`same_sheet_nearest_vertices` (Euclidean unless that crosses
  a gap between two sheets of surface, where two body parts touch).
- :func:`orientation_report`, :func:`orient_faces` and :func:`count_pinched_vertices` check and
  repair what ``symtorch.io.mesh_report`` does not look at: consistent, outward winding and
  vertices where the surface touches itself.

Everything here is numpy in, numpy out (float64 positions, int64 ids): it prepares data on disk.
"""
from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from ._checks import check_faces, check_mesh, check_verts

__all__ = ["SurfacePoints", "closest_points", "nearest_vertices", "projected_vertices",
           "geodesic_nearest_vertices", "same_sheet_nearest_vertices",
           "orientation_report", "orient_faces", "count_pinched_vertices", "clean_remesh",
           "fill_nonmanifold", "remesh_acvd"]


class SurfacePoints(NamedTuple):
    """Closest points on a triangle mesh (see :func:`closest_points`).

    Attributes:
        face: [N] int64 face holding each closest point.
        bary: [N, 3] barycentric coordinates of the point in that face (rows sum to 1).
        points: [N, 3] the closest points.
        dist: [N] Euclidean distance from each query to its closest point.
    """

    face: np.ndarray
    bary: np.ndarray
    points: np.ndarray
    dist: np.ndarray


def _closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates [N, 3] of the closest point of triangle (a, b, c) to p, row-wise.

    Ericson, *Real-Time Collision Detection* (2005), §5.1.5, vectorised: the Voronoi regions of the
    three vertices, three edges and the face are tested in turn; a point is assigned to the first
    region that holds it. Degenerate triangles fall through to an edge or vertex region.
    """
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2

    n = p.shape[0]
    bary = np.empty((n, 3))
    done = np.zeros(n, dtype=bool)

    def put(mask, u, v, w):
        m = mask & ~done
        bary[m, 0], bary[m, 1], bary[m, 2] = u[m] if np.ndim(u) else u, v[m] if np.ndim(v) else v, \
            w[m] if np.ndim(w) else w
        done[m] = True

    with np.errstate(divide="ignore", invalid="ignore"):
        put((d1 <= 0) & (d2 <= 0), 1.0, 0.0, 0.0)  # vertex a
        put((d3 >= 0) & (d4 <= d3), 0.0, 1.0, 0.0)  # vertex b
        put((d6 >= 0) & (d5 <= d6), 0.0, 0.0, 1.0)  # vertex c
        t = d1 / (d1 - d3)
        put((vc <= 0) & (d1 >= 0) & (d3 <= 0), 1 - t, t, 0.0)  # edge ab
        t = d2 / (d2 - d6)
        put((vb <= 0) & (d2 >= 0) & (d6 <= 0), 1 - t, 0.0, t)  # edge ac
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        put((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), 0.0, 1 - t, t)  # edge bc
        denom = va + vb + vc
        v, w = vb / denom, vc / denom
        put(np.isfinite(v) & np.isfinite(w), 1 - v - w, v, w)  # inside the face
    if not done.all():  # a zero-area triangle the tests above missed: take its nearest vertex
        rest = np.flatnonzero(~done)
        d = np.stack([np.linalg.norm(p[rest] - q[rest], axis=1) for q in (a, b, c)], axis=1)
        bary[rest] = np.eye(3)[d.argmin(1)]
    return bary


def closest_points(verts, faces, points, chunk: int = 4096) -> SurfacePoints:
    """Exact closest point on a triangle mesh to each query point.

    The nearest vertex bounds the distance to the surface from above, so every face that can hold a
    closer point has its centroid within that distance plus the largest centroid-to-corner radius of
    any face; those candidates are tested exactly (:func:`_closest_on_triangles`). Cost grows with
    how uneven the face sizes are; on a mesh of even triangles a query tests a few dozen faces.

    Args:
        verts: [V, 3] mesh vertices.
        faces: [F, 3] triangles.
        points: [N, 3] query points.
        chunk: queries handled at once (bounds the memory of the candidate lists).

    Returns:
        :class:`SurfacePoints` with ``face [N]``, ``bary [N, 3]``, ``points [N, 3]``, ``dist [N]``.
    """
    v, f = check_mesh(verts, faces)
    q = check_verts(points, name="points")
    tri = v[f]  # [F, 3, 3]
    cent = tri.mean(axis=1)  # [F, 3]
    radius = float(np.linalg.norm(tri - cent[:, None], axis=2).max())
    vtree, ctree = cKDTree(v), cKDTree(cent)
    bound, _ = vtree.query(q)  # [N] an upper bound on the distance to the surface
    face = np.empty(len(q), dtype=np.int64)
    bary = np.empty((len(q), 3))
    dist = np.empty(len(q))
    for start in range(0, len(q), chunk):
        sl = slice(start, start + chunk)
        # 1e-9 relative slack: a face touching the nearest vertex must not be lost to rounding
        cand = ctree.query_ball_point(q[sl], bound[sl] + radius * (1 + 1e-9) + 1e-12)
        counts = np.fromiter((len(c) for c in cand), dtype=np.int64, count=len(cand))
        rows = np.repeat(np.arange(len(cand)), counts)  # [M] query of each candidate
        cols = np.fromiter((i for c in cand for i in c), dtype=np.int64, count=int(counts.sum()))
        pq = q[sl][rows]
        b = _closest_on_triangles(pq, tri[cols, 0], tri[cols, 1], tri[cols, 2])  # [M, 3]
        cp = np.einsum("mk,mkd->md", b, tri[cols])
        d2 = np.sum((cp - pq) ** 2, axis=1)
        # the candidate of least distance per query: sort by (query, distance), keep each first
        order = np.lexsort((d2, rows))
        first = order[np.r_[True, rows[order][1:] != rows[order][:-1]]]
        face[sl], bary[sl], dist[sl] = cols[first], b[first], np.sqrt(d2[first])
    pts = np.einsum("nk,nkd->nd", bary, tri[face])
    return SurfacePoints(face, bary, pts, dist)


def nearest_vertices(verts, points) -> np.ndarray:
    """Id of the Euclidean nearest vertex of ``verts`` [V, 3] to each of ``points`` [N, 3]: [N] int64."""
    _, idx = cKDTree(check_verts(verts)).query(check_verts(points, name="points"))
    return np.asarray(idx, dtype=np.int64)


def projected_vertices(verts, faces, points) -> np.ndarray:
    """Vertex ids [N] through the surface: the corner nearest to the closest point, of its face.

    Differs from :func:`nearest_vertices` only where the nearest vertex is not a corner of the face
    that holds the closest point: skewed triangles, or two sheets of surface closer together than an
    edge (between fingers, thighs), where the Euclidean nearest vertex may lie on the other sheet.
    """
    v, f = check_mesh(verts, faces)
    sp = closest_points(v, f, points)
    corners = f[sp.face]  # [N, 3]
    d = np.linalg.norm(v[corners] - sp.points[:, None], axis=2)
    return corners[np.arange(len(corners)), d.argmin(axis=1)]


def _site_graph(src_verts: np.ndarray, src_faces: np.ndarray, sites: np.ndarray):
    """Edge graph of the source with one extra node per site, joined to the corners of its face.

    Returns (graph [V + S, V + S] csr, site node ids [S]); sites are located by :func:`closest_points`.
    """
    import scipy.sparse as sp

    from .geodesics import edge_graph

    n = src_verts.shape[0]
    loc = closest_points(src_verts, src_faces, sites)
    corners = src_faces[loc.face]  # [S, 3]
    # a site on a vertex would give a zero weight, which csgraph reads as no edge
    w = np.linalg.norm(src_verts[corners] - loc.points[:, None], axis=2) + 1e-12
    G = edge_graph(src_verts, src_faces).tocoo()
    node = n + np.arange(len(sites))
    rows = np.concatenate([G.row, np.repeat(node, 3)])
    cols = np.concatenate([G.col, corners.ravel()])
    A = sp.coo_matrix((np.concatenate([G.data, w.ravel()]), (rows, cols)), shape=(n + len(sites),) * 2)
    A = A.tocsr()
    return A.maximum(A.T).tocsr(), node


def geodesic_nearest_vertices(src_verts, src_faces, verts) -> np.ndarray:
    """For each source vertex, the vertex of ``verts`` nearest along the source surface (graph metric).

    ``verts`` must lie on (or very near) the source surface, as a remesh's vertices do: each is
    placed at its closest point of the source and joined to that face's corners, and one
    multi-source Dijkstra over the source edges assigns every source vertex to its nearest site.
    Never crosses a gap between two sheets of surface, but edge paths over-estimate distances by
    up to ~15 %, so in flat regions it may pick a vertex slightly farther than the Euclidean nearest.

    Args:
        src_verts: [V, 3] source mesh.
        src_faces: [F, 3] its triangles.
        verts: [N, 3] sites on the source surface.

    Returns:
        [V] int64 ids into ``verts``.
    """
    from scipy.sparse.csgraph import dijkstra

    v, f = check_mesh(src_verts, src_faces)
    A, node = _site_graph(v, f, check_verts(verts))
    _, _, src = dijkstra(A, indices=node, min_only=True, return_predecessors=True)
    return (src[: v.shape[0]] - v.shape[0]).astype(np.int64)


def same_sheet_nearest_vertices(src_verts, src_faces, verts, detour: float = 2.0,
                                chunk: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Euclidean nearest vertex, except where it lies across a gap: then the geodesic nearest one.

    The Euclidean nearest vertex of ``verts`` to a source vertex can sit on another sheet of the
    surface (the inside of the other thigh, the next finger). It is kept where the path along the
    source (edge graph, :func:`geodesic_nearest_vertices`' graph) to it is at most ``detour`` times
    the straight distance plus one mean source edge, which an edge path on the same sheet always is;
    elsewhere the geodesic nearest vertex replaces it. Both agree on most vertices; only those where
    they differ are checked.

    Args:
        src_verts: [V, 3] source mesh.
        src_faces: [F, 3] its triangles.
        verts: [N, 3] vertices on the source surface (a remesh of it).
        detour: largest accepted ratio of path length to straight distance.
        chunk: source vertices checked per Dijkstra call.

    Returns:
        (ids [V] int64 into ``verts``, replaced [V] bool: where the nearest vertex was rejected).
    """
    from scipy.sparse.csgraph import dijkstra

    v, f = check_mesh(src_verts, src_faces)
    q = check_verts(verts)
    near = nearest_vertices(q, v)
    A, node = _site_graph(v, f, q)
    _, _, src = dijkstra(A, indices=node, min_only=True, return_predecessors=True)
    geo = (src[: v.shape[0]] - v.shape[0]).astype(np.int64)
    edge = float(np.linalg.norm(v[f[:, 0]] - v[f[:, 1]], axis=1).mean())
    straight = np.linalg.norm(q[near] - v, axis=1)
    bound = detour * straight + edge  # [V]
    todo = np.flatnonzero(near != geo)
    replaced = np.zeros(v.shape[0], dtype=bool)
    for start in range(0, todo.size, chunk):
        t = todo[start:start + chunk]
        D = dijkstra(A, indices=t, limit=float(bound[t].max()))  # [T, V + N], inf beyond the limit
        replaced[t] = D[np.arange(t.size), node[near[t]]] > bound[t]
    return np.where(replaced, geo, near), replaced


def orientation_report(verts, faces) -> dict:
    """Whether the faces are consistently oriented, and the signed volume they enclose.

    Args:
        verts: [V, 3] vertices.
        faces: [F, 3] triangles.

    Returns:
        dict with ``n_misoriented_edges`` (directed edges used twice: neighbouring faces that
        disagree; 0 for a consistently oriented manifold), ``signed_volume`` (positive when the
        normals ``(b - a) x (c - a)`` point outward of a closed surface) and ``outward`` (bool).
    """
    v, f = check_mesh(verts, faces)
    n = v.shape[0]
    directed = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, counts = np.unique(directed[:, 0] * n + directed[:, 1], return_counts=True)
    tri = v[f] - v.mean(axis=0)  # centred: the volume of an open surface is then less arbitrary
    vol = float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)
    return dict(n_misoriented_edges=int((counts > 1).sum()), signed_volume=vol, outward=vol > 0)


def _edge_neighbours(faces: np.ndarray, n_verts: int):
    """Pairs of faces sharing an undirected edge, from consecutive half-edges sorted by edge.

    Returns (a, b, u, w, agree): faces a and b share edge (u, w); ``agree`` when they traverse it in
    opposite directions (consistently oriented). An edge in k faces gives k - 1 pairs.
    """
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)  # [3F, 2] in winding order
    owner = np.repeat(np.arange(faces.shape[0]), 3)
    key = directed.min(1) * n_verts + directed.max(1)
    order = np.argsort(key, kind="stable")
    key, owner, directed = key[order], owner[order], directed[order]
    same = np.flatnonzero(key[1:] == key[:-1])
    forward = directed[:, 0] < directed[:, 1]
    agree = forward[same] != forward[same + 1]
    return owner[same], owner[same + 1], directed[same].min(1), directed[same].max(1), agree


def count_pinched_vertices(faces, n_verts: int) -> int:
    """Extra fans at vertices whose incident faces form more than one (the surface touches itself).

    An edge-manifold mesh can still be pinched at a vertex; ``mesh_report`` only sees that through an
    odd Euler characteristic. Corners (face, vertex) are joined across the edges at that vertex;
    each vertex should then hold one group of corners, a fan.
    """
    f = check_faces(faces, n_verts)
    fans = _fan_counts(f, n_verts)
    return int(np.clip(fans - 1, 0, None).sum())


def _fan_counts(faces: np.ndarray, n_verts: int) -> np.ndarray:
    """[V] number of fans (edge-connected groups of incident faces) at each vertex; 0 if unused."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    a, b, u, w, _ = _edge_neighbours(faces, n_verts)

    def corner(face, vert):  # index of the corner of `face` at `vert`
        return 3 * face + np.argmax(faces[face] == vert[:, None], axis=1)

    rows = np.concatenate([corner(a, u), corner(a, w)])
    cols = np.concatenate([corner(b, u), corner(b, w)])
    n_c = 3 * faces.shape[0]
    _, label = connected_components(sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n_c, n_c)),
                                    directed=False)
    fans = np.unique(np.stack([faces.ravel(), label], axis=1), axis=0)[:, 0]  # one row per (vertex, fan)
    return np.bincount(fans, minlength=n_verts)


def orient_faces(verts, faces, outward: bool = True) -> np.ndarray:
    """Orient the faces consistently, component by component, and outward (or inward).

    A breadth-first walk over the faces flips each face to agree with the one it was reached from
    across a shared edge; then every component whose signed volume has the wrong sign is flipped
    whole. Faces on non-manifold edges (3+ faces) are walked through as well, so the result can
    still disagree there: check ``orientation_report`` afterwards.

    Args:
        verts: [V, 3] vertices.
        faces: [F, 3] triangles.
        outward: make each component's signed volume positive (False: negative).

    Returns:
        [F, 3] int64 faces, the same triangles in the same order, some with their winding reversed.
    """
    import scipy.sparse as sp
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    v, f = check_mesh(verts, faces)
    n_f = f.shape[0]
    a, b, _, _, agree = _edge_neighbours(f, v.shape[0])
    # store 1 (agree) / 2 (disagree) so that no entry is an explicit zero
    rel = sp.coo_matrix((np.where(agree, 1, 2), (a, b)), shape=(n_f, n_f)).tocsr()
    rel = rel.maximum(rel.T).tocsr()
    n_comp, comp = connected_components(rel, directed=False)
    flip = np.zeros(n_f, dtype=bool)
    seen = np.zeros(n_f, dtype=bool)
    for root in range(n_f):
        if seen[root]:
            continue
        walk, pred = breadth_first_order(rel, root, directed=False, return_predecessors=True)
        seen[walk] = True
        for j in walk[1:]:
            i = pred[j]
            flip[j] = flip[i] ^ (rel[i, j] == 2)
    f = np.where(flip[:, None], f[:, ::-1], f)
    tri = v[f]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))  # 6x signed volume
    comp_vol = np.bincount(comp, weights=vol, minlength=n_comp)
    wrong = (comp_vol < 0) if outward else (comp_vol > 0)
    return np.where(wrong[comp][:, None], f[:, ::-1], f).astype(np.int64)


def clean_remesh(verts, faces) -> tuple[np.ndarray, np.ndarray]:
    """Drop collapsed and duplicated faces, keep the largest component, drop unreferenced vertices.

    A clustering remesher can leave a few such faces and tiny islands where clusters meet badly;
    everything else (vertex order within what is kept, the face orientation) is left as it is.

    Returns:
        (verts [V', 3] float64, faces [F', 3] int64), vertices renumbered in their old order.
    """
    from .sampling import vertex_adjacency
    from scipy.sparse.csgraph import connected_components

    v = check_verts(verts)
    f = check_faces(faces, v.shape[0])
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    f = f[np.sort(first)]
    _, labels = connected_components(vertex_adjacency(f, v.shape[0]), directed=False)
    used = np.zeros(v.shape[0], dtype=bool)
    used[f.ravel()] = True
    sizes = np.bincount(labels[used], minlength=labels.max() + 1)
    keep_v = used & (labels == sizes.argmax())
    f = f[keep_v[f[:, 0]]]
    new = np.cumsum(keep_v) - 1
    return v[keep_v], new[f].astype(np.int64)


def _edge_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(edges [E, 2] as sorted vertex pairs, the number of faces on each [E])."""
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return np.unique(e, axis=0, return_counts=True)


def _boundary_loops(faces: np.ndarray) -> list[np.ndarray] | None:
    """Vertex loops of the boundary edges (edges in one face), or None where they do not form
    simple loops (a vertex on more than two boundary edges)."""
    u, c = _edge_counts(faces)
    b = u[c == 1]
    if b.size == 0:
        return []
    verts, deg = np.unique(b, return_counts=True)
    if (deg != 2).any():
        return None
    nbr: dict[int, list[int]] = {}
    for i, j in b:
        nbr.setdefault(int(i), []).append(int(j))
        nbr.setdefault(int(j), []).append(int(i))
    loops, seen = [], set()
    for start in nbr:
        if start in seen:
            continue
        loop, prev, cur = [start], None, start
        seen.add(start)
        while True:
            nxt = nbr[cur][0] if nbr[cur][0] != prev else nbr[cur][1]
            if nxt == start:
                break
            loop.append(nxt)
            seen.add(nxt)
            prev, cur = cur, nxt
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def fill_nonmanifold(verts, faces, project=None, max_rounds: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Cut out the faces around non-manifold edges and pinched vertices, and close the holes.

    ACVD can leave a few faces where clusters wrap around a feature thinner than a cluster (toes,
    fingers): an edge in three faces next to a small hole. The faces on such edges, on boundary
    edges and at pinched vertices are removed, the region grown by one ring per round until the
    hole boundaries are simple loops with no bad edge left, and each loop is closed by a fan around
    one new vertex at its centroid, moved onto the surface by ``project``.

    Args:
        verts: [V, 3] vertices.
        faces: [F, 3] triangles.
        project: callable [N, 3] -> [N, 3] placing new vertices (e.g. on the source surface);
            None keeps the loop centroids.
        max_rounds: most growth rounds before giving up.

    Returns:
        (verts [V + L, 3], faces [F', 3]); unchanged when nothing is wrong. The result may still be
        unusable where the rounds ran out: check it (``mesh_report``, :func:`count_pinched_vertices`).
        Fill faces are not oriented: run :func:`orient_faces` afterwards.
    """
    from .sampling import vertex_adjacency

    v = check_verts(verts)
    f = check_faces(faces, v.shape[0])
    n = v.shape[0]

    def bad_vertices(f):
        u, c = _edge_counts(f)
        bad = np.zeros(n, dtype=bool)
        bad[u[c != 2].ravel()] = True
        return bad

    def pinched(f):
        return count_pinched_vertices(f, n) if len(f) else 0

    bad = bad_vertices(f)
    if not bad.any() and pinched(f) == 0:
        return v, f
    if not bad.any():  # only pinches: find them by the faces whose corners share a fan problem
        bad = _fan_counts(f, n) > 1
    A = vertex_adjacency(f, n)
    for _ in range(max_rounds):
        keep = f[~bad[f].any(axis=1)]  # every face touching a bad vertex goes
        loops = _boundary_loops(keep) if len(keep) else None
        inner = bad_vertices(keep) if len(keep) else bad
        # what is left may only have hole boundaries (simple loops), no edge in 3+ faces, no pinch
        if loops is not None and all(len(lp) >= 3 for lp in loops) and pinched(keep) == 0 and \
                _edge_counts_ok(keep):
            centres = np.stack([v[lp].mean(axis=0) for lp in loops]) if loops else np.zeros((0, 3))
            if project is not None and len(centres):
                centres = np.asarray(project(centres), dtype=np.float64)
            fans = [np.stack([lp, np.roll(lp, -1), np.full(len(lp), n + k)], axis=1)
                    for k, lp in enumerate(loops)]
            return clean_remesh(np.vstack([v, centres]), np.vstack([keep] + fans))
        bad = bad | inner | (A @ bad.astype(np.float64) > 0)  # grow by one ring and retry
    return v, f


def _edge_counts_ok(faces: np.ndarray) -> bool:
    """No edge in three or more faces."""
    return bool((_edge_counts(faces)[1] <= 2).all())


def remesh_acvd(verts, faces, n_verts: int = 5000, subdivide: int = 0, seed: int = 0,
                maxiter: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Remesh a surface to about ``n_verts`` evenly spread vertices with ACVD (``pyacvd``).

    The vertices and faces are first shuffled by a permutation drawn from ``seed``: ACVD grows its
    first clusters in vertex order, so shapes sharing one template numbering (SCAPE, FAUST) would
    otherwise start alike and end with correlated connectivity. Give every shape its own seed.
    Subdivide when the input has fewer than ~10 vertices per cluster: a cluster's vertex is the
    centroid of its points, and clusters of one or two template vertices put the new vertex on a
    template vertex (SCAPE, 12.5k -> 5k without subdivision: 20-25 % of one pose's remeshed vertices
    coincide with another's in template coordinates; with ``subdivide=2``, 0.5-1 %).
    The new vertices are moved onto the input surface and the faces oriented like it
    (``create_mesh(moveclus=True, flipnorm=True)``), then :func:`clean_remesh` is applied.

    Args:
        verts: [V, 3] vertices.
        faces: [F, 3] triangles.
        n_verts: number of clusters, i.e. output vertices before cleaning.
        subdivide: linear subdivisions before clustering; needed when V is not well above n_verts.
        seed: seed of the input shuffle.
        maxiter: clustering iterations.

    Returns:
        (verts [V', 3] float64, faces [F', 3] int64).

    Raises:
        ImportError: without pyacvd (``pip install pyacvd``, which brings pyvista and vtk).
    """
    try:
        import pyacvd
        import pyvista as pv
    except ImportError as err:
        raise ImportError(f"remesh_acvd needs pyacvd ({err}): pip install pyacvd") from None
    v, f = check_mesh(verts, faces)
    rng = np.random.default_rng(seed)
    perm = rng.permutation(v.shape[0])  # new vertex i is old vertex perm[i]
    inv = np.empty_like(perm)
    inv[perm] = np.arange(perm.size)
    f = inv[f][rng.permutation(f.shape[0])]
    f = np.roll(f, int(rng.integers(3)), axis=1)  # a cyclic shift keeps each face's orientation
    with warnings.catch_warnings():
        # pyacvd 0.4 reads a private pyvista array that pyvista 0.49 deprecates; not the caller's concern
        warnings.filterwarnings("ignore", message=".*_connectivity_array.*")
        clus = pyacvd.Clustering(pv.PolyData.from_regular_faces(v[perm], f))
        if subdivide:
            clus.subdivide(subdivide)
        clus.cluster(int(n_verts), maxiter=maxiter)
        out = clus.create_mesh(moveclus=True, flipnorm=True, clean=True)
    return clean_remesh(np.asarray(out.points, dtype=np.float64),
                        np.asarray(out.regular_faces, dtype=np.int64))
