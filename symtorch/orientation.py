"""Surface orientation: face gradients, orientation operators, and resolving a map's mirror flip.

A map found "up to symmetry" (by a network, or any intrinsic method) may be the true map composed with
a reflection of the shape: both preserve every intrinsic quantity. What tells them apart is the
orientation of the surface. This module measures it in two ways:

- **Orientation operators** (Ren, Poulenard, Wonka, Ovsjanikov, "Continuous and
  orientation-preserving correspondences via functional maps", SIGGRAPH Asia 2018): for a scalar
  descriptor f, the operator ``g -> <n x grad f, grad g> = n . (grad f x grad g)``. An
  orientation-preserving map that sends f to f' commutes with it, ``C_xy O^x_f ≈ O^y_{f'} C_xy``; an
  orientation-reversing one anti-commutes, ``C_xy O^x_f ≈ -O^y_{f'} C_xy``.
- **An orientation vote** of a point map: do the images of y's triangles on x keep their winding?

:func:`resolve_symmetry` and :func:`resolve_symmetry_p2p` use them to pick, among the symmetries of the
target, the one whose composition with a given map is orientation-consistent (ALGORITHM §2
conventions: ``C_xy [K_y, K_x]``, ``p2p_yx [V_y]``; the map "first the symmetry g of y, then T" has
pull-back ``S_y[g] @ C_xy`` and vertex map ``p2p_yx[sym_p2p_y[g]]``).
"""
from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

_CHUNK = 2 ** 24  # elements of the largest per-face intermediate of orientation_operators

__all__ = ["FaceGeometry", "face_geometry", "vertex_normals", "face_gradients", "faces_to_vertices",
           "unit_columns", "orientation_operators", "orientation_residual", "face_orientation_votes",
           "orientation_agreement", "resolve_symmetry",
           "resolve_symmetry_p2p", "FmapResolution", "P2PResolution"]


# ------------------------------------------------------------------------------------- validation
def _check_mesh(verts: Tensor, faces: Tensor, name: str = "") -> Tensor:
    if not isinstance(verts, Tensor) or verts.ndim != 2 or verts.shape[1] != 3 \
            or not verts.is_floating_point():
        got = list(verts.shape) if isinstance(verts, Tensor) else type(verts).__name__
        raise ValueError(f"verts{name} must be a [V, 3] float tensor, got {got}")
    faces = torch.as_tensor(faces, device=verts.device)
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.is_floating_point() or faces.dtype == torch.bool:
        raise ValueError(f"faces{name} must be [F, 3] long, got {list(faces.shape)} {faces.dtype}")
    faces = faces.long()
    if faces.numel() and (int(faces.min()) < 0 or int(faces.max()) >= verts.shape[0]):
        raise ValueError(f"faces{name} index out of range: indices span [{int(faces.min())}, "
                         f"{int(faces.max())}] but there are {verts.shape[0]} vertices")
    return faces


# -------------------------------------------------------------------------------- face gradients
class FaceGeometry(NamedTuple):
    """Per-face quantities of a triangle mesh that gradients are built from."""

    normals: Tensor    # [F, 3] unit normals, right-hand rule on the winding (outward if consistent)
    areas: Tensor      # [F] triangle areas
    hat_grads: Tensor  # [F, 3, 3] gradient of each corner's hat function: hat_grads[f, i] for corner i


def face_geometry(verts: Tensor, faces: Tensor) -> FaceGeometry:
    """Unit normals, areas and hat-function gradients of each face.

    Args:
        verts: [V, 3]; faces: [F, 3] long.

    Returns:
        FaceGeometry(normals [F, 3], areas [F], hat_grads [F, 3, 3]). Degenerate faces get zero
        area and zero gradients. Differentiable in ``verts`` away from degenerate faces.
    """
    faces = _check_mesh(verts, faces)
    vf = verts[faces]  # [F, 3, 3]
    N = torch.cross(vf[:, 1] - vf[:, 0], vf[:, 2] - vf[:, 0], dim=-1)
    dbl = N.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(verts.dtype).tiny)  # twice the area
    n = N / dbl
    # gradient of a linear function on a triangle: sum_i u_i (n x e_i) / (2 area), e_i opposite i
    e = torch.stack([vf[:, 2] - vf[:, 1], vf[:, 0] - vf[:, 2], vf[:, 1] - vf[:, 0]], 1)  # [F, 3, 3]
    hat = torch.cross(n[:, None, :].expand_as(e), e, dim=-1) / dbl[:, None]
    return FaceGeometry(n, 0.5 * dbl[:, 0], hat)


