"""Sample transforms: composable callables in the PyTorch Geometric / torchvision style.

A transform is ``sample -> sample`` on a ``dict[str, Tensor]`` (keys: :mod:`symtorch.data`). It copies
the dict before changing it and its ``repr`` lists every argument that changes the output, because
``repr(pre_transform)`` is the key of the :class:`~symtorch.data.MeshDataset` cache. Random transforms
draw their parameters once per call from an optional ``torch.Generator``; the generator is not part of
the repr (random transforms belong in ``transform``, never in the cached ``pre_transform``).

Expensive, deterministic work goes in ``pre_transform``::

    Compose([NormalizeArea(), ComputeSpectrum(k=30), ComputeDescriptors(), DetectSymmetries()])

and cheap augmentation in ``transform``: :class:`~symtorch.data.RandomSymmetry` (in
:mod:`symtorch.data.symmetry`, with :class:`~symtorch.data.SymmetryFromCorrespondence`),
:class:`RandomEigenSigns`, :class:`RandomBandRotation`.
"""
from __future__ import annotations

import hashlib
import inspect
from collections.abc import Callable, Iterable

import torch
from torch import Tensor

from ..maps import p2p_to_fmap
from ..procrustes import block_project
from ..spectrum import band_index, eigen_bands, laplacian_spectrum

__all__ = ["VERTEX_FIELDS", "INDEX_FIELDS", "ON_UNCERTAIN", "Compose", "NormalizeArea", "ComputeSpectrum",
           "ComputeDescriptors", "DetectSymmetries", "SetSymmetries", "RandomEigenSigns",
           "RandomBandRotation", "change_basis", "symmetry_fmaps", "bands_from_index"]

#: Keys whose rows are per-vertex values (dim 0 is V).
VERTEX_FIELDS = ("verts", "normals", "mass", "evecs", "hks", "wks", "desc", "labels")
#: Keys naming points by vertex id of the same shape (ground truth; -1: none). ``faces`` and
#: ``sym_p2p`` hold vertex ids too but are structure, handled on their own.
INDEX_FIELDS = ("corr", "corr_sym")


def _require(sample: dict, keys: Iterable[str], who: str, hint: str) -> None:
    missing = [k for k in keys if k not in sample]
    if missing:
        raise ValueError(f"{who} needs sample keys {missing} ({hint})")


def bands_from_index(band_ids: Tensor) -> list[range]:
    """The inverse of :func:`symtorch.spectrum.band_index`: ``[K]`` band ids -> list of ranges."""
    ids = band_ids.tolist()
    bands, start = [], 0
    for i in range(1, len(ids) + 1):
        if i == len(ids) or ids[i] != ids[start]:
            bands.append(range(start, i))
            start = i
    return bands


def _sample_bands(sample: dict) -> list[range]:
    if "bands" in sample:
        return bands_from_index(sample["bands"])
    return eigen_bands(sample["evals"])


def symmetry_fmaps(sym_p2p: Tensor, evecs: Tensor, mass: Tensor,
                   bands: list[range] | None = None) -> Tensor:
    """Matrices of symmetries given as vertex maps, in one basis.

    Args:
        sym_p2p: [G, V] long, ``sym_p2p[g, i]`` the image of vertex i under element g.
        evecs: [V, K] mass-orthonormal basis.
        mass: [V] lumped mass.
        bands: eigenvalue bands of the basis; when given, each matrix is projected onto the nearest
            block-diagonal orthogonal matrix (exact symmetries are such; a nearest-neighbour map only
            approximately, and the projection keeps ``S.T`` its inverse).

    Returns:
        [G, K, K] pull-backs ``evecs.T @ (mass[:, None] * evecs[p2p])`` (ALGORITHM §2).
    """
    C = p2p_to_fmap(sym_p2p, evecs, mass)
    return C if bands is None else block_project(C, bands)


