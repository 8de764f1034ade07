"""Loaders for the shared symmetry benchmarks (meshes and ground truth), see ``shared/data/README.md``.

Every loader returns **0-based vertex ids** into the mesh as read with vertex order preserved
(``symtorch.io.read_mesh``, or ``trimesh.load(..., process=False, maintain_order=True)``).
Index bases on disk (checked by geometry in the data README):

- BIM/SCB ``.pid`` and Watertight ``.vts``: 0-based vertex ids; ``.sym.info``: 0-based *feature*
  indices (lines of the ``.pid``/``.vts`` file).
- BCICP ``corres/<name>.vts`` and ``<name>.sym.vts``: **1-based** vertex ids.
- FmapLib TOSCA ``<class>.sym``: **1-based** vertex ids, one line per vertex.

The data is academic-licensed and lives outside the package; where it is absent the loaders raise
``FileNotFoundError`` naming the missing file, so tests can skip.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..paths import shared_data_dir

__all__ = ["DATASETS", "load_klc_pairs", "load_orbits", "load_dense_pairs", "load_tosca_dense_pairs", "list_benchmark",
           "load_ground_truth", "load_mesh", "watertight_class", "GroundTruth"]

#: dataset name -> (folder of meshes relative to shared/data, mesh file suffix)
DATASETS = {
    "SCAPE": ("bim_scb_benchmark/SCAPE/Meshes", ".off"),
    "TOSCA": ("bim_scb_benchmark/TOSCA/Meshes", ".off"),
    "Watertight": ("bim_scb_benchmark/Watertight/Meshes", ".off"),
    "FAUST": ("bcicp_5k/FAUST/vtx_5k", ".off"),
    "TOSCA_Isometric": ("bcicp_5k/TOSCA_Isometric/vtx_5k", ".off"),
    "TOSCA_dense": ("bim_scb_benchmark/TOSCA/Meshes", ".off"),
}
_SPARSE = ("SCAPE", "TOSCA")
_DENSE = ("FAUST", "TOSCA_Isometric")
#: classes whose dense TOSCA map is only partly an involution (data README §2): their involutive
#: entries are the ground truth
_APPROXIMATE_TOSCA = ("michael", "wolf")


class GroundTruth(NamedTuple):
    """Ground truth of one benchmark mesh.

    Attributes:
        kind: ``"pairs"`` (SCAPE, TOSCA, FAUST, TOSCA_Isometric, TOSCA_dense) or ``"orbits"``
            (Watertight).
        pairs: [P, 2] int64 vertex pairs ``(p, g*(p))`` for ``kind == "pairs"``, else None.
        orbits: list of int64 vertex-id arrays for ``kind == "orbits"``, else None.
    """

    kind: str
    pairs: np.ndarray | None
    orbits: list[np.ndarray] | None


def _root() -> Path:
    root = shared_data_dir()
    if root is None:
        raise FileNotFoundError("shared data folder not found (set $SYMTORCH_SHARED or place "
                                "shared/data beside the project)")
    return root


def _file(*parts: str) -> Path:
    path = _root().joinpath(*parts)
    if not path.exists():
        raise FileNotFoundError(f"ground-truth file not found: {path}")
    return path


def _check_dataset(dataset: str, allowed) -> None:
    if dataset not in allowed:
        raise ValueError(f"dataset must be one of {list(allowed)}, got {dataset!r}")


def _first_column(path: Path) -> np.ndarray:
    """First integer of every non-blank line (``.pid``: ``id 0 0 0``; ``.vts``: ``id x y z`` or ``id``)."""
    ids = [int(line.split()[0]) for line in path.read_text().splitlines() if line.strip()]
    return np.asarray(ids, dtype=np.int64)


def _int_groups(path: Path) -> list[list[int]]:
    """Lines of a ``.sym.info`` file that are all integers; blank and free-text lines are skipped."""
    groups = []
    for line in path.read_text().splitlines():
        tokens = line.split()
        if tokens and all(re.fullmatch(r"[+-]?\d+", t) for t in tokens):
            groups.append([int(t) for t in tokens])
    return groups


def _features_to_verts(groups: list[list[int]], feature_verts: np.ndarray, path: Path):
    n = feature_verts.shape[0]
    for g in groups:
        if max(g) >= n or min(g) < 0:
            raise ValueError(f"{path.name}: feature index {max(g)} out of range for {n} features")
    return [feature_verts[np.asarray(g, dtype=np.int64)] for g in groups]


def _class_name(mesh_name: str) -> str:
    """TOSCA class of a mesh name: ``cat0`` -> ``cat``, ``michael11`` -> ``michael``."""
    m = re.fullmatch(r"([A-Za-z_]+)\d*", Path(mesh_name).stem)
    if m is None:
        raise ValueError(f"cannot read a TOSCA class from mesh name {mesh_name!r}")
    return m.group(1)


def load_klc_pairs(dataset: str, mesh_name: str, include_fixed: bool = True) -> np.ndarray:
    """Sparse KLC10-style reflection ground truth of a SCAPE or TOSCA mesh.

    Reads the feature points (``.pid``) and the symmetric feature pairs (``.sym.info``). SCAPE has one
    file pair, ``1.pid`` / ``1.sym.info``, for all 71 meshes; TOSCA one per class (``cat.pid`` for
    ``cat0``, ``cat1``, ...).

    Protocol: a listed pair ``a b`` gives both directions ``(a, b)`` and ``(b, a)``. A fixed point
    ``a`` (on the symmetry plane) gives ``(a, a)`` and IS scored, mapping to itself, when
    ``include_fixed`` is True (the default; KLC10 leave this open, the data README asks to record it).
    SCAPE: 14 pairs + 8 fixed points -> 36 rows (28 without fixed points).

    Args:
        dataset: ``"SCAPE"`` or ``"TOSCA"``.
        mesh_name: e.g. ``"mesh000"`` or ``"cat0"`` (a path or file name also works).
        include_fixed: score fixed points as mapping to themselves.

    Returns:
        [P, 2] int64 vertex ids ``(p, g*(p))``, 0-based.
    """
    _check_dataset(dataset, _SPARSE)
    stem = "1" if dataset == "SCAPE" else _class_name(mesh_name)
    pid = _file("bim_scb_benchmark", dataset, "Corrs", f"{stem}.pid")
    info = _file("bim_scb_benchmark", dataset, "Corrs", f"{stem}.sym.info")
    groups = _features_to_verts(_int_groups(info), _first_column(pid), info)
    rows = []
    for g in groups:
        if g.size == 2:
            rows += [(g[0], g[1]), (g[1], g[0])]
        elif g.size == 1:
            if include_fixed:
                rows.append((g[0], g[0]))
        else:
            raise ValueError(f"{info.name}: expected pairs or fixed points, got a group of {g.size}")
    return np.asarray(rows, dtype=np.int64).reshape(-1, 2)


def watertight_class(mesh_id: int | str) -> int:
    """SHREC'07 Watertight class of a mesh id: ``(id - 1) // 20 + 1`` (1 Human ... 20 Fourleg)."""
    i = int(Path(str(mesh_id)).stem)
    if not 1 <= i <= 400:
        raise ValueError(f"Watertight mesh ids are 1..400, got {i}")
    return (i - 1) // 20 + 1


