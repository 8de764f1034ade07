"""Constraint columns of the band-by-band Procrustes (ALGORITHM §3).

A symmetry ``g`` pulls a function back, ``f ∘ g``; in the basis its matrix maps the coefficients of
``f`` to those of ``f ∘ g``. Functions whose pull-back is known from a few symmetric points give the
columns of ``C A ≈ B``: the indicator of a geodesic disk around ``g(p)`` pulls back to the disk
around ``p``, and an isometry-invariant descriptor pulls back to itself.
"""
from __future__ import annotations

import math

import torch
from torch import Tensor

from ..units import EPS_KLC
from ..geodesics import disk_indicators

__all__ = ["DISK_RADII", "disk_coefficients", "descriptor_coefficients"]

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
