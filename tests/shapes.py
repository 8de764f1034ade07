"""Shapes built in code with known symmetries, and a quiet detection, shared by the tests."""
import warnings

import torch

from symtorch.shapes import mirror_blob, symmetry_maps, true_symmetries


def mirror_mesh(subdivisions: int = 2, dtype=torch.float64):
    """A bumpy sphere, mirror-symmetric in x by construction: (verts, faces, mirror permutation).

    The icosphere's vertex set and connectivity are symmetric under x -> -x, and the bumps are placed
    in mirror pairs, so ``mirror`` (found by nearest neighbour on the sphere) is an exact automorphism.
    No other symmetry: the bumps and the anisotropic stretch break them.
    """
    verts, f = mirror_blob(subdivisions)
    mirror = symmetry_maps(verts, true_symmetries("mirror_blob"))[1]
    return (torch.tensor(verts, dtype=dtype), torch.tensor(f, dtype=torch.long),
            torch.tensor(mirror, dtype=torch.long))


SUB = 4  # 2562 vertices: the icosphere's triangulation is only approximately 5- or 6-fold symmetric


def detect_quietly(verts, faces, mode: str = "group"):
    """``detect_symmetries(mode=mode, k_refine=40)`` with the group path's closure notes silenced."""
    from symtorch.detect import detect_symmetries

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return detect_symmetries(verts, faces, mode=mode, k_refine=40)
