"""What the reflection path's second opinion (the confidence's guided selection) costs.

    python scripts/bench_second_opinion.py

Median end-to-end ``detect_symmetries`` time on every 7th SCAPE mesh (10 meshes; ``--dataset``, ``--every``, ``--limit``), with and without
``ReflectionConfig(second_opinion=...)``; spectrum included.
"""
import argparse
import time
import warnings

import numpy as np

from symtorch.detect import DetectConfig, detect_symmetries
from symtorch.detect.config import ReflectionConfig
from symtorch.eval.benchmarks import list_benchmark, load_mesh


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="SCAPE")
    ap.add_argument("--every", type=int, default=7, help="every N-th mesh")
    ap.add_argument("--limit", type=int, default=10)
    args = ap.parse_args()
    warnings.filterwarnings("ignore")
    meshes = list_benchmark(args.dataset)[::args.every][:args.limit]
    for so in (True, False):
        ts = []
        for m in meshes:
            v, f = load_mesh(m[1])
            t = time.perf_counter()
            cfg = DetectConfig(reflection=ReflectionConfig(second_opinion=so))
            detect_symmetries(v, f, config=cfg)
            ts.append(time.perf_counter() - t)
        print("second_opinion", so, "median", round(float(np.median(ts)), 3), "s")


if __name__ == "__main__":
    main()
