"""Time the spectrum solve against plain scipy, and batched band-by-band Procrustes throughput.

    python scripts/bench_spectrum.py [--k 60 100] [--meshes FAUST:tr_reg_000 SCAPE:mesh000 ...]
                                     [--repeat 1] [--candidates 10000] [--skip-spectrum]
                                     [--skip-procrustes] [--device cpu]

Spectrum: for each mesh (real meshes from the shared data, 5K to 50K vertices), the robust Laplacian
is built once; then ``laplacian_spectrum`` (build + our solve: one factorisation, shift-invert
Lanczos at tol 1e-8, the deflated check for missed repeated eigenvalues, normalisation) and
``generalized_eigsh`` alone (CHOLMOD's Cholesky, and again with SuperLU) are timed against one plain ``scipy.sparse.linalg.eigsh(W, k, M, sigma=-1e-3, which='LM')`` on
the same unit-area matrices (scipy's default tol, machine precision). Best of ``--repeat`` runs.

Procrustes: ``block_procrustes`` on ``[candidates, K, J]`` coefficient tensors with K = 20 in the
band sizes most common on SCAPE and J = 104 constraint columns (4 disk indicators + 100 HKS/WKS
columns, ALGORITHM §3), float32 and float64.
"""
from __future__ import annotations

import argparse
import logging
import sys
import time
import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
import torch

from symtorch.eval.benchmarks import list_benchmark, load_mesh
from symtorch.procrustes import block_procrustes
from symtorch.spectrum import bands_from_sizes, generalized_eigsh, laplacian_matrices, laplacian_spectrum

DEFAULT_MESHES = ["FAUST:tr_reg_000", "SCAPE:mesh000", "TOSCA:horse0", "TOSCA:cat0",
                  "TOSCA:victoria0", "TOSCA:david0"]
# the band structure of the first 20 eigenvalues of SCAPE mesh000 (scripts/band_report.py)
BAND_SIZES = [1, 2, 1, 1, 1, 2, 2, 2, 1, 1, 1, 1, 1, 1, 1, 1]


def best_of(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def bench_spectrum(specs: list[str], ks: list[int], repeat: int) -> None:
    print("| mesh | V | k | build W, M (s) | laplacian_spectrum (s) | our solve (s) | ours, SuperLU (s) "
          "| plain eigsh (s) | solve ratio ours/plain | max abs eval diff |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for spec in specs:
        dataset, name = spec.split(":")
        path = dict(list_benchmark(dataset))[name]
        verts, faces = load_mesh(path)
        t_build, (W, mass) = best_of(lambda: laplacian_matrices(verts, faces), repeat)
        mass = mass / mass.sum()  # unit area, as laplacian_spectrum does
        M = sp.diags(mass).tocsc()
        for k in ks:
            t_full, _ = best_of(lambda: laplacian_spectrum(verts, faces, k), repeat)
            t_ours, (evals, _) = best_of(lambda: generalized_eigsh(W, mass, k), repeat)
            t_lu, (ev_lu, _) = best_of(lambda: generalized_eigsh(W, mass, k, solver="superlu"), repeat)
            assert np.abs(ev_lu - evals).max() <= 1e-6 * evals.max(), "the two factorisations disagree"
            t_plain, (ev_plain, _) = best_of(
                lambda: sla.eigsh(W, k, M, sigma=-1e-3, which="LM"), repeat)
            diff = np.abs(np.sort(np.maximum(ev_plain, 0)) - evals).max()
            print(f"| {dataset}/{name} | {verts.shape[0]} | {k} | {t_build:.2f} | {t_full:.2f} "
                  f"| {t_ours:.2f} | {t_lu:.2f} | {t_plain:.2f} | {t_ours / t_plain:.2f} | {diff:.1e} |",
                  flush=True)


def bench_procrustes(n: int, device: str, repeat: int, J: int = 104) -> None:
    bands = bands_from_sizes(BAND_SIZES)
    K = bands[-1].stop
    g = torch.Generator().manual_seed(0)
    A = torch.randn(n, K, J, generator=g, dtype=torch.float64)
    B = torch.randn(n, K, J, generator=g, dtype=torch.float64)
    print("\n| dtype | device | candidates | K | J | band sizes | time (s) | candidates / s |")
    print("|---|---|---:|---:|---:|---|---:|---:|")
    for dtype in (torch.float32, torch.float64):
        a, b = A.to(device, dtype), B.to(device, dtype)
        block_procrustes(a[:16], b[:16], bands)  # warm-up

        def run():
            out = block_procrustes(a, b, bands)
            if device.startswith("cuda"):
                torch.cuda.synchronize()
            return out

        t, _ = best_of(run, repeat)
        print(f"| {str(dtype).removeprefix('torch.')} | {device} | {n} | {K} | {J} "
              f"| {','.join(map(str, BAND_SIZES))} | {t:.3f} | {n / t:,.0f} |", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--k", type=int, nargs="+", default=[60, 100])
    ap.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES, help="DATASET:name")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--candidates", type=int, default=10000)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--skip-spectrum", action="store_true")
    ap.add_argument("--skip-procrustes", action="store_true")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)
    warnings.filterwarnings("ignore", category=UserWarning)
    print(f"# torch {torch.__version__}, threads {torch.get_num_threads()}", file=sys.stderr)
    if not args.skip_spectrum:
        bench_spectrum(args.meshes, args.k, args.repeat)
    if not args.skip_procrustes:
        bench_procrustes(args.candidates, args.device, args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
