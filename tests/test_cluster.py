"""symtorch.cluster: batched mean shift."""
import torch

from symtorch.cluster import mean_shift


# ------------------------------------------------------------------------------- building blocks
def test_mean_shift_finds_three_modes():
    g = torch.Generator().manual_seed(0)
    centres = torch.tensor([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]], dtype=torch.float64)
    X = torch.cat([c + 0.05 * torch.randn(20, 2, generator=g, dtype=torch.float64) for c in centres])
    modes, labels, counts = mean_shift(X, bandwidth=0.5)
    assert len(modes) == 3, f"modes {modes}"
    assert counts.tolist() == [20.0, 20.0, 20.0]
    for j in range(3):  # each cluster is one label, its mode near its centre
        assert len(set(labels[20 * j:20 * (j + 1)].tolist())) == 1
        m = modes[labels[20 * j]]
        assert float((m - centres[j]).norm()) < 0.1


# ------------------------------------------------------------------------------------- devices
def test_mean_shift_on_device(cuda_device):
    device = cuda_device  # on CPU the comparison would be with itself
    g = torch.Generator().manual_seed(0)
    centres = torch.tensor([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]], dtype=torch.float64)
    X = torch.cat([c + 0.05 * torch.randn(20, 2, generator=g, dtype=torch.float64) for c in centres])
    modes, labels, counts = mean_shift(X.to(device), bandwidth=0.5)
    ref = mean_shift(X, bandwidth=0.5)
    assert modes.device == labels.device == counts.device == device
    torch.testing.assert_close(modes.cpu(), ref[0])
    assert torch.equal(labels.cpu(), ref[1]) and torch.equal(counts.cpu(), ref[2])
