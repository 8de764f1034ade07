"""Shared validation of public inputs: one-line ValueErrors that name the problem."""
from __future__ import annotations

import numpy as np
import torch

# A face is degenerate when its area is below this fraction of the squared bounding-box diagonal:
# exact zeros miss collinear float64 triangles, whose cross product rounds to ~1e-16 relative.
DEGENERATE_REL_AREA = 1e-12
# Vertices whose spread across their main direction is below this fraction of their length lie on
# a line up to float32 rounding (~6e-8 relative).
_COLLINEAR_REL = 1e-7


def to_numpy(x, dtype=None) -> np.ndarray:
    """Tensor or array-like -> numpy array (detached, on CPU)."""
    if isinstance(x, torch.Tensor):
        x = x.detach().cpu().numpy()
    x = np.asarray(x)
    return x.astype(dtype, copy=False) if dtype is not None else x


def _rows_of_three(x, name: str, shape: str, empty: str) -> np.ndarray:
    """``x`` as a numpy array of shape [N, 3] with N >= 1; ``shape`` and ``empty`` end the errors."""
    a = to_numpy(x)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must be {shape}, got {list(a.shape)}")
    if a.shape[0] == 0:
        raise ValueError(f"{name} is empty {empty}")
    return a


def check_verts(verts, name: str = "verts") -> np.ndarray:
    """Validate vertex positions: [V, 3] finite floats, V >= 1.

    Returns:
        [V, 3] float64 numpy array.
    """
    v = _rows_of_three(verts, name, "[V, 3]", "(no vertices)")
    if not np.issubdtype(v.dtype, np.number):
        raise ValueError(f"{name} must be numeric, got {v.dtype}")
    v = v.astype(np.float64, copy=False)
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise ValueError(f"{name} has {int(bad.sum())} vertices with NaN or inf coordinates "
                         f"(first at index {int(np.flatnonzero(bad)[0])})")
    return v


def check_faces(faces, n_verts: int, name: str = "faces") -> np.ndarray:
    """Validate triangle indices: [F, 3] integers in [0, n_verts), F >= 1.

    Returns:
        [F, 3] int64 numpy array.
    """
    f = _rows_of_three(faces, name, "[F, 3] (triangles)",
                       "(no triangles); pass faces=None for a point cloud")
    if not np.issubdtype(f.dtype, np.integer):
        if np.issubdtype(f.dtype, np.floating) and np.all(np.mod(f, 1) == 0):
            f = f.astype(np.int64)
        else:
            raise ValueError(f"{name} must hold integer vertex indices, got {f.dtype}")
    return check_index_range(f.astype(np.int64, copy=False), n_verts, f"{name} index", "indices")


def check_index_range(ids: np.ndarray, n_verts: int, name: str, what: str = "ids") -> np.ndarray:
    """``ids`` (int64) unchanged if every entry is a vertex id in [0, n_verts); else a ValueError
    naming ``name`` and the span of the ``what``."""
    lo, hi = int(ids.min()), int(ids.max())
    if lo < 0 or hi >= n_verts:
        raise ValueError(f"{name} out of range: {what} span [{lo}, {hi}] but there are "
                         f"{n_verts} vertices")
    return ids


def face_areas(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """[F] triangle areas."""
    e1 = verts[faces[:, 1]] - verts[faces[:, 0]]
    e2 = verts[faces[:, 2]] - verts[faces[:, 0]]
    return 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)


def check_mesh(verts, faces) -> tuple[np.ndarray, np.ndarray]:
    """Validate a triangle mesh; returns (verts [V,3] float64, faces [F,3] int64) numpy arrays.

    Areas are measured on the vertices scaled to a unit bounding box, so that coordinates as small
    as 1e-150 (whose areas underflow float64) are accepted: the spectrum rescales them exactly
    (by a power of two) before it solves.

    Raises:
        ValueError: wrong shapes, NaN/inf coordinates, indices out of range, zero total area
            (exactly, or up to rounding: every face degenerate, or the vertices on a line), an area
            that overflows float64.
    """
    v = check_verts(verts)
    f = check_faces(faces, v.shape[0])
    referenced = np.zeros(v.shape[0], dtype=bool)
    referenced[f.ravel()] = True
    used = v[referenced]
    lo, span = used.min(axis=0), float(np.max(np.ptp(used, axis=0)))
    if not np.isfinite(span):
        raise ValueError(f"mesh area overflows float64 (coordinates up to {np.abs(v).max():.3g}); "
                         "rescale the mesh")
    if span == 0.0:
        raise ValueError(f"mesh has zero total area (its {used.shape[0]} vertices coincide)")
    unit = (used - lo) / span  # [U, 3] in the unit box
    index = (np.cumsum(referenced) - 1)[f]  # faces into the referenced vertices
    areas = face_areas(unit, index)
    if not areas.any():
        raise ValueError(f"mesh has zero total area ({v.shape[0]} vertices, {f.shape[0]} faces)")
    diag2 = float(np.sum(np.ptp(unit, axis=0) ** 2))
    if areas.max() <= DEGENERATE_REL_AREA * diag2:
        raise ValueError(f"mesh has zero area up to rounding: all {f.shape[0]} faces are degenerate "
                         f"(largest {areas.max() * span ** 2:.3g} against a bounding-box diagonal of "
                         f"{np.sqrt(diag2) * span:.3g}; collinear or coincident vertices?)")
    sv = np.linalg.svd(unit - unit.mean(axis=0), compute_uv=False)
    if sv[1] <= _COLLINEAR_REL * sv[0]:
        raise ValueError(f"mesh has zero area up to rounding: its vertices lie on a line (spread "
                         f"across it {sv[1] / sv[0]:.2g} of its length)")
    with np.errstate(over="ignore", invalid="ignore"):
        area = float(areas.sum()) * span * span
    if not np.isfinite(area):
        raise ValueError(f"mesh area overflows float64 (coordinates up to {np.abs(v).max():.3g}); "
                         "rescale the mesh")
    return v, f
