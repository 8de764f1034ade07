"""What a group is called and what its elements are: structure, Schoenflies names, orientation.

A finite group of intrinsic symmetries is named from its table (``groups.algebra``) and from which
elements reverse the orientation of the surface (:func:`orientation_score`): the rotations form a
subgroup of index 1 or 2, and the name says which (``C_n``, ``D_n``, ``T``, ``O``, ``I``) and how the
reversing coset sits beside it (``C_nv``, ``C_nh``, ``D_nh``, ...). :func:`group_info` gathers table,
inverses, orders, orientation and name in one :class:`GroupInfo`.

Note:
    Orientation is intrinsic: an element "reverses" when it flips the orientation of the surface
    (``orientation_reversing``). A reversing element of order 2 is a *reflection*, of higher order a
    *rotoreflection*; a preserving element other than the identity is a *rotation* (:func:`kind_of`).
"""
from __future__ import annotations

import warnings
from collections import Counter
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import Tensor

from ..orientation import vertex_normals
from ..units import mean_edge
from .algebra import (_check_p2p, _check_reversing, _check_table, _generated, _is_table, _orders_np,
                      _subtable, _z2_homs, cayley_table, check_group, element_orders, identity_index,
                      inverses)

__all__ = ["abstract_group", "identify_group", "kind_of", "fixes_points", "orientation_score", "orientation_reversing",
           "GroupInfo", "group_info"]


# ----------------------------------------------------------------------------------- group names
def _structure(T: np.ndarray) -> tuple:
    G = T.shape[0]
    e = int(np.flatnonzero((T == np.arange(G)[None]).all(1))[0])
    orders = _orders_np(T, e)
    if orders.max() == G:
        return ("cyclic", G)
    if G % 2 == 0 and G >= 4:  # D_n: a cyclic subgroup of index 2 and involutions everywhere else
        n = G // 2
        for r in np.flatnonzero(orders == n):
            rot = _generated(T, [int(r)], e)
            if (orders[~rot] == 2).all():
                return ("dihedral", n)
    counts = Counter(orders.tolist())
    # Polyhedral rotation groups are fixed by their element-order statistics at these orders.
    if G == 12 and counts[3] == 8:
        return ("alternating", 4)
    if G == 24 and counts == Counter({1: 1, 2: 9, 3: 8, 4: 6}):
        return ("symmetric", 4)
    if G == 60 and counts[5] == 24:
        return ("alternating", 5)
    if G % 2 == 0:  # K × Z2: a central involution outside an index-2 subgroup K
        central = (T == T.T).all(1) & (orders == 2)
        best = None
        for phi in _z2_homs(T, e):
            if (central & phi).any():
                inner = _structure(_subtable(T, np.flatnonzero(~phi)))
                best = ("direct", inner, ("cyclic", 2))
                if inner[0] != "unknown":
                    break
        if best is not None:
            return best
    return ("unknown", G)


def _group_np(table: Tensor) -> np.ndarray:
    T = _check_table(table)
    check = check_group(T)
    if not check.is_group:
        raise ValueError(f"table is {check}")
    return T.cpu().numpy()


def abstract_group(table: Tensor) -> tuple:
    """Abstract structure of a group from its table.

    Returns one of ``("cyclic", n)`` (Z_n; n = 1 is the trivial group), ``("dihedral", n)`` (D_n of
    order 2n; n = 2 is the Klein four-group), ``("alternating", 4)``, ``("symmetric", 4)``,
    ``("alternating", 5)`` (the rotation groups T, O, I), ``("direct", inner, ("cyclic", 2))``
    (inner × Z2), or ``("unknown", G)``. The first match in that order wins, so D_n × Z2 with n odd
    reads ``("dihedral", 2n)`` and Z_n × Z2 with n odd reads ``("cyclic", 2n)``.

    Raises:
        ValueError: the table is not a group (with the problems found).
    """
    return _structure(_group_np(table))


def _fallback(G: int) -> str:
    return f"order-{G} group"


