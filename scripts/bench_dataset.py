"""Time MeshDataset's first pass (read, spectrum, descriptors, cache write) against its cached pass.

    python scripts/bench_dataset.py [--dataset FAUST|SCAPE] [--n 10] [--k 30]

Both passes construct the dataset and load every sample; the cache goes to a fresh temporary folder.
"""
from __future__ import annotations

import argparse
import logging
import tempfile
import time
import warnings

from symtorch.data import Compose, ComputeDescriptors, ComputeSpectrum, MeshDataset, NormalizeArea
from symtorch.paths import shared_path

FOLDERS = {"FAUST": ("bcicp_5k", "FAUST", "vtx_5k"), "SCAPE": ("bim_scb_benchmark", "SCAPE", "Meshes")}


def one_pass(root, names, cache, k):
    t0 = time.perf_counter()
    pre = Compose([NormalizeArea(), ComputeSpectrum(k=k), ComputeDescriptors()])
    ds = MeshDataset(root, pre, processed_dir=cache, names=names)
    n_verts = sum(ds[i]["evecs"].shape[0] for i in range(len(ds)))
    return time.perf_counter() - t0, n_verts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--dataset", choices=sorted(FOLDERS), default="FAUST")
    ap.add_argument("--n", type=int, default=10, help="number of meshes")
    ap.add_argument("--k", type=int, default=30, help="eigenpairs per mesh")
    args = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)  # the reader's reports on duplicated vertices
    warnings.filterwarnings("ignore", category=UserWarning)
    root = shared_path(*FOLDERS[args.dataset])
    if root is None:
        raise SystemExit(f"shared data not found: {'/'.join(FOLDERS[args.dataset])}")
    names = sorted(p.stem for p in root.glob("*.off"))[: args.n]
    with tempfile.TemporaryDirectory() as cache:
        first, n_verts = one_pass(root, names, cache, args.k)
        second, _ = one_pass(root, names, cache, args.k)
    print(f"{args.dataset}: {len(names)} meshes, {n_verts} vertices, k={args.k}")
    print(f"first pass (process + load): {first:.2f} s")
    print(f"cached pass (load):          {second:.3f} s")
    print(f"speed-up: {first / second:.0f}x")


if __name__ == "__main__":
    main()
