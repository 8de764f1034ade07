"""Does symmetry make a shape-matching network better?  The field's protocol, five runs per setting.

    python scripts/train_symmetry.py --dataset FAUST                      # all train shapes, 5 runs
    python scripts/train_symmetry.py --dataset TOSCA_Isometric --regime quarter
    python scripts/build_scape_r.py && python scripts/train_symmetry.py --dataset SCAPE_r

Backbone: geomfum's DiffusionNet (4 blocks, spectral diffusion in the first ``--k-eig`` eigenpairs,
gradient features) on WKS (default) or on xyz with a random rotation per shape and step
(``--input xyz``); the differentiable functional-map layer with the resolvent Laplacian mask
(:func:`symtorch.fmap_solve.regularized_fmap`, GeomFmaps / ULRSSM) in the first ``--k`` eigenpairs;
supervised by the ground-truth functional map (GeomFmaps, Donati et al. 2020). One pair per step,
Adam with the learning rate decayed to 0 over the run (``--schedule cosine``, the default; ``constant``
keeps it), the same seed and the same number of steps for every run.

Data (remeshed independently per shape, as the field trains): FAUST and TOSCA_Isometric at 5k
vertices (``../shared/data/bcicp_5k``; TOSCA pairs within a class), SCAPE remeshed to 5k by
``scripts/build_scape_r.py`` (SCAPE_r layout). Shapes, not pairs, are split into train and held-out;
``--regime quarter`` trains on a quarter of the train shapes. The shapes' reflections come from the
datasets' symmetric ground truth (``.sym.vts``, made dense by ``SymmetryFromCorrespondence``), or are
detected by symtorch on every shape (``--symmetries detect``).

Runs:

- ``baseline``: supervised loss ``||C - C_gt||^2``;
- ``augment``: + symmetry augmentation, ``RandomSymmetry(mode="mirror")``: a shape with a detected
  reflection becomes its mirror image half of the time, its ground truth composed with the reflection
  (still an orientation-preserving correspondence), so the network must use orientation;
- ``symmetrize``: the baseline's loss on a network averaged over each shape's reflection group
  (:func:`symtorch.tta.symmetrized_features`: ``(f(x)[v] + f(x')[R(v)]) / 2`` with ``x'`` the
  mirror image), in training and at test time; mirror-equivariant by construction, so no
  augmentation; two feature passes per shape and step;
- ``spectral``: ``symmetrize`` with the average taken in the reduced basis through the
  reflection's matrix, ``(A + S A') / 2`` (:meth:`Matcher.spectral_average`), in training and at
  test time: it reads only the reflection's first K frequencies, not its vertex map;
- ``equivariant``: the baseline's network and loss + ``||A - S A'||^2 / ||A||^2`` per shape
  (:func:`feature_equivariance`): its features' coefficients against those of its mirror image read
  through the reflection's matrix. The symmetry is used in training only: at test time the network
  runs alone, needing no symmetry of the held-out shapes;
- ``losses``: augment + symmetry equivariance ``||C S_x - S_y C||^2`` (hinged at the ground truth's value);
- ``full``: + the orientation term (relative residual of ``C O_x = O_y C``, Ren et al. 2018, WKS
  operators; hinged the same way) in training and ``resolve_symmetry_p2p`` on the predicted maps.

Evaluation (the field's protocol) on held-out pairs: the point map from the functional map by
nearest neighbours in the spectral embedding (also after ZoomOut, ``+zo``, as the field reports it),
geodesic error per template point on the unit-area target, divided by sqrt(area) (= 1): mean error,
share of maps closer to the symmetric ground truth than to the truth (flipped), error up to
symmetry. Every run is also scored after ``resolve_symmetry`` (a post-process any user can bolt on
to any network's maps).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import logging
import math
import sys
import time
import warnings
from pathlib import Path

import torch

from symtorch.backbone import ComputeGradientOperator, DiffusionNetFeatures
from symtorch.data import (Compose, ComputeDescriptors, ComputeOrientationOperators, ComputeSpectrum,
                           DetectSymmetries, MeshDataset, NormalizeArea, RandomSymmetry,
                           SymmetryFromCorrespondence,
                           corr_to_fmap)
from symtorch.data.consensus import template_reflection, with_template_reflection
from symtorch.data.layouts import class_key
from symtorch.data.transforms import _haar_orthogonal
from symtorch.fmap_solve import regularized_fmap
from symtorch.losses import fmap_loss, symmetry_equivariance_loss
from symtorch.eval import CorrespondenceEvaluator, summarize_pairs
from symtorch.maps import fmap_to_p2p
from symtorch.data.symmetry import mirror_shape
from symtorch.flips import VoteSmoother, resolve_symmetry_parts
from symtorch.tta import (mirror_pair, reflection_average, reflection_index, spectral_reflection_average,
                          symmetrized_features)
from symtorch.orientation import orientation_residual, resolve_symmetry_p2p
from symtorch.paths import shared_path
from symtorch.detect.verification import isometry_score
from symtorch.geodesics import GeodesicSolver
from symtorch.sampling import farthest_point_sampling
from symtorch.zoomout import zoomout

ROOT = Path(__file__).resolve().parent.parent
RUNS = ("baseline", "augment", "symmetrize", "spectral", "equivariant", "losses", "full")
log = logging.getLogger("train_symmetry")


# ------------------------------------------------------------------------------------------- data
def dataset_root(name: str, scape_r: Path) -> Path:
    """The dataset's folder, in one of the layouts ``MeshDataset.from_layout`` reads."""
    if name == "SCAPE_r":
        if not (scape_r / "off").is_dir():
            raise SystemExit(f"{scape_r}/off not found: build it with scripts/build_scape_r.py")
        return scape_r
    root = shared_path("bcicp_5k", name)
    if root is None:
        raise SystemExit(f"shared data not found: bcicp_5k/{name}")
    return root


