"""Symmetry augmentation that never damages a mesh, and symmetry ground truth without detection.

A symmetry g of a shape X (``sym_p2p[g]``, ``p2p[i]`` the image of vertex i) can augment a training
sample in two ways, neither of which touches the triangulation's connectivity:

- ``"relabel"``: the shape stays as it is and its *ground truth* moves: the template point that was at
  vertex ``corr[k]`` is now declared to be at ``g(corr[k])``. Intrinsically this is as valid a
  correspondence as the original (an isometry composed with an isometry); for an orientation-reversing
  g it reverses orientation.
- ``"mirror"`` (orientation-reversing g only): the shape becomes its extrinsic mirror image, whose
  orientation is reversed, and the ground truth is composed with g as above. The two reversals cancel:
  the new ground truth preserves orientation, which orientation-aware methods (orientation operators,
  complex functional maps) need.

Moving the vertices instead (``verts' = verts[p2p_g]`` with the old faces) tears the mesh wherever g's
vertex map is not a bijection, which a detected or remeshed map never is; both modes avoid it.

:class:`SymmetryFromCorrespondence` builds the reflection from the symmetric ground truth of a dataset
(``corr`` / ``corr_sym``, the BCICP ``.sym.vts`` layout), for training on real symmetries without
running the detector.
"""
from __future__ import annotations

import torch
from torch import Tensor

from .transforms import INDEX_FIELDS, _require, _store_symmetries

__all__ = ["AUGMENT_MODES", "DENSE_METHODS", "apply_symmetry", "mirror_shape", "RandomSymmetry",
           "SymmetryFromCorrespondence", "dense_map_from_pairs", "one_rings", "reflection_index"]

#: The ways :func:`apply_symmetry` can use a symmetry.
AUGMENT_MODES = ("relabel", "mirror")
#: Keys that change sign when the surface orientation is reversed (orientation operators,
#: ``[D, K, K]``: they act on functions through ``n x grad``).
ORIENTED_FIELDS = ("orient_op",)
#: Keys of complex tangent-frame operators stored as (real, imaginary) columns (DiffusionNet's
#: ``grad_val [nnz, 2]``, :mod:`symtorch.backbone`): the mirror image has the complex conjugate.
CONJUGATED_FIELDS = ("grad_val",)


def _map_ids(ids: Tensor, p2p: Tensor) -> Tensor:
    """Send vertex ids through ``p2p``, keeping -1 (no vertex) as is."""
    return torch.where(ids >= 0, p2p[ids.clamp_min(0)], ids)


def _check_axis(axis: int) -> int:
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2 (the coordinate negated), got {axis!r}")
    return int(axis)


def mirror_shape(sample: dict, axis: int = 0) -> dict:
    """The extrinsic mirror image of a shape, still oriented outward.

    - ``verts``: coordinate ``axis`` negated (the reflection ``M = diag(..., -1, ...)``);
    - ``faces``: winding reversed (``[i, j, k] -> [i, k, j]``). A reflection reverses orientation, so
      without this an outward-oriented mesh would come out inward-oriented (negative signed volume);
    - ``normals``: ``M @ n``, the mirror image of each normal, which is the outward normal of the
      mirrored surface with the reversed winding (``cross(M a, M b) = -M cross(a, b)``, and reversing
      the winding negates once more);
    - ``orient_op`` (``ORIENTED_FIELDS``): negated, since orientation operators depend on the sign of
      the surface orientation;
    - ``grad_val`` (``CONJUGATED_FIELDS``, DiffusionNet's tangent-frame gradient): conjugated, the
      operator of the mirrored surface in mirrored frames (frame axis ``Y = n x X`` flips);
    - everything intrinsic (``mass``, ``evals``, ``evecs``, ``bands``, descriptors, ``sym_p2p``,
      ``sym_fmap``, ground truth) unchanged: a reflection of space is an isometry of the surface, and
      the vertex labels do not change.

    Args:
        sample: with ``verts [V, 3]`` and optionally ``faces [F, 3]``, ``normals [V, 3]``.
        axis: the coordinate negated (0: x).

    Returns:
        a new sample.
    """
    axis = _check_axis(axis)
    _require(sample, ("verts",), "mirror_shape", "vertex positions")
    out = dict(sample)
    for key in sample.keys() & {"verts", "normals"}:
        x = sample[key].clone()
        x[:, axis] = -x[:, axis]
        out[key] = x
    if "faces" in sample:
        out["faces"] = sample["faces"][:, [0, 2, 1]]
    for key in sample.keys() & set(ORIENTED_FIELDS):
        out[key] = -sample[key]
    for key in sample.keys() & set(CONJUGATED_FIELDS):
        out[key] = sample[key] * torch.tensor([1.0, -1.0], dtype=sample[key].dtype)
    return out


