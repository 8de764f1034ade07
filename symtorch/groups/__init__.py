"""Finite symmetry groups from their matrices and maps.

- :mod:`.algebra`: composition, inverses, orders, Cayley tables, the group axioms, closure;
- :mod:`.naming`: structure and Schoenflies names, orientation of an element, :class:`GroupInfo`;
- :mod:`.from_maps`: tables, closed subsets, orientation flags and element order from vertex maps.
"""
from .algebra import (DEFAULT_TOL, Cayley, Closure, GroupCheck, cayley_table, check_group, closure,
                      compose_fmap, compose_p2p, element_orders, identity_index, inverse_fmap, inverse_p2p,
                      inverses)
from .from_maps import canonical_order, consistent_orientation, largest_subgroup, map_table
from .naming import (GroupInfo, abstract_group, fixes_points, group_info, identify_group, kind_of,
                     orientation_reversing, orientation_score)

__all__ = ["DEFAULT_TOL", "compose_fmap", "compose_p2p", "inverse_fmap", "inverse_p2p", "Cayley",
           "cayley_table", "identity_index", "element_orders", "inverses", "GroupCheck", "check_group",
           "Closure", "closure", "abstract_group", "identify_group", "kind_of", "fixes_points", "orientation_score",
           "orientation_reversing", "GroupInfo", "group_info", "map_table", "largest_subgroup",
           "consistent_orientation", "canonical_order"]
