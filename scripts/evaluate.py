"""Evaluate reflection detection on a whole benchmark (ALGORITHM §6) and print a table.

    python scripts/evaluate.py --dataset SCAPE [--limit N] [--method symtorch|pyfm ...] [--k-refine K] [--out results.csv]
    python scripts/evaluate.py --dataset FAUST --method symtorch pyfm     # per-mesh table, side by side
    python scripts/evaluate.py --dataset SCAPE --point-cloud [--subsample 5000 --seed 0] [--cloud-min-cos none]

Per mesh: name, V, kind of the scored symmetry, correspondence rate (share of ground-truth points
with geodesic error below sqrt(area/(20 pi))), normalised mean error (mean / sqrt(area), ×1e-3),
method wall and CPU time (CPU time is steadier on a shared machine; it sums threads), scoring time. Summary: mean correspondence rate, mesh rate (share of meshes with a
rate above 0.75), mean normalised error ×1e-3, median method time.

Ground truth: SCAPE / TOSCA sparse KLC10 pairs (fixed points scored, mapping to themselves);
FAUST / TOSCA_Isometric dense BCICP pairs and TOSCA_dense (the 15 TOSCA meshes with FmapLib's dense
maps; michael and wolf: the involutive entries) (``--max-pairs`` evenly spaced ones, default 1000, to
keep scoring fast: one heat solve per unique true image); Watertight orbits (``symtorch.eval.orbit_errors``;
the two vases have none and are skipped).

For ``--method symtorch`` the scored symmetry is the first reflection of
``symtorch.detect_symmetries(verts, faces).symmetries``, else the first non-identity one, else the
identity. ``--method pyfm`` runs ``baseline_pyfm.pyfm_reflection`` (pyFM + orientation term + ZoomOut).

``--point-cloud``: the detector gets the mesh's vertices alone (``detect_symmetries(verts)``: the
point-cloud Laplacian and heat method); ``--subsample N`` (implies it) a seeded random N of them
(``--seed``). The map is scored on the mesh as always: each mesh vertex goes where the map sends its
nearest sample (Euclidean), so the error includes the sampling's. ``V`` is then the points detected on.
"""
from __future__ import annotations

import argparse
import csv
import logging
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))  # for baseline_pyfm

from symtorch.eval.benchmarks import DATASETS, list_benchmark, load_ground_truth, load_mesh  # noqa: E402
from symtorch.eval import (evenly_spaced, geodesic_errors, klc_rates, mesh_rate, normalized_error,  # noqa: E402
                           orbit_errors)
from symtorch.geodesics import GeodesicSolver  # noqa: E402


def pick_symmetry(result):
    """The symmetry to score: first reflection, else first non-identity, else the identity."""
    syms = list(result.symmetries)
    if not syms:
        return None
    for want in (lambda s: s.kind == "reflection", lambda s: s.kind != "identity", lambda s: True):
        for s in syms:
            if want(s):
                return s
    return None


def run_symtorch(verts: np.ndarray, faces: np.ndarray | None, mode: str = "auto",
                 k_refine: int | None = None, **knobs) -> tuple[np.ndarray, str]:
    import symtorch

    kw = {} if k_refine is None else {"k_refine": k_refine}  # None: the detector's default
    kw.update(knobs)
    result = symtorch.detect_symmetries(torch.as_tensor(verts),
                                        None if faces is None else torch.as_tensor(faces), mode=mode, **kw)
    sym = pick_symmetry(result)
    if sym is None:
        return np.arange(len(verts)), "none"
    return np.asarray(torch.as_tensor(sym.p2p).cpu(), dtype=np.int64), str(sym.kind)


def run_pyfm(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, str]:
    from baseline_pyfm import pyfm_reflection

    return pyfm_reflection(verts, faces), "reflection"


def point_subset(n_verts: int, subsample: int | None, seed: int) -> np.ndarray:
    """[N] sorted vertex ids the point cloud keeps: all, or a seeded random ``subsample`` of them."""
    if not subsample or subsample >= n_verts:
        return np.arange(n_verts)
    return np.sort(np.random.default_rng(seed).choice(n_verts, subsample, replace=False))