def split_shapes(names: list[str], dataset: str, seed: int) -> tuple[list[int], list[int]]:
    """(train, test) indices of shapes, the field's split where it has one."""
    n = len(names)
    if dataset == "SCAPE_r":  # the field: the first 51 poses train, the last 20 test
        return list(range(n - 20)), list(range(n - 20, n))
    if dataset == "FAUST":  # the field: the first 80 of 100 train; here the last 3 of 10 test
        return list(range(n - 3)), list(range(n - 3, n))
    g = torch.Generator().manual_seed(seed)
    train, test = [], []
    for cls in sorted({class_key(s) for s in names}):
        idx = [i for i, s in enumerate(names) if class_key(s) == cls]
        idx = [idx[j] for j in torch.randperm(len(idx), generator=g).tolist()]
        k = max(1, round(0.25 * len(idx))) if len(idx) > 2 else 1
        test += idx[:k]
        train += idx[k:]
    return sorted(train), sorted(test)


def pairs_of(indices: list[int], names: list[str], within_class: bool) -> list[tuple[int, int]]:
    return [(i, j) for i in indices for j in indices
            if i != j and (not within_class or class_key(names[i]) == class_key(names[j]))]


def pre_transform(k: int, n_wks: int, symmetries: str = "ground-truth", on_uncertain: str = "keep") -> Compose:
    """What is cached per shape: unit area, spectrum, WKS, the symmetries, the WKS orientation
    operators (Ren et al. 2018) and DiffusionNet's gradient operator.

    ``symmetries="ground-truth"`` builds the reflection from the dataset's symmetric ground truth
    (``.sym.vts``, :class:`~symtorch.data.SymmetryFromCorrespondence`); ``"detect"`` runs the detector
    (``on_uncertain="drop"``: a shape whose reflection the detector reports as uncertain gets none).
    """
    sym = (SymmetryFromCorrespondence() if symmetries == "ground-truth"
           else DetectSymmetries(on_uncertain=on_uncertain))
    return Compose([NormalizeArea(), ComputeSpectrum(k=k), ComputeDescriptors(n_hks=0, n_wks=n_wks),
                    sym, ComputeOrientationOperators(), ComputeGradientOperator()])


