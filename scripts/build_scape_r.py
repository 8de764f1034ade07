"""Build SCAPE_r-style data: every SCAPE pose remeshed on its own to about 5k vertices, ground truth carried.

    python scripts/build_scape_r.py                       # all 71 poses -> /work/data_derived/SCAPE_r
    python scripts/build_scape_r.py --limit 3 --out /tmp/scape_r_try
    python scripts/build_scape_r.py --names mesh000,mesh042 --corres projected

The layout is the one FAUST_r / SCAPE_r use (Ren et al. 2018, remeshed with LRVD):

    OUT/off/<name>.off           the remeshed pose (0-based faces, outward like the source)
    OUT/corres/<name>.vts        line t: 1-based id of the remeshed vertex nearest to vertex t of the
                                 source pose (t = 1..12,500, SCAPE's common template numbering), on
                                 the same sheet of surface (--corres)
    OUT/corres/<name>.sym.vts    line t: the remeshed vertex corresponding to the mirror image of
                                 template vertex t, i.e. line sym(t) of <name>.vts
    OUT/template_reflection.txt  line t: 1-based template vertex sym(t), the dense reflection used
    OUT/manifest.json            sources (sha1), parameters, versions, per-shape counts and checks
    OUT/README.md                how it was built

Stages, per pose: remesh with ACVD (``symtorch.remesh.remesh_acvd``: a seeded shuffle first, so no two
poses share connectivity; linear subdivision before clustering, so the new vertices are not
template vertices); accept the mesh when it is closed, manifold, unpinched, one piece, without
degenerate faces or angles below ``min_angle_deg``, with the vertex count within tolerance, else try
the next seed; where no seed of ``max_tries`` passes, use the first whose edges in three faces could
be cut out and the holes filled (``fill_nonmanifold``: one coarse fan per hole); orient the faces
consistently and outward like the source; carry the ground truth by closest vertex (not across a
gap: see :func:`carry_correspondence`); write atomically; check. The template reflection comes from
``symtorch.detect_symmetries`` on mesh000 (the neutral pose) and is checked against the KLC10
feature points (``1.pid`` / ``1.sym.info``) on every pose built; below ``--min-klc`` on mesh000 no
``.sym.vts`` is written.

Checks printed per pose (lengths relative to sqrt(area) of the source pose, x1e-3):
``corr`` mean and max distance from each template vertex to its assigned remeshed vertex;
``differ`` the share of template vertices whose written vertex differs from a reference choice (the
Euclidean nearest vertex; for ``--corres nearest``, the same-sheet choice), and ``jump`` the largest
geodesic distance on the remesh between the two (large = one of them sits across a gap); ``sym`` median of
|d(a_k, a_l) - d(b_k, b_l)| over random pairs of carried symmetric pairs (a, b) on the remesh, next to
``sym_src``, the same for the dense template reflection on the source pose; ``klc`` the KLC10 rate of
the carried symmetry against the feature points on the remesh, next to ``klc_src`` for the template
reflection on the source pose; ``shared`` the share of remeshed vertices that coincide (within 5 % of
an edge, in template coordinates) with the previous pose's: ~1 % for independent remeshes.

Re-running skips poses whose three files exist (resumable); every file is written atomically.
The data is academic (SCAPE licence): OUT must lie outside the repository and is never committed.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import platform
import sys
import time
import warnings
import zlib
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Iterable

import numpy as np

import symtorch
from symtorch.io import atomic_write, mesh_report, read_mesh, write_mesh
from symtorch.remesh import (closest_points, count_pinched_vertices, fill_nonmanifold, nearest_vertices,
                             orient_faces, orientation_report, projected_vertices, remesh_acvd,
                             same_sheet_nearest_vertices)

DEFAULT_OUT = "/work/data_derived/SCAPE_r"
SCAPE = ("bim_scb_benchmark", "SCAPE")
_REPO = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class BuildConfig:
    """Knobs of the build.

    Attributes:
        n_verts: ACVD clusters, i.e. target vertex count of each remesh.
        subdivide: linear subdivisions of the source before clustering (2: 16x the points, so each
            cluster averages ~40 of them instead of ~2.5 template vertices).
        max_tries: seeds tried per pose before giving up on it.
        seed: base seed; pose ``name`` starts at ``seed + crc32(name)``, then +1 per retry.
        vertex_tolerance: accept a remesh whose vertex count is within this share of ``n_verts``.
        min_angle_deg: accept a remesh whose smallest triangle angle is at least this.
        repair: where no seed gives a clean mesh, fall back on the first seed whose only defects
            were edges in three faces (clusters wrapped round a toe or a finger), cut out and the
            holes closed (``symtorch.remesh.fill_nonmanifold``).
        corres: how template vertices find their remeshed vertex (:func:`carry_correspondence`):
            ``"same_sheet"`` (default), ``"nearest"`` (what FAUST_r / SCAPE_r do) or ``"projected"``.
        n_check: template vertices sampled for the geodesic check of the symmetric pairs.
        min_klc: least KLC10 rate of the template reflection on mesh000 for ``.sym.vts`` to be written.
    """

    n_verts: int = 5000
    subdivide: int = 2
    max_tries: int = 8
    seed: int = 0
    vertex_tolerance: float = 0.01
    min_angle_deg: float = 5.0
    repair: bool = True
    corres: str = "same_sheet"
    n_check: int = 100
    min_klc: float = 0.9


@dataclass(frozen=True)
class Remesh:
    """One accepted remesh: geometry, the seed that gave it, and how many seeds were tried."""

    verts: np.ndarray  # [V, 3]
    faces: np.ndarray  # [F, 3]
    seed: int
    tries: int
    rejected: tuple[str, ...]  # why earlier seeds were rejected
    repaired: str | None  # what fill_nonmanifold fixed on the accepted seed, if anything


@dataclass(frozen=True)
class ShapeRecord:
    """What was built for one pose, and its checks (lengths relative to sqrt(source area))."""

    name: str
    n_vertices: int
    n_faces: int
    seed: int
    tries: int
    seconds: float
    skipped: bool
    min_angle_deg: float
    corr_mean: float
    corr_max: float
    differ: float
    jump_max: float
    sym_median: float | None
    sym_src_median: float | None
    klc_rate: float | None
    klc_src_rate: float | None
    sha1_off: str
    sha1_vts: str
    sha1_sym_vts: str | None
    coincide_prev: float | None = None
    rejected: tuple[str, ...] = ()  # why the seeds before the accepted one were rejected
    repaired: str | None = None  # what was cut out and filled on the accepted seed


# ------------------------------------------------------------------------------------------ stages

def min_angle(verts: np.ndarray, faces: np.ndarray) -> float:
    """Smallest interior angle of any triangle, in degrees."""
    tri = verts[faces]
    angles = []
    for i in range(3):
        e1, e2 = tri[:, (i + 1) % 3] - tri[:, i], tri[:, (i + 2) % 3] - tri[:, i]
        cos = np.einsum("ij,ij->i", e1, e2) / (np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1))
        angles.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    return float(np.min(angles))


def remesh_problems(verts: np.ndarray, faces: np.ndarray, config: BuildConfig, closed: bool) -> list[str]:
    """Why a remesh is unusable (empty list: usable). ``closed``: the source is closed."""
    target, tolerance = config.n_verts, config.vertex_tolerance
    rep = mesh_report(verts, faces)
    out = []
    if rep["n_components"] != 1:
        out.append(f"{rep['n_components']} components")
    if rep["n_nonmanifold_edges"]:
        out.append(f"{rep['n_nonmanifold_edges']} non-manifold edges")
    if closed and rep["n_boundary_edges"]:
        out.append(f"{rep['n_boundary_edges']} boundary edges")
    for key in ("n_degenerate_faces", "n_duplicated_vertices", "n_unreferenced"):
        if rep[key]:
            out.append(f"{rep[key]} {key[2:].replace('_', ' ')}")
    pinched = count_pinched_vertices(faces, len(verts))
    if pinched:
        out.append(f"{pinched} pinched vertices")
    if abs(rep["n_vertices"] - target) > tolerance * target:
        out.append(f"{rep['n_vertices']} vertices, target {target}")
    angle = min_angle(verts, faces)
    if angle < config.min_angle_deg:
        out.append(f"smallest angle {angle:.2f} deg")
    return out


def remesh_shape(verts: np.ndarray, faces: np.ndarray, name: str, config: BuildConfig) -> Remesh:
    """Remesh one pose with ACVD, retrying seeds until :func:`remesh_problems` finds nothing.

    The faces are then oriented consistently, outward when the source is (signed volume > 0).

    Raises:
        RuntimeError: no seed of ``config.max_tries`` gave a usable mesh.
    """
    closed = bool(mesh_report(verts, faces)["is_closed"])
    outward = orientation_report(verts, faces)["outward"]
    base = config.seed + zlib.crc32(name.encode())
    rejected, fallback = [], None

    def oriented(v, f):  # faces oriented like the source, or None where that fails
        f = orient_faces(v, f, outward=outward)
        orient = orientation_report(v, f)
        return None if orient["n_misoriented_edges"] or orient["outward"] != outward else f

    for i in range(config.max_tries):
        seed = base + i
        v, f = remesh_acvd(verts, faces, n_verts=config.n_verts, subdivide=config.subdivide, seed=seed)
        problems = remesh_problems(v, f, config, closed)
        if not problems:
            fo = oriented(v, f)
            if fo is not None:
                return Remesh(v, fo, seed, i + 1, tuple(rejected), None)
            problems = ["misoriented edges after orienting"]
        if fallback is None and config.repair and any(w in p for p in problems for w in _TOPOLOGY):
            # a repaired mesh has one coarse fan per hole: keep it only in case no seed gives a clean one.
            # New vertices go onto the source surface, where ACVD puts its own.
            v2, f2 = fill_nonmanifold(v, f, project=lambda p: closest_points(verts, faces, p).points)
            if not remesh_problems(v2, f2, config, closed):
                f2 = oriented(v2, f2)
                if f2 is not None:
                    note = (f"seed {seed}: {', '.join(problems)}: cut out and filled "
                            f"({len(v)} -> {len(v2)} vertices)")
                    fallback = (v2, f2, seed, note)
        rejected.append(f"seed {seed}: " + ", ".join(problems))
    if fallback is not None:
        v, f, seed, note = fallback
        return Remesh(v, f, seed, config.max_tries, tuple(rejected), note)
    raise RuntimeError(f"{name}: no usable remesh in {config.max_tries} tries ({'; '.join(rejected)})")


_TOPOLOGY = ("non-manifold", "boundary", "pinched")
CORRES = ("same_sheet", "nearest", "projected")


def carry_correspondence(src_verts: np.ndarray, src_faces: np.ndarray, verts: np.ndarray, faces: np.ndarray,
                         method: str) -> tuple[np.ndarray, np.ndarray]:
    """Template -> remesh vertex map, and a reference map to compare it with.

    Methods: ``"nearest"``, the Euclidean nearest remeshed vertex (FAUST_r / SCAPE_r);
    ``"projected"``, the nearest corner of the remeshed face holding the closest surface point;
    ``"same_sheet"``, the Euclidean nearest vertex unless the path to it along the source is a
    detour (it lies across a gap: between the thighs, the fingers, or where a hand touches the
    body), then the geodesic nearest one
    (``symtorch.remesh.same_sheet_nearest_vertices``).

    Returns:
        (vts [V_src] 0-based by ``method``, reference [V_src] 0-based: ``same_sheet`` for
        ``nearest``, ``nearest`` otherwise).
    """
    if method not in CORRES:
        raise ValueError(f"corres must be one of {CORRES}, got {method!r}")
    near = nearest_vertices(verts, src_verts)
    if method == "projected":
        return projected_vertices(verts, faces, src_verts), near
    sheet, _ = same_sheet_nearest_vertices(src_verts, src_faces, verts)
    return (sheet, near) if method == "same_sheet" else (near, sheet)


def template_reflection(verts: np.ndarray, faces: np.ndarray, pairs: np.ndarray | None):
    """The template's dense reflection, detected on one pose, and its KLC10 rate against ``pairs``.

    Returns:
        (p2p [V] int64, rate or None, normalised error or None).
    """
    from symtorch.eval import geodesic_errors, klc_rates, normalized_error
    from symtorch.geodesics import GeodesicSolver

    result = symtorch.detect_symmetries(verts, faces, mode="reflection")
    sym = result.reflection
    if sym is None:
        return None, None, None
    p2p = sym.p2p.cpu().numpy().astype(np.int64)
    if pairs is None:
        return p2p, None, None
    solver = GeodesicSolver(verts, faces)
    err = geodesic_errors(solver, p2p, pairs)
    return p2p, float(klc_rates(err, solver.area)), normalized_error(err, solver.area)


def pair_distortion(solver, a: np.ndarray, b: np.ndarray) -> float:
    """Median over point pairs (k, l) of |d(a_k, a_l) - d(b_k, b_l)|, in the units of the mesh."""
    Da = solver.distances_from(a).cpu().numpy()[:, a]
    Db = solver.distances_from(b).cpu().numpy()[:, b]
    iu = np.triu_indices(len(a), 1)
    Da, Db = 0.5 * (Da + Da.T), 0.5 * (Db + Db.T)  # the heat method is not exactly symmetric
    return float(np.median(np.abs(Da - Db)[iu]))


def check_shape(name: str, src_verts, src_faces, verts, faces, vts, alt, sym_vts, sym, pairs,
                config: BuildConfig) -> dict:
    """The checks of one built pose (see the module docstring), as a dict of ShapeRecord fields."""
    from symtorch.eval import geodesic_errors, klc_rates
    from symtorch.geodesics import GeodesicSolver

    scale = math.sqrt(mesh_report(src_verts, src_faces)["area"])
    d = np.linalg.norm(verts[vts] - src_verts, axis=1)
    solver = GeodesicSolver(verts, faces)
    differ = vts != alt
    jump = 0.0
    if differ.any():
        src, inv = np.unique(vts[differ], return_inverse=True)
        D = solver.distances_from(src).cpu().numpy()  # [S, V]
        jump = float(D[inv, alt[differ]].max())
    out = dict(min_angle_deg=min_angle(verts, faces), corr_mean=float(d.mean() / scale),
               corr_max=float(d.max() / scale), differ=float(differ.mean()), jump_max=jump / scale,
               sym_median=None, sym_src_median=None, klc_rate=None, klc_src_rate=None)
    if sym_vts is None:
        return out
    rng = np.random.default_rng(zlib.crc32(name.encode()) + config.seed)
    k = rng.choice(len(vts), min(config.n_check, len(vts)), replace=False)
    area = mesh_report(verts, faces)["area"]
    out["sym_median"] = pair_distortion(solver, vts[k], sym_vts[k]) / math.sqrt(area)
    src_solver = GeodesicSolver(src_verts, src_faces)
    out["sym_src_median"] = pair_distortion(src_solver, k, sym[k]) / scale
    if pairs is not None:
        # the carried symmetry, scored on the remesh against the carried feature points
        remesh_pairs = np.stack([vts[pairs[:, 0]], vts[pairs[:, 1]]], axis=1)
        p2p = np.arange(len(verts))
        p2p[vts[pairs[:, 0]]] = sym_vts[pairs[:, 0]]
        out["klc_rate"] = float(klc_rates(geodesic_errors(solver, p2p, remesh_pairs), area))
        out["klc_src_rate"] = float(klc_rates(geodesic_errors(src_solver, sym, pairs), src_solver.area))
    return out


# ------------------------------------------------------------------------------------------ output

def _sha1(path: Path) -> str:
    h = hashlib.sha1()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _write_ids(path: Path, ids0: np.ndarray) -> None:
    """One 1-based id per line, atomically."""
    text = "".join(f"{int(i) + 1}\n" for i in ids0)
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def _read_ids(path: Path) -> np.ndarray:
    return np.loadtxt(path, dtype=np.int64, ndmin=1) - 1


def shape_paths(out: Path, name: str) -> tuple[Path, Path, Path]:
    """(off, vts, sym.vts) of pose ``name`` under ``out``."""
    return out / "off" / f"{name}.off", out / "corres" / f"{name}.vts", out / "corres" / f"{name}.sym.vts"


def build_shape(name: str, src_verts: np.ndarray, src_faces: np.ndarray, out: Path, config: BuildConfig,
                sym: np.ndarray | None = None, pairs: np.ndarray | None = None) -> ShapeRecord:
    """Remesh, carry and write one pose (or read it back when already built), then check it.

    Args:
        name: pose name; the files are ``off/<name>.off``, ``corres/<name>.vts`` [, ``.sym.vts``].
        src_verts: [V, 3] the pose, in the template numbering.
        src_faces: [F, 3] its triangles.
        out: dataset folder.
        config: the build knobs.
        sym: [V] template reflection (0-based), or None: no ``.sym.vts``.
        pairs: [P, 2] feature-point pairs (template ids) for the KLC10 check, or None.
    """
    off, vts_path, sym_path = shape_paths(out, name)
    off.parent.mkdir(parents=True, exist_ok=True)
    vts_path.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    done = off.exists() and vts_path.exists() and (sym is None or sym_path.exists())
    if done:
        mesh = read_mesh(off)
        verts, faces, seed, tries, rejected, repaired = mesh.verts, mesh.faces, -1, 0, (), None
        vts = _read_ids(vts_path)
        _, alt = carry_correspondence(src_verts, src_faces, verts, faces, config.corres)
    else:
        r = remesh_shape(src_verts, src_faces, name, config)
        verts, faces, seed, tries = r.verts, r.faces, r.seed, r.tries
        rejected, repaired = r.rejected, r.repaired
        vts, alt = carry_correspondence(src_verts, src_faces, verts, faces, config.corres)
    sym_vts = None if sym is None else vts[sym]
    seconds = time.perf_counter() - t0
    if not done:
        # ids first, mesh last: a pose counts as built only once its mesh exists
        _write_ids(vts_path, vts)
        if sym_vts is not None:
            _write_ids(sym_path, sym_vts)
        write_mesh(off, verts, faces)
    checks = check_shape(name, src_verts, src_faces, verts, faces, vts, alt, sym_vts, sym, pairs, config)
    return ShapeRecord(name=name, n_vertices=len(verts), n_faces=len(faces), seed=seed, tries=tries,
                       rejected=tuple(rejected), repaired=repaired, seconds=seconds, skipped=done,
                       sha1_off=_sha1(off), sha1_vts=_sha1(vts_path),
                       sha1_sym_vts=_sha1(sym_path) if sym_vts is not None else None, **checks)


def coincidence(verts: np.ndarray, a: tuple[np.ndarray, np.ndarray],
                b: tuple[np.ndarray, np.ndarray]) -> float:
    """Share of remesh b's vertices within 5 % of a mean edge of one of remesh a's, in template terms.

    Each remesh vertex is located on its source pose as barycentric coordinates over three template
    vertices (``(corners [N, 3], bary [N, 3])``); both remeshes are then placed on one pose
    (``verts``, template numbering; SCAPE poses share vertices but not all faces, hence corners
    rather than face ids). Independent remeshes share ~1 %; a remesh transferred from one pose to
    the others shares 100 %, clusters of ~2 template vertices (ACVD without subdivision) ~20 %.
    """
    from scipy.spatial import cKDTree

    pa = np.einsum("nk,nkd->nd", a[1], verts[a[0]])
    pb = np.einsum("nk,nkd->nd", b[1], verts[b[0]])
    d, _ = cKDTree(pa).query(pb)
    _, near = cKDTree(pb).query(pb, 2)
    edge = float(np.mean(np.linalg.norm(pb - pb[near[:, 1]], axis=1)))  # nearest-neighbour spacing
    return float(np.mean(d < 0.05 * edge))


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version(), "symtorch": symtorch.__version__}
    for pkg in ("pyacvd", "pyvista", "vtk", "numpy", "scipy", "potpourri3d", "torch"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    try:
        import subprocess

        out["symtorch_commit"] = subprocess.run(["git", "-C", str(_REPO), "rev-parse", "HEAD"], check=True,
                                                capture_output=True, text=True).stdout.strip()
    except Exception:
        out["symtorch_commit"] = None
    return out


def build(shapes: Iterable[tuple[str, np.ndarray, np.ndarray]], out: str | os.PathLike, config: BuildConfig,
          sym: np.ndarray | None = None, pairs: np.ndarray | None = None, sources: dict | None = None,
          notes: dict | None = None, log=None) -> list[ShapeRecord]:
    """Build the dataset folder from ``(name, verts, faces)`` poses sharing one template numbering.

    Writes ``off/``, ``corres/``, ``template_reflection.txt`` (when ``sym`` is given), and rewrites
    ``manifest.json`` after every pose (atomically) and ``README.md`` at the end. Poses that fail
    to remesh are reported and skipped; the others are still built.

    Args:
        shapes: ``(name, verts [V, 3], faces [F, 3])`` per pose, all in one vertex numbering.
        out: dataset folder (created).
        config: build knobs.
        sym: [V] template reflection, 0-based, or None (no ``.sym.vts``).
        pairs: [P, 2] template feature pairs for the KLC10 check, or None.
        sources: name -> source file (its sha1 goes into the manifest).
        notes: extra entries for the manifest (how ``sym`` was obtained, the command line).
        log: callable taking one line of progress (default: none).

    Returns:
        One :class:`ShapeRecord` per built pose, in order.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    log = log or (lambda line: None)
    previous = {}
    if (out / "manifest.json").exists():
        with open(out / "manifest.json") as fh:
            previous = {s["name"]: s for s in json.load(fh).get("shapes", [])}
    if sym is not None:
        _write_ids(out / "template_reflection.txt", sym)
    manifest = {"layout": {"off/<name>.off": "remeshed pose, 0-based faces",
                           "corres/<name>.vts": "line t: 1-based remesh vertex of template vertex t",
                           "corres/<name>.sym.vts": "line t: 1-based remesh vertex of the mirror of "
                                                    "template vertex t",
                           "template_reflection.txt": "line t: 1-based template vertex sym(t)"},
                "config": asdict(config), "versions": _versions(), "notes": notes or {},
                "failed": {}, "shapes": []}
    records = []
    prev = None  # (n template vertices, corners [N, 3], bary [N, 3]) of the previous remesh's vertices
    for name, verts, faces in shapes:
        try:
            rec = build_shape(name, verts, faces, out, config, sym=sym, pairs=pairs)
        except RuntimeError as err:
            manifest["failed"][name] = str(err)
            log(f"FAILED {err}")
            continue
        if rec.skipped and name in previous:  # keep how it was built the first time
            old = previous[name]
            rec = replace(rec, seed=old["seed"], tries=old["tries"], seconds=old["seconds"],
                          rejected=tuple(old.get("rejected", ())), repaired=old.get("repaired"))
        here = closest_points(verts, faces, read_mesh(shape_paths(out, name)[0]).verts)
        corners = faces[here.face]  # template vertex ids: the poses share them, not their faces
        if prev is not None and prev[0] == len(verts):
            rec = replace(rec, coincide_prev=coincidence(verts, prev[1:], (corners, here.bary)))
        prev = (len(verts), corners, here.bary)
        records.append(rec)
        entry = asdict(rec)
        if sources and name in sources:
            entry["source"] = str(sources[name])
            entry["source_sha1"] = _sha1(Path(sources[name]))
        entry["n_source_vertices"] = int(len(verts))
        manifest["shapes"].append(entry)
        atomic_write(out / "manifest.json", lambda tmp: Path(tmp).write_text(json.dumps(manifest, indent=1)))
        log(format_record(rec))
    manifest["summary"] = summarize(records)
    atomic_write(out / "manifest.json", lambda tmp: Path(tmp).write_text(json.dumps(manifest, indent=1)))
    atomic_write(out / "README.md", lambda tmp: Path(tmp).write_text(readme(manifest)))
    return records


