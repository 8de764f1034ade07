"""The reflection path (ALGORITHM §4): the identity and, where one exists, the intrinsic reflection.

Pipeline; each stage is a function below and its seconds are kept under its name in
``SymmetryResult.timings``:

1. **candidates** (:func:`find_candidates`, steps in :mod:`.involutions`): heat-kernel maxima at
   ``t = 4 ln 10 / λ2`` and ``t/4`` (limb tips), thinned by geodesic non-maximum suppression.
   Seeds are two mutually symmetric pairs chosen by descriptor closeness and geodesic consistency
   (the paper's step); each seed is extended to an *involutive permutation of all extrema*, and
   each permutation is scored by how well it keeps the geodesic distances among all extrema (a
   map that swaps the hands but not the feet keeps the distances among its own two pairs, not
   among all five limb tips).
2. **procrustes** (:func:`candidate_fmaps`): one block-orthogonal matrix per permutation in the
   coarse basis, from multi-scale geodesic disks around every paired extremum plus the HKS/WKS
   columns, all candidates in one batched band-by-band Procrustes (ALGORITHM §3).
3. **select** (:func:`select_candidate`): each candidate is upsampled to a medium basis with the
   involution structure (``refine.zoomout_symmetry``); one that already preserves the orientation
   halfway is dropped there. Among those that reverse the orientation clearly (a reflection
   reverses it everywhere, an identity-like collapse nowhere, a partial swap in places) the most
   isometric one wins.
4. **refine**, **p2p**, **verify** (:func:`refine_and_verify`): the winner is grown to the final
   basis, its dense vertex map found by a two-level search (``maps.TwoLevelSearch``), and the map
   checked (:mod:`.verification`): near-isometric, orientation-reversing everywhere, no part wrong,
   descriptors kept. A map that fails is not reported: no forced symmetry on an asymmetric shape.
   **final** (:func:`final_selection`): the candidates the selection measured nearly as isometric
   as the winner are refined and verified too, and the verified map that is most isometric and
   most clearly orientation-reversing is reported (on a posed human, a candidate with one limb
   mirrored onto itself can measure a few percent better at the selection, not at the end).
5. **select_guided**: only where nothing verified, the selection again with each candidate's
   upsampling guided by features whose sign a reflection flips (:func:`orientation_guide`), then
   refine and verify once more. On posed humans the right candidate's plain upsampling can slide to
   the orientation-preserving near-isometry (left-right and front-back swapped at once).
6. **second_opinion**: where the first selection's map verified, the guided selection runs over
   the candidates up to the one chosen, unrefined, and the share of the vote samples on which its
   map agrees with the reported one is the reflection's confidence (:mod:`.confidence`); where
   two near-symmetries compete (posed humans: arms swapped, each leg mirrored onto itself), the
   two selections tend to part. Where the reported map verified only with local errors of its
   dense map set aside and the second opinion chose the same candidate, its guided upsampling is
   refined too and replaces the map where it fits better (:func:`guided_rival`).

The knobs are :class:`~symtorch.detect.config.ReflectionConfig`; why each default is what it is, with
the measurements, is in ``BENCHMARKS.md`` and ``docs/notes/``.
"""
from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import replace
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

from ..descriptors import descriptors, gradient_cross
from ..geodesics import GeodesicSolver, voronoi_cells
from ..groups.naming import GroupInfo, fixes_points, group_info, kind_of, orientation_reversing
from ..maps import TwoLevelSearch, nearest_neighbors
from ..procrustes import block_procrustes
from ..refine import zoomout_symmetry
from ..sampling import farthest_point_sampling
from ..spectrum import Spectrum, band_boundary, solved_bands
from ..units import EPS_KLC
from .confidence import reflection_confidence
from .config import ReflectionConfig
from .constraints import descriptor_coefficients, disk_coefficients
from .fmap_candidate import reversing_fmap_candidate
from .involutions import heat_extrema, involution_candidates
from .result import Checks, Diagnostics, ReflectionDiagnostics, Symmetry, SymmetryResult, Trial
from .verification import (descriptor_gap, involution_distortion, involution_error, isometry_score,
                           local_errors, orientation_vote, vertex_normals)

