"""Constraint columns of the band-by-band Procrustes (ALGORITHM §3).

A symmetry ``g`` pulls a function back, ``f ∘ g``; in the basis its matrix maps the coefficients of
``f`` to those of ``f ∘ g``. Functions whose pull-back is known from a few symmetric points give the
columns of ``C A ≈ B``: the indicator of a geodesic disk around ``g(p)`` pulls back to the disk
around ``p``, and an isometry-invariant descriptor pulls back to itself.

A disk is isotropic: where every point of a tuple lies on a mirror plane (the corners and cap
centres of a prism, the HKS extrema of most shapes with mirrors), the disks are even under that
mirror and carry no coefficient in a band the mirror negates, and that band's block is left to
noise. A *dipole*, a disk tilted towards a second point of the tuple, is as well pulled back by an
isometry that maps both points (any pointwise function of their distance fields is), and is even
under no mirror that separates the two: :func:`dipole_coefficients`.
"""
from __future__ import annotations

import math

import numpy as np
import torch
from torch import Tensor

from ..units import EPS_KLC
from ..geodesics import disk_indicators

__all__ = ["DISK_RADII", "disk_coefficients", "dipole_coefficients", "descriptor_coefficients"]

DISK_RADII = (0.5, 1.0, 2.0)  # Gaussian disk radii, in units of the KLC tolerance EPS_KLC


def disk_coefficients(evecs: Tensor, mass: Tensor, dist: Tensor, radii=DISK_RADII) -> Tensor:
    """Unit-norm spectral coefficients of multi-scale Gaussian geodesic disks around n points.

    Args:
        evecs: [V, K] mass-orthonormal basis of the unit-area shape; mass: [V].
        dist: [n, V] geodesic distances from the n points (unit-area shape).
        radii: disk radii ``r`` (``exp(-(d / (r EPS_KLC))^2)``), in units of ``EPS_KLC``.

    Returns:
        [n, R, K] coefficients ``<disk, phi_k>_M``, each [K] row of unit norm.
    """
    Mx = evecs * mass[:, None]
    cols = torch.stack([Mx.mT @ disk_indicators(dist, r * EPS_KLC) for r in radii], -1)  # [K, n, R]
    cols = cols.permute(1, 2, 0)
    return cols / cols.norm(dim=-1, keepdim=True).clamp_min(1e-12)


def dipole_coefficients(evecs: Tensor, mass: Tensor, dist: Tensor, points, radii=DISK_RADII) -> Tensor:
    """Unit-norm spectral coefficients of geodesic dipoles among n points: the Gaussian disk at
    point ``i`` tilted towards point ``j``, ``exp(-(d_i / r)^2) (d_j - d_j(p_i)) / r``.

    The tilt is the first-order change of the distance to ``p_j`` across the disk, so the dipole is
    odd under a mirror through ``p_i`` that does not fix ``p_j`` (the module docstring). Each disk
    is cut where its weight falls below ``exp(-16)`` (four radii), so the cost is that of the
    disk's support.

    Args:
        evecs: [V, K] mass-orthonormal basis of the unit-area shape; mass: [V].
        dist: [n, V] geodesic distances from the n points (unit-area shape); points: [n] their vertices.
        radii: disk radii, in units of ``EPS_KLC``.

    Returns:
        [n, n, R, K] (``i``, towards ``j``); zero rows where ``i == j``.
    """
    n, K = dist.shape[0], evecs.shape[1]
    Mx = evecs * mass[:, None]
    at = dist[:, torch.as_tensor(np.asarray(points))]  # [n(j), n(i)]: d_j(p_i)
    out = dist.new_zeros(n, n, len(radii), K)
    for i in range(n):
        for r_i, r in enumerate(radii):
            rad = r * EPS_KLC
            sup = torch.nonzero(dist[i] < 4 * rad)[:, 0]
            disk = torch.exp(-(dist[i, sup] / rad) ** 2)  # [S]
            tilt = (dist[:, sup] - at[:, i:i + 1]) / rad  # [n, S]
            out[i, :, r_i] = (disk * tilt) @ Mx[sup]
    out[torch.arange(n), torch.arange(n)] = 0
    norm = out.norm(dim=-1, keepdim=True)
    return torch.where(norm > 1e-12, out / norm.clamp_min(1e-12), out)


def descriptor_coefficients(evecs: Tensor, mass: Tensor, desc: Tensor) -> Tensor:
    """Spectral coefficients of D descriptor columns, each of norm ``1 / sqrt(D)`` (together they
    weigh as much as one disk constraint).

    Args:
        evecs: [V, K]; mass: [V]; desc: [V, D] isometry-invariant descriptors (``descriptors``).

    Returns:
        [K, D].
    """
    A = (evecs * mass[:, None]).mT @ desc
    return A / A.norm(dim=0, keepdim=True).clamp_min(1e-12) / math.sqrt(desc.shape[1])
