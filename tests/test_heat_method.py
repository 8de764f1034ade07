import numpy as np
import potpourri3d as pp3d
import pytest
import torch
import trimesh

from symtorch.geodesics import GeodesicSolver
from symtorch.heat_method import BLOCK, BatchedHeatMethod

RADIUS = 2.0


@pytest.fixture(scope="module")
def sphere():
    m = trimesh.creation.icosphere(subdivisions=4, radius=RADIUS)
    return np.asarray(m.vertices), np.asarray(m.faces)


@pytest.fixture(scope="module")
def bumpy():
    """A sphere with a non-uniform bump pattern and jittered vertices: no symmetry, uneven triangles."""
    m = trimesh.creation.icosphere(subdivisions=4)
    v = np.asarray(m.vertices)
    rng = np.random.default_rng(3)
    r = 1.0 + 0.15 * np.sin(3 * v[:, 0] + 1) * np.cos(2 * v[:, 1]) + 0.01 * rng.standard_normal(len(v))
    return v * r[:, None], np.asarray(m.faces)


def test_matches_great_circle(sphere):
    verts, faces = sphere
    heat = BatchedHeatMethod.build(verts, faces)
    src = np.array([0, 17, 100, 2000])
    D = heat.distances_from(src)
    unit = verts / np.linalg.norm(verts, axis=1, keepdims=True)
    G = RADIUS * np.arccos(np.clip(unit[src] @ unit.T, -1.0, 1.0))
    far = G > 0.2 * RADIUS
    rel = np.abs(D - G)[far] / G[far]
    assert D.shape == (4, len(verts))
    assert np.allclose(D[np.arange(4), src], 0.0)
    # the bounds potpourri3d's solver meets in tests/test_geodesics.py
    assert np.median(rel) < 0.02 and np.quantile(rel, 0.95) < 0.05
    assert np.abs(D - G).max() < 0.05 * np.pi * RADIUS


def test_agrees_with_potpourri3d_on_uneven_triangles(bumpy):
    verts, faces = bumpy
    src = np.arange(0, len(verts), 97)
    D = BatchedHeatMethod.build(verts, faces).distances_from(src)
    plain = pp3d.MeshHeatMethodDistanceSolver(verts, faces, t_coef=1.0, use_robust=False)
    robust = pp3d.MeshHeatMethodDistanceSolver(verts, faces, t_coef=1.0, use_robust=True)
    P = np.stack([plain.compute_distance(int(s)) for s in src])
    R = np.stack([robust.compute_distance(int(s)) for s in src])
    # the same method on the same operators: solver tolerance; the robust cover: a little more
    assert np.abs(D - P).mean() < 1e-3 * P.mean()
    assert np.abs(D - R).mean() < 5e-3 * R.mean()


def test_blocks_give_what_single_sources_give(bumpy):
    verts, faces = bumpy
    heat = BatchedHeatMethod.build(verts, faces)
    src = np.arange(BLOCK + 5) * 31  # two blocks, the second partial
    D = heat.distances_from(src)
    for i in (0, BLOCK - 1, BLOCK, BLOCK + 4):
        np.testing.assert_allclose(D[i], heat.distances_from(src[i:i + 1])[0], atol=1e-10)


def test_refuses_meshes_it_does_not_suit(sphere):
    verts, faces = sphere
    two = np.concatenate([verts, verts + 10.0]), np.concatenate([faces, faces + len(verts)])
    assert BatchedHeatMethod.build(*two) is None  # two pieces: the Poisson constant is free on each
    isolated = np.concatenate([verts, [[5.0, 5.0, 5.0]]]), faces
    assert BatchedHeatMethod.build(*isolated) is None


def test_geodesic_solver_backend(sphere, bumpy):
    verts, faces = bumpy
    fast = GeodesicSolver(verts, faces, backend="batched")
    assert fast.backend == "batched" and fast.uses_heat
    ref = GeodesicSolver(verts, faces)
    assert ref.backend == "potpourri3d"
    src = [0, 5, 900]
    a, b = fast.distances_from(src), ref.distances_from(src)
    assert a.shape == b.shape and a.dtype == torch.float64
    assert (a - b).abs().mean() < 5e-3 * b.mean()
    assert torch.allclose(fast.distance(5), ref.distance(5))  # multi-source: potpourri3d in both
    # where the mesh does not suit it, the batched backend falls back to potpourri3d
    v2, f2 = sphere
    two = GeodesicSolver(np.concatenate([v2, v2 + 10.0]), np.concatenate([f2, f2 + len(v2)]),
                         backend="batched")
    assert two.backend == "potpourri3d" and two.distances_from([0]).shape == (1, 2 * len(v2))
    with pytest.raises(ValueError, match="backend"):
        GeodesicSolver(verts, faces, backend="exact")


def sheared_grid(n: int = 20, shear: float = 2.0):
    """A flat grid of parallelograms, each split along its long diagonal: every diagonal has two
    obtuse opposite angles (a negative cotan weight), as on sliver remeshes."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    verts = np.stack([i + shear * j, 0.5 * j, np.zeros_like(i)], axis=-1).reshape(-1, 3).astype(float)
    idx = lambda a, b: a * n + b  # noqa: E731
    a, b, c, d = (idx(i[:-1, :-1], j[:-1, :-1]), idx(i[1:, :-1], j[1:, :-1]),
                  idx(i[:-1, 1:], j[:-1, 1:]), idx(i[1:, 1:], j[1:, 1:]))
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                            np.stack([a, d, c], -1).reshape(-1, 3)])
    return verts, faces


def test_refuses_meshes_that_are_far_from_delaunay(sphere):
    import scipy.sparse as sp

    from symtorch.heat_method import MAX_NON_DELAUNAY, non_delaunay_share

    verts, faces = sheared_grid()
    assert BatchedHeatMethod.build(verts, faces) is None
    solver = GeodesicSolver(verts, faces, backend="batched")
    assert solver.backend == "potpourri3d"  # the robust solver takes over
    # the measure itself: a regular mesh has no such edge, the sheared grid a third of them
    heat = BatchedHeatMethod.build(*sphere)
    assert heat.non_delaunay == 0.0
    lap = sp.csr_matrix(np.array([[1.0, -1.0, 0.5], [-1.0, 1.0, 0.0], [0.5, 0.0, -0.5]]))
    assert non_delaunay_share(lap) == pytest.approx(0.5)  # edges (0,1) and (0,2): one negative weight
    assert MAX_NON_DELAUNAY < 0.05
