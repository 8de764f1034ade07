"""Time the batched torch stages on each device: CPU against CUDA where a GPU is present.

    python scripts/bench_device.py [--devices cpu cuda] [--repeat 5] [--candidates 10000 100000]

Stages (all on code-built shapes, no data files needed):

- ``block_procrustes`` on ``[N, 20, 104]`` (SCAPE mesh000's first bands, 104 constraint columns),
  float32 and float64: the core of both detection paths (ALGORITHM §3);
- ``batched_icp`` of 400 candidate matrices (k0 = 20) on the star prism, and ``mean_shift`` of those
  400 flattened matrices: the group path's candidate stages (ALGORITHM §5);
- ``zoomout_symmetry`` of a reflection from 6 to 60 basis functions on the mirror blob (1000 samples);
- ``detect_symmetries(mode='group', device=...)`` end to end on the star prism (the spectrum solved
  once, outside the timing): what ``device=`` buys a whole detection;
- the training losses (``symmetry_equivariance_loss`` + ``orthogonality_loss``) forward and backward
  on a batch of 64 maps of size 60 with 4 group elements each.

Each row: the median of ``--repeat`` runs after one warm-up, the device synchronised; the last column
is CPU time / device time.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings

import torch

from symtorch import shapes
from symtorch.cluster import mean_shift
from symtorch.detect import detect_symmetries
from symtorch.detect.group_path import batched_icp
from symtorch.losses import orthogonality_loss, symmetry_equivariance_loss
from symtorch.maps import p2p_to_fmap
from symtorch.procrustes import block_procrustes
from symtorch.refine import zoomout_symmetry
from symtorch.sampling import farthest_point_sampling
from symtorch.spectrum import band_boundary, bands_from_sizes, laplacian_spectrum, solved_bands

BAND_SIZES = [1, 2, 1, 1, 1, 2, 2, 2, 1, 1, 1, 1, 1, 1, 1, 1]  # SCAPE mesh000, K = 20


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def timed(fn, device: torch.device, repeat: int) -> float:
    fn()  # warm-up: kernels, allocator, lazy initialisation
    _sync(device)
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        _sync(device)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def cases(candidates: list[int]):
    """(name, shape note, build(device) -> zero-argument callable)."""
    g = torch.Generator().manual_seed(0)
    bands = bands_from_sizes(BAND_SIZES)
    K = bands[-1].stop
    for n in candidates:
        A = torch.randn(n, K, 104, generator=g, dtype=torch.float64)
        B = torch.randn(n, K, 104, generator=g, dtype=torch.float64)
        for dtype in (torch.float32, torch.float64):
            yield (f"block_procrustes {str(dtype)[6:]}", f"[{n}, {K}, 104]",
                   lambda d, A=A, B=B, dtype=dtype: (lambda a=A.to(d, dtype), b=B.to(d, dtype):
                                                     block_procrustes(a, b, bands)))
    v, f = shapes.star_prism(subdivisions=4)
    spec = laplacian_spectrum(v, f, k=60)
    sb = solved_bands(spec.evals)
    k0 = band_boundary(sb, 20)
    b0 = [b for b in sb if b.stop <= k0]
    E = spec.evecs[:, :k0]
    true = [torch.as_tensor(m) for m in shapes.symmetry_maps(v, shapes.true_symmetries("star_prism"))]
    C = torch.stack([p2p_to_fmap(p, E, spec.mass) for p in true])  # [20, k0, k0]
    C = C.repeat(20, 1, 1) + 0.05 * torch.randn(400, k0, k0, generator=g, dtype=torch.float64)
    src, tgt = torch.arange(0, len(v), len(v) // 200)[:200], torch.arange(0, len(v), len(v) // 600)[:600]
    yield ("batched_icp (3 steps)", f"400 x [{k0}, {k0}], S=200, T=600",
           lambda d: (lambda c=C.to(d), es=E[src].to(d), et=E[tgt].to(d): batched_icp(c, es, et, b0, 3)))
    X = C.reshape(400, -1)
    yield ("mean_shift", f"[400, {k0 * k0}]", lambda d: (lambda x=X.to(d): mean_shift(x, 0.6)))
    vb, fb = shapes.mirror_blob(subdivisions=4)
    sp = laplacian_spectrum(vb, fb, k=70)
    bb = solved_bands(sp.evals)
    ka, kz = band_boundary(bb, 6), band_boundary(bb, 60)
    mirror = torch.as_tensor(shapes.symmetry_maps(vb, shapes.true_symmetries("mirror_blob"))[1])
    C0 = p2p_to_fmap(mirror, sp.evecs[:, :ka], sp.mass)
    smp = farthest_point_sampling(torch.as_tensor(vb), 1000)
    yield ("zoomout_symmetry", f"V={len(vb)}, {ka}->{kz}, 1000 samples",
           lambda d: (lambda c=C0.to(d), e=sp.evecs.to(d), m=sp.mass.to(d), s=smp.to(d):
                      zoomout_symmetry(c, e, m, bb, kz, samples=s, involution=True)))

    def detect(d):
        def run():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = detect_symmetries(v, f, spectrum=spec, mode="group", k_refine=40, device=d)
            assert res.group.name == "D5h", res.group.name
        return run
    yield ("detect_symmetries group (device=)", f"star prism V={len(v)}, D5h", detect)
    Kl = 60
    Cl = torch.randn(64, Kl, Kl, generator=g, dtype=torch.float32)
    S = torch.linalg.qr(torch.randn(64, 4, Kl, Kl, generator=g))[0]

    def losses(d):
        c0, s = Cl.to(d), S.to(d)

        def run():
            c = c0.clone().requires_grad_()
            (symmetry_equivariance_loss(c, s, s, match="best") + orthogonality_loss(c)).backward()
        return run
    yield ("losses fwd+bwd float32", f"[64, {Kl}, {Kl}], G=4", losses)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--devices", nargs="+", default=["cpu"] + (["cuda"] if torch.cuda.is_available() else []))
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--candidates", type=int, nargs="+", default=[10000, 100000])
    args = ap.parse_args(argv)
    devices = [torch.device(d) for d in args.devices]
    names = [torch.cuda.get_device_name(d) if d.type == "cuda" else f"cpu ({torch.get_num_threads()} threads)"
             for d in devices]
    print(f"# torch {torch.__version__}; " + "; ".join(names), file=sys.stderr)
    head = " | ".join(f"{d} s" for d in devices)
    ratios = " | ".join(f"cpu/{d}" for d in devices[1:])
    print(f"| stage | size | {head} |" + (f" {ratios} |" if ratios else ""))
    print("|---|---|" + "---:|" * (len(devices) + len(devices) - 1))
    for name, size, build in cases(args.candidates):
        t = [timed(build(d), d, args.repeat) for d in devices]
        cells = " | ".join(f"{x:.4f}" for x in t)
        rat = " | ".join(f"{t[0] / x:.1f}" for x in t[1:])
        print(f"| {name} | {size} | {cells} |" + (f" {rat} |" if rat else ""), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
