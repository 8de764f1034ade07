"""Train a small functional-map network with Lightning, without and with symmetry awareness.

    python scripts/train_fmap_example.py                    # SCAPE, both runs (CPU, a few minutes)
    python scripts/train_fmap_example.py --dataset FAUST    # FAUST 5k (symmetries detected per shape)

Data: the shared SCAPE meshes (71 poses of one 12,500-vertex template, so the ground-truth map between
two of them is the identity) or the 10 FAUST shapes remeshed to ~5k vertices (ground truth through
``corres/*.vts``). The shapes (not the pairs) are split into train and held-out test shapes with a
seeded generator; every ordered pair of test shapes is evaluated.

Model: a per-vertex MLP on log HKS/WKS descriptors and vertex positions, with two spectral diffusion
layers, projected on each shape's eigenbasis, and the regularised least-squares functional map of the
two projections (Laplacian-commutativity mask, as in GeomFmaps, Donati et al. 2020). Descriptors
cannot tell left from right, and positions cannot either here: the SCAPE poses face different
directions (their horizontal axes are not aligned), so left/right flips are the expected failure. Two
runs from the same seed:

- ``baseline``: supervised loss ``||C - C_gt||^2``;
- ``symmetry``: ``RandomSymmetry`` augmentation of the train shapes, the symmetry-aware supervised
  loss ``min_g ||C - S_y[g] C_gt||^2`` and the equivariance regulariser ``||C S_x - S_y C||^2``.

Symmetries: SCAPE's left/right reflection is detected once on ``mesh000`` with
``symtorch.detect_symmetries`` and shared by every pose (``SetSymmetries``: one template); FAUST's is
detected on every shape (``DetectSymmetries``). Both are cached.

Evaluation on held-out pairs, at ``--n-points`` template points: the point map comes from the
functional map by nearest neighbours in the spectral embedding; its geodesic error is measured on the
unit-area target shape against the truth and against the symmetric flip of the truth (SCAPE: the
template reflection; FAUST: the ``.sym.vts`` ground truth). A map counts as *flipped* when it is closer
to the flip than to the truth. Printed per run: the mean geodesic error (unit-area shapes), the share
of flipped maps and the mean error up to symmetry (the smaller of the two errors); a reference line
gives the error of the ground-truth functional map converted the same way (the floor of a k-basis).
"""
from __future__ import annotations

import argparse
import logging
import time
import warnings
from pathlib import Path

import torch
from torch import Tensor, nn

from symtorch.data import pad_collate
from symtorch.geodesics import GeodesicSolver
from symtorch.losses import (fmap_loss, p2p_error, symmetric_fmap_loss,
                             symmetry_equivariance_loss)
from symtorch.maps import fmap_to_p2p
from symtorch.paths import shared_path

FOLDERS = {"SCAPE": ("bim_scb_benchmark", "SCAPE", "Meshes"),
           "FAUST": ("bcicp_5k", "FAUST", "vtx_5k")}
ROOT = Path(__file__).resolve().parent.parent


def template_symmetries(root: Path, name: str, cache: Path) -> Tensor:
    """[2, V] identity and reflection of the template mesh ``name``, detected once and cached."""
    path = cache / f"{root.parent.name}_{name}_symmetries.pt"
    if path.exists():
        return torch.load(path, weights_only=True)
    from symtorch.detect import detect_symmetries
    from symtorch.io import read_mesh

    print(f"detecting the symmetries of {name} (once) ...", flush=True)
    mesh = read_mesh(root / f"{name}.off")
    result = detect_symmetries(mesh.verts, mesh.faces)
    if len(result.symmetries) < 2:
        raise SystemExit(f"no reflection found on {name}; cannot build the symmetric run")
    p2ps = result.p2ps[:2]
    cache.mkdir(parents=True, exist_ok=True)
    torch.save(p2ps, path)
    return p2ps


def solve_fmap(A_x: Tensor, A_y: Tensor, evals_x: Tensor, evals_y: Tensor, lam: float) -> Tensor:
    """``C_xy [B, K_y, K_x]`` minimising ``||C A_x - A_y||^2 + lam ||C ∘ Δ||^2`` row by row, with
    ``Δ_ij = (evals_y_i - evals_x_j)^2`` on eigenvalues scaled to [0, 1] (GeomFmaps)."""
    scale = torch.maximum(evals_x.amax(-1), evals_y.amax(-1))[:, None]
    ex, ey = evals_x / scale, evals_y / scale
    delta = (ey[:, :, None] - ex[:, None, :]).square()  # [B, K_y, K_x]
    AAt = A_x @ A_x.mT  # [B, K_x, K_x]
    lhs = AAt[:, None] + lam * torch.diag_embed(delta)  # [B, K_y, K_x, K_x]
    rhs = (A_y @ A_x.mT)[..., None]  # [B, K_y, K_x, 1]
    return torch.linalg.solve(lhs, rhs)[..., 0]


