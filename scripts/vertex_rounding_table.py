"""What the rounding of each image to a vertex costs the group path's elements, on remeshes.

    OMP_NUM_THREADS=1 python scripts/vertex_rounding_table.py                    # the default rows, ACVD 3000
    OMP_NUM_THREADS=1 python scripts/vertex_rounding_table.py arms5_bent3 --remesh 0   # a regular mesh

Per ``tests/shapes.py`` ``GROUP_SHAPES`` row (``--remesh N``: ACVD-remeshed to about N vertices,
pyacvd needed; 0: the row's own mesh; bent where the row is), ``detect_symmetries`` with
``GroupConfig(near_mirrors="keep")`` (near-symmetric halves stay in the group), and for each element
two distortions in KLC radii: the exact stage's, of the vertex map (10 farthest-point sources, as
``group_elements.upsample_elements`` measures it), and the one the detector kept
(``diagnostics.group.distortion``: the smaller of that and the vertex-to-point map's, where
``group_path.coset_spread`` asked for it, ``group_elements.point_map_distortions``). Elements are split into those whose vertex
map lands within a KLC radius of a true symmetry's on >= 95 % of the vertices (as the tests match
them) and the others (near-symmetries);
the true symmetries' own nearest-vertex maps are measured as vertex maps and as vertex-to-point
maps (``group_elements._SourcePool``, their matrices ``p2p_to_fmap``). Each cell: median (min-max)
of the two.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the shape builders
from shapes import GROUP_SHAPES, bend  # noqa: E402

from symtorch import detect_symmetries  # noqa: E402
from symtorch.detect.config import DetectConfig, GroupConfig  # noqa: E402
from symtorch.detect.group_elements import N_SOURCES, Geometry, _SourcePool  # noqa: E402
from symtorch.geodesics import GeodesicSolver  # noqa: E402
from symtorch.maps import p2p_to_fmap  # noqa: E402
from symtorch.sampling import farthest_point_sampling  # noqa: E402
from symtorch.shapes import symmetry_maps  # noqa: E402
from symtorch.units import EPS_KLC  # noqa: E402

DEFAULT = ["hex_prism", "pinwheel3", "centrosymmetric", "antiprism3_flat"]


def vertex_distortion(geo: Geometry, solver: GeodesicSolver, p2p: torch.Tensor) -> float:
    """The exact stage's distortion of a vertex map."""
    S, src = geo.score_samples, geo.samples[:N_SOURCES].numpy()
    D0 = solver.distances_from(src)[:, S]
    return float((solver.distances_from(p2p[src].numpy())[:, p2p[S]] - D0).abs().mean() / EPS_KLC)


def cell(pairs) -> str:
    if not pairs:
        return "–"
    a = np.asarray(pairs)
    return " / ".join(f"{np.median(a[:, j]):.3f} ({a[:, j].min():.3f}-{a[:, j].max():.3f})" for j in range(2))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("words", nargs="*", help="rows whose name contains one of these (default: four remeshed rows)")
    ap.add_argument("--remesh", type=int, default=3000, metavar="N", help="ACVD to about N vertices (0: not)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cfg = DetectConfig(group=GroupConfig(near_mirrors="keep"))
    print("| shape | V | found (kept whole) | true elements: vertex map / kept | near-symmetries: vertex map / kept "
          "| true maps: vertex / vertex-to-point |")
    print("|---|---:|---|---|---|---|")
    for name, build, _, _, radius in GROUP_SHAPES:
        if not (any(w in name for w in args.words) if args.words else name in DEFAULT):
            continue
        v0, f, mats = build()
        if args.remesh:
            from symtorch.remesh import remesh_acvd

            v0, f = remesh_acvd(v0, f, n_verts=args.remesh, subdivide=3)
            name = f"{name} ACVD"
        v = np.asarray(bend(v0, radius) if radius else v0, dtype=np.float64)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = detect_symmetries(v, f, config=cfg)
        spec = res.spectrum
        vu = v * float(spec.scale)
        solver = GeodesicSolver(vu, f)
        pts = farthest_point_sampling(torch.as_tensor(vu), 8).numpy()
        geo = Geometry(vu, spec, pts, solver.distances_from(pts), cfg.group.n_samples, f)
        pool = _SourcePool(geo, solver)
        true = torch.as_tensor(symmetry_maps(np.asarray(v0), mats))
        x = torch.as_tensor(vu)
        matched, other = [], []
        for s, kept in list(zip(res.symmetries, res.diagnostics.group.distortion))[1:]:
            rate = ((x[true] - x[s.p2p][None]).norm(dim=-1) < EPS_KLC).double().mean(-1).max()
            (matched if rate >= 0.95 else other).append((vertex_distortion(geo, solver, s.p2p), kept))
        K = res.symmetries[0].fmap.shape[0]
        truth = [(vertex_distortion(geo, solver, t), pool.distortion(t, p2p_to_fmap(t, spec.evecs[:, :K], spec.mass)))
                 for t in true if not torch.equal(t, torch.arange(len(v)))]
        print(f"| {name} | {len(v)} | {res.group.name} ({res.group.order}) | {cell(matched)} | {cell(other)} | "
              f"{cell(truth)} |", flush=True)


if __name__ == "__main__":
    main()
