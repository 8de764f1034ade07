"""Tests for symtorch.zoomout: a coarse map between two shapes sharpened, a flipped one kept flipped."""
from __future__ import annotations

import pytest
import torch

from symtorch.maps import fmap_to_p2p, p2p_to_fmap
from symtorch.shapes import asymmetric, mirror_blob, symmetry_maps, true_symmetries
from symtorch.spectrum import laplacian_spectrum
from symtorch.zoomout import zoomout


def _pair(builder):
    """x and y: the same surface, y's vertices shuffled; ``truth [V_y]`` the image on x of each y vertex."""
    v, f = builder(3)
    v = torch.as_tensor(v)
    f = torch.as_tensor(f)
    perm = torch.randperm(len(v), generator=torch.Generator().manual_seed(0))
    inv = torch.argsort(perm)
    vy, fy = v[perm], inv[f]
    sx, sy = laplacian_spectrum(v, f, k=48), laplacian_spectrum(vy, fy, k=48)
    return v, vy, sx, sy, perm


def _error(p2p, truth, v):
    return float((v[p2p] - v[truth]).norm(dim=1).mean())


def test_zoomout_sharpens_a_noisy_coarse_map():
    v, _, sx, sy, truth = _pair(asymmetric)
    C_true = p2p_to_fmap(truth, sx.evecs[:, :10], sy.mass, evecs_src=sy.evecs[:, :10])
    g = torch.Generator().manual_seed(1)
    C0 = C_true + 0.1 * torch.randn(10, 10, generator=g, dtype=C_true.dtype)
    coarse = fmap_to_p2p(C0, sx.evecs[:, :10], sy.evecs[:, :10])
    res = zoomout(C0, sx.evecs, sy.evecs, sy.mass, 40)
    assert res.fmap.shape == (40, 40) and res.p2p.shape == (len(v),)
    assert (res.p2p == fmap_to_p2p(res.fmap, sx.evecs[:, :40], sy.evecs[:, :40])).all()
    before, after = _error(coarse, truth, v), _error(res.p2p, truth, v)
    assert after < 0.5 * before, (before, after)
    assert float((res.p2p == truth).double().mean()) > 0.8


def test_zoomout_keeps_a_flipped_map_flipped():
    # it refines whatever side the map takes: the mirror-composed map stays the mirror's
    v, _, sx, sy, truth = _pair(mirror_blob)
    mirror = torch.as_tensor(symmetry_maps(v.numpy(), true_symmetries("mirror_blob"))[1])
    flipped = mirror[truth]
    C0 = p2p_to_fmap(flipped, sx.evecs[:, :8], sy.mass, evecs_src=sy.evecs[:, :8])
    res = zoomout(C0, sx.evecs, sy.evecs, sy.mass, 40, step=2)
    assert _error(res.p2p, flipped, v) < 0.2 * _error(res.p2p, truth, v)


def test_zoomout_rejects_bad_sizes():
    _, _, sx, sy, _ = _pair(asymmetric)
    C = torch.eye(10, dtype=sx.evecs.dtype)
    with pytest.raises(ValueError, match="k_final"):
        zoomout(C, sx.evecs, sy.evecs, sy.mass, 60)
    with pytest.raises(ValueError, match="square"):
        zoomout(C[:, :8], sx.evecs, sy.evecs, sy.mass, 20)
    with pytest.raises(ValueError, match="step"):
        zoomout(C, sx.evecs, sy.evecs, sy.mass, 20, step=0)
