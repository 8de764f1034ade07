"""Tests for symtorch.vertex_to_point: the faces around each vertex, and images as points of
triangles recovered from their spectral embedding."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from symtorch.shapes import ellipsoid
from symtorch.spectrum import laplacian_spectrum
from symtorch.vertex_to_point import vertex_faces, vertex_to_point


@pytest.fixture(scope="module")
def mesh():
    verts, faces = ellipsoid(2)
    s = laplacian_spectrum(verts, faces, k=30)
    return np.asarray(verts), torch.as_tensor(np.asarray(faces), dtype=torch.long), s.evecs


def test_vertex_faces_lists_every_face_at_its_three_vertices(mesh):
    verts, faces, _ = mesh
    vf = vertex_faces(faces, len(verts))
    deg = np.bincount(faces.reshape(-1).numpy(), minlength=len(verts))
    assert vf.shape == (len(verts), deg.max())
    assert torch.equal((vf >= 0).sum(1), torch.as_tensor(deg))
    for v in (0, 7, len(verts) - 1):
        listed = set(vf[v][vf[v] >= 0].tolist())
        assert listed == set(torch.nonzero((faces == v).any(1)).flatten().tolist())


def test_vertex_faces_pads_an_isolated_vertex():
    vf = vertex_faces(torch.tensor([[0, 1, 2]]), 4)
    assert vf[3].tolist() == [-1]


def test_a_point_inside_a_triangle_is_recovered_from_its_embedding(mesh):
    """The embedding is affine over each triangle: the target of a point inside one gives back its
    triangle and barycentric coordinates, starting from any vertex of that triangle."""
    verts, faces, E = mesh
    vf = vertex_faces(faces, len(verts))
    rng = np.random.default_rng(0)
    fi = torch.as_tensor(rng.choice(len(faces), 40, replace=False))
    b = torch.as_tensor(rng.dirichlet([2.0, 2.0, 2.0], size=40), dtype=E.dtype)
    tri = faces[fi]
    target = (b[..., None] * E[tri]).sum(1)
    nearest = tri[torch.arange(40), b.argmax(1)]
    got_tri, got_b = vertex_to_point(E, faces, vf, target, nearest)
    point = (got_b[..., None] * torch.as_tensor(verts)[got_tri]).sum(1)
    truth = (b[..., None] * torch.as_tensor(verts)[tri]).sum(1)
    assert torch.allclose(point, truth, atol=1e-8)
    assert torch.allclose(got_b.sum(1), torch.ones(40, dtype=E.dtype))


def test_a_target_off_the_surface_lands_on_the_nearest_edge_or_vertex(mesh):
    """Barycentric coordinates stay in the simplex: a target beyond a vertex gives that vertex."""
    verts, faces, E = mesh
    vf = vertex_faces(faces, len(verts))
    v = 11
    others = E[faces[vf[v][vf[v] >= 0]]].mean(1)  # centres of the faces around v
    target = E[v] + 3.0 * (E[v] - others.mean(0))  # pushed outwards, away from every face
    tri, b = vertex_to_point(E, faces, vf, target[None], torch.tensor([v]))
    assert (b >= -1e-12).all() and torch.allclose(b.sum(1), torch.ones(1, dtype=E.dtype))
    assert int(tri[0, b[0].argmax()]) == v and float(b.max()) > 0.5