def identify_group(table: Tensor, reversing: Tensor, fixes: Tensor | None = None) -> str:
    """Schoenflies name of a symmetry group, from its table and which elements reverse orientation.

    The orientation-preserving elements H (rotations) form a subgroup of index 1 or 2. With no
    reversing element the name is that of H: ``C1``, ``Cn``, ``Dn``, ``T``, ``O``, ``I``. Otherwise:

    - H trivial: ``Cs`` (one reflection; intrinsically a reversing involution is a reflection, so a
      point inversion ``Ci`` is also reported as ``Cs``);
    - H = C_n: ``Cnv`` when every reversing element is a reflection (G ≅ D_n), else ``Cnh`` when a
      central reflection exists (G = C_n × σh), else ``S2n`` when G is cyclic;
    - H = D_n: ``Dnh`` when a central reflection exists, else ``Dnd`` when G ≅ D_2n;
    - H = T: ``Th`` (central reflection) or ``Td`` (G ≅ S4); H = O: ``Oh``; H = I: ``Ih``;
    - anything else: ``"order-G group"``.

    Note:
        A table with orientation flags cannot tell apart Cs / Ci, C2v / C2h, Cnh / S2n for odd n,
        and Dnh / Dnd for odd n (same abstract group, same reversing coset); without ``fixes`` the
        first of each pair is returned. An orientation-reversing involution of a closed surface
        either fixes a curve (a mirror) or no point at all (the point inversion of a centrally
        symmetric shape, intrinsically too): ``fixes`` tells them apart. Then ``Ci`` is the
        inversion alone, ``C2h`` is ``C2`` with an inversion, and for odd n the central reversing
        involution is ``σh`` (``Cnh``, ``Dnh``) where it fixes a curve and the inversion (``S2n``,
        ``Dnd``) where it does not.

    Args:
        table: [G, G] group table (``table[a, b]`` = ``a ∘ b``).
        reversing: [G] bool, True for orientation-reversing elements (``orientation_reversing``).
        fixes: optional [G] bool, whether each element's map fixes some point (``fixes_points``);
            read for the reversing involutions only.

    Returns:
        The name, e.g. ``"D5h"``.

    Raises:
        ValueError: the table is not a group.
    """
    T = _group_np(table)
    G = T.shape[0]
    rev = _check_reversing(reversing, G)
    e = int(np.flatnonzero((T == np.arange(G)[None]).all(1))[0])
    # Orientation is a homomorphism onto Z2: rev(a ∘ b) = rev(a) xor rev(b), rev(e) = False.
    if rev[e] or (rev[T] != (rev[:, None] ^ rev[None, :])).any():
        warnings.warn("reversing flags are inconsistent with the table (rev(a∘b) ≠ rev(a) xor "
                      "rev(b), or the identity reverses); cannot name the group", stacklevel=2)
        return _fallback(G)
    H = np.flatnonzero(~rev)
    sH = _structure(_subtable(T, H))
    if not rev.any():
        if sH[0] == "cyclic":
            return f"C{sH[1]}"
        if sH[0] == "dihedral":
            return f"D{sH[1]}"
        return {("alternating", 4): "T", ("symmetric", 4): "O", ("alternating", 5): "I"}.get(
            sH, _fallback(G))
    fix = np.ones(G, dtype=bool) if fixes is None else np.asarray(torch.as_tensor(fixes).cpu(), dtype=bool)
    if fix.shape != (G,):
        raise ValueError(f"fixes must be [G] = [{G}] bools, got {list(fix.shape)}")
    if len(H) == 1:
        return "Cs" if fix[rev].all() else "Ci"
    orders = _orders_np(T, e)
    central = (T == T.T).all(1)
    central_rev = central & rev & (orders == 2)
    has_central = bool(central_rev.any())
    has_sigma_h = bool((central_rev & fix).any())
    sG = _structure(T)
    if sH[0] == "cyclic":
        n = sH[1]
        if (orders[rev] == 2).all():
            return f"C{n}v" if fix[rev].all() else f"C{n}h"  # C2h: C2, sigma_h and the inversion
        if has_sigma_h:
            return f"C{n}h"
        if sG == ("cyclic", G):
            return f"S{2 * n}"
    elif sH[0] == "dihedral":
        n = sH[1]
        if has_sigma_h:
            return f"D{n}h"
        if sG == ("dihedral", 2 * n) or (has_central and n % 2 == 1):
            return f"D{n}d"
    elif sH == ("alternating", 4):
        if has_central:  # the inversion
            return "Th"
        if sG == ("symmetric", 4):
            return "Td"
    elif sH == ("symmetric", 4) and has_central:
        return "Oh"
    elif sH == ("alternating", 5) and has_central:
        return "Ih"
    return _fallback(G)