def load_orbits(mesh_id: int | str, include_fixed: bool = True) -> list[np.ndarray]:
    """Symmetry orbits of a SHREC'07 Watertight mesh, as vertex ids.

    Reads ``<id>.vts`` (feature points, 0-based vertex ids) and ``<class>.sym.info`` (one orbit of
    feature indices per line). Orbits of size 2 are reflection pairs, of size 1 fixed points (kept
    when ``include_fixed``), larger ones rotation orbits (octopus legs: 8, table corners: 4).

    Args:
        mesh_id: e.g. ``121`` or ``"121"``.
        include_fixed: keep the size-1 orbits.

    Returns:
        list of int64 arrays of vertex ids, one per orbit, in file order.

    Raises:
        FileNotFoundError: no ground truth (class 19, Vase, has none) or data absent.
    """
    i = int(Path(str(mesh_id)).stem)
    cls = watertight_class(i)
    vts = _file("bim_scb_benchmark", "Watertight", "Corrs", f"{i}.vts")
    info = _file("bim_scb_benchmark", "Watertight", "Corrs", f"{cls}.sym.info")
    orbits = _features_to_verts(_int_groups(info), _first_column(vts), info)
    return [o for o in orbits if include_fixed or o.size > 1]


def load_dense_pairs(dataset: str, name: str) -> np.ndarray:
    """Dense symmetric pairs of a BCICP 5k mesh (Ren et al. 2018).

    Line k of ``corres/<name>.vts`` is the vertex of reference sample k, line k of
    ``<name>.sym.vts`` the vertex of its mirror image; both are **1-based** on disk.

    Args:
        dataset: ``"FAUST"`` or ``"TOSCA_Isometric"``.
        name: e.g. ``"tr_reg_000"`` or ``"cat0"``.

    Returns:
        [5000, 2] int64 vertex ids ``(p, g*(p))``, 0-based. Vertices may repeat (several samples
        can land on one vertex of the remeshed shape).
    """
    _check_dataset(dataset, _DENSE)
    stem = Path(name).stem
    folder = ("bcicp_5k", dataset, "vtx_5k", "corres")
    a = _first_column(_file(*folder, f"{stem}.vts")) - 1
    b = _first_column(_file(*folder, f"{stem}.sym.vts")) - 1
    if a.shape != b.shape:
        raise ValueError(f"{stem}: .vts has {a.size} lines but .sym.vts has {b.size}")
    if min(a.min(), b.min()) < 0:
        raise ValueError(f"{stem}: a vertex id is 0 in a 1-based file")
    return np.stack([a, b], axis=1)


