"""symtorch.eval.metrics: geodesic errors, KLC10 rates, orbit errors, group matching."""
import math

import numpy as np
import pytest
import torch
import trimesh
from scipy.spatial import cKDTree

from symtorch.eval import (benchmarks as bm, geodesic_errors, klc_rates, klc_threshold, mesh_rate,
                           normalized_error, orbit_errors, score_group)
from symtorch.geodesics import GeodesicSolver


@pytest.fixture(scope="module")
def sphere():
    """Unit icosphere (642 vertices): exactly symmetric under x -> -x, y -> -y and z -> -z."""
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    verts, faces = np.asarray(m.vertices), np.asarray(m.faces)
    tree = cKDTree(verts)
    maps = {"id": np.arange(len(verts))}
    for axis, name in enumerate("xyz"):
        flip = verts.copy()
        flip[:, axis] *= -1
        dist, maps[name] = tree.query(flip)
        assert dist.max() < 1e-9
    return GeodesicSolver(verts, faces), maps


def test_perfect_map_has_zero_error_and_rate_one(sphere):
    solver, maps = sphere
    pairs = np.stack([np.arange(0, 642, 7), maps["x"][::7]], axis=1)  # (p, g*(p))
    errors = geodesic_errors(solver, maps["x"], pairs)
    assert errors.shape == (len(pairs),) and torch.all(errors == 0)
    assert float(klc_rates(errors, solver.area)) == 1.0
    assert normalized_error(errors, solver.area) == 0.0


def test_identity_on_reflection_ground_truth_scores_low(sphere):
    solver, maps = sphere
    pairs = np.stack([np.arange(642), maps["x"]], axis=1)
    errors = geodesic_errors((solver.verts, solver.faces), maps["id"], pairs)
    rate = float(klc_rates(errors, solver.area))
    on_plane = float((maps["x"] == np.arange(642)).mean())
    assert rate < 0.35, f"rate {rate:.3f}"  # only points near the symmetry plane are within eps
    assert rate >= on_plane
    assert normalized_error(errors, solver.area) > 0.2


def test_rates_and_threshold():
    area = 20 * math.pi * 4.0  # eps = 2
    assert klc_threshold(area) == pytest.approx(2.0)
    rates = klc_rates(torch.tensor([[0.0, 1.9, 2.0, 5.0], [0.0, 0.0, 0.0, 0.0]]), area)
    torch.testing.assert_close(rates, torch.tensor([0.5, 1.0], dtype=torch.float64))
    assert float(klc_rates(np.array([0.5, 1.5]), area, eps=1.0)) == 0.5
    assert mesh_rate([0.5, 0.75, 0.76, 1.0]) == 0.5  # strictly above beta
    assert mesh_rate([0.5, 0.9], beta=0.4) == 1.0
    assert normalized_error([1.0, 3.0], 16.0) == pytest.approx(0.5)


def test_orbit_errors(sphere):
    solver, maps = sphere
    a, b, c = np.flatnonzero(np.abs(solver.verts[:, 0]) > 0.3)[[0, 10, 20]]  # off the plane
    orbits = [np.array([a, maps["x"][a]]), np.array([b, maps["x"][b]]), np.array([c])]
    # The reflection maps each pair onto the other element; the fixed point is not on the plane,
    # so it is moved: its error is the distance to its mirror image.
    err = orbit_errors(solver, maps["x"], orbits)
    assert err.shape == (5,) and torch.all(err[:4] == 0) and err[4] > 0.1
    # The identity leaves everything in place: wrong for orbits unless scored as the identity.
    assert torch.all(orbit_errors(solver, maps["id"], orbits)[:4] > 0.1)
    assert torch.all(orbit_errors(solver, maps["id"], orbits, identity=True) == 0)


def test_hungarian_matching_finds_the_permutation(sphere):
    solver, maps = sphere
    true = [maps[k] for k in ("id", "x", "y", "z")]
    detected = torch.as_tensor(np.stack([maps[k] for k in ("z", "id", "y", "x")]))
    s = score_group(true, detected, solver)
    assert (s.found, s.missed, s.spurious) == (4, 0, 0)
    assert [(t, d) for t, d, _ in s.matches] == [(0, 1), (1, 3), (2, 2), (3, 0)]
    assert torch.all(s.errors == 0) and s.cost.shape == (4, 4)


def test_group_score_counts_missed_and_spurious(sphere):
    solver, maps = sphere
    g = torch.Generator().manual_seed(0)
    random_map = torch.randperm(642, generator=g).numpy()
    true = [maps[k] for k in ("id", "x", "y", "z")]
    s = score_group(true, [maps["z"], random_map, maps["id"], maps["x"]], solver, n_points=50)
    assert (s.found, s.missed, s.spurious) == (3, 1, 1), s.cost
    assert torch.isinf(s.errors[2])  # "y" was not found
    empty = score_group(true, [], solver)
    assert (empty.found, empty.missed, empty.spurious) == (0, 4, 0)


def test_value_errors(sphere):
    solver, maps = sphere
    with pytest.raises(ValueError, match=r"p2p must be \[V\]"):
        geodesic_errors(solver, maps["x"][:-1], np.array([[0, 1]]))
    with pytest.raises(ValueError, match="pairs must be"):
        geodesic_errors(solver, maps["x"], np.array([0, 1]))
    with pytest.raises(ValueError, match="pairs out of range"):
        geodesic_errors(solver, maps["x"], np.array([[0, 642]]))
    with pytest.raises(ValueError, match="mesh must be"):
        geodesic_errors("mesh.off", maps["x"], np.array([[0, 1]]))
    with pytest.raises(ValueError, match="dataset must be one of"):
        bm.load_klc_pairs("FAUST", "tr_reg_000")
    with pytest.raises(ValueError, match="dataset must be one of"):
        bm.list_benchmark("SHREC")
