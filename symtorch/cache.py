"""An on-disk cache of Laplace–Beltrami spectra, keyed by the mesh and every parameter of the solve.

The sparse eigensolve is the slowest step of the pipeline (seconds per 10K-vertex mesh), and the
benchmarks, the detector and the dataset code ask for the same spectra again and again. A cached
spectrum is one ``.npz`` file (no pickle) named by :func:`spectrum_key`: a SHA-256 of the mesh arrays
(shape, dtype and bytes of the validated float64 vertices and int64 faces) and of every parameter that
changes the result (``k``, ``normalize_area``, mesh or point cloud, the solver defaults of
:mod:`symtorch.spectrum`, the ``robust_laplacian`` version). The file also stores the full key and
the symtorch version and a SHA-256 of its arrays; a file whose stored key or version differs, whose
arrays do not match the checksum, or that cannot be read (truncated, corrupt, wrong shapes), is
recomputed and overwritten, never trusted. Writes go through a temporary
file in the cache folder and ``os.replace``, so a reader never sees a half-written file and
concurrent writers of the same key leave one complete file.
"""
from __future__ import annotations

import hashlib
import inspect
import json
import logging
import os
from pathlib import Path

import numpy as np
import torch

from ._checks import check_mesh, check_verts
from .io import atomic_write
from .spectrum import (Spectrum, generalized_eigsh, laplacian_matrices, laplacian_spectrum,
                       warn_if_disconnected)

log = logging.getLogger(__name__)

__all__ = ["cached_spectrum", "spectrum_key", "spectrum_key_dict", "default_spectrum_cache_dir"]

_FORMAT = 2  # bump when the file layout changes (2: a checksum of the arrays)


def default_spectrum_cache_dir() -> Path:
    """``$SYMTORCH_CACHE/spectra`` (default ``~/.cache/symtorch/spectra``), never inside the data."""
    base = Path(os.environ.get("SYMTORCH_CACHE", Path.home() / ".cache" / "symtorch"))
    return base / "spectra"


def _version() -> str:
    from . import __version__

    return __version__


def _defaults(fn) -> dict:
    """Keyword defaults of ``fn``: the solver settings ``laplacian_spectrum`` uses implicitly."""
    return {name: p.default for name, p in inspect.signature(fn).parameters.items()
            if p.default is not inspect.Parameter.empty and p.kind is inspect.Parameter.KEYWORD_ONLY}


def _robust_laplacian_version() -> str:
    try:
        from importlib.metadata import version

        return version("robust-laplacian")
    except Exception:  # not installed as a distribution (e.g. vendored): key on "unknown"
        return "unknown"


def _digest(a: np.ndarray) -> str:
    a = np.ascontiguousarray(a)
    h = hashlib.sha256(f"{a.dtype.str}{list(a.shape)}".encode())
    h.update(a.tobytes())
    return h.hexdigest()


def spectrum_key_dict(verts, faces=None, k: int = 30, *, normalize_area: bool = True) -> dict:
    """Everything a cached spectrum depends on, as a JSON-able dict (see :func:`spectrum_key`).

    The mesh is validated first (same ``ValueError`` as :func:`symtorch.laplacian_spectrum`) and
    hashed as float64 vertices and int64 faces, so float32 and float64 copies of one mesh share a key.
    """
    if faces is None:
        v, f = check_verts(verts), None
    else:
        v, f = check_mesh(verts, faces)
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
        raise ValueError(f"k must be an int, got {type(k).__name__}")
    return {
        "format": _FORMAT,
        "verts": _digest(v),
        "faces": None if f is None else _digest(f),
        "k": int(k),
        "normalize_area": bool(normalize_area),
        "laplacian": {key: repr(val) for key, val in _defaults(laplacian_matrices).items()},
        "eigsh": {key: repr(val) for key, val in _defaults(generalized_eigsh).items()},
        "robust_laplacian": _robust_laplacian_version(),
    }


def spectrum_key(verts, faces=None, k: int = 30, *, normalize_area: bool = True) -> str:
    """Hex SHA-256 naming the cache file of ``laplacian_spectrum(verts, faces, k, normalize_area)``.

    It covers the mesh arrays and every parameter that affects the result, but not the package
    version (stored inside the file instead, so a new version overwrites rather than accumulates)
    nor the output ``dtype``/``device`` (the file holds float64; the cast happens on load).
    """
    return _key_name(spectrum_key_dict(verts, faces, k, normalize_area=normalize_area))


def _key_name(key: dict) -> str:
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()


