"""MeshDataset cache and PairDataset ground truth."""
import json

import pytest
import torch

from symtorch.data import (Compose, ComputeSpectrum, MeshDataset, NormalizeArea, PairDataset,
                           RandomSymmetry, SetSymmetries, corr_to_fmap, default_cache_dir,
                           read_sample)
from symtorch.io import write_mesh
from symtorch.maps import p2p_to_fmap
from symtorch.paths import shared_path
from shapes import mirror_mesh


class Counting:
    """A pre-transform that counts its calls (its repr, the cache key, stays fixed)."""

    def __init__(self, inner, tag="a"):
        self.inner, self.tag, self.calls = inner, tag, 0

    def __call__(self, sample):
        self.calls += 1
        return self.inner(sample)

    def __repr__(self):
        return f"Counting({self.inner!r}, tag={self.tag})"


def poses(n=3):
    """n poses of one mirror-symmetric template (same faces, same vertex order)."""
    verts, faces, mirror = mirror_mesh()
    out = []
    for i in range(n):
        stretch = torch.tensor([1.0, 1.0 + 0.1 * i, 1.0 - 0.05 * i], dtype=verts.dtype)
        out.append(verts * stretch)
    return out, faces, mirror


@pytest.fixture()
def folder(tmp_path):
    root = tmp_path / "meshes"
    root.mkdir()
    vs, faces, _ = poses()
    for i, v in enumerate(vs):
        write_mesh(root / f"pose{i}.off", v, faces)
    return root


def pre(k=8):
    return Counting(Compose([NormalizeArea(), ComputeSpectrum(k=k)]))


def test_cache_is_built_once_and_reused(folder, tmp_path):
    cache = tmp_path / "cache"
    t = pre()
    ds = MeshDataset(folder, t, processed_dir=cache, ground_truth="template")
    assert t.calls == 3 and len(ds) == 3 and ds.names == ["pose0", "pose1", "pose2"]
    t2 = pre()
    ds2 = MeshDataset(folder, t2, processed_dir=cache, ground_truth="template")
    assert t2.calls == 0
    for a, b in zip(ds, ds2):
        assert a["name"] == b["name"] and torch.equal(a["evecs"], b["evecs"])
    assert set(ds[0]) >= {"name", "verts", "faces", "corr", "mass", "evals", "evecs", "bands"}
    assert ds[0]["verts"].dtype == torch.float32
    meta = json.loads((cache / "meta.json").read_text())
    assert meta["key"]["pre_transform"] == repr(t) and meta["key"]["version"]
    assert not list(cache.glob("*.tmp")) and not list(cache.glob(".*"))  # atomic writes


def test_changed_key_reprocesses_with_a_warning(folder, tmp_path):
    cache = tmp_path / "cache"
    MeshDataset(folder, pre(8), processed_dir=cache)
    t = pre(10)
    with pytest.warns(UserWarning, match="different \\['pre_transform'\\].*processing again"):
        ds = MeshDataset(folder, t, processed_dir=cache)
    assert t.calls == 3 and ds[0]["evecs"].shape[1] == 10
    with pytest.warns(UserWarning, match="different \\['dtype'\\]"):
        ds = MeshDataset(folder, pre(10), processed_dir=cache, dtype=torch.float64)
    assert ds[0]["evecs"].dtype == torch.float64


def test_changed_file_and_force_reload(folder, tmp_path):
    cache = tmp_path / "cache"
    ds = MeshDataset(folder, pre(), processed_dir=cache)
    assert ds.process() == []
    verts, faces, _ = mirror_mesh()
    write_mesh(folder / "pose1.off", verts * 2.0, faces)
    assert MeshDataset(folder, pre(), processed_dir=cache).process() == []  # done in __init__
    t = pre()
    MeshDataset(folder, t, processed_dir=cache, force_reload=True)
    assert t.calls == 3
    write_mesh(folder / "pose1.off", verts * 3.0, faces)
    t = pre()
    MeshDataset(folder, t, processed_dir=cache)
    assert t.calls == 1


def test_names_transform_and_errors(folder, tmp_path):
    ds = MeshDataset(folder, pre(), processed_dir=tmp_path / "c", names=["pose2", "pose0"],
                     transform=lambda s: dict(s, seen=torch.tensor(1)))
    assert [s["name"] for s in ds] == ["pose2", "pose0"] and "seen" in ds[0] and "seen" not in ds.get(0)
    with pytest.raises(FileNotFoundError, match="no mesh named \\['nope'\\]"):
        MeshDataset(folder, processed_dir=tmp_path / "c", names=["nope"])
    with pytest.raises(FileNotFoundError, match="mesh folder not found"):
        MeshDataset(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="no .off/.obj/.ply/.stl files"):
        MeshDataset(tmp_path / "empty", processed_dir=tmp_path / "c2")
    with pytest.raises(ValueError, match="ground_truth must be None, 'template', 'vts'"):
        MeshDataset(folder, ground_truth="identity")


def test_default_cache_dir_is_outside_the_data(monkeypatch, tmp_path, folder):
    monkeypatch.setenv("SYMTORCH_CACHE", str(tmp_path / "usercache"))
    path = default_cache_dir(folder)
    assert path.parent == tmp_path / "usercache" and path.name.startswith("meshes-")
    assert default_cache_dir(folder) == path and default_cache_dir(tmp_path) != path


