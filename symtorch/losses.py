"""Losses on functional maps and errors of point maps, symmetry-aware ones included.

Conventions (ALGORITHM §2, STYLE "Names"): ``C_xy`` is ``[..., K_y, K_x]`` and sends coefficients of
functions on x to those on y (the pull-back by the point map ``p2p_yx [V_y]``, which gives for each
vertex of y its image on x). A symmetry of x has matrix ``S_x [K_x, K_x]`` (``f -> f ∘ g``).

Every loss takes any leading batch dims, is differentiable in its matrix arguments, follows their dtype
and device, and is 0 at its ideal. Each is a squared Frobenius norm per map (summed over entries),
reduced over the batch dims by ``reduction``: ``"mean"`` (default), ``"sum"`` or ``"none"`` (keep
``[...]``). The symmetry-aware terms are ``symmetry_equivariance_loss`` (``C_xy S_x = S_y C_xy``) and
``symmetric_fmap_loss`` (distance to the nearest of the truth's symmetric images); ``orientation_loss``
(Ren et al. 2018) tells a map from its mirror-flipped twin. The point-map errors
``p2p_error`` and ``symmetric_p2p_error`` ("accuracy up to symmetry") are evaluation measures, not
differentiable.
"""
from __future__ import annotations

from collections.abc import Callable

import torch
from torch import Tensor

__all__ = ["fmap_loss", "orthogonality_loss", "bijectivity_loss", "laplacian_commutativity_loss",
           "orientation_loss", "symmetry_equivariance_loss", "symmetric_fmap_loss", "p2p_error",
           "symmetric_p2p_error"]

_REDUCTIONS = ("mean", "sum", "none")


def _reduce(x: Tensor, reduction: str) -> Tensor:
    if reduction == "mean":
        return x.mean()
    if reduction == "sum":
        return x.sum()
    if reduction == "none":
        return x
    raise ValueError(f"reduction must be one of {_REDUCTIONS}, got {reduction!r}")


def _sqnorm(X: Tensor) -> Tensor:
    return X.square().sum((-2, -1))


def _check_matrix(C: Tensor, name: str) -> None:
    if C.dim() < 2:
        raise ValueError(f"{name} must be [..., K_y, K_x], got {list(C.shape)}")


def _eye_like(n: int, C: Tensor) -> Tensor:
    return torch.eye(n, dtype=C.dtype, device=C.device)


def fmap_loss(C: Tensor, C_gt: Tensor, reduction: str = "mean") -> Tensor:
    """Supervised loss ``||C - C_gt||_F^2``.

    Args:
        C, C_gt: [..., K_y, K_x] predicted and ground-truth maps.
    """
    if C.shape[-2:] != C_gt.shape[-2:]:
        raise ValueError(f"C is {list(C.shape)} but C_gt is {list(C_gt.shape)}")
    return _reduce(_sqnorm(C - C_gt), reduction)


def orthogonality_loss(C: Tensor, reduction: str = "mean") -> Tensor:
    """``||C.T @ C - I||_F^2``: a near-isometric map has an orthogonal functional map
    (Ovsjanikov et al. 2012, §5.1).

    Args:
        C: [..., K_y, K_x], with ``K_x <= K_y`` for the ideal to be reachable.
    """
    _check_matrix(C, "C")
    return _reduce(_sqnorm(C.mT @ C - _eye_like(C.shape[-1], C)), reduction)


def bijectivity_loss(C_xy: Tensor, C_yx: Tensor, reduction: str = "mean") -> Tensor:
    """``||C_xy @ C_yx - I||_F^2 + ||C_yx @ C_xy - I||_F^2``: the two directions invert each other
    (Roufosse et al. 2019; Eisenberger et al. 2020).

    Args:
        C_xy: [..., K_y, K_x]; C_yx: [..., K_x, K_y].
    """
    if C_xy.shape[-2:] != C_yx.shape[-2:][::-1]:
        raise ValueError(f"C_xy {list(C_xy.shape)} and C_yx {list(C_yx.shape)} are not transposed "
                         f"shapes")
    Ky, Kx = C_xy.shape[-2:]
    loss = _sqnorm(C_xy @ C_yx - _eye_like(Ky, C_xy)) + _sqnorm(C_yx @ C_xy - _eye_like(Kx, C_xy))
    return _reduce(loss, reduction)


