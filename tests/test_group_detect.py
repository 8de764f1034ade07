"""Whole symmetry groups (issue 4): symtorch.detect.group_path, the 'group'/'auto' modes of detect_symmetries."""
import json
import warnings
from itertools import permutations

import numpy as np
import pytest
import torch
from scipy.spatial import cKDTree

from symtorch import shapes
from symtorch.detect import detect_symmetries
from symtorch.eval import klc_threshold
from symtorch.geodesics import GeodesicSolver
from symtorch.cluster import mean_shift
from symtorch.detect.group_path import has_multiplicities
from symtorch.groups.from_maps import canonical_order, consistent_orientation, largest_subgroup
from symtorch.eval.groups import dihedral_orbit_errors, dihedral_permutations, element_rates, rigid_residual
from symtorch.groups import check_group
from symtorch.spectrum import laplacian_spectrum

SUB = 4  # 2562 vertices: the icosphere's triangulation is only approximately 5- or 6-fold symmetric


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    """The detector works on many small tensors: intra-op threads only contend (7x slower on the
    shared 2-core test machine). Restored after the module."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def _detect(verts, faces, mode="group"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return detect_symmetries(verts, faces, mode=mode, k_refine=40)


def bend(verts, radius=4.0):
    """Wrap x around a cylinder: extrinsic symmetry gone, intrinsic kept (up to the slab's stretch)."""
    x, y, z = verts.T
    return np.stack([(radius - z) * np.sin(x / radius), y, radius - (radius - z) * np.cos(x / radius)], 1)


# ------------------------------------------------------------------------------- building blocks
def test_mean_shift_finds_three_modes():
    g = torch.Generator().manual_seed(0)
    centres = torch.tensor([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]], dtype=torch.float64)
    X = torch.cat([c + 0.05 * torch.randn(20, 2, generator=g, dtype=torch.float64) for c in centres])
    modes, labels, counts = mean_shift(X, bandwidth=0.5)
    assert len(modes) == 3, f"modes {modes}"
    assert counts.tolist() == [20.0, 20.0, 20.0]
    for j in range(3):  # each cluster is one label, its mode near its centre
        assert len(set(labels[20 * j:20 * (j + 1)].tolist())) == 1
        m = modes[labels[20 * j]]
        assert float((m - centres[j]).norm()) < 0.1


def test_has_multiplicities():
    assert has_multiplicities(torch.tensor([0.0, 1, 1, 2, 3, 3, 5, 7, 7, 9, 11, 11, 13, 15, 15, 17,
                                            19, 19, 21, 23, 23.0]))
    assert not has_multiplicities(torch.arange(25, dtype=torch.float64))


def test_rigid_residual_is_zero_for_a_rigid_symmetry_only():
    v, _ = shapes.polar_prism(5)  # exactly D5h, triangulation included
    maps = shapes.symmetry_maps(v, shapes.polar_prism_symmetries(5))
    assert max(rigid_residual(v, p) for p in maps) < 1e-6
    scrambled = np.random.default_rng(0).permutation(len(v))
    assert rigid_residual(v, scrambled) > 0.3


def test_dihedral_permutations():
    P = dihedral_permutations(4)
    assert P.shape == (8, 4) and len({tuple(p) for p in P}) == 8
    assert dihedral_permutations(2).tolist() == [[0, 1], [1, 0]]


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


# --------------------------------------------------------------------------- shapes with known groups
CASES = [("star_prism", "D5h", 20), ("ngon_prism", "D6h", 24), ("table", "C4v", 8), ("propeller", "C3", 3),
         ("asymmetric", "C1", 1)]


def _true_order(R: np.ndarray) -> int:
    P = np.eye(3)
    for n in range(1, 25):
        P = P @ R
        if np.abs(P - np.eye(3)).max() < 1e-9:
            return n
    raise AssertionError("not a finite-order matrix")


