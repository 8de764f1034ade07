"""Result types of symmetry detection: the elements, the result, and each path's diagnostics."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any, NamedTuple

import torch
from torch import Tensor

from ..groups.naming import GroupInfo
from ..spectrum import BAND_REL_GAP, Spectrum

__all__ = ["Symmetry", "SymmetryResult", "Diagnostics", "ReflectionDiagnostics", "GroupDiagnostics",
           "Checks", "Trial"]


@dataclass(frozen=True)
class Symmetry:
    """One detected symmetry.

    Attributes:
        fmap: [K, K] block-orthogonal pull-back matrix, ``evecs[p2p] ≈ evecs @ fmap`` (ALGORITHM §2).
        p2p: [V] long, ``p2p[i]`` is the image of vertex ``i``.
        kind: 'identity' | 'reflection' | 'rotation' | 'rotoreflection'.
        order: smallest n with ``g^n = e`` (from the group table).
        score: ``exp(-distortion^2)`` in [0, 1], the geodesic distortion of the map; higher is
            better. It measures how isometric the map is, not whether it is the right symmetry.
        confidence: in [0, 1], whose ranking separates right maps from wrong ones (a reflection:
            :func:`~symtorch.detect.confidence.reflection_confidence`); None on construction: the
            ``score``. The identity's is 1.
        uncertain: the confidence is below the detector's ``DetectConfig.min_confidence``.
    """

    fmap: Tensor
    p2p: Tensor
    kind: str
    order: int
    score: float
    confidence: float | None = None
    uncertain: bool = False

    def __post_init__(self):
        if self.confidence is None:  # frozen: set through object's own setter
            object.__setattr__(self, "confidence", float(self.score))

    @property
    def C(self) -> Tensor:
        """``fmap`` under its mathematical name (kept for code written before the rename)."""
        return self.fmap


# ------------------------------------------------------------------------------------ diagnostics
class Trial(NamedTuple):
    """One candidate of the reflection path's selection, upsampled and measured."""

    vote: float        # orientation vote of its map on the vote samples, in [-1, 1]
    distortion: float  # geodesic distortion on the selection samples (inf: not measured)


class Checks(NamedTuple):
    """The verification of one refined reflection (thresholds in ``ReflectionConfig``)."""

    score: float             # exp(-distortion^2)
    distortion: float        # mean geodesic distortion, EPS_KLC units
    worst_distortion: float  # largest per-sample mean distortion, local errors of the map aside
    orientation: float       # orientation vote of the dense map (-1: reverses everywhere)
    descriptor_gap: float    # how much the map changes the descriptors
    accepted: bool
    involution_error: float = math.nan  # mean d(s, g(g(s))) over the samples, EPS_KLC units
    local_errors: int = 0    # samples left out of worst_distortion (verification.local_errors)

    def to_dict(self) -> dict[str, float]:
        return {"distortion": self.distortion, "worst_distortion": self.worst_distortion,
                "orientation": self.orientation, "descriptor_gap": self.descriptor_gap,
                "involution_error": self.involution_error, "local_errors": self.local_errors}


