"""The automatic policy of symmetry detection: which path to run, and which result to keep.

Two paths find symmetries (``docs/method.md``): the reflection path (ALGORITHM §4,
:mod:`.reflection`) looks for one intrinsic mirror; the group path (§5, :mod:`.group_path`) for a
whole finite group, or a continuous symmetry. :func:`detect_symmetries` chooses:

1. **spectrum**: the Laplace-Beltrami eigenpairs, unless given.
2. **group first** where the low spectrum has repeated eigenvalues at more than one scale
   (``has_multiplicities``: rotations of order >= 3 make 2-dimensional eigenspaces all the way
   up); its result is kept when it is a continuous symmetry or a group of order > 2.
3. **reflection** otherwise (and after a group path that found at most a mirror).
4. **second opinion**: where the spectrum is simple but the reflection path verified no
   reflection (a lone half turn), or its reflection came from the functional-map candidate alone
   (a box whose heat-kernel extrema are too few to pair), or it found at
   least three equally consistent involutions of its extrema (a C2v or D2h shape: all its
   irreducible representations are 1-D, so its spectrum is simple), or the spectrum is dominated
   by pairs at one of the two scales only (a bend splits a chiral C4's pairs of the larger basis,
   and a near-mirror passes the reflection path), the group path runs too, asked for a group
   larger than the reflection path's.
5. **keep** the larger verified group (the reflection path's on a tie), with every element's
   matrix expressed in the ``k_refine`` basis whichever path found it.
"""
from __future__ import annotations

import logging
import time
import warnings
from dataclasses import replace

import numpy as np
import torch

from .._checks import check_mesh
from ..geodesics import GeodesicSolver
from ..maps import p2p_to_fmap
from ..point_cloud import (check_point_cloud, fan_spectrum, local_triangles, local_triangulation,
                           oriented_normals)
from ..procrustes import block_project
from ..sampling import count_components
from ..spectrum import Spectrum, band_boundary, full_bands, laplacian_spectrum, solved_bands
from ..threads import bounded_threads
from .config import DetectConfig
from .result import Diagnostics, SymmetryResult

log = logging.getLogger(__name__)

__all__ = ["detect_symmetries", "in_basis", "cloud_surface", "mark_uncertain"]

MODES = ("auto", "reflection", "group")


class _Timer:
    """Seconds per named stage: ``lap(name)`` charges the time since the last lap to ``name``."""

    def __init__(self):
        self.t = time.perf_counter()
        self.timings: dict[str, float] = {}

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.timings[name] = self.timings.get(name, 0.0) + now - self.t
        self.t = now


