"""Tests for symtorch.io: order-preserving round trips, real files, and a corpus of bad input."""
from __future__ import annotations

import json
import logging
import os
import re
import warnings

import numpy as np
import pytest
import torch
import trimesh

from symtorch.io import Mesh, MeshWarning, mesh_report, read_mesh, write_mesh
from symtorch.paths import shared_path

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"  # OBJ vertices of one unit right triangle


def shuffled_icosphere(subdivisions: int = 2, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Icosphere (162 vertices at 2 subdivisions) with its vertices in a random order."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    verts, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    perm = np.random.default_rng(seed).permutation(len(verts))  # new vertex j = old vertex perm[j]
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(perm))
    return verts[perm], inv[faces]


def write_text(tmp_path, name: str, content: str | bytes):
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


def read_quietly(path) -> Mesh:
    """read_mesh, failing the test on any MeshWarning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeshWarning)
        return read_mesh(path)


def read_warning(path, pattern: str) -> tuple[Mesh, list[str]]:
    """read_mesh, asserting that one MeshWarning starts with the path and matches pattern."""
    with pytest.warns(MeshWarning) as record:
        mesh = read_mesh(path)
    messages = [str(w.message) for w in record if issubclass(w.category, MeshWarning)]
    hits = [m for m in messages if m.startswith(f"{path}: ") and re.search(pattern, m)]
    assert hits, f"no warning matching {pattern!r} for {path.name}; got {messages}"
    assert all("\n" not in m for m in messages), messages
    return mesh, messages


def ply_ascii(verts: list[str], faces: list[str]) -> str:
    header = ["ply", "format ascii 1.0", f"element vertex {len(verts)}", "property float x",
              "property float y", "property float z"]
    if faces:
        header += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    return "\n".join(header + ["end_header"] + verts + faces) + "\n"


# ---------------------------------------------------------------------------------- round trips

@pytest.mark.parametrize("ext", [".off", ".obj", ".ply"])
def test_round_trip_keeps_vertex_order_exactly(tmp_path, ext):
    verts, faces = shuffled_icosphere()
    path = tmp_path / f"sphere{ext}"
    write_mesh(path, verts, faces)
    mesh = read_quietly(path)
    assert isinstance(mesh, Mesh) and mesh.path == str(path)
    assert mesh.verts.dtype == np.float64 and mesh.faces.dtype == np.int64
    np.testing.assert_array_equal(mesh.verts, verts, err_msg=f"ext={ext}")  # bit-exact
    np.testing.assert_array_equal(mesh.faces, faces, err_msg=f"ext={ext}")


@pytest.mark.parametrize("ext", [".off", ".obj", ".ply"])
def test_round_trip_point_cloud(tmp_path, ext):
    verts = np.random.default_rng(1).normal(size=(20, 3))
    path = tmp_path / f"cloud{ext}"
    write_mesh(path, verts, None)
    mesh = read_quietly(path)
    assert mesh.faces is None, f"ext={ext}"
    np.testing.assert_array_equal(mesh.verts, verts, err_msg=f"ext={ext}")


def test_write_accepts_tensors_and_overwrites_atomically(tmp_path):
    verts, faces = shuffled_icosphere(subdivisions=1)
    path = tmp_path / "sphere.off"
    path.write_text("old content")
    write_mesh(path, torch.from_numpy(verts).float(), torch.from_numpy(faces))
    mesh = read_quietly(path)
    np.testing.assert_allclose(mesh.verts, verts, atol=1e-6)
    assert sorted(os.listdir(tmp_path)) == ["sphere.off"], "temporary file left behind"


def test_write_failure_leaves_old_file_and_no_temporary(tmp_path, monkeypatch):
    verts, faces = shuffled_icosphere(subdivisions=1)
    path = tmp_path / "sphere.obj"
    path.write_text("old content")

    def failing_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError, match="disk full"):
        write_mesh(path, verts, faces)
    assert path.read_text() == "old content"
    assert sorted(os.listdir(tmp_path)) == ["sphere.obj"]


@pytest.mark.parametrize("ext,verts,faces,match", [
    (".stl", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], r"cannot write \.stl"),
    (".off", [[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]], [[0, 1, 2]], r"NaN or inf"),
    (".off", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]], r"out of range"),
    (".ply", [[0, 0, 0], [1, 0, 0]], [[0, 1, 2, 0]], r"must be \[F, 3\]"),
    (".obj", [[0, 0], [1, 0]], None, r"must be \[V, 3\]"),
])
def test_write_rejects_bad_input(tmp_path, ext, verts, faces, match):
    path = tmp_path / f"bad{ext}"
    with pytest.raises(ValueError, match=match):
        write_mesh(path, np.array(verts, dtype=float), None if faces is None else np.array(faces))
    assert not os.listdir(tmp_path), "nothing is written for bad input"


# ---------------------------------------------------------------------------------- real files

@pytest.mark.parametrize("parts,n_verts,n_faces,first_vertex", [
    (("bim_scb_benchmark", "SCAPE", "Meshes", "mesh000.off"), 12500, 24998,
     [0.0148762, -0.0614501, 0.276644]),
    (("iglict_intrinsicsym", "cone3.obj"), 1538, 3072, [0.0, -1.5, 0.0]),
])
def test_real_text_files(parts, n_verts, n_faces, first_vertex):
    path = shared_path(*parts)
    if path is None:
        pytest.skip(f"shared data file {'/'.join(parts)} not found (set $SYMTORCH_SHARED)")
    mesh = read_quietly(path)
    assert mesh.verts.shape == (n_verts, 3) and mesh.faces.shape == (n_faces, 3)
    np.testing.assert_array_equal(mesh.verts[0], first_vertex)
    # every vertex used, indices 0-based (OBJ's 1-based indices shifted by one)
    assert mesh.faces.min() == 0 and mesh.faces.max() == n_verts - 1
    rep = mesh_report(mesh.verts, mesh.faces)
    assert rep["n_components"] == 1 and rep["is_closed"] and rep["n_unreferenced"] == 0, rep


def test_real_binary_ply_matches_trimesh():
    path = shared_path("pyvista_builtin", "ant.ply")
    if path is None:
        pytest.skip("shared data file pyvista_builtin/ant.ply not found (set $SYMTORCH_SHARED)")
    mesh, _ = read_warning(path, r"connected components")  # the ant's legs are separate parts
    ref = trimesh.load(path, process=False, maintain_order=True)
    assert mesh.verts.shape == (486, 3) and mesh.faces.shape == (912, 3)
    np.testing.assert_array_equal(mesh.verts, ref.vertices)
    np.testing.assert_array_equal(mesh.faces, ref.faces)


# ---------------------------------------------------------------------- bad input: raises

GARBAGE = b"\x00\xff" + np.random.default_rng(0).bytes(510)

RAISES = [
    ("empty.off", "", r"file is empty"),
    ("empty.obj", "", r"file is empty"),
    ("empty.ply", "", r"file is empty"),
    ("comments.off", "# nothing\n\n   \n", r"no content besides comments"),
    ("comments.obj", "# nothing\nvn 0 0 1\n", r"no vertices found"),
    ("garbage.off", GARBAGE, r"binary data"),
    ("garbage.obj", GARBAGE, r"binary data"),
    ("garbage.ply", GARBAGE, r"cannot read it as \.ply"),
    ("garbage.stl", GARBAGE, r"no geometry found|no vertices found"),
    ("garbage.xyz123", GARBAGE, r"cannot read it as \.xyz123"),
    ("text.off", "hello world\nnot a mesh\n", r"not an OFF file"),
    ("binary_header.off", "OFF BINARY\n", r"binary OFF is not supported"),
    ("four_d.off", "4OFF\n1 0 0\n0 0 0 0\n", r"only 3D OFF"),
    ("counts.off", "OFF\nthree one zero\n", r"bad OFF count line"),
    ("truncated.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n", r"truncated"),
    ("short_vertex.off", "OFF\n3 0 0\n0 0 0\n1 0\n0 1 0\n", r"fewer than 3 coordinates"),
    ("words.off", "OFF\n3 0 0\n0 0 0\n1 0 zero\n0 1 0\n", r"cannot parse vertex"),
    ("two_gon.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n2 0 1\n", r"face 1 declares 2"),
    ("two_gon.obj", TRI + "f 1 2\n", r"line 4: face has 2 vertices"),
    ("nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n", r"NaN or inf.*index 1"),
    ("inf.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 -inf 0\n3 0 1 2\n", r"NaN or inf.*index 2"),
    ("nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", r"NaN or inf"),
    ("inf.obj", "v inf 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"NaN or inf"),
    ("nan.ply", ply_ascii(["0 0 0", "1 0 0", "0 nan 0"], ["3 0 1 2"]), r"NaN or inf"),
    ("nan_cloud.off", "OFF\n2 0 0\n0 0 0\ninf 0 0\n", r"NaN or inf"),
    ("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n", r"out of range.*\[0, 5\].*3 vertices"),
    ("negative.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", r"out of range"),
    ("range.obj", TRI + "f 1 2 7\n", r"out of range.*\[0, 6\]"),
    ("zero_index.obj", TRI + "f 0 1 2\n", r"index 0 \(OBJ indices are 1-based\)"),
    ("negative.obj", TRI + "f -1 -2 -5\n", r"out of range"),
    ("range.ply", ply_ascii(["0 0 0", "1 0 0", "0 1 0"], ["3 0 1 9"]), r"out of range"),
    ("zero_area.off", "OFF\n3 1 0\n1 1 1\n1 1 1\n1 1 1\n3 0 1 2\n", r"zero total area"),
    ("collinear.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 3 2 1\n", r"zero total area"),
]


@pytest.mark.parametrize("name,content,match", RAISES, ids=[r[0] for r in RAISES])
def test_bad_input_raises_one_line_value_error(tmp_path, name, content, match):
    path = write_text(tmp_path, name, content)
    with pytest.raises(ValueError, match=match) as info:
        read_mesh(path)
    message = str(info.value)
    assert message.startswith(f"{path}: "), message
    assert "\n" not in message, message
    err = info.value
    assert err.__cause__ is None and (err.__context__ is None or err.__suppress_context__), \
        "no chained traceback from the parser or trimesh"


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"missing\.off: no such file"):
        read_mesh(tmp_path / "missing.off")
    (tmp_path / "folder.off").mkdir()
    with pytest.raises(ValueError, match=r"folder\.off: not a regular file"):
        read_mesh(tmp_path / "folder.off")


# ---------------------------------------------------------------------- bad input: warns

@pytest.mark.parametrize("name,content,faces", [
    ("quad.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n", [[0, 1, 2], [0, 2, 3]]),
    ("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", [[0, 1, 2], [0, 2, 3]]),
    ("pentagon.off", "OFF\n5 1 0\n0 0 0\n1 0 0\n1 1 0\n.5 2 0\n0 1 0\n5 0 1 2 3 4\n",
     [[0, 1, 2], [0, 2, 3], [0, 3, 4]]),
    ("pentagon.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv .5 2 0\nv 0 1 0\nf 1/1 2/2 3/3 4/4 5/5\n",
     [[0, 1, 2], [0, 2, 3], [0, 3, 4]]),
    ("mixed.off", "OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n.5 2 0\n4 0 1 2 3\n3 3 2 4\n",
     [[0, 1, 2], [0, 2, 3], [3, 2, 4]]),
])
def test_polygons_are_triangulated_fan_wise(tmp_path, name, content, faces):
    path = write_text(tmp_path, name, content)
    mesh, messages = read_warning(path, r"1 polygon faces \(4\+ vertices\) triangulated fan-wise")
    np.testing.assert_array_equal(mesh.faces, faces)
    assert len(messages) == 1, messages


def test_ply_polygons_warn(tmp_path):
    verts = ["0 0 0", "1 0 0", "1 1 0", "0 1 0", "0.5 2 0"]
    path = write_text(tmp_path, "mixed.ply", ply_ascii(verts, ["4 0 1 2 3", "3 3 2 4"]))
    mesh, _ = read_warning(path, r"2 faces, some of them polygons .* into 3 triangles")
    np.testing.assert_array_equal(mesh.verts[:, :2], [[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 2]])
    assert mesh.faces.shape == (3, 3)
    assert mesh_report(mesh.verts, mesh.faces)["area"] == pytest.approx(1.5)


WARNS = [
    # name, content, warning pattern, (V, F) read back
    ("degenerate.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n2 0 0\n3 0 1 2\n3 0 1 3\n",
     r"1 degenerate \(zero-area\) faces", (4, 2)),
    ("collapsed.obj", TRI + "f 1 2 3\nf 1 1 2\n", r"1 degenerate", (3, 2)),
    ("duplicated.obj", TRI + "v 0 0 0\nf 1 2 3\nf 4 3 2\n", r"1 duplicated vertices", (4, 2)),
    ("unreferenced.obj", "v 0 0 0\nv 9 9 9\nv 1 0 0\nv 0 1 0\nf 1 3 4\n",
     r"1 vertices referenced by no face", (4, 1)),
    ("components.off", "OFF\n6 2 0\n0 0 0\n1 0 0\n0 1 0\n5 0 0\n6 0 0\n5 1 0\n3 0 1 2\n3 3 4 5\n",
     r"2 connected components", (6, 2)),
    ("nonmanifold.obj", TRI + "v 0 0 1\nv 0 -1 0\nf 1 2 3\nf 1 2 4\nf 2 1 5\n",
     r"1 non-manifold edges \(shared by 3\+ faces\)", (5, 3)),
]


@pytest.mark.parametrize("name,content,pattern,shape", WARNS, ids=[w[0] for w in WARNS])
def test_suspicious_input_warns_and_keeps_everything(tmp_path, name, content, pattern, shape):
    path = write_text(tmp_path, name, content)
    mesh, _ = read_warning(path, pattern)
    assert (len(mesh.verts), len(mesh.faces)) == shape, "nothing merged or dropped"


def test_warning_points_at_caller_and_is_logged(tmp_path, caplog):
    path = write_text(tmp_path, "unreferenced.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n9 9 9\n3 0 1 2\n")
    with caplog.at_level(logging.WARNING, logger="symtorch.io"), pytest.warns(MeshWarning) as record:
        read_mesh(path)
    assert record[0].filename == __file__, "stacklevel should blame the caller of read_mesh"
    logged = [r.getMessage() for r in caplog.records if r.name == "symtorch.io"]
    assert logged == [f"{path}: 1 vertices referenced by no face (kept; indices unchanged)"]


def test_stl_reads_as_triangle_soup(tmp_path):
    path = tmp_path / "ico.stl"
    trimesh.creation.icosphere(subdivisions=0).export(path)
    mesh, messages = read_warning(path, r"48 duplicated vertices")
    assert mesh.verts.shape == (60, 3) and mesh.faces.shape == (20, 3)
    assert any("20 connected components" in m for m in messages), messages


def test_scene_is_concatenated(tmp_path):
    path = tmp_path / "two.glb"
    trimesh.Scene([trimesh.creation.box(), trimesh.creation.icosphere(subdivisions=1)]).export(path)
    mesh, _ = read_warning(path, r"2 connected components")
    assert mesh.verts.shape == (8 + 42, 3) and mesh.faces.shape == (12 + 80, 3)


# ---------------------------------------------------------------------- valid odd input: works

WORKS = [
    # name, content, faces read back (None: point cloud)
    ("triangle.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", [[0, 1, 2]]),
    ("triangle.obj", TRI + "f 1 2 3\n", [[0, 1, 2]]),
    ("triangle.ply", ply_ascii(["0 0 0", "1 0 0", "0 1 0"], ["3 0 1 2"]), [[0, 1, 2]]),
    ("cloud.off", "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", None),
    ("cloud.obj", TRI, None),
    ("cloud.ply", ply_ascii(["0 0 0", "1 0 0", "0 1 0"], []), None),
    ("edges_count.off", "OFF\n3 1 3\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", [[0, 1, 2]]),
    ("one_line_header.off", "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", [[0, 1, 2]]),
    ("commented.off", "# made by hand\nOFF\n# counts\n3 1 0\n0 0 0 # origin\n1 0 0\n\n0 1 0\n3 0 1 2\n",
     [[0, 1, 2]]),
    ("colours.off", "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n"
     "3 0 1 2 10 20 30\n", [[0, 1, 2]]),
    ("ragged_colours.off", "COFF\n3 1 0\n0 0 0 1 0 0\n1 0 0\n0 1 0 0 0 1\n3 0 1 2 0.5 0.5 0.5\n",
     [[0, 1, 2]]),
    ("negative.obj", TRI + "f -3 -2 -1\n", [[0, 1, 2]]),
    ("slashes.obj", TRI + "vt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3//1\n", [[0, 1, 2]]),
    ("bom.obj", "\ufeff" + TRI + "f 1 2 3\n", [[0, 1, 2]]),
]


@pytest.mark.parametrize("name,content,faces", WORKS, ids=[w[0] for w in WORKS])
def test_valid_input_reads_without_warnings(tmp_path, name, content, faces):
    path = write_text(tmp_path, name, content)
    mesh = read_quietly(path)
    np.testing.assert_array_equal(mesh.verts, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    if faces is None:
        assert mesh.faces is None
    else:
        np.testing.assert_array_equal(mesh.faces, faces)


def test_obj_materials_do_not_split_or_reorder_vertices(tmp_path):
    # trimesh splits an OBJ per material and reorders its vertices; read_mesh must not
    content = ("mtllib none.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 1\n"
               "usemtl a\nf 2/1 4/2 3/1\nusemtl b\nf 1/2 2/1 3/2\n")
    mesh = read_quietly(write_text(tmp_path, "materials.obj", content))
    np.testing.assert_array_equal(mesh.verts, [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    np.testing.assert_array_equal(mesh.faces, [[1, 3, 2], [0, 1, 2]])


# ---------------------------------------------------------------------------------- mesh_report

def test_report_closed_sphere_and_torus():
    verts, faces = shuffled_icosphere()
    rep = mesh_report(verts, faces)
    assert rep["n_vertices"] == 162 and rep["n_faces"] == 320 and rep["n_edges"] == 480
    assert rep["is_closed"] and rep["is_manifold"] and rep["n_components"] == 1
    assert rep["euler_characteristic"] == 2 and rep["genus"] == 0, rep
    assert rep["area"] == pytest.approx(trimesh.Trimesh(verts, faces, process=False).area)
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    rep = mesh_report(torus.vertices, torus.faces)
    assert rep["euler_characteristic"] == 0 and rep["genus"] == 1, rep


def test_report_two_spheres_counts_components_and_sums_genus():
    verts, faces = shuffled_icosphere(subdivisions=1)
    rep = mesh_report(np.vstack([verts, verts + 3.0]), np.vstack([faces, faces + len(verts)]))
    assert rep["n_components"] == 2 and rep["euler_characteristic"] == 4 and rep["genus"] == 0, rep


def test_report_open_and_degenerate_cases_are_json_ready():
    rep = mesh_report(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]]),
                      torch.tensor([[0, 1, 2]]))
    assert rep["n_boundary_edges"] == 3 and not rep["is_closed"] and rep["genus"] is None
    assert rep["n_unreferenced"] == 1 and rep["n_components"] == 1 and rep["area"] == 0.5
    assert json.loads(json.dumps(rep)) == rep, "report must be plain JSON types"
    cloud = mesh_report(np.zeros((4, 3)), None)
    assert cloud["n_faces"] == 0 and cloud["genus"] is None and cloud["n_duplicated_vertices"] == 3
    json.dumps(cloud)
    nonmanifold = mesh_report(np.eye(3).tolist() + [[0, 0, 0], [1, 1, 1]], [[0, 1, 2], [0, 1, 3], [1, 0, 4]])
    assert nonmanifold["n_nonmanifold_edges"] == 1 and not nonmanifold["is_manifold"]


def test_report_rejects_bad_input():
    with pytest.raises(ValueError, match=r"faces index out of range"):
        mesh_report(np.zeros((3, 3)), [[0, 1, 3]])
    with pytest.raises(ValueError, match=r"verts must be \[V, 3\]"):
        mesh_report(np.zeros((3, 2)), None)
