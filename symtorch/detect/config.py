"""The knobs of symmetry detection, one frozen dataclass per path.

:class:`ReflectionConfig` tunes the reflection path (:mod:`.reflection`), :class:`GroupConfig` the
group path (:mod:`.group_path`) and :class:`DetectConfig` the automatic policy of
:func:`~symtorch.detect.detect_symmetries`, which also sets the two basis sizes both paths work in.
The defaults are the settings the benchmarks in ``BENCHMARKS.md`` were run with. Lengths are in
units of the KLC radius ``EPS_KLC`` of the unit-area shape; distortions likewise.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

__all__ = ["ReflectionConfig", "GroupConfig", "DetectConfig", "LEGACY_REFLECTION_KEYWORDS",
           "DETECTOR_REVISION"]

#: Raised whenever the default detection's results change (a new stage, a new default): it is part
#: of the cache key of ``symtorch.data.DetectSymmetries``, so that symmetries cached by an earlier
#: detector are recomputed rather than trusted. 2: the final comparison of the selection's near-ties;
#: 3: the orientation-reversing functional-map candidate; 4: the group path's alternative elements;
#: 5: the verification sets local errors of the dense map aside (``ReflectionConfig.max_local_errors``).
DETECTOR_REVISION = 5


@dataclass(frozen=True)
class ReflectionConfig:
    """Knobs of the reflection path (ALGORITHM §4); the stages are in :mod:`.reflection`.

    Attributes:
        n_extrema: most heat-kernel extrema used as candidate points.
        nms_radius: no two extrema closer than this (geodesic, in EPS_KLC).
        n_candidates: candidate involutions upsampled and compared.
        k_select: basis size the candidates are compared in (snapped to a band end).
        block_refine: keep every upsampling step block-orthogonal (else band-wise only at the end).
        prune_k: each candidate's upsampling stops at this basis size (a band end) to vote;
            0: no stop.
        prune_vote: a candidate whose vote there exceeds this already preserves the orientation
            and is not grown further.
        select_vote: candidates voting below ``-select_vote`` are compared by geodesic distortion
            on ``n_select_verify`` samples, the others by their vote alone.
        n_select_verify: samples of the selection's distortion measure.
        early_vote, early_distortion: stop comparing once a candidate votes below ``-early_vote``
            with a distortion below ``early_distortion`` and the next candidate's consistency
            score exceeds ``compare_ratio`` times the first's.
        compare_ratio: see ``early_vote``; 0 stops at the first clear reflection, inf compares all.
        n_samples: vertices the refinement fits on (farthest-point samples).
        step_refine: smallest basis growth per step of the final upsampling.
        n_iter_all: final upsampling iterations fitted against every vertex (0: samples only).
        n_local: the dense vertex map searches each vertex's image among this many vertices near
            the image of its sample (``maps.TwoLevelSearch``); 0: among all vertices.
        n_verify: samples of the final verification.
        min_score: smallest confidence ``exp(-distortion^2)`` of a reported reflection.
        max_vote: a reported reflection's orientation vote is below ``-max_vote``.
        max_worst: and no sample's mean distortion exceeds this, local errors aside (a map right
            on most of the shape but wrong on one part is no symmetry).
        max_local_errors: at most this many of the worst verification samples may be set aside
            as local errors of the dense map (``verification.local_errors``: another image fits
            the other samples' distances and keeps the sample's descriptors; a point cloud's
            touching sheets pull a few points of a right map across); 0: none.
        local_error_z: the descriptor match of such an image (mean gap of the standardised
            log-descriptors, in column spreads).
        max_descriptor_gap: and the map changes the descriptors by less than this
            (``descriptor_gap``).
        final_ratio: every candidate whose selection distortion is within this factor of the
            lowest one is refined and verified to the end (stage **final**), not only the lowest;
            1: the lowest alone. The selection measures 16 samples in a medium basis, where two
            candidates that differ in one limb's pairing can measure within a few percent.
        final_vote_weight: among the verified finalists the reported one minimises its final
            distortion plus this weight times ``1 + vote`` (a reflection reverses the orientation
            everywhere, vote -1; a map with one limb mirrored onto itself reverses it in places).
        w_guide: weight of the orientation guide in the second selection, run only where the first
            one verifies nothing (0: no second selection).
        second_opinion: where the first selection's map verifies, run the guided selection too
            and measure how well its choice agrees with the map (``ReflectionDiagnostics.agreement``,
            a signal of :mod:`.confidence`); off, the confidence goes without it.
        verify: the final distortion measure: ``'involution'`` (``involution_distortion``, read off
            the samples' own distance fields) or ``'images'`` (``isometry_score``, one heat solve
            per sample image).
        fmap_candidate: also solve the orientation-reversing functional map of the shape onto
            itself (:mod:`.fmap_candidate`: descriptors, Laplacian and descriptor commutativity, the
            orientation term; no point pairs) and refine and verify it as one more finalist of the
            final stage; where the extrema give no candidate, it is the only one.
        fmap_k: its basis size (snapped to a band end).
        fmap_ratio: it is refined to the end only where, grown to ``k_select``, it reverses the
            orientation clearly and distorts by at most this factor times the selection's winner.
    """

    n_extrema: int = 12
    nms_radius: float = 2.0
    n_candidates: int = 8
    k_select: int = 30
    block_refine: bool = False
    prune_k: int = 14
    prune_vote: float = 0.3
    select_vote: float = 0.4
    n_select_verify: int = 16
    early_vote: float = 0.6
    early_distortion: float = 0.25
    compare_ratio: float = 2.0
    n_samples: int = 2000
    step_refine: int = 12
    n_iter_all: int = 0
    n_local: int = 64
    n_verify: int = 32
    min_score: float = 0.5
    max_vote: float = 0.2
    max_worst: float = 1.5
    max_local_errors: int = 2
    local_error_z: float = 3.0
    max_descriptor_gap: float = 0.4
    final_ratio: float = 1.15
    final_vote_weight: float = 0.5
    w_guide: float = 1.0
    second_opinion: bool = True
    verify: str = "involution"
    fmap_candidate: bool = True
    fmap_k: int = 20
    fmap_ratio: float = 1.5

    def __post_init__(self):
        if self.max_local_errors < 0:
            raise ValueError(f"max_local_errors must be at least 0, got {self.max_local_errors}")
        if self.verify not in ("involution", "images"):
            raise ValueError(f"verify must be 'involution' or 'images', got {self.verify!r}")


@dataclass(frozen=True)
class GroupConfig:
    """Knobs of the group path (ALGORITHM §5); the stages are in :mod:`.group_path`.

    Attributes:
        refine: ``'zoomout'`` (band-by-band upsampling, kept block-orthogonal) or ``'icp'``
            (fixed-size spectral ICP in the coarse basis).
        n_eigen: the group path cuts the spectrum at the band end nearest this many eigenpairs
            (its descriptors, and so the candidate pruning, then do not depend on the spectrum
            size it is given).
        n_points: most invariant points.
        n_sources: source tuples paired with every target tuple.
        delta: geodesic ratio threshold of the pruning.
        desc_tol: two points may correspond when their descriptor distance is at most this share
            of the median distance over all pairs of points.
        partner_radius: ... up to where each point sits within this many KLC radii (an extremum
            on a ridge moves along it under a near-isometry: ``candidates.descriptor_ratios``);
            0: the points' own descriptors only.
        max_candidates: most candidates kept for clustering (those whose Procrustes fit is best).
        n_icp: batched spectral ICP steps applied to every candidate before clustering (0: none).
        bandwidth: mean-shift kernel width (absolute Frobenius distance of the coarse matrices).
        max_modes: most clusters refined.
        n_samples: sample vertices for refinement and verification.
        max_distortion: an element whose geodesic distortion exceeds this is rejected.
        n_alternatives: per element, most coarse duplicates kept as alternatives (those whose maps
            differ from it by at least ``alternative_gap`` KLC radii on average); each is upsampled
            and measured exactly too, and the least distorted version kept (0: none).
        alternative_gap: mean image gap, in KLC radii, from which a duplicate is an alternative.
        near_miss_ratio, n_near_misses: at most this many candidates the coarse screen rejected
            by at most this ratio of ``max_distortion`` are measured exactly too (the coarse basis
            can distort what the refined one does not); 0: none.
        near_mirrors: where half of the group is a near-symmetry riding on a near-exact index-2
            subgroup (:func:`~symtorch.detect.group_path.near_symmetry_coset`: several times more
            distorted; most often the orientation-reversing half, a chiral shape's mirrors),
            ``'drop'`` reports the subgroup as the group (the half's distortions stay in
            ``diagnostics.group.near_symmetry_coset``); ``'keep'`` reports the whole group.
        merged_gap: where the group found leaves the spectrum's multiplicities unexplained (every
            element of order <= 2: ``group_path.unexplained_multiplicities``) or is what a bend
            leaves of a larger one (a half turn among involutions: ``group_path.bend_remnant``),
            the group path runs again in bands merged at this many local spacings, its maps refined as full orthogonal
            matrices (a bend splits the eigenspaces its rotations mix, and mixes eigenfunctions
            of different bands); the larger group is kept. 0: no second run.
        merged_desc_tol: ``desc_tol`` of that second run where the multiplicities asked for it:
            a bend moves the descriptors too (the tips of four arms bent at R = 4 differ by 1.6
            median distances from their partners').
        merged_relative_tol: ... and a pair is also admitted there within this share of the two
            points' own typical descriptor distances (``candidates.partner_mask``).
        merged_n_sources: ``n_sources`` of that second run where the multiplicities asked for it:
            a bend moves some extrema off their partners' images, and a source tuple holding one
            finds no target (four arms bent at R = 4 and elevation -17 degrees: C2v with 3
            tuples, C4v with 6).
        merged_max_missing: in that second run, a candidate target tuple may leave this many of
            its source points without a target where no point of the set extends it
            (``candidates.candidate_tuples``): a bend moves some extrema off their partners'
            images (0: every source point needs one). Measured on ``group_shapes_table.py``: at
            1, four arms drooping 17 degrees bent at R = 4 come out C4v for C2v, every other row
            and random draw as at 0, and the merged rows take 1.3-2 times as long.
        dipoles: weight of the dipole constraints (each tuple point's disk tilted towards the
            next, ``constraints.dipole_coefficients``) in a second solution of every candidate,
            kept where it differs from the disks' (``group_path.candidate_fmaps``); 0: none. They
            pin the bands that every mirror through the tuple points negates (a regular hexagonal
            prism: 6 of its 24 elements without them).
        persistence: the least height, as a share of its function's range, of the hill an
            invariant point tops for it to be in the first source tuple
            (``candidates.persistent_points``; where at least a tuple's worth qualify); 0: none
            singled out. A remeshed prism's flat
            caps put extrema of the finest HKS scale at no symmetric spot, a hundredth of the
            range high; with such points in every source tuple, half of its group was missed.
        max_level_change: the most of the area whose heat level an isometry may change
            (``verification.HeatLevels``): the continuous test's rotation (surfaces of revolution
            change at most 2 %, prisms and antiprisms of 6-9 sides whose rotation passes as
            near-isometric 5-30 %), and every element of the group (``group_path.keep_heat_levels``:
            true elements, bent and remeshed, at most 2 %; an S6 solid's near-D3d half turns 5 %,
            a square antiprism's eighth turns half the area); 1: neither bound.
    """

    refine: str = "zoomout"
    n_eigen: int = 60
    n_points: int = 40
    n_sources: int = 3
    delta: float = 0.9
    desc_tol: float = 0.6
    partner_radius: float = 0.25
    max_candidates: int = 400
    n_icp: int = 3
    bandwidth: float = 0.6
    max_modes: int = 64
    n_samples: int = 1000
    max_distortion: float = 0.25
    n_alternatives: int = 1
    alternative_gap: float = 0.1
    near_miss_ratio: float = 1.25
    n_near_misses: int = 4
    near_mirrors: str = "drop"
    merged_gap: float = 1.0
    merged_desc_tol: float = 1.2
    merged_relative_tol: float = 0.5
    merged_n_sources: int = 6
    merged_max_missing: int = 1
    dipoles: float = 1.0
    persistence: float = 0.05
    max_level_change: float = 0.03

    def __post_init__(self):
        if self.refine not in ("zoomout", "icp"):
            raise ValueError(f"refine must be 'zoomout' or 'icp', got {self.refine!r}")
        if self.near_mirrors not in ("drop", "keep"):
            raise ValueError(f"near_mirrors must be 'drop' or 'keep', got {self.near_mirrors!r}")
        if self.dipoles < 0:
            raise ValueError(f"dipoles must be at least 0, got {self.dipoles!r}")
        if not 0 <= self.persistence < 1:
            raise ValueError(f"persistence must be in [0, 1), got {self.persistence!r}")
        if not 0 < self.max_level_change <= 1:
            raise ValueError(f"max_level_change must be in (0, 1], got {self.max_level_change!r}")
        if self.merged_gap < 0:
            raise ValueError(f"merged_gap must be at least 0, got {self.merged_gap!r}")
        if self.merged_relative_tol < 0:
            raise ValueError(f"merged_relative_tol must be at least 0, got {self.merged_relative_tol!r}")
        if self.merged_n_sources < 1:
            raise ValueError(f"merged_n_sources must be at least 1, got {self.merged_n_sources!r}")
        if self.merged_max_missing < 0:
            raise ValueError(f"merged_max_missing must be at least 0, got {self.merged_max_missing!r}")


# The keywords ``detect_symmetries`` took before ``config=`` existed, and the reflection-path field
# each one sets (``n_refine`` was the name of ``n_candidates`` there).
LEGACY_REFLECTION_KEYWORDS = {"n_samples": "n_samples", "block_refine": "block_refine",
                              "n_extrema": "n_extrema", "nms_radius": "nms_radius",
                              "min_score": "min_score", "n_refine": "n_candidates"}


@dataclass(frozen=True)
class DetectConfig:
    """Knobs of :func:`~symtorch.detect.detect_symmetries`: basis sizes, the policy, each path's config.

    Attributes:
        k: target size of the coarse basis the candidates are solved in (snapped to a band end),
            or several sizes (the reflection path tries each per candidate).
        k_refine: target size of the refined basis; the result's matrices live in it, whichever
            path found them.
        group_k: the group path's coarse basis is ``max(k, group_k)``.
        group_k_refine: the group path refines its elements to ``min(k_refine, group_k_refine)``
            (one refinement per element: the cost grows with the group); their matrices are then
            expressed in the ``k_refine`` basis from their vertex maps.
        group_tol: where the reflection path finds at least three involutive permutations of its
            extrema with consistency scores below this (a C2v or D2h shape, whose spectrum is
            simple), the group path runs too; 0 disables that second opinion.
        cloud_min_cos: point clouds: the Laplacian and the heat method run on the local
            triangle fans (``point_cloud.local_triangles``) without the triangles whose corner
            normals disagree, some cosine below this (fans bridging two sheets that touch); None:
            on the point cloud as it is (``robust_laplacian.point_cloud_laplacian``,
            ``potpourri3d.PointCloudHeatSolver``), bridges included.
        min_confidence: a reported symmetry whose confidence (``Symmetry.confidence``,
            :mod:`.confidence`) is below this is marked ``uncertain``. Chosen on SCAPE and TOSCA
            (``scripts/confidence_stats.py``): the centre of the range of thresholds that flag the
            same maps there; FAUST and TOSCA_Isometric were held out.
        geodesics: the heat-method backend of the detection's distances
            (:class:`~symtorch.geodesics.GeodesicSolver` ``backend``): ``"batched"``, a block of
            sources per solve on the mesh's cotan operators, or ``"potpourri3d"`` (its robust
            intrinsic-Delaunay solver, one source at a time). Point clouds always use potpourri3d.
        reflection: the reflection path's knobs.
        group: the group path's knobs.
    """

    k: int | tuple[int, ...] = 6
    k_refine: int = 100
    group_k: int = 20
    group_k_refine: int = 40
    group_tol: float = 0.06
    cloud_min_cos: float | None = 0.0
    min_confidence: float = 0.37
    geodesics: str = "batched"
    reflection: ReflectionConfig = field(default_factory=ReflectionConfig)
    group: GroupConfig = field(default_factory=GroupConfig)

    @property
    def group_basis(self) -> tuple[int, int]:
        """(coarse, refined) target sizes of the group path."""
        k = max(self.k) if isinstance(self.k, (tuple, list)) else self.k
        return max(k, self.group_k), min(self.k_refine, self.group_k_refine)

    def with_keywords(self, **keywords) -> DetectConfig:
        """This config with keyword shortcuts applied: any field of DetectConfig, or one of the
        legacy reflection keywords (``n_samples``, ``block_refine``, ``n_extrema``,
        ``nms_radius``, ``min_score``, ``n_refine``).

        Raises:
            TypeError: an unknown keyword.
        """
        own = {f.name for f in fields(self)}
        top = {k: v for k, v in keywords.items() if k in own}
        refl = {LEGACY_REFLECTION_KEYWORDS[k]: v for k, v in keywords.items()
                if k in LEGACY_REFLECTION_KEYWORDS}
        unknown = sorted(set(keywords) - own - set(LEGACY_REFLECTION_KEYWORDS))
        if unknown:
            raise TypeError(f"detect_symmetries() got unexpected keyword(s) {', '.join(unknown)}; "
                            f"knobs: {', '.join(sorted(own | set(LEGACY_REFLECTION_KEYWORDS)))}")
        if "n_candidates" in refl:
            refl["n_candidates"] = max(int(refl["n_candidates"]), 1)
        out = replace(self, **top)
        return replace(out, reflection=replace(out.reflection, **refl)) if refl else out