@dataclass(frozen=True)
class ReflectionDiagnostics:
    """What the reflection path saw and decided.

    Attributes:
        n_extrema: heat-kernel extrema kept; n_seeds: seed pair-sets; n_candidates: distinct
            involutive permutations of the extrema.
        k0: coarse basis sizes the upsampling started from; k_refine: the final basis size.
        candidate_scores: consistency scores of the first candidates (EPS_KLC units, best first).
        trials: one per candidate and start compared; chosen: (candidate, start) reported.
        finalists: the (candidate, start) pairs refined and verified to choose it (the
            selection's winner first; ``ReflectionConfig.final_ratio``).
        checks: the verification of the refined map.
        guided_trials, guided_chosen, guided: the same for the guided second selection, where the
            first one verified nothing (else empty / None).
        second_chosen: where the first selection verified and ``second_opinion`` is on, the
            candidate the guided selection would have chosen.
        agreement: (share within one, share within two EPS_KLC) of the vote samples on which the
            reported map and the other selection's map agree (``reflection.map_agreement``);
            None: no second selection ran.
    """

    n_extrema: int
    n_seeds: int
    n_candidates: int
    k0: list[int]
    k_refine: int
    candidate_scores: list[float]
    trials: list[Trial] = field(default_factory=list)
    chosen: tuple[int, int] | None = None
    finalists: list[tuple[int, int]] = field(default_factory=list)
    checks: Checks | None = None
    guided_trials: list[Trial] = field(default_factory=list)
    guided_chosen: tuple[int, int] | None = None
    guided: Checks | None = None
    second_chosen: tuple[int, int] | None = None
    agreement: tuple[float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        out = {"n_extrema": self.n_extrema, "n_seeds": self.n_seeds, "n_candidates": self.n_candidates,
               "k0": list(self.k0), "k_refine": self.k_refine,
               "candidate_scores": list(self.candidate_scores)}
        if self.chosen is not None:
            out.update(trials=[tuple(t) for t in self.trials], chosen=self.chosen,
                       finalists=[tuple(f) for f in self.finalists])
        if self.checks is not None:
            out.update(self.checks.to_dict())
        if self.guided is not None:
            out.update(guided_trials=[tuple(t) for t in self.guided_trials],
                       guided_chosen=self.guided_chosen, guided=self.guided.to_dict())
        if self.second_chosen is not None:
            out["second_chosen"] = self.second_chosen
        if self.agreement is not None:
            out["agreement"] = list(self.agreement)
        return out


@dataclass(frozen=True)
class GroupDiagnostics:
    """What the group path saw and decided, stage by stage (None: the stage did not run).

    Attributes:
        k0, k_refine: coarse and refined basis sizes; m: largest band of the coarse basis;
            bands0: band sizes of the coarse basis; band_gap: the gap, in local spacings, above
            which the bands split (``GroupConfig.merged_gap`` where the merged bands were kept).
        n_points: invariant points; n_points_with_partner: those with a descriptor partner.
        continuous_test: the continuous-symmetry test's measurements.
        tuple_size, n_source_tuples: candidate tuples; n_candidates_before / n_candidates: ordered
            target tuples before / after pruning; n_candidates_kept: after the best-fit cut.
        n_clusters, cluster_sizes: mean shift.
        trace: (distortion, duplicate index or -1) per coarse element tried; n_verified: elements
            kept before closure; rejected_distortion: distortions of the rejected ones;
            n_after_closure: elements after closure.
        rejected_exact: exact distortions of the elements rejected after upsampling; dropped:
            elements left out of the largest closed subset; cayley_max_residual: largest residual of
            the matrices' table; distortion: per element of the result; near_symmetry_coset: the
            distortions of the orientation-reversing elements where they read as near-symmetries
            on near-exact rotations (:func:`~symtorch.detect.group_path.near_symmetry_coset`);
            level_changes: the share of the area whose heat level each element left out by
            :func:`~symtorch.detect.group_path.keep_heat_levels` changes.
        name, order: the group found; reason: why the trivial group was returned early;
            coarse_half_turn: where that was fewer coarse elements than asked for, whether they
            are the identity and one orientation-keeping map (a half turn: what a bend leaves of a
            chiral C_2n, :func:`~symtorch.detect.group_path.bend_remnant`).
    """

    k0: int
    k_refine: int
    m: int
    bands0: list[int]
    band_gap: float = BAND_REL_GAP
    n_points: int = 0
    continuous_test: dict | None = None
    n_points_with_partner: int | None = None
    tuple_size: int | None = None
    n_source_tuples: int | None = None
    n_candidates_before: int | None = None
    n_candidates: int | None = None
    n_candidates_kept: int | None = None
    n_clusters: int | None = None
    cluster_sizes: list[int] | None = None
    trace: list[tuple[float, int]] | None = None
    n_verified: int | None = None
    rejected_distortion: list[float] | None = None
    n_after_closure: int | None = None
    rejected_exact: list[float] | None = None
    dropped: list[int] | None = None
    near_symmetry_coset: list[float] | None = None
    level_changes: list[float] | None = None
    cayley_max_residual: float | None = None
    distortion: list[float] | None = None
    name: str = "C1"
    order: int = 1
    reason: str | None = None
    coarse_half_turn: bool | None = None

    def to_dict(self) -> dict[str, Any]:
        out = {"path": "group"}
        out.update((k, v) for k, v in asdict(self).items()
                   if v is not None and k not in ("name", "order"))
        return out


@dataclass(frozen=True)
class Diagnostics:
    """Diagnostics of a detection: which path's result was kept, and what each path that ran saw.

    Attributes:
        path: ``'reflection'`` or ``'group'``, the path whose result was kept.
        reflection: the reflection path's record, where it ran.
        group: the group path's record, where it ran.
    """

    path: str
    reflection: ReflectionDiagnostics | None = None
    group: GroupDiagnostics | None = None

    def to_dict(self) -> dict[str, Any]:
        """The kept path's record as a plain dict; where the group path ran but the reflection
        path's result was kept, ``"group_path"`` says what the group path found."""
        if self.path == "group":
            return self.group.to_dict() if self.group is not None else {"path": "group"}
        out = self.reflection.to_dict() if self.reflection is not None else {}
        if self.group is not None:
            out["group_path"] = {"name": self.group.name, "order": self.group.order}
            if self.group.reason is not None:
                out["group_path"]["reason"] = self.group.reason
        return out


# ------------------------------------------------------------------------------------------ result
@dataclass(frozen=True)
class SymmetryResult:
    """Every symmetry found on one shape, identity first, then in the group's reading order.

    Attributes:
        symmetries: the group elements; each ``fmap`` is [K, K] in the first K eigenfunctions of
            ``spectrum``, whichever path found it.
        spectrum: the spectrum the detection ran on (``evecs [V, K']``, K' >= K).
        bands: eigenvalue bands of the basis (index ranges covering ``0..K-1``).
        group: table, inverses, orders, orientation and name (``GroupInfo``).
        continuous: True when the shape has a continuous symmetry (then ``symmetries`` is the identity).
        timings: seconds per stage, in the order they ran.
        diagnostics: what each path saw and decided.
        input: ``'mesh'`` or ``'point_cloud'``, what the detection ran on.
        min_confidence: the threshold the elements' ``uncertain`` flags were set with (None: not set).
    """

    symmetries: list[Symmetry]
    spectrum: Spectrum
    bands: list[range]
    group: GroupInfo
    continuous: bool = False
    timings: dict[str, float] = field(default_factory=dict)
    diagnostics: Diagnostics | None = None
    input: str = "mesh"
    min_confidence: float | None = None

    def to(self, device: torch.device | str) -> SymmetryResult:
        """The result with its matrices, maps, spectrum and group tables on ``device`` (itself when
        already there)."""
        device = torch.empty(0, device=device).device  # 'cuda' -> 'cuda:0', as tensors report it
        tensors = [self.spectrum.evecs] + [t for s in self.symmetries for t in (s.fmap, s.p2p)]
        if all(t.device == device for t in tensors) and self.group.table.device == device:
            return self
        return replace(self, spectrum=self.spectrum.to(device), group=self.group.to(device),
                       symmetries=[replace(s, fmap=s.fmap.to(device), p2p=s.p2p.to(device))
                                   for s in self.symmetries])

    @property
    def fmaps(self) -> Tensor:
        """[G, K, K] the matrices, identity first."""
        return torch.stack([s.fmap for s in self.symmetries])

    @property
    def p2ps(self) -> Tensor:
        """[G, V] the vertex maps, identity first."""
        return torch.stack([s.p2p for s in self.symmetries])

    @property
    def reflection(self) -> Symmetry | None:
        """The best orientation-reversing involution, if any."""
        return next((s for s in self.symmetries if s.kind == "reflection"), None)

    @property
    def confidences(self) -> Tensor:
        """[G] each element's confidence, identity first (float64)."""
        return torch.tensor([float(s.confidence) for s in self.symmetries], dtype=torch.float64)

    @property
    def uncertain(self) -> bool:
        """Some element other than the identity is uncertain."""
        return any(s.uncertain for s in self.symmetries)

    @property
    def info(self) -> dict[str, Any]:
        """``diagnostics.to_dict()``: the diagnostics as the plain dict of earlier versions."""
        return self.diagnostics.to_dict() if self.diagnostics is not None else {}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no matrices): the schema of ``symtorch detect``.

        ``symmetries[i]`` is group element ``i``: the indices of ``group["table"]``,
        ``group["inverses"]`` and ``group["orders"]`` refer to it, and it carries its ``kind``, ``order``,
        ``score``, ``confidence``, ``uncertain`` flag and vertex map ``p2p``; the top-level
        ``uncertain`` says whether any element is, ``min_confidence`` the threshold. ``group["elements"]`` repeats, per element, its kind, order,
        inverse and orientation next to the table; ``group["table_paper"]`` is the table in the layout
        of the paper's Table 3 (``table.T``: entry (i, j) is "g_i, then g_j").
        """
        group = self.group.to_dict()
        inv, rev = group["inverses"], group["reversing"]
        group["table_paper"] = [list(col) for col in zip(*group["table"])]
        group["elements"] = [
            {"index": i, "kind": s.kind, "order": s.order, "score": round(float(s.score), 6),
             "confidence": round(float(s.confidence), 6), "uncertain": bool(s.uncertain),
             **({"inverse": inv[i]} if i < len(inv) else {}),
             **({"reversing": bool(rev[i])} if i < len(rev) else {})}
            for i, s in enumerate(self.symmetries)]
        return {
            "input": self.input,
            "n_vertices": int(self.spectrum.evecs.shape[0]),
            "k": int(self.symmetries[0].fmap.shape[-1]),
            "bands": [[b.start, b.stop] for b in self.bands],
            "continuous": self.continuous,
            "uncertain": self.uncertain,
            "min_confidence": self.min_confidence,
            "symmetries": [{"kind": s.kind, "order": s.order, "score": round(float(s.score), 6),
                            "confidence": round(float(s.confidence), 6), "uncertain": bool(s.uncertain),
                            "p2p": s.p2p.tolist()} for s in self.symmetries],
            "group": group,
            "timings": {k: round(v, 4) for k, v in self.timings.items()},
        }
