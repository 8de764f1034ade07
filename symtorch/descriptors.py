"""Heat and wave kernel signatures (Sun et al. 2009; Aubry et al. 2011), batched over leading dims."""
from __future__ import annotations

import math

import torch
from torch import Tensor

from .orientation import face_geometry, face_gradients, faces_to_vertices


def _check(evals: Tensor, evecs: Tensor) -> None:
    if evals.shape[-1] != evecs.shape[-1]:
        raise ValueError(f"evals has K={evals.shape[-1]} but evecs has K={evecs.shape[-1]}")


def default_times(evals: Tensor, n_times: int = 16) -> Tensor:
    """[T] log-spaced HKS times from 4 ln10 / lambda_max to 4 ln10 / lambda_1 (Sun et al. 2009).

    Args:
        evals: [K] ascending eigenvalues (the constant one, ~0, is skipped).
    """
    lam = evals[evals > 1e-8 * evals.max().clamp_min(1e-12)]
    if lam.numel() < 2:
        raise ValueError("need at least two non-zero eigenvalues for a time grid")
    lo, hi = 4 * math.log(10) / lam.max(), 4 * math.log(10) / lam.min()
    return torch.logspace(math.log10(lo), math.log10(hi), n_times, dtype=evals.dtype,
                          device=evals.device)


def hks(evals: Tensor, evecs: Tensor, times: Tensor, normalize: bool = False) -> Tensor:
    """Heat kernel signature at each vertex.

    Args:
        evals: [..., K] Laplacian eigenvalues, ascending.
        evecs: [..., V, K] eigenvectors, mass-orthonormal.
        times: [T] diffusion times.
        normalize: divide each column by its heat trace ``sum_k exp(-evals_k t)`` (scale-free).

    Returns:
        [..., V, T], entry (i, t) = sum_k exp(-evals_k * t) * evecs_ik ** 2.
    """
    _check(evals, evecs)
    coefs = torch.exp(-times[:, None] * evals[..., None, :])  # [..., T, K]
    out = evecs.square() @ coefs.mT  # [..., V, T]
    if normalize:
        out = out / coefs.sum(-1)[..., None, :]
    return out


def hks_at_scales(evals: Tensor, evecs: Tensor, scales) -> Tensor:
    """[V, T] the HKS at times ``scales`` of ``4 ln 10 / lambda_2`` (1.0: the diffusion time at
    which the first non-constant mode has decayed to 1e-4; smaller scales see finer features)."""
    lam = evals[evals > 1e-8 * evals.max().clamp_min(1e-12)]  # skip the constant mode(s)
    t0 = 4 * math.log(10) / float(lam[0])
    return hks(evals, evecs, torch.tensor([t0 * s for s in scales], dtype=evals.dtype))


def default_energies(evals: Tensor, n_energies: int = 16) -> tuple[Tensor, float]:
    """WKS log-energy grid and sigma (Aubry et al. 2011): ([E] energies, sigma)."""
    lam = evals[evals > 1e-8 * evals.max().clamp_min(1e-12)]
    if lam.numel() < 2:
        raise ValueError("need at least two non-zero eigenvalues for an energy grid")
    lo, hi = math.log(float(lam.min())), math.log(float(lam.max()))
    sigma = 7.0 * (hi - lo) / n_energies
    lo, hi = lo + 2 * sigma, hi - 2 * sigma
    if hi <= lo:  # narrow spectrum: fall back to the full range
        lo, hi = math.log(float(lam.min())), math.log(float(lam.max()))
    energies = torch.linspace(lo, hi, n_energies, dtype=evals.dtype, device=evals.device)
    return energies, sigma


def wks(evals: Tensor, evecs: Tensor, energies: Tensor, sigma: float) -> Tensor:
    """Wave kernel signature at each vertex.

    Args:
        evals: [..., K] eigenvalues; the constant mode (~0) gets zero weight.
        evecs: [..., V, K] mass-orthonormal eigenvectors.
        energies: [E] log-energies.
        sigma: bandwidth in log-energy.

    Returns:
        [..., V, E], each column normalised by its total weight.
    """
    _check(evals, evecs)
    pos = evals > 1e-8 * evals.amax(-1, keepdim=True).clamp_min(1e-12)
    log_lam = torch.log(torch.where(pos, evals, torch.ones_like(evals)))
    coefs = torch.exp(-(energies[:, None] - log_lam[..., None, :]) ** 2 / (2 * sigma ** 2))
    coefs = coefs * pos[..., None, :]  # [..., E, K]
    out = evecs.square() @ coefs.mT  # [..., V, E]
    return out / coefs.sum(-1).clamp_min(1e-300)[..., None, :]


def descriptors(evals: Tensor, evecs: Tensor, n_hks: int = 16, n_wks: int = 16) -> Tensor:
    """Multi-scale HKS and WKS on the default grids, each column scaled to unit mean.

    Returns:
        [..., V, n_hks + n_wks], symmetry invariant (f o g = f for every intrinsic symmetry g).
    """
    h = hks(evals, evecs, default_times(evals, n_hks)) if n_hks else evecs[..., :0]
    energies, sigma = default_energies(evals, n_wks) if n_wks else (None, 0.0)
    w = wks(evals, evecs, energies, sigma) if n_wks else evecs[..., :0]
    d = torch.cat([h, w], dim=-1)
    return d / d.mean(dim=-2, keepdim=True).clamp_min(1e-300)


def gradient_cross(verts: Tensor, faces: Tensor, fields: Tensor, pairs: Tensor) -> Tensor:
    """Signed area of the gradients of pairs of scalar fields: ``n . (grad u_a x grad u_b)`` per vertex.

    An orientation-preserving isometry that maps field ``a`` to ``a'`` and ``b`` to ``b'`` keeps this
    value; an orientation-reversing one (a reflection) flips its sign. With distance fields of
    paired points it tells the front of a limb from its back, which the distances alone cannot.

    Args:
        verts: [V, 3]; faces: [F, 3] long, consistently oriented.
        fields: [n, V] piecewise-linear scalar fields.
        pairs: [P, 2] long indices into ``fields``.

    Returns:
        [V, P], per face values averaged to the vertices with face-area weights (the face gradients
        of :mod:`symtorch.orientation`, shared with its orientation operators).
    """
    faces = torch.as_tensor(faces, device=verts.device)
    geo = face_geometry(verts, faces)
    g = face_gradients(verts, faces, fields.mT, geo)  # [F, n, 3]
    pairs = torch.as_tensor(pairs, device=verts.device).reshape(-1, 2)
    cross = torch.cross(g[:, pairs[:, 0]], g[:, pairs[:, 1]], dim=-1)  # [F, P, 3]
    s = torch.einsum("fd,fpd->fp", geo.normals, cross)
    return faces_to_vertices(s, faces, geo.areas, verts.shape[0])
