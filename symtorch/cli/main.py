"""The ``symtorch`` command line: ``detect``, ``info`` (and the sub-commands registered below).

Progress goes to stderr; results to stdout or ``--out``. Any bad input ends with one line
``symtorch: error: <what>`` on stderr and exit status 2, never a traceback.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
import warnings

import numpy as np

__all__ = ["main", "build_parser", "load_shape", "write_json_atomic", "run_detector", "detect_summary"]

log = logging.getLogger("symtorch")


class CLIError(Exception):
    """An error to report as one line with a non-zero exit."""


def _progress(msg: str) -> None:
    print(f"symtorch: {msg}", file=sys.stderr, flush=True)


def load_shape(path: str | None, demo: str | None = None):
    """(verts [V, 3], faces [F, 3] or None, label) from a mesh file or a built-in shape name."""
    if demo is not None:
        from .. import shapes
        if demo not in shapes.SHAPES:
            raise CLIError(f"unknown demo shape {demo!r}; choose from {', '.join(shapes.SHAPES)}")
        v, f = shapes.SHAPES[demo]()
        return v, f, f"demo:{demo}"
    if path is None:
        raise CLIError("give a mesh file, or --demo [NAME] for a built-in shape")
    from ..io import read_mesh
    mesh = read_mesh(path)
    return mesh.verts, mesh.faces, path


def make_parent(path: str) -> None:
    """Create the folder of an output file; a failure names the folder and the cause."""
    from ..io import WriteError
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as e:
        raise WriteError(e.errno or 0, f"cannot write {path}: cannot create its folder {folder} "
                                       f"({(e.strerror or type(e).__name__).lower()})") from None


def check_output_path(path: str | None) -> None:
    """Refuse, before any work, an output that exists and is no regular file or whose folder is
    read-only (the write itself would fail the same way, after the detection)."""
    if path is None:
        return
    from ..io import WriteError
    if os.path.lexists(path) and not os.path.isfile(path) or os.path.islink(path):
        from ..io import _KINDS
        mode = os.lstat(path).st_mode
        kind = next((name for test, name in _KINDS if test(mode)), "special file")
        raise CLIError(f"{path}: is a {kind}, not a regular file; refusing to replace it")
    folder = os.path.dirname(os.path.abspath(path))
    while not os.path.isdir(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)  # the nearest folder that exists
    if not os.access(folder, os.W_OK):
        try:
            read_only = bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
        except OSError:
            read_only = False
        raise WriteError(0, f"cannot write {path}: "
                            f"{'read-only file system' if read_only else 'permission denied'}")


def check_basis_args(args) -> None:
    """``--k`` / ``--k-refine`` of the detector: at least 2 (the constant eigenfunction and one
    more), the refined basis no smaller than the coarse one."""
    for flag, value in (("--k", args.k), ("--k-refine", args.k_refine)):
        if value is not None and value < 2:
            raise CLIError(f"{flag} must be >= 2, got {value}")
    if args.k is not None and args.k_refine is not None and args.k_refine < args.k:
        raise CLIError(f"--k-refine must be >= --k, got --k {args.k} --k-refine {args.k_refine}")


def write_json_atomic(path: str, obj) -> None:
    """Write ``obj`` as JSON to ``path`` via a temporary file and a rename (never half-written)."""
    from ..io import atomic_write
    make_parent(path)

    def write(tmp: str) -> None:
        with open(tmp, "w") as fh:
            json.dump(obj, fh)

    atomic_write(path, write)


def run_detector(verts, faces, label: str, **kw):
    """``detect_symmetries`` for the CLI: input it cannot handle and its crashes become one line."""
    from ..detect.auto import detect_symmetries
    from ..io import mesh_report
    if faces is None:  # a point cloud: detect_symmetries checks it (too few points, duplicates, parts)
        from ..point_cloud import check_point_cloud
        try:
            check_point_cloud(verts)
        except ValueError as e:
            raise CLIError(f"{label}: {str(e).removeprefix('points: ')}") from None
    else:
        rep = mesh_report(verts, faces)
        if rep["n_components"] > 1:
            raise CLIError(f"{label}: has {rep['n_components']} connected components; symmetry "
                           "detection needs one connected surface (detect each part on its own; if "
                           "the parts come from vertices duplicated along seams, merge them first)")
        if rep["n_unreferenced"]:
            raise CLIError(f"{label}: {rep['n_unreferenced']} vertices are referenced by no face; "
                           "remove them first (symmetry maps are reported per vertex)")
    from ..spectrum import _exact_rescale
    c = _exact_rescale(np.asarray(verts, dtype=np.float64))
    if c != 1.0:  # detect_symmetries applies this exact power of two itself; say so here
        _progress(f"{label}: coordinates up to {np.abs(verts).max():.3g}; scaled by 2^"
                  f"{int(np.log2(c))} for the detector")
    try:
        return detect_symmetries(verts, faces, **kw)
    except Exception as e:  # noqa: BLE001 -- a detector failure on odd input: one line, -v traceback
        log.debug("detect_symmetries failed", exc_info=True)
        hint = (f"; the mesh has only {len(verts)} vertices, too few for the spectral detector "
                "(subdivide it)" if len(verts) < 100 else "")
        raise CLIError(f"{label}: symmetry detection failed ({type(e).__name__}: "
                       f"{' '.join(str(e).split())}){hint}") from None


def load_triangle_mesh(args, task: str = "symmetry detection", note: str = ""):
    """``load_shape`` for the sub-commands that need faces: (verts, faces, label); progress line."""
    verts, faces, label = load_shape(args.mesh, args.demo)
    if faces is None:
        raise CLIError(f"{label}: is a point cloud (no faces); {task} needs a triangle mesh")
    _progress(f"{label}: {len(verts)} vertices, {len(faces)} faces{note}")
    return verts, faces, label


def _cmd_detect(args) -> int:
    t0 = time.perf_counter()
    check_basis_args(args)
    for path in (args.out, args.matrices):
        check_output_path(path)
    verts, faces, label = load_shape(args.mesh, args.demo)
    _progress(f"{label}: {len(verts)} points (a point cloud: no faces)" if faces is None
              else f"{label}: {len(verts)} vertices, {len(faces)} faces")
    kw = {}
    if args.k is not None:
        kw["k"] = args.k
    if args.k_refine is not None:
        kw["k_refine"] = args.k_refine
    res = run_detector(verts, faces, label, mode=args.mode, **kw)
    out = {"mesh": label, **res.to_dict()}
    out["timings"]["read"] = round(time.perf_counter() - t0 - sum(res.timings.values()), 4)
    out["timings"]["total"] = round(time.perf_counter() - t0, 4)
    # JSON on stdout when asked, or when stdout is a pipe or a file and no --out takes it;
    # a person at a terminal gets the summary there instead
    json_to_stdout = args.json or (not args.out and not sys.stdout.isatty())
    summary_to_stdout = not json_to_stdout and sys.stdout.isatty()
    if not summary_to_stdout:
        _progress(_group_line(out))
        _progress("timings " + " ".join(f"{k}={v:.3f}s" for k, v in out["timings"].items()))
    if args.matrices:
        from ..io import atomic_write
        make_parent(args.matrices)

        def write(tmp: str) -> None:
            with open(tmp, "wb") as fh:  # a file object: np.savez would add .npz to a path
                np.savez(fh, fmaps=res.fmaps.cpu().numpy(), p2ps=res.p2ps.cpu().numpy(),
                         k=np.int64(res.fmaps.shape[-1]),
                         evals=res.spectrum.evals[: res.fmaps.shape[-1]].cpu().numpy(),
                         kinds=np.array([s.kind for s in res.symmetries]))

        atomic_write(args.matrices, write)
        _progress(f"matrices -> {args.matrices}")
    if args.out:
        write_json_atomic(args.out, out)
        if not summary_to_stdout:
            _progress(f"result -> {args.out}")
    if json_to_stdout:
        json.dump(out, sys.stdout)
        sys.stdout.write("\n")
    if summary_to_stdout:
        where = f"JSON with every vertex map -> {args.out}" if args.out else \
            "JSON with every vertex map: not written (--out FILE, or --json for stdout; a pipe gets it)"
        print(detect_summary(out) + "\n" + where)
    return 0


def _group_line(out: dict) -> str:
    if out.get("continuous"):
        return ("continuous symmetry (a surface of revolution or a sphere): no finite group; only the "
                "identity is returned")
    names = ", ".join(f"{s['kind']}({s.get('confidence', s['score']):.2f}"
                      f"{', uncertain' if s.get('uncertain') else ''})" for s in out["symmetries"])
    return f"group {out['group'].get('name')} of order {out['group'].get('order')}: {names}"


def detect_summary(out: dict) -> str:
    """The result of ``detect`` (``SymmetryResult.to_dict()`` plus the mesh) for a person to read."""
    from .show import element_labels

    syms, group = out["symmetries"], out["group"]
    labels = element_labels([s["kind"] for s in syms], [s["order"] for s in syms])
    head = f"{out['mesh']}: {out['n_vertices']} vertices, basis K={out['k']}"
    if out.get("continuous"):
        lines = [head, "continuous symmetry (a surface of revolution or a sphere): no finite group; "
                       "only the identity is returned"]
    else:
        lines = [f"{head}, group {group.get('name')} of order {group.get('order')}",
                 f"  {'#':>2}  {'':<4} {'kind':<15} {'order':>5}  {'score':>5}  {'conf':>5}  {'inverse':>7}"]
        inverses = group.get("inverses", [])
        for i, (s, name) in enumerate(zip(syms, labels)):
            inv = labels[inverses[i]] if i < len(inverses) and inverses[i] >= 0 else "-"
            conf = s.get("confidence", s["score"])
            lines.append(f"  {i:>2}  {name:<4} {s['kind']:<15} {s['order']:>5}  {s['score']:>5.2f}  "
                         f"{conf:>5.2f}  {inv:>7}{'  uncertain' if s.get('uncertain') else ''}")
        if out.get("uncertain"):
            lines.append(f"  uncertain: a confidence below min_confidence = {out.get('min_confidence')}; "
                         "the map may be a competing near-symmetry")
    t = out["timings"]
    stages = ", ".join(f"{k} {v:.2f}" for k, v in t.items() if k != "total")
    lines.append(f"time {t.get('total', 0.0):.2f} s ({stages})")
    return "\n".join(lines)


def _cmd_info(args) -> int:
    from ..io import mesh_report
    from ..spectrum import eigen_bands, laplacian_spectrum
    if args.k < 0:
        raise CLIError(f"--k must be >= 0 (0: no eigenvalues), got {args.k}")
    verts, faces, label = load_shape(args.mesh, args.demo)
    rep = mesh_report(verts, faces)
    info = {"mesh": label, **{k: (v.item() if hasattr(v, "item") else v) for k, v in rep.items()}}
    k = min(args.k, len(verts) - 1)  # the eigensolver needs k < V
    if 0 < k < args.k:
        _progress(f"{label}: only {len(verts)} vertices; computing {k} eigenvalues, not {args.k}")
    if k > 0:
        spec = laplacian_spectrum(verts, faces, k=k)
        info["scale"] = float(spec.scale)
        info["eigenvalues"] = [round(float(x), 6) for x in spec.evals]
        info["bands"] = [[b.start, b.stop] for b in eigen_bands(spec.evals)]
    if args.json:
        json.dump(info, sys.stdout)
        sys.stdout.write("\n")
    else:
        for key, val in info.items():
            print(f"{key:>22}: {val}")
    return 0


def add_shape_arguments(parser: argparse.ArgumentParser) -> None:
    """The input of every sub-command that reads one shape: a mesh file or ``--demo [NAME]``."""
    parser.add_argument("mesh", nargs="?", help="mesh file (OFF, OBJ, PLY, ...)")
    parser.add_argument("--demo", nargs="?", const="mirror_blob", default=None, metavar="NAME",
                        help="use a built-in shape instead of a file (default mirror_blob)")


def add_thread_argument(parser: argparse.ArgumentParser) -> None:
    """``--threads N``: the threads of the solves and of torch (default: the free cores)."""
    parser.add_argument("--threads", type=int, default=None, metavar="N",
                        help="threads for the solves and torch (default: the cores not busy "
                             "at the start of each solve; 1: bit-for-bit reproducible)")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="symtorch", description=__doc__.splitlines()[0])
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging on stderr")
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("detect", help="find the intrinsic symmetries of a mesh or point cloud: a summary, or JSON")
    add_shape_arguments(d)
    d.add_argument("--out", help="write the JSON result here")
    d.add_argument("--json", action="store_true",
                   help="print the JSON result on stdout (the default when stdout is not a terminal "
                        "and there is no --out); on a terminal the default is a summary")
    d.add_argument("--matrices", help="write the fmaps, p2ps and basis size to this .npz")
    d.add_argument("--k", type=int, default=None,
                   help="coarse basis size (default 6, snapped to a band end)")
    d.add_argument("--k-refine", type=int, default=None,
                   help="refined basis size, the matrices' K (default 100, snapped to a band end)")
    d.add_argument("--mode", choices=["auto", "reflection", "group"], default="auto")
    add_thread_argument(d)
    d.set_defaults(func=_cmd_detect)

    i = sub.add_parser("info", help="mesh statistics, first eigenvalues and bands")
    add_shape_arguments(i)
    i.add_argument("--k", type=int, default=20, help="eigenvalues to compute (0: none)")
    i.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_thread_argument(i)
    i.set_defaults(func=_cmd_info)

    for register in _register_optional():  # imported here: those modules import this one
        register(sub)
    return p


def _register_optional():
    """Sub-commands living in their own modules (precompute, show) register themselves here."""
    regs = []
    for mod in ("precompute", "show"):
        try:
            m = __import__(f"symtorch.cli.{mod}", fromlist=["register_cli"])
        except ImportError:
            continue
        if hasattr(m, "register_cli"):
            regs.append(m.register_cli)
    return regs


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format="symtorch: %(levelname)s: %(message)s", stream=sys.stderr)
    if not args.verbose:  # the reader both logs and warns each mesh problem: print the warning once
        logging.getLogger("symtorch.io").setLevel(logging.ERROR)
    warnings.simplefilter("default")
    warnings.formatwarning = lambda msg, cat, *a, **k: f"symtorch: warning: {msg}\n"
    from ..data.precompute import FolderInUse
    try:
        return int(_run_command(args) or 0)
    except (CLIError, ValueError, OSError, FolderInUse) as e:  # bad input, unwritable output
        msg = " ".join(str(e).split()) or type(e).__name__
        print(f"symtorch: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("symtorch: error: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print("symtorch: error: out of memory", file=sys.stderr)
        return 2
    except Exception as e:  # a bug or an unforeseen input: still one line; -v shows the traceback
        if args.verbose:
            import traceback
            traceback.print_exc()
        msg = " ".join(str(e).split()) or "no message"
        print(f"symtorch: error: internal error ({type(e).__name__}: {msg}); rerun with -v for the "
              "traceback", file=sys.stderr)
        return 3


def _run_command(args) -> int:
    """The sub-command, its thread pools bounded (``--threads``; precompute bounds its own)."""
    if not hasattr(args, "threads"):
        return args.func(args)
    from ..threads import limit_threads, set_num_threads
    if args.threads is not None and args.threads < 1:
        raise CLIError(f"--threads must be >= 1, got {args.threads}")
    set_num_threads(args.threads)  # the solves inside follow it
    try:
        with limit_threads(args.threads):
            return args.func(args)
    finally:
        set_num_threads(None)


if __name__ == "__main__":
    sys.exit(main())
