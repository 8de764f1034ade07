"""Symmetry groups as algebra: composition, inverses, orders, Cayley tables, axioms and closure.

``docs/method.md`` §2 (conventions) and §5 (closure, tables); each convention is pinned by
``tests/test_algebra.py``. Names and orientation: :mod:`symtorch.groups.naming`.

Note:
    - A symmetry ``g`` is a vertex map ``p2p [V]`` (``p2p[i]`` is the image of vertex ``i``) or its
      matrix ``C = evecs.mT @ (mass[:, None] * evecs[p2p])`` [K, K] (pullback:
      ``f ∘ g ≈ evecs @ (C @ a)``).
    - "Apply h, then g" is ``g ∘ h``: ``p2p = g[h]`` and ``C = C_h @ C_g`` (order reversed).
    - The identity is ``I``, the inverse of an orthogonal ``C`` is ``C.mT``, and the order of ``g``
      is the smallest ``n`` with ``C^n ≈ I``.
    - Cayley table: ``table[a, b]`` is the index of ``a ∘ b`` ("apply b, then a"), i.e. of the
      element nearest to ``fmaps[b] @ fmaps[a]``: row times column, the usual reading of a group
      table. The caption of the paper's Table 3 reads its entry (i, j) as ``g_j · g_i`` with the
      paper's product ``g_x · g_y ↔ C_y C_x`` (row applied first), so the paper's layout is
      ``table.mT``. Inverses, orders and names do not depend on this choice.
    - Matrices are compared by relative Frobenius distance ``||A - B||_F / ||B||_F`` (B the element
      of the set; ``||B||_F = sqrt(K)`` when B is orthogonal).
"""
from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

from ..procrustes import nearest_orthogonal

log = logging.getLogger(__name__)

__all__ = ["DEFAULT_TOL", "compose_fmap", "compose_p2p", "inverse_fmap", "inverse_p2p", "Cayley",
           "cayley_table", "identity_index", "element_orders", "inverses", "GroupCheck", "check_group",
           "Closure", "closure"]

DEFAULT_TOL = 0.25  # relative Frobenius distance under which two symmetry matrices are "the same"


# ---------------------------------------------------------------------------------- validation
def _check_p2p(p2p, name: str = "p2p", n_verts: int | None = None) -> Tensor:
    p2p = torch.as_tensor(p2p)
    if p2p.ndim < 1 or p2p.is_floating_point() or p2p.is_complex() or p2p.dtype == torch.bool:
        raise ValueError(f"{name} must be [..., V] integer vertex indices, got {list(p2p.shape)} "
                         f"{p2p.dtype}")
    p2p = p2p.long()
    V = p2p.shape[-1] if n_verts is None else n_verts
    if p2p.numel() and (int(p2p.min()) < 0 or int(p2p.max()) >= V):
        raise ValueError(f"{name} index out of range: values span [{int(p2p.min())}, "
                         f"{int(p2p.max())}] but there are {V} vertices")
    return p2p


def _check_fmaps(fmaps, name: str = "fmaps", batched: bool = True) -> Tensor:
    if not isinstance(fmaps, Tensor) or not fmaps.is_floating_point():
        raise ValueError(f"{name} must be a floating-point tensor, got {type(fmaps).__name__}"
                         + (f" {fmaps.dtype}" if isinstance(fmaps, Tensor) else ""))
    if (batched and fmaps.ndim != 3) or fmaps.ndim < 2 or fmaps.shape[-1] != fmaps.shape[-2]:
        want = "[G, K, K]" if batched else "[..., K, K]"
        raise ValueError(f"{name} must be {want}, got {list(fmaps.shape)}")
    if batched and fmaps.shape[0] == 0:
        raise ValueError(f"{name} is empty (G = 0 symmetries)")
    return fmaps


def _is_table(x) -> bool:
    return isinstance(x, Tensor) and not x.is_floating_point() and x.dtype != torch.bool


