"""Does the detector's confidence separate right reflections from wrong ones? A table per dataset.

    python scripts/confidence_stats.py [--dataset SCAPE TOSCA FAUST TOSCA_Isometric] [--cache DIR] [--recompute]

Per mesh the default ``detect_symmetries(verts, faces)`` runs once and its scored symmetry
(``scripts/evaluate.py``'s ``pick_symmetry``: the first reflection, else the first non-identity one)
is scored against the ground truth as ``scripts/evaluate.py`` scores it (KLC10 correspondence rate;
dense ground truth: 1000 evenly spaced pairs). The **label**: a map is *right* when its rate is at
least ``--right`` (0.9), else *wrong*. A mesh on which only the identity is reported has no
confidence to judge and is counted apart (``none``).

Per dataset the table gives the AUROC of the confidence (``symtorch.detect.confidence.
reflection_confidence`` of the cached diagnostics, what ``Symmetry.confidence`` holds) for right
against wrong maps (the probability that a random right map has a higher confidence than a random
wrong one, ties count half), how many wrong maps are at or above the threshold
(``DetectConfig.min_confidence``: certain although wrong) and how many right ones below it
(uncertain although right), and the median seconds of the whole detection and of its
``second_opinion`` stage. The threshold and the rule were chosen on SCAPE and TOSCA (``symtorch.detect.confidence``);
FAUST and TOSCA_Isometric are held out. ``--signals`` also prints the AUROC of each signal the rule
could use, alone (``confidence_signals``), on every dataset.

Each mesh's measurements (rate, time, the reflection path's diagnostics, the confidence) are kept
in ``--cache`` (default ``/tmp/symtorch_confidence``), one JSON file per dataset, keyed by the
detector's config; a later run reads them back instead of detecting again (``--recompute``: detect).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import statistics
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))  # for evaluate.pick_symmetry

from evaluate import pick_symmetry  # noqa: E402

from symtorch.detect import DetectConfig, detect_symmetries  # noqa: E402
from symtorch.detect.confidence import confidence_signals, reflection_confidence  # noqa: E402
from symtorch.detect.result import Checks, ReflectionDiagnostics, Trial  # noqa: E402
from symtorch.eval import evenly_spaced, geodesic_errors, klc_rates  # noqa: E402
from symtorch.eval.benchmarks import list_benchmark, load_ground_truth, load_mesh  # noqa: E402
from symtorch.geodesics import GeodesicSolver  # noqa: E402

FIT = ("SCAPE", "TOSCA")          # the rule and threshold were chosen on these
HELD_OUT = ("FAUST", "TOSCA_Isometric")


def measure_mesh(dataset: str, name: str, path: Path, max_pairs: int = 1000) -> dict:
    """One mesh: detect, score the picked symmetry, keep what the confidence is computed from."""
    verts, faces = load_mesh(path)
    t0 = time.perf_counter()
    result = detect_symmetries(torch.as_tensor(verts), torch.as_tensor(faces))
    seconds = time.perf_counter() - t0
    sym = pick_symmetry(result)
    p2p = np.asarray(sym.p2p.cpu(), dtype=np.int64)
    gt = load_ground_truth(dataset, name)
    pairs = evenly_spaced(gt.pairs, max_pairs) if max_pairs else gt.pairs
    solver = GeodesicSolver(verts, faces)
    rate = float(klc_rates(geodesic_errors(solver, p2p, pairs), solver.area))
    refl = result.diagnostics.reflection if result.diagnostics is not None else None
    return {"name": name, "V": len(verts), "kind": sym.kind, "rate": rate, "time": seconds,
            "timings": dict(result.timings),
            "path": result.diagnostics.path if result.diagnostics is not None else "",
            "confidence": float(getattr(sym, "confidence", float("nan"))),
            "reflection": None if refl is None else diagnostics_to_json(refl)}


def diagnostics_to_json(d: ReflectionDiagnostics) -> dict:
    """The reflection path's record in full (``to_dict`` drops the fields a user need not see)."""
    return {"candidate_scores": list(d.candidate_scores), "trials": [list(t) for t in d.trials],
            "chosen": None if d.chosen is None else list(d.chosen),
            "checks": None if d.checks is None else list(d.checks),
            "guided_trials": [list(t) for t in d.guided_trials],
            "guided_chosen": None if d.guided_chosen is None else list(d.guided_chosen),
            "guided": None if d.guided is None else list(d.guided),
            "n_extrema": d.n_extrema, "n_seeds": d.n_seeds, "n_candidates": d.n_candidates,
            "k0": list(d.k0), "k_refine": d.k_refine,
            "second_chosen": None if d.second_chosen is None else list(d.second_chosen),
            "agreement": None if d.agreement is None else list(d.agreement)}