def laplacian_commutativity_loss(C_xy: Tensor, evals_x: Tensor, evals_y: Tensor,
                                 reduction: str = "mean", normalize: bool = True) -> Tensor:
    """``||C_xy diag(evals_x) - diag(evals_y) C_xy||_F^2 = sum_ij C_ij^2 (evals_y_i - evals_x_j)^2``:
    an isometry commutes with the Laplacian (Ovsjanikov et al. 2012).

    Raw eigenvalues grow like k, so at large K this term swamps the others. With ``normalize`` both
    eigenvalue vectors are first divided by the larger of their two maxima (per map, over the batch
    dims), as GeomFmaps (Donati et al. 2020) and ULRSSM (Cao et al. 2023) do in their regularised
    solvers: the term is then O(1) whatever K and the area of the shapes.

    Args:
        C_xy: [..., K_y, K_x]; evals_x: [..., K_x]; evals_y: [..., K_y].
        normalize: divide by ``max(evals_x.max(), evals_y.max())`` (the largest absolute value, so a
            padded batch's zeros do not matter); False: raw eigenvalues (unit-area shapes,
            ``ComputeSpectrum``, make them comparable across shapes, and their size weights the term).
    """
    if evals_x.shape[-1] != C_xy.shape[-1] or evals_y.shape[-1] != C_xy.shape[-2]:
        raise ValueError(f"C_xy is {list(C_xy.shape)} but evals_x has {evals_x.shape[-1]} and "
                         f"evals_y {evals_y.shape[-1]} values")
    if normalize:
        top = torch.maximum(evals_x.abs().amax(-1), evals_y.abs().amax(-1))[..., None]
        top = top.clamp_min(torch.finfo(top.dtype).tiny)  # all-zero spectra: leave them zero
        evals_x, evals_y = evals_x / top, evals_y / top
    gap = evals_y[..., :, None] - evals_x[..., None, :]  # [..., K_y, K_x]
    return _reduce((C_xy * gap).square().sum((-2, -1)), reduction)


def orientation_loss(C_xy: Tensor, O_x: Tensor, O_y: Tensor, reduction: str = "mean",
                     reversing: bool = False) -> Tensor:
    """``mean_d ||C_xy O_x[d] - O_y[d] C_xy||_F^2``: the map preserves the surface orientation
    (Ren, Poulenard, Wonka, Ovsjanikov, SIGGRAPH Asia 2018).

    ``O_x[d]``, ``O_y[d]`` are the orientation operators of corresponding descriptors
    (:func:`symtorch.orientation.orientation_operators`, sample key ``orient_op``); an
    orientation-preserving map commutes with them, an orientation-reversing one anti-commutes. It is
    what tells the true map from its mirror-flipped twin, which every intrinsic term scores equally.
    Padded entries of a batch (zero rows and columns of C and the operators) add nothing, so no mask
    is needed.

    Args:
        C_xy: [..., K_y, K_x].
        O_x: [..., D, K_x, K_x]; O_y: [..., D, K_y, K_y].
        reversing: ask for an orientation-reversing map, ``C_xy O_x ≈ -O_y C_xy`` (a map onto a
            mirror image).
    """
    Ky, Kx = C_xy.shape[-2:] if C_xy.dim() >= 2 else (-1, -1)
    if C_xy.dim() < 2 or O_x.dim() < 3 or O_y.dim() < 3 or O_x.shape[-2:] != (Kx, Kx) \
            or O_y.shape[-2:] != (Ky, Ky) or O_x.shape[-3] != O_y.shape[-3]:
        raise ValueError(f"C_xy [..., K_y, K_x] = {list(C_xy.shape)} needs O_x [..., D, K_x, K_x] and "
                         f"O_y [..., D, K_y, K_y], got {list(O_x.shape)} and {list(O_y.shape)}")
    C = C_xy[..., None, :, :]
    rhs = O_y @ C
    per = _sqnorm(C @ O_x + rhs if reversing else C @ O_x - rhs).mean(-1)  # [...]
    return _reduce(per, reduction)


