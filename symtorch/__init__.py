"""symtorch: global intrinsic symmetry groups of 3D shapes (Wang & Huang, PG 2017), as torch tensors.

Quick start::

    import symtorch
    mesh = symtorch.read_mesh("shape.off")
    result = symtorch.detect_symmetries(mesh)
    result.fmaps   # [G, K, K] block-orthogonal symmetry matrices, identity first
    result.p2ps    # [G, V] vertex maps
    result.group   # GroupInfo: name, order, table, inverses, orders

The public API is ``__all__`` below; its conventions (names, shapes, map direction, dtype and device)
are the README's "Conventions". Sub-packages and modules not listed here (``symtorch.eval``,
``symtorch.cli``, ``symtorch.descriptors.descriptors``, ...) are imported by their full name.
"""
__version__ = "0.1.0"

from .cache import cached_spectrum, spectrum_key
from .descriptors import hks, wks  # the module stays ``symtorch.descriptors``
from .detect.auto import detect_symmetries
from .detect.config import DetectConfig, GroupConfig, ReflectionConfig
from .groups import (GroupInfo, cayley_table, check_group, closure, compose_fmap, compose_p2p, element_orders,
                     group_info, identify_group, inverse_fmap, inverse_p2p, inverses)
from .io import Mesh, MeshWarning, mesh_report, read_mesh, write_mesh
from .losses import (bijectivity_loss, fmap_loss, laplacian_commutativity_loss, orientation_loss,
                     orthogonality_loss, p2p_error, symmetric_fmap_loss, symmetric_p2p_error,
                     symmetry_equivariance_loss)
from .orientation import orientation_operators, resolve_symmetry, resolve_symmetry_p2p
from .maps import fmap_to_p2p, p2p_to_fmap
from .procrustes import block_procrustes, nearest_orthogonal
from .detect.result import Symmetry, SymmetryResult
from .spectrum import Spectrum, eigen_bands, laplacian_spectrum
from .data import (Compose, ComputeDescriptors, ComputeOrientationOperators, ComputeSpectrum,
                   DetectSymmetries, MeshDataset, NormalizeArea, PairDataset, RandomBandRotation,
                   RandomEigenSigns, RandomSymmetry, SetSymmetries, apply_symmetry, pad_collate)

__all__ = [
    "__version__",
    # meshes and spectra
    "Mesh", "MeshWarning", "read_mesh", "write_mesh", "mesh_report",
    "Spectrum", "laplacian_spectrum", "eigen_bands", "cached_spectrum", "spectrum_key", "hks", "wks",
    # maps and matrices
    "p2p_to_fmap", "fmap_to_p2p", "block_procrustes", "nearest_orthogonal",
    # detection
    "detect_symmetries", "DetectConfig", "ReflectionConfig", "GroupConfig", "Symmetry", "SymmetryResult",
    # groups
    "GroupInfo", "group_info", "cayley_table", "check_group", "closure", "compose_fmap", "compose_p2p",
    "element_orders", "identify_group", "inverse_fmap", "inverse_p2p", "inverses",
    # orientation
    "orientation_operators", "resolve_symmetry", "resolve_symmetry_p2p",
    # learning
    "bijectivity_loss", "fmap_loss", "laplacian_commutativity_loss", "orientation_loss",
    "orthogonality_loss", "p2p_error", "symmetric_fmap_loss", "symmetric_p2p_error",
    "symmetry_equivariance_loss",
    "Compose", "ComputeDescriptors", "ComputeOrientationOperators", "ComputeSpectrum", "DetectSymmetries",
    "MeshDataset", "NormalizeArea", "PairDataset", "RandomBandRotation", "RandomEigenSigns",
    "RandomSymmetry", "SetSymmetries", "apply_symmetry", "pad_collate",
]  # SymmetryDataModule is left out: it needs the optional lightning extra (``symtorch.SymmetryDataModule``)


def __getattr__(name: str):
    # lightning is an optional extra: import it only when the DataModule is asked for
    if name == "SymmetryDataModule":
        from .lightning import SymmetryDataModule
        return SymmetryDataModule
    raise AttributeError(f"module 'symtorch' has no attribute {name!r}")
