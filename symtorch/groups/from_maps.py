"""Group structure from vertex maps: table, largest closed subset, orientation, element order.

The matrices of a detected group can be ill-determined in a nearly repeated band, and a map can be
wrong on a small part only; the vertex maps are the robust evidence. Products are matched to the
nearest map by the median gap of the images of sample vertices (unit-area shape, units of
``eps = sqrt(area / (20 pi))``), so that the table, its largest subset closed under composition
(:func:`largest_subgroup`), the orientation flags (:func:`consistent_orientation`) and a readable
element order (:func:`canonical_order`) rest on the maps. Table convention of :mod:`symtorch.groups`:
``table[a, b]`` is ``a ∘ b`` ("apply b, then a").
"""
from __future__ import annotations

import logging

import numpy as np
import torch
from torch import Tensor

from ..units import EPS_KLC
from .algebra import _subtable, _z2_homs, check_group

log = logging.getLogger(__name__)


__all__ = ["map_table", "largest_subgroup", "closed_subsets", "consistent_orientation", "canonical_order"]


def map_table(p2ps: list[Tensor], verts_unit: Tensor, samples: Tensor) -> tuple[Tensor, Tensor]:
    """Group table of vertex maps: ``table[a, b]`` = the map nearest to ``a ∘ b`` ("b, then a").

    Distances are the median Euclidean gap of the images of ``samples`` on the unit-area shape, in
    units of eps: robust where a matrix is ill-determined in a nearly repeated band, and where a map
    is wrong on a small part only.

    Returns:
        (table [G, G] long, gap [G, G] of each product to its nearest map, in eps).
    """
    P = torch.stack(p2ps)  # [G, V]
    img = P[:, samples]  # [G, S]
    comp = P[:, None, :].expand(-1, len(p2ps), -1).gather(2, img[None].expand(len(p2ps), -1, -1))
    # comp[a, b] = p2p_a[p2p_b[samples]]
    # median, not mean: a map that differs from another only on a small part (a near-identity that
    # flips one limb) is the same element, not a new one; one row a at a time, so that memory grows
    # as G^2 S, not G^3 S (150 noisy elements once asked for 16 GB here)
    pos = verts_unit[img]  # [G, S, 3]
    gap = torch.stack([(verts_unit[comp[a]][:, None] - pos[None]).norm(dim=-1).median(-1).values
                       for a in range(len(p2ps))])  # [G, G, G]: product (a, b) to element c
    best, idx = gap.min(-1)
    return idx, best / EPS_KLC


def _forms_group(T: np.ndarray, idx: list[int]) -> bool:
    """Whether the elements ``idx`` of the product table ``T`` form a group by themselves."""
    try:
        sub = _subtable(T, np.asarray(idx))
    except ValueError:  # a product falls outside the set
        return False
    return check_group(torch.as_tensor(sub)).is_group


def largest_subgroup(p2ps: list[Tensor], cost: list[float], verts_unit: Tensor, samples: Tensor,
                     tol: float = 1.0, same_tol: float = 0.5) -> tuple[list[int], Tensor]:
    """The largest set of elements (identity first, lowest ``cost`` first) closed under composition.

    Greedy: an element joins when the set it generates, by products matched to the elements present
    (within ``tol`` eps, :func:`map_table`), stays inside the verified elements; otherwise it is left
    out (a near-isometry the rest of the group does not confirm). Maps closer than ``same_tol`` eps,
    or two vertex spacings where that is more, are one element, represented by the lowest-cost
    copy, also where a product matches another copy: two copies of an element differ by the jitter
    of a nearest-neighbour map, a vertex or two, or the resolution of the basis. ``same_tol`` is
    the coarse stage's own duplicate test (mean gap under eps / 2, ``detect.group_elements``): with
    ``tol`` there, the top/bottom mirror of a slab about one eps thick (its images a median 0.9 eps
    from those of the identity) was merged with the identity, and half of a D_nh group with it.

    Returns:
        (indices kept, [G', G'] long table among them, renumbered in the order kept).
    """
    T, ok, rep, order = _matched_table(p2ps, cost, verts_unit, samples, tol, same_tol)
    group = _greedy_closed(T, ok, rep, order)
    return group, torch.as_tensor(_subtable(T, np.asarray(group)), dtype=torch.long)


def closed_subsets(p2ps: list[Tensor], cost: list[float], verts_unit: Tensor, samples: Tensor,
                   tol: float = 1.0, same_tol: float = 0.5) -> list[tuple[list[int], Tensor]]:
    """:func:`largest_subgroup`'s greedy set first, then the distinct greedy sets seeded by each
    element it left out (that element first, then the rest by ``cost``): where two near-isometries
    that do not compose (a bent chiral shape's quarter turns and two near-mirrors of its half
    turn) each close a group with the exact elements, the cheapest is not always the true one.

    Returns:
        [(indices kept, [G', G'] long table among them)], the first :func:`largest_subgroup`'s.
    """
    T, ok, rep, order = _matched_table(p2ps, cost, verts_unit, samples, tol, same_tol)
    e = order[0]
    first = _greedy_closed(T, ok, rep, order)
    found = [first]
    for seed in order[1:]:
        if rep[seed] != seed or seed in first:
            continue
        group = _greedy_closed(T, ok, rep, [e, seed] + [i for i in order[1:] if i != seed])
        if len(group) > 1 and all(sorted(group) != sorted(g) for g in found):
            found.append(group)
    return [(g, torch.as_tensor(_subtable(T, np.asarray(g)), dtype=torch.long)) for g in found]


