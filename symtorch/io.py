"""Mesh input and output that keeps vertex order: no merging, no reordering, no silent repair.

Ground-truth symmetry maps index vertices, so a loader that merges or sorts vertices silently breaks
them. `read_mesh` parses ASCII OFF and OBJ itself (trimesh splits OBJ vertices per material and
cannot read OFF files mixing triangles and polygons) and hands every other format (PLY, STL, GLB, ...)
to `trimesh.load(..., process=False, maintain_order=True)`, after checking that a PLY or STL file
holds what its header promises (:mod:`symtorch._file_checks`). Bad input, a cut file included,
raises a one-line `ValueError` naming the file; valid but suspicious input (unreferenced or
duplicated vertices, several components, degenerate faces, non-manifold edges) logs and emits one
`MeshWarning` per problem. The one repair, faces flipped to agree with their neighbours' orientation
(the detector tells reflections from rotations by it), is announced the same way.
"""
from __future__ import annotations

import contextlib
import errno
import io
import logging
import os
import re
import secrets
import stat
import warnings
from typing import NamedTuple

import numpy as np

from ._checks import DEGENERATE_REL_AREA, check_faces, check_mesh, check_verts, face_areas
from ._file_checks import check_ply, check_stl, cut_last_line, cut_message

logger = logging.getLogger(__name__)

__all__ = ["Mesh", "MeshWarning", "WriteError", "read_mesh", "write_mesh", "mesh_report", "atomic_write"]

_WRITERS = (".off", ".obj", ".ply")
_DEGENERATE_REL_AREA = DEGENERATE_REL_AREA  # see symtorch._checks


class Mesh(NamedTuple):
    """A triangle mesh or point cloud as read from disk.

    Attributes:
        verts: [V, 3] float64 vertex positions, in file order.
        faces: [F, 3] int64 0-based triangle indices, or None for a point cloud.
        path: the file it was read from ("" when built in memory).
    """

    verts: np.ndarray
    faces: np.ndarray | None
    path: str = ""


class MeshWarning(UserWarning):
    """Valid but degenerate mesh input; silence with ``warnings.simplefilter("ignore", MeshWarning)``."""


def _warn(msg: str) -> None:
    logger.warning(msg)
    warnings.warn(msg, MeshWarning, stacklevel=3)  # point at the caller of read_mesh


# ----------------------------------------------------------------------------------------- reading

def read_mesh(path: str | os.PathLike) -> Mesh:
    """Read a triangle mesh or point cloud, keeping the vertex order of the file.

    OFF (``OFF``, ``COFF``, ``NOFF``, ``STOFF``..., extra colour/normal columns ignored, the edge count
    ignored) and OBJ (1-based or negative indices, ``v/vt/vn`` face tokens) are parsed here; other
    formats go through trimesh without processing. A file with vertices but no faces is a point cloud.
    Polygons (quads and larger) are triangulated fan-wise, ``(v0, vi, vi+1)``, with a warning; for PLY,
    trimesh triangulates them and may move triangles ahead of polygons (face order only, never vertex
    order). STL stores each triangle's corners, not shared vertices: exactly equal corners are merged
    into one vertex, in order of first appearance (STL has no vertex order to keep). Scenes (GLB,
    multi-object files) are concatenated in trimesh's geometry order, with the scene transforms applied.

    What a header promises is checked against what the file holds: OFF and PLY counts (fewer or more
    records than announced), binary PLY and STL sizes, a text file whose last data line has no
    newline (cut: its last number may be a prefix of the real one), a PLY cut inside its header.
    Faces oriented against their neighbours (across manifold edges) are flipped to agree, the
    orientation of the majority kept per connected piece, with a warning; a non-orientable piece is
    left as it is and reported.

    Args:
        path: mesh file; the format follows the extension.

    Returns:
        Mesh(verts [V, 3] float64, faces [F, 3] int64 or None, path).

    Raises:
        FileNotFoundError: no file at ``path`` (or a broken symbolic link).
        ValueError: a symbolic link loop; an empty, binary, unparsable or cut file, counts that
            disagree with the data, no vertices, NaN or inf coordinates, face indices out of range,
            or zero total area (also up to rounding: collinear vertices). The message is one line
            starting with the path.

    Warns:
        MeshWarning: (also logged) polygons triangulated, faces flipped to a consistent orientation
            (or a non-orientable piece), unreferenced vertices, duplicated vertices (identical
            coordinates), several connected components, degenerate faces, non-manifold edges.
    """
    path = os.fspath(path)
    _check_input_file(path)
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext in (".off", ".obj"):
            text = _read_text(path)
            verts, faces, polygons = (_parse_off if ext == ".off" else _parse_obj)(text)
        else:
            verts, faces, polygons = _load_trimesh(path, ext)
    except ValueError as e:
        raise ValueError(f"{path}: {_one_line(e)}") from None
    except Exception as e:  # a reader bug or odd input must not surface as a raw traceback
        raise ValueError(f"{path}: cannot read as {ext or 'mesh'} ({type(e).__name__}: "
                         f"{_one_line(e)})") from None
    if len(verts) == 0:
        raise ValueError(f"{path}: no vertices found (empty or not a {ext or 'mesh'} file?)")

    try:
        if faces is None:
            verts = check_verts(verts)
        else:
            verts, faces = check_mesh(verts, faces)  # shapes, finite coordinates, range, area > 0
    except ValueError as e:
        raise ValueError(f"{path}: {_one_line(e)}") from None

    notes = [polygons] if polygons else []
    if faces is not None:
        faces, orientation = _orient(faces, len(verts))
        notes += [orientation] if orientation else []
    report = _report(verts, faces)
    for problem in notes + _problems(report):
        _warn(f"{path}: {problem}")
    logger.debug("read %s: %d vertices, %d faces", path, len(verts), report["n_faces"])
    return Mesh(verts, faces, path)


