"""How isometric is the benchmark's own symmetry, against the map the detector chose?

    python scripts/ground_truth_distortion.py --dataset SCAPE [--limit N] [--names mesh013,mesh033]

The reflection path selects among candidate maps by geodesic distortion (``verification.isometry_score``:
mean ``|d(g(x), g(y)) - d(x, y)|`` over sample pairs, unit area, in KLC units). That can only pick the
ground truth where the ground truth is the more isometric map. Per mesh this prints, on the ground
truth's own source points (at most ``--max-points``): the distortion of the ground-truth map, the
distortion of the detected map, the detected map's correspondence rate, and ``ambiguous`` where the
detection is wrong (rate <= 0.75) although its map is *more* isometric than the ground truth — a
failure no isometry criterion can repair — or ``no reflection`` where none passed verification.
"""
from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np
import torch

from symtorch import detect_symmetries
from symtorch.eval.benchmarks import list_benchmark, load_ground_truth, load_mesh
from symtorch._checks import face_areas
from symtorch.eval import evenly_spaced, geodesic_errors, klc_rates
from symtorch.geodesics import GeodesicSolver
from symtorch.detect.verification import isometry_score


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", default="SCAPE", choices=["SCAPE", "TOSCA", "FAUST", "TOSCA_Isometric"])
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--names", default=None, help="comma-separated mesh names")
    ap.add_argument("--max-points", type=int, default=48, help="source points the distortion is measured on")
    args = ap.parse_args(argv)
    warnings.filterwarnings("ignore")
    meshes = list_benchmark(args.dataset)
    if args.names:
        keep = set(args.names.split(","))
        meshes = [m for m in meshes if m[0] in keep]
    meshes = meshes[: args.limit]
    print(f"{'mesh':>12s} {'gt_dist':>8s} {'our_dist':>8s} {'rate':>6s}")
    n_wrong = n_ambiguous = 0
    for name, path in meshes:
        verts, faces = load_mesh(path)
        pairs = load_ground_truth(args.dataset, name).pairs
        src, first = np.unique(pairs[:, 0], return_index=True)
        pick = evenly_spaced(np.arange(len(src)), args.max_points)
        src, img = src[pick], pairs[first[pick], 1]
        result = detect_symmetries(torch.as_tensor(verts), torch.as_tensor(faces))
        sym = result.reflection
        p2p = sym.p2p if sym is not None else torch.arange(len(verts))
        # one solver at unit area (isometry_score's unit); the KLC rate is scale-free
        unit = GeodesicSolver(verts / np.sqrt(float(face_areas(verts, faces).sum())), faces)
        rate = float(klc_rates(geodesic_errors(unit, p2p.numpy(), pairs), unit.area))
        gt = torch.arange(len(verts))
        gt[torch.as_tensor(src)] = torch.as_tensor(img)
        samples = torch.as_tensor(src)
        base = unit.pairwise(samples)
        gt_dist = isometry_score(unit, gt, samples, source_dist=base).distortion
        our_dist = isometry_score(unit, p2p, samples, source_dist=base).distortion
        flag = "" if sym is not None else "no reflection"
        if rate <= 0.75:
            n_wrong += 1
            if sym is not None and our_dist < gt_dist:
                n_ambiguous += 1
                flag = "ambiguous"
        print(f"{name:>12s} {gt_dist:8.3f} {our_dist:8.3f} {rate:6.3f} {flag}", flush=True)
    print(f"{args.dataset}: {len(meshes)} meshes, {n_wrong} wrong, {n_ambiguous} of them with a map more "
          f"isometric than the ground truth")
    return 0


if __name__ == "__main__":
    sys.exit(main())
