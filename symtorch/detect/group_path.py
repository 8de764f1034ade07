"""Whole finite symmetry groups: rotations and reflections together (ALGORITHM §5; Wang & Huang 2017 §4.2).

Pipeline, every step automatic (no hand-typed bands, orbit or group size; steps 1 and 2 live in
:mod:`symtorch.detect.candidates`):

1. **Invariant points** ``P``: local maxima and minima of the heat kernel signature at three
   scales (``t = 4 ln10 / lambda_2`` times 1, 1/10, 1/50: limb tips down to corners), thinned by
   farthest-point suppression (no two kept points closer than ``nms_radius * eps`` on the unit-area
   shape, ``eps = sqrt(area / (20 pi))``). Maxima of invariant functions form a union of orbits.
2. **Candidates**: ``m`` = the largest band of the coarse basis; tuples of ``t = m + 1`` points pin
   every band (each point gives one direction per band). The paper pairs *all* source tuples with all
   ordered target tuples (``C(n, m)^2 m!``); one source tuple already pins each symmetry, so here a
   few well-spread source tuples (``n_sources``) are paired with every ordered target tuple of ``P``,
   enumerated level by level and pruned on the fly when a geodesic ratio ``d(p_i, p_j) / d(q_i, q_j)``
   (or its inverse) falls below ``delta = 0.9`` (with a slack of ``0.5 eps`` for short distances and
   heat-method error), or when ``p_i`` and ``q_i`` disagree in their multi-scale log HKS/WKS or in
   their sorted geodesic distances to all of ``P`` (equal for orbit partners). Source points are
   taken among those that have such a partner. Counts before/after pruning go to ``info``; at most
   ``max_candidates`` (best Procrustes fit) go on.
3. **Matrices**: one batched ``block_procrustes`` over all candidates. Constraints as in the
   reflection path: Gaussian geodesic disks of radii 0.5, 1, 2 ``eps`` around each tuple point
   (``1_{g(p)} ∘ g = 1_p``), plus the HKS/WKS columns unchanged.
4. **Mean shift** of the flattened matrices (Euclidean, Gaussian kernel), all points moved at once
   in torch. Bandwidth: ``bandwidth`` (absolute Frobenius); default ``0.6``, below the distance 2 of
   two orthogonal matrices that differ by one sign (the closest distinct symmetries can be).
   Before clustering every candidate takes ``n_icp`` batched spectral-ICP steps on sample vertices,
   so that the candidates of one symmetry found from different tuples agree (the raw Procrustes
   solutions of noisy tuples scatter by more than the gap between elements).
5. **Refinement, verification, closure**. Stage A, in the coarse basis and on 1000 sample vertices:
   each mode's member nearest the mode is refined (``refine.zoomout_symmetry(block=True)`` from
   samples to samples: ZoomOut kept block-orthogonal, or fixed-size spectral ICP with
   ``refine='icp'``; both give the same groups, see BENCHMARKS.md), screened by distortion, and
   dropped if it duplicates an element; the set is closed under composition (``groups.closure``) and
   what closure adds is refined and screened the same way. Stage B upsamples the distinct elements to
   ``k_refine``, maps every vertex (two-level nearest neighbour) and measures the distortion exactly.
   The group is the largest set of verified elements closed under composition of their *maps*
   (``group_maps.largest_subgroup``); table, inverses, orders and name by ``groups.group_info``, with
   orientation flags that are a homomorphism of the table and agree best with
   ``groups.orientation_score`` (``group_maps.consistent_orientation``); elements ordered as the
   paper's Table 3 (identity, rotation powers, reflection coset).
6. **Continuous symmetry** (sphere, surface of revolution): an incommensurate rotation (0.55 and
   0.83 rad) of the first multi-dimensional band is refined; if both stay where they were put *and*
   are near-isometries, the shape has a one-parameter family of symmetries and the result is
   ``continuous=True`` with the identity only.

Confidence of an element: ``exp(-distortion^2)``. A first, cheap screen (every cluster) uses only the
distance fields of P: the mean over the points ``p`` of ``P`` and 200 sample vertices ``x`` of
``|d(pi(p), g(x)) - d(p, x)| - off(p)`` (clamped at 0), plus a quarter of the mean ``off``, in units of
``eps``, where ``pi(p)`` is the point of ``P`` nearest to ``g(p)`` and ``off(p) = d(g(p), pi(p))``. P is
invariant, so for an exact symmetry ``pi(p) = g(p)`` and this is 0; the ``off`` discount (triangle
inequality) keeps points of P placed slightly asymmetrically (flat extrema) from counting. It needs
no new distance field. The elements that pass are then measured exactly,
``|d(g(s), g(x)) - d(s, x)|`` from 10 spread sources ``s`` to the 200 samples ``x`` (10 heat solves
per element), and that is the distortion reported and thresholded (``max_distortion = 0.25``).
True symmetries measure 0.0-0.15 (table.off 0.03, SCAPE's mirror 0.12); wrong maps > 0.3 (the
spurious "rotation" the screen lets through on SCAPE mesh000 measures 0.35).

Limits: triangle meshes only (``detect_symmetries`` refuses point clouds); one connected component
(HKS times use the first non-zero eigenvalue); a symmetry is representable only where the spectrum
keeps its eigenspaces together, so a shape whose quarter-turn eigenspaces split by more than
``eigen_bands``' tolerance (SHREC'07 table 143: 14 %) gives the subgroup its bands can carry; the
continuous test looks at the first repeated band only (a rotation axis that shows up only in higher
bands is missed, and the shape is treated as finite).
"""
from __future__ import annotations

