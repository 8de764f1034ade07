"""The continuous-symmetry test on surfaces of revolution and on near-round solids, in mean edges.

    OMP_NUM_THREADS=1 python scripts/continuous_test_table.py             # every row
    OMP_NUM_THREADS=1 python scripts/continuous_test_table.py cone anti   # rows whose name contains a word

Per shape (``--remesh N``: also each one ACVD-remeshed to about N vertices, pyacvd needed), what
``group_path.continuous_test`` measured in ``detect_symmetries(v, f, mode="group")``: the band it
rotated, the refined rotation's distortion at both test angles (KLC radii, and in mean edge lengths
of the unit-area mesh, ``units.mean_edge``), its bound, the share of the area whose heat level it
changes (``verification.HeatLevels``; bound ``GroupConfig.max_level_change``), and the verdict. A
vertex map of an exact rotation costs about a quarter of an edge; the bound is half an edge (and
0.6 radii). ``--group max_level_change=1`` runs the test without the heat-level bound.
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from shapes import _trimesh_arrays, antiprism, convex_solid, extruded_polygon  # noqa: E402

from symtorch import detect_symmetries, shapes  # noqa: E402
from symtorch.detect.config import DetectConfig, GroupConfig  # noqa: E402
from symtorch.units import EPS_KLC, mean_edge  # noqa: E402


def _trimesh(name: str, edge: float):
    import trimesh

    make = {"capsule": lambda: trimesh.creation.capsule(height=1.0, radius=0.4, count=[32, 32]),
            "cylinder": lambda: trimesh.creation.cylinder(radius=0.5, height=1.2, sections=64),
            "torus": lambda: trimesh.creation.torus(1.0, 0.35, major_sections=64, minor_sections=32),
            "cone": lambda: trimesh.creation.cone(radius=0.6, height=1.0, sections=64),
            "vase": lambda: trimesh.creation.revolve(np.array([[0.0, 0.0], [0.5, 0.0], [0.35, 0.4], [0.55, 0.9],
                                                              [0.3, 1.3], [0.32, 1.6], [0.0, 1.6]]), sections=64)}[name]
    return lambda: _trimesh_arrays(make(), edge)


ROWS = [("sphere", lambda: shapes.icosphere(3), "continuous"), ("ellipsoid", lambda: shapes.ellipsoid(3), "continuous"),
        ("capsule", _trimesh("capsule", 0.06), "continuous"), ("cylinder", _trimesh("cylinder", 0.06), "continuous"),
        ("torus", _trimesh("torus", 0.1), "continuous"), ("cone", _trimesh("cone", 0.05), "continuous"),
        ("vase", _trimesh("vase", 0.05), "continuous"),
        ("antiprism4", lambda: convex_solid(antiprism(4, 0.6))[:2], "D4d"),
        ("antiprism6", lambda: convex_solid(antiprism(6, 0.5))[:2], "D6d"),
        ("antiprism8", lambda: convex_solid(antiprism(8, 0.5))[:2], "D8d"),
        ("prism7", lambda: extruded_polygon(7, 0.5, None)[:2], "D7h"),
        ("prism9", lambda: extruded_polygon(9, 0.5, None)[:2], "D9h")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("words", nargs="*", help="only the rows whose name contains one of these")
    ap.add_argument("--remesh", type=int, default=None, metavar="N", help="also each row ACVD-remeshed to N vertices")
    ap.add_argument("--group", nargs="*", default=[], metavar="KEY=VALUE",
                    help="GroupConfig fields, e.g. max_level_change=1 (the heat-level bound off)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    config = DetectConfig(group=GroupConfig(**{k: json.loads(v) for k, v in (kv.split("=", 1) for kv in args.group)}))
    print("| shape | V | truth | band | distortion 0.55 / 0.83 rad (KLC radii) | in mean edges | bound | "
          "level change 0.55 / 0.83 | verdict |")
    print("|---|---:|---|---|---|---|---:|---|---|")
    for name, build, truth in ROWS:
        if args.words and not any(w in name for w in args.words):
            continue
        versions = [(name, build())]
        if args.remesh:
            from symtorch.remesh import remesh_acvd

            versions.append((f"{name} ACVD", remesh_acvd(*versions[0][1], n_verts=args.remesh, subdivide=2)))
        for label, (v, f) in versions:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = detect_symmetries(v, f, mode="group", config=config)
            ct = res.diagnostics.group.continuous_test
            edge = mean_edge(np.asarray(v) * float(res.spectrum.scale), f) / EPS_KLC
            d = [ct.get(f"angle_{a}", {}).get("distortion") for a in (0.55, 0.83)]
            # none: that angle's block snapped away (stay >= 0.1), or an earlier angle failed and it did not run
            txt = " / ".join("–" if x is None else f"{x:.3f}" for x in d)
            edges = " / ".join("–" if x is None else f"{x / edge:.2f}" for x in d)
            # none: not measured (the angle failed before it, or the bound is off)
            levels = " / ".join("–" if x is None else f"{x:.3f}"
                                for x in (ct.get(f"angle_{a}", {}).get("level_change") for a in (0.55, 0.83)))
            verdict = "continuous" if res.continuous else f"{res.group.name} ({res.group.order})"
            print(f"| {label} | {len(v)} | {truth} | {ct.get('tested_band')} | {txt} | {edges} | "
                  f"{ct.get('max_distortion', float('nan')):.3f} | {levels} | {verdict} |", flush=True)


if __name__ == "__main__":
    main()
