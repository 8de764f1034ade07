"""Mesh input and output that keeps vertex order: no merging, no reordering, no silent repair.

Ground-truth symmetry maps index vertices, so a loader that merges or sorts vertices silently breaks
them. `read_mesh` parses ASCII OFF and OBJ itself (trimesh splits OBJ vertices per material and
cannot read OFF files mixing triangles and polygons) and hands every other format (PLY, STL, GLB, ...)
to `trimesh.load(..., process=False, maintain_order=True)`. Bad input raises a one-line `ValueError`
naming the file; valid but suspicious input (unreferenced or duplicated vertices, several components,
degenerate faces, non-manifold edges) logs and emits one `MeshWarning` per problem.
"""
from __future__ import annotations

import contextlib
import io
import logging
import os
import re
import secrets
import warnings
from typing import NamedTuple

import numpy as np

from ._checks import check_faces, check_mesh, check_verts, face_areas

logger = logging.getLogger(__name__)

__all__ = ["Mesh", "MeshWarning", "read_mesh", "write_mesh", "mesh_report"]

_WRITERS = (".off", ".obj", ".ply")
# A face is degenerate when its area is below this fraction of the squared bounding-box diagonal:
# exact zeros miss collinear float32 triangles, whose cross product rounds to ~1e-16 relative.
_DEGENERATE_REL_AREA = 1e-12


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
    order). STL stores no shared vertices, so an STL mesh reads as a triangle soup (duplicated-vertex
    warning); merge it yourself if that is what you want. Scenes (GLB, multi-object files) are
    concatenated in trimesh's geometry order, with the scene transforms applied.

    Args:
        path: mesh file; the format follows the extension.

    Returns:
        Mesh(verts [V, 3] float64, faces [F, 3] int64 or None, path).

    Raises:
        FileNotFoundError: no file at ``path``.
        ValueError: empty, binary or unparsable file, no vertices, NaN or inf coordinates, face
            indices out of range, or zero total area. The message is one line starting with the path.

    Warns:
        MeshWarning: (also logged) polygons triangulated, unreferenced vertices, duplicated vertices
            (identical coordinates), several connected components, degenerate faces, non-manifold edges.
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    if not os.path.isfile(path):
        raise ValueError(f"{path}: not a regular file")
    if os.path.getsize(path) == 0:
        raise ValueError(f"{path}: file is empty")
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext in (".off", ".obj"):
            text = _read_text(path)
            verts, faces, polygons = (_parse_off if ext == ".off" else _parse_obj)(text)
        else:
            verts, faces, polygons = _load_trimesh(path)
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

    report = _report(verts, faces)
    for problem in ([polygons] if polygons else []) + _problems(report):
        _warn(f"{path}: {problem}")
    logger.debug("read %s: %d vertices, %d faces", path, len(verts), report["n_faces"])
    return Mesh(verts, faces, path)


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
    if len(body) < n_verts + n_faces:
        raise ValueError(f"truncated: header promises {n_verts} vertices and {n_faces} faces but "
                         f"only {len(body)} data lines follow")

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


def _load_trimesh(path: str) -> tuple[np.ndarray, np.ndarray | None, str | None]:
    import trimesh

    try:
        # no force="mesh": it would turn a point cloud into an empty mesh
        loaded = trimesh.load(path, process=False, maintain_order=True)
    except Exception as e:  # trimesh's messages are terse ("Not a ply file!"): say who failed
        ext = os.path.splitext(path)[1] or "mesh"
        raise ValueError(f"trimesh cannot read it as {ext} ({type(e).__name__}: {_one_line(e)})") from None
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
    if faces is not None and path.lower().endswith(".ply"):
        declared = _ply_declared_faces(path)
        if declared is not None and len(faces) > declared:
            # trimesh triangulated polygons without telling how many there were
            note = (f"{declared} faces, some of them polygons (4+ vertices), triangulated fan-wise "
                    f"into {len(faces)} triangles")
    return verts, faces, note


def _ply_declared_faces(path: str) -> int | None:
    with open(path, "rb") as fh:
        head = fh.read(65536)
    head = head.split(b"end_header", 1)[0].decode("latin-1")
    m = re.search(r"^\s*element\s+face\s+(\d+)", head, flags=re.MULTILINE)
    return int(m.group(1)) if m else None


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


def atomic_write(path: str | os.PathLike, write) -> None:
    """Write a file so that no reader ever sees it half-written: the one way symtorch writes files.

    ``write(tmp)`` fills a temporary file beside ``path`` (``.<name>.<random>.tmp``, permissions from
    the umask like a plain ``open``); it is flushed to disk and moved into place with ``os.replace``.
    On any error the temporary file is removed and the error re-raised; ``path`` is untouched.

    Args:
        path: the file to write (its folder must exist).
        write: callable taking the temporary file's path, e.g. ``lambda tmp: torch.save(x, tmp)``.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    tmp = os.path.join(folder, f".{os.path.basename(path)}.{secrets.token_hex(4)}.tmp")
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


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

    areas = face_areas(v, f)
    diag2 = float(np.sum(np.ptp(v, axis=0) ** 2))
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
               n_degenerate_faces=int(degenerate.sum()), area=float(areas.sum()),
               euler_characteristic=chi, genus=genus)
    return rep
