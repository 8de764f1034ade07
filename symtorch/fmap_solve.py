"""The differentiable functional-map layer of learned shape matching (FMNet, GeomFmaps, ULRSSM).

Given the spectral coefficients of corresponding descriptors on two shapes, solve for the
functional map that carries one set onto the other, regularised towards maps that commute with the
Laplacian. The regulariser is the resolvent mask of Ren, Melzi, Wonka & Ovsjanikov, "Structured
regularization of functional map computations" (SGP 2019), on eigenvalues divided by the larger of
the two shapes' largest ones, as DUO-FM and ULRSSM use it. Each row of the map is an independent
``K_x x K_x`` linear system; all rows and batch entries are solved at once, and gradients flow to
the descriptors.
"""
from __future__ import annotations

import torch
from torch import Tensor

__all__ = ["resolvent_mask", "regularized_fmap"]


def resolvent_mask(evals_x: Tensor, evals_y: Tensor, gamma: float = 0.5) -> Tensor:
    """Resolvent Laplacian-commutativity mask ``M [..., K_y, K_x]`` (Ren et al. 2019).

    ``M_ij = (r_y_i - r_x_j)^2 + (s_y_i - s_x_j)^2`` with ``r = l / (l^2 + 1)``, ``s = 1 / (l^2 + 1)``
    and ``l = (evals / max(evals_x.max(), evals_y.max())) ** gamma``: zero on the diagonal of
    matching eigenvalues, growing away from it.

    Args:
        evals_x: [..., K_x]; evals_y: [..., K_y], non-negative, ascending.
        gamma: resolvent exponent.
    """
    scale = torch.maximum(evals_x.amax(-1), evals_y.amax(-1)).clamp_min(1e-12)[..., None]
    lx = (evals_x.clamp_min(0) / scale) ** gamma
    ly = (evals_y.clamp_min(0) / scale) ** gamma
    rx, sx = lx / (lx.square() + 1), 1 / (lx.square() + 1)
    ry, sy = ly / (ly.square() + 1), 1 / (ly.square() + 1)
    return (ry[..., :, None] - rx[..., None, :]).square() + (sy[..., :, None] - sx[..., None, :]).square()


def regularized_fmap(A_x: Tensor, A_y: Tensor, evals_x: Tensor, evals_y: Tensor,
                     lam: float = 100.0, gamma: float = 0.5) -> Tensor:
    """Functional map ``C_xy [..., K_y, K_x]`` minimising ``||C A_x - A_y||^2 + lam sum_ij M_ij C_ij^2``.

    Args:
        A_x: [..., K_x, D] spectral coefficients of D descriptors on x (``evecs_x.T @ (mass_x * F_x)``).
        A_y: [..., K_y, D] the same descriptors on y.
        evals_x: [..., K_x]; evals_y: [..., K_y].
        lam: weight of the Laplacian-commutativity mask (:func:`resolvent_mask`).
        gamma: resolvent exponent.

    Returns:
        [..., K_y, K_x], the pull-back map (sends functions on x to functions on y), differentiable.
    """
    if A_x.shape[-1] != A_y.shape[-1]:
        raise ValueError(f"A_x {list(A_x.shape)} and A_y {list(A_y.shape)} must have the same number "
                         f"of descriptors (last dim)")
    if evals_x.shape[-1] != A_x.shape[-2] or evals_y.shape[-1] != A_y.shape[-2]:
        raise ValueError(f"evals_x [{evals_x.shape[-1]}] / evals_y [{evals_y.shape[-1]}] do not match "
                         f"A_x {list(A_x.shape)} / A_y {list(A_y.shape)}")
    M = resolvent_mask(evals_x, evals_y, gamma)  # [..., K_y, K_x]
    AAt = A_x @ A_x.mT  # [..., K_x, K_x]
    lhs = AAt[..., None, :, :] + lam * torch.diag_embed(M)  # [..., K_y, K_x, K_x]
    rhs = (A_y @ A_x.mT)[..., None]  # [..., K_y, K_x, 1]
    return torch.linalg.solve(lhs, rhs)[..., 0]
