"""Finite symmetry groups from their matrices and maps: algebra (compose, inverse, closure, tables),
naming (Schoenflies), and groups from vertex maps."""
from .algebra import (DEFAULT_TOL, compose_fmap, compose_p2p, inverse_fmap, inverse_p2p, Cayley, cayley_table, identity_index, element_orders, inverses, GroupCheck, check_group, Closure, closure, abstract_group, identify_group, kind_of, orientation_score, orientation_reversing, GroupInfo, group_info)
from .from_maps import (map_table, largest_subgroup, consistent_orientation, canonical_order)

__all__ = ['DEFAULT_TOL', 'compose_fmap', 'compose_p2p', 'inverse_fmap', 'inverse_p2p', 'Cayley', 'cayley_table', 'identity_index', 'element_orders', 'inverses', 'GroupCheck', 'check_group', 'Closure', 'closure', 'abstract_group', 'identify_group', 'kind_of', 'orientation_score', 'orientation_reversing', 'GroupInfo', 'group_info', 'map_table', 'largest_subgroup', 'consistent_orientation', 'canonical_order']