def symmetry_equivariance_loss(C_xy: Tensor, sym_x: Tensor, sym_y: Tensor,
                               mask_x: Tensor | None = None, mask_y: Tensor | None = None,
                               match: str = "index", reduction: str = "mean") -> Tensor:
    """``sum_g ||C_xy S_x[g] - S_y[g] C_xy||_F^2``: the map commutes with the symmetries.

    A correspondence T: y -> x that sends the symmetry g_y of y to the symmetry g_x of x
    (``T ∘ g_y = g_x ∘ T``) has ``C_xy S_x = S_y C_xy`` under the pull-back. The true map between two
    poses of one template commutes with their (left/right) symmetry; its symmetric flip does too.

    Args:
        C_xy: [..., K_y, K_x].
        sym_x: [..., G, K_x, K_x] matrices of the group of x (``sym_fmap``).
        sym_y: [..., G', K_y, K_y] matrices of the group of y.
        mask_x, mask_y: [..., G] / [..., G'] bool, valid elements (``sym_mask`` of a padded batch).
        match: ``"index"``: element g of x goes with element g of y (same template, or both C2 with the
            identity first), ``G == G'``; ``"best"``: each element of x goes with the element of y that
            fits it best (groups detected separately, in unrelated orders).

    Returns:
        the loss, reduced over the batch dims.
    """
    if sym_x.shape[-1] != C_xy.shape[-1] or sym_y.shape[-1] != C_xy.shape[-2]:
        raise ValueError(f"C_xy is {list(C_xy.shape)} but sym_x is {list(sym_x.shape)} and sym_y "
                         f"{list(sym_y.shape)}")
    C = C_xy[..., None, :, :]
    if match == "index":
        if sym_x.shape[-3] != sym_y.shape[-3]:
            raise ValueError(f"match='index' needs groups of one order, got {sym_x.shape[-3]} and "
                             f"{sym_y.shape[-3]}")
        per = _sqnorm(C @ sym_x - sym_y @ C)  # [..., G]
        valid = _and_masks(mask_x, mask_y, per)
        per = torch.where(valid, per, torch.zeros_like(per))
    elif match == "best":
        lhs = (C @ sym_x)[..., :, None, :, :]  # [..., G, 1, K_y, K_x]
        rhs = (sym_y @ C)[..., None, :, :, :]  # [..., 1, G', K_y, K_x]
        pair = _sqnorm(lhs - rhs)  # [..., G, G']
        if mask_y is not None:
            pair = torch.where(mask_y[..., None, :], pair, torch.full_like(pair, float("inf")))
        per = pair.amin(-1)
        if mask_x is not None:
            per = torch.where(mask_x, per, torch.zeros_like(per))
    else:
        raise ValueError(f"match must be 'index' or 'best', got {match!r}")
    return _reduce(per.sum(-1), reduction)


def _and_masks(a: Tensor | None, b: Tensor | None, like: Tensor) -> Tensor:
    valid = torch.ones_like(like, dtype=torch.bool)
    for m in (a, b):
        if m is not None:
            valid = valid & m
    return valid


def symmetric_fmap_loss(C_xy: Tensor, C_gt: Tensor, sym_y: Tensor, mask: Tensor | None = None,
                        reduction: str = "mean") -> Tensor:
    """Supervised loss up to symmetry: ``min_g ||C_xy - S_y[g] @ C_gt||_F^2``.

    ``S_y[g] @ C_gt`` is the pull-back of the truth composed with the symmetry g of y
    (``p2p_gt[sym_p2p_y[g]]``: first g, then the true map), i.e. every map as good as the truth for a
    method that cannot tell a shape from its mirror image. With the identity in the group, the loss
    is at most :func:`fmap_loss`. Differentiable almost everywhere (through the minimising element).

    Args:
        C_xy: [..., K_y, K_x] predicted map.
        C_gt: [..., K_y, K_x] ground truth.
        sym_y: [..., G, K_y, K_y] symmetries of y (identity included).
        mask: [..., G] bool, valid elements of a padded batch.
    """
    if C_xy.shape[-2:] != C_gt.shape[-2:] or sym_y.shape[-1] != C_xy.shape[-2]:
        raise ValueError(f"C_xy {list(C_xy.shape)}, C_gt {list(C_gt.shape)} and sym_y "
                         f"{list(sym_y.shape)} do not fit")
    per = _sqnorm(C_xy[..., None, :, :] - sym_y @ C_gt[..., None, :, :])  # [..., G]
    if mask is not None:
        per = torch.where(mask, per, torch.full_like(per, float("inf")))
    return _reduce(per.amin(-1), reduction)


