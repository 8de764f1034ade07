"""symtorch.eval.groups: scoring whole groups (rigid residual, dihedral orbits)."""
import numpy as np

from symtorch import shapes
from symtorch.eval.groups import dihedral_permutations, rigid_residual


def test_rigid_residual_is_zero_for_a_rigid_symmetry_only():
    v, _ = shapes.polar_prism(5)  # exactly D5h, triangulation included
    maps = shapes.symmetry_maps(v, shapes.polar_prism_symmetries(5))
    assert max(rigid_residual(v, p) for p in maps) < 1e-6
    scrambled = np.random.default_rng(0).permutation(len(v))
    assert rigid_residual(v, scrambled) > 0.3


def test_dihedral_permutations():
    P = dihedral_permutations(4)
    assert P.shape == (8, 4) and len({tuple(p) for p in P.tolist()}) == 8
    assert dihedral_permutations(2).tolist() == [[0, 1], [1, 0]]


def test_orbit_dihedral_elements_follow_geometry_not_listing_order():
    """A table's orbits (corners, edge midpoints listed the other way round, two fixed points):
    the 8 elements are permutations; rot 2 is the half turn, ref 1 the mirror through the
    first edge midpoint; the rigid maps they imply are the square's own symmetries."""
    from symtorch.eval.groups import orbit_dihedral_elements, rigid_maps_from_points

    a = np.deg2rad([45, 135, 225, 315])
    corners = np.stack([np.cos(a), 0 * a, np.sin(a)], 1)
    b = np.deg2rad([0, 270, 180, 90])  # clockwise, unlike the corners
    mids = np.stack([np.cos(b), 0 * b, np.sin(b)], 1)
    verts = np.concatenate([corners, mids, [[0, 0.1, 0], [0, -0.1, 0]]])
    orbits = [np.arange(4), np.arange(4, 8), np.array([8]), np.array([9])]
    names, perm = orbit_dihedral_elements(verts, orbits)
    assert names[2] == "rot 2" and perm.shape == (8, 10)
    assert all(sorted(p) == list(range(10)) for p in perm.tolist())
    assert perm[0].tolist() == list(range(10))
    assert np.allclose(verts[perm[2]][:8], -verts[:8])             # half turn
    assert (perm[:, 8:] == [8, 9]).all()                            # fixed points stay
    maps = rigid_maps_from_points(verts, np.arange(10), perm)
    assert (maps == perm).all()                                     # exact on an exact square
    assert len({tuple(p) for p in perm.tolist()}) == 8
