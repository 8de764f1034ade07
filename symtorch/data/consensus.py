"""One reflection for a whole dataset: the shapes' detected reflections voted through their
correspondences to a common template.

A detector judges each shape alone. On a dataset whose shapes correspond to one template (``corr``,
the FAUST / SCAPE layouts), the reflections of all of them are one reflection of the template, read
through each shape's correspondence. Voting it out of the shapes' detected maps does three things at
once: a shape whose detector settled on a competing near-symmetry (an arm swapped, a leg mirrored
onto itself) is outvoted by the others; the imprecision of each detected map averages out; and the
reflections become *consistent with the correspondences* (``T_xy ∘ R_x = R_y ∘ T_xy`` on the template
points), which the dataset's own symmetric ground truth (``.sym.vts``) is by construction and a
symmetry-averaged network needs. Only the shapes whose correspondences may be used vote (the
training shapes); held-out shapes keep their own detection.

Steps:

1. **read**: each voting shape ``i`` sends template point ``t`` to ``pi_i(t)``, the template point
   whose vertex is nearest to the image of ``t``'s vertex under the shape's detected reflection;
2. **vote**: among the candidates ``{pi_i(t)}``, the one that the most shapes agree with (within
   ``tol`` of their own candidate, on their own surface) is the template's reflection of ``t``;
3. **write**: each shape gets ``corr_sym = corr[pi]`` and, through
   :class:`~symtorch.data.SymmetryFromCorrespondence`, a dense reflection.
"""
from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np
import torch
from scipy.spatial import cKDTree
from torch import Tensor

from .symmetry import SymmetryFromCorrespondence, reflection_index

__all__ = ["TemplateReflection", "template_reflection", "with_template_reflection"]


class TemplateReflection(NamedTuple):
    """The template's reflection as voted by the shapes."""

    perm: Tensor     # [N] long: the template point each point is sent to, -1 where no shape voted
    support: Tensor  # [N] float: share of the voting shapes that agree with it (0 where -1)
    n_shapes: int    # shapes that voted (those with a reflection and a correspondence)


def _unit_radius(verts: np.ndarray, faces: np.ndarray | None) -> float:
    """sqrt(area / (20 pi)) of the shape (its KLC radius); the bounding-box scale for a cloud."""
    if faces is None or len(faces) == 0:
        return float(np.linalg.norm(verts.max(0) - verts.min(0))) / 20.0
    a, b, c = (verts[faces[:, j]] for j in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    return math.sqrt(area / (20 * math.pi))


def _read(sample: dict) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Step 1 for one shape: ``pi_i [N]`` (-1 where unknown), the template points' positions on
    the shape ``[N, 3]`` and the agreement radius; None without a reflection or a correspondence."""
    r = reflection_index(sample)
    if r is None or "corr" not in sample or "sym_p2p" not in sample:
        return None
    corr = torch.as_tensor(sample["corr"]).long().cpu().numpy()
    R = torch.as_tensor(sample["sym_p2p"][r]).long().cpu().numpy()
    verts = torch.as_tensor(sample["verts"]).double().cpu().numpy()
    faces = sample.get("faces")
    faces = None if faces is None else torch.as_tensor(faces).long().cpu().numpy()
    ok = corr >= 0
    if not ok.any():
        return None
    known = np.flatnonzero(ok)
    _, nearest = cKDTree(verts[corr[known]]).query(verts[R[corr[known]]])
    pi = np.full(len(corr), -1, dtype=np.int64)
    pi[known] = known[nearest]
    pos = np.full((len(corr), 3), np.nan)
    pos[known] = verts[corr[known]]
    return pi, pos, _unit_radius(verts, faces)


def template_reflection(samples: Sequence[dict], tol: float = 0.5) -> TemplateReflection:
    """The template reflection the shapes' detected reflections agree on.

    Args:
        samples: shapes of one dataset with ``verts``, ``corr [N]`` (one template: the same N for
            all), and their detected symmetries (``sym_p2p``, ``sym_reverses``); shapes without a
            reflection or a correspondence do not vote.
        tol: two template points agree on a shape when their vertices there lie within ``tol``
            KLC radii (``sqrt(area / (20 pi))``) of each other (Euclidean: the radius is small
            beside a limb).

    Returns:
        :class:`TemplateReflection`; ``perm`` -1 everywhere when no shape votes.
    """
    if not samples:
        raise ValueError("template_reflection needs at least one sample")
    reads = [x for x in (_read(s) for s in samples) if x is not None]
    n = len(torch.as_tensor(samples[0]["corr"])) if "corr" in samples[0] else 0
    if any(len(pi) != n for pi, _, _ in reads):
        raise ValueError("template_reflection: the samples' corr have different lengths "
                         "(one template for all is needed)")
    if not reads:
        return TemplateReflection(torch.full((n,), -1, dtype=torch.long), torch.zeros(n), 0)
    cand = np.stack([pi for pi, _, _ in reads], 1)             # [N, S] each shape's candidate
    votes = np.zeros(cand.shape)                                 # [N, S] shapes agreeing with it
    spread = np.zeros(cand.shape)                                # [N, S] their summed distance
    rows = np.arange(n)[:, None]
    for j, (pi_j, pos_j, radius) in enumerate(reads):
        mine = pi_j >= 0
        at = pos_j[np.where(cand >= 0, cand, 0)]                 # [N, S, 3] candidates on shape j
        own = pos_j[np.where(mine, pi_j, 0)]                     # [N, 3] shape j's own candidate
        d = np.linalg.norm(at - own[:, None], axis=-1)           # nan where a point is unknown
        valid = (cand >= 0) & mine[:, None] & np.isfinite(d)
        votes += valid & (d < tol * radius)
        spread += np.where(valid, d / radius, 0.0)
    votes = np.where(cand >= 0, votes, -1)
    key = votes - spread / (spread.max() + 1.0)                 # most votes, then the tightest
    best = key.argmax(1)
    perm = cand[rows[:, 0], best]
    voters = (cand >= 0).sum(1)
    support = np.where(perm >= 0, votes[rows[:, 0], best] / np.maximum(voters, 1), 0.0)
    return TemplateReflection(torch.as_tensor(perm), torch.as_tensor(support, dtype=torch.float32),
                              len(reads))


def with_template_reflection(sample: dict, reflection: TemplateReflection,
                             method: str = "local") -> dict:
    """The sample with its reflection replaced by the template's, read through its ``corr``:
    ``corr_sym = corr[perm]``, then :class:`~symtorch.data.SymmetryFromCorrespondence` (``sym_p2p
    [2, V]``, ``sym_reverses``, ``sym_fmap``); the detector's other keys about the old symmetries
    (scores, confidences) are dropped, since they described other maps."""
    corr = torch.as_tensor(sample["corr"]).long()
    perm = reflection.perm.to(corr.device)
    if perm.shape != corr.shape:
        raise ValueError(f"template reflection has {perm.numel()} points, the sample's corr "
                         f"{corr.numel()} ({sample.get('name', '')!r})")
    corr_sym = torch.where(perm >= 0, corr[perm.clamp_min(0)], torch.full_like(corr, -1))
    out = {k: v for k, v in sample.items() if k not in ("sym_score", "sym_confidence", "sym_uncertain")}
    out["corr_sym"] = torch.where(corr >= 0, corr_sym, torch.full_like(corr, -1))
    return SymmetryFromCorrespondence(method)(out)