class Compose:
    """Apply transforms in order.

    Args:
        transforms: callables ``sample -> sample``.
    """

    def __init__(self, transforms: Iterable[Callable[[dict], dict]]):
        self.transforms = list(transforms)

    def __call__(self, sample: dict) -> dict:
        for t in self.transforms:
            sample = t(sample)
        return sample

    def __repr__(self) -> str:
        inner = "".join(f"\n  {t!r}," for t in self.transforms)
        return f"{type(self).__name__}([{inner}\n])" if inner else f"{type(self).__name__}([])"


class NormalizeArea:
    """Scale ``verts`` to unit total surface area (and centre them at the area-weighted centroid).

    Multiplies ``scale`` (a 0-dim float64 tensor, 1 when absent) by the factor applied, so that lengths
    on the input are ``lengths_now / scale``. Spectral keys need no change: they always describe the
    unit-area shape (ALGORITHM §1).

    Args:
        center: also translate the area-weighted centroid to the origin.
    """

    def __init__(self, center: bool = True):
        self.center = center

    def __call__(self, sample: dict) -> dict:
        _require(sample, ("verts", "faces"), type(self).__name__, "a triangle mesh")
        sample = dict(sample)
        verts, faces = sample["verts"], sample["faces"]
        tri = verts[faces]  # [F, 3, 3]
        areas = 0.5 * torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).norm(dim=-1)
        area = areas.sum()
        if not torch.isfinite(area) or area <= 0:
            raise ValueError(f"mesh {sample.get('name', '')!r} has zero or non-finite area ({area})")
        if self.center:
            centroid = (areas[:, None] * tri.mean(dim=1)).sum(0) / area
            verts = verts - centroid
        factor = area.double().rsqrt()
        sample["verts"] = verts * factor.to(verts.dtype)
        sample["scale"] = sample.get("scale", torch.tensor(1.0, dtype=torch.float64)) * factor
        return sample

    def __repr__(self) -> str:
        return f"{type(self).__name__}(center={self.center})"


class ComputeSpectrum:
    """Laplace–Beltrami spectrum of the unit-area shape: ``mass``, ``evals``, ``evecs``, ``bands``.

    Calls :func:`symtorch.spectrum.laplacian_spectrum` (float64 sparse solve on CPU) and casts to the
    dtype of ``verts``. ``bands`` is the ``[K]`` band id of each eigenvalue (``eigen_bands``).

    Args:
        k: number of eigenpairs, the constant one included. Bands are grouped within these ``k``, so
            the last band may be cut; ask for a few more than you need when that matters.
        rel_gap: band threshold of :func:`symtorch.spectrum.eigen_bands`; None: its default, resolved
            here so that the repr (the cache key) names the value used.
    """

    def __init__(self, k: int = 30, rel_gap: float | None = None):
        if k < 2:
            raise ValueError(f"k must be >= 2, got {k}")
        if rel_gap is None:
            rel_gap = inspect.signature(eigen_bands).parameters["rel_gap"].default
        self.k, self.rel_gap = k, rel_gap

    def __call__(self, sample: dict) -> dict:
        _require(sample, ("verts",), type(self).__name__, "vertex positions")
        sample = dict(sample)
        verts = sample["verts"]
        spec = laplacian_spectrum(verts, sample.get("faces"), k=self.k, dtype=verts.dtype)
        sample["mass"], sample["evals"], sample["evecs"] = spec.mass, spec.evals, spec.evecs
        sample["bands"] = band_index(eigen_bands(spec.evals, rel_gap=self.rel_gap), self.k)
        return sample

    def __repr__(self) -> str:
        return f"{type(self).__name__}(k={self.k}, rel_gap={self.rel_gap})"


