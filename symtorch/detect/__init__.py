"""Symmetry detection: the auto policy, the reflection path (§4), the group path (§5), result types.

- :mod:`.auto`: :func:`detect_symmetries`, which path to run and which result to keep;
- :mod:`.reflection` with :mod:`.involutions`: heat-kernel extrema, involutive pair sets, refinement;
- :mod:`.group_path` with :mod:`.candidates`: invariant points, candidate tuples, clustering, closure;
- :mod:`.constraints`: the point and descriptor constraints both paths solve Procrustes on;
- :mod:`.result`: :class:`Symmetry`, :class:`SymmetryResult`.
"""
from .auto import detect_symmetries
from .result import Symmetry, SymmetryResult

__all__ = ["detect_symmetries", "Symmetry", "SymmetryResult"]
