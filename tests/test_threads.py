"""symtorch.threads: the solves' thread pools capped at the free cores or a fixed number."""
from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
import scipy.linalg  # noqa: F401 -- loads scipy's OpenBLAS, one of the pools capped
import torch
from threadpoolctl import threadpool_info

import symtorch.spectrum as spectrum_module
from symtorch import cli, shapes
from symtorch.threads import free_cores, limit_threads, num_threads, set_num_threads


def blas_threads() -> list[int]:
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


def test_limit_caps_blas_and_torch_and_restores_them():
    blas, tt = blas_threads(), torch.get_num_threads()
    with limit_threads(1) as cap:
        assert cap == 1 and blas_threads() == [1] * len(blas) and torch.get_num_threads() == 1
        with limit_threads() as inner:  # nested: keeps the outer cap, no new reading of the load
            assert inner == 1 and torch.get_num_threads() == 1
    assert blas_threads() == blas and torch.get_num_threads() == tt


def test_limit_never_raises_a_pool():
    tt = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with limit_threads(64):
            assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(tt)


def test_setting_and_environment(monkeypatch):
    set_num_threads(3)
    try:
        assert num_threads() == 3
    finally:
        set_num_threads(None)
    monkeypatch.setenv("SYMTORCH_NUM_THREADS", "2")
    assert num_threads() == 2
    monkeypatch.setenv("SYMTORCH_NUM_THREADS", "many")
    with pytest.raises(ValueError, match="SYMTORCH_NUM_THREADS must be a positive integer"):
        num_threads()
    with pytest.raises(ValueError, match="n must be a positive int or None, got 0"):
        set_num_threads(0)


@pytest.mark.multiprocess
def test_busy_processes_take_their_cores():
    """One CPU-bound process per core: the solves are left one thread (they swung tenfold)."""
    cores = len(os.sched_getaffinity(0))
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(cores)]
    try:
        time.sleep(0.5)
        assert free_cores() == 1
    finally:
        for p in burners:
            p.kill()
            p.wait()


def test_the_spectrum_solves_inside_the_cap(monkeypatch):
    seen = []
    real = spectrum_module.SPDFactor

    def recording(*args, **kwargs):
        seen.append((blas_threads(), torch.get_num_threads()))
        return real(*args, **kwargs)

    monkeypatch.setattr(spectrum_module, "SPDFactor", recording)
    v, f = shapes.mirror_blob(2)
    set_num_threads(1)
    try:
        spectrum_module.laplacian_spectrum(v, f, k=8)
    finally:
        set_num_threads(None)
    assert seen and all(b == [1] * len(b) and t == 1 for b, t in seen), seen


def test_cli_threads_option(capsys):
    assert cli.main(["info", "--demo", "--k", "4", "--threads", "1", "--json"]) == 0
    assert cli.main(["info", "--demo", "--k", "4", "--threads", "0"]) == 2
    assert capsys.readouterr().err.strip() == "symtorch: error: --threads must be >= 1, got 0"
