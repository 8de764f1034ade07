"""How far the refinement can go: ZoomOut variants started from the ground truth, and the ground
truth's own floor, on the dense FAUST / TOSCA_Isometric benchmarks.

    python scripts/study_refinement.py --dataset FAUST --limit 4

For each mesh, the ground-truth symmetric map (BCICP ``.vts`` / ``.sym.vts`` pairs, extended to every
vertex by its nearest paired vertex) gives the true matrix ``C_gt``. Printed, as the mean geodesic error
/ sqrt(area) ×1e-3 on 1000 evenly spaced pairs:

- ``oracle K``: ``C_gt`` at size K converted to a vertex map by nearest neighbours (what a perfect
  matrix gives, the floor of spectral nearest neighbours);
- each refinement variant: ``refine.zoomout_symmetry`` started from ``C_gt`` at k0=12 (band-projected),
  with its time.
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings

import numpy as np
import torch
from scipy.spatial import cKDTree

from symtorch import laplacian_spectrum
from symtorch.eval.benchmarks import list_benchmark, load_ground_truth, load_mesh
from symtorch.eval import evenly_spaced, geodesic_errors, normalized_error
from symtorch.geodesics import GeodesicSolver
from symtorch.maps import nearest_neighbors, p2p_to_fmap
from symtorch.procrustes import block_project
from symtorch.refine import zoomout_symmetry
from symtorch.sampling import farthest_point_sampling
from symtorch.spectrum import band_boundary, solved_bands

VARIANTS = {  # name: (k_final, samples (0: all vertices), zoomout_symmetry keywords)
    "k60": (60, 2000, dict(involution=True, block=False)),
    "k60_all": (60, 0, dict(involution=True, block=False)),
    "k60_orth": (60, 2000, dict(involution=False, block=False)),
    "k60_block": (60, 2000, dict(involution=False, block=True)),
    "k60_step1": (60, 2000, dict(involution=True, block=False, step=1)),
    "k100": (100, 2000, dict(involution=True, block=False)),
}


def dense_truth(verts: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """[V] the true symmetric map: paired vertices from the pairs, the others from their nearest one."""
    g = -np.ones(len(verts), dtype=np.int64)
    g[pairs[:, 0]] = pairs[:, 1]
    known, unknown = np.flatnonzero(g >= 0), np.flatnonzero(g < 0)
    if len(unknown):
        g[unknown] = g[known[cKDTree(verts[known]).query(verts[unknown])[1]]]
    return g


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="FAUST", choices=["FAUST", "TOSCA_Isometric"])
    ap.add_argument("--limit", type=int, default=4)
    ap.add_argument("--oracle-k", type=int, nargs="+", default=[30, 60, 100, 150])
    args = ap.parse_args(argv)
    warnings.filterwarnings("ignore")
    rows: dict[str, list[tuple[float, float]]] = {}
    for name, path in list_benchmark(args.dataset)[: args.limit]:
        v, f = load_mesh(path)
        pairs = load_ground_truth(args.dataset, name).pairs
        spec = laplacian_spectrum(v, f, k=max(args.oracle_k) + 10)
        E, M = spec.evecs, spec.mass
        bands = solved_bands(spec.evals)
        g = torch.as_tensor(dense_truth(v, pairs))
        solver = GeodesicSolver(v, f)
        scored = evenly_spaced(pairs, 1000)

        def err(p2p: torch.Tensor) -> float:
            return 1e3 * normalized_error(geodesic_errors(solver, p2p.numpy(), scored), solver.area)

        line = [f"{name:>12s}"]
        for K in args.oracle_k:
            C = p2p_to_fmap(g, E[:, :K], M)
            e = err(nearest_neighbors(E[:, :K] @ C, E[:, :K]))
            rows.setdefault(f"oracle K={K}", []).append((e, 0.0))
            line.append(f"oracle{K} {e:5.1f}")
        k0 = band_boundary(bands, 12)
        C0 = block_project(p2p_to_fmap(g, E[:, :k0], M), [b for b in bands if b.stop <= k0])
        S = farthest_point_sampling(torch.as_tensor(v * spec.scale), 2000)
        for key, (kf, ns, kw) in VARIANTS.items():
            kf = band_boundary(bands, kf)
            t0 = time.perf_counter()
            Cf = zoomout_symmetry(C0, E, M, bands, kf, samples=S[:ns] if ns else None, **kw)
            p2p = nearest_neighbors(E[:, :kf] @ Cf, E[:, :kf])
            t = time.perf_counter() - t0
            e = err(p2p)
            rows.setdefault(key, []).append((e, t))
            line.append(f"{key} {e:5.1f} ({t:.1f}s)")
        print(" | ".join(line), flush=True)
    print(f"\n{args.dataset}: mean error x1e-3 (mean seconds)")
    for key, r in rows.items():
        a = np.array(r)
        print(f"{key:>14s} {a[:, 0].mean():6.1f} ({a[:, 1].mean():.2f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
