"""ZoomOut between two shapes (Melzi et al. 2019): a functional map refined by growing its basis.

A network's functional map is solved in few eigenfunctions (30 here), so its vertex map is coarse.
ZoomOut alternates the two representations: the vertex map of the current matrix by nearest
neighbours in the spectral embedding, then the matrix of that vertex map a few eigenfunctions
larger, until the basis has ``k_final`` functions. It uses no descriptor and no training, only the two
bases, which is why the field reports it as a test-time refinement beside the plain maps (GeomFmaps,
ULRSSM). It keeps whichever side the map sends each part to: it sharpens a map, it does not turn a
flipped one around (that is :func:`symtorch.orientation.resolve_symmetry_p2p`'s job).

Conventions as :mod:`symtorch.maps`: ``C_xy [K_y, K_x]`` is the pull-back of the vertex map
``p2p_yx`` (for each vertex of y its image on x): ``evecs_y @ C_xy ≈ evecs_x[p2p_yx]``. The refinement
of a *symmetry* matrix, which must stay block-diagonal and orthogonal, is
:func:`symtorch.refine.zoomout_symmetry`.
"""
from __future__ import annotations

from typing import NamedTuple

from torch import Tensor

from .maps import fmap_to_p2p, p2p_to_fmap


class ZoomOutResult(NamedTuple):
    """``fmap [k_final, k_final]`` the refined functional map, ``p2p [V_y]`` its vertex map (y -> x)."""

    fmap: Tensor
    p2p: Tensor


def zoomout(C: Tensor, evecs_x: Tensor, evecs_y: Tensor, mass_y: Tensor, k_final: int,
            *, step: int = 4) -> ZoomOutResult:
    """Grow ``C [k, k]`` to ``[k_final, k_final]``, ``step`` eigenfunctions at a time.

    Each step: ``p2p = NN(evecs_y[:, :k] @ C, evecs_x[:, :k])``, then ``C`` the pull-back of ``p2p`` in
    the first ``k + step`` eigenfunctions (the last step ends at ``k_final``); the vertex map returned
    is that of the final matrix.

    Args:
        C: [k, k] functional map x -> y (pull-back), ``k <= k_final``.
        evecs_x: [V_x, K] and evecs_y: [V_y, K] mass-orthonormal bases, ``K >= k_final``.
        mass_y: [V_y] lumped mass of y.
        k_final: basis size at the end.
        step: eigenfunctions added per step (ZoomOut's 1 is the most precise and the slowest).

    Raises:
        ValueError: a non-square ``C``, a basis shorter than ``k_final``, or ``step < 1``.
    """
    k = C.shape[-1]
    if C.dim() != 2 or C.shape[0] != k:
        raise ValueError(f"C must be a square [k, k] matrix, got {list(C.shape)}")
    if min(evecs_x.shape[1], evecs_y.shape[1]) < k_final or k_final < k:
        raise ValueError(f"k_final={k_final} must lie between C's size {k} and the bases' "
                         f"{min(evecs_x.shape[1], evecs_y.shape[1])} eigenfunctions")
    if step < 1:
        raise ValueError(f"step must be at least 1, got {step}")
    while k < k_final:
        k_next = min(k + step, k_final)
        p2p = fmap_to_p2p(C, evecs_x[:, :k], evecs_y[:, :k])
        C = p2p_to_fmap(p2p, evecs_x[:, :k_next], mass_y, evecs_src=evecs_y[:, :k_next])
        k = k_next
    return ZoomOutResult(C, fmap_to_p2p(C, evecs_x[:, :k], evecs_y[:, :k]))
