"""The markdown table of ``scripts/train_symmetry.py --json FILE`` rows (BENCHMARKS.md's layout).

    python scripts/train_symmetry_table.py results.jsonl
    python scripts/train_symmetry_table.py --by-seed results.jsonl   # per seed, and the mean over seeds

One line per dataset, regime and run: the plain error and flipped share, then the error after each
post-process, and the ratio of the symmetry pipeline (``augment+tta``: mirror augmentation,
mirror test-time averaging) to the baseline, with its flipped share. Later
rows of the same setting replace earlier ones.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

POSTS = ("", "+resolve", "+parts", "+tta", "+tta+parts")
RUNS = ("baseline", "augment", "augment-pair", "losses", "full")
PIPELINE = "augment+tta"


def by_seed(rows: dict) -> None:
    """One line per dataset, regime and seed (the seeds that have every column), then the means and
    the ratio of the pipeline's mean to the baseline's."""
    cols = ("baseline", "baseline+tta", "augment", PIPELINE)
    print("| setting | seed | " + " | ".join(cols) + " |")
    print("|---|---:|" + "---:|" * len(cols))
    for ds, regime, sym in sorted({(k[0], k[1], k[4]) for k in rows}):
        seeds = sorted({k[3] for k in rows if (k[0], k[1], k[4]) == (ds, regime, sym)})
        table = {s: [rows.get((ds, regime, c, s, sym)) for c in cols] for s in seeds}
        table = {s: r for s, r in table.items() if all(r)}
        if not table:
            continue
        for s, r in table.items():
            print(f"| {ds} {regime} | {s} | " + " | ".join(
                f"{x['error']:.4f}" + (f" ({100 * x['flipped']:.1f} % flipped)" if x["flipped"] else "")
                for x in r) + " |")
        means = [sum(r[c]["error"] for r in table.values()) / len(table) for c in range(len(cols))]
        print(f"| {ds} {regime} | mean of {len(table)} | " + " | ".join(f"{m:.4f}" for m in means[:-1])
              + f" | **{means[-1]:.4f} ({means[-1] / means[0]:.2f}x)** |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("rows", type=Path, nargs="+")
    ap.add_argument("--by-seed", action="store_true",
                    help="baseline, baseline+tta, augment and the pipeline per seed, and their means")
    args = ap.parse_args()
    rows = {}
    for path in args.rows:
        for line in path.read_text().splitlines():
            r = json.loads(line)
            rows[(r["dataset"], r["regime"], r["run"], r.get("seed", 0), r.get("symmetries"))] = r
    if args.by_seed:
        by_seed(rows)
        return
    settings = sorted({k[:2] + k[3:] for k in rows})
    print("| dataset | regime | train shapes | run | error | flipped | +resolve | +parts | +tta | "
          "+tta+parts | ratio to baseline |")
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for ds, regime, seed, sym in settings:
        base = rows.get((ds, regime, "baseline", seed, sym))
        for run in RUNS:
            got = [rows.get((ds, regime, run + p, seed, sym)) for p in POSTS]
            if got[0] is None:
                continue
            cells = [f"{g['error']:.4f}" if g else "–" for g in got]
            best = rows.get((ds, regime, PIPELINE, seed, sym))
            ratio = (f"{got[0]['error'] / base['error']:.2f}" if base else "–")
            if run == "augment" and best and base:
                ratio += (f" (pipeline {best['error'] / base['error']:.2f}, "
                          f"{100 * best['flipped']:.1f} % flipped)")
            print(f"| {ds} | {regime} | {got[0]['n_train']} | {run} | {cells[0]} | "
                  f"{100 * got[0]['flipped']:.1f} % | " + " | ".join(cells[1:]) + f" | {ratio} |")


if __name__ == "__main__":
    main()
