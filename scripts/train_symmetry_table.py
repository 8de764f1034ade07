"""The markdown table of ``scripts/train_symmetry.py --json FILE`` rows (BENCHMARKS.md's layout).

    python scripts/train_symmetry_table.py results.jsonl

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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("rows", type=Path, nargs="+")
    args = ap.parse_args()
    rows = {}
    for path in args.rows:
        for line in path.read_text().splitlines():
            r = json.loads(line)
            rows[(r["dataset"], r["regime"], r["run"], r.get("seed", 0), r.get("symmetries"))] = r
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