def vertex_normals(verts: Tensor, faces: Tensor, unit: bool = True) -> Tensor:
    """[V, 3] area-weighted vertex normals: the sum of the adjacent faces' ``cross(b - a, c - a)``
    (twice their area times their unit normal), scaled to unit length when ``unit``."""
    faces = torch.as_tensor(faces, device=verts.device).long()
    vf = verts[faces]  # [F, 3, 3]
    fn = torch.cross(vf[:, 1] - vf[:, 0], vf[:, 2] - vf[:, 0], dim=-1)
    vn = torch.zeros_like(verts).index_add_(0, faces.reshape(-1), fn.repeat_interleave(3, 0))
    return vn / vn.norm(dim=1, keepdim=True).clamp_min(1e-30) if unit else vn


def face_gradients(verts: Tensor, faces: Tensor, fields: Tensor,
                   geometry: FaceGeometry | None = None) -> Tensor:
    """Gradients of piecewise-linear scalar fields, one constant tangent vector per face.

    Args:
        verts: [V, 3]; faces: [F, 3] long.
        fields: [V, D] vertex values of D fields, or [V] for one.
        geometry: :func:`face_geometry` of the mesh, when already computed.

    Returns:
        [F, D, 3] (or [F, 3]). Differentiable in ``verts`` and ``fields``.
    """
    if geometry is None:
        faces = _check_mesh(verts, faces)
        geometry = face_geometry(verts, faces)
    else:  # validated by face_geometry
        faces = torch.as_tensor(faces, device=verts.device).long()
    if fields.ndim not in (1, 2) or fields.shape[0] != verts.shape[0]:
        raise ValueError(f"fields must be [V, D] = [{verts.shape[0]}, D], got {list(fields.shape)}")
    hat = geometry.hat_grads
    if fields.ndim == 1:
        return torch.einsum("fi,fic->fc", fields[faces], hat)
    return torch.einsum("fid,fic->fdc", fields[faces], hat)


def faces_to_vertices(values: Tensor, faces: Tensor, weights: Tensor, n_verts: int) -> Tensor:
    """Weighted average, at each vertex, of per-face values over its incident faces.

    Args:
        values: [F, ...] per-face values; faces: [F, 3] long; weights: [F] (face areas).
        n_verts: V.

    Returns:
        [V, ...]; 0 at vertices without a face.
    """
    shape = (-1, *([1] * (values.ndim - 1)))
    out = values.new_zeros(n_verts, *values.shape[1:])
    den = weights.new_zeros(n_verts)
    for i in range(3):
        out.index_add_(0, faces[:, i], values * weights.reshape(shape))
        den.index_add_(0, faces[:, i], weights)
    return out / den.clamp_min(torch.finfo(weights.dtype).tiny).reshape(shape)


# ---------------------------------------------------------------------------- orientation operators
def _check_basis(verts: Tensor, evecs: Tensor, mass: Tensor, fields: Tensor) -> None:
    V = verts.shape[0]
    if evecs.ndim != 2 or evecs.shape[0] != V:
        raise ValueError(f"evecs must be [V, K] = [{V}, K], got {list(evecs.shape)}")
    if mass.shape != (V,):
        raise ValueError(f"mass must be [V] = [{V}], got {list(mass.shape)}")
    if fields.ndim not in (1, 2) or fields.shape[0] != V:
        raise ValueError(f"fields must be [V, D] = [{V}, D], got {list(fields.shape)}")
    dtypes = {t.dtype for t in (verts, evecs, mass, fields)}
    if len(dtypes) > 1:
        raise ValueError(f"verts, evecs, mass and fields must share one dtype, got "
                         f"{verts.dtype}, {evecs.dtype}, {mass.dtype}, {fields.dtype}")


def unit_columns(fields: Tensor, mass: Tensor) -> Tensor:
    """[V, D] descriptors, each column scaled to unit mass-weighted L2 norm (an all-zero column
    stays zero, not NaN)."""
    return fields / (mass[:, None] * fields.square()).sum(0, keepdim=True).sqrt().clamp_min(
        torch.finfo(fields.dtype).tiny)


