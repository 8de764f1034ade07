"""DiffusionNet features on symtorch samples (Sharp, Attaiki, Crane & Ovsjanikov, TOG 2022).

The network itself is geomfum's maintained implementation (``geomfum.wrap.diffusionnet.DiffusionNet``,
``pip install symtorch[train]``); this module feeds it from a sample dict:

- :func:`gradient_operator` / :class:`ComputeGradientOperator` build DiffusionNet's per-vertex
  gradient operator once per shape (cached with the spectrum): for a function ``u [V]``, ``G @ u`` is
  the gradient at each vertex in its tangent frame, as a complex number ``x + i y`` (frame axes
  ``X`` and ``Y = n x X``, ``n`` the outward vertex normal), fitted by least squares on the vertex's
  edges. The operator is stored as ``grad_idx [2, nnz]`` and ``grad_val [nnz, 2]`` (real, imaginary).
- :class:`DiffusionNetFeatures` runs DiffusionNet on one sample (spectral diffusion in the sample's
  own ``evecs``/``evals``/``mass``) and returns ``[V, D]`` features.

Orientation: the frame's second axis ``Y = n x X`` is where the surface's orientation enters, so
DiffusionNet's gradient features can tell a shape from its mirror image. The mirror image of a shape
(one coordinate negated, face winding reversed) has the complex conjugate operator (``grad_val[:, 1]``
negated) in mirrored frames, up to a rotation of each frame, to which DiffusionNet's gradient features
are invariant; :func:`symtorch.data.apply_symmetry` in ``"mirror"`` mode applies exactly that.

Note:
    geomfum 1.0's ``TriangleMesh.gradient`` fits each vertex's gradient on its edges to
    higher-numbered neighbours only (one direction of each undirected edge); here every directed
    edge is used, as in the reference DiffusionNet, with geomfum's own fitting functions.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import Tensor, nn

__all__ = ["gradient_operator", "ComputeGradientOperator", "DiffusionNetFeatures",
           "sparse_gradient"]

_HINT = "DiffusionNet needs geomfum: pip install symtorch[train]"


def _geomfum():
    try:
        from geomfum.shape import TriangleMesh
        from geomfum.shape.shape_utils import (compute_edge_tangent_vectors,
                                               compute_gradient_matrix_fem)
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(_HINT) from err
    return TriangleMesh, compute_edge_tangent_vectors, compute_gradient_matrix_fem


def gradient_operator(verts: Tensor, faces: Tensor) -> tuple[Tensor, Tensor]:
    """DiffusionNet's vertex gradient operator in tangent frames.

    Args:
        verts: [V, 3]; faces: [F, 3] long, consistently oriented (outward normals).

    Returns:
        ``(grad_idx [2, nnz] long, grad_val [nnz, 2])``: the sparse ``[V, V]`` complex operator as
        (row, column) indices and (real, imaginary) values, dtype of ``verts``.
    """
    if verts.dim() != 2 or verts.shape[-1] != 3:
        raise ValueError(f"verts must be [V, 3], got {list(verts.shape)}")
    if faces.dim() != 2 or faces.shape[-1] != 3:
        raise ValueError(f"faces must be [F, 3], got {list(faces.shape)}")
    TriangleMesh, edge_vectors, fit = _geomfum()
    mesh = TriangleMesh(verts.detach().cpu().double().numpy(), faces.detach().cpu().numpy())
    edges = np.asarray(mesh.edges)
    edges = np.concatenate([edges, edges[:, ::-1]])  # every directed edge
    G = fit(mesh.vertices, edges, edge_vectors(mesh.vertices, edges, mesh.vertex_tangent_frames))
    G = G.tocoo()
    idx = torch.as_tensor(np.stack([G.row, G.col]).astype(np.int64))
    val = torch.as_tensor(np.stack([G.data.real, G.data.imag], axis=1), dtype=verts.dtype)
    return idx, val


def sparse_gradient(sample: dict, dtype: torch.dtype = torch.float32) -> tuple[Tensor, Tensor]:
    """The sample's gradient operator as two sparse ``[V, V]`` tensors (real part, imaginary part)."""
    V = sample["verts"].shape[0]
    idx, val = sample["grad_idx"], sample["grad_val"].to(dtype)
    gx = torch.sparse_coo_tensor(idx, val[:, 0], (V, V), check_invariants=False).coalesce()
    gy = torch.sparse_coo_tensor(idx, val[:, 1], (V, V), check_invariants=False).coalesce()
    return gx, gy


class ComputeGradientOperator:
    """Add DiffusionNet's gradient operator: ``grad_idx [2, nnz]``, ``grad_val [nnz, 2]``.

    Deterministic and costly (a least-squares fit per vertex): put it in ``pre_transform``, after
    ``NormalizeArea`` (the operator scales with the shape).
    """

    def __call__(self, sample: dict) -> dict:
        if "verts" not in sample or "faces" not in sample:
            raise ValueError("ComputeGradientOperator needs sample keys ['verts', 'faces'] "
                             "(a triangle mesh)")
        sample = dict(sample)
        sample["grad_idx"], sample["grad_val"] = gradient_operator(sample["verts"], sample["faces"])
        return sample

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class DiffusionNetFeatures(nn.Module):
    """Per-vertex features of one shape from geomfum's DiffusionNet.

    Args:
        in_channels: input feature size (e.g. the number of WKS energies, or 3 for xyz).
        out_channels: output feature size D.
        hidden_channels: width of the blocks.
        n_block: number of DiffusionNet blocks.
        k_eig: eigenpairs used for spectral diffusion (the first ``k_eig`` of the sample's basis).
        dropout: dropout in the blocks' MLPs.
    """

    def __init__(self, in_channels: int, out_channels: int, hidden_channels: int = 64,
                 n_block: int = 4, k_eig: int = 64, dropout: bool = False):
        super().__init__()
        try:
            from geomfum.wrap.diffusionnet import DiffusionNet
        except ImportError as err:  # pragma: no cover - depends on the environment
            raise ImportError(_HINT) from err
        self.k_eig = k_eig
        self.net = DiffusionNet(in_channels, out_channels, hidden_channels=hidden_channels,
                                n_block=n_block, k_eig=k_eig, dropout=dropout,
                                with_gradient_features=True, with_gradient_rotations=True)

    def forward(self, sample: dict, features: Tensor) -> Tensor:
        """Features ``[V, D]`` of ``sample`` (``verts, faces, mass, evals, evecs, grad_idx, grad_val``)
        from input ``features [V, C]``."""
        missing = [k for k in ("verts", "faces", "mass", "evals", "evecs", "grad_idx", "grad_val")
                   if k not in sample]
        if missing:
            raise ValueError(f"DiffusionNetFeatures needs sample keys {missing} (ComputeSpectrum, "
                             f"ComputeGradientOperator)")
        K = self.k_eig
        if sample["evecs"].shape[-1] < K:
            raise ValueError(f"k_eig={K} but the sample has {sample['evecs'].shape[-1]} eigenpairs")
        dtype = features.dtype
        gx, gy = sparse_gradient(sample, dtype)
        out = self.net(sample["verts"].to(dtype)[None], sample["faces"][None], features[None], None,
                       sample["mass"].to(dtype)[None], None, sample["evals"][:K].to(dtype)[None],
                       sample["evecs"][:, :K].to(dtype)[None], gx[None], gy[None])
        return out[0]
