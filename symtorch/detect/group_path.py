"""The group path (ALGORITHM §5; Wang & Huang 2017 §4.2): every symmetry of a mesh, as a finite group.

Pipeline, every step automatic (no hand-typed bands, orbit or group size); each stage is a function
here or in :mod:`.candidates` / :mod:`.group_elements`, and its seconds are kept under its name in
``SymmetryResult.timings``:

1. **points** (:func:`invariant_point_set`): a symmetry-invariant point set ``P``, the local maxima
   and minima of the heat kernel signature at three scales (limb tips down to corners), thinned by
   farthest-point suppression that never merges two extrema of one function a valley separates
   (orbit partners closer than the radius), and the geodesic distance fields from them. Extrema of
   invariant functions form a union of orbits.
2. **samples**: sample vertices for refinement and verification, and the two-level vertex-map
   search (:class:`.group_elements.Geometry`).
3. **continuous** (:func:`continuous_test`): a sphere or a surface of revolution has a
   one-parameter family of symmetries; it is reported as such, with the identity only.
4. **candidates** (:func:`.candidates.tuple_pairs`): ``m`` = the largest band of the coarse basis;
   tuples of ``m + 1`` points in general position pin every band, and a tuple that holds some band
   weakly (its points near that band's nodal set, :class:`.candidates.Pinning`) is grown by up to
   two points until it does. The paper pairs *all* source tuples with all ordered
   target tuples (``C(n, m)^2 m!``); one source tuple already pins each symmetry, so a few
   well-spread source tuples are paired with every ordered target tuple of ``P``, pruned on the fly
   by the geodesic ratio test (``delta``) and by descriptor agreement.
5. **procrustes** (:func:`candidate_fmaps`): batched ``block_procrustes`` over all candidates,
   with the reflection path's constraints (geodesic disks around each tuple point, the descriptors
   unchanged), and again with dipoles beside them (each tuple point's disk tilted towards the
   next, ``constraints.dipole_coefficients``: a disk is even under every mirror through its
   centre, so where every tuple point lies on mirror planes the disks leave the bands those
   mirrors negate to noise), that solution kept where it differs; the ``max_candidates`` best fits
   of each go on.
6. **icp**: a few batched spectral-ICP steps on every candidate (:func:`batched_icp`), so that the
   candidates of one symmetry found from different tuples agree (raw Procrustes solutions of noisy
   tuples scatter by more than the gap between elements).
7. **cluster** (:func:`cluster_representatives`): mean shift of the flattened matrices; the member
   nearest each mode stands for it. The bandwidth (0.6) is below 2, the distance of two orthogonal
   matrices that differ by one sign, the closest two distinct symmetries can be.
8. **refine**, **closure** (:class:`.group_elements.CoarseElements`): in the coarse basis and on
   sample vertices, each representative is refined (ZoomOut kept block-orthogonal, or fixed-size
   spectral ICP), screened by distortion and dropped if it duplicates an element; the set is closed
   under composition (``groups.closure``) and what closure adds is refined and screened the same way.
9. **upsample** (:func:`.group_elements.upsample_elements`): the distinct elements are grown to the
   refined basis, every vertex is mapped, and the distortion is measured exactly; a coarse
   duplicate that the refined basis tells apart joins as an element of its own, and where that
   happens, or the coarse closure did not end closed, the exact vertex maps are closed under
   composition.
10. **group** (:func:`group_of_elements`): the largest set of verified elements closed under
    composition of their *maps* (``groups.largest_subgroup``); table, inverses, orders and name
    (``groups.group_info``), with orientation flags that are a homomorphism of the table and agree
    best with the per-element votes (half of the group several times more distorted than the other
    half, the mirrors of a chiral shape most often, is a near-symmetry: left out of the group by
    default, with one warning and its distortions in the diagnostics,
    :func:`near_symmetry_coset`); elements in the order of the paper's Table 3 (identity, rotation
    powers, reflection coset).

The confidence of an element is ``exp(-distortion^2)``. Knobs: :class:`~symtorch.detect.config.GroupConfig`.

Limits: triangle meshes only; one connected component (HKS times use the first non-zero eigenvalue);
a symmetry is representable only where the spectrum keeps its eigenspaces together, so a shape
whose quarter-turn eigenspaces split by more than ``eigen_bands``' tolerance gives the subgroup its
bands can carry (SHREC'07 table 143, ``BENCHMARKS.md``); the continuous test looks at the first
repeated band only (a rotation axis that shows up only in higher bands is missed).
"""
from __future__ import annotations

import logging
import math
import warnings
from dataclasses import replace
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

from ..cluster import mean_shift
from ..descriptors import descriptors, hks_at_scales
from ..geodesics import GeodesicSolver
from ..groups.algebra import _subtable, _z2_homs, cayley_table, identity_index
from ..groups.naming import GroupInfo, fixes_points, group_info, kind_of, orientation_score
from ..groups.from_maps import canonical_order, closed_subsets, consistent_orientation
from ..procrustes import block_procrustes
from ..spectrum import BAND_REL_GAP, Spectrum, band_boundary, eigen_bands, full_bands, solved_bands
from ..units import EPS_KLC, mean_edge
from .candidates import Pinning, invariant_points, partner_mask, persistent_points, tuple_pairs
from .config import GroupConfig
from .constraints import descriptor_coefficients, dipole_coefficients, disk_coefficients
from .group_elements import (EXACT_ENOUGH, OUTLIER_FLOOR, CoarseElements, Element, Geometry, batched_icp, far_above,
                             point_map_distortions, upsample_elements, zoomout)
from .result import Diagnostics, GroupDiagnostics, Symmetry, SymmetryResult
from .verification import HeatLevels

log = logging.getLogger(__name__)

__all__ = ["detect_group", "GroupBasis", "PointSet", "group_basis", "invariant_point_set",
           "continuous_test", "candidate_fmaps", "batched_icp", "cluster_representatives", "keep_heat_levels",
           "group_of_elements", "near_symmetry_coset", "has_multiplicities", "unexplained_multiplicities",
           "bend_remnant", "bent_coset_ratios"]


class GroupBasis(NamedTuple):
    """The basis sizes of the group path.

    Attributes:
        bands: solved bands of the (cut) spectrum; bands0: those of the coarse basis;
        k0: the coarse size; k_refine: the refined size (k0 with ``refine='icp'``);
        m: the largest band of the coarse basis.
    """

    bands: list[range]
    bands0: list[range]
    k0: int
    k_refine: int
    m: int