def _check_input_file(path: str) -> None:
    """One-line errors for a path that is no readable, non-empty regular file."""
    try:
        st = os.stat(path)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise ValueError(f"{path}: symbolic link loop") from None
        if e.errno == errno.ENOENT and os.path.islink(path):
            raise FileNotFoundError(f"{path}: broken symbolic link (to {os.readlink(path)})") from None
        if e.errno == errno.ENOENT:
            raise FileNotFoundError(f"{path}: no such file") from None
        raise ValueError(f"{path}: cannot open ({e.strerror or type(e).__name__})") from None
    if not stat.S_ISREG(st.st_mode):
        raise ValueError(f"{path}: not a regular file")
    if st.st_size == 0:
        raise ValueError(f"{path}: file is empty")


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split()) or type(e).__name__


def _read_text(path: str) -> str:
    with open(path, "rb") as fh:
        data = fh.read()
    head = data[:65536]
    # NUL bytes or many control characters: binary data, not an ASCII mesh
    controls = sum(head.count(bytes([c])) for c in range(32) if c not in (9, 10, 11, 12, 13))
    if b"\x00" in head or controls > 0.01 * len(head):
        raise ValueError("binary data, not an ASCII mesh file")
    if data.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte-order mark would hide the first record
        data = data[3:]
    return data.decode("latin-1")  # never fails; mesh syntax is ASCII


def _fan(poly: list[int]) -> list[list[int]]:
    return [[poly[0], poly[i], poly[i + 1]] for i in range(1, len(poly) - 1)]


def _polygon_note(n_polygons: int, n_tris: int) -> str | None:
    if not n_polygons:
        return None
    return f"{n_polygons} polygon faces (4+ vertices) triangulated fan-wise into {n_tris} triangles"


