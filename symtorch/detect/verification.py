"""Verification of candidate symmetries: geodesic distortion, orientation, descriptor change.

A candidate map is accepted as a symmetry only when it is a near-isometry (:func:`isometry_score`,
or :func:`involution_distortion` for an involution, which needs no heat solve per map), reverses or
keeps the orientation consistently (:func:`orientation_vote`), and keeps the isometry-invariant
descriptors (:func:`descriptor_gap`). Distortions are in units of the KLC radius of the unit-area
shape; the confidence of a map is ``exp(-distortion^2)``.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

from .._checks import to_numpy
from ..geodesics import GeodesicSolver
from ..orientation import vertex_normals
from ..units import EPS_KLC

__all__ = ["Distortion", "isometry_score", "involution_distortion", "local_errors", "involution_error",
           "descriptor_gap", "standardized_descriptors", "HeatLevels", "vertex_normals", "orientation_vote"]


class Distortion(NamedTuple):
    """Geodesic distortion of a map among sample points.

    Attributes:
        score: confidence ``exp(-distortion^2)`` in [0, 1].
        distortion: mean over sample pairs, in EPS_KLC units.
        worst: the largest per-sample mean (over the samples not skipped): a map good on most
            of the shape but wrong on one part of it has a small ``distortion`` and a large
            ``worst``.
    """

    score: float
    distortion: float
    worst: float


def _distortion(err: np.ndarray, skip: Tensor | None = None) -> Distortion:
    """``err`` [n, n]: per-pair disagreement in EPS_KLC units; ``skip`` [n] bool: samples left out
    of ``worst`` (:func:`local_errors`)."""
    distortion = float(err.mean())
    rows = err.mean(1)
    keep = None if skip is None else ~np.asarray(skip)
    if keep is not None and keep.any():  # every sample skipped: none is left out
        rows = rows[keep]
    return Distortion(math.exp(-distortion ** 2), distortion, float(rows.max()))


def isometry_score(solver: GeodesicSolver, p2p: Tensor, samples: Tensor,
                   source_dist: Tensor | None = None, skip: Tensor | None = None) -> Distortion:
    """Confidence that ``p2p`` is an isometry, from geodesic distortion among sample points.

    distortion = mean over sample pairs of ``|d(g(s_i), g(s_j)) - d(s_i, s_j)|`` on the unit-area
    shape, in EPS_KLC units. True symmetries of the benchmark meshes measure about 0.1; a wrong map
    more than 1.

    Args:
        solver: heat-method solver of the unit-area shape.
        p2p: [V] the map; samples: [n] vertex ids.
        source_dist: [n, n] ``solver.pairwise(samples)``, when several maps are scored on one
            sample set (each call then solves only from the images).
        skip: [n] bool, samples ``worst`` leaves out (:func:`local_errors`).
    """
    D0 = solver.pairwise(samples) if source_dist is None else source_dist
    D1 = solver.pairwise(p2p[samples])
    return _distortion(np.asarray((D1 - D0).abs()) / EPS_KLC, skip)


def involution_distortion(fields: Tensor, samples: Tensor, p2p: Tensor,
                          skip: Tensor | None = None) -> Distortion:
    """:func:`isometry_score` for a map that should be an isometric involution, with no solve per map.

    For an isometry ``g`` with ``g∘g = id``, ``d(s_i, g(s_j)) = d(g(s_i), g(g(s_j))) = d(g(s_i), s_j)``:
    the matrix ``X[i, j] = d(s_i, g(s_j))``, read off the samples' own distance fields, is symmetric.
    distortion = mean over sample pairs of ``|X[i, j] - X[j, i]|`` (0 for a reflection; a partial
    swap, a collapse or a non-involutive map breaks it).

    Args:
        fields: [n, V] geodesic distances from ``samples`` (unit-area shape); samples: [n] vertex ids;
        p2p: [V] the map; skip: as in :func:`isometry_score`.
    """
    _, err = _involution_disagreement(fields, samples, p2p)
    return _distortion(to_numpy(err), skip)


def _involution_disagreement(fields: Tensor, samples: Tensor, p2p: Tensor) -> tuple[Tensor, Tensor]:
    """``X [n, n] = d(s_i, g(s_j))`` read off the samples' fields, and ``|X - X.T| / EPS_KLC``."""
    X = fields[:, p2p[samples]]
    return X, (X - X.mT).abs() / EPS_KLC


