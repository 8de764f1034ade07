"""How isometric is each training dataset's dense reflection (what ``symmetrize`` averages through)?

    python scripts/train_reflection_distortion.py                  # FAUST, TOSCA_Isometric, SCAPE_r
    python scripts/train_reflection_distortion.py --shapes 8

For evenly spaced shapes of each dataset, the reflection R that ``scripts/train_symmetry.py`` uses
(``SymmetryFromCorrespondence`` on the unit-area shape, cached by that script): the mean of
``|d(a, b) - d(R(a), R(b))|`` over 15 seeded sources a and 400 targets b (heat-method geodesics,
unit area; 0 for an exact isometry), the same over the pairs closer than ``--local`` (how isometric
the reflection is at the scale a network's receptive field sees), and the share of vertices that
are some vertex's image.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import train_symmetry as T  # noqa: E402  (the same data, transforms and cache)

from symtorch.data import MeshDataset  # noqa: E402
from symtorch.geodesics import GeodesicSolver  # noqa: E402
from symtorch.tta import reflection_index  # noqa: E402


def distortion(sample: dict, R: np.ndarray, n_sources: int = 15, n_targets: int = 400,
               seed: int = 0, local: float = 0.25) -> tuple[float, float]:
    """Mean ``|d(a, b) - d(R(a), R(b))|`` of the map ``R [V]`` on the sample's unit-area mesh: over
    every sampled pair, and over the pairs with ``d(a, b) < local``."""
    v, f = sample["verts"].double().numpy(), sample["faces"].numpy()
    rng = np.random.default_rng(seed)
    src = rng.choice(len(v), n_sources, replace=False)
    tgt = rng.choice(len(v), n_targets, replace=False)
    g = GeodesicSolver(v, f)
    D, DR = g.distances_from(src).numpy(), g.distances_from(R[src]).numpy()  # [S, V]
    E = np.abs(D[:, tgt] - DR[:, R[tgt]])
    near = D[:, tgt] < local
    return float(E.mean()), float(E[near].mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--datasets", nargs="+", default=["FAUST", "TOSCA_Isometric", "SCAPE_r"])
    ap.add_argument("--shapes", type=int, default=4, help="evenly spaced shapes per dataset")
    ap.add_argument("--scape-r", type=Path, default=Path("/work/data_derived/SCAPE_r"))
    ap.add_argument("--cache", type=Path, default=T.ROOT / ".symtorch_cache" / "train_symmetry")
    ap.add_argument("--local", type=float, default=0.25,
                    help="the local column's pairs: closer than this (unit area; 2 EPS_KLC ~ 0.25)")
    args = ap.parse_args()
    warnings.filterwarnings("ignore")
    print("| dataset | shapes | mean distortion | range | local (pairs closer than --local) | range | "
          "images / vertices |")
    print("|---|---:|---:|---|---:|---|---:|")
    for name in args.datasets:
        ds = MeshDataset.from_layout(T.dataset_root(name, args.scape_r), T.pre_transform(78, 64),
                                     processed_dir=args.cache / f"{name}-ground-truth")
        rows = []
        for i in np.linspace(0, len(ds) - 1, args.shapes).astype(int):
            s = ds[int(i)]
            R = s["sym_p2p"][reflection_index(s)].numpy()
            rows.append((*distortion(s, R, local=args.local), len(np.unique(R)) / len(R)))
        d, loc = [r[0] for r in rows], [r[1] for r in rows]
        print(f"| {name} | {len(rows)} | {np.mean(d):.4f} | {min(d):.4f}-{max(d):.4f} | {np.mean(loc):.4f} | "
              f"{min(loc):.4f}-{max(loc):.4f} | {np.mean([r[2] for r in rows]):.2f} |", flush=True)

if __name__ == "__main__":
    main()