def _parse_off(text: str) -> tuple[np.ndarray, np.ndarray | None, str | None]:
    """ASCII OFF -> (verts [V, 3], faces [F, 3] or None, note on triangulated polygons or None)."""
    lines = [s for s in (raw.split("#", 1)[0].strip() for raw in text.splitlines()) if s]
    if not lines:
        raise ValueError("no content besides comments")
    tokens = lines[0].split()
    header = re.fullmatch(r"(ST)?C?N?(4)?(n)?OFF", tokens[0])
    if header is None:
        raise ValueError(f"not an OFF file: first token is {tokens[0][:20]!r}, expected 'OFF'")
    if "BINARY" in tokens[1:]:
        raise ValueError("binary OFF is not supported; convert it to ASCII")
    if header.group(2) or header.group(3):
        raise ValueError(f"only 3D OFF is supported, got header {tokens[0]!r}")
    if len(tokens) > 1:  # counts on the header line: "OFF 12500 24998 0"
        counts, body = tokens[1:], lines[1:]
    else:
        counts, body = (lines[1].split() if len(lines) > 1 else []), lines[2:]
    try:
        n_verts, n_faces = int(counts[0]), int(counts[1])  # a third count (edges) is ignored
    except (IndexError, ValueError):
        raise ValueError(f"bad OFF count line {' '.join(counts)[:40]!r}, expected 'nV nF nE'") from None
    if n_verts < 0 or n_faces < 0:
        raise ValueError(f"negative OFF counts nV={n_verts} nF={n_faces}")
    held = len(body)
    if held < n_verts:
        raise ValueError(f"truncated: header promises {n_verts} vertices and {n_faces} faces, file "
                         f"holds {held} vertices and no faces")
    if held < n_verts + n_faces:
        raise ValueError(f"truncated: header promises {n_faces} faces, file holds {held - n_verts}")
    if held > n_verts + n_faces:
        raise ValueError(f"header promises {n_verts} vertices and {n_faces} faces but "
                         f"{held - n_verts - n_faces} more data lines follow them")
    cut = cut_last_line(text)
    if cut is not None:
        raise ValueError(cut_message(cut))

    verts = _table(body[:n_verts], np.float64)  # [V, 3+]; colour / normal columns follow xyz
    if verts is None:  # ragged columns: go line by line
        rows = [line.split() for line in body[:n_verts]]
        short = [i for i, r in enumerate(rows) if len(r) < 3]
        if short:
            raise ValueError(f"vertex {short[0]} has fewer than 3 coordinates")
        try:
            verts = np.array([[float(t) for t in r[:3]] for r in rows], dtype=np.float64)
        except ValueError:
            raise ValueError("cannot parse vertex coordinates as numbers") from None
    elif verts.shape[1] < 3:
        raise ValueError(f"vertices have {verts.shape[1]} coordinates, expected 3")
    verts = verts[:, :3].reshape(-1, 3)
    if n_faces == 0:
        return verts, None, None

    table = _table(body[n_verts:n_verts + n_faces], np.int64)  # [F, 1 + 3 + colour columns]
    if table is not None and table.shape[1] >= 4 and (table[:, 0] == 3).all():  # all triangles
        return verts, table[:, 1:4], None
    faces, n_polygons, n_tris = [], 0, 0
    for i, line in enumerate(body[n_verts:n_verts + n_faces]):
        tokens = line.split()
        try:
            n = int(tokens[0])
            r = [int(t) for t in tokens[1:n + 1]]  # colour columns may follow, as floats
        except ValueError:
            raise ValueError(f"face {i}: cannot parse {line[:40]!r} as integers") from None
        if n < 3 or len(r) < n:
            raise ValueError(f"face {i} declares {n} vertices and lists {len(tokens) - 1} numbers")
        tris = _fan(r)
        faces += tris
        if n > 3:
            n_polygons, n_tris = n_polygons + 1, n_tris + len(tris)
    return verts, np.array(faces, dtype=np.int64), _polygon_note(n_polygons, n_tris)


def _table(lines: list[str], dtype) -> np.ndarray | None:
    """Lines of numbers -> [N, C] array (C code, fast), or None when columns are ragged or unparsable."""
    if not lines:
        return np.zeros((0, 3), dtype=dtype)
    try:
        return np.loadtxt(lines, dtype=dtype, ndmin=2, comments=None)
    except ValueError:
        return None


