"""How often does orientation tell the true map from its mirror flip? FAUST (BCICP 5k), all ordered pairs.

    python scripts/measure_resolution.py [--k 30 50] [--descriptor wks] [--n-descriptors 16]
        [--sigma 0.5 1 2 3] [--outliers 0.2 0.5] [--partial 0.2 0.3 0.4]

For each ordered pair (x, y) of the shapes in ``bcicp_5k/FAUST/vtx_5k`` (unit area, ``laplacian_spectrum``):
the ground-truth map ``C_xy`` (``corr_to_fmap``), its flip (through x's ``corr_sym``), and y's reflection
``S_y`` (``corr_sym`` against ``corr`` on y). Starting from the truth the resolution must choose the
identity, from the flip the reflection. Rows:

- ``fmap``: :func:`symtorch.orientation.resolve_symmetry` on ``C + noise`` (Gaussian entries, Frobenius
  norm ``sigma * ||C||``), operators of ``--n-descriptors`` WKS (or HKS) columns;
- ``p2p vote`` / ``p2p operator``: :func:`resolve_symmetry_p2p` (orientation vote), and the operator
  residual of the point map's pull-back, on vertex maps: the truth (each vertex of y sent through its
  nearest template point), with a share ``--outliers`` of vertices sent to random vertices, or the
  nearest-neighbour map of the noisy fmap (``fmap_to_p2p``), or with the patch of a share
  ``--partial`` of y's area around a random vertex taken from the other map (flipped on one region:
  the majority of the area decides what is right).

Prints accuracy (%) per start (gt, flip) and noise level.
"""
from __future__ import annotations

import argparse
import itertools
import logging
import time
import warnings

import torch

from symtorch import laplacian_spectrum
from symtorch.data import corr_to_fmap, read_sample
from symtorch.descriptors import default_energies, default_times, hks, wks
from symtorch.maps import fmap_to_p2p, nearest_neighbors, p2p_to_fmap
from symtorch.orientation import orientation_operators, resolve_symmetry, resolve_symmetry_p2p
from symtorch.paths import shared_path


def load(path, k: int, descriptor: str, n: int) -> dict:
    s = read_sample(path, dtype=torch.float64, ground_truth="vts")
    spec = laplacian_spectrum(s["verts"], s["faces"], k=k)
    if descriptor == "wks":
        desc = wks(spec.evals, spec.evecs, *default_energies(spec.evals, n))
    else:
        desc = hks(spec.evals, spec.evecs, default_times(spec.evals, n))
    s.update(evecs=spec.evecs, mass=spec.mass,
             O=orientation_operators(s["verts"], s["faces"], spec.evecs, spec.mass, desc))
    # vertex maps through the template: each vertex takes its nearest template point on the shape
    s["nearest"] = nearest_neighbors(s["verts"], s["verts"][s["corr"]])
    return s


def noisy(C: torch.Tensor, sigma: float, g: torch.Generator) -> torch.Tensor:
    if sigma == 0:
        return C
    N = torch.randn(C.shape, generator=g, dtype=C.dtype)
    return C + sigma * C.norm() * N / N.norm()


def outliers(p2p: torch.Tensor, share: float, n_to: int, g: torch.Generator) -> torch.Tensor:
    hit = torch.rand(p2p.shape, generator=g) < share
    return torch.where(hit, torch.randint(n_to, p2p.shape, generator=g), p2p)


def partial(p2p: torch.Tensor, other: torch.Tensor, verts: torch.Tensor, mass: torch.Tensor,
            share: float, g: torch.Generator) -> torch.Tensor:
    """``p2p`` with the patch of ``share`` of the area nearest a random vertex taken from ``other``
    (a map flipped on one region, e.g. one limb, as a network's errors often are)."""
    centre = int(torch.randint(len(verts), (1,), generator=g))
    order = (verts - verts[centre]).norm(dim=-1).argsort()
    patch = order[mass[order].cumsum(0) <= share * mass.sum()]
    out = p2p.clone()
    out[patch] = other[patch]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--k", type=int, nargs="+", default=[30, 50])
    ap.add_argument("--descriptor", choices=["wks", "hks"], default="wks")
    ap.add_argument("--n-descriptors", type=int, default=16)
    ap.add_argument("--sigma", type=float, nargs="+", default=[0.5, 1.0, 2.0, 3.0])
    ap.add_argument("--outliers", type=float, nargs="+", default=[0.2, 0.5])
    ap.add_argument("--partial", type=float, nargs="+", default=[0.2, 0.3, 0.4])
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    folder = shared_path("bcicp_5k", "FAUST", "vtx_5k")
    if folder is None:
        print("shared data not found (bcicp_5k/FAUST/vtx_5k)")
        return 1
    warnings.filterwarnings("ignore")  # some meshes have a duplicated vertex
    logging.getLogger("symtorch").setLevel(logging.ERROR)
    t0 = time.time()
    for k in args.k:
        shapes = [load(p, k, args.descriptor, args.n_descriptors) for p in sorted(folder.glob("*.off"))]
        hits: dict[str, list[bool]] = {}

        def score(row: str, start: str, index: int, want: int) -> None:
            hits.setdefault(f"{row:<26s} {start:<4s}", []).append(index == want)

        g = torch.Generator().manual_seed(args.seed)
        for x, y in itertools.permutations(shapes, 2):
            ex, ey = x["evecs"], y["evecs"]
            S_y = corr_to_fmap(y["corr_sym"], y["corr"], ey, ey, y["mass"])
            sym_fmap = torch.stack([torch.eye(k, dtype=S_y.dtype), S_y])
            sym_p2p = torch.stack([torch.arange(len(y["verts"])), y["corr_sym"][y["nearest"]]])
            truth = {"gt": x["corr"], "flip": x["corr_sym"]}
            for (start, cx), want in zip(truth.items(), (0, 1)):
                C = corr_to_fmap(cx, y["corr"], ex, ey, y["mass"])
                p2p = cx[y["nearest"]]
                other = truth["flip" if start == "gt" else "gt"][y["nearest"]]
                maps = {"exact": p2p}
                maps.update({f"outliers={q:g}": outliers(p2p, q, len(x["verts"]), g) for q in args.outliers})
                maps.update({f"partial flip={q:g}": partial(p2p, other, y["verts"], y["mass"], q, g) for q in args.partial})
                for sigma in [0.0, *args.sigma]:
                    Cn = noisy(C, sigma, g)
                    score(f"fmap sigma={sigma:g}", start, int(resolve_symmetry(Cn, sym_fmap, x["O"], y["O"]).index), want)
                    if sigma > 0:
                        maps[f"nn(fmap sigma={sigma:g})"] = fmap_to_p2p(Cn, ex, ey)
                for name, m in maps.items():
                    vote = resolve_symmetry_p2p(m, x["verts"], x["faces"], y["verts"], y["faces"], sym_p2p)
                    score(f"p2p vote {name}", start, int(vote.index), want)
                    Cm = p2p_to_fmap(m, ex, y["mass"], ey)
                    score(f"p2p operator {name}", start,
                          int(resolve_symmetry(Cm, sym_fmap, x["O"], y["O"]).index), want)
        print(f"k={k}, {len(shapes)} shapes, {len(shapes) * (len(shapes) - 1)} ordered pairs, "
              f"{args.n_descriptors} {args.descriptor.upper()} operators ({time.time() - t0:.0f} s)")
        for key, v in hits.items():
            print(f"  {key}  {100.0 * sum(v) / len(v):6.1f} %  ({sum(v)}/{len(v)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
