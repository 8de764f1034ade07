import math

import numpy as np
import pytest
import torch
import trimesh
from scipy.spatial import cKDTree

from symtorch.eval import benchmarks as bm
from symtorch.eval import (geodesic_errors, klc_rates, klc_threshold, mesh_rate, normalized_error,
                           orbit_errors, score_group)
from symtorch.geodesics import GeodesicSolver
from symtorch.paths import shared_path


# ---------------------------------------------------------------- synthetic: a mirror-symmetric sphere

@pytest.fixture(scope="module")
def sphere():
    """Unit icosphere (642 vertices): exactly symmetric under x -> -x, y -> -y and z -> -z."""
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    verts, faces = np.asarray(m.vertices), np.asarray(m.faces)
    tree = cKDTree(verts)
    maps = {"id": np.arange(len(verts))}
    for axis, name in enumerate("xyz"):
        flip = verts.copy()
        flip[:, axis] *= -1
        dist, maps[name] = tree.query(flip)
        assert dist.max() < 1e-9
    return GeodesicSolver(verts, faces), maps


def test_perfect_map_has_zero_error_and_rate_one(sphere):
    solver, maps = sphere
    pairs = np.stack([np.arange(0, 642, 7), maps["x"][::7]], axis=1)  # (p, g*(p))
    errors = geodesic_errors(solver, maps["x"], pairs)
    assert errors.shape == (len(pairs),) and torch.all(errors == 0)
    assert float(klc_rates(errors, solver.area)) == 1.0
    assert normalized_error(errors, solver.area) == 0.0


def test_identity_on_reflection_ground_truth_scores_low(sphere):
    solver, maps = sphere
    pairs = np.stack([np.arange(642), maps["x"]], axis=1)
    errors = geodesic_errors((solver.verts, solver.faces), maps["id"], pairs)
    rate = float(klc_rates(errors, solver.area))
    on_plane = float((maps["x"] == np.arange(642)).mean())
    assert rate < 0.35, f"rate {rate:.3f}"  # only points near the symmetry plane are within eps
    assert rate >= on_plane
    assert normalized_error(errors, solver.area) > 0.2


def test_rates_and_threshold():
    area = 20 * math.pi * 4.0  # eps = 2
    assert klc_threshold(area) == pytest.approx(2.0)
    rates = klc_rates(torch.tensor([[0.0, 1.9, 2.0, 5.0], [0.0, 0.0, 0.0, 0.0]]), area)
    torch.testing.assert_close(rates, torch.tensor([0.5, 1.0], dtype=torch.float64))
    assert float(klc_rates(np.array([0.5, 1.5]), area, eps=1.0)) == 0.5
    assert mesh_rate([0.5, 0.75, 0.76, 1.0]) == 0.5  # strictly above beta
    assert mesh_rate([0.5, 0.9], beta=0.4) == 1.0
    assert normalized_error([1.0, 3.0], 16.0) == pytest.approx(0.5)


def test_orbit_errors(sphere):
    solver, maps = sphere
    a, b, c = np.flatnonzero(np.abs(solver.verts[:, 0]) > 0.3)[[0, 10, 20]]  # off the plane
    orbits = [np.array([a, maps["x"][a]]), np.array([b, maps["x"][b]]), np.array([c])]
    # The reflection maps each pair onto the other element; the fixed point is not on the plane,
    # so it is moved: its error is the distance to its mirror image.
    err = orbit_errors(solver, maps["x"], orbits)
    assert err.shape == (5,) and torch.all(err[:4] == 0) and err[4] > 0.1
    # The identity leaves everything in place: wrong for orbits unless scored as the identity.
    assert torch.all(orbit_errors(solver, maps["id"], orbits)[:4] > 0.1)
    assert torch.all(orbit_errors(solver, maps["id"], orbits, identity=True) == 0)


def test_hungarian_matching_finds_the_permutation(sphere):
    solver, maps = sphere
    true = [maps[k] for k in ("id", "x", "y", "z")]
    detected = torch.as_tensor(np.stack([maps[k] for k in ("z", "id", "y", "x")]))
    s = score_group(true, detected, solver)
    assert (s.found, s.missed, s.spurious) == (4, 0, 0)
    assert [(t, d) for t, d, _ in s.matches] == [(0, 1), (1, 3), (2, 2), (3, 0)]
    assert torch.all(s.errors == 0) and s.cost.shape == (4, 4)


def test_group_score_counts_missed_and_spurious(sphere):
    solver, maps = sphere
    g = torch.Generator().manual_seed(0)
    random_map = torch.randperm(642, generator=g).numpy()
    true = [maps[k] for k in ("id", "x", "y", "z")]
    s = score_group(true, [maps["z"], random_map, maps["id"], maps["x"]], solver, n_points=50)
    assert (s.found, s.missed, s.spurious) == (3, 1, 1), s.cost
    assert torch.isinf(s.errors[2])  # "y" was not found
    empty = score_group(true, [], solver)
    assert (empty.found, empty.missed, empty.spurious) == (0, 4, 0)


def test_value_errors(sphere):
    solver, maps = sphere
    with pytest.raises(ValueError, match=r"p2p must be \[V\]"):
        geodesic_errors(solver, maps["x"][:-1], np.array([[0, 1]]))
    with pytest.raises(ValueError, match="pairs must be"):
        geodesic_errors(solver, maps["x"], np.array([0, 1]))
    with pytest.raises(ValueError, match="pairs out of range"):
        geodesic_errors(solver, maps["x"], np.array([[0, 642]]))
    with pytest.raises(ValueError, match="mesh must be"):
        geodesic_errors("mesh.off", maps["x"], np.array([[0, 1]]))
    with pytest.raises(ValueError, match="dataset must be one of"):
        bm.load_klc_pairs("FAUST", "tr_reg_000")
    with pytest.raises(ValueError, match="dataset must be one of"):
        bm.list_benchmark("SHREC")


