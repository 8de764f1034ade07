"""symtorch.detect.group_elements: batched ICP, refinement and verification of the group path's elements."""
import torch

from symtorch import shapes


def test_batched_icp_on_device(device):
    """Batched spectral ICP of perturbed quarter turns of the table: the CPU's matrices on ``device``."""
    from symtorch.detect.group_path import batched_icp
    from symtorch.maps import p2p_to_fmap
    from symtorch.spectrum import laplacian_spectrum, band_boundary, solved_bands

    v, f = shapes.table(3)
    s = laplacian_spectrum(v, f, k=30)
    bands = solved_bands(s.evals)
    k0 = band_boundary(bands, 12)
    bands0 = [b for b in bands if b.stop <= k0]
    true = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, shapes.true_symmetries("table"))]
    E = s.evecs[:, :k0]
    C = torch.stack([p2p_to_fmap(p, E, s.mass) for p in true])
    g = torch.Generator().manual_seed(0)
    noisy = C + 0.05 * torch.randn(C.shape, generator=g, dtype=C.dtype)
    src, tgt = torch.arange(0, len(v), 3), torch.arange(len(v))
    ref = batched_icp(noisy, E[src], E[tgt], bands0, n_iter=3, chunk=4)
    got = batched_icp(noisy.to(device), E[src].to(device), E[tgt].to(device), bands0, n_iter=3, chunk=4)
    assert got.device == device and got.shape == C.shape
    torch.testing.assert_close(got.cpu(), ref, atol=1e-8, rtol=0)
    assert float((ref - C).norm(dim=(1, 2)).max()) < float((noisy - C).norm(dim=(1, 2)).min())
