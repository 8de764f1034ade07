"""Symmetry detection: reflections (ALGORITHM §4) and whole groups (§5), as block-orthogonal matrices."""
from __future__ import annotations

import itertools
import logging
import math
import time

import numpy as np
import torch
from torch import Tensor

from ._checks import check_mesh, check_verts
from .descriptors import descriptors, hks
from .geodesics import GeodesicSolver
from .maps import nearest_neighbors
from .procrustes import block_procrustes
from .refine import zoomout_symmetry
from .result import Symmetry, SymmetryResult
from .sampling import farthest_point_sampling, knn_adjacency, local_maxima, vertex_adjacency
from .spectrum import Spectrum, band_boundary, eigen_bands, laplacian_spectrum

log = logging.getLogger(__name__)

EPS_KLC = 1.0 / math.sqrt(20 * math.pi)  # sqrt(area / (20 pi)) on a unit-area shape


class _Timer:
    def __init__(self):
        self.t = time.perf_counter()
        self.timings: dict[str, float] = {}

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.timings[name] = self.timings.get(name, 0.0) + now - self.t
        self.t = now


def embedding_residual(C: Tensor, evecs_src: Tensor, evecs_dst: Tensor) -> Tensor:
    """Mean squared distance from each mapped point ``evecs_src[i] @ C`` to its nearest ``evecs_dst``.

    Args:
        C: [B, k, k] candidate matrices.
        evecs_src: [S, k] rows of the sample vertices.
        evecs_dst: [T, k] rows of the target vertices.

    Returns:
        [B] residual relative to the mean squared norm of the rows (0 for an exact symmetry).
    """
    Q = evecs_src @ C  # [B, S, k]
    d = torch.cdist(Q, evecs_dst.expand(C.shape[0], -1, -1))  # [B, S, T]
    res = d.amin(-1).square().mean(-1)
    return res / evecs_src.square().sum(-1).mean()


