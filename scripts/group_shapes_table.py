"""The group path on the test suite's shapes with exactly known groups: one table row per shape.

    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py              # every GROUP_SHAPES row + the limits
    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py arms chiral  # rows whose name contains a word
    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py star6_thin_bent --bend 4 --partners
    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py star6_thin_bent --bend 4 --group partner_radius=0
    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py --remesh 3000        # every row remeshed (pyacvd)
    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py --random-arms 12 --seed 1   # random bent arms
    OMP_NUM_THREADS=1 python scripts/group_shapes_table.py --random-shapes 12 --seed 1 --remesh 3000

The shapes are ``tests/shapes.py``'s ``GROUP_SHAPES`` (what ``tests/test_group_shapes.py`` checks)
and the shapes of the measured limit, :data:`LIMITS`. Per shape, as the tests score it:
``detect_symmetries(v, f)`` (``mode="auto"``, default knobs), the group found, the true elements
matched within sqrt(area / (20 pi)) on >= 95 % of 100 evenly spaced vertices and the spurious ones
(``eval.groups.element_rates``), the warnings, the median distortion of the group path's rotations
and of its orientation-reversing elements (``diagnostics.group.distortion``, EPS_KLC), and the
wall and CPU seconds of the detection. ``--bend R`` bends the rows chosen around a cylinder of
radius R instead of their own; ``--remesh N`` remeshes each shape (before its bend) to about N
vertices with ACVD, so that no symmetry maps the triangulation onto itself (the truth: the nearest
remeshed vertex to each transformed one); ``--group KEY=VALUE`` sets a ``GroupConfig`` field; ``--partners``
adds, per shape, how the group path's descriptor gate (``candidates.partner_mask``) treats the true
partners among its invariant points: the largest descriptor ratio of a point and its image under a
true element (``candidates.descriptor_ratios``; the gate admits a pair up to ``desc_tol``), and the
share of those pairs it cuts. ``--truth`` adds the largest exact distortion of the true elements
(64 evenly spaced samples, ``verification.isometry_score``, KLC radii), the coarse screen's rejected
distortions (``diagnostics.group.rejected_distortion``), and, over the orientation-reversing elements
found, the medians of their per-vertex distortion (mean over 16 farthest-point sources of
``|d(g s, g x) - d(s, x)|``: median / 95th percentile over the vertices) and of the change of the
standardised descriptors on the worst 1 % of the area (``verification.standardized_descriptors``).
``--levels`` adds the share of the area whose heat level each element found changes
(``verification.HeatLevels``, the measure of ``group_path.keep_heat_levels``): the largest over the
elements that match a true one, and the range over the spurious ones; with ``--group
max_level_change=1 near_mirrors='"keep"'`` the elements that measure would leave out stay in.
``--offband`` adds, over the true elements, the largest share (Frobenius norm) of the pull-back of
the true map (``maps.p2p_to_fmap``) in the group path's coarse basis that lies outside its bands,
split at the bands' 0.3 and at ``merged_gap``: what no block-diagonal matrix can carry.
``--cosets`` adds, where the result came from the merged-band attempt, the largest ratio of an
index-2 coset other than the orientation one to its subgroup's bent elements, and whether it lies
apart from the subgroup (``group_path.bent_coset_ratios``: what ``near_symmetry_coset`` drops above
``APPROXIMATE_SUBGROUP_RATIO``), and the distortions of a coset dropped; with ``--group
near_mirrors='"keep"'`` a dropped coset stays and reads in the ratio. ``--shares`` adds the
spectrum's 2-D shares at the group path's two scales (``group_path.multiplicity_shares``, the
spectrum ``detect_symmetries`` computes): what routes a shape to the group path (both >= 0.45), to
a second opinion or the merged attempt (one).
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the shape builders
from shapes import (GROUP_SHAPES, antiprism, armed_ball, bend, convex_solid, extruded_polygon,  # noqa: E402
                    pinwheel_prism, star_slab, twisted_blades)

from symtorch import detect_symmetries, laplacian_spectrum  # noqa: E402
from symtorch.descriptors import descriptors  # noqa: E402
from symtorch.detect.candidates import descriptor_ratios  # noqa: E402
from symtorch.detect.config import DetectConfig, GroupConfig  # noqa: E402
from symtorch.detect.group_elements import EXACT_ENOUGH  # noqa: E402
from symtorch.detect.group_path import (bent_coset_ratios, group_basis, invariant_point_set,  # noqa: E402
                                        multiplicity_shares)
from symtorch.maps import p2p_to_fmap  # noqa: E402
from symtorch.spectrum import BAND_REL_GAP  # noqa: E402
from symtorch.detect.verification import HeatLevels, isometry_score, standardized_descriptors  # noqa: E402
from symtorch.descriptors import hks_at_scales  # noqa: E402
from symtorch.sampling import farthest_point_sampling  # noqa: E402
from symtorch.units import EPS_KLC  # noqa: E402
from symtorch.eval.groups import element_rates  # noqa: E402
from symtorch.geodesics import GeodesicSolver  # noqa: E402
from symtorch.remesh import remesh_acvd  # noqa: E402
from symtorch.shapes import symmetry_maps  # noqa: E402

# the measured limit (BENCHMARKS.md, "Wider shapes"): the swept arms' mirrors hold only
# approximately (many times more distorted than their rotations, as the chiral arms'
# are), so they are reported as a near-symmetry and the group as the rotations (the six swept arms
# lose them before that); bends the merged bands do not recover (four arms at R = 2.5; six and five
# chiral arms at R = 3: a mirror, spurious)
LIMITS = [(f"arms{n}_swept", (lambda n=n: armed_ball(n, sweep=0.5)), f"C{n}v", 2 * n, 0) for n in (6, 8, 10)]
LIMITS += [("arms4_bent2.5", lambda: armed_ball(4), "C4v", 8, 2.5)]
SHAPES = GROUP_SHAPES + LIMITS


def random_bent_arms(n_shapes: int, seed: int) -> list:
    """Rows of armed balls drawn at random (``--random-arms``): 4-10 arms, 30 % chiral, elevation
    -30 to -5 degrees, arm length 0.7-1.2, width 0.3-0.4, bent at R = 3.5-8."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n_shapes):
        n, chiral = int(rng.integers(4, 11)), bool(rng.random() < 0.3)
        radius = float(rng.choice([3.5, 4, 5, 6, 8]))
        elev, length, width = float(rng.uniform(-30, -5)), float(rng.uniform(0.7, 1.2)), float(rng.uniform(0.3, 0.4))
        name = f"{'chiral' if chiral else 'arms'}{n} elev={elev:.0f} len={length:.2f} w={width:.2f} R={radius:g}"
        build = (lambda n=n, c=chiral, e=elev, ln=length, w=width:
                 armed_ball(n, chiral=c, elev=e, length=ln, width=w))
        rows.append((name, build, f"C{n}" if chiral else f"C{n}v", n if chiral else 2 * n, radius))
    return rows