import logging
import math
import warnings

import numpy as np
import torch
from torch import Tensor

from ..cluster import mean_shift
from .constraints import descriptor_coefficients, disk_coefficients
from ..descriptors import descriptors
from ..units import EPS_KLC
from ..geodesics import GeodesicSolver
from .candidates import candidate_tuples, invariant_points, source_tuples
from ..groups.from_maps import canonical_order, consistent_orientation, largest_subgroup
from ..groups.algebra import (DEFAULT_TOL, _rel_dist, cayley_table, closure, group_info, kind_of,
                     orientation_reversing, orientation_score)
from ..procrustes import block_procrustes, block_project
from ..maps import TwoLevelSearch, p2p_to_fmap
from ..refine import zoomout_symmetry
from .result import Symmetry, SymmetryResult
from ..sampling import farthest_point_sampling
from ..spectrum import Spectrum, band_boundary, eigen_bands, solved_bands

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------- refinement
def batched_icp(C: Tensor, E_src: Tensor, E_tgt: Tensor, bands: list[range], n_iter: int = 2,
                chunk: int = 128) -> Tensor:
    """A few spectral ICP steps on many candidates at once (before clustering).

    Each step maps the source rows to their nearest target rows (``E_src @ C``), then solves the block
    Procrustes ``E_src @ C ≈ E_tgt[nn]`` (transposed: ``C.T @ E_src.T ≈ E_tgt[nn].T``). Candidates of
    one symmetry found from different point tuples then agree closely, so that mean shift merges them.

    Args:
        C: [B, k, k]; E_src: [S, k] rows of sample vertices; E_tgt: [T, k] rows of target vertices
            (a superset of the sources' images); bands: covering ``0..k-1``.

    Returns:
        [B, k, k] block-orthogonal.
    """
    out = []
    Et = E_tgt.float()
    sq = Et.square().sum(-1)
    for Cb in C.split(chunk):
        for _ in range(n_iter):
            Q = (E_src @ Cb).float()  # [b, S, k]
            nn = (sq[None, None] - 2 * Q @ Et.mT).argmin(-1)  # [b, S]
            Cb = block_procrustes(E_src.mT.expand(len(Cb), -1, -1), E_tgt[nn].mT, bands).mT
        out.append(Cb)
    return torch.cat(out)