class PointSet(NamedTuple):
    """Stage 1: invariant points ``[n]``, their distance fields ``fields [n, V]``, the
    symmetrised distances among them ``dist [n, n]`` (unit-area shape), and which are
    ``persistent [n]`` (``candidates.persistent_points``)."""

    points: np.ndarray
    fields: Tensor
    dist: np.ndarray
    persistent: np.ndarray


def detect_group(verts, faces, spectrum: Spectrum, *, k: int = 20, k_refine: int = 60,
                 config: GroupConfig | None = None, device: torch.device | str | None = None,
                 solver: GeodesicSolver | None = None, min_order: int = 1, timer=None) -> SymmetryResult:
    """Every symmetry of a mesh as a group (ALGORITHM §5); see the module docstring for the stages.

    Args:
        verts: [V, 3] vertices (original units); faces: [F, 3].
        spectrum: ``laplacian_spectrum`` of the mesh with at least ``k_refine`` (plus margin) pairs.
        k: target size of the coarse basis (snapped to a band end).
        k_refine: target size of the refined basis; the matrices returned live in it.
        config: the knobs (default ``GroupConfig()``).
        device: where the batched candidate stages run (block Procrustes, batched ICP, mean shift);
            default CPU. Everything else runs on CPU, and the result is on CPU.
        solver: a ``GeodesicSolver`` of the unit-area mesh (``verts * spectrum.scale``) to reuse
            (``detect_symmetries`` shares one between the two paths); default one of its own.
        min_order: the caller only wants a group of at least this order (a second opinion after
            the reflection path found a mirror: 3). Where the coarse stage verifies fewer elements
            than that, the exact stage cannot find more, and the trivial group is returned at once
            (``diagnostics.group.reason`` says so) instead of upsampling and measuring them.
        timer: optional stage timer (``lap(name)``).

    Returns:
        SymmetryResult with its group, identity first, on the CPU.

    Warns:
        UserWarning, at most one per call, where a stage cut its work short (the closure of the
        coarse elements did not converge, candidate tuples were truncated, a geodesic fallback),
        saying what that means for the group returned.
    """
    cfg = GroupConfig() if config is None else config

    def attempt(rel_gap: float, run_cfg: GroupConfig, approximate: bool = False,
                at_least: int = min_order) -> tuple[SymmetryResult, list]:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            return _detect_group(verts, faces, spectrum, k=k, k_refine=k_refine, config=run_cfg, device=device,
                                 solver=solver, min_order=at_least, timer=timer, rel_gap=rel_gap,
                                 approximate=approximate), caught

    result, caught = attempt(BAND_REL_GAP, cfg)
    unexplained = unexplained_multiplicities(result, result.spectrum.evals, k)  # the cut spectrum
    if cfg.merged_gap > 0 and (unexplained or bend_remnant(result)):
        # the near-isometry that splits the bands moves the descriptors and the extrema too: where
        # the pairs it split are many, the gate is relaxed and more source tuples are tried (where
        # only bend_remnant asks, the first attempt's gates: relaxed, they cost a box's D2h 3-8
        # times as much); only a larger group replaces the first one, so its coarse stage stops
        # where it verifies no more elements than that
        run_cfg = (replace(cfg, desc_tol=max(cfg.desc_tol, cfg.merged_desc_tol),
                           n_sources=max(cfg.n_sources, cfg.merged_n_sources)) if unexplained else cfg)
        merged, caught_m = attempt(cfg.merged_gap, run_cfg, approximate=True,
                                   at_least=max(min_order, result.group.order + 1))
        if merged.group.order > result.group.order:
            result, caught = merged, caught_m
    for w in caught:  # other categories (a library's deprecation notice) pass through as they were
        if not issubclass(w.category, UserWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    note = _summary_warning([w.message for w in caught if issubclass(w.category, UserWarning)], result)
    if note:
        warnings.warn(note, UserWarning, stacklevel=2)
    return result


def _summary_warning(messages: list, result: SymmetryResult) -> str | None:
    """One warning for everything the stages of one detection warned about, saying what it means.

    The closure of the coarse elements runs up to three rounds, and candidate tuples are cut per
    source tuple: alone, each would warn again in every round (nine copies of one closure note on
    one star prism).
    """
    texts = list(dict.fromkeys(str(m) for m in messages))  # distinct, in order
    if not texts:
        return None
    what = []
    closure_notes = ("closure exceeded max_order", "did not end closed")
    if any(c in t for t in texts for c in closure_notes):
        what.append("the products of the elements did not close into a finite group within the size "
                    "and rounds allowed, neither as coarse matrices nor as exact vertex maps (maps too "
                    "noisy to compose, or a continuous symmetry the continuous test missed); the group "
                    "is the largest set of verified maps closed under composition, and may lack elements")
    if any("partial candidates" in t for t in texts):
        what.append("candidate tuples were cut short (a point set with little structure); elements "
                    "whose candidates were cut may be missing")
    rest = [t for t in texts if not any(c in t for c in closure_notes + ("partial candidates",))]
    what += rest
    g = result.group
    return (f"group path: {'continuous symmetry' if result.continuous else f'{g.name} ({g.order} elements)'}"
            f" found, but " + "; ".join(what))


def unexplained_multiplicities(result: SymmetryResult, evals: Tensor, k: int = 20) -> bool:
    """Whether the group found leaves the spectrum's repeated eigenvalues ``evals [K]`` unexplained:
    every element of order <= 2 (all irreducible representations 1-D, so no symmetry-forced
    multiplicity), while the low spectrum is dominated by 2-D bands at one of
    :func:`has_multiplicities`' two scales. A near-isometry (a bend) splits the eigenspaces its
    rotations mix by up to about one local spacing; with those bands split, block-diagonal matrices
    cannot carry the rotations, and only their 1-D subgroup is found. False for a continuous symmetry (its result has no finite group)."""
    if result.continuous or int(result.group.orders.max()) > 2:
        return False
    # at either scale: the group path has run already, and a bend that splits the pairs of the
    # larger basis still leaves the coarse one dominated by them (six arms bent at R = 4)
    return has_multiplicities(evals, k, both=False)


def bend_remnant(result: SymmetryResult) -> bool:
    """Whether the group found is what a bend about one axis leaves exact of a larger group: a half
    turn, every element of order <= 2 (C2 of a chiral C_2n, C2v of C_2n v, D2h of D_nh). Six arms
    bent at R = 6 keep their C2v exactly, a chiral four their half turn, and both split their
    eigenvalue pairs by more than the bands' 0.3 of a spacing, down to a 2-D share of 0.32-0.37
    at both scales, below what :func:`unexplained_multiplicities` asks; the merged-band attempt
    finds their C6v and C4. An exact C2v (a table, a box's D2h) costs one more attempt, whose
    elements are verified as any; a lone mirror (Cs, the humans') does not ask for it. Where a
    second opinion asked for more than two elements, its first attempt stops at the coarse stage:
    ``diagnostics.group.coarse_half_turn`` then says whether its two elements were a half turn."""
    g = result.group
    if result.continuous or int(g.orders.max()) > 2:
        return False
    # a second opinion asked for more than two elements stops at the coarse stage: its half turn
    # is in the diagnostics
    return (bool(((g.orders == 2) & ~torch.as_tensor(g.reversing, dtype=torch.bool)).any())
            or bool(getattr(result.diagnostics.group, "coarse_half_turn", False)))


def _detect_group(verts, faces, spectrum: Spectrum, *, k: int, k_refine: int, config: GroupConfig | None,
                  device, solver: GeodesicSolver | None, min_order: int, timer,
                  rel_gap: float = BAND_REL_GAP, approximate: bool = False) -> SymmetryResult:
    """:func:`detect_group` without its warning summary, in bands split at ``rel_gap``; with
    ``approximate`` (the merged attempt: a near-isometry split the eigenspaces, and its maps are only
    nearly block-diagonal) the maps are refined as full orthogonal matrices, the descriptor gate is
    also relative (``merged_relative_tol``) and only the orientation coset is weighed as a
    near-symmetry."""
    cfg = GroupConfig() if config is None else config
    lap = timer.lap if timer is not None else (lambda name: None)
    dev = torch.device("cpu") if device is None else torch.device(device)
    spectrum = _at_most(spectrum.to("cpu"), cfg.n_eigen)
    basis = group_basis(spectrum.evals, k, k_refine, cfg.refine, rel_gap)
    verts_unit = np.asarray(verts, dtype=np.float64) * spectrum.scale
    solver = GeodesicSolver(verts_unit, faces, backend="batched") if solver is None else solver
    diag = GroupDiagnostics(k0=basis.k0, k_refine=basis.k_refine, m=basis.m,
                            bands0=[len(b) for b in basis.bands0], band_gap=rel_gap)

    def trivial(why: str, continuous: bool = False) -> SymmetryResult:
        return _trivial_result(spectrum, basis, replace(diag, reason=why), continuous, timer)

    pts = invariant_point_set(spectrum, faces, verts_unit, solver, cfg.n_points, cfg.persistence)
    diag = replace(diag, n_points=int(len(pts.points)))
    lap("points")
    geo = Geometry(verts_unit, spectrum, pts.points, pts.fields, cfg.n_samples, faces)
    lap("samples")
    heat = (HeatLevels(hks_at_scales(spectrum.evals, spectrum.evecs, (0.1, 0.02)), faces)
            if cfg.max_level_change < 1 else None)
    continuous, diag_c = continuous_test(geo, solver, basis.bands, basis.k0, spectrum.evals,
                                         mean_edge(verts_unit, faces), heat=heat,
                                         max_changed=cfg.max_level_change)
    diag = replace(diag, continuous_test=diag_c)
    lap("continuous")
    if continuous:
        return trivial("continuous symmetry: a rotation by an arbitrary angle is an isometry", True)
    if len(pts.points) < 2:
        return trivial("fewer than 2 invariant points")
    desc = descriptors(spectrum.evals, spectrum.evecs)  # [V, D]
    near = (desc, pts.fields <= cfg.partner_radius * EPS_KLC) if cfg.partner_radius > 0 else None
    allowed = partner_mask(desc[pts.points], pts.dist, cfg.desc_tol, near,
                           cfg.merged_relative_tol if approximate else 0.0)
    coef = disk_coefficients(spectrum.evecs[:, :basis.k0], spectrum.mass, pts.fields)  # [n, R, k0]
    pairs = tuple_pairs(pts.dist, allowed, min(basis.m + 1, len(pts.points)), cfg.n_sources, cfg.delta,
                        Pinning(coef, basis.bands0), pts.persistent,
                        max_missing=cfg.merged_max_missing if approximate else 0)
    diag = replace(diag, n_points_with_partner=pairs.n_with_partner, tuple_size=pairs.src.shape[1],
                   n_source_tuples=pairs.n_sources, n_candidates_before=pairs.n_before,
                   n_candidates=int(len(pairs.src)))
    lap("candidates")
    if len(pairs.src) == 0:
        return trivial("no candidate survived pruning")
    dip = (cfg.dipoles * dipole_coefficients(spectrum.evecs[:, :basis.k0], spectrum.mass, pts.fields, pts.points)
           if cfg.dipoles > 0 else None)
    C = candidate_fmaps(pairs, coef, desc, spectrum, basis, dev, cfg.max_candidates, dip, cfg.bandwidth)
    if len(C) < len(pairs.src):
        diag = replace(diag, n_candidates_kept=len(C))
    lap("procrustes")
    if cfg.n_icp > 0:
        E0 = spectrum.evecs[:, :basis.k0]
        targets = geo.samples[: min(len(geo.samples), 600)]
        C = batched_icp(C, E0[geo.score_samples].to(dev), E0[targets].to(dev), basis.bands0, cfg.n_icp)
        lap("icp")
    reps, sizes = cluster_representatives(C, cfg.bandwidth, cfg.max_modes)
    diag = replace(diag, n_clusters=len(sizes), cluster_sizes=sizes[:cfg.max_modes])
    lap("cluster")
    coarse = CoarseElements(geo, basis.bands0, basis.k0, cfg, block=not approximate)
    for C_rep in reps:
        coarse.add(C_rep)
    diag = replace(diag, trace=list(coarse.trace), n_verified=len(coarse.elements),
                   rejected_distortion=coarse.rejected[:10])
    lap("refine")
    coarse_closed = coarse.close()
    diag = replace(diag, n_after_closure=len(coarse.elements))
    lap("closure")
    if len(coarse.elements) < min_order:  # the largest subgroup of these has at most that many
        if len(coarse.elements) == 2:  # closed: the identity and an involution, a mirror or a half turn
            keeps = orientation_score(geo.p2p(coarse.elements[1].fmap), geo.verts, geo.faces) > 0
            diag = replace(diag, coarse_half_turn=bool(keeps))
        return trivial(f"{len(coarse.elements)} elements verified in the coarse basis, fewer than the "
                       f"{min_order} asked for")
    elements, rejected, closed = upsample_elements(coarse.elements, geo, solver, basis.bands, basis.k0,
                                                   basis.k_refine, cfg.max_distortion, coarse.alternatives,
                                                   close=not coarse_closed, near_misses=coarse.near_misses,
                                                   block=not approximate)
    if not closed:
        warnings.warn(f"closure of the {len(elements)} elements did not end closed", stacklevel=2)
    diag = replace(diag, rejected_exact=rejected)
    lap("upsample")
    symmetries, group, diag = group_of_elements(elements, geo, faces, diag, cfg.near_mirrors, solver,
                                                heat, cfg.max_level_change, approximate, cfg.max_distortion)
    lap("group")
    bands = full_bands(basis.k_refine) if approximate else _bands_upto(basis.bands, basis.k_refine)
    return SymmetryResult(symmetries, spectrum, bands, group=group,
                          timings=dict(timer.timings) if timer is not None else {},
                          diagnostics=Diagnostics("group", group=diag))


# ------------------------------------------------------------------------------------------ stages
def group_basis(evals: Tensor, k: int, k_refine: int, refine: str = "zoomout",
                rel_gap: float = BAND_REL_GAP) -> GroupBasis:
    """The coarse and refined basis sizes (band ends) and the largest coarse band, in the solved
    bands split at ``rel_gap`` local spacings (``spectrum.eigen_bands``)."""
    bands = solved_bands(evals, rel_gap)
    bands0, k0 = _coarse_bands(bands, k)
    kf = k0 if refine == "icp" else band_boundary(bands, k_refine)
    return GroupBasis(bands, bands0, k0, kf, max(len(b) for b in bands0))


def invariant_point_set(spectrum: Spectrum, faces, verts_unit: np.ndarray, solver: GeodesicSolver,
                        n_points: int, persistence: float = GroupConfig.persistence) -> PointSet:
    """Stage 1: invariant points (:func:`.candidates.invariant_points`) and their distance fields."""
    pts = invariant_points(spectrum.evals, spectrum.evecs, faces, verts_unit, n_max=n_points)
    fields = torch.as_tensor(np.asarray(solver.distances_from(pts)), dtype=spectrum.evecs.dtype)  # [n, V]
    dist = fields[:, pts].numpy()
    persistent = (persistent_points(spectrum.evals, spectrum.evecs, faces, verts_unit, pts, share=persistence)
                  if persistence > 0 else np.ones(len(pts), dtype=bool))
    return PointSet(pts, fields, 0.5 * (dist + dist.T), persistent)


def continuous_test(geo: Geometry, solver: GeodesicSolver, bands: list[range], k0: int,
                    evals: Tensor | None = None, edge: float | None = None,
                    angles=(0.55, 0.83), max_distortion: float = 0.6, max_edges: float = 0.5,
                    max_stay: float = 0.1, heat: HeatLevels | None = None,
                    max_changed: float = GroupConfig.max_level_change) -> tuple[bool, dict]:
    """Whether the shape has a continuous (one-parameter) family of isometries (ALGORITHM §7).

    The first band of size >= 2 is rotated by an angle no finite group of small order has there
    (0.55, then 0.83 rad), the rest kept; the matrix is refined. A finite group snaps it to one of its
    elements (or the refinement is no isometry); a continuous symmetry keeps it: the refined band
    block stays near the rotation put in, and the map is a near-isometry. Both angles must pass.
    Within the band, the rotation mixes its two closest eigenvalues (``evals``): the band can hold
    an accidental near-pair beside the rotation's own pair (a cone's axial mode next to its first
    pair), and rotating the axial mode into the pair snaps away.

    How isometric: a vertex map of an exact isometry still moves each image to a vertex, which
    costs up to about a quarter of the mean edge length in ``|d(g x, g y) - d(x, y)|`` (0.04-0.32
    edges on spheres, ellipsoids, tori, capsules, cylinders and cones, regular and ACVD-remeshed:
    ``scripts/continuous_test_table.py``); the refined
    rotation must stay within ``max_edges`` mean edges ``edge`` (twice that floor; unit-area shape)
    and ``max_distortion`` KLC radii. A near-round polyhedron (a square antiprism) keeps the rotation
    put in but bends it by more than its resolution: 1.36 edges, where the finite group's own
    elements are exact.

    How it keeps the heat: an isometry keeps the heat kernel signature everywhere, so the refined
    rotation may change the heat level (``heat``, :class:`.verification.HeatLevels`) of at most
    ``max_changed`` of the area. A prism or an antiprism of 6-9 sides, remeshed or not, has a
    rotation by such an angle that stays within the distortion bound (its corners carry little of
    the area), but moves the corners onto the rim between them: 5-30 % of the area changes level
    at the finer scales, against at most 2 % on surfaces of revolution (the same table).

    How near: a group with rotations by ``2 pi / n`` can snap an angle by as little as its distance
    to the nearest multiple of ``2 pi / n``, less than ``pi / n``; "stay" is the block's change
    ``||D1 - D0||_F / sqrt(len(band))`` (``2 sin(angle / 2)`` for a rotation block). Under
    ``max_stay = 0.1`` both test angles lie that close to a group angle only for ``n > 20``, while
    surfaces of revolution keep them to about 0.02 (``tests/test_group_path.py``). The earlier
    bound 0.3 read the eight-fold rotation of a C8v shape (0.55 snapped to pi / 4: stay 0.23) as
    continuous.

    Returns:
        (continuous, measurements per angle).
    """
    multi = [b for b in bands[1:] if len(b) >= 2 and b.stop <= k0]
    diag: dict = {"tested_band": None}
    if not multi:
        return False, diag
    b = multi[0]
    diag["tested_band"] = [b.start, b.stop]
    i = b.start
    if evals is not None and len(b) > 2:
        i += int(torch.diff(evals[b.start:b.stop]).argmin())
    j = i + 1
    bound = max_distortion if edge is None else min(max_distortion, max_edges * edge / EPS_KLC)
    diag["max_distortion"] = round(bound, 4)
    ks = b.stop
    passed = []
    smp = geo.samples[:: max(1, len(geo.samples) // 12)][:12]
    D_smp = None  # distances among smp: the same for every angle
    for a in angles:
        C0 = torch.eye(ks, dtype=geo.evecs.dtype)
        c, s = math.cos(a), math.sin(a)
        C0[i, i], C0[i, j], C0[j, i], C0[j, j] = c, -s, s, c
        C = zoomout(geo, C0, bands, k0)
        D0, D1 = C0[b.start:b.stop, b.start:b.stop], C[b.start:b.stop, b.start:b.stop]
        stay = float((D1 - D0).norm() / math.sqrt(len(b)))
        if stay >= max_stay:  # snapped away from the rotation put in: no need to measure distortion
            diag[f"angle_{a}"] = {"stay": round(stay, 3), "pass": False}
            passed.append(False)
            break
        img = geo.p2p(C, smp)
        if D_smp is None:
            D_smp = solver.pairwise(smp)
        dist = float((solver.pairwise(img) - D_smp).abs().mean() / EPS_KLC)
        ok = stay < max_stay and dist < bound
        row = {"stay": round(stay, 3), "distortion": round(dist, 3)}
        if ok and heat is not None:
            row["level_change"] = round(changed := heat.changed_share(geo.p2p(C), geo.mass), 4)
            ok = changed <= max_changed
        diag[f"angle_{a}"] = {**row, "pass": ok}
        passed.append(ok)
        if not ok:
            break
    return all(passed), diag


def _constraints(pairs, coef: Tensor, desc: Tensor, spectrum: Spectrum, k0: int) -> tuple[Tensor, Tensor]:
    """[B, k0, J] constraint coefficients ``(A, B)`` with ``C A ≈ B`` for each tuple pair.

    ``1_{g(p)} ∘ g = 1_p``: the functions (A) are disks at the targets q, their pull-backs (B) at
    the sources p; the descriptors are their own pull-backs. ``coef`` [n, R, k0]: the disk
    coefficients of the points; a tuple padded with -1 (shorter than the longest) gets zero columns.
    """
    E0 = spectrum.evecs[:, :k0]
    A_disk = torch.cat([coef, torch.zeros_like(coef[:1])]).permute(2, 0, 1)  # [k0, n + 1, R]: -1 -> 0
    A_desc = descriptor_coefficients(E0, spectrum.mass, desc)  # [k0, D]
    Pt, Qt = torch.as_tensor(pairs.src), torch.as_tensor(pairs.dst)
    Bn = len(Pt)
    A = torch.cat([A_disk[:, Qt].permute(1, 0, 2, 3).reshape(Bn, k0, -1), A_desc.expand(Bn, -1, -1)], -1)
    B = torch.cat([A_disk[:, Pt].permute(1, 0, 2, 3).reshape(Bn, k0, -1), A_desc.expand(Bn, -1, -1)], -1)
    return A, B


def _dipole_constraints(pairs, dip: Tensor) -> tuple[Tensor, Tensor]:
    """[B, k0, J'] the dipole columns of each tuple pair, beside :func:`_constraints`' ``(A, B)``:
    the dipole at each tuple point towards the next (cyclically), at q (A) and at p (B).
    ``dip`` [n, n, R, k0] (``constraints.dipole_coefficients``); -1 padding gets zero columns."""
    n, k0 = dip.shape[0], dip.shape[-1]
    D = dip.new_zeros(n + 1, n + 1, *dip.shape[2:])  # -1 (padding) -> zeros
    D[:n, :n] = dip
    Pt, Qt = torch.as_tensor(pairs.src), torch.as_tensor(pairs.dst)
    Bn = len(Pt)
    return (D[Qt, Qt.roll(-1, 1)].reshape(Bn, -1, k0).mT, D[Pt, Pt.roll(-1, 1)].reshape(Bn, -1, k0).mT)


def candidate_fmaps(pairs, coef: Tensor, desc: Tensor, spectrum: Spectrum, basis: GroupBasis,
                    device: torch.device, max_candidates: int, dip: Tensor | None = None,
                    same: float = 0.6) -> Tensor:
    """Stage 5: [B', k0, k0] matrices of the tuple pairs in batched block Procrustes; of more than
    ``max_candidates``, those whose matrix fits its constraints best (relative residual).
    ``coef`` [n, R, k0]: the points' disk coefficients; ``dip`` [n, n, R, k0]: their dipoles
    (:func:`_constraints`). With ``dip``, each pair is solved with the disks alone and with the
    dipoles beside them, and a dipole solution goes on too where it differs from the pair's disk
    solution by more than ``same`` (Frobenius; the clustering's bandwidth, under which the two
    would merge anyway): where the disks pin every band the two agree and nothing is added; where
    every tuple point lies on mirror planes the disks leave the bands those mirrors negate to noise
    (a regular hexagonal prism: 6 of its 24 elements without the dipoles), and the dipoles pin
    them. Neither set alone serves every shape: the dipoles outvote the disks on Watertight 156's
    thin top (the half turn composed with the swap of its two faces), at half weight they lose a
    strongly bent slab's cap swaps (star6_h03_bent3: C6v for D6h)."""
    A0, B0 = (x.to(device) for x in _constraints(pairs, coef, desc, spectrum, basis.k0))
    systems = [(A0, B0)]
    if dip is not None:
        Ad, Bd = (x.to(device) for x in _dipole_constraints(pairs, dip))
        systems.append((torch.cat([A0, Ad], -1), torch.cat([B0, Bd], -1)))
    out = []
    for A, B in systems:
        C = block_procrustes(A, B, basis.bands0)
        keep = torch.arange(len(C), device=C.device)
        if out:  # the dipole solutions that differ from their pair's disk solution
            keep = keep[(C - out[0][0]).flatten(1).norm(dim=1) > same]
        fit = (C @ A - B).square().sum((-2, -1)) / B.square().sum((-2, -1))
        out.append((C, keep, fit))
    picked = []
    for C, keep, fit in out:
        if len(keep) > max_candidates:
            keep = keep[torch.argsort(fit[keep])[:max_candidates]]
        picked.append(C[keep])
    return torch.cat(picked)


def cluster_representatives(C: Tensor, bandwidth: float, max_modes: int) -> tuple[list[Tensor], list[int]]:
    """Stage 7: mean shift of the flattened matrices; for each of the densest ``max_modes`` clusters
    the member nearest its mode. Returns (representatives [k0, k0] on the CPU, every cluster's size)."""
    modes, labels, counts = (x.cpu() for x in mean_shift(C.reshape(len(C), -1), bandwidth))
    C = C.cpu()
    reps = []
    for j in range(min(len(modes), max_modes)):
        members = torch.nonzero(labels == j)[:, 0]
        reps.append(C[members[(C[members].reshape(len(members), -1) - modes[j]).norm(dim=1).argmin()]])
    return reps, [int(c) for c in counts.tolist()]


#: near_symmetry_coset's rule for the orientation-reversing half (``group_elements.far_above``): its
#: median distortion this many times the rotations'. The halves of one true group read about one
#: size on regular meshes and ACVD remeshes, bent or not (0.8-1.1 times), and where the elements
#: were refined as full orthogonal matrices (the merged-band attempt: 0.5-1.01). A chiral shape's
#: mirrors read 2.9-5.0 times on a remesh and 25-40 times on a regular mesh; a bend adds to both
#: halves, so a bent chiral shape's read only 1.45-2.45 times its rotations (nine arms at R = 8:
#: 1.71, C9v for C9 at the former 2.0; the merged attempt's 1.6-1.9; BENCHMARKS.md, "Wider shapes")
COSET_RATIO = 1.3
#: ... and for any other index-2 coset, this, and every element of the coset above every element of
#: the subgroup: a bend spares the half of a slab's group that respects it, up to 3.8 times less
#: distorted than the rest and apart from it (a bent thin eight-pointed star), as far apart as the
#: remeshed octagonal prism's spurious eighth turns (4.2 times); a near-symmetric half riding on an
#: exactly symmetric triangulation (a squashed trigonal antiprism's D3d read as D6h: 0.19 against
#: 0.0004) stands out by far more
SUBGROUP_RATIO = 10.0
#: ... and any other coset of the merged attempt's maps (full orthogonal matrices), against its
#: subgroup's inexact elements (above :data:`~.group_elements.EXACT_ENOUGH` of ``max_distortion``:
#: what the bend spares is left out),
#: with every element of the coset above every element of the subgroup: the other halves of true
#: bent groups read 0.48-1.01 times their subgroups' bent elements and never apart from them, the
#: horizontal mirrors of seven arms drooping 6 degrees and bent at R = 5 (a spurious D7h for C7v)
#: 2.04 times, apart (``group_shapes_table.py --cosets``)
APPROXIMATE_SUBGROUP_RATIO = 1.5


def near_symmetry_coset(table, distortion, reversing=None, approximate: bool = False,
                        exact: float = EXACT_ENOUGH * GroupConfig.max_distortion) -> np.ndarray | None:
    """The index-2 coset of the group that is a near-symmetry riding on an exact subgroup, if any.

    The elements of one exact group share the mesh's discretisation, so their distortions are of
    one size, on regular meshes and remeshed. Where one half of the group, the complement of an
    index-2 subgroup H, is several times more distorted than H, that half is a near-symmetry: the
    mirrors of a shape made chiral by small features, mirrors that hold only approximately (arms
    swept sideways by a near-isometry: the two read alike, BENCHMARKS.md, "Wider shapes"), or the
    turns of a near-round shape that its resolution admits (an octagonal prism remeshed: D16h,
    twice its D8h). Every index-2 subgroup is the kernel of a homomorphism onto Z2
    (``groups.algebra._z2_homs``); the orientation-reversing elements are one such coset.

    Args:
        table: [G, G] group table; distortion: [G] floats, KLC radii; reversing: optional [G] bool,
            the orientation-reversing elements (their coset is held to :data:`COSET_RATIO`, any
            other to :data:`SUBGROUP_RATIO` and separation); approximate: the elements are maps of
            a near-isometry refined as full orthogonal matrices (the merged-band attempt): any
            coset other than the orientation one is held to :data:`APPROXIMATE_SUBGROUP_RATIO`
            of its subgroup's elements above ``exact`` and to separation (a bend spares the elements that respect it: four arms bent about one axis
            keep their two mirrors and half turn exactly and their quarter turns to 0.16 KLC
            radii; a subgroup that is exact throughout gives nothing to compare with).

    Returns:
        [G] bool, the coset (True) whose median distortion is :func:`~.group_elements.far_above`
        the median of H's non-identity elements by the ratios above, the most so where several
        are; None where none is, or where H is the identity alone (Cs keeps its mirror: nothing to
        compare it with).
    """
    d = np.asarray(distortion, dtype=np.float64)
    rev = None if reversing is None else np.asarray(reversing, dtype=bool)
    best, best_ratio = None, 0.0
    for coset, inner, mc, mh in _index2_cosets(table, d):
        orientation = rev is not None and bool((coset == rev).all())
        if orientation:
            stands_out = far_above(mc, mh, COSET_RATIO)
        elif approximate:
            mh = _bent_median(d, inner, exact)
            if mh is None:
                continue
            stands_out = far_above(mc, mh, APPROXIMATE_SUBGROUP_RATIO) and _apart(d, coset, inner)
        else:
            stands_out = far_above(mc, mh, SUBGROUP_RATIO) and _apart(d, coset, inner)
        ratio = mc / max(mh, OUTLIER_FLOOR)
        if stands_out and ratio > best_ratio:
            best, best_ratio = coset, ratio
    return best


def _apart(d: np.ndarray, coset: np.ndarray, inner: np.ndarray) -> bool:
    """Every element of the coset more distorted than every element of its subgroup."""
    return bool(d[coset].min() > d[inner].max())


def bent_coset_ratios(table, distortion, reversing, exact: float = EXACT_ENOUGH * GroupConfig.max_distortion
                      ) -> list[tuple[float, bool]]:
    """Per index-2 coset other than the orientation one, whose subgroup has elements above
    ``exact``: (its median distortion over theirs, whether it lies apart from the subgroup), what
    :func:`near_symmetry_coset` weighs for approximate maps (``group_shapes_table.py --cosets``)."""
    d = np.asarray(distortion, dtype=np.float64)
    rev = np.asarray(reversing, dtype=bool)
    out = []
    for coset, inner, mc, _ in _index2_cosets(table, d):
        mh = _bent_median(d, inner, exact)
        if not (coset == rev).all() and mh is not None:
            out.append((mc / max(mh, OUTLIER_FLOOR), _apart(d, coset, inner)))
    return out


def _bent_median(d: np.ndarray, inner: np.ndarray, exact: float) -> float | None:
    """The median distortion of the subgroup's elements above ``exact`` (None: none is)."""
    bent = inner[d[inner] > exact]
    return float(np.median(d[bent])) if len(bent) else None


def _index2_cosets(table, d: np.ndarray):
    """Each index-2 coset of the group (``groups.algebra._z2_homs``) with a non-identity subgroup:
    (coset [G] bool, the subgroup's non-identity elements, the coset's and their median of ``d``)."""
    T = np.asarray(table)
    e = identity_index(torch.as_tensor(T))
    for coset in _z2_homs(T, e):
        inner = np.flatnonzero(~coset)
        inner = inner[inner != e]
        if len(inner):
            yield coset, inner, float(np.median(d[coset])), float(np.median(d[inner]))


def coset_spread(table, distortion) -> float:
    """The largest ratio of an index-2 coset's median distortion to its subgroup's (0 where the
    group has no such coset; the subgroup's median floored at 1e-3 KLC radii)."""
    d = np.asarray(distortion, dtype=np.float64)
    return max((mc / max(mh, 1e-3) for _, _, mc, mh in _index2_cosets(table, d)), default=0.0)


#: a coset this many times its subgroup's distortion is measured again as vertex-to-point maps
#: (:func:`group_of_elements`) before the near-symmetry rule weighs it: where the orientation
#: coset's rule (:data:`COSET_RATIO`) could drop it
PRECISE_SPREAD = COSET_RATIO


def keep_heat_levels(elements: list[Element], heat: HeatLevels, mass: Tensor, max_changed: float,
                     diag: GroupDiagnostics) -> tuple[list[Element], GroupDiagnostics]:
    """The elements that keep the heat levels, before the largest closed subset is taken.

    An isometry keeps the heat kernel signature everywhere (:class:`.verification.HeatLevels`): the
    true elements of the tables' shapes, bent, swept and remeshed ones included, change the heat
    level of at most 2 % of the area (``group_shapes_table.py --levels``). A near-symmetry of a near-more-symmetric shape can pass
    every distortion test and still move its features onto others: a square antiprism's eighth
    turns (the corners onto the middles of the other cap's edges: half the area), an S6 solid's
    near-D3d half turns (5 %), a remeshed pinwheel's near mirrors (20 %); mixed with the true
    elements, their products also lead the largest closed subset astray (a hexagonal antiprism of
    half height 0.46, ``scripts/group_shapes_table.py --random-shapes 12 --seed 2``: D6 of 78 maps,
    D6d of the 32 that keep the heat). The elements that change more than
    ``max_changed`` of it are left out, with one warning; ``diag.level_changes`` keeps their shares.
    """
    share = np.asarray([heat.changed_share(e.p2p, mass) for e in elements])
    keep = np.flatnonzero(share <= max_changed)
    if len(keep) == len(elements):
        return elements, diag
    out = np.setdiff1d(np.arange(len(elements)), keep)
    warnings.warn(f"{len(out)} of the {len(elements)} verified maps change the heat levels of "
                  f"{share[out].min():.0%}-{share[out].max():.0%} of the area (an isometry keeps them): "
                  f"near-symmetries, left out (diagnostics.group.level_changes)", stacklevel=3)
    diag = replace(diag, level_changes=[round(float(x), 4) for x in share[out]])
    return [elements[i] for i in keep], diag


def _near_symmetry_rounds(table, distortion, rev, approximate: bool, exact: float, drop: bool = True
                          ) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`near_symmetry_coset`'s rounds: [(indices of the elements weighed, [len] bool coset
    found among them)], until none is left (``drop``: each round weighs the subgroup the last left)
    or once."""
    table = np.asarray(table)
    d, rev = np.asarray(distortion, dtype=np.float64), np.asarray(rev, dtype=bool)
    idx, rounds = np.arange(len(d)), []
    while len(idx) > 2:
        coset = near_symmetry_coset(table, d[idx], rev[idx], approximate, exact)
        if coset is None:
            break
        rounds.append((idx, coset))
        if not drop:
            break
        keep = np.flatnonzero(~coset)
        table, idx = _subtable(table, keep), idx[keep]
    return rounds


def _survivors(rounds: list[tuple[np.ndarray, np.ndarray]], n: int) -> np.ndarray:
    """The indices of the ``n`` elements that :func:`_near_symmetry_rounds`' dropping leaves."""
    if not rounds:
        return np.arange(n)
    idx, coset = rounds[-1]
    return idx[~coset]


def _drop_near_symmetries(elements: list[Element], table, rev: list[bool], near_mirrors: str,
                          diag: GroupDiagnostics, approximate: bool = False,
                          exact: float = EXACT_ENOUGH * GroupConfig.max_distortion
                          ) -> tuple[list[Element], np.ndarray, list[bool], GroupDiagnostics]:
    """:func:`near_symmetry_coset` (``approximate`` and ``exact`` passed on), until none is left
    (``near_mirrors='drop'``: each round halves the group, the table restricted to the subgroup) or
    once (``'keep'``), with one warning."""
    table = np.asarray(table)
    dist = np.asarray([e.distortion for e in elements])
    rounds = _near_symmetry_rounds(table, dist, rev, approximate, exact, near_mirrors == "drop")
    dropped: list[float] = []
    said = []
    for idx, coset in rounds:
        d = dist[idx]
        inner = np.flatnonzero(~coset)[1:]  # identity first, never in the coset
        what = ("orientation-reversing elements" if list(coset) == [rev[i] for i in idx]
                else "elements of an index-2 coset")
        said.append(f"the {int(coset.sum())} {what} are near-symmetries riding on a near-exact subgroup "
                    f"of {int((~coset).sum())} (median distortion {np.median(d[coset]):.3f} against "
                    f"{np.median(d[inner]):.3f} EPS_KLC)")
        dropped += [round(float(x), 4) for x in d[coset]]
    if said:
        diag = replace(diag, near_symmetry_coset=dropped)
        if near_mirrors == "drop":
            keep = _survivors(rounds, len(elements))
            table = _subtable(table, keep)
            elements = [elements[i] for i in keep]
            rev = [rev[i] for i in keep]
            rest = "rotations" if not any(rev) else "elements of the subgroup"
            warnings.warn(f"{'; '.join(said)}: left out, the group is the {len(elements)} {rest} "
                          f"(GroupConfig(near_mirrors='keep') keeps them; their distortions: "
                          f"diagnostics.group.near_symmetry_coset)", stacklevel=3)
        else:
            idx, coset = rounds[0]
            sub = int((~coset).sum())
            rest = "rotations" if list(coset) == list(rev) else "elements of that subgroup"
            warnings.warn(f"{said[0]}: kept, but the exact group may be the {sub} {rest} alone "
                          f"(diagnostics.group.near_symmetry_coset)", stacklevel=3)
    return elements, table, rev, diag


def _whole_closed_subset(options: list[tuple[list[int], Tensor]], dist: np.ndarray, scores: list[float],
                         near_mirrors: str, approximate: bool, exact: float
                         ) -> tuple[list[int], Tensor, Tensor]:
    """Of :func:`~symtorch.groups.from_maps.closed_subsets`, the one that keeps the most elements
    after :func:`near_symmetry_coset` (the first, the cheapest greedy set, among equals), with its
    orientation flags (``groups.consistent_orientation`` of the votes ``scores``): two
    near-mirrors of a bent chiral shape's half turn close a group of four with it as its quarter
    turns do, and come first where they are cheaper, yet ride on it as a near-symmetry the coset
    rule strips, while the quarter turns are whole.

    Returns:
        (indices kept, [G', G'] table among them, [G'] bool orientation-reversing flags).
    """
    revs = [consistent_orientation(table, [scores[i] for i in keep]) for keep, table in options]
    if len(options) == 1:
        return (*options[0], revs[0])

    def kept(option, rev) -> int:
        keep, table = option
        if near_mirrors != "drop":
            return len(keep)
        rounds = _near_symmetry_rounds(table, dist[keep], rev.numpy(), approximate, exact)
        return len(_survivors(rounds, len(keep)))

    sizes = [kept(o, r) for o, r in zip(options, revs)]
    best = int(np.argmax(sizes))
    log.debug("closed subsets %s kept %s", [o[0] for o in options], sizes)
    return (*options[best], revs[best])


def group_of_elements(elements: list[Element], geo: Geometry, faces, diag: GroupDiagnostics,
                      near_mirrors: str = "drop", solver: GeodesicSolver | None = None,
                      heat: HeatLevels | None = None, max_changed: float = GroupConfig.max_level_change,
                      approximate: bool = False, max_distortion: float = GroupConfig.max_distortion
                      ) -> tuple[list[Symmetry], GroupInfo, GroupDiagnostics]:
    """Stage 10: the largest closed subset of the verified elements, its table, orientation flags,
    name, and the elements in the paper's order (Table 3). Where half of the group is a
    near-symmetry riding on the other half (:func:`near_symmetry_coset`: the mirrors of a chiral
    shape, most often), ``near_mirrors='drop'`` leaves it out: the group is that index-2 subgroup.
    Where some index-2 coset reads more than :data:`PRECISE_SPREAD` times its subgroup, the elements
    are measured again as vertex-to-point maps first (``solver``;
    ``group_elements.point_map_distortions``): the vertex rounding that every element of a
    remeshed group shares would otherwise hide how far apart the two halves are. With ``heat``,
    the elements that change the heat levels of more than ``max_changed`` of the area are left out
    before anything else (:func:`keep_heat_levels`). ``approximate``: the elements were refined as
    full orthogonal matrices (:func:`near_symmetry_coset`'s rule for them)."""
    x_unit = geo.verts
    faces_t = torch.as_tensor(faces)
    if heat is not None:
        elements, diag = keep_heat_levels(elements, heat, geo.mass, max_changed, diag)
    dist = np.asarray([e.distortion for e in elements])
    scores = [orientation_score(e.p2p, x_unit, faces_t) for e in elements]
    options = closed_subsets([e.p2p for e in elements], list(dist), x_unit, geo.score_samples)
    keep, table, rev = _whole_closed_subset(options, dist, scores, near_mirrors, approximate,
                                            EXACT_ENOUGH * max_distortion)
    if len(keep) < len(elements):
        diag = replace(diag, dropped=sorted(set(range(len(elements))) - set(keep)))
    elements = [elements[i] for i in keep]
    if solver is not None and coset_spread(table, [e.distortion for e in elements]) > PRECISE_SPREAD:
        elements = point_map_distortions(elements, geo, solver)
    elements, table, rev, diag = _drop_near_symmetries(elements, table, list(rev), near_mirrors, diag, approximate,
                                                       EXACT_ENOUGH * max_distortion)
    dist = [e.distortion for e in elements]
    _, residual = cayley_table(torch.stack([e.fmap for e in elements]))
    fixes = fixes_points(torch.stack([e.p2p for e in elements]), x_unit, faces_t)  # Dnh / Dnd, Cs / Ci
    table, rev = torch.as_tensor(table, dtype=torch.long), torch.as_tensor(rev, dtype=torch.bool)
    order = canonical_order(table, rev, dist)
    perm = torch.tensor(order)
    inv_perm = torch.empty_like(perm)
    inv_perm[perm] = torch.arange(len(perm))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        group = group_info(inv_perm[table[perm][:, perm]], rev[perm], fixes=fixes[perm])
    symmetries = []
    for new_i, i in enumerate(order):
        e = elements[i]
        kind = kind_of(int(group.orders[new_i]), bool(group.reversing[new_i]))
        symmetries.append(Symmetry(e.fmap, e.p2p, kind, int(group.orders[new_i]), math.exp(-e.distortion ** 2)))
    diag = replace(diag, cayley_max_residual=round(float(residual.max()), 4),
                   distortion=[round(elements[i].distortion, 4) for i in order],
                   name=group.name, order=group.order)
    return symmetries, group, diag


# ------------------------------------------------------------------------------------------ helpers
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


def _bands_upto(bands: list[range], K: int) -> list[range]:
    return [b for b in bands if b.stop <= K]


def _trivial_result(spectrum: Spectrum, basis: GroupBasis, diag: GroupDiagnostics, continuous: bool,
                    timer) -> SymmetryResult:
    """The identity alone (the trivial group), with the reason in the diagnostics."""
    kf, V = basis.k_refine, spectrum.evecs.shape[0]
    eye = torch.eye(kf, dtype=spectrum.evecs.dtype)
    identity = Symmetry(eye, torch.arange(V), "identity", 1, 1.0)
    group = group_info(eye[None], torch.zeros(1, dtype=torch.bool))
    return SymmetryResult([identity], spectrum, _bands_upto(basis.bands, kf), group=group,
                          continuous=continuous, timings=dict(timer.timings) if timer is not None else {},
                          diagnostics=Diagnostics("group", group=diag))


# ------------------------------------------------------------------------ used by detect_symmetries
#: :func:`has_multiplicities`' least share of eigenvalues in 2-D bands
MULTIPLICITY_SHARE = 0.45


def has_multiplicities(evals: Tensor, k: int = 20, min_share: float = MULTIPLICITY_SHARE,
                       both: bool = True) -> bool:
    """Whether the low spectrum is dominated by repeated eigenvalues, at two scales (``both``) or
    at one of them at least.

    The share of the non-constant eigenvalues lying in bands of size >= 2 must reach ``min_share``
    both in the coarse basis (``k`` snapped to a band end) and in twice that (as far as ``evals``
    goes). A group with rotations of order >= 3 has 2-dimensional irreducible representations, and by
    Weyl's law their share of the spectrum is fixed: 1/2 for C4v (a square table), 2/3 for C3 and
    D3, about 0.8 for D5h. A mirror-symmetric or asymmetric shape only has accidental near-pairs
    (``eigen_bands`` merges gaps below 0.3 of the local spacing), well below 0.45 on the benchmark
    meshes (``docs/notes/2026-11-detector-parameters.md``), except two weakly coupled identical parts
    (a pair of glasses), which the group path then answers with its mirror.
    """
    return (min if both else max)(multiplicity_shares(evals, k)) >= min_share


def multiplicity_shares(evals: Tensor, k: int = 20) -> tuple[float, float]:
    """The shares of the non-constant eigenvalues ``evals [K]`` in bands of size >= 2, in the coarse
    basis (``k`` snapped to a band end) and in twice that (:func:`has_multiplicities`)."""
    bands = solved_bands(evals)

    def share(kk: int) -> float:
        b0 = [b for b in _coarse_bands(bands, kk)[0] if b.start > 0]
        n = sum(len(b) for b in b0)
        return sum(len(b) for b in b0 if len(b) >= 2) / max(n, 1)

    return share(k), share(2 * k)
