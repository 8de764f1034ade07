"""symtorch.detect.group_elements: batched ICP, refinement and verification of the group path's elements."""
import numpy as np
import torch

from symtorch import shapes
from symtorch.units import EPS_KLC


def test_batched_icp_on_device(device):
    """Batched spectral ICP of perturbed quarter turns of the table: the CPU's matrices on ``device``."""
    from symtorch.detect.group_path import batched_icp
    from symtorch.maps import p2p_to_fmap
    from symtorch.spectrum import laplacian_spectrum, band_boundary, solved_bands

    v, f = shapes.table(3)
    s = laplacian_spectrum(v, f, k=30)
    bands = solved_bands(s.evals)
    k0 = band_boundary(bands, 12)
    bands0 = [b for b in bands if b.stop <= k0]
    true = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, shapes.true_symmetries("table"))]
    E = s.evecs[:, :k0]
    C = torch.stack([p2p_to_fmap(p, E, s.mass) for p in true])
    g = torch.Generator().manual_seed(0)
    noisy = C + 0.05 * torch.randn(C.shape, generator=g, dtype=C.dtype)
    src, tgt = torch.arange(0, len(v), 3), torch.arange(len(v))
    ref = batched_icp(noisy, E[src], E[tgt], bands0, n_iter=3, chunk=4)
    got = batched_icp(noisy.to(device), E[src].to(device), E[tgt].to(device), bands0, n_iter=3, chunk=4)
    assert got.device == device and got.shape == C.shape
    torch.testing.assert_close(got.cpu(), ref, atol=1e-8, rtol=0)
    assert float((ref - C).norm(dim=(1, 2)).max()) < float((noisy - C).norm(dim=(1, 2)).min())


def _table_setup():
    """The table (subdivided 3 times), its spectrum, bands, coarse size 24, geodesics, the group
    path's geometry, the true vertex maps and their coarse matrices."""
    from symtorch.detect.group_elements import Geometry
    from symtorch.geodesics import GeodesicSolver
    from symtorch.maps import p2p_to_fmap
    from symtorch.procrustes import block_project
    from symtorch.sampling import farthest_point_sampling
    from symtorch.spectrum import band_boundary, laplacian_spectrum, solved_bands

    v, f = shapes.table(3)
    s = laplacian_spectrum(v, f, k=40)
    bands = solved_bands(s.evals)
    k0 = band_boundary(bands, 24)
    bands0 = [b for b in bands if b.stop <= k0]
    vu = v * s.scale
    solver = GeodesicSolver(vu, f)
    points = farthest_point_sampling(torch.as_tensor(vu), 8)
    geo = Geometry(vu, s, points.numpy(), solver.distances_from(points.numpy()).double(), n_samples=300)
    mats = shapes.true_symmetries("table")
    true = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, mats)]
    fm = [block_project(p2p_to_fmap(p, s.evecs[:, :k0], s.mass), bands0) for p in true]
    return v, s, bands, k0, bands0, solver, geo, mats, true, fm


