"""Datasets of meshes with a processed-once cache, and pairs of meshes with ground-truth maps."""
from __future__ import annotations

import hashlib
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

log = logging.getLogger(__name__)

__all__ = ["MeshDataset", "PairDataset", "read_sample", "process_file", "corr_to_fmap",
           "default_cache_dir"]

MESH_SUFFIXES = (".off", ".obj", ".ply")
_GROUND_TRUTH = (None, "template", "vts")


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
            - ``"vts"``: the BCICP layout (``corres/<name>.vts`` and ``corres/<name>.sym.vts`` beside the
              mesh, 1-based vertex ids, one per line; FAUST and TOSCA remeshed to 5k vertices);
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
        corres = path.parent / "corres"
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
    """``[size, mtime_ns]`` of a mesh file: a cached sample is valid while its file's stamp holds."""
    st = Path(path).stat()
    return [st.st_size, st.st_mtime_ns]


def cache_is_current(meta: dict | None, key: dict, name: str, raw: Path, out: Path) -> bool:
    """Whether ``out`` holds ``raw`` processed under ``key``: the folder's ``meta`` has the same key
    and ``raw``'s file stamp, and ``out`` exists (the one staleness rule of the caches)."""
    return (meta is not None and meta.get("key") == key and out.exists()
            and meta.get("files", {}).get(name) == file_stamp(raw))


def cache_key(pre_transform: Callable[[dict], dict] | None, dtype: torch.dtype,
              ground_truth: str | Callable[[Path], dict] | None) -> dict:
    """What a cached sample depends on besides its mesh file (``meta.json["key"]``)."""
    gt = ground_truth if isinstance(ground_truth, str) or ground_truth is None \
        else getattr(ground_truth, "__qualname__", repr(ground_truth))
    return {"pre_transform": repr(pre_transform), "version": _version(), "dtype": str(dtype),
            "ground_truth": gt}


def read_meta(processed_dir: Path) -> dict | None:
    """``processed_dir/meta.json`` (``{"key": ..., "files": {name: stamp}}``), None if absent or bad."""
    try:
        return json.loads((Path(processed_dir) / "meta.json").read_text())
    except (OSError, ValueError):
        return None


def write_meta(processed_dir: Path, meta: dict) -> None:
    """Write ``processed_dir/meta.json`` atomically."""
    def write(tmp: str) -> None:
        Path(tmp).write_text(json.dumps(meta, indent=1))

    atomic_write(Path(processed_dir) / "meta.json", write)


def process_file(raw: str | os.PathLike, out: str | os.PathLike,
                 pre_transform: Callable[[dict], dict] | None = None,
                 dtype: torch.dtype = torch.float32,
                 ground_truth: str | Callable[[Path], dict] | None = None) -> dict:
    """Read one mesh, apply ``pre_transform`` and save the sample to ``out`` (atomically).

    The one code path that fills a cache: :class:`MeshDataset` and ``symtorch precompute`` both call
    it, so either can read what the other wrote.

    Returns:
        the saved sample.
    """
    sample = read_sample(raw, dtype, ground_truth)
    if pre_transform is not None:
        sample = pre_transform(sample)
    atomic_write(Path(out), lambda tmp: torch.save(sample, tmp))
    return sample


