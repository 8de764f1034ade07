"""symtorch precompute: MeshDataset-compatible caches, resume after kill -9, workers, torchrun."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch

import symtorch.data.dataset as dataset_module
from symtorch import cli, shapes
from symtorch.data import MeshDataset
from symtorch.io import write_mesh
from symtorch.data.precompute import (FAILURES, SETTINGS, default_pre_transform, done_names,
                                 find_meshes, open_dataset, precompute)

K = 6
ARGS = ["--k", str(K), "--no-detect", "--quiet"]


def make_tree(root: Path, n: int = 6, subdivisions: int = 1) -> list[str]:
    """n small meshes in root/ and root/sub/ (OFF, OBJ, PLY), each stretched differently."""
    v, f = shapes.mirror_blob(subdivisions)
    rels = []
    for i in range(n):
        rel = f"{'sub/' if i % 2 else ''}m{i}{('.off', '.obj', '.ply')[i % 3]}"
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        write_mesh(root / rel, v * np.array([1.0 + 0.07 * i, 1.0, 1.0 - 0.03 * i]), f)
        rels.append(rel)
    return rels


def cache_files(out: Path) -> dict[str, Path]:
    """The cache (.pt and meta.json) by relative path; settings, lock and failures aside."""
    return {p.relative_to(out).as_posix(): p for p in out.rglob("*")
            if p.is_file() and (p.suffix == ".pt" or p.name == "meta.json")}


def assert_same_cache(a: Path, b: Path) -> None:
    fa, fb = cache_files(a), cache_files(b)
    assert sorted(fa) == sorted(fb)
    for rel in fa:
        if rel.endswith("meta.json"):
            assert json.loads(fa[rel].read_text()) == json.loads(fb[rel].read_text()), rel
            continue
        sa, sb = torch.load(fa[rel], weights_only=True), torch.load(fb[rel], weights_only=True)
        assert sa.keys() == sb.keys(), rel
        for key in sa:
            same = torch.equal(sa[key], sb[key]) if torch.is_tensor(sa[key]) else sa[key] == sb[key]
            assert same, f"{rel}: {key} differs"
    assert not list(a.rglob("*.tmp")) and not list(b.rglob("*.tmp")), "temporary files left"


def test_find_meshes_natural_order_skips_hidden_and_out(tmp_path):
    make_tree(tmp_path, n=4)
    (tmp_path / ".hidden.off").write_text("OFF\n")
    (tmp_path / "notes.txt").write_text("x")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "x.off").write_text("OFF\n")
    rels = [p.relative_to(tmp_path).as_posix() for p in find_meshes(tmp_path, exclude=tmp_path / "out")]
    assert rels == ["m0.off", "m2.ply", "sub/m1.obj", "sub/m3.off"]


def test_cache_is_what_meshdataset_reads(tmp_path, capsys, monkeypatch):
    src, out = tmp_path / "src", tmp_path / "out"
    make_tree(src)
    assert cli.main(["precompute", str(src), str(out), *ARGS]) == 0
    assert "6 done, 0 already done, 0 failed" in capsys.readouterr().err
    # MeshDataset over the same folder, same pre_transform: loads, processes nothing
    monkeypatch.setattr(dataset_module, "read_sample",
                        lambda *a, **k: pytest.fail("MeshDataset processed a mesh again"))
    ds = MeshDataset(src / "sub", default_pre_transform(K, detect=False), processed_dir=out / "sub")
    assert ds.names == ["m1", "m3", "m5"] and ds[0]["evecs"].shape[1] == K
    assert open_dataset(src, out).names == ["m0", "m2", "m4"]
    assert done_names(out / "sub") == ["m1", "m3", "m5"]
    monkeypatch.undo()
    # ... and holds what MeshDataset itself would have written
    ref = tmp_path / "ref"
    MeshDataset(src, default_pre_transform(K, detect=False), processed_dir=ref / ".")
    MeshDataset(src / "sub", default_pre_transform(K, detect=False), processed_dir=ref / "sub")
    assert_same_cache(out, ref)
    # a second run does nothing
    s = precompute(src, out, k=K, detect=False, progress=False)
    assert (s.done, s.skipped, s.failed) == (0, 6, 0)


def test_changed_mesh_and_settings_are_redone(tmp_path, caplog):
    src, out = tmp_path / "src", tmp_path / "out"
    make_tree(src, n=3)
    precompute(src, out, k=K, detect=False, progress=False)
    time.sleep(0.01)
    v, f = shapes.mirror_blob(1)
    write_mesh(src / "m0.off", v * 2.0, f)  # new contents: new stamp
    s = precompute(src, out, k=K, detect=False, progress=False)
    assert (s.done, s.skipped) == (1, 2)
    s = precompute(src, out, k=K + 1, detect=False, progress=False)  # new key: all again
    assert (s.done, s.skipped) == (3, 0)
    assert "made with other settings" in caplog.text


def test_failures_are_listed_then_cleared_when_fixed(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    make_tree(src, n=2)
    (src / "bad.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\nnan 0 0\n3 0 1 2\n")
    (src / "m0.ply").write_bytes((src / "m0.off").read_bytes())  # same stem as m0.off
    s = precompute(src, out, k=K, detect=False, progress=False)
    assert (s.done, s.failed) == (2, 2)
    lines = [json.loads(x) for x in (out / FAILURES).read_text().splitlines()]
    assert {x["file"] for x in lines} == {"bad.off", "m0.ply"}
    assert any("NaN or inf" in x["reason"] for x in lines)
    assert any("same name 'm0'" in x["reason"] for x in lines)
    v, f = shapes.mirror_blob(1)
    write_mesh(src / "bad.off", v, f)
    (src / "m0.ply").unlink()
    s = precompute(src, out, k=K, detect=False, progress=False)
    assert (s.done, s.skipped, s.failed) == (1, 2, 0)
    assert not (out / FAILURES).exists()


def test_workers_write_the_same_cache(tmp_path):
    src = tmp_path / "src"
    make_tree(src, n=4)
    s1 = precompute(src, tmp_path / "one", k=K, detect=False, workers=1, progress=False)
    s2 = precompute(src, tmp_path / "two", k=K, detect=False, workers=2, progress=False)
    assert s1.done == s2.done == 4 and s2.peak_rss_mb > 0
    assert_same_cache(tmp_path / "one", tmp_path / "two")


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1]) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def test_resume_after_kill_9(tmp_path):
    """Kill -9 partway, restart: only the missing meshes are redone; same cache as one clean run."""
    src, out, ref = tmp_path / "src", tmp_path / "out", tmp_path / "ref"
    n = 16
    make_tree(src, n=n, subdivisions=3)  # 642 vertices each: slow enough to be killed partway
    cmd = [sys.executable, "-m", "symtorch", "precompute", str(src), str(out), "--k", "12",
           "--no-detect", "--quiet"]
    proc = subprocess.Popen(cmd, env=_env(), stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.time() + 120
    try:
        while len(list(out.rglob("*.pt"))) < 4 and proc.poll() is None and time.time() < deadline:
            time.sleep(0.02)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)  # the whole group this test started
        proc.wait(timeout=30)
        proc.stderr.close()
    n_written = len(list(out.rglob("*.pt")))
    assert 0 < n_written < n, f"the run was not killed partway ({n_written} of {n} written)"
    done = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    summary = done.stderr.strip().splitlines()[-1]
    redone = int(summary.split("precompute: ")[1].split(" done")[0])
    assert 0 < redone <= n - n_written + 1, summary  # at most the mesh being recorded is redone
    precompute(src, ref, k=12, detect=False, progress=False)  # one uninterrupted run
    assert_same_cache(out, ref)


def test_torchrun_two_ranks(tmp_path):
    """Two ranks on one machine: each does its share, one summary, same cache as one process."""
    src, out, ref = tmp_path / "src", tmp_path / "out", tmp_path / "ref"
    make_tree(src, n=7)
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2",
           "-m", "symtorch", "precompute", str(src), str(out), *ARGS]
    proc = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "rank 0/2: 3 done" in proc.stderr and "rank 1/2: 4 done" in proc.stderr \
        or "rank 0/2: 4 done" in proc.stderr and "rank 1/2: 3 done" in proc.stderr, proc.stderr
    assert "all 2 ranks: 7 done, 0 already done, 0 failed, of 7" in proc.stderr, proc.stderr
    precompute(src, ref, k=K, detect=False, progress=False)
    assert_same_cache(out, ref)


def test_bad_arguments(tmp_path, capsys):
    with pytest.raises(FileNotFoundError, match="no such folder"):
        precompute(tmp_path / "nope", tmp_path / "out")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="no .off/.obj/.ply files"):
        precompute(tmp_path / "empty", tmp_path / "out")
    with pytest.raises(ValueError, match="workers must be >= 0"):
        precompute(tmp_path, tmp_path / "out", workers=-1)
    with pytest.raises(ValueError, match="ground_truth must be"):
        precompute(tmp_path, tmp_path / "out", ground_truth="gt")
    assert cli.main(["precompute", str(tmp_path), str(tmp_path / "out"), "--k", "1"]) == 2
    assert "symtorch: error: --k must be >= 2, got 1" in capsys.readouterr().err


def test_open_dataset_needs_the_default_pre_transform(tmp_path):
    from symtorch.data import Compose, NormalizeArea

    make_tree(tmp_path / "src", n=2)
    precompute(tmp_path / "src", tmp_path / "out", pre_transform=Compose([NormalizeArea()]),
               progress=False)
    assert json.loads((tmp_path / "out" / SETTINGS).read_text())["default_pre_transform"] is False
    with pytest.raises(ValueError, match="custom pre_transform"):
        open_dataset(tmp_path / "src", tmp_path / "out")
    with pytest.raises(FileNotFoundError, match="not a symtorch precompute folder"):
        open_dataset(tmp_path / "src", tmp_path / "src")


def test_k_refine_reaches_the_detector_and_the_settings(tmp_path, capsys):
    make_tree(tmp_path / "src", n=1, subdivisions=2)
    assert cli.main(["precompute", str(tmp_path / "src"), str(tmp_path / "out"), "--k", "40",
                     "--k-refine", "20", "--quiet"]) == 0
    s = json.loads((tmp_path / "out" / SETTINGS).read_text())
    assert s["k_refine"] == 20 and s["default_pre_transform"] is True  # the CLI built the default
    # the detector's settings are part of the cache key: another k_refine is another cache
    assert "k_refine=20" in s["key"]["pre_transform"]
    assert repr(default_pre_transform(40, True, 0, 20)) != repr(default_pre_transform(40, True, 0))
    ds = open_dataset(tmp_path / "src", tmp_path / "out")
    sample = ds[0]
    assert sample["sym_p2p"].shape[0] == 2  # the mirror blob: identity and its reflection
    assert cli.main(["precompute", str(tmp_path / "src"), str(tmp_path / "o2"), "--k-refine", "1"]) == 2
    assert "--k-refine must be >= 2, got 1" in capsys.readouterr().err
    assert cli.main(["precompute", str(tmp_path / "src"), str(tmp_path / "o2"), "--k-refine", "60"]) == 2
    assert "--k must be at least --k-refine + 8" in capsys.readouterr().err
