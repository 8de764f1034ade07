"""Datasets of meshes with a processed-once cache, and pairs of meshes with ground-truth maps."""
from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import re
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch
from torch import Tensor
from torch.utils.data import Dataset

from ..io import atomic_write, read_mesh
from ..maps import least_squares
from .layouts import MESH_SUFFIXES, class_key, corres_dir, find_layout, read_geodesic_matrix

log = logging.getLogger(__name__)

__all__ = ["MeshDataset", "PairDataset", "read_sample", "process_file", "corr_to_fmap",
           "default_cache_dir", "PAIR_MODES"]

_CACHE_FORMAT = 2  # .pt files hold {"key", "mesh", "sample"}; meta.json entries carry checksums
_GROUND_TRUTH = (None, "template", "vts")
#: The pair sets :class:`PairDataset` builds by name.
PAIR_MODES = ("all", "same_class")


def _natural_key(name: str):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def _read_ids(path: Path) -> Tensor:
    """1-based vertex ids, one per line (BCICP ``.vts``) -> 0-based long tensor."""
    ids = np.loadtxt(path, dtype=np.int64, ndmin=2)[:, 0] - 1
    if ids.size and ids.min() < 0:
        raise ValueError(f"{path}: vertex id 0 in a 1-based file")
    return torch.as_tensor(ids)


def read_sample(path: str | os.PathLike, dtype: torch.dtype = torch.float32,
                ground_truth: str | Callable[[Path], dict] | None = None) -> dict:
    """Read one mesh file into a raw sample: ``name``, ``verts [V, 3]``, ``faces [F, 3]``, ground truth.

    Args:
        path: a mesh file (read with ``symtorch.io.read_mesh``: vertex order preserved).
        dtype: of ``verts``.
        ground_truth: correspondence to the dataset's template, stored as ``corr [N]`` (the vertex of
            template point k) and, where known, ``corr_sym [N]`` (the vertex of the mirror image of
            template point k):

            - ``None``: none;
            - ``"template"``: every mesh of the folder is the same template in another pose, with the
              same vertex order (SCAPE): ``corr = arange(V)``;
            - ``"vts"``: ``corres/<name>.vts`` and, when present, ``corres/<name>.sym.vts`` (1-based
              vertex ids, one per line), with ``corres/`` inside the mesh folder (BCICP:
              ``vtx_5k/corres``) or beside it (FAUST_r / SCAPE_r: ``off/`` and ``corres/``; see
              :mod:`symtorch.data.layouts`);
            - a callable ``path -> dict`` of extra tensors, merged into the sample.

    Returns:
        the raw sample, before any transform.
    """
    path = Path(path)
    mesh = read_mesh(path)
    verts, faces = mesh.verts, mesh.faces
    sample = {"name": path.stem, "verts": torch.as_tensor(np.asarray(verts), dtype=dtype)}
    if faces is not None:
        sample["faces"] = torch.as_tensor(np.asarray(faces), dtype=torch.long)
    V = sample["verts"].shape[0]
    if ground_truth == "template":
        sample["corr"] = torch.arange(V)
    elif ground_truth == "vts":
        corres = corres_dir(path.parent)
        if corres is None:
            raise FileNotFoundError(f"ground_truth='vts' needs a corres/ folder in or beside "
                                    f"{path.parent}")
        if not (corres / f"{path.stem}.vts").exists():
            raise FileNotFoundError(f"ground_truth='vts': no {path.stem}.vts in {corres}")
        sample["corr"] = _read_ids(corres / f"{path.stem}.vts")
        if (corres / f"{path.stem}.sym.vts").exists():
            sample["corr_sym"] = _read_ids(corres / f"{path.stem}.sym.vts")
    elif callable(ground_truth):
        sample.update(ground_truth(path))
    elif ground_truth is not None:
        raise ValueError(f"ground_truth must be None, 'template', 'vts' or a callable, "
                         f"got {ground_truth!r}")
    for key in ("corr", "corr_sym"):
        if key in sample and sample[key].numel() and int(sample[key].max()) >= V:
            raise ValueError(f"{path}: {key} names vertex {int(sample[key].max())} but the mesh has "
                             f"{V} vertices")
    return sample