def kind_of(order: int, reversing: bool) -> str:
    """``'identity'`` (order 1), ``'reflection'`` (reversing, order 2), ``'rotation'`` (preserving),
    or ``'rotoreflection'`` (reversing, order > 2 or unknown = 0).

    Raises:
        ValueError: a negative order, or a reversing element of order 1.
    """
    order, reversing = int(order), bool(reversing)
    if order < 0:
        raise ValueError(f"order must be >= 0 (0 = unknown), got {order}")
    if order == 1:
        if reversing:
            raise ValueError("an element of order 1 is the identity and cannot reverse orientation")
        return "identity"
    if reversing:
        return "reflection" if order == 2 else "rotoreflection"
    return "rotation"


# ----------------------------------------------------------------------------------- orientation
def orientation_score(p2p: Tensor, verts: Tensor, faces: Tensor, *,
                      max_stretch: float = 3.0) -> Tensor:
    """Area-weighted vote in [-1, 1]: +1 for a map that keeps the surface orientation, -1 for one
    that flips it (a reflection).

    For each face ``(a, b, c)`` the image triangle ``(p2p[a], p2p[b], p2p[c])``, placed at
    ``verts[p2p]``, is compared with the mesh's own orientation there: the sign of the dot product
    of its normal with the sum of the vertex normals at its corners. Only local quantities enter,
    so it works for intrinsic (non-rigid) symmetries. Faces whose image collapses (repeated vertex,
    zero area) or is not local (an image edge longer than ``max_stretch`` times the face's longest
    edge) do not vote.

    Args:
        p2p: [..., V] vertex maps.
        verts: [V, 3] vertex positions.
        faces: [F, 3] triangles, consistently oriented.
        max_stretch: locality bound for a vote.

    Returns:
        [...] scores in the dtype of ``verts`` (0 where no face could vote).
    """
    verts = torch.as_tensor(verts)
    if verts.ndim != 2 or verts.shape[1] != 3 or not verts.is_floating_point():
        raise ValueError(f"verts must be [V, 3] floats, got {list(verts.shape)} {verts.dtype}")
    faces = torch.as_tensor(faces, device=verts.device)
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.is_floating_point():
        raise ValueError(f"faces must be [F, 3] long, got {list(faces.shape)} {faces.dtype}")
    faces = faces.long()
    V = verts.shape[0]
    p2p = _check_p2p(p2p, n_verts=V).to(verts.device)
    if p2p.shape[-1] != V:
        raise ValueError(f"p2p must be [..., V] = [..., {V}], got {list(p2p.shape)}")
    x = verts
    fn = torch.linalg.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])  # [F, 3]
    vn = vertex_normals(x, faces, unit=False)  # [V, 3]
    src_edge = (x[faces] - x[faces.roll(1, -1)]).norm(dim=-1).amax(-1)  # [F]
    img = p2p[..., faces]                                                 # [..., F, 3]
    y = x[img]                                                            # [..., F, 3, 3]
    n_img = torch.linalg.cross(y[..., 1, :] - y[..., 0, :], y[..., 2, :] - y[..., 0, :])
    vote = torch.sign((n_img * vn[img].sum(-2)).sum(-1))                  # [..., F]
    img_edge = (y - y.roll(1, -2)).norm(dim=-1).amax(-1)                  # [..., F]
    distinct = (img != img.roll(1, -1)).all(-1)                           # no repeated vertex
    # 1e-12: a numerically flat image triangle has no orientation
    valid = distinct & (img_edge <= max_stretch * src_edge) \
        & (n_img.norm(dim=-1) > 1e-12 * src_edge.square())
    w = fn.norm(dim=-1) * valid  # face area (x2) weights
    return (w * vote).sum(-1) / w.sum(-1).clamp_min(torch.finfo(w.dtype).tiny)


def fixes_points(p2p: Tensor, verts: Tensor, faces: Tensor, *, edges: float = 2.0) -> Tensor:
    """Whether each vertex map fixes a point: some vertex lands within ``edges`` mean edge lengths
    of itself. A mirror fixes a curve, and its map moves the vertices on it by about an edge; a
    point inversion moves every point by at least the shape's thickness through its centre.

    Args:
        p2p: [..., V] vertex maps; verts: [V, 3]; faces: [F, 3].

    Returns:
        [...] bool.
    """
    verts = torch.as_tensor(verts)
    p2p = _check_p2p(p2p, n_verts=verts.shape[0]).to(verts.device)
    return (verts[p2p] - verts).norm(dim=-1).amin(-1) < edges * mean_edge(verts.cpu(), torch.as_tensor(faces).cpu())


