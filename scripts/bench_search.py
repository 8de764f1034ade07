"""The dense vertex map's local search: tiled by group against one gather per query.

    python scripts/bench_search.py [--dataset SCAPE --name mesh020] [--repeat 5]

On one benchmark mesh (unit area, its 110-eigenpair spectrum, 2000 farthest-point samples, graph
Voronoi cells, the 64 vertices nearest each sample's image, K = 110 in float32: the reflection
path's final map) this times ``maps.nearest_neighbors_among`` against the per-query form it
replaced (each query gathers its own ``[m, K]`` candidate rows) and reports the share of equal
answers (float32 near-ties may resolve differently), then times a whole ``maps.TwoLevelSearch``
map and the brute-force search over all vertices it stands for.
"""
from __future__ import annotations

import argparse
import statistics
import time
import warnings

import torch
from scipy.spatial import cKDTree

from symtorch.eval.benchmarks import list_benchmark, load_mesh
from symtorch.geodesics import voronoi_cells
from symtorch.maps import TwoLevelSearch, nearest_neighbors, nearest_neighbors_among
from symtorch.sampling import farthest_point_sampling
from symtorch.spectrum import laplacian_spectrum


def per_query(queries, points, candidates, groups, chunk: int = 2048):
    """The former search: every query gathers its group's candidate rows."""
    out = torch.empty(queries.shape[0], dtype=torch.long)
    sq = points.square().sum(-1)
    for s in range(0, queries.shape[0], chunk):
        c = candidates[groups[s:s + chunk]]
        d = sq[c] - 2 * torch.einsum("nd,nmd->nm", queries[s:s + chunk], points[c])
        out[s:s + chunk] = c.gather(1, d.argmin(1, keepdim=True))[:, 0]
    return out


def timed(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", default="SCAPE")
    ap.add_argument("--name", default="mesh020")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    v, f = load_mesh(dict(list_benchmark(args.dataset))[args.name])
    spec = laplacian_spectrum(v, f, k=110)
    vu = torch.as_tensor(v) * spec.scale
    samples = farthest_point_sampling(vu, 2000)
    cells = voronoi_cells(vu, torch.as_tensor(f), samples)
    E = spec.evecs.float()
    g = torch.Generator().manual_seed(0)
    Q = E + 0.01 * torch.randn(E.shape, generator=g)  # a map's embedding: near, not on, the vertices
    _, near = cKDTree(vu.numpy()).query(vu[samples].numpy(), k=64)
    near = torch.as_tensor(near)
    tiled = nearest_neighbors_among(Q, E, near, cells)
    same = float((tiled == per_query(Q, E, near, cells)).double().mean())
    t_tiled = timed(lambda: nearest_neighbors_among(Q, E, near, cells), args.repeat)
    t_query = timed(lambda: per_query(Q, E, near, cells), args.repeat)
    C = torch.eye(110, dtype=spec.evecs.dtype)
    search = TwoLevelSearch(vu, spec.evecs, samples, cells, 64)
    t_two = timed(lambda: search(C), args.repeat)
    t_full = timed(lambda: nearest_neighbors(spec.evecs.float(), E), max(1, args.repeat // 2))
    print(f"{args.dataset}/{args.name}: V={len(v)}, 2000 samples, 64 candidates, K=110, "
          f"{torch.get_num_threads()} threads")
    print(f"nearest_neighbors_among tiled {t_tiled * 1e3:.1f} ms, per query {t_query * 1e3:.1f} ms "
          f"(ratio {t_query / t_tiled:.1f}), equal answers {100 * same:.2f} %")
    print(f"TwoLevelSearch map {t_two * 1e3:.1f} ms, brute force over all vertices {t_full * 1e3:.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