class ComputeDescriptors:
    """Heat and wave kernel signatures (``hks [V, T]``, ``wks [V, E]``) on the default grids.

    Args:
        n_hks: number of HKS times (``default_times``); 0 skips ``hks``.
        n_wks: number of WKS energies (``default_energies``); 0 skips ``wks``.
        normalize: scale each column to unit mean over the vertices, as
            :func:`symtorch.descriptors.descriptors` does (comparable magnitudes across columns).
    """

    def __init__(self, n_hks: int = 16, n_wks: int = 16, normalize: bool = True):
        self.n_hks, self.n_wks, self.normalize = n_hks, n_wks, normalize

    def __call__(self, sample: dict) -> dict:
        from ..descriptors import default_energies, default_times, hks, wks

        _require(sample, ("evals", "evecs"), type(self).__name__, "run ComputeSpectrum first")
        sample = dict(sample)
        evals, evecs = sample["evals"], sample["evecs"]
        out = {}
        if self.n_hks:
            out["hks"] = hks(evals, evecs, default_times(evals, self.n_hks))
        if self.n_wks:
            energies, sigma = default_energies(evals, self.n_wks)
            out["wks"] = wks(evals, evecs, energies, sigma)
        for key, d in out.items():
            sample[key] = d / d.mean(dim=0, keepdim=True).clamp_min(1e-300) if self.normalize else d
        return sample

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(n_hks={self.n_hks}, n_wks={self.n_wks}, "
                f"normalize={self.normalize})")


#: What :class:`DetectSymmetries` does with an uncertain symmetry.
ON_UNCERTAIN = ("keep", "flag", "drop")
#: ``Symmetry.kind`` values of orientation-reversing elements.
_REVERSING = ("reflection", "rotoreflection")


def _store_symmetries(sample: dict, sym_p2p: Tensor) -> dict:
    sample["sym_p2p"] = sym_p2p.long()
    if "evecs" in sample:
        sample["sym_fmap"] = symmetry_fmaps(sample["sym_p2p"], sample["evecs"], sample["mass"],
                                            _sample_bands(sample))
    return sample


class DetectSymmetries:
    """Detect the shape's intrinsic symmetries: ``sym_p2p [G, V]`` and ``sym_fmap [G, K, K]``.

    Runs :func:`symtorch.detect_symmetries` on ``verts``/``faces``, reusing the sample's spectrum when
    present (``ComputeSpectrum`` before it). ``sym_p2p`` holds the detected vertex maps, identity first;
    ``sym_fmap`` their matrices in the *sample's* basis, recomputed from the maps with
    :func:`symmetry_fmaps` (block-projected on the sample's bands), so that they match ``evecs`` whatever
    basis size the detector refined in. ``sym_score [G]`` holds each element's distortion score
    (``Symmetry.score``), ``sym_confidence [G]`` its confidence (``Symmetry.confidence``: the one
    whose ranking separates right maps from wrong ones) and ``sym_reverses [G]`` whether it reverses
    orientation (its ``Symmetry.kind`` is ``'reflection'`` or ``'rotoreflection'``).

    A symmetry whose confidence is below the detector's ``min_confidence`` (a ``DetectConfig``
    field, passed through ``**kwargs``) is *uncertain*; ``on_uncertain`` says what the sample gets:

    - ``"keep"``: every element, as detected;
    - ``"flag"``: every element, and ``sym_uncertain [G]`` bool marking the uncertain ones;
    - ``"drop"``: where any element is uncertain, the identity alone (``G = 1``): a wrong map fed to
      augmentation or an equivariance loss teaches the wrong thing, no map teaches nothing.

    Args:
        seed: seed of the generator handed to the detector where it takes one (precompute must be
            deterministic).
        on_uncertain: ``"keep"``, ``"flag"`` or ``"drop"``, see above.
        **kwargs: keywords of ``detect_symmetries`` (``k``, ``k_refine``, ``mode``,
            ``min_confidence``, ...).

    Raises:
        ValueError: an unknown ``on_uncertain``.
    """

    def __init__(self, seed: int = 0, on_uncertain: str = "keep", **kwargs):
        if on_uncertain not in ON_UNCERTAIN:
            raise ValueError(f"on_uncertain must be one of {', '.join(map(repr, ON_UNCERTAIN))}, "
                             f"got {on_uncertain!r}")
        self.seed, self.on_uncertain, self.kwargs = seed, on_uncertain, kwargs

    def __call__(self, sample: dict) -> dict:
        try:
            from .. import detect_symmetries
        except ImportError:
            from ..detect.auto import detect_symmetries
        from ..spectrum import Spectrum

        _require(sample, ("verts", "faces"), type(self).__name__, "a triangle mesh")
        sample = dict(sample)
        verts, faces = sample["verts"].double(), sample["faces"]
        spectrum = None
        if "evecs" in sample:
            tri = verts[faces]
            area = 0.5 * torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).norm(dim=-1)
            spectrum = Spectrum(sample["evals"].double(), sample["evecs"].double(),
                                sample["mass"].double(), float(area.sum().rsqrt()))
        extra = {}
        if "generator" in inspect.signature(detect_symmetries).parameters:
            extra["generator"] = torch.Generator().manual_seed(self.seed)
        result = detect_symmetries(verts, faces, spectrum=spectrum, **extra, **self.kwargs)
        syms = list(result.symmetries)
        if self.on_uncertain == "drop" and any(s.uncertain for s in syms):
            syms = syms[:1]  # the identity
        dtype, device = sample["verts"].dtype, result.p2ps.device
        sample["sym_score"] = torch.tensor([float(s.score) for s in syms], dtype=dtype)
        sample["sym_confidence"] = torch.tensor([float(s.confidence) for s in syms], dtype=dtype)
        sample["sym_reverses"] = torch.tensor([s.kind in _REVERSING for s in syms], device=device)
        if self.on_uncertain == "flag":
            sample["sym_uncertain"] = torch.tensor([bool(s.uncertain) for s in syms], device=device)
        return _store_symmetries(sample, result.p2ps[: len(syms)])

    def __repr__(self) -> str:
        # The repr is the cache key: the detector's revision is in it (a cache made by a detector
        # whose results differ is recomputed); on_uncertain="keep" is left out (caches made before
        # the option existed hold what "keep" gives, less sym_confidence)
        from ..detect.config import DETECTOR_REVISION

        args = [f"seed={self.seed}", f"revision={DETECTOR_REVISION}"]
        args += [f"on_uncertain={self.on_uncertain!r}"] if self.on_uncertain != "keep" else []
        args += [f"{k}={v!r}" for k, v in sorted(self.kwargs.items())]
        return f"{type(self).__name__}({', '.join(args)})"


