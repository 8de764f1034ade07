"""The markdown table of ``scripts/train_symmetry.py --json FILE`` rows (BENCHMARKS.md's layout).

    python scripts/train_symmetry_table.py results.jsonl
    python scripts/train_symmetry_table.py --by-seed results.jsonl   # per seed, and the mean over seeds

One line per dataset, regime and run: the plain error and flipped share, then the error after each
post-process, and the ratio of the symmetry pipeline (``symmetrize+tta``: the network averaged
over each shape's reflection, with mirror test-time averaging) to the baseline, with its flipped
share. Later rows of the same setting replace earlier ones.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from train_symmetry import POSTS, RUNS as TRAINED  # the script beside this one

RUNS = TRAINED[:2] + ("augment-pair",) + TRAINED[2:]  # augment-pair: train_symmetry --mirror pair
PIPELINE = "symmetrize+tta"


def by_seed(rows: dict, pipeline: str) -> None:
    """One line per dataset, regime and seed, then per column the mean over the seeds that have it
    and the baseline (``+resolve``: the baseline's maps after ``resolve_symmetry_p2p``, the
    post-process any user can bolt on): error (its ratio to the baseline's mean over the same seeds,
    mean flipped share). The ``+zo`` columns (after ZoomOut) are compared with ``baseline+zo``: a
    refinement any network's maps get is not counted as the symmetry's gain."""
    cols = ("baseline", "baseline+resolve", "baseline+tta", "baseline+stta", "augment", "augment+tta",
            "augment+stta", "symmetrize", "symmetrize+tta", "baseline+zo", "symmetrize+tta+zo")
    cols = tuple(c for c in cols if any(k[2] == c for k in rows))
    print("| setting | seed | " + " | ".join(cols) + " |")
    print("|---|---:|" + "---:|" * len(cols))
    for ds, regime, sym in sorted({(k[0], k[1], k[4]) for k in rows}):
        seeds = sorted(k[3] for k in rows if k[:3] == (ds, regime, "baseline") and k[4] == sym)
        if not seeds:
            continue
        table = {s: [rows.get((ds, regime, c, s, sym)) for c in cols] for s in seeds}
        setting = f"{ds} {regime}" + (" (detected symmetries)" if sym == "detect" else "")
        for s, r in table.items():
            print(f"| {setting} | {s} | " + " | ".join(
                "–" if x is None else f"{x['error']:.4f}"
                + (f" ({100 * x['flipped']:.1f} % flipped)" if x["flipped"] else "") for x in r) + " |")
        cells = []
        for c, col in enumerate(cols):
            have = [r for r in table.values() if r[c] is not None]
            if not have:
                cells.append("–")
                continue
            ref = cols.index("baseline+zo") if col.endswith("+zo") and "baseline+zo" in cols else 0
            have = [r for r in have if r[ref] is not None]
            mean = sum(r[c]["error"] for r in have) / len(have)
            base = sum(r[ref]["error"] for r in have) / len(have)
            flipped = 100 * sum(r[c]["flipped"] for r in have) / len(have)
            cell = f"{mean:.4f} (" + ("" if c == ref else f"{mean / base:.2f}x, ") + f"{flipped:.1f} %)"
            cells.append(f"**{cell}**" if col in (pipeline, pipeline + "+zo") else cell)
        n = {sum(r[c] is not None for r in table.values()) for c in range(len(cols))} - {0}
        label = f"mean of {max(n)}" if len(n) == 1 else f"mean ({min(n)}-{max(n)} seeds)"
        print(f"| {setting} | {label} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("rows", type=Path, nargs="+")
    ap.add_argument("--by-seed", action="store_true",
                    help="the runs and post-processes per seed, and their means")
    ap.add_argument("--steps", type=int, default=300, help="the rows of runs this long (default 300)")
    ap.add_argument("--schedule", choices=["constant", "cosine"], default="cosine",
                    help="the rows of runs with this learning-rate schedule (default cosine)")
    args = ap.parse_args()
    rows = {}
    for path in args.rows:
        for line in path.read_text().splitlines():
            r = json.loads(line)
            if r.get("steps", 300) != args.steps or r.get("schedule", "constant") != args.schedule:
                continue
            rows[(r["dataset"], r["regime"], r["run"], r.get("seed", 0), r.get("symmetries"))] = r
    if args.by_seed:
        by_seed(rows, PIPELINE)
        return
    settings = sorted({k[:2] + k[3:] for k in rows})
    print("| dataset | regime | train shapes | run | error | flipped | +resolve | +parts | +tta | "
          "+tta+parts | +stta | ratio to baseline |")
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for ds, regime, seed, sym in settings:
        base = rows.get((ds, regime, "baseline", seed, sym))
        for run in RUNS:
            got = [rows.get((ds, regime, run + p, seed, sym)) for p in POSTS]
            if got[0] is None:
                continue
            cells = [f"{g['error']:.4f}" if g else "–" for g in got]
            best = rows.get((ds, regime, PIPELINE, seed, sym))
            ratio = (f"{got[0]['error'] / base['error']:.2f}" if base else "–")
            if run == PIPELINE.split("+")[0] and best and base:
                ratio += (f" (pipeline {best['error'] / base['error']:.2f}, "
                          f"{100 * best['flipped']:.1f} % flipped)")
            print(f"| {ds} | {regime} | {got[0]['n_train']} | {run} | {cells[0]} | "
                  f"{100 * got[0]['flipped']:.1f} % | " + " | ".join(cells[1:]) + f" | {ratio} |")


if __name__ == "__main__":
    main()
