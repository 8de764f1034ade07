"""symtorch.groups.naming: abstract structure, Schoenflies names, orientation, GroupInfo.

Fixtures: ``d5h`` / ``d4h`` (``tests/prisms.py``), exact vertex permutations of prisms and their matrices.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from symtorch.groups import (GroupInfo, abstract_group, cayley_table, check_group, closure, element_orders,
                             group_info, identify_group, inverses, kind_of, orientation_reversing,
                             orientation_score)

from prisms import signed_permutations


def _rz(a: float) -> np.ndarray:
    c, s_ = np.cos(a), np.sin(a)
    return np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])


def test_paper_table3_has_table4_inverses_orders_and_names_c4v():
    # Paper Table 3 (Table model, g1..g8, 0-based here); its entry (i, j) is "g_i, then g_j".
    t3 = torch.tensor([[1, 2, 3, 4, 5, 6, 7, 8], [2, 3, 4, 1, 7, 8, 6, 5], [3, 4, 1, 2, 6, 5, 8, 7],
                       [4, 1, 2, 3, 8, 7, 5, 6], [5, 8, 6, 7, 1, 3, 4, 2], [6, 7, 5, 8, 3, 1, 2, 4],
                       [7, 5, 8, 6, 2, 4, 1, 3], [8, 6, 7, 5, 4, 2, 3, 1]]) - 1
    ours = t3.mT  # table[a, b] = "b, then a"
    assert check_group(ours).is_group and check_group(t3).is_group
    assert inverses(ours).tolist() == [0, 3, 2, 1, 4, 5, 6, 7]        # Table 4: g1 g4 g3 g2 g5..g8
    assert element_orders(ours).tolist() == [1, 4, 2, 4, 2, 2, 2, 2]  # Table 4
    reversing = torch.tensor([False] * 4 + [True] * 4)                # 4 rotations, 4 reflections
    assert identify_group(ours, reversing) == "C4v"
    assert identify_group(ours, torch.zeros(8, dtype=torch.bool)) == "D4"
    assert abstract_group(ours) == ("dihedral", 4)


# ----------------------------------------------------------------------------------------- names
@pytest.mark.parametrize("name,gens", [
    ("C1", []), ("Cs", [(0, 0, 1)]), ("Cs", [(0, 1, 0)]), ("C2", [(0, 1, 1)]),
    ("C5", [(1, 0, 0)]), ("C5v", [(1, 0, 0), (0, 1, 0)]), ("C5h", [(1, 0, 0), (0, 0, 1)]),
    ("D5", [(1, 0, 0), (0, 1, 1)]), ("D5h", [(1, 0, 0), (0, 1, 0), (0, 0, 1)]),
])
def test_identify_group_on_pentagonal_prism(d5h, name, gens):
    idx = d5h.generated(*gens)
    fmaps, rev = d5h.sub(idx)
    table, residual = cayley_table(fmaps, tol=0.1)
    assert check_group(table, residual).is_group
    assert identify_group(table, rev) == name, f"gens={gens}, |G|={len(idx)}"


@pytest.mark.parametrize("name,order,gens", [
    ("C4", 4, [(1, 0, 0)]), ("C4v", 8, [(1, 0, 0), (0, 1, 0)]), ("C4h", 8, [(1, 0, 0), (0, 0, 1)]),
    ("D4", 8, [(1, 0, 0), (0, 1, 1)]), ("D4h", 16, [(1, 0, 0), (0, 1, 0), (0, 0, 1)]),
    ("S4", 4, [(1, 0, 1)]), ("D2d", 8, [(1, 0, 1), (0, 1, 1)]),
    ("D2h", 8, [(2, 0, 0), (0, 1, 0), (0, 0, 1)]), ("C2v", 4, [(2, 0, 0), (0, 1, 0)]),
])
def test_identify_group_on_square_prism(d4h, name, order, gens):
    idx = d4h.generated(*gens)
    assert len(idx) == order
    fmaps, rev = d4h.sub(idx)
    assert identify_group(cayley_table(fmaps).table, rev) == name, f"gens={gens}"


def test_abstract_group_structures(d5h, d4h):
    assert abstract_group(cayley_table(d5h.fmaps).table) == ("dihedral", 10)  # D5 × Z2 ≅ D10
    d4xz2 = ("direct", ("dihedral", 4), ("cyclic", 2))
    assert abstract_group(cayley_table(d4h.fmaps).table) == d4xz2
    c4h = d4h.sub(d4h.generated((1, 0, 0), (0, 0, 1)))[0]
    assert abstract_group(cayley_table(c4h).table) == ("direct", ("cyclic", 4), ("cyclic", 2))
    assert abstract_group(torch.zeros(1, 1, dtype=torch.long)) == ("cyclic", 1)


def test_identify_polyhedral_groups():
    Oh = signed_permutations()
    det = torch.linalg.det(Oh)
    tetra = torch.tensor([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=torch.float64)
    keeps = torch.tensor([torch.cdist(tetra @ M.mT, tetra).min(1).values.max() < 1e-9 for M in Oh])
    cases = {"Oh": torch.ones(48, dtype=torch.bool), "O": det > 0, "Td": keeps,
             "T": keeps & (det > 0)}
    cases["Th"] = torch.tensor([bool(cases["T"][i]) or bool(cases["T"][j])
                                for i, j in enumerate(torch.cdist(Oh.flatten(1),
                                                                  -Oh.flatten(1)).argmin(1))])
    orders = {"Oh": 48, "O": 24, "Td": 24, "T": 12, "Th": 24}
    for name, mask in cases.items():
        fmaps = Oh[mask]
        assert len(fmaps) == orders[name], name
        assert identify_group(cayley_table(fmaps).table, det[mask] < 0) == name


@pytest.mark.parametrize("name, gens", [
    ("Cs", [np.diag([1.0, 1.0, -1.0])]), ("Ci", [-np.eye(3)]),
    ("C2v", [_rz(np.pi), np.diag([1.0, -1.0, 1.0])]), ("C2h", [_rz(np.pi), -np.eye(3)]),
    ("C3h", [_rz(2 * np.pi / 3), np.diag([1.0, 1.0, -1.0])]), ("S6", [-_rz(2 * np.pi / 3)]),
    ("D3h", [_rz(2 * np.pi / 3), np.diag([1.0, -1.0, 1.0]), np.diag([1.0, 1.0, -1.0])]),
    ("D3d", [_rz(2 * np.pi / 3), np.diag([1.0, -1.0, -1.0]), -np.eye(3)]),
    ("D5d", [_rz(2 * np.pi / 5), np.diag([1.0, -1.0, -1.0]), -np.eye(3)]),
    ("D4d", [_rz(np.pi / 4) @ np.diag([1.0, 1.0, -1.0]), np.diag([1.0, -1.0, 1.0])]),
])
def test_fixed_points_tell_mirrors_from_inversions(name, gens):
    """Same table and orientation flags, told apart by whether the reversing involutions fix a
    point of the unit sphere (a mirror: a great circle; the inversion: none)."""
    M = closure(torch.as_tensor(np.stack(gens))).fmaps  # the group the generators generate
    els = list(M.numpy())
    table, _ = cayley_table(M)
    rev = torch.linalg.det(M) < 0
    fixes = torch.tensor([bool(np.isclose(np.linalg.eigvals(m), 1.0).any()) for m in els])
    assert identify_group(table, rev, fixes) == name
    assert group_info(table, rev, fixes=fixes).name == name
    assert identify_group(table, rev) == {"Ci": "Cs", "C2h": "C2v", "S6": "C3h", "D3d": "D3h",
                                          "D5d": "D5h"}.get(name, name)  # the flags alone


def test_fixes_points_of_vertex_maps():
    """A mirror's vertex map fixes the vertices on its plane; the inversion of a sphere none."""
    import trimesh

    from symtorch.groups import fixes_points

    m = trimesh.creation.icosphere(3)
    v, f = torch.as_tensor(m.vertices), torch.as_tensor(m.faces)
    near = lambda x: torch.cdist(x, v).argmin(1)  # noqa: E731
    mirror, inversion = near(v * torch.tensor([1.0, 1.0, -1.0], dtype=v.dtype)), near(-v)
    assert fixes_points(torch.stack([mirror, inversion, torch.arange(len(v))]), v, f).tolist() == [True, False, True]


