"""Symmetry detection: the auto policy, the reflection path (§4), the group path (§5), result types.

- :mod:`.auto`: :func:`detect_symmetries`, which path to run and which result to keep;
- :mod:`.config`: :class:`DetectConfig`, :class:`ReflectionConfig`, :class:`GroupConfig`, the knobs;
- :mod:`.reflection` with :mod:`.involutions`: heat-kernel extrema, involutive pair sets, selection,
  refinement;
- :mod:`.group_path` with :mod:`.candidates` and :mod:`.group_elements`: invariant points, candidate
  tuples, clustering, refinement, closure, the group;
- :mod:`.constraints`: the point and descriptor constraints both paths solve Procrustes on;
- :mod:`.verification`: geodesic distortion, orientation and descriptor checks;
- :mod:`.confidence`: the reported reflection's confidence (a second selection's agreement) and the
  signals measured against it;
- :mod:`.result`: :class:`Symmetry`, :class:`SymmetryResult` and the diagnostics records.
"""
from .auto import detect_symmetries
from .config import DetectConfig, GroupConfig, ReflectionConfig
from .result import (Checks, Diagnostics, GroupDiagnostics, ReflectionDiagnostics, Symmetry,
                     SymmetryResult, Trial)

__all__ = ["detect_symmetries", "DetectConfig", "ReflectionConfig", "GroupConfig", "Symmetry",
           "SymmetryResult", "Diagnostics", "ReflectionDiagnostics", "GroupDiagnostics", "Checks",
           "Trial"]