def _read(path: Path, key: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, float] | None:
    """The cached arrays, or None when the file is missing, unreadable or made for another key."""
    if not path.exists():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            evals, evecs, mass = z["evals"], z["evecs"], z["mass"]
            scale = float(z["scale"])
    except Exception as err:  # any unreadable file (truncated zip, bad JSON, missing array): redo
        log.warning("spectrum cache %s is unreadable (%s: %s); recomputing", path.name,
                    type(err).__name__, err)
        return None
    if meta.get("version") != _version():
        log.info("spectrum cache %s was written by symtorch %s, not %s; recomputing", path.name,
                 meta.get("version"), _version())
        return None
    if meta.get("key") != key:
        log.warning("spectrum cache %s holds another key; recomputing", path.name)
        return None
    if meta.get("sha256") != _arrays_digest(evals, evecs, mass, scale):
        log.warning("spectrum cache %s does not match its checksum (damaged); recomputing", path.name)
        return None
    K = key["k"]
    ok = (evals.shape == (K,) and evecs.ndim == 2 and evecs.shape[1] == K
          and mass.shape == (evecs.shape[0],) and np.isfinite(scale)
          and all(np.isfinite(a).all() for a in (evals, evecs, mass)))
    if not ok:
        log.warning("spectrum cache %s has inconsistent arrays; recomputing", path.name)
        return None
    return evals, evecs, mass, scale


def _arrays_digest(evals, evecs, mass, scale) -> str:
    h = hashlib.sha256()
    for a in (evals, evecs, mass, np.array(scale, dtype=np.float64)):
        h.update(_digest(np.asarray(a, dtype=np.float64)).encode())
    return h.hexdigest()


def _write(path: Path, key: dict, spec: Spectrum) -> None:
    """Atomic write: a temporary file in the same folder, then ``os.replace``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = dict(evals=spec.evals.detach().cpu().double().numpy(),
                  evecs=spec.evecs.detach().cpu().double().numpy(),
                  mass=spec.mass.detach().cpu().double().numpy(),
                  scale=np.array(spec.scale, dtype=np.float64))
    meta = {"version": _version(), "key": key, "sha256": _arrays_digest(*arrays.values())}

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, meta=np.array(json.dumps(meta)), **arrays)

    atomic_write(path, write)


def cached_spectrum(verts, faces=None, k: int = 30, *, normalize_area: bool = True,
                    dtype: torch.dtype = torch.float64, device: torch.device | str | None = None,
                    cache_dir: str | os.PathLike | None = None) -> Spectrum:
    """:func:`symtorch.laplacian_spectrum`, read from an on-disk cache when a valid entry exists.

    Args:
        verts: [V, 3] vertex positions, numpy or torch.
        faces: [F, 3] triangles, or None for a point cloud.
        k: number of eigenpairs, the constant one included.
        normalize_area: scale to unit total area first.
        dtype, device: of the returned tensors (the file holds float64; not part of the key).
        cache_dir: folder of the cache files; default :func:`default_spectrum_cache_dir`.

    Returns:
        Spectrum(evals [k], evecs [V, k], mass [V], scale), equal to what ``laplacian_spectrum``
        returns for the same arguments (bit for bit in float64: the file stores its float64 output).

    Raises:
        ValueError: as :func:`symtorch.laplacian_spectrum` (bad shapes, NaN, zero area, k too large).

    Note:
        An unwritable cache folder is not an error: the spectrum is computed and returned, with a
        logged warning.
    """
    key = spectrum_key_dict(verts, faces, k, normalize_area=normalize_area)
    path = Path(cache_dir if cache_dir is not None else default_spectrum_cache_dir()) / f"{_key_name(key)}.npz"
    hit = _read(path, key)
    out = dict(dtype=dtype, device=device)
    if hit is not None:
        evals, evecs, mass, scale = hit
        log.debug("spectrum cache hit %s", path.name)
        if faces is not None:
            warn_if_disconnected(evals, stacklevel=2, faces=faces, n_verts=evecs.shape[0])
        return Spectrum(torch.as_tensor(evals, **out), torch.as_tensor(evecs, **out),
                        torch.as_tensor(mass, **out), scale)
    spec = laplacian_spectrum(verts, faces, k, normalize_area=normalize_area)  # float64, CPU
    try:
        _write(path, key, spec)
    except OSError as err:
        log.warning("could not write spectrum cache %s (%s); continuing without it", path, err)
    return Spectrum(spec.evals.to(**out), spec.evecs.to(**out), spec.mass.to(**out), spec.scale)

