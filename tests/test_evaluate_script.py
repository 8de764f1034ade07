"""scripts/evaluate.py's point-cloud options: the seeded subsample and the map lifted to the mesh."""

import numpy as np
from script_loader import load_script



def _load_script():
    return load_script("evaluate")


def test_point_subset_is_seeded_sorted_and_distinct():
    ev = _load_script()
    a, b = ev.point_subset(1000, 300, seed=0), ev.point_subset(1000, 300, seed=0)
    assert np.array_equal(a, b) and len(np.unique(a)) == 300 and (np.diff(a) > 0).all()
    assert not np.array_equal(a, ev.point_subset(1000, 300, seed=1))
    assert np.array_equal(ev.point_subset(1000, None, 0), np.arange(1000))
    assert np.array_equal(ev.point_subset(1000, 5000, 0), np.arange(1000))


def test_lift_to_mesh_sends_each_vertex_where_its_nearest_point_goes():
    ev = _load_script()
    rng = np.random.default_rng(0)
    verts = rng.normal(size=(500, 3))
    mirror = verts * [-1.0, 1.0, 1.0]
    verts = np.concatenate([verts, mirror])  # vertex i and i + 500 are mirror twins
    keep = np.arange(0, 1000, 2)              # even ids: twins stay twins (500 is even)
    twin = (keep + 500) % 1000
    p2p_sub = np.searchsorted(keep, twin)     # the mirror on the kept points
    lifted = ev.lift_to_mesh(p2p_sub, keep, verts)
    assert lifted.shape == (1000,)
    assert np.array_equal(lifted[keep], twin)  # a kept point goes where the map sends it
    odd = np.arange(1, 1000, 2)
    nearest = keep[np.argmin(((verts[odd, None] - verts[keep][None]) ** 2).sum(-1), 1)]
    assert np.array_equal(lifted[odd], (nearest + 500) % 1000)


def test_side_by_side_table_has_one_line_per_mesh_and_marks_wrong_maps(capsys):
    ev = _load_script()
    rows = [dict(method="symtorch", name="a", rate=0.99, nerr=0.0213, time=1.0),
            dict(method="pyfm", name="a", rate=0.60, nerr=0.2504, time=4.0),
            dict(method="symtorch", name="b", rate=0.97, nerr=0.0300, time=1.5)]
    ev.print_side_by_side(rows, ["symtorch", "pyfm"])
    lines = [l for l in capsys.readouterr().out.splitlines() if l.startswith("| ")]
    assert lines[0].startswith("| mesh | symtorch rate") and "pyfm s |" in lines[0]
    assert lines[1] == "| a | 99.0 % | 21.3 | 1.00 | **60.0 %** | 250.4 | 4.00 |"
    assert lines[2] == "| b | 97.0 % | 30.0 | 1.50 | – | – | – |"