def orientation_operators(verts: Tensor, faces: Tensor, evecs: Tensor, mass: Tensor, fields: Tensor,
                          normalize: bool = True) -> Tensor:
    """Orientation operators of descriptors in a reduced basis (Ren et al. 2018).

    For each descriptor f, the operator ``g -> <n x grad f, grad g> = n . (grad f x grad g)`` on
    piecewise-linear functions (constant per face), in the basis ``evecs``::

        O_f[i, j] = sum_faces area/3 * (sum of evecs_i at the corners) * n . (grad f x grad evecs_j)
                  = integral of evecs_i * n . (grad f x grad evecs_j)       (exact on the mesh)

    Face values reach the vertices as in Ren et al.'s code: a vertex takes the sum over its faces of
    ``area / 3 * value``, divided by its mass. With the barycentric lumped mass that is the
    face-area-weighted average of :func:`symtorch.descriptors.gradient_cross`, and ``O_f = evecs.T @
    diag(mass) @ (those vertex values of the operator applied to each evecs_j)`` is the integral above
    for any lumped mass (the mass cancels). Integrating exactly makes ``O_f`` antisymmetric on a
    closed mesh (``∫ h df∧dg = -∫ g df∧dh``: their sum is ``∫ d(f d(hg)) = 0``, and the discrete
    integral obeys Stokes too), zero in the row and column of a constant function, and independent of
    the scale of ``verts`` (an area times two gradients).

    Note:
        Map relations (``C_xy [K_y, K_x]`` the pull-back of ``p2p_yx``, f on x corresponding to f' on
        y): orientation-preserving ``C_xy O^x_f ≈ O^y_{f'} C_xy``, orientation-reversing
        ``C_xy O^x_f ≈ -O^y_{f'} C_xy``. For a symmetry S of one shape that fixes f,
        ``S O_f S.T ≈ +O_f`` (rotation) or ``-O_f`` (reflection). Mirroring the mesh (one coordinate
        negated, winding reversed) negates every ``O_f`` in the same basis. ``faces`` must be
        consistently oriented.

    Args:
        verts: [V, 3]; faces: [F, 3] long, consistently oriented.
        evecs: [V, K] basis (mass-orthonormal Laplace–Beltrami eigenfunctions).
        mass: [V] lumped mass of the basis; used to normalise the descriptors.
        fields: [V, D] descriptors (WKS / HKS columns), or [V] for one.
        normalize: scale each descriptor column to unit mass-weighted L2 norm (as Ren et al.'s code
            does), so that corresponding descriptors on two shapes give operators of comparable size.

    Returns:
        [D, K, K] (or [K, K] for ``fields [V]``) in the dtype of ``verts``. Differentiable in every
        input.
    """
    faces = _check_mesh(verts, faces)
    _check_basis(verts, evecs, mass, fields)
    f = fields[:, None] if fields.ndim == 1 else fields
    if normalize:
        f = unit_columns(f, mass)
    geo = face_geometry(verts, faces)
    rot = torch.cross(geo.normals[:, None, :].expand(-1, f.shape[1], 3),
                      face_gradients(verts, faces, f, geo), dim=-1)  # [F, D, 3] n x grad f
    grads = face_gradients(verts, faces, evecs, geo)                 # [F, K, 3]
    P = (geo.areas / 3)[:, None] * evecs[faces].sum(1)              # [F, K] exact integration weights
    F, D, K = rot.shape[0], rot.shape[1], evecs.shape[1]
    step = max(1, _CHUNK // max(F * K, 1))  # descriptors per chunk: bounds the [F, step, K] product
    O = []
    for d in range(0, D, step):
        s = torch.einsum("fdc,fjc->fdj", rot[:, d:d + step], grads)  # n . (grad f x grad evecs_j)
        n = s.shape[1]
        O.append((P.mT @ s.reshape(F, n * K)).reshape(K, n, K).transpose(0, 1))
    O = torch.cat(O)  # [D, K, K]
    return O[0] if fields.ndim == 1 else O


def _leading(O: Tensor, K: int, name: str) -> Tensor:
    if O.ndim < 3 or O.shape[-1] != O.shape[-2] or O.shape[-1] < K:
        raise ValueError(f"{name} must be [..., D, K, K] with K >= {K}, got {list(O.shape)}")
    return O[..., :K, :K]  # the leading block is the operator in the first K functions


def orientation_residual(C_xy: Tensor, O_x: Tensor, O_y: Tensor) -> Tensor:
    """Relative orientation residual of functional maps (Ren et al. 2018's term, made scale-free).

    ``sum_d ||C O_x[d] - O_y[d] C||^2 / sum_d (||C O_x[d]||^2 + ||O_y[d] C||^2)``: 0 for an
    orientation-preserving map, 2 for an orientation-reversing one, about 1 for an unrelated one.

    Args:
        C_xy: [..., K_y, K_x].
        O_x: [..., D, K, K] operators of x, K >= K_x (the leading block is used);
        O_y: [..., D, K', K'] the corresponding ones of y, K' >= K_y.

    Returns:
        [...] in [0, 2].
    """
    if C_xy.ndim < 2:
        raise ValueError(f"C_xy must be [..., K_y, K_x], got {list(C_xy.shape)}")
    Ky, Kx = C_xy.shape[-2:]
    O_x, O_y = _leading(O_x, Kx, "O_x"), _leading(O_y, Ky, "O_y")
    if O_x.shape[-3] != O_y.shape[-3]:
        raise ValueError(f"O_x has D={O_x.shape[-3]} descriptors but O_y has D={O_y.shape[-3]}")
    C = C_xy[..., None, :, :]
    a, b = C @ O_x, O_y @ C  # [..., D, K_y, K_x]
    num = (a - b).square().sum((-3, -2, -1))
    den = (a.square() + b.square()).sum((-3, -2, -1))
    return num / den.clamp_min(torch.finfo(den.dtype).tiny)


class FmapResolution(NamedTuple):
    """The symmetry that makes a functional map orientation-consistent."""

    index: Tensor     # [...] long, the chosen element g of y's group
    fmap: Tensor      # [..., K_y, K_x] S_y[g] @ C_xy
    residual: Tensor  # [..., G] orientation residual of each candidate (inf: masked)


def resolve_symmetry(C_xy: Tensor, sym_fmap_y: Tensor, O_x: Tensor, O_y: Tensor,
                     mask_y: Tensor | None = None) -> FmapResolution:
    """Compose a functional map with the symmetry of its target that makes it orientation-preserving.

    A map known up to symmetry (``T`` or ``T ∘ g`` for any symmetry g of y, first g then T) has
    candidates ``S_y[g] @ C_xy``; each is scored by :func:`orientation_residual` against the
    orientation operators of corresponding descriptors (:func:`orientation_operators`, Ren et al.
    2018) and the smallest wins.

    Args:
        C_xy: [..., K_y, K_x] e.g. a network's map.
        sym_fmap_y: [..., G, K_y, K_y] symmetries of y (``sym_fmap``), identity included.
        O_x: [..., D, K, K], K >= K_x; O_y: [..., D, K', K'], K' >= K_y (``orient_op``).
        mask_y: [..., G] bool, valid elements of a padded batch (``sym_mask``); zero matrices (the
            padding of :func:`~symtorch.data.pad_collate`) are skipped even without it.

    Returns:
        FmapResolution(index [...], fmap [..., K_y, K_x], residual [..., G]).
    """
    if C_xy.ndim < 2 or sym_fmap_y.ndim < 3 or sym_fmap_y.shape[-1] != sym_fmap_y.shape[-2] \
            or sym_fmap_y.shape[-1] != C_xy.shape[-2]:
        raise ValueError(f"sym_fmap_y must be [..., G, K_y, K_y] for C_xy [..., K_y, K_x] = "
                         f"{list(C_xy.shape)}, got {list(sym_fmap_y.shape)}")
    cand = sym_fmap_y @ C_xy[..., None, :, :]  # [..., G, K_y, K_x]
    res = orientation_residual(cand, O_x[..., None, :, :, :], O_y[..., None, :, :, :])
    # a zero candidate (a padded element) has no orientation: it must never win
    res = torch.where(cand.square().sum((-2, -1)) > 0, res, torch.full_like(res, float("inf")))
    if mask_y is not None:
        if mask_y.shape[-1] != sym_fmap_y.shape[-3]:
            raise ValueError(f"mask_y must be [..., G] = [..., {sym_fmap_y.shape[-3]}], got "
                             f"{list(mask_y.shape)}")
        res = torch.where(mask_y, res, torch.full_like(res, float("inf")))
    index = res.argmin(-1)
    cand = cand.expand(*res.shape, *cand.shape[-2:])  # O_x, O_y may carry more batch dims
    fmap = cand.gather(-3, index[..., None, None, None].expand(*index.shape, 1, *cand.shape[-2:]))
    return FmapResolution(index, fmap.squeeze(-3), res)


# ------------------------------------------------------------------------------ point-map votes
def _check_p2p(p2p: Tensor, n_from: int, n_to: int, name: str) -> Tensor:
    if not isinstance(p2p, Tensor) or p2p.ndim < 1 or p2p.is_floating_point() \
            or p2p.dtype == torch.bool or p2p.shape[-1] != n_from:
        got = f"{list(p2p.shape)} {p2p.dtype}" if isinstance(p2p, Tensor) else type(p2p).__name__
        raise ValueError(f"{name} must be [..., {n_from}] long vertex ids, got {got}")
    if p2p.numel() and (int(p2p.min()) < 0 or int(p2p.max()) >= n_to):
        raise ValueError(f"{name} index out of range: values span [{int(p2p.min())}, "
                         f"{int(p2p.max())}] but the target has {n_to} vertices")
    return p2p.long()


def face_orientation_votes(p2p_yx: Tensor, verts_x: Tensor, faces_x: Tensor, verts_y: Tensor,
                           faces_y: Tensor, max_stretch: float = 3.0) -> tuple[Tensor, Tensor]:
    """Each face of y votes whether a point map keeps its winding on x.

    The face ``(a, b, c)`` of y is sent to the triangle ``verts_x[p2p_yx[[a, b, c]]]`` on x; it votes
    +1 when the image's normal (right-hand rule on that order) agrees with x's vertex normals at the
    three images (their sum), -1 otherwise. Faces whose image collapses (a repeated vertex, a
    numerically flat triangle) or is not local (an image edge longer than ``max_stretch`` times the
    face's longest edge, in units where both shapes have the same area) get weight 0; the others
    weigh their area on y. Only local quantities enter, so non-rigid (intrinsic) maps are scored
    correctly.

    Args:
        p2p_yx: [..., V_y] long, image on x of each vertex of y.
        verts_x: [V_x, 3]; faces_x: [F_x, 3] long, consistently oriented.
        verts_y: [V_y, 3]; faces_y: [F_y, 3] long, consistently oriented.
        max_stretch: locality bound.

    Returns:
        (vote [..., F_y] in {-1, 0, 1}, weight [..., F_y]) in the dtype of ``verts_x``. Not
        differentiable.
    """
    faces_x = _check_mesh(verts_x, faces_x, "_x")
    faces_y = _check_mesh(verts_y, faces_y, "_y")
    p2p = _check_p2p(torch.as_tensor(p2p_yx, device=verts_x.device), verts_y.shape[0],
                     verts_x.shape[0], "p2p_yx")
    gx, gy = face_geometry(verts_x, faces_x), face_geometry(verts_y, faces_y)
    vn = vertex_normals(verts_x, faces_x, unit=False)  # [V_x, 3]
    unit = (gx.areas.sum() / gy.areas.sum().clamp_min(torch.finfo(verts_y.dtype).tiny)).sqrt()
    fy = faces_y.to(p2p.device)
    edge_y = (verts_y[fy] - verts_y[fy.roll(1, -1)]).norm(dim=-1).amax(-1) * unit  # [F_y] on x's scale
    img = p2p[..., fy]                                                    # [..., F_y, 3]
    t = verts_x[img]                                                      # [..., F_y, 3, 3]
    n_img = torch.cross(t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :], dim=-1)
    vote = torch.sign((n_img * vn[img].sum(-2)).sum(-1))                  # [..., F_y]
    edge_img = (t - t.roll(1, -2)).norm(dim=-1).amax(-1)
    distinct = (img != img.roll(1, -1)).all(-1)
    # 1e-12: a numerically flat image triangle has no orientation
    valid = distinct & (edge_img <= max_stretch * edge_y) & (n_img.norm(dim=-1) > 1e-12 * edge_y.square())
    return vote, gy.areas.to(vote) * valid