def _check_table(table, name: str = "table") -> Tensor:
    table = torch.as_tensor(table)
    if table.ndim != 2 or table.shape[0] != table.shape[1] or table.is_floating_point() \
            or table.dtype == torch.bool or table.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty [G, G] integer table, got "
                         f"{list(table.shape)} {table.dtype}")
    G = table.shape[0]
    if int(table.min()) < -1 or int(table.max()) >= G:
        raise ValueError(f"{name} entries must lie in [-1, {G - 1}] (-1 = not in the set), got "
                         f"[{int(table.min())}, {int(table.max())}]")
    return table.long()


def _check_reversing(reversing, G: int) -> np.ndarray:
    rev = np.asarray(torch.as_tensor(reversing).detach().cpu()).astype(bool).reshape(-1)
    if rev.shape[0] != G:
        raise ValueError(f"reversing must be [G] = [{G}] bools, got {rev.shape[0]} values")
    return rev


# ------------------------------------------------------------------------- composition and inverses
def compose_fmap(C_g: Tensor, C_h: Tensor) -> Tensor:
    """Matrix of ``g ∘ h`` ("apply h, then g"): ``C_h @ C_g`` (order reversed by the pullback).

    Args:
        C_g, C_h: [..., K, K] symmetry matrices (broadcast).

    Returns:
        [..., K, K].
    """
    _check_fmaps(C_g, "C_g", batched=False), _check_fmaps(C_h, "C_h", batched=False)
    if C_g.shape[-1] != C_h.shape[-1]:
        raise ValueError(f"C_g is K={C_g.shape[-1]} but C_h is K={C_h.shape[-1]}")
    return C_h @ C_g


def compose_p2p(g: Tensor, h: Tensor) -> Tensor:
    """Vertex map of ``g ∘ h`` ("apply h, then g"): ``g[h]``.

    Args:
        g, h: [..., V] vertex maps (broadcast over the leading dims).

    Returns:
        [..., V] long, entry i = g[h[i]].
    """
    g, h = _check_p2p(g, "g"), _check_p2p(h, "h")
    if g.shape[-1] != h.shape[-1]:
        raise ValueError(f"g maps V={g.shape[-1]} vertices but h maps V={h.shape[-1]}")
    batch = torch.broadcast_shapes(g.shape[:-1], h.shape[:-1])
    V = g.shape[-1]
    return torch.gather(g.expand(*batch, V), -1, h.expand(*batch, V))


def inverse_fmap(C: Tensor) -> Tensor:
    """Matrix of ``g^-1``: ``C.mT``.

    Exact for an orthogonal C; for an approximately orthogonal one it is the inverse of the nearest
    orthogonal matrix up to first order, which is what a symmetry matrix should be.

    Args:
        C: [..., K, K].

    Returns:
        [..., K, K].
    """
    return _check_fmaps(C, "C", batched=False).mT


def inverse_p2p(p2p: Tensor, points: Tensor | None = None) -> Tensor:
    """Vertex map of ``g^-1``.

    A permutation is inverted exactly (``inv[p2p[i]] = i``, same as ``argsort``). A map that is not
    a bijection (a nearest-neighbour map from a functional map usually is not) has no exact inverse;
    the fallback gives each vertex ``j`` the vertex ``i`` whose image ``p2p[i]`` lies nearest to
    ``j`` in ``points`` (several preimages: one of them). Pass ``verts`` for a near-rigid shape, or
    the spectral embedding ``evecs`` for an intrinsic one.

    Args:
        p2p: [..., V] vertex map.
        points: [V, D] coordinates for the nearest fallback; needed only when p2p is not a
            permutation.

    Returns:
        [..., V] long.

    Raises:
        ValueError: p2p is not a permutation and ``points`` is None, or shapes disagree.
    """
    p2p = _check_p2p(p2p)
    V = p2p.shape[-1]
    flat = p2p.reshape(-1, V)
    hits = torch.zeros_like(flat).scatter_add_(-1, flat, torch.ones_like(flat))
    if bool((hits == 1).all()):
        inv = torch.empty_like(flat)
        inv.scatter_(-1, flat, torch.arange(V, device=p2p.device).expand_as(flat).contiguous())
        return inv.reshape(p2p.shape)
    if points is None:
        n_bad = int((hits == 0).sum())
        raise ValueError(f"p2p is not a permutation ({n_bad} vertices are nobody's image); pass "
                         "points (e.g. verts or evecs) for the nearest-neighbour fallback")
    from scipy.spatial import cKDTree

    pts = np.asarray(torch.as_tensor(points).detach().cpu(), dtype=np.float64)
    if pts.ndim != 2 or pts.shape[0] != V:
        raise ValueError(f"points must be [V, D] = [{V}, D], got {list(pts.shape)}")
    rows = []
    for row in flat.cpu().numpy():
        _, idx = cKDTree(pts[row]).query(pts)  # idx[j] = i with p2p[i] nearest to j
        rows.append(torch.as_tensor(idx, dtype=torch.long))
    return torch.stack(rows).to(p2p.device).reshape(p2p.shape)