def _parse_obj(text: str) -> tuple[np.ndarray, np.ndarray | None, str | None]:
    """ASCII OBJ -> (verts [V, 3], faces [F, 3] 0-based or None, note on triangulated polygons or None).

    Only ``v`` and ``f`` records matter; texture, normal, group, material and line records are skipped.
    """
    cut = cut_last_line(text)
    if cut is not None:
        raise ValueError(cut_message(cut))
    verts, faces, n_polygons, n_tris = [], [], 0, 0
    text = text.replace("\\\r\n", " ").replace("\\\n", " ")  # line continuations
    for lineno, raw in enumerate(text.splitlines(), 1):
        r = raw.split("#", 1)[0].split()
        if not r:
            continue
        if r[0] == "v":
            if len(r) < 4:
                raise ValueError(f"line {lineno}: vertex has fewer than 3 coordinates")
            try:
                verts.append([float(t) for t in r[1:4]])  # extra w or colour columns ignored
            except ValueError:
                raise ValueError(f"line {lineno}: cannot parse vertex {raw.strip()[:40]!r}") from None
        elif r[0] == "f":
            try:
                idx = [int(t.split("/", 1)[0]) for t in r[1:]]
            except ValueError:
                raise ValueError(f"line {lineno}: cannot parse face {raw.strip()[:40]!r}") from None
            if len(idx) < 3:
                raise ValueError(f"line {lineno}: face has {len(idx)} vertices, need at least 3")
            if 0 in idx:
                raise ValueError(f"line {lineno}: face index 0 (OBJ indices are 1-based)")
            # positive indices are 1-based; negative ones count back from the latest vertex
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            tris = _fan(idx)
            faces += tris
            if len(idx) > 3:
                n_polygons, n_tris = n_polygons + 1, n_tris + len(tris)
    v = np.array(verts, dtype=np.float64).reshape(-1, 3)
    faces = np.array(faces, dtype=np.int64) if faces else None
    return v, faces, _polygon_note(n_polygons, n_tris)


def _load_trimesh(path: str, ext: str) -> tuple[np.ndarray, np.ndarray | None, str | None]:
    import trimesh

    source, ply = path, None
    if ext in (".ply", ".stl"):  # check what the header promises before trimesh reads it
        with open(path, "rb") as fh:
            data = fh.read()
        if ext == ".ply":
            ply = check_ply(data)
        else:
            check_stl(data)
        source = dict(file_obj=io.BytesIO(data), file_type=ext[1:])
    try:
        # no force="mesh": it would turn a point cloud into an empty mesh
        kw = dict(process=False, maintain_order=True)
        loaded = trimesh.load(**source, **kw) if isinstance(source, dict) else trimesh.load(path, **kw)
    except Exception as e:  # trimesh's messages are terse ("Not a ply file!"): say who failed
        raise ValueError(f"trimesh cannot read it as {ext or 'mesh'} ({type(e).__name__}: "
                         f"{_one_line(e)})") from None
    if isinstance(loaded, trimesh.Scene):
        geoms = loaded.dump()  # scene transforms applied
        if not geoms:
            raise ValueError("no geometry found (empty or not a mesh file?)")
        kinds = {type(g).__name__ for g in geoms}
        if not all(isinstance(g, (trimesh.Trimesh, trimesh.PointCloud)) for g in geoms) or len(kinds) > 1:
            raise ValueError(f"scene mixes geometry types {sorted(kinds)}; cannot concatenate")
        if len(geoms) > 1:
            logger.info("%s: concatenating %d scene geometries", path, len(geoms))
        loaded = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
    if not isinstance(loaded, (trimesh.Trimesh, trimesh.PointCloud)):
        raise ValueError(f"unsupported geometry type {type(loaded).__name__}")
    verts = np.asarray(loaded.vertices, dtype=np.float64).reshape(-1, 3)
    faces = getattr(loaded, "faces", None)
    faces = None if faces is None or len(faces) == 0 else np.asarray(faces, dtype=np.int64)
    note = None
    if faces is not None and ext == ".stl":
        verts, faces = _merge_soup(verts, faces)
    declared = next((count for name, count, _ in ply.elements if name == "face"), None) if ply else None
    if faces is not None and declared is not None and len(faces) > declared:
        # trimesh triangulated polygons without telling how many there were
        note = (f"{declared} faces, some of them polygons (4+ vertices), triangulated fan-wise "
                f"into {len(faces)} triangles")
    return verts, faces, note