def test_a_less_distorted_alternative_replaces_its_element_and_remakes_its_products():
    """The table's C4v with one mirror and its product with the other mirror (the half turn) given as
    noisy coarse maps: the exact version of the mirror, given as its alternative, replaces it, and the
    half turn is re-made from it; without the alternative both stay noisy. Mirrors and half turn
    because the subdivided table keeps them exactly; it is not 4-fold symmetric, so an exact quarter
    turn distorts about as much as a noisy element and a product made from one replaces nothing."""
    from symtorch.detect.group_elements import CoarseElement, upsample_elements
    from symtorch.procrustes import block_project

    v, s, bands, k0, bands0, solver, geo, mats, true, fm = _table_setup()
    # element a (the mirror y -> -y) and c = a∘b (the half turn) noisy; b (the mirror x -> -x) exact
    a, b = (j for j, M in enumerate(mats) if np.linalg.det(M) < 0 and np.allclose(M, np.diag(np.diag(M))))
    prod = true[a][true[b]]
    c = next(j for j, p in enumerate(true) if bool((p == prod).all()))
    assert c not in (0, a, b)
    g = torch.Generator().manual_seed(0)
    # a: a wrong map, distorted well past EXACT_ENOUGH * max_distortion, under which an element keeps
    # its map; c: the same map as the truth, only more distorted (the case
    # alternatives are for); c's noise must change its vertex map
    noisy = {j: block_project(fm[j] + w * torch.randn(fm[j].shape, generator=g, dtype=fm[j].dtype), bands0)
             for j, w in ((a, 2.0), (c, 0.6))}

    def coarse_of(C):
        return CoarseElement(C, geo.p2p(C, geo.score_samples), 0.1)

    coarse = [CoarseElement(torch.eye(k0, dtype=s.evecs.dtype), geo.score_samples.clone(), 0.0)]
    coarse += [coarse_of(noisy.get(j, fm[j])) for j in range(1, len(true))]
    plain, _, _ = upsample_elements(coarse, geo, solver, bands, k0, k0, 10.0)
    fixed, _, _ = upsample_elements(coarse, geo, solver, bands, k0, k0, 10.0, {a: [coarse_of(fm[a])]})

    def error(p2p, j):  # mean distance to the true image (unit-area shape)
        return float((geo.verts[p2p] - geo.verts[true[j]]).norm(dim=1).mean())

    assert fixed[a].distortion < plain[a].distortion
    assert error(fixed[a].p2p, a) < 1.5 * error(geo.p2p(fm[a]), a) < error(plain[a].p2p, a)
    assert fixed[c].distortion < plain[c].distortion  # re-made from the fixed mirror
    assert any(bool((fixed[c].p2p == p).all()) for p in (fixed[a].p2p[fixed[b].p2p], fixed[b].p2p[fixed[a].p2p]))
    # the identity and b keep their maps; a product of the fixed mirror replaces an element only where
    # it is less distorted (the quarter turns may be re-made, never made worse)
    assert all(bool((fixed[i].p2p == plain[i].p2p).all()) for i in (0, b))
    assert all(fixed[i].distortion <= plain[i].distortion for i in range(len(plain)))


def test_an_alternative_that_is_another_element_joins_and_the_maps_are_closed():
    """The table's C4v given as its four rotations, with one mirror as a coarse duplicate of the
    identity (as the crude coarse maps of a bent slab's cap swaps read): upsampling finds it is an
    element of its own, appends it and closes the vertex maps into all eight; an alternative that
    is the same map as an element (the identity again) is not appended. The same from a near miss
    of the coarse screen; a wrong near miss (the mirror's matrix plus noise) is not appended."""
    from symtorch.detect.group_elements import CoarseElement, upsample_elements
    from symtorch.procrustes import block_project

    v, s, bands, k0, bands0, solver, geo, mats, true, fm = _table_setup()
    rot = [j for j, M in enumerate(mats) if np.linalg.det(M) > 0]
    mirror = next(j for j, M in enumerate(mats) if np.linalg.det(M) < 0)

    def coarse_of(C):
        return CoarseElement(C, geo.p2p(C, geo.score_samples), 0.1)

    # at k0 = kf = 24 the quarter turns read ~0.32 (no refined basis to grow into): screen at 0.5
    eye = CoarseElement(torch.eye(k0, dtype=s.evecs.dtype), geo.score_samples.clone(), 0.0)
    coarse = [eye] + [coarse_of(fm[j]) for j in rot if j != 0]
    plain, _, _ = upsample_elements(coarse, geo, solver, bands, k0, k0, 0.5)
    assert len(plain) == 4
    same, _, _ = upsample_elements(coarse, geo, solver, bands, k0, k0, 0.5, {0: [coarse_of(fm[0])]})
    assert len(same) == 4
    whole, _, _ = upsample_elements(coarse, geo, solver, bands, k0, k0, 0.5, {0: [coarse_of(fm[mirror])]})
    assert len(whole) == 8
    assert bool((whole[0].p2p == torch.arange(len(v))).all())  # the identity stays first
    missed, _, _ = upsample_elements(coarse, geo, solver, bands, k0, k0, 0.5, near_misses=[coarse_of(fm[mirror])])
    assert len(missed) == 8  # a mirror the coarse screen rejected, measured exactly
    wrong = coarse_of(block_project(fm[mirror] + torch.randn(fm[mirror].shape, generator=torch.Generator().manual_seed(0),
                                                             dtype=fm[mirror].dtype), bands0))
    assert len(upsample_elements(coarse, geo, solver, bands, k0, k0, 0.5, near_misses=[wrong]).elements) == 4
    for p in true:  # every true element is found once, within a vertex or two
        gaps = torch.stack([(geo.verts[e.p2p] - geo.verts[p]).norm(dim=1).mean() for e in whole])
        assert int((gaps < 0.5 * EPS_KLC).sum()) == 1, gaps.tolist()