class SetSymmetries:
    """Attach known symmetries, given as vertex maps, their matrices in the sample's basis and their
    orientation: ``sym_p2p [G, V]``, ``sym_fmap [G, K, K]``, ``sym_reverses [G]``.

    For ground truth, or for a dataset whose meshes share one template (SCAPE, FAUST registrations),
    where the maps detected once on one mesh hold for every mesh.

    Args:
        sym_p2p: [G, V] long vertex maps, identity first.
        reverses: [G] bool, whether each element reverses orientation. None: decided on each sample
            by the orientation vote of its faces (:func:`symtorch.groups.orientation_score` < 0; the
            first element, the identity, is False); a point cloud then gets no ``sym_reverses``.
    """

    def __init__(self, sym_p2p: Tensor, reverses: Tensor | None = None):
        sym_p2p = torch.as_tensor(sym_p2p)
        if sym_p2p.dim() != 2 or sym_p2p.is_floating_point():
            raise ValueError(f"sym_p2p must be [G, V] long, got {list(sym_p2p.shape)} {sym_p2p.dtype}")
        self.sym_p2p = sym_p2p.long()
        self._digest = hashlib.sha1(self.sym_p2p.numpy().tobytes()).hexdigest()[:12]
        if reverses is not None:
            reverses = torch.as_tensor(reverses)
            if reverses.shape != (sym_p2p.shape[0],) or reverses.is_floating_point():
                raise ValueError(f"reverses must be [G] = [{sym_p2p.shape[0]}] bools, got "
                                 f"{list(reverses.shape)} {reverses.dtype}")
            reverses = reverses.bool()
        self.reverses = reverses

    def __call__(self, sample: dict) -> dict:
        V = sample["verts"].shape[0]
        if self.sym_p2p.shape[1] != V:
            raise ValueError(f"sym_p2p has {self.sym_p2p.shape[1]} vertices but sample "
                             f"{sample.get('name', '')!r} has {V}")
        sample = dict(sample)
        device = sample["verts"].device
        sym_p2p = self.sym_p2p.to(device)
        if self.reverses is not None:
            sample["sym_reverses"] = self.reverses.to(device)
        elif "faces" in sample:
            from ..groups import orientation_score

            score = orientation_score(sym_p2p, sample["verts"], sample["faces"])
            rev = score < 0
            rev[0] = False
            sample["sym_reverses"] = rev
        return _store_symmetries(sample, sym_p2p.clone())

    def __repr__(self) -> str:
        G, V = self.sym_p2p.shape
        rev = None if self.reverses is None else self.reverses.tolist()
        return f"{type(self).__name__}(G={G}, V={V}, sha1={self._digest}, reverses={rev})"