def _check_against_truth(res, verts, faces, true_maps, name, true_mats):
    G = len(true_maps)
    assert len(res.symmetries) == G, f"{name}: {len(res.symmetries)} elements, expected {G}; {res.info}"
    table = torch.as_tensor(res.group["table"])
    assert check_group(table).is_group, f"{name}: {check_group(table)}"
    solver = GeodesicSolver(verts, faces)
    sc, rates = element_rates(solver, true_maps, res.p2ps)
    assert sc.found == G and sc.spurious == 0, f"{name}: found {sc.found}/{G}, spurious {sc.spurious}"
    assert rates.min() >= 0.95, f"{name}: per-element rates {np.round(rates, 3)}"
    # each element's order and orientation are those of the true symmetry its map matches (from the
    # builder's 3x3 matrices: the order of R, det R < 0), and its kind follows from them
    agree = (res.p2ps[:, None] == torch.as_tensor(np.asarray(true_maps))[None]).double().mean(-1)  # [G, G]
    for s, j, o, r in zip(res.symmetries, agree.argmax(1).tolist(), res.group["orders"], res.group["reversing"]):
        R = true_mats[j]
        assert s.order == o == _true_order(R), f"{name}: order {s.order} / {o} vs true {_true_order(R)}"
        assert bool(r) == (np.linalg.det(R) < 0), f"{name}: reversing {r} vs det {np.linalg.det(R):.0f}"
        assert (s.kind == "reflection") == (np.linalg.det(R) < 0 and _true_order(R) == 2)


@pytest.mark.parametrize("name,group,order", CASES)
def test_code_built_shapes(name, group, order):
    v, f = shapes.SHAPES[name](subdivisions=SUB)
    res = _detect(v, f)
    assert not res.continuous
    assert res.group["name"] == group and res.group["order"] == order, (res.group["name"], res.info)
    mats = shapes.true_symmetries(name)
    _check_against_truth(res, v, f, shapes.symmetry_maps(v, mats), name, mats)
    if name == "propeller":
        assert not any(res.group["reversing"]), "a twisted propeller has no reflection"
    info = res.info
    assert info["n_candidates_before"] >= info["n_candidates"] > 0 or order == 1
    assert set(res.timings) >= {"spectrum", "points", "candidates", "procrustes", "cluster", "refine"}


def test_bent_star_keeps_its_intrinsic_group():
    v0, f = shapes.star_prism(SUB)
    v = bend(v0)
    res = _detect(v, f)
    assert res.group["name"] == "D5h" and len(res.symmetries) == 20, res.info
    mats = shapes.true_symmetries("star_prism")
    _check_against_truth(res, v, f, shapes.symmetry_maps(v0, mats), "bent", mats)


@pytest.mark.parametrize("builder", [lambda: shapes.ellipsoid(3), lambda: shapes.icosphere(3)],
                         ids=["ellipsoid", "sphere"])
def test_continuous_symmetry_is_reported(builder):
    v, f = builder()
    res = _detect(v, f)
    assert res.continuous, res.info
    assert len(res.symmetries) == 1 and res.symmetries[0].kind == "identity"
    assert res.group["order"] == 1
    res = _detect(v, f, mode="auto")
    assert res.continuous and len(res.symmetries) == 1


