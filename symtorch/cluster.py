"""Mean-shift clustering in torch (Comaniciu & Meer 2002), batched: all points move at once.

Used to find the dense clusters of candidate symmetry matrices (ALGORITHM §5 step 4; the matrices
flattened, Euclidean distance).
"""
from __future__ import annotations

import torch
from torch import Tensor

__all__ = ["mean_shift"]


def mean_shift(X: Tensor, bandwidth: float, n_iter: int = 50, tol: float = 1e-6,
               weights: Tensor | None = None) -> tuple[Tensor, Tensor, Tensor]:
    """Gaussian mean shift, every point moved at once (Comaniciu & Meer 2002).

    Args:
        X: [N, D] points (flattened matrices).
        bandwidth: kernel width (same units as X).
        weights: [N] optional point weights.

    Returns:
        (modes [M, D], labels [N] mode of each point, counts [M] weighted members), modes sorted by
        decreasing count. Modes closer than ``bandwidth / 2`` are merged.
    """
    w = torch.ones(X.shape[0], dtype=X.dtype, device=X.device) if weights is None else weights
    Y = X.clone()
    for _ in range(n_iter):
        K = torch.exp(-torch.cdist(Y, X).square() / (2 * bandwidth ** 2)) * w[None]  # [N, N]
        Yn = (K @ X) / K.sum(1, keepdim=True)
        shift = (Yn - Y).norm(dim=1).max()
        Y = Yn
        if float(shift) < tol * bandwidth:
            break
    # merge converged points into modes (greedy over the densest first)
    dens = (torch.exp(-torch.cdist(Y, X).square() / (2 * bandwidth ** 2)) * w[None]).sum(1)
    labels = torch.full((X.shape[0],), -1, dtype=torch.long, device=X.device)
    close = torch.cdist(Y, Y) < bandwidth / 2  # [N, N]
    modes = []
    while bool((labels < 0).any()):  # one iteration per mode, not per point
        free = labels < 0
        i = int(torch.where(free, dens, torch.full_like(dens, -1.0)).argmax())
        labels[close[i] & free] = len(modes)
        modes.append(Y[i])
    modes_t = torch.stack(modes)
    counts = torch.zeros(len(modes), dtype=X.dtype, device=X.device).index_add_(0, labels, w)
    srt = torch.sort(counts, descending=True, stable=True).indices  # ties keep density order, on any device
    relabel = torch.empty_like(srt)
    relabel[srt] = torch.arange(len(srt), device=X.device)
    return modes_t[srt], relabel[labels], counts[srt]