def change_basis(sample: dict, R: Tensor) -> dict:
    """Replace the eigenbasis by ``evecs @ R`` for a block-orthogonal ``R`` ([K, K], within bands).

    Per-vertex fields do not move; operators expressed in the basis follow: ``sym_fmap[h] ->
    R.T @ sym_fmap[h] @ R`` (the pull-back in the new basis), ``orient_op[d] -> R.T @ orient_op[d] @ R``,
    and a coefficient vector ``a`` of a function becomes ``R.T @ a``.
    """
    _require(sample, ("evecs",), "change_basis", "run ComputeSpectrum first")
    out = dict(sample)
    R = R.to(sample["evecs"])
    out["evecs"] = sample["evecs"] @ R
    for key in sample.keys() & {"sym_fmap", "orient_op"}:
        out[key] = R.mT @ sample[key] @ R
    return out


class RandomEigenSigns:
    """Flip the sign of each eigenvector with probability 1/2 (the sign ambiguity of any eigensolver).

    See :func:`change_basis` for what follows the basis.

    Args:
        generator: source of the one draw (K signs) per call.
    """

    def __init__(self, generator: torch.Generator | None = None):
        self.generator = generator

    def __call__(self, sample: dict) -> dict:
        _require(sample, ("evecs",), type(self).__name__, "run ComputeSpectrum first")
        K = sample["evecs"].shape[-1]
        signs = torch.randint(2, (K,), generator=self.generator) * 2 - 1
        return change_basis(sample, torch.diag(signs.double()))

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def _haar_orthogonal(n: int, generator: torch.Generator | None) -> Tensor:
    """[n, n] orthogonal matrix drawn from the Haar measure on O(n) (QR of a Gaussian, signs fixed)."""
    A = torch.randn(n, n, generator=generator, dtype=torch.float64)
    Q, R = torch.linalg.qr(A)
    return Q * torch.sign(torch.diagonal(R))[None, :]


class RandomBandRotation:
    """Rotate the basis by a random orthogonal matrix within each eigenvalue band.

    Within a band of (near-)repeated eigenvalues any orthonormal basis is as valid as the one the
    solver returned; one-dimensional bands get a random sign. See :func:`change_basis`.

    Args:
        generator: source of the one draw per call.
    """

    def __init__(self, generator: torch.Generator | None = None):
        self.generator = generator

    def __call__(self, sample: dict) -> dict:
        _require(sample, ("evecs", "evals"), type(self).__name__, "run ComputeSpectrum first")
        K = sample["evecs"].shape[-1]
        R = torch.zeros(K, K, dtype=torch.float64)
        for b in _sample_bands(sample):
            R[b.start:b.stop, b.start:b.stop] = _haar_orthogonal(len(b), self.generator)
        return change_basis(sample, R)

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


def __getattr__(name: str):
    # apply_symmetry and RandomSymmetry moved to symtorch.data.symmetry (which imports this module)
    if name in ("apply_symmetry", "RandomSymmetry"):
        from . import symmetry

        return getattr(symmetry, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