class _Geometry:
    """What verification and refinement need, computed once per shape."""

    def __init__(self, verts_unit: np.ndarray, faces: np.ndarray, spectrum: Spectrum, points: np.ndarray,
                 dist_points: Tensor, n_samples: int):
        self.evecs, self.mass = spectrum.evecs, spectrum.mass
        V = self.evecs.shape[0]
        vt = torch.as_tensor(verts_unit)
        # farthest points among a regular subset of the vertices (4 per sample): the same spread at
        # a fraction of the cost of running over every vertex
        sub = torch.arange(0, V, max(1, V // (4 * n_samples)))
        self.samples = sub[farthest_point_sampling(vt[sub], min(n_samples, len(sub)))]  # [S]
        self.score_samples = self.samples[: min(200, len(self.samples))]
        self.points = torch.as_tensor(points)
        self.dist_points = dist_points  # [n, V]
        # two-level vertex maps: the map on the samples, carried to every vertex by continuity
        # (cells: the nearest sample in space; ~2 Voronoi cells of a sample searched per vertex)
        from scipy.spatial import cKDTree

        _, ns = cKDTree(verts_unit[self.samples.numpy()]).query(verts_unit)
        c = min(max(2 * V // max(len(self.samples), 1), 12), V)
        self.search = TwoLevelSearch(verts_unit, self.evecs, self.samples, torch.as_tensor(np.asarray(ns)), c)

    def p2p(self, C: Tensor, at: Tensor | None = None) -> Tensor:
        """Vertex map of C [k, k] at the vertices ``at`` (default all): ``maps.TwoLevelSearch``."""
        return self.search(C, at)

    def distortion_at(self, gp: Tensor, gx: Tensor) -> float:
        """Geodesic distortion (units of eps) from the images ``gp`` of the points and ``gx`` of the
        score samples (see the module docstring)."""
        D = self.dist_points  # [n, V]
        pi = D[:, gp].argmin(0)  # [n] point nearest to g(p)
        off = D[pi, gp]  # [n] how far g(p) lands from the point of P standing for it
        # |d(pi(p), g(x)) - d(g(p), g(x))| <= off(p) (triangle inequality): discount that much, so
        # that points of P placed slightly asymmetrically (flat extrema) do not count as distortion
        dev = ((D[pi][:, gx] - D[:, self.score_samples]).abs() - off[:, None]).clamp_min(0).mean()
        return float((dev + 0.25 * off.mean()) / EPS_KLC)


# ------------------------------------------------------------------------------------ detection
def _at_most(spectrum: Spectrum, n: int) -> Spectrum:
    """The spectrum cut at the band end nearest ``n`` (unchanged when it has no more)."""
    K = spectrum.evals.shape[0]
    if K <= n:
        return spectrum
    end = band_boundary(eigen_bands(spectrum.evals), n)
    if end >= K:
        return spectrum
    return Spectrum(spectrum.evals[:end], spectrum.evecs[:, :end], spectrum.mass, spectrum.scale)


def _coarse_bands(bands: list[range], k: int) -> tuple[list[range], int]:
    k0 = band_boundary(bands, k)
    return [b for b in bands if b.stop <= k0], k0


def continuous_test(geo: _Geometry, solver: GeodesicSolver, bands: list[range], k0: int,
                    angles=(0.55, 0.83), max_distortion: float = 0.6) -> tuple[bool, dict]:
    """Whether the shape has a continuous (one-parameter) family of isometries (ALGORITHM §7).

    The first band of size >= 2 is rotated by an angle no finite group of small order has there
    (0.55, then 0.83 rad), the rest kept; the matrix is refined. A finite group snaps it to one of its
    elements (or the refinement is no isometry); a continuous symmetry keeps it: the refined band
    block stays near the rotation put in, and the map is a near-isometry. Both angles must pass.

    Returns:
        (continuous, diagnostics).
    """
    multi = [b for b in bands[1:] if len(b) >= 2 and b.stop <= k0]
    diag: dict = {"tested_band": None}
    if not multi:
        return False, diag
    b = multi[0]
    diag["tested_band"] = [b.start, b.stop]
    ks = b.stop
    passed = []
    smp = geo.samples[:: max(1, len(geo.samples) // 12)][:12]
    D_smp = None  # distances among smp: the same for every angle
    for a in angles:
        C0 = torch.eye(ks, dtype=geo.evecs.dtype)
        c, s = math.cos(a), math.sin(a)
        i, j = b.start, b.start + 1
        C0[i, i], C0[i, j], C0[j, i], C0[j, j] = c, -s, s, c
        C = _zoomout(geo, C0, bands, k0)
        D0, D1 = C0[b.start:b.stop, b.start:b.stop], C[b.start:b.stop, b.start:b.stop]
        stay = float((D1 - D0).norm() / math.sqrt(len(b)))
        if stay >= 0.3:  # snapped away from the rotation put in: no need to measure distortion
            diag[f"angle_{a}"] = {"stay": round(stay, 3), "pass": False}
            passed.append(False)
            break
        img = geo.p2p(C, smp)
        if D_smp is None:
            D_smp = solver.pairwise(smp)
        dist = float((solver.pairwise(img) - D_smp).abs().mean() / EPS_KLC)
        ok = stay < 0.3 and dist < max_distortion
        diag[f"angle_{a}"] = {"stay": round(stay, 3), "distortion": round(dist, 3), "pass": ok}
        passed.append(ok)
        if not ok:
            break
    return all(passed), diag


def _zoomout(geo, C0: Tensor, bands: list[range], k_final: int, step: int = 4, n_iter_end: int = 3) -> Tensor:
    """Block-orthogonal ZoomOut (``refine.zoomout_symmetry``) from samples to samples."""
    return zoomout_symmetry(C0, geo.evecs, geo.mass, bands, k_final, step=step, samples=geo.samples,
                            targets=geo.samples, block=True, n_iter_end=n_iter_end)


def detect_group(verts: np.ndarray, faces: np.ndarray, spectrum: Spectrum, *, k: int = 20,
                 k_refine: int = 60, n_points: int = 40, n_sources: int = 3, delta: float = 0.9,
                 bandwidth: float = 0.6, n_samples: int = 1000, max_distortion: float = 0.25,
                 refine: str = "zoomout", max_modes: int = 64, desc_tol: float = 0.6, n_icp: int = 3,
                 max_candidates: int = 400, device: torch.device | str | None = None,
                 n_eigen: int = 60, solver: GeodesicSolver | None = None, min_order: int = 1,
                 timer=None) -> SymmetryResult:
    """Every symmetry of a mesh as a group (ALGORITHM §5); see the module docstring for the steps.

    Args:
        verts: [V, 3] vertices (original units); faces: [F, 3].
        spectrum: ``laplacian_spectrum`` of the mesh with at least ``k_refine`` (plus margin) pairs.
        k: target size of the coarse basis (snapped to a band end).
        k_refine: target size of the refined basis; the matrices returned live in it.
        n_points: most invariant points.
        n_sources: source tuples paired with all target tuples.
        delta: geodesic ratio threshold of the pruning.
        bandwidth: mean-shift kernel width (absolute Frobenius distance of the coarse matrices).
        n_samples: sample vertices for refinement and verification.
        max_distortion: an element whose geodesic distortion (units of eps) exceeds this is rejected.
        refine: ``'zoomout'`` (band-by-band upsampling) or ``'icp'`` (fixed-size spectral ICP).
        max_modes: most clusters refined.
        max_candidates: most candidates kept for clustering (those whose Procrustes fit is best).
        n_icp: batched spectral ICP steps applied to every candidate before clustering (0: none).
        desc_tol: a target point must have standardised log-descriptors within ``desc_tol`` times the
            median distance of all point pairs of its source point. 0.25 lost the n-gon prism's
            rotations (D2h for D6h) with 50, 70 or 86 eigenpairs, kept them with 60; 0.6 finds the
            same groups as 0.25 everywhere else (code-built shapes, table.off, Watertight) with
            any of those spectrum sizes (octopus meshes +0.5-1 s: more candidates).
        device: where the batched candidate stages run (block Procrustes, batched ICP, mean shift);
            default CPU. Everything else runs on CPU, and the result is on CPU.
        n_eigen: the eigenpairs used (the spectrum is cut at the band end nearest this): the
            descriptors, and so the candidate pruning, change with the number of eigenpairs; the
            n-gon prism gave D2h for D6h from 110 eigenpairs (the reflection path's default
            spectrum) and from 50, 70, 86 at the old ``desc_tol`` 0.25.
        solver: a ``GeodesicSolver`` of the unit-area mesh (``verts * spectrum.scale``) to reuse
            (``detect_symmetries`` shares one between the two paths); default one of its own.
        min_order: the caller only wants a group of at least this order (a second opinion after
            the reflection path found a mirror: 3). Where the coarse stage verifies fewer elements
            than that, the exact stage cannot find more, and the trivial group is returned at once
            (``info["reason"]`` says so) instead of upsampling and measuring them.
        timer: optional ``detect._Timer``.

    Returns:
        SymmetryResult with ``group`` filled (``GroupInfo.to_dict()``), identity first.
    """
    lap = timer.lap if timer is not None else (lambda name: None)
    dev = torch.device("cpu") if device is None else torch.device(device)
    spectrum = _at_most(spectrum.to("cpu"), n_eigen)
    evals, evecs, mass = spectrum.evals, spectrum.evecs, spectrum.mass
    V = evecs.shape[0]
    bands = solved_bands(evals)
    bands0, k0 = _coarse_bands(bands, k)
    kf = band_boundary(bands, k_refine)
    if refine == "icp":
        kf = k0
    m = max(len(b) for b in bands0)
    verts_unit = np.asarray(verts, dtype=np.float64) * spectrum.scale
    solver = GeodesicSolver(verts_unit, faces) if solver is None else solver
    info: dict = {"path": "group", "k0": k0, "k_refine": kf, "m": m,
                  "bands0": [len(b) for b in bands0]}
    # 1. invariant points and their distance fields
    pts = invariant_points(evals, evecs, faces, verts_unit, n_max=n_points)
    D_pts = solver.distances_from(pts)  # [n, V]
    D_pts = torch.as_tensor(np.asarray(D_pts), dtype=evecs.dtype)
    dist = D_pts[:, pts].numpy()
    dist = 0.5 * (dist + dist.T)
    info["n_points"] = int(len(pts))
    lap("points")
    geo = _Geometry(verts_unit, faces, spectrum, pts, D_pts, n_samples)
    lap("samples")
    identity = Symmetry(torch.eye(kf, dtype=evecs.dtype), torch.arange(V), "identity", 1, 1.0)

    def trivial(continuous=False, why=""):
        info["reason"] = why
        g = group_info(torch.eye(kf, dtype=evecs.dtype)[None], torch.zeros(1, dtype=torch.bool))
        return SymmetryResult([identity], spectrum, bands[: len([b for b in bands if b.stop <= kf])],
                              group=g.to_dict(), continuous=continuous,
                              timings=timer.timings if timer else {}, info=info)

    # 6 (first): continuous symmetry
    cont, cdiag = continuous_test(geo, solver, bands, k0)
    info["continuous_test"] = cdiag
    lap("continuous")
    if cont:
        return trivial(True, "continuous symmetry: a rotation by an arbitrary angle is an isometry")
    if len(pts) < 2:
        return trivial(False, "fewer than 2 invariant points")
    # 2. candidates
    desc = descriptors(evals, evecs)  # [V, D]
    logd = torch.log(desc[pts].clamp_min(1e-12))
    logd = logd / logd.std(0, keepdim=True).clamp_min(1e-12)
    dd = torch.cdist(logd, logd).numpy()
    # exact mirror partners have identical descriptors, so the scale is the spread of all pairs
    off = dd[~np.eye(len(pts), dtype=bool)]
    allowed = dd <= max(desc_tol * float(np.median(off)) if off.size else 0.0, 1e-9)
    t = min(m + 1, len(pts))
    # a second invariant: the sorted distances to all of P (equal for orbit partners if P is invariant)
    prof = np.sort(dist, 1)
    pd = np.abs(prof[:, None, :] - prof[None, :, :])
    dist_profile_agree = np.median(pd, -1) <= 0.5 * EPS_KLC + 0.05 * np.median(prof[:, 1:], 1)[:, None]
    allowed &= dist_profile_agree | np.eye(len(pts), dtype=bool)
    partner = allowed.sum(1) > 1
    info["n_points_with_partner"] = int(partner.sum())
    srcs = source_tuples(dist, t, n_sources, partner)
    tuples_src, tuples_dst, before = [], [], 0
    for src in srcs:
        q, tot = candidate_tuples(src, dist, allowed, delta)
        before += tot
        tuples_src.append(np.repeat(np.asarray(src)[None], len(q), 0))
        tuples_dst.append(q)
    P = np.concatenate(tuples_src) if tuples_src else np.zeros((0, t), dtype=np.int64)
    Q = np.concatenate(tuples_dst) if tuples_dst else np.zeros((0, t), dtype=np.int64)
    info.update(tuple_size=t, n_source_tuples=len(srcs), n_candidates_before=int(before),
                n_candidates=int(len(P)))
    lap("candidates")
    if len(P) == 0:
        return trivial(False, "no candidate survived pruning")
    # 3. one batched Procrustes
    E0 = evecs[:, :k0]
    A_disk = disk_coefficients(E0, mass, D_pts).permute(2, 0, 1)  # [k0, n, R]
    A_desc = descriptor_coefficients(E0, mass, desc)  # [k0, D]
    Pt, Qt = torch.as_tensor(P), torch.as_tensor(Q)
    Bn = len(P)
    # 1_{g(p)} ∘ g = 1_p: the functions (A) are disks at the targets q, their pull-backs (B) at p
    A = torch.cat([A_disk[:, Qt].permute(1, 0, 2, 3).reshape(Bn, k0, -1), A_desc.expand(Bn, -1, -1)], -1)
    B = torch.cat([A_disk[:, Pt].permute(1, 0, 2, 3).reshape(Bn, k0, -1), A_desc.expand(Bn, -1, -1)], -1)
    A, B = A.to(dev), B.to(dev)
    C = block_procrustes(A, B, bands0)  # [Bn, k0, k0]
    if Bn > max_candidates:  # keep the candidates whose constraints the matrix fits best
        fit = (C @ A - B).square().sum((-2, -1)) / B.square().sum((-2, -1))
        best = torch.argsort(fit)[:max_candidates]
        C, P, Q, Bn = C[best], P[best.cpu().numpy()], Q[best.cpu().numpy()], max_candidates
        info["n_candidates_kept"] = Bn
    lap("procrustes")
    if n_icp > 0:
        tgt = geo.samples[: min(len(geo.samples), 600)]
        C = batched_icp(C, E0[geo.score_samples].to(dev), E0[tgt].to(dev), bands0, n_icp)
        lap("icp")
    # 4. mean shift
    modes, labels, counts = (x.cpu() for x in mean_shift(C.reshape(Bn, -1), bandwidth))
    C = C.cpu()
    info["n_clusters"] = int(len(modes))
    info["cluster_sizes"] = [int(c) for c in counts[:max_modes].tolist()]
    reps = []
    for j in range(min(len(modes), max_modes)):
        members = torch.nonzero(labels == j)[:, 0]
        best = members[(C[members].reshape(len(members), -1) - modes[j]).norm(dim=1).argmin()]
        reps.append(int(best))
    lap("cluster")
    # 5. refine, verify, deduplicate. Stage A works in the coarse basis and on sample vertices only
    # (cheap), so that every cluster can be checked; stage B upsamples the distinct verified
    # elements to k_refine and maps every vertex.
    elems: list[dict] = []  # C0 [k0, k0], img (images of score samples), dst (distortion)
    rejected, trace = [], []
    x_unit = torch.as_tensor(verts_unit)

    def duplicate_of(img: Tensor, C0: Tensor) -> int:
        """An accepted element with the same images (mean gap < eps/2) or matrix (< DEFAULT_TOL)."""
        if not elems:
            return -1
        imgs = torch.stack([e["img"] for e in elems])  # [G, S']
        gap = (x_unit[imgs] - x_unit[img][None]).norm(dim=-1).mean(-1)  # [G]
        j = int(gap.argmin())
        if float(gap[j]) < 0.5 * EPS_KLC:
            return j
        # maps can differ where an element is ill-pinned; the matrices then still agree
        d = _rel_dist(C0[None], torch.stack([e["C0"] for e in elems]))[0]
        return int(d.argmin()) if float(d.min()) < DEFAULT_TOL else -1

    def add(C0: Tensor) -> bool:
        """Refine a coarse candidate, verify it, and keep it unless it duplicates an element."""
        if refine == "icp":
            E_s = evecs[geo.samples, :k0]  # paper §4.1 step 3: fixed-size spectral ICP on the samples
            C0 = batched_icp(C0[None], E_s, E_s, bands0, n_iter=10)[0]
        else:
            C0 = _zoomout(geo, C0, bands0, k0)
        at = torch.cat([geo.points, geo.score_samples])
        img = geo.p2p(C0, at)
        dst = geo.distortion_at(img[: len(geo.points)], img[len(geo.points):])
        img = img[len(geo.points):]
        j = -1 if dst > max_distortion else duplicate_of(img, C0)
        trace.append((round(dst, 3), j))
        if dst > max_distortion:
            rejected.append(round(dst, 3))
            return False
        if j >= 0:
            if dst < elems[j]["dst"]:
                elems[j] = {"C0": C0, "img": img, "dst": dst}
            return False
        elems.append({"C0": C0, "img": img, "dst": dst})
        return True

    eye0 = torch.eye(k0, dtype=evecs.dtype)
    elems.append({"C0": eye0, "img": geo.score_samples.clone(), "dst": 0.0})
    for i in reps:
        add(C[i])
    info["trace"] = list(trace)
    info["n_verified"] = len(elems)
    info["rejected_distortion"] = rejected[:10]
    lap("refine")
    # closure: add what composition implies, refine and verify those too
    for _ in range(3):
        cl = closure(torch.stack([e["C0"] for e in elems]), tol=DEFAULT_TOL, max_order=2 * len(elems) + 8)
        new = cl.mats[cl.added]
        if len(new) == 0 or not any([add(block_project(Cn, bands0)) for Cn in new]):
            break
    info["n_after_closure"] = len(elems)
    lap("closure")
    if len(elems) < min_order:  # the largest subgroup of these elements has at most len(elems)
        return trivial(False, f"{len(elems)} elements verified in the coarse basis, fewer than the "
                              f"{min_order} asked for")
    # stage B: upsample the distinct elements, map every vertex, measure again -- now exactly:
    # |d(g(s), g(x)) - d(s, x)| from 10 spread sources s (one heat solve per image g(s))
    src = geo.samples[:10].numpy()
    D_src = torch.as_tensor(np.asarray(solver.distances_from(src)))[:, geo.score_samples]

    def exact_distortion(p2p: Tensor) -> float:
        g = p2p.numpy()
        D_img = torch.as_tensor(np.asarray(solver.distances_from(g[src])))[:, p2p[geo.score_samples]]
        return float((D_img - D_src).abs().mean() / EPS_KLC)

    final = []
    for e in elems:
        if e["dst"] == 0.0 and float((e["C0"] - eye0).abs().max()) == 0.0:
            Cf, p2p = torch.eye(kf, dtype=evecs.dtype), torch.arange(V)
        else:
            Cf = e["C0"] if kf == k0 else _zoomout(geo, e["C0"], bands, kf, step=6, n_iter_end=2)
            p2p = geo.p2p(Cf)
        final.append((Cf, p2p, exact_distortion(p2p) if len(final) else 0.0))
    # an element that upsampling made worse than the threshold falls back to its verified coarse map
    for i, e in enumerate(final):
        if e[2] > max_distortion and elems[i]["dst"] <= max_distortion and kf != k0:
            p2p = geo.p2p(elems[i]["C0"])
            Cf = block_project(p2p_to_fmap(p2p, evecs[:, :kf], mass), [b for b in bands if b.stop <= kf])
            final[i] = (Cf, p2p, exact_distortion(p2p))
    info["rejected_exact"] = [round(e[2], 3) for e in final if e[2] > max_distortion]
    elems = [e for e in final if e[2] <= max_distortion or e is final[0]]
    lap("upsample")
    # group table from the vertex maps; keep the largest set of verified elements closed under
    # composition (lowest distortion first)
    keep, table = largest_subgroup([e[1] for e in elems], [e[2] for e in elems], x_unit,
                                   geo.score_samples)
    if len(keep) < len(elems):
        info["dropped"] = sorted(set(range(len(elems))) - set(keep))
    elems = [elems[i] for i in keep]
    rev = consistent_orientation(table, [orientation_score(e[1], x_unit, torch.as_tensor(faces))
                                         for e in elems])
    _, residual = cayley_table(torch.stack([e[0] for e in elems]))
    info["cayley_max_residual"] = round(float(residual.max()), 4)
    lap("group")
    # elements in the paper's order (Table 3), then the group report of the reordered table
    table, rev = torch.as_tensor(table, dtype=torch.long), torch.as_tensor(np.asarray(rev, dtype=bool))
    order_ = canonical_order(table, rev, [e[2] for e in elems])
    perm = torch.tensor(order_)
    inv_perm = torch.empty_like(perm)
    inv_perm[perm] = torch.arange(len(perm))
    table = inv_perm[table[perm][:, perm]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ginfo = group_info(table, rev[perm])
    symmetries = []
    for new_i, i in enumerate(order_):
        Cf, p2p, dst = elems[i]
        kind = kind_of(int(ginfo.orders[new_i]), bool(ginfo.reversing[new_i]))
        symmetries.append(Symmetry(Cf, p2p, kind, int(ginfo.orders[new_i]), math.exp(-dst ** 2)))
    info["distortion"] = [round(e[2], 4) for e in (elems[i] for i in order_)]
    return SymmetryResult(symmetries, spectrum, [b for b in bands if b.stop <= kf], group=ginfo.to_dict(),
                          continuous=False, timings=timer.timings if timer else {}, info=info)


# ------------------------------------------------------------------------ used by detect_symmetries
def has_multiplicities(evals: Tensor, k: int = 20, min_share: float = 0.45) -> bool:
    """Whether the low spectrum is dominated by repeated eigenvalues, at two scales.

    The share of the non-constant eigenvalues lying in bands of size >= 2 must reach ``min_share``
    both in the coarse basis (``k`` snapped to a band end) and in twice that (as far as ``evals``
    goes). A group with rotations of order >= 3 has 2-dimensional irreducible representations, and by
    Weyl's law their share of the spectrum is fixed: 1/2 for C4v (table), 2/3 for C3 and D3, about
    0.8 for D5h; the shapes built in code measure 0.58-0.82. A mirror-symmetric or asymmetric shape
    only has accidental near-pairs (``eigen_bands`` merges gaps below 0.3 of the local spacing): 0.11-0.47
    on SCAPE, TOSCA and Watertight meshes, except two weakly coupled identical parts (glasses: 0.58),
    which the group path then answers with its mirror.
    """
    bands = solved_bands(evals)

    def share(kk: int) -> float:
        b0 = [b for b in _coarse_bands(bands, kk)[0] if b.start > 0]
        n = sum(len(b) for b in b0)
        return sum(len(b) for b in b0 if len(b) >= 2) / max(n, 1)

    return share(k) >= min_share and share(2 * k) >= min_share


def with_group(result: SymmetryResult, verts, faces) -> SymmetryResult:
    """The result with ``group`` filled from its symmetries (for the reflection path: C2/Cs or C1),
    and each element's ``kind`` set from its order and orientation (``groups.kind_of``)."""
    import dataclasses

    syms = result.symmetries
    vt = torch.as_tensor(np.asarray(verts, dtype=np.float64))
    ft = torch.as_tensor(np.asarray(faces, dtype=np.int64))
    rev = [False]
    for s in syms[1:]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rev.append(bool(orientation_reversing(s.p2p, vt, ft)))
    G = len(syms)
    if G <= 2:  # identity, or identity and one involution: the table is known
        table = torch.tensor([[0]]) if G == 1 else torch.tensor([[0, 1], [1, 0]])
        g = group_info(table, torch.tensor(rev))
    else:
        g = group_info(result.fmaps, torch.tensor(rev))
    syms = [dataclasses.replace(s, kind=kind_of(int(o), bool(r)), order=int(o))
            for s, o, r in zip(syms, g.orders.tolist(), g.reversing.tolist())]
    return dataclasses.replace(result, symmetries=syms, group=g.to_dict())