def default_cache_dir(root: str | os.PathLike) -> Path:
    """Where ``MeshDataset(root)`` caches by default: ``$SYMTORCH_CACHE`` (or ``~/.cache/symtorch``)
    ``/<folder name>-<hash of its absolute path>``, never inside the (often read-only, shared) data."""
    root = Path(root).resolve()
    base = Path(os.environ.get("SYMTORCH_CACHE", Path.home() / ".cache" / "symtorch"))
    return base / f"{root.name}-{hashlib.sha1(str(root).encode()).hexdigest()[:8]}"


def _version() -> str:
    from .. import __version__

    return __version__


def file_stamp(path: Path) -> list[int]:
    """``[size, mtime_ns, ctime_ns]`` of a mesh file: while it holds, the file is unchanged.

    The change time is in it because copies that keep the modification time (``cp -p``,
    ``rsync -t``, ``tar x``) cannot set it back; a stamp that changed with the same contents (a copy
    of the whole folder) costs one content hash, not a reprocessing.
    """
    st = Path(path).stat()
    return [st.st_size, st.st_mtime_ns, st.st_ctime_ns]


def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's contents."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def cache_problem(meta: dict | None, key: dict, name: str, raw: Path, out: Path, *,
                  checksum: bool = True) -> str | None:
    """Why ``out`` does not hold ``raw`` processed under ``key``, or None when it does.

    The one staleness rule of the caches: ``meta`` (the folder's ``meta.json``) has the same key and
    an entry for ``name`` whose mesh is ``raw`` (same stamp, or else same content hash: the stamp
    is then refreshed in the entry), and ``out`` has the size and, with ``checksum``, the SHA-256
    recorded there.

    Returns:
        None, or a reason: ``"not cached"``, ``"mesh changed"`` (both call for processing, not for
        a warning), or what is wrong with ``out`` (``"cache file missing"``, ``"cache file has
        1234 bytes, not 5678 (truncated or replaced)"``, ``"cache file does not match its checksum
        (damaged or replaced)"``).
    """
    if meta is None or meta.get("key") != key:
        return "not cached"
    entry = meta.get("files", {}).get(name)
    if not isinstance(entry, dict) or not {"stamp", "mesh", "sha256", "bytes"} <= entry.keys():
        return "not cached"
    stamp = file_stamp(raw)
    if stamp != entry["stamp"]:
        if file_sha256(raw) != entry["mesh"]:
            return "mesh changed"
        entry["stamp"] = stamp  # same contents (a copy, a touch): the cache still holds
    try:
        size = out.stat().st_size
    except FileNotFoundError:
        return "cache file missing"
    if size != entry["bytes"]:
        return f"cache file has {size} bytes, not {entry['bytes']} (truncated or replaced)"
    if checksum and file_sha256(out) != entry["sha256"]:
        return "cache file does not match its checksum (damaged or replaced)"
    return None


def cache_is_current(meta: dict | None, key: dict, name: str, raw: Path, out: Path) -> bool:
    """Whether ``out`` holds ``raw`` processed under ``key`` (:func:`cache_problem` finds nothing)."""
    return cache_problem(meta, key, name, raw, out) is None


def cache_key(pre_transform: Callable[[dict], dict] | None, dtype: torch.dtype,
              ground_truth: str | Callable[[Path], dict] | None) -> dict:
    """What a cached sample depends on besides its mesh file (``meta.json["key"]``, and in each
    ``.pt``): the pre-transform's repr, the package version, ``dtype``, the ground truth and the
    layout of the cache files."""
    gt = ground_truth if isinstance(ground_truth, str) or ground_truth is None \
        else getattr(ground_truth, "__qualname__", repr(ground_truth))
    return {"pre_transform": repr(pre_transform), "version": _version(), "dtype": str(dtype),
            "ground_truth": gt, "format": _CACHE_FORMAT}


