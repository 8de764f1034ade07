"""Evaluation of detected symmetries against ground truth (ALGORITHM §6; Kim, Lipman & Funkhouser 2011,
Kim, Lipman, Chen & Funkhouser 2010, "KLC10").

Protocol, pinned:

- The error of a computed image ``g(p)`` against the true ``g*(p)`` is the geodesic distance between
  them on the ORIGINAL (unscaled) mesh, by the heat method (:class:`~symtorch.geodesics.GeodesicSolver`;
  distances are taken from the unique true images only).
- Correspondence rate: the share of ground-truth points whose error is strictly below
  ``eps = sqrt(area / (20 pi))`` (the radius of a disk covering 1/20 of the surface).
- Mesh rate: the share of meshes whose correspondence rate is strictly above ``beta = 0.75``.
- Normalised error: mean error / sqrt(area); scale-free, reported ×1e-3 by ``scripts/evaluate.py``.
- Fixed points of the reflection (on the symmetry plane) are scored, mapping to themselves, unless
  the loaders are called with ``include_fixed=False`` (see :mod:`symtorch.eval.benchmarks`).
- Groups: true and detected symmetries are matched one-to-one by the Hungarian method on their mean
  geodesic disagreement (:func:`score_group`).
- Watertight orbits: see :func:`orbit_errors`.

Ground-truth loaders live in :mod:`symtorch.eval.benchmarks`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from .._checks import to_numpy
from ..geodesics import GeodesicSolver
from ..units import EPS_KLC, klc_threshold  # noqa: F401  (re-exported)

__all__ = ["klc_threshold", "geodesic_errors", "orbit_errors", "klc_rates", "mesh_rate",
           "normalized_error", "score_group", "GroupScore"]


def _solver(mesh) -> GeodesicSolver:
    if isinstance(mesh, GeodesicSolver):
        return mesh
    if isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        return GeodesicSolver(*mesh)
    raise ValueError(f"mesh must be a GeodesicSolver or a (verts, faces) pair, got {type(mesh)}")


def _check_p2p(p2p, n_verts: int, name: str = "p2p") -> np.ndarray:
    p = to_numpy(p2p)
    if p.ndim != 1 or p.shape[0] != n_verts or not np.issubdtype(p.dtype, np.integer):
        raise ValueError(f"{name} must be [V] = [{n_verts}] integer, got {list(p.shape)} {p.dtype}")
    p = p.astype(np.int64, copy=False)
    if p.min() < 0 or p.max() >= n_verts:
        raise ValueError(f"{name} out of range: values span [{p.min()}, {p.max()}], V={n_verts}")
    return p


def _check_pairs(pairs, n_verts: int) -> np.ndarray:
    q = to_numpy(pairs)
    if q.ndim != 2 or q.shape[1] != 2 or not np.issubdtype(q.dtype, np.integer):
        raise ValueError(f"pairs must be [P, 2] integer, got {list(q.shape)} {q.dtype}")
    q = q.astype(np.int64, copy=False)
    if q.size and (q.min() < 0 or q.max() >= n_verts):
        raise ValueError(f"pairs out of range: ids span [{q.min()}, {q.max()}], V={n_verts}")
    return q


def evenly_spaced(rows, n: int):
    """At most ``n`` rows of ``rows`` (array or tensor), evenly spaced, first and last kept: the
    subsample the benchmark scripts score dense ground truth on."""
    if n <= 0 or len(rows) <= n:
        return rows
    return rows[np.linspace(0, len(rows) - 1, n).round().astype(np.int64)]




def geodesic_errors(mesh, p2p, pairs) -> Tensor:
    """Geodesic error of a self-map at ground-truth pairs: ``d(p2p[p], g*(p))`` for each ``(p, g*(p))``.

    Args:
        mesh: a :class:`GeodesicSolver` of the original (unscaled) mesh, or ``(verts, faces)``.
        p2p: [V] computed symmetry, ``p2p[i]`` the image of vertex i.
        pairs: [P, 2] ground-truth vertex pairs ``(p, g*(p))``.

    Returns:
        [P] float64 errors, in the units of the mesh. One heat solve per unique ``g*(p)``.
    """
    solver = _solver(mesh)
    p = _check_p2p(p2p, solver.n_verts)
    q = _check_pairs(pairs, solver.n_verts)
    if q.shape[0] == 0:
        return torch.zeros(0, dtype=torch.float64)
    targets, inv = np.unique(q[:, 1], return_inverse=True)
    D = solver.distances_from(targets).to("cpu", torch.float64)  # [U, V]
    return D[torch.as_tensor(inv), torch.as_tensor(p[q[:, 0]])]


def orbit_errors(mesh, p2p, orbits, identity: bool = False) -> Tensor:
    """Geodesic error of a self-map on symmetry orbits (SHREC'07 Watertight ground truth).

    For each point ``p`` of an orbit ``O`` with more than one element, the error is the distance from
    ``p2p[p]`` to the nearest element of ``O`` other than ``p`` itself: any non-identity symmetry of
    the group must move ``p`` to another element of its orbit, and which one depends on the symmetry,
    which the orbit data does not say. For a fixed point (an orbit of size 1), and for every point
    when ``identity`` is True, the error is the distance from ``p2p[p]`` to ``p``.

    Caveat: a non-identity symmetry may legitimately fix some orbit elements (a diagonal reflection
    of a square table fixes two of the four corners); such points are counted wrong here. Use
    :func:`score_group` with dense true maps where they can be derived.

    Args:
        mesh: a :class:`GeodesicSolver` of the original mesh, or ``(verts, faces)``.
        p2p: [V] computed symmetry.
        orbits: list of [n_o] vertex-id arrays (:func:`symtorch.eval.benchmarks.load_orbits`).
        identity: score as the identity (every point should stay where it is).

    Returns:
        [P] float64 errors, one per orbit element, orbits concatenated in the given order.
    """
    solver = _solver(mesh)
    p = _check_p2p(p2p, solver.n_verts)
    orbits = [to_numpy(o).astype(np.int64).reshape(-1) for o in orbits]
    if not orbits or sum(o.size for o in orbits) == 0:
        return torch.zeros(0, dtype=torch.float64)
    allv = np.concatenate(orbits)
    if allv.min() < 0 or allv.max() >= solver.n_verts:
        raise ValueError(f"orbit ids out of range: span [{allv.min()}, {allv.max()}], "
                         f"V={solver.n_verts}")
    uniq, inv = np.unique(allv, return_inverse=True)
    D = solver.distances_from(uniq).to("cpu", torch.float64).numpy()  # [U, V]
    errors, start = [], 0
    for o in orbits:
        rows = inv[start:start + o.size]  # rows of D for the orbit elements
        start += o.size
        img = p[o]  # [n_o]
        d = D[rows][:, img]  # [n_o (candidate target), n_o (point)]
        if o.size == 1 or identity:
            errors.append(np.diagonal(d).copy())
        else:
            np.fill_diagonal(d, np.inf)  # exclude the point itself (by position in the orbit)
            errors.append(d.min(axis=0))
    return torch.as_tensor(np.concatenate(errors), dtype=torch.float64)


def klc_rates(errors, area: float, eps: float | None = None) -> Tensor:
    """Correspondence rate: share of errors strictly below ``eps`` (default ``sqrt(area/(20 pi))``).

    Args:
        errors: [..., P] geodesic errors (torch or numpy).
        area: surface area of the mesh the errors were measured on.
        eps: threshold; overrides the area-based default.

    Returns:
        [...] rates in [0, 1] (a 0-d tensor for one mesh); NaN where P = 0.
    """
    e = errors if isinstance(errors, Tensor) else torch.as_tensor(to_numpy(errors, np.float64))
    eps = klc_threshold(area) if eps is None else float(eps)
    return (e < eps).to(torch.float64).mean(-1)


def mesh_rate(rates, beta: float = 0.75) -> float:
    """Share of meshes whose correspondence rate is strictly above ``beta`` (NaN rates are excluded)."""
    r = to_numpy(rates, np.float64).reshape(-1)
    r = r[np.isfinite(r)]
    return float((r > beta).mean()) if r.size else float("nan")


def normalized_error(errors, area: float) -> float:
    """Mean geodesic error divided by sqrt(area): comparable across meshes of any scale."""
    e = to_numpy(errors, np.float64).reshape(-1)
    return float(e.mean() / math.sqrt(float(area))) if e.size else float("nan")


@dataclass(frozen=True)
class GroupScore:
    """One-to-one matching of true to detected symmetries (see :func:`score_group`).

    Attributes:
        found: true symmetries matched to a detected one with mean error <= ``max_error``.
        missed: true symmetries not found.
        spurious: detected symmetries not matched to a found true one.
        matches: ``(true index, detected index, mean error)`` for every found symmetry.
        errors: [T] mean error of each true symmetry's match (inf where missed).
        cost: [T, D] mean geodesic disagreement of every true/detected pair.
        max_error: the threshold used.
    """

    found: int
    missed: int
    spurious: int
    matches: list[tuple[int, int, float]]
    errors: Tensor
    cost: Tensor
    max_error: float


def _stack_maps(maps, n_verts: int, name: str) -> np.ndarray:
    if isinstance(maps, (list, tuple)):
        if len(maps) == 0:
            return np.zeros((0, n_verts), dtype=np.int64)
        maps = [to_numpy(m) for m in maps]
        return np.stack([_check_p2p(m, n_verts, f"{name}[{i}]") for i, m in enumerate(maps)])
    m = to_numpy(maps)
    if m.ndim == 1:
        m = m[None]
    return np.stack([_check_p2p(r, n_verts, f"{name}[{i}]") for i, r in enumerate(m)]) if len(m) \
        else np.zeros((0, n_verts), dtype=np.int64)


def score_group(true_maps, detected_maps, mesh, points=None, n_points: int = 100,
                max_error: float | None = None) -> GroupScore:
    """Match true symmetries to detected ones one-to-one and count found / missed / spurious.

    The cost of a (true t, detected d) pair is the mean over sample points p of the geodesic distance
    ``d(p2p_d[p], p2p_t[p])``. The Hungarian method (``scipy.optimize.linear_sum_assignment``) finds
    the matching of least total cost; a matched pair counts as found when its cost is at most
    ``max_error``, otherwise the true symmetry is missed and the detected one spurious. Include the
    identity in both lists if it should be scored.

    Args:
        true_maps: [T, V] (or a list of [V]) true symmetries as p2p.
        detected_maps: [D, V] (or a list, possibly empty) detected symmetries.
        mesh: a :class:`GeodesicSolver` of the original mesh, or ``(verts, faces)``.
        points: [N] vertex ids where maps are compared; default ``n_points`` vertices evenly spaced
            in vertex order (deterministic).
        n_points: number of default sample points.
        max_error: threshold on the mean error; default ``sqrt(area / (20 pi))``.

    Returns:
        :class:`GroupScore`. Costs one heat solve per unique true image of a sample point.
    """
    from scipy.optimize import linear_sum_assignment

    solver = _solver(mesh)
    V = solver.n_verts
    T = _stack_maps(true_maps, V, "true_maps")  # [T, V]
    Dm = _stack_maps(detected_maps, V, "detected_maps")  # [D, V]
    if points is None:
        pts = np.unique(np.linspace(0, V - 1, min(n_points, V)).round().astype(np.int64))
    else:
        pts = to_numpy(points).astype(np.int64).reshape(-1)
        if pts.size == 0 or pts.min() < 0 or pts.max() >= V:
            raise ValueError(f"points must be non-empty vertex ids in [0, {V}), got {pts.size} ids")
    thr = klc_threshold(solver.area) if max_error is None else float(max_error)
    nT, nD = T.shape[0], Dm.shape[0]
    cost = np.zeros((nT, nD))
    if nT and nD:
        targets = T[:, pts]  # [T, N] true images
        uniq, inv = np.unique(targets, return_inverse=True)
        dist = solver.distances_from(uniq).to("cpu", torch.float64).numpy()  # [U, V]
        rows = inv.reshape(nT, pts.size)  # [T, N]
        imgs = Dm[:, pts]  # [D, N]
        cost = dist[rows[:, None, :], imgs[None, :, :]].mean(-1)  # [T, D]
    matches, errors = [], np.full(nT, np.inf)
    if nT and nD:
        for t, d in zip(*linear_sum_assignment(cost)):
            if cost[t, d] <= thr:
                matches.append((int(t), int(d), float(cost[t, d])))
                errors[t] = cost[t, d]
    found = len(matches)
    return GroupScore(found=found, missed=nT - found, spurious=nD - found, matches=matches,
                      errors=torch.as_tensor(errors), cost=torch.as_tensor(cost), max_error=thr)