def symmetric_pairs(points: np.ndarray, desc: np.ndarray, dist: np.ndarray, n_partners: int = 3,
                    delta: float = 0.8) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Candidate sets of two symmetric pairs for an involution (ALGORITHM §4 step 2).

    A pair ``{p, q}`` (``p == q``: a fixed point) is allowed when ``q`` is among the ``n_partners``
    descriptor-nearest points of ``p``. Two disjoint allowed pairs form a candidate when the geodesic
    distances they imply agree (``d(p1,p2) ~ d(q1,q2)`` and ``d(p1,q2) ~ d(q1,p2)``, ratio >= delta),
    and they are not both fixed points (that is the identity).

    Args:
        points: [N] vertex ids (indices into ``desc``/``dist`` rows are 0..N-1).
        desc: [N, D] descriptors of the points.
        dist: [N, N] geodesic distances among the points.

    Returns:
        list of ((i1, j1), (i2, j2)) in point indices.
    """
    N = len(points)
    dd = np.linalg.norm(desc[:, None] - desc[None], axis=-1)
    allowed = set()
    for i in range(N):
        for j in np.argsort(dd[i])[: n_partners + 1]:
            allowed.add((min(i, int(j)), max(i, int(j))))
    pairs = sorted(allowed)

    def ratio(a, b):
        lo, hi = min(a, b), max(a, b)
        return 1.0 if hi <= 1e-12 else lo / hi

    out = []
    for (a, b), (c, e) in itertools.combinations(pairs, 2):
        if len({a, b} & {c, e}) > 0:
            continue
        if a == b and c == e:
            continue
        for (p1, q1), (p2, q2) in (((a, b), (c, e)), ((a, b), (e, c))):
            if c == e and (p2, q2) != (c, e):
                continue  # fixed point: one orientation only
            if ratio(dist[p1, p2], dist[q1, q2]) >= delta and ratio(dist[p1, q2], dist[q1, p2]) >= delta:
                out.append(((p1, q1), (p2, q2)))
    return out


def _shape_inputs(shape, faces, k, spectrum):
    if isinstance(shape, Spectrum):
        raise ValueError("pass verts and faces with spectrum=...; detection needs the geometry")
    if hasattr(shape, "verts"):  # symtorch.io.Mesh
        shape, faces = shape.verts, shape.faces
    if faces is None:
        raise ValueError("symmetry detection needs a triangle mesh; got a point cloud (faces=None)")
    verts, faces = check_mesh(shape, faces)
    return verts, faces


def detect_symmetries(shape, faces=None, *, k: int = 6, k_refine: int = 60,
                      spectrum: Spectrum | None = None, mode: str = "auto",
                      n_samples: int = 2000, block_refine: bool = False, n_extrema: int = 12, nms_radius: float = 2.0, min_score: float = 0.5,
                      n_refine: int = 8,
                      generator: torch.Generator | None = None) -> SymmetryResult:
    """Find the global intrinsic symmetries of a triangle mesh.

    Args:
        shape: [V, 3] vertices (numpy or torch), or a ``symtorch.io.Mesh``.
        faces: [F, 3] triangles.
        k: target size of the coarse basis the candidates are solved in (snapped to a band end).
        k_refine: target size of the refined basis (snapped to a band end); the matrices returned
            live in this basis.
        spectrum: a precomputed ``laplacian_spectrum(verts, faces, k >= k_refine + margin)``.
        mode: 'reflection' (ALGORITHM §4), 'group' (§5, ``symtorch.group_detect``) or 'auto'.
            'auto' runs the group path when the low spectrum has repeated eigenvalues at more than one
            scale (``group_detect.has_multiplicities``: rotations make 2-dimensional eigenspaces all
            the way up), and keeps its result when it is a continuous symmetry or a verified group of
            order > 2; otherwise it runs the reflection path and keeps the larger verified group of
            the two (the reflection path's on a tie). Shapes with a simple spectrum (a single mirror,
            or none) go straight to the reflection path. The group path uses a coarse basis of
            ``max(k, 20)`` and refines every element to ``min(k_refine, 40)`` (cost: one refinement
            per element). Either way ``result.group`` holds the group report
            (``groups.GroupInfo.to_dict()``) and each ``kind`` follows its order and orientation.
        n_samples: vertices the refinement evaluates the map on.
        n_extrema: most heat-kernel extrema used as candidate points.
        min_score: a candidate whose confidence is below this is not reported.

    Returns:
        SymmetryResult, identity first, then best first.

    Raises:
        ValueError: for a point cloud, or bad mesh input.
    """
    timer = _Timer()
    verts, faces = _shape_inputs(shape, faces, k, spectrum)
    if mode not in ("auto", "reflection", "group"):
        raise ValueError(f"mode must be 'auto', 'reflection' or 'group', got {mode!r}")
    if spectrum is None:
        spectrum = laplacian_spectrum(verts, faces, k=int(k_refine * 1.3) + 8)
    timer.lap("spectrum")
    from .group_detect import detect_group, has_multiplicities, with_group
    grouped = None
    if mode == "group" or (mode == "auto" and has_multiplicities(spectrum.evals, max(k, 20))):
        grouped = detect_group(verts, faces, spectrum, k=max(k, 20), k_refine=min(k_refine, 40),
                               timer=timer)
        if mode == "group" or grouped.continuous or grouped.group["order"] > 2:
            return grouped
    result = with_group(_detect_reflection(verts, faces, spectrum, k=k, k_refine=k_refine, n_samples=n_samples,
                              n_extrema=n_extrema, nms_radius=nms_radius, block_refine=block_refine, min_score=min_score,
                              n_refine=n_refine, timer=timer), verts, faces)
    if grouped is not None and grouped.group["order"] > result.group["order"]:
        return grouped
    return result


def _detect_reflection(verts, faces, spectrum, *, k, k_refine, n_samples, n_extrema, nms_radius, block_refine,
                       min_score, n_refine, timer):
    from .reflect import detect_reflection
    return detect_reflection(verts, faces, spectrum, k=k, k_refine=k_refine, n_samples=n_samples,
                             n_extrema=n_extrema, nms_radius=nms_radius, n_candidates=max(n_refine, 1),
                             block_refine=block_refine, min_score=min_score, timer=timer)


def isometry_score(solver: GeodesicSolver, p2p: Tensor, samples: Tensor) -> tuple[float, float]:
    """Confidence that ``p2p`` is an isometry, from geodesic distortion on sample points.

    distortion = mean over sample pairs of ``|d(g(s_i), g(s_j)) - d(s_i, s_j)|`` on the unit-area
    shape, in units of the KLC10 tolerance ``sqrt(area / (20 pi))``; score = ``exp(-distortion)``...
    squared so that the ground truth of the benchmarks (distortion ~0.12) scores ~0.98.

    Returns:
        (score in [0, 1], distortion).
    """
    s = samples.numpy()
    gs = p2p[samples].numpy()
    D0 = np.asarray(solver.distances_from(s))[:, s]
    D1 = np.asarray(solver.distances_from(gs))[:, gs]
    D0 = 0.5 * (D0 + D0.T)
    D1 = 0.5 * (D1 + D1.T)
    distortion = float(np.abs(D1 - D0).mean() / EPS_KLC)
    return math.exp(-distortion ** 2), distortion