def read_meta(processed_dir: Path) -> dict | None:
    """``processed_dir/meta.json`` (``{"key": ..., "files": {name: entry}}``), None if absent or bad.

    An entry is ``{"stamp": file_stamp(mesh), "mesh": its SHA-256, "sha256": SHA-256 of the .pt,
    "bytes": its size}``; ``symtorch precompute --on-uncertain flag`` adds ``"uncertain"`` (bool).
    """
    try:
        meta = json.loads((Path(processed_dir) / "meta.json").read_text())
    except (OSError, ValueError):
        return None
    return meta if isinstance(meta, dict) and isinstance(meta.get("files"), dict) else None


def write_meta(processed_dir: Path, meta: dict) -> None:
    """Write ``processed_dir/meta.json`` atomically."""
    def write(tmp: str) -> None:
        Path(tmp).write_text(json.dumps(meta, indent=1))

    atomic_write(Path(processed_dir) / "meta.json", write)


def process_entry(raw: str | os.PathLike, out: str | os.PathLike,
                  pre_transform: Callable[[dict], dict] | None = None,
                  dtype: torch.dtype = torch.float32,
                  ground_truth: str | Callable[[Path], dict] | None = None) -> tuple[dict, dict]:
    """:func:`process_file`, also returning the ``meta.json`` entry of the file written.

    Returns:
        (the saved sample, its entry ``{"stamp", "mesh", "sha256", "bytes"}``).
    """
    raw, out = Path(raw), Path(out)
    stamp, mesh = file_stamp(raw), file_sha256(raw)  # before reading: a file changed meanwhile is redone
    sample = read_sample(raw, dtype, ground_truth)
    if pre_transform is not None:
        sample = pre_transform(sample)
    payload = {"key": cache_key(pre_transform, dtype, ground_truth), "mesh": mesh, "sample": sample}
    buf = io.BytesIO()
    torch.save(payload, buf)
    data = buf.getvalue()

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)

    atomic_write(out, write)
    return sample, {"stamp": stamp, "mesh": mesh, "sha256": hashlib.sha256(data).hexdigest(),
                    "bytes": len(data)}


def process_file(raw: str | os.PathLike, out: str | os.PathLike,
                 pre_transform: Callable[[dict], dict] | None = None,
                 dtype: torch.dtype = torch.float32,
                 ground_truth: str | Callable[[Path], dict] | None = None) -> dict:
    """Read one mesh, apply ``pre_transform`` and save the sample to ``out`` (atomically).

    The one code path that fills a cache: :class:`MeshDataset` and ``symtorch precompute`` both call
    it, so either can read what the other wrote. The file holds ``{"key": cache_key(...), "mesh":
    SHA-256 of the mesh file, "sample": sample}`` (:func:`load_cache_file` checks and unwraps it).

    Returns:
        the saved sample.
    """
    return process_entry(raw, out, pre_transform, dtype, ground_truth)[0]


def load_cache_file(out: Path, entry: dict, key: dict) -> dict:
    """The sample in cache file ``out``, checked against its ``meta.json`` entry and the key.

    Raises:
        ValueError: the file's size or SHA-256 is not the entry's, it cannot be loaded, or it was
            made under another key or from another mesh.
    """
    data = Path(out).read_bytes()
    if len(data) != entry.get("bytes") or hashlib.sha256(data).hexdigest() != entry.get("sha256"):
        raise ValueError(f"{out}: cache file does not match its checksum (damaged or replaced)")
    try:
        payload = torch.load(io.BytesIO(data), weights_only=True)
    except Exception as e:  # noqa: BLE001 -- checksum right but unreadable: treat as damaged
        raise ValueError(f"{out}: cache file cannot be loaded ({type(e).__name__})") from None
    if not isinstance(payload, dict) or payload.get("key") != key \
            or payload.get("mesh") != entry.get("mesh") or not isinstance(payload.get("sample"), dict):
        raise ValueError(f"{out}: cache file was made under another key or from another mesh")
    return payload["sample"]


