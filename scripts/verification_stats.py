"""The statistics behind three thresholds of the detector, on the benchmark meshes.

    python scripts/verification_stats.py [--dataset SCAPE TOSCA FAUST TOSCA_Isometric] [--limit N]

Per dataset (``--limit N``: N evenly spaced meshes), with the default ``detect_symmetries(mode='reflection')``
and its own spectrum:

- ``descriptor_gap`` of the reflections reported (``reflect.descriptor_gap``; a map is rejected above
  ``max_descriptor_gap`` = 0.4);
- the third-best extrema-permutation consistency score (``info['candidate_scores'][2]``); below
  ``detect_symmetries``' ``group_tol`` = 0.06 the automatic mode asks the group path for a second opinion;
- the smallest relative gap between non-zero eigenvalues of the spectrum; the eigensolver's probe for
  missed repeated eigenvalues runs only below 1e-6 (``spectrum._has_repeats``).
"""
from __future__ import annotations

import argparse
import warnings

import numpy as np

from symtorch.eval.benchmarks import list_benchmark, load_mesh
from symtorch.detect import detect_symmetries
from symtorch.eval import evenly_spaced
from symtorch.spectrum import smallest_relative_gap


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", nargs="+", default=["SCAPE", "TOSCA", "FAUST", "TOSCA_Isometric"])
    ap.add_argument("--limit", type=int, default=None, help="N evenly spaced meshes per dataset")
    ap.add_argument("--group-tol", type=float, default=0.06)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    print("| dataset | meshes | reflections | descriptor_gap min-max | 3rd score < group_tol | "
          "3rd score min | smallest eigen gap (relative) |")
    print("|---|---:|---:|---|---:|---:|---:|")
    for ds in args.dataset:
        meshes = list_benchmark(ds)
        if args.limit:
            meshes = [meshes[i] for i in evenly_spaced(np.arange(len(meshes)), args.limit)]
        gaps, thirds, eig = [], [], []
        for name, path in meshes:
            verts, faces = load_mesh(path)
            res = detect_symmetries(verts, faces, mode="reflection")
            if res.reflection is not None:  # the checks of the map reported (the guided one if it ran)
                d = res.diagnostics.reflection
                gaps.append((d.guided or d.checks).descriptor_gap)
            scores = res.diagnostics.reflection.candidate_scores
            thirds.append(scores[2] if len(scores) > 2 else np.inf)
            eig.append(smallest_relative_gap(res.spectrum.evals.numpy()))
        thirds = np.asarray(thirds)
        print(f"| {ds} | {len(meshes)} | {len(gaps)} | {min(gaps):.2f}-{max(gaps):.2f} | "
              f"{int((thirds < args.group_tol).sum())} | {thirds.min():.3f} | {min(eig):.1e} |", flush=True)


if __name__ == "__main__":
    main()
