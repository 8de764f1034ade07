"""The heat method for many sources at once: cotan operators, two CHOLMOD factors, blocked solves.

Crane, Weischedel & Wardetzky's heat method (CACM 2017) on the mesh's own cotan operators: for each
source ``s``,

1. ``u = (M + t L)^-1 delta_s`` (one implicit heat step, ``t = t_coef * h^2``, ``h`` the mean edge
   length, ``M`` the lumped mass, ``L = G^T A G`` the cotan Laplacian),
2. ``X = -grad u / |grad u|`` on each face,
3. ``L phi = G^T A X`` (the Poisson problem whose gradient best fits ``X``), shifted so that
   ``phi(s) = 0``.

:class:`BatchedHeatMethod` factors both systems once and solves a block of sources per call, so the
per-source cost is a few sparse products and two multi-column back-substitutions: about 0.7 ms a
source on a 12.5K-vertex mesh against potpourri3d's 3.2 ms (``scripts/bench_geodesics.py``). It
gives the same distances as potpourri3d's plain (non-robust) solver up to the solvers' tolerance;
potpourri3d's robust mode, which works on the intrinsic Delaunay tufted cover, differs from both by
about 0.1 % of the mean distance on scanned meshes. Being built on the mesh's own triangles, it
needs a mesh that is one connected piece without isolated vertices, and one that is nearly Delaunay:
where many edges have negative cotan weights (the opposite angles sum to more than pi, as on meshes
remeshed with slivers) the cotan heat method is off by tens of percent, and only the intrinsic
Delaunay cover of potpourri3d's robust mode is right. :meth:`BatchedHeatMethod.build` returns None
for such meshes (the caller then uses potpourri3d).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .sparse_solve import SPDFactor

__all__ = ["BatchedHeatMethod", "non_delaunay_share"]

#: Sources solved per block: multi-column back-substitutions pay off up to a few dozen columns,
#: and beyond that the [F, block] face arrays leave the cache (per source, 88 at once cost 3-4x
#: what blocks of 16 do on a 12.5K-vertex mesh).
BLOCK = 16

#: Largest share of interior edges with a negative cotan weight (not locally Delaunay) that the
#: batched solver accepts. Scanned and template meshes have 0-0.3 %, where it agrees with the robust
#: solver to ~1e-3 of the mean distance; sliver remeshes have 15-18 %, where it is 16-70 % off.
MAX_NON_DELAUNAY = 0.01


def non_delaunay_share(lap: sp.spmatrix) -> float:
    """Share of a cotan Laplacian's edges (``[V, V]``, ``L_ij = -w_ij``) whose weight is negative."""
    upper = sp.triu(lap, k=1).tocoo()
    if upper.nnz == 0:
        return 0.0
    tol = 1e-12 * float(np.abs(upper.data).max())
    return float((upper.data > tol).mean())


class BatchedHeatMethod:
    """Heat-method distances on one triangle mesh, many sources per solve.

    Use :meth:`build`, which checks that the mesh suits the method; ``distances_from(sources)``
    returns ``[S, V]`` float64 distances in the units of ``verts``.
    """

    def __init__(self, verts: np.ndarray, faces: np.ndarray, t_coef: float = 1.0):
        v = np.asarray(verts, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
        V, F = len(v), len(f)
        p = v[f]  # [F, 3 corners, 3]
        edges = np.roll(p, -1, axis=1) - np.roll(p, 1, axis=1)  # [F, 3, 3], edge opposite corner i
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # [F, 3], length twice the area
        twice_area = np.linalg.norm(normal, axis=1)
        ok = twice_area > 1e-12 * max(float(twice_area.max(initial=0.0)), 1e-300)
        inv = np.where(ok, 1.0 / np.where(ok, twice_area, 1.0), 0.0)  # degenerate faces: no gradient
        # gradient of corner i's hat function on its face: n x e_i / (2 A)
        hat = np.cross((normal * inv[:, None])[:, None, :], edges) * inv[:, None, None]  # [F, 3, 3]
        area = 0.5 * twice_area * ok
        rows = np.repeat(np.arange(F), 3)
        self._grad = [sp.csr_matrix((hat[:, :, c].ravel(), (rows, f.ravel())), shape=(F, V))
                      for c in range(3)]  # x, y, z components, each [F, V]
        self._div = [(g.T.multiply(area[None, :])).tocsr() for g in self._grad]  # G^T A, [V, F]
        lap = (self._div[0] @ self._grad[0] + self._div[1] @ self._grad[1]
               + self._div[2] @ self._grad[2]).tocsc()
        self.non_delaunay = non_delaunay_share(lap)
        if self.non_delaunay > MAX_NON_DELAUNAY:
            raise ValueError(f"{100 * self.non_delaunay:.1f} % of the edges are not Delaunay")
        mass = np.bincount(f.ravel(), weights=np.repeat(area / 3.0, 3), minlength=V)
        if not (mass > 0).all():
            raise ValueError("a vertex has no area (isolated, or only in degenerate faces)")
        h = float(np.linalg.norm(edges, axis=2).mean())
        M = sp.diags(mass)
        self._heat = SPDFactor((M + (t_coef * h * h) * lap).tocsc())
        # L is only semi-definite (constants): a shift far below its smallest non-zero eigenvalue
        eps = 1e-8 * float(lap.diagonal().mean() / mass.mean())
        self._poisson = SPDFactor((lap + eps * M).tocsc())
        self.n_verts, self.n_faces = V, F

    @classmethod
    def build(cls, verts: np.ndarray, faces: np.ndarray, t_coef: float = 1.0
              ) -> "BatchedHeatMethod | None":
        """The solver, or None where the mesh does not suit it: several connected pieces (the
        Poisson step's constant is then free on each), a vertex in no face, more than
        ``MAX_NON_DELAUNAY`` of the edges not Delaunay, or a factorisation that fails."""
        f = np.asarray(faces, dtype=np.int64)
        V = len(verts)
        if f.size == 0 or np.bincount(f.ravel(), minlength=V).min() == 0:
            return None
        adj = sp.coo_matrix((np.ones(2 * f.shape[0]), (f[:, [0, 1]].ravel(), f[:, [1, 2]].ravel())),
                            shape=(V, V))
        if connected_components(adj, directed=False)[0] != 1:
            return None
        try:
            return cls(verts, f, t_coef)
        except (ValueError, RuntimeError):
            return None

    def distances_from(self, sources: np.ndarray) -> np.ndarray:
        """[S, V] distances from each of ``sources`` ([S] vertex ids), ``BLOCK`` sources a solve."""
        s = np.asarray(sources, dtype=np.int64).reshape(-1)
        out = np.empty((s.size, self.n_verts))
        for b in range(0, s.size, BLOCK):
            out[b:b + BLOCK] = self._block(s[b:b + BLOCK])
        return out

    def _block(self, s: np.ndarray) -> np.ndarray:
        S = s.size
        delta = np.zeros((self.n_verts, S))
        delta[s, np.arange(S)] = 1.0
        u = self._heat.solve(delta)  # [V, S]
        gx, gy, gz = (g @ u for g in self._grad)  # [F, S] each
        scale = np.sqrt(gx * gx + gy * gy + gz * gz)
        np.divide(-1.0, scale, out=scale, where=scale > 0)  # X = -grad u / |grad u|
        div = self._div[0] @ (gx * scale) + self._div[1] @ (gy * scale) + self._div[2] @ (gz * scale)
        phi = self._poisson.solve(div)  # [V, S]
        phi -= phi[s, np.arange(S)][None, :]
        return phi.T
