"""Every reversing candidate refined to the end: would the final maps' own checks pick the right one?

    python scripts/final_selection.py --dataset FAUST --out final.jsonl
    python scripts/final_selection.py --dataset SCAPE --names mesh013 mesh070 --out final.jsonl

The reflection path compares its candidates at ``k_select`` on a few samples and refines only the
winner (``select_candidate``, then ``refine_and_verify``). This development tool runs the final
refinement on *every* candidate whose map reverses the orientation at the selection (finite
distortion) and writes one JSON row per (mesh, candidate, coarse start): the selection's vote and
distortion, the final checks (score, distortion, worst distortion, orientation vote, descriptor gap,
involution error, accepted), the ground truth's KLC10 rate and normalised error of the final map,
and whether the detector's own selection picked it. The rows are what a rule over the finalists is
chosen from (fit on some datasets, reported on the others).

    python scripts/final_selection.py --summary final.jsonl      # the rule at several ratios

``--summary`` reads such rows back and prints, per dataset, what the detector's rule (verified
finalists within ``--ratios`` of the winner's selection distortion, lowest final distortion +
``final_vote_weight`` (1 + vote)) would report: mean KLC10 rate, mesh rate (> 75 %), mean error, and
the extra refinements per mesh, beside the selection's own choice.
"""
from __future__ import annotations

import argparse
import json
import math
import time
import warnings
from pathlib import Path

import numpy as np
import torch

import symtorch.detect.reflection as reflect
from symtorch.detect import ReflectionConfig
from symtorch.eval import evenly_spaced, geodesic_errors, klc_rates, normalized_error
from symtorch.eval.benchmarks import list_benchmark, load_ground_truth, load_mesh
from symtorch.geodesics import GeodesicSolver
from symtorch.spectrum import laplacian_spectrum


def candidate_rows(dataset: str, name: str, path, cfg: ReflectionConfig, k_refine: int = 100):
    """One dict per reversing (candidate, coarse start) of one mesh."""
    v, f = load_mesh(path)
    pairs = evenly_spaced(load_ground_truth(dataset, name).pairs, 1000)
    spec = laplacian_spectrum(v, f, k=k_refine + 10)
    basis = reflect.reflection_basis(spec.evals, 6, cfg.k_select, k_refine, cfg.prune_k)
    vu = torch.as_tensor(v) * spec.scale
    faces = torch.as_tensor(f)
    solver = GeodesicSolver(vu, faces)
    cands = reflect.find_candidates(spec, faces, solver, cfg)
    if not cands.perms:
        return []
    cands = cands._replace(perms=cands.perms[:cfg.n_candidates])
    C0 = reflect.candidate_fmaps(cands, spec, basis)
    samples = reflect.SampleSet(vu, faces, spec, solver, cfg)
    chosen = reflect.select_candidate(C0, cands, samples, basis, cfg, guided=False).chosen
    rows = []
    for c in range(len(cands.perms)):
        for kc in basis.starts:
            Cs, vote, dist = reflect._upsample_and_measure(C0[c, :kc, :kc], samples, basis, cfg, None)
            if not math.isfinite(dist):
                continue
            found = reflect.refine_and_verify(Cs, samples, cands.desc, basis, cfg, lambda stage: None)
            err = geodesic_errors(solver, found.p2p.numpy(), pairs)
            ch = found.checks
            rows.append(dict(dataset=dataset, mesh=name, candidate=c, k0=kc, chosen=(c, kc) == chosen,
                             candidate_score=float(cands.scores[c]), select_vote=vote,
                             select_distortion=dist, score=ch.score, distortion=ch.distortion,
                             worst=ch.worst_distortion, vote=ch.orientation, gap=ch.descriptor_gap,
                             involution=ch.involution_error, accepted=ch.accepted,
                             rate=float(klc_rates(err, solver.area)),
                             error=float(normalized_error(err, solver.area))))
    return rows


def rule_pick(rows: list[dict], ratio: float, vote_weight: float) -> tuple[dict, int]:
    """The row the final stage reports among one mesh's rows, and how many finalists it refined."""
    best = min(r["select_distortion"] for r in rows)
    fin = [r for r in rows if r["select_distortion"] <= ratio * best]
    fin = [r for r in fin if r["accepted"]] or fin
    return min(fin, key=lambda r: reflect.final_cost(r["distortion"], r["vote"], vote_weight)), len(fin)


def summarize(path: Path, ratios: list[float], vote_weight: float) -> None:
    """Per dataset: the selection's choice, then the final rule at each ratio."""
    by_mesh: dict = {}
    for line in path.read_text().splitlines():
        r = json.loads(line)
        by_mesh.setdefault((r["dataset"], r["mesh"]), []).append(r)
    print("| dataset | rule | meshes | KLC10 rate | mesh rate | error x1e-3 | extra refinements / mesh |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for ds in sorted({d for d, _ in by_mesh}):
        meshes = [rows for (d, _), rows in by_mesh.items() if d == ds]
        rules = [("selection", lambda rows: (next((r for r in rows if r["chosen"]),
                                                  min(rows, key=lambda r: r["select_distortion"])), 1))]
        rules += [(f"final, ratio {x}", lambda rows, x=x: rule_pick(rows, x, vote_weight)) for x in ratios]
        for label, pick in rules:
            picks = [pick(rows) for rows in meshes]
            n = len(picks)
            print(f"| {ds} | {label} | {n} | {100 * sum(p['rate'] for p, _ in picks) / n:.1f} % | "
                  f"{100 * sum(p['rate'] > 0.75 for p, _ in picks) / n:.1f} % | "
                  f"{1e3 * sum(p['error'] for p, _ in picks) / n:.1f} | "
                  f"{sum(k - 1 for _, k in picks) / n:.1f} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", default="FAUST", choices=["SCAPE", "TOSCA", "FAUST", "TOSCA_Isometric"])
    ap.add_argument("--names", nargs="*", default=None, help="only these meshes (default all)")
    ap.add_argument("--out", type=Path, help="append JSON rows to this file")
    ap.add_argument("--summary", type=Path, help="summarise the rows of this file instead of detecting")
    ap.add_argument("--ratios", type=float, nargs="+", default=[1.15, 1.3, 1.5])
    args = ap.parse_args(argv)
    if args.summary is not None:
        summarize(args.summary, args.ratios, ReflectionConfig().final_vote_weight)
        return 0
    if args.out is None:
        ap.error("--out is required unless --summary is given")
    warnings.filterwarnings("ignore")
    meshes = list_benchmark(args.dataset)
    if args.names:
        meshes = [(n, p) for n, p in meshes if n in set(args.names)]
    cfg = ReflectionConfig()
    for name, path in meshes:
        t0 = time.perf_counter()
        try:
            rows = candidate_rows(args.dataset, name, path, cfg)
        except Exception as e:  # a batch tool: log the mesh and go on
            print(f"{name}: failed: {type(e).__name__}: {e}", flush=True)
            continue
        with args.out.open("a") as fh:
            for r in rows:
                fh.write(json.dumps(r) + "\n")
        best = max(rows, key=lambda r: r["rate"], default=None)
        pick = next((r for r in rows if r["chosen"]), None)
        print(f"{name}: {len(rows)} finalists, chosen rate {pick and round(pick['rate'], 3)}, "
              f"best {best and round(best['rate'], 3)} ({time.perf_counter() - t0:.1f} s)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