class MeshDataset(Dataset):
    """A folder of meshes, processed once by ``pre_transform`` into a cache, then transformed per item.

    Processing reads each mesh (:func:`read_sample`), applies ``pre_transform`` and saves the sample to
    ``processed_dir/<name>.pt``; ``processed_dir/meta.json`` records the cache key,
    ``repr(pre_transform)``, the package version, ``dtype`` and ``ground_truth``, and the size and
    modification time of each mesh file. A later construction loads the cache; when the key differs
    it warns and processes everything again, and it reprocesses meshes whose file changed or that are
    new. Writes are atomic (temporary file + ``os.replace``). ``__getitem__`` loads one file
    (``torch.load(weights_only=True)``) and applies ``transform``.

    Args:
        root: folder holding the mesh files (``.off``, ``.obj``, ``.ply``).
        pre_transform: deterministic, expensive transform whose output is cached.
        transform: cheap (possibly random) transform applied on every access.
        processed_dir: cache folder; default :func:`default_cache_dir` (not inside ``root``).
        names: mesh names (file stems) to use, in this order; default all, in natural order.
        ground_truth: see :func:`read_sample`.
        dtype: floating dtype of the raw ``verts`` (spectral keys follow it).
        force_reload: process everything again even if the cache matches.

    Example:
        >>> ds = MeshDataset("FAUST/vtx_5k", ground_truth="vts",
        ...                  pre_transform=Compose([NormalizeArea(), ComputeSpectrum(30)]))
        >>> ds[0]["evecs"].shape
        torch.Size([4999, 30])
    """

    def __init__(self, root: str | os.PathLike, pre_transform: Callable[[dict], dict] | None = None,
                 transform: Callable[[dict], dict] | None = None, *,
                 processed_dir: str | os.PathLike | None = None, names: Sequence[str] | None = None,
                 ground_truth: str | Callable[[Path], dict] | None = None,
                 dtype: torch.dtype = torch.float32, force_reload: bool = False):
        self.root = Path(root)
        if not self.root.is_dir():
            raise FileNotFoundError(f"mesh folder not found: {self.root}")
        if not (ground_truth in _GROUND_TRUTH or callable(ground_truth)):
            raise ValueError(f"ground_truth must be None, 'template', 'vts' or a callable, "
                             f"got {ground_truth!r}")
        self.pre_transform, self.transform = pre_transform, transform
        self.ground_truth, self.dtype = ground_truth, dtype
        self.processed_dir = Path(processed_dir) if processed_dir else default_cache_dir(self.root)
        files = {p.stem: p for p in self.root.iterdir() if p.suffix.lower() in MESH_SUFFIXES}
        if names is None:
            names = sorted(files, key=_natural_key)
        missing = [n for n in names if n not in files]
        if missing:
            raise FileNotFoundError(f"no mesh named {missing[:3]} in {self.root}")
        if not names:
            raise FileNotFoundError(f"no {'/'.join(MESH_SUFFIXES)} files in {self.root}")
        self.names = list(names)
        self.raw_paths = [files[n] for n in self.names]
        self.process(force=force_reload)

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
        todo = []
        for name, raw, out in zip(self.names, self.raw_paths, self.processed_paths):
            if not cache_is_current(meta, key, name, raw, out):
                todo.append((name, raw, out, file_stamp(raw)))
        for i, (name, raw, out, stamp) in enumerate(todo):
            t0 = time.perf_counter()
            process_file(raw, out, self.pre_transform, self.dtype, self.ground_truth)
            meta["files"][name] = stamp
            self._write_meta(meta)  # after each mesh: an interrupted run resumes where it stopped
            log.info("processed %s (%d/%d) in %.2fs", name, i + 1, len(todo),
                     time.perf_counter() - t0)
        return [t[0] for t in todo]

    # ------------------------------------------------------------------------------------- access
    def __len__(self) -> int:
        return len(self.names)

    def get(self, index: int) -> dict:
        """The cached (pre-transformed) sample, without ``transform``."""
        return torch.load(self.processed_path(index), weights_only=True)  # O(1), not a list per item

    def __getitem__(self, index: int) -> dict:
        sample = self.get(index)
        return self.transform(sample) if self.transform is not None else sample

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({str(self.root)!r}, n={len(self)}, "
                f"pre_transform={self.pre_transform!r}, transform={self.transform!r})")


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
    return torch.linalg.lstsq(w * evecs_y[cy], w * evecs_x[cx]).solution


class PairDataset(Dataset):
    """Pairs of shapes of one dataset, with their ground-truth correspondence where it has one.

    Item: ``{"x": sample_x, "y": sample_y}``, plus, when both samples carry ``corr`` (the same
    template points), ``p2p_yx [V_y]`` (for each vertex of y its image on x; -1 where the ground truth
    says nothing) and, when both carry a spectrum, ``fmap_xy [K_y, K_x]`` (:func:`corr_to_fmap`,
    pull-back convention: it sends functions on x to functions on y). Ground truth is built after each
    shape's ``transform``, so augmentations that move ``corr`` (``RandomSymmetry``) keep it valid.

    Args:
        dataset: a dataset of samples (``MeshDataset`` or a ``Subset`` of one).
        pairs: ``(i, j)`` index pairs (x = item i, y = item j); default all ordered pairs.
        include_self: with the default pairs, also pair each shape with itself.
    """

    def __init__(self, dataset: Dataset, pairs: Sequence[tuple[int, int]] | None = None,
                 include_self: bool = False):
        self.dataset = dataset
        n = len(dataset)
        if pairs is None:
            pairs = [(i, j) for i in range(n) for j in range(n) if include_self or i != j]
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
