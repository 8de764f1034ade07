"""Orientation operators (Ren et al. 2018) and flip resolution (symtorch.orientation)."""
import pytest
import torch

from symtorch import laplacian_spectrum
from symtorch.descriptors import default_energies, wks
from symtorch.maps import p2p_to_fmap
from symtorch.orientation import (face_geometry, face_gradients, orientation_agreement,
                                  orientation_operators, orientation_residual, resolve_symmetry,
                                  resolve_symmetry_p2p)
from symtorch.paths import shared_path
from symtorch.shapes import polar_prism, polar_prism_symmetries, symmetry_maps
from symtorch.spectrum import eigen_bands
from shapes import mirror_mesh, wobble

F64 = torch.float64


def rel(a, b):
    return float((a - b).norm() / b.norm())


def spectrum_and_wks(verts, faces, k=30, n_wks=8):
    s = laplacian_spectrum(verts, faces, k=k)
    energies, sigma = default_energies(s.evals, n_wks)
    return s, wks(s.evals, s.evecs, energies, sigma)


@pytest.fixture(scope="module")
def blob():
    """The mirror blob, its spectrum, WKS and operators: (verts, faces, mirror, spectrum, O [8, 30, 30])."""
    verts, faces, mirror = mirror_mesh(3)
    s, d = spectrum_and_wks(verts, faces)
    return verts, faces, mirror, s, orientation_operators(verts, faces, s.evecs, s.mass, d)


@pytest.fixture(scope="module")
def bent(blob):
    """The blob (x) and its bent copy (y), with the identity as ground truth: operators of both, the
    true map, its mirror flip, and the mirror of y (exact on x, approximate on y)."""
    verts, faces, mirror, sx, Ox = blob
    vy = wobble(verts)
    sy, dy = spectrum_and_wks(vy, faces)
    Oy = orientation_operators(vy, faces, sy.evecs, sy.mass, dy)
    C_gt = p2p_to_fmap(torch.arange(len(vy)), sx.evecs, sy.mass, sy.evecs)  # [K_y, K_x]
    C_flip = p2p_to_fmap(mirror, sx.evecs, sy.mass, sy.evecs)
    S_y = p2p_to_fmap(mirror, sy.evecs, sy.mass)
    sym = torch.stack([torch.eye(S_y.shape[0], dtype=F64), S_y])
    return dict(vy=vy, Ox=Ox, Oy=Oy, C_gt=C_gt, C_flip=C_flip, sym=sym)


# ------------------------------------------------------------------------------------ gradients
def test_face_gradient_of_a_linear_field_is_its_tangential_part(blob):
    verts, faces = blob[0], blob[1]
    a = torch.tensor([0.3, -1.2, 0.7], dtype=F64)
    geo = face_geometry(verts, faces)
    g = face_gradients(verts, faces, verts @ a)  # [F, 3]
    n = geo.normals
    torch.testing.assert_close(g, a - (n @ a)[:, None] * n)
    assert face_gradients(verts, faces, torch.stack([verts @ a, 2 * verts @ a], 1)).shape == (len(faces), 2, 3)
    assert float(geo.areas.sum()) == pytest.approx(float(laplacian_spectrum(verts, faces, 3,
                                                   normalize_area=False).mass.sum()), rel=1e-9)


# ------------------------------------------------------------------------------------ operators
def test_operator_is_antisymmetric_and_kills_constants(blob):
    # ∫ h df∧dg = -∫ g df∧dh on a closed surface (Stokes: h df∧dg + g df∧dh = d(f d(hg))), and the
    # exact face integration keeps it on the mesh; a constant h or g gives 0
    O = blob[4]
    assert O.shape == (8, 30, 30)
    assert rel(O.mT, -O) < 1e-12
    assert float(O[:, 0].abs().max()) < 1e-12 * float(O.abs().max())
    assert float(O[:, :, 0].abs().max()) < 1e-12 * float(O.abs().max())
    # with a boundary the Stokes term ∮ f d(hg) remains: no antisymmetry on an open mesh
    verts, faces, _, s, _ = blob
    cap = verts[faces].mean(1)[:, 2] > 0.5 * float(verts[:, 2].max())
    d = spectrum_and_wks(verts, faces)[1]
    Oo = orientation_operators(verts, faces[~cap], s.evecs, s.mass, d)
    assert rel(Oo.mT, -Oo) > 0.1


