"""Candidate pair-sets for the group path (ALGORITHM §5.1-5.2): invariant points, pruned tuples.

A symmetry maps the set ``P`` of multi-scale heat-kernel extrema onto itself (:func:`invariant_points`).
Two points may correspond only where their descriptors and their sorted distances to all of ``P``
agree (:func:`partner_mask`). Tuples of ``m + 1`` points of ``P`` pin every band of size ``m``: a few
well-spread source tuples (:func:`source_tuples`) are paired with every ordered target tuple that
keeps their geodesic distances (:func:`candidate_tuples`), pruned level by level;
:func:`tuple_pairs` runs the three. ``symtorch.detect.group_path`` turns each (source, target) pair
into a matrix by one batched block Procrustes.
"""
from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

from ..descriptors import hks
from ..units import EPS_KLC
from ..sampling import local_maxima, vertex_adjacency

__all__ = ["invariant_points", "partner_mask", "source_tuples", "candidate_tuples", "tuple_pairs", "TuplePairs"]


def invariant_points(evals: Tensor, evecs: Tensor, faces, verts_unit: np.ndarray, *, n_max: int = 40,
                     nms_radius: float = 1.0, scales=(1.0, 0.1, 0.02), per_scale: int = 40) -> np.ndarray:
    """A symmetry-invariant point set: multi-scale HKS maxima and minima, thinned by farthest-point suppression.

    Args:
        evals: [K]; evecs: [V, K] of the unit-area shape.
        faces: [F, 3].
        verts_unit: [V, 3] unit-area vertex positions (for the suppression radius).
        n_max: most points returned.
        nms_radius: no two points closer than this many ``eps`` (Euclidean, unit area).
        scales: HKS times as fractions of ``4 ln 10 / lambda_2``.
        per_scale: maxima considered per scale (by decreasing value).

    Returns:
        [N] vertex ids, coarse scales first.
    """
    V = evecs.shape[0]
    lam = evals[evals > 1e-8 * evals.max().clamp_min(1e-12)]  # skip the constant mode(s)
    t0 = 4 * math.log(10) / float(lam[0])
    h = hks(evals, evecs, torch.tensor([t0 * s for s in scales], dtype=evals.dtype))  # [V, T]
    adj = vertex_adjacency(faces, V)
    cand: list[int] = []
    for col in range(h.shape[1]):
        for sign in (1.0, -1.0):  # maxima (tips, convex corners), then minima (concave corners)
            for v in local_maxima(sign * h[:, col].numpy(), adj, rings=2)[:per_scale]:
                if int(v) not in cand:
                    cand.append(int(v))
    x = np.asarray(verts_unit)
    keep: list[int] = []
    r = nms_radius * EPS_KLC
    for v in cand:
        if not keep or np.linalg.norm(x[keep] - x[v], axis=1).min() > r:
            keep.append(v)
        if len(keep) == n_max:
            break
    return np.asarray(keep, dtype=np.int64)


def source_tuples(dist: np.ndarray, size: int, n_sources: int, usable: np.ndarray | None = None) -> list[list[int]]:
    """Well-spread point tuples: geodesic farthest-point orders from different starting points.

    ``usable`` [n] bool marks the points preferred in a tuple (those with a descriptor partner: a
    point of P without one is either on every symmetry axis, or an extremum whose partners were
    lost, which would leave the tuple with no image at all); others fill in when too few.
    """
    n = dist.shape[0]
    ok = np.ones(n, dtype=bool) if usable is None or usable.sum() < size else usable
    out: list[list[int]] = []
    starts = [int(i) for i in np.argsort(-dist.sum(1)) if ok[i]]  # most eccentric first
    for s in starts:
        tup = [int(s)]
        while len(tup) < min(size, n):
            dmin = dist[tup].min(0)
            dmin[tup] = -1
            dmin[~ok] = -1
            if dmin.max() < 0:
                dmin = dist[tup].min(0)
                dmin[tup] = -1
            tup.append(int(dmin.argmax()))
        if sorted(tup) not in [sorted(t) for t in out]:
            out.append(tup)
        if len(out) == n_sources:
            break
    return out


