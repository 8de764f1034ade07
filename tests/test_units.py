"""symtorch.units: the KLC10 radius sqrt(area / (20 pi))."""
from __future__ import annotations

import math

import pytest

from symtorch.units import EPS_KLC, klc_threshold


def test_klc_threshold_values():
    assert klc_threshold(20 * math.pi) == pytest.approx(1.0)
    assert EPS_KLC == pytest.approx(0.12616, abs=1e-5)
    # scales with the square root of the area: 4x the area, 2x the radius
    assert klc_threshold(4.0) == pytest.approx(2 * EPS_KLC)