def lift_to_mesh(p2p_sub: np.ndarray, keep: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """[V] a map of the kept points as a map of every mesh vertex: the image of the nearest kept point."""
    from symtorch.remesh import nearest_vertices

    return keep[p2p_sub[nearest_vertices(verts[keep], verts)]]


def evaluate_mesh(dataset: str, name: str, path: Path, methods: list[str], max_pairs: int,
                  mode: str = "auto", k_refine: int | None = None, point_cloud: bool = False,
                  subsample: int | None = None, seed: int = 0,
                  cloud_knobs: dict | None = None) -> list[dict] | None:
    """One row per method on one mesh (the mesh, its ground truth and the scoring solver are read
    and built once); None where the mesh has no ground truth."""
    try:
        gt = load_ground_truth(dataset, name)
    except FileNotFoundError:
        print(f"{name:>12s}  (no ground truth, skipped)", file=sys.stderr)
        return None
    verts, faces = load_mesh(path)
    keep = point_subset(len(verts), subsample, seed) if point_cloud else np.arange(len(verts))
    solver = None
    rows = []
    for method in methods:
        t0, c0 = time.perf_counter(), time.process_time()
        if point_cloud:
            if method != "symtorch":
                raise SystemExit("--point-cloud needs --method symtorch")
            p2p, kind = run_symtorch(verts[keep], None, mode, k_refine, **(cloud_knobs or {}))
        else:
            p2p, kind = (run_symtorch(verts, faces, mode, k_refine) if method == "symtorch"
                         else run_pyfm(verts, faces))
        t_method, c_method = time.perf_counter() - t0, time.process_time() - c0
        if len(keep) < len(verts):
            p2p = lift_to_mesh(p2p, keep, verts)

        t0 = time.perf_counter()
        if solver is None:
            solver = GeodesicSolver(verts, faces)  # original units: errors and area agree
        if gt.kind == "pairs":
            pairs = gt.pairs
            if max_pairs:
                pairs = evenly_spaced(pairs, max_pairs)
            errors = geodesic_errors(solver, p2p, pairs)
        else:
            errors = orbit_errors(solver, p2p, gt.orbits, identity=(kind in ("identity", "none")))
        area = solver.area
        rows.append(dict(method=method, name=name, V=len(keep), kind=kind, n_gt=len(errors),
                         rate=float(klc_rates(errors, area)), nerr=normalized_error(errors, area),
                         time=t_method, cpu_time=c_method, eval_time=time.perf_counter() - t0))
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Evaluate reflection detection on a benchmark.")
    parser.add_argument("--dataset", required=True, choices=list(DATASETS))
    parser.add_argument("--method", nargs="+", default=["symtorch"], choices=["symtorch", "pyfm"],
                        help="one or more methods; with several, each mesh is run by each and a "
                             "per-mesh table puts them side by side")
    parser.add_argument("--mode", default="auto", choices=["auto", "reflection", "group"],
                        help="detect_symmetries mode (symtorch method)")
    parser.add_argument("--k-refine", type=int, default=None,
                        help="detect_symmetries k_refine, the final basis size (symtorch method; "
                             "default the detector's)")
    parser.add_argument("--limit", type=int, default=None, help="first N meshes only")
    parser.add_argument("--names", nargs="*", default=None, help="only these meshes")
    parser.add_argument("--max-pairs", type=int, default=1000,
                        help="dense ground truth: score this many evenly spaced pairs (0: all)")
    parser.add_argument("--out", type=Path, default=None, help="write per-mesh rows as CSV")
    parser.add_argument("--point-cloud", action="store_true",
                        help="detect on the mesh's vertices alone, as a point cloud (symtorch method)")
    parser.add_argument("--subsample", type=int, default=None, metavar="N",
                        help="detect on a seeded random N of the vertices (implies --point-cloud)")
    parser.add_argument("--seed", type=int, default=0, help="seed of --subsample")
    parser.add_argument("--cloud-min-cos", default=None, metavar="X|none",
                        help="point clouds: DetectConfig.cloud_min_cos (default the detector's; "
                             "'none': robust_laplacian.point_cloud_laplacian and "
                             "potpourri3d.PointCloudHeatSolver as they are)")
    args = parser.parse_args(argv)
    args.point_cloud = args.point_cloud or bool(args.subsample)
    cloud_knobs = {} if args.cloud_min_cos is None else {
        "cloud_min_cos": None if args.cloud_min_cos.lower() == "none" else float(args.cloud_min_cos)}
    logging.basicConfig(level=logging.WARNING)
    warnings.filterwarnings("ignore", category=DeprecationWarning)

    meshes = list_benchmark(args.dataset)
    if args.names:
        meshes = [m for m in meshes if m[0] in set(args.names)]
    if args.limit is not None:
        meshes = meshes[:args.limit]
    cloud = (f", point cloud of {args.subsample} random vertices (seed {args.seed})" if args.subsample
             else ", point cloud of the vertices" if args.point_cloud else "")
    cloud += "".join(f", {k}={v}" for k, v in cloud_knobs.items())
    methods = list(dict.fromkeys(args.method))
    print(f"{args.dataset}: {len(meshes)} meshes, method={','.join(methods)}{cloud}", file=sys.stderr)
    header = f"{'mesh':>12s} {'method':>8s} {'V':>6s} {'kind':>10s} {'n_gt':>5s} {'rate':>6s} " \
             f"{'err e-3':>8s} {'time s':>7s} {'cpu s':>7s} {'eval s':>7s}"
    print(header)
    rows = []
    for name, path in meshes:
        for row in evaluate_mesh(args.dataset, name, path, methods, args.max_pairs, args.mode,
                                 args.k_refine, args.point_cloud, args.subsample, args.seed,
                                 cloud_knobs) or []:
            rows.append(row)
            print(f"{row['name']:>12s} {row['method']:>8s} {row['V']:>6d} {row['kind']:>10s} "
                  f"{row['n_gt']:>5d} {row['rate']:>6.3f} {row['nerr'] * 1e3:>8.1f} {row['time']:>7.2f} "
                  f"{row['cpu_time']:>7.2f} {row['eval_time']:>7.2f}", flush=True)
    if not rows:
        print("no meshes evaluated")
        return 1
    if len(methods) > 1:
        print_side_by_side(rows, methods)
    for method in methods:
        mine = [r for r in rows if r["method"] == method]
        rates = [r["rate"] for r in mine]
        print(f"\n{args.dataset} / {method}: {len(mine)} meshes | "
              f"mean correspondence rate {100 * np.nanmean(rates):.1f} % | "
              f"mesh rate (>75 %) {100 * mesh_rate(rates):.1f} % | "
              f"mean normalised error {1e3 * np.mean([r['nerr'] for r in mine]):.1f} e-3 | "
              f"median time {statistics.median(r['time'] for r in mine):.2f} s")
    if args.out:
        with open(args.out, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


def print_side_by_side(rows: list[dict], methods: list[str]) -> None:
    """Markdown: one line per mesh, each method's KLC10 rate, error (x1e-3) and seconds; a mesh
    whose rate is at most 75 % (a wrong map) is marked in bold."""
    by_mesh: dict[str, dict[str, dict]] = {}
    for r in rows:
        by_mesh.setdefault(r["name"], {})[r["method"]] = r
    print("\n| mesh | " + " | ".join(f"{m} rate | {m} error ×1e-3 | {m} s" for m in methods) + " |")
    print("|---|" + "---:|---:|---:|" * len(methods))
    for name, got in by_mesh.items():
        cells = []
        for m in methods:
            r = got.get(m)
            if r is None:
                cells += ["–"] * 3
                continue
            rate = f"{100 * r['rate']:.1f} %"
            cells += [f"**{rate}**" if r["rate"] <= 0.75 else rate, f"{1e3 * r['nerr']:.1f}",
                      f"{r['time']:.2f}"]
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    sys.exit(main())