def candidate_tuples(src: list[int], dist: np.ndarray, allowed: np.ndarray, delta: float = 0.9,
                     slack: float = 0.5 * EPS_KLC, max_candidates: int = 20000) -> tuple[np.ndarray, int]:
    """Ordered target tuples ``q`` for a source tuple ``p`` that keep geodesic distances (ALGORITHM §5.2).

    Enumerated level by level (all targets for ``p_1``, extended by all targets for ``p_2``, ...),
    dropping a partial tuple as soon as ``|d(p_i, p_j) - d(q_i, q_j)| > (1 - delta) max(...) + slack``
    (the ratio test with a slack for short distances) or ``allowed[p_i, q_i]`` is False.

    Args:
        src: [t] indices into the point set.
        dist: [n, n] geodesic distances between the points.
        allowed: [n, n] bool descriptor agreement.

    Returns:
        ([N, t] target tuples, number of ordered tuples before pruning).
    """
    n, t = dist.shape[0], len(src)
    total = math.perm(n, t)
    part = np.flatnonzero(allowed[src[0]])[:, None]  # [N, 1]
    for j in range(1, t):
        q = np.flatnonzero(allowed[src[j]])
        if len(part) == 0 or len(q) == 0:
            return np.zeros((0, t), dtype=np.int64), total
        dp = dist[src[:j], src[j]]  # [j]
        dq = dist[part][:, :, q]  # [N, j, nq]
        lim = (1 - delta) * np.maximum(dq, dp[None, :, None]) + slack
        ok = (np.abs(dq - dp[None, :, None]) <= lim).all(1)  # [N, nq]
        ok &= (part[:, :, None] != q[None, None, :]).all(1)  # distinct targets
        a, b = np.nonzero(ok)
        part = np.concatenate([part[a], q[b, None]], 1)
        if len(part) > max_candidates:
            warnings.warn(f"{len(part)} partial candidates; keeping {max_candidates} (continuous "
                          "symmetry or a point set with little structure)", stacklevel=2)
            part = part[:max_candidates]
    return part, total


def partner_mask(desc: Tensor, dist: np.ndarray, desc_tol: float) -> np.ndarray:
    """[n, n] bool: which points of ``P`` may be the image of which.

    Two points may correspond when their standardised multi-scale log-descriptors lie within
    ``desc_tol`` times the median distance of all pairs of points (exact mirror partners have
    identical descriptors, so the scale is the spread of all pairs), and when their sorted geodesic
    distances to all of ``P`` agree (equal for orbit partners when ``P`` is invariant) to within
    ``0.5 eps`` plus 5 % of a typical distance. Every point may be its own image.

    Args:
        desc: [n, D] positive descriptors of the points; dist: [n, n] geodesic distances among them.
    """
    n = len(dist)
    logd = torch.log(desc.clamp_min(1e-12))
    logd = logd / logd.std(0, keepdim=True).clamp_min(1e-12)
    dd = torch.cdist(logd, logd).numpy()
    off = dd[~np.eye(n, dtype=bool)]
    allowed = dd <= max(desc_tol * float(np.median(off)) if off.size else 0.0, 1e-9)
    prof = np.sort(dist, 1)
    pd = np.abs(prof[:, None, :] - prof[None, :, :])
    profile_agrees = np.median(pd, -1) <= 0.5 * EPS_KLC + 0.05 * np.median(prof[:, 1:], 1)[:, None]
    return allowed & (profile_agrees | np.eye(n, dtype=bool))


class TuplePairs(NamedTuple):
    """Candidate correspondences: row ``i`` pairs source tuple ``src[i]`` with target ``dst[i]``.

    Attributes:
        src, dst: [B, t] indices into the point set.
        n_with_partner: points with a partner other than themselves.
        n_sources: source tuples used; n_before: ordered target tuples before pruning.
    """

    src: np.ndarray
    dst: np.ndarray
    n_with_partner: int
    n_sources: int
    n_before: int


def tuple_pairs(dist: np.ndarray, allowed: np.ndarray, size: int, n_sources: int,
                delta: float) -> TuplePairs:
    """A few well-spread source tuples of ``size`` points, each paired with every ordered target
    tuple that keeps its geodesic distances (ratio ``delta``) and whose points are allowed partners.

    Source points are taken among those that have a partner other than themselves.
    """
    partner = allowed.sum(1) > 1
    srcs = source_tuples(dist, size, n_sources, partner)
    tuples_src, tuples_dst, before = [], [], 0
    for src in srcs:
        q, tot = candidate_tuples(src, dist, allowed, delta)
        before += tot
        tuples_src.append(np.repeat(np.asarray(src)[None], len(q), 0))
        tuples_dst.append(q)
    P = np.concatenate(tuples_src) if tuples_src else np.zeros((0, size), dtype=np.int64)
    Q = np.concatenate(tuples_dst) if tuples_dst else np.zeros((0, size), dtype=np.int64)
    return TuplePairs(P, Q, int(partner.sum()), len(srcs), int(before))