def diagnostics_from_json(d: dict) -> ReflectionDiagnostics:
    """Inverse of :func:`diagnostics_to_json`."""
    return ReflectionDiagnostics(
        n_extrema=d["n_extrema"], n_seeds=d["n_seeds"], n_candidates=d["n_candidates"], k0=d["k0"],
        k_refine=d["k_refine"], candidate_scores=d["candidate_scores"],
        trials=[Trial(*t) for t in d["trials"]],
        chosen=None if d["chosen"] is None else tuple(d["chosen"]),
        checks=None if d["checks"] is None else Checks(*d["checks"]),
        guided_trials=[Trial(*t) for t in d["guided_trials"]],
        guided_chosen=None if d["guided_chosen"] is None else tuple(d["guided_chosen"]),
        guided=None if d["guided"] is None else Checks(*d["guided"]),
        second_chosen=None if d.get("second_chosen") is None else tuple(d["second_chosen"]),
        agreement=None if d.get("agreement") is None else tuple(d["agreement"]))


def auroc(pos: np.ndarray, neg: np.ndarray) -> float:
    """P(a random positive scores above a random negative), ties half, over the values that are not
    NaN (a signal some maps do not have); NaN without both classes."""
    pos, neg = pos[~np.isnan(pos)], neg[~np.isnan(neg)]
    if len(pos) == 0 or len(neg) == 0:
        return float("nan")
    diff = pos[:, None] - neg[None, :]
    return float((diff > 0).mean() + 0.5 * (diff == 0).mean())


def cache_key(cfg: DetectConfig) -> str:
    """The detector's knobs, except the threshold, which changes no measurement."""
    return hashlib.sha1(repr(replace(cfg, min_confidence=0.0)).encode()).hexdigest()[:10]


def collect(dataset: str, cache_dir: Path, recompute: bool) -> list[dict]:
    """Every mesh's measurements, from the cache where present, else measured (and cached)."""
    cache_dir.mkdir(parents=True, exist_ok=True)
    path = cache_dir / f"{dataset}_{cache_key(DetectConfig())}.json"
    rows = {} if recompute or not path.exists() else json.loads(path.read_text())
    for name, mesh_path in list_benchmark(dataset):
        if name in rows:
            continue
        try:
            load_ground_truth(dataset, name)
        except FileNotFoundError:
            continue
        rows[name] = measure_mesh(dataset, name, mesh_path)
        r = rows[name]
        print(f"{dataset:>15s} {name:>12s} rate {r['rate']:.3f} conf {r['confidence']:.3f} "
              f"{r['time']:.2f} s", file=sys.stderr, flush=True)
        path.write_text(json.dumps(rows))
    return list(rows.values())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", nargs="+", default=list(FIT + HELD_OUT))
    ap.add_argument("--cache", type=Path, default=Path("/tmp/symtorch_confidence"))
    ap.add_argument("--recompute", action="store_true", help="detect again, ignoring the cache")
    ap.add_argument("--right", type=float, default=0.9, help="a map is right at this rate or above")
    ap.add_argument("--signals", action="store_true", help="also the AUROC of each signal alone")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    cfg = DetectConfig()
    thr = cfg.min_confidence
    print(f"threshold (DetectConfig.min_confidence) = {thr}; right: KLC10 rate >= {args.right}")
    print("| dataset | role | meshes | right | wrong | none | AUROC | wrong >= threshold | "
          "right < threshold | median s | second opinion s |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    per_signal = {}
    for ds in args.dataset:
        rows = collect(ds, args.cache, args.recompute)
        refl = [r for r in rows if r["kind"] == "reflection" and r["reflection"] is not None]
        conf = np.array([reflection_confidence(diagnostics_from_json(r["reflection"]))
                         for r in refl])
        right = np.array([r["rate"] >= args.right for r in refl], dtype=bool)
        n_none = len(rows) - len(refl)
        wrong_above = [r["name"] for r, c, ok in zip(refl, conf, right) if not ok and c >= thr]
        right_below = [r["name"] for r, c, ok in zip(refl, conf, right) if ok and c < thr]
        role = "chosen on" if ds in FIT else "held out"
        print(f"| {ds} | {role} | {len(rows)} | {int(right.sum())} | {int((~right).sum())} | {n_none} | "
              f"{auroc(conf[right], conf[~right]):.3f} | {len(wrong_above)} | "
              f"{len(right_below)} ({100 * len(right_below) / max(right.sum(), 1):.1f} %) | "
              f"{statistics.median(r['time'] for r in rows):.2f} | "
              f"{statistics.median(r['timings'].get('second_opinion', 0.0) for r in rows):.2f} |")
        if wrong_above or right_below:
            print(f"|   | wrong above: {', '.join(wrong_above) or '-'}; right below: "
                  f"{', '.join(right_below) or '-'} |")
        sig = [confidence_signals(diagnostics_from_json(r["reflection"])) for r in refl]
        for key in (sig[0] if sig else {}):
            x = np.array([s[key] for s in sig], dtype=float)
            per_signal.setdefault(key, {})[ds] = auroc(x[right], x[~right])
    if args.signals:
        print("\nAUROC of each signal alone (higher-is-right orientation as computed):")
        print("| signal | " + " | ".join(args.dataset) + " |")
        print("|---|" + "---:|" * len(args.dataset))
        for key, vals in per_signal.items():
            print(f"| {key} | " + " | ".join(f"{vals.get(ds, float('nan')):.3f}" for ds in args.dataset) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