class MeshDataset(Dataset):
    """A folder of meshes, processed once by ``pre_transform`` into a cache, then transformed per item.

    Processing reads each mesh (:func:`read_sample`), applies ``pre_transform`` and saves the sample to
    ``processed_dir/<name>.pt``; ``processed_dir/meta.json`` records the cache key,
    ``repr(pre_transform)``, the package version, ``dtype`` and ``ground_truth``, and for each mesh
    its file's stamp and content hash and the size and SHA-256 of its ``.pt`` (which holds the key
    and the mesh hash too). A later construction loads the cache; when the key differs it warns and
    processes everything again, and it reprocesses meshes whose contents changed (also behind a
    restored modification time) or that are new. Writes are atomic (temporary file +
    ``os.replace``). ``__getitem__`` loads one file (``torch.load(weights_only=True)``), checked
    against its checksum, key and mesh hash, and applies ``transform``; a file that does not verify
    (truncated, damaged, copied from another cache) is processed again with a warning.

    For the field's folder layouts (``root/off`` + ``root/corres`` + ``root/dist``, or BCICP's
    ``root/vtx_5k``) use :meth:`from_layout`, which finds the folders and the ground truth.

    Geodesic matrices (``dist_dir/<name>.mat``, ``[V, V]``) are never cached or loaded with the
    samples: each sample gets the path, ``dist_path`` (a str, ``""`` where that shape has none), and
    :meth:`geodesic_matrix` loads one when asked.

    Args:
        root: folder holding the mesh files (``.off``, ``.obj``, ``.ply``, ``.stl``).
        pre_transform: deterministic, expensive transform whose output is cached.
        transform: cheap (possibly random) transform applied on every access.
        processed_dir: cache folder; default :func:`default_cache_dir` (not inside ``root``).
        names: mesh names (file stems) to use, in this order; default all, in natural order.
        ground_truth: see :func:`read_sample`.
        dtype: floating dtype of the raw ``verts`` (spectral keys follow it).
        force_reload: process everything again even if the cache matches.
        dist_dir: folder of geodesic matrices ``<name>.mat`` (MATLAB variable ``dist``); None: none.

    Example:
        >>> ds = MeshDataset("FAUST/vtx_5k", ground_truth="vts",
        ...                  pre_transform=Compose([NormalizeArea(), ComputeSpectrum(30)]))
        >>> ds[0]["evecs"].shape
        torch.Size([4999, 30])
        >>> faust_r = MeshDataset.from_layout("FAUST_r", pre_transform=ComputeSpectrum(30))
    """

    def __init__(self, root: str | os.PathLike, pre_transform: Callable[[dict], dict] | None = None,
                 transform: Callable[[dict], dict] | None = None, *,
                 processed_dir: str | os.PathLike | None = None, names: Sequence[str] | None = None,
                 ground_truth: str | Callable[[Path], dict] | None = None,
                 dtype: torch.dtype = torch.float32, force_reload: bool = False,
                 dist_dir: str | os.PathLike | None = None):
        self.root = Path(root)
        if not self.root.is_dir():
            raise FileNotFoundError(f"mesh folder not found: {self.root}")
        if not (ground_truth in _GROUND_TRUTH or callable(ground_truth)):
            raise ValueError(f"ground_truth must be None, 'template', 'vts' or a callable, "
                             f"got {ground_truth!r}")
        self.pre_transform, self.transform = pre_transform, transform
        self.ground_truth, self.dtype = ground_truth, dtype
        self.processed_dir = Path(processed_dir) if processed_dir else default_cache_dir(self.root)
        self.dist_dir = Path(dist_dir) if dist_dir is not None else None
        files = {p.stem: p for p in self.root.iterdir() if p.suffix.lower() in MESH_SUFFIXES}
        if names is None:
            names = sorted(files, key=_natural_key)
        missing = [n for n in names if n not in files]
        if missing:
            raise FileNotFoundError(f"no mesh named {missing[:3]} in {self.root}")
        if not names:
            hint = next((f"; MeshDataset.from_layout(root) reads {self.root / sub}"
                         for sub in ("off", "vtx_5k") if (self.root / sub).is_dir()), "")
            raise FileNotFoundError(f"no {'/'.join(MESH_SUFFIXES)} files in {self.root}{hint}")
        self.names = list(names)
        self.raw_paths = [files[n] for n in self.names]
        self.process(force=force_reload)

    @classmethod
    def from_layout(cls, root: str | os.PathLike,
                    pre_transform: Callable[[dict], dict] | None = None,
                    transform: Callable[[dict], dict] | None = None, **kwargs) -> MeshDataset:
        """A dataset in one of the field's folder layouts (:func:`symtorch.data.layouts.find_layout`).

        ``root/off`` (FAUST_r, SCAPE_r, SHREC'19_r), ``root/vtx_5k`` (BCICP), or the mesh folder
        itself. Ground truth is ``"vts"`` when a ``corres/`` folder exists (else None) and the
        geodesic matrices are those of the ``dist/`` folder, unless ``kwargs`` say otherwise.

        Args:
            root: the dataset folder.
            pre_transform, transform: as for the constructor.
            **kwargs: other keywords of the constructor (``processed_dir``, ``names``, ...).
        """
        layout = find_layout(root)
        kwargs.setdefault("ground_truth", "vts" if layout.corres is not None else None)
        kwargs.setdefault("dist_dir", layout.dist)
        return cls(layout.meshes, pre_transform, transform, **kwargs)

    # ------------------------------------------------------------------------------------- cache
    @property
    def cache_key(self) -> dict:
        """What a cached sample depends on besides its mesh file."""
        return cache_key(self.pre_transform, self.dtype, self.ground_truth)

    def processed_path(self, index: int) -> Path:
        return self.processed_dir / f"{self.names[index]}.pt"

    @property
    def processed_paths(self) -> list[Path]:
        return [self.processed_path(i) for i in range(len(self.names))]

    def _read_meta(self) -> dict | None:
        return read_meta(self.processed_dir)

    def _write_meta(self, meta: dict) -> None:
        write_meta(self.processed_dir, meta)

    def process(self, force: bool = False) -> list[str]:
        """Process what the cache lacks (everything when ``force`` or the key changed).

        Returns:
            the names processed by this call.
        """
        self.processed_dir.mkdir(parents=True, exist_ok=True)
        key = self.cache_key
        meta = self._read_meta()
        if meta is not None and meta.get("key") != key and not force:
            old = meta.get("key", {})
            diff = [k for k in key if old.get(k) != key[k]]
            warnings.warn(f"cache in {self.processed_dir} was made with different {diff} "
                          f"(cached: {[old.get(k) for k in diff]}); processing again",
                          stacklevel=3)
        if force or meta is None or meta.get("key") != key:
            meta = {"key": key, "files": {}}
        before = json.dumps(meta["files"], sort_keys=True)
        todo = []
        for name, raw, out in zip(self.names, self.raw_paths, self.processed_paths):
            # sizes here; each file's checksum when get() loads it
            problem = cache_problem(meta, key, name, raw, out, checksum=False)
            if problem is None:
                continue
            if problem not in ("not cached", "mesh changed"):
                warnings.warn(f"{out}: {problem}; processing {name} again", stacklevel=3)
            todo.append((name, raw, out))
        self._key, self._meta = key, meta
        if not todo and json.dumps(meta["files"], sort_keys=True) != before:
            self._write_meta(meta)  # stamps refreshed for unchanged contents
        for i, (name, raw, out) in enumerate(todo):
            t0 = time.perf_counter()
            _, meta["files"][name] = process_entry(raw, out, self.pre_transform, self.dtype,
                                                   self.ground_truth)
            self._write_meta(meta)  # after each mesh: an interrupted run resumes where it stopped
            log.info("processed %s (%d/%d) in %.2fs", name, i + 1, len(todo),
                     time.perf_counter() - t0)
        return [t[0] for t in todo]

    # ------------------------------------------------------------------------------------- access
    def __len__(self) -> int:
        return len(self.names)

    def get(self, index: int) -> dict:
        """The cached (pre-transformed) sample, without ``transform`` (plus ``dist_path`` when the
        dataset has a ``dist_dir``)."""
        name, out = self.names[index], self.processed_path(index)
        try:  # O(1), not a list per item; checked against meta.json's checksum and the key
            sample = load_cache_file(out, self._meta["files"].get(name, {}), self._key)
        except (OSError, ValueError) as e:
            warnings.warn(f"{' '.join(str(e).split())}; processing {name} again", stacklevel=2)
            sample, self._meta["files"][name] = process_entry(
                self.raw_paths[index], out, self.pre_transform, self.dtype, self.ground_truth)
            self._write_meta(self._meta)
        if self.dist_dir is not None:
            path = self.dist_path(index)
            sample["dist_path"] = "" if path is None else str(path)
        return sample

    def dist_path(self, index: int) -> Path | None:
        """The geodesic matrix file of shape ``index``, or None."""
        if self.dist_dir is None:
            return None
        path = self.dist_dir / f"{self.names[index]}.mat"
        return path if path.exists() else None

    def geodesic_matrix(self, index: int, dtype: torch.dtype | None = None) -> Tensor:
        """The ``[V, V]`` geodesic matrix of shape ``index``, read from its file (not cached), in the
        units of the mesh file (multiply by the sample's ``scale`` after :class:`NormalizeArea`).

        Raises:
            FileNotFoundError: the shape has no geodesic matrix.
        """
        path = self.dist_path(index)
        if path is None:
            raise FileNotFoundError(f"no geodesic matrix {self.names[index]}.mat in "
                                    f"{self.dist_dir}")
        return read_geodesic_matrix(path, dtype)

    def __getitem__(self, index: int) -> dict:
        sample = self.get(index)
        return self.transform(sample) if self.transform is not None else sample

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({str(self.root)!r}, n={len(self)}, "
                f"pre_transform={self.pre_transform!r}, transform={self.transform!r})")


