"""symtorch.eval.benchmarks: the loaders of the shared benchmarks (skipped where the data is absent)."""
import numpy as np
import pytest
import torch

from symtorch.eval import benchmarks as bm, geodesic_errors, klc_rates
from symtorch.geodesics import GeodesicSolver
from symtorch.paths import shared_path


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