def reflection_index(sample: dict) -> int | None:
    """The index in ``sym_p2p`` of the sample's first orientation-reversing symmetry
    (``sym_reverses``), or None where it has none."""
    rev = sample.get("sym_reverses")
    if rev is None:
        return None
    idx = torch.nonzero(torch.as_tensor(rev)).flatten()
    return int(idx[0]) if len(idx) else None


def _reverses(sample: dict, who: str) -> Tensor:
    _require(sample, ("sym_reverses",), who,
             "DetectSymmetries, SetSymmetries and SymmetryFromCorrespondence write it; a cache made "
             "before it existed needs force_reload=True")
    return sample["sym_reverses"]


def apply_symmetry(sample: dict, index: int, mode: str = "relabel", axis: int = 0) -> dict:
    """Augment a sample by one of its symmetries g (``sym_p2p[index]``) without changing its mesh.

    Both modes compose the ground truth with g: ``corr' = sym_p2p[g][corr]`` and
    ``corr_sym' = sym_p2p[g][corr_sym]`` (``INDEX_FIELDS``; -1 stays -1). The template point k is now
    the image under g of the vertex it was at. A :class:`~symtorch.data.PairDataset` builds ``p2p_yx``
    and ``fmap_xy`` from ``corr`` after each shape's transform, so the pair's functional-map ground
    truth follows. For the reflection of exact ground truth, ``g(corr[k]) = corr_sym[k]``: the
    augmented ``corr`` is the old ``corr_sym`` and vice versa.

    - ``mode="relabel"`` (any element): nothing else changes. ``verts``, ``faces``, ``normals``,
      ``mass``, ``evals``, ``evecs``, descriptors and orientation operators stay exactly as they are.
      The group needs no conjugation either: the shape and its vertex ids did not move, so every
      ``sym_p2p[h]`` is still a symmetry of this mesh and ``sym_fmap[h]`` its matrix in this basis.
      (Seen from the template, the element that plays the role of template symmetry s becomes
      ``g h g^-1``; for an abelian group, C2 included, that is ``h`` itself.) With an
      orientation-reversing g the new ground truth reverses orientation.
    - ``mode="mirror"`` (orientation-reversing g only, ``sym_reverses[index]``): the shape also becomes
      its extrinsic mirror image, :func:`mirror_shape` (coordinate ``axis`` negated, faces rewound,
      ``normals`` mirrored, ``orient_op`` negated; intrinsic fields, ``sym_p2p`` and ``sym_fmap``
      unchanged: a symmetry of X is a symmetry of its mirror image). A left/right reflection g makes
      the old right hand the mirrored shape's left hand, so the composed ground truth is orientation
      preserving, as the original was.

    Args:
        sample: with ``sym_p2p [G, V]`` (and ``sym_reverses [G]`` for ``mode="mirror"``).
        index: the group element, ``0 <= index < G``.
        mode: ``"relabel"`` or ``"mirror"``.
        axis: coordinate negated by ``mode="mirror"``.

    Returns:
        a new sample.

    Raises:
        ValueError: an index out of range, an unknown mode, or ``mode="mirror"`` with an element that
            preserves orientation (the identity, a rotation).
    """
    _require(sample, ("sym_p2p",), "apply_symmetry", "run DetectSymmetries, SetSymmetries or "
             "SymmetryFromCorrespondence first")
    if mode not in AUGMENT_MODES:
        raise ValueError(f"mode must be one of {AUGMENT_MODES}, got {mode!r}")
    G = sample["sym_p2p"].shape[0]
    if not 0 <= index < G:
        raise ValueError(f"index must be in [0, {G - 1}], got {index}")
    axis = _check_axis(axis)
    if mode == "mirror" and not bool(_reverses(sample, "apply_symmetry(mode='mirror')")[index]):
        raise ValueError(f"mode='mirror' needs an orientation-reversing element, but element {index} "
                         f"preserves orientation (identity or rotation); use mode='relabel'")
    out = mirror_shape(sample, axis) if mode == "mirror" else dict(sample)
    p = sample["sym_p2p"][index]
    for key in INDEX_FIELDS:
        if key in sample:
            out[key] = _map_ids(sample[key], p)
    return out


