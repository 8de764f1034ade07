import numpy as np
import pytest
import torch
import trimesh

from symtorch.geodesics import (GeodesicSolver, disk_indicators, geodesic_distances,
                                graph_distances, voronoi_cells)

RADIUS = 2.0


@pytest.fixture(scope="module")
def sphere():
    """Icosphere (2562 vertices) of radius 2 and its exact great-circle distance function."""
    m = trimesh.creation.icosphere(subdivisions=4, radius=RADIUS)
    verts, faces = np.asarray(m.vertices), np.asarray(m.faces)
    unit = verts / np.linalg.norm(verts, axis=1, keepdims=True)

    def great_circle(src):
        return RADIUS * np.arccos(np.clip(unit[src] @ unit.T, -1.0, 1.0))  # [S, V]

    return verts, faces, great_circle


@pytest.fixture(scope="module")
def solver(sphere):
    verts, faces, _ = sphere
    return GeodesicSolver(verts, faces)


SOURCES = [0, 17, 100, 2000]


def test_heat_matches_great_circle(sphere, solver):
    _, _, great_circle = sphere
    D = solver.distances_from(SOURCES)
    assert D.shape == (len(SOURCES), solver.n_verts) and D.dtype == torch.float64
    G = great_circle(SOURCES)
    far = G > 0.2 * RADIUS  # relative error is meaningless next to the source
    rel = np.abs(D.numpy() - G)[far] / G[far]
    assert np.median(rel) < 0.02, f"median relative error {np.median(rel):.4f}"
    assert np.quantile(rel, 0.95) < 0.05, f"95th percentile {np.quantile(rel, 0.95):.4f}"
    assert np.abs(D.numpy() - G).max() < 0.05 * np.pi * RADIUS
    assert torch.all(D[torch.arange(len(SOURCES)), torch.tensor(SOURCES)] == 0)


def test_rows_follow_source_order_with_repeats(solver):
    D = solver.distances_from([100, 0, 100])
    torch.testing.assert_close(D[0], D[2])
    torch.testing.assert_close(D[1], solver.distances_from(0)[0])


def test_multisource_distance_is_nearest(sphere, solver):
    _, _, great_circle = sphere
    d = solver.distance(SOURCES)
    assert d.shape == (solver.n_verts,)
    nearest = great_circle(SOURCES).min(axis=0)
    assert np.abs(d.numpy() - nearest).max() < 0.05 * np.pi * RADIUS
    assert torch.all(d[SOURCES] < 1e-6)


def test_pairwise_is_symmetric(solver):
    pts = [3, 50, 400, 900, 2500]
    P = solver.pairwise(pts)
    assert P.shape == (5, 5)
    torch.testing.assert_close(P, P.mT)
    assert torch.all(P.diagonal() == 0) and torch.all(P + torch.eye(5, dtype=P.dtype) > 0)


def test_graph_distances_bound_geodesics(sphere):
    verts, faces, great_circle = sphere
    Dg = graph_distances(verts, faces, SOURCES).numpy()
    G = great_circle(SOURCES)
    # Edge paths are longer than geodesics, except for the chord-vs-arc shortfall (< 0.1 %).
    assert np.all(Dg >= G * (1 - 1e-3) - 1e-9)
    assert np.median((Dg - G)[G > 0] / G[G > 0]) < 0.15


def test_one_off_function_and_output_dtype(sphere, solver):
    verts, faces, _ = sphere
    D = geodesic_distances(torch.as_tensor(verts, dtype=torch.float32), faces, [0, 17])
    assert D.dtype == torch.float32
    torch.testing.assert_close(D, solver.distances_from([0, 17]).float())
    Dg = geodesic_distances(verts, faces, 5, method="graph")
    assert Dg.shape == (1, len(verts))


@pytest.mark.parametrize("profile", ["gaussian", "smoothstep"])
def test_disk_indicator_is_one_at_source_and_decays(solver, profile):
    radius = 0.5
    D = solver.distances_from(SOURCES)
    ind = disk_indicators(D, radius, profile=profile)
    assert ind.shape == (solver.n_verts, len(SOURCES))
    torch.testing.assert_close(ind[SOURCES, torch.arange(len(SOURCES))],
                               torch.ones(len(SOURCES), dtype=ind.dtype), msg=profile)
    assert torch.all((ind >= 0) & (ind <= 1))
    for s in range(len(SOURCES)):  # non-increasing in the distance
        order = torch.argsort(D[s])
        assert torch.all(torch.diff(ind[order, s]) <= 1e-12), profile
    assert torch.all(ind[D.mT > 3 * radius] < 1e-3), profile
    if profile == "smoothstep":
        assert torch.all(ind[D.mT >= radius] == 0)
    torch.testing.assert_close(disk_indicators(solver, radius, sources=SOURCES, profile=profile), ind)


def test_disk_indicator_is_differentiable():
    d = torch.tensor([[0.0, 0.3, 1.2]], dtype=torch.float64, requires_grad=True)
    torch.autograd.gradcheck(lambda x: disk_indicators(x, 0.7), (d,))


