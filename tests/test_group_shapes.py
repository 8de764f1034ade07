"""The group path on a wider set of shapes with exactly known groups: D_nh star slabs
of several n and thicknesses, C_nv balls with 4-12 drooping arms, chiral C_n, D_n twisted blades,
a subdivided box, shapes built with trimesh (extruded polygons, unions of primitives), jittered
and bent versions, convex polyhedra (Td, Oh, D2d, D_nd antiprisms, Ci) and pinwheel prisms (C_nh) (``tests/shapes.py``, ``GROUP_SHAPES``; the swept arms, whose
mirrors hold only approximately, are measured in ``scripts/group_shapes_table.py``, not checked).

Each detected element is matched to a true one (``eval.groups.element_rates``: the share of 100
evenly spaced vertices whose image lies within sqrt(area / (20 pi)) of the true image), no element
may be spurious, and the group's name, order, element orders and orientation are the truth's.
The quick default run has the thin four-pointed star (the mirror between the caps) and the box, CI
adds the thin five-pointed star, the eight arms, the six arms bent at R = 3 (the merged-band
retry), the extruded star (the closure's held-back outliers), the jittered chiral arms (the
near-mirror rule off a symmetric triangulation), the regular hexagonal prism (the dipole
constraints), the pentagonal antiprism and the centrosymmetric solid (inversions named from fixed
points), the flat trigonal antiprism (a near-symmetric index-2 coset) and the nonagonal prism (not
continuous: the heat levels) and the four arms bent at R = 4 (a coset that only nearly holds:
the merged attempt's full orthogonal maps) and the chiral five arms bent at R = 3 (the closed
subset the coset rule leaves whole; ``extended``); the rest is ``slow``. Eight rows are checked
ACVD-remeshed too (``REMESHED``, with pyacvd; extended).
"""
import warnings

import numpy as np
import pytest
import torch

from symtorch import detect_symmetries
from symtorch.eval.groups import element_rates
from symtorch.geodesics import GeodesicSolver
from symtorch.groups import check_group
from symtorch.shapes import symmetry_maps

from shapes import GROUP_SHAPES, bend, matrix_order, star_slab, subdivided_box  # tests/shapes.py

pytestmark = pytest.mark.usefixtures("one_thread")

QUICK = {"star4_thin", "box"}  # the quick run; CI (extended) adds these two, the rest is slow
EXTENDED = {"star5_thin", "arms8", "star4_h035_bent", "star8_thin_bent", "arms6_bent3", "star5_extruded",
            "chiral8_jitter", "hex_prism", "antiprism5", "antiprism3_flat", "centrosymmetric", "nonagon_prism",
            "arms4_bent4", "chiral5_bent3"}


def _params():
    for name, build, group, order, radius in GROUP_SHAPES:
        marks = () if name in QUICK else (pytest.mark.extended,) if name in EXTENDED else (pytest.mark.slow,)
        yield pytest.param(build, group, order, radius, id=name, marks=marks)


@pytest.mark.parametrize("build,group,order,radius", list(_params()))
def test_every_element_of_the_group_is_found(build, group, order, radius):
    v0, f, mats = build()
    v = bend(v0, radius) if radius else v0
    true_maps = symmetry_maps(v0, mats)  # a bend keeps the vertex correspondence
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = detect_symmetries(v, f)  # mode="auto", as a user would call it
    assert len(caught) <= 1, [str(w.message) for w in caught]
    assert not res.continuous
    assert (res.group.name, res.group.order) == (group, order), (res.group.name, res.diagnostics)
    assert check_group(torch.as_tensor(res.group.table)).is_group
    sc, rates = element_rates(GeodesicSolver(v, f), true_maps, res.p2ps)
    assert sc.found == order and sc.spurious == 0, f"found {sc.found}/{order}, spurious {sc.spurious}"
    assert rates.min() >= 0.95, f"per-element rates {rates.tolist()}"
    # each element's order and orientation are those of the true symmetry its map matches
    agree = (res.p2ps[:, None] == torch.as_tensor(true_maps)[None]).double().mean(-1)  # [G, G]
    for s, j, rev in zip(res.symmetries, agree.argmax(1).tolist(), res.group.reversing.tolist()):
        R = mats[j]
        assert s.order == matrix_order(R), f"order {s.order} vs true {matrix_order(R)}"
        assert bool(rev) == (np.linalg.det(R) < 0), f"reversing {rev} vs det {np.linalg.det(R):.0f}"


def test_a_thin_slab_keeps_both_caps_in_its_invariant_points():
    """The corners of the two caps lie closer than the suppression radius; both are kept, so the
    point set is a union of orbits of the top/bottom mirror too."""
    from symtorch.detect.candidates import invariant_points
    from symtorch.spectrum import laplacian_spectrum

    v, f, mats = star_slab(5, 0.25)
    spec = laplacian_spectrum(v, f, k=60)
    pts = invariant_points(spec.evals, spec.evecs, f, v * spec.scale)
    sigma_h = symmetry_maps(v, [np.diag([1.0, 1.0, -1.0])])[0]
    assert set(sigma_h[pts].tolist()) == set(pts.tolist())
    assert (np.abs(v[pts, 2]) > 0.1).sum() >= 10  # corners on both caps, not only the rim


