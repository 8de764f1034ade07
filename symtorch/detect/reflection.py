"""Reflective (C2) symmetry detection (ALGORITHM §4), with candidate verification that holds on
real, posed meshes.

Pipeline (stage names as in ``SymmetryResult.timings``):

1. **candidates** (``symtorch.detect.involutions``) — heat-kernel maxima at ``t = 4 ln 10 / λ2`` and
   ``t/4`` (limb tips), thinned by geodesic non-maximum suppression. Seeds: two mutually symmetric pairs chosen by descriptor
   closeness and geodesic consistency (the paper's step). Each seed is then *extended to an
   involutive permutation of all extrema*: every other extremum takes the partner (possibly itself)
   whose geodesic distances to the already-paired extrema agree best. Seeds giving the same
   permutation collapse into one candidate, and each permutation is scored by how well it keeps all
   geodesic distances among the extrema — a map that swaps the hands but not the feet keeps the
   distances among its own two pairs but not among all five limb tips.
2. **procrustes** — one block-orthogonal matrix per candidate permutation in the coarse basis, from
   multi-scale geodesic-disk indicators around every paired extremum plus HKS/WKS columns, all
   candidates in one batched band-by-band Procrustes (ALGORITHM §3).
3. **refine** — each of the best candidates is grown to a medium basis by spectral upsampling with
   the involution structure (``refine.zoomout_symmetry``; one that already preserves the
   orientation halfway, near k=14, is dropped there); the one whose vertex map reverses the
   orientation most consistently (``orientation_vote``: a reflection reverses it everywhere, an
   identity-like collapse nowhere, a partial swap in places) wins and is grown to the final basis.
4. **p2p**, **verify** — the dense vertex map (the samples' images searched among the samples,
   every other vertex near the image of its sample: ``maps.TwoLevelSearch``) and a geodesic-distortion
   confidence (``involution_distortion``: read off the samples' own distance fields, no solve per
   map); below ``min_score`` the reflection is not reported (no forced symmetry on an asymmetric
   shape).
5. **select_guided** — only where nothing verified: the selection again, each candidate's
   upsampling guided by features whose sign a reflection flips (``_orientation_guide``), then
   refine/p2p/verify once more. On posed humans the right candidate's plain upsampling can slide to
   the orientation-preserving near-isometry (left-right and front-back swapped at once).
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import torch
from torch import Tensor

from .._checks import to_numpy
from .constraints import descriptor_coefficients, disk_coefficients
from ..descriptors import descriptors, gradient_cross
from ..units import EPS_KLC
from ..geodesics import GeodesicSolver, voronoi_cells
from .involutions import heat_extrema, involution_candidates
from ..maps import TwoLevelSearch, nearest_neighbors
from ..procrustes import block_procrustes
from ..refine import zoomout_symmetry
from .result import Symmetry, SymmetryResult
from ..sampling import farthest_point_sampling
from ..spectrum import Spectrum, band_boundary, solved_bands


__all__ = ["detect_reflection", "isometry_score", "involution_distortion", "descriptor_gap",
           "orientation_vote", "EPS_KLC"]


def isometry_score(solver: GeodesicSolver, p2p: Tensor, samples: Tensor, return_worst: bool = False,
                   source_dist: Tensor | None = None) -> tuple[float, float] | tuple[float, float, float]:
    """Confidence that ``p2p`` is an isometry, from geodesic distortion among sample points.

    distortion = mean over sample pairs of ``|d(g(s_i), g(s_j)) - d(s_i, s_j)|`` on the unit-area
    shape, in units of the KLC tolerance; score = ``exp(-distortion²)`` (the benchmarks' ground
    truth, distortion ~0.1, scores ~0.99; a wrong map, distortion > 1, scores < 0.4).

    Returns:
        (score in [0, 1], distortion), and with ``return_worst`` the largest per-sample distortion
        (mean over the other samples), which exposes a map that is good on most of the shape but
        wrong on one part of it.

    ``source_dist``: ``solver.pairwise(samples)``, when several maps are scored on one sample set
    (it does not depend on the map; each call then solves only from the images).
    """
    D0 = solver.pairwise(samples) if source_dist is None else source_dist
    D1 = solver.pairwise(p2p[samples])
    err = np.asarray((D1 - D0).abs()) / EPS_KLC
    distortion = float(err.mean())
    if return_worst:
        return math.exp(-distortion ** 2), distortion, float(err.mean(1).max())
    return math.exp(-distortion ** 2), distortion


def involution_distortion(fields: Tensor, samples: Tensor, p2p: Tensor,
                          return_worst: bool = False) -> tuple[float, float] | tuple[float, float, float]:
    """``isometry_score`` for a map that should be an isometric involution, with no solve per map.

    For an isometry ``g`` with ``g∘g = id``, ``d(s_i, g(s_j)) = d(g(s_i), g(g(s_j))) = d(g(s_i), s_j)``:
    the matrix ``X[i, j] = d(s_i, g(s_j))``, read off the samples' own distance fields, is symmetric.
    distortion = mean over sample pairs of ``|X[i, j] - X[j, i]|`` in KLC units (0 for a reflection;
    a partial swap, a collapse or a non-involutive map breaks it), score = ``exp(-distortion²)``.

    Args:
        fields: [n, V] geodesic distances from ``samples`` (unit-area shape); samples: [n] vertex ids;
        p2p: [V] the map.

    Returns:
        (score, distortion), and with ``return_worst`` the largest per-sample mean.
    """
    X = fields[:, p2p[samples]]  # [n, n]
    err = to_numpy((X - X.mT).abs()) / EPS_KLC
    distortion = float(err.mean())
    if return_worst:
        return math.exp(-distortion ** 2), distortion, float(err.mean(1).max())
    return math.exp(-distortion ** 2), distortion


def descriptor_gap(desc: Tensor, p2p: Tensor, mass: Tensor) -> float:
    """How much a vertex map changes the isometry-invariant descriptors: an intrinsic symmetry keeps
    them (exactly for an isometry), a map that only keeps geodesic distances on the whole may not
    (a lopsided shape's near-reflection sends one bump onto a smooth patch).

    gap = mass-weighted mean over vertices and columns of ``|z(x) - z(g(x))|``, with ``z`` the
    log-descriptors standardised per column (units of each column's spread over the shape).
    Measured: 0.00-0.24 for the reflections reported on all SCAPE, TOSCA, FAUST and TOSCA_Isometric
    meshes (``scripts/verification_stats.py``), 0.70 for the best near-reflection of the code-built
    asymmetric shape.

    Args:
        desc: [V, D] positive descriptors (``descriptors``); p2p: [V]; mass: [V].
    """
    L = torch.log(desc.clamp_min(1e-12))
    Z = (L - L.mean(0)) / L.std(0).clamp_min(1e-12)
    per_vertex = (Z - Z[p2p]).abs().mean(1)
    return float((mass * per_vertex).sum() / mass.sum())


def vertex_normals(verts: Tensor, faces: Tensor) -> Tensor:
    """[V, 3] area-weighted unit vertex normals."""
    faces = torch.as_tensor(faces).long()
    fn = torch.linalg.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    vn = torch.zeros_like(verts).index_add_(0, faces.reshape(-1), fn.repeat_interleave(3, 0))
    return vn / vn.norm(dim=1, keepdim=True).clamp_min(1e-30)


def orientation_vote(p2p: Tensor, verts: Tensor, normals: Tensor, samples: Tensor, n_neighbors: int = 4,
                     max_stretch: float = 3.0, min_cos: float = 0.5) -> Tensor:
    """Orientation of a vertex map at the scale of a sample spacing, robust to vertex-level noise.

    Every sample ``s`` and two of its nearest samples ``a, b`` form a small triangle; its orientation
    about the normal at ``s`` is compared with that of the image triangle ``g(s), g(a), g(b)`` about
    the normal at ``g(s)``. Triangles several edges wide keep their orientation under the jitter of a
    nearest-neighbour map, where the mesh's own faces do not. Images that collapse or stretch more
    than ``max_stretch`` times do not vote, nor do triangles whose corner normals disagree (cosine
    below ``min_cos``): on a posed shape, Euclidean neighbours may lie on two touching parts (an arm
    against the torso), and such a triangle has no orientation.

    Args:
        p2p: [..., V] vertex maps; verts: [V, 3]; normals: [V, 3]; samples: [S] vertex ids.

    Returns:
        [...] vote in [-1, 1]: +1 keeps the orientation, -1 reverses it (a reflection).
    """
    x = verts[samples]
    nn = torch.cdist(x, x).topk(n_neighbors + 1, largest=False).indices[:, 1:]  # [S, n]
    ia, ib = torch.triu_indices(n_neighbors, n_neighbors, 1)
    a, b = samples[nn[:, ia]], samples[nn[:, ib]]  # [S, P]
    s = samples[:, None].expand_as(a)

    def det(p, q, r):
        e1, e2 = verts[q] - verts[p], verts[r] - verts[p]
        return (torch.linalg.cross(e1, e2) * normals[p]).sum(-1), torch.maximum(e1.norm(dim=-1), e2.norm(dim=-1))

    d0, l0 = det(s, a, b)
    g = p2p[..., s], p2p[..., a], p2p[..., b]
    d1, l1 = det(*g)

    def flat(p, q, r):  # all three normals agree: the triangle lies on one sheet of the surface
        return ((normals[p] * normals[q]).sum(-1) > min_cos) & ((normals[p] * normals[r]).sum(-1) > min_cos)

    ok = (d0.abs() > 0.1 * l0.square()) & (d1.abs() > 0.05 * l1.square()) & (l1 < max_stretch * l0) \
        & flat(s, a, b) & flat(*g)
    vote = torch.sign(d0) * torch.sign(d1) * ok
    return vote.sum((-2, -1)) / ok.sum((-2, -1)).clamp_min(1)


def detect_reflection(verts: Tensor, faces: Tensor, spectrum: Spectrum, *, k: int = 6, k_refine: int = 100,
                      k_select: int = 30, n_samples: int = 2000, n_extrema: int = 12, nms_radius: float = 2.0,
                      n_candidates: int = 8, block_refine: bool = False, min_score: float = 0.5,
                      max_vote: float = 0.2, max_worst: float = 1.5, early_vote: float = 0.6, early_distortion: float = 0.25,
                      select_vote: float = 0.4, n_select_verify: int = 16, n_verify: int = 32,
                      n_local: int = 64, w_guide: float = 1.0, compare_ratio: float = 2.0,
                      verify: str = "involution", n_iter_all: int = 0, step_refine: int = 12,
                      max_descriptor_gap: float = 0.4, prune_k: int = 14, prune_vote: float = 0.3,
                      solver: GeodesicSolver | None = None, timer=None) -> SymmetryResult:
    """The identity and, where one exists, the intrinsic reflection of a mesh (see module doc).

    Args:
        verts: [V, 3] float64 (original units); faces: [F, 3] long.
        spectrum: ``laplacian_spectrum(verts, faces, k > k_refine)`` (unit area).
        k: coarse basis size the upsampling starts from, or several (each is tried per candidate;
            on SCAPE a second start of 12 or 20 did not help); k_select: basis size the candidates
            are compared in; k_refine: final basis size (each snapped to a band end).
        n_candidates: candidate permutations refined and compared.
        min_score: smallest isometry confidence (``isometry_score``) a reported reflection has.
        max_vote: a reported reflection's orientation vote is below ``-max_vote``.
        max_worst: and no sample's mean geodesic distortion exceeds this (KLC units): a map that
            is right on most of the shape but wrong on one part is not a symmetry.
        max_descriptor_gap: and the map changes the descriptors by less than this
            (``descriptor_gap``: at most 0.24 measured on real reflections, 0.70 on the near-
            reflection of a lopsided shape that keeps geodesic distances to 0.23 eps).
        select_vote: candidates voting below ``-select_vote`` are compared by geodesic distortion
            (``isometry_score`` on ``n_select_verify`` samples), the others only by their vote.
        early_vote, early_distortion: stop comparing candidates once one votes below
            ``-early_vote`` with a distortion below ``early_distortion`` (KLC units) and the next
            candidate's consistency score exceeds ``compare_ratio`` times the first's.
        prune_k, prune_vote: each candidate's upsampling stops at ``prune_k`` (a band end) to vote;
            one whose vote exceeds ``prune_vote`` (it already preserves the orientation) is not grown
            to ``k_select`` (0: no stop). Against no stop: SCAPE (71) 94.1 -> 94.5 % / 44.6 -> 44.1e-3,
            TOSCA_Isometric (76) 95.5 -> 95.4 % / 33.5 -> 33.4, TOSCA 17.8 -> 17.7, FAUST 46.4 -> 46.6;
            selection ~15 % faster. The rate changes come from the two-stage schedule itself (the same
            with ``prune_vote=2``, nothing dropped): per-mesh ups and downs, not a systematic gain.
        step_refine: smallest basis growth per step of the final upsampling (12 instead of 4: the same
            accuracy on 8 SCAPE meshes at k_refine=100, refine 0.26 -> 0.07 s).
        n_iter_all: final upsampling iterations fitted against every vertex rather than the samples
            (1: SCAPE 45.6e-3, TOSCA 17.5e-3, refine +0.06 s a SCAPE mesh; 0: 45.4, 17.8; FAUST and
            TOSCA_Isometric the same either way).
        n_verify: samples of the final geodesic verification (one heat solve each, shared with the
            selection's first ``n_select_verify``).
        verify: the final verification's distortion: 'involution' (``involution_distortion``, no
            solve per map) or 'images' (``isometry_score``, one solve per sample image). The same
            rates and errors on SCAPE (71), TOSCA, FAUST and TOSCA_Isometric (76); verify stage
            0.08 -> 0.00 s a SCAPE mesh. (As the selection's measure, on 16 or 32 samples, it moved
            TOSCA_Isometric 94.6 -> 94.2 / 93.6 %: the selection keeps ``isometry_score``.)
        w_guide: weight of the orientation guide (``_orientation_guide``) in a second selection,
            run only where the first one yields no verified reflection (0: no second selection).
        n_local: the final vertex map searches each vertex's image among this many vertices near
            the image of its sample (``maps.TwoLevelSearch``, graph Voronoi cells; 0: among all).
            On SCAPE (71) and FAUST (10) the same rates and errors as the full search, p2p stage
            0.38 -> 0.14 s at 12.5K; the samples' images searched among the samples instead of all
            vertices: the same rates and errors on all four datasets (TOSCA 17.6 -> 17.8e-3,
            TOSCA_Isometric 33.4 -> 33.5), 0.05 s less.

        solver: a ``GeodesicSolver`` of the unit-area mesh (``verts * spectrum.scale``) to reuse
            (``detect_symmetries`` shares one between the two paths); default one of its own.

    Returns:
        SymmetryResult (``group`` left empty for the caller), on CPU.
    """
    if verify not in ("involution", "images"):
        raise ValueError(f"verify must be 'involution' or 'images', got {verify!r}")
    lap = timer.lap if timer is not None else (lambda name: None)
    spectrum = spectrum.to("cpu")  # the geometry it meets is solved on the host
    evals, evecs, mass = spectrum.evals, spectrum.evecs, spectrum.mass
    bands = solved_bands(evals)
    ks, kf = band_boundary(bands, k_select), band_boundary(bands, k_refine)
    # coarse sizes the upsampling may start from: near-identity and reflection differ in few of the
    # first modes, so a small start can collapse to the identity where a larger one holds
    starts = sorted({band_boundary(bands, x) for x in (k if isinstance(k, (tuple, list)) else (k,))})
    k0 = starts[-1]
    V = evecs.shape[0]
    verts_unit = torch.as_tensor(verts) * spectrum.scale
    solver = GeodesicSolver(verts_unit, faces) if solver is None else solver
    ext, dist_ext = heat_extrema(evals, evecs, faces, solver, n_extrema, nms_radius)
    desc = descriptors(evals, evecs)  # [V, D]
    D_ext = dist_ext[:, ext].numpy()
    D_ext = 0.5 * (D_ext + D_ext.T)
    logdesc = torch.log(desc[ext].clamp_min(1e-12)).numpy()
    perms, perm_scores, n_seeds = involution_candidates(logdesc, D_ext)
    lap("candidates")
    info = {"n_extrema": int(len(ext)), "n_seeds": n_seeds, "n_candidates": len(perms), "k0": starts,
            "k_refine": kf, "candidate_scores": [round(float(s), 4) for s in perm_scores[:8]]}
    symmetries = [Symmetry(torch.eye(kf, dtype=evecs.dtype), torch.arange(V), "identity", 1, 1.0)]
    if not perms:
        return SymmetryResult(symmetries, spectrum, bands, timings=_timings(timer), info=info)
    perms = perms[:n_candidates]
    # constraints: multi-scale geodesic disks around each paired extremum, plus descriptors
    bands0 = [b for b in bands if b.stop <= k0]
    E0 = evecs[:, :k0]
    A_disk = disk_coefficients(E0, mass, dist_ext)  # [N, R, k0]
    A_desc = descriptor_coefficients(E0, mass, desc)  # [k0, D]
    n_radii = A_disk.shape[1]
    n_max = max(int((p >= 0).sum()) for p in perms)
    A = torch.zeros(len(perms), k0, n_max * n_radii + desc.shape[1], dtype=evecs.dtype)
    B = torch.zeros_like(A)
    for c, perm in enumerate(perms):
        src = np.flatnonzero(perm >= 0)
        # 1_{g(a)} ∘ g = 1_a: the disk at the image goes to F, the disk at the point to G
        A[c, :, : len(src) * n_radii] = A_disk[perm[src]].reshape(-1, k0).mT
        B[c, :, : len(src) * n_radii] = A_disk[src].reshape(-1, k0).mT
        A[c, :, n_max * n_radii:] = A_desc
        B[c, :, n_max * n_radii:] = A_desc
    C0 = block_procrustes(A, B, bands0)  # [P, k0, k0]
    lap("procrustes")
    samples = farthest_point_sampling(verts_unit, min(n_samples, V))
    sel = samples[: max(len(samples) // 2, 1)]
    vt, ft = verts_unit, torch.as_tensor(faces)
    normals = vertex_normals(vt, ft)
    vote_samples = samples[: min(500, len(samples))]
    # distances among the first samples, solved once: the selection compares every candidate on
    # the first n_select_verify of them, the verification uses the first n_verify
    base_dist = []

    def sample_fields() -> Tensor:
        if not base_dist:
            base_dist.append(solver.distances_from(samples[: max(n_verify, n_select_verify)]))
        return base_dist[0]

    def sample_dist(n: int) -> Tensor:
        D = sample_fields()[:n, samples[:n]]
        D = 0.5 * (D + D.mT)
        return D.fill_diagonal_(0.0)

    search = []

    def dense_search() -> TwoLevelSearch:
        if not search:  # graph Voronoi cells: parts that touch in space but not on the surface stay apart
            cells = voronoi_cells(vt, ft, samples) if 0 < n_local < V else torch.zeros(V, dtype=torch.long)
            search.append(TwoLevelSearch(vt, evecs, samples, cells, n_local))
        return search[0]

    km = band_boundary(bands, prune_k) if prune_k > 0 else 0

    def vote_of(C: Tensor) -> tuple[Tensor, float]:
        """The map of ``C`` on the vote samples (identity elsewhere) and its orientation vote."""
        kk = C.shape[-1]
        p2p_s = torch.arange(V)
        p2p_s[vote_samples] = samples[nearest_neighbors(evecs[vote_samples, :kk] @ C, evecs[samples, :kk])]
        return p2p_s, float(orientation_vote(p2p_s, vt, normals, vote_samples))

    def select(guided: bool):
        """Upsample the candidates to ``ks``; the best one (see below) and the trials."""
        best, trials, guides = None, [], {}
        for c, kc in itertools.product(range(len(perms)), starts):
            if guided and c not in guides:  # one per candidate, whatever the coarse start
                guides[c] = _orientation_guide(verts_unit, faces, dist_ext, perms[c], w_guide)
            guide = guides.get(c)
            Cs, pruned = C0[c, :kc, :kc], False
            if kc < km < ks:  # halfway: a candidate that already preserves orientation is dropped
                Cs = zoomout_symmetry(Cs, evecs, mass, bands, km, samples=sel, involution=True,
                                      block=block_refine, targets=samples, guide=guide, n_iter_end=0)
                p2p_s, vote = vote_of(Cs)
                pruned = vote > prune_vote
            if not pruned:
                Cs = zoomout_symmetry(Cs, evecs, mass, bands, ks, samples=sel, involution=True,
                                      block=block_refine, targets=samples, guide=guide)
                p2p_s, vote = vote_of(Cs)
            # a reflection reverses the orientation everywhere (identity-like collapses vote +1,
            # partial swaps near 0); among the clearly reversing candidates the most isometric one
            # wins: a limb mirrored onto itself instead of onto its twin also reverses orientation,
            # but breaks the distances where it joins the body
            distortion = math.inf
            if not pruned and vote < -select_vote:
                distortion = isometry_score(solver, p2p_s, samples[:n_select_verify],
                                            source_dist=sample_dist(n_select_verify))[1]
            trials.append((round(vote, 3), round(distortion, 3)))
            key = (0, distortion) if math.isfinite(distortion) else (1, vote)
            if best is None or key < best[0]:
                best = (key, (c, kc), Cs)
            if (vote < -early_vote and distortion < early_distortion
                    and (c + 1 >= len(perms) or perm_scores[c + 1] > compare_ratio * perm_scores[0])):
                # clearly a full reflection, and the next candidates are clearly less consistent
                # (candidates nearly as consistent as the first are all compared: they differ in how
                # a few extrema pair up, e.g. a paw swapped or kept, which only the maps tell apart)
                break
        return best, trials

    def refine_and_verify(Cs):
        """Final ZoomOut, dense map and verification: (C, p2p, score, accepted, checks)."""
        Cf = zoomout_symmetry(Cs, evecs, mass, bands, kf, samples=samples, involution=True,
                              block=block_refine, targets=samples, n_iter_end=1, step=step_refine)
        if n_iter_all > 0:  # last steps against every vertex
            Cf = zoomout_symmetry(Cf, evecs, mass, bands, kf, samples=samples, involution=True,
                                  block=block_refine, n_iter_end=n_iter_all)
        lap("refine")
        p2p = dense_search()(Cf)
        lap("p2p")
        if verify == "involution":  # no solve: the samples' own fields, read at the images
            score, distortion, worst = involution_distortion(sample_fields()[:n_verify], samples[:n_verify], p2p,
                                                             return_worst=True)
        else:
            score, distortion, worst = isometry_score(solver, p2p, samples[:n_verify], return_worst=True,
                                                      source_dist=sample_dist(n_verify))
        vote = float(orientation_vote(p2p, vt, normals, vote_samples))
        gap = descriptor_gap(desc, p2p, mass)
        lap("verify")
        ok = score >= min_score and vote < -max_vote and worst < max_worst and gap < max_descriptor_gap
        return Cf, p2p, score, ok, {"distortion": distortion, "worst_distortion": worst, "orientation": vote,
                                    "descriptor_gap": gap}

    best, trials = select(False)
    info["trials"], info["chosen"] = trials, best[1]
    lap("select")
    Cf, p2p, score, ok, checks = refine_and_verify(best[2])
    info.update(checks)
    if not ok and w_guide > 0:
        # nothing verified: on strongly posed shapes the right candidate's upsampling can slide to
        # the orientation-preserving near-isometry (left-right and front-back swapped at once);
        # try again with features whose sign a reflection must flip (only here: as the first
        # choice the guide also makes wrong candidates reverse orientation, SCAPE 87 % vs 94.5 %)
        best, trials = select(True)
        info["guided_trials"], info["guided_chosen"] = trials, best[1]
        lap("select_guided")
        Cf, p2p, score, ok, checks = refine_and_verify(best[2])
        info["guided"] = checks
    if ok:
        symmetries.append(Symmetry(Cf, p2p, "reflection", 2, score))
    return SymmetryResult(symmetries, spectrum, bands, timings=_timings(timer), info=info)


def _orientation_guide(verts: Tensor, faces: Tensor, dist: Tensor, perm: np.ndarray,
                       weight: float) -> tuple[Tensor, Tensor]:
    """Guide features for a candidate: gradient crosses of its paired extrema's distance fields.

    Source side ``weight * x(a, b)``, target side ``-weight * x(perm a, perm b)``: a reflection that
    maps ``a`` to ``perm a`` flips the sign of the cross product (``descriptors.gradient_cross``).
    """
    src = np.flatnonzero(perm >= 0)
    pairs = torch.as_tensor(list(itertools.combinations(range(len(src)), 2)), dtype=torch.long).reshape(-1, 2)
    fields = dist[torch.as_tensor(src)]
    images = dist[torch.as_tensor(perm[src])]
    return (weight * gradient_cross(verts, faces, fields, pairs),
            -weight * gradient_cross(verts, faces, images, pairs))


def _timings(timer) -> dict:
    return dict(timer.timings) if timer is not None else {}