def reflection_distortions(data: list[dict], path: Path, n_samples: int = 64) -> dict[str, float]:
    """Each shape's reflection distortion (``verification.isometry_score`` on ``n_samples``
    farthest-point samples of the unit-area shape, KLC radii; inf without a reflection), by shape name.

    Kept in ``path`` (JSON) under a key of the reflection's vertex map itself (a digest) and
    ``n_samples``, so that a later call reads it back and a changed reflection is measured again.
    """
    known = json.loads(path.read_text()) if path.exists() else {}
    out, new = {}, False
    for s in data:
        r = reflection_index(s)
        R = None if r is None else s["sym_p2p"][r].long()
        key = (f"{s['name']}:{n_samples}:"
               f"{'none' if R is None else hashlib.sha1(R.numpy().tobytes()).hexdigest()[:16]}")
        if key not in known:
            new = True
            if R is None:
                known[key] = math.inf
            else:
                solver = GeodesicSolver(s["verts"].double(), s["faces"])
                samples = farthest_point_sampling(s["verts"].double(), n_samples)
                known[key] = isometry_score(solver, R, samples).distortion
        out[s["name"]] = known[key]
    if new:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(known))
    return out


def drop_distorted_reflections(data: list[dict], distortions: dict[str, float], limit: float) -> list[dict]:
    """The samples with the reflection of every shape distorted by more than ``limit`` (KLC radii)
    removed (``sym_reverses`` all False): such a shape is neither symmetrized nor mirrored."""
    out = []
    for s in data:
        if distortions[s["name"]] > limit and "sym_reverses" in s:
            s = dict(s, sym_reverses=torch.zeros_like(torch.as_tensor(s["sym_reverses"])))
        out.append(s)
    return out


# ------------------------------------------------------------------------------------------ model
def random_rotation(generator: torch.Generator) -> torch.Tensor:
    """[3, 3] uniformly random rotation (Haar on O(3), the reflections negated)."""
    Q = _haar_orthogonal(3, generator)
    return Q if torch.det(Q) > 0 else -Q


class Matcher(torch.nn.Module):
    """DiffusionNet features -> spectral coefficients -> regularised functional map."""

    def __init__(self, inp: str, n_wks: int, k: int, k_eig: int, width: int, out: int,
                 symmetrize: bool = False, spectral: bool = False):
        super().__init__()
        self.inp, self.k, self.symmetrize, self.spectral = inp, k, symmetrize, spectral
        self.features = DiffusionNetFeatures(n_wks if inp == "wks" else 3, out,
                                             hidden_channels=width, k_eig=k_eig)

    def coefs(self, s: dict, generator: torch.Generator | None = None) -> torch.Tensor:
        """[K, D] the spectral coefficients of the shape's features (with ``spectral``, averaged
        over the reflection group in the reduced basis, :meth:`spectral_average`)."""
        A = self.project(self.point_features(s, generator), s)
        if self.spectral and reflection_index(s) is not None:
            A = self.spectral_average(A, self.project(self.point_features(mirror_shape(s), generator), s), s)
        return A

    def spectral_average(self, A: torch.Tensor, A_m: torch.Tensor, s: dict) -> torch.Tensor:
        """``(A + S A') / 2``: the coefficients of ``(f(x) + f(x')∘R) / 2`` with the reflection
        taken as its matrix ``S`` (``sym_fmap``, pull-back) in the first K eigenfunctions instead
        of its vertex map: the average then depends only on the reflection's low frequencies,
        where a detected matrix is as good as the ground truth's. ``A`` where there is no reflection."""
        return spectral_reflection_average(A, A_m, s)

    def project(self, F: torch.Tensor, s: dict) -> torch.Tensor:
        ev = s["evecs"][:, :self.k].float()
        return ev.mT @ (s["mass"].float()[:, None] * F)  # [K, D]

    def point_features(self, s: dict, generator: torch.Generator | None = None) -> torch.Tensor:
        """[V, D] DiffusionNet's features of the shape; with ``symmetrize``, averaged over the
        shape's reflection group {1, R}: ``(f(x)[v] + f(x')[R(v)]) / 2`` with ``x'`` the mirror
        image, whose vertex R(v) carries v's label. The features are then mirror-equivariant by
        construction (those of ``x'`` are those of ``x`` read through R), as an equivariant network
        would be (group averaging, as in frame averaging)."""
        if self.symmetrize:
            return symmetrized_features(lambda t: self._features(t, generator), s)
        return self._features(s, generator)

    def _features(self, s: dict, generator: torch.Generator | None) -> torch.Tensor:
        if self.inp == "wks":
            x = s["wks"].float()
        else:
            R = random_rotation(generator) if generator is not None else torch.eye(3, dtype=torch.float64)
            x = (s["verts"].double() @ R.mT).float()
        return self.features(s, x)  # [V, D]

    def fmap(self, A_x, A_y, s_x, s_y) -> torch.Tensor:
        return regularized_fmap(A_x, A_y, s_x["evals"][:self.k].float(), s_y["evals"][:self.k].float())


