"""symtorch.groups.algebra: the conventions (ALGORITHM §2), tables, the group axioms, closure.

Fixtures: ``d5h`` / ``d4h`` (``tests/prisms.py``), exact vertex permutations of prisms and their matrices.
"""
from __future__ import annotations

import math

import pytest
import torch

from symtorch.groups import (abstract_group, cayley_table, check_group, closure, compose_fmap,
                             compose_p2p, element_orders, identify_group, identity_index,
                             inverse_fmap, inverse_p2p, inverses)

from prisms import axis_rotation, fmap, is_latin


# ----------------------------------------------------------------------------------- conventions
def test_prism_matrices_are_exact_orthogonal_representation(d5h):
    eye = torch.eye(d5h.K, dtype=torch.float64)
    err = (d5h.fmaps.mT @ d5h.fmaps - eye).abs().max()
    assert err < 1e-8, f"K={d5h.K}: orthogonality error {err:.2e}"
    d = torch.cdist(d5h.fmaps.flatten(1), d5h.fmaps.flatten(1)) + 1e9 * torch.eye(20)
    assert d.min() > 0.5, "the 20 matrices must be distinct (faithful representation)"


def test_composition_order_is_reversed_for_matrices(d5h):
    g, h = d5h.idx(k=1), d5h.idx(s=1)  # rotation and mirror: they do not commute
    gh = compose_p2p(d5h.p2p[g], d5h.p2p[h])
    assert torch.equal(gh, d5h.p2p[g][d5h.p2p[h]])
    C_gh = fmap(d5h.spec, d5h.K, gh)
    C_g, C_h = d5h.fmaps[g], d5h.fmaps[h]
    torch.testing.assert_close(C_gh, C_h @ C_g, atol=1e-10, rtol=0)
    torch.testing.assert_close(compose_fmap(C_g, C_h), C_gh, atol=1e-10, rtol=0)
    assert (C_gh - C_g @ C_h).abs().max() > 0.1, "the pin is vacuous if g and h commute"


def test_composition_broadcasts_over_batch(d5h):
    out = compose_p2p(d5h.p2p[:, None], d5h.p2p[None])  # [G, G, V]: out[a, b] = a ∘ b
    assert out.shape == (20, 20, d5h.p2p.shape[1])
    assert torch.equal(out[3, 7], d5h.p2p[3][d5h.p2p[7]])
    C = compose_fmap(d5h.fmaps[:, None], d5h.fmaps[None])
    torch.testing.assert_close(C[3, 7], d5h.fmaps[7] @ d5h.fmaps[3])


def test_inverses_of_maps_and_matrices(d5h):
    V = d5h.p2p.shape[1]
    inv = inverse_p2p(d5h.p2p)  # batched
    ar = torch.arange(V).expand(20, V)
    assert torch.equal(compose_p2p(d5h.p2p, inv), ar) and torch.equal(compose_p2p(inv, d5h.p2p), ar)
    assert torch.equal(inv, torch.argsort(d5h.p2p, dim=-1))
    g = d5h.idx(k=2, f=1)  # rotoreflection of order 10
    torch.testing.assert_close(fmap(d5h.spec, d5h.K, inv[g]), inverse_fmap(d5h.fmaps[g]))
    torch.testing.assert_close(d5h.fmaps[g] @ inverse_fmap(d5h.fmaps[g]),
                               torch.eye(d5h.K, dtype=torch.float64))


def test_inverse_p2p_nearest_fallback_for_non_bijective_map(d5h):
    p = d5h.p2p[d5h.idx(k=1)].clone()
    a = int(d5h.p2p[d5h.idx(k=1)][0])
    p[1] = p[0]  # vertex 1 now shares vertex 0's image: not a permutation
    with pytest.raises(ValueError, match="not a permutation"):
        inverse_p2p(p)
    inv = inverse_p2p(p, points=d5h.verts)
    assert inv.shape == p.shape
    assert int(p[inv[a]]) == a, "an image vertex gets one of its preimages"
    # every vertex j gets an i whose image p[i] is the nearest image vertex to j
    assert (torch.cdist(d5h.verts[p[inv]], d5h.verts).diagonal()
            <= torch.cdist(d5h.verts, d5h.verts[p]).min(1).values + 1e-6).all()