Dist = Tensor | Callable[[Tensor, Tensor], Tensor]


def _lookup(dist: Dist, a: Tensor, b: Tensor) -> Tensor:
    """Distances between vertices ``a`` and ``b`` (same shape) on one shape."""
    if callable(dist) and not isinstance(dist, Tensor):
        return dist(a, b)
    V = dist.shape[-1]
    flat = dist.flatten(-2)  # [..., V*V]
    idx = a * V + b
    if flat.dim() == 1:
        return flat[idx]
    return flat.expand(*idx.shape[:-1], flat.shape[-1]).gather(-1, idx)  # batched distances


def _masked_mean(x: Tensor, valid: Tensor) -> Tensor:
    x = torch.where(valid, x, torch.zeros_like(x))
    return x.sum(-1) / valid.sum(-1).clamp_min(1)


def p2p_error(p2p: Tensor, p2p_gt: Tensor, dist: Dist, mask: Tensor | None = None) -> Tensor:
    """Mean distance on x between computed and true images: ``mean_i d_x(p2p[i], p2p_gt[i])``.

    Args:
        p2p: [..., V_y] long, computed image on x of each vertex of y.
        p2p_gt: [..., V_y] long, true images (-1: unknown, skipped).
        dist: distances on x, a ``[V_x, V_x]`` (or ``[..., V_x, V_x]``) tensor, or a callable
            ``dist(a, b) -> d`` taking two long tensors of one shape (e.g. a geodesic lookup).
        mask: [..., V_y] bool, vertices to score (``mask`` of a padded batch).

    Returns:
        [...] mean error per map, in the units of ``dist``.
    """
    valid = (p2p_gt >= 0) & (p2p >= 0)
    if mask is not None:
        valid = valid & mask
    d = _lookup(dist, p2p.clamp_min(0), p2p_gt.clamp_min(0))
    return _masked_mean(d, valid)


def symmetric_p2p_error(p2p: Tensor, p2p_gt: Tensor, sym_p2p: Tensor, dist: Dist,
                        mask: Tensor | None = None,
                        sym_mask: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """Error up to symmetry: the smallest :func:`p2p_error` against the truth composed with each
    symmetry of x, ``g ∘ p2p_gt`` ("accuracy up to symmetry").

    Args:
        p2p, p2p_gt, dist, mask: as in :func:`p2p_error`.
        sym_p2p: [..., G, V_x] long, symmetries of x, identity first (``sym_p2p`` of x).
        sym_mask: [..., G] bool, valid elements of a padded batch.

    Returns:
        (error [...], element [...] long): the smallest error and the element reaching it; 0 (the
        identity) means the map is closest to the truth itself, anything else to a symmetric flip.
    """
    G = sym_p2p.shape[-2]
    gt = p2p_gt[..., None, :].expand(*p2p_gt.shape[:-1], G, p2p_gt.shape[-1])  # [..., G, V_y]
    truths = sym_p2p.gather(-1, gt.clamp_min(0))
    truths = torch.where(gt >= 0, truths, gt)
    pred = p2p[..., None, :].expand_as(truths)
    m = None if mask is None else mask[..., None, :].expand_as(truths)
    if isinstance(dist, Tensor) and dist.dim() > 2:
        dist = dist[..., None, :, :]
    per = p2p_error(pred, truths, dist, m)  # [..., G]
    if sym_mask is not None:
        per = torch.where(sym_mask, per, torch.full_like(per, float("inf")))
    err, idx = per.min(-1)
    return err, idx
