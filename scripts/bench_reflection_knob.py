"""What one knob of the detection costs, end to end.

    python scripts/bench_reflection_knob.py                          # --knob second_opinion
    python scripts/bench_reflection_knob.py --knob fmap_candidate
    python scripts/bench_reflection_knob.py --knob geodesics --values batched potpourri3d

Median end-to-end ``detect_symmetries`` time (spectrum included) on every 7th SCAPE mesh (10 meshes;
``--dataset``, ``--every``, ``--limit``) with the knob at its two ``--values`` (a boolean
``ReflectionConfig`` knob: True and False; a ``DetectConfig`` field: the two values given), the
two settings interleaved mesh by mesh so that a change in the machine's load reaches both, each
run ``--repeats`` times (the fastest kept), and the median of the per-mesh differences.
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
TOP = [f.name for f in fields(DetectConfig) if f.name not in ("reflection", "group")]


def config(knob: str, value) -> DetectConfig:
    if knob in TOP:
        return DetectConfig(**{knob: value})
    return DetectConfig(reflection=ReflectionConfig(**{knob: value}))


def parse(value: str):
    return {"true": True, "false": False}.get(value.lower(), value)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--knob", default="second_opinion", choices=KNOBS + TOP)
    ap.add_argument("--values", nargs=2, default=["true", "false"], metavar=("A", "B"))
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--dataset", default="SCAPE")
    ap.add_argument("--every", type=int, default=7, help="every N-th mesh")
    ap.add_argument("--limit", type=int, default=10)
    args = ap.parse_args()
    warnings.filterwarnings("ignore")
    meshes = list_benchmark(args.dataset)[::args.every][:args.limit]
    a, b = (parse(x) for x in args.values)
    times: dict[object, list[float]] = {a: [], b: []}
    for name, path in meshes:
        v, f = load_mesh(path)
        best = {a: float("inf"), b: float("inf")}
        for _ in range(args.repeats):
            for value in (a, b):
                t = time.perf_counter()
                detect_symmetries(v, f, config=config(args.knob, value))
                best[value] = min(best[value], time.perf_counter() - t)
        for value in (a, b):
            times[value].append(best[value])
        print(f"{name:>12s}  {a} {best[a]:.3f} s  {b} {best[b]:.3f} s", flush=True)
    diff = np.array(times[a]) - np.array(times[b])
    print(f"{args.knob}: median {np.median(times[a]):.3f} s {a}, {np.median(times[b]):.3f} s {b} "
          f"({len(meshes)} {args.dataset} meshes); median per-mesh difference {np.median(diff):+.3f} s")


if __name__ == "__main__":
    main()
