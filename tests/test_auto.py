"""symtorch.detect.auto: detect_symmetries, its input checks, devices, and which path it takes."""
import warnings

import numpy as np
import pytest
import torch

from symtorch import detect_symmetries, laplacian_spectrum, shapes
from symtorch.detect.group_path import has_multiplicities
from symtorch.eval.groups import rigid_residual
from symtorch.geodesics import GeodesicSolver
from symtorch.shapes import mirror_blob

from shapes import SUB, detect_quietly, mirror_cloud  # tests/shapes.py


pytestmark = pytest.mark.usefixtures("one_thread")


def test_detect_accepts_a_precomputed_spectrum(mirror3):
    v, f, mirror = mirror3
    spec = laplacian_spectrum(v, f, k=90)
    res = detect_symmetries(v, f, spectrum=spec, mode="reflection")
    assert res.spectrum is spec
    assert torch.equal(res.reflection.p2p, mirror)


def test_detect_errors():
    v, f = mirror_blob(1)
    with pytest.raises(ValueError, match="a point cloud needs at least 100 points"):
        detect_symmetries(v, None)
    with pytest.raises(ValueError, match="mode"):
        detect_symmetries(v, f, mode="nope")
    two_v = np.concatenate([v, v + 10.0])
    two_f = np.concatenate([f, f + len(v)])
    with pytest.raises(ValueError, match="2 connected components"):
        detect_symmetries(two_v, two_f)


def test_detect_with_a_spectrum_on_device(mirror3, device):
    """A spectrum on ``device`` (as a GPU data pipeline holds it): the result comes back there, the
    same as from the CPU spectrum."""
    v, f, mirror = mirror3
    spec = laplacian_spectrum(v, f, k=86)
    ref = detect_symmetries(v, f, spectrum=spec, mode="reflection")
    res = detect_symmetries(v, f, spectrum=spec.to(device), mode="reflection")
    assert res.spectrum.evecs.device == torch.device(device)
    assert [s.kind for s in res.symmetries] == ["identity", "reflection"]
    for s, r in zip(res.symmetries, ref.symmetries):
        assert s.fmap.device == s.p2p.device == torch.device(device)
        assert torch.equal(s.p2p.cpu(), r.p2p)
        torch.testing.assert_close(s.fmap.cpu(), r.fmap)
    assert torch.equal(res.reflection.p2p.cpu(), mirror)
    assert res.fmaps.device == res.p2ps.device == torch.device(device)


