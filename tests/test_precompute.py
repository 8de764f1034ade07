"""symtorch precompute: MeshDataset-compatible caches, resume after kill -9, workers, torchrun."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

import symtorch.data.dataset as dataset_module
from symtorch import cli, shapes
from symtorch.data import MeshDataset
from symtorch.detect import DetectConfig
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
    """Bit for bit: the same meta.json entries (checksums included) and the same .pt bytes."""
    fa, fb = cache_files(a), cache_files(b)
    assert sorted(fa) == sorted(fb)
    for rel in fa:
        if rel.endswith("meta.json"):
            assert json.loads(fa[rel].read_text()) == json.loads(fb[rel].read_text()), rel
            continue
        if fa[rel].read_bytes() == fb[rel].read_bytes():
            continue
        sa = torch.load(fa[rel], weights_only=True)["sample"]
        sb = torch.load(fb[rel], weights_only=True)["sample"]
        diff = {key: float((sa[key].double() - sb[key].double()).abs().max())
                for key in sa if torch.is_tensor(sa[key]) and not torch.equal(sa[key], sb[key])}
        pytest.fail(f"{rel} differs: max abs difference per field {diff}")
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


@pytest.mark.multiprocess
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


@pytest.mark.multiprocess
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


@pytest.mark.multiprocess
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
    with pytest.raises(FileNotFoundError, match="no .off/.obj/.ply/.stl files"):
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


# --------------------------------------------------------------- faults: real signals, processes
# (once: a worker killed with -9 lost its mesh; Ctrl-C printed tracebacks; a second run
# deleted the first one's files; orphaned torchrun ranks slept for two hours; damaged caches
# were "already done")

def _children(pid: int) -> list[int]:
    """Pids whose parent is ``pid`` (from /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            fields = stat[stat.rfind(")") + 2:].split()
            if int(fields[1]) == pid and fields[0] != "Z":
                out.append(int(entry))
    return out


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rfind(")") + 2] != "Z"


def _wait_for(condition, timeout: float, what: str, proc=None) -> None:
    deadline = time.time() + timeout
    while not condition():
        if proc is not None and proc.poll() is not None:
            pytest.fail(f"the run ended before {what}: {proc.stderr.read() if proc.stderr else ''}")
        if time.time() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        time.sleep(0.05)


def _start(cmd: list[str]) -> subprocess.Popen:
    return subprocess.Popen(cmd, env=_env(), stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)  # the whole group this test started
    proc.wait(timeout=30)


def _precompute_cmd(src, out, *extra) -> list[str]:
    return [sys.executable, "-m", "symtorch", "precompute", str(src), str(out), "--k", "12",
            "--no-detect", "--quiet", *extra]


