"""scripts/persistence_table.py: its per-point persistence and orbit test on a regular slab."""
import numpy as np

from script_loader import load_script
from shapes import star_slab


def test_a_regular_slab_has_every_point_orbit_closed_and_its_corners_high():
    mod = load_script("persistence_table")
    v, f, mats = star_slab(5, 0.25)
    pers, closed = mod.persistence(v, f, mats, v)
    assert closed.all()  # a symmetric triangulation: the point set is a union of orbits
    assert (pers >= 0.5).sum() >= 5 and (pers < 0.05).any()
    assert set(np.round(pers, 6)) <= set(np.round(np.concatenate([[0.0], mod.LEVELS]), 6))