def load_tosca_dense_pairs(name: str) -> np.ndarray:
    """Dense reflection pairs of a TOSCA high-resolution mesh (FmapLib's ``<class>.sym``).

    Line ``i`` of ``tosca_dense_sym_fmaplib/<class>.sym`` holds the **1-based** vertex id of the
    mirror image of vertex ``i``; one file serves every mesh of the class. For michael and wolf,
    whose files are only partly involutive (data README §2), only the entries with
    ``sym[sym[i]] == i`` are kept.

    Returns:
        [P, 2] int64 vertex ids ``(p, g*(p))``, 0-based, ``p`` ascending.
    """
    cls = _class_name(name)
    path = _file("tosca_dense_sym_fmaplib", f"{cls}.sym")
    sym = _first_column(path) - 1
    if sym.min() < 0 or sym.max() >= sym.size:
        raise ValueError(f"{path}: vertex ids outside 1..{sym.size}")
    src = np.arange(sym.size)
    if cls in _APPROXIMATE_TOSCA:
        src = src[sym[sym] == src]
    return np.stack([src, sym[src]], axis=1)


def _natural_key(name: str):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def list_benchmark(dataset: str) -> list[tuple[str, Path]]:
    """Meshes of a benchmark, in natural order (``cat2`` before ``cat10``).

    Args:
        dataset: one of ``"SCAPE"``, ``"TOSCA"`` (bim_scb_benchmark), ``"Watertight"``,
            ``"FAUST"``, ``"TOSCA_Isometric"`` (bcicp_5k), ``"TOSCA_dense"`` (the TOSCA meshes
            with FmapLib's dense maps).

    Returns:
        list of ``(name, mesh_path)``; name is the file stem (``"mesh000"``, ``"cat0"``, ``"121"``).
        Watertight lists every mesh present, including the two vases (366, 367) that have no
        ground truth (``load_orbits`` raises for them).
    """
    _check_dataset(dataset, DATASETS)
    folder, suffix = DATASETS[dataset]
    path = _root() / folder
    if not path.is_dir():
        raise FileNotFoundError(f"benchmark folder not found: {path}")
    files = sorted(path.glob(f"*{suffix}"), key=lambda p: _natural_key(p.stem))
    return [(p.stem, p) for p in files]


def load_ground_truth(dataset: str, name: str, include_fixed: bool = True) -> GroundTruth:
    """The ground truth of one benchmark mesh, whatever its form (see :class:`GroundTruth`)."""
    _check_dataset(dataset, DATASETS)
    if dataset in _SPARSE:
        return GroundTruth("pairs", load_klc_pairs(dataset, name, include_fixed), None)
    if dataset in _DENSE:
        return GroundTruth("pairs", load_dense_pairs(dataset, name), None)
    if dataset == "TOSCA_dense":
        return GroundTruth("pairs", load_tosca_dense_pairs(name), None)
    return GroundTruth("orbits", None, load_orbits(name, include_fixed))


def load_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """Read a mesh with vertex order preserved: ``(verts [V, 3] float64, faces [F, 3] int64)``.

    Uses ``symtorch.io.read_mesh`` where it exists, else ``trimesh`` with processing off (no vertex
    merging or reordering, so ground-truth vertex ids stay valid).
    """
    try:
        from ..io import read_mesh
    except ImportError:
        read_mesh = None
    if read_mesh is not None:
        mesh = read_mesh(path)
        verts, faces = mesh.verts, mesh.faces
        if faces is None:
            raise ValueError(f"{path}: a point cloud; the benchmarks need triangle meshes")
        if hasattr(verts, "detach"):
            verts, faces = verts.detach().cpu().numpy(), faces.detach().cpu().numpy()
    else:
        import trimesh

        mesh = trimesh.load(str(path), process=False, maintain_order=True, force="mesh")
        verts, faces = mesh.vertices, mesh.faces
    return np.asarray(verts, dtype=np.float64), np.asarray(faces, dtype=np.int64)