def test_mirrored_mesh_negates_the_operator(blob):
    verts, faces, _, s, O = blob
    d = spectrum_and_wks(verts, faces)[1]
    mirrored = verts * torch.tensor([-1.0, 1.0, 1.0], dtype=F64)
    Om = orientation_operators(mirrored, faces.flip(1), s.evecs, s.mass, d)  # winding reversed
    assert rel(Om, -O) < 1e-12
    # a rigid motion and a rescaling change nothing (area x two gradients is scale free)
    R = torch.linalg.qr(torch.randn(3, 3, generator=torch.Generator().manual_seed(0), dtype=F64))[0]
    R = R * torch.det(R)  # a rotation
    moved = 3.0 * verts @ R.mT + 1.0
    assert rel(orientation_operators(moved, faces, s.evecs, s.mass, d), O) < 1e-12


def test_reflection_anticommutes(blob):
    _, _, mirror, s, O = blob
    S = p2p_to_fmap(mirror, s.evecs, s.mass)
    assert rel(S @ O @ S.mT, -O) < 1e-12  # an exact automorphism of the mesh, WKS invariant


def test_rotations_commute_and_reflections_anticommute_on_an_exact_prism():
    v, f = polar_prism(6)
    mats = polar_prism_symmetries(6)
    p2p = torch.as_tensor(symmetry_maps(v, mats))
    v, f = torch.as_tensor(v), torch.as_tensor(f)
    s, d = spectrum_and_wks(v, f, k=40)
    K = [b.stop for b in eigen_bands(s.evals) if b.stop < 40][-1]  # never cut a band
    O = orientation_operators(v, f, s.evecs[:, :K], s.mass, d)
    for g, M in enumerate(mats):
        S = p2p_to_fmap(p2p[g], s.evecs[:, :K], s.mass)
        sign = float(torch.det(torch.as_tensor(M)).sign())  # +1 rotation, -1 (roto)reflection
        assert rel(S @ O @ S.mT, sign * O) < 1e-10, f"element {g}, det {sign:+.0f}"


def test_operators_follow_dtype_device_and_single_fields(blob, device):
    verts, faces, _, s, O = blob
    d = spectrum_and_wks(verts, faces)[1]
    args = [t.to(device, torch.float32) for t in (verts, s.evecs, s.mass, d)]
    got = orientation_operators(args[0], faces.to(device), args[1], args[2], args[3])
    assert got.dtype == torch.float32 and got.device == torch.device(device)
    assert rel(got.cpu().double(), O) < 1e-4
    one = orientation_operators(verts, faces, s.evecs, s.mass, d[:, 2])
    assert one.shape == (30, 30) and rel(one, O[2]) < 1e-14


def test_operators_in_chunks_equal_in_one(blob, monkeypatch):
    import symtorch.orientation as orientation

    verts, faces, _, s, O = blob
    d = spectrum_and_wks(verts, faces)[1]
    monkeypatch.setattr(orientation, "_CHUNK", 3 * len(faces) * 30)  # 3 descriptors at a time
    torch.testing.assert_close(orientation.orientation_operators(verts, faces, s.evecs, s.mass, d), O)


def test_operator_value_errors(blob):
    verts, faces, _, s, _ = blob
    d = torch.ones(len(verts), 2, dtype=F64)
    with pytest.raises(ValueError, match=r"evecs must be \[V, K\] = \[642, K\], got \[641, 30\]"):
        orientation_operators(verts, faces, s.evecs[1:], s.mass, d)
    with pytest.raises(ValueError, match=r"mass must be \[V\] = \[642\], got \[642, 1\]"):
        orientation_operators(verts, faces, s.evecs, s.mass[:, None], d)
    with pytest.raises(ValueError, match=r"fields must be \[V, D\] = \[642, D\], got \[2, 642\]"):
        orientation_operators(verts, faces, s.evecs, s.mass, d.mT)
    with pytest.raises(ValueError, match=r"faces must be \[F, 3\] long, got \[1280, 2\]"):
        orientation_operators(verts, faces[:, :2], s.evecs, s.mass, d)
    with pytest.raises(ValueError, match="must share one dtype, got torch.float64, torch.float32"):
        orientation_operators(verts, faces, s.evecs.float(), s.mass, d)
    with pytest.raises(ValueError, match="faces index out of range"):
        face_geometry(verts[:10], faces)
    with pytest.raises(ValueError, match=r"verts must be a \[V, 3\] float tensor, got \[642, 2\]"):
        face_geometry(verts[:, :2], faces)
    with pytest.raises(ValueError, match=r"fields must be \[V, D\] = \[642, D\], got \[10\]"):
        face_gradients(verts, faces, d[:10, 0])