def _matched_table(p2ps: list[Tensor], cost: list[float], verts_unit: Tensor, samples: Tensor,
                   tol: float, same_tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """What :func:`largest_subgroup`'s greedy sets are grown from: (the [G, G] map table with every
    duplicate read as its representative, [G, G] bool products matched within ``tol``, [G] the
    representative of each element, the identity then the elements by ``cost``)."""
    T, gap = (x.numpy() for x in map_table(p2ps, verts_unit, samples))
    log.debug("map table %s gaps %s", T.tolist(), np.round(gap, 2).tolist())
    pos = verts_unit[torch.stack(p2ps)[:, samples]]  # [G, S, 3]
    from scipy.spatial import cKDTree

    x = np.asarray(verts_unit.detach().cpu(), dtype=np.float64)
    spacing = float(np.median(cKDTree(x).query(x, k=2)[0][:, 1])) / EPS_KLC  # a vertex spacing, in eps
    same_tol = max(same_tol, 2 * spacing)
    same = ((pos[:, None] - pos[None]).norm(dim=-1).median(-1).values / EPS_KLC).numpy() <= same_tol  # [G, G]
    e = 0  # the identity is the first element
    order = [e] + [int(i) for i in np.argsort(cost, kind="stable") if i != e]
    # duplicates (the same map twice, e.g. a closure product that upsampled onto an element) stand
    # for the lowest-cost copy: a product matched to a copy is a product matched to that element
    rep = np.arange(len(p2ps))
    for i in order:
        if rep[i] == i:
            rep[[j for j in order if rep[j] == j and j != i and same[i, j]]] = i
    T = rep[T]
    ok = gap <= tol
    return T, ok, rep, order


def _greedy_closed(T: np.ndarray, ok: np.ndarray, rep: np.ndarray, order: list[int]) -> list[int]:
    """The greedy closed set of :func:`largest_subgroup`, the elements tried in ``order`` (identity first)."""
    group = [order[0]]
    for el in order[1:]:
        if rep[el] != el or el in group:
            continue  # a duplicate of another element, or present
        trial = group + [el]
        while trial is not None:
            sub = np.ix_(trial, trial)
            if not ok[sub].all():
                trial = None
                break
            new = sorted(set(T[sub].reshape(-1).tolist()) - set(trial))
            if not new:
                break
            trial += new
        if trial is not None and _forms_group(T, trial):
            group = trial
    return group


def consistent_orientation(table: Tensor, scores) -> Tensor:
    """Orientation flags consistent with the group table, closest to the per-element votes.

    Orientation is a homomorphism onto Z2 (reversing ∘ reversing preserves); of the trivial one and
    every homomorphism of the table (``groups._z2_homs``), the one that agrees best with the
    orientation votes (``groups.orientation_score`` in [-1, 1]; negative = reversing) is returned, so
    one ambiguous vote (a noisy map) cannot make the group unnamable.

    Returns:
        [G] bool, True for orientation-reversing elements.
    """

    T = np.asarray(table)
    G = T.shape[0]
    e = int(np.flatnonzero((T == np.arange(G)[None]).all(1))[0])
    votes = np.asarray([float(v) for v in scores])
    options = [np.zeros(G, dtype=bool)] + _z2_homs(T, e)
    agree = [float((votes * np.where(h, -1.0, 1.0)).sum()) for h in options]
    return torch.as_tensor(options[int(np.argmax(agree))])


def canonical_order(table: Tensor, reversing: Tensor, cost: list[float]) -> list[int]:
    """An element order that reads like the paper's Table 3: the identity, the rotations as powers
    ``r, r^2, ...`` of a generator when they form a cyclic group (else by ``cost``), then the
    orientation-reversing coset as ``s, s∘r, s∘r^2, ...`` for its best (lowest-cost) involution ``s``.

    Args:
        table: [G, G] group table (``table[a, b] = a∘b``); reversing: [G] bool; cost: [G] (lower first).

    Returns:
        a permutation of ``range(G)``.
    """
    T = table.numpy()
    G = T.shape[0]
    e = int(np.flatnonzero((T == np.arange(G)[None]).all(1))[0])
    rev = np.asarray(reversing, dtype=bool)
    rots = [i for i in np.argsort(cost) if not rev[i] and i != e]
    out = [e]
    gen = None
    for r in rots:  # a generator of the rotation subgroup, if it is cyclic
        pw, seen_ = [int(r)], {e, int(r)}
        while T[r, pw[-1]] not in seen_:
            pw.append(int(T[r, pw[-1]]))
            seen_.add(pw[-1])
        if len(pw) == len(rots):
            gen = pw
            break
    out += gen if gen is not None else [int(r) for r in rots]
    refl = [int(i) for i in np.argsort(cost) if rev[i]]
    if refl:
        inv2 = [i for i in refl if T[i, i] == e] or refl
        s0 = inv2[0]
        coset = [int(T[s0, h]) for h in out]  # s∘h: apply h, then s
        out += coset if sorted(coset) == sorted(refl) else refl
    return out