def _build_model():
    import lightning as L

    class FmapNet(L.LightningModule):
        """Descriptors and positions -> MLP with two spectral diffusion layers -> functional map."""

        def __init__(self, width: int = 64, out_dim: int = 64, lam: float = 0.1, lr: float = 1e-3,
                     symmetric: bool = False, w_equiv: float = 1.0, use_xyz: bool = True):
            super().__init__()
            self.save_hyperparameters()
            in_dim = 32 + 3 if use_xyz else 32
            self.inp = nn.Sequential(nn.Linear(in_dim, width), nn.ReLU(), nn.Linear(width, width))
            self.mid = nn.Sequential(nn.ReLU(), nn.Linear(2 * width, width))
            self.out = nn.Sequential(nn.ReLU(), nn.Linear(2 * width, width), nn.ReLU(),
                                     nn.Linear(width, out_dim))
            # learned diffusion times per channel (log scale; eigenvalues of unit-area shapes)
            self.log_t1 = nn.Parameter(torch.linspace(-6, -1, width))
            self.log_t2 = nn.Parameter(torch.linspace(-6, -1, width))

        @staticmethod
        def diffuse(f: Tensor, s: dict, log_t: Tensor) -> Tensor:
            a = s["evecs"].mT @ (s["mass"][..., None] * f)  # [B, K, W]
            return s["evecs"] @ (torch.exp(-s["evals"][..., None] * log_t.exp()) * a)

        def coefs(self, s: dict) -> Tensor:
            """[B, K, D] coefficients of the learned features on one (padded) batch of shapes."""
            s = {k: s[k].float() for k in ("hks", "wks", "verts", "evecs", "mass", "evals")}
            d = torch.cat([s["hks"], s["wks"]], dim=-1).clamp_min(1e-6).log()
            d = (d - d.mean(-2, keepdim=True)) / d.std(-2, keepdim=True).clamp_min(1e-6)
            if self.hparams.use_xyz:
                d = torch.cat([d, 4 * s["verts"]], dim=-1)  # unit-area shapes: |verts| ~ 0.3
            f = self.inp(d)
            f = self.mid(torch.cat([f, self.diffuse(f, s, self.log_t1)], dim=-1))
            g = self.out(torch.cat([f, self.diffuse(f, s, self.log_t2)], dim=-1))
            return s["evecs"].mT @ (s["mass"][..., None] * g)

        def fmap(self, batch: dict) -> Tensor:
            x, y = batch["x"], batch["y"]
            return solve_fmap(self.coefs(x), self.coefs(y), x["evals"].float(), y["evals"].float(),
                              self.hparams.lam)

        def training_step(self, batch: dict, _) -> Tensor:
            C = self.fmap(batch)
            C_gt = batch["fmap_xy"].float()
            if not self.hparams.symmetric:
                loss = fmap_loss(C, C_gt)
            else:
                x, y = batch["x"], batch["y"]
                S_x, S_y = x["sym_fmap"].float(), y["sym_fmap"].float()
                loss = (symmetric_fmap_loss(C, C_gt, S_y, mask=y["sym_mask"])
                        + self.hparams.w_equiv * symmetry_equivariance_loss(
                            C, S_x, S_y, mask_x=x["sym_mask"], mask_y=y["sym_mask"]))
            self.log("loss", loss, prog_bar=True, batch_size=C.shape[0])
            return loss

        def configure_optimizers(self):
            return torch.optim.Adam(self.parameters(), lr=self.hparams.lr)

    return FmapNet


class GroundTruthMaps:
    """Stands in for a model: returns the ground-truth functional maps (the floor of the k-basis)."""

    def eval(self) -> None:
        pass

    def fmap(self, batch: dict) -> Tensor:
        return batch["fmap_xy"]