# ---------------------------------------------------------------------------------- resolution
def test_map_relations_on_a_bent_copy(bent):
    # orientation-preserving: C O_x ≈ O_y C; the flip: C O_x ≈ -O_y C
    r = orientation_residual(torch.stack([bent["C_gt"], bent["C_flip"]]), bent["Ox"], bent["Oy"])
    assert float(r[0]) < 0.1 and float(r[1]) > 1.9, r.tolist()


def test_resolve_symmetry_unflips_a_functional_map(bent):
    C = torch.stack([bent["C_gt"], bent["C_flip"]])  # [B, K_y, K_x]
    sym = bent["sym"].expand(2, 2, -1, -1)
    res = resolve_symmetry(C, sym, bent["Ox"].expand(2, -1, -1, -1), bent["Oy"])
    assert res.index.tolist() == [0, 1] and res.residual.shape == (2, 2)
    assert rel(res.fmap[0], bent["C_gt"]) == 0
    assert rel(res.fmap[1], bent["C_gt"]) < 0.1  # S_y is only approximately a symmetry of y
    # unbatched, and the scale of the map does not matter
    one = resolve_symmetry(5.0 * bent["C_flip"], bent["sym"], bent["Ox"], bent["Oy"])
    assert int(one.index) == 1 and one.fmap.shape == bent["C_gt"].shape
    # operators computed at a larger K serve through their leading block
    assert int(resolve_symmetry(bent["C_flip"][:20, :10], bent["sym"][:, :20, :20], bent["Ox"],
                                bent["Oy"]).index) == 1


def test_resolve_symmetry_skips_padded_elements(bent):
    K = bent["sym"].shape[-1]
    padded = torch.cat([bent["sym"][:1], torch.zeros(1, K, K, dtype=F64)])  # a C1 group, padded to 2
    res = resolve_symmetry(bent["C_flip"], padded, bent["Ox"], bent["Oy"], mask_y=torch.tensor([True, False]))
    assert int(res.index) == 0 and res.residual[1] == float("inf")
    res = resolve_symmetry(bent["C_flip"], padded, bent["Ox"], bent["Oy"])  # zero matrices never win
    assert int(res.index) == 0 and res.residual[1] == float("inf")
    with pytest.raises(ValueError, match=r"mask_y must be \[..., G\] = \[..., 2\], got \[3\]"):
        resolve_symmetry(bent["C_flip"], padded, bent["Ox"], bent["Oy"], mask_y=torch.ones(3, dtype=bool))


def test_resolve_symmetry_value_errors(bent):
    C, Ox, Oy, sym = bent["C_gt"], bent["Ox"], bent["Oy"], bent["sym"]
    with pytest.raises(ValueError, match=r"sym_fmap_y must be \[..., G, K_y, K_y\]"):
        resolve_symmetry(C, sym[:, :20, :20], Ox, Oy)
    with pytest.raises(ValueError, match=r"O_x must be \[..., D, K, K\] with K >= 30, got \[8, 20, 20\]"):
        orientation_residual(C, Ox[:, :20, :20], Oy)
    with pytest.raises(ValueError, match="O_x has D=8 descriptors but O_y has D=4"):
        orientation_residual(C, Ox, Oy[:4])
    with pytest.raises(ValueError, match=r"C_xy must be \[..., K_y, K_x\], got \[30\]"):
        orientation_residual(C[0], Ox, Oy)


def test_orientation_agreement_and_p2p_resolution(blob, bent):
    verts, faces, mirror = blob[0], blob[1], blob[2]
    vy, ident = bent["vy"], torch.arange(len(verts))
    vote = orientation_agreement(torch.stack([ident, mirror]), verts, faces, vy, faces)
    assert float(vote[0]) == 1.0 and float(vote[1]) < -0.99, vote.tolist()
    sym = torch.stack([ident, mirror])
    res = resolve_symmetry_p2p(mirror, verts, faces, vy, faces, sym)
    assert int(res.index) == 1 and torch.equal(res.p2p, ident)  # the mirror is an involution
    res = resolve_symmetry_p2p(torch.stack([ident, mirror]), verts, faces, vy, faces, sym)
    assert res.index.tolist() == [0, 1] and torch.equal(res.p2p, ident.expand(2, -1))
    # a collapsed map votes for nothing
    assert float(orientation_agreement(torch.zeros_like(ident), verts, faces, vy, faces)) == 0
    # padded group elements (rows of -1) are skipped
    padded = torch.stack([ident, torch.full_like(ident, -1)])
    res = resolve_symmetry_p2p(mirror, verts, faces, vy, faces, padded, mask_y=torch.tensor([True, False]))
    assert int(res.index) == 0 and res.vote[1] == -float("inf")