def gt_fmap(x: dict, y: dict, k: int) -> torch.Tensor:
    return corr_to_fmap(x["corr"], y["corr"], x["evecs"][:, :k].float(), y["evecs"][:, :k].float(),
                        y["mass"].float())


def sym_mats(s: dict, k: int) -> torch.Tensor:
    return s["sym_fmap"][:, :k, :k].float()


def orient_ops(s: dict, k: int) -> torch.Tensor:
    return s["orient_op"][:, :k, :k].float()


def feature_equivariance(model: Matcher, s: dict, A: torch.Tensor, g: torch.Generator, k: int) -> torch.Tensor:
    """``||A - S A'||^2 / ||A||^2``: how far the network is from mirror-equivariant on this shape.

    ``A [K, D]`` are the spectral coefficients of its features, ``A'`` those of its mirror image
    ``x'`` and ``S [K, K]`` the reflection's matrix (``sym_fmap``, pull-back: the coefficients of
    ``f'∘R`` are ``S A'``). An equivariant network has ``f(x)[v] = f(x')[R(v)]``: the term is 0. In
    the reduced basis the term is smooth in the reflection: an imprecise detected map costs little.
    0 where the shape has no reflection.
    """
    r = reflection_index(s)
    if r is None:
        return A.new_zeros(())
    A_m = model.coefs(mirror_shape(s), g)
    S = s["sym_fmap"][r][:k, :k].to(A)
    return (A - S @ A_m).square().sum() / A.square().sum().clamp_min(1e-12)


