"""Laplace–Beltrami spectrum: stiffness, lumped mass, generalized eigenpairs, eigenvalue bands.

Conventions (ALGORITHM §1): the mesh is scaled to unit total area before anything else, so that
eigenvalues, diffusion times and geodesic thresholds mean the same on every mesh; ``scale`` is the
factor applied to the vertices (``verts_unit = verts * scale``). ``evecs`` are mass-orthonormal:
``evecs.mT @ (mass[:, None] * evecs) = I``.
"""
from __future__ import annotations

import logging
import math
import warnings
from typing import NamedTuple

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as sla
import torch
from torch import Tensor

from ._checks import check_mesh, check_verts, to_numpy
from .sparse_solve import SPDFactor
from .threads import bounded_threads

log = logging.getLogger(__name__)


class Spectrum(NamedTuple):
    """Laplace–Beltrami eigenpairs of a unit-area shape.

    Attributes:
        evals: [K] eigenvalues, ascending (evals[0] ~ 0 for a connected mesh).
        evecs: [V, K] eigenfunctions, mass-orthonormal.
        mass: [V] lumped (diagonal) mass of the unit-area shape; sums to 1 for a mesh.
        scale: factor applied to the input vertices to reach unit area (1 / sqrt(area)).
    """

    evals: Tensor
    evecs: Tensor
    mass: Tensor
    scale: float

    def to(self, device: torch.device | str | None = None, dtype: torch.dtype | None = None) -> Spectrum:
        """The spectrum with its tensors on ``device`` / in ``dtype`` (unchanged where None)."""
        moved = [t.to(device=device, dtype=dtype) for t in (self.evals, self.evecs, self.mass)]
        if all(a is b for a, b in zip(moved, (self.evals, self.evecs, self.mass))):
            return self  # already there: the same object, as ``Tensor.to`` does
        return Spectrum(*moved, self.scale)


def laplacian_matrices(verts, faces=None, *, n_neighbors: int = 30,
                       mollify_factor: float = 1e-5) -> tuple[sp.csc_matrix, np.ndarray]:
    """Cotangent stiffness and lumped mass from ``robust_laplacian``.

    Args:
        verts: [V, 3] vertex positions (numpy or torch).
        faces: [F, 3] triangles, or None for a point cloud.
        n_neighbors: neighbourhood size of the point-cloud Laplacian.
        mollify_factor: intrinsic mollification of the robust mesh Laplacian (Sharp & Crane 2020).

    Returns:
        (W [V, V] sparse, positive semi-definite, rows sum to 0; mass [V] float64).
    """
    import robust_laplacian

    if faces is None:
        v = check_verts(verts)
        if v.shape[0] < 8:
            raise ValueError(f"point cloud needs at least 8 points, got {v.shape[0]}")
        # Coincident or collinear points have zero area; robust_laplacian would fail on them with
        # an opaque geometry-central assertion (RuntimeError), so say what is wrong instead.
        s = np.linalg.svd(v - v.mean(axis=0), compute_uv=False)
        if s[0] == 0 or s[1] <= 1e-8 * s[0]:
            raise ValueError(f"point cloud has zero area: its {v.shape[0]} points are coincident "
                             f"or collinear")
        W, M = robust_laplacian.point_cloud_laplacian(v, mollify_factor=mollify_factor,
                                                      n_neighbors=min(n_neighbors, v.shape[0] - 1))
    else:
        v, f = check_mesh(verts, faces)
        W, M = robust_laplacian.mesh_laplacian(v, f, mollify_factor=mollify_factor)
    mass = np.asarray(M.diagonal(), dtype=np.float64)
    return sp.csc_matrix(W, dtype=np.float64), mass