@bounded_threads  # the torch and BLAS pools capped at the free cores for the whole detection
def detect_symmetries(shape, faces=None, *, mode: str = "auto", spectrum: Spectrum | None = None,
                      device: torch.device | str | None = None, config: DetectConfig | None = None,
                      **knobs) -> SymmetryResult:
    """Find the global intrinsic symmetries of a triangle mesh or point cloud (see the module docstring).

    Args:
        shape: [V, 3] vertices (numpy or torch), or a ``symtorch.io.Mesh``.
        faces: [F, 3] triangles, or None for a point cloud. A point cloud's Laplacian and heat
            method run on its local triangle fans, those bridging two touching sheets dropped
            (``robust_laplacian``'s point-cloud construction; ``config.cloud_min_cos=None``: the
            point-cloud tools as they are, ``robust_laplacian.point_cloud_laplacian`` and
            ``potpourri3d.PointCloudHeatSolver``), and what the paths take from faces (neighbours,
            orientation, gradients) comes from its oriented local triangulation
            (:func:`cloud_surface`, ``symtorch.point_cloud``).
        mode: ``'reflection'`` (ALGORITHM §4), ``'group'`` (§5) or ``'auto'`` (the policy above).
        spectrum: a precomputed ``laplacian_spectrum(verts, faces, k)``. Without one,
            ``max(k_refine + 10, 60)`` eigenpairs are solved: the bands up to ``k_refine`` complete,
            and at least 60 for the group path's descriptors.
        device: where the group path's batched candidate stages run (block Procrustes over all
            candidate tuples, batched ICP, mean shift); default the spectrum's device. The mesh
            geometry (heat-method geodesics, Dijkstra, k-d trees) and the refinement run on the CPU
            in float64 whatever the device.
        config: the knobs (``DetectConfig``; default the benchmarked settings).
        **knobs: shortcuts for ``config`` fields: ``k``, ``k_refine``, ``group_tol``, ... (any field
            of ``DetectConfig``), and the reflection-path keywords of earlier versions
            (``n_samples``, ``min_score``, ``n_extrema``, ``nms_radius``, ``block_refine``,
            ``n_refine``); ``detect_symmetries(mesh, k_refine=40)`` is
            ``detect_symmetries(mesh, config=DetectConfig(k_refine=40))``.

    Returns:
        SymmetryResult, identity first; ``fmaps`` is ``[G, K, K]`` with ``K`` the band end nearest
        ``k_refine``, whichever path found the elements. Its tensors are on the device of the
        ``spectrum`` passed in (CPU without one), in its dtype.

    Raises:
        ValueError: several connected components, bad mesh input; for a point cloud, fewer than
            ``point_cloud.MIN_POINTS`` points, NaN coordinates, duplicated points, several parts.
        TypeError: an unknown keyword.
    """
    cfg = (DetectConfig() if config is None else config).with_keywords(**knobs)
    timer = _Timer()
    if mode not in MODES:
        raise ValueError(f"mode must be 'auto', 'reflection' or 'group', got {mode!r}")
    verts, faces = _shape_inputs(shape, faces)
    cloud = faces is None
    surface = faces  # what the Laplacian and the heat method run on: the mesh, fans, or the cloud
    if cloud:
        faces, surface = cloud_surface(verts, cfg.cloud_min_cos)
        timer.lap("triangulation")
    if spectrum is None:
        k = max(cfg.k_refine + 10, 60)
        spectrum = fan_spectrum(verts, surface, k) if cloud and surface is not None \
            else laplacian_spectrum(verts, surface, k=k)
    elif spectrum.evecs.shape[0] != len(verts):
        raise ValueError(f"spectrum has {spectrum.evecs.shape[0]} vertices but the shape has "
                         f"{len(verts)}")
    out_device = spectrum.evecs.device
    batch_device = torch.device(device) if device is not None else out_device
    spectrum = spectrum.to("cpu")  # the geometry is solved on the host; the result goes back
    timer.lap("spectrum")
    # one factorisation for both paths (the timer counts it in the first path's first stage)
    solver = GeodesicSolver(np.asarray(verts, dtype=np.float64) * spectrum.scale, surface,
                            backend=cfg.geodesics)
    result = _run_policy(verts, faces, spectrum, mode, cfg, solver, timer, batch_device)
    result = in_basis(result, spectrum, band_boundary(solved_bands(spectrum.evals), cfg.k_refine))
    result = mark_uncertain(result, cfg.min_confidence)
    return replace(result, timings=dict(timer.timings),
                   input="point_cloud" if cloud else "mesh").to(out_device)


def _run_policy(verts, faces, spectrum: Spectrum, mode: str, cfg: DetectConfig, solver: GeodesicSolver,
                timer: _Timer, batch_device: torch.device) -> SymmetryResult:
    """Steps 2-5 of the module docstring: the kept result, with every path's diagnostics."""
    from .group_path import detect_group, has_multiplicities  # imported here: tests patch them
    from .reflection import detect_reflection

    k_group, k_refine_group = cfg.group_basis

    def group_path(min_order: int = 1) -> SymmetryResult:
        return detect_group(verts, faces, spectrum, k=k_group, k_refine=k_refine_group, config=cfg.group,
                            device=batch_device, solver=solver, min_order=min_order, timer=timer)

    grouped = None
    if mode == "group" or (mode == "auto" and has_multiplicities(spectrum.evals, k_group)):
        grouped = group_path()
        if mode == "group" or grouped.continuous or grouped.group.order > 2:
            return grouped
    reflected = detect_reflection(verts, faces, spectrum, k=cfg.k, k_refine=cfg.k_refine,
                                  config=cfg.reflection, solver=solver, timer=timer)
    # no reflection, or one from the functional-map candidate alone (the extrema paired nothing:
    # too few of them, as on a box), or several near-equal involutions, or pairs at one scale:
    # the group path too
    if mode == "auto" and grouped is None and (len(reflected.symmetries) == 1
                                               or not reflected.diagnostics.reflection.n_candidates
                                               or _several_involutions(reflected, cfg.group_tol)
                                               or has_multiplicities(spectrum.evals, k_group, both=False)):
        with warnings.catch_warnings():  # a second opinion: its closure notes are not the user's concern
            warnings.simplefilter("ignore")
            # only a group larger than the reflection path's can replace its result
            grouped = group_path(min_order=reflected.group.order + 1)
    kept = grouped if grouped is not None and grouped.group.order > reflected.group.order else reflected
    both = Diagnostics("group" if kept is grouped else "reflection",
                       reflection=reflected.diagnostics.reflection,
                       group=grouped.diagnostics.group if grouped is not None else None)
    return replace(kept, diagnostics=both)