def test_element_orders_from_matrices_and_table(d5h):
    expect = []
    for k, s, f in d5h.labels:
        rot = 5 // math.gcd(k, 5)
        expect.append(2 if s else (rot if not f else math.lcm(2, rot)))
    expect = torch.tensor(expect)
    assert torch.equal(element_orders(d5h.fmaps), expect)
    table, _ = cayley_table(d5h.fmaps)
    assert torch.equal(element_orders(table), expect)
    assert identity_index(d5h.fmaps) == d5h.idx() == identity_index(table)


# ------------------------------------------------------------------------------------------ tables
def test_cayley_table_reads_row_after_column(d5h):
    table, residual = cayley_table(d5h.fmaps)
    assert residual.max() < 1e-8
    assert is_latin(table)
    for a in range(20):
        for b in range(20):  # table[a, b] = a ∘ b = "apply b, then a" = p2p_a[p2p_b]
            assert table[a, b] == d5h.index(d5h.p2p[a][d5h.p2p[b]]), (a, b)
    assert not torch.equal(table, table.mT), "D5h is not abelian: the layout matters"


def test_check_group_and_inverses_on_full_group(d5h):
    table, residual = cayley_table(d5h.fmaps, tol=0.1)
    check = check_group(table, residual)
    assert check.is_group and check.closed and check.associative, str(check)
    assert check.problems == [] and str(check) == "group"
    inv = inverses(table)
    for a in range(20):
        assert torch.equal(d5h.p2p[int(inv[a])], inverse_p2p(d5h.p2p[a])), a


def test_check_group_reports_a_set_that_is_not_closed(d5h):
    idx = [d5h.idx(), d5h.idx(k=1), d5h.idx(s=1)]  # r∘r = r^2 is missing
    table, residual = cayley_table(d5h.fmaps[idx], tol=0.1)
    check = check_group(table, residual)
    assert not check.is_group and not check.closed
    assert check.has_identity
    assert any("not closed" in p and "1∘1" in p for p in check.problems), check.problems


def test_check_group_reports_non_associative_and_missing_identity():
    # A Latin square with identity 0 that is not associative (the smallest loop, order 5).
    loop = torch.tensor([[0, 1, 2, 3, 4], [1, 0, 3, 4, 2], [2, 4, 0, 1, 3], [3, 2, 4, 0, 1],
                         [4, 3, 1, 2, 0]])
    check = check_group(loop)
    assert check.closed and check.has_identity and check.has_inverses
    assert not check.associative and not check.is_group
    assert any("not associative" in p for p in check.problems)
    no_e = torch.tensor([[1, 1], [0, 0]])  # a∘b = 1 - a: no identity
    check = check_group(no_e)
    assert not check.has_identity and not check.is_group
    with pytest.raises(ValueError, match="not a group"):
        identify_group(no_e, torch.tensor([False, False]))


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_table_orders_and_closure_tolerate_noise(d5h, dtype):
    g = torch.Generator().manual_seed(0)
    noise = torch.randn(d5h.fmaps.shape, generator=g, dtype=torch.float64)
    noisy = (d5h.fmaps + 0.02 * noise).to(dtype)
    exact_table = cayley_table(d5h.fmaps).table
    table, residual = cayley_table(noisy, tol=0.25)
    assert residual.dtype == dtype and residual.max() < 0.25
    assert torch.equal(table, exact_table), f"dtype={dtype}"
    assert identify_group(table, d5h.reversing) == "D5h"
    out = closure(noisy[[d5h.idx(k=1), d5h.idx(s=1), d5h.idx(f=1)]])
    assert out.converged and len(out.fmaps) == 20 and out.fmaps.dtype == dtype
    assert torch.equal(element_orders(noisy[:11]), element_orders(exact_table)[:11])


# -------------------------------------------------------------------------------------- closure
def test_closure_recovers_d5h_from_generators(d5h):
    gens = [d5h.idx(k=1), d5h.idx(s=1), d5h.idx(f=1)]
    out = closure(d5h.fmaps[gens], tol=0.1)
    assert out.converged and len(out.fmaps) == 20
    assert out.added.tolist() == [False] * 3 + [True] * 17
    torch.testing.assert_close(out.fmaps[:3], d5h.fmaps[gens])
    d = torch.cdist(out.fmaps.flatten(1), d5h.fmaps.flatten(1))
    assert (d.min(1).values < 1e-8).all() and len(set(d.argmin(1).tolist())) == 20
    assert check_group(cayley_table(out.fmaps, tol=0.1).table).is_group


