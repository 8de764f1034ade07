"""symtorch.point_cloud: input checks, oriented normals, the local fans and triangulation, the k-NN graph."""
import numpy as np
import pytest
import torch

from symtorch.detect.verification import vertex_normals
from symtorch.point_cloud import (MIN_POINTS, check_point_cloud, knn_graph, local_triangles,
                                  local_triangulation, oriented_normals, pca_normals)
from symtorch.sampling import count_components
from symtorch.shapes import mirror_blob


@pytest.fixture(scope="module")
def blob():
    v, f = mirror_blob(3)  # 642 vertices
    return v, f


def test_check_point_cloud_accepts_a_cloud(blob):
    v, _ = blob
    out = check_point_cloud(torch.as_tensor(v, dtype=torch.float32))
    assert out.dtype == np.float64 and out.shape == v.shape


@pytest.mark.parametrize("points, match", [
    (np.random.default_rng(0).normal(size=(MIN_POINTS - 1, 3)), f"at least {MIN_POINTS} points for symmetry detection, got 99"),
    (np.full((200, 3), np.nan), "200 vertices with NaN or inf"),
    (np.zeros((200, 3)), "zero area"),
    (np.c_[np.linspace(0, 1, 200), np.zeros((200, 2))], "coincident or collinear"),
    (np.zeros((200, 2)), r"must be \[V, 3\], got \[200, 2\]"),
])
def test_check_point_cloud_errors(points, match):
    with pytest.raises(ValueError, match=match):
        check_point_cloud(points)


def test_check_point_cloud_refuses_duplicates(blob):
    v, _ = blob
    with pytest.raises(ValueError, match="3 duplicated points"):
        check_point_cloud(np.vstack([v, v[:3]]))


def test_pca_normals_are_unit_and_normal_to_the_surface(blob):
    v, f = blob
    n = pca_normals(v)
    truth = vertex_normals(torch.as_tensor(v), torch.as_tensor(f)).numpy()
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    assert np.abs((n * truth).sum(1)).min() > 0.8


def test_oriented_normals_agree_with_the_mesh_and_point_outward(blob):
    v, f = blob
    n = oriented_normals(v)
    truth = vertex_normals(torch.as_tensor(v), torch.as_tensor(f)).numpy()  # outward: faces wound so
    agree = (n * truth).sum(1) > 0
    assert agree.all(), f"{(~agree).sum()} of {len(v)} normals flipped"


def test_oriented_normals_ignore_a_touching_sheet():
    """Two parallel planes a little closer than the point spacing, joined nowhere: each keeps one
    orientation (the propagation does not jump across the gap and flip a patch). Their PCA
    normals lean where the other sheet's points enter the fit, hence the loose 0.5."""
    g = np.stack(np.meshgrid(np.linspace(0, 1, 20), np.linspace(0, 1, 20)), -1).reshape(-1, 2)
    low = np.c_[g, np.zeros(len(g))]
    high = np.c_[g + 0.5 / 19, np.full(len(g), 0.04)]  # spacing 1/19 = 0.053
    n = oriented_normals(np.vstack([low, high]))
    for part in (n[: len(g)], n[len(g):]):
        assert np.abs(part[:, 2]).min() > 0.5
        assert len(np.unique(np.sign(part[:, 2]))) == 1


def test_local_triangulation_is_consistently_oriented(blob):
    v, f = blob
    n = oriented_normals(v)
    tri = local_triangulation(v, n)
    assert tri.dtype == np.int64 and tri.ndim == 2 and tri.shape[1] == 3
    assert len(np.unique(np.sort(tri, 1), axis=0)) == len(tri)  # each triangle once
    assert np.unique(tri).size == len(v) and count_components(tri, len(v)) == 1
    fn = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    assert ((fn * n[tri].sum(1)).sum(1) > 0).all()
    # the soup covers the surface about once: its area is close to the mesh's
    mesh_area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()
    assert 0.9 < 0.5 * np.linalg.norm(fn, axis=1).sum() / mesh_area < 2.0


def test_knn_graph_is_symmetric_with_euclidean_lengths(blob):
    v, _ = blob
    G = knn_graph(v, k=6)
    assert (abs(G - G.T) > 0).nnz == 0
    i, j = G.nonzero()
    np.testing.assert_allclose(np.asarray(G[i, j]).ravel(), np.linalg.norm(v[i] - v[j], axis=1))
    assert (np.diff(G.indptr) >= 6).all()


def _flat_ellipsoid(n: int = 3000, c: float = 0.08) -> np.ndarray:
    """A Fibonacci sphere squashed to height ``2 c``: its two faces lie about one point spacing
    apart (spacing ~0.065, gap 0.1 near the middle)."""
    i = np.arange(n) + 0.5
    phi, th = np.arccos(1 - 2 * i / n), np.pi * (1 + 5 ** 0.5) * i
    return np.c_[np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), c * np.cos(phi)]


def test_local_triangles_drop_the_bridges_between_close_sheets():
    """The fans of a flat ellipsoid bridge its two faces: from the top's centre to the bottom's, the
    heat method on every fan takes the short cut (~0.1); without the bridging triangles it goes
    round the rim (~2), and the soup stays one piece."""
    from symtorch.geodesics import GeodesicSolver

    v = _flat_ellipsoid()
    top, bottom = int(np.argmax(v[:, 2])), int(np.argmin(v[:, 2]))
    n = oriented_normals(v)
    assert (np.sign(n[:, 2]) == np.sign(v[:, 2]))[np.abs(v[:, 2]) > 0.04].all()
    every = local_triangles(v, n, min_cos=None)
    kept = local_triangles(v, n, min_cos=0.0)
    assert len(kept) < 0.6 * len(every) and count_components(kept, len(v)) == 1
    short = GeodesicSolver(v, every).distances_from([top])[0, bottom]
    around = GeodesicSolver(v, kept).distances_from([top])[0, bottom]
    assert short < 0.5 < 1.8 < around < 2.3, (float(short), float(around))


def test_local_triangles_keep_the_soup_connected(blob):
    """With every triangle refused (min_cos above 1), each point keeps its own fan: nothing is cut."""
    v, _ = blob
    every = local_triangles(v, min_cos=None)
    assert every.shape[1] == 3 and (every[:, 0][:, None] != every[:, 1:]).all()
    kept = local_triangles(v, min_cos=1.5)
    assert count_components(kept, len(v)) == 1 and np.unique(kept).size == len(v)


def test_fan_spectrum_is_the_surfaces(blob):
    """The fans' spectrum (robust-laplacian's count: each triangle in three fans) agrees with the
    mesh's to a few percent (``point_cloud_laplacian``'s, on this coarse blob, to ~10 %); its
    ``scale`` is the unit-area one (uncorrected, both would be off by 3 and sqrt(3))."""
    from symtorch.point_cloud import fan_spectrum
    from symtorch.spectrum import laplacian_spectrum

    v, f = blob
    fans = local_triangles(v, min_cos=None)
    spec = fan_spectrum(v, fans, k=12)
    mesh = laplacian_spectrum(v, f, k=12)
    cloud = laplacian_spectrum(v, None, k=12)
    for other, tol in ((mesh, 0.05), (cloud, 0.15)):
        np.testing.assert_allclose(spec.evals[1:].numpy(), other.evals[1:].numpy(), rtol=tol)
        assert abs(spec.scale / other.scale - 1) < 0.04
    np.testing.assert_allclose(float(spec.mass.sum()), 1.0, rtol=1e-12)
