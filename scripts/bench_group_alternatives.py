"""What the group path's alternative elements cost: ``GroupConfig(n_alternatives=0)`` against the default.

    OMP_NUM_THREADS=1 python scripts/bench_group_alternatives.py             # two runs per setting
    OMP_NUM_THREADS=1 python scripts/bench_group_alternatives.py --runs 3

CPU seconds of ``detect_symmetries`` (``mode="auto"``, spectrum included) on the paper's table, the
SHREC'07 Watertight table 156 (the shapes read from the shared data where present) and five shapes
of ``tests/shapes.py``'s ``GROUP_SHAPES``; the two settings interleaved (their order swapped every
run) so that a change in the machine's load reaches both. Prints the group each setting finds and
the ratio of the medians.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

from symtorch.detect import DetectConfig, detect_symmetries
from symtorch.detect.config import GroupConfig
from symtorch.eval.benchmarks import load_mesh
from symtorch.paths import shared_path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from shapes import GROUP_SHAPES, bend  # noqa: E402

SHAPES = ("star5_thin", "star5_thin_bent", "star8_thin", "box", "arms8")


def meshes() -> dict:
    out = {}
    for name, rel in (("table.off", ("wang_huang_pg2017", "table.off")),
                      ("Watertight 156", ("bim_scb_benchmark", "Watertight", "Meshes", "156.off"))):
        path = shared_path(*rel)
        if path is not None:
            out[name] = load_mesh(path)
    for sid, build, _, _, radius in GROUP_SHAPES:
        if sid in SHAPES:
            v, f, _ = build()
            out[sid] = (bend(v, radius) if radius else v, f)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2)
    args = ap.parse_args()
    default = GroupConfig().n_alternatives
    settings = (0, default)
    for name, (v, f) in meshes().items():
        cpu = {a: [] for a in settings}
        groups = {}
        for run in range(args.runs):
            for a in (settings if run % 2 == 0 else settings[::-1]):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t = time.process_time()
                    res = detect_symmetries(v, f, config=DetectConfig(group=GroupConfig(n_alternatives=a)))
                    cpu[a].append(time.process_time() - t)
                groups[a] = res.group.name
        m0, m1 = statistics.median(cpu[0]), statistics.median(cpu[default])
        print(f"{name:16s} without {m0:6.2f} s ({groups[0]:5s})  with {m1:6.2f} s ({groups[default]:5s})  "
              f"ratio {m1 / m0:.2f}", flush=True)


if __name__ == "__main__":
    main()