__all__ = ["detect_reflection", "reflection_basis", "find_candidates", "candidate_fmaps",
           "select_candidate", "refine_and_verify", "fmap_finalist", "final_selection", "final_cost",
           "second_opinion", "guided_rival", "map_agreement", "orientation_guide", "reflection_group", "Basis",
           "Candidates", "SampleSet", "Selection", "Refined"]


class Basis(NamedTuple):
    """The basis sizes of the reflection path, each at a band end.

    Attributes:
        bands: the solved bands of the spectrum.
        starts: coarse sizes the upsampling may start from (ascending); k0: the largest.
        k_prune: where a candidate's upsampling stops to vote (0: no stop).
        k_select: where the candidates are compared; k_refine: the final size.
    """

    bands: list[range]
    starts: list[int]
    k0: int
    k_prune: int
    k_select: int
    k_refine: int


class Candidates(NamedTuple):
    """Stage 1: candidate involutions of the heat-kernel extrema.

    Attributes:
        extrema: [N] vertex ids; dist: [N, V] geodesic distances from them (unit-area shape).
        desc: [V, D] descriptors of every vertex (``descriptors``).
        perms: the candidate permutations, best first ([N] int each; -1 = unpaired);
        scores: [P] their consistency scores (EPS_KLC units); n_seeds: seeds they grew from.
    """

    extrema: np.ndarray
    dist: Tensor
    desc: Tensor
    perms: list[np.ndarray]
    scores: np.ndarray
    n_seeds: int


class Selection(NamedTuple):
    """Stage 3: the candidate chosen (index, coarse start), its matrix at ``k_select``, the trials,
    and every measured candidate as ``((index, start), distortion, matrix at k_select)``."""

    chosen: tuple[int, int]
    fmap: Tensor
    trials: list[Trial]
    measured: tuple[tuple[tuple[int, int], float, Tensor], ...] = ()

    @property
    def distortion(self) -> float:
        """The chosen candidate's selection distortion (inf where it was not measured)."""
        return next((d for key, d, _ in self.measured if key == self.chosen), math.inf)

    def finalists(self, ratio: float) -> list[tuple[tuple[int, int], Tensor]]:
        """The measured candidates within ``ratio`` of the chosen one's distortion, the chosen
        one first, then by distortion."""
        best = self.distortion
        near = sorted((d, key, C) for key, d, C in self.measured
                      if key != self.chosen and (math.isinf(ratio) or d <= ratio * best))
        return [(self.chosen, self.fmap)] + [(key, C) for _, key, C in near]


class Refined(NamedTuple):
    """Stage 4: the final matrix, its dense vertex map and the verification."""

    fmap: Tensor
    p2p: Tensor
    checks: Checks


