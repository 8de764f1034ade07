"""Evaluation: KLC10 metrics and the benchmark loaders. Nothing in the library above imports it."""
from ..units import EPS_KLC, klc_threshold
from .metrics import (evenly_spaced, geodesic_errors, orbit_errors, klc_rates, mesh_rate, normalized_error, GroupScore, score_group)
from .groups import (dihedral_permutations, dihedral_orbit_errors, element_rates, rigid_residual)
from .correspondence import (CorrespondenceEvaluator, CorrespondenceScore, PairScore, ShapeDistances, pair_score, summarize_pairs)

__all__ = ['EPS_KLC', 'klc_threshold', 'evenly_spaced', 'geodesic_errors', 'orbit_errors', 'klc_rates', 'mesh_rate', 'normalized_error', 'GroupScore', 'score_group', 'dihedral_permutations', 'dihedral_orbit_errors', 'element_rates', 'rigid_residual', 'CorrespondenceEvaluator', 'CorrespondenceScore', 'PairScore', 'ShapeDistances', 'pair_score', 'summarize_pairs']
