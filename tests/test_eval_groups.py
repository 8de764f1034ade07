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