def orientation_reversing(p2p: Tensor, verts: Tensor, faces: Tensor, *, max_stretch: float = 3.0) -> bool:
    """Whether a vertex map reverses the surface orientation (``orientation_score < 0``).

    Warns when the vote is weak (|score| < 0.2: a very noisy map, or no face could vote); use
    :func:`orientation_score` for the vote itself.

    Args:
        p2p: [V] vertex map.
        verts: [V, 3]; faces: [F, 3] consistently oriented.
        max_stretch: see ``orientation_score``.
    """
    p2p = _check_p2p(p2p)
    if p2p.ndim != 1:
        raise ValueError(f"p2p must be [V] (orientation_score takes a batch), got "
                         f"{list(p2p.shape)}")
    score = float(orientation_score(p2p, verts, faces, max_stretch=max_stretch))
    if abs(score) < 0.2:
        warnings.warn(f"orientation vote is ambiguous (score {score:+.2f})", stacklevel=2)
    return score < 0


# ---------------------------------------------------------------------------------------- summary
@dataclass(frozen=True)
class GroupInfo:
    """A symmetry group, described.

    Attributes:
        name: Schoenflies name (``identify_group``), e.g. ``"D5h"``.
        order: G.
        table: [G, G] long, ``table[a, b]`` = index of ``a ∘ b`` ("apply b, then a").
        inverses: [G] long.
        orders: [G] long.
        reversing: [G] bool, orientation-reversing elements.
        identity: index of the identity.
        abstract: ``abstract_group(table)``.
        residual: [G, G] Cayley residuals when built from matrices, else None.
    """

    name: str
    order: int
    table: Tensor
    inverses: Tensor
    orders: Tensor
    reversing: Tensor
    identity: int
    abstract: tuple
    residual: Tensor | None = None

    def to(self, device: torch.device | str) -> GroupInfo:
        """The report with its tensors on ``device``."""
        move = {k: getattr(self, k).to(device) for k in ("table", "inverses", "orders", "reversing")}
        if self.residual is not None:
            move["residual"] = self.residual.to(device)
        return replace(self, **move)

    @property
    def kinds(self) -> list[str]:
        """``kind_of`` each element."""
        return [kind_of(o, r) for o, r in zip(self.orders.tolist(), self.reversing.tolist())]

    def to_dict(self) -> dict:
        """JSON-ready dict (lists and plain numbers)."""
        def plain(t):
            return [plain(x) for x in t] if isinstance(t, (tuple, list)) else t

        out = dict(name=self.name, order=self.order, abstract=plain(self.abstract),
                   identity=self.identity, table=self.table.tolist(),
                   inverses=self.inverses.tolist(), orders=self.orders.tolist(),
                   reversing=self.reversing.tolist(), kinds=self.kinds,
                   table_convention="table[a][b] = a∘b (apply b, then a)")
        if self.residual is not None:
            out["max_residual"] = float(self.residual.max())
        return out


def group_info(x: Tensor, reversing: Tensor, *, tol: float | None = None,
               fixes: Tensor | None = None) -> GroupInfo:
    """Table, inverses, orders, structure and name of a symmetry group.

    Args:
        x: [G, K, K] symmetry matrices (tabled by ``cayley_table(x, tol)``) or a [G, G] table.
        reversing: [G] bool orientation flags.
        tol: see ``cayley_table``.
        fixes: optional [G] bool, whether each map fixes a point (:func:`identify_group`).

    Returns:
        GroupInfo.

    Raises:
        ValueError: the table is not a group (run ``closure`` first).
    """
    residual = None
    if _is_table(x):
        table = _check_table(x)
    else:
        table, residual = cayley_table(x, tol)
    G = table.shape[0]
    rev = torch.as_tensor(_check_reversing(reversing, G), device=table.device)
    name = identify_group(table, rev, fixes)
    return GroupInfo(name=name, order=G, table=table, inverses=inverses(table),
                     orders=element_orders(table), reversing=rev, identity=identity_index(table),
                     abstract=abstract_group(table), residual=residual)