def test_the_coarse_closure_holds_back_elements_far_more_distorted_than_the_rest():
    """A spurious element just under the screen, composed with a whole group, would bring its coset
    through the screen (each product as distorted as itself): it is no factor of the coarse
    closure, and the closure then reports itself not closed, so the exact maps close it instead."""
    from types import SimpleNamespace

    from symtorch.detect.config import GroupConfig
    from symtorch.detect.group_elements import CoarseElement, CoarseElements

    geo = SimpleNamespace(evecs=torch.zeros(4, 3, dtype=torch.float64), score_samples=torch.arange(4))
    coarse = CoarseElements(geo, [range(0, 1), range(1, 3)], 3, GroupConfig())

    def with_distortions(ds):
        coarse.elements = coarse.elements[:1] + [CoarseElement(torch.eye(3), torch.arange(4), d) for d in ds]
        return coarse.factors()

    # twenty near-exact elements and four at 0.24: those four are held back
    assert with_distortions([0.02] * 19 + [0.24] * 4) == list(range(20))
    # one size, however large (a bent shape's group), or everything small: all compose
    assert with_distortions([0.2, 0.22, 0.19, 0.23]) == list(range(5))
    assert with_distortions([0.001, 0.002, 0.03]) == list(range(4))
    # too few to tell a typical element from an outlier
    assert with_distortions([0.01, 0.24]) == [0, 1, 2]


def test_vertex_to_point_distortion_removes_the_vertex_rounding():
    """The ellipsoid's three mirrors on a jittered triangulation (no symmetry maps it onto itself):
    the vertex maps of the exact mirrors distort by the rounding of each image to a vertex; as
    vertex-to-point maps they distort about half as much (0.066 against 0.128). Without faces nothing changes."""
    from symtorch.detect.group_elements import Element, Geometry, point_map_distortions, upsample_elements
    from symtorch.geodesics import GeodesicSolver
    from symtorch.maps import p2p_to_fmap
    from symtorch.sampling import farthest_point_sampling
    from symtorch.spectrum import laplacian_spectrum
    from shapes import jitter

    v0, f = shapes.ellipsoid(3)
    v = jitter(np.asarray(v0), np.asarray(f), 0.45)
    s = laplacian_spectrum(v, f, k=40)
    vu = v * s.scale
    solver = GeodesicSolver(vu, f)
    points = farthest_point_sampling(torch.as_tensor(vu), 8)
    fields = solver.distances_from(points.numpy()).double()
    mats = [np.diag(d) for d in ([-1.0, 1, 1], [1, -1.0, 1], [1, 1, -1.0])]
    maps = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, mats)]  # nearest vertex to each image
    K = 30
    for faces, fewer in ((f, True), (None, False)):
        geo = Geometry(vu, s, points.numpy(), fields, n_samples=300, faces=faces)
        src = geo.samples[:10].numpy()
        D0 = solver.distances_from(src)[:, geo.score_samples]
        elements = [Element(torch.eye(K, dtype=s.evecs.dtype), torch.arange(len(v)), 0.0)]
        for p in maps:
            d = float((solver.distances_from(p[src].numpy())[:, p[geo.score_samples]] - D0).abs().mean() / EPS_KLC)
            elements.append(Element(p2p_to_fmap(p, s.evecs[:, :K], s.mass), p, d))
        out = point_map_distortions(elements, geo, solver)
        assert out[0] is elements[0]
        before, after = np.array([e.distortion for e in elements[1:]]), np.array([e.distortion for e in out[1:]])
        if fewer:
            assert (before > 0.02).all() and (after <= before).all() and after.mean() < 0.6 * before.mean()
        else:
            assert (after == before).all()


def test_two_elements_on_one_map_are_seen():
    """The exact stage closes the maps again where two coarse elements upsampled onto one map."""
    from symtorch.detect.group_elements import Element, _Maps

    v, s, bands, k0, bands0, solver, geo, mats, true, fm = _table_setup()
    els = [Element(f, p, 0.0) for f, p in zip(fm, true)]
    assert not _Maps(list(els), geo).has_duplicates()
    assert _Maps(els + [els[3]], geo).has_duplicates()
