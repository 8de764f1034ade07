"""Datasets, transforms and batching for deep learning on meshes and their symmetries.

A **sample** is a ``dict[str, Tensor]`` describing one shape. Its keys, documented here once
(V vertices, F faces, K eigenpairs, G group elements, N template points, T/E descriptor scales):

============== ============ =========================================================================
key            shape        meaning (who writes it)
============== ============ =========================================================================
``name``       str          file stem of the mesh (:func:`read_sample`)
``verts``      [V, 3] float vertex positions (:func:`read_sample`; :class:`NormalizeArea` rescales)
``faces``      [F, 3] long  triangles, 0-based (:func:`read_sample`)
``scale``      [] float64   factor applied to the input vertices (:class:`NormalizeArea`)
``mass``       [V]          lumped mass of the unit-area shape, sums to 1 (:class:`ComputeSpectrum`)
``evals``      [K]          Laplace–Beltrami eigenvalues of the unit-area shape, ascending
``evecs``      [V, K]       eigenfunctions, mass-orthonormal: ``evecs.T @ (mass[:, None] * evecs) = I``
``bands``      [K] long     band id of each eigenvalue (near-repeated eigenvalues share one;
                            :func:`bands_from_index` gives the ranges)
``hks``        [V, T]       heat kernel signature (:class:`ComputeDescriptors`)
``wks``        [V, E]       wave kernel signature (:class:`ComputeDescriptors`)
``sym_p2p``    [G, V] long  symmetries as vertex maps, identity first: ``sym_p2p[g, i]`` is the image
                            of vertex i (:class:`DetectSymmetries`, :class:`SetSymmetries`)
``sym_fmap``   [G, K, K]    their matrices in this sample's basis, pull-back convention (ALGORITHM
                            §2): ``evecs[sym_p2p[g]] ≈ evecs @ sym_fmap[g]``
``sym_score``  [G]          distortion score ``exp(-distortion^2)`` of each element
                            (:class:`DetectSymmetries`)
``sym_confidence`` [G]      detector confidence of each element, in [0, 1]: its ranking separates
                            right maps from wrong ones (:class:`DetectSymmetries`)
``sym_uncertain`` [G] bool  confidence below the detector's ``min_confidence``
                            (:class:`DetectSymmetries` with ``on_uncertain="flag"``)
``sym_reverses`` [G] bool   whether each element reverses orientation (reflections,
                            rotoreflections; :class:`DetectSymmetries`, :class:`SetSymmetries`,
                            :class:`SymmetryFromCorrespondence`)
``corr``       [N] long     ground truth: the vertex of template point k (:func:`read_sample`,
                            ``ground_truth=``); two shapes of one dataset correspond through
                            ``corr_x[k] <-> corr_y[k]``. -1: the point is missing on this shape
``corr_sym``   [N] long     the vertex of the mirror image of template point k, where known
``orient_op``  [D, K, K]    orientation operators of D descriptors in this basis (Ren et al. 2018;
                            :class:`ComputeOrientationOperators`)
``dist_path``  str          geodesic matrix file of the shape (``""``: none), added on access by a
                            :class:`MeshDataset` with a ``dist_dir``; :meth:`MeshDataset.geodesic_matrix`
============== ============ =========================================================================

Per-vertex keys (``VERTEX_FIELDS``) have V rows; ground-truth keys (``INDEX_FIELDS``) name points by
vertex ids of the same shape. Symmetry augmentation (:func:`apply_symmetry`,
:class:`RandomSymmetry`) moves ground truth, never the vertices: ``mode="relabel"`` composes ``corr``
with a symmetry, ``mode="mirror"`` also mirrors the shape (:func:`mirror_shape`: ``orient_op``
changes sign) so that the ground truth stays orientation preserving. Folder layouts of the field:
:mod:`symtorch.data.layouts`, :meth:`MeshDataset.from_layout`. A **pair** (:class:`PairDataset`) is
``{"x": sample, "y": sample}`` plus, where the dataset has ground truth, ``p2p_yx [V_y]`` (image on
x of each vertex of y, -1 unknown) and ``fmap_xy [K_y, K_x]`` (functional map sending functions on
x to functions on y).
:func:`pad_collate` batches either, adding ``mask [B, V]`` and the other masks.
"""
from .collate import pad_collate, pad_stack
from .dataset import (PAIR_MODES, MeshDataset, PairDataset, corr_to_fmap, default_cache_dir,
                      read_sample)
from .layouts import Layout, class_key, find_layout, read_geodesic_matrix
from .operators import ComputeOrientationOperators
from .symmetry import (AUGMENT_MODES, RandomSymmetry, SymmetryFromCorrespondence, apply_symmetry,
                       dense_map_from_pairs, mirror_shape)
from .transforms import (INDEX_FIELDS, VERTEX_FIELDS, Compose, ComputeDescriptors, ComputeSpectrum,
                         DetectSymmetries, NormalizeArea, RandomBandRotation, RandomEigenSigns,
                         SetSymmetries, bands_from_index, change_basis, symmetry_fmaps)

__all__ = ["MeshDataset", "PairDataset", "read_sample", "corr_to_fmap", "default_cache_dir",
           "pad_collate", "pad_stack", "Compose", "NormalizeArea", "ComputeSpectrum",
           "ComputeDescriptors", "DetectSymmetries", "SetSymmetries", "RandomSymmetry",
           "RandomEigenSigns", "RandomBandRotation", "apply_symmetry", "change_basis",
           "symmetry_fmaps", "bands_from_index", "VERTEX_FIELDS", "INDEX_FIELDS",
           "ComputeOrientationOperators", "SymmetryFromCorrespondence", "mirror_shape",
           "dense_map_from_pairs", "AUGMENT_MODES", "PAIR_MODES", "Layout", "find_layout",
           "read_geodesic_matrix", "class_key"]