def _shape_inputs(shape, faces):
    """(verts [V, 3] float64, faces [F, 3] or None for a point cloud): checked, rescaled near 1."""
    if isinstance(shape, Spectrum):
        raise ValueError("pass verts and faces with spectrum=...; detection needs the geometry")
    if hasattr(shape, "verts"):  # symtorch.io.Mesh
        shape, faces = shape.verts, shape.faces
    verts, faces = (check_point_cloud(shape), None) if faces is None else check_mesh(shape, faces)
    from ..spectrum import _exact_rescale

    c = _exact_rescale(np.asarray(verts.detach().cpu() if torch.is_tensor(verts) else verts,
                                  dtype=np.float64))
    if c != 1.0:  # coordinates far from 1 (areas of 1e-150 underflow): a power of two is exact and
        verts = verts * c  # changes no map; the geometry code (geodesics, tolerances) needs it
    n_parts = 1 if faces is None else count_components(faces, len(verts))
    if n_parts > 1:
        raise ValueError(f"mesh has {n_parts} connected components; symmetry detection needs one "
                         "connected surface (detect each part on its own, or merge seam duplicates)")
    return verts, faces


def cloud_surface(points: np.ndarray, min_cos: float | None) -> tuple[np.ndarray, np.ndarray | None]:
    """What a point cloud's detection runs on: (faces [F, 3], surface [T, 3] or None).

    ``faces`` stand in for a mesh's in the paths (neighbours, orientation votes, gradients): the
    local triangulation, oriented (``point_cloud.local_triangulation``). ``surface`` is what the
    Laplacian and the heat method run on: the fans without their bridging triangles
    (``point_cloud.local_triangles(min_cos)``), or None (``min_cos=None``) for the point cloud itself.

    Raises:
        ValueError: the points form several separate parts.
    """
    normals = oriented_normals(points)
    fans = local_triangles(points, normals, min_cos)
    faces = local_triangulation(points, normals, fans)
    n_parts = count_components(faces, len(points))
    if n_parts > 1:
        raise ValueError(f"point cloud has {n_parts} separate parts (no local triangle joins them); "
                         "symmetry detection needs one connected surface (detect each part on its "
                         "own, or remove outlying points)")
    return faces, None if min_cos is None else fans


def _several_involutions(reflected: SymmetryResult, tol: float) -> bool:
    """At least three involutive extrema permutations as consistent as ``tol`` (KLC units)."""
    scores = reflected.diagnostics.reflection.candidate_scores
    return tol > 0 and len(scores) >= 3 and scores[2] < tol


def mark_uncertain(result: SymmetryResult, min_confidence: float) -> SymmetryResult:
    """The result with each element's ``uncertain`` flag set: its confidence is below
    ``min_confidence`` (the identity never is)."""
    symmetries = [replace(s, uncertain=s.kind != "identity" and float(s.confidence) < min_confidence)
                  for s in result.symmetries]
    return replace(result, symmetries=symmetries, min_confidence=float(min_confidence))


def in_basis(result: SymmetryResult, spectrum: Spectrum, K: int) -> SymmetryResult:
    """The result with every element's matrix in the first ``K`` eigenfunctions of ``spectrum``.

    The group path refines its elements in a smaller basis than the reflection path (one refinement
    per element); an element whose matrix has another size gets the block-projected pull-back of its
    vertex map (``p2p_to_fmap``, ``block_project``), the identity the identity. The maps are unchanged.
    Where the result's matrices are full orthogonal ones (``result.bands`` is
    :func:`~symtorch.spectrum.full_bands`: the group path's merged attempt, a near-isometry that
    mixes eigenfunctions of different bands), they stay so.
    """
    full = result.bands == full_bands(result.bands[-1].stop)
    bands = full_bands(K) if full else [b for b in solved_bands(spectrum.evals) if b.stop <= K]
    evecs = spectrum.evecs[:, :K]
    symmetries = []
    for s in result.symmetries:
        if s.fmap.shape[-1] != K:
            fmap = torch.eye(K, dtype=evecs.dtype) if s.kind == "identity" \
                else block_project(p2p_to_fmap(s.p2p, evecs, spectrum.mass), bands)
            s = replace(s, fmap=fmap)
        symmetries.append(s)
    return replace(result, symmetries=symmetries, spectrum=spectrum, bands=bands)
