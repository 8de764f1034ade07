"""Would another measure of a candidate map pick the ground truth where geodesic distortion does not?

    python scripts/candidate_measures.py --dataset SCAPE --names mesh013,mesh070,mesh001

The reflection path upsamples each candidate (extrema permutation) to ``k_select`` and keeps the
orientation-reversing one with the lowest geodesic distortion on 16 samples. On the meshes where it
picks a wrong map, no candidate that is right is more isometric by that measure
(``scripts/ground_truth_distortion.py``). This script runs both selections (plain and guided) over
every candidate (no early stop, nothing verified, so both always run) and prints, for each upsampled
candidate whose map reverses orientation: its correspondence rate against the ground truth and
measures of how isometric its dense map (nearest neighbour over all vertices) is, each lower-is-better:

- ``dist``: the selection's own 16-sample geodesic distortion (KLC units);
- ``local``: mean ``|log(|g(a) - g(b)| / |a - b|)|`` over 1000 samples and their 6 nearest samples
  in space (a tear or a fold shows up here where the global distortion averages it away);
- ``1-cover``: the share of the area no vertex maps to (a fold leaves holes);
- ``invol``: mean ``|g(g(x)) - x|`` in KLC units (a reflection is an involution);
- ``offblock``: the share of the map's 20x20 functional map outside the eigenvalue bands (an
  isometry commutes with the Laplacian);
- ``disp`` (not a lower-is-better measure): mean geodesic displacement ``d(x, g(x))`` over 200
  samples in KLC units. A map that mirrors limbs onto themselves moves points less than the
  left-right reflection (SCAPE mesh013: 1.6 against 3.4), but it does not separate right from wrong
  across body plans (quadrupeds' right maps measure 1.5-2.6).

A measure that could replace the distortion would rank the right candidate (rate near 1) first on
the failing meshes and not break the others. Development tool; it wraps
``symtorch.detect.reflection.zoomout_symmetry`` to record the candidates' matrices.
"""
from __future__ import annotations

import argparse
import math
import warnings

import numpy as np
import torch
from scipy.spatial import cKDTree

import symtorch.detect.reflection as reflect
from symtorch.detect import ReflectionConfig
from symtorch.eval.benchmarks import list_benchmark, load_ground_truth, load_mesh
from symtorch.eval import evenly_spaced, geodesic_errors, klc_rates
from symtorch.geodesics import GeodesicSolver
from symtorch.maps import nearest_neighbors, p2p_to_fmap
from symtorch.procrustes import block_mask
from symtorch.sampling import farthest_point_sampling
from symtorch.spectrum import laplacian_spectrum, solved_bands


def measures(p2p: np.ndarray, verts_unit: np.ndarray, vertex_mass: np.ndarray, evecs, mass, bands,
             samples: np.ndarray, sample_fields: np.ndarray) -> dict:
    """The dense-map measures of the module doc for one vertex map ``p2p [V]``.

    ``sample_fields``: [n, V] unit-area geodesic distances from ``samples[:n]`` (for ``disp``).
    """
    eps = math.sqrt(1 / (20 * math.pi))
    _, nb = cKDTree(verts_unit[samples]).query(verts_unit[samples], k=7)
    a, b = np.repeat(samples, 6), samples[nb[:, 1:]].ravel()
    d0 = np.linalg.norm(verts_unit[a] - verts_unit[b], axis=1)
    d1 = np.linalg.norm(verts_unit[p2p[a]] - verts_unit[p2p[b]], axis=1)
    hit = np.zeros(len(p2p), dtype=bool)
    hit[p2p] = True
    K = 20
    C = p2p_to_fmap(torch.as_tensor(p2p), evecs[:, :K], mass)
    inside = block_mask([r for r in bands if r.stop <= K], K)
    n = len(sample_fields)
    disp = sample_fields[np.arange(n), p2p[samples[:n]]].mean() / eps
    return {"extr": extrinsic_agreement(p2p, verts_unit, vertex_mass), "disp": float(disp), "local": float(np.abs(np.log((d1 + 1e-3) / (d0 + 1e-3))).mean()),
            "1-cover": float(vertex_mass[~hit].sum() / vertex_mass.sum()),
            "invol": float(np.linalg.norm(verts_unit[p2p[p2p]] - verts_unit, axis=1).mean() / eps),
            "offblock": float((C[~inside] ** 2).sum() / (C ** 2).sum())}