def test_auto_mode_chooses_the_path():
    v, f = shapes.star_prism(SUB)
    res = _detect(v, f, mode="auto")
    assert res.group["name"] == "D5h" and res.info.get("path") == "group"
    v, f = shapes.mirror_blob(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = detect_symmetries(v, f)  # mirror: the reflection path, with its group report
    assert res.group["name"] in ("Cs", "C1") and res.group["order"] == len(res.symmetries)
    assert res.symmetries[0].kind == "identity"


def test_auto_mode_asks_the_group_path_where_no_reflection_verifies():
    """A two-bladed propeller has a half turn and no mirror: its irreducible representations are
    1-D, so the spectrum is simple and the automatic mode starts with the reflection path, which
    finds no reflection; the group path then finds C2."""
    v, f = shapes.propeller(subdivisions=3, blades=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert not has_multiplicities(laplacian_spectrum(v, f, k=60).evals)
        res = detect_symmetries(v, f)
        alone = detect_symmetries(v, f, mode="reflection")
    assert len(alone.symmetries) == 1
    assert res.group["name"] == "C2" and [s.kind for s in res.symmetries] == ["identity", "rotation"]
    assert res.info.get("path") == "group"


@pytest.mark.parametrize("name, group", [("cube", "D2h"), ("cone33", "C2v"), ("cone3", "C3v")])
def test_auto_mode_on_the_iglict_shapes(shared_data, name, group):
    """Qiao et al.'s exactly symmetric test shapes (a box, an elliptic cone, a three-fold cone): the
    box and the elliptic cone have too few heat-kernel extrema for the reflection path to pair, so
    the automatic mode finds their groups through the group path; every element is one of the
    shape's rigid symmetries."""
    from symtorch.io import read_mesh

    path = shared_data / "iglict_intrinsicsym" / f"{name}.obj"
    if not path.exists():
        pytest.skip(f"{path} not found")
    mesh = read_mesh(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = detect_symmetries(mesh)
    assert res.group["name"] == group, res.info.get("group_path")
    for s in res.symmetries:
        assert rigid_residual(mesh.verts, s.p2p.numpy()) < 0.02, s.kind


def test_to_dict_and_cli_schema(tmp_path):
    from symtorch.cli import main

    out = tmp_path / "table.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["detect", "--demo", "table", "--mode", "group", "--k-refine", "40",
                     "--out", str(out)]) == 0
    d = json.loads(out.read_text())
    assert {"mesh", "n_vertices", "symmetries", "group", "timings"} <= set(d)
    g = d["group"]
    assert g["name"] == "C4v" and g["order"] == 8 == len(d["symmetries"])
    assert {"table", "inverses", "orders", "elements", "table_paper"} <= set(g)
    assert np.array_equal(np.array(g["table_paper"]), np.array(g["table"]).T)
    for s, e in zip(d["symmetries"], g["elements"]):
        assert {"kind", "order", "score", "p2p"} <= set(s) and len(s["p2p"]) == d["n_vertices"]
        assert e["kind"] == s["kind"]


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


# ------------------------------------------------------------------------------------- real meshes
PAPER_TABLE3 = np.array([  # Wang & Huang 2017, Table 3 (1-based); entry (i, j) = g_j · g_i
    [1, 2, 3, 4, 5, 6, 7, 8], [2, 3, 4, 1, 7, 8, 6, 5], [3, 4, 1, 2, 6, 5, 8, 7], [4, 1, 2, 3, 8, 7, 5, 6],
    [5, 8, 6, 7, 1, 3, 4, 2], [6, 7, 5, 8, 3, 1, 2, 4], [7, 5, 8, 6, 2, 4, 1, 3], [8, 6, 7, 5, 4, 2, 3, 1]]) - 1


def _isomorphic_to_paper(table_paper: np.ndarray, reversing) -> bool:
    """A relabelling of our elements (rotations to g2-g4, reflections to g5-g8) turns our table, in
    the paper's layout, into Table 3."""
    rev = np.asarray(reversing)
    rot = [i for i in range(8) if not rev[i] and i != 0]
    ref = [i for i in range(8) if rev[i]]
    if len(rot) != 3 or len(ref) != 4:
        return False
    for pr in permutations(rot):
        for pf in permutations(ref):
            pi = np.array([0, *pr, *pf])  # paper g_(k+1) -> our element pi[k]
            if (table_paper[np.ix_(pi, pi)] == pi[PAPER_TABLE3]).all():
                return True
    return False


def test_paper_table_off(shared_data):
    from symtorch.eval.benchmarks import load_mesh

    v, f = load_mesh(shared_data / "wang_huang_pg2017" / "table.off")
    res = _detect(v, f)
    total = sum(res.timings.values())
    print(f"table.off: {res.group['name']} {len(res.symmetries)} elements; candidates "
          f"{res.info['n_candidates_before']} -> {res.info['n_candidates']}; timings "
          f"{ {k: round(t, 3) for k, t in res.timings.items()} } total {total:.2f}s (shared machine)")
    assert res.group["name"] == "C4v" and len(res.symmetries) == 8
    assert sorted(res.group["orders"]) == [1, 2, 2, 2, 2, 2, 4, 4]
    assert _isomorphic_to_paper(np.asarray(res.to_dict()["group"]["table_paper"]), res.group["reversing"])
    # the 8-vertex orbit of the authors' demo is permuted onto itself by every element
    orbit = np.array([60, 62, 4610, 4644, 9185, 9186, 13637, 13648])
    solver = GeodesicSolver(v, f)
    eps = klc_threshold(solver.area)
    D = solver.distances_from(orbit).numpy()
    for s in res.symmetries:
        err = D[:, s.p2p[orbit].numpy()].min(0)
        assert (err < eps).mean() >= 0.95, f"{s.kind}: orbit errors / eps {np.round(err / eps, 2)}"


@pytest.mark.parametrize("mesh_id", [121, 122, 143, 152, 156])
def test_watertight_orbits(shared_data, mesh_id):
    """Every detected element permutes the ground-truth orbits dihedrally, within eps.

    Expected groups, as measured (see shared/data/README): the octopus legs differ in length, so
    D8 is not intrinsic (trivial group or one mirror); the tables 152/156 are rectangular (C2v);
    table 143 is square to within eps geodesically, but its spectrum splits the 2-dimensional
    eigenspaces of a quarter turn by ~14 %, so only its C2v subgroup is representable.
    """
    from symtorch.eval.benchmarks import load_mesh, load_orbits

    v, f = load_mesh(shared_data / "bim_scb_benchmark" / "Watertight" / "Meshes" / f"{mesh_id}.off")
    orbits = load_orbits(mesh_id)
    res = _detect(v, f)
    assert check_group(torch.as_tensor(res.group["table"])).is_group
    if mesh_id > 140:
        assert res.group["name"] == "C2v", res.info
    else:
        assert res.group["order"] <= 2
    solver = GeodesicSolver(v, f)
    eps = klc_threshold(solver.area)
    for s in res.symmetries:
        rate = float((dihedral_orbit_errors(solver, s.p2p, orbits) < eps).double().mean())
        assert rate >= 0.85, f"{mesh_id} {s.kind}: orbit rate {rate:.2f}"


# ------------------------------------------------------------------------------------- devices
def test_mean_shift_on_device(cuda_device):
    device = cuda_device  # on CPU the comparison would be with itself
    g = torch.Generator().manual_seed(0)
    centres = torch.tensor([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]], dtype=torch.float64)
    X = torch.cat([c + 0.05 * torch.randn(20, 2, generator=g, dtype=torch.float64) for c in centres])
    modes, labels, counts = mean_shift(X.to(device), bandwidth=0.5)
    ref = mean_shift(X, bandwidth=0.5)
    assert modes.device == labels.device == counts.device == device
    torch.testing.assert_close(modes.cpu(), ref[0])
    assert torch.equal(labels.cpu(), ref[1]) and torch.equal(counts.cpu(), ref[2])


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