def detect_reflection(verts, faces, spectrum: Spectrum, *, k: int | tuple[int, ...] = 6,
                      k_refine: int = 100, config: ReflectionConfig | None = None,
                      solver: GeodesicSolver | None = None, timer=None) -> SymmetryResult:
    """The identity and, where one exists, the intrinsic reflection of a mesh (see the module doc).

    Args:
        verts: [V, 3] float64 (original units); faces: [F, 3] long.
        spectrum: ``laplacian_spectrum(verts, faces, k > k_refine)`` (unit area).
        k: coarse basis size the upsampling starts from, or several (each is tried per candidate).
        k_refine: final basis size; the matrices returned live in it (both snapped to a band end).
        config: the knobs (default ``ReflectionConfig()``).
        solver: a ``GeodesicSolver`` of the unit-area mesh (``verts * spectrum.scale``) to reuse
            (``detect_symmetries`` shares one between the two paths); default one of its own.
        timer: optional stage timer (``lap(name)``).

    Returns:
        SymmetryResult on the CPU, with its group report (Cs or C1).
    """
    cfg = ReflectionConfig() if config is None else config
    lap = timer.lap if timer is not None else (lambda name: None)
    spectrum = spectrum.to("cpu")  # the geometry it meets is solved on the host
    basis = reflection_basis(spectrum.evals, k, cfg.k_select, k_refine, cfg.prune_k)
    V = spectrum.evecs.shape[0]
    verts_unit = torch.as_tensor(verts) * spectrum.scale
    solver = GeodesicSolver(verts_unit, faces, backend="batched") if solver is None else solver
    cands = find_candidates(spectrum, faces, solver, cfg)
    lap("candidates")
    diag = ReflectionDiagnostics(
        n_extrema=int(len(cands.extrema)), n_seeds=cands.n_seeds, n_candidates=len(cands.perms),
        k0=basis.starts, k_refine=basis.k_refine,
        candidate_scores=[round(float(s), 4) for s in cands.scores[:8]])
    symmetries = [Symmetry(torch.eye(basis.k_refine, dtype=spectrum.evecs.dtype), torch.arange(V),
                           "identity", 1, 1.0)]
    found = None  # the reported map's refinement, where a candidate was refined
    if cands.perms:
        cands = cands._replace(perms=cands.perms[:cfg.n_candidates])
        C0 = candidate_fmaps(cands, spectrum, basis)
        lap("procrustes")
        samples = SampleSet(verts_unit, faces, spectrum, solver, cfg)
        chosen = select_candidate(C0, cands, samples, basis, cfg, guided=False)
        lap("select")
        found = refine_and_verify(chosen.fmap, samples, cands.desc, basis, cfg, lap)
        extra = fmap_finalist(verts_unit, faces, spectrum, cands.desc, basis, cfg, lap, samples, chosen)
        pick, found, finalists = final_selection(chosen, found, samples, cands.desc, basis, cfg, lap,
                                                 extra)
        diag = replace(diag, trials=chosen.trials, chosen=pick, finalists=finalists,
                       checks=found.checks)
        other = None  # the selection the reported map did not come from: its matrix at k_select
        if not found.checks.accepted and cfg.w_guide > 0:
            # only here: as the first choice the guide also makes wrong candidates reverse the
            # orientation (docs/notes/2026-11-sessions-1-5.md, "orientation guide")
            other = chosen.fmap
            chosen = select_candidate(C0, cands, samples, basis, cfg, guided=True)
            lap("select_guided")
            found = refine_and_verify(chosen.fmap, samples, cands.desc, basis, cfg, lap)
            diag = replace(diag, guided_trials=chosen.trials, guided_chosen=chosen.chosen,
                           guided=found.checks)
        elif found.checks.accepted and cfg.second_opinion and cfg.w_guide > 0:
            # the extrema candidates up to the reported one (up to the selection's own choice
            # where the functional-map candidate was reported)
            last = chosen.chosen[0] if pick[0] == FMAP_KEY else pick[0]
            second = second_opinion(C0, cands, last, samples, basis, cfg)
            lap("second_opinion")
            other = second.fmap
            diag = replace(diag, second_chosen=second.chosen)
            rival = guided_rival(found, pick, second, samples, cands.desc, basis, cfg, lap)
            if rival is not None:
                other, found = chosen.fmap, rival
                diag = replace(diag, guided_trials=second.trials, guided_chosen=second.chosen,
                               guided=rival.checks, second_chosen=None)
        if found.checks.accepted and other is not None:
            diag = replace(diag, agreement=map_agreement(samples, found.p2p, other))
    elif cfg.fmap_candidate:  # no extrema pairs: the functional-map candidate alone
        samples = SampleSet(verts_unit, faces, spectrum, solver, cfg)
        (key, C), = fmap_finalist(verts_unit, faces, spectrum, cands.desc, basis, cfg, lap)
        found = refine_and_verify(C, samples, cands.desc, basis, cfg, lap)
        diag = replace(diag, chosen=key, finalists=[key], checks=found.checks)
    if found is not None and found.checks.accepted:
        symmetries.append(Symmetry(found.fmap, found.p2p, "reflection", 2, found.checks.score,
                                   confidence=reflection_confidence(diag)))
    symmetries, group = reflection_group(symmetries, verts, faces)
    return SymmetryResult(symmetries, spectrum, basis.bands, group=group,
                          timings=dict(timer.timings) if timer is not None else {},
                          diagnostics=Diagnostics("reflection", reflection=diag))


