"""Tests for symtorch.cache: keys, hits and misses, version and key checks, corrupt files, atomicity."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest
import torch

import symtorch
import symtorch.cache as cache_mod
from symtorch.cache import (cached_spectrum, default_spectrum_cache_dir, spectrum_key,
                            spectrum_key_dict)
from symtorch.shapes import icosphere, mirror_blob
from symtorch.spectrum import laplacian_spectrum


@pytest.fixture(scope="module")
def mesh():
    return mirror_blob(1)  # 42 vertices: every solve is milliseconds


@pytest.fixture
def counter(monkeypatch):
    """Counts the real solves behind cached_spectrum."""
    calls = []

    def counted(*args, **kwargs):
        calls.append(kwargs)
        return laplacian_spectrum(*args, **kwargs)

    monkeypatch.setattr(cache_mod, "laplacian_spectrum", counted)
    return calls


def only_file(folder):
    files = [p for p in folder.iterdir()]
    assert len(files) == 1, f"expected one cache file, got {files}"
    return files[0]


def test_miss_then_hit_returns_identical_spectrum(mesh, tmp_path, counter):
    verts, faces = mesh
    a = cached_spectrum(verts, faces, 10, cache_dir=tmp_path)
    b = cached_spectrum(verts, faces, 10, cache_dir=tmp_path)
    assert len(counter) == 1
    ref = laplacian_spectrum(verts, faces, 10)
    for x, y, z in zip(a[:3], b[:3], ref[:3]):
        assert torch.equal(x, y) and torch.equal(x, z)
    assert a.scale == b.scale == ref.scale
    path = only_file(tmp_path)
    assert path.name == f"{spectrum_key(verts, faces, 10)}.npz"


def test_exported_from_package():
    assert symtorch.cached_spectrum is cached_spectrum and symtorch.spectrum_key is spectrum_key


def test_dtype_and_device_follow_arguments_not_key(mesh, tmp_path, counter):
    verts, faces = mesh
    a = cached_spectrum(verts, faces, 8, cache_dir=tmp_path, dtype=torch.float32, device="cpu")
    b = cached_spectrum(verts, faces, 8, cache_dir=tmp_path)
    assert len(counter) == 1
    assert a.evecs.dtype == torch.float32 and b.evecs.dtype == torch.float64
    torch.testing.assert_close(a.evecs, b.evecs.float())


def test_key_covers_mesh_and_parameters(mesh):
    verts, faces = mesh
    base = spectrum_key(verts, faces, 10)
    assert spectrum_key(verts, faces, 10) == base
    assert spectrum_key(torch.as_tensor(verts), torch.as_tensor(faces), 10) == base
    moved = verts.copy()
    moved[0, 0] += 1e-12
    swapped = faces.copy()
    swapped[0] = swapped[0, [1, 0, 2]]
    others = [spectrum_key(verts, faces, 11), spectrum_key(verts, faces, 10, normalize_area=False),
              spectrum_key(moved, faces, 10), spectrum_key(verts, swapped, 10),
              spectrum_key(verts, None, 10), spectrum_key(verts[:, [1, 0, 2]], faces, 10)]
    assert len(set(others) | {base}) == len(others) + 1


def test_key_is_independent_of_input_dtype(mesh):
    verts, faces = mesh
    v32 = verts.astype(np.float32)
    # float32 coordinates widen exactly to float64: same mesh, same key, same spectrum
    assert spectrum_key(v32, faces.astype(np.int32), 6) == spectrum_key(v32.astype(np.float64), faces, 6)


def test_key_records_solver_settings(mesh):
    key = spectrum_key_dict(*mesh, 6)
    assert key["laplacian"]["mollify_factor"] == repr(1e-5)
    assert set(key["eigsh"]) >= {"shift", "tol", "retries"}
    assert key["k"] == 6 and key["normalize_area"] is True and key["faces"] is not None
    json.dumps(key)  # JSON-able


def test_file_from_another_version_is_recomputed(mesh, tmp_path, counter, monkeypatch):
    verts, faces = mesh
    monkeypatch.setattr(symtorch, "__version__", "0.0.0-old")
    cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    monkeypatch.undo()  # back to the real version (and the real solver: count by file contents)
    path = only_file(tmp_path)
    with np.load(path) as z:
        assert json.loads(str(z["meta"]))["version"] == "0.0.0-old"
    cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    with np.load(only_file(tmp_path)) as z:
        assert json.loads(str(z["meta"]))["version"] == symtorch.__version__


def test_version_mismatch_triggers_a_solve(mesh, tmp_path, counter, monkeypatch):
    verts, faces = mesh
    cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    monkeypatch.setattr(symtorch, "__version__", "9.9.9")
    cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    assert len(counter) == 2  # once per version, then a hit


def test_file_with_another_key_is_recomputed(mesh, tmp_path, counter):
    verts, faces = mesh
    other = cached_spectrum(*icosphere(1), 6, cache_dir=tmp_path / "other")
    # plant the other mesh's (valid, same-shaped) file under this mesh's name
    key = spectrum_key_dict(*icosphere(1), 6)
    path = tmp_path / f"{spectrum_key(verts, faces, 6)}.npz"
    cache_mod._write(path, key, other)
    s = cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    assert len(counter) == 2
    assert torch.equal(s.evals, laplacian_spectrum(verts, faces, 6).evals)


@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty", "drop_array", "bad_shape"])
def test_corrupt_file_is_recomputed(mesh, tmp_path, counter, damage):
    verts, faces = mesh
    ref = cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    path = only_file(tmp_path)
    data = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(os.urandom(len(data)))
    elif damage == "empty":
        path.write_bytes(b"")
    else:
        with np.load(path) as z:
            arrays = dict(z)
        if damage == "drop_array":
            del arrays["evecs"]
        else:
            arrays["evecs"] = arrays["evecs"][:, :3]
        with open(path, "wb") as fh:
            np.savez(fh, **arrays)
    s = cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    assert len(counter) == 2, damage
    assert torch.equal(s.evecs, ref.evecs)
    cached_spectrum(verts, faces, 6, cache_dir=tmp_path)  # repaired: a hit again
    assert len(counter) == 2


def test_atomic_write_leaves_no_temporary_and_keeps_old_file(mesh, tmp_path, monkeypatch):
    verts, faces = mesh
    cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    path = only_file(tmp_path)
    before = path.read_bytes()

    def broken_savez(fh, **arrays):
        fh.write(b"half a file")
        raise OSError("disk full (test)")

    monkeypatch.setattr(cache_mod.np, "savez", broken_savez)
    spec = cache_mod.laplacian_spectrum(verts, faces, 6)
    with pytest.raises(OSError, match="disk full"):
        cache_mod._write(path, spectrum_key_dict(verts, faces, 6), spec)
    assert only_file(tmp_path) == path and path.read_bytes() == before  # no .tmp left, old intact
    # through the public function the failure is logged, not raised, and the result still returned
    path.unlink()
    s = cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    assert s.evecs.shape == (42, 6) and list(tmp_path.iterdir()) == []


def test_unwritable_cache_dir_still_returns(mesh, tmp_path, caplog):
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("a file where the cache folder should be")
    s = cached_spectrum(*mesh, 6, cache_dir=blocker)
    assert s.evals.shape == (6,)
    assert any("could not write spectrum cache" in r.message for r in caplog.records)


def test_default_cache_dir_from_environment(mesh, tmp_path, monkeypatch, counter):
    monkeypatch.setenv("SYMTORCH_CACHE", str(tmp_path))
    assert default_spectrum_cache_dir() == tmp_path / "spectra"
    cached_spectrum(*mesh, 6)
    cached_spectrum(*mesh, 6)
    assert len(counter) == 1 and len(list((tmp_path / "spectra").iterdir())) == 1


def test_point_cloud_is_cached_separately(mesh, tmp_path, counter):
    verts, faces = mesh
    a = cached_spectrum(verts, None, 6, cache_dir=tmp_path)
    b = cached_spectrum(verts, faces, 6, cache_dir=tmp_path)
    cached_spectrum(verts, None, 6, cache_dir=tmp_path)
    assert len(counter) == 2 and not torch.equal(a.evals, b.evals)


@pytest.mark.parametrize("verts, faces, k, match", [
    (np.full((42, 3), np.nan), icosphere(1)[1], 6, "NaN or inf"),
    (icosphere(1)[0][:, :2], icosphere(1)[1], 6, r"verts must be \[V, 3\]"),
    (icosphere(1)[0], icosphere(1)[1] + 1, 6, "faces index out of range"),
    (np.zeros((42, 3)), icosphere(1)[1], 6, "zero total area"),
    (icosphere(1)[0], icosphere(1)[1], 42, r"k must be in \[1, V-1\]"),
    (icosphere(1)[0], icosphere(1)[1], 6.0, "k must be an int"),
])
def test_value_errors_pass_through(tmp_path, verts, faces, k, match):
    with pytest.raises(ValueError, match=match):
        cached_spectrum(verts, faces, k, cache_dir=tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_several_components_warn_on_a_miss_and_on_a_hit(tmp_path):
    v, f = icosphere(1)
    verts, faces = np.concatenate([v, v + 5.0]), np.concatenate([f, f + len(v)])
    for _ in range(2):  # computed and written, then read back
        with pytest.warns(UserWarning, match="connected components"):
            cached_spectrum(verts, faces, k=4, cache_dir=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 1