def test_group_path_batched_stages_on_device(device):
    """``device=``: the candidate stages run there; the same group, the result on the CPU spectrum's
    device."""
    v, f = shapes.table(SUB)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = detect_symmetries(v, f, mode="group", k_refine=40)
        res = detect_symmetries(v, f, mode="group", k_refine=40, device=device)
    assert res.group["name"] == ref.group["name"] == "C4v"
    assert res.p2ps.device.type == "cpu"
    # the same elements: each found map is one of the CPU run's maps on >= 95 % of the vertices
    agree = (res.p2ps[:, None] == ref.p2ps[None]).float().mean(-1)  # [G, G]
    assert bool((agree.max(1).values >= 0.95).all()), agree.max(1).values


def test_fixed_size_icp_refinement_finds_the_same_group():
    """refine='icp' (the paper's spectral ICP at a fixed size, through ``batched_icp``) instead of
    the band-by-band upsampling: the table's C4v, every element a true symmetry."""
    from symtorch.detect.group_path import detect_group
    from symtorch.spectrum import laplacian_spectrum

    v, f = shapes.table(SUB)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = detect_group(v, f, laplacian_spectrum(v, f, k=60), k=20, k_refine=40, refine="icp")
    assert res.group["name"] == "C4v"
    assert res.fmaps.shape[-1] == res.info["k0"]  # ICP keeps the coarse size
    mats = shapes.true_symmetries("table")
    _check_against_truth(res, v, f, shapes.symmetry_maps(v, mats), "table icp", mats)


