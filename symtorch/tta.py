"""Mirror test-time averaging: a second view of a pair for networks trained with mirror images.

Reflect both shapes of a pair in the same plane (:func:`symtorch.data.mirror_shape`: one coordinate
negated, faces rewound). A reflection of space sends an orientation-preserving correspondence
between x and y to an orientation-preserving correspondence between their mirror images *with the
same vertex ids*, so the functional map between the two mirror images, written in the same
(intrinsic, unchanged) bases, estimates the same matrix as the map between the originals. A network
that was shown mirror images in training (``RandomSymmetry(mode="mirror")``) sees two different
inputs (its gradient features are orientation-aware) and gives two estimates; their mean is a
two-view ensemble that needs no symmetry at test time. A network never shown mirror images sees the
mirrored view out of distribution, and averaging with it does harm (BENCHMARKS.md, "Training with
symmetries").
"""
from __future__ import annotations

from typing import Callable

from torch import Tensor

from .data.symmetry import mirror_shape

__all__ = ["mirror_pair", "mirror_averaged_fmap"]


def mirror_pair(x: dict, y: dict, axis: int = 0) -> tuple[dict, dict]:
    """Both shapes' mirror images in the plane ``coordinate[axis] = 0``; their vertex-id
    correspondence (``corr``, ground-truth maps) is the pair's own and is left unchanged."""
    return mirror_shape(x, axis), mirror_shape(y, axis)


def mirror_averaged_fmap(fmap_fn: Callable[[dict, dict], Tensor], x: dict, y: dict,
                         axis: int = 0) -> Tensor:
    """``(fmap_fn(x, y) + fmap_fn(x', y')) / 2`` with ``x', y'`` the mirror images (:func:`mirror_pair`).

    Args:
        fmap_fn: the network's functional map of a pair of samples, ``[..., K_y, K_x]``.
        x, y: samples with ``verts`` (and ``faces``, orientation-aware operators such as
            ``grad_val`` / ``orient_op``, which :func:`symtorch.data.mirror_shape` transforms).
        axis: the coordinate negated.

    Returns:
        the averaged functional map, shaped as ``fmap_fn``'s.
    """
    xm, ym = mirror_pair(x, y, axis)
    return 0.5 * (fmap_fn(x, y) + fmap_fn(xm, ym))
