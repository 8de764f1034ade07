"""Tests for symtorch.detect.involutions: heat-kernel extrema and the involutive permutations of them."""
import numpy as np
import pytest
import torch

from symtorch import laplacian_spectrum
from symtorch.units import EPS_KLC
from symtorch.geodesics import GeodesicSolver
from symtorch.detect.involutions import extend_involution, heat_extrema, involution_candidates, seed_pairs
from symtorch.shapes import mirror_blob, symmetry_maps, true_symmetries


def _tips():
    # five points of a symmetric "star figure": a head on the axis, two mirrored pairs of limbs
    pts = np.array([[0, 3.0], [-2, 1], [2, 1], [-1, -2], [1, -2]])
    dist = np.linalg.norm(pts[:, None] - pts[None], axis=-1) * EPS_KLC
    desc = np.array([[0.0], [1.0], [1.0], [2.0], [2.0]])
    return dist, desc


def test_extend_involution_completes_the_permutation():
    dist, desc = _tips()
    allowed = np.ones((5, 5), dtype=bool)
    perm = extend_involution(((1, 2), (3, 4)), dist, allowed, tol=0.5 * EPS_KLC)
    assert perm.tolist() == [0, 2, 1, 4, 3]  # the head is a fixed point
    perm = extend_involution(((1, 2), (0, 0)), dist, allowed, tol=0.5 * EPS_KLC)
    assert perm.tolist() == [0, 2, 1, 4, 3]


def test_involution_candidates_rank_the_full_swap_first():
    dist, desc = _tips()
    seeds = seed_pairs(desc, dist)
    assert seeds, "mirrored limbs make seeds"
    perms, scores, n_seeds = involution_candidates(desc, dist)
    assert n_seeds == len(seeds)
    assert perms[0].tolist() == [0, 2, 1, 4, 3]
    assert scores[0] == pytest.approx(0.0, abs=1e-9)
    assert all(s > scores[0] for s in scores[1:])
    # duplicates collapse: each permutation appears once
    assert len({tuple(p) for p in perms}) == len(perms)


def test_heat_extrema_are_spread_and_closed_under_the_mirror():
    v, f = mirror_blob(3)
    spec = laplacian_spectrum(v, f, k=30)
    unit = v * spec.scale
    solver = GeodesicSolver(unit, f)
    ext, dist = heat_extrema(spec.evals, spec.evecs, f, solver, n_extrema=12, nms_radius=2.0)
    assert 2 <= len(ext) <= 12 and dist.shape == (len(ext), len(v))
    assert torch.allclose(dist[torch.arange(len(ext)), torch.as_tensor(ext)],
                          torch.zeros(len(ext), dtype=dist.dtype), atol=1e-6)  # rows start at their point
    D = dist[:, ext].numpy()
    off = D + np.eye(len(ext)) * 1e9
    assert off.min() > 2.0 * EPS_KLC * 0.99  # geodesic non-maximum suppression
    # a union of mirror orbits: the mirror image of each extremum is (near) an extremum
    mirror = symmetry_maps(v, true_symmetries("mirror_blob"))[1]
    to_nearest = dist[:, mirror[ext]].numpy().min(0)  # [N]: distance from g(e) to the nearest extremum
    assert to_nearest.max() < EPS_KLC