@pytest.mark.parametrize("n_eigen", [50, 70, 86, 110])
def test_group_does_not_depend_on_the_spectrum_size(n_eigen):
    """The descriptors (and so the candidate pruning) change with the number of eigenpairs; the
    n-gon prism's D6h must not (its rotations were pruned with 50, 70 and 86 at desc_tol=0.25, and
    with 110 at 0.6: the group path now cuts the spectrum near 60 eigenpairs)."""
    from symtorch.spectrum import laplacian_spectrum

    v, f = shapes.ngon_prism(subdivisions=SUB)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = detect_symmetries(v, f, spectrum=laplacian_spectrum(v, f, k=n_eigen), mode="group", k_refine=40)
    assert res.group["name"] == "D6h" and len(res.symmetries) == 24, (res.group["name"], res.info["n_candidates"])


def test_auto_mode_finds_c2v_on_a_table_with_a_simple_spectrum(shared_data):
    """Watertight 152 (C2v: two mirrors and a half turn, all irreducible representations 1-D, so no
    repeated eigenvalues): the reflection path sees three equally consistent involutions of its
    extrema and the automatic mode asks the group path, which finds C2v."""
    from symtorch.eval.benchmarks import load_mesh

    v, f = load_mesh(shared_data / "bim_scb_benchmark" / "Watertight" / "Meshes" / "152.off")
    res = detect_symmetries(v, f)
    assert res.group["name"] == "C2v" and len(res.symmetries) == 4, res.info.get("group_path")
    assert sorted(s.kind for s in res.symmetries) == ["identity", "reflection", "reflection", "rotation"]
    assert detect_symmetries(v, f, group_tol=0).group["name"] == "Cs"  # the reflection path alone


def test_auto_mode_factors_the_geodesic_solver_once_for_both_paths(shared_data, monkeypatch):
    """Watertight 152 goes through both paths (above); they share one heat-method factorisation."""
    import symtorch.detect.group_path as group_detect
    import symtorch.detect.reflection as reflect
    from symtorch.eval.benchmarks import load_mesh

    made, passed = [], []
    real_init = GeodesicSolver.__init__

    def counting_init(self, *a, **kw):
        made.append(self)
        real_init(self, *a, **kw)

    def recording(fn):
        def wrapped(*a, **kw):
            passed.append(kw.get("solver"))
            return fn(*a, **kw)
        return wrapped

    monkeypatch.setattr(GeodesicSolver, "__init__", counting_init)
    monkeypatch.setattr(group_detect, "detect_group", recording(group_detect.detect_group))
    monkeypatch.setattr(reflect, "detect_reflection", recording(reflect.detect_reflection))
    v, f = load_mesh(shared_data / "bim_scb_benchmark" / "Watertight" / "Meshes" / "152.off")
    res = detect_symmetries(v, f)
    assert res.group["name"] == "C2v" and len(passed) == 2  # both paths ran
    assert len(made) == 1 and passed[0] is made[0] and passed[1] is made[0]


def test_min_order_stops_after_the_coarse_stage():
    """A second opinion asks for more than the reflection path's two elements: where the coarse
    stage verifies only the mirror, the group path stops there instead of upsampling it."""
    from symtorch.detect.group_path import detect_group

    v, f = shapes.mirror_blob(3)
    spec = laplacian_spectrum(v, f, k=60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        full = detect_group(v, f, spec, k=20, k_refine=40)
        asked = detect_group(v, f, spec, k=20, k_refine=40, min_order=3)
    assert full.group["name"] == "Cs" and full.info["n_after_closure"] == 2
    assert asked.group["order"] == 1 and "fewer than the 3 asked for" in asked.info["reason"]