# ------------------------------------------------------------------------------------------ stages
def reflection_basis(evals: Tensor, k, k_select: int, k_refine: int, prune_k: int) -> Basis:
    """The basis sizes, each snapped to a band end of the solved bands of ``evals``."""
    bands = solved_bands(evals)
    # several coarse starts: near-identity and reflection differ in few of the first modes, so a
    # small start can collapse to the identity where a larger one holds
    starts = sorted({band_boundary(bands, x) for x in (k if isinstance(k, (tuple, list)) else (k,))})
    k_prune = band_boundary(bands, prune_k) if prune_k > 0 else 0
    return Basis(bands, starts, starts[-1], k_prune, band_boundary(bands, k_select),
                 band_boundary(bands, k_refine))


def find_candidates(spectrum: Spectrum, faces, solver: GeodesicSolver, cfg: ReflectionConfig) -> Candidates:
    """Stage 1: heat-kernel extrema and the involutive permutations of them (``.involutions``)."""
    evals, evecs = spectrum.evals, spectrum.evecs
    ext, dist_ext = heat_extrema(evals, evecs, faces, solver, cfg.n_extrema, cfg.nms_radius)
    desc = descriptors(evals, evecs)  # [V, D]
    D_ext = dist_ext[:, ext].numpy()
    D_ext = 0.5 * (D_ext + D_ext.T)
    logdesc = torch.log(desc[ext].clamp_min(1e-12)).numpy()
    perms, scores, n_seeds = involution_candidates(logdesc, D_ext)
    return Candidates(ext, dist_ext, desc, perms, scores, n_seeds)


def candidate_fmaps(cands: Candidates, spectrum: Spectrum, basis: Basis) -> Tensor:
    """Stage 2: [P, k0, k0] one block-orthogonal matrix per candidate, one batched Procrustes.

    Constraints: multi-scale geodesic disks around each paired extremum (``1_{g(a)} ∘ g = 1_a``:
    the disk at the image is the function, the disk at the point its pull-back), plus the
    descriptors unchanged.
    """
    evecs, mass, k0 = spectrum.evecs, spectrum.mass, basis.k0
    E0 = evecs[:, :k0]
    A_disk = disk_coefficients(E0, mass, cands.dist)  # [N, R, k0]
    A_desc = descriptor_coefficients(E0, mass, cands.desc)  # [k0, D]
    n_radii = A_disk.shape[1]
    n_max = max(int((p >= 0).sum()) for p in cands.perms)
    A = torch.zeros(len(cands.perms), k0, n_max * n_radii + cands.desc.shape[1], dtype=evecs.dtype)
    B = torch.zeros_like(A)
    for c, perm in enumerate(cands.perms):
        src = np.flatnonzero(perm >= 0)
        A[c, :, : len(src) * n_radii] = A_disk[perm[src]].reshape(-1, k0).mT
        B[c, :, : len(src) * n_radii] = A_disk[src].reshape(-1, k0).mT
        A[c, :, n_max * n_radii:] = A_desc
        B[c, :, n_max * n_radii:] = A_desc
    return block_procrustes(A, B, [b for b in basis.bands if b.stop <= k0])  # [P, k0, k0]


