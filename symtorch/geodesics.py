"""Geodesic distances on triangle meshes and point clouds: the heat method, with a graph (Dijkstra)
fallback.

The heat method (Crane, Weischedel & Wardetzky, "The Heat Method for Distance Computation", CACM 2017)
comes from ``potpourri3d``; with ``use_robust=True`` it runs on the intrinsic Delaunay / tufted cover of
the mesh (Sharp & Crane 2020), so non-manifold and badly shaped meshes work. The system is factored
once per mesh in :class:`GeodesicSolver`; each source then costs one back-substitution (about 1.5 ms at
5k vertices, 3 ms at 12.5k, 16 ms at 52k on one CPU core).

Distances are in the units of the vertices passed in: the solver does not rescale to unit area.
Multiply by ``Spectrum.scale`` to express them on the unit-area shape. Outputs are not differentiable
with respect to the vertices (the solve runs in numpy); :func:`disk_indicators` is differentiable with
respect to the distances it is given.

``backend="batched"`` solves many sources at once on the mesh's own cotan operators
(:mod:`symtorch.heat_method`: 4-5x faster a source) wherever the mesh suits it (one piece, nearly
every edge Delaunay) and potpourri3d elsewhere; the detector uses it (``DetectConfig.geodesics``).

A point cloud (``faces=None``) gets ``potpourri3d.PointCloudHeatSolver`` instead, the heat method on
the point cloud's own Laplacian (Sharp & Crane 2020), and the graph fallback runs on the
k-nearest-neighbour graph (``point_cloud.knn_graph``). Each of its sources costs more (about 30 ms at
12.5k points, against 3 ms on the mesh of those vertices).

The graph fallback (:func:`graph_distances`) runs Dijkstra on edge lengths. It over-estimates geodesic
distance (paths follow edges; typically by 5-15 % on irregular triangulations) but never fails, and
gives ``inf`` between connected components, where the heat method gives meaningless finite values.
"""
from __future__ import annotations

import functools
import logging
import warnings
from typing import Literal

import numpy as np
import scipy.sparse as sp
import torch
from scipy.sparse.csgraph import dijkstra
from torch import Tensor

from ._checks import check_index_range, check_mesh, check_verts, face_areas, to_numpy
from .heat_method import BatchedHeatMethod

log = logging.getLogger(__name__)

__all__ = ["GeodesicSolver", "geodesic_distances", "graph_distances", "disk_indicators",
           "edge_graph"]


def _out_format(verts) -> dict:
    """dtype/device of outputs: those of ``verts`` when it is a floating tensor, else float64 CPU."""
    if isinstance(verts, Tensor) and verts.is_floating_point():
        return dict(dtype=verts.dtype, device=verts.device)
    return dict(dtype=torch.float64, device=torch.device("cpu"))


def _check_sources(sources, n_verts: int, name: str = "sources") -> np.ndarray:
    """int / sequence / array / tensor of vertex ids -> 1-D int64 numpy array, validated."""
    s = to_numpy(sources)
    if s.ndim == 0:
        s = s.reshape(1)
    if s.ndim != 1:
        raise ValueError(f"{name} must be a vertex id or a 1-D list of ids, got shape {list(s.shape)}")
    if s.size == 0:
        raise ValueError(f"{name} is empty")
    if not np.issubdtype(s.dtype, np.integer):
        raise ValueError(f"{name} must hold integer vertex ids, got {s.dtype}")
    return check_index_range(s.astype(np.int64, copy=False), n_verts, name)


def edge_graph(verts, faces) -> sp.csr_matrix:
    """[V, V] symmetric sparse matrix of mesh edge lengths (each undirected edge once per direction)."""
    v, f = check_mesh(verts, faces)
    V = v.shape[0]
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)  # [3F, 2]
    key = np.unique(e[:, 0].astype(np.int64) * V + e[:, 1])  # each edge once (5x faster than rows)
    e = np.stack([key // V, key % V], axis=1)
    e = e[e[:, 0] != e[:, 1]]  # degenerate faces may repeat a vertex
    w = np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)
    # Zero-length edges (duplicate vertices) would be dropped as "no edge" by csgraph: keep them tiny.
    w = np.maximum(w, 1e-12 * max(float(w.max(initial=0.0)), 1e-300))
    G = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([e[:, 0], e[:, 1]]),
                                                np.concatenate([e[:, 1], e[:, 0]]))), shape=(V, V))
    return G.tocsr()