def _item_names(dataset) -> list[str]:
    """Shape names of a dataset's items without loading them where it can (``MeshDataset.names``,
    through ``Subset``s), else from each item's ``name``."""
    from torch.utils.data import Subset

    if isinstance(dataset, MeshDataset):
        return list(dataset.names)
    if isinstance(dataset, Subset):
        names = _item_names(dataset.dataset)
        return [names[i] for i in dataset.indices]
    return [dataset[i]["name"] for i in range(len(dataset))]


def corr_to_fmap(corr_x: Tensor, corr_y: Tensor, evecs_x: Tensor, evecs_y: Tensor,
                 mass_y: Tensor) -> Tensor:
    """Ground-truth functional map ``C_xy [K_y, K_x]`` from corresponding vertices.

    Least squares ``evecs_y[corr_y] @ C_xy ≈ evecs_x[corr_x]``, each pair weighted by
    ``mass_y[corr_y]``. When ``corr_y`` lists every vertex of y once this is exactly the pull-back
    ``evecs_y.T @ (mass_y[:, None] * evecs_x[p2p_yx])`` of :func:`symtorch.maps.p2p_to_fmap`.

    Args:
        corr_x, corr_y: [N] long, ``corr_x[k]`` on x corresponds to ``corr_y[k]`` on y (-1: skipped).
        evecs_x: [V_x, K_x]; evecs_y: [V_y, K_y]; mass_y: [V_y].
    """
    ok = (corr_x >= 0) & (corr_y >= 0)
    cx, cy = corr_x[ok], corr_y[ok]
    w = mass_y[cy].sqrt()[:, None]
    return least_squares(w * evecs_y[cy], w * evecs_x[cx])


