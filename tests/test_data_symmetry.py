"""Symmetry augmentation on remeshed real data, and symmetry ground truth from .sym.vts pairs."""
import math

import pytest
import torch

from symtorch.data import (Compose, ComputeSpectrum, DetectSymmetries, MeshDataset, NormalizeArea,
                           PairDataset, RandomSymmetry, SetSymmetries, SymmetryFromCorrespondence,
                           apply_symmetry, dense_map_from_pairs, read_sample)
from symtorch.data.symmetry import DENSE_METHODS, one_rings
from symtorch.eval.metrics import evenly_spaced, geodesic_errors
from symtorch.geodesics import GeodesicSolver, graph_distances
from symtorch.paths import shared_path
from shapes import mirror_mesh

N_POINTS = 400  # template points scored on the 5k meshes (evenly spaced; one heat solve each)


# ------------------------------------------------------------------------------------ helpers
def face_normals(verts, faces):
    return torch.linalg.cross(verts[faces[:, 1]] - verts[faces[:, 0]],
                              verts[faces[:, 2]] - verts[faces[:, 0]])


def area(verts, faces):
    return 0.5 * face_normals(verts, faces).norm(dim=-1).sum()


def signed_volume(verts, faces):
    return torch.linalg.det(verts[faces]).sum() / 6


def repeated_vertex_faces(faces):
    return int((faces == faces.roll(1, -1)).any(-1).sum())


def orientation_vote(p2p_yx, verts_y, faces_y, verts_x, faces_x):
    """Area-weighted mean sign of the orientation of a map y -> x, face by face: +1 preserving.

    Each face of y whose three vertices have distinct images is sent to x; its image triangle's normal
    is compared with x's vertex normals there (the face's own winding on y says which way is ccw)."""
    vn = torch.zeros_like(verts_x).index_add_(0, faces_x.reshape(-1),
                                              face_normals(verts_x, faces_x).repeat_interleave(3, 0))
    img = p2p_yx[faces_y]  # [F, 3]
    ok = (img >= 0).all(-1) & (img != img.roll(1, -1)).all(-1)
    img = img[ok]
    n_img = face_normals(verts_x, img)
    vote = torch.sign((n_img * vn[img].sum(1)).sum(-1))
    w = face_normals(verts_y, faces_y[ok]).norm(dim=-1)
    return float((w * vote).sum() / w.sum())


# ------------------------------------------------------------------------------ tiny, exact
def tiny_sample(every=1):
    verts, faces, mirror = mirror_mesh()
    V = verts.shape[0]
    corr = torch.arange(0, V, every)
    sample = {"name": "mirror", "verts": verts, "faces": faces, "corr": corr, "corr_sym": mirror[corr]}
    return Compose([NormalizeArea(), ComputeSpectrum(k=12)])(sample), mirror


def test_symmetry_from_correspondence_is_exact_where_every_vertex_is_paired():
    sample, mirror = tiny_sample()
    out = SymmetryFromCorrespondence()(sample)
    V = mirror.shape[0]
    assert torch.equal(out["sym_p2p"], torch.stack([torch.arange(V), mirror]))
    assert out["sym_reverses"].tolist() == [False, True]
    ref = SetSymmetries(torch.stack([torch.arange(V), mirror]))(sample)
    torch.testing.assert_close(out["sym_fmap"], ref["sym_fmap"])
    for method in DENSE_METHODS:
        other = SymmetryFromCorrespondence(method=method)(sample)
        assert torch.equal(other["sym_p2p"], out["sym_p2p"]), method