def extrinsic_agreement(p2p: np.ndarray, verts_unit: np.ndarray, vertex_mass: np.ndarray,
                        radius: float = 0.5, n_iter: int = 8) -> float:
    """The share of the area (higher is better) that one plane reflection of space carries onto the
    map's images: ``|Q x + t - g(x)| < radius`` KLC radii for an improper rigid motion ``(Q, t)``
    fitted robustly (trimmed Kabsch with ``det Q = -1``) to the pairs ``(x, g(x))``."""
    eps = math.sqrt(1 / (20 * math.pi))
    x, y, w = verts_unit, verts_unit[p2p], vertex_mass / vertex_mass.sum()
    keep = np.ones(len(x), dtype=bool)
    for _ in range(n_iter):
        ww = w * keep
        cx, cy = ww @ x / ww.sum(), ww @ y / ww.sum()
        H = ((x - cx) * ww[:, None]).T @ (y - cy)
        U, _, Vt = np.linalg.svd(H)
        d = -np.sign(np.linalg.det(Vt.T @ U.T))
        Q = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
        r = np.linalg.norm((x - cx) @ Q.T + cy - y, axis=1) / eps
        keep = r < max(radius, float(np.quantile(r, 0.5)))
    return float(w[r < radius].sum())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", default="SCAPE", choices=["SCAPE", "TOSCA", "FAUST", "TOSCA_Isometric"])
    ap.add_argument("--names", required=True, help="comma-separated mesh names")
    args = ap.parse_args(argv)
    warnings.filterwarnings("ignore")
    meshes = dict(list_benchmark(args.dataset))
    recorded, halfway = [], []
    upsample = reflect.zoomout_symmetry

    def recording(C0, evecs, mass, bands, k_final, **kw):
        # one trial per candidate: its halfway stop (n_iter_end=0, the pruning vote), then unless
        # pruned its full selection upsampling (n_iter_end=2); the final refinement passes 1
        C = upsample(C0, evecs, mass, bands, k_final, **kw)
        stage = kw.get("n_iter_end", 2)
        if stage == 0:
            recorded.append(C)
            halfway.append(True)
        elif stage == 2:
            if halfway and halfway[-1]:
                recorded[-1] = C
                halfway[-1] = False
            else:
                recorded.append(C)
                halfway.append(False)
        return C

    reflect.zoomout_symmetry = recording
    for name in args.names.split(","):
        v, f = load_mesh(meshes[name])
        pairs = evenly_spaced(load_ground_truth(args.dataset, name).pairs, 1000)
        spec = laplacian_spectrum(v, f, k=110)
        bands = solved_bands(spec.evals)
        recorded.clear()
        halfway.clear()
        # unreachable bars: nothing verifies, so the guided selection runs too; every candidate compared
        res = reflect.detect_reflection(torch.as_tensor(v), torch.as_tensor(f), spec,
                                        config=ReflectionConfig(max_vote=2.0, early_vote=2.0))
        trials = res.diagnostics.reflection.trials + res.diagnostics.reflection.guided_trials
        solver = GeodesicSolver(v, f)
        vu = v * spec.scale
        samples = farthest_point_sampling(torch.as_tensor(vu), 1000).numpy()
        fields = solver.distances_from(samples[:200]).numpy() * spec.scale
        print(f"{name}: {len(trials)} upsampled candidates (plain, then guided)")
        print(f"  {'#':>3} {'rate':>6} {'vote':>7} {'dist':>6} {'local':>6} {'1-cover':>7} {'invol':>6} {'offblock':>8} {'disp':>6} {'extr':>6}")
        for i, (C, (vote, dist)) in enumerate(zip(recorded, trials)):
            if not math.isfinite(dist):
                continue  # not orientation-reversing: the selection does not compare it
            ks = C.shape[0]
            p2p = nearest_neighbors(spec.evecs[:, :ks] @ C, spec.evecs[:, :ks]).numpy()
            rate = float(klc_rates(geodesic_errors(solver, p2p, pairs), solver.area))
            m = measures(p2p, vu, spec.mass.numpy(), spec.evecs, spec.mass, bands, samples, fields)
            print(f"  {i:>3} {rate:6.3f} {vote:7.3f} {dist:6.3f} {m['local']:6.3f} {m['1-cover']:7.3f} "
                  f"{m['invol']:6.3f} {m['offblock']:8.3f} {m['disp']:6.3f} {m['extr']:6.3f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
