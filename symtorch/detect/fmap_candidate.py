"""An orientation-reversing functional map of a shape onto itself: the reflection path's second
kind of evidence, beside the heat-kernel extrema pairs (Ren, Poulenard, Wonka & Ovsjanikov 2018).

The extrema candidates are built from a few symmetric point pairs; this one uses no points at all.
In the first ``k`` eigenfunctions the pull-back ``C [k, k]`` of an intrinsic reflection

- keeps every (intrinsic, hence symmetric) descriptor: ``C A ≈ A`` with ``A = Φᵀ M F``;
- commutes with the Laplacian: ``C Λ ≈ Λ C``;
- commutes with the descriptors' multiplication operators: ``C P_f ≈ P_f C``, ``P_f = Φᵀ M diag(f) Φ``;
- **reverses the orientation**: ``C O_f ≈ -O_f C`` for the orientation operator ``O_f`` of each
  descriptor (:func:`symtorch.orientation.orientation_operators`, the implementation the training
  layer's orientation term uses).

The identity satisfies the first three exactly; only the fourth tells the reflection from it. All
four are linear in ``C``, so the minimiser of their weighted sum of squares is one linear least
squares problem in ``k²`` unknowns (:func:`orientation_reversing_fmap`), solved in closed form in
torch, batched over shapes; no iterative optimiser (pyFM runs L-BFGS on the same energy). The
result is projected onto the symmetry structure (block-orthogonal over the bands, symmetric) and
grown by the same band-preserving upsampling as every other candidate.
"""
from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

from ..orientation import orientation_operators, unit_columns
from ..refine import bands_upto, project_structure

__all__ = ["FmapWeights", "fmap_energy_terms", "orientation_reversing_fmap", "reversing_fmap_candidate"]


class FmapWeights(NamedTuple):
    """Weights of the four terms (pyFM's defaults: descriptors 1, Laplacian 0.1, commutativity 1,
    orientation 1); each term is normalised by its number of entries first."""

    descriptors: float = 1.0
    laplacian: float = 0.1
    commutativity: float = 1.0
    orientation: float = 1.0


