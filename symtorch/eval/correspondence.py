"""Geodesic error of shape correspondences, with the protocol of the shape-matching field.

The protocol of ULRSSM, DUO-FM, AttentiveFMaps and earlier deep functional-map papers (FAUST_r,
SCAPE_r, SHREC'19_r, TOSCA): two shapes x and y name the same template points, ``corr_x[k]`` and
``corr_y[k]``. A predicted map ``p2p_yx`` (for each vertex of y, its image on x) is scored at each
template point k by

    error_k = d_x(p2p_yx[corr_y[k]], corr_x[k]) / sqrt(area_x),

the geodesic distance on x between the predicted and the true image, divided by the square root of
x's area (scale free). Where x also has ``corr_sym_x`` (the vertex of the mirror image of each template
point) the same error is taken against it: a map that sends left to right scores well against the
symmetric ground truth, and is reported as *flipped*. Distances come from a geodesic matrix when
given (``root/dist/<name>.mat``), else from the heat method (:class:`~symtorch.geodesics.GeodesicSolver`)
from the true images, cached per shape.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from .._checks import check_mesh, face_areas
from ..geodesics import GeodesicSolver
from .metrics import evenly_spaced

__all__ = ["ShapeDistances", "PairScore", "CorrespondenceScore", "pair_score",
           "summarize_pairs", "CorrespondenceEvaluator"]


class ShapeDistances:
    """Geodesic distances on one shape: rows of a stored matrix, or heat-method fields on demand.

    Args:
        verts: [V, 3] vertex positions, in the units of the distances.
        faces: [F, 3] triangles.
        dist: [V, V] geodesic matrix in the units of ``verts``; None: solved with
            :class:`~symtorch.geodesics.GeodesicSolver` when first needed (its factorisation and up to
            64 MB of fields are kept).
    """

    def __init__(self, verts, faces, dist: Tensor | None = None):
        v, f = check_mesh(verts, faces)
        self._verts, self._faces = v, f
        self.n_verts = v.shape[0]
        self.area = float(face_areas(v, f).sum())
        if dist is not None:
            dist = torch.as_tensor(dist)
            if dist.shape != (self.n_verts, self.n_verts):
                raise ValueError(f"dist must be [V, V] = [{self.n_verts}, {self.n_verts}], got "
                                 f"{list(dist.shape)}")
        self.dist = dist
        self._solver: GeodesicSolver | None = None

    def rows(self, sources: Tensor) -> Tensor:
        """[S, V] float64 distances from each of ``sources`` ([S] vertex ids) to every vertex."""
        sources = torch.as_tensor(sources).long().cpu()
        if self.dist is not None:
            return self.dist[sources].to(torch.float64)
        if self._solver is None:
            self._solver = GeodesicSolver(self._verts, self._faces)
        return self._solver.distances_from(sources.numpy()).to("cpu", torch.float64)


@dataclass(frozen=True)
class PairScore:
    """The errors of one predicted map ``p2p_yx`` of a pair (x, y).

    Attributes:
        points: [N] the template points scored.
        errors: [N] ``d_x(p2p_yx[corr_y[k]], corr_x[k]) / sqrt(area_x)``.
        errors_sym: [N] the same against the symmetric ground truth ``corr_sym_x[k]``, or None.
        mean: mean of ``errors``.
        mean_sym: mean of ``errors_sym`` (nan without symmetric ground truth).
        mean_up_to_symmetry: ``min(mean, mean_sym)`` (``mean`` without symmetric ground truth).
        flipped: the map is closer to the symmetric ground truth than to the truth
            (``mean_sym < mean``).
    """

    points: Tensor
    errors: Tensor
    errors_sym: Tensor | None
    mean: float
    mean_sym: float
    mean_up_to_symmetry: float
    flipped: bool


@dataclass(frozen=True)
class CorrespondenceScore:
    """Scores of many pairs and their means over the pairs.

    Attributes:
        pairs: the per-pair scores.
        mean: mean over pairs of ``PairScore.mean``.
        mean_sym: mean over pairs of ``PairScore.mean_sym`` (nan where no pair has symmetric truth).
        mean_up_to_symmetry: mean over pairs of ``PairScore.mean_up_to_symmetry``.
        flipped_share: share of the pairs with symmetric truth whose map is flipped (nan: none).
    """

    pairs: list[PairScore]
    mean: float
    mean_sym: float
    mean_up_to_symmetry: float
    flipped_share: float


def _ids(x, name: str) -> Tensor:
    t = torch.as_tensor(x)
    if t.dim() != 1 or t.is_floating_point():
        raise ValueError(f"{name} must be a 1-D tensor of vertex ids, got {list(t.shape)} {t.dtype}")
    return t.long().cpu()


def pair_score(p2p_yx: Tensor, corr_x: Tensor, corr_y: Tensor, dist_x: ShapeDistances, *,
               corr_sym_x: Tensor | None = None, points: Tensor | None = None,
               n_points: int | None = None) -> PairScore:
    """Geodesic errors of a predicted map at the template points (see the module docstring).

    Template points missing on either shape (-1 in ``corr_x``, ``corr_y`` or ``corr_sym_x``) are not
    scored.

    Args:
        p2p_yx: [V_y] long, the predicted image on x of each vertex of y.
        corr_x, corr_y: [N] long, the vertex of template point k on x and on y.
        dist_x: distances on x (:class:`ShapeDistances`).
        corr_sym_x: [N] long, the vertex of x mirroring template point k (symmetric ground truth).
        points: template point ids to score (default: all).
        n_points: score at most this many of them, evenly spaced (``symtorch.eval.evenly_spaced``).

    Returns:
        the pair's score.
    """
    p2p_yx, corr_x, corr_y = _ids(p2p_yx, "p2p_yx"), _ids(corr_x, "corr_x"), _ids(corr_y, "corr_y")
    if corr_x.shape != corr_y.shape:
        raise ValueError(f"corr_x and corr_y must name the same template points, got "
                         f"{corr_x.numel()} and {corr_y.numel()}")
    ok = (corr_x >= 0) & (corr_y >= 0)
    if corr_sym_x is not None:
        corr_sym_x = _ids(corr_sym_x, "corr_sym_x")
        if corr_sym_x.shape != corr_x.shape:
            raise ValueError(f"corr_sym_x has {corr_sym_x.numel()} template points, corr_x "
                             f"{corr_x.numel()}")
        ok &= corr_sym_x >= 0
    pts = torch.arange(corr_x.numel()) if points is None else _ids(points, "points")
    pts = pts[ok[pts]]
    if n_points is not None:
        pts = evenly_spaced(pts, n_points)
    if pts.numel() == 0:
        raise ValueError("no template point is present on both shapes")
    if int(corr_y[pts].max()) >= p2p_yx.numel():
        raise ValueError(f"corr_y names vertex {int(corr_y[pts].max())} but p2p_yx has "
                         f"{p2p_yx.numel()} entries")
    pred = p2p_yx[corr_y[pts]]
    if int(pred.min()) < 0 or int(pred.max()) >= dist_x.n_verts:
        raise ValueError(f"p2p_yx must map into [0, {dist_x.n_verts - 1}] (x's vertices), got values "
                         f"in [{int(pred.min())}, {int(pred.max())}]")
    norm = math.sqrt(dist_x.area)

    def errors(truth: Tensor) -> Tensor:
        # distances from the true images: each row is one heat solve, shared by repeated truths
        uniq, inv = torch.unique(truth, return_inverse=True)
        return dist_x.rows(uniq)[inv, pred] / norm

    err = errors(corr_x[pts])
    mean = float(err.mean())
    err_sym, mean_sym = None, math.nan
    if corr_sym_x is not None:
        err_sym = errors(corr_sym_x[pts])
        mean_sym = float(err_sym.mean())
    best = mean if err_sym is None else min(mean, mean_sym)
    return PairScore(pts, err, err_sym, mean, mean_sym, best, err_sym is not None and mean_sym < mean)


def summarize_pairs(scores: Sequence[PairScore]) -> CorrespondenceScore:
    """Means over pairs of the per-pair means, and the share of flipped maps."""
    scores = list(scores)
    if not scores:
        raise ValueError("summarize_pairs got no pair scores")
    with_sym = [s for s in scores if s.errors_sym is not None]
    mean_sym = float(np.mean([s.mean_sym for s in with_sym])) if with_sym else math.nan
    flipped = float(np.mean([s.flipped for s in with_sym])) if with_sym else math.nan
    return CorrespondenceScore(scores, float(np.mean([s.mean for s in scores])), mean_sym,
                               float(np.mean([s.mean_up_to_symmetry for s in scores])), flipped)


class CorrespondenceEvaluator:
    """Scores predicted maps on pairs of samples, keeping each shape's distances between pairs.

    Samples are those of :class:`~symtorch.data.MeshDataset` (``name``, ``verts``, ``faces``,
    ``corr`` and optionally ``corr_sym``, ``dist_path``, ``scale``). A shape's distances are built
    once per ``(name, V)``: from its geodesic matrix file (``dist_path``, in the units of the mesh
    file, multiplied by the sample's ``scale`` to match ``verts`` after
    :class:`~symtorch.data.NormalizeArea`) when ``use_dist_files``, else by the heat method.

    Args:
        n_points: score at most this many template points per pair, evenly spaced (None: all).
        use_dist_files: read ``dist_path`` matrices where samples name one.

    Example:
        >>> ev = CorrespondenceEvaluator(n_points=1000)
        >>> scores = [ev.score(model_p2p(item), item["x"], item["y"]) for item in PairDataset(ds)]
        >>> summarize_pairs(scores).mean_up_to_symmetry
    """

    def __init__(self, n_points: int | None = None, use_dist_files: bool = True):
        self.n_points, self.use_dist_files = n_points, use_dist_files
        self._shapes: dict[tuple[str, int], ShapeDistances] = {}

    def distances(self, sample: dict) -> ShapeDistances:
        """The (cached) distances on one sample's shape."""
        key = (str(sample.get("name", id(sample))), int(sample["verts"].shape[0]))
        if key not in self._shapes:
            dist = None
            if self.use_dist_files and sample.get("dist_path"):
                from ..data.layouts import read_geodesic_matrix

                dist = read_geodesic_matrix(sample["dist_path"], torch.float64)
                if "scale" in sample:
                    dist = dist * float(sample["scale"])
            self._shapes[key] = ShapeDistances(sample["verts"], sample["faces"], dist)
        return self._shapes[key]

    def score(self, p2p_yx: Tensor, x: dict, y: dict) -> PairScore:
        """Score ``p2p_yx`` ([V_y], image on x of each vertex of y) against the pair's ground truth."""
        for s, who in ((x, "x"), (y, "y")):
            if "corr" not in s:
                raise ValueError(f"sample {who} ({s.get('name', '')!r}) has no corr ground truth")
        return pair_score(p2p_yx, x["corr"], y["corr"], self.distances(x),
                          corr_sym_x=x.get("corr_sym"), n_points=self.n_points)

    def evaluate(self, items: Iterable[tuple[Tensor, dict, dict]]) -> CorrespondenceScore:
        """Score ``(p2p_yx, x, y)`` triples and summarise them (:func:`summarize_pairs`)."""
        return summarize_pairs([self.score(p, x, y) for p, x, y in items])
