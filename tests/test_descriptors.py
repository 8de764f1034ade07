"""Tests for symtorch.descriptors: HKS / WKS shapes, batching, identities and symmetry invariance."""
from __future__ import annotations

import math

import pytest
import torch

from shapes import mirror_mesh
from symtorch.descriptors import default_energies, default_times, descriptors, hks, wks
from symtorch.spectrum import laplacian_spectrum


@pytest.fixture(scope="module")
def mirror():
    verts, faces, perm = mirror_mesh(2)
    return laplacian_spectrum(verts, faces, k=30), perm


def test_hks_shape_and_heat_trace(mirror):
    s, _ = mirror
    times = default_times(s.evals, 12)
    assert times.shape == (12,) and (times.diff() > 0).all()
    h = hks(s.evals, s.evecs, times)
    assert h.shape == (162, 12) and h.dtype == torch.float64 and (h > 0).all()
    # mass-weighted sum of HKS over the vertices is the heat trace sum_k exp(-lambda_k t)
    trace = torch.exp(-times[:, None] * s.evals[None, :]).sum(-1)
    torch.testing.assert_close((s.mass[:, None] * h).sum(0), trace, rtol=1e-10, atol=0)
    hn = hks(s.evals, s.evecs, times, normalize=True)
    torch.testing.assert_close((s.mass[:, None] * hn).sum(0), torch.ones(12, dtype=torch.float64))


def test_default_time_grid_follows_paper(mirror):
    s, _ = mirror
    t = default_times(s.evals, 5)
    lam = s.evals[1:]
    torch.testing.assert_close(t[0], 4 * math.log(10) / lam.max())
    torch.testing.assert_close(t[-1], 4 * math.log(10) / lam.min())


def test_wks_shape_and_normalisation(mirror):
    s, _ = mirror
    energies, sigma = default_energies(s.evals, 10)
    assert energies.shape == (10,) and sigma > 0
    w = wks(s.evals, s.evecs, energies, sigma)
    assert w.shape == (162, 10) and (w >= 0).all()
    # each column is a weighted average of evecs**2, so its mass-weighted sum is 1
    torch.testing.assert_close((s.mass[:, None] * w).sum(0), torch.ones(10, dtype=torch.float64))
    # the constant mode has zero weight: changing evecs[:, 0] changes nothing
    e2 = s.evecs.clone()
    e2[:, 0] = 7.0
    torch.testing.assert_close(wks(s.evals, e2, energies, sigma), w)


@pytest.mark.parametrize("fn", ["hks", "wks", "descriptors"])
def test_batch_dims_match_per_item(mirror, fn):
    s, _ = mirror
    g = torch.Generator().manual_seed(0)
    evals = torch.stack([s.evals, s.evals * 1.5, s.evals * 0.7])[None].expand(2, 3, -1)  # [2, 3, K]
    signs = torch.randint(0, 2, (2, 3, 1, 30), generator=g).double() * 2 - 1
    evecs = s.evecs * signs  # [2, 3, V, K]
    times = default_times(s.evals, 8)
    energies, sigma = default_energies(s.evals, 8)
    call = {"hks": lambda e, v: hks(e, v, times),
            "wks": lambda e, v: wks(e, v, energies, sigma),
            "descriptors": lambda e, v: descriptors(e, v, n_hks=4, n_wks=4)}[fn]
    if fn == "descriptors":  # its grids are per spectrum: batch the same spectrum only
        evals = s.evals.expand(2, 3, -1)
    out = call(evals, evecs)
    assert out.shape == (2, 3, 162, 8), fn
    for i in range(2):
        for j in range(3):
            torch.testing.assert_close(out[i, j], call(evals[i, j], evecs[i, j]), msg=f"{fn} [{i},{j}]")
    # eigenvector signs do not matter (squares)
    torch.testing.assert_close(out[0, 0], call(evals[0, 0], s.evecs))


def test_descriptors_columns_unit_mean(mirror):
    s, _ = mirror
    d = descriptors(s.evals, s.evecs, n_hks=6, n_wks=5)
    assert d.shape == (162, 11)
    torch.testing.assert_close(d.mean(0), torch.ones(11, dtype=torch.float64))
    assert descriptors(s.evals, s.evecs, n_hks=0, n_wks=3).shape == (162, 3)
    assert descriptors(s.evals, s.evecs, n_hks=3, n_wks=0).shape == (162, 3)


