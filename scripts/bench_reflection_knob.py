"""What one on/off knob of the reflection path costs, end to end.

    python scripts/bench_reflection_knob.py                          # --knob second_opinion
    python scripts/bench_reflection_knob.py --knob fmap_candidate

Median end-to-end ``detect_symmetries`` time (spectrum included) on every 7th SCAPE mesh (10 meshes;
``--dataset``, ``--every``, ``--limit``) with ``ReflectionConfig(<knob>=True)`` and ``=False``,
the two settings interleaved mesh by mesh so that a change in the machine's load reaches both, and
the median of the per-mesh differences.
"""
import argparse
import time
import warnings
from dataclasses import fields

import numpy as np

from symtorch.detect import DetectConfig, detect_symmetries
from symtorch.detect.config import ReflectionConfig
from symtorch.eval.benchmarks import list_benchmark, load_mesh

KNOBS = [f.name for f in fields(ReflectionConfig) if f.type in (bool, "bool")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--knob", default="second_opinion", choices=KNOBS)
    ap.add_argument("--dataset", default="SCAPE")
    ap.add_argument("--every", type=int, default=7, help="every N-th mesh")
    ap.add_argument("--limit", type=int, default=10)
    args = ap.parse_args()
    warnings.filterwarnings("ignore")
    meshes = list_benchmark(args.dataset)[::args.every][:args.limit]
    times: dict[bool, list[float]] = {True: [], False: []}
    for name, path in meshes:
        v, f = load_mesh(path)
        for on in (True, False):
            cfg = DetectConfig(reflection=ReflectionConfig(**{args.knob: on}))
            t = time.perf_counter()
            detect_symmetries(v, f, config=cfg)
            times[on].append(time.perf_counter() - t)
        print(f"{name:>12s}  on {times[True][-1]:.3f} s  off {times[False][-1]:.3f} s", flush=True)
    diff = np.array(times[True]) - np.array(times[False])
    print(f"{args.knob}: median {np.median(times[True]):.3f} s on, {np.median(times[False]):.3f} s off "
          f"({len(meshes)} {args.dataset} meshes); median per-mesh difference {np.median(diff):+.3f} s")


if __name__ == "__main__":
    main()
