"""Candidate reflections: involutive permutations of heat-kernel extrema (ALGORITHM §4, steps 1-2).

:func:`heat_extrema` finds the limb tips (heat-kernel maxima, geodesically thinned). A reflection
pairs them up: :func:`seed_pairs` proposes two mutually symmetric pairs from descriptor closeness and
geodesic consistency (the paper's step), :func:`extend_involution` grows each seed into an involutive
permutation of all extrema, and :func:`involution_candidates` keeps the distinct permutations, ranked
by how well they keep the geodesic distances among all extrema. ``symtorch.detect.reflection`` turns each into
a matrix and chooses among them.
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import torch
from torch import Tensor

from ..descriptors import hks
from ..units import EPS_KLC
from ..geodesics import GeodesicSolver
from ..sampling import local_maxima, vertex_adjacency

__all__ = ["heat_extrema", "seed_pairs", "extend_involution", "involution_candidates"]


def heat_extrema(evals: Tensor, evecs: Tensor, faces, solver: GeodesicSolver, n_extrema: int = 12,
                 nms_radius: float = 2.0) -> tuple[np.ndarray, Tensor]:
    """Local maxima of the HKS at ``t = 4 ln 10 / λ2`` and ``t/4`` (3-ring), geodesically thinned.

    Returns:
        (points [N] vertex ids, dist [N, V] geodesic distances from them on the unit-area shape).
    """
    V = evecs.shape[0]
    t = 4 * math.log(10) / float(evals[1])
    h = hks(evals, evecs, torch.tensor([t, t / 4], dtype=evals.dtype))
    adj = vertex_adjacency(faces, V)
    ext: list[int] = []
    for col in range(h.shape[1]):
        for v in local_maxima(h[:, col].numpy(), adj, rings=3):
            if int(v) not in ext:
                ext.append(int(v))
    # greedy geodesic non-maximum suppression; distances are solved only from the points kept
    keep: list[int] = []
    rows: list[np.ndarray] = []
    for v in ext[: 4 * n_extrema]:
        if all(row[v] > nms_radius * EPS_KLC for row in rows):
            keep.append(v)
            rows.append(np.asarray(solver.distances_from(np.array([v]))).reshape(-1))
        if len(keep) == n_extrema:
            break
    return np.array(keep, dtype=np.int64), torch.as_tensor(np.stack(rows), dtype=evecs.dtype)


def _ratio(a: float, b: float) -> float:
    lo, hi = min(a, b), max(a, b)
    return 1.0 if hi <= 1e-12 else lo / hi


def seed_pairs(desc: np.ndarray, dist: np.ndarray, n_partners: int = 3,
               delta: float = 0.8) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Seeds: two disjoint symmetric pairs ``(p1, q1), (p2, q2)`` (ALGORITHM §4 step 2).

    A pair ``{p, q}`` (``p == q``: a fixed point) is allowed when ``q`` is among the ``n_partners``
    descriptor-nearest points of ``p``; two allowed pairs form a seed when the distances they imply
    agree (``d(p1,p2) ~ d(q1,q2)``, ``d(p1,q2) ~ d(q1,p2)``, ratio >= ``delta``) and they are not
    both fixed points (that is the identity).

    Args:
        desc: [N, D] descriptors of the N points; dist: [N, N] geodesic distances among them.

    Returns:
        list of ((p1, q1), (p2, q2)) in point indices 0..N-1.
    """
    N = len(desc)
    dd = np.linalg.norm(desc[:, None] - desc[None], axis=-1)
    allowed = sorted({(min(i, int(j)), max(i, int(j))) for i in range(N)
                      for j in np.argsort(dd[i])[: n_partners + 1]})
    out = []
    for (a, b), (c, e) in itertools.combinations(allowed, 2):
        if {a, b} & {c, e} or (a == b and c == e):
            continue
        for (p1, q1), (p2, q2) in (((a, b), (c, e)), ((a, b), (e, c))):
            if c == e and (p2, q2) != (c, e):
                continue  # fixed point: one orientation only
            if _ratio(dist[p1, p2], dist[q1, q2]) >= delta and \
                    _ratio(dist[p1, q2], dist[q1, p2]) >= delta:
                out.append(((p1, q1), (p2, q2)))
    return out


