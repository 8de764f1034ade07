"""Thread pools under load: the spectrum and one detection, alone and beside a busy process.

    python scripts/bench_threads.py [--mesh PATH] [--calls 5] [--k 110] [--skip-detect]

``laplacian_spectrum(k=110)`` and ``detect_symmetries`` on SCAPE ``mesh000.off`` (12.5K vertices), each
called ``--calls`` times in every setting:

- ``default``: the library as it is (the solves cap their pools at the cores not busy when they start,
  ``symtorch.threads``); for the detection also ``default, capped``: the whole call inside
  ``limit_threads()``, as the command line runs it (the detector's own torch work included);
- ``one thread``: ``set_num_threads(1)`` and ``torch.set_num_threads(1)``.

and in two conditions: ``alone`` and ``beside busy`` (a CPU-bound subprocess this script starts and
stops). Prints the median and the slowest call of each, the load averages before each condition
(``os.getloadavg()``), and the ratio *default's slowest beside busy / one thread's median beside busy*
(target: at most 1.3). On a shared machine the numbers move with the others' load: read them with
the load averages printed.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
import warnings
from contextlib import contextmanager, nullcontext

import torch

from symtorch.detect import detect_symmetries
from symtorch.io import read_mesh
from symtorch.paths import shared_path
from symtorch.spectrum import laplacian_spectrum
from symtorch.threads import free_cores, limit_threads, set_num_threads


@contextmanager
def busy_process():
    """A CPU-bound process beside this one, for the duration of the block."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    time.sleep(1.0)  # let it take its core
    try:
        yield
    finally:
        proc.kill()
        proc.wait()


@contextmanager
def one_thread():
    torch_before = torch.get_num_threads()
    set_num_threads(1)
    torch.set_num_threads(1)
    try:
        yield
    finally:
        set_num_threads(None)
        torch.set_num_threads(torch_before)


def timed(fn, calls: int) -> list[float]:
    out = []
    for _ in range(calls):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def load() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", default=None, help="mesh file (default SCAPE mesh000.off)")
    parser.add_argument("--calls", type=int, default=5)
    parser.add_argument("--k", type=int, default=110)
    parser.add_argument("--skip-detect", action="store_true")
    args = parser.parse_args()
    path = args.mesh or shared_path("bim_scb_benchmark", "SCAPE", "Meshes", "mesh000.off")
    if path is None:
        raise SystemExit("SCAPE mesh000.off not found: pass --mesh or set $SYMTORCH_SHARED")
    warnings.simplefilter("ignore")
    mesh = read_mesh(path)
    print(f"{path}: {len(mesh.verts)} vertices; {len(os.sched_getaffinity(0))} cores, torch "
          f"{torch.get_num_threads()} threads; {args.calls} calls each")
    laplacian_spectrum(mesh.verts, mesh.faces, k=10)  # imports and first-call costs out of the way

    tasks = {"spectrum": lambda: laplacian_spectrum(mesh.verts, mesh.faces, k=args.k)}
    if not args.skip_detect:
        tasks["detection"] = lambda: detect_symmetries(mesh.verts, mesh.faces)
    settings = {"default": nullcontext, "one thread": one_thread}
    rows = []
    for condition in ("alone", "beside busy"):
        with busy_process() if condition == "beside busy" else nullcontext():
            print(f"{condition}: load average {load()}, free cores now {free_cores()}", flush=True)
            for task, fn in tasks.items():
                names = ["default", "one thread"] + (["default, capped"] if task == "detection" else [])
                for name in names:
                    ctx = (lambda: limit_threads()) if name == "default, capped" else settings[name]
                    with ctx():
                        times = timed(fn, args.calls)
                    rows.append((task, condition, name, times))
                    print(f"  {task:9s} {name:16s} median {statistics.median(times):6.2f} s  "
                          f"slowest {max(times):6.2f} s", flush=True)

    print(f"\nload average at the end {load()}\n")
    print("| task | condition | setting | median (s) | slowest (s) |")
    print("|---|---|---|---:|---:|")
    for task, condition, name, times in rows:
        print(f"| {task} | {condition} | {name} | {statistics.median(times):.2f} | {max(times):.2f} |")
    print()
    for task in tasks:
        one = next(t for k, c, n, t in rows if (k, c, n) == (task, "beside busy", "one thread"))
        for name in ("default", "default, capped"):
            hit = [t for k, c, n, t in rows if (k, c, n) == (task, "beside busy", name)]
            if hit:
                ratio = max(hit[0]) / statistics.median(one)
                print(f"{task}, {name}: slowest beside busy / one thread's median beside busy = "
                      f"{ratio:.2f} (target <= 1.3)")


if __name__ == "__main__":
    main()