class Evaluator:
    """Geodesic errors of predicted maps at fixed template points, against the truth and its flip."""

    def __init__(self, n_points: int, seed: int):
        self.n_points, self.seed = n_points, seed
        self._dist: dict[str, tuple[dict, Tensor]] = {}

    def points(self, n_template: int) -> Tensor:
        g = torch.Generator().manual_seed(self.seed)
        return torch.randperm(n_template, generator=g)[: self.n_points]

    @staticmethod
    def flip_of(x: dict) -> Tensor:
        """[N] the vertex of x mirroring each template point."""
        if "corr_sym" in x:
            return x["corr_sym"]
        return x["sym_p2p"][1][x["corr"]]

    def distances(self, x: dict, targets: Tensor):
        """Lookup ``dist(a, b)`` of geodesic distances on x to the vertices in ``targets``."""
        if x["name"] not in self._dist:
            uniq = torch.unique(targets[targets >= 0])
            solver = GeodesicSolver(x["verts"].double(), x["faces"])
            rows = {int(v): i for i, v in enumerate(uniq)}
            self._dist[x["name"]] = (rows, solver.distances_from(uniq))
        rows, D = self._dist[x["name"]]
        return lambda a, b: D[torch.tensor([rows[int(v)] for v in b]), a]

    @torch.no_grad()
    def __call__(self, model, pairs) -> dict:
        model.eval()
        errors, flipped, up_to_sym = [], [], []
        for item in pairs:
            x, y = item["x"], item["y"]
            C = model.fmap(pad_collate([item]))[0].double()
            ks = self.points(x["corr"].shape[0])
            dist = self.distances(x, torch.cat([x["corr"][ks], self.flip_of(x)[ks]]))
            ks = ks[(x["corr"][ks] >= 0) & (y["corr"][ks] >= 0) & (self.flip_of(x)[ks] >= 0)]
            truth, flip = x["corr"][ks], self.flip_of(x)[ks]
            # the point map at the scored vertices of y only: p2p_yx = fmap_to_p2p(C, ...)[corr_y]
            Ky, Kx = C.shape
            pred = fmap_to_p2p(C, x["evecs"][:, :Kx].double(),
                               evecs_src=y["evecs"][y["corr"][ks], :Ky].double())
            e_true, e_flip = float(p2p_error(pred, truth, dist)), float(p2p_error(pred, flip, dist))
            errors.append(e_true)
            flipped.append(e_flip < e_true)
            up_to_sym.append(min(e_true, e_flip))
        n = len(errors)
        return {"n": n, "error": sum(errors) / n, "flipped": sum(flipped) / n,
                "up_to_sym": sum(up_to_sym) / n}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--dataset", choices=sorted(FOLDERS), default="SCAPE")
    ap.add_argument("--k", type=int, default=20, help="eigenpairs per shape (functional map size)")
    ap.add_argument("--n-train", type=int, default=None, help="train shapes (default: all but test)")
    ap.add_argument("--n-test", type=int, default=None, help="held-out shapes (SCAPE 8, FAUST 3)")
    ap.add_argument("--steps", type=int, default=500, help="optimisation steps per run")
    ap.add_argument("--batch-size", type=int, default=4)
    ap.add_argument("--n-points", type=int, default=400, help="template points scored per pair")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--intrinsic", action="store_true",
                    help="descriptors only (no vertex positions): blind to left / right")
    ap.add_argument("--cache", type=Path, default=ROOT / ".symtorch_cache" / "example")
    ap.add_argument("--runs", nargs="+", default=["baseline", "symmetry"],
                    choices=["baseline", "symmetry"])
    args = ap.parse_args()

    import lightning as L

    from symtorch.lightning import SymmetryDataModule

    logging.basicConfig(level=logging.ERROR)
    logging.getLogger("lightning.pytorch").setLevel(logging.ERROR)
    warnings.filterwarnings("ignore")  # mesh reports (duplicated vertices) and lightning hints
    root = shared_path(*FOLDERS[args.dataset])
    if root is None:
        raise SystemExit(f"shared data not found: {'/'.join(FOLDERS[args.dataset])}")
    n_shapes = len(list(root.glob("*.off")))
    n_test = args.n_test or (8 if args.dataset == "SCAPE" else 3)
    n_train = args.n_train or n_shapes - n_test
    if args.dataset == "SCAPE":
        data = dict(ground_truth="template",
                    symmetries=template_symmetries(root, "mesh000", args.cache))
    else:
        data = dict(ground_truth="vts", symmetries="detect")
    t0 = time.perf_counter()
    common = dict(processed_dir=args.cache / args.dataset, k=args.k, batch_size=args.batch_size,
                  split=(n_train, 0, n_test), seed=args.seed, **data)
    SymmetryDataModule(root, **common).prepare_data()
    print(f"{args.dataset}: {n_train} train / {n_test} test shapes, k={args.k}; precompute "
          f"{time.perf_counter() - t0:.0f} s", flush=True)

    FmapNet = _build_model()
    evaluator = Evaluator(args.n_points, args.seed)
    dm = SymmetryDataModule(root, **common)
    dm.setup("test")
    ref = evaluator(GroundTruthMaps(), dm.test_set)
    lines = [f"reference: the ground-truth functional map, converted the same way: mean geodesic "
             f"error {ref['error']:.4f}"]
    print(lines[0], flush=True)
    for run in args.runs:
        symmetric = run == "symmetry"
        L.seed_everything(args.seed, verbose=False)
        dm = SymmetryDataModule(root, augment_symmetry=symmetric, **common)
        dm.setup("fit")
        model = FmapNet(symmetric=symmetric, use_xyz=not args.intrinsic)
        trainer = L.Trainer(max_steps=args.steps, accelerator="cpu", logger=False,
                            enable_checkpointing=False, enable_progress_bar=False,
                            enable_model_summary=False, limit_val_batches=0)
        t0 = time.perf_counter()
        trainer.fit(model, datamodule=dm)
        t_train = time.perf_counter() - t0
        res = evaluator(model, dm.test_set)
        line = (f"{run:8s}: {res['n']} held-out pairs, mean geodesic error {res['error']:.4f} "
                f"(unit area), flipped {100 * res['flipped']:.0f}% of maps, error up to symmetry "
                f"{res['up_to_sym']:.4f} [train {t_train:.0f} s]")
        print(line, flush=True)
        lines.append(line)
    print("\n".join(["", f"== {args.dataset}, {args.steps} steps, seed {args.seed} =="] + lines))


if __name__ == "__main__":
    main()