# ---------------------------------------------------------------- real data (skipped where absent)

def _need(*parts):
    if shared_path(*parts) is None:
        pytest.skip(f"shared data absent: {'/'.join(parts)}")


def test_list_benchmark_counts():
    _need("bim_scb_benchmark")
    _need("bcicp_5k")
    counts = {ds: len(bm.list_benchmark(ds)) for ds in bm.DATASETS}
    assert counts == {"SCAPE": 71, "TOSCA": 15, "Watertight": 60, "FAUST": 10,
                      "TOSCA_Isometric": 76, "TOSCA_dense": 15}
    names = [n for n, _ in bm.list_benchmark("TOSCA_Isometric")]
    assert names.index("cat2") < names.index("cat10")  # natural order


def test_scape_pairs():
    _need("bim_scb_benchmark", "SCAPE", "Corrs", "1.pid")
    pairs = bm.load_klc_pairs("SCAPE", "mesh000")
    assert pairs.shape == (36, 2) and pairs.dtype == np.int64  # 14 pairs both ways + 8 fixed
    assert pairs.min() >= 0 and pairs.max() < 12500
    assert bm.load_klc_pairs("SCAPE", "mesh050", include_fixed=False).shape == (28, 2)
    # an involution on its points: (a, b) listed implies (b, a)
    assert {tuple(r) for r in pairs} == {(b, a) for a, b in pairs}


@pytest.mark.parametrize("name, n", [("cat0", 21), ("centaur1", 46), ("david0", 36),
                                     ("victoria0", 36), ("wolf2", 21)])
def test_tosca_pairs(name, n):
    _need("bim_scb_benchmark", "TOSCA", "Corrs")
    pairs = bm.load_klc_pairs("TOSCA", name)
    V = {"cat": 27894, "centaur": 15768, "david": 52565, "victoria": 45659, "wolf": 4344}
    assert pairs.shape == (n, 2) and pairs.min() >= 0
    assert pairs.max() < V[name.rstrip("0123456789")]


def test_dense_pairs_in_range():
    _need("bcicp_5k", "FAUST", "vtx_5k", "corres", "tr_reg_000.vts")
    for ds, name in [("FAUST", "tr_reg_000"), ("TOSCA_Isometric", "dog0")]:
        pairs = bm.load_dense_pairs(ds, name)
        verts, _ = bm.load_mesh(dict(bm.list_benchmark(ds))[name])
        assert pairs.shape == (5000, 2) and pairs.min() >= 0 and pairs.max() < len(verts), name


def test_tosca_dense_pairs():
    _need("tosca_dense_sym_fmaplib", "cat.sym")
    _need("bim_scb_benchmark", "TOSCA", "Meshes", "cat0.off")
    cat = bm.load_tosca_dense_pairs("cat0")
    assert cat.shape == (27894, 2) and (cat[:, 0] == np.arange(27894)).all()
    sym = cat[:, 1]
    assert (sym[sym] == np.arange(27894)).all()  # an exact involution for the cat
    assert bm.load_ground_truth("TOSCA_dense", "cat1").pairs.shape == (27894, 2)
    wolf = bm.load_tosca_dense_pairs("wolf2")  # approximate file: its involutive entries only
    full = dict(map(tuple, wolf))
    assert 0.6 * 4344 < len(wolf) < 4344 and all(full[b] == a for a, b in wolf)
    # the dense maps agree with the sparse KLC points to within a small share of the shape
    verts, _ = bm.load_mesh(dict(bm.list_benchmark("TOSCA_dense"))["cat0"])
    diag = np.linalg.norm(verts.max(0) - verts.min(0))
    klc = bm.load_klc_pairs("TOSCA", "cat0")
    assert np.median(np.linalg.norm(verts[sym[klc[:, 0]]] - verts[klc[:, 1]], axis=1)) < 0.02 * diag


def test_watertight_orbits():
    _need("bim_scb_benchmark", "Watertight", "Corrs", "121.vts")
    assert [bm.watertight_class(i) for i in (1, 20, 21, 121, 142, 400)] == [1, 1, 2, 7, 8, 20]
    octopus = bm.load_orbits(121)
    assert [len(o) for o in octopus] == [8, 8, 1, 1]
    assert [len(o) for o in bm.load_orbits("142", include_fixed=False)] == [4, 4, 4, 4]
    verts, _ = bm.load_mesh(dict(bm.list_benchmark("Watertight"))["121"])
    assert max(o.max() for o in octopus) < len(verts)
    with pytest.raises(FileNotFoundError):
        bm.load_orbits(366)  # vases have no ground truth
    assert bm.load_ground_truth("Watertight", "121").kind == "orbits"


def test_ground_truth_is_nearly_perfect_on_scape():
    """The true pairing, read as a map on its own points, scores rate 1 and zero error."""
    _need("bim_scb_benchmark", "SCAPE", "Meshes", "mesh000.off")
    verts, faces = bm.load_mesh(shared_path("bim_scb_benchmark", "SCAPE", "Meshes", "mesh000.off"))
    pairs = bm.load_klc_pairs("SCAPE", "mesh000")
    solver = GeodesicSolver(verts, faces)
    p2p = np.arange(len(verts))
    p2p[pairs[:, 0]] = pairs[:, 1]
    errors = geodesic_errors(solver, p2p, pairs)
    assert torch.all(errors == 0) and float(klc_rates(errors, solver.area)) == 1.0
    identity = float(klc_rates(geodesic_errors(solver, np.arange(len(verts)), pairs), solver.area))
    assert identity < 0.4, f"identity scores {identity:.3f}"  # mostly the 8 fixed points
