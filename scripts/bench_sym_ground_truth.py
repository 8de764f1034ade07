"""Symmetry ground truth for training on the BCICP 5k meshes: how accurate each source is.

Two measurements, on unit-area shapes, errors as geodesic distance (heat method) at the template
points of ``.vts`` / ``.sym.vts`` (x1e-3 in the table):

1. Dense reflection maps built from the ``.sym.vts`` pairs (``SymmetryFromCorrespondence``): the
   pairs of a random 20 % of the template points are held out, the map is built from the rest, and
   its error is taken at the held-out points whose vertex no kept pair covers (the vertices the map
   had to fill in). ``nearest``: image of the nearest paired vertex along the surface; ``spectral@K``:
   least-squares functional map from the pairs in a K-function basis, then spectral nearest neighbour;
   ``local@K``: ``nearest``, then the spectral best match within the one-ring of that image.
2. Augmented ground truth: ``apply_symmetry(mode="mirror")`` with the detected reflection
   (``DetectSymmetries``) and with the map from all pairs; error of the augmented ``corr`` against
   the true mirror correspondence (``corr_sym``), next to the map's own KLC error at the pairs, and
   the faces the old augmentation (vertices moved by the map, faces kept) would tear.

    python scripts/bench_sym_ground_truth.py                    # FAUST 10 + TOSCA 8 (one per class)
    python scripts/bench_sym_ground_truth.py --names FAUST:tr_reg_000 TOSCA_Isometric:cat0
"""
from __future__ import annotations

import argparse
import statistics
import time

import torch

from symtorch.data import (Compose, ComputeSpectrum, DetectSymmetries, NormalizeArea,
                           SymmetryFromCorrespondence, apply_symmetry, dense_map_from_pairs,
                           read_sample)
from symtorch.eval.metrics import geodesic_errors
from symtorch.geodesics import GeodesicSolver
from symtorch.paths import shared_path

DEFAULT = ([f"FAUST:tr_reg_{i:03d}" for i in range(0, 100, 11)]
           + [f"TOSCA_Isometric:{c}0" for c in ("cat", "centaur", "david", "dog", "horse",
                                                  "michael", "victoria", "wolf")])
K_SPECTRAL = (30, 60, 120)
K_LOCAL = (30, 60)


def load(spec: str, k: int) -> dict:
    dataset, name = spec.split(":")
    path = shared_path("bcicp_5k", dataset, "vtx_5k", f"{name}.off")
    if path is None:
        raise SystemExit(f"shared data bcicp_5k/{dataset}/vtx_5k/{name}.off not found")
    s = read_sample(path, torch.float64, ground_truth="vts")
    return Compose([NormalizeArea(), ComputeSpectrum(k=k)])(s)


def held_out_errors(s: dict, solver: GeodesicSolver, seed: int = 0) -> dict[str, float]:
    corr, corr_sym = s["corr"], s["corr_sym"]
    V = s["verts"].shape[0]
    perm = torch.randperm(corr.numel(), generator=torch.Generator().manual_seed(seed))
    test, keep = perm[: corr.numel() // 5], perm[corr.numel() // 5:]
    src, dst = torch.cat([corr[keep], corr_sym[keep]]), torch.cat([corr_sym[keep], corr[keep]])
    covered = torch.zeros(V, dtype=torch.bool)
    covered[src] = True
    test = test[~covered[corr[test]]]
    D = solver.distances_from(corr_sym[test])
    rows = torch.arange(test.numel())
    out = {}
    p = dense_map_from_pairs(src, dst, s["verts"], s["faces"], method="nearest")
    out["nearest"] = float(D[rows, p[corr[test]]].mean())
    for k in K_SPECTRAL:
        p = dense_map_from_pairs(src, dst, s["verts"], s["faces"], method="spectral",
                                 evecs=s["evecs"][:, :k])
        out[f"spectral@{k}"] = float(D[rows, p[corr[test]]].mean())
    for k in K_LOCAL:
        p = dense_map_from_pairs(src, dst, s["verts"], s["faces"], method="local",
                                 evecs=s["evecs"][:, :k])
        out[f"local@{k}"] = float(D[rows, p[corr[test]]].mean())
    out["n_test"] = test.numel()
    out["covered"] = float(covered.double().mean())
    return out


def augmented_errors(s: dict, solver: GeodesicSolver, sym: dict) -> tuple[float, float, int]:
    g = sym["sym_p2p"][1]
    pairs = torch.stack([s["corr"], s["corr_sym"]], 1)
    map_err = float(geodesic_errors(solver, g, pairs).mean())
    out = apply_symmetry(sym, 1, mode="mirror")
    D = solver.distances_from(s["corr_sym"])
    aug_err = float(D[torch.arange(s["corr"].numel()), out["corr"]].mean())
    torn = int((g[s["faces"]] == g[s["faces"]].roll(1, -1)).any(-1).sum())
    return aug_err, map_err, torn


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--names", nargs="+", default=DEFAULT, help="dataset:name of bcicp_5k meshes")
    args = parser.parse_args()
    rows = []
    cols = ["nearest"] + [f"local@{k}" for k in K_LOCAL] + [f"spectral@{k}" for k in K_SPECTRAL]
    print(f"{'mesh':28s} {'cov':>5s} " + " ".join(f"{c.replace('spectral', 'sp'):>8s}" for c in cols)
          + f" | {'aug(det)':>8s} {'map(det)':>8s} {'torn':>5s} {'aug(vts)':>8s} {'map(vts)':>8s}")
    for spec in args.names:
        t0 = time.perf_counter()
        s = load(spec, max(K_SPECTRAL) + 10)
        solver = GeodesicSolver(s["verts"], s["faces"])
        h = held_out_errors(s, solver)
        # the detector with its own spectrum (its default basis sizes); the pairs' map (default
        # method) in a training-size basis of 30
        geometry = {k: v for k, v in s.items() if k not in ("mass", "evals", "evecs", "bands")}
        det = augmented_errors(s, solver, DetectSymmetries()(geometry))
        vts = augmented_errors(s, solver, SymmetryFromCorrespondence()(ComputeSpectrum(30)(geometry)))
        rows.append((spec, h, det, vts))
        print(f"{spec:28s} {h['covered']:5.2f} " + " ".join(f"{1e3 * h[c]:8.1f}" for c in cols)
              + f" | {1e3 * det[0]:8.1f} {1e3 * det[1]:8.1f} {det[2]:5d} {1e3 * vts[0]:8.1f} "
              f"{1e3 * vts[1]:8.1f}   ({time.perf_counter() - t0:.1f} s)", flush=True)
    for prefix in ("FAUST", "TOSCA_Isometric"):
        sel = [r for r in rows if r[0].startswith(prefix + ":")]
        if not sel:
            continue
        mean = lambda xs: statistics.fmean(xs)  # noqa: E731
        print(f"{'mean ' + prefix:28s} {mean([r[1]['covered'] for r in sel]):5.2f} "
              + " ".join(f"{1e3 * mean([r[1][c] for r in sel]):8.1f}" for c in cols)
              + f" | {1e3 * mean([r[2][0] for r in sel]):8.1f} {1e3 * mean([r[2][1] for r in sel]):8.1f} "
              f"{mean([r[2][2] for r in sel]):5.0f} {1e3 * mean([r[3][0] for r in sel]):8.1f} "
              f"{1e3 * mean([r[3][1] for r in sel]):8.1f}")


if __name__ == "__main__":
    main()