def local_errors(fields: Tensor, samples: Tensor, p2p: Tensor, desc: Tensor, max_worst: float,
                 limit: int, max_z: float) -> Tensor:
    """The samples where the dense map alone is wrong, not the shape's symmetry: [n] bool.

    A sample ``s_i`` whose row of ``involution_distortion`` exceeds ``max_worst`` is a *local
    error* when another image fits it: some vertex ``y`` whose distances to the samples match
    ``d(s_i, g(s_j))`` (``g`` is an involution: ``d(y, s_j) = d(s_i, g(s_j))`` for the true image
    ``y = g(s_i)``) to within ``max_worst`` on average, and whose descriptors match the sample's
    (standardised log-descriptors, :func:`standardized_descriptors`, computed only where some row
    exceeds ``max_worst``; mean column gap below ``max_z``). Where the shape itself is asymmetric
    (a bump on one side), the point that fits the distances is a smooth patch whose descriptors
    differ. On a point cloud, where two sheets touch
    (the soles of two feet), a few points of a right map are pulled across and fixed there.
    At most ``limit`` of the worst samples are examined: a wrong part of the map (a limb mirrored
    onto itself) covers more of them.

    Args:
        fields: [n, V] geodesic distances from ``samples`` (unit-area shape); samples: [n];
        p2p: [V] the map; desc: [V, D] positive descriptors (as for :func:`descriptor_gap`).
    """
    X, err = _involution_disagreement(fields, samples, p2p)
    rows = err.mean(1)
    out = torch.zeros(len(samples), dtype=torch.bool)
    order = torch.argsort(rows, descending=True)[:limit]
    flagged = order[rows[order] > max_worst].tolist()
    z = standardized_descriptors(desc) if flagged else None
    for i in flagged:
        others = torch.arange(len(samples)) != i
        fit = (fields[others] - X[i, others, None]).abs().mean(0) / EPS_KLC  # [V]
        y = int(fit.argmin())
        out[i] = bool(fit[y] < max_worst) and float((z[samples[i]] - z[y]).abs().mean()) < max_z
    return out


def standardized_descriptors(desc: Tensor, like: Tensor | None = None) -> Tensor:
    """[V, D] log-descriptors standardised per column (units of each column's spread), by the
    columns' mean and spread over ``like`` [V', D] (default ``desc`` itself)."""
    L = torch.log(desc.clamp_min(1e-12))
    R = L if like is None else torch.log(like.clamp_min(1e-12))
    return (L - R.mean(0)) / R.std(0).clamp_min(1e-12)


def involution_error(fields: Tensor, samples: Tensor, p2p: Tensor) -> float:
    """How far a map applied twice lands from where it started: mean ``d(s, g(g(s)))`` over the samples.

    0 for an involution; the dense map of a reflection is one up to the vertex-level jitter of a
    nearest-neighbour search, a map that slides along a near-symmetry drifts.

    Args:
        fields: [n, V] geodesic distances from ``samples`` (unit-area shape); samples: [n] vertex ids;
        p2p: [V] the map.

    Returns:
        The mean, in EPS_KLC units.
    """
    back = p2p[p2p[samples]]  # [n]
    d = fields[torch.arange(len(samples)), back]
    return float(d.mean()) / EPS_KLC


def descriptor_gap(desc: Tensor, p2p: Tensor, mass: Tensor) -> float:
    """How much a vertex map changes the isometry-invariant descriptors.

    An intrinsic symmetry keeps them (exactly, for an isometry); a map that only keeps geodesic
    distances on the whole may not: a lopsided shape's near-reflection sends one bump onto a smooth
    patch. gap = mass-weighted mean over vertices and columns of ``|z(x) - z(g(x))|``, with ``z``
    the log-descriptors standardised per column (units of each column's spread over the shape).

    Args:
        desc: [V, D] positive descriptors (``descriptors``); p2p: [V]; mass: [V].
    """
    Z = standardized_descriptors(desc)
    per_vertex = (Z - Z[p2p]).abs().mean(1)
    return float((mass * per_vertex).sum() / mass.sum())


