"""Constraint columns (ALGORITHM §3): the pull-back of a symmetry maps them as the Procrustes assumes."""
import math

import torch

from shapes import mirror_mesh
from symtorch.detect.constraints import DISK_RADII, descriptor_coefficients, disk_coefficients
from symtorch.descriptors import descriptors
from symtorch.geodesics import GeodesicSolver
from symtorch.maps import p2p_to_fmap
from symtorch.spectrum import band_boundary, eigen_bands, laplacian_spectrum


def test_a_symmetry_maps_disks_at_images_to_disks_at_points_and_fixes_descriptors():
    verts, faces, mirror = mirror_mesh(3)
    s = laplacian_spectrum(verts, faces, k=40)
    K = band_boundary(eigen_bands(s.evals), 20)
    E = s.evecs[:, :K]
    C = p2p_to_fmap(mirror, E, s.mass)  # the pull-back f -> f ∘ g, coefficients
    solver = GeodesicSolver(verts * s.scale, faces)
    pts = torch.tensor([3, 40, 200, 511])
    at_pts = disk_coefficients(E, s.mass, solver.distances_from(pts))  # [n, R, K]
    at_images = disk_coefficients(E, s.mass, solver.distances_from(mirror[pts]))
    assert at_pts.shape == (4, len(DISK_RADII), K)
    torch.testing.assert_close(at_pts.norm(dim=-1), torch.ones(4, len(DISK_RADII), dtype=E.dtype))
    # 1_{g(p)} ∘ g = 1_p: C maps the image's disk to the point's
    torch.testing.assert_close(at_images @ C.mT, at_pts, atol=1e-6, rtol=0)
    assert float((at_images - at_pts).abs().max()) > 0.1  # the points are not on the mirror plane
    desc = descriptors(s.evals, s.evecs)
    A = descriptor_coefficients(E, s.mass, desc)  # [K, D]
    torch.testing.assert_close(A.norm(dim=0), torch.full((desc.shape[1],), 1 / math.sqrt(desc.shape[1]),
                                                         dtype=E.dtype))
    torch.testing.assert_close(C @ A, A, atol=1e-6, rtol=0)
