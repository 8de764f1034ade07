"""How the part-wise flip resolution's scale and threshold were chosen (BENCHMARKS "Training with symmetries").

    python scripts/train_symmetry.py --dataset FAUST --regime full --runs baseline   # saves the model
    python scripts/flip_parts_sweep.py --dataset FAUST --model .symtorch_cache/train_symmetry/models/FAUST_full_wks_baseline_s0_n300.pt

For each held-out pair (at most 30) of a saved ``train_symmetry`` model: where the smoothed
orientation vote (:class:`symtorch.flips.VoteSmoother`) is negative, at the template points the map
flips locally (closer to the symmetric truth, error > 0.1) and at the right ones (error < 0.05); then
the mean error after :func:`~symtorch.flips.resolve_symmetry_parts` over a grid of scales,
thresholds and locality bounds, against the plain map's.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import train_symmetry as ts  # noqa: E402  (the same data, split and model)

from symtorch.data import MeshDataset  # noqa: E402
from symtorch.eval import CorrespondenceEvaluator  # noqa: E402
from symtorch.flips import VoteSmoother, resolve_symmetry_parts  # noqa: E402
from symtorch.maps import fmap_to_p2p  # noqa: E402
from symtorch.orientation import face_orientation_votes  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--dataset", choices=["FAUST", "TOSCA_Isometric", "SCAPE_r"], default="FAUST")
    ap.add_argument("--model", type=Path, required=True, help="a state dict saved by train_symmetry.py")
    ap.add_argument("--scales", type=float, nargs="+", default=[4e-3, 8e-3, 1.6e-2])
    ap.add_argument("--thresholds", type=float, nargs="+", default=[0.0, -0.3, -0.6])
    ap.add_argument("--stretches", type=float, nargs="+", default=[3.0, 8.0])
    ap.add_argument("--scape-r", type=Path, default=Path("/work/data_derived/SCAPE_r"))
    args = ap.parse_args()
    torch.set_num_threads(1)
    ds = MeshDataset.from_layout(ts.dataset_root(args.dataset, args.scape_r), ts.pre_transform(78, 64),
                                 processed_dir=ts.ROOT / ".symtorch_cache" / "train_symmetry"
                                 / f"{args.dataset}-ground-truth")
    data = [ds[i] for i in range(len(ds))]
    names = [s["name"] for s in data]
    _, test = ts.split_shapes(names, args.dataset, 0)
    pairs = ts.pairs_of(test, names, args.dataset == "TOSCA_Isometric")
    pairs = [pairs[int(i * len(pairs) / 30)] for i in range(30)] if len(pairs) > 30 else pairs
    model = ts.Matcher("wks", 64, 30, 64, 64, 64)
    model.load_state_dict(torch.load(args.model, weights_only=True))
    model.eval()
    ev = CorrespondenceEvaluator(n_points=500)
    plain, grid = [], {}
    for i, j in pairs:
        x, y = data[i], data[j]
        with torch.no_grad():
            C = model.fmap(model.coefs(x), model.coefs(y), x, y)
        p2p = fmap_to_p2p(C.double(), x["evecs"][:, :30].double(), y["evecs"][:, :30].double())
        s = ev.score(p2p, x, y)
        plain.append(s.mean)
        smoothers = {t: VoteSmoother(y["verts"].double(), y["faces"], t) for t in args.scales}
        flipped, right = (s.errors_sym < s.errors) & (s.errors > 0.1), s.errors < 0.05
        vote, w = face_orientation_votes(p2p, x["verts"].double(), x["faces"], y["verts"].double(),
                                         y["faces"])
        for t, sm in smoothers.items():
            field = sm(vote, w)[y["corr"][s.points]]
            print(f"{names[i]} -> {names[j]} scale {t:g}: vote < 0 at "
                  f"{100 * float((field[flipped] < 0).float().mean()):.0f} % of {int(flipped.sum())} "
                  f"locally flipped points, {100 * float((field[right] < 0).float().mean()):.0f} % of "
                  f"{int(right.sum())} right ones")
        for ms in args.stretches:
            for t, sm in smoothers.items():
                for thr in args.thresholds:
                    r = resolve_symmetry_parts(p2p, x["verts"].double(), x["faces"], y["verts"].double(),
                                               y["faces"], x["sym_p2p"][1], threshold=thr,
                                               max_stretch=ms, smoother=sm)
                    grid.setdefault((ms, t, thr), []).append(ev.score(r.p2p, x, y).mean)
    base = sum(plain) / len(plain)
    print(f"plain: {base:.4f} over {len(pairs)} pairs")
    for (ms, t, thr), v in grid.items():
        m = sum(v) / len(v)
        print(f"max_stretch {ms:g} scale {t:g} threshold {thr:g}: {m:.4f} ({m / base:.2f}x)")


if __name__ == "__main__":
    main()