class HeatLevels:
    """Which share of the area a vertex map moves to a different heat level: the test that a
    rotation by an arbitrary angle is an isometry (``group_path.continuous_test``) and that a
    verified map is one (``group_path.keep_heat_levels``).

    An isometry keeps the heat kernel signature at every point. Of a vertex map, the image of ``x``
    is a vertex within about an edge of the true image, so ``h(x)`` must lie within the range ``h``
    takes on the ``rings``-ring of ``g(x)``; a vertex that falls outside that range by more than
    ``tol`` of the function's range over the shape has changed level. A surface of revolution
    keeps the level of (almost) every vertex under any rotation; a prism or an antiprism whose
    rotation by such an angle passes as near-isometric (its corners carry little area) moves its
    corners onto the smooth rim between them, and at the finer heat scales they differ.
    Functions whose range is under ``min_contrast`` of their mean (a sphere's: a few per cent, all
    of it triangulation) carry no shape and are skipped.

    Args:
        h: [V, T] heat kernel signatures (``descriptors.hks_at_scales``); faces: [F, 3].
    """

    def __init__(self, h: Tensor, faces, rings: int = 2, tol: float = 0.1, min_contrast: float = 0.1):
        import scipy.sparse as sp

        from ..sampling import vertex_adjacency

        x = to_numpy(h).astype(np.float64)
        V = x.shape[0]
        A = (vertex_adjacency(faces, V) + sp.eye(V)).tocsr()
        reach = A
        for _ in range(rings - 1):
            reach = (reach @ A).tocsr()
        spread = x.max(0) - x.min(0)
        keep = spread >= min_contrast * np.abs(x).mean(0)
        x, spread = x[:, keep], spread[keep]
        self.h = x  # [V, T'] the functions kept
        around = x[reach.indices]  # [nnz, T'] row by row: each vertex's rings
        self.lo = np.minimum.reduceat(around, reach.indptr[:-1], axis=0)  # [V, T']
        self.hi = np.maximum.reduceat(around, reach.indptr[:-1], axis=0)
        self.margin = tol * spread  # [T']

    def changed_share(self, p2p: Tensor, mass: Tensor) -> float:
        """The largest share, over the functions, of the area whose level the map [V] changes."""
        if self.h.shape[1] == 0:
            return 0.0
        g = to_numpy(p2p)
        out = np.maximum(self.lo[g] - self.h, self.h - self.hi[g]) > self.margin  # [V, T']
        w = to_numpy(mass).astype(np.float64)
        return float((w[:, None] * out).sum(0).max() / w.sum())


def orientation_vote(p2p: Tensor, verts: Tensor, normals: Tensor, samples: Tensor, n_neighbors: int = 4,
                     max_stretch: float = 3.0, min_cos: float = 0.5) -> Tensor:
    """Orientation of a vertex map at the scale of a sample spacing, robust to vertex-level noise.

    Every sample ``s`` and two of its nearest samples ``a, b`` form a small triangle; its orientation
    about the normal at ``s`` is compared with that of the image triangle ``g(s), g(a), g(b)`` about
    the normal at ``g(s)``. Triangles several edges wide keep their orientation under the jitter of a
    nearest-neighbour map, where the mesh's own faces do not. Images that collapse or stretch more
    than ``max_stretch`` times do not vote, nor do triangles whose corner normals disagree (cosine
    below ``min_cos``): on a posed shape, Euclidean neighbours may lie on two touching parts (an arm
    against the torso), and such a triangle has no orientation.

    Args:
        p2p: [..., V] vertex maps; verts: [V, 3]; normals: [V, 3]; samples: [S] vertex ids.

    Returns:
        [...] vote in [-1, 1]: +1 keeps the orientation, -1 reverses it (a reflection).
    """
    x = verts[samples]
    nn = torch.cdist(x, x).topk(n_neighbors + 1, largest=False).indices[:, 1:]  # [S, n]
    ia, ib = torch.triu_indices(n_neighbors, n_neighbors, 1)
    a, b = samples[nn[:, ia]], samples[nn[:, ib]]  # [S, P]
    s = samples[:, None].expand_as(a)

    def det(p, q, r):
        e1, e2 = verts[q] - verts[p], verts[r] - verts[p]
        return (torch.linalg.cross(e1, e2) * normals[p]).sum(-1), torch.maximum(e1.norm(dim=-1), e2.norm(dim=-1))

    d0, l0 = det(s, a, b)
    g = p2p[..., s], p2p[..., a], p2p[..., b]
    d1, l1 = det(*g)

    def flat(p, q, r):  # all three normals agree: the triangle lies on one sheet of the surface
        return ((normals[p] * normals[q]).sum(-1) > min_cos) & ((normals[p] * normals[r]).sum(-1) > min_cos)

    ok = (d0.abs() > 0.1 * l0.square()) & (d1.abs() > 0.05 * l1.square()) & (l1 < max_stretch * l0) \
        & flat(s, a, b) & flat(*g)
    vote = torch.sign(d0) * torch.sign(d1) * ok
    return vote.sum((-2, -1)) / ok.sum((-2, -1)).clamp_min(1)