@pytest.mark.multiprocess
def test_worker_killed_with_sigkill_has_its_mesh_retried(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    n = 12
    make_tree(src, n=n, subdivisions=4)  # 2562 vertices: a mesh takes long enough to be killed in
    proc = _start(_precompute_cmd(src, out, "--workers", "2"))
    try:
        workers = lambda: [p for p in _children(proc.pid) if "spawn_main" in _cmdline(p)]  # noqa: E731
        _wait_for(lambda: len(workers()) == 2 and list(out.rglob("*.pt")), 180, "two busy workers",
                  proc)
        os.kill(workers()[0], signal.SIGKILL)
        _, err = proc.communicate(timeout=300)
    finally:
        _stop(proc)
    assert proc.returncode == 0, err
    assert "a worker process died (killed by SIGKILL); retrying" in err, err
    assert f"{n} done, 0 already done, 0 failed, of {n}" in err, err
    assert len(list(out.rglob("*.pt"))) == n and not (out / FAILURES).exists()
    assert sum(len(json.loads(m.read_text())["files"]) for m in out.rglob("meta.json")) == n


class KillWorkerOn:
    """A pre-transform that kills its own process (SIGKILL) on one mesh, as an OOM kill would."""

    def __init__(self, name: str):
        self.name = name

    def __call__(self, sample: dict) -> dict:
        if sample["name"] == self.name:
            os.kill(os.getpid(), signal.SIGKILL)
        return sample

    def __repr__(self) -> str:
        return f"KillWorkerOn({self.name!r})"


@pytest.mark.multiprocess
def test_mesh_that_kills_its_worker_twice_is_listed_with_the_cause(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    make_tree(src, n=5)
    s = precompute(src, out, pre_transform=KillWorkerOn("m2"), workers=2, progress=False)
    assert (s.done, s.failed) == (4, 1), s
    [line] = [json.loads(x) for x in (out / FAILURES).read_text().splitlines()]
    assert line["file"] == "m2.ply" and line["error"] == "WorkerDied"
    assert "died on this mesh twice (killed by SIGKILL" in line["reason"], line


@pytest.mark.multiprocess
@pytest.mark.parametrize("when", ["starting", "busy"])
def test_ctrl_c_with_workers_prints_one_line_and_exits_130(tmp_path, when):
    src, out = tmp_path / "src", tmp_path / "out"
    make_tree(src, n=12, subdivisions=4)
    proc = _start(_precompute_cmd(src, out, "--workers", "2"))
    try:
        workers = lambda: [p for p in _children(proc.pid) if "spawn_main" in _cmdline(p)]  # noqa: E731
        _wait_for(lambda: len(workers()) == 2 and (when == "starting" or list(out.rglob("*.pt"))),
                  180, f"two {when} workers", proc)
        started = workers()
        os.killpg(proc.pid, signal.SIGINT)  # what a terminal sends on Ctrl-C: the whole group
        _, err = proc.communicate(timeout=120)
    finally:
        _stop(proc)
    assert proc.returncode == 130, err
    assert err.strip() == "symtorch: error: interrupted", err
    _wait_for(lambda: not any(_alive(p) for p in started), 30, "the workers to end")
    rerun = subprocess.run(_precompute_cmd(src, out), env=_env(), capture_output=True, text=True,
                           timeout=300)  # what was recorded holds
    assert rerun.returncode == 0 and "0 failed, of 12" in rerun.stderr, rerun.stderr


@pytest.mark.multiprocess
def test_second_run_on_the_same_folder_is_refused(tmp_path, capsys):
    src, out = tmp_path / "src", tmp_path / "out"
    n = 10
    make_tree(src, n=n, subdivisions=4)
    first = _start(_precompute_cmd(src, out))
    try:
        _wait_for(lambda: list(out.rglob("*.pt")), 180, "the first run to write", first)
        planted = out / ".m9.pt.0123abcd.tmp"  # a temporary file of the first run
        planted.write_bytes(b"partial")
        rc = cli.main(["precompute", str(src), str(out), "--k", "12", "--no-detect", "--quiet"])
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1, err
        assert f"in use by another symtorch precompute (pid {first.pid} on" in err, err
        assert planted.exists(), "the second run deleted the first one's temporary file"
        planted.unlink()
        _, first_err = first.communicate(timeout=300)
    finally:
        _stop(first)
    assert first.returncode == 0 and f"{n} done, 0 already done, 0 failed" in first_err, first_err


@pytest.mark.multiprocess
def test_lock_of_a_killed_run_is_taken_over(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    make_tree(src, n=10, subdivisions=4)
    proc = _start(_precompute_cmd(src, out))
    try:
        _wait_for(lambda: list(out.rglob("*.pt")), 180, "the run to write", proc)
    finally:
        _stop(proc)  # kill -9: its lock file stays, naming it
    assert json.loads((out / ".run.lock").read_text())["pid"] == proc.pid
    s = precompute(src, out, k=12, detect=False, progress=False)
    assert s.failed == 0 and s.done + s.skipped == 10
    assert json.loads((out / ".run.lock").read_text())["pid"] == os.getpid()


@pytest.mark.multiprocess
def test_torchrun_ranks_leave_when_their_agent_dies(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    v, f = shapes.mirror_blob(5)  # rank 0: four 10242-vertex meshes; rank 1: three tiny ones
    small_v, small_f = shapes.mirror_blob(1)
    src.mkdir()
    for i in range(7):
        write_mesh(src / f"m{i}.off", *((v, f) if i % 2 == 0 else (small_v, small_f)))
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2",
           "-m", "symtorch", "precompute", str(src), str(out), "--k", "40", "--quiet"]
    agent = _start(cmd)
    try:
        ranks = lambda: [p for p in _children(agent.pid) if "symtorch" in _cmdline(p)]  # noqa: E731
        _wait_for(lambda: len(ranks()) == 2 and all((out / f"m{i}.pt").exists() for i in (1, 3, 5)),
                  240, "rank 1 to finish its share", agent)
        assert not (out / "m6.pt").exists(), "rank 0 finished too soon for the test"
        pids = ranks()
        os.kill(agent.pid, signal.SIGKILL)
        agent.wait(timeout=30)
        _wait_for(lambda: not any(_alive(p) for p in pids), 30, "the orphaned ranks to leave")
    finally:
        _stop(agent)
        for p in _children(1):  # anything of this test still running: end it
            if str(out) in _cmdline(p):
                os.kill(p, signal.SIGKILL)


@pytest.mark.multiprocess
def test_workers_1_and_2_write_bit_identical_files(tmp_path):
    """Floating-point sums follow the thread count: every process uses one thread in every pool."""
    src = tmp_path / "src"
    v, f = shapes.mirror_blob(5)  # 10242 vertices: large enough for OpenBLAS to use its threads
    src.mkdir()
    for i in range(2):
        write_mesh(src / f"m{i}.off", v * np.array([1.0 + 0.05 * i, 1.0, 0.9]), f)
    kw = dict(k=12, detect=False, dtype=torch.float64, progress=False)
    precompute(src, tmp_path / "one", workers=1, **kw)
    precompute(src, tmp_path / "two", workers=2, **kw)
    assert_same_cache(tmp_path / "one", tmp_path / "two")


# ------------------------------------------------------------------ damaged caches are recomputed

def _damage(path: Path, how: str, other: Path) -> None:
    data = path.read_bytes()
    if how == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif how == "randomise":
        path.write_bytes(np.random.default_rng(0).bytes(len(data)))
    elif how == "empty":
        path.write_bytes(b"")
    elif how == "bitflip":  # one bit of the last tensor's data: loads fine, values changed
        flipped = bytearray(data)
        at = data.rfind(b"archive/data/") - 200
        flipped[at] ^= 0x10
        path.write_bytes(bytes(flipped))
    elif how == "other_settings":
        path.write_bytes(other.read_bytes())


@pytest.mark.parametrize("how", ["truncate", "randomise", "empty", "bitflip", "other_settings"])
def test_damaged_cache_file_is_recomputed_by_precompute(tmp_path, caplog, how):
    src, out = tmp_path / "src", tmp_path / "out"
    make_tree(src, n=3)
    precompute(src, out, k=K, detect=False, progress=False)
    precompute(src, tmp_path / "other", k=K + 1, detect=False, progress=False)
    reference = (out / "m0.pt").read_bytes()
    _damage(out / "m0.pt", how, tmp_path / "other" / "m0.pt")
    s = precompute(src, out, k=K, detect=False, progress=False)
    assert (s.done, s.skipped) == (1, 2), f"{how}: {s}"
    assert "m0.pt: cache file" in caplog.text and "processing it again" in caplog.text, caplog.text
    assert (out / "m0.pt").read_bytes() == reference


@pytest.mark.parametrize("how", ["truncate", "bitflip", "other_settings"])
def test_damaged_cache_file_is_recomputed_by_meshdataset(tmp_path, how):
    src, cache = tmp_path / "src", tmp_path / "cache"
    make_tree(src, n=3)
    ds = MeshDataset(src, default_pre_transform(K, detect=False), processed_dir=cache)
    reference = ds.get(0)
    MeshDataset(src, default_pre_transform(K + 1, detect=False), processed_dir=tmp_path / "other")
    _damage(cache / "m0.pt", how, tmp_path / "other" / "m0.pt")
    # a wrong size shows when the dataset is built, a wrong checksum when the sample is loaded
    with pytest.warns(UserWarning, match=r"m0.pt: cache file .*; processing m0 again"):
        sample = MeshDataset(src, default_pre_transform(K, detect=False), processed_dir=cache)[0]
    assert all(torch.equal(sample[key], reference[key]) for key in reference
               if torch.is_tensor(reference[key])), how
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        MeshDataset(src, default_pre_transform(K, detect=False), processed_dir=cache)[0]  # verified


def test_mesh_edited_behind_a_restored_mtime_is_reprocessed(tmp_path):
    from symtorch.io import read_mesh

    src, cache = tmp_path / "src", tmp_path / "cache"
    make_tree(src, n=2)
    mesh = src / "m0.off"
    MeshDataset(src, processed_dir=cache)
    before = mesh.stat()
    lines = mesh.read_text().splitlines(keepends=True)
    lines[2] = lines[2].replace("1", "2", 1)  # one digit of vertex 0: the same size
    mesh.write_text("".join(lines))
    os.utime(mesh, ns=(before.st_atime_ns, before.st_mtime_ns))  # as cp -p, rsync -t, tar x do
    assert mesh.stat().st_size == before.st_size and mesh.stat().st_mtime_ns == before.st_mtime_ns
    ds = MeshDataset(src, processed_dir=cache)
    np.testing.assert_array_equal(ds.get(0)["verts"].numpy(), read_mesh(mesh).verts.astype(np.float32))
    touched = MeshDataset(src, processed_dir=cache)  # contents unchanged since: nothing to redo
    assert touched.process() == []


def test_on_uncertain_reaches_the_detector_the_settings_and_the_manifest(tmp_path, capsys):
    make_tree(tmp_path / "src", n=1, subdivisions=2)
    assert cli.main(["precompute", str(tmp_path / "src"), str(tmp_path / "out"), "--k", "40",
                     "--k-refine", "20", "--on-uncertain", "flag"]) == 0
    s = json.loads((tmp_path / "out" / SETTINGS).read_text())
    assert s["on_uncertain"] == "flag" and s["default_pre_transform"] is True
    assert "on_uncertain='flag'" in s["key"]["pre_transform"]
    assert repr(default_pre_transform(40, True, 0, 20)) == repr(default_pre_transform(40, True, 0, 20, "keep"))
    sample = open_dataset(tmp_path / "src", tmp_path / "out")[0]
    G = sample["sym_p2p"].shape[0]
    assert sample["sym_uncertain"].shape == sample["sym_confidence"].shape == (G,)
    flagged = bool(sample["sym_uncertain"].any())
    assert flagged == bool((sample["sym_confidence"][1:] < DetectConfig().min_confidence).any())
    entry = json.loads((tmp_path / "out" / "meta.json").read_text())["files"]["m0"]
    assert entry["uncertain"] is flagged
    assert ("1 uncertain" in capsys.readouterr().err) is flagged
    with pytest.raises(SystemExit):  # argparse: not one of keep, flag, drop
        cli.main(["precompute", str(tmp_path / "src"), str(tmp_path / "o2"), "--on-uncertain", "skip"])
    assert "invalid choice: 'skip'" in capsys.readouterr().err
