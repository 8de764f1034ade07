"""Which detected reflections are wrong, and what they cost a trained network: one table per model.

    python scripts/train_reflection_check.py --dataset SCAPE_r --seed 0 [--regime quarter] [--run symmetrize] [--gate 0.45]

Reads what ``scripts/train_symmetry.py`` cached (the shapes with detected and with ground-truth
reflections, the model saved by ``--symmetries detect``). Per shape: how right its detected
reflection is (share of 200 farthest-point samples sent within one KLC radius of the ground truth's
image; *wrong* below 0.75), the detector's confidence, and the network's own check of it,
``symtorch.tta.reflection_residual`` (``||f(x) - f(x')∘R|| / ||f(x)||``). Prints the AUROC of each
for wrong against right, then the held-out pairs' mean error (``+tta``) split by whether a pair has a
shape with a wrong reflection, and with ``--gate`` the error when the held-out shapes whose residual
exceeds it are scored without their reflection. The gate is a diagnostic, chosen by looking at the
residuals: no threshold is fitted here for use elsewhere.
"""
from __future__ import annotations

import argparse
import math
import sys
import types
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))

import train_symmetry as T  # noqa: E402

from symtorch.data.symmetry import mirror_shape, reflection_index  # noqa: E402
from symtorch.eval import CorrespondenceEvaluator  # noqa: E402
from symtorch.geodesics import GeodesicSolver  # noqa: E402
from symtorch.sampling import farthest_point_sampling  # noqa: E402
from symtorch.tta import reflection_residual  # noqa: E402


def reflection_rate(s: dict, truth: dict, n: int = 200) -> float:
    """Share of ``n`` farthest-point samples whose detected image lies within one KLC radius of the
    ground truth's image (unit-area shape)."""
    R, Rg = (x["sym_p2p"][reflection_index(x)].long() for x in (s, truth))
    smp = torch.as_tensor(farthest_point_sampling(s["verts"].double(), n)).long()
    d = GeodesicSolver(s["verts"].double(), s["faces"]).distances_from(Rg[smp])
    return float((d[torch.arange(n), R[smp]] < math.sqrt(1 / (20 * math.pi))).double().mean())


def auroc(wrong: np.ndarray, x: np.ndarray) -> float:
    """P(a wrong map's value > a right one's), ties half."""
    p, q = x[wrong], x[~wrong]
    return float(np.mean([(a > b) + 0.5 * (a == b) for a in p for b in q])) if len(p) and len(q) else math.nan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--dataset", choices=["FAUST", "TOSCA_Isometric", "SCAPE_r"], default="SCAPE_r")
    ap.add_argument("--regime", choices=["full", "quarter"], default="quarter")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--run", default="symmetrize")
    ap.add_argument("--gate", type=float, default=None)
    ap.add_argument("--scape-r", type=Path, default=Path("/work/data_derived/SCAPE_r"))
    ap.add_argument("--cache", type=Path, default=T.ROOT / ".symtorch_cache" / "train_symmetry")
    args = ap.parse_args()
    warnings.filterwarnings("ignore")
    torch.set_num_threads(1)
    root = T.dataset_root(args.dataset, args.scape_r)

    def load(kind: str) -> list[dict]:  # train_symmetry.py's cache, in its dataset order
        ds = T.MeshDataset.from_layout(root, T.pre_transform(78, 64, kind),
                                       processed_dir=args.cache / f"{args.dataset}-{kind}")
        return [ds[i] for i in range(len(ds))]

    det, gt = load("detect"), load("ground-truth")
    if not det or [s["name"] for s in det] != [s["name"] for s in gt]:
        raise SystemExit("error: run train_symmetry.py with --symmetries detect and ground-truth first")
    name = f"{args.dataset}_{args.regime}_wks_{args.run}_detect_s{args.seed}_n300_cos.pt"
    model = T.Matcher("wks", 64, 30, 64, 64, 64, symmetrize=args.run == "symmetrize")
    model.load_state_dict(torch.load(args.cache / "models" / name, weights_only=True))
    model.eval()
    rates, conf, resid = [], [], []
    with torch.no_grad():
        for s, g in zip(det, gt):
            rates.append(reflection_rate(s, g))
            conf.append(float(s["sym_confidence"][reflection_index(s)]) if "sym_confidence" in s else math.nan)
            resid.append(reflection_residual(model._features(s, None), model._features(mirror_shape(s), None), s))
    rates, conf, resid = map(np.asarray, (rates, conf, resid))
    wrong = rates < 0.75
    names = [s["name"] for s in det]
    print(f"{args.dataset}: {wrong.sum()} of {len(det)} detected reflections wrong: "
          + ", ".join(f"{names[i]} (rate {rates[i]:.2f}, confidence {conf[i]:.2f}, residual {resid[i]:.3f})"
                      for i in np.flatnonzero(wrong)))
    print(f"right ones: residual {np.min(resid[~wrong]):.3f}-{np.max(resid[~wrong]):.3f}")
    print(f"AUROC wrong vs right: network residual {auroc(wrong, resid):.3f}, "
          f"detector confidence {auroc(wrong, -conf):.3f} (low confidence = wrong)")
    _, test_idx = T.split_shapes(names, args.dataset, args.seed)
    pairs = T.pairs_of(test_idx, names, args.dataset == "TOSCA_Isometric")
    if len(pairs) > 100:
        pairs = [pairs[int(i * len(pairs) / 100)] for i in range(100)]
    ev, opts = CorrespondenceEvaluator(n_points=500), types.SimpleNamespace(k=30, parts=False)
    split = {True: [], False: []}
    for p in pairs:
        split[bool(wrong[p[0]] or wrong[p[1]])].append(T.evaluate(model, det, [p], opts, ev)["+tta"].mean)
    for bad, errs in split.items():
        if errs:
            print(f"held-out pairs {'with' if bad else 'without'} a wrong reflection: {len(errs)}, "
                  f"mean error {np.mean(errs):.4f}")
    if args.gate is not None:
        off = {i for i in test_idx if resid[i] > args.gate}
        gated = [dict(s, sym_reverses=torch.zeros_like(torch.as_tensor(s["sym_reverses"]))) if i in off else s
                 for i, s in enumerate(det)]
        r = T.evaluate(model, gated, pairs, opts, ev)["+tta"]
        print(f"gate {args.gate}: {len(off)} held-out shapes without reflection "
              f"({', '.join(sorted(names[i] for i in off))}); mean error {r.mean:.4f}, "
              f"flipped {100 * r.flipped_share:.1f} %")


if __name__ == "__main__":
    main()