def orientation_agreement(p2p_yx: Tensor, verts_x: Tensor, faces_x: Tensor, verts_y: Tensor,
                          faces_y: Tensor, max_stretch: float = 3.0) -> Tensor:
    """Area-weighted orientation vote of point maps between two shapes, in [-1, 1]: the mean of
    :func:`face_orientation_votes` (same arguments) over the faces of y that vote.

    Returns:
        [...] votes in the dtype of ``verts_x``: +1 orientation-preserving, -1 reversing (0 where
        no face could vote). Not differentiable.
    """
    vote, w = face_orientation_votes(p2p_yx, verts_x, faces_x, verts_y, faces_y, max_stretch)
    return (w * vote).sum(-1) / w.sum(-1).clamp_min(torch.finfo(w.dtype).tiny)


class P2PResolution(NamedTuple):
    """The symmetry that makes a point map orientation-consistent."""

    index: Tensor  # [...] long, the chosen element g of y's group
    p2p: Tensor    # [..., V_y] long, p2p_yx[sym_p2p_y[g]]
    vote: Tensor   # [..., G] orientation_agreement of each candidate (-inf: masked)


def resolve_symmetry_p2p(p2p_yx: Tensor, verts_x: Tensor, faces_x: Tensor, verts_y: Tensor,
                         faces_y: Tensor, sym_p2p_y: Tensor, mask_y: Tensor | None = None,
                         max_stretch: float = 3.0) -> P2PResolution:
    """Compose a point map with the symmetry of its target that makes it orientation-preserving.

    The candidates are ``p2p_yx[sym_p2p_y[g]]`` (first the symmetry g of y, then the map), scored by
    :func:`orientation_agreement`; the largest vote wins.

    Args:
        p2p_yx: [..., V_y] long, image on x of each vertex of y.
        verts_x, faces_x, verts_y, faces_y: the two meshes, consistently oriented.
        sym_p2p_y: [G, V_y] or [..., G, V_y] long, symmetries of y (``sym_p2p``), identity included.
        mask_y: [..., G] bool, valid elements of a padded group.
        max_stretch: see :func:`orientation_agreement`.

    Returns:
        P2PResolution(index [...], p2p [..., V_y], vote [..., G]).
    """
    Vy = verts_y.shape[0] if isinstance(verts_y, Tensor) and verts_y.ndim == 2 else -1
    sym = torch.as_tensor(sym_p2p_y, device=verts_x.device)
    if sym.ndim < 2:
        raise ValueError(f"sym_p2p_y must be [..., G, V_y], got {list(sym.shape)}")
    G = sym.shape[-2]
    if mask_y is not None:
        if mask_y.shape[-1] != G:
            raise ValueError(f"mask_y must be [..., G] = [..., {G}], got {list(mask_y.shape)}")
        mask_y = mask_y.to(sym.device)
        # padded elements (rows of -1): a stand-in map, their vote is masked below
        sym = torch.where(mask_y[..., None], sym, torch.zeros_like(sym))
    sym = _check_p2p(sym, Vy, Vy, "sym_p2p_y")
    p2p = torch.as_tensor(p2p_yx, device=verts_x.device)
    if p2p.ndim < 1 or p2p.shape[-1] != Vy:
        raise ValueError(f"p2p_yx must be [..., {Vy}] long vertex ids, got {list(p2p.shape)}")
    batch = torch.broadcast_shapes(p2p.shape[:-1], sym.shape[:-2])
    src = p2p.long()[..., None, :].expand(*batch, G, Vy)
    cand = src.gather(-1, sym.expand(*batch, G, Vy))  # [..., G, V_y]
    vote = orientation_agreement(cand, verts_x, faces_x, verts_y, faces_y, max_stretch)
    if mask_y is not None:
        vote = torch.where(mask_y, vote, torch.full_like(vote, -float("inf")))
    index = vote.argmax(-1)
    best = cand.expand(*vote.shape, Vy).gather(-2, index[..., None, None].expand(*index.shape, 1, Vy))
    return P2PResolution(index, best.squeeze(-2), vote)
