"""symtorch.remesh: exact closest points, orientation, pinches, the same-sheet nearest vertex, ACVD."""
import numpy as np
import pytest

from symtorch.io import mesh_report
from symtorch.remesh import (_closest_on_triangles, clean_remesh, closest_points, count_pinched_vertices,
                             geodesic_nearest_vertices, nearest_vertices, orient_faces, orientation_report,
                             projected_vertices, same_sheet_nearest_vertices)
from symtorch.shapes import icosphere, mirror_blob


def test_closest_on_triangles_beats_dense_samples():
    g = np.random.default_rng(0)
    a, b, c = g.normal(size=(3, 200, 3))
    p = 2 * g.normal(size=(200, 3))
    bary = _closest_on_triangles(p, a, b, c)
    assert (bary >= -1e-12).all() and np.allclose(bary.sum(1), 1)
    d = np.linalg.norm(bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c - p, axis=1)
    u = g.random((2000, 2))
    u[u.sum(1) > 1] = 1 - u[u.sum(1) > 1]
    samples = a[:, None] + (b - a)[:, None] * u[None, :, :1] + (c - a)[:, None] * u[None, :, 1:]
    assert (np.linalg.norm(samples - p[:, None], axis=2).min(1) >= d - 1e-12).all()


def test_closest_points_matches_brute_force():
    verts, faces = mirror_blob(2)
    q = 0.8 * np.random.default_rng(1).normal(size=(100, 3))
    sp = closest_points(verts, faces, q)
    tri = verts[faces]
    for i in range(0, 100, 7):
        P = np.repeat(q[i:i + 1], len(faces), 0)
        b = _closest_on_triangles(P, tri[:, 0], tri[:, 1], tri[:, 2])
        best = np.linalg.norm(np.einsum("mk,mkd->md", b, tri) - P, axis=1).min()
        assert abs(sp.dist[i] - best) < 1e-12, i
    np.testing.assert_allclose(np.linalg.norm(sp.points - q, axis=1), sp.dist, atol=1e-12)
    on = closest_points(verts, faces, verts)  # vertices are their own closest points
    assert on.dist.max() < 1e-12


def test_orient_faces_repairs_random_flips():
    verts, faces = mirror_blob(2)
    flipped = faces.copy()
    pick = np.random.default_rng(2).random(len(faces)) < 0.4
    flipped[pick] = flipped[pick, ::-1]
    assert orientation_report(verts, flipped)["n_misoriented_edges"] > 0
    np.testing.assert_array_equal(orient_faces(verts, flipped), faces)
    inward = orient_faces(verts, flipped, outward=False)
    rep = orientation_report(verts, inward)
    assert rep["n_misoriented_edges"] == 0 and not rep["outward"]


def test_count_pinched_vertices():
    verts, faces = icosphere(1)
    assert count_pinched_vertices(faces, len(verts)) == 0
    other = faces + len(verts)
    other[other == len(verts)] = 0  # two spheres touching at vertex 0
    assert count_pinched_vertices(np.vstack([faces, other]), 2 * len(verts)) == 1


def test_clean_remesh_drops_collapsed_duplicate_and_islands():
    verts, faces = icosphere(1)
    island = np.array([[10.0, 0, 0], [11, 0, 0], [10, 1, 0]])
    v = np.vstack([verts, island])
    n = len(verts)
    f = np.vstack([faces, faces[:3], [[0, 0, 1]], [[n, n + 1, n + 2]]])
    cv, cf = clean_remesh(v, f)
    np.testing.assert_array_equal(cv, verts)
    np.testing.assert_array_equal(cf, faces)


def test_same_sheet_nearest_does_not_cross_a_gap():
    # a flat ellipsoid: top and bottom sheets 0.04 apart in the middle, joined only at the rim
    verts, faces = icosphere(4)
    verts = verts * [1.0, 1.0, 0.02]
    g = np.random.default_rng(3)
    top = np.flatnonzero(verts[:, 2] > 0)
    bottom = np.flatnonzero(verts[:, 2] < 0)
    # sparse sites on the top sheet, dense ones on the bottom: many top vertices have their
    # Euclidean nearest site right below them, across the gap
    chosen = np.concatenate([g.choice(top, 30, replace=False), g.choice(bottom, 400, replace=False)])
    sites = verts[chosen]
    site_top = sites[:, 2] > 0
    near = nearest_vertices(sites, verts)
    ids, replaced = same_sheet_nearest_vertices(verts, faces, sites)
    inner = (verts[:, 2] > 0) & (np.linalg.norm(verts[:, :2], axis=1) < 0.5)  # far from the rim
    crossing = inner & ~site_top[near]
    assert crossing.sum() > 20, crossing.sum()
    assert site_top[ids[crossing]].all() and replaced[crossing].all()
    same = inner & site_top[near]  # where the nearest site is on the same sheet, it is kept
    assert same.sum() > 5
    np.testing.assert_array_equal(ids[same], near[same])
    assert not replaced[same].any()
    assert site_top[geodesic_nearest_vertices(verts, faces, sites)[inner]].all()


def test_projected_vertices_are_corners_of_the_closest_face():
    verts, faces = mirror_blob(2)
    q = verts[::5] * 1.01
    ids = projected_vertices(verts, faces, q)
    sp = closest_points(verts, faces, q)
    assert (faces[sp.face] == ids[:, None]).any(1).all()


def test_remesh_acvd_gives_a_clean_independent_mesh():
    pytest.importorskip("pyacvd", reason="remesh_acvd needs pyacvd (pip install pyacvd)")
    from symtorch.remesh import remesh_acvd

    verts, faces = mirror_blob(3)
    a = remesh_acvd(verts, faces, n_verts=250, subdivide=2, seed=0)
    b = remesh_acvd(verts, faces, n_verts=250, subdivide=2, seed=1)
    for v, f in (a, b):
        rep = mesh_report(v, f)
        assert rep["n_components"] == 1 and rep["n_degenerate_faces"] == 0 and rep["n_unreferenced"] == 0
        assert abs(rep["n_vertices"] - 250) <= 5, rep
        assert closest_points(verts, faces, v).dist.max() < 1e-3  # vertices on the source surface
    assert not (a[0].shape == b[0].shape and np.allclose(a[0], b[0]))  # the seed changes the mesh
