"""scripts/build_scape_r.py on poses built in code: layout, 1-based ids, closest vertices, resume.

Needs the optional remesher (``pip install pyacvd``); skipped without it. No shared data is read.
"""
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from symtorch.io import MeshWarning, mesh_report, read_mesh
from symtorch.remesh import orientation_report
from symtorch.shapes import mirror_blob, symmetry_maps, true_symmetries
from script_loader import SCRIPTS, load_script

pytest.importorskip("pyacvd", reason="remeshing needs pyacvd (pip install pyacvd; brings pyvista and vtk)")



def _load_script():
    return load_script("build_scape_r")


@pytest.fixture(scope="module")
def bs():
    return _load_script()


def _poses():
    """Two poses on one template numbering: the mirror blob, and the blob stretched and sheared."""
    verts, faces = mirror_blob(3)  # 642 vertices
    bent = verts * [1.0, 0.9, 1.25]
    bent[:, 2] += 0.15 * bent[:, 1] ** 2  # keeps x -> -x a symmetry (intrinsically and extrinsically)
    sym = symmetry_maps(verts, true_symmetries("mirror_blob"))[1]
    return [("blob_a", verts, faces), ("blob_b", bent, faces)], sym


def _read_ids(path: Path) -> np.ndarray:
    return np.loadtxt(path, dtype=np.int64, ndmin=1)


@pytest.fixture(scope="module")
def built(bs, tmp_path_factory):
    out = tmp_path_factory.mktemp("scape_r")
    shapes, sym = _poses()
    config = bs.BuildConfig(n_verts=300, subdivide=2, n_check=16, corres="nearest", vertex_tolerance=0.05)
    records = bs.build(shapes, out, config, sym=sym, notes={"command": "test"})
    return out, shapes, sym, config, records


def test_layout_and_manifest(built):
    out, shapes, _, _, records = built
    assert [r.name for r in records] == ["blob_a", "blob_b"]
    for name, _, _ in shapes:
        for rel in (f"off/{name}.off", f"corres/{name}.vts", f"corres/{name}.sym.vts"):
            assert (out / rel).is_file(), rel
    assert (out / "README.md").is_file() and (out / "template_reflection.txt").is_file()
    manifest = json.loads((out / "manifest.json").read_text())
    assert [s["name"] for s in manifest["shapes"]] == ["blob_a", "blob_b"]
    assert manifest["config"]["n_verts"] == 300 and manifest["versions"]["pyacvd"]
    for s in manifest["shapes"]:
        mesh = read_mesh(out / "off" / f"{s['name']}.off")
        assert s["n_vertices"] == len(mesh.verts) and s["n_faces"] == len(mesh.faces)
        assert s["n_source_vertices"] == 642


def test_remesh_is_clean_and_oriented_like_the_source(built):
    out, shapes, _, config, _ = built
    for name, verts, faces in shapes:
        with warnings.catch_warnings():
            warnings.simplefilter("error", MeshWarning)  # no suspicious-mesh warning on reading
            mesh = read_mesh(out / "off" / f"{name}.off")
        rep = mesh_report(mesh.verts, mesh.faces)
        assert rep["is_closed"] and rep["n_components"] == 1 and rep["genus"] == 0, (name, rep)
        assert rep["n_degenerate_faces"] == 0, name
        assert abs(rep["n_vertices"] - config.n_verts) <= config.vertex_tolerance * config.n_verts, rep
        orient = orientation_report(mesh.verts, mesh.faces)
        assert orient["n_misoriented_edges"] == 0 and orient["outward"], (name, orient)
        assert orientation_report(verts, faces)["outward"]
        assert abs(rep["area"] / mesh_report(verts, faces)["area"] - 1) < 0.05, name


def test_ids_one_based_in_range_and_closest(built):
    out, shapes, sym, _, _ = built
    for name, verts, _ in shapes:
        remesh = read_mesh(out / "off" / f"{name}.off").verts
        vts = _read_ids(out / "corres" / f"{name}.vts")
        sym_vts = _read_ids(out / "corres" / f"{name}.sym.vts")
        assert vts.shape == sym_vts.shape == (len(verts),), name
        for ids in (vts, sym_vts):
            assert ids.min() >= 1 and ids.max() <= len(remesh), (name, ids.min(), ids.max())
        # closest-point property: line t names the remeshed vertex nearest to source vertex t
        d = np.linalg.norm(verts[:, None] - remesh[None], axis=2)  # [V_src, V_remesh]
        best = d.min(axis=1)
        np.testing.assert_allclose(d[np.arange(len(verts)), vts - 1], best, rtol=0, atol=1e-12,
                                   err_msg=name)
        # line t of .sym.vts is the remeshed vertex of the mirror image of template vertex t
        np.testing.assert_array_equal(sym_vts, vts[sym], err_msg=name)
    np.testing.assert_array_equal(_read_ids(out / "template_reflection.txt"), sym + 1)


def test_remeshes_are_independent(built):
    out, shapes, _, _, records = built
    a, b = (read_mesh(out / "off" / f"{n}.off") for n, _, _ in shapes)
    assert not (a.faces.shape == b.faces.shape and np.array_equal(a.faces, b.faces))
    # located in template coordinates, few vertices of one remesh coincide with the other's
    assert records[1].coincide_prev is not None and records[1].coincide_prev < 0.1, records[1]


def test_checks_are_small(built):
    *_, records = built
    for r in records:
        assert r.corr_mean < 0.05 and r.corr_max < 0.15, r  # x sqrt(area): a fraction of an edge
        assert r.sym_median is not None and r.sym_median < 0.05, r  # a mirror-symmetric shape
        assert r.klc_rate is None  # no feature points given


def test_resume_skips_built_shapes(bs, built):
    out, shapes, sym, config, _ = built
    files = [p for p in sorted(out.rglob("*")) if p.is_file() and p.suffix in (".off", ".vts")]
    before = {p: p.read_bytes() for p in files}
    records = bs.build(shapes, out, config, sym=sym)
    assert all(r.skipped for r in records)
    after = {p: p.read_bytes() for p in before}
    assert before == after
    assert not list(out.rglob("*.tmp")), "temporary files left behind"


def test_same_sheet_default_matches_nearest_on_a_convex_shape(bs, tmp_path):
    shapes, sym = _poses()
    config = bs.BuildConfig(n_verts=200, subdivide=2, n_check=8, vertex_tolerance=0.05)
    assert config.corres == "same_sheet"
    (rec,) = bs.build(shapes[:1], tmp_path, config, sym=sym)
    name, verts, _ = shapes[0]
    remesh = read_mesh(tmp_path / "off" / f"{name}.off").verts
    vts = _read_ids(tmp_path / "corres" / f"{name}.vts") - 1
    near = np.linalg.norm(verts[:, None] - remesh[None], axis=2).argmin(axis=1)
    assert np.mean(vts == near) > 0.99 and rec.differ < 0.01, rec


def test_unknown_corres_method_raises(bs):
    verts, faces = mirror_blob(1)
    with pytest.raises(ValueError, match="corres must be one of"):
        bs.carry_correspondence(verts, faces, verts, faces, "closest")


def test_refuses_to_write_inside_the_repository(bs, capsys):
    assert bs.main(["--out", str(SCRIPTS.parent / "data_r"), "--limit", "0"]) == 2
    assert "inside the repository" in capsys.readouterr().err
