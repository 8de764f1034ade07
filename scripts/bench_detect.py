"""Stage timings of ``detect_symmetries`` on real meshes: spectrum vs detection, end to end.

    python scripts/bench_detect.py --dataset SCAPE --limit 10 [--mode auto|reflection|group]

Per mesh: each stage's seconds (``SymmetryResult.timings``), the spectrum time, the detection time
after it, their ratio, and the end-to-end wall time (reading the mesh excluded). Summary: medians.
Each mesh is run twice and the second run is reported (the first pays one-off import and
allocation costs).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings

import torch

from symtorch import detect_symmetries
from symtorch.eval.benchmarks import DATASETS, list_benchmark, load_mesh


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dataset", default="SCAPE", choices=list(DATASETS))
    p.add_argument("--limit", type=int, default=10)
    p.add_argument("--mode", default="auto", choices=["auto", "reflection", "group"])
    args = p.parse_args(argv)
    warnings.filterwarnings("ignore")
    meshes = list_benchmark(args.dataset)
    step = max(len(meshes) // args.limit, 1)
    meshes = meshes[::step][: args.limit]
    print(f"{args.dataset}: {len(meshes)} meshes, mode={args.mode}, torch threads "
          f"{torch.get_num_threads()}", file=sys.stderr)
    rows = []
    for name, path in meshes:
        v, f = load_mesh(path)
        for _ in range(2):
            t0 = time.perf_counter()
            res = detect_symmetries(v, f, mode=args.mode)
            total = time.perf_counter() - t0
        spec = res.timings.get("spectrum", 0.0)
        det = sum(res.timings.values()) - spec
        rows.append((spec, det, total))
        stages = " ".join(f"{k}={t:.3f}" for k, t in res.timings.items())
        print(f"{name:>12s} V={len(v):>6d} group={res.group.name!s:>4s} total {total:5.2f} s | "
              f"spectrum {spec:.2f} detection {det:.2f} ratio {det / max(spec, 1e-9):.2f} | {stages}",
              flush=True)
    med = [statistics.median(r[i] for r in rows) for i in range(3)]
    print(f"\nmedian: total {med[2]:.2f} s, spectrum {med[0]:.2f} s, detection {med[1]:.2f} s, "
          f"detection/spectrum {statistics.median(r[1] / max(r[0], 1e-9) for r in rows):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
