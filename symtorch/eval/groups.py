"""Scoring whole detected groups: per-element KLC10 rates, and orbit ground truth.

Protocol, pinned:

- Dense truth (shapes built in code, ``symtorch.shapes.symmetry_maps``): true and detected elements
  are matched one-to-one by :func:`symtorch.eval.score_group` (Hungarian, mean geodesic error); the
  rate of a matched element is the share of the sample points whose image lies strictly within
  ``eps = sqrt(area / (20 pi))`` (geodesic) of the true image.
- Orbit truth (SHREC'07 Watertight ``.sym.info``, each orbit listed in cyclic order around the
  axis): a detected element must permute every orbit as a dihedral symmetry of that cycle (a
  rotation by j steps or a reflection). Per orbit, the dihedral permutation with the least total
  error is taken; the error of a point is the geodesic distance from its image to its partner under
  that permutation; fixed points (orbits of size 1) must map to themselves. Unlike
  :func:`symtorch.eval.orbit_errors`, an element may fix orbit points (a diagonal mirror of a square
  table fixes two corners).
- Rigid truth (shapes whose symmetries are rigid motions, e.g. Qiao et al.'s box and cones): an
  element is scored by :func:`rigid_residual`, how far its map is from the best rigid motion.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from .metrics import klc_threshold, score_group
from ..geodesics import GeodesicSolver

__all__ = ["dihedral_permutations", "dihedral_orbit_errors", "element_rates", "rigid_residual"]


def dihedral_permutations(n: int) -> Tensor:
    """[2n, n] long, the permutations of a cycle of n positions: n rotations, then n reflections
    (for n <= 2 the reflections repeat rotations: [n, n])."""
    return torch.as_tensor(_dihedral(n))


def _dihedral(n: int) -> np.ndarray:
    i = np.arange(n)
    rots = [(i + j) % n for j in range(n)]
    refl = [(j - i) % n for j in range(n)]
    return np.asarray(rots + refl if n > 2 else rots, dtype=np.int64)


def dihedral_orbit_errors(solver: GeodesicSolver, p2p, orbits) -> Tensor:
    """[P] geodesic error of each orbit point under the best dihedral permutation of its orbit.

    Args:
        solver: heat-method solver of the mesh (errors in its units).
        p2p: [V] detected element.
        orbits: list of vertex-id arrays, each in cyclic order (``benchmarks.load_orbits``).
    """
    p = np.asarray(torch.as_tensor(p2p).cpu()).astype(np.int64)
    out = []
    for o in orbits:
        o = np.asarray(o, dtype=np.int64).reshape(-1)
        D = solver.distances_from(o).to("cpu", torch.float64).numpy()[:, p[o]]  # [target, point]
        perms = _dihedral(len(o)) if len(o) > 1 else np.zeros((1, 1), dtype=np.int64)
        err = D[perms, np.arange(len(o))[None]]  # [n_perm, n]: d(g(o_i), o_perm(i))
        out.append(err[err.sum(1).argmin()])
    return torch.as_tensor(np.concatenate(out) if out else np.zeros(0))


def element_rates(solver: GeodesicSolver, true_maps, detected_maps, n_points: int = 100):
    """Match detected elements to true ones and give each matched pair's KLC10 rate.

    Returns:
        (GroupScore, rates [T] float64: share of the points within eps of the true image, 0 where
        the true element was missed).
    """
    sc = score_group(true_maps, detected_maps, solver, n_points=n_points)
    V = solver.n_verts
    pts = np.unique(np.linspace(0, V - 1, min(n_points, V)).round().astype(np.int64))
    eps = klc_threshold(solver.area)
    T = np.asarray(true_maps)
    Dm = np.stack([np.asarray(torch.as_tensor(m).cpu()) for m in detected_maps])
    rates = np.zeros(len(T))
    for t, d, _ in sc.matches:
        D = solver.distances_from(T[t][pts]).to("cpu", torch.float64).numpy()  # [N, V]
        err = D[np.arange(len(pts)), Dm[d][pts]]
        rates[t] = float((err < eps).mean())
    return sc, torch.as_tensor(rates)


def rigid_residual(verts, p2p) -> float:
    """How far a vertex map is from a rigid symmetry of the shape.

    The best orthogonal transform ``R`` (Procrustes) of the vertices about their centroid onto their
    images is fitted; returned is the 95th percentile of ``|x R - g(x)|`` as a share of the
    bounding-box diagonal: ~0 for a map that is one of the shape's rigid symmetries.

    Args:
        verts: [V, 3]; p2p: [V] the map.
    """
    x = np.asarray(verts, dtype=np.float64)
    x = x - x.mean(0)
    y = x[np.asarray(p2p)]
    U, _, Vt = np.linalg.svd(x.T @ y)
    res = np.linalg.norm(x @ (U @ Vt) - y, axis=1)
    return float(np.percentile(res, 95) / np.linalg.norm(x.max(0) - x.min(0)))