def test_auto_mode_chooses_the_path():
    v, f = shapes.star_prism(SUB)
    res = detect_quietly(v, f, mode="auto")
    assert res.group.name == "D5h" and res.diagnostics.path == "group"
    v, f = shapes.mirror_blob(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = detect_symmetries(v, f)  # mirror: the reflection path, with its group report
    assert res.group.name == "Cs" and res.diagnostics.path == "reflection"
    assert [s.kind for s in res.symmetries] == ["identity", "reflection"]
    assert res.diagnostics.group is None  # a simple spectrum and a verified mirror: no second opinion


def test_auto_mode_asks_the_group_path_where_no_reflection_verifies():
    """A two-bladed propeller has a half turn and no mirror: its irreducible representations are
    1-D, so the spectrum is simple and the automatic mode starts with the reflection path, which
    finds no reflection; the group path then finds C2."""
    v, f = shapes.propeller(subdivisions=3, blades=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert not has_multiplicities(laplacian_spectrum(v, f, k=60).evals)
        res = detect_symmetries(v, f)
        alone = detect_symmetries(v, f, mode="reflection")
    assert len(alone.symmetries) == 1
    assert res.group.name == "C2" and [s.kind for s in res.symmetries] == ["identity", "rotation"]
    assert res.diagnostics.path == "group"


@pytest.mark.parametrize("name, group", [("cube", "D2h"), ("cone33", "C2v"), ("cone3", "C3v")])
def test_auto_mode_on_the_iglict_shapes(shared_data, name, group):
    """Qiao et al.'s exactly symmetric test shapes (a box, an elliptic cone, a three-fold cone): the
    box and the elliptic cone have too few heat-kernel extrema for the reflection path to pair, so
    the automatic mode finds their groups through the group path; every element is one of the
    shape's rigid symmetries."""
    from symtorch.io import read_mesh

    path = shared_data / "iglict_intrinsicsym" / f"{name}.obj"
    if not path.exists():
        pytest.skip(f"{path} not found")
    mesh = read_mesh(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = detect_symmetries(mesh)
    assert res.group.name == group, res.diagnostics.group
    for s in res.symmetries:
        assert rigid_residual(mesh.verts, s.p2p.numpy()) < 0.02, s.kind


def test_group_path_batched_stages_on_device(device):
    """``device=``: the candidate stages run there; the same group, the result on the CPU spectrum's
    device."""
    v, f = shapes.table(SUB)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = detect_symmetries(v, f, mode="group", k_refine=40)
        res = detect_symmetries(v, f, mode="group", k_refine=40, device=device)
    assert res.group.name == ref.group.name == "C4v"
    assert res.p2ps.device.type == "cpu"
    # the same elements: each found map is one of the CPU run's maps on >= 95 % of the vertices
    agree = (res.p2ps[:, None] == ref.p2ps[None]).float().mean(-1)  # [G, G]
    assert bool((agree.max(1).values >= 0.95).all()), agree.max(1).values


@pytest.mark.extended
def test_auto_mode_finds_c2v_on_a_table_with_a_simple_spectrum(shared_data):
    """Watertight 152 (C2v: two mirrors and a half turn, all irreducible representations 1-D, so no
    repeated eigenvalues): the reflection path sees three equally consistent involutions of its
    extrema and the automatic mode asks the group path, which finds C2v."""
    from symtorch.eval.benchmarks import load_mesh

    v, f = load_mesh(shared_data / "bim_scb_benchmark" / "Watertight" / "Meshes" / "152.off")
    res = detect_symmetries(v, f)
    assert res.group.name == "C2v" and len(res.symmetries) == 4, res.diagnostics.group
    assert sorted(s.kind for s in res.symmetries) == ["identity", "reflection", "reflection", "rotation"]
    assert detect_symmetries(v, f, group_tol=0).group.name == "Cs"  # the reflection path alone


@pytest.mark.extended
def test_auto_mode_factors_the_geodesic_solver_once_for_both_paths(shared_data, monkeypatch):
    """Watertight 152 goes through both paths (above); they share one heat-method factorisation."""
    import symtorch.detect.group_path as group_detect
    import symtorch.detect.reflection as reflect
    from symtorch.eval.benchmarks import load_mesh

    made, passed = [], []
    real_init = GeodesicSolver.__init__

    def counting_init(self, *a, **kw):
        made.append(self)
        real_init(self, *a, **kw)

    def recording(fn):
        def wrapped(*a, **kw):
            passed.append(kw.get("solver"))
            return fn(*a, **kw)
        return wrapped

    monkeypatch.setattr(GeodesicSolver, "__init__", counting_init)
    monkeypatch.setattr(group_detect, "detect_group", recording(group_detect.detect_group))
    monkeypatch.setattr(reflect, "detect_reflection", recording(reflect.detect_reflection))
    v, f = load_mesh(shared_data / "bim_scb_benchmark" / "Watertight" / "Meshes" / "152.off")
    res = detect_symmetries(v, f)
    assert res.group.name == "C2v" and len(passed) == 2  # both paths ran
    assert len(made) == 1 and passed[0] is made[0] and passed[1] is made[0]


def test_tiny_and_huge_coordinates_are_detected_like_the_unit_mesh():
    # areas of 1e-150 coordinates underflow float64: the detector rescales by a power of two
    import numpy as np

    from symtorch import detect_symmetries, shapes

    verts, faces = shapes.mirror_blob()
    ref = detect_symmetries(np.asarray(verts), faces)
    for scale in (1e-150, 1e150):
        res = detect_symmetries(np.asarray(verts) * scale, faces)
        assert [s.kind for s in res.symmetries] == [s.kind for s in ref.symmetries] == \
            ["identity", "reflection"]
        assert (res.p2ps == ref.p2ps).all()


# ------------------------------------------------------------------------------------ point clouds
def test_detect_on_a_point_cloud_finds_the_mirror(mirror3):
    """The vertices alone: the point-cloud Laplacian and heat method, the same result fields."""
    v, f, mirror = mirror3
    res = detect_symmetries(v)  # no faces
    assert res.input == "point_cloud" and res.group.name == "Cs"
    assert [s.kind for s in res.symmetries] == ["identity", "reflection"]
    # the fans without their bridges are not exactly symmetric (the normals' signs decide ties)
    assert (res.reflection.p2p == mirror).double().mean() > 0.99
    assert res.fmaps.dtype == torch.float64 and res.p2ps.shape == (2, len(v))
    assert "triangulation" in res.timings
    mesh = detect_symmetries(v, f)
    d, dm = res.to_dict(), mesh.to_dict()
    assert set(d) == set(dm) and d["input"] == "point_cloud" and dm["input"] == "mesh"
    assert res.fmaps.shape == mesh.fmaps.shape


def test_detect_on_the_point_cloud_tools_as_they_are(mirror3):
    """``cloud_min_cos=None``: robust_laplacian's point-cloud Laplacian and potpourri3d's
    point-cloud heat method, unchanged; on the exactly symmetric vertices, the exact mirror."""
    v, _, mirror = mirror3
    res = detect_symmetries(v, cloud_min_cos=None)
    assert res.group.name == "Cs" and torch.equal(res.reflection.p2p, mirror)


def test_detect_on_surface_samples():
    """Random points on a mirror-symmetric surface (no mesh vertex among them), as a Mesh without
    faces: its exact mirror permutation is found."""
    from symtorch.io import Mesh

    points, mirror = mirror_cloud(600)
    res = detect_symmetries(Mesh(points, None, "cloud.ply"))
    assert res.group.name == "Cs" and res.input == "point_cloud"
    agree = (res.reflection.p2p.numpy() == mirror).mean()
    assert agree > 0.99, f"mirror found on {agree:.3f} of the points"


def test_detect_on_an_asymmetric_point_cloud_reports_no_mirror():
    points, _ = mirror_cloud(600)
    x = points[:, 0]
    bumped = points + np.exp(-((points - points[np.argmax(x)]) ** 2).sum(1) / 0.05)[:, None] * points * 0.5
    res = detect_symmetries(bumped, mode="reflection")
    assert res.group.name == "C1", res.info


@pytest.mark.parametrize("make, match", [
    (lambda p: p[:50], "at least 100 points"),
    (lambda p: np.where(np.arange(len(p))[:, None] == 7, np.nan, p), "NaN or inf"),
    (lambda p: np.vstack([p, p[:4]]), "4 duplicated points"),
    (lambda p: np.vstack([p, p + [10.0, 0, 0]]), "point cloud has 2 separate parts"),
])
def test_detect_point_cloud_errors(make, match):
    points, _ = mirror_cloud(300)
    with pytest.raises(ValueError, match=match):
        detect_symmetries(make(points))