def extend_involution(seed, dist: np.ndarray, allowed: np.ndarray, tol: float) -> np.ndarray:
    """Extend two seed pairs to an involutive permutation of all N points.

    Greedy: repeatedly pair the unpaired point ``i`` with the unpaired partner ``j`` (``j == i``: a
    fixed point; ``allowed[i, j]`` must hold) whose distances to the paired points agree best,
    ``c(i, j) = mean_a |d(i, a) - d(j, π(a))|``, cheapest first. A point whose best cost exceeds
    ``tol`` stays unpaired (``-1``): an extremum with no symmetric twin.

    Args:
        seed: ((p1, q1), (p2, q2)).
        dist: [N, N] geodesic distances; allowed: [N, N] bool (descriptor gate, symmetric).
        tol: largest mean distance disagreement for a pairing.

    Returns:
        [N] int, ``perm[i]`` the partner of i, or -1.
    """
    N = len(dist)
    perm = -np.ones(N, dtype=np.int64)
    for p, q in seed:
        perm[p], perm[q] = q, p
    while True:
        paired = np.flatnonzero(perm >= 0)
        free = np.flatnonzero(perm < 0)
        if len(free) == 0:
            break
        # cost[i, j] for free i, j: mean over paired a of |d(i,a) - d(j,perm[a])|
        cost = np.abs(dist[np.ix_(free, paired)][:, None, :]
                      - dist[np.ix_(free, perm[paired])][None, :, :]).mean(-1)
        cost = np.where(allowed[np.ix_(free, free)], cost, np.inf)
        # a pair costs the worse of its two directions
        cost = np.maximum(cost, cost.T)
        flat = int(np.argmin(cost))
        i, j = divmod(flat, len(free))
        if not np.isfinite(cost[i, j]) or cost[i, j] > tol:
            break
        perm[free[i]], perm[free[j]] = free[j], free[i]
    return perm


def involution_candidates(desc: np.ndarray, dist: np.ndarray, n_partners: int = 3, delta: float = 0.8,
                          tol: float = 1.0 * EPS_KLC) -> tuple[list[np.ndarray], np.ndarray, int]:
    """Distinct involutive permutations of the extrema grown from the seeds, best first.

    Score of a permutation: mean over paired points ``a, b`` of ``|d(a, b) - d(π(a), π(b))|``, in
    units of the KLC tolerance, plus one tolerance per unpaired point (so that pairing everything
    consistently wins over leaving the hard points out).

    Returns:
        (permutations, scores [P], number of seeds).
    """
    N = len(desc)
    dd = np.linalg.norm(desc[:, None] - desc[None], axis=-1)
    allowed = np.zeros((N, N), dtype=bool)
    for i in range(N):
        allowed[i, np.argsort(dd[i])[: n_partners + 1]] = True
    allowed |= allowed.T
    seeds = seed_pairs(desc, dist, n_partners, delta)
    perms: dict[tuple, np.ndarray] = {}
    for seed in seeds:
        perm = extend_involution(seed, dist, allowed, tol)
        perms.setdefault(tuple(perm.tolist()), perm)
    out, scores = [], []
    for perm in perms.values():
        if np.all(perm == np.arange(N)):
            continue
        paired = np.flatnonzero(perm >= 0)
        D0 = dist[np.ix_(paired, paired)]
        D1 = dist[np.ix_(perm[paired], perm[paired])]
        score = np.abs(D0 - D1).sum() / max(len(paired) * (len(paired) - 1), 1) / EPS_KLC
        score += (N - len(paired)) / max(N, 1)
        out.append(perm)
        scores.append(score)
    order = np.argsort(scores, kind="stable")
    return [out[i] for i in order], np.asarray(scores)[order], len(seeds)