def _rel_dist(A: Tensor, B: Tensor) -> Tensor:
    """[N, M] relative Frobenius distances ``||A_n - B_m||_F / ||B_m||_F``; A [N,K,K], B [M,K,K]."""
    a, b = A.reshape(A.shape[0], -1), B.reshape(B.shape[0], -1)
    # Not the matrix-product expansion: it loses the small distances that decide "same element".
    d = torch.cdist(a[None], b[None], compute_mode="donot_use_mm_for_euclid_dist")[0]
    return d / b.norm(dim=-1).clamp_min(torch.finfo(b.dtype).tiny)[None]


# ---------------------------------------------------------------------------------- group tables
class Cayley(NamedTuple):
    """Group table and its residuals.

    Attributes:
        table: [G, G] long, ``table[a, b]`` = index of ``a ∘ b`` (-1 where none is within tol).
        residual: [G, G] relative distance from ``fmaps[b] @ fmaps[a]`` to its nearest element.
    """

    table: Tensor
    residual: Tensor


def cayley_table(fmaps: Tensor, tol: float | None = None) -> Cayley:
    """Group table of a set of symmetry matrices (paper §5).

    ``table[a, b]`` is the index of the element nearest to ``fmaps[b] @ fmaps[a]``, the matrix of
    ``a ∘ b`` = "apply b, then a": row ``a`` is applied last. The paper's Table 3 is ``table.mT``
    (its caption reads entry (i, j) as "g_i, then g_j"); see the module note.

    Args:
        fmaps: [G, K, K] symmetry matrices.
        tol: if given, products farther than ``tol`` (relative Frobenius) from every element get -1,
            so that ``check_group`` reports the set as not closed. None: always the nearest.

    Returns:
        Cayley(table [G, G] long, residual [G, G] relative distances).
    """
    fmaps = _check_fmaps(fmaps)
    G, K = fmaps.shape[0], fmaps.shape[-1]
    table = torch.empty(G, G, dtype=torch.long, device=fmaps.device)
    residual = torch.empty(G, G, dtype=fmaps.dtype, device=fmaps.device)
    rows = max(1, (1 << 24) // max(G * K * K, 1))  # bound the [rows, G, K, K] product tensor
    for lo in range(0, G, rows):
        a = fmaps[lo:lo + rows]
        prod = fmaps[None, :] @ a[:, None]  # [a, b] = fmaps[b] @ fmaps[a]: "apply b, then a"
        res, idx = _rel_dist(prod.reshape(-1, K, K), fmaps).min(-1)
        table[lo:lo + rows], residual[lo:lo + rows] = idx.view(-1, G), res.view(-1, G)
    if tol is not None:
        table[residual > tol] = -1
        if G > 1:
            d = _rel_dist(fmaps, fmaps) + torch.eye(G, dtype=fmaps.dtype, device=fmaps.device) * 1e30
            if bool((d < tol).any()):
                warnings.warn(f"some elements are within tol={tol} of each other: duplicates make "
                              "the table ambiguous", stacklevel=2)
    return Cayley(table, residual)


def identity_index(x: Tensor, tol: float = DEFAULT_TOL) -> int:
    """Index of the identity element.

    Args:
        x: [G, K, K] symmetry matrices (the one nearest to ``I``; warns if farther than ``tol``)
            or a [G, G] integer table (the ``e`` with ``table[e, b] = table[b, e] = b``; -1 if
            none).
        tol: relative distance to ``I`` accepted for matrices.

    Returns:
        int.
    """
    if _is_table(x):
        T = _check_table(x)
        ar = torch.arange(T.shape[0], device=T.device)
        ok = ((T == ar[None]).all(1) & (T == ar[:, None]).all(0)).nonzero()
        return int(ok[0]) if len(ok) else -1
    fmaps = _check_fmaps(x)
    eye = torch.eye(fmaps.shape[-1], dtype=fmaps.dtype, device=fmaps.device)
    d = _rel_dist(fmaps, eye[None])[:, 0]
    e = int(d.argmin())
    if float(d[e]) > tol:
        warnings.warn(f"no element is within tol={tol} of the identity (nearest: "
                      f"{float(d[e]):.3f}, index {e})", stacklevel=2)
    return e


def _orders_np(T: np.ndarray, e: int) -> np.ndarray:
    """[G] orders from a table (0 where a power leaves the set before reaching e)."""
    G = T.shape[0]
    ar = np.arange(G)
    orders = np.zeros(G, dtype=np.int64)
    cur = ar.copy()  # a^n
    for n in range(1, G + 1):
        orders[(orders == 0) & (cur == e)] = n
        if (orders > 0).all():
            break
        cur = np.where(cur >= 0, T[np.maximum(cur, 0), ar], -1)  # a^(n+1) = a^n ∘ a
    return orders


def element_orders(x: Tensor, *, tol: float = DEFAULT_TOL, max_order: int = 120) -> Tensor:
    """Order of each element: the smallest n with ``g^n = e``.

    Args:
        x: [G, G] integer table, or [..., K, K] symmetry matrices (smallest n with
            ``||Q^n - I||_F / sqrt(K) < tol``, Q the nearest orthogonal matrix to C). The error of
            ``Q^n`` grows about n times that of Q, so for noisy matrices of high order prefer the
            table, which only compares each product with the set.
        tol: identity tolerance for matrices.
        max_order: largest power tried for matrices.

    Returns:
        [G] (or [...]) long; 0 where no finite order was found (within ``max_order``, or inside
        the set for a table).

    Raises:
        ValueError: a table without an identity element.
    """
    if _is_table(x):
        T = _check_table(x)
        e = identity_index(T)
        if e < 0:
            raise ValueError("table has no identity element: orders are undefined")
        return torch.as_tensor(_orders_np(T.cpu().numpy(), e), device=T.device)
    # Powers of a non-orthogonal C drift in norm; its nearest orthogonal matrix only in angle.
    C = nearest_orthogonal(_check_fmaps(x, "x", batched=False))
    K = C.shape[-1]
    eye = torch.eye(K, dtype=C.dtype, device=C.device)
    orders = torch.zeros(C.shape[:-2], dtype=torch.long, device=C.device)
    P = C
    for n in range(1, max_order + 1):
        hit = (orders == 0) & ((P - eye).flatten(-2).norm(dim=-1) / math.sqrt(K) < tol)
        orders[hit] = n
        if bool((orders > 0).all()):
            break
        P = P @ C
    return orders


def inverses(table: Tensor) -> Tensor:
    """[G] long: ``inv[a]`` = the b with ``table[a, b] = table[b, a] = e``; -1 where none.

    Raises:
        ValueError: the table has no identity element.
    """
    T = _check_table(table)
    e = identity_index(T)
    if e < 0:
        raise ValueError("table has no identity element: inverses are undefined")
    ok = (T == e) & (T.mT == e)
    first = ok.int().argmax(1)
    return torch.where(ok.any(1), first, torch.full_like(first, -1))


@dataclass(frozen=True)
class GroupCheck:
    """Which group axioms a table satisfies; ``problems`` says where it fails, in words."""

    is_group: bool
    closed: bool
    has_identity: bool
    has_inverses: bool
    associative: bool
    problems: list[str] = field(default_factory=list)

    def __str__(self) -> str:
        return "group" if self.is_group else "not a group: " + "; ".join(self.problems)


def check_group(table: Tensor, residual: Tensor | None = None, max_report: int = 5) -> GroupCheck:
    """Check the group axioms on a table (``table[a, b]`` = ``a ∘ b``; -1 = product not in the set).

    Args:
        table: [G, G] integer table, e.g. from ``cayley_table(fmaps, tol)``.
        residual: [G, G] optional, quoted in the report of products that are not in the set.
        max_report: examples quoted per failed axiom.

    Returns:
        GroupCheck(is_group, closed, has_identity, has_inverses, associative, problems).
    """
    T = _check_table(table).cpu().numpy()
    G = T.shape[0]
    problems: list[str] = []
    missing = np.argwhere(T < 0)
    closed = len(missing) == 0
    if not closed:
        ex = []
        for a, b in missing[:max_report]:
            r = f" (nearest at {float(residual[a, b]):.3f})" if residual is not None else ""
            ex.append(f"{a}∘{b}{r}")
        problems.append(f"not closed: {len(missing)} of {G * G} products are not in the set, e.g. "
                        + ", ".join(ex) + " (a∘b = apply b, then a)")
    e = identity_index(torch.as_tensor(T))
    has_identity = e >= 0
    has_inverses = False
    if not has_identity:
        problems.append("no identity element (no e with e∘b = b∘e = b for all b)")
    else:
        inv = inverses(torch.as_tensor(T)).numpy()
        has_inverses = bool((inv >= 0).all())
        if not has_inverses:
            lost = np.flatnonzero(inv < 0)[:max_report].tolist()
            problems.append(f"no inverse for elements {lost}")
    # Associativity (a∘b)∘c = a∘(b∘c) over every triple whose products are in the set.
    n_bad, bad = 0, []
    for a in range(G):  # one [G, G] slab per a keeps memory at G^2
        ab, abc = T[a], T[a][np.maximum(T, 0)]           # a∘b [b];  a∘(b∘c) [b, c]
        left = np.where(ab[:, None] >= 0, T[np.maximum(ab, 0)], -1)  # (a∘b)∘c [b, c]
        right = np.where(T >= 0, abc, -1)
        hits = np.argwhere((left >= 0) & (right >= 0) & (left != right))
        n_bad += len(hits)
        bad += [(a, int(b), int(c)) for b, c in hits[:max_report - len(bad)]]
    associative = n_bad == 0
    if not associative:
        problems.append(f"not associative on {n_bad} triples, e.g. "
                        + ", ".join(f"({a}∘{b})∘{c} ≠ {a}∘({b}∘{c})" for a, b, c in bad))
    # A group table is a Latin square; say where it is not (nearest matching can merge products).
    for axis, what in ((1, "row"), (0, "column")):
        dup = [i for i in range(G) if len(np.unique(np.take(T, i, axis=1 - axis))) < G]
        if dup:
            problems.append(f"{what}s {dup[:max_report]} repeat an element (not a Latin square)")
    is_group = closed and has_identity and has_inverses and associative
    return GroupCheck(is_group, closed, has_identity, has_inverses, associative, problems)


class Closure(NamedTuple):
    """``fmaps [G', K, K]`` (the input first, then what was added), ``added [G']`` bool, and
    ``converged`` (False when ``max_order`` stopped the growth)."""

    fmaps: Tensor
    added: Tensor
    converged: bool


def closure(fmaps: Tensor, tol: float = DEFAULT_TOL, max_order: int = 240) -> Closure:
    """Close a set of symmetry matrices under composition (ALGORITHM §5 step 5).

    Breadth-first over the Cayley graph: each round composes the newest elements with every input
    element, projects each product to the nearest orthogonal matrix (SVD polar factor, which keeps
    the block-diagonal structure), and adds the products farther than ``tol`` from everything
    present (and from each other), until a round adds nothing. For a finite group the products of
    the inputs are the whole generated group, identity included.

    Args:
        fmaps: [G, K, K] symmetry matrices (left unchanged at the front of the output).
        tol: relative Frobenius distance under which a product counts as already present.
        max_order: stop (and warn) once the set exceeds this size: a continuous symmetry, or a
            ``tol`` tighter than the noise of the matrices, makes the set grow without bound.

    Returns:
        Closure(fmaps [G', K, K], added [G'] bool, converged).
    """
    fmaps = _check_fmaps(fmaps)
    G, K = fmaps.shape[0], fmaps.shape[-1]
    gens = nearest_orthogonal(fmaps)
    cur, frontier, converged = fmaps, gens, True
    while len(frontier):
        cand = (frontier[:, None] @ gens[None, :]).reshape(-1, K, K)  # C_x @ C_s: "x, then s"
        cand = nearest_orthogonal(cand)
        cand = cand[_rel_dist(cand, cur).min(-1).values > tol]
        keep: list[int] = []
        if len(cand):
            d = _rel_dist(cand, cand).cpu().numpy()
            for i in range(len(cand)):  # greedy: the first of each cluster of near-equal products
                if not keep or d[i, keep].min() > tol:
                    keep.append(i)
        frontier = cand[keep]
        cur = torch.cat([cur, frontier])
        if len(cur) > max_order:
            converged = False
            warnings.warn(f"closure exceeded max_order={max_order} elements: continuous "
                          f"symmetry, or tol={tol} below the noise of the matrices", stacklevel=2)
            break
    added = torch.zeros(len(cur), dtype=torch.bool, device=fmaps.device)
    added[G:] = True
    if len(cur) > G:
        log.info("closure added %d elements to %d (indices %d..%d)", len(cur) - G, G, G,
                 len(cur) - 1)
    return Closure(cur, added, converged)


# ---------------------------------------------------------------------------------- subgroups
def _subtable(T: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Table of the subgroup on ``idx`` (renumbered 0..len-1)."""
    lookup = np.full(T.shape[0], -1)
    lookup[idx] = np.arange(len(idx))
    sub = lookup[T[np.ix_(idx, idx)]]
    if (sub < 0).any():
        raise ValueError("elements do not form a subgroup")
    return sub


def _generated(T: np.ndarray, gens: list[int], e: int) -> np.ndarray:
    """[G] bool: the subgroup generated by ``gens`` (finite group: right multiples suffice)."""
    inside = np.zeros(T.shape[0], dtype=bool)
    inside[e] = True
    frontier = [e]
    while frontier:
        nxt = np.unique(T[np.asarray(frontier)][:, gens])
        nxt = nxt[~inside[nxt]]
        inside[nxt] = True
        frontier = nxt.tolist()
    return inside


def _z2_homs(T: np.ndarray, e: int) -> list[np.ndarray]:
    """Every nontrivial homomorphism onto Z2 as a [G] bool mask (True = odd); kernel = index 2."""
    G = T.shape[0]
    gens: list[int] = []
    inside = _generated(T, gens, e)
    while not inside.all():
        gens.append(int(np.flatnonzero(~inside)[0]))
        inside = _generated(T, gens, e)
    homs = []
    for bits in range(1, 2 ** len(gens)):
        val = {g: bool(bits >> i & 1) for i, g in enumerate(gens)}
        phi = np.full(G, -1)
        phi[e] = 0
        queue, consistent = [e], True
        while queue and consistent:
            a = queue.pop()
            for g in gens:  # phi(a ∘ g) = phi(a) + phi(g) on every edge of the Cayley graph
                b, v = T[a, g], phi[a] ^ val[g]
                if phi[b] < 0:
                    phi[b] = v
                    queue.append(b)
                elif phi[b] != v:
                    consistent = False
                    break
        if consistent:
            homs.append(phi.astype(bool))
    return homs
