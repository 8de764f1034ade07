"""Constraint columns (ALGORITHM §3): the pull-back of a symmetry maps them as the Procrustes assumes."""
import math

import torch

from shapes import mirror_mesh
from symtorch.detect.constraints import DISK_RADII, descriptor_coefficients, dipole_coefficients, disk_coefficients
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
    # the dipoles too: at the images, each towards the image of its partner, map to the points'
    dip_pts = dipole_coefficients(E, s.mass, solver.distances_from(pts), pts)  # [n, n, R, K]
    dip_images = dipole_coefficients(E, s.mass, solver.distances_from(mirror[pts]), mirror[pts])
    torch.testing.assert_close(dip_images @ C.mT, dip_pts, atol=1e-6, rtol=0)


def test_dipoles_see_what_a_disk_on_a_mirror_plane_cannot():
    """A disk centred on the plane z = 0 of a sphere is even under that mirror: no coefficient on
    the odd function z. Tilted towards a point above the plane it has one; towards a point on the
    plane it has none again (both points fixed by the mirror)."""
    import trimesh


    m = trimesh.creation.icosphere(4)
    v = torch.as_tensor(m.vertices)
    mass = torch.as_tensor(m.area_faces).repeat_interleave(3).new_zeros(len(v))
    mass.index_add_(0, torch.as_tensor(m.faces).flatten(), torch.as_tensor(m.area_faces).repeat_interleave(3) / 3)
    v_unit = v / float(mass.sum()) ** 0.5  # unit area, the units of EPS_KLC
    points = [int((v - torch.tensor(p, dtype=v.dtype)).norm(dim=1).argmin()) for p in
              ([1.0, 0, 0], [0, 0.6, 0.8], [0, 1.0, 0])]
    assert all(abs(float(v[p, 2])) < 1e-9 for p in (points[0], points[2]))  # on the plane
    dist = torch.cdist(v_unit[points], v_unit)  # [3, V]: any mirror-invariant distance will do
    basis = torch.stack([torch.ones(len(v)), v[:, 2]], 1).to(v.dtype)  # constant, the odd z
    disk = disk_coefficients(basis, mass, dist)
    dip = dipole_coefficients(basis, mass, dist, points)
    assert disk[0, :, 1].abs().max() < 1e-9
    assert dip[0, 1, :, 1].abs().min() > 0.1  # towards the point above the plane
    assert dip[0, 2, :, 1].abs().max() < 1e-9  # towards a point on it
    assert dip[0, 0].abs().max() == 0  # no dipole towards itself