def test_identify_group_warns_on_inconsistent_orientation(d5h):
    table = cayley_table(d5h.fmaps).table
    rev = d5h.reversing.clone()
    rev[d5h.idx(k=1)] = True  # a rotation flagged as reversing breaks rev(a∘b) = rev(a) xor rev(b)
    with pytest.warns(UserWarning, match="inconsistent"):
        assert identify_group(table, rev) == "order-20 group"
    with pytest.raises(ValueError, match=r"reversing must be \[G\]"):
        identify_group(table, rev[:3])


def test_identify_group_fallback_for_unnamed_group():
    # Quaternion group Q8 as 4x4 orthogonal matrices (left multiplication): no point group.
    def left(q):
        a, b, c, d = q
        return torch.tensor([[a, -b, -c, -d], [b, a, -d, c], [c, d, a, -b], [d, -c, b, a]],
                            dtype=torch.float64)
    units = [(1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)]
    fmaps = torch.stack([s * left(u) for u in units for s in (1, -1)])
    table = cayley_table(fmaps).table
    assert identify_group(table, torch.zeros(8, dtype=torch.bool)) == "order-8 group"
    assert abstract_group(table) == ("unknown", 8)


# ------------------------------------------------------------------------------------ orientation
def test_orientation_of_prism_symmetries(d5h):
    score = orientation_score(d5h.p2p, d5h.verts, d5h.faces)  # batched
    torch.testing.assert_close(score, torch.where(d5h.reversing, -1.0, 1.0).double())
    assert orientation_reversing(d5h.p2p[d5h.idx(s=1)], d5h.verts, d5h.faces) is True   # mirror
    assert orientation_reversing(d5h.p2p[d5h.idx(k=1)], d5h.verts, d5h.faces) is False  # rotation
    rotoreflection = d5h.p2p[d5h.idx(k=2, f=1)]
    assert orientation_reversing(rotoreflection, d5h.verts, d5h.faces) is True
    assert float(orientation_score(rotoreflection, d5h.verts, d5h.faces)) == pytest.approx(-1.0)


