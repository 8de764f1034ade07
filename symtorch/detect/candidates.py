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

from ..descriptors import hks_at_scales
from ..units import EPS_KLC
from ..sampling import local_maxima, vertex_adjacency
from .config import GroupConfig
from .verification import standardized_descriptors

__all__ = ["invariant_points", "persistent_points", "descriptor_ratios", "partner_mask", "Pinning", "source_tuples",
           "candidate_tuples", "tuple_pairs", "TuplePairs"]


def invariant_points(evals: Tensor, evecs: Tensor, faces, verts_unit: np.ndarray, *, n_max: int = 40,
                     nms_radius: float = 1.0, scales=(1.0, 0.1, 0.02), per_scale: int = 40,
                     valley: float = 1e-3, border: float = 0.25, like: float = 0.05,
                     hill: float = GroupConfig.persistence) -> np.ndarray:
    """A symmetry-invariant point set: multi-scale HKS maxima and minima, thinned by farthest-point suppression.

    The suppression merges one feature found at several scales (or at neighbouring vertices); it
    must not merge two points of one orbit, or the set stops being invariant: the top and bottom
    corners of a thin prism lie closer than ``nms_radius``, and keeping one of each pair leaves a
    set that no top/bottom mirror maps onto itself (nor can its tuples pin the eigenfunctions odd
    under that mirror). So a point near a kept one is kept where both are extrema of the same
    function (scale and sign) separated by a valley: on every path between them inside the
    suppression ball's neighbourhood the function drops by more than ``valley`` times its range
    over the shape (a topological persistence test). Orbit partners are such distinct extrema
    (the corners of a star slab 0.9 eps apart: about 1e-2); the extrema that noise makes on a flat
    region (the top of a table) are not (below 1e-4).

    Args:
        evals: [K]; evecs: [V, K] of the unit-area shape.
        faces: [F, 3].
        verts_unit: [V, 3] unit-area vertex positions (for the suppression radius).
        n_max: most points returned.
        nms_radius: no two points closer than this many ``eps`` (Euclidean, unit area), unless
            they are distinct extrema of one function (above).
        scales: HKS times as fractions of ``4 ln 10 / lambda_2``.
        per_scale: maxima considered per scale (by decreasing value).
        valley: the least drop, relative to the function's range, between two distinct extrema.
        border, like, hill: a point suppressed only from the outer ``border`` of its ball, by points
            of other functions, stays where a kept point of its own function matches its HKS within
            ``like`` of each scale's range (:func:`_orbit_partner_kept`) and it tops a hill of its
            function ``hill`` of that range high (:func:`persistent_points`' test); ``border=0``: never.

    Returns:
        [N] vertex ids, coarse scales first.
    """
    V = evecs.shape[0]
    h = hks_at_scales(evals, evecs, scales)  # [V, T]
    adj = vertex_adjacency(faces, V)
    cand: list[int] = []
    source: dict[int, int] = {}  # the function (scale, sign) a candidate is an extremum of
    for col in range(h.shape[1]):
        for sign in (1.0, -1.0):  # maxima (tips, convex corners), then minima (concave corners)
            for v in local_maxima(sign * h[:, col].numpy(), adj, rings=2)[:per_scale]:
                if int(v) not in cand:
                    cand.append(int(v))
                    source[int(v)] = 2 * col + (sign < 0)
    x = np.asarray(verts_unit)
    hn = h.numpy()
    spread = hn.max(0) - hn.min(0)

    def own(v: int) -> np.ndarray:  # [V] the function v is an extremum of, its maxima on top
        return hn[:, source[v] // 2] * (-1 if source[v] % 2 else 1)

    keep: list[int] = []
    r = nms_radius * EPS_KLC
    held: list[int] = []  # suppressed, for the second look
    for v in cand:
        near = [k for k in keep if np.linalg.norm(x[k] - x[v]) <= r] if keep else []
        if all(source[k] == source[v] and _separated(own(v), adj, x, k, v, 2.5 * r, valley) for k in near):
            keep.append(v)
        else:
            held.append(v)
        if len(keep) == n_max:
            break
    for v in held:  # once every partner it may have is kept
        if len(keep) == n_max:
            break
        near = [k for k in keep if np.linalg.norm(x[k] - x[v]) <= r]
        if _orbit_partner_kept(v, near, keep, source, x, hn, spread, r, border, like) \
                and _top_of_hill(own(v), adj, np.linalg.norm(x - x[v], axis=1) <= 2.5 * EPS_KLC, v,
                                 hill * float(spread[source[v] // 2])):
            keep.append(v)
    return np.asarray(keep, dtype=np.int64)


def _orbit_partner_kept(v: int, near: list[int], keep: list[int], source: dict, x: np.ndarray,
                        hn: np.ndarray, spread: np.ndarray, r: float, border: float, like: float) -> bool:
    """Whether a candidate the suppression would drop must stay because its orbit stays.

    Two features found at different scales merge where they lie within the suppression radius; an
    orbit's members lie at the same distance from their coarse-scale partners, but only up to the
    triangulation (a square antiprism's corners 0.92 and 1.02 radii from the coarsest scale's
    maxima: half its corners dropped, and with them every element that moves them). So ``v`` stays
    where every point that suppresses it lies in the outer ``border`` of the ball, none is of its own
    function, and a kept point of its own function matches its HKS at every scale within ``like``
    of each scale's range: an orbit partner that the radius let through. (:func:`invariant_points`
    also asks that ``v`` tops a hill of its function: on a remeshed octagonal prism, finest-scale
    minima of the flat walls, which noise places, passed the rest, and the extra points let
    through spurious sixteenth turns.)"""
    if not near or any(source[k] == source[v] or np.linalg.norm(x[k] - x[v]) < (1 - border) * r for k in near):
        return False
    return any(source[u] == source[v] and bool((np.abs(hn[u] - hn[v]) <= like * spread).all()) for u in keep)


def persistent_points(evals: Tensor, evecs: Tensor, faces, verts_unit: np.ndarray, points: np.ndarray, *,
                      share: float = GroupConfig.persistence, radius: float = 2.5,
                      scales=(1.0, 0.1, 0.02)) -> np.ndarray:
    """[n] bool: the points that are the top of their hill in one of :func:`invariant_points`'
    functions (an HKS scale, maximum or minimum), a hill ``share`` of its range high.

    A point passes when, within ``radius`` KLC radii of it, no path from it that stays above its
    value less ``share`` of the function's range reaches a higher vertex (0-dimensional persistence,
    cut at that ball). On a flat region of a triangulation no symmetry preserves (a prism's cap,
    remeshed) the finest HKS scale has extrema wherever the mesh puts them, a hundredth of its range
    high, and at no symmetric spots; the corners, tips and cap centres stand most of the range
    above their surroundings. Source tuples drawn from the first kind miss every element that
    maps them nowhere near a point of the set.
    """
    h = hks_at_scales(evals, evecs, scales).numpy()
    adj = vertex_adjacency(faces, evecs.shape[0])
    x = np.asarray(verts_unit)
    out = np.zeros(len(points), dtype=bool)
    funcs = [sign * h[:, col] for col in range(h.shape[1]) for sign in (1.0, -1.0)]
    for i, p in enumerate(np.asarray(points)):
        ball = np.linalg.norm(x - x[p], axis=1) <= radius * EPS_KLC
        ring = adj.indices[adj.indptr[p]:adj.indptr[p + 1]]
        out[i] = any(_top_of_hill(f, adj, ball, int(p), share * float(f.max() - f.min()))
                     for f in funcs if not (f[ring] > f[p]).any())  # a 1-ring maximum of f first
    return out


def _top_of_hill(f: np.ndarray, adj, ball: np.ndarray, p: int, drop: float) -> bool:
    """Whether no vertex above ``f[p]`` is reached from ``p`` within ``ball`` staying above ``f[p] - drop``."""
    return bool(f[_component(adj, ball & (f >= f[p] - drop), p)].max() <= f[p])


def _component(adj, mask: np.ndarray, p: int) -> np.ndarray:
    """The vertices of ``mask`` [V] bool connected to ``p`` (in ``mask``) through ``mask``."""
    from scipy.sparse.csgraph import connected_components

    sub = np.flatnonzero(mask)
    _, lab = connected_components(adj[sub][:, sub], directed=False)
    return sub[lab == lab[np.searchsorted(sub, p)]]


def _separated(f: np.ndarray, adj, x: np.ndarray, a: int, b: int, radius: float, valley: float) -> bool:
    """Whether two maxima ``a``, ``b`` of ``f`` [V] are separated by a valley: no path between them
    within ``radius`` of ``b`` keeps ``f`` above ``min(f[a], f[b]) - valley * range(f)``."""
    level = min(f[a], f[b]) - valley * float(f.max() - f.min())
    mask = (np.linalg.norm(x - x[b], axis=1) <= radius) & (f >= level)
    if not (mask[a] and mask[b]):
        return True
    return bool(a not in _component(adj, mask, b))


class Pinning:
    """How well the points of ``P`` pin each band: the disk constraints of a tuple, band by band.

    The Procrustes block of band ``b`` is determined by a tuple ``T`` when the disk coefficients of
    its points in that band, ``X_b(T)`` [|T| R, k_b], have full rank: its smallest singular value is
    the tuple's hold on the band. ``m + 1`` points in general position pin a band of size ``m``,
    but an orbit can lie on the nodal set of an eigenfunction: the eight corners of a box sit near
    the zeros of one eigenfunction that every mirror negates, and the tips of a thin star lie on
    its mid-plane, where every eigenfunction its top/bottom mirror negates vanishes. A tuple of
    such points leaves the sign (or the block) of that band to noise, and the candidates of a
    mirror come out as a rotation. ``strength`` compares the hold of a tuple with that of a
    typical tuple of its size, ``sigma_min(X_b(T)) / (sigma_min(X_b(P)) sqrt(|T| / n))``: about 1
    for points in general position.

    Args:
        coef: [n, R, K] disk coefficients of the points (``constraints.disk_coefficients``).
        bands: bands covering ``0..K-1``.
    """

    def __init__(self, coef: Tensor, bands: list[range]):
        self.coef = coef.double()
        self.bands = [b for b in bands if b.start > 0]  # the constant band is pinned by any disk
        n = coef.shape[0]
        self.ref = torch.stack([self._hold(np.arange(n), b) for b in self.bands]) / math.sqrt(n)

    def _hold(self, tup, b: range) -> Tensor:
        X = self.coef[torch.as_tensor(np.asarray(tup))][:, :, b.start:b.stop].reshape(-1, len(b))
        if X.shape[0] < len(b):
            return X.new_zeros(())
        return torch.linalg.svdvals(X)[-1]

    def strength(self, tup) -> float:
        """Weakest relative hold of the tuple over the bands (1: as a typical tuple; 0: a band free)."""
        if not self.bands:
            return 1.0
        hold = torch.stack([self._hold(tup, b) for b in self.bands])
        return float((hold / (self.ref * math.sqrt(len(tup))).clamp_min(1e-12)).min())


def source_tuples(dist: np.ndarray, size: int, n_sources: int, usable: np.ndarray | None = None,
                  pinning: Pinning | None = None, min_pin: float = 0.3,
                  max_extra: int = 2) -> list[list[int]]:
    """Well-spread point tuples: geodesic farthest-point orders from different starting points.

    ``usable`` [n] bool marks the points preferred in a tuple (those with a descriptor partner: a
    point of P without one is either on every symmetry axis, or an extremum whose partners were
    lost, which would leave the tuple with no image at all); others fill in when too few.

    With ``pinning``, a tuple that holds some band weakly (``Pinning.strength`` below ``min_pin``)
    is grown by up to ``max_extra`` points, each the usable point that most strengthens its weakest
    band, while that helps: a longer tuple also prunes its targets harder, so the candidates do not
    multiply.
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
        if pinning is not None:
            tup = _pinned(tup, pinning, ok, min_pin, max_extra)
        if sorted(tup) not in [sorted(t) for t in out]:
            out.append(tup)
        if len(out) == n_sources:
            break
    return out


def _pinned(tup: list[int], pinning: Pinning, ok: np.ndarray, min_pin: float, max_extra: int) -> list[int]:
    """``tup`` grown greedily until every band is held (see :func:`source_tuples`)."""
    best = pinning.strength(tup)
    for _ in range(max_extra):
        if best >= min_pin:
            break
        trial = [(pinning.strength(tup + [int(c)]), int(c)) for c in np.flatnonzero(ok) if int(c) not in tup]
        if not trial:
            break
        s, c = max(trial)
        if s <= best:
            break
        tup, best = tup + [c], s
    return tup


def candidate_tuples(src: list[int], dist: np.ndarray, allowed: np.ndarray, delta: float = 0.9,
                     slack: float = 0.5 * EPS_KLC, max_candidates: int = 20000,
                     max_missing: int = 0) -> tuple[np.ndarray, int]:
    """Ordered target tuples ``q`` for a source tuple ``p`` that keep geodesic distances (ALGORITHM §5.2).

    Enumerated level by level (all targets for ``p_1``, extended by all targets for ``p_2``, ...),
    dropping a partial tuple as soon as ``|d(p_i, p_j) - d(q_i, q_j)| > (1 - delta) max(...) + slack``
    (the ratio test with a slack for short distances) or ``allowed[p_i, q_i]`` is False.

    With ``max_missing`` > 0 a partial tuple that no target extends at some level goes on with -1
    there (no target; at most that many per tuple, and only where none extends it): a near-isometry
    moves some extrema off their partners' images (four arms bent at R = 4: six of sixteen points
    map 1.2 KLC radii from any point of the set), and a tuple holding one would otherwise find none.

    Args:
        src: [t] indices into the point set.
        dist: [n, n] geodesic distances between the points.
        allowed: [n, n] bool descriptor agreement.

    Returns:
        ([N, t] target tuples, -1 where missing; number of ordered tuples before pruning).
    """
    n, t = dist.shape[0], len(src)
    total = math.perm(n, t)
    part = np.flatnonzero(allowed[src[0]])[:, None]  # [N, 1]
    if max_missing > 0:  # index -1: a missing target, its distances unchecked
        part = np.concatenate([part, [[-1]]])
        dist = np.pad(dist, ((0, 1), (0, 1)))
    for j in range(1, t):
        q = np.flatnonzero(allowed[src[j]])
        if len(part) == 0:
            return np.zeros((0, t), dtype=np.int64), total
        dp = dist[src[:j], src[j]]  # [j]
        dq = dist[part][:, :, q]  # [N, j, nq]
        lim = (1 - delta) * np.maximum(dq, dp[None, :, None]) + slack
        close = np.abs(dq - dp[None, :, None]) <= lim
        ok = (close | (part[:, :, None] < 0) if max_missing > 0 else close).all(1)  # [N, nq]
        ok &= (part[:, :, None] != q[None, None, :]).all(1)  # distinct targets
        a, b = np.nonzero(ok)
        grown = np.concatenate([part[a], q[b, None]], 1)
        if max_missing > 0:  # the tuples nothing extends, with room for one more miss
            stuck = np.flatnonzero(~ok.any(1) & ((part < 0).sum(1) < max_missing))
            grown = np.concatenate([grown, np.concatenate([part[stuck], np.full((len(stuck), 1), -1)], 1)])
        part = grown
        if len(part) > max_candidates:
            warnings.warn(f"{len(part)} partial candidates; keeping {max_candidates} (continuous "
                          "symmetry or a point set with little structure)", stacklevel=2)
            part = part[:max_candidates]
    if max_missing > 0:  # a tuple needs two targets to say anything
        part = part[(part >= 0).sum(1) >= 2]
    return part, total


def descriptor_ratios(desc: Tensor, near: tuple[Tensor, Tensor] | None = None) -> np.ndarray:
    """[n, n] distances between the points' standardised multi-scale log-descriptors, as a share of
    their median over all pairs of distinct points (what :func:`partner_mask` compares with
    ``desc_tol``; 0 on the diagonal).

    An extremum on a ridge or a flat cap is only placed up to the ridge: a near-isometry (a bend)
    moves it along the ridge, so that orbit partners sit at slightly different spots and their own
    descriptors differ, although the symmetry maps each onto a vertex next to the other. With
    ``near``, the distance of ``i`` to ``j`` is the smallest over the vertices around ``j`` (and of
    ``j`` to those around ``i``), each standardised like the points.

    Args:
        desc: [n, D] positive descriptors of the points.
        near: optional ``(desc_all [V, D], mask [n, V] bool)``: every vertex's descriptors, and the
            vertices around each point (each point's own vertex among them).
    """
    n = len(desc)
    z = standardized_descriptors(desc)
    dd = torch.cdist(z, z).numpy()
    off = dd[~np.eye(n, dtype=bool)]
    scale = float(np.median(off)) if off.size else 0.0
    if near is not None:
        z_all = standardized_descriptors(near[0], like=desc)  # [V, D], in the points' units
        around = np.stack([torch.cdist(z, z_all[near[1][j]]).min(1).values.numpy() for j in range(n)], 1)
        dd = np.minimum(dd, np.minimum(around, around.T))
    return dd / scale if scale > 0 else np.where(dd > 1e-9, np.inf, 0.0)


def partner_mask(desc: Tensor, dist: np.ndarray, desc_tol: float,
                 near: tuple[Tensor, Tensor] | None = None, relative_tol: float = 0.0) -> np.ndarray:
    """[n, n] bool: which points of ``P`` may be the image of which.

    Two points may correspond when their standardised multi-scale log-descriptors lie within
    ``desc_tol`` times the median distance of all pairs of points (exact mirror partners have
    identical descriptors, so the scale is the spread of all pairs; with ``near``, up to where the
    extremum sits on its ridge: :func:`descriptor_ratios`), and when their sorted geodesic
    distances to all of ``P`` agree (equal for orbit partners when ``P`` is invariant) to within
    ``0.5 eps`` plus 5 % of a typical distance. Every point may be its own image.

    With ``relative_tol`` a pair is also allowed where its distance is at most that share of the
    two points' own typical distances (the geometric mean of their rows' medians): a near-isometry
    that stretches a part changes the descriptors of a distinctive point (an arm's tip) in
    proportion to how far they are from every other point's, so that its partners, though beyond
    ``desc_tol``, stay its nearest by far (the tips of four arms bent at R = 6: 3.3 median
    distances apart, 8-10 from every other point).

    Args:
        desc: [n, D] positive descriptors of the points; dist: [n, n] geodesic distances among them;
        near: as for :func:`descriptor_ratios`.
    """
    n = len(dist)
    ratios = descriptor_ratios(desc, near)
    allowed = ratios <= desc_tol
    if relative_tol > 0 and n > 2:
        own = np.nanmedian(np.where(np.eye(n, dtype=bool), np.nan, ratios), axis=1, keepdims=True)
        allowed |= ratios <= relative_tol * np.sqrt(own * own.T)
    prof = np.sort(dist, 1)
    pd = np.abs(prof[:, None, :] - prof[None, :, :])
    profile_agrees = np.median(pd, -1) <= 0.5 * EPS_KLC + 0.05 * np.median(prof[:, 1:], 1)[:, None]
    return allowed & (profile_agrees | np.eye(n, dtype=bool))


class TuplePairs(NamedTuple):
    """Candidate correspondences: row ``i`` pairs source tuple ``src[i]`` with target ``dst[i]``.

    Attributes:
        src, dst: [B, t] indices into the point set; -1 pads a row whose tuple is shorter than ``t``.
        n_with_partner: points with a partner other than themselves.
        n_sources: source tuples used; n_before: ordered target tuples before pruning.
    """

    src: np.ndarray
    dst: np.ndarray
    n_with_partner: int
    n_sources: int
    n_before: int


def tuple_pairs(dist: np.ndarray, allowed: np.ndarray, size: int, n_sources: int,
                delta: float, pinning: Pinning | None = None, persistent: np.ndarray | None = None,
                max_missing: int = 0) -> TuplePairs:
    """A few well-spread source tuples of ``size`` points (more where ``pinning`` says a band is
    held weakly), each paired with every ordered target tuple that keeps its geodesic distances
    (ratio ``delta``) and whose points are allowed partners.

    Source points are taken among those that have a partner other than themselves; with
    ``persistent`` (:func:`persistent_points`) and ``size`` such points, the first of the
    ``n_sources`` tuples is drawn from those alone: a target tuple exists only where the element maps
    every source point onto a point of the set, which the flat-region extrema of a remesh are not
    near. Tuples may differ in length; the rows of the result are padded with -1 (``TuplePairs``),
    and a source point whose target is missing (``max_missing``, :func:`candidate_tuples`) is -1 in
    its row too, so that it constrains nothing.
    """
    partner = allowed.sum(1) > 1
    srcs = []
    if persistent is not None and n_sources > 1 and (partner & persistent).sum() >= size:
        srcs = source_tuples(dist, size, 1, partner & persistent, pinning)
    srcs += [t for t in source_tuples(dist, size, n_sources, partner, pinning)
             if sorted(t) not in [sorted(u) for u in srcs]][:n_sources - len(srcs)]
    tuples_src, tuples_dst, before = [], [], 0
    width = max([len(t) for t in srcs], default=size)
    for src in srcs:
        q, tot = candidate_tuples(src, dist, allowed, delta, max_missing=max_missing)
        before += tot
        pad = np.full((len(q), width - len(src)), -1, dtype=np.int64)
        p = np.where(q >= 0, np.asarray(src)[None], -1)
        tuples_src.append(np.concatenate([p, pad], 1))
        tuples_dst.append(np.concatenate([q, pad], 1))
    P = np.concatenate(tuples_src) if tuples_src else np.zeros((0, size), dtype=np.int64)
    Q = np.concatenate(tuples_dst) if tuples_dst else np.zeros((0, size), dtype=np.int64)
    return TuplePairs(P, Q, int(partner.sum()), len(srcs), int(before))