def test_descriptors_invariant_under_mirror(mirror):
    s, perm = mirror
    d = descriptors(s.evals, s.evecs)
    # f o g = f: the descriptor at the mirror image equals the descriptor at the vertex
    err = (d[perm] - d).abs().max() / d.abs().max()
    assert err < 1e-8, f"mirror invariance error {err:.2e}"
    # and they do tell vertices apart (not a constant function)
    assert d.std(0).median() > 0.05


def test_float32(mirror):
    s, perm = mirror
    d = descriptors(s.evals.float(), s.evecs.float())
    assert d.dtype == torch.float32
    assert (d[perm] - d).abs().max() < 1e-4 * d.abs().max()


def test_value_errors(mirror):
    s, _ = mirror
    times = default_times(s.evals, 4)
    with pytest.raises(ValueError, match="evals has K=29 but evecs has K=30"):
        hks(s.evals[:29], s.evecs, times)
    with pytest.raises(ValueError, match="evals has K=30 but evecs has K=29"):
        wks(s.evals, s.evecs[:, :29], times, 1.0)
    with pytest.raises(ValueError, match="at least two non-zero eigenvalues for a time grid"):
        default_times(s.evals[:2])
    with pytest.raises(ValueError, match="at least two non-zero eigenvalues for an energy grid"):
        default_energies(torch.zeros(5, dtype=torch.float64))


def test_gradient_cross_flips_sign_under_a_reflection():
    from symtorch.descriptors import gradient_cross
    from symtorch.geodesics import GeodesicSolver

    verts, faces, mirror = mirror_mesh(3)
    solver = GeodesicSolver(verts, faces)
    a, b = 5, 200
    fields = solver.distances_from([a, b])  # [2, V]
    images = solver.distances_from([int(mirror[a]), int(mirror[b])])
    pairs = torch.tensor([[0, 1]])
    x = gradient_cross(verts, faces, fields, pairs)[:, 0]  # [V]
    y = gradient_cross(verts, faces, images, pairs)[:, 0]
    assert x.shape == (verts.shape[0],)
    # the reflection maps a -> a', b -> b' and reverses orientation: x(v) = -y(mirror v)
    far = (fields.min(0).values > 0.3) & (images.min(0).values > 0.3)  # away from the sources' kinks
    assert float((x + y[mirror])[far].abs().max()) < 1e-6 * float(x.abs().max()) + 1e-9
    assert float(x[far].abs().mean()) > 0.1  # not trivially zero
    # swapping the pair flips the sign too
    assert torch.allclose(gradient_cross(verts, faces, fields, torch.tensor([[1, 0]]))[:, 0], -x)


def test_descriptors_on_device(mirror, device):
    """HKS, WKS and the combined descriptor on ``device``: the CPU values, and mirror-invariant."""
    s, perm = mirror
    evals, evecs = s.evals.to(device), s.evecs.to(device)
    times = default_times(evals, 4)
    energies, sigma = default_energies(evals, 4)
    assert times.device == evals.device and energies.device == evals.device
    for got, ref in ((hks(evals, evecs, times), hks(s.evals, s.evecs, times.cpu())),
                     (wks(evals, evecs, energies, sigma), wks(s.evals, s.evecs, energies.cpu(), sigma)),
                     (descriptors(evals, evecs), descriptors(s.evals, s.evecs))):
        assert got.device == evecs.device
        torch.testing.assert_close(got.cpu(), ref)
    d = descriptors(evals, evecs)
    assert float((d[perm.to(device)] - d).abs().max()) < 1e-6 * float(d.abs().max())


def test_gradient_cross_on_device(cuda_device):
    from symtorch.descriptors import gradient_cross
    from symtorch.geodesics import GeodesicSolver

    device = cuda_device  # on CPU the comparison would be with itself
    verts, faces, _ = mirror_mesh(2)
    fields = GeodesicSolver(verts, faces).distances_from([5, 100])
    pairs = torch.tensor([[0, 1]])
    got = gradient_cross(verts.to(device), faces.to(device), fields.to(device), pairs.to(device))
    assert got.device == torch.device(device)
    torch.testing.assert_close(got.cpu(), gradient_cross(verts, faces, fields, pairs))
