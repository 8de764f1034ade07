"""The unit of length of the detectors: the KLC10 correctness radius.

Kim, Lipman & Funkhouser (2010) count a symmetric point as found when its image lies within
``sqrt(area / (20 pi))`` of the truth. The detectors work on unit-area shapes and express their own
tolerances (sampling radii, verification thresholds) in that radius, :data:`EPS_KLC`.
"""
from __future__ import annotations

import math

__all__ = ["klc_threshold", "EPS_KLC"]


def klc_threshold(area: float) -> float:
    """KLC10 correctness radius ``sqrt(area / (20 pi))``, in the units of the mesh."""
    return math.sqrt(float(area) / (20.0 * math.pi))


EPS_KLC = klc_threshold(1.0)  # the KLC10 radius on a unit-area shape