def test_orientation_survives_bending(d5h):
    # A non-rigid (intrinsic) deformation: bend the prism around the y axis; local votes still hold.
    v = d5h.verts.clone()
    ang = 0.6 * v[:, 2]
    rad = 2.0 + v[:, 0]
    bent = torch.stack([rad * torch.cos(ang) - 2.0, v[:, 1], rad * torch.sin(ang)], 1)
    score = orientation_score(d5h.p2p, bent, d5h.faces)
    assert ((score > 0.9) == ~d5h.reversing).all() and ((score < -0.9) == d5h.reversing).all()


def test_orientation_ignores_collapsed_faces_and_warns_when_ambiguous(d5h):
    V = d5h.verts.shape[0]
    const = torch.zeros(V, dtype=torch.long)
    assert orientation_score(const, d5h.verts, d5h.faces) == 0
    with pytest.warns(UserWarning, match="ambiguous"):
        orientation_reversing(const, d5h.verts, d5h.faces)
    with pytest.raises(ValueError, match="p2p index out of range"):
        orientation_score(torch.full((V,), V), d5h.verts, d5h.faces)
    with pytest.raises(ValueError, match=r"faces must be \[F, 3\]"):
        orientation_score(const, d5h.verts, d5h.faces[:, :2])


def test_kind_of():
    assert kind_of(1, False) == "identity"
    assert kind_of(2, True) == "reflection"
    assert kind_of(5, False) == "rotation" and kind_of(2, False) == "rotation"
    assert kind_of(10, True) == "rotoreflection"
    with pytest.raises(ValueError, match="order 1"):
        kind_of(1, True)
    with pytest.raises(ValueError, match="order must be"):
        kind_of(-1, False)


# ---------------------------------------------------------------------------------------- summary
def test_group_info_to_dict_is_json(d5h):
    info = group_info(d5h.fmaps, d5h.reversing, tol=0.1)
    assert isinstance(info, GroupInfo)
    assert info.name == "D5h" and info.order == 20 and info.identity == d5h.idx()
    kinds = info.kinds
    assert kinds.count("identity") == 1 and kinds.count("reflection") == 6  # 5 σv + σh
    assert kinds.count("rotation") == 4 + 5 and kinds.count("rotoreflection") == 4
    d = json.loads(json.dumps(info.to_dict()))
    assert d["name"] == "D5h" and d["abstract"] == ["dihedral", 10] and len(d["table"]) == 20
    assert d["max_residual"] < 1e-8
    with pytest.raises(Exception):
        info.name = "C1"  # frozen
    assert group_info(info.table, info.reversing).name == "D5h"