def train(run: str, data: list[dict], pairs: list[tuple[int, int]], args) -> Matcher:
    torch.manual_seed(args.seed)
    g = torch.Generator().manual_seed(args.seed)
    model = Matcher(args.input, args.n_wks, args.k, args.k_eig, args.width, args.out,
                    symmetrize=run == "symmetrize", spectral=run == "spectral")
    opt = torch.optim.Adam(model.parameters(), lr=args.lr)
    # cosine decay to 0 over the run: the model scored is not one noisy Adam step away from another
    sched = (torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=args.steps)
             if args.schedule == "cosine" else None)
    # a symmetrized network sees a mirror image through its own group average: no augmentation
    augment = (RandomSymmetry(mode="mirror", generator=g)
               if run not in ("baseline", "symmetrize", "spectral", "equivariant") else None)
    t0, k = time.perf_counter(), args.k
    for step in range(args.steps):
        i, j = pairs[int(torch.randint(len(pairs), (1,), generator=g))]
        x, y = data[i], data[j]
        if augment is not None and args.mirror == "pair":  # both or neither: no symmetry used
            if bool(torch.rand((), generator=g) < 0.5):
                x, y = mirror_pair(x, y)
        elif augment is not None:
            x, y = augment(x), augment(y)
        A_x, A_y = model.coefs(x, g), model.coefs(y, g)
        C = model.fmap(A_x, A_y, x, y)
        C_gt = gt_fmap(x, y, k)
        loss = fmap_loss(C, C_gt)
        if run == "equivariant":
            loss = loss + args.w_feq * (feature_equivariance(model, x, A_x, g, k)
                                        + feature_equivariance(model, y, A_y, g, k))
        # The symmetry terms are hinged at the ground truth's own value: detected symmetries are
        # approximate (and occasionally wrong), so the true map is not exactly equivariant nor
        # exactly orientation-consistent in a truncated basis; only a map *worse* than the truth
        # is penalised, which needs no weight tuned to the detector's accuracy.
        if run in ("losses", "full"):
            S_x, S_y = sym_mats(x, k), sym_mats(y, k)
            loss = loss + args.w_equiv * torch.relu(
                symmetry_equivariance_loss(C, S_x, S_y, match="best")
                - symmetry_equivariance_loss(C_gt, S_x, S_y, match="best"))
        if run == "full":
            # the relative residual (0 for an orientation-preserving map, 2 for a reversing one)
            O_x, O_y = orient_ops(x, k), orient_ops(y, k)
            loss = loss + args.w_orient * torch.relu(orientation_residual(C, O_x, O_y)
                                                     - orientation_residual(C_gt, O_x, O_y))
        opt.zero_grad()
        loss.backward()
        opt.step()
        if sched is not None:
            sched.step()
        if (step + 1) % max(1, args.steps // 5) == 0:
            log.info(f"{run}: step {step + 1}/{args.steps} loss {float(loss):.4f} "
                     f"[{time.perf_counter() - t0:.0f} s]")
    return model


# ------------------------------------------------------------------------------------- evaluation
#: Post-processes scored for every run: none, the global orientation vote, the part-wise one (with
#: ``--parts``), mirror test-time averaging (the pair and its mirror image), the same followed by the
#: part-wise vote (``--parts``), symmetric feature averaging (each shape's features and its
#: mirror image's read through the shape's reflection, :func:`symtorch.tta.symmetrized_features`),
#: and ZoomOut (:func:`symtorch.zoomout.zoomout`, to ``--zoomout-k`` eigenfunctions) after the plain
#: map and after mirror test-time averaging.
POSTS = ("", "+resolve", "+parts", "+tta", "+tta+parts", "+stta", "+zo", "+tta+zo")


@torch.no_grad()
def evaluate(model: Matcher, data: list[dict], pairs: list[tuple[int, int]], args, evaluator) -> dict:
    """Scores of the model's maps on the held-out pairs, plain and after each post-process."""
    model.eval()
    k = args.k
    ids = {p for pair in pairs for p in pair}
    feats = {i: model.point_features(data[i]) for i in ids}
    feats_m = {i: model.point_features(mirror_shape(data[i])) for i in ids}
    coefs = {i: model.project(feats[i], data[i]) for i in ids}
    mirrored = {i: model.project(feats_m[i], data[i]) for i in ids}
    if model.spectral:  # the shape and its mirror image, each averaged with the other
        coefs, mirrored = ({i: model.spectral_average(coefs[i], mirrored[i], data[i]) for i in ids},
                           {i: model.spectral_average(mirrored[i], coefs[i], data[i]) for i in ids})
    # symmetric averaging, shape by shape, of the features computed above (symmetrized_features)
    symmetrized = {i: model.project(reflection_average(feats[i], feats_m[i], data[i]), data[i])
                   for i in ids}
    scores: dict[str, list] = {post: [] for post in POSTS if (args.parts or "parts" not in post)
                               and (args.zoomout_k > 0 or "zo" not in post)}

    def p2p_of(C, x, y):
        return fmap_to_p2p(C.double(), x["evecs"][:, :k].double(), y["evecs"][:, :k].double())

    smoothers: dict = {}  # one factorised vote smoother per shape y whose vertices are mapped

    def parts(p2p, j, x, y):  # flipped parts sent through the target's reflection
        if j not in smoothers:
            smoothers[j] = VoteSmoother(y["verts"].double(), y["faces"])
        return resolve_symmetry_parts(p2p, x["verts"].double(), x["faces"], y["verts"].double(),
                                      y["faces"], x["sym_p2p"][1], smoother=smoothers[j]).p2p

    for i, j in pairs:
        x, y = data[i], data[j]
        C = model.fmap(coefs[i], coefs[j], x, y)
        p2p = p2p_of(C, x, y)
        # both shapes mirrored keep their vertex-id correspondence: symtorch.tta.mirror_averaged_fmap,
        # written out so that each shape's coefficients are computed once, not once per pair
        C_tta = 0.5 * (C + model.fmap(mirrored[i], mirrored[j], x, y))
        p2p_tta = p2p_of(C_tta, x, y)
        # the global choice: the orientation vote of the mapped triangles over the whole shape
        glob = resolve_symmetry_p2p(p2p, x["verts"].double(), x["faces"], y["verts"].double(),
                                    y["faces"], y["sym_p2p"]).p2p
        p2p_stta = p2p_of(model.fmap(symmetrized[i], symmetrized[j], x, y), x, y)
        maps = {"": p2p, "+resolve": glob, "+tta": p2p_tta, "+stta": p2p_stta}
        if args.zoomout_k > 0:
            for post, C_post in (("+zo", C), ("+tta+zo", C_tta)):
                maps[post] = zoomout(C_post.double(), x["evecs"].double(), y["evecs"].double(),
                                     y["mass"].double(), args.zoomout_k).p2p
        if args.parts:
            maps.update({"+parts": parts(p2p, j, x, y), "+tta+parts": parts(p2p_tta, j, x, y)})
        for post, m in maps.items():
            scores[post].append(evaluator.score(m, x, y))
    model.train()
    return {post: summarize_pairs(v) for post, v in scores.items()}


@torch.no_grad()
def ground_truth_floor(data: list[dict], pairs: list[tuple[int, int]], args, evaluator) -> dict:
    """Scores of the ground truth's own ``--k`` functional map converted like a network's (plain and
    after ZoomOut to ``--zoomout-k``): the floor of the protocol in that basis."""
    k, scores = args.k, {"": [], "+zo": []}
    for i, j in pairs:
        x, y = data[i], data[j]
        C = gt_fmap(x, y, k).double()
        scores[""].append(evaluator.score(fmap_to_p2p(C, x["evecs"][:, :k].double(),
                                                      y["evecs"][:, :k].double()), x, y))
        if args.zoomout_k > 0:
            scores["+zo"].append(evaluator.score(zoomout(C, x["evecs"].double(), y["evecs"].double(),
                                                         y["mass"].double(), args.zoomout_k).p2p, x, y))
    return {post: summarize_pairs(v) for post, v in scores.items() if v}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--dataset", choices=["FAUST", "TOSCA_Isometric", "SCAPE_r"], default="FAUST")
    ap.add_argument("--regime", choices=["full", "quarter"], default="full")
    ap.add_argument("--runs", nargs="*", choices=RUNS, default=list(RUNS),
                    help="the runs (none: with --floor, the floor alone)")
    ap.add_argument("--input", choices=["wks", "xyz"], default="wks")
    ap.add_argument("--symmetries", choices=["ground-truth", "detect", "consensus"], default="ground-truth",
                    help="the shapes' reflections: from the .sym.vts ground truth, detected, or detected "
                         "and, on the training shapes, voted into one through their correspondences "
                         "(symtorch.data.consensus; the held-out shapes keep their detected ones)")
    ap.add_argument("--on-uncertain", choices=["keep", "drop"], default="keep",
                    help="detected symmetries (--symmetries detect, --test-symmetries detect): 'drop' "
                         "gives a shape whose reflection the detector reports as uncertain none")
    ap.add_argument("--test-symmetries", choices=["ground-truth", "detect"], default=None,
                    help="the held-out shapes' reflections, where they differ from --symmetries "
                         "(e.g. trained with detected ones, tested with the ground truth's: what the "
                         "detector's errors cost at test time, apart from in training)")
    ap.add_argument("--mirror", choices=["shape", "pair"], default="shape",
                    help="augment: mirror each shape on its own through its reflection (shape), or "
                         "both shapes of a pair together, which keeps their correspondence and needs "
                         "no symmetry (pair: the control)")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--k", type=int, default=30, help="functional map size")
    ap.add_argument("--k-eig", type=int, default=64, help="eigenpairs for DiffusionNet's diffusion")
    ap.add_argument("--k-spectrum", type=int, default=78, help="eigenpairs cached per shape")
    ap.add_argument("--n-wks", type=int, default=64)
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--out", type=int, default=64, help="feature size")
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--schedule", choices=["constant", "cosine"], default="cosine",
                    help="learning rate: cosine decay to 0 over --steps (default), or constant")
    ap.add_argument("--w-equiv", type=float, default=1.0)
    ap.add_argument("--w-orient", type=float, default=1.0)
    ap.add_argument("--w-feq", type=float, default=1.0,
                    help="weight of the feature equivariance term of the equivariant run")
    ap.add_argument("--max-distortion", type=float, default=None,
                    help="use a shape's reflection only where its distortion (KLC radii, 64 samples) "
                         "is at most this; the others are neither symmetrized nor mirrored")
    ap.add_argument("--parts", action="store_true",
                    help="also score the part-wise flip vote (+parts, +tta+parts; slower)")
    ap.add_argument("--zoomout-k", type=int, default=None,
                    help="also score each map after ZoomOut to this many eigenfunctions (+zo, "
                         "+tta+zo; default: all --k-spectrum cached; 0: not)")
    ap.add_argument("--n-points", type=int, default=500, help="template points scored per pair")
    ap.add_argument("--max-pairs", type=int, default=100, help="held-out pairs scored (evenly spaced)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--scape-r", type=Path, default=Path("/work/data_derived/SCAPE_r"))
    ap.add_argument("--cache", type=Path, default=ROOT / ".symtorch_cache" / "train_symmetry")
    ap.add_argument("--reuse", action="store_true",
                    help="evaluate the models an earlier call saved with the same settings")
    ap.add_argument("--json", type=Path, default=None, help="append the result rows to this file")
    ap.add_argument("--per-pair", type=Path, default=None,
                    help="append each held-out pair's scores (per run and post-process) to this file")
    ap.add_argument("--floor", action="store_true",
                    help="also score the ground truth's own functional map (--k, and after ZoomOut): "
                         "the best any network's map in this basis can do under this protocol")
    args = ap.parse_args()
    if args.zoomout_k is None:
        args.zoomout_k = args.k_spectrum

    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)
    warnings.filterwarnings("ignore")
    torch.set_num_threads(1)
    root = dataset_root(args.dataset, args.scape_r)
    t0 = time.perf_counter()
    source = "detect" if args.symmetries == "consensus" else args.symmetries
    def drop(symmetries: str) -> str:  # detected reflections, uncertain ones dropped: their own cache
        return "-drop" if args.on_uncertain == "drop" and symmetries in ("detect", "consensus") else ""

    ds = MeshDataset.from_layout(root, pre_transform(args.k_spectrum, args.n_wks, source, args.on_uncertain),
                                 processed_dir=args.cache / f"{args.dataset}-{source}{drop(source)}")
    data = [ds[i] for i in range(len(ds))]
    names = [s["name"] for s in data]
    log.info(f"{args.dataset}: {len(data)} shapes, precompute/load {time.perf_counter() - t0:.0f} s")
    if args.max_distortion is not None:
        dist = reflection_distortions(data, args.cache / f"{args.dataset}-{args.symmetries}-distortion.json")
        data = drop_distorted_reflections(data, dist, args.max_distortion)
        log.info(f"reflections kept (distortion <= {args.max_distortion}): "
                 f"{sum(d <= args.max_distortion for d in dist.values())} of {len(dist)}")
    args.test_symmetries = args.test_symmetries or args.symmetries
    data_test = data
    if args.test_symmetries != args.symmetries:
        ds_t = MeshDataset.from_layout(root, pre_transform(args.k_spectrum, args.n_wks, args.test_symmetries,
                                                           args.on_uncertain),
                                       processed_dir=args.cache / f"{args.dataset}-{args.test_symmetries}"
                                       f"{drop(args.test_symmetries)}")
        data_test = [ds_t[i] for i in range(len(ds_t))]
        if [s["name"] for s in data_test] != names:
            raise SystemExit("error: the two symmetry sources list different shapes")
    within = args.dataset == "TOSCA_Isometric"
    train_idx, test_idx = split_shapes(names, args.dataset, args.seed)
    if args.regime == "quarter":
        g = torch.Generator().manual_seed(args.seed + 1)
        keep = max(2, math.ceil(len(train_idx) / 4))
        if within:  # keep every class represented
            by_cls: dict[str, list[int]] = {}
            for i in train_idx:
                by_cls.setdefault(class_key(names[i]), []).append(i)
            train_idx = sorted(i for idx in by_cls.values()
                               for i in [idx[j] for j in torch.randperm(len(idx), generator=g).tolist()]
                               [:max(1, math.ceil(len(idx) / 4))])
        else:
            train_idx = sorted(train_idx[j] for j in torch.randperm(len(train_idx), generator=g)[:keep].tolist())
    if args.symmetries == "consensus":  # the training shapes' reflections, voted through their corr
        data = list(data)
        for cls in sorted({class_key(names[i]) if within else "" for i in train_idx}):
            voters = [i for i in train_idx if not within or class_key(names[i]) == cls]
            tr = template_reflection([data[i] for i in voters])
            log.info(f"consensus{' ' + cls if cls else ''}: {tr.n_shapes} shapes voted, median "
                     f"support {float(tr.support.median()):.2f}")
            for i in voters:
                data[i] = with_template_reflection(data[i], tr)
        if args.test_symmetries == args.symmetries:
            data_test = data  # the held-out shapes keep their detected reflections
    train_pairs = pairs_of(train_idx, names, within)
    test_pairs = pairs_of(test_idx, names, within)
    if len(test_pairs) > args.max_pairs:
        step = len(test_pairs) / args.max_pairs
        test_pairs = [test_pairs[int(i * step)] for i in range(args.max_pairs)]
    log.info(f"{len(train_idx)} train shapes ({len(train_pairs)} pairs), {len(test_idx)} held-out "
             f"({len(test_pairs)} pairs scored)")
    evaluator = CorrespondenceEvaluator(n_points=args.n_points)
    rows = []
    if args.floor:
        floor = ground_truth_floor(data_test, test_pairs, args, evaluator)
        for post, res in floor.items():
            print(f"{args.dataset:15s} {args.regime:7s} {'ground-truth' + post:17s} error {res.mean:.4f}  "
                  f"flipped {100 * res.flipped_share:5.1f}%  [{len(res.pairs)} pairs; the basis's floor]",
                  flush=True)
    for run in args.runs:
        t1 = time.perf_counter()
        tag = "" if run == "baseline" else f"_{args.symmetries}{drop(args.symmetries)}"  # baseline: none
        if run != "baseline" and args.mirror == "pair":
            tag = "_pair"
        saved = args.cache / "models" / (f"{args.dataset}_{args.regime}_{args.input}_{run}{tag}_s{args.seed}"
                                         f"_n{args.steps}{'_cos' if args.schedule == 'cosine' else ''}"
                                         f"{'' if args.max_distortion is None else f'_d{args.max_distortion}'}.pt")
        if args.reuse and saved.exists():  # evaluate a model trained by an earlier call
            model = Matcher(args.input, args.n_wks, args.k, args.k_eig, args.width, args.out,
                            symmetrize=run == "symmetrize", spectral=run == "spectral")
            model.load_state_dict(torch.load(saved, weights_only=True))
        else:
            model = train(run, data, train_pairs, args)
            saved.parent.mkdir(parents=True, exist_ok=True)
            torch.save(model.state_dict(), saved)
        t_train = time.perf_counter() - t1
        results = evaluate(model, data_test, test_pairs, args, evaluator)
        for post, res in results.items():
            run_name = run if args.mirror == "shape" or run == "baseline" else f"{run}-pair"
            if args.max_distortion is not None and run != "baseline":
                run_name += f"-d{args.max_distortion:g}"
            row = dict(dataset=args.dataset, regime=args.regime, input=args.input, run=run_name + post,
                       symmetries=args.symmetries, test_symmetries=args.test_symmetries,
                       on_uncertain=args.on_uncertain,
                       schedule=args.schedule,
                       max_distortion=args.max_distortion,
                       n_train=len(train_idx), n_pairs=len(res.pairs), error=res.mean,
                       flipped=res.flipped_share, up_to_symmetry=res.mean_up_to_symmetry,
                       error_sym=res.mean_sym, train_s=round(t_train, 1), steps=args.steps,
                       seed=args.seed)
            rows.append(row)
            print(f"{args.dataset:15s} {args.regime:7s} {run_name + post:17s} error {res.mean:.4f}  "
                  f"flipped {100 * res.flipped_share:5.1f}%  up to symmetry "
                  f"{res.mean_up_to_symmetry:.4f}  [{len(train_idx)} train shapes, "
                  f"{len(res.pairs)} pairs, train {t_train:.0f} s]",
                  flush=True)
        if args.json is not None:
            with open(args.json, "a") as fh:
                for row in rows[-len(results):]:
                    fh.write(json.dumps(row) + "\n")
        if args.per_pair is not None:  # one line per run, post-process and held-out pair
            with open(args.per_pair, "a") as fh:
                for post, res in results.items():
                    for (i, j), p in zip(test_pairs, res.pairs):
                        fh.write(json.dumps(dict(dataset=args.dataset, regime=args.regime, run=run + post,
                                                 seed=args.seed, x=names[i], y=names[j], error=p.mean,
                                                 error_sym=p.mean_sym, flipped=p.flipped)) + "\n")


if __name__ == "__main__":
    main()
