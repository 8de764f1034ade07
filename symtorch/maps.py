"""Point-to-point maps and functional maps in a Laplace–Beltrami basis (ALGORITHM §2).

A symmetry ``g`` is a vertex map ``p2p [V]`` (``p2p[i]`` is the image of vertex ``i``) and its matrix is
the pull-back ``C = evecs.T @ (mass[:, None] * evecs[p2p])``, so that rows move as
``evecs[p2p] ≈ evecs @ C``. Composition and inverses live in :mod:`symtorch.groups`.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from ._checks import to_numpy

_BRUTE_FORCE_MAX = 2 * 10 ** 8  # query x point pairs up to which brute force is used on CPU
_EXACT_DTYPE_MAX = 2 * 10 ** 7  # above this, brute force runs in float32
_KDTREE_MAX_DIM = 1024  # spectral embeddings are 2-manifolds: KD-trees stay fast in 100+ dims


def p2p_to_fmap(p2p: Tensor, evecs: Tensor, mass: Tensor, evecs_src: Tensor | None = None) -> Tensor:
    """Functional map (pull-back) of a vertex map.

    Args:
        p2p: [..., V] long, image of each vertex.
        evecs: [V, K] mass-orthonormal basis of the shape the images live on.
        mass: [V] lumped mass of the domain.
        evecs_src: [V, K'] basis of the domain (defaults to ``evecs``, a self-map).

    Returns:
        [..., K', K] ``evecs_src.T @ (mass[:, None] * evecs[p2p])``.
    """
    src = evecs if evecs_src is None else evecs_src
    if p2p.shape[-1] != src.shape[0]:
        raise ValueError(f"p2p has {p2p.shape[-1]} entries but the domain has {src.shape[0]} vertices")
    return (src * mass[:, None]).mT @ evecs[p2p]


def least_squares(A: Tensor, B: Tensor) -> Tensor:
    """``argmin_X ||A X - B||`` for a full-column-rank ``A [N, K]`` (``B [N, M]``), in float64.

    Solved by QR (LAPACK ``gels``), which gives the same bits on every run; torch's CPU default
    (``gelsy``, pivoted QR) does not, and a ground-truth functional map that differs in its last
    bits from run to run makes two trainings from one seed drift apart.

    Returns:
        [K, M] in ``A``'s dtype.
    """
    return torch.linalg.lstsq(A.double(), B.double(), driver="gels").solution.to(A.dtype)


def nearest_neighbors(queries: Tensor, points: Tensor, chunk: int = 4096) -> Tensor:
    """Index of the nearest row of ``points`` for each row of ``queries``.

    Args:
        queries: [N, D].
        points: [M, D].

    Returns:
        [N] long, on the device of ``queries``. Blocked brute force (float32 above
        ``_EXACT_DTYPE_MAX`` pairs: distance ties may then resolve differently), or on CPU above
        ``_BRUTE_FORCE_MAX`` pairs a KD-tree (spectral embeddings are 2-manifolds, so it stays
        fast in 100+ dimensions, but its search degrades when queries lie far from the points).
    """
    pairs = queries.shape[0] * points.shape[0]
    big = pairs > _BRUTE_FORCE_MAX
    if queries.device.type == "cpu" and big and queries.shape[-1] <= _KDTREE_MAX_DIM:
        from scipy.spatial import cKDTree

        tree = cKDTree(points.detach().double().numpy())
        # threads pay off only for large queries (each call starts them anew)
        workers = -1 if queries.shape[0] >= 20000 else 1
        _, idx = tree.query(queries.detach().double().numpy(), k=1, workers=workers)
        return torch.as_tensor(np.asarray(idx, dtype=np.int64))
    out = torch.empty(queries.shape[0], dtype=torch.long, device=queries.device)
    if pairs > _EXACT_DTYPE_MAX and queries.dtype == torch.float64:
        queries, points = queries.float(), points.float()
        chunk = max(min(chunk, 2 ** 25 // max(points.shape[0], 1)), 1)  # ~128 MB of distances
    sq = points.square().sum(-1)  # [M]
    for s in range(0, queries.shape[0], chunk):
        q = queries[s:s + chunk]
        # ||q||^2 is constant per row; one fused addmm is ~30 % faster than the two-step form
        out[s:s + chunk] = torch.addmm(sq[None, :], q, points.mT, alpha=-2).argmin(-1)
    return out


def nearest_neighbors_among(queries: Tensor, points: Tensor, candidates: Tensor, groups: Tensor,
                            chunk: int = 2048) -> Tensor:
    """Index of the nearest row of ``points`` for each query, searched only among its candidates.

    Args:
        queries: [N, D].
        points: [M, D].
        candidates: [G, m] long, candidate point ids of each group.
        groups: [N] long, the group (row of ``candidates``) each query searches.

    Returns:
        [N] long point ids. N * m distances instead of N * M: a local search where an earlier map
        says roughly where each query's image is.
    """
    if groups.shape[0] != queries.shape[0]:
        raise ValueError(f"groups has {groups.shape[0]} entries for {queries.shape[0]} queries")
    out = torch.empty(queries.shape[0], dtype=torch.long, device=queries.device)
    if queries.shape[0] == 0:
        return out
    sq = points.square().sum(-1)  # [M]
    # queries of one group share its candidates: sorted by group and cut into tiles of at most
    # ``width`` queries, each tile is one [width, D] x [D, m] product, so a candidate row is
    # gathered once per tile rather than once per query
    counts = torch.bincount(groups, minlength=candidates.shape[0])
    width = max(1, -(-2 * queries.shape[0] // max(int((counts > 0).sum()), 1)))
    order = torch.argsort(groups, stable=True)
    g = groups[order]
    slot = torch.arange(len(order), device=groups.device) - (torch.cumsum(counts, 0) - counts)[g]
    tiles = -(-counts // width)  # tiles per group
    tile = (torch.cumsum(tiles, 0) - tiles)[g] + slot // width  # [N] tile of each sorted query
    tile_group = torch.repeat_interleave(torch.arange(len(counts), device=groups.device), tiles)
    n_tiles = int(tile_group.shape[0])
    step = max(1, chunk // width)  # tiles per block: about ``chunk`` queries' worth of memory
    col = slot % width
    # ``tile`` ascends along the sorted queries: each block of tiles is one slice of them
    cut = torch.searchsorted(tile, torch.arange(0, n_tiles + step, step, device=tile.device)).tolist()
    for b, s in enumerate(range(0, n_tiles, step)):
        q = slice(cut[b], cut[b + 1])
        c = candidates[tile_group[s:s + step]]  # [T, m]
        padded = queries.new_zeros(c.shape[0], width, queries.shape[1])
        padded[tile[q] - s, col[q]] = queries[order[q]]
        d = sq[c][:, None, :] - 2 * padded @ points[c].mT  # [T, width, m]
        best = c.gather(1, d.argmin(-1))  # [T, width]
        out[order[q]] = best[tile[q] - s, col[q]]
    return out


def fmap_to_p2p(C: Tensor, evecs: Tensor, evecs_src: Tensor | None = None) -> Tensor:
    """Vertex map of a functional map: ``p2p[i] = argmin_j ||evecs[j] - evecs_src[i] @ C||``.

    Args:
        C: [K', K] or [B, K', K] pull-back functional map(s).
        evecs: [V, K] basis of the image shape.
        evecs_src: [V', K'] basis of the domain (defaults to ``evecs``, a self-map).

    Returns:
        [V'] or [B, V'] long.
    """
    src = evecs if evecs_src is None else evecs_src
    if C.shape[-2] != src.shape[-1] or C.shape[-1] != evecs.shape[-1]:
        raise ValueError(f"C must be [{src.shape[-1]}, {evecs.shape[-1]}], got {list(C.shape)}")
    if C.dim() == 3:
        return torch.stack([nearest_neighbors(src @ c, evecs) for c in C])
    return nearest_neighbors(src @ C, evecs)


class TwoLevelSearch:
    """Vertex maps ``p2p[i] = argmin_j ||evecs[j] - evecs[i] @ C||`` of a shape onto itself, in two levels.

    The samples' images are searched among the samples; every vertex then searches only the
    ``n_local`` vertices nearest in space to the image of its own sample (its ``cells`` entry):
    V * n_local distances instead of V * V. An isometry is continuous and the samples lie much
    closer together than the accuracy asked of the map, so the answers are those of the full search
    up to near-ties (``tests/test_maps.py``). The images of samples are samples, so each sample's
    ``n_local`` spatial neighbours are looked up once, when the search is built.

    Args:
        verts: [V, 3] positions; evecs: [V, K] the embedding (searched in float32 at the vertex level).
        samples: [S] vertex ids; cells: [V] long, position in ``samples`` of each vertex's sample
            (``geodesics.voronoi_cells``, or the nearest sample in space); -1 anywhere, or
            ``n_local`` <= 0, means the full search.
    """

    def __init__(self, verts, evecs: Tensor, samples: Tensor, cells: Tensor, n_local: int):
        from scipy.spatial import cKDTree

        V = evecs.shape[0]
        self.evecs, self.evecs32 = evecs, evecs.float()
        self.samples, self.cells = samples.to(evecs.device), cells.to(evecs.device)
        self.full = n_local <= 0 or n_local >= V or bool((cells < 0).any())
        self.near = None  # [S, n_local] the spatial neighbours of each sample
        if not self.full:
            x = to_numpy(verts)
            _, nb = cKDTree(x).query(x[self.samples.cpu().numpy()], k=n_local)
            self.near = torch.as_tensor(np.asarray(nb).reshape(len(samples), -1), device=evecs.device)

    def __call__(self, C: Tensor, at: Tensor | None = None) -> Tensor:
        """Images of the vertices ``at`` (default all) under ``C [k, k]``: [N] long."""
        k = C.shape[-1]
        E = self.evecs[:, :k]
        at = torch.arange(E.shape[0], device=E.device) if at is None else at
        if self.full:
            return nearest_neighbors(E[at] @ C, E)
        Es = E[self.samples]
        pos = nearest_neighbors(Es @ C, Es)  # [S] images of the samples, as positions in samples
        return nearest_neighbors_among((E[at] @ C).float(), self.evecs32[:, :k], self.near[pos], self.cells[at])
