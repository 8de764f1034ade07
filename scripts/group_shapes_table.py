"""The group path on the test suite's shapes with exactly known groups: one table row per shape.

    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py              # every GROUP_SHAPES row + chiral 8 arms
    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py arms chiral  # rows whose name contains a word

The shapes are ``tests/shapes.py``'s ``GROUP_SHAPES`` (what ``tests/test_group_shapes.py`` checks)
and the chiral eight arms (``tests/test_group_path.py``). Per shape, as the tests score it:
``detect_symmetries(v, f)`` (``mode="auto"``, default knobs), the group found, the true elements
matched within sqrt(area / (20 pi)) on >= 95 % of 100 evenly spaced vertices and the spurious ones
(``eval.groups.element_rates``), the warnings, the median distortion of the group path's rotations
and of its orientation-reversing elements (``diagnostics.group.distortion``, EPS_KLC), and the
wall and CPU seconds of the detection.
"""
from __future__ import annotations

import statistics
import sys
import time
import warnings
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the shape builders
from shapes import GROUP_SHAPES, armed_ball, bend  # noqa: E402

from symtorch import detect_symmetries  # noqa: E402
from symtorch.eval.groups import element_rates  # noqa: E402
from symtorch.geodesics import GeodesicSolver  # noqa: E402
from symtorch.shapes import symmetry_maps  # noqa: E402

SHAPES = GROUP_SHAPES + [("chiral8", lambda: armed_ball(8, chiral=True), "C8", 8, 0)]


def _median(xs: list[float]) -> str:
    return f"{statistics.median(xs):.3f}" if xs else "–"


def main() -> None:
    words = sys.argv[1:]
    torch.set_num_threads(1)
    print("| shape | V | truth | found | matched | spurious | warnings | rotations' / mirrors' distortion | wall s | CPU s |")
    print("|---|---:|---|---|---:|---:|---:|---|---:|---:|")
    for name, build, group, order, radius in SHAPES:
        if words and not any(w in name for w in words):
            continue
        v0, f, mats = build()
        v = bend(v0, radius) if radius else v0
        t0, c0 = time.perf_counter(), time.process_time()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = detect_symmetries(v, f)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        sc, _ = element_rates(GeodesicSolver(v, f), symmetry_maps(v0, mats), res.p2ps)
        g = res.diagnostics.group
        rot, mir = [], []
        if g is not None and g.distortion is not None:
            for d, r in list(zip(g.distortion, res.group.reversing.tolist()))[1:]:
                (mir if r else rot).append(d)
        print(f"| {name} | {len(v)} | {group} ({order}) | {res.group.name} ({res.group.order}) | "
              f"{sc.found}/{order} | {sc.spurious} | {len(caught)} | {_median(rot)} / {_median(mir)} | "
              f"{wall:.1f} | {cpu:.1f} |", flush=True)


if __name__ == "__main__":
    main()
