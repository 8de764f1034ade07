"""Heat-method backends on real meshes: set-up and per-source time, and how far they agree.

    python scripts/bench_geodesics.py --dataset SCAPE --limit 5 [--sources 96]

Per mesh, for potpourri3d's robust solver (the intrinsic-Delaunay tufted cover), its plain solver and
``symtorch.heat_method.BatchedHeatMethod``: the set-up time (factorisations), the time per source
for ``--sources`` evenly spaced sources (potpourri3d one ``compute_distance`` each, the batched one
all of them in one ``distances_from``), and each one's mean absolute difference from the robust
solver, relative to the robust solver's mean distance. Summary: medians and the per-source speed-up.
Times are wall seconds, fastest of two runs.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np
import potpourri3d as pp3d

from symtorch.eval.benchmarks import DATASETS, list_benchmark, load_mesh
from symtorch.heat_method import BatchedHeatMethod


def _fastest(fn, repeats: int = 2):
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dataset", default="SCAPE", choices=list(DATASETS))
    p.add_argument("--limit", type=int, default=5)
    p.add_argument("--sources", type=int, default=96)
    args = p.parse_args(argv)
    meshes = list_benchmark(args.dataset)
    meshes = meshes[:: max(len(meshes) // args.limit, 1)][: args.limit]
    names = ("robust", "plain", "batched")
    rows = []
    for name, path in meshes:
        v, f = load_mesh(path)
        src = np.linspace(0, len(v) - 1, args.sources).astype(np.int64)
        build = {
            "robust": lambda: pp3d.MeshHeatMethodDistanceSolver(v, f, use_robust=True),
            "plain": lambda: pp3d.MeshHeatMethodDistanceSolver(v, f, use_robust=False),
            "batched": lambda: BatchedHeatMethod.build(v, f),
        }
        setup, per_src, dist = {}, {}, {}
        for key in names:
            setup[key], solver = _fastest(build[key])
            if solver is None:
                print(f"{name}: the batched solver refuses this mesh", file=sys.stderr)
                break
            run = (lambda s=solver: s.distances_from(src)) if key == "batched" else \
                (lambda s=solver: np.stack([s.compute_distance(int(i)) for i in src]))
            t, dist[key] = _fastest(run)
            per_src[key] = t / len(src)
        else:
            ref = dist["robust"]
            diff = {k: float(np.abs(dist[k] - ref).mean() / ref.mean()) for k in names}
            rows.append((setup, per_src, diff))
            print(f"{name:>12s} V={len(v):>6d} | " + " | ".join(
                f"{k}: set-up {setup[k]:.3f} s, {1e3 * per_src[k]:.2f} ms/source, "
                f"diff {diff[k]:.1e}" for k in names), flush=True)
    if not rows:
        return 1
    med = {k: tuple(statistics.median(r[i][k] for r in rows) for i in range(3)) for k in names}
    print("\nmedian: " + " | ".join(f"{k}: set-up {m[0]:.3f} s, {1e3 * m[1]:.2f} ms/source, diff "
                                    f"{m[2]:.1e}" for k, m in med.items()))
    print(f"per-source speed-up of batched over robust: {med['robust'][1] / med['batched'][1]:.1f}x; "
          f"set-up + {args.sources} sources: robust {med['robust'][0] + args.sources * med['robust'][1]:.3f} s, "
          f"batched {med['batched'][0] + args.sources * med['batched'][1]:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