# ----------------------------------------------------------------------------------------- summary

HEADER = (f"{'name':>10s} {'V':>5s} {'F':>6s} {'try':>3s} {'sec':>5s} {'minang':>6s} {'corr':>6s} "
          f"{'max':>6s} {'differ':>6s} {'jump':>6s} {'sym':>6s} {'sym_src':>7s} {'klc':>5s} {'klc_src':>7s} "
          f"{'shared':>6s}")


def _f(x, fmt: str, scale: float = 1.0) -> str:
    return "-" if x is None else format(x * scale, fmt)


def format_record(r: ShapeRecord) -> str:
    """One summary line (lengths x1e-3 of sqrt(area); ``differ`` in %)."""
    return (f"{r.name:>10s} {r.n_vertices:5d} {r.n_faces:6d} {r.tries:3d} {r.seconds:5.1f} "
            f"{r.min_angle_deg:6.1f} {_f(r.corr_mean, '6.2f', 1e3)} {_f(r.corr_max, '6.1f', 1e3)} "
            f"{_f(r.differ, '6.2f', 1e2)} {_f(r.jump_max, '6.1f', 1e3)} {_f(r.sym_median, '6.2f', 1e3)} "
            f"{_f(r.sym_src_median, '7.2f', 1e3)} {_f(r.klc_rate, '5.3f')} {_f(r.klc_src_rate, '7.3f')} "
            f"{_f(r.coincide_prev, '6.2f', 1e2)}"
            + ("  (already built)" if r.skipped else ""))


