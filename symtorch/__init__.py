"""symtorch: global intrinsic symmetry groups of 3D shapes (Wang & Huang, PG 2017), as torch tensors.

Quick start::

    import symtorch
    mesh = symtorch.read_mesh("shape.off")
    result = symtorch.detect_symmetries(mesh)
    result.fmaps   # [G, K, K] block-orthogonal symmetry matrices, identity first
    result.p2ps    # [G, V] vertex maps
"""
__version__ = "0.1.0"

from .cache import cached_spectrum, spectrum_key
from .descriptors import descriptors, hks, wks
from .detect.auto import detect_symmetries
from .groups.algebra import (cayley_table, check_group, closure, compose_fmap, compose_p2p, element_orders,
                     group_info, identify_group, inverse_fmap, inverse_p2p, inverses)
from .io import Mesh, MeshWarning, mesh_report, read_mesh, write_mesh
from .losses import (bijectivity_loss, fmap_loss, laplacian_commutativity_loss, orthogonality_loss,
                     p2p_error, symmetric_fmap_loss, symmetric_p2p_error, symmetry_equivariance_loss)
from .maps import fmap_to_p2p, p2p_to_fmap
from .procrustes import block_procrustes, nearest_orthogonal
from .detect.result import Symmetry, SymmetryResult
from .spectrum import Spectrum, eigen_bands, laplacian_spectrum
from .data import (Compose, ComputeDescriptors, ComputeSpectrum, DetectSymmetries, MeshDataset,
                   NormalizeArea, PairDataset, RandomBandRotation, RandomEigenSigns, RandomSymmetry,
                   SetSymmetries, apply_symmetry, pad_collate)


def __getattr__(name: str):
    # lightning is an optional extra: import it only when the DataModule is asked for
    if name == "SymmetryDataModule":
        from .lightning import SymmetryDataModule
        return SymmetryDataModule
    raise AttributeError(f"module 'symtorch' has no attribute {name!r}")
