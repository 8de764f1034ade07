"""Resolving a point map's symmetric flips part by part.

A network that matches shapes "up to symmetry" rarely flips a whole map; more often one part is
flipped: the left arm of y lands on the right arm of x while the rest is right. A global choice
(:func:`symtorch.orientation.resolve_symmetry_p2p`) cannot repair that. Where a part is flipped, the
map is the true map composed with the reflection, so it reverses orientation *there*: the images of
y's triangles on x are wound the wrong way. :func:`resolve_symmetry_parts` reads that local vote,
smooths it over y at a scale set by a heat-diffusion time, and sends the vertices whose smoothed
vote is clearly negative (below ``threshold``) through x's reflection
(``p2p'[j] = sym_p2p_x[p2p[j]]``). A map flipped as a whole has a negative vote everywhere and is
composed with the reflection everywhere, so this subsumes the global choice for a shape with one
reflection.

A spectral point map is noisy at the scale of one triangle: only a third or so of the faces have a
local, non-degenerate image that can vote, and a vote of exactly 0 is no evidence either way; the
threshold keeps correct parts whose smoothed vote merely wavers around 0 (BENCHMARKS.md, "Training
with symmetries", has the measured effect).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import torch
from torch import Tensor

from .orientation import _check_p2p, face_orientation_votes
from .sparse_solve import SPDFactor
from .spectrum import laplacian_matrices

__all__ = ["PartResolution", "VoteSmoother", "resolve_symmetry_parts", "DEFAULT_FLIP_SCALE", "DEFAULT_FLIP_THRESHOLD"]

#: The smoothing time of the vote, in units of y's area: the heat kernel's width ``sqrt(t)`` is about
#: 6 % of ``sqrt(area)``, smaller than a limb and larger than the noise of a spectral point map.
DEFAULT_FLIP_SCALE = 4e-3
#: A part is flipped where its smoothed vote (in [-1, 1]) is below this.
DEFAULT_FLIP_THRESHOLD = -0.3


class PartResolution(NamedTuple):
    """A point map with its flipped parts sent through the target's reflection.

    Attributes:
        p2p: [V_y] long, the resolved map.
        flipped: [V_y] bool, the vertices of y whose image was composed with the reflection.
        vote: [V_y] the smoothed orientation vote in [-1, 1] (nan where no face near voted).
    """

    p2p: Tensor
    flipped: Tensor
    vote: Tensor


class VoteSmoother:
    """Normalised heat smoothing of a face vote on one shape y, factorised once.

    ``smoother(vote, weight) = (M + tW)^-1 (vote density) / (M + tW)^-1 (weight density)`` with the
    cotangent stiffness W, the lumped mass M and ``t = scale * area``. Build one per target shape and
    pass it to :func:`resolve_symmetry_parts` for every map onto that shape.

    Args:
        verts_y: [V, 3]; faces_y: [F, 3] long.
        scale: heat-diffusion time in units of y's area.
    """

    def __init__(self, verts_y: Tensor, faces_y: Tensor, scale: float = DEFAULT_FLIP_SCALE):
        if not scale > 0:
            raise ValueError(f"scale must be positive, got {scale!r}")
        W, mass = laplacian_matrices(verts_y.detach().cpu().double().numpy(), faces_y.cpu().numpy())
        self.scale, self.n_verts = float(scale), verts_y.shape[0]
        self.dtype, self.device = verts_y.dtype, verts_y.device
        self._faces = faces_y.cpu().numpy().reshape(-1)
        self._factor = SPDFactor(sp.diags(mass) + scale * float(mass.sum()) * W)

    def __call__(self, face_vote: Tensor, face_weight: Tensor) -> Tensor:
        """[V] smoothed vote in [-1, 1] (nan where no face near voted) of ``face_vote [F]``
        weighted by ``face_weight [F]``."""
        wv = (face_weight * face_vote).detach().cpu().double().numpy()
        w = face_weight.detach().cpu().double().numpy()
        rhs = np.zeros((self.n_verts, 2))
        np.add.at(rhs[:, 0], self._faces, np.repeat(wv, 3) / 3)
        np.add.at(rhs[:, 1], self._faces, np.repeat(w, 3) / 3)
        u = self._factor.solve(rhs)
        with np.errstate(invalid="ignore", divide="ignore"):
            vote = np.where(u[:, 1] > 1e-12 * max(u[:, 1].max(), 1e-300), u[:, 0] / u[:, 1], np.nan)
        return torch.as_tensor(vote, dtype=self.dtype, device=self.device)


def resolve_symmetry_parts(p2p_yx: Tensor, verts_x: Tensor, faces_x: Tensor, verts_y: Tensor,
                           faces_y: Tensor, sym_p2p_x: Tensor, *, scale: float = DEFAULT_FLIP_SCALE,
                           threshold: float = DEFAULT_FLIP_THRESHOLD, max_stretch: float = 3.0,
                           smoother: VoteSmoother | None = None) -> PartResolution:
    """Compose the flipped parts of a point map with the target's reflection.

    Args:
        p2p_yx: [V_y] long, image on x of each vertex of y.
        verts_x, faces_x, verts_y, faces_y: the two meshes, consistently oriented.
        sym_p2p_x: [V_x] long, an orientation-reversing symmetry of x (its reflection).
        scale: heat-diffusion time of the vote's smoothing, in units of y's area.
        threshold: vertices whose smoothed vote is below it are flipped, in [-1, 1).
        max_stretch: faces whose image is longer than this many times the face (both shapes at the
            same area) do not vote (see :func:`symtorch.orientation.orientation_agreement`).
        smoother: a :class:`VoteSmoother` of y, reused across maps onto y (then ``scale`` is its).

    Returns:
        PartResolution(p2p [V_y], flipped [V_y], vote [V_y]).
    """
    if not -1 <= threshold < 1:
        raise ValueError(f"threshold must be in [-1, 1), got {threshold!r}")
    Vx, Vy = verts_x.shape[0], verts_y.shape[0]
    p2p = _check_p2p(torch.as_tensor(p2p_yx), Vy, Vx, "p2p_yx")
    if p2p.ndim != 1:
        raise ValueError(f"p2p_yx must be one map [V_y], got {list(p2p.shape)}")
    sym = _check_p2p(torch.as_tensor(sym_p2p_x), Vx, Vx, "sym_p2p_x")
    if sym.ndim != 1:
        raise ValueError(f"sym_p2p_x must be one reflection [V_x], got {list(sym.shape)}")
    p2p, sym = p2p.to(verts_x.device), sym.to(verts_x.device)
    vote, weight = face_orientation_votes(p2p, verts_x, faces_x, verts_y, faces_y, max_stretch)
    if smoother is None:
        smoother = VoteSmoother(verts_y, faces_y, scale)
    elif smoother.n_verts != Vy:
        raise ValueError(f"smoother is for {smoother.n_verts} vertices but y has {Vy}")
    field = smoother(vote, weight)
    flipped = (field < threshold).to(p2p.device)
    return PartResolution(torch.where(flipped, sym[p2p], p2p), flipped, field)