def fmap_energy_terms(evecs: Tensor, evals: Tensor, mass: Tensor, fields: Tensor,
                      O: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """The reduced operators of the energy: (A [k, D], Λ [k] in [0, 1], P [D, k, k], O [D, k, k]).

    Args:
        evecs: [V, k] mass-orthonormal eigenfunctions; evals: [k]; mass: [V] lumped mass.
        fields: [V, D] descriptors; O: [D, k, k] their orientation operators in ``evecs``.
    """
    F = unit_columns(fields, mass)  # as orientation_operators normalises them
    MPhi = mass[:, None] * evecs
    A = MPhi.mT @ F                                           # [k, D]
    V, k, D = evecs.shape[0], evecs.shape[1], F.shape[1]
    P = (MPhi.mT @ (F[:, :, None] * evecs[:, None, :]).reshape(V, D * k)).reshape(k, D, k).transpose(0, 1)
    lam = evals / evals.abs().max().clamp_min(torch.finfo(evals.dtype).tiny)
    return A, lam, P, O


def _kron(X: Tensor, Y: Tensor) -> Tensor:
    """Batched Kronecker product of two [..., k, k] matrices: [..., k², k²]."""
    k = X.shape[-1]
    K = X[..., :, None, :, None] * Y[..., None, :, None, :]          # [..., a, i, b, j]
    return K.reshape(*K.shape[:-4], k * k, k * k)


def _kron_sum(X: Tensor) -> Tensor:
    """``Σ_d X_d ⊗ X_d`` of [..., D, k, k] matrices as one product: [..., k², k²]."""
    k = X.shape[-1]
    flat = X.reshape(*X.shape[:-2], k * k)                            # [..., D, (a, b)]
    G = flat.mT @ flat                                                # [..., (a, b), (i, j)]
    return G.reshape(*G.shape[:-2], k, k, k, k).transpose(-3, -2).reshape(*G.shape[:-2], k * k, k * k)


def orientation_reversing_fmap(A: Tensor, lam: Tensor, P: Tensor, O: Tensor,
                               weights: FmapWeights = FmapWeights()) -> Tensor:
    """The least-squares ``C [k, k]`` of ``w_d |C A - A|² + w_l |C Λ - Λ C|² + w_c Σ_f |C P_f - P_f C|²
    + w_o Σ_f |C O_f + O_f C|²`` (each term divided by its number of entries), batched over leading
    dimensions.

    With ``vec`` stacking columns, ``vec(C X) = (Xᵀ ⊗ I) vec(C) = R vec(C)`` and ``vec(X C) = (I ⊗ X)
    vec(C) = L vec(C)``, so ``RᵀR = X Xᵀ ⊗ I``, ``LᵀL = I ⊗ XᵀX``, ``RᵀL = X ⊗ X`` and ``LᵀR = Xᵀ ⊗ Xᵀ``:
    the normal equations of the commutators (``R - L``) and anticommutators (``R + L``) are
    assembled from ``k × k`` products and one Kronecker product per descriptor, and solved directly.

    Args:
        A: [..., k, D]; lam: [..., k]; P: [..., D, k, k]; O: [..., D, k, k] (see
            :func:`fmap_energy_terms`).

    Returns:
        [..., k, k] in the dtype of ``A``.
    """
    k, D = A.shape[-2], A.shape[-1]
    I = torch.eye(k, dtype=A.dtype, device=A.device)
    AAt = A @ A.mT
    wd = weights.descriptors / (k * D)
    N = wd * _kron(AAt, I)
    rhs = wd * AAt.mT.reshape(*AAt.shape[:-2], k * k)                 # vec(A Aᵀ)
    dl = (lam[..., None, :] - lam[..., :, None]).square().mT.reshape(*lam.shape[:-1], k * k)
    N = N + weights.laplacian / (k * k) * torch.diag_embed(dl)
    for X, sign, w in ((P, -1.0, weights.commutativity), (O, 1.0, weights.orientation)):
        w = w / (X.shape[-3] * k * k)
        gram = _kron((X @ X.mT).sum(-3), I) + _kron(I, (X.mT @ X).sum(-3))
        cross = _kron_sum(X) + _kron_sum(X.mT)
        N = N + w * (gram + sign * cross)
    N = 0.5 * (N + N.mT)
    c = torch.linalg.solve(N, rhs[..., None])[..., 0]
    return c.reshape(*c.shape[:-1], k, k).mT                          # columns were stacked


def reversing_fmap_candidate(verts: Tensor, faces: Tensor, evecs: Tensor, evals: Tensor, mass: Tensor,
                             fields: Tensor, bands: list[range], k: int,
                             weights: FmapWeights = FmapWeights()) -> Tensor:
    """The orientation-reversing self-map of one shape in its first ``k`` eigenfunctions (``k`` a
    band end), projected onto the reflection's structure (block-orthogonal over ``bands``,
    symmetric).

    Args:
        verts: [V, 3] (any scale); faces: [F, 3] long, consistently oriented.
        evecs: [V, K >= k]; evals: [K]; mass: [V]; fields: [V, D] intrinsic descriptors.
        bands: the spectrum's bands (covering ``0..k-1``); k: the basis size.

    Returns:
        [k, k] in the dtype of ``evecs``.
    """
    E = evecs[:, :k]
    dtype = E.dtype
    O = orientation_operators(verts.to(dtype), faces, E, mass.to(dtype), fields.to(dtype))
    A, lam, P, O = fmap_energy_terms(E, evals[:k].to(dtype), mass.to(dtype), fields.to(dtype), O)
    C = orientation_reversing_fmap(A, lam, P, O, weights)
    return project_structure(C, bands_upto(bands, k), involution=True)
