"""The unit of length of the detectors: the KLC10 correctness radius.

Kim, Lipman & Funkhouser (2010) count a symmetric point as found when its image lies within
``sqrt(area / (20 pi))`` of the truth. The detectors work on unit-area shapes and express their own
tolerances (sampling radii, verification thresholds) in that radius, :data:`EPS_KLC`.
"""
from __future__ import annotations

import math

__all__ = ["klc_threshold", "EPS_KLC", "mean_edge"]


def klc_threshold(area: float) -> float:
    """KLC10 correctness radius ``sqrt(area / (20 pi))``, in the units of the mesh."""
    return math.sqrt(float(area) / (20.0 * math.pi))


EPS_KLC = klc_threshold(1.0)  # the KLC10 radius on a unit-area shape


def mean_edge(verts, faces) -> float:
    """Mean edge length of a triangle mesh ``verts [V, 3]``, ``faces [F, 3]``, in the units of
    ``verts`` (each interior edge counted twice, from its two faces: the same mean)."""
    import numpy as np
    import torch

    v = torch.as_tensor(np.asarray(verts, dtype=np.float64))
    f = torch.as_tensor(np.asarray(faces, dtype=np.int64))
    return float((v[f] - v[f.roll(1, 1)]).norm(dim=-1).mean())
