"""Eigenvalue band structure of every mesh of a benchmark, and why it differs between meshes.

    python scripts/band_report.py --dataset SCAPE [--first 20] [--k 30] [--rel-gap 0.3] [--window 4]
                                  [--limit N] [--cache-dir DIR] [--no-cache]

For each mesh: the unit-area spectrum (``symtorch.cached_spectrum``: a second run reads the cache),
then ``eigen_bands`` and the band sizes of the bands that start among the first ``--first``
eigenvalues. The report gives the most common structure, how many meshes differ from it, and for each
differing mesh the gaps whose split/merge decision differs from the most common mesh's, with the
ratio gap / local mean spacing that ``eigen_bands`` compares with ``rel_gap`` (a ratio near the
threshold means the decision is fragile). A summary counts ratios close to the threshold on all
meshes.
"""
from __future__ import annotations

import argparse
import logging
import sys
import time
import warnings
from collections import Counter

import numpy as np

from symtorch.eval.benchmarks import DATASETS, list_benchmark, load_mesh
from symtorch.cache import cached_spectrum
from symtorch.spectrum import eigen_bands, laplacian_spectrum


def gap_ratios(evals: np.ndarray, window: int) -> np.ndarray:
    """[K-1] gap_i / local mean spacing, exactly as ``eigen_bands`` computes them."""
    gaps = np.diff(evals)
    K = evals.shape[0]
    local = np.array([gaps[max(0, i - window):min(K - 2, i + window) + 1].mean()
                      for i in range(K - 1)])
    return gaps / np.maximum(local, 1e-300)


def analyse(evals: np.ndarray, first: int, rel_gap: float, window: int) -> dict:
    """Band sizes over the first ``first`` eigenvalues, split decisions and gap ratios."""
    bands = eigen_bands(evals, rel_gap=rel_gap, window=window)
    ratios = gap_ratios(evals, window)
    splits = np.zeros(evals.shape[0] - 1, dtype=bool)
    for b in bands[:-1]:
        splits[b.stop - 1] = True  # a band ends after index b.stop - 1
    sizes = tuple(len(b) for b in bands if b.start < first)
    return {"sizes": sizes, "splits": splits[:first], "ratios": ratios[:first]}