def _merge_soup(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge exactly equal vertices of a triangle soup (STL), in order of first appearance."""
    _, first, inverse = np.unique(verts + 0.0, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # unique rows by first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return verts[first[order]], rank[inverse.reshape(-1)][faces]


def _orient(faces: np.ndarray, n_verts: int) -> tuple[np.ndarray, str | None]:
    """Faces flipped so that neighbours agree on orientation, and a note saying what was done.

    Two faces sharing a manifold edge agree when they traverse it in opposite directions. Per
    connected piece the orientation flipping the fewest faces is kept; a non-orientable piece (a
    Moebius strip) is left as it is and reported.
    """
    F = len(faces)
    a = faces[:, [0, 1, 2]].reshape(-1)
    b = faces[:, [1, 2, 0]].reshape(-1)
    ok = a != b
    directed = np.sort(a[ok] * n_verts + b[ok])
    if not (directed[1:] == directed[:-1]).any():
        return faces, None  # no directed edge twice: every manifold edge is consistent
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    fid = np.repeat(np.arange(F), 3)[ok]
    lo, hi = np.minimum(a[ok], b[ok]), np.maximum(a[ok], b[ok])
    order = np.argsort(lo * n_verts + hi, kind="stable")
    key = (lo * n_verts + hi)[order]
    # manifold edges: a key that occurs exactly twice
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    counts = np.diff(np.r_[starts, key.size])
    pair = starts[counts == 2]
    f1, f2 = fid[order][pair], fid[order][pair + 1]
    forward = (a[ok] < b[ok])[order]
    same = forward[pair] == forward[pair + 1]  # same direction: one of the two must flip
    # double cover: node f (kept) and F + f (flipped); agreeing faces join kept-kept and
    # flipped-flipped, disagreeing ones kept-flipped
    r = np.r_[f1, f1 + F]
    c = np.r_[np.where(same, f2 + F, f2), np.where(same, f2, f2 + F)]
    graph = coo_matrix((np.ones(r.size), (r, c)), shape=(2 * F, 2 * F))
    _, labels = connected_components(graph, directed=False)
    keep, flip = labels[:F], labels[F:]
    twisted = keep == flip  # a piece whose faces cannot all agree
    kept_count = np.bincount(keep, minlength=labels.max() + 1)
    # per piece, keep the assignment that leaves more faces as they are (ties: the smaller label)
    better = (kept_count[keep] > kept_count[flip]) | ((kept_count[keep] == kept_count[flip])
                                                      & (keep < flip))
    flipped = ~better & ~twisted
    notes = []
    if flipped.any():
        faces = faces.copy()
        faces[flipped] = faces[flipped][:, [0, 2, 1]]
        notes.append(f"{int(flipped.sum())} of {F} faces were oriented against their neighbours; "
                     "flipped to agree (vertices and face order unchanged)")
    if twisted.any():
        notes.append(f"{int(twisted.sum())} faces lie on a non-orientable piece (a Moebius strip) "
                     "and cannot be oriented consistently; left as they are")
    return faces, "; ".join(notes) or None


def _problems(rep: dict) -> list[str]:
    """One line per valid-but-suspicious property of a `mesh_report`."""
    checks = [
        ("n_unreferenced", "vertices referenced by no face (kept; indices unchanged)"),
        ("n_duplicated_vertices", "duplicated vertices (same coordinates as an earlier vertex; not merged)"),
        ("n_degenerate_faces", "degenerate (zero-area) faces"),
        ("n_nonmanifold_edges", "non-manifold edges (shared by 3+ faces)"),
    ]
    out = [f"{rep[key]} {what}" for key, what in checks if rep.get(key)]
    if (rep.get("n_components") or 0) > 1:
        out.append(f"{rep['n_components']} connected components")
    return out


# ----------------------------------------------------------------------------------------- writing

def write_mesh(path: str | os.PathLike, verts, faces=None) -> None:
    """Write a mesh (or point cloud) to OFF, OBJ or PLY, atomically and without touching vertex order.

    OFF and OBJ are ASCII with 17 significant digits, so float64 coordinates read back bit-exactly;
    PLY is binary little-endian with ``double`` coordinates (trimesh's own exporters write float32 PLY
    and fixed-decimal text, hence these small writers). The file is written to a temporary file in the
    same folder and moved into place with `os.replace`, so readers never see a half-written mesh.

    Args:
        path: output file; ``.off``, ``.obj`` or ``.ply``.
        verts: [V, 3] vertex positions (numpy array or tensor).
        faces: [F, 3] 0-based triangle indices, or None for a point cloud.

    Raises:
        ValueError: unsupported extension, bad shapes, NaN/inf coordinates or indices out of range.
    """
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in _WRITERS:
        raise ValueError(f"{path}: cannot write {ext or 'files without extension'}; use one of {_WRITERS}")
    v = check_verts(verts)
    f = None if faces is None else check_faces(faces, v.shape[0])
    data = {".off": _off_bytes, ".obj": _obj_bytes, ".ply": _ply_bytes}[ext](v, f)
    _write_bytes(path, data)


def _savetxt(arr: np.ndarray, fmt: str, prefix: str = "") -> str:
    buf = io.StringIO()
    np.savetxt(buf, arr, fmt=fmt)
    text = buf.getvalue()
    return "".join(prefix + line + "\n" for line in text.splitlines()) if prefix else text


def _off_bytes(v: np.ndarray, f: np.ndarray | None) -> bytes:
    n_faces = 0 if f is None else len(f)
    out = f"OFF\n{len(v)} {n_faces} 0\n" + _savetxt(v, "%.17g")
    if f is not None:
        out += _savetxt(np.hstack([np.full((n_faces, 1), 3), f]), "%d")
    return out.encode("ascii")


def _obj_bytes(v: np.ndarray, f: np.ndarray | None) -> bytes:
    out = "# symtorch\n" + _savetxt(v, "%.17g", prefix="v ")
    if f is not None:
        out += _savetxt(f + 1, "%d", prefix="f ")  # OBJ is 1-based
    return out.encode("ascii")


def _ply_bytes(v: np.ndarray, f: np.ndarray | None) -> bytes:
    header = ["ply", "format binary_little_endian 1.0", "comment symtorch",
              f"element vertex {len(v)}", "property double x", "property double y", "property double z"]
    body = np.ascontiguousarray(v, dtype="<f8").tobytes()
    if f is not None:
        if f.max(initial=0) > np.iinfo(np.int32).max:
            raise ValueError(f"PLY face indices are int32, got max index {int(f.max())}")
        header += [f"element face {len(f)}", "property list uchar int vertex_indices"]
        rec = np.zeros(len(f), dtype=[("n", "u1"), ("idx", "<i4", (3,))])
        rec["n"], rec["idx"] = 3, f
        body += rec.tobytes()
    return ("\n".join(header) + "\nend_header\n").encode("ascii") + body


class WriteError(OSError):
    """A file that could not be written; the message names it and the cause, on one line."""

    def __str__(self) -> str:
        return str(self.strerror)


_KINDS = ((stat.S_ISLNK, "symbolic link"), (stat.S_ISFIFO, "FIFO"), (stat.S_ISCHR, "character device"),
          (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket"), (stat.S_ISDIR, "folder"))


def _write_error(path: str, err: OSError) -> WriteError:
    cause = err.strerror.lower() if getattr(err, "strerror", None) else _one_line(err)
    return WriteError(getattr(err, "errno", None) or 0, f"cannot write {path}: {cause}")


def atomic_write(path: str | os.PathLike, write) -> None:
    """Write a file so that no reader ever sees it half-written: the one way symtorch writes files.

    ``write(tmp)`` fills a temporary file beside ``path`` (``.<name>.<random>.tmp``, permissions from
    the umask like a plain ``open``); it is flushed to disk and moved into place with ``os.replace``.
    On any error the temporary file is removed and the error re-raised; ``path`` is untouched.
    ``path`` must be a regular file or absent: a symbolic link, FIFO or device is never replaced.

    Args:
        path: the file to write (its folder must exist).
        write: callable taking the temporary file's path, e.g. ``lambda tmp: torch.save(x, tmp)``.

    Raises:
        ValueError: ``path`` exists and is not a regular file.
        WriteError: (an ``OSError``) the file cannot be written, with the cause: ``cannot write
            result.json: read-only file system``, ``... no space left on device``.
    """
    path = os.fspath(path)
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as e:
        raise _write_error(path, e) from None
    if mode is not None and not stat.S_ISREG(mode):
        kind = next((name for test, name in _KINDS if test(mode)), "special file")
        raise ValueError(f"{path}: is a {kind}, not a regular file; refusing to replace it")
    folder = os.path.dirname(os.path.abspath(path))
    tmp = os.path.join(folder, f".{os.path.basename(path)}.{secrets.token_hex(4)}.tmp")
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    except OSError as e:
        raise _write_error(path, e) from None
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(e, OSError) and not isinstance(e, WriteError):
            raise _write_error(path, e) from None
        if isinstance(e, RuntimeError) and _disk_full(folder):  # torch.save: "unexpected pos"
            raise _write_error(path, OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))) from None
        raise


def _disk_full(folder: str) -> bool:
    try:
        return os.statvfs(folder).f_bavail == 0
    except OSError:
        return False


def _write_bytes(path: str, data: bytes) -> None:
    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)

    atomic_write(path, write)


# ------------------------------------------------------------------------------------------ report

def mesh_report(verts, faces=None) -> dict:
    """Summary statistics of a mesh, JSON-serialisable (plain int, float, bool or None).

    Args:
        verts: [V, 3] vertex positions (numpy array or tensor).
        faces: [F, 3] 0-based triangle indices, or None for a point cloud.

    Returns:
        dict with keys
        ``n_vertices``, ``n_faces``, ``n_edges`` (undirected, self-edges of collapsed faces skipped),
        ``n_components`` (connected components of the referenced vertices),
        ``is_manifold`` (edge-manifold: no edge in 3+ faces; vertex-manifoldness is not checked),
        ``n_boundary_edges`` (in 1 face), ``n_nonmanifold_edges`` (in 3+ faces), ``is_closed``
        (manifold, no boundary), ``n_unreferenced`` (vertices in no face), ``n_duplicated_vertices``
        (exactly equal coordinates as an earlier vertex), ``n_degenerate_faces`` (area below 1e-12 times
        the squared bounding-box diagonal), ``area``, ``euler_characteristic`` (V - E + F over referenced
        vertices) and ``genus`` ((2 * n_components - chi) / 2, summed over components; None unless the
        mesh is closed and that number is a whole number >= 0: an odd chi on a closed mesh points at a
        pinched, non-manifold vertex). For a point cloud, the face-based entries are None and ``area`` is 0.

    Raises:
        ValueError: bad shapes, NaN/inf coordinates or indices out of range.
    """
    v = check_verts(verts)
    f = None if faces is None else check_faces(faces, v.shape[0])
    return _report(v, f)


def _report(v: np.ndarray, f: np.ndarray | None) -> dict:
    n_verts = int(v.shape[0])
    # +0.0 turns -0.0 into 0.0, so the two compare equal as rows
    n_dup = n_verts - int(np.unique(v + 0.0, axis=0).shape[0])
    rep = dict(n_vertices=n_verts, n_faces=0, n_edges=0, n_components=None, is_manifold=None,
               is_closed=None, n_boundary_edges=None, n_nonmanifold_edges=None, n_unreferenced=None,
               n_duplicated_vertices=n_dup, n_degenerate_faces=None, area=0.0,
               euler_characteristic=None, genus=None)
    if f is None:
        return rep
    from .sampling import count_components

    span = float(np.max(np.ptp(v, axis=0)))
    unit = v / span if 0 < span < np.inf else v  # degeneracy is relative: tiny meshes too
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        areas = face_areas(unit, f)
        diag2 = float(np.sum(np.ptp(unit, axis=0) ** 2))
        area = float(face_areas(v, f).sum()) if unit is not v else float(areas.sum())
    collapsed = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    degenerate = collapsed | (areas <= _DEGENERATE_REL_AREA * diag2)

    edges = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)  # [3F, 2]
    edges = edges[edges[:, 0] != edges[:, 1]]
    keys, counts = np.unique(edges[:, 0] * n_verts + edges[:, 1], return_counts=True)
    uniq = np.stack([keys // n_verts, keys % n_verts], axis=1)  # [E, 2]

    referenced = np.zeros(n_verts, dtype=bool)
    referenced[f.ravel()] = True
    n_comp = count_components(f, n_verts)

    n_boundary, n_nonmanifold = int((counts == 1).sum()), int((counts > 2).sum())
    chi = int(referenced.sum()) - len(uniq) + len(f)
    closed = n_boundary == 0 and n_nonmanifold == 0
    twice_genus = 2 * n_comp - chi
    genus = twice_genus // 2 if closed and twice_genus >= 0 and twice_genus % 2 == 0 else None
    rep.update(n_faces=int(len(f)), n_edges=int(len(uniq)), n_components=n_comp,
               is_manifold=n_nonmanifold == 0, is_closed=closed, n_boundary_edges=n_boundary,
               n_nonmanifold_edges=n_nonmanifold, n_unreferenced=int((~referenced).sum()),
               n_degenerate_faces=int(degenerate.sum()), area=area,
               euler_characteristic=chi, genus=genus)
    return rep
