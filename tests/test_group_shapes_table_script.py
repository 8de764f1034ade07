"""scripts/group_shapes_table.py: the random rows it draws (``--random-shapes``) and their truth."""
from script_loader import load_script


def test_random_shapes_are_reproducible_and_their_truth_has_the_order_it_names():
    mod = load_script("group_shapes_table")
    rows = mod.random_shapes(12, 3)
    assert [r[0] for r in rows] == [r[0] for r in mod.random_shapes(12, 3)]
    assert [r[0] for r in rows] != [r[0] for r in mod.random_shapes(12, 4)]
    for name, build, group, order, radius in rows:
        v, f, mats = build()
        assert len(mats) == order, (name, group, len(mats))
        assert radius == 0 or (4 <= radius <= 8 and not name.startswith("antiprism")), name