def test_tuples_grow_until_every_band_is_pinned():
    """The box's corners lie near the zeros of an eigenfunction every mirror negates: a tuple of
    corners alone leaves that band's sign to noise, and is grown by a point that holds it."""
    from symtorch.detect.candidates import Pinning, source_tuples
    from symtorch.detect.constraints import disk_coefficients
    from symtorch.detect.group_path import group_basis, invariant_point_set
    from symtorch.geodesics import GeodesicSolver as Solver
    from symtorch.spectrum import laplacian_spectrum

    v, f, _ = subdivided_box()
    spec = laplacian_spectrum(v, f, k=60)
    basis = group_basis(spec.evals, 20, 40)
    vu = v * spec.scale
    pts = invariant_point_set(spec, f, vu, Solver(vu, f), 40)
    pin = Pinning(disk_coefficients(spec.evecs[:, :basis.k0], spec.mass, pts.fields), basis.bands0)
    plain = source_tuples(pts.dist, basis.m + 1, 3)
    grown = source_tuples(pts.dist, basis.m + 1, 3, pinning=pin)
    assert min(pin.strength(t) for t in plain) < 0.3
    assert all(pin.strength(t) >= 0.3 for t in grown) and max(len(t) for t in grown) > basis.m + 1


def test_one_warning_per_detection(monkeypatch):
    """Every round of the closure stops at max_order and warns: where the exact vertex maps then
    close, the group is whole and nothing is said; where they do not either, the detection says
    so once, and what it means for the group."""
    import symtorch.detect.group_elements as ge
    from symtorch.detect.group_path import detect_group
    from symtorch.spectrum import laplacian_spectrum

    real = ge.closure

    def noisy(*args, **kwargs):
        warnings.warn("closure exceeded max_order=38 elements: continuous symmetry, or tol=0.25 "
                      "below the noise of the matrices", stacklevel=2)
        return real(*args, **kwargs)._replace(converged=False)

    monkeypatch.setattr(ge, "closure", noisy)
    v, f, _ = star_slab(4, 0.25)
    spectrum = laplacian_spectrum(v, f, k=60)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = detect_group(v, f, spectrum, k=20, k_refine=40)
    assert not caught, [str(w.message) for w in caught]
    assert (res.group.name, res.group.order) == ("D4h", 16)

    real_close = ge._Maps.close
    monkeypatch.setattr(ge._Maps, "close", lambda *a, **k: real_close(*a, **k) and False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = detect_group(v, f, spectrum, k=20, k_refine=40)
    assert len(caught) == 1, [str(w.message) for w in caught]
    msg = str(caught[0].message)
    assert res.group.name in msg and "may lack elements" in msg


#: rows whose triangulation, ACVD-remeshed, no symmetry preserves, and which came out wrong there:
#: a hexagonal prism's flat caps put finest-scale HKS extrema at random spots (persistent sources),
#: near-symmetric halves under the vertex rounding of every element (vertex-to-point distortions)
REMESHED = {"hex_prism": "D6h", "pinwheel3": "C3h", "centrosymmetric": "Ci", "antiprism3_flat": "D3d",
            "hept_prism": "D7h", "antiprism6": "D6d",  # the continuous test's heat levels
            "oct_prism_extruded": "D8h",  # no noise extremum let through by the suppression's orbit rule
            "s6_solid": "S6"}  # Oh before: 42 near-symmetries that change the heat levels


@pytest.mark.extended
@pytest.mark.parametrize("name", sorted(REMESHED))
def test_a_remeshed_shape_keeps_its_whole_group(name):
    pytest.importorskip("pyacvd", reason="ACVD remeshing needs pyacvd (pip install symtorch[remesh])")
    from symtorch.remesh import remesh_acvd

    build, group, order = next((b, g, o) for n, b, g, o, _ in GROUP_SHAPES if n == name)
    v0, f0, mats = build()
    v, f = remesh_acvd(v0, f0, n_verts=3000, subdivide=3)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        res = detect_symmetries(v, f)
    assert (res.group.name, res.group.order) == (group, order)
    sc, rates = element_rates(GeodesicSolver(v, f), symmetry_maps(v, mats), res.p2ps)
    assert sc.found == order and sc.spurious == 0 and rates.min() >= 0.95


@pytest.mark.extended
def test_a_remeshed_prism_cap_has_no_persistent_noise():
    """ACVD-remeshed, the hexagonal prism's caps put extrema of the finest HKS scale at no
    symmetric spot (every true image of them far from the point set); none of them is persistent,
    while the side edges' midpoints and the cap centres are."""
    pytest.importorskip("pyacvd", reason="ACVD remeshing needs pyacvd (pip install symtorch[remesh])")
    from shapes import extruded_polygon
    from symtorch.detect.candidates import invariant_points, persistent_points
    from symtorch.remesh import remesh_acvd
    from symtorch.spectrum import laplacian_spectrum
    from symtorch.units import mean_edge

    v0, f0, mats = extruded_polygon(6, 0.5, None)
    v, f = remesh_acvd(v0, f0, n_verts=3000, subdivide=3)
    spec = laplacian_spectrum(v, f, k=60)
    vu = v * spec.scale
    pts = invariant_points(spec.evals, spec.evecs, f, vu)
    keep = persistent_points(spec.evals, spec.evecs, f, vu, pts)
    maps, e = symmetry_maps(v, mats), mean_edge(v, f)
    closed = np.array([all(np.linalg.norm(v[pts] - v[g[p]], axis=1).min() < 3 * e for g in maps) for p in pts])
    assert (~closed).sum() >= 5  # the noise this is about
    assert not (keep & ~closed).any()
    assert keep.sum() >= 8
