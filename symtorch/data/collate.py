"""Batching samples of different sizes: pad to the largest and return masks."""
from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import Tensor

from .transforms import VERTEX_FIELDS

__all__ = ["pad_collate", "pad_stack"]

#: dim-0 length group of a key -> the mask that covers it
_MASK_OF = {"verts": "mask", "faces": "faces_mask", "corr": "corr_mask", "corr_sym": "corr_mask",
            "sym_p2p": "sym_mask", "sym_fmap": "sym_mask", "sym_score": "sym_mask",
            "sym_confidence": "sym_mask", "sym_uncertain": "sym_mask", "sym_reverses": "sym_mask"}


def _pad_value(t: Tensor):
    if t.dtype == torch.bool:
        return False
    return 0 if t.is_floating_point() or t.is_complex() else -1


def pad_stack(tensors: Sequence[Tensor], value=None) -> Tensor:
    """Stack tensors of equal rank, padding every dim to the largest size.

    Args:
        tensors: B tensors ``[n_1, n_2, ...]`` of one rank and dtype.
        value: pad value; default 0 for floats, -1 for integers (an invalid index), False for bools.

    Returns:
        [B, max n_1, max n_2, ...].
    """
    ranks = {t.dim() for t in tensors}
    if len(ranks) != 1:
        raise ValueError(f"cannot stack tensors of ranks {sorted(ranks)}")
    shape = [max(s) for s in zip(*(t.shape for t in tensors))]
    value = _pad_value(tensors[0]) if value is None else value
    out = tensors[0].new_full((len(tensors), *shape), value)
    for b, t in enumerate(tensors):
        out[(b, *(slice(0, n) for n in t.shape))] = t
    return out


def _lengths_mask(lengths: list[int], device) -> Tensor:
    return torch.arange(max(lengths), device=device)[None, :] < torch.tensor(lengths,
                                                                             device=device)[:, None]


def pad_collate(batch: Sequence[dict]) -> dict:
    """Collate samples (or pairs of samples) of different sizes into one padded batch.

    Tensors are stacked, each dim padded to the largest in the batch with 0 (floats), -1 (integers,
    so that a padded vertex id is invalid) or False. Masks of valid entries, along dim 0:

    - ``mask [B, V]`` for the vertices (``verts`` and every per-vertex key: ``evecs``, ``mass``,
      ``hks``, ...). Padded vertices have ``mass`` 0 and ``evecs`` rows 0, so spectral projections
      ``evecs.mT @ (mass[..., None] * f)`` need no masking;
    - ``faces_mask [B, F]``, ``corr_mask [B, N]`` (``corr``, ``corr_sym``), ``sym_mask [B, G]``
      (``sym_p2p``, ``sym_fmap``, ``sym_score``, ``sym_confidence``, ``sym_uncertain``,
      ``sym_reverses``; padded group elements have zero matrices, vertex maps of -1, confidence 0
      and ``sym_reverses``/``sym_uncertain`` False);
    - ``<key>_mask`` for any other key whose dim-0 length varies.

    Nested dicts (the ``x``/``y`` of :class:`~symtorch.data.PairDataset`) are collated recursively;
    strings become lists; Python numbers become tensors.

    Args:
        batch: samples with the same keys.

    Returns:
        the batch, a dict with the keys of the samples plus the masks.
    """
    if not batch:
        raise ValueError("pad_collate got an empty batch")
    keys = list(batch[0].keys())
    for s in batch[1:]:
        if set(s.keys()) != set(keys):
            raise ValueError(f"samples have different keys: {sorted(keys)} vs {sorted(s.keys())}")
    out: dict = {}
    n_verts = [s["verts"].shape[0] for s in batch] if "verts" in batch[0] else None
    for key in keys:
        vals = [s[key] for s in batch]
        first = vals[0]
        if isinstance(first, dict):
            out[key] = pad_collate(vals)
        elif isinstance(first, Tensor):
            out[key] = pad_stack(vals)
            lengths = [v.shape[0] if v.dim() else 1 for v in vals]
            if key in _MASK_OF:
                out[_MASK_OF[key]] = _lengths_mask(lengths, first.device)
            elif (key in VERTEX_FIELDS or lengths == n_verts) and n_verts is not None:
                pass  # covered by `mask`
            elif len(set(lengths)) > 1:
                out[f"{key}_mask"] = _lengths_mask(lengths, first.device)
        elif isinstance(first, (bool, int, float)):
            out[key] = torch.tensor(vals)
        else:
            out[key] = list(vals)
    return out
