"""Batched orthogonal Procrustes, block by block over eigenvalue bands (ALGORITHM §3).

Given coefficient matrices ``A`` (constraint functions projected on the basis) and ``B`` (their
transported versions), find the block-diagonal orthogonal ``C`` with one orthogonal block ``D_i`` per
band minimising ``sum_i ||D_i A_i - B_i||_F``: ``D_i = U @ Vh`` with ``U, S, Vh = svd(B_i @ A_i.T)``.
Bands of the same size are stacked and solved by one batched SVD, so thousands of candidates cost a
handful of ``torch.linalg.svd`` calls and no Python loop over candidates.
"""
from __future__ import annotations

from collections import defaultdict

import torch
from torch import Tensor


def nearest_orthogonal(X: Tensor) -> Tensor:
    """The orthogonal matrix nearest to each ``X`` in Frobenius norm (polar factor).

    Args:
        X: [..., n, n].

    Returns:
        [..., n, n] ``U @ Vh`` of the SVD ``X = U S Vh``.
    """
    U, _, Vh = torch.linalg.svd(X)
    return U @ Vh


def procrustes_rotation(A: Tensor, B: Tensor, weights: Tensor | None = None) -> Tensor:
    """Orthogonal ``D`` minimising ``||D @ A - B||_F`` (columns weighted by ``weights``).

    Args:
        A: [..., n, J] source coefficients.
        B: [..., n, J] target coefficients.
        weights: [..., J] non-negative column weights, or None.

    Returns:
        [..., n, n] orthogonal (det may be -1: reflections of the eigenspace are allowed).
    """
    if weights is not None:
        B = B * weights[..., None, :]
    return nearest_orthogonal(B @ A.mT)


def _band_groups(bands: list[range]) -> dict[int, list[range]]:
    groups: dict[int, list[range]] = defaultdict(list)
    for b in bands:
        groups[len(b)].append(b)
    return groups


def block_procrustes(A: Tensor, B: Tensor, bands: list[range], weights: Tensor | None = None,
                     fixed_first: bool = True) -> Tensor:
    """Block-diagonal orthogonal ``C`` with ``C @ A ≈ B``, one block per band.

    Args:
        A: [..., K, J] coefficients of the constraint functions F (``A = evecs.T @ (mass * F)``).
        B: [..., K, J] coefficients of the transported functions G (``G ≈ F ∘ g``).
        bands: index ranges covering ``0..K-1`` (from ``eigen_bands``).
        weights: [..., J] optional column weights.
        fixed_first: keep the constant eigenfunction (band ``range(0, 1)``) as a fixed ``+1`` block.

    Returns:
        [..., K, K] block-diagonal orthogonal matrices, dtype and device of ``A``.

    Note:
        Under the pullback convention (ALGORITHM §2) the symmetry matrix maps coefficients of ``f`` to
        those of ``f ∘ g``; so A holds the functions and B their pull-backs.
    """
    K = A.shape[-2]
    if B.shape != A.shape:
        raise ValueError(f"A and B must have the same shape, got {list(A.shape)} and {list(B.shape)}")
    if not bands or bands[0].start != 0 or bands[-1].stop != K:
        raise ValueError(f"bands must cover 0..{K - 1}, got {bands[:1]}...{bands[-1:]}")
    if weights is not None:
        B = B * weights[..., None, :]
    C = torch.zeros(*A.shape[:-2], K, K, dtype=A.dtype, device=A.device)
    for size, group in _band_groups(bands).items():
        idx = torch.stack([torch.arange(b.start, b.stop, device=A.device) for b in group])  # [nb, s]
        Ab = A[..., idx, :]  # [..., nb, s, J]
        Bb = B[..., idx, :]
        D = nearest_orthogonal(Bb @ Ab.mT)  # [..., nb, s, s]
        rows = idx[:, :, None].expand(-1, size, size)
        cols = idx[:, None, :].expand(-1, size, size)
        C[..., rows, cols] = D
    if fixed_first and bands[0] == range(0, 1):
        C[..., 0, :] = 0
        C[..., :, 0] = 0
        C[..., 0, 0] = 1
    return C


def block_mask(bands: list[range], K: int | None = None, device=None) -> Tensor:
    """[K, K] bool mask of the block-diagonal pattern of ``bands``."""
    K = bands[-1].stop if K is None else K
    mask = torch.zeros(K, K, dtype=torch.bool, device=device)
    for b in bands:
        if b.start < K:
            mask[b.start:min(b.stop, K), b.start:min(b.stop, K)] = True
    return mask


def block_project(C: Tensor, bands: list[range], fixed_first: bool = True) -> Tensor:
    """Nearest block-diagonal orthogonal matrix to ``C`` (each diagonal block made orthogonal).

    Args:
        C: [..., K, K] any matrices.

    Returns:
        [..., K, K] block-diagonal orthogonal matrices.
    """
    K = C.shape[-1]
    eye = torch.eye(K, dtype=C.dtype, device=C.device)
    # Procrustes of C (as B) against the identity (as A) gives the polar factor of each block.
    return block_procrustes(eye.expand_as(C), C, bands, fixed_first=fixed_first)
