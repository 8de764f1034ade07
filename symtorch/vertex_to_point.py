"""Vertex-to-point maps: the image of a vertex as a point inside a triangle, not a vertex.

A vertex map (:mod:`symtorch.maps`) sends each vertex to the vertex whose spectral embedding is
nearest its target ``evecs[i] @ C``. On a triangulation that no symmetry maps onto itself (a remesh,
a scan) the true image lies inside a triangle, and rounding it to a vertex moves it by up to about
half an edge: every element of the group then distorts by that much, however exact it is.

The embedding of the piecewise-linear basis is affine over each triangle, so the point of a triangle
whose embedding is nearest the target is a least-squares fit of barycentric coordinates
(the precise map of Ezuz & Ben-Chen, "Deblurring and Denoising of Maps between Shapes", SGP 2017,
restricted here to the triangles around the nearest vertex).
"""
from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from ._checks import to_numpy

__all__ = ["vertex_faces", "vertex_to_point"]


def vertex_faces(faces, n_verts: int) -> Tensor:
    """[V, m] long: the faces around each vertex, padded with -1 (m: the largest degree)."""
    f = to_numpy(faces).astype(np.int64)
    flat = f.reshape(-1)
    order = np.argsort(flat, kind="stable")
    deg = np.bincount(flat, minlength=n_verts)
    start = np.concatenate([[0], np.cumsum(deg)[:-1]])
    slot = np.arange(len(flat)) - np.repeat(start, deg)
    out = np.full((n_verts, max(int(deg.max(initial=0)), 1)), -1, dtype=np.int64)
    out[flat[order], slot] = order // 3
    return torch.as_tensor(out)


def _fit_triangle(P: Tensor, q: Tensor) -> tuple[Tensor, Tensor]:
    """Barycentric coordinates [N, 3] of the point of each triangle ``P [N, 3, k]`` nearest ``q [N, k]``
    (the exact projection onto the simplex: inside, or on the nearest edge), and its distance [N]."""
    d1, d2, r = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0], q - P[:, 0]
    g11, g12, g22 = (d1 * d1).sum(-1), (d1 * d2).sum(-1), (d2 * d2).sum(-1)
    h1, h2 = (d1 * r).sum(-1), (d2 * r).sum(-1)
    det = (g11 * g22 - g12 * g12).clamp_min(1e-30)
    s, t = (g22 * h1 - g12 * h2) / det, (g11 * h2 - g12 * h1) / det
    inside = (s >= 0) & (t >= 0) & (s + t <= 1)
    best_b = torch.stack([1 - s - t, s, t], -1)
    best_r = torch.where(inside, ((q - (best_b[..., None] * P).sum(1)) ** 2).sum(-1), torch.inf)
    for a, b in ((0, 1), (1, 2), (2, 0)):  # the nearest point of each edge
        e = P[:, b] - P[:, a]
        u = (((q - P[:, a]) * e).sum(-1) / (e * e).sum(-1).clamp_min(1e-30)).clamp(0, 1)
        res = ((q - P[:, a] - u[:, None] * e) ** 2).sum(-1)
        bary = torch.zeros_like(best_b)
        bary[:, a], bary[:, b] = 1 - u, u
        better = res < best_r
        best_r = torch.where(better, res, best_r)
        best_b = torch.where(better[:, None], bary, best_b)
    return best_b, best_r.sqrt()


def vertex_to_point(evecs: Tensor, faces: Tensor, vf: Tensor, target: Tensor,
                    nearest: Tensor) -> tuple[Tensor, Tensor]:
    """Images as points of triangles: the point, on a triangle around the nearest vertex, whose
    embedding fits the target best.

    Args:
        evecs: [V, k] the embedding; faces: [F, 3] long; vf: [V, m] :func:`vertex_faces`.
        target: [N, k] the target embeddings (``evecs[at] @ C``); nearest: [N] the vertex map's
            images (the nearest vertices in the embedding).

    Returns:
        (tri [N, 3] long, bary [N, 3]): the image is ``sum_j bary[:, j] * verts[tri[:, j]]``.
    """
    faces = torch.as_tensor(faces, device=evecs.device)
    N = len(nearest)
    cand = vf.to(evecs.device)[nearest]  # [N, m] the faces around each nearest vertex
    m = cand.shape[1]
    t = faces[cand.clamp_min(0)]  # [N, m, 3]
    b, r = _fit_triangle(evecs[t.reshape(-1, 3)], target.repeat_interleave(m, 0))
    r = torch.where(cand.reshape(-1) >= 0, r, torch.inf).reshape(N, m)
    best = r.argmin(1)
    rows = torch.arange(N, device=evecs.device)
    return t[rows, best], b.reshape(N, m, 3)[rows, best]