def summarize(records: list[ShapeRecord]) -> dict:
    """Means, medians and extremes of the per-pose checks."""
    if not records:
        return {}

    def col(key):
        return np.array([getattr(r, key) for r in records if getattr(r, key) is not None], dtype=float)

    out = {"n_shapes": len(records)}
    for key in ("n_vertices", "n_faces", "tries", "seconds", "min_angle_deg", "corr_mean", "corr_max",
                "differ", "jump_max", "sym_median", "sym_src_median", "klc_rate", "klc_src_rate",
                "coincide_prev"):
        c = col(key)
        if c.size:
            out[key] = {"mean": float(c.mean()), "median": float(np.median(c)), "min": float(c.min()),
                        "max": float(c.max())}
    return out


_CORRES_TEXT = {
    "nearest": "nearest (Euclidean) to",
    "projected": "nearest to the closest point on the remeshed surface of",
    "same_sheet": "nearest (Euclidean) to, unless that vertex lies across a gap (the path to it along the "
                  "source surface, edge graph, is longer than 2x the straight distance plus one source edge: "
                  "the inside of the other thigh, the next finger), then the one nearest along the source "
                  "surface to,",
}


def readme(manifest: dict) -> str:
    cfg, ver, notes = manifest["config"], manifest["versions"], manifest["notes"]
    s = manifest.get("summary", {})
    n = s.get("n_shapes", 0)

    def stat(key, scale=1e3, fmt=".2f"):
        if key not in s:
            return "-"
        d = s[key]
        return (f"mean {d['mean'] * scale:{fmt}}, median {d['median'] * scale:{fmt}}, "
                f"max {d['max'] * scale:{fmt}}")

    lines = [
        "# SCAPE_r-style remeshed SCAPE (derived data, built by a script)",
        "",
        "Derived from the SCAPE meshes of the BIM/KLC10 benchmark (Anguelov et al. 2005; Kim, Lipman &",
        "Funkhouser 2011). **Academic, non-commercial use only; do not redistribute**: the SCAPE licence",
        "applies to everything here. Rebuild it rather than copying it.",
        "",
        "## How it was built",
        "",
        f"    {notes.get('command', 'python scripts/build_scape_r.py')}",
        "",
        f"- symtorch {ver.get('symtorch')} (commit {ver.get('symtorch_commit')}), "
        "`scripts/build_scape_r.py`.",
        f"- Remesher: ACVD (Valette, Chassery & Prost 2008) via pyacvd {ver.get('pyacvd')} (pyvista "
        f"{ver.get('pyvista')}, vtk {ver.get('vtk')}), `symtorch.remesh.remesh_acvd`: the source pose's "
        f"vertices and faces shuffled by a seeded permutation (seed {cfg['seed']} + crc32(name), +1 per "
        f"retry), {cfg['subdivide']} linear subdivisions, {cfg['n_verts']} clusters, vertices moved onto "
        "the source surface, faces oriented like it; collapsed/duplicate faces and small pieces dropped.",
        "- A remesh is accepted when it is one closed, edge- and vertex-manifold piece without degenerate, "
        f"duplicated or unreferenced elements, with {cfg['n_verts']} ± {cfg['vertex_tolerance']:.0%} "
        f"vertices and no angle below {cfg['min_angle_deg']} degrees. "
        + f"Otherwise the next seed is tried (at most {cfg['max_tries']}; manifest: `rejected`). "
        + ("Where none passes, the first seed whose edges in three faces (ACVD clusters wrapped round a "
           "toe or finger) could be cut out is used, each hole closed by a fan around one new vertex on "
           "the source surface (`symtorch.remesh.fill_nonmanifold`; manifest: `repaired`; a coarse patch "
           "of a few edges). " if cfg["repair"] else "")
        + "Faces are then oriented consistently (breadth-first) and outward, as the source is.",
        "- `corres/<name>.vts`: line t (t = 1..12,500, SCAPE's template numbering) is the 1-based id of the "
        "remeshed vertex " + _CORRES_TEXT[cfg["corres"]] + " vertex t of the source pose.",
        "- `corres/<name>.sym.vts`: line t is line sym(t) of `<name>.vts`, sym = `template_reflection.txt`.",
        f"- Template reflection: {notes.get('reflection', '-')}",
        "",
        f"## Checks ({n} shapes; lengths in 1e-3 sqrt(area))",
        "",
        f"- vertices: {stat('n_vertices', 1, '.0f')}; faces: {stat('n_faces', 1, '.0f')}; "
        f"smallest angle (deg): {stat('min_angle_deg', 1, '.1f')}",
        "- carried correspondence, mean distance template vertex -> its remeshed vertex: "
        f"{stat('corr_mean')};"
        f" largest per shape: {stat('corr_max', 1e3, '.1f')}",
        "- share of template vertices whose vertex differs from the "
        f"{'same-sheet choice' if cfg['corres'] == 'nearest' else 'Euclidean nearest vertex'}"
        f" (%): {stat('differ', 1e2)}; largest geodesic distance on the remesh between the two: "
        f"{stat('jump_max', 1e3, '.1f')}",
        f"- symmetric pairs on the remesh, median |d(a_k,a_l) - d(b_k,b_l)|: {stat('sym_median')} "
        f"(the template reflection on the source poses: {stat('sym_src_median')})",
        "- KLC10 rate of the carried symmetry at the feature points, on the remesh: "
        f"{stat('klc_rate', 1, '.3f')}"
        f" (on the source poses: {stat('klc_src_rate', 1, '.3f')})",
        f"- independence: share of a remesh's vertices within 5 % of an edge of the previous pose's remesh "
        f"vertices, compared in template coordinates (%): {stat('coincide_prev', 1e2)} (independent: ~1 %; "
        "one remesh transferred to every pose: 100 %)",
        "",
        "`manifest.json` holds the per-shape numbers, the sha1 of every source and output file, and the",
        "parameters and package versions.",
    ]
    repaired = [sh["name"] for sh in manifest["shapes"] if sh.get("repaired")]
    retried = [f"{sh['name']} ({sh['tries']})" for sh in manifest["shapes"] if sh.get("tries", 1) > 1]
    lines += ["", f"Repaired ({len(repaired)}): {', '.join(repaired) or 'none'}. "
              f"Seeds tried, where more than one: {', '.join(retried) or 'none'}."]
    if manifest.get("failed"):
        lines += ["", "## Failed", ""] + [f"- {k}: {v}" for k, v in manifest["failed"].items()]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------- main

