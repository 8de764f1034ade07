"""The field's folder layouts (root/off + corres + dist, BCICP vtx_5k), geodesic matrices, and
within-class pairs."""
import numpy as np
import pytest
import scipy.io
import torch
from torch.utils.data import Subset

from symtorch.data import (MeshDataset, PairDataset, class_key, find_layout, read_geodesic_matrix,
                           read_sample)
from symtorch.geodesics import graph_distances
from symtorch.io import write_mesh
from symtorch.paths import shared_path
from shapes import mirror_mesh


def write_ids(path, ids):
    path.write_text("".join(f"{i + 1}\n" for i in ids.tolist()))  # 1-based, one per line


def make_dataset(root, names, corres_inside=False, dist_for=()):
    """Meshes of one mirror template under ``names``, with .vts/.sym.vts and some .mat files."""
    verts, faces, mirror = mirror_mesh(1)
    meshes = root / ("vtx_5k" if corres_inside else "off")
    corres = meshes / "corres" if corres_inside else root / "corres"
    meshes.mkdir(parents=True)
    corres.mkdir()
    V = verts.shape[0]
    corr = torch.arange(0, V, 2)
    out = {}
    for i, name in enumerate(names):
        v = verts * (1.0 + 0.1 * i)
        write_mesh(meshes / f"{name}.off", v, faces)
        write_ids(corres / f"{name}.vts", corr)
        write_ids(corres / f"{name}.sym.vts", mirror[corr])
        if name in dist_for:
            (root / "dist").mkdir(exist_ok=True)
            D = graph_distances(v, faces, torch.arange(V)).numpy()
            scipy.io.savemat(root / "dist" / f"{name}.mat", {"dist": D})
            out[name] = D
    return corr, mirror[corr], out


def test_field_layout_off_corres_dist(tmp_path):
    root = tmp_path / "FAUST_r"
    corr, corr_sym, dists = make_dataset(root, ["tr_reg_000", "tr_reg_001"], dist_for=["tr_reg_000"])
    layout = find_layout(root)
    assert layout.kind == "field" and layout.meshes == root / "off"
    assert layout.corres == root / "corres" and layout.dist == root / "dist"
    ds = MeshDataset.from_layout(root, processed_dir=tmp_path / "cache")
    assert ds.ground_truth == "vts" and ds.names == ["tr_reg_000", "tr_reg_001"]
    s = ds[0]
    assert torch.equal(s["corr"], corr) and torch.equal(s["corr_sym"], corr_sym)
    # geodesic matrices: a path in the sample, loaded on request only
    assert s["dist_path"] == str(root / "dist" / "tr_reg_000.mat") and ds[1]["dist_path"] == ""
    assert "dist_path" not in torch.load(ds.processed_path(0), weights_only=True)
    D = ds.geodesic_matrix(0)
    assert D.dtype == torch.float64 and np.allclose(D.numpy(), dists["tr_reg_000"])
    assert ds.geodesic_matrix(0, torch.float32).dtype == torch.float32
    with pytest.raises(FileNotFoundError, match="no geodesic matrix tr_reg_001.mat in"):
        ds.geodesic_matrix(1)
    # the dataset root is not itself a mesh folder: the error names from_layout
    with pytest.raises(FileNotFoundError, match="MeshDataset.from_layout\\(root\\) reads"):
        MeshDataset(root, processed_dir=tmp_path / "cache2")
    # read_sample finds corres/ beside off/ too
    s2 = read_sample(root / "off" / "tr_reg_001.off", ground_truth="vts")
    assert torch.equal(s2["corr_sym"], corr_sym)


def test_bcicp_and_flat_layouts(tmp_path):
    root = tmp_path / "TOSCA_Isometric"
    corr, corr_sym, _ = make_dataset(root, ["cat0", "cat1", "dog0"], corres_inside=True)
    layout = find_layout(root)
    assert layout.kind == "bcicp" and layout.corres == root / "vtx_5k" / "corres"
    assert layout.dist is None
    ds = MeshDataset.from_layout(root, processed_dir=tmp_path / "cache")
    assert torch.equal(ds[2]["corr_sym"], corr_sym) and "dist_path" not in ds[0]
    flat = find_layout(root / "vtx_5k")  # the mesh folder itself
    assert flat.kind == "flat" and flat.meshes == root / "vtx_5k" and flat.corres == layout.corres
    # explicit keywords win over the layout's defaults
    plain = MeshDataset.from_layout(root, processed_dir=tmp_path / "c2", ground_truth=None)
    assert "corr" not in plain[0]


