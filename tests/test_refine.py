"""Tests for symtorch.refine: the structure projections and the band-by-band upsampling."""
from __future__ import annotations

import pytest
import torch

from symtorch.maps import fmap_to_p2p, p2p_to_fmap
from symtorch.procrustes import block_mask
from symtorch.refine import nearest_involution, project_structure, zoomout_symmetry
from symtorch.sampling import farthest_point_sampling
from symtorch.shapes import mirror_blob, symmetry_maps, true_symmetries
from symtorch.spectrum import band_boundary, laplacian_spectrum, solved_bands


@pytest.fixture(scope="module")
def blob():
    v, f = mirror_blob(3)
    mirror = torch.as_tensor(symmetry_maps(v, true_symmetries("mirror_blob"))[1])
    s = laplacian_spectrum(v, f, k=50)
    return torch.as_tensor(v), s, solved_bands(s.evals), mirror


def _random_involution(K: int, g: torch.Generator) -> torch.Tensor:
    U, _ = torch.linalg.qr(torch.randn(K, K, generator=g, dtype=torch.float64))
    signs = torch.where(torch.rand(K, generator=g) < 0.5, -1.0, 1.0).double()
    return (U * signs) @ U.T


def test_nearest_involution_is_a_symmetric_orthogonal_block_matrix():
    g = torch.Generator().manual_seed(0)
    bands = [range(0, 1), range(1, 3), range(3, 6)]
    J = torch.zeros(6, 6, dtype=torch.float64)
    for b in bands:
        J[b.start:b.stop, b.start:b.stop] = _random_involution(len(b), g)
    noisy = J + 0.05 * torch.randn(6, 6, generator=g, dtype=torch.float64)
    out = nearest_involution(noisy, bands)
    torch.testing.assert_close(out, out.T)
    torch.testing.assert_close(out @ out, torch.eye(6, dtype=torch.float64))
    assert float(out[~block_mask(bands, 6)].abs().max()) == 0.0
    # a small perturbation of an involution projects back near it, and an involution is kept
    assert float((out - J).norm()) < float((noisy - J).norm())
    torch.testing.assert_close(nearest_involution(J, bands), J)


def test_project_structure_without_involution_is_orthogonal():
    g = torch.Generator().manual_seed(1)
    C = torch.randn(5, 5, generator=g, dtype=torch.float64)
    for bands in (None, [range(0, 2), range(2, 5)]):
        Q = project_structure(C, bands, involution=False)
        torch.testing.assert_close(Q.T @ Q, torch.eye(5, dtype=torch.float64))
    assert float(project_structure(C, [range(0, 2), range(2, 5)], involution=False)[:2, 2:].abs().max()) == 0.0


def test_zoomout_grows_a_coarse_mirror_matrix_to_the_exact_mirror(blob):
    v, s, bands, mirror = blob
    k0, kf = band_boundary(bands, 6), band_boundary(bands, 40)
    C0 = p2p_to_fmap(mirror, s.evecs[:, :k0], s.mass)  # only the first few modes are known
    samples = farthest_point_sampling(v, 400)
    for kw in ({}, {"samples": samples, "targets": samples}):
        C = zoomout_symmetry(C0, s.evecs, s.mass, bands, kf, involution=True, **kw)
        assert C.shape == (kf, kf)
        torch.testing.assert_close(C, C.T)
        assert float((fmap_to_p2p(C, s.evecs[:, :kf]) == mirror).double().mean()) > 0.99
    # the start decides which symmetry is grown: the identity's coarse matrix stays the identity
    C = zoomout_symmetry(torch.eye(k0, dtype=torch.float64), s.evecs, s.mass, bands, kf, involution=True,
                         samples=samples)
    assert float((fmap_to_p2p(C, s.evecs[:, :kf]) == torch.arange(len(v))).double().mean()) > 0.99


def test_zoomout_from_a_larger_start_cuts_it_to_the_final_size(blob):
    v, s, bands, mirror = blob
    k_big, kf = band_boundary(bands, 40), band_boundary(bands, 20)
    C0 = p2p_to_fmap(mirror, s.evecs[:, :k_big], s.mass)
    C = zoomout_symmetry(C0, s.evecs, s.mass, bands, kf, involution=True)
    assert C.shape == (kf, kf)
    assert float((fmap_to_p2p(C, s.evecs[:, :kf]) == mirror).double().mean()) > 0.99


def test_zoomout_rejects_a_final_size_inside_a_band():
    C0 = torch.eye(1, dtype=torch.float64)
    evecs = torch.eye(4, dtype=torch.float64)
    with pytest.raises(ValueError, match="cuts a band"):
        zoomout_symmetry(C0, evecs, torch.ones(4, dtype=torch.float64), [range(0, 1), range(1, 3), range(3, 4)], 2)


def test_zoomout_symmetry_on_device(mirror3, cuda_device):
    """The band-by-band upsampling on ``device`` gives the CPU's matrix."""
    from symtorch.refine import zoomout_symmetry
    from symtorch.spectrum import band_boundary, solved_bands

    device = cuda_device  # on CPU the comparison would be with itself
    v, f, mirror = mirror3
    s = laplacian_spectrum(v, f, k=40)
    bands = solved_bands(s.evals)
    k0, kf = band_boundary(bands, 6), band_boundary(bands, 30)
    C0 = p2p_to_fmap(mirror, s.evecs[:, :k0], s.mass)
    samples = farthest_point_sampling(v, 300)
    ref = zoomout_symmetry(C0, s.evecs, s.mass, bands, kf, samples=samples, involution=True)
    got = zoomout_symmetry(C0.to(device), s.evecs.to(device), s.mass.to(device), bands, kf,
                           samples=samples.to(device), involution=True)
    assert got.device == torch.device(device) and got.shape == (kf, kf)
    torch.testing.assert_close(got.cpu(), ref, atol=1e-8, rtol=0)