def voronoi_cells(verts, faces, sites) -> Tensor:
    """Graph-geodesic Voronoi cells: for each vertex, the position in ``sites`` of its nearest site.

    One multi-source Dijkstra along the mesh edges (intrinsic: parts that touch in space but not
    on the surface stay apart).

    Args:
        verts: [V, 3]; faces: [F, 3].
        sites: [S] vertex ids.

    Returns:
        [V] long in ``0..S-1`` (-1 for a vertex no site reaches: another connected component).
    """
    n = len(verts)
    s = _check_sources(sites, n, "sites")
    _, _, src = dijkstra(edge_graph(verts, faces), directed=False, indices=s, min_only=True,
                         return_predecessors=True)
    pos = np.full(n, -1, dtype=np.int64)
    pos[s] = np.arange(s.size)  # a repeated site keeps its last position
    return torch.as_tensor(np.where(src >= 0, pos[np.maximum(src, 0)], -1))


def graph_distances(verts, faces, sources) -> Tensor:
    """Shortest-path distances along mesh edges (Dijkstra), the fallback to the heat method.

    Args:
        verts: [V, 3] vertex positions (numpy or torch).
        faces: [F, 3] triangles, or None for a point cloud (its k-nearest-neighbour graph).
        sources: [S] vertex ids (or one id).

    Returns:
        [S, V] distances; ``inf`` for vertices in another connected component. Float64 unless
        ``verts`` is a floating tensor, whose dtype and device are then followed.
    """
    if faces is None:
        from .point_cloud import knn_graph

        G = knn_graph(check_verts(verts))
    else:
        G = edge_graph(verts, faces)
    s = _check_sources(sources, G.shape[0])
    D = dijkstra(G, directed=False, indices=s)  # [S, V]
    return torch.as_tensor(np.atleast_2d(D), **_out_format(verts))