def test_errors(sphere, solver):
    verts, faces, _ = sphere
    with pytest.raises(ValueError, match="sources out of range"):
        solver.distances_from([0, len(verts)])
    with pytest.raises(ValueError, match="sources is empty"):
        solver.distance([])
    with pytest.raises(ValueError, match="integer vertex ids"):
        solver.distances_from([0.5])
    with pytest.raises(ValueError, match="radius must be > 0"):
        disk_indicators(torch.zeros(1, 3), 0.0)
    with pytest.raises(ValueError, match="profile must be"):
        disk_indicators(torch.zeros(1, 3), 1.0, profile="box")
    with pytest.raises(ValueError, match="sources is required"):
        disk_indicators(solver, 1.0)
    with pytest.raises(ValueError, match="method must be"):
        geodesic_distances(verts, faces, [0], method="exact")


def test_voronoi_cells_follow_graph_distance(sphere):
    verts, faces, _ = sphere
    sites = np.array([0, 17, 100, 2000])
    cells = voronoi_cells(verts, faces, sites)
    assert cells.shape == (len(verts),) and cells.dtype == torch.long
    assert torch.equal(cells[sites], torch.arange(4))
    D = graph_distances(verts, faces, sites).numpy()  # [4, V]
    # each vertex lies in the cell of a graph-nearest site (ties may go either way)
    own = D[cells.numpy(), np.arange(len(verts))]
    assert np.allclose(own, D.min(axis=0))


def test_voronoi_cells_mark_unreached_components(sphere):
    verts, faces, _ = sphere
    two_v = np.concatenate([verts, verts + 10.0])
    two_f = np.concatenate([faces, faces + len(verts)])
    cells = voronoi_cells(two_v, two_f, [0, 5])
    assert bool((cells[: len(verts)] >= 0).all()) and bool((cells[len(verts):] == -1).all())


def test_distances_from_reads_back_what_it_solved(sphere):
    verts, faces = sphere[:2]
    solver = GeodesicSolver(verts, faces)
    # potpourri3d is a dependency: a solver without the heat method is a broken install, not a skip
    assert solver.uses_heat, "GeodesicSolver fell back to Dijkstra: is potpourri3d importable?"
    calls = []

    class Counting:  # the heat solver, counting its solves
        def __init__(self, inner):
            self.inner = inner

        def compute_distance(self, src):
            calls.append(src)
            return self.inner.compute_distance(src)

    fresh = GeodesicSolver(verts, faces).distances_from([3, 7, 11, 3])
    solver._heat = Counting(solver._heat)
    first = solver.distances_from([3, 7])
    both = solver.distances_from([11, 3, 7, 11])
    assert sorted(calls) == [3, 7, 11]  # 3 and 7 read back, 11 solved once
    torch.testing.assert_close(both[1:3], first, rtol=0, atol=0)
    torch.testing.assert_close(both[[1, 2, 0]], fresh[[0, 1, 2]], rtol=0, atol=0)
    # the store is bounded: beyond it, fields are solved again
    small = GeodesicSolver(verts, faces)
    small._max_fields = 2
    small.distances_from([1, 2, 3, 4])
    assert len(small._fields) == 2


# ------------------------------------------------------------------------------------ point clouds
@pytest.fixture(scope="module")
def cloud_solver(sphere):
    verts, _, _ = sphere
    return GeodesicSolver(verts, None)


def test_point_cloud_heat_matches_great_circle(sphere, cloud_solver):
    """Without faces the solver runs potpourri3d's point-cloud heat method, as accurate here."""
    _, _, great_circle = sphere
    assert cloud_solver.is_point_cloud and cloud_solver.uses_heat
    D = cloud_solver.distances_from(SOURCES)
    assert D.shape == (len(SOURCES), cloud_solver.n_verts) and D.dtype == torch.float64
    G = great_circle(SOURCES)
    far = G > 0.2 * RADIUS
    rel = np.abs(D.numpy() - G)[far] / G[far]
    assert rel.mean() < 0.03 and rel.max() < 0.15, (rel.mean(), rel.max())
    assert torch.all(D[torch.arange(len(SOURCES)), torch.tensor(SOURCES)] < 0.05 * RADIUS)


def test_point_cloud_area_repr_and_graph_fallback(sphere, cloud_solver):
    verts, _, great_circle = sphere
    assert abs(cloud_solver.area - 4 * np.pi * RADIUS ** 2) < 0.02 * 4 * np.pi * RADIUS ** 2
    assert "point cloud" in repr(cloud_solver) and "method=heat" in repr(cloud_solver)
    D = graph_distances(verts, None, SOURCES)  # Dijkstra on the k-nearest-neighbour graph
    G = great_circle(SOURCES)
    # edge paths are longer than geodesics, up to the chord-vs-arc shortfall
    assert np.all(D.numpy() >= G * (1 - 1e-3) - 1e-9) and np.median(D.numpy() / np.maximum(G, 1e-9)) < 1.2
    D2 = geodesic_distances(verts, None, SOURCES, method="graph")
    assert torch.equal(D, D2)
    P = cloud_solver.pairwise(SOURCES)
    assert torch.equal(P, P.mT) and torch.all(P.diagonal() == 0)
