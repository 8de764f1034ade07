"""What group-path knobs cost: ``GroupConfig(KEY=VALUE, ...)`` against the default, interleaved.

    OMP_NUM_THREADS=1 python scripts/bench_group_knob.py                                 # n_alternatives=0
    OMP_NUM_THREADS=1 python scripts/bench_group_knob.py --set partner_radius=0 --runs 3
    OMP_NUM_THREADS=1 python scripts/bench_group_knob.py --set n_near_misses=0
    OMP_NUM_THREADS=1 python scripts/bench_group_knob.py --set partner_radius=0 n_near_misses=0 \
        --mode group --k-refine 40 --only table.off --runs 6 --wall      # as evaluate_groups.py times it
    OMP_NUM_THREADS=1 python scripts/bench_group_knob.py --set merged_gap=0 --only blades2 "Watertight 126"

CPU seconds (``--wall``: wall seconds) of ``detect_symmetries`` (``mode="auto"`` or ``--mode``, spectrum included) on the paper's table, the
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
          "star6_h03_bent3", "arms8_bent4", "chiral8_bent4")


def meshes(only: list[str] | None = None) -> dict:
    """The shapes timed: the default set, or those named in ``only`` (any ``GROUP_SHAPES`` row,
    ``table.off`` or ``Watertight N``)."""
    watertight = [n.split()[1] for n in only or [] if n.startswith("Watertight ")] or ["156"]
    out = {}
    for name, rel in [("table.off", ("wang_huang_pg2017", "table.off"))] + [
            (f"Watertight {i}", ("bim_scb_benchmark", "Watertight", "Meshes", f"{i}.off")) for i in watertight]:
        path = shared_path(*rel)
        if path is not None and (not only or name in only):
            out[name] = load_mesh(path)
    for sid, build, _, _, radius in GROUP_SHAPES:
        if (sid in only) if only else (sid in SHAPES):
            v, f, _ = build()
            out[sid] = (bend(v, radius) if radius else v, f)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", nargs="+", default=["n_alternatives=0"], metavar="KEY=VALUE",
                    help="GroupConfig fields (JSON values) to compare the default with")
    ap.add_argument("--mode", default="auto", choices=["auto", "group"])
    ap.add_argument("--k-refine", type=int, default=100, help="detect_symmetries' k_refine "
                    "(evaluate_groups.py times the group mode at 40)")
    ap.add_argument("--only", nargs="*", default=None,
                    help="only these shapes (any GROUP_SHAPES row, table.off, 'Watertight N')")
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--wall", action="store_true", help="wall seconds instead of CPU seconds")
    args = ap.parse_args()
    knobs = {k: json.loads(v) for k, v in (kv.split("=", 1) for kv in args.set)}
    base = GroupConfig()
    configs = {"knobs": GroupConfig(**knobs), "default": base}
    label = " ".join(args.set)
    print(f"{label} against the default ({', '.join(f'{k}={getattr(base, k)}' for k in knobs)}), "
          f"mode={args.mode}, {'wall' if args.wall else 'CPU'} s")
    clock = time.perf_counter if args.wall else time.process_time
    totals = {k: 0.0 for k in configs}
    for name, (v, f) in meshes(args.only).items():
        secs = {k: [] for k in configs}
        groups = {}
        for run in range(args.runs):
            for k in (list(configs) if run % 2 == 0 else list(configs)[::-1]):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t = clock()
                    res = detect_symmetries(v, f, mode=args.mode, k_refine=args.k_refine,
                                            config=DetectConfig(group=configs[k]))
                    secs[k].append(clock() - t)
                g = res.diagnostics.group
                cands = g.n_candidates if g is not None and g.n_candidates is not None else "-"
                groups[k] = f"{res.group.name}, {cands} cand."  # the candidate tuples the group path kept
        m0, m1 = statistics.median(secs["knobs"]), statistics.median(secs["default"])
        totals["knobs"] += m0
        totals["default"] += m1
        print(f"{name:18s} {label} {m0:6.2f} s ({groups['knobs']:14s})  default {m1:6.2f} s "
              f"({groups['default']:14s})  ratio {m1 / m0:.2f}", flush=True)
    print(f"{'sum':18s} {totals['knobs']:.2f} s against {totals['default']:.2f} s: ratio "
          f"{totals['default'] / totals['knobs']:.2f}")


if __name__ == "__main__":
    main()