def test_one_rings():
    _, faces, _ = mirror_mesh(1)
    V = int(faces.max()) + 1
    rings = one_rings(faces, V)
    edges = {tuple(e) for f in faces.tolist() for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    for i in range(V):
        got = set(rings[i].tolist())
        want = {i} | {b for a, b in edges if a == i} | {a for a, b in edges if b == i}
        assert got == want, i


@pytest.mark.parametrize("method", DENSE_METHODS)
def test_symmetry_from_correspondence_fills_unpaired_vertices_nearby(method):
    sample, mirror = tiny_sample(every=5)  # pairs cover 2 of 5 vertices at most
    out = SymmetryFromCorrespondence(method=method)(sample)
    p = out["sym_p2p"][1]
    src = torch.cat([sample["corr"], sample["corr_sym"]])
    assert torch.equal(p[src], mirror[src]), method  # the given pairs are kept
    D = graph_distances(sample["verts"], sample["faces"], torch.arange(len(p)))  # [V, V]
    edge = D[sample["faces"][:, 0], sample["faces"][:, 1]].mean()
    err = D[mirror, p] / edge  # in mean edge lengths
    assert err.max() <= 3 and err.mean() < 0.7, (method, err.max(), err.mean())


def test_dense_map_from_pairs_point_cloud_and_errors():
    sample, mirror = tiny_sample(every=5)
    src, dst = sample["corr"], sample["corr_sym"]
    p = dense_map_from_pairs(src, dst, sample["verts"], method="nearest")  # no faces: Euclidean
    v, f = sample["verts"], sample["faces"]
    edge = (v[f[:, 0]] - v[f[:, 1]]).norm(dim=-1).mean()
    assert torch.equal(p[src], dst) and (v[p] - v[mirror]).norm(dim=-1).max() < 3 * edge
    spectral = dense_map_from_pairs(src, dst, sample["verts"], method="spectral",
                                    evecs=sample["evecs"])
    assert torch.equal(spectral[src], dst)
    with pytest.raises(ValueError, match="method must be one of \\('local', 'nearest', 'spectral'\\), "
                                         "got 'nn'"):
        dense_map_from_pairs(src, dst, sample["verts"], method="nn")
    with pytest.raises(ValueError, match="method='spectral' needs evecs"):
        dense_map_from_pairs(src, dst, sample["verts"], method="spectral")
    with pytest.raises(ValueError, match="method='local' needs evecs"):
        dense_map_from_pairs(src, dst, sample["verts"], sample["faces"])
    with pytest.raises(ValueError, match="method='local' needs faces"):
        dense_map_from_pairs(src, dst, sample["verts"], evecs=sample["evecs"])
    with pytest.raises(ValueError, match="src and dst must be \\[N\\] vertex ids of one"):
        dense_map_from_pairs(src, dst[:3], sample["verts"])
    with pytest.raises(ValueError, match="src and dst must hold vertex ids in \\[0, 161\\]"):
        dense_map_from_pairs(src, dst + 1000, sample["verts"])
    with pytest.raises(ValueError, match="method must be one of"):
        SymmetryFromCorrespondence("nn")
    with pytest.raises(ValueError, match="needs sample keys \\['corr_sym'\\]"):
        SymmetryFromCorrespondence()({k: v for k, v in sample.items() if k != "corr_sym"})
    no_basis = {k: v for k, v in sample.items() if k != "evecs"}
    with pytest.raises(ValueError, match="needs sample keys \\['evecs'\\] \\(run ComputeSpectrum "
                                         "first for method='local', or use 'nearest'\\)"):
        SymmetryFromCorrespondence()(no_basis)
    assert SymmetryFromCorrespondence("nearest")(no_basis)["sym_p2p"].shape == (2, len(mirror))
    with pytest.raises(ValueError, match="corr and corr_sym must have one length"):
        SymmetryFromCorrespondence()(dict(sample, corr_sym=dst[:4]))
    with pytest.raises(ValueError, match="has no symmetric pair"):
        SymmetryFromCorrespondence()(dict(sample, corr=torch.full_like(src, -1)))


# ------------------------------------------------------------------- remeshed real data (5k)
SHAPES = [("FAUST", "tr_reg_000"), pytest.param("TOSCA_Isometric", "cat0", marks=pytest.mark.extended)]
SOURCES = ["detect", "vts"]
_CACHE = {}


def real_sample(dataset, name, source):
    """A unit-area 5k shape with its BCICP ground truth and its symmetries (detected or from vts)."""
    key = (dataset, name, source)
    if key not in _CACHE:
        path = shared_path("bcicp_5k", dataset, "vtx_5k", f"{name}.off")
        if path is None:
            pytest.skip(f"shared data (bcicp_5k/{dataset}/vtx_5k/{name}.off) not found")
        base = ("base", dataset, name)
        if base not in _CACHE:
            s = read_sample(path, torch.float64, ground_truth="vts")
            _CACHE[base] = Compose([NormalizeArea(), ComputeSpectrum(k=30)])(s)
        step = DetectSymmetries() if source == "detect" else SymmetryFromCorrespondence()
        _CACHE[key] = step(_CACHE[base])
    return _CACHE[key]


def solver_of(sample):
    key = ("solver", sample["name"])
    if key not in _CACHE:
        _CACHE[key] = GeodesicSolver(sample["verts"], sample["faces"])
    return _CACHE[key]


@pytest.mark.parametrize("source", SOURCES)
@pytest.mark.parametrize("dataset,name", SHAPES)
def test_augmentation_never_damages_a_remeshed_mesh(dataset, name, source):
    s = real_sample(dataset, name, source)
    g = s["sym_p2p"][1]
    assert s["sym_reverses"].tolist() == [False, True], (name, source)
    # moving the vertices by the map with the old faces (the old augmentation) would tear the mesh
    torn = repeated_vertex_faces(g[s["faces"]])
    if source == "detect":
        assert torn > 0, f"{name}: the detected map is a bijection; the test shows nothing"
    F, A = s["faces"].shape[0], area(s["verts"], s["faces"])
    for mode in ("relabel", "mirror"):
        out = apply_symmetry(s, 1, mode=mode)
        msg = f"{name} {source} {mode}"
        assert out["faces"].shape[0] == F, msg
        assert repeated_vertex_faces(out["faces"]) == repeated_vertex_faces(s["faces"]) == 0, msg
        torch.testing.assert_close(area(out["verts"], out["faces"]), A, rtol=1e-12, atol=0,
                                   msg=msg)
        for key in ("mass", "evals", "evecs", "sym_p2p", "sym_fmap"):
            assert torch.equal(out[key], s[key]), (msg, key)


@pytest.mark.parametrize("dataset,name", SHAPES)
def test_mirror_mode_keeps_the_mesh_outward_oriented(dataset, name):
    s = real_sample(dataset, name, "vts")
    out = apply_symmetry(s, 1, mode="mirror")
    vol, vol2 = signed_volume(s["verts"], s["faces"]), signed_volume(out["verts"], out["faces"])
    assert vol > 0, f"{name}: the input mesh is not outward oriented (volume {float(vol):.3g})"
    torch.testing.assert_close(vol2, vol, rtol=1e-10, atol=0)
    M = torch.tensor([-1.0, 1.0, 1.0], dtype=s["verts"].dtype)
    torch.testing.assert_close(face_normals(out["verts"], out["faces"]),
                               face_normals(s["verts"], s["faces"]) * M)


@pytest.mark.parametrize("source", SOURCES)
@pytest.mark.parametrize("dataset,name", SHAPES)
def test_augmented_ground_truth_is_as_accurate_as_the_map(dataset, name, source):
    """The augmented ``corr`` against the true mirror correspondence (``corr_sym``): its geodesic error
    on the unit-area shape is the symmetry map's own error at the ground-truth pairs, no more."""
    s = real_sample(dataset, name, source)
    solver = solver_of(s)
    k = evenly_spaced(torch.arange(s["corr"].numel()), N_POINTS)
    g = s["sym_p2p"][1]
    pairs = torch.stack([s["corr"][k], s["corr_sym"][k]], 1)
    map_err = geodesic_errors(solver, g, pairs)  # the map's error, KLC protocol (unit area)
    for mode in ("relabel", "mirror"):
        out = apply_symmetry(s, 1, mode=mode)
        D = solver.distances_from(s["corr_sym"][k])  # geodesics are intrinsic: same on the mirror
        aug_err = D[torch.arange(k.numel()), out["corr"][k]]
        torch.testing.assert_close(aug_err, map_err, rtol=0, atol=1e-12, msg=f"{name} {mode}")
        # and the augmented corr_sym lands back on the true correspondence, to the same accuracy
        D2 = solver.distances_from(s["corr"][k])
        back = D2[torch.arange(k.numel()), out["corr_sym"][k]]
        assert back.mean() < 2 * map_err.mean() + 0.01, (name, source, mode)
    bound = 0.08 if source == "detect" else 0.01  # unit area; ~0.02 is one edge of a 5k mesh
    assert map_err.mean() < bound, (name, source, float(map_err.mean()))


@pytest.mark.parametrize("dataset,names", [("TOSCA_Isometric", ["cat0", "cat1"]),
                                           ("FAUST", ["tr_reg_000", "tr_reg_011"])])
def test_mirror_mode_pairs_keep_an_orientation_preserving_ground_truth(dataset, names, tmp_path):
    root = shared_path("bcicp_5k", dataset, "vtx_5k")
    if root is None:
        pytest.skip(f"shared data (bcicp_5k/{dataset}) not found")
    pre = Compose([NormalizeArea(), ComputeSpectrum(k=20), SymmetryFromCorrespondence()])
    ds = MeshDataset(root, pre, processed_dir=tmp_path / "cache", names=names, ground_truth="vts",
                     dtype=torch.float64)
    x, y = ds[0], ds[1]
    votes = {}
    for mode in (None, "relabel", "mirror"):
        y2 = y if mode is None else apply_symmetry(y, 1, mode=mode)
        item = PairDataset([x, y2], pairs=[(0, 1)])[0]
        votes[mode] = orientation_vote(item["p2p_yx"], y2["verts"], y2["faces"], x["verts"],
                                       x["faces"])
        assert item["fmap_xy"].shape == (20, 20)
    assert votes[None] > 0.8 and votes["mirror"] > 0.8 and votes["relabel"] < -0.8, votes
    # RandomSymmetry(mode="mirror") mirrors exactly the draws of the reflection
    t = RandomSymmetry(mode="mirror", generator=torch.Generator().manual_seed(0))
    outs = [t(y) for _ in range(8)]
    mirrored = [bool(torch.equal(o["faces"], y["faces"][:, [0, 2, 1]])) for o in outs]
    relabelled = [bool(torch.equal(o["corr"], y["sym_p2p"][1][y["corr"]])) for o in outs]
    assert mirrored == relabelled and 0 < sum(mirrored) < 8, mirrored
    assert math.isfinite(float(x["scale"]))


@pytest.mark.parametrize("method", DENSE_METHODS)
def test_symmetry_from_correspondence_on_device(method, cuda_device):
    """A sample on the GPU gets its maps there, equal to the CPU's."""
    sample, _ = tiny_sample(every=3)
    on_dev = {k: v.to(cuda_device) if torch.is_tensor(v) else v for k, v in sample.items()}
    out, ref = (SymmetryFromCorrespondence(method)(s) for s in (on_dev, sample))
    for key in ("sym_p2p", "sym_reverses", "sym_fmap"):
        assert out[key].device == torch.device(cuda_device), key
        torch.testing.assert_close(out[key].cpu(), ref[key], msg=f"{method} {key}")
    mirrored = apply_symmetry(out, 1, mode="mirror")
    assert mirrored["faces"].device == torch.device(cuda_device)