def random_shapes(n_shapes: int, seed: int) -> list:
    """Rows drawn at random from every family of the table (``--random-shapes``), with parameters
    the tests do not use: star slabs (3-8 points, height 0.2-0.6, inner radius 0.4-0.7), extruded
    regular polygons (3-8 sides, height 0.3-1.0), pinwheels (3-6 blades, height 0.2-0.5), twisted
    blades (2-5, twist 0.8-1.6), armed balls (4-10 arms, 30 % chiral, elevation -30 to -5 degrees),
    antiprisms (3-7 sides, half height 0.3-0.8); a third of them bent at R = 4-8 (not the
    antiprisms, whose bend is no isometry of a convex solid's metric)."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n_shapes):
        kind = str(rng.choice(["star", "prism", "pinwheel", "blades", "arms", "antiprism"]))
        if kind == "star":
            n, h, inner = int(rng.integers(3, 9)), float(rng.uniform(0.2, 0.6)), float(rng.uniform(0.4, 0.7))
            name, build, truth = f"star{n} h={h:.2f} inner={inner:.2f}", (lambda n=n, h=h, i=inner: star_slab(n, h, i)), (f"D{n}h", 4 * n)
        elif kind == "prism":
            n, h = int(rng.integers(3, 9)), float(rng.uniform(0.3, 1.0))
            name, build, truth = f"prism{n} h={h:.2f}", (lambda n=n, h=h: extruded_polygon(n, h, None)), (f"D{n}h", 4 * n)
        elif kind == "pinwheel":
            n, h = int(rng.integers(3, 7)), float(rng.uniform(0.2, 0.5))
            name, build, truth = f"pinwheel{n} h={h:.2f}", (lambda n=n, h=h: pinwheel_prism(n, h)), (f"C{n}h", 2 * n)
        elif kind == "blades":
            n, tw = int(rng.integers(2, 6)), float(rng.uniform(0.8, 1.6))
            name, build, truth = f"blades{n} twist={tw:.2f}", (lambda n=n, t=tw: twisted_blades(n, t)), (f"D{n}", 2 * n)
        elif kind == "arms":
            n, chiral, elev = int(rng.integers(4, 11)), bool(rng.random() < 0.3), float(rng.uniform(-30, -5))
            name = f"{'chiral' if chiral else 'arms'}{n} elev={elev:.0f}"
            build, truth = (lambda n=n, c=chiral, e=elev: armed_ball(n, chiral=c, elev=e)), ((f"C{n}", n) if chiral else (f"C{n}v", 2 * n))
        else:
            n, h = int(rng.integers(3, 8)), float(rng.uniform(0.3, 0.8))
            name, build, truth = f"antiprism{n} h={h:.2f}", (lambda n=n, h=h: convex_solid(antiprism(n, h))), (f"D{n}d", 4 * n)
        radius = float(rng.choice([4, 5, 6, 8])) if kind != "antiprism" and rng.random() < 1 / 3 else 0
        rows.append((name + (f" R={radius:g}" if radius else ""), build, *truth, radius))
    return rows


def _median(xs: list[float]) -> str:
    return f"{statistics.median(xs):.3f}" if xs else "–"


def truth_columns(v, f, true_maps: np.ndarray, res) -> str:
    """The ``--truth`` columns (see the module docstring)."""
    sp = res.spectrum
    vu = np.asarray(v, dtype=np.float64) * sp.scale
    solver = GeodesicSolver(vu, f)
    samples = torch.as_tensor(np.linspace(0, len(v) - 1, 64).astype(np.int64))
    D0 = solver.pairwise(samples)
    true_max = max(isometry_score(solver, torch.as_tensor(g), samples, D0).distortion for g in true_maps)
    rej = res.diagnostics.group.rejected_distortion or []
    src = farthest_point_sampling(torch.as_tensor(vu), 16).numpy()
    D = torch.as_tensor(np.asarray(solver.distances_from(src)))  # [16, V]
    Z = standardized_descriptors(descriptors(sp.evals, sp.evecs))
    w = sp.mass / sp.mass.sum()
    med, p95, worst = [], [], []
    for s, reversing in zip(res.symmetries, res.group.reversing.tolist()):
        if not reversing:
            continue
        g = s.p2p.numpy()
        per_vertex = ((torch.as_tensor(np.asarray(solver.distances_from(g[src])))[:, g] - D).abs().mean(0)
                      / EPS_KLC).numpy()
        med.append(float(np.median(per_vertex)))
        p95.append(float(np.quantile(per_vertex, 0.95)))
        change = (Z - Z[s.p2p]).abs().mean(1)
        order = torch.argsort(change, descending=True)
        top = torch.cumsum(w[order], 0) <= 0.01
        worst.append(float((change[order] * w[order])[top].sum() / 0.01))
    rej_s = f"{min(rej):.2f}-{max(rej):.2f}" if rej else "–"
    mir = f"{_median(med)} / {_median(p95)} | {_median(worst)}" if med else "– | –"
    return f" {true_max:.3f} | {rej_s} | {mir} |"


def partner_ratios(v, f, true_maps: np.ndarray, cfg: GroupConfig) -> np.ndarray:
    """Descriptor ratios of every (point, image) pair of the group path's invariant points under the
    true elements, where the image lands within one KLC radius of another point."""
    spectrum = laplacian_spectrum(torch.as_tensor(v), torch.as_tensor(f), k=cfg.n_eigen)
    verts_unit = np.asarray(v, dtype=np.float64) * spectrum.scale
    pts = invariant_point_set(spectrum, f, verts_unit, GeodesicSolver(verts_unit, f), cfg.n_points)
    P, fields = np.asarray(pts.points), pts.fields.numpy()
    desc = descriptors(spectrum.evals, spectrum.evecs)
    near = (desc, pts.fields <= cfg.partner_radius * EPS_KLC) if cfg.partner_radius > 0 else None
    ratio = descriptor_ratios(desc[P], near)
    out = []
    for g in true_maps:
        near = fields[:, g[P]].argmin(0)  # [n] the point nearest to each image
        ok = (fields[near, g[P]] < EPS_KLC) & (near != np.arange(len(P)))
        out += ratio[np.flatnonzero(ok), near[ok]].tolist()
    return np.asarray(out)


def level_columns(f, res, sc) -> str:
    """The ``--levels`` columns (see the module docstring)."""
    sp = res.spectrum
    heat = HeatLevels(hks_at_scales(sp.evals, sp.evecs, (0.1, 0.02)), f)
    share = [heat.changed_share(p, sp.mass) for p in res.p2ps]
    matched = {d for _, d, _ in sc.matches}
    true = [x for i, x in enumerate(share) if i in matched]
    spurious = [x for i, x in enumerate(share) if i not in matched]
    return (f" {max(true):.3f} |" if true else " – |") + (f" {min(spurious):.3f}-{max(spurious):.3f} |" if spurious else " – |")


def offband_columns(v, f, true_maps: np.ndarray, cfg: DetectConfig) -> str:
    """The ``--offband`` columns (see the module docstring)."""
    sp = laplacian_spectrum(v, f, k=cfg.group.n_eigen)
    out = ""
    for gap in (BAND_REL_GAP, cfg.group.merged_gap):
        basis = group_basis(sp.evals, cfg.group_basis[0], cfg.group_basis[1], rel_gap=gap)
        P = sp.evecs[:, :basis.k0].double()
        inside = torch.zeros(basis.k0, basis.k0, dtype=torch.bool)
        for b in basis.bands0:
            inside[b.start:b.stop, b.start:b.stop] = True
        shares = [float(C[~inside].norm() / C.norm()) for C in (p2p_to_fmap(torch.as_tensor(g), P, sp.mass)
                                                                  for g in true_maps[1:])]
        out += f" {max(shares, default=0.0):.2f} |"
    return out


def coset_columns(res, cfg: GroupConfig) -> str:
    """``--cosets``: where the merged attempt gave the result, its largest other-coset ratio
    (``group_path.bent_coset_ratios``, apart or not) and the median of a coset it dropped."""
    g = res.diagnostics.group
    if g is None or g.distortion is None or g.band_gap != cfg.merged_gap:
        return " – | – |"
    ratios = bent_coset_ratios(res.group.table, g.distortion, res.group.reversing,
                               EXACT_ENOUGH * cfg.max_distortion)
    r = max(ratios, default=None)
    dropped = g.near_symmetry_coset
    return (f" {f'{r[0]:.2f}' + (' apart' if r[1] else '') if r else '–'} |"
            f" {f'{len(dropped)} at {statistics.median(dropped):.3f}' if dropped else '–'} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("words", nargs="*", help="only the rows whose name contains one of these")
    ap.add_argument("--bend", type=float, default=None, help="bend radius of the rows chosen (0: flat)")
    ap.add_argument("--remesh", type=int, default=None, metavar="N",
                    help="remesh each shape to about N vertices with ACVD first (symtorch.remesh.remesh_acvd, "
                         "pip install pyacvd): the triangulation no longer symmetric, the truth by nearest vertices")
    ap.add_argument("--random-arms", type=int, default=None, metavar="N",
                    help="instead of the table's rows, N bent armed balls drawn at random (--seed)")
    ap.add_argument("--random-shapes", type=int, default=None, metavar="N",
                    help="instead of the table's rows, N shapes of every family drawn at random (--seed)")
    ap.add_argument("--seed", type=int, default=1, help="--random-arms' and --random-shapes' seed")
    ap.add_argument("--group", nargs="*", default=[], metavar="KEY=VALUE", help="GroupConfig fields")
    ap.add_argument("--partners", action="store_true", help="the descriptor gate on the true partners")
    ap.add_argument("--truth", action="store_true", help="the true elements' distortion, the screen's "
                    "rejections, the mirrors' per-vertex distortion and descriptor change")
    ap.add_argument("--levels", action="store_true", help="the heat-level change of the true and the "
                    "spurious elements found (verification.HeatLevels)")
    ap.add_argument("--offband", action="store_true", help="the largest share of a true element's "
                    "coarse matrix outside the bands, split at 0.3 and at merged_gap")
    ap.add_argument("--cosets", action="store_true", help="the merged attempt's cosets other than the "
                    "orientation one, against their subgroups' bent elements")
    ap.add_argument("--shares", action="store_true", help="the spectrum's 2-D shares at the group "
                    "path's two scales (group_path.multiplicity_shares)")
    args = ap.parse_args()
    knobs = {k: json.loads(v) for k, v in (kv.split("=", 1) for kv in args.group)}
    cfg = DetectConfig(group=GroupConfig(**knobs))
    torch.set_num_threads(1)
    extra = " | partners' largest ratio (cut, desc_tol)" if args.partners else ""
    extra += (" | true elements' largest distortion | coarse rejections | mirrors' per-vertex distortion "
              "median / p95 | mirrors' worst-1 % descriptor change") if args.truth else ""
    extra += " | true elements' largest level change | spurious elements' level change" if args.levels else ""
    extra += " | true elements' off-band share, bands at 0.3 | at merged_gap" if args.offband else ""
    extra += " | other cosets' largest ratio to bent subgroup (apart) | dropped coset's median" if args.cosets else ""
    extra += " | 2-D shares (coarse / twice)" if args.shares else ""
    print("| shape | V | truth | found | matched | spurious | warnings | rotations' / mirrors' distortion | wall s | CPU s"
          + extra + " |")
    print("|---|---:|---|---|---:|---:|---:|---|---:|---:|" + ("---:|" if args.partners else "")
          + ("---:|---|---|---:|" if args.truth else "") + ("---:|---|" if args.levels else "")
          + ("---:|---:|" if args.offband else "") + ("---:|---:|" if args.cosets else "")
          + ("---:|" if args.shares else ""))
    rows = (random_bent_arms(args.random_arms, args.seed) if args.random_arms
            else random_shapes(args.random_shapes, args.seed) if args.random_shapes else SHAPES)
    for name, build, group, order, radius in rows:
        if args.words and not any(w in name for w in args.words):
            continue
        if args.bend is not None:
            radius = args.bend
            name = f"{name.removesuffix('_bent')} bent R={radius:g}" if radius else f"{name} flat"
        v0, f, mats = build()
        if args.remesh:
            v0, f = remesh_acvd(v0, f, n_verts=args.remesh, subdivide=3)
            name = f"{name} ACVD"
        v = bend(v0, radius) if radius else v0
        t0, c0 = time.perf_counter(), time.process_time()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = detect_symmetries(v, f, config=cfg)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        sc, _ = element_rates(GeodesicSolver(v, f), symmetry_maps(v0, mats), res.p2ps)
        g = res.diagnostics.group
        rot, mir = [], []
        if g is not None and g.distortion is not None:
            for d, r in list(zip(g.distortion, res.group.reversing.tolist()))[1:]:
                (mir if r else rot).append(d)
        print(f"| {name} | {len(v)} | {group} ({order}) | {res.group.name} ({res.group.order}) | "
              f"{sc.found}/{order} | {sc.spurious} | {len(caught)} | {_median(rot)} / {_median(mir)} | "
              f"{wall:.1f} | {cpu:.1f} |", end="", flush=True)
        if args.partners:
            r = partner_ratios(v, f, symmetry_maps(v0, mats), cfg.group)
            print(f" {r.max():.2f} ({100 * (r > cfg.group.desc_tol).mean():.0f} %, {cfg.group.desc_tol:g}) |"
                  if len(r) else " – |", end="")
        if args.truth:
            print(truth_columns(v, f, symmetry_maps(v0, mats), res), end="")
        if args.levels:
            print(level_columns(f, res, sc), end="")
        if args.offband:
            print(offband_columns(v, f, symmetry_maps(v0, mats), cfg), end="")
        if args.cosets:
            print(coset_columns(res, cfg.group), end="")
        if args.shares:
            sp = laplacian_spectrum(v, f, k=max(cfg.k_refine + 10, 60))  # as detect_symmetries computes it
            print(" {:.2f} / {:.2f} |".format(*multiplicity_shares(sp.evals, cfg.group_basis[0])), end="")
        print(flush=True)


if __name__ == "__main__":
    main()