class GeodesicSolver:
    """Prefactored heat-method geodesic distances on one mesh or point cloud.

    Wraps ``potpourri3d.MeshHeatMethodDistanceSolver(verts, faces, t_coef, use_robust)``, or for a
    point cloud (``faces=None``) ``potpourri3d.PointCloudHeatSolver(verts, t_coef)``. Where the heat
    method cannot be built, or returns non-finite values for a source, the graph (Dijkstra) distance
    is used instead, with a warning (see the module docstring for its bias).

    Args:
        verts: [V, 3] vertex positions (numpy or torch). Distances are in these units.
        faces: [F, 3] triangles, or None for a point cloud.
        t_coef: heat-method time step, as a multiple of the squared mean edge length (1 = paper).
        use_robust: run on the intrinsic Delaunay tufted cover (robust to bad meshes; meshes only,
            the point-cloud solver always does).
        backend: ``"potpourri3d"``, or ``"batched"``: :class:`~symtorch.heat_method.BatchedHeatMethod`
            (the mesh's own cotan operators, a block of sources per solve, 3-4x faster a source;
            ``use_robust`` does not apply) for ``distances_from`` on a connected, nearly Delaunay
            mesh, potpourri3d where the mesh does not suit it and for point clouds and ``distance``. ``self.backend``
            says which one ``distances_from`` uses.

    Note:
        Heat-method distances are approximate: a few percent of error, largest near the source
        (they are smoothed over about one edge length) and at cut-locus ridges. They are 0 at the
        source by construction.

    Example:
        >>> solver = GeodesicSolver(verts, faces)
        >>> D = solver.distances_from([0, 10, 20])   # [3, V]
        >>> d = solver.distance([0, 10, 20])         # [V], to the nearest of the three
    """

    def __init__(self, verts, faces=None, t_coef: float = 1.0, use_robust: bool = True,
                 backend: Literal["potpourri3d", "batched"] = "potpourri3d"):
        if backend not in ("potpourri3d", "batched"):
            raise ValueError(f"backend must be 'potpourri3d' or 'batched', got {backend!r}")
        if faces is None:
            self.verts, self.faces = check_verts(verts), None
        else:
            self.verts, self.faces = check_mesh(verts, faces)
        self.n_verts = self.verts.shape[0]
        self._out = _out_format(verts)
        self._graph: sp.csr_matrix | None = None
        # fields already solved, by source: a detection asks for some sources again (the images
        # of the samples under several candidate maps often coincide); at most 64 MB of them
        self._fields: dict[int, np.ndarray] = {}
        self._max_fields = max(1, (64 << 20) // (8 * max(self.n_verts, 1)))
        self._t_coef, self._use_robust = t_coef, use_robust
        self._heat = None
        self._heat_failed = False
        # many sources per solve on the mesh's own cotan operators (meshes only; None where the
        # mesh does not suit it, and potpourri3d is used)
        self._batched = None if backend != "batched" or self.faces is None else \
            BatchedHeatMethod.build(self.verts, self.faces, t_coef)
        self.backend = "batched" if self._batched is not None else "potpourri3d"
        if self._batched is None:
            self._pp3d()

    def _pp3d(self):
        """potpourri3d's solver, built on first use (None, after one warning, where it cannot be)."""
        if self._heat is None and not self._heat_failed:
            try:
                import potpourri3d as pp3d

                self._heat = pp3d.PointCloudHeatSolver(self.verts, t_coef=self._t_coef) \
                    if self.faces is None else pp3d.MeshHeatMethodDistanceSolver(
                        self.verts, self.faces, t_coef=self._t_coef, use_robust=self._use_robust)
            except (ImportError, RuntimeError, ValueError) as err:
                self._heat_failed = True
                warnings.warn(f"heat-method solver unavailable ({err}); using graph (Dijkstra) "
                              f"distances, which over-estimate geodesics", stacklevel=3)
        return self._heat

    @property
    def uses_heat(self) -> bool:
        """Whether the heat method is available (False: every distance comes from Dijkstra)."""
        return self._batched is not None or self._heat is not None

    @property
    def is_point_cloud(self) -> bool:
        """Whether the solver works on a point cloud (no faces)."""
        return self.faces is None

    @functools.cached_property
    def area(self) -> float:
        """Total surface area of the mesh, in the units of ``verts`` squared (of a point cloud: the
        sum of its Laplacian's lumped mass, ``spectrum.laplacian_matrices``); computed once."""
        if self.faces is None:
            from .spectrum import laplacian_matrices

            return float(laplacian_matrices(self.verts, None)[1].sum())
        return float(face_areas(self.verts, self.faces).sum())

    def _graph_rows(self, sources: np.ndarray) -> np.ndarray:
        if self._graph is None:
            from .point_cloud import knn_graph

            self._graph = knn_graph(self.verts) if self.faces is None \
                else edge_graph(self.verts, self.faces)
        return np.atleast_2d(dijkstra(self._graph, directed=False, indices=sources))

    def _tensor(self, x: np.ndarray) -> Tensor:
        return torch.as_tensor(x, **self._out)

    def distance(self, sources) -> Tensor:
        """Distance from each vertex to the nearest of ``sources``.

        Args:
            sources: one vertex id or [S] ids.

        Returns:
            [V] distances (one multi-source heat solve). With several sources the heat method only
            fixes the additive constant on average, so the field is clamped at 0 and set to exactly
            0 at the sources; it then agrees with the minimum of the single-source fields to within
            about one edge length.
        """
        s = _check_sources(sources, self.n_verts)
        d = None
        heat = self._pp3d()
        if heat is not None:
            d = (heat.compute_distance(int(s[0])) if s.size == 1
                 else heat.compute_distance_multisource(s.tolist()))
            d = np.asarray(d, dtype=np.float64)
            if s.size > 1:
                # The multi-source heat solve fixes the additive constant on average over the
                # sources, so single sources may read slightly negative (about one edge length).
                d = np.maximum(d, 0.0)
                d[s] = 0.0
            if not np.isfinite(d).all():
                warnings.warn("heat method returned non-finite distances; using Dijkstra",
                              stacklevel=2)
                d = None
        if d is None:
            d = self._graph_rows(s).min(axis=0)
        return self._tensor(d)

    def distances_from(self, sources) -> Tensor:
        """Distances from each source separately: one heat solve per source.

        Args:
            sources: [S] vertex ids (repeats allowed; each is solved once, and a source this solver
                has solved before, up to 64 MB of fields, is read back instead).

        Returns:
            [S, V], row i the distance field of ``sources[i]``.
        """
        s = _check_sources(sources, self.n_verts)
        uniq, inv = np.unique(s, return_inverse=True)
        D = np.empty((uniq.size, self.n_verts), dtype=np.float64)
        known = np.asarray([int(src) in self._fields for src in uniq], dtype=bool)
        for i in np.flatnonzero(known):
            D[i] = self._fields[int(uniq[i])]
        bad = np.zeros(uniq.size, dtype=bool)
        todo = np.flatnonzero(~known)
        if self._batched is not None and todo.size:
            D[todo] = self._batched.distances_from(uniq[todo])
            bad[todo] = ~np.isfinite(D[todo]).all(axis=1)
            if bad.any():
                warnings.warn(f"heat method returned non-finite distances for {int(bad.sum())} "
                              f"source(s); using Dijkstra for those", stacklevel=2)
        elif self._heat is not None:
            for i in todo:
                D[i] = self._heat.compute_distance(int(uniq[i]))
            bad[todo] = ~np.isfinite(D[todo]).all(axis=1)
            if bad.any():
                warnings.warn(f"heat method returned non-finite distances for {int(bad.sum())} "
                              f"source(s); using Dijkstra for those", stacklevel=2)
        else:
            bad[todo] = True
        if bad.any():
            D[bad] = self._graph_rows(uniq[bad])
        for i in todo[: max(self._max_fields - len(self._fields), 0)]:
            self._fields[int(uniq[i])] = D[i].copy()
        return self._tensor(D[inv])

    def pairwise(self, points) -> Tensor:
        """Symmetric matrix of geodesic distances between ``points``.

        The heat method is not exactly symmetric (``d(a, b) != d(b, a)`` by a few percent); the
        result is the average of both directions, with an exact zero diagonal.

        Args:
            points: [N] vertex ids.

        Returns:
            [N, N] symmetric distances.
        """
        p = _check_sources(points, self.n_verts, "points")
        D = self.distances_from(p)[:, torch.as_tensor(p, device=self._out["device"])]  # [N, N]
        D = 0.5 * (D + D.mT)
        D.fill_diagonal_(0.0)
        return D

    def __repr__(self) -> str:
        faces = "point cloud" if self.faces is None else f"F={self.faces.shape[0]}"
        return (f"{type(self).__name__}(V={self.n_verts}, {faces}, "
                f"method={'heat' if self.uses_heat else 'graph'})")


def geodesic_distances(verts, faces, sources, method: Literal["heat", "graph"] = "heat") -> Tensor:
    """One-off geodesic distances from each source (builds a :class:`GeodesicSolver` and drops it).

    Args:
        verts: [V, 3] vertex positions (numpy or torch).
        faces: [F, 3] triangles, or None for a point cloud.
        sources: [S] vertex ids (or one id).
        method: ``"heat"`` (heat method, Dijkstra where it fails) or ``"graph"`` (Dijkstra only).

    Returns:
        [S, V] distances, float64 unless ``verts`` is a floating tensor.
    """
    if method == "graph":
        return graph_distances(verts, faces, sources)
    if method != "heat":
        raise ValueError(f"method must be 'heat' or 'graph', got {method!r}")
    return GeodesicSolver(verts, faces).distances_from(sources)


def disk_indicators(dist: Tensor | GeodesicSolver, radius: float, sources=None,
                    profile: Literal["gaussian", "smoothstep"] = "gaussian") -> Tensor:
    """Smooth indicators of geodesic disks, one column per centre (ALGORITHM §3 constraints).

    Profiles, with ``x = d / radius``:

    - ``"gaussian"``: ``exp(-x^2)``; 1 at the centre, ``1/e`` at ``d = radius``, smooth everywhere,
      never exactly 0 (every vertex carries some weight).
    - ``"smoothstep"``: ``1 - (3 s^2 - 2 s^3)`` with ``s = clamp(x, 0, 1)``; 1 at the centre, 0.5 at
      ``d = radius / 2``, exactly 0 for ``d >= radius`` (compact support, C1).

    Args:
        dist: [S, V] distances from S centres (e.g. ``solver.distances_from(centres)``), or a
            :class:`GeodesicSolver`, in which case ``sources`` must be given.
        radius: disk radius, in the units of ``dist`` (> 0).
        sources: [S] centre vertex ids; only with a solver.
        profile: ``"gaussian"`` or ``"smoothstep"``.

    Returns:
        [V, S] indicator values in [0, 1] (transposed, so columns are functions on the mesh).
        Differentiable with respect to ``dist`` and ``radius`` when they are tensors.
    """
    if isinstance(dist, GeodesicSolver):
        if sources is None:
            raise ValueError("sources is required when dist is a GeodesicSolver")
        dist = dist.distances_from(sources)
    elif sources is not None:
        raise ValueError("sources is only used with a GeodesicSolver; pass dist as [S, V]")
    if not isinstance(dist, Tensor):
        dist = torch.as_tensor(to_numpy(dist, np.float64))
    if dist.ndim == 1:
        dist = dist[None]
    if dist.ndim != 2:
        raise ValueError(f"dist must be [S, V], got {list(dist.shape)}")
    if not float(radius) > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    x = dist.mT / radius  # [V, S]
    if profile == "gaussian":
        return torch.exp(-x.square())
    if profile == "smoothstep":
        s = x.clamp(0.0, 1.0)
        return 1.0 - s.square() * (3.0 - 2.0 * s)
    raise ValueError(f"profile must be 'gaussian' or 'smoothstep', got {profile!r}")
