"""Refinement of a symmetry matrix: spectral ICP and spectral upsampling that keep its structure.

The paper refines with spectral ICP (Ovsjanikov et al. 2012, §6.2) at a fixed basis size; an
independent comparison found that step its weak point. Here the refinement grows the basis band by
band as ZoomOut does (Melzi et al. 2019) — vertex map by nearest neighbour, then the matrix of that
map one band larger — while keeping what a symmetry matrix must be: block-diagonal over the
eigenvalue bands and orthogonal, and, for an involution (a reflection), symmetric (``C = C.T``).
"""
from __future__ import annotations

import torch
from torch import Tensor

from .maps import nearest_neighbors
from .procrustes import block_mask, block_project


def nearest_involution(C: Tensor, bands: list[range] | None = None) -> Tensor:
    """Nearest symmetric orthogonal matrix (an orthogonal involution) to ``C``, block by block.

    ``C = C.T = C^-1`` has eigenvalues ±1: ``C = U diag(sign(l)) U.T`` from the eigendecomposition of
    the symmetric part of ``C`` (restricted to the bands' blocks when ``bands`` is given).

    Args:
        C: [..., K, K].
        bands: optional band ranges covering ``0..K-1``.

    Returns:
        [..., K, K] symmetric orthogonal.
    """
    if bands is not None:
        C = C * block_mask(bands, C.shape[-1], device=C.device).to(C.dtype)
    S = 0.5 * (C + C.mT)
    lam, U = torch.linalg.eigh(S)
    sign = torch.where(lam >= 0, torch.ones_like(lam), -torch.ones_like(lam))
    return (U * sign[..., None, :]) @ U.mT


def project_structure(C: Tensor, bands: list[range] | None, involution: bool) -> Tensor:
    """Project a [K, K] matrix onto the symmetry-matrix set: bands, orthogonality, involution."""
    if involution:
        return nearest_involution(C, bands)
    if bands is None:
        U, _, Vh = torch.linalg.svd(C)
        return U @ Vh
    return block_project(C, bands, fixed_first=False)


def bands_upto(bands: list[range], K: int) -> list[range]:
    """The bands that end at or before ``K``; ``K`` must be a band end."""
    out = [b for b in bands if b.stop <= K]
    if not out or out[-1].stop != K:
        raise ValueError(f"K={K} cuts a band")
    return out


def zoomout_symmetry(C0: Tensor, evecs: Tensor, mass: Tensor, bands: list[range], k_final: int,
                     *, step: int = 4, samples: Tensor | None = None, involution: bool = False,
                     block: bool = True, n_iter_end: int = 2,
                     targets: Tensor | None = None, guide: tuple[Tensor, Tensor] | None = None) -> Tensor:
    """Grow a symmetry matrix from ``C0 [k0, k0]`` to ``[k_final, k_final]``, band by band.

    Each step: ``p2p = NN(evecs_k[S] @ C, evecs_k)`` for the sample vertices ``S``, then the
    matrix of that map in the next basis (ending on a band boundary at least ``step`` larger),
    mass-weighted least squares on the samples, projected back onto the structure (block-orthogonal
    over ``bands``, and symmetric for an involution). ``n_iter_end`` extra iterations at ``k_final``.

    Args:
        C0: [k0, k0] initial matrix, k0 a band boundary.
        evecs: [V, K] with K >= k_final.
        mass: [V].
        bands: bands covering at least ``0..k_final-1``.
        k_final: final basis size, a band boundary.
        samples: [S] vertex ids to evaluate the map on (default all vertices).
        involution: enforce ``C = C.T`` (reflections).
        block: enforce the band structure (else the full orthogonal matrix, as ZoomOut).
        targets: [T] vertex ids the sample images are searched among (default all vertices);
            a sample set makes each step's nearest-neighbour search V/T times cheaper.
        guide: optional ([V, G] source features, [V, G] target features) appended to the spectral
            coordinates in each nearest-neighbour search (weighted by the caller).

    Returns:
        [k_final, k_final] matrix.
    """
    ends = [b.stop for b in bands if b.stop <= k_final]
    k = C0.shape[-1]
    C = C0
    S = torch.arange(evecs.shape[0], device=evecs.device) if samples is None else samples
    w = mass[S]
    schedule = []
    while k < k_final:
        nxt = next((e for e in ends if e >= k + step), k_final)
        schedule.append(nxt)
        k = nxt
    schedule += [k_final] * n_iter_end
    k = C0.shape[-1]
    T = torch.arange(evecs.shape[0], device=evecs.device) if targets is None else targets
    # the rows the loop reads, gathered once (each step then slices columns)
    kmax = max(k_final, C0.shape[-1])  # a start larger than k_final is cut to it by the first step
    ES, ET = evecs[S, :kmax], evecs[T, :kmax]
    for k_next in schedule:
        Q, P = ES[:, :k] @ C, ET[:, :k]
        if guide is not None:
            Q, P = torch.cat([Q, guide[0][S]], 1), torch.cat([P, guide[1][T]], 1)
        nn = nearest_neighbors(Q, P)
        A = ES[:, :k_next]
        B = ET[nn, :k_next]
        # weighted least squares on the samples: (A^T W A)^-1 A^T W B
        AtW = (A * w[:, None]).mT
        Cn = torch.linalg.solve(AtW @ A, AtW @ B)
        C = project_structure(Cn, bands_upto(bands, k_next) if block else None, involution)
        k = k_next
    return C