class RandomSymmetry:
    """Augment by a random element of the shape's symmetry group (uniform, identity included).

    - ``mode="relabel"``: :func:`apply_symmetry` with ``mode="relabel"`` for the drawn element.
    - ``mode="mirror"``: the drawn element is applied with ``mode="mirror"`` when it reverses
      orientation (``sym_reverses``: reflections, rotoreflections) and with ``mode="relabel"`` when it
      does not (identity, rotations), so the ground truth always stays orientation preserving. For a
      C2 shape half of the draws give the mirror image.

    Shapes without ``sym_p2p`` raise; ``mode="mirror"`` also needs ``sym_reverses``.

    Args:
        generator: source of the one draw per call.
        mode: ``"relabel"`` or ``"mirror"``.
        axis: coordinate negated when mirroring.
    """

    def __init__(self, generator: torch.Generator | None = None, *, mode: str = "relabel",
                 axis: int = 0):
        if mode not in AUGMENT_MODES:
            raise ValueError(f"mode must be one of {AUGMENT_MODES}, got {mode!r}")
        self.mode, self.axis, self.generator = mode, _check_axis(axis), generator

    def __call__(self, sample: dict) -> dict:
        _require(sample, ("sym_p2p",), type(self).__name__,
                 "run DetectSymmetries, SetSymmetries or SymmetryFromCorrespondence")
        G = sample["sym_p2p"].shape[0]
        index = int(torch.randint(G, (1,), generator=self.generator))
        mode = "relabel"
        if self.mode == "mirror" and bool(_reverses(sample, type(self).__name__)[index]):
            mode = "mirror"
        return apply_symmetry(sample, index, mode=mode, axis=self.axis)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(mode={self.mode!r}, axis={self.axis})"


#: The ways :func:`dense_map_from_pairs` fills the vertices no pair names.
DENSE_METHODS = ("local", "nearest", "spectral")


