"""symtorch.groups.from_maps: tables, closed subsets, orientation and element order from vertex maps."""
import numpy as np
import torch
from scipy.spatial import cKDTree

from symtorch import shapes
from symtorch.groups import check_group
from symtorch.groups.from_maps import canonical_order, closed_subsets, consistent_orientation, largest_subgroup


def test_consistent_orientation_overrides_a_weak_vote():
    # C2v table (e, r, s, s∘r); one reflection's vote is wrong but weak
    T = torch.tensor([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
    rev = consistent_orientation(T, [1.0, 0.9, -0.95, 0.1])
    assert rev.tolist() == [False, False, True, True]


def test_largest_subgroup_drops_a_duplicate():
    v, f = shapes.table(3)
    maps = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, shapes.true_symmetries("table"))]
    maps.insert(3, maps[1].clone())  # a duplicate of the quarter turn
    keep, table = largest_subgroup(maps, [0.0] + [0.1] * 8, torch.as_tensor(v), torch.arange(0, len(v), 7))
    assert len(keep) == 8 and not (1 in keep and 3 in keep)
    assert check_group(table).is_group


def test_largest_subgroup_reads_a_product_that_matches_a_copy_as_the_element():
    """Watertight 160: a mirror's map is off on a few vertices, so mirror∘mirror is matched to a
    near-copy of the identity (a closure product) rather than to the identity; the copy is the
    identity, and the group is kept whole."""
    v, f = shapes.table(3)
    mats = shapes.true_symmetries("table")
    maps = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, mats)]
    samples = torch.arange(0, len(v), 7)
    m = next(i for i, R in enumerate(mats) if np.linalg.det(R) < 0)  # a mirror
    _, nearest = cKDTree(v).query(v, k=2)
    moved = torch.arange(len(v)) % 3 != 0  # two thirds of the vertices land next to their image
    maps[m] = torch.where(moved, torch.as_tensor(nearest[:, 1])[maps[m]], maps[m])
    copy = maps[m][maps[m]]  # mirror∘mirror: the identity up to a vertex's neighbour
    p2ps = maps + [copy]
    cost = [0.0] + [0.1] * 7 + [0.01]
    keep, table = largest_subgroup(p2ps, cost, torch.as_tensor(v), samples)
    assert sorted(keep) == list(range(8)) and check_group(table).is_group


def _c4v_parts(v):
    """The table's C4v maps sorted out: identity, quarter turns, half turn, two perpendicular mirrors."""
    mats = shapes.true_symmetries("table")
    maps = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, mats)]
    det, tr = [np.linalg.det(R) for R in mats], [np.trace(R) for R in mats]
    e = next(i for i in range(8) if np.isclose(tr[i], 3))
    quarter = [i for i in range(8) if det[i] > 0 and np.isclose(tr[i], 1)]
    half = next(i for i in range(8) if det[i] > 0 and np.isclose(tr[i], -1))
    m1 = next(i for i in range(8) if det[i] < 0)
    m2 = next(i for i in range(8) if det[i] < 0 and np.allclose(mats[m1] @ mats[i], mats[half]))
    return maps, e, quarter, half, m1, m2


def test_closed_subsets_also_seeds_the_elements_the_greedy_set_left_out():
    """Quarter turns and two perpendicular mirrors each close a group of four with the half turn
    but not with each other: the cheaper mirrors' set comes first, the quarter turns' is found too."""
    v, f = shapes.table(3)
    maps, e, quarter, half, m1, m2 = _c4v_parts(v)
    idx = [e, *quarter, half, m1, m2]
    cost = [0.0, 0.15, 0.15, 0.001, 0.1, 0.1]  # the mirrors cheaper than the quarter turns
    options = closed_subsets([maps[i] for i in idx], cost, torch.as_tensor(v), torch.arange(0, len(v), 7))
    sets = [sorted(idx[i] for i in keep) for keep, _ in options]
    assert sets[0] == sorted([e, half, m1, m2])  # largest_subgroup's, the cheapest first
    assert sorted([e, half, *quarter]) in sets
    assert all(check_group(table).is_group for _, table in options)
    assert largest_subgroup([maps[i] for i in idx], cost, torch.as_tensor(v), torch.arange(0, len(v), 7))[0] \
        == options[0][0]


def test_canonical_order_reads_like_the_paper():
    # D4 from maps: identity, r, r^2, r^3, then the reflections
    v, f = shapes.table(3)
    maps = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, shapes.true_symmetries("table"))]
    keep, T = largest_subgroup(maps, [0.0] * 8, torch.as_tensor(v), torch.arange(0, len(v), 7))
    rev = torch.tensor([False] * 4 + [True] * 4)[keep]
    order = canonical_order(T, rev, [0.0] * 8)
    Tn = T.numpy()
    r = order[1]
    assert [order[2], order[3]] == [Tn[r, r], Tn[r, Tn[r, r]]]
    assert all(rev[i] for i in order[4:])