def _scape_dir(arg: str | None) -> Path:
    if arg:
        return Path(arg)
    from symtorch.paths import shared_data_dir

    root = shared_data_dir()
    if root is None:
        raise SystemExit("shared data not found: set $SYMTORCH_SHARED or pass --scape")
    return root.joinpath(*SCAPE)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--out", default=DEFAULT_OUT, help=f"dataset folder (default {DEFAULT_OUT})")
    ap.add_argument("--scape", default=None, help="SCAPE folder holding Meshes/ and Corrs/ "
                    "(default: shared/data/bim_scb_benchmark/SCAPE)")
    ap.add_argument("--limit", type=int, default=None, help="build only the first N poses")
    ap.add_argument("--names", default=None, help="comma-separated pose names (mesh000,...)")
    ap.add_argument("--n-verts", type=int, default=BuildConfig.n_verts)
    ap.add_argument("--subdivide", type=int, default=BuildConfig.subdivide)
    ap.add_argument("--seed", type=int, default=BuildConfig.seed)
    ap.add_argument("--max-tries", type=int, default=BuildConfig.max_tries)
    ap.add_argument("--corres", choices=CORRES, default=BuildConfig.corres,
                    help="same_sheet: Euclidean nearest vertex unless across a gap (default); nearest: "
                         "Euclidean nearest, as FAUST_r/SCAPE_r; projected: closest point, nearest corner")
    ap.add_argument("--n-check", type=int, default=BuildConfig.n_check)
    ap.add_argument("--min-klc", type=float, default=BuildConfig.min_klc)
    ap.add_argument("--reflection-from", default="mesh000",
                    help="pose the template reflection is detected on")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")  # the source's pinched vertex warns on every read
    out = Path(args.out).resolve()
    if out == _REPO or _REPO in out.parents:
        print(f"refusing to write derived SCAPE data inside the repository ({out})", file=sys.stderr)
        return 2
    config = BuildConfig(n_verts=args.n_verts, subdivide=args.subdivide, seed=args.seed,
                         max_tries=args.max_tries, corres=args.corres, n_check=args.n_check,
                         min_klc=args.min_klc)
    scape = _scape_dir(args.scape)
    paths = sorted((scape / "Meshes").glob("*.off"))
    if not paths:
        print(f"no meshes in {scape / 'Meshes'}", file=sys.stderr)
        return 2
    if args.names:
        keep = set(args.names.split(","))
        paths = [p for p in paths if p.stem in keep]
    paths = paths[: args.limit]

    from symtorch.eval.benchmarks import load_klc_pairs

    try:
        pairs = load_klc_pairs("SCAPE", "mesh000") if args.scape is None else None
    except FileNotFoundError:
        pairs = None
    t0 = time.perf_counter()
    ref = read_mesh(scape / "Meshes" / f"{args.reflection_from}.off")
    sym, rate, nerr = template_reflection(ref.verts, ref.faces, pairs)
    msg = (f"symtorch.detect_symmetries(mode='reflection') on {args.reflection_from}: KLC10 rate "
           f"{_f(rate, '.3f')} at the {0 if pairs is None else len(pairs)} feature rows of 1.pid/1.sym.info "
           f"(14 pairs both ways + 8 fixed points), normalised error {_f(nerr, '.1f', 1e3)}e-3")
    if sym is None or rate is None or rate < config.min_klc:
        msg += f"; below --min-klc {config.min_klc} or unchecked: no .sym.vts written"
        sym = None
    print(f"template reflection ({time.perf_counter() - t0:.1f} s): {msg}", file=sys.stderr)

    def shapes():
        for p in paths:
            m = read_mesh(p)
            yield p.stem, m.verts, m.faces

    command = "python scripts/build_scape_r.py " + " ".join(sys.argv[1:] if argv is None else argv)
    print(HEADER, flush=True)
    t0 = time.perf_counter()
    records = build(shapes(), out, config, sym=sym, pairs=pairs, sources={p.stem: p for p in paths},
                    notes={"command": command.strip(), "reflection": msg},
                    log=lambda line: print(line, flush=True))
    s = summarize(records)
    print(f"\n{len(records)} of {len(paths)} poses in {out} ({time.perf_counter() - t0:.0f} s)")
    for key, scale, unit in (("corr_mean", 1e3, "1e-3"), ("corr_max", 1e3, "1e-3"), ("differ", 1e2, "%"),
                             ("jump_max", 1e3, "1e-3"), ("sym_median", 1e3, "1e-3"),
                             ("sym_src_median", 1e3, "1e-3"), ("klc_rate", 1, ""), ("klc_src_rate", 1, ""),
                             ("coincide_prev", 1e2, "%")):
        if key in s:
            d = s[key]
            print(f"  {key:>15s} [{unit}]: mean {d['mean'] * scale:.3f}  median {d['median'] * scale:.3f}  "
                  f"min {d['min'] * scale:.3f}  max {d['max'] * scale:.3f}")
    return 0 if len(records) == len(paths) else 1


if __name__ == "__main__":
    sys.exit(main())
