"""Throughput of ``symtorch precompute`` (meshes per minute) and peak memory per worker.

    python scripts/bench_precompute.py [--limit 12] [--workers 1 2] [--k 64] [--no-detect]

Reads the shared ``bcicp_5k`` meshes (FAUST and TOSCA remeshed to ~5k vertices) in place: ``--limit``
meshes evenly spaced over the sorted list are linked into a temporary folder, and each worker count
processes them into a fresh temporary cache. Peak memory is the largest ``ru_maxrss`` of a process
that processed meshes (with one worker: the main process, imports included).
"""
from __future__ import annotations

import argparse
import logging
import os
import platform
import tempfile
import time
import warnings
from pathlib import Path

from symtorch.paths import shared_path
from symtorch.data.precompute import find_meshes, precompute


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--limit", type=int, default=12, help="number of meshes (default 12; 0: all 86)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--k", type=int, default=64)
    ap.add_argument("--detect", action=argparse.BooleanOptionalAction, default=True)
    args = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    warnings.filterwarnings("ignore")
    root = shared_path("bcicp_5k")
    if root is None:
        raise SystemExit("shared data not found: bcicp_5k")
    files = find_meshes(root)
    if args.limit and args.limit < len(files):
        step = len(files) / args.limit
        files = [files[int(i * step)] for i in range(args.limit)]
    print(f"{len(files)} meshes from {root} (k={args.k}, detect={args.detect}); "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}, {platform.processor() or ''}")
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "src"
        for f in files:
            link = src / f.relative_to(root)
            link.parent.mkdir(parents=True, exist_ok=True)
            link.symlink_to(f)
        print("| workers | meshes | seconds | meshes/min | peak RSS per worker (MB) | load avg |")
        print("|---|---|---|---|---|---|")
        for w in args.workers:
            t0 = time.perf_counter()
            s = precompute(src, Path(tmp) / f"out{w}", k=args.k, detect=args.detect, workers=w,
                           progress=False)
            sec = time.perf_counter() - t0
            print(f"| {w} | {s.done} ({s.failed} failed) | {sec:.1f} | {60 * s.done / sec:.1f} | "
                  f"{s.peak_rss_mb:.0f} | {os.getloadavg()[0]:.1f} |", flush=True)


if __name__ == "__main__":
    main()