def test_vts_ground_truth(folder):
    corres = folder / "corres"
    corres.mkdir()
    (corres / "pose0.vts").write_text("1\n5\n3\n")
    (corres / "pose0.sym.vts").write_text("2\n4\n3\n")
    s = read_sample(folder / "pose0.off", ground_truth="vts")
    assert s["corr"].tolist() == [0, 4, 2] and s["corr_sym"].tolist() == [1, 3, 2]
    (corres / "pose0.vts").write_text("0\n")
    with pytest.raises(ValueError, match="vertex id 0 in a 1-based file"):
        read_sample(folder / "pose0.off", ground_truth="vts")
    (corres / "pose0.vts").write_text("100000\n")
    with pytest.raises(ValueError, match="corr names vertex 99999 but the mesh has 162"):
        read_sample(folder / "pose0.off", ground_truth="vts")
    with pytest.raises(ValueError, match="ground_truth must be None, 'template', 'vts'"):
        read_sample(folder / "pose0.off", ground_truth="identity")
    extra = read_sample(folder / "pose0.off", ground_truth=lambda p: {"label": torch.tensor(7)})
    assert extra["label"] == 7


def test_shared_faust_ground_truth():
    path = shared_path("bcicp_5k", "FAUST", "vtx_5k", "tr_reg_000.off")
    if path is None:
        pytest.skip("shared data (bcicp_5k/FAUST) not found")
    s = read_sample(path, ground_truth="vts")
    V = s["verts"].shape[0]
    assert s["corr"].shape == s["corr_sym"].shape == (5000,)
    assert 0 <= int(s["corr"].min()) and int(s["corr"].max()) < V


def test_pair_dataset_ground_truth(folder, tmp_path):
    ds = MeshDataset(folder, Compose([NormalizeArea(), ComputeSpectrum(k=8)]),
                     processed_dir=tmp_path / "c", ground_truth="template", dtype=torch.float64)
    pairs = PairDataset(ds)
    assert len(pairs) == 6 and len(PairDataset(ds, include_self=True)) == 9
    item = pairs[0]
    x, y = item["x"], item["y"]
    assert (x["name"], y["name"]) == ("pose0", "pose1")
    assert torch.equal(item["p2p_yx"], torch.arange(y["verts"].shape[0]))
    ref = p2p_to_fmap(item["p2p_yx"], x["evecs"], y["mass"], evecs_src=y["evecs"])
    torch.testing.assert_close(item["fmap_xy"], ref)
    assert item["fmap_xy"].shape == (8, 8)
    with pytest.raises(ValueError, match="pairs index a dataset of 3 items"):
        PairDataset(ds, pairs=[(0, 3)])
    plain = PairDataset(MeshDataset(folder, processed_dir=tmp_path / "c2"))[0]
    assert set(plain) == {"x", "y"}  # no ground truth in this dataset
    short = dict(ds[1], corr=ds[1]["corr"][:5])
    with pytest.raises(ValueError, match="pose0 and pose1 have 162 and 5 template points"):
        PairDataset([ds[0], short])[0]


def test_corr_to_fmap_sparse_matches_dense(folder, tmp_path):
    ds = MeshDataset(folder, Compose([NormalizeArea(), ComputeSpectrum(k=6)]),
                     processed_dir=tmp_path / "c", dtype=torch.float64)
    x, y = ds[0], ds[1]
    V = x["verts"].shape[0]
    idx = torch.arange(V)
    dense = corr_to_fmap(idx, idx, x["evecs"], y["evecs"], y["mass"])
    torch.testing.assert_close(dense, p2p_to_fmap(idx, x["evecs"], y["mass"], evecs_src=y["evecs"]))
    skip = torch.where(idx % 7 == 0, -1, idx)  # unknown points are skipped
    sparse = corr_to_fmap(skip, skip, x["evecs"], y["evecs"], y["mass"])
    torch.testing.assert_close(sparse, dense, atol=0.05, rtol=0)


def test_random_symmetry_keeps_pair_ground_truth(folder, tmp_path):
    vs, faces, mirror = poses()
    V = vs[0].shape[0]
    pre_t = Compose([NormalizeArea(), ComputeSpectrum(k=8),
                     SetSymmetries(torch.stack([torch.arange(V), mirror]))])
    ds = MeshDataset(folder, pre_t, processed_dir=tmp_path / "c", ground_truth="template",
                     dtype=torch.float64)
    x, y = ds[0], ds[1]
    flip = RandomSymmetry(torch.Generator().manual_seed(0))
    y2 = next(s for s in (flip(y) for _ in range(20)) if not torch.equal(s["corr"], y["corr"]))
    a, b = PairDataset([x, y], pairs=[(0, 1)])[0], PairDataset([x, y2], pairs=[(0, 1)])[0]
    # the mesh did not move; the template points did: vertex i of y now goes to x's mirror[i]
    assert torch.equal(b["y"]["verts"], a["y"]["verts"]) and torch.equal(b["y"]["faces"], faces)
    assert torch.equal(b["p2p_yx"], a["p2p_yx"][mirror])
    # the ground-truth functional map follows: C' = S_y @ C (an exact symmetry of y)
    torch.testing.assert_close(b["fmap_xy"], y["sym_fmap"][1] @ a["fmap_xy"], atol=1e-6, rtol=0)
    ref = p2p_to_fmap(b["p2p_yx"], x["evecs"], y["mass"], evecs_src=y["evecs"])
    torch.testing.assert_close(b["fmap_xy"], ref)
