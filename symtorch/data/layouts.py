"""The folder layouts of the shape-matching field, found from a dataset's root.

Two layouts are read (:func:`find_layout`; :meth:`MeshDataset.from_layout
<symtorch.data.MeshDataset.from_layout>` builds a dataset from either):

- ``"field"``, the layout of the remeshed FAUST_r / SCAPE_r / SHREC'19_r folders used by ULRSSM,
  DUO-FM and AttentiveFMaps::

      root/off/<name>.off
      root/corres/<name>.vts        1-based template vertex ids, one per line
      root/corres/<name>.sym.vts    optional: the vertex of the mirror image of each template point
      root/dist/<name>.mat          optional: geodesic matrix, MATLAB variable ``dist`` [V, V]

- ``"bcicp"``, the BCICP release (Ren et al. 2018; FAUST and TOSCA_Isometric remeshed to 5k)::

      root/vtx_5k/<name>.off
      root/vtx_5k/corres/<name>.vts and <name>.sym.vts

A folder that holds the meshes itself (``"flat"``) is read too, with ``corres/`` and ``dist/`` inside
it or beside it.
"""
from __future__ import annotations

import os
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

__all__ = ["Layout", "find_layout", "corres_dir", "dist_dir", "read_geodesic_matrix", "class_key"]

#: The mesh files the datasets read (``symtorch.io.read_mesh`` formats).
MESH_SUFFIXES = (".off", ".obj", ".ply", ".stl")


class Layout(NamedTuple):
    """Where one dataset keeps its meshes and ground truth.

    Attributes:
        meshes: the folder of mesh files.
        corres: the folder of ``<name>.vts`` / ``<name>.sym.vts`` files, or None.
        dist: the folder of ``<name>.mat`` geodesic matrices, or None.
        kind: ``"field"`` (``root/off``), ``"bcicp"`` (``root/vtx_5k``) or ``"flat"``.
    """

    meshes: Path
    corres: Path | None
    dist: Path | None
    kind: str


def _sub_dir(mesh_folder: Path, name: str) -> Path | None:
    """``mesh_folder/name`` or, failing that, ``mesh_folder/../name``, if it is a folder."""
    for path in (mesh_folder / name, mesh_folder.parent / name):
        if path.is_dir():
            return path
    return None


def corres_dir(mesh_folder: str | os.PathLike) -> Path | None:
    """The ``corres`` folder of a mesh folder: inside it (BCICP) or beside it (``root/off`` layout)."""
    return _sub_dir(Path(mesh_folder), "corres")


def dist_dir(mesh_folder: str | os.PathLike) -> Path | None:
    """The ``dist`` folder of geodesic matrices of a mesh folder: inside it or beside it."""
    return _sub_dir(Path(mesh_folder), "dist")


def _has_meshes(folder: Path) -> bool:
    return folder.is_dir() and any(p.suffix.lower() in MESH_SUFFIXES for p in folder.iterdir())


def find_layout(root: str | os.PathLike) -> Layout:
    """The layout of a dataset folder (see the module docstring).

    Args:
        root: the dataset root (holding ``off/`` or ``vtx_5k/``) or the mesh folder itself.

    Returns:
        the folders found.

    Raises:
        FileNotFoundError: ``root`` is not a folder, or holds neither meshes nor a known layout.
    """
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"dataset folder not found: {root}")
    for sub, kind in (("off", "field"), ("vtx_5k", "bcicp")):
        if _has_meshes(root / sub):
            meshes = root / sub
            return Layout(meshes, corres_dir(meshes), dist_dir(meshes), kind)
    if _has_meshes(root):
        return Layout(root, corres_dir(root), dist_dir(root), "flat")
    raise FileNotFoundError(f"no meshes in {root}, {root / 'off'} or {root / 'vtx_5k'}")


def read_geodesic_matrix(path: str | os.PathLike, dtype: torch.dtype | None = None) -> Tensor:
    """A geodesic distance matrix stored as the MATLAB variable ``dist`` (``root/dist/<name>.mat``).

    Reads MATLAB v5 files with ``scipy.io.loadmat`` and v7.3 (HDF5) files with ``h5py`` when it is
    installed. Distances are in the units of the mesh file they were computed on.

    Args:
        path: the ``.mat`` file.
        dtype: of the result; None keeps the stored one (MATLAB double: float64).

    Returns:
        [V, V] distances.

    Raises:
        ValueError: the file has no ``dist`` variable, or it is not a square matrix.
    """
    import scipy.io

    path = Path(path)
    try:
        dist = scipy.io.loadmat(path, variable_names=["dist"]).get("dist")
    except NotImplementedError:  # MATLAB v7.3 is HDF5
        try:
            import h5py
        except ImportError as err:
            raise ImportError(f"{path} is a MATLAB v7.3 file: reading it needs h5py "
                              f"(pip install h5py)") from err
        with h5py.File(path, "r") as f:
            dist = np.asarray(f["dist"]).T if "dist" in f else None  # MATLAB is column-major
    if dist is None:
        raise ValueError(f"{path} has no variable 'dist'")
    dist = np.asarray(dist)
    if dist.ndim != 2 or dist.shape[0] != dist.shape[1]:
        raise ValueError(f"{path}: dist must be a square [V, V] matrix, got {list(dist.shape)}")
    out = torch.as_tensor(dist)
    return out if dtype is None else out.to(dtype)


def class_key(name: str) -> str:
    """The class of a shape named ``<class><number>``: the name without trailing digits (and without
    a separator before them): ``"cat10" -> "cat"``, ``"tr_reg_000" -> "tr_reg"``."""
    return re.sub(r"[_\-. ]*\d+$", "", name)