def test_layout_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="dataset folder not found"):
        find_layout(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="no meshes in"):
        find_layout(tmp_path / "empty")
    verts, faces, _ = mirror_mesh(1)
    (tmp_path / "m").mkdir()
    write_mesh(tmp_path / "m" / "a.off", verts, faces)
    with pytest.raises(FileNotFoundError, match="ground_truth='vts' needs a corres/ folder"):
        read_sample(tmp_path / "m" / "a.off", ground_truth="vts")
    (tmp_path / "m" / "corres").mkdir()
    with pytest.raises(FileNotFoundError, match="no a.vts in"):
        read_sample(tmp_path / "m" / "a.off", ground_truth="vts")
    scipy.io.savemat(tmp_path / "nodist.mat", {"D": np.zeros((2, 2))})
    with pytest.raises(ValueError, match="has no variable 'dist'"):
        read_geodesic_matrix(tmp_path / "nodist.mat")
    scipy.io.savemat(tmp_path / "rect.mat", {"dist": np.zeros((2, 3))})
    with pytest.raises(ValueError, match="dist must be a square \\[V, V\\] matrix, got \\[2, 3\\]"):
        read_geodesic_matrix(tmp_path / "rect.mat")


def test_class_key():
    assert class_key("cat10") == "cat" and class_key("michael5") == "michael"
    assert class_key("tr_reg_000") == "tr_reg" and class_key("horse") == "horse"


def test_same_class_pairs(tmp_path):
    root = tmp_path / "tosca"
    make_dataset(root, ["cat0", "cat1", "dog0", "dog1", "dog2"], corres_inside=True)
    ds = MeshDataset.from_layout(root, processed_dir=tmp_path / "cache")
    pairs = PairDataset(ds, pairs="same_class")
    names = [(ds.names[i], ds.names[j]) for i, j in pairs.pairs]
    assert len(pairs) == 2 + 6 and all(class_key(a) == class_key(b) and a != b for a, b in names)
    assert len(PairDataset(ds, pairs="same_class", include_self=True)) == 8 + 5
    assert len(PairDataset(ds, pairs="all")) == len(PairDataset(ds)) == 20
    assert PairDataset(ds, pairs=[(0, 2)]).pairs == [(0, 2)]  # explicit lists still work
    sub = PairDataset(Subset(ds, [0, 2, 3]), pairs="same_class")  # names through the Subset
    assert sub.pairs == [(1, 2), (2, 1)]
    items = [ds[i] for i in range(len(ds))]  # a plain list: names read from the items
    assert PairDataset(items, pairs="same_class").pairs == pairs.pairs
    everyone = PairDataset(ds, pairs="same_class", class_of=lambda name: "all")
    assert len(everyone) == 20
    item = pairs[0]
    assert item["p2p_yx"].shape == (item["y"]["verts"].shape[0],)
    with pytest.raises(ValueError, match="pairs must be a list of \\(i, j\\) or one of "
                                         "\\('all', 'same_class'\\), got 'class'"):
        PairDataset(ds, pairs="class")


def test_shared_bcicp_tosca_layout(tmp_path):
    root = shared_path("bcicp_5k", "TOSCA_Isometric")
    if root is None:
        pytest.skip("shared data (bcicp_5k/TOSCA_Isometric) not found")
    ds = MeshDataset.from_layout(root, processed_dir=tmp_path / "cache",
                                 names=["cat0", "cat1", "dog0"])
    assert ds.ground_truth == "vts" and ds.root == root / "vtx_5k"
    pairs = PairDataset(ds, pairs="same_class")
    assert [(ds.names[i], ds.names[j]) for i, j in pairs.pairs] == [("cat0", "cat1"),
                                                                    ("cat1", "cat0")]
    s = ds[0]
    assert s["corr"].shape == s["corr_sym"].shape == (5000,)
    assert int(s["corr"].max()) < s["verts"].shape[0]
