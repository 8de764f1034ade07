"""Part-wise flip resolution of point maps (symtorch.flips)."""
import pytest
import torch

from symtorch.flips import resolve_symmetry_parts
from shapes import mirror_mesh, wobble


@pytest.fixture(scope="module")
def pair():
    """The mirror blob (x), its bent copy (y: the identity is the true map), and x's mirror."""
    verts, faces, mirror = mirror_mesh(3)
    return verts, faces, wobble(verts), mirror


def test_a_flipped_part_is_sent_back_and_the_rest_kept(pair):
    vx, faces, vy, mirror = pair
    ident = torch.arange(len(vx))
    part = (vy[:, 0] > 0.35) & (vy[:, 1] > 0.2)  # the right front bump of y lands on the left one
    assert 0.05 < float(part.float().mean()) < 0.3
    p2p = torch.where(part, mirror, ident)
    res = resolve_symmetry_parts(p2p, vx, faces, vy, faces, mirror)
    right = res.p2p == ident  # 84 % before; the part's border band (its vote near 0) stays flipped
    assert float(right.float().mean()) > 0.95, float(right.float().mean())
    assert float(right[part].float().mean()) > 0.7
    assert float(res.flipped[~part].float().mean()) < 0.01
    assert res.vote.shape == (len(vy),) and res.flipped.dtype == torch.bool


def test_a_map_flipped_as_a_whole_is_flipped_back_and_a_right_map_kept(pair):
    vx, faces, vy, mirror = pair
    ident = torch.arange(len(vx))
    res = resolve_symmetry_parts(mirror, vx, faces, vy, faces, mirror)
    assert bool(res.flipped.all()) and torch.equal(res.p2p, ident)
    res = resolve_symmetry_parts(ident, vx, faces, vy, faces, mirror)
    assert not bool(res.flipped.any()) and torch.equal(res.p2p, ident)


def test_value_errors(pair):
    vx, faces, vy, mirror = pair
    with pytest.raises(ValueError, match="scale must be positive"):
        resolve_symmetry_parts(mirror, vx, faces, vy, faces, mirror, scale=0.0)
    with pytest.raises(ValueError, match=r"threshold must be in \[-1, 1\)"):
        resolve_symmetry_parts(mirror, vx, faces, vy, faces, mirror, threshold=1.0)
    with pytest.raises(ValueError, match="sym_p2p_x must be one reflection"):
        resolve_symmetry_parts(mirror, vx, faces, vy, faces, torch.stack([mirror, mirror]))
    with pytest.raises(ValueError, match="p2p_yx index out of range"):
        resolve_symmetry_parts(mirror + 1, vx, faces, vy, faces, mirror)


def test_a_reused_smoother_gives_the_same_resolution(pair):
    from symtorch.flips import VoteSmoother

    vx, faces, vy, mirror = pair
    part = (vy[:, 0] > 0.35) & (vy[:, 1] > 0.2)
    p2p = torch.where(part, mirror, torch.arange(len(vx)))
    smoother = VoteSmoother(vy, faces, scale=4e-3)
    a = resolve_symmetry_parts(p2p, vx, faces, vy, faces, mirror, scale=4e-3)
    b = resolve_symmetry_parts(p2p, vx, faces, vy, faces, mirror, smoother=smoother)
    assert torch.equal(a.p2p, b.p2p) and torch.equal(a.flipped, b.flipped)
    with pytest.raises(ValueError, match="smoother is for 642 vertices but y has 162"):
        v2, f2, m2 = mirror_mesh(2)
        resolve_symmetry_parts(m2, v2, f2, v2, f2, m2, smoother=smoother)
