"""symtorch.detect.verification: geodesic distortion, orientation vote, descriptor gap."""
import math

import numpy as np
import pytest
import torch

from symtorch import laplacian_spectrum
from symtorch.detect.verification import orientation_vote, vertex_normals
from symtorch.geodesics import GeodesicSolver
from symtorch.sampling import farthest_point_sampling


def test_descriptor_gap_is_zero_for_a_symmetry_and_large_for_a_scramble(mirror3):
    from symtorch.descriptors import descriptors
    from symtorch.detect.verification import descriptor_gap

    v, f, mirror = mirror3
    s = laplacian_spectrum(v, f, k=40)
    desc = descriptors(s.evals, s.evecs)
    assert descriptor_gap(desc, torch.arange(len(v)), s.mass) == 0.0
    assert descriptor_gap(desc, mirror, s.mass) < 1e-6
    # pointwise, a partial swap keeps descriptors too: that is the geodesic distortion's job
    x = v[:, 0] - v[:, 0].mean()
    assert descriptor_gap(desc, torch.where(x > 0, mirror, torch.arange(len(v))), s.mass) < 1e-6
    # vertices sent to unrelated places do not
    assert descriptor_gap(desc, torch.roll(torch.arange(len(v)), len(v) // 3), s.mass) > 0.4


def test_orientation_vote_separates_reflection_from_identity(mirror3):
    v, f, mirror = mirror3
    vn = vertex_normals(v, f)
    S = farthest_point_sampling(v, 200)
    assert float(orientation_vote(torch.arange(len(v)), v, vn, S)) == pytest.approx(1.0)
    assert float(orientation_vote(mirror, v, vn, S)) < -0.9
    batch = torch.stack([torch.arange(len(v)), mirror])
    votes = orientation_vote(batch, v, vn, S)
    assert votes.shape == (2,) and votes[0] > 0.9 and votes[1] < -0.9


def test_involution_distortion_needs_no_solve_and_tracks_the_isometry_score(mirror3):
    from symtorch.detect.verification import involution_distortion, isometry_score

    v, f, mirror = mirror3
    v = v / math.sqrt(GeodesicSolver(v, f).area)  # unit area: distortions in KLC units
    solver = GeodesicSolver(v, f)
    S = farthest_point_sampling(v, 24)
    fields = solver.distances_from(S)  # [24, V]: the only solves
    score, d_mirror, worst = involution_distortion(fields, S, mirror)
    assert d_mirror < 0.15 and worst < 0.3  # the heat method's own asymmetry, not the map's
    assert score == pytest.approx(math.exp(-d_mirror ** 2))
    # half the shape mirrored, the other half kept: no isometric involution
    x = v[:, 0] - v[:, 0].mean()
    half = torch.where(x > 0, mirror, torch.arange(len(v)))
    d_half = involution_distortion(fields, S, half).distortion
    d_half_images = isometry_score(solver, half, S).distortion
    assert d_half > 0.5 and d_half == pytest.approx(d_half_images, rel=0.5)
    # a map that moves every sample onto one point is no involution either
    assert involution_distortion(fields, S, torch.zeros(len(v), dtype=torch.long))[1] > 0.5


def test_involution_error_is_zero_for_an_involution_and_large_for_a_drift(mirror3):
    from symtorch.detect.verification import involution_error

    v, f, mirror = mirror3
    v = v / math.sqrt(GeodesicSolver(v, f).area)
    solver = GeodesicSolver(v, f)
    S = farthest_point_sampling(v, 24)
    fields = solver.distances_from(S)
    assert involution_error(fields, S, mirror) < 0.05  # g(g(s)) = s up to the heat method's error
    assert involution_error(fields, S, torch.arange(len(v))) < 0.05
    # a map that sends every vertex a quarter of the way round the list is no involution
    drift = torch.roll(torch.arange(len(v)), len(v) // 4)
    assert involution_error(fields, S, drift) > 1.0


def test_local_errors_set_aside_a_lone_wrong_image_not_a_wrong_part(mirror3):
    """A sample sent to the far end of a symmetric shape is a local error (its true image fits the
    other samples and keeps its descriptors): the worst row leaves it out. Half the shape kept in
    place is a wrong part: more samples than the limit, the worst row stays large."""
    from symtorch.descriptors import descriptors
    from symtorch.detect.verification import involution_distortion, local_errors

    v, f, mirror = mirror3
    v = v / math.sqrt(GeodesicSolver(v, f).area)
    solver = GeodesicSolver(v, f)
    s = laplacian_spectrum(v, f, k=40)
    desc = descriptors(s.evals, s.evecs)
    S = farthest_point_sampling(v, 24)
    fields = solver.distances_from(S)
    one_off = mirror.clone()
    one_off[S[0]] = int(fields[0].argmax())
    skip = local_errors(fields, S, one_off, desc, 1.5, 2, 3.0)
    assert skip.tolist() == [True] + [False] * 23
    assert involution_distortion(fields, S, one_off).worst > 1.5 > 0.5 > \
        involution_distortion(fields, S, one_off, skip).worst
    assert not local_errors(fields, S, mirror, desc, 1.5, 2, 3.0).any()  # nothing to set aside
    x = v[:, 0] - v[:, 0].mean()
    half = torch.where(x > 0, mirror, torch.arange(len(v)))
    skip = local_errors(fields, S, half, desc, 0.5, 2, 3.0)
    assert int(skip.sum()) <= 2 and involution_distortion(fields, S, half, skip).worst > 0.5


def _rotation_map(v: np.ndarray, angle: float) -> torch.Tensor:
    """[V] the vertex map of the rotation about z by ``angle``: the nearest vertex to each image."""
    from scipy.spatial import cKDTree

    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return torch.as_tensor(cKDTree(v).query(v @ R.T)[1])


def test_heat_levels_keep_a_rotation_invariant_function_and_see_a_moved_bump():
    """A rotation's vertex map keeps a function of the height alone (all but rounding, which the
    2-ring absorbs) and moves a bump off the axis onto where the function is flat; a function
    nearly constant over the shape (a sphere's HKS) says nothing and is skipped."""
    from symtorch.detect.verification import HeatLevels
    from symtorch.shapes import icosphere

    v, f = icosphere(4)
    mass = torch.ones(len(v), dtype=torch.float64)
    height = 1.0 + v[:, 2] ** 2  # [V] rotation-invariant, range 1 over a mean of 1.3
    bump = 1.0 + np.exp(-np.sum((v - [1.0, 0.0, 0.0]) ** 2, 1) / 0.1)  # off the axis
    flat = 1.0 + 0.01 * np.sin(9 * v[:, 0])  # range 2 % of its mean
    g = _rotation_map(v, 1.0)
    same = HeatLevels(torch.as_tensor(np.stack([height, flat], 1)), f)
    assert same.h.shape[1] == 1  # the flat one skipped
    assert same.changed_share(g, mass) < 0.005
    moved = HeatLevels(torch.as_tensor(np.stack([height, bump], 1)), f).changed_share(g, mass)
    assert moved > 0.05  # where the bump was and where it lands: 8 % of the sphere
    assert HeatLevels(torch.as_tensor(bump[:, None]), f).changed_share(torch.arange(len(v)), mass) == 0.0
    assert HeatLevels(torch.as_tensor(flat[:, None]), f).changed_share(g, mass) == 0.0
