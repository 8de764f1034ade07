"""``symtorch precompute SRC OUT``: a whole folder tree of meshes into MeshDataset caches."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..data.precompute import _DTYPES, FAILURES, precompute, _hms


def _cmd_precompute(args) -> int:
    if args.k < 2:
        raise ValueError(f"--k must be >= 2, got {args.k}")
    gt = None if args.ground_truth == "none" else args.ground_truth
    if args.k_refine is not None and args.k_refine < 2:
        raise ValueError(f"--k-refine must be >= 2, got {args.k_refine}")
    if args.k_refine is not None and args.k < args.k_refine + 8:
        raise ValueError(f"--k must be at least --k-refine + 8 (the detector refines in the cached "
                         f"basis, whose last band may be cut): got --k {args.k}, --k-refine {args.k_refine}")
    if args.dist_timeout <= 0:
        raise ValueError(f"--dist-timeout must be > 0 minutes, got {args.dist_timeout}")
    s = precompute(args.src, args.out, k=args.k, detect=args.detect, k_refine=args.k_refine,
                   workers=args.workers,
                   dtype=_DTYPES[args.dtype], ground_truth=gt, seed=args.seed,
                   progress=not args.quiet, dist_timeout_min=args.dist_timeout,
                   on_uncertain=args.on_uncertain)
    who = f"rank {s.rank}/{s.world_size}: " if s.world_size > 1 else ""
    print(f"symtorch: precompute: {who}{s.line()}", file=sys.stderr, flush=True)
    ranks = s.ranks
    if ranks:  # rank 0 under torchrun: the total
        tot = {key: sum(r[key] for r in ranks) for key in ("total", "done", "skipped", "failed")}
        secs = max(r["seconds"] for r in ranks)
        print(f"symtorch: precompute: all {len(ranks)} ranks: {tot['done']} done, {tot['skipped']} "
              f"already done, {tot['failed']} failed, of {tot['total']} in {_hms(secs)}",
              file=sys.stderr, flush=True)
    failed = sum(r["failed"] for r in ranks) if ranks else s.failed
    if failed:
        print(f"symtorch: precompute: failures listed in {Path(args.out) / FAILURES}",
              file=sys.stderr, flush=True)
    return 1 if args.strict and (s.failed or failed) else 0


def register_cli(subparsers) -> None:
    """Add ``symtorch precompute SRC OUT`` to the ``symtorch`` command line."""
    p = subparsers.add_parser(
        "precompute", help="process a folder tree of meshes into MeshDataset caches",
        description="Process every mesh under SRC into OUT (one .pt per mesh, read by MeshDataset). "
                    "Resumable; bad meshes go to OUT/failures.jsonl; under torchrun each rank takes "
                    "its share.")
    p.add_argument("src", help="folder tree of meshes (.off, .obj, .ply, .stl)")
    p.add_argument("out", help="cache folder; OUT/<folder> is MeshDataset's processed_dir")
    p.add_argument("--k", type=int, default=64, help="eigenpairs per mesh (default 64)")
    p.add_argument("--workers", type=int, default=1,
                   help="worker processes, one thread each (default 1: this one)")
    p.add_argument("--detect", action=argparse.BooleanOptionalAction, default=True,
                   help="also detect the symmetries (default yes)")
    p.add_argument("--k-refine", type=int, default=None, metavar="K",
                   help="the detector's final basis size (default: detect_symmetries' 100, capped by "
                        "the --k eigenpairs cached, about --k minus 8); needs --k >= K + 8")
    p.add_argument("--dtype", choices=sorted(_DTYPES), default="float32")
    p.add_argument("--ground-truth", choices=["none", "template", "vts"], default="none",
                   help="ground-truth correspondences to store (see MeshDataset)")
    p.add_argument("--seed", type=int, default=0, help="seed of the detector")
    p.add_argument("--on-uncertain", choices=["keep", "flag", "drop"], default="keep",
                   help="a shape whose detected symmetry is uncertain (confidence below the "
                        "detector's min_confidence): keep it as detected (default), flag it "
                        "(sym_uncertain), or drop its symmetries (the identity alone)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--strict", action="store_true",
                   help="exit with status 1 when some meshes failed (default 0: they are listed)")
    p.add_argument("--dist-timeout", type=float, default=120.0, metavar="MIN",
                   help="under torchrun, minutes a rank waits for the others at the end")
    p.set_defaults(func=_cmd_precompute)