def fmt_sizes(sizes) -> str:
    return "(" + ",".join(map(str, sizes)) + ")"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--dataset", choices=sorted(DATASETS), default="SCAPE")
    ap.add_argument("--first", type=int, default=20, help="eigenvalues whose bands are compared")
    ap.add_argument("--k", type=int, default=30,
                    help="eigenpairs solved (>= first + window + 1 so every local spacing is full)")
    ap.add_argument("--rel-gap", type=float, default=None, help="eigen_bands rel_gap (default: its own)")
    ap.add_argument("--window", type=int, default=None, help="eigen_bands window (default: its own)")
    ap.add_argument("--near", type=float, default=0.5,
                    help="report gaps whose ratio is within this factor of rel_gap (x0.5 .. x2)")
    ap.add_argument("--limit", type=int, default=None, help="only the first N meshes")
    ap.add_argument("--names", nargs="*", default=None, help="only these meshes")
    ap.add_argument("--cache-dir", default=None, help="spectrum cache folder (default: symtorch's)")
    ap.add_argument("--no-cache", action="store_true", help="always solve")
    args = ap.parse_args(argv)

    import inspect
    defaults = inspect.signature(eigen_bands).parameters
    rel_gap = defaults["rel_gap"].default if args.rel_gap is None else args.rel_gap
    window = defaults["window"].default if args.window is None else args.window
    if args.k < args.first + window + 1:
        ap.error(f"--k must be >= first + window + 1 = {args.first + window + 1}")
    logging.basicConfig(level=logging.ERROR)
    warnings.filterwarnings("ignore", category=UserWarning)  # mesh reader reports

    meshes = list_benchmark(args.dataset)
    if args.names:
        meshes = [m for m in meshes if m[0] in set(args.names)]
    meshes = meshes[:args.limit] if args.limit else meshes
    print(f"# {args.dataset}: {len(meshes)} meshes, first {args.first} eigenvalues, k={args.k}, "
          f"rel_gap={rel_gap}, window={window}", file=sys.stderr)

    rows = {}
    t0 = time.perf_counter()
    for i, (name, path) in enumerate(meshes):
        verts, faces = load_mesh(path)
        if args.no_cache:
            spec = laplacian_spectrum(verts, faces, args.k)
        else:
            spec = cached_spectrum(verts, faces, args.k, cache_dir=args.cache_dir)
        rows[name] = analyse(spec.evals.numpy(), args.first, rel_gap, window)
        rows[name]["V"] = verts.shape[0]
        print(f"  [{i + 1}/{len(meshes)}] {name} V={verts.shape[0]} "
              f"{fmt_sizes(rows[name]['sizes'])} ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)

    counts = Counter(r["sizes"] for r in rows.values())
    mode, n_mode = counts.most_common(1)[0]
    ref_name = next(n for n, r in rows.items() if r["sizes"] == mode)
    ref = rows[ref_name]
    differ = [n for n, r in rows.items() if r["sizes"] != mode]
    print(f"\n## {args.dataset}: band structure of the first {args.first} eigenvalues "
          f"(rel_gap={rel_gap}, window={window})")
    print(f"most common: {fmt_sizes(mode)}  ({len(mode)} bands, {n_mode}/{len(rows)} meshes, "
          f"largest band {max(mode)})")
    print(f"differing:   {len(differ)}/{len(rows)} meshes ({100 * len(differ) / len(rows):.1f} %)")
    for sizes, c in counts.most_common():
        if sizes != mode:
            print(f"  {c:3d} x {fmt_sizes(sizes)}")

    if differ:
        print(f"\nwhy (gaps whose decision differs from the most common structure; "
              f"ratio = gap / local spacing, split when > {rel_gap}; reference mesh {ref_name}):")
    for name in differ:
        r = rows[name]
        idx = np.flatnonzero(r["splits"] != ref["splits"])
        parts = []
        for i in idx:
            what = "split" if r["splits"][i] else "merged"
            parts.append(f"gap {i}-{i + 1} {what} at ratio {r['ratios'][i]:.3f} "
                         f"(reference {ref['ratios'][i]:.3f})")
        print(f"  {name}: {fmt_sizes(r['sizes'])}: " + "; ".join(parts))

    # how fragile the threshold is on this data set: ratios within [rel_gap*near, rel_gap/near]
    all_r = np.concatenate([r["ratios"][1:] for r in rows.values()])  # gap 0 (constant mode) aside
    lo, hi = rel_gap * args.near, rel_gap / args.near
    near = (all_r > lo) & (all_r < hi)
    print(f"\ngap ratios over all meshes (gaps 1..{args.first - 1}): {near.sum()} of {all_r.size} "
          f"within [{lo:.3f}, {hi:.3f}] of the threshold; "
          f"smallest ratio above it {all_r[all_r > rel_gap].min():.3f}, "
          f"largest below it {all_r[all_r <= rel_gap].max() if (all_r <= rel_gap).any() else float('nan'):.3f}")
    hist_edges = [0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.6, 1.0, np.inf]
    hist, _ = np.histogram(all_r, bins=hist_edges)
    print("histogram of ratios: " + ", ".join(
        f"[{a:g},{b:g}): {h}" for a, b, h in zip(hist_edges[:-1], hist_edges[1:], hist)))
    print(f"meshes with a ratio within [{lo:.3f}, {hi:.3f}]: "
          f"{sum(bool(((r['ratios'][1:] > lo) & (r['ratios'][1:] < hi)).any()) for r in rows.values())}"
          f"/{len(rows)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