@bounded_threads
def generalized_eigsh(W: sp.spmatrix, mass: np.ndarray, k: int, *, shift: float = -1e-3,
                      tol: float = 1e-8, retries: int = 3, check_missing: bool | None = None,
                      solver: str = "cholmod") -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` smallest pairs of ``W phi = lambda M phi`` by shift-invert Lanczos.

    One sparse factorisation of ``W - shift * M`` (``shift < 0`` keeps it positive definite, since W
    is only semi-definite): CHOLMOD's Cholesky (``solver="cholmod"``, :class:`~symtorch.sparse_solve.SPDFactor`;
    SuperLU where cholespy is missing or refuses the matrix) or SuperLU (``"superlu"``). On failure
    the shift is made ten times larger and the solve retried. Runs in float64 on CPU, inside
    :func:`symtorch.threads.limit_threads` (BLAS threads: the free cores, or the number set).

    Exactly repeated eigenvalues (a mesh with exact symmetry) defeat single-vector Lanczos: its Krylov
    space holds one direction per eigenspace, so ARPACK can return 3 of a 5-fold eigenvalue and fill
    up with larger ones. After the solve, a deflated probe (:func:`_missing_pairs`, reusing the
    factorisation) looks for eigenpairs below the largest one found that the basis lacks, and adds
    them until there are none. ``check_missing=None`` runs that probe only when the solve returned an
    exactly repeated eigenvalue (relative gap < 1e-6): every miss seen on 50 code-built symmetric
    meshes came with several such repeats among the pairs found, while scanned meshes (SCAPE, TOSCA,
    FAUST, TOSCA_Isometric: smallest relative gap 5.7e-6 at 110 eigenpairs,
    ``scripts/verification_stats.py``) have none and would pay for nothing: 0.05-0.07 s of a
    0.40 s solve of 110 pairs at 12.5K vertices with CHOLMOD (0.2 s of 0.7 s with SuperLU).
    True / False: always / never.

    The Lanczos basis holds ``1.5 k`` vectors (ARPACK's default is ``2 k``): at ``k = 110`` each
    restart then costs fewer back-substitutions than the larger basis saves in restarts (the
    eigenvalues agree to 1e-11; ``scripts/bench_spectrum.py``).

    Returns:
        (evals [k] ascending, evecs [V, k] mass-orthonormal) numpy float64.
    """
    V = W.shape[0]
    if not 1 <= k < V:
        raise ValueError(f"k must be in [1, V-1] = [1, {V - 1}], got {k}")
    M = sp.diags(mass).tocsc()
    rng = np.random.default_rng(0)  # deterministic start vector: same mesh, same basis
    v0 = rng.standard_normal(V)
    last_err: Exception | None = None
    for attempt in range(retries + 1):
        sigma = shift * (10.0 ** attempt)
        try:
            lu = SPDFactor(W - sigma * M, prefer=solver)
            op = sla.LinearOperator((V, V), matvec=lu.solve, dtype=np.float64)
            evals, evecs = sla.eigsh(W, k=k, M=M, sigma=sigma, which="LM", OPinv=op, tol=tol,
                                     v0=v0, ncv=min(V, k + max(k // 2, 20)))
            break
        except (RuntimeError, sla.ArpackError, sla.ArpackNoConvergence) as err:
            last_err = err
            log.warning("eigensolve failed with shift %.1e (%s); retrying", sigma, err)
    else:
        raise RuntimeError(f"generalized eigensolve failed after {retries + 1} shifts: {last_err}")
    for _ in range(k if check_missing or (check_missing is None and _has_repeats(evals)) else 0):
        # each round adds at least one missing pair, or stops
        try:
            lam, phi = _missing_pairs(lu, mass, sigma, evecs, float(evals.max()), tol, v0)
        except (RuntimeError, sla.ArpackError, sla.ArpackNoConvergence) as err:
            log.warning("check for missed repeated eigenvalues failed (%s); keeping the solve", err)
            break
        if lam.size == 0:
            break
        log.debug("deflated probe found %d eigenpairs missed by the solve", lam.size)
        evals, evecs = np.concatenate([evals, lam]), np.concatenate([evecs, phi], axis=1)
        order = np.argsort(evals)[:k]
        evals, evecs = evals[order], evecs[:, order]
    order = np.argsort(evals)
    evals, evecs = evals[order], evecs[:, order]
    # Re-normalise against the lumped mass (ARPACK returns M-orthonormal vectors up to tol) and fix a
    # deterministic sign: the entry of largest magnitude is positive.
    evecs /= np.sqrt(np.einsum("vk,v,vk->k", evecs, mass, evecs))[None, :]
    flip = np.sign(evecs[np.abs(evecs).argmax(axis=0), np.arange(k)])
    evecs *= np.where(flip == 0, 1.0, flip)[None, :]
    return np.maximum(evals, 0.0), evecs


def smallest_relative_gap(evals) -> float:
    """Smallest ``(lam[i+1] - lam[i]) / lam[i+1]`` over the sorted non-zero eigenvalues (inf for fewer
    than two): how close the spectrum comes to an exactly repeated eigenvalue."""
    evals = np.asarray(evals, dtype=np.float64)
    lam = np.sort(evals[evals > 1e-9 * max(float(np.max(evals, initial=0.0)), 1e-300)])
    return float((np.diff(lam) / lam[1:]).min()) if lam.size > 1 else math.inf


def _has_repeats(evals: np.ndarray, rel_tol: float = 1e-6) -> bool:
    """Whether two of the non-zero eigenvalues agree to ``rel_tol`` (an exact multiplicity)."""
    return smallest_relative_gap(evals) < rel_tol


def _missing_pairs(lu, mass: np.ndarray, sigma: float, evecs: np.ndarray, lam_max: float,
                   tol: float, v0: np.ndarray, n_probe: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs with eigenvalue below ``lam_max`` that are M-orthogonal to ``evecs``.

    Works on ``S = M^1/2 (W - sigma M)^-1 M^1/2`` (symmetric, eigenvalues ``1 / (lambda - sigma)``)
    with the span of ``M^1/2 evecs`` projected out: its largest eigenvalues are the smallest
    eigenvalues the basis lacks, and Lanczos always finds the dominant one.

    Returns:
        (evals [n], evecs [V, n]) with ``n <= n_probe``, possibly 0.
    """
    V, k = evecs.shape
    nev = min(n_probe, V - k - 1)
    if nev < 1:
        return np.zeros(0), np.zeros((V, 0))
    sq = np.sqrt(mass)
    # Orthonormal basis of the found span. The vectors are already orthonormal up to the solver
    # tolerance, so a Cholesky of the small Gram matrix is enough (and much cheaper than a QR).
    Y = evecs * sq[:, None]
    L = np.linalg.cholesky(Y.T @ Y)
    Y = np.ascontiguousarray(scipy.linalg.solve_triangular(L, Y.T, lower=True).T)

    def proj(y):
        return y - Y @ (Y.T @ y)

    def matvec(y):
        # Projecting the output alone keeps the Lanczos vectors in the complement: S maps the found
        # span into itself up to the solver tolerance, so the input needs no projection.
        return proj(sq * lu.solve(sq * np.ravel(y)))

    op = sla.LinearOperator((V, V), matvec=matvec, dtype=np.float64)
    # Cheap detection first: a loose tolerance is enough to see whether anything lies below lam_max
    # (a top Ritz value is a lower bound on the top eigenvalue of S, so lambda is over-estimated;
    # the 1e-3 margin covers the loose tolerance). Only then solve to ``tol``.
    # Only the top eigenvalue matters for detection (nev=1 converges in a few dozen solves).
    coarse = max(tol, 1e-4)
    mu, Z = sla.eigsh(op, k=1, which="LA", tol=coarse, v0=proj(v0))
    with np.errstate(divide="ignore"):
        lam = sigma + 1.0 / mu
    below = (mu > 0) & (lam < lam_max + 1e-3 * max(abs(lam_max), 1e-12))
    if not below.any():
        return np.zeros(0), np.zeros((V, 0))
    if coarse > tol or nev > 1:
        mu, Z = sla.eigsh(op, k=nev, which="LA", tol=tol, v0=proj(Z[:, below].sum(axis=1)))
        with np.errstate(divide="ignore"):
            lam = sigma + 1.0 / mu
    # strictly below the largest eigenvalue found (relative margin well above the solver tolerance)
    keep = (mu > 0) & (lam < lam_max - 1e-7 * max(abs(lam_max), 1e-12))
    return lam[keep], Z[:, keep] / sq[:, None]


@bounded_threads
def laplacian_spectrum(verts, faces=None, k: int = 30, *, normalize_area: bool = True,
                       dtype: torch.dtype = torch.float64,
                       device: torch.device | str | None = None) -> Spectrum:
    """Laplace–Beltrami eigenpairs of a mesh or point cloud, scaled to unit area.

    Args:
        verts: [V, 3] vertex positions, numpy or torch.
        faces: [F, 3] triangles (numpy or torch), or None for a point cloud.
        k: number of eigenpairs, the constant one included.
        normalize_area: scale to unit total area first (recommended; ``scale`` records the factor).
        dtype, device: of the returned tensors. The solve itself runs in float64 on CPU, its
            thread pools capped by :func:`symtorch.threads.limit_threads`.

    Returns:
        Spectrum(evals [k], evecs [V, k], mass [V], scale).

    Raises:
        ValueError: bad shapes, NaN coordinates, indices out of range, zero area (also up to
            rounding), k too large, coordinates far from 1 (below ~1e-18 or above ~1e18) with
            ``normalize_area=False``.
    """
    if faces is None:
        v, f = check_verts(verts), None
    else:
        v, f = check_mesh(verts, faces)
    # Cotangent stiffness is scale invariant in 2D; the mass scales with area. Coordinates far from
    # 1 (areas of 1e-150 coordinates underflow) are scaled by a power of two, which is exact.
    c = _exact_rescale(v)
    W, mass = laplacian_matrices(v * c if c != 1.0 else v, f)
    area = float(mass.sum())
    if not np.isfinite(area) or area <= 0:
        raise ValueError(f"shape has zero total area (mass sums to {area})")
    if normalize_area:
        scale = c / np.sqrt(area)
        mass = mass * (1.0 / np.sqrt(area)) ** 2
    elif c != 1.0:  # eigenvalues would scale by 1/c^2 and the shifted factorisation break down
        raise ValueError(f"coordinates too {'small' if c > 1 else 'large'} to represent areas "
                         f"(max |x| = {np.abs(v).max():.3g}) with normalize_area=False; rescale "
                         "the mesh or keep normalize_area=True")
    else:
        scale = 1.0
    evals, evecs = generalized_eigsh(W, mass, k)
    if f is not None:
        warn_if_disconnected(evals, stacklevel=3, faces=f, n_verts=v.shape[0])
    out = dict(dtype=dtype, device=device)
    return Spectrum(torch.as_tensor(evals, **out), torch.as_tensor(evecs, **out),
                    torch.as_tensor(mass, **out), float(scale))


def warn_if_disconnected(evals: np.ndarray, stacklevel: int = 2, *, faces=None,
                         n_verts: int | None = None) -> None:
    """Warn when the shape has several connected components.

    With ``faces``, the components are counted on the mesh itself; the spectrum alone (second
    eigenvalue ~0 relative to the last) also fires on one component whose parts differ in size by
    many orders of magnitude (one huge triangle on a small mesh), so it is only the fallback.
    """
    if faces is not None:
        from .sampling import count_components

        f = to_numpy(faces, np.int64)
        n = count_components(f, int(n_verts if n_verts is not None else f.max() + 1))
        if n > 1:
            warnings.warn(f"the mesh has {n} connected components; symmetries are only meaningful "
                          "per component", stacklevel=stacklevel + 1)
        return
    if evals.shape[0] > 1 and evals[1] < 1e-6 * max(evals[-1], 1e-12):
        warnings.warn("second eigenvalue is ~0: the mesh has several connected components; "
                      "symmetries are only meaningful per component", stacklevel=stacklevel + 1)


def _exact_rescale(v: np.ndarray) -> float:
    """1, or the power of two bringing the extent of ``v`` near 1 when it is far from it."""
    span = float(np.max(np.ptp(v, axis=0)))
    if not 0 < span < np.inf or 2.0 ** -60 <= span <= 2.0 ** 60:
        return 1.0
    return float(2.0 ** -round(math.log2(span)))


#: the gap, as a share of the local spacing, above which :func:`eigen_bands` starts a new band
BAND_REL_GAP = 0.3


def eigen_bands(evals, rel_gap: float = BAND_REL_GAP, window: int = 4) -> list[range]:
    """Group consecutive eigenvalues into bands of (near-)repeated eigenvalues.

    A new band starts between ``evals[i]`` and ``evals[i+1]`` when their gap is larger than
    ``rel_gap`` times the local mean spacing (the spacing averaged over ``window`` neighbours on each
    side). Exact multiplicities of a symmetric shape give gaps ~1e-8 of the spacing; the
    near-multiplicities of a real, approximately symmetric mesh give a few percent; unrelated
    eigenvalues are about one mean spacing apart (Weyl's law). The constant eigenfunction (an
    eigenvalue ~0) always forms its own band.

    Args:
        evals: [K] ascending eigenvalues (numpy or torch).
        rel_gap: threshold on gap / local mean spacing.
        window: half-width of the local spacing average.

    Returns:
        index ranges into ``evals``, in order, covering it.
    """
    lam = to_numpy(evals, np.float64).reshape(-1)
    K = lam.shape[0]
    if K == 0:
        return []
    gaps = np.diff(lam)  # [K-1]
    if np.any(gaps < -1e-9 * max(abs(lam[-1]), 1.0)):
        raise ValueError("evals must be ascending")
    bands, start = [], 0
    for i in range(K - 1):
        lo, hi = max(0, i - window), min(K - 2, i + window)
        local = gaps[lo:hi + 1].mean()
        zero_mode = lam[i] <= 1e-8 * max(lam[-1], 1e-12)
        if zero_mode or gaps[i] > rel_gap * max(local, 1e-300):
            bands.append(range(start, i + 1))
            start = i + 1
    bands.append(range(start, K))
    return bands


def bands_from_sizes(sizes) -> list[range]:
    """Consecutive index ranges of the given sizes: ``[1, 2, 1] -> [range(0, 1), range(1, 3), range(3, 4)]``."""
    bands, start = [], 0
    for n in sizes:
        bands.append(range(start, start + int(n)))
        start += int(n)
    return bands


def solved_bands(evals, rel_gap: float = BAND_REL_GAP) -> list[range]:
    """``eigen_bands(evals, rel_gap)`` without the last band, which the eigensolve may have cut (kept
    when it is the only one): the bands a symmetry matrix can be block-diagonal over."""
    bands = eigen_bands(evals, rel_gap)
    return bands[:-1] if len(bands) > 1 else bands


def full_bands(K: int) -> list[range]:
    """The structure of a full orthogonal matrix that keeps the constant: one band after it,
    ``[range(0, 1), range(1, K)]`` (the group path's maps of a near-isometry that mixes the
    eigenfunctions of different bands)."""
    return [range(1), range(1, K)]


def band_boundary(bands: list[range], target: int) -> int:
    """The end of the band whose end is closest to ``target`` (never cutting a band)."""
    ends = np.array([b.stop for b in bands])
    return int(ends[np.argmin(np.abs(ends - target))])


def band_index(bands: list[range], K: int | None = None) -> Tensor:
    """[K] long tensor: the band id of each eigenvalue (for ``K`` up to the end of the bands)."""
    K = bands[-1].stop if K is None else K
    out = torch.empty(K, dtype=torch.long)
    for i, b in enumerate(bands):
        if b.start >= K:
            break
        out[b.start:min(b.stop, K)] = i
    return out
