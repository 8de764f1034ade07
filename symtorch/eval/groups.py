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

__all__ = ["dihedral_permutations", "dihedral_orbit_errors", "element_rates", "rigid_residual",
           "orbit_dihedral_elements", "sparse_distortion", "rigid_maps_from_points"]


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


def orbit_dihedral_elements(verts, orbits) -> tuple[list[str], np.ndarray]:
    """The 2n elements of the dihedral group that cyclic orbit ground truth implies, as permutations
    of the orbit points (SHREC'07 Watertight: the tables' four orbits of 4 and two fixed points).

    The orbits' points are placed around the axis of the first orbit of size n > 1, the reference
    orbit (normal of the plane fitted to its points, through their centroid); each point gets a
    fractional rank ``r`` in that reference orbit's counter-clockwise order (rank interpolated
    in angle, so a point between two reference points, such as an edge midpoint between two
    corners, gets a half-integer rank). Element ``rot j`` sends rank ``r`` to ``r + j``,
    ``ref m`` sends ``r`` to ``m - r`` (``ref 0`` fixes reference points 0 and n/2, ``ref 1``
    fixes the points half-way after them); each point goes to the member of its own orbit
    with the nearest rank. Fixed points (orbits of size 1) map to themselves. The file's listing
    order of each orbit is not used, only the geometry of its points.

    Args:
        verts: [V, 3]; orbits: list of vertex-id arrays (``benchmarks.load_orbits``).

    Returns:
        (names [2n], perm [2n, P] long: ``points[perm[e, i]]`` is the image of ``points[i]`` under
        element e, with ``points = np.concatenate(orbits)``).
    """
    x = np.asarray(verts, dtype=np.float64)
    orbits = [np.asarray(o, dtype=np.int64).reshape(-1) for o in orbits]
    ref = next(o for o in orbits if o.size > 1)
    n = ref.size
    c = x[ref].mean(0)
    _, _, Vt = np.linalg.svd(x[ref] - c)  # the plane of the reference orbit (a table's corners)
    e1, e2 = Vt[0], Vt[1]

    def angle(ids):
        y = x[ids] - c
        return np.arctan2(y @ e2, y @ e1) % (2 * np.pi)

    ra = np.sort(angle(ref))
    ra_ext = np.concatenate([ra, [ra[0] + 2 * np.pi]])

    def rank(ids):
        a = angle(ids)
        a = np.where(a < ra[0], a + 2 * np.pi, a)
        return np.interp(a, ra_ext, np.arange(n + 1)) % n

    ranks = [rank(o) for o in orbits]
    names = [f"rot {j}" for j in range(n)] + [f"ref {m}" for m in range(n)]
    offsets = np.cumsum([0] + [o.size for o in orbits])
    perm = np.zeros((2 * n, offsets[-1]), dtype=np.int64)
    for e in range(2 * n):
        for k, (o, r) in enumerate(zip(orbits, ranks)):
            if o.size == 1:
                perm[e, offsets[k]] = offsets[k]
                continue
            g = (r + e) % n if e < n else (e - n - r) % n
            d = np.abs(g[:, None] - r[None, :])
            d = np.minimum(d, n - d)
            perm[e, offsets[k]:offsets[k + 1]] = offsets[k] + d.argmin(1)
    return names, perm


def sparse_distortion(D0: np.ndarray, D1: np.ndarray, radius: float) -> float:
    """Mean over point pairs of ``|D1 - D0|`` in units of ``radius`` (``D0``: [P, P] geodesic
    distances among points, ``D1``: among their images; e.g. ``D0[perm][:, perm]``)."""
    P = D0.shape[0]
    off = ~np.eye(P, dtype=bool)
    return float(np.abs(np.asarray(D1) - np.asarray(D0))[off].mean() / radius)


def rigid_maps_from_points(verts, points, perm) -> np.ndarray:
    """Dense vertex maps of sparse ground-truth elements, through the rigid motion they imply.

    For each element (a permutation of ``points``, e.g. from :func:`orbit_dihedral_elements`) the
    best orthogonal transform about the points' centroid (Procrustes, reflections allowed) of the
    points onto their images is fitted, and every vertex goes to the nearest vertex of its
    transformed position. A proxy for the intrinsic element where the shape's symmetry is also
    extrinsic (a table on its legs), to be measured like any detected map (``isometry_score``).

    Returns:
        [E, V] long maps.
    """
    from scipy.spatial import cKDTree

    x = np.asarray(verts, dtype=np.float64)
    pts = np.asarray(points, dtype=np.int64)
    c = x[pts].mean(0)
    a = x[pts] - c
    tree = cKDTree(x)
    out = []
    for p in np.asarray(perm):
        U, _, Vt = np.linalg.svd(a.T @ a[p])
        out.append(tree.query((x - c) @ (U @ Vt) + c)[1])
    return np.stack(out).astype(np.int64)