class SampleSet:
    """The sample vertices the selection and the verification measure maps on, and what is built
    on them once: normals, the samples' distance fields and the dense search (both on first use).

    Attributes:
        samples: [S] farthest-point samples (unit-area shape); fit: the first half, which the
            selection's upsampling fits on; vote_samples: the first 500, which vote on orientation.
    """

    def __init__(self, verts_unit: Tensor, faces, spectrum: Spectrum, solver: GeodesicSolver,
                 cfg: ReflectionConfig):
        self.verts, self.faces = verts_unit, torch.as_tensor(faces)
        self.evecs, self.mass, self.solver, self.cfg = spectrum.evecs, spectrum.mass, solver, cfg
        V = self.evecs.shape[0]
        self.samples = farthest_point_sampling(verts_unit, min(cfg.n_samples, V))
        self.fit = self.samples[: max(len(self.samples) // 2, 1)]
        self.normals = vertex_normals(self.verts, self.faces)
        self.vote_samples = self.samples[: min(500, len(self.samples))]
        self._fields: Tensor | None = None
        self._search: TwoLevelSearch | None = None

    def fields(self) -> Tensor:
        """[n, V] distances from the first samples, solved once: the selection compares every
        candidate on the first ``n_select_verify`` of them, the verification uses ``n_verify``."""
        if self._fields is None:
            n = max(self.cfg.n_verify, self.cfg.n_select_verify)
            self._fields = self.solver.distances_from(self.samples[:n])
        return self._fields

    def pairwise(self, n: int) -> Tensor:
        """[n, n] symmetrised distances among the first ``n`` samples."""
        D = self.fields()[:n, self.samples[:n]]
        D = 0.5 * (D + D.mT)
        return D.fill_diagonal_(0.0)

    def search(self) -> TwoLevelSearch:
        """The dense vertex map of a matrix: samples first, every other vertex near its sample's image."""
        if self._search is None:
            # graph Voronoi cells: parts that touch in space but not on the surface stay apart
            V, n_local = len(self.verts), self.cfg.n_local
            cells = voronoi_cells(self.verts, self.faces, self.samples) if 0 < n_local < V \
                else torch.zeros(V, dtype=torch.long)
            self._search = TwoLevelSearch(self.verts, self.evecs, self.samples, cells, n_local)
        return self._search

    def vote(self, C: Tensor) -> tuple[Tensor, float]:
        """The map of ``C`` on the vote samples (the identity elsewhere) and its orientation vote."""
        kk, V = C.shape[-1], len(self.verts)
        p2p_s = torch.arange(V)
        E = self.evecs
        p2p_s[self.vote_samples] = self.samples[nearest_neighbors(E[self.vote_samples, :kk] @ C,
                                                                  E[self.samples, :kk])]
        return p2p_s, float(orientation_vote(p2p_s, self.verts, self.normals, self.vote_samples))


def select_candidate(C0: Tensor, cands: Candidates, samples: SampleSet, basis: Basis,
                     cfg: ReflectionConfig, guided: bool) -> Selection:
    """Stage 3: upsample the candidates to ``k_select`` and choose one.

    A reflection reverses the orientation everywhere (identity-like collapses vote +1, partial
    swaps near 0); among the clearly reversing candidates the most isometric one wins: a limb
    mirrored onto itself instead of onto its twin also reverses the orientation, but breaks the
    distances where it joins the body. ``guided``: each candidate's upsampling also fits
    :func:`orientation_guide`.
    """
    perms, scores = cands.perms, cands.scores
    best, trials, guides, measured = None, [], {}, []
    for c, kc in itertools.product(range(len(perms)), basis.starts):
        if guided and c not in guides:  # one per candidate, whatever the coarse start
            guide = orientation_guide(samples.verts, samples.faces, cands.dist, perms[c], cfg.w_guide)
            guides[c] = tuple(g.to(samples.evecs.dtype) for g in guide)  # searched beside evecs
        Cs, vote, distortion = _upsample_and_measure(C0[c, :kc, :kc], samples, basis, cfg, guides.get(c))
        trials.append(Trial(round(vote, 3), round(distortion, 3)))
        if math.isfinite(distortion):
            measured.append(((c, kc), distortion, Cs))
        key = (0, distortion) if math.isfinite(distortion) else (1, vote)
        if best is None or key < best[0]:
            best = (key, (c, kc), Cs)
        if (vote < -cfg.early_vote and distortion < cfg.early_distortion
                and (c + 1 >= len(perms) or scores[c + 1] > cfg.compare_ratio * scores[0])):
            # clearly a full reflection, and the next candidates are clearly less consistent
            # (candidates nearly as consistent as the first are all compared: they differ in how
            # a few extrema pair up, e.g. a paw swapped or kept, which only the maps tell apart)
            break
    return Selection(best[1], best[2], trials, tuple(measured))


def _upsample_and_measure(Cs: Tensor, samples: SampleSet, basis: Basis, cfg: ReflectionConfig,
                          guide) -> tuple[Tensor, float, float]:
    """One candidate grown to ``k_select``: (matrix, orientation vote, distortion or inf)."""
    grow = dict(samples=samples.fit, involution=True, block=cfg.block_refine, targets=samples.samples,
                guide=guide)
    pruned = False
    if Cs.shape[-1] < basis.k_prune < basis.k_select:
        # halfway: a candidate that already preserves the orientation is dropped
        Cs = zoomout_symmetry(Cs, samples.evecs, samples.mass, basis.bands, basis.k_prune,
                              n_iter_end=0, **grow)
        _, vote = samples.vote(Cs)
        pruned = vote > cfg.prune_vote
    if not pruned:
        Cs = zoomout_symmetry(Cs, samples.evecs, samples.mass, basis.bands, basis.k_select, **grow)
        p2p_s, vote = samples.vote(Cs)
    distortion = math.inf
    if not pruned and vote < -cfg.select_vote:
        n = cfg.n_select_verify
        distortion = isometry_score(samples.solver, p2p_s, samples.samples[:n],
                                    source_dist=samples.pairwise(n)).distortion
    return Cs, vote, distortion


def refine_and_verify(Cs: Tensor, samples: SampleSet, desc: Tensor, basis: Basis, cfg: ReflectionConfig,
                      lap) -> Refined:
    """Stage 4: the final upsampling, the dense vertex map and its verification."""
    grow = dict(samples=samples.samples, involution=True, block=cfg.block_refine)
    Cf = zoomout_symmetry(Cs, samples.evecs, samples.mass, basis.bands, basis.k_refine,
                          targets=samples.samples, n_iter_end=1, step=cfg.step_refine, **grow)
    if cfg.n_iter_all > 0:  # last steps against every vertex
        Cf = zoomout_symmetry(Cf, samples.evecs, samples.mass, basis.bands, basis.k_refine,
                              n_iter_end=cfg.n_iter_all, **grow)
    lap("refine")
    p2p = samples.search()(Cf)
    lap("p2p")
    n = cfg.n_verify
    skip = local_errors(samples.fields()[:n], samples.samples[:n], p2p, desc, cfg.max_worst,
                        cfg.max_local_errors, cfg.local_error_z) if cfg.max_local_errors > 0 else None
    if cfg.verify == "involution":  # no solve: the samples' own fields, read at the images
        d = involution_distortion(samples.fields()[:n], samples.samples[:n], p2p, skip)
    else:
        d = isometry_score(samples.solver, p2p, samples.samples[:n], source_dist=samples.pairwise(n),
                           skip=skip)
    vote = float(orientation_vote(p2p, samples.verts, samples.normals, samples.vote_samples))
    gap = descriptor_gap(desc, p2p, samples.mass)
    inv = involution_error(samples.fields()[:n], samples.samples[:n], p2p)
    lap("verify")
    ok = d.score >= cfg.min_score and vote < -cfg.max_vote and d.worst < cfg.max_worst \
        and gap < cfg.max_descriptor_gap
    n_local = int(skip.sum()) if skip is not None else 0
    return Refined(Cf, p2p, Checks(d.score, d.distortion, d.worst, vote, gap, ok, inv, n_local))


#: The (candidate, start) key of the functional-map candidate: it has no extrema permutation.
FMAP_KEY = -1


def fmap_finalist(verts_unit: Tensor, faces, spectrum: Spectrum, desc: Tensor, basis: Basis,
                  cfg: ReflectionConfig, lap, samples: SampleSet | None = None,
                  chosen: Selection | None = None) -> list[tuple[tuple[int, int], Tensor]]:
    """Stage 4, **fmap**: the orientation-reversing functional map of the shape onto itself
    (:func:`.fmap_candidate.reversing_fmap_candidate` on the descriptors ``desc``) as a finalist
    ``((FMAP_KEY, k), matrix)``; none when ``cfg.fmap_candidate`` is off.

    With the selection (``samples``, ``chosen``) it is screened as the extrema candidates are:
    grown to ``k_select`` and measured there, it is a finalist only when it reverses the
    orientation clearly and its distortion is within ``cfg.fmap_ratio`` of the selection's
    winner (the refinement to the end is the costly part). Without one it is returned unscreened.
    """
    if not cfg.fmap_candidate:
        return []
    k = band_boundary(basis.bands, min(cfg.fmap_k, basis.k_refine))
    C = reversing_fmap_candidate(verts_unit, torch.as_tensor(faces), spectrum.evecs, spectrum.evals,
                                 spectrum.mass, desc, basis.bands, k)
    keep = True
    if samples is not None and chosen is not None:
        # measured at k_select; refined from its own basis (measured better than from k_select)
        _, _, distortion = _upsample_and_measure(C, samples, basis, cfg, None)
        keep = distortion <= cfg.fmap_ratio * chosen.distortion  # inf: not clearly reversing
    lap("fmap")
    return [((FMAP_KEY, k), C)] if keep else []


def final_selection(chosen: Selection, found: Refined, samples: SampleSet, desc: Tensor, basis: Basis,
                    cfg: ReflectionConfig, lap, extra: list[tuple[tuple[int, int], Tensor]] = ()
                    ) -> tuple[tuple[int, int], Refined, list[tuple[int, int]]]:
    """Stage 4, **final**: the selection's near-ties refined and verified too; the best verified one wins.

    ``found`` is the chosen candidate refined (stage 4). Every other candidate whose selection
    distortion is within ``cfg.final_ratio`` of the chosen one's is refined and verified the same
    way, and among the verified maps the one with the lowest ``distortion + final_vote_weight *
    (1 + vote)`` is reported (the final checks measure twice the samples, on the dense map in the
    final basis). Where none verifies, the chosen one stays (and the guided selection follows).

    ``extra`` finalists (the functional-map candidate, :func:`fmap_finalist`, which screens it
    itself) are refined and verified the same way.

    Returns:
        ((candidate, start) reported, its Refined, the (candidate, start) of every finalist).
    """
    finalists = chosen.finalists(cfg.final_ratio) + list(extra)
    if len(finalists) < 2:
        return chosen.chosen, found, [chosen.chosen]
    best = (chosen.chosen, found)
    for key, Cs in finalists[1:]:
        other = refine_and_verify(Cs, samples, desc, basis, cfg, lambda stage: None)
        if other.checks.accepted and (not best[1].checks.accepted
                                      or refined_cost(other, cfg) < refined_cost(best[1], cfg)):
            best = (key, other)
    lap("final")
    return best[0], best[1], [key for key, _ in finalists]


def final_cost(distortion: float, vote: float, vote_weight: float) -> float:
    """What the final stage minimises over the verified finalists: ``distortion + vote_weight *
    (1 + vote)`` (a reflection's orientation vote is -1; one limb mirrored onto itself is less)."""
    return distortion + vote_weight * (1.0 + vote)


def refined_cost(r: Refined, cfg: ReflectionConfig) -> float:
    """:func:`final_cost` of a refined, verified map."""
    return final_cost(r.checks.distortion, r.checks.orientation, cfg.final_vote_weight)


def guided_rival(found: Refined, pick: tuple[int, int], second: Selection, samples: SampleSet,
                 desc: Tensor, basis: Basis, cfg: ReflectionConfig, lap) -> Refined | None:
    """Stage 6 too: where the reported map verified only with local errors of its dense map set
    aside (``verification.local_errors``) and the second opinion chose the same candidate, its
    guided upsampling refined and verified; it replaces the reported map where it verifies and
    costs less (:func:`final_cost`). None: the reported map stays. Another candidate is another
    symmetry, which the selection already ranked lower: it is never a rival."""
    if found.checks.local_errors == 0 or second.chosen[0] != pick[0]:
        return None
    rival = refine_and_verify(second.fmap, samples, desc, basis, cfg, lambda stage: None)
    lap("guided_rival")
    return rival if rival.checks.accepted and refined_cost(rival, cfg) < refined_cost(found, cfg) else None


def second_opinion(C0: Tensor, cands: Candidates, chosen: int, samples: SampleSet, basis: Basis,
                   cfg: ReflectionConfig) -> Selection:
    """Stage 6: the guided selection over the candidates up to the ``chosen`` one, left unrefined.

    Only those the first selection ranked before its choice, and the choice: a second opinion on
    whether a more consistent candidate, upsampled with the orientation guide, beats it (where two
    near-symmetries compete, the guide tends to prefer the other one). Its map's agreement with
    the reported one (:func:`map_agreement`) is the confidence (:mod:`.confidence`).
    """
    c = chosen + 1
    head = cands._replace(perms=cands.perms[:c], scores=cands.scores[:c])
    return select_candidate(C0[:c], head, samples, basis, cfg, guided=True)


def map_agreement(samples: SampleSet, p2p: Tensor, fmap: Tensor) -> tuple[float, float]:
    """How well a dense map agrees with another matrix's map on the vote samples.

    Returns:
        (share of the vote samples whose two images lie within one EPS_KLC of each other,
        the same within two), distances Euclidean on the unit-area shape.
    """
    p2p_s, _ = samples.vote(fmap)
    s = samples.vote_samples
    d = (samples.verts[p2p[s]] - samples.verts[p2p_s[s]]).norm(dim=-1) / EPS_KLC
    return float((d < 1).double().mean()), float((d < 2).double().mean())


def orientation_guide(verts: Tensor, faces: Tensor, dist: Tensor, perm: np.ndarray,
                      weight: float) -> tuple[Tensor, Tensor]:
    """Guide features for a candidate: gradient crosses of its paired extrema's distance fields.

    Source side ``weight * x(a, b)``, target side ``-weight * x(perm a, perm b)``: a reflection that
    maps ``a`` to ``perm a`` flips the sign of the cross product (``descriptors.gradient_cross``).
    """
    src = np.flatnonzero(perm >= 0)
    pairs = torch.as_tensor(list(itertools.combinations(range(len(src)), 2)), dtype=torch.long).reshape(-1, 2)
    # the geometry's dtype (a float32 spectrum gives float32 distance fields; verts stay float64)
    fields = dist[torch.as_tensor(src)].to(verts.dtype)
    images = dist[torch.as_tensor(perm[src])].to(verts.dtype)
    return (weight * gradient_cross(verts, faces, fields, pairs),
            -weight * gradient_cross(verts, faces, images, pairs))


def reflection_group(symmetries: list[Symmetry], verts, faces) -> tuple[list[Symmetry], GroupInfo]:
    """The group report of the reflection path's elements (C1, or Cs/Ci/C2 with one involution), and
    each element's ``kind`` and ``order`` from it (``groups.kind_of``)."""
    vt = torch.as_tensor(np.asarray(verts, dtype=np.float64))
    ft = torch.as_tensor(np.asarray(faces, dtype=np.int64))
    rev = [False]
    for s in symmetries[1:]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rev.append(bool(orientation_reversing(s.p2p, vt, ft)))
    # identity, or identity and one involution: the table is known
    table = torch.tensor([[0]]) if len(symmetries) == 1 else torch.tensor([[0, 1], [1, 0]])
    fixes = fixes_points(torch.stack([s.p2p for s in symmetries]), vt, ft)  # Cs, or Ci: no fixed point
    g = group_info(table, torch.tensor(rev), fixes=fixes)
    symmetries = [replace(s, kind=kind_of(int(o), bool(r)), order=int(o))
                  for s, o, r in zip(symmetries, g.orders.tolist(), g.reversing.tolist())]
    return symmetries, g