def one_rings(faces: Tensor, n_verts: int) -> Tensor:
    """Each vertex and its edge neighbours: ``[V, m]`` long, row i padded with i itself."""
    e = torch.cat([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    self_loops = torch.arange(n_verts, device=faces.device)[:, None].expand(-1, 2)
    e = torch.unique(torch.cat([e, e.flip(1), self_loops]), dim=0)  # sorted by the first column
    counts = torch.bincount(e[:, 0], minlength=n_verts)
    slot = torch.arange(e.shape[0], device=faces.device) - (torch.cumsum(counts, 0) - counts)[e[:, 0]]
    rings = torch.arange(n_verts, device=faces.device)[:, None].repeat(1, int(counts.max()))
    rings[e[:, 0], slot] = e[:, 1]
    return rings


def _first_pairs(src: Tensor, dst: Tensor) -> tuple[Tensor, Tensor]:
    """One pair per source vertex, the first listed (deterministic, unlike an indexed write with
    repeated indices)."""
    uniq, inv = torch.unique(src, return_inverse=True)
    first = torch.full((uniq.numel(),), src.numel(), device=src.device).scatter_reduce_(
        0, inv, torch.arange(src.numel(), device=src.device), "amin")
    return src[first], dst[first]


def dense_map_from_pairs(src: Tensor, dst: Tensor, verts: Tensor, faces: Tensor | None = None, *,
                         method: str = "local", evecs: Tensor | None = None) -> Tensor:
    """A vertex map on every vertex from its values at some vertices (``p2p[src[j]] = dst[j]``).

    Vertices in ``src`` keep their given image (the first one where ``src`` repeats a vertex, so order
    the pairs by priority); the others get one by ``method``:

    - ``"nearest"``: the image of the nearest vertex of ``src`` along the surface (graph-geodesic
      Voronoi cells, :func:`symtorch.geodesics.voronoi_cells`; Euclidean nearest for a point cloud).
      Intrinsic and needs no basis; its error is about the distance to the nearest listed vertex.
    - ``"spectral"``: least-squares functional map ``evecs[src] @ C ≈ evecs[dst]`` from all pairs,
      then the nearest neighbour of ``evecs[i] @ C`` among all rows of ``evecs`` (ALGORITHM §2). Its
      accuracy grows with the basis size, and a small basis confuses distant parts.
    - ``"local"``: ``"nearest"``, then the best match of ``evecs[i] @ C`` (the functional map above)
      within the one-ring of that image: the nearest map decides where, the basis decides which of
      the neighbouring vertices.

    Args:
        src, dst: [N] long vertex ids, ``dst[j]`` the image of ``src[j]``.
        verts: [V, 3]; faces: [F, 3] (None: a point cloud; not for ``"local"``).
        method: ``"local"``, ``"nearest"`` or ``"spectral"``.
        evecs: [V, K] mass-orthonormal basis, for ``"spectral"`` and ``"local"``.

    Returns:
        [V] long, on the device of ``verts``.
    """
    if method not in DENSE_METHODS:
        raise ValueError(f"method must be one of {DENSE_METHODS}, got {method!r}")
    V = verts.shape[0]
    if src.shape != dst.shape or src.dim() != 1 or src.numel() == 0:
        raise ValueError(f"src and dst must be [N] vertex ids of one non-zero length, got "
                         f"{list(src.shape)} and {list(dst.shape)}")
    if int(torch.minimum(src.min(), dst.min())) < 0 or int(torch.maximum(src.max(), dst.max())) >= V:
        raise ValueError(f"src and dst must hold vertex ids in [0, {V - 1}]")
    if method != "nearest" and evecs is None:
        raise ValueError(f"method={method!r} needs evecs (run ComputeSpectrum first)")
    if method == "local" and faces is None:
        raise ValueError("method='local' needs faces (use 'nearest' or 'spectral' for a point cloud)")
    from ..maps import least_squares, nearest_neighbors, nearest_neighbors_among

    device = verts.device
    src_all, dst_all = src.to(device), dst.to(device)
    src, dst = _first_pairs(src_all, dst_all)
    if method in ("spectral", "local"):
        C = least_squares(evecs[src_all], evecs[dst_all])  # [K, K], every pair
        query = evecs @ C                                  # [V, K]
    if method == "spectral":
        p2p = nearest_neighbors(query, evecs)
    elif faces is not None:
        from ..geodesics import voronoi_cells

        cell = voronoi_cells(verts.detach().cpu(), faces.detach().cpu(), src.cpu()).to(device)
        # -1: a vertex in a component no pair reaches keeps itself
        p2p = torch.where(cell >= 0, dst[cell.clamp_min(0)], torch.arange(V, device=device))
    else:
        p2p = dst[nearest_neighbors(verts, verts[src])]
    if method == "local":
        free = torch.ones(V, dtype=torch.bool, device=device)
        free[src] = False
        free = torch.nonzero(free).flatten()
        if free.numel():
            rings = one_rings(faces.to(device), V)
            p2p[free] = nearest_neighbors_among(query[free], evecs, rings, p2p[free])
    p2p = p2p.clone()
    p2p[src] = dst
    return p2p


class SymmetryFromCorrespondence:
    """The identity and the reflection from symmetric ground truth: ``sym_p2p [2, V]``,
    ``sym_reverses = [False, True]`` and ``sym_fmap [2, K, K]`` (when the sample has a spectrum).

    The sample's ``corr`` and ``corr_sym`` (the vertex of template point k and of its mirror image;
    BCICP ``.vts`` / ``.sym.vts``) are symmetric vertex pairs: the reflection sends ``corr[k]`` to
    ``corr_sym[k]`` and, being an involution, ``corr_sym[k]`` to ``corr[k]`` (where a vertex is in
    several pairs, the first ``corr`` entry naming it wins, then the first ``corr_sym`` entry). They
    cover the vertices the template samples landed on, not every vertex, so the map is made dense by
    :func:`dense_map_from_pairs`. ``"local"`` (the nearest paired vertex's image, then the best
    spectral match in its one-ring) is the default: against held-out pairs it is the most accurate
    of the three in a training-size basis (30-60 functions), where a global spectral search confuses
    distant parts and the nearest paired vertex is off by a fraction of an edge
    (``scripts/bench_sym_ground_truth.py`` measures them). ``"nearest"`` needs no basis.

    Args:
        method: ``"local"`` or ``"spectral"`` (both need ``ComputeSpectrum`` first) or ``"nearest"``;
            see :func:`dense_map_from_pairs`.
    """

    def __init__(self, method: str = "local"):
        if method not in DENSE_METHODS:
            raise ValueError(f"method must be one of {DENSE_METHODS}, got {method!r}")
        self.method = method

    def __call__(self, sample: dict) -> dict:
        who = type(self).__name__
        _require(sample, ("verts", "corr", "corr_sym"), who,
                 "symmetric ground truth, e.g. ground_truth='vts' with .sym.vts files")
        if self.method != "nearest":
            _require(sample, ("evecs",), who,
                     f"run ComputeSpectrum first for method={self.method!r}, or use 'nearest'")
        corr, corr_sym = sample["corr"], sample["corr_sym"]
        if corr.shape != corr_sym.shape:
            raise ValueError(f"corr and corr_sym must have one length, got {corr.numel()} and "
                             f"{corr_sym.numel()} in {sample.get('name', '')!r}")
        ok = (corr >= 0) & (corr_sym >= 0)
        if not bool(ok.any()):
            raise ValueError(f"sample {sample.get('name', '')!r} has no symmetric pair")
        src = torch.cat([corr[ok], corr_sym[ok]])  # the given direction first: it wins repeats
        dst = torch.cat([corr_sym[ok], corr[ok]])
        verts = sample["verts"]
        reflection = dense_map_from_pairs(src, dst, verts, sample.get("faces"), method=self.method,
                                          evecs=sample.get("evecs"))
        V = verts.shape[0]
        out = dict(sample)
        out["sym_reverses"] = torch.tensor([False, True], device=verts.device)
        return _store_symmetries(out, torch.stack([torch.arange(V, device=verts.device),
                                                   reflection]))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(method={self.method!r})"
