"""What one group-path knob costs: ``GroupConfig(KNOB=VALUE)`` against the default, interleaved.

    OMP_NUM_THREADS=1 python scripts/bench_group_knob.py                                 # n_alternatives=0
    OMP_NUM_THREADS=1 python scripts/bench_group_knob.py --knob partner_radius --value 0 --runs 3
    OMP_NUM_THREADS=1 python scripts/bench_group_knob.py --knob n_near_misses --value 0

CPU seconds of ``detect_symmetries`` (``mode="auto"``, spectrum included) on the paper's table, the
SHREC'07 Watertight table 156 (the shapes read from the shared data where present) and some shapes
of ``tests/shapes.py``'s ``GROUP_SHAPES``; the two settings interleaved (their order swapped every
run) so that a change in the machine's load reaches both. Prints the group each setting finds and
the ratio of the medians (default over the knob's value).
"""
from __future__ import annotations

import argparse
import json
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

SHAPES = ("star5_thin", "star5_thin_bent", "star8_thin", "box", "arms8", "chiral5", "star6_thin_bent4",
          "star6_h03_bent3")


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
    ap.add_argument("--knob", default="n_alternatives", help="a GroupConfig field")
    ap.add_argument("--value", default="0", help="its value to compare the default with (JSON)")
    ap.add_argument("--runs", type=int, default=2)
    args = ap.parse_args()
    base = GroupConfig()
    configs = {"knob": GroupConfig(**{args.knob: json.loads(args.value)}), "default": base}
    print(f"{args.knob}: {json.loads(args.value)} against the default {getattr(base, args.knob)}")
    totals = {k: 0.0 for k in configs}
    for name, (v, f) in meshes().items():
        cpu = {k: [] for k in configs}
        groups = {}
        for run in range(args.runs):
            for k in (list(configs) if run % 2 == 0 else list(configs)[::-1]):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t = time.process_time()
                    res = detect_symmetries(v, f, config=DetectConfig(group=configs[k]))
                    cpu[k].append(time.process_time() - t)
                groups[k] = res.group.name
        m0, m1 = statistics.median(cpu["knob"]), statistics.median(cpu["default"])
        totals["knob"] += m0
        totals["default"] += m1
        print(f"{name:18s} {args.knob}={args.value} {m0:6.2f} s ({groups['knob']:5s})  default {m1:6.2f} s "
              f"({groups['default']:5s})  ratio {m1 / m0:.2f}", flush=True)
    print(f"{'sum':18s} {totals['knob']:.2f} s against {totals['default']:.2f} s: ratio "
          f"{totals['default'] / totals['knob']:.2f}")


if __name__ == "__main__":
    main()