class PairDataset(Dataset):
    """Pairs of shapes of one dataset, with their ground-truth correspondence where it has one.

    Item: ``{"x": sample_x, "y": sample_y}``, plus, when both samples carry ``corr`` (the same
    template points), ``p2p_yx [V_y]`` (for each vertex of y its image on x; -1 where the ground truth
    says nothing) and, when both carry a spectrum, ``fmap_xy [K_y, K_x]`` (:func:`corr_to_fmap`,
    pull-back convention: it sends functions on x to functions on y). Ground truth is built after each
    shape's ``transform``, so augmentations that move ``corr`` (``RandomSymmetry``) keep it valid.

    Args:
        dataset: a dataset of samples (``MeshDataset`` or a ``Subset`` of one).
        pairs: ``(i, j)`` index pairs (x = item i, y = item j), or

            - ``"all"`` (or None): all ordered pairs;
            - ``"same_class"``: the ordered pairs of shapes of one class, ``class_of(name)`` (TOSCA:
              cat with cat, ...; the default class is the name without trailing digits).
        include_self: with ``"all"`` or ``"same_class"``, also pair each shape with itself.
        class_of: the class of a shape name, for ``"same_class"``.
    """

    def __init__(self, dataset: Dataset, pairs: Sequence[tuple[int, int]] | str | None = None,
                 include_self: bool = False, class_of: Callable[[str], str] = class_key):
        self.dataset = dataset
        n = len(dataset)
        if pairs is None or isinstance(pairs, str):
            pairs = "all" if pairs is None else pairs
            if pairs not in PAIR_MODES:
                raise ValueError(f"pairs must be a list of (i, j) or one of {PAIR_MODES}, "
                                 f"got {pairs!r}")
            same = (lambda i, j: True)
            if pairs == "same_class":
                classes = [class_of(name) for name in _item_names(dataset)]
                same = (lambda i, j: classes[i] == classes[j])
            pairs = [(i, j) for i in range(n) for j in range(n)
                     if (include_self or i != j) and same(i, j)]
        self.pairs = [(int(i), int(j)) for i, j in pairs]
        bad = [p for p in self.pairs if not (0 <= p[0] < n and 0 <= p[1] < n)]
        if bad:
            raise ValueError(f"pairs index a dataset of {n} items, got {bad[:3]}")

    def __len__(self) -> int:
        return len(self.pairs)

    def __getitem__(self, index: int) -> dict:
        i, j = self.pairs[index]
        x, y = self.dataset[i], self.dataset[j]
        out = {"x": x, "y": y}
        if "corr" in x and "corr" in y:
            cx, cy = x["corr"], y["corr"]
            if cx.shape != cy.shape:
                raise ValueError(f"{x.get('name')} and {y.get('name')} have {cx.numel()} and "
                                 f"{cy.numel()} template points")
            ok = (cx >= 0) & (cy >= 0)
            p2p = torch.full((y["verts"].shape[0],), -1, dtype=torch.long)
            p2p[cy[ok]] = cx[ok]
            out["p2p_yx"] = p2p
            if "evecs" in x and "evecs" in y:
                out["fmap_xy"] = corr_to_fmap(cx, cy, x["evecs"], y["evecs"], y["mass"])
        return out

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.dataset!r}, n_pairs={len(self)})"