def test_p2p_value_errors(blob):
    verts, faces, mirror = blob[0], blob[1], blob[2]
    with pytest.raises(ValueError, match=r"p2p_yx must be \[..., 642\] long vertex ids, got \[641\]"):
        orientation_agreement(mirror[1:], verts, faces, verts, faces)
    with pytest.raises(ValueError, match="p2p_yx index out of range"):
        orientation_agreement(mirror + 1, verts, faces, verts, faces)
    with pytest.raises(ValueError, match=r"sym_p2p_y must be \[..., G, V_y\], got \[642\]"):
        resolve_symmetry_p2p(mirror, verts, faces, verts, faces, mirror)
    with pytest.raises(ValueError, match=r"faces_y must be \[F, 3\] long"):
        orientation_agreement(mirror, verts, faces, verts, faces.double())
    with pytest.raises(ValueError, match=r"p2p_yx must be \[..., 642\] long vertex ids, got \[10\]"):
        resolve_symmetry_p2p(mirror[:10], verts, faces, verts, faces, mirror[None])


def test_resolution_on_device(bent, blob, cuda_device):
    d = cuda_device
    C = torch.stack([bent["C_gt"], bent["C_flip"]]).to(d)
    res = resolve_symmetry(C, bent["sym"].to(d), bent["Ox"].to(d), bent["Oy"].to(d))
    assert res.index.device == C.device and res.index.tolist() == [0, 1]
    verts, faces, mirror = (t.to(d) for t in blob[:3])
    res = resolve_symmetry_p2p(mirror, verts, faces, bent["vy"].to(d), faces,
                               torch.stack([torch.arange(len(mirror), device=d), mirror]))
    assert res.p2p.device == verts.device and int(res.index) == 1


# ------------------------------------------------------------------------- a real remeshed pair
def _faust(name, k):
    from symtorch.data import read_sample

    path = shared_path("bcicp_5k", "FAUST", "vtx_5k", f"{name}.off")
    if path is None:
        pytest.skip("shared data not found: bcicp_5k/FAUST/vtx_5k (set $SYMTORCH_SHARED)")
    s = read_sample(path, dtype=F64, ground_truth="vts")
    spec, d = spectrum_and_wks(s["verts"], s["faces"], k=k, n_wks=16)
    s.update(evecs=spec.evecs, mass=spec.mass,
             O=orientation_operators(s["verts"], s["faces"], spec.evecs, spec.mass, d))
    return s


@pytest.mark.filterwarnings("ignore:.*duplicated vertices")
def test_resolution_on_faust_remeshed_pair():
    from symtorch.data import corr_to_fmap
    from symtorch.maps import nearest_neighbors

    k = 30
    a, b = _faust("tr_reg_000", k), _faust("tr_reg_011", k)
    for x, y in ((a, b), (b, a)):
        ex, ey = x["evecs"], y["evecs"]
        S_y = corr_to_fmap(y["corr_sym"], y["corr"], ey, ey, y["mass"])  # y's reflection
        sym = torch.stack([torch.eye(k, dtype=F64), S_y])
        C_gt = corr_to_fmap(x["corr"], y["corr"], ex, ey, y["mass"])
        C_flip = corr_to_fmap(x["corr_sym"], y["corr"], ex, ey, y["mass"])
        res = resolve_symmetry(torch.stack([C_gt, C_flip]), sym, x["O"], y["O"])
        assert res.index.tolist() == [0, 1], f"{x['name']} -> {y['name']}: {res.residual.tolist()}"
        assert rel(res.fmap[1], C_gt) < 0.3
        # point maps through the template: each vertex of y via its nearest template point
        near = nearest_neighbors(y["verts"], y["verts"][y["corr"]])
        sym_p2p = torch.stack([torch.arange(len(near)), y["corr_sym"][near]])
        p2p = torch.stack([x["corr"][near], x["corr_sym"][near]])
        res = resolve_symmetry_p2p(p2p, x["verts"], x["faces"], y["verts"], y["faces"], sym_p2p)
        assert res.index.tolist() == [0, 1], f"{x['name']} -> {y['name']}: {res.vote.tolist()}"