def test_closure_of_a_group_adds_nothing_and_stops_on_runaway(d5h):
    out = closure(d5h.fmaps, tol=0.1)
    assert len(out.fmaps) == 20 and not out.added.any() and out.converged
    irrational = axis_rotation([0, 0, 1], 1.0)[None]  # infinite order: the set never closes
    with pytest.warns(UserWarning, match="max_order"):
        out = closure(irrational, tol=1e-6, max_order=30)
    assert not out.converged and len(out.fmaps) > 30


def test_closure_builds_icosahedral_groups():
    phi = (1 + 5 ** 0.5) / 2
    a = axis_rotation([0, 1, phi], 2 * math.pi / 5)  # through an icosahedron vertex
    b = axis_rotation([0, 0, 1], math.pi)            # through an edge midpoint, not ⟂ to a's axis
    I60 = closure(torch.stack([a, b]), tol=1e-6).fmaps
    assert len(I60) == 60
    rev = torch.linalg.det(I60) < 0
    assert identify_group(cayley_table(I60).table, rev) == "I"
    Ih = torch.cat([I60, -I60])
    table, residual = cayley_table(Ih)
    assert residual.max() < 1e-9
    assert identify_group(table, torch.linalg.det(Ih) < 0) == "Ih"
    assert abstract_group(table) == ("direct", ("alternating", 5), ("cyclic", 2))


def test_input_validation():
    with pytest.raises(ValueError, match=r"fmaps must be \[G, K, K\]"):
        cayley_table(torch.zeros(3, 4, 5))
    with pytest.raises(ValueError, match="empty"):
        closure(torch.zeros(0, 3, 3))
    with pytest.raises(ValueError, match="integer table"):
        check_group(torch.zeros(3, 4, dtype=torch.long))
    with pytest.raises(ValueError, match=r"entries must lie in \[-1, 1\]"):
        check_group(torch.tensor([[0, 2], [1, 0]]))
    with pytest.raises(ValueError, match="no identity"):
        inverses(torch.tensor([[1, 1], [0, 0]]))
    with pytest.raises(ValueError, match="integer vertex indices"):
        compose_p2p(torch.zeros(4), torch.zeros(4, dtype=torch.long))
    with pytest.raises(ValueError, match="g maps V=4 vertices but h maps V=3"):
        compose_p2p(torch.zeros(4, dtype=torch.long), torch.zeros(3, dtype=torch.long))
    with pytest.raises(ValueError, match="C_g is K=3 but C_h is K=4"):
        compose_fmap(torch.eye(3), torch.eye(4))
    with pytest.raises(ValueError, match="floating-point"):
        inverse_fmap(torch.eye(3, dtype=torch.long))
    with pytest.raises(ValueError, match=r"points must be \[V, D\]"):
        inverse_p2p(torch.zeros(4, dtype=torch.long), points=torch.zeros(3, 3))
    with pytest.warns(UserWarning, match="identity"):
        identity_index(2 * torch.eye(3, dtype=torch.float64)[None])
    with pytest.warns(UserWarning, match="duplicates"):
        cayley_table(torch.eye(3, dtype=torch.float64).expand(2, 3, 3).contiguous(), tol=0.1)


def test_group_algebra_on_device(d5h, device):
    """Tables, orders, inverses, closure and the name from matrices on ``device``: as on CPU."""
    fmaps, rev = d5h.fmaps.to(device), d5h.reversing.to(device)
    cay = cayley_table(fmaps)
    assert cay.table.device == fmaps.device
    ref = cayley_table(d5h.fmaps)
    assert torch.equal(cay.table.cpu(), ref.table)
    assert torch.equal(element_orders(fmaps).cpu(), element_orders(d5h.fmaps))
    assert torch.equal(inverses(cay.table).cpu(), inverses(ref.table))
    assert check_group(cay.table).is_group
    gens = fmaps[[d5h.idx(k=1), d5h.idx(s=1), d5h.idx(f=1)]]
    cl = closure(gens)
    assert len(cl.fmaps) == 20 and cl.fmaps.device == fmaps.device
    assert identify_group(cay.table, rev) == "D5h"
    p2p = d5h.p2p.to(device)
    assert torch.equal(compose_p2p(p2p[3], p2p[7]).cpu(), d5h.p2p[3][d5h.p2p[7]])
