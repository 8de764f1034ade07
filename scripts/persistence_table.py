"""How high the invariant points' hills stand, split by whether the point set holds their images.

    OMP_NUM_THREADS=1 python scripts/persistence_table.py                      # the default rows, regular and ACVD 3000
    OMP_NUM_THREADS=1 python scripts/persistence_table.py hex_prism antiprism5 # rows whose name contains a word

Per ``tests/shapes.py`` ``GROUP_SHAPES`` row (bent where the row is; ``--remesh N``: ACVD-remeshed to
about N vertices first, pyacvd needed; default 3000, 0 for the regular mesh only): the invariant
points (``candidates.invariant_points``), each one's persistence (the largest share of
``candidates.persistent_points`` it passes, on a geometric grid 0.002-0.6) and whether every true
image of it lies within 3 mean edges of a point of the set ("orbit-closed"). The group path's first
source tuple takes the points at ``GroupConfig.persistence`` (0.05) or more.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the shape builders
from shapes import GROUP_SHAPES, bend  # noqa: E402

from symtorch import laplacian_spectrum  # noqa: E402
from symtorch.detect.candidates import invariant_points, persistent_points  # noqa: E402
from symtorch.shapes import symmetry_maps  # noqa: E402
from symtorch.units import mean_edge  # noqa: E402

DEFAULT = ["hex_prism", "hept_prism", "pinwheel3", "arms8", "star5_thin", "box", "chiral5", "antiprism5",
           "arms6_bent4", "star6_thin_bent"]
LEVELS = np.geomspace(0.002, 0.6, 18)


def persistence(v, f, mats, v_truth) -> tuple[np.ndarray, np.ndarray]:
    """(persistence [n], orbit-closed [n] bool) of the invariant points of ``(v, f)``."""
    spec = laplacian_spectrum(v, f, k=60)
    vu = v * float(spec.scale)
    pts = invariant_points(spec.evals, spec.evecs, f, vu, n_max=40)
    maps, e = symmetry_maps(v_truth, mats), mean_edge(v, f)
    closed = np.array([all(np.linalg.norm(v[pts] - v[g[p]], axis=1).min() < 3 * e for g in maps) for p in pts])
    pers = np.zeros(len(pts))
    for lv in LEVELS:
        pers[persistent_points(spec.evals, spec.evecs, f, vu, pts, share=float(lv))] = lv
    return pers, closed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("words", nargs="*", help="rows whose name contains one of these (default: a mixed set)")
    ap.add_argument("--remesh", type=int, default=3000, metavar="N", help="also ACVD-remeshed (0: not)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    print("| shape | V | points | orbit-closed: persistence | not orbit-closed: persistence |")
    print("|---|---:|---:|---|---|")
    for name, build, _, _, radius in GROUP_SHAPES:
        if not (any(w in name for w in args.words) if args.words else name in DEFAULT):
            continue
        v0, f, mats = build()
        versions = [(name, v0, f)]
        if args.remesh:
            from symtorch.remesh import remesh_acvd

            versions.append((f"{name} ACVD", *remesh_acvd(v0, f, n_verts=args.remesh, subdivide=3)))
        for label, vt, ft in versions:
            v = np.asarray(bend(vt, radius) if radius else vt, dtype=np.float64)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                pers, closed = persistence(v, np.asarray(ft), mats, np.asarray(vt))
            fmt = lambda x: ", ".join(f"{y:.3f}" for y in np.sort(x)) or "–"  # noqa: E731
            print(f"| {label} | {len(v)} | {len(pers)} | {fmt(pers[closed])} | {fmt(pers[~closed])} |", flush=True)


if __name__ == "__main__":
    main()
