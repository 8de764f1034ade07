"""Transforms that precompute operators in a sample's basis (cached with the spectrum).

:class:`ComputeOrientationOperators` writes ``orient_op [D, K, K]``, the orientation operators of D
descriptors (Ren et al., SIGGRAPH Asia 2018; :func:`symtorch.orientation.orientation_operators`), for
:func:`symtorch.losses.orientation_loss` and :func:`symtorch.orientation.resolve_symmetry`.

How ``orient_op`` follows the other transforms (each pinned against a recomputation in
``tests/test_operators.py``):

- :func:`~symtorch.data.mirror_shape` (one coordinate negated, winding reversed, same vertex order and
  basis; ``apply_symmetry(mode="mirror")``) negates it;
- :func:`~symtorch.data.change_basis` (``evecs @ R``: :class:`~symtorch.data.RandomEigenSigns`,
  :class:`~symtorch.data.RandomBandRotation`) sends it to ``R.T @ orient_op @ R``;
- ``apply_symmetry(mode="relabel")`` leaves it alone: only the ground truth moves, not the mesh or the
  basis.
"""
from __future__ import annotations

import torch
from torch import Tensor

from ..orientation import orientation_operators

__all__ = ["ComputeOrientationOperators"]

_DESCRIPTORS = ("wks", "hks")


def _columns(field: Tensor, n: int, key: str) -> Tensor:
    """``n`` evenly spaced columns of a ``[V, E]`` descriptor (all of them when E == n)."""
    E = field.shape[1]
    if E < n:
        raise ValueError(f"n_descriptors={n} but the sample's {key!r} has {E} columns")
    idx = torch.linspace(0, E - 1, n, device=field.device).round().long()
    return field[:, idx]


class ComputeOrientationOperators:
    """Orientation operators of descriptors in the sample's basis: ``orient_op [D, K, K]``.

    Uses the sample's ``wks`` (or ``hks``) where present (``n_descriptors`` evenly spaced columns of
    it, so the descriptors match those the model sees), and otherwise computes them on the default
    grid (:func:`symtorch.descriptors.default_energies` / ``default_times``) with ``n_descriptors``
    scales. Each column is scaled to unit mass-weighted norm (``normalize``). Deterministic:
    put it in ``pre_transform`` after :class:`~symtorch.data.ComputeSpectrum`.

    Args:
        n_descriptors: D, the number of operators.
        descriptor: ``"wks"`` or ``"hks"``.
        normalize: see :func:`symtorch.orientation.orientation_operators`.

    Sample keys read: ``verts``, ``faces``, ``evecs``, ``evals``, ``mass`` (and ``wks`` / ``hks``);
    written: ``orient_op``, in the dtype of ``evecs``.
    """

    def __init__(self, n_descriptors: int = 16, descriptor: str = "wks", normalize: bool = True):
        if descriptor not in _DESCRIPTORS:
            raise ValueError(f"descriptor must be one of {_DESCRIPTORS}, got {descriptor!r}")
        if n_descriptors < 1:
            raise ValueError(f"n_descriptors must be >= 1, got {n_descriptors}")
        self.n_descriptors, self.descriptor, self.normalize = n_descriptors, descriptor, normalize

    def _fields(self, sample: dict) -> Tensor:
        from ..descriptors import default_energies, default_times, hks, wks

        if self.descriptor in sample:
            return _columns(sample[self.descriptor], self.n_descriptors, self.descriptor)
        evals, evecs = sample["evals"], sample["evecs"]
        if self.descriptor == "wks":
            energies, sigma = default_energies(evals, self.n_descriptors)
            return wks(evals, evecs, energies, sigma)
        return hks(evals, evecs, default_times(evals, self.n_descriptors))

    def __call__(self, sample: dict) -> dict:
        missing = [k for k in ("verts", "faces", "evecs", "evals", "mass") if k not in sample]
        if missing:
            raise ValueError(f"{type(self).__name__} needs sample keys {missing} (a triangle mesh; "
                             f"run ComputeSpectrum first)")
        sample = dict(sample)
        evecs = sample["evecs"]
        verts = sample["verts"].to(evecs)
        fields = self._fields(sample).to(evecs)
        sample["orient_op"] = orientation_operators(verts, sample["faces"], evecs,
                                                    sample["mass"].to(evecs), fields, self.normalize)
        return sample

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(n_descriptors={self.n_descriptors}, "
                f"descriptor={self.descriptor!r}, normalize={self.normalize})")
