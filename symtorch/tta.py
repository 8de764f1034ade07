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

Symmetric feature averaging (:func:`symmetrized_features`) uses the shape's own reflection R: the
mirror image x' carries at vertex R(v) the label of v (``RandomSymmetry(mode="mirror")`` composes the
ground truth so), so a network that learned orientation gives ``f(x')[R(v)] ~ f(x)[v]``, and the
mean of the two is the network averaged over the shape's reflection group {1, R} (group averaging):
features that are mirror-equivariant by construction, one shape at a time, in training
(``scripts/train_symmetry.py``'s ``symmetrize`` run) or at test time on any network.

:func:`spectral_reflection_average` takes the same average in the reduced basis, through the
reflection's matrix ``S`` (``sym_fmap``) instead of its vertex map: ``(A + S A') / 2`` on the
features' spectral coefficients. It reads only the reflection's first K frequencies, so a detected
reflection, whose vertex map is off by a fraction of a KLC radius, averages almost as the exact one
does; the vertex-level average is sensitive to that offset (BENCHMARKS.md, "Training with
symmetries").
"""
from __future__ import annotations

from typing import Callable

import torch
from torch import Tensor

from .data.symmetry import mirror_shape, reflection_index

__all__ = ["mirror_pair", "mirror_averaged_fmap", "symmetrized_features", "reflection_average",
           "spectral_reflection_average", "reflection_residual", "reflection_index"]


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


def symmetrized_features(feature_fn: Callable[[dict], Tensor], sample: dict, axis: int = 0) -> Tensor:
    """``(f(x)[v] + f(x')[R(v)]) / 2``: a point-feature network averaged over the shape's reflection.

    Args:
        feature_fn: the network, a sample -> ``[V, D]`` per-vertex features.
        sample: with ``verts``, ``sym_p2p [G, V]`` and ``sym_reverses [G]`` (the reflection R is the
            first orientation-reversing element), and whatever ``feature_fn`` and
            :func:`symtorch.data.mirror_shape` read.
        axis: the coordinate negated to make the mirror image x'.

    Returns:
        [V, D] the averaged features; ``feature_fn(sample)`` unchanged where the sample has no
        reflection.
    """
    F = feature_fn(sample)
    if reflection_index(sample) is None:
        return F
    return reflection_average(F, feature_fn(mirror_shape(sample, axis)), sample)


def reflection_average(F: Tensor, F_mirror: Tensor, sample: dict) -> Tensor:
    """``(F[v] + F_mirror[R(v)]) / 2`` for features already computed on the shape and on its mirror
    image (the average :func:`symmetrized_features` takes); ``F`` where the sample has no reflection.

    Args:
        F, F_mirror: [V, D] features of the shape and of its mirror image.
        sample: with ``sym_p2p [G, V]`` and ``sym_reverses [G]``.
    """
    r = reflection_index(sample)
    if r is None:
        return F
    R = torch.as_tensor(sample["sym_p2p"][r], device=F.device).long()
    if R.shape != (F.shape[0],):
        raise ValueError(f"sym_p2p[{r}] must be [V] = [{F.shape[0]}], got {list(R.shape)}")
    return 0.5 * (F + F_mirror[R])


def spectral_reflection_average(A: Tensor, A_mirror: Tensor, sample: dict) -> Tensor:
    """``(A + S A') / 2``: :func:`reflection_average` on spectral coefficients, with the reflection
    taken as its matrix in the first K eigenfunctions.

    With ``A = evecs_K^T M F`` the coefficients of features on the shape and ``A'`` those of the
    features on its mirror image, the coefficients of ``F'∘R`` are ``S A'`` for the pull-back matrix
    ``S`` of R (``evecs[R] ≈ evecs @ S``), up to what R does above the K-th frequency.

    Args:
        A, A_mirror: [K, D] coefficients of the features of the shape and of its mirror image.
        sample: with ``sym_fmap [G, K', K']`` (K' >= K) and ``sym_reverses [G]``.

    Returns:
        [K, D]; ``A`` where the sample has no reflection.
    """
    r = reflection_index(sample)
    if r is None:
        return A
    k = A.shape[-2]
    S = torch.as_tensor(sample["sym_fmap"][r])
    if S.shape[-1] < k:
        raise ValueError(f"sym_fmap[{r}] is {S.shape[-1]} x {S.shape[-1]}, smaller than the {k} "
                         "coefficients to average")
    return 0.5 * (A + S[:k, :k].to(A) @ A_mirror)


def reflection_residual(F: Tensor, F_mirror: Tensor, sample: dict) -> float:
    """``||F - F'∘R|| / ||F||``: how far a network's features are from agreeing with the shape's
    reflection R, a check of R by the network.

    A network shown mirror images gives ``f(x')[R(v)] ~ f(x)[v]`` for the true reflection; a wrong
    R (a competing near-symmetry: an arm swapped, a leg mirrored onto itself) reads the mirror's
    features at the wrong places. On SCAPE_r the ranking separates the detector's wrong reflections
    from its right ones better than the detector's own confidence does (BENCHMARKS.md, "Training
    with symmetries"); no threshold is fixed here.

    Args:
        F, F_mirror: [V, D] features of the shape and of its mirror image.
        sample: with ``sym_p2p [G, V]`` and ``sym_reverses [G]``.

    Returns:
        the residual, nan where the sample has no reflection.
    """
    if reflection_index(sample) is None:
        return float("nan")
    avg = reflection_average(F, F_mirror, sample)  # (F + F'∘R) / 2, so F - F'∘R = 2 (F - avg)
    return float(2 * (F - avg).norm() / F.norm().clamp_min(1e-12))

