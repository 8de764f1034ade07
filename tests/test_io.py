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
    ("garbage.stl", GARBAGE, r"binary STL|header promises \d+ triangles"),
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


@pytest.mark.parametrize("encoding", ["binary", "ascii"])
def test_stl_vertices_are_merged_in_order_of_appearance(tmp_path, encoding):
    """STL stores each triangle's corners: equal corners become one vertex, first appearance first."""
    sphere = trimesh.creation.icosphere(subdivisions=0)
    path = tmp_path / f"ico_{encoding}.stl"
    path.write_bytes(trimesh.exchange.stl.export_stl(sphere) if encoding == "binary"
                     else trimesh.exchange.stl.export_stl_ascii(sphere).encode())
    mesh = read_quietly(path)  # one closed component, no duplicated vertices
    assert mesh.verts.shape == (12, 3) and mesh.faces.shape == (20, 3)
    soup = trimesh.load(path, process=False)  # a corner per triangle, as the file stores them
    np.testing.assert_array_equal(mesh.verts[mesh.faces], soup.vertices[soup.faces])
    assert mesh.faces[0].tolist() == [0, 1, 2]  # the first triangle's corners come first


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


# ------------------------------------------- what the header promises against what the file holds
# (once, cut files were read with exit 0, a face pointing at vertex 300 instead of 3001)

def _ico_file(tmp_path, ext: str, subdivisions: int = 2):
    """An icosphere written by write_mesh (OFF/OBJ text, PLY binary): (path, bytes, V, F)."""
    verts, faces = shuffled_icosphere(subdivisions)
    path = tmp_path / f"ico{ext}"
    write_mesh(path, verts, faces)
    return path, path.read_bytes(), len(verts), len(faces)


def _raises_one_line(path, pattern: str) -> str:
    with pytest.raises(ValueError, match=pattern) as info:
        read_mesh(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    return message


@pytest.mark.parametrize("ext", [".off", ".obj"])
@pytest.mark.parametrize("cut", [1, 2, 3, 7])
def test_text_file_cut_in_its_last_line_is_an_error(tmp_path, ext, cut):
    """Cutting the last bytes leaves a complete-looking last face (``f 95 12 3`` of ``f 95 12 31``)."""
    path, data, _, _ = _ico_file(tmp_path, ext)
    path.write_bytes(data[:-cut])
    _raises_one_line(path, r"last line .* has no newline at its end: the file looks cut")


@pytest.mark.parametrize("ext", [".off", ".obj"])
def test_text_file_cut_in_the_middle_is_an_error(tmp_path, ext):
    path, data, _, _ = _ico_file(tmp_path, ext)
    path.write_bytes(data[: len(data) // 2])
    _raises_one_line(path, r"truncated: header promises|file looks cut|out of range")


def test_off_face_count_must_match_the_faces_held(tmp_path):
    path, data, V, F = _ico_file(tmp_path, ".off")
    lines = data.decode().splitlines(keepends=True)
    head = lines[1]
    assert head == f"{V} {F} 0\n"
    (tmp_path / "more.off").write_text("OFF\n" + f"{V} {F + 88} 0\n" + "".join(lines[2:]))
    _raises_one_line(tmp_path / "more.off", rf"truncated: header promises {F + 88} faces, file holds {F}$")
    (tmp_path / "fewer.off").write_text("OFF\n" + f"{V} {F - 20} 0\n" + "".join(lines[2:]))
    _raises_one_line(tmp_path / "fewer.off", rf"promises {V} vertices and {F - 20} faces but 20 more "
                                             "data lines follow them")
    (tmp_path / "lines.off").write_text("OFF\n" + f"{V} {F} 0\n" + "".join(lines[2:2 + V // 2]))
    _raises_one_line(tmp_path / "lines.off", rf"header promises {V} vertices and {F} faces, file "
                                             rf"holds {V // 2} vertices and no faces")


def _ascii_ply(verts, faces, n_faces=None) -> str:
    header = ["ply", "format ascii 1.0", f"element vertex {len(verts)}", "property double x",
              "property double y", "property double z",
              f"element face {len(faces) if n_faces is None else n_faces}",
              "property list uchar int vertex_indices", "end_header"]
    body = [" ".join(repr(float(x)) for x in p) for p in verts]
    body += [f"{len(f)} " + " ".join(str(int(i)) for i in f) for f in faces]
    return "\n".join(header + body) + "\n"


def test_ascii_ply_counts_and_cuts(tmp_path):
    verts, faces = shuffled_icosphere(2)
    F = len(faces)
    good = tmp_path / "good.ply"
    good.write_text(_ascii_ply(verts, faces))
    np.testing.assert_array_equal(read_quietly(good).faces, faces)
    text = good.read_text()
    lines = text.splitlines(keepends=True)
    kept = len(lines) - int(0.4 * F)  # 40 % of the faces cut away, at a line end
    (tmp_path / "cut.ply").write_text("".join(lines[:kept]))
    _raises_one_line(tmp_path / "cut.ply", rf"truncated: header promises {F} faces, file holds "
                                           rf"{F - int(0.4 * F)}$")
    (tmp_path / "more.ply").write_text(_ascii_ply(verts, faces, n_faces=F + 5))
    _raises_one_line(tmp_path / "more.ply", rf"header promises {F + 5} faces, file holds {F}")
    (tmp_path / "fewer.ply").write_text(_ascii_ply(verts, faces, n_faces=F - 3))
    _raises_one_line(tmp_path / "fewer.ply", r"3 data lines after the .* records the header promises")
    (tmp_path / "midline.ply").write_text(text[:-3])
    _raises_one_line(tmp_path / "midline.ply", r"face \d+ has 3 numbers|file looks cut")
    (tmp_path / "lastbyte.ply").write_text(text[:-1])
    _raises_one_line(tmp_path / "lastbyte.ply", r"file looks cut")


def test_binary_ply_counts_and_cuts(tmp_path):
    path, data, V, F = _ico_file(tmp_path, ".ply")
    record = 1 + 3 * 4  # uchar count + 3 int32
    for n_cut, held in ((1, F - 1), (record * 100 + 5, F - 101)):
        (tmp_path / "cut.ply").write_bytes(data[:-n_cut])
        _raises_one_line(tmp_path / "cut.ply", rf"truncated: header promises {F} faces, file holds {held}$")
    head_end = data.index(b"end_header\n") + len(b"end_header\n")
    (tmp_path / "verts_cut.ply").write_bytes(data[:head_end + 24 * (V // 3)])
    _raises_one_line(tmp_path / "verts_cut.ply", rf"header promises {V} vertices, file holds {V // 3}$")
    (tmp_path / "more.ply").write_bytes(data.replace(f"element face {F}\n".encode(),
                                                     f"element face {F + 9}\n".encode()))
    _raises_one_line(tmp_path / "more.ply", rf"header promises {F + 9} faces, file holds {F}")
    (tmp_path / "fewer.ply").write_bytes(data.replace(f"element face {F}\n".encode(),
                                                      f"element face {F - 2}\n".encode()))
    _raises_one_line(tmp_path / "fewer.ply", rf"{2 * record} bytes after the records the header promises")
    (tmp_path / "header.ply").write_bytes(data[:head_end - 20])  # cut inside the header
    _raises_one_line(tmp_path / "header.ply", r"PLY header is cut: no 'end_header' line")


def test_binary_ply_with_mixed_polygons_is_walked_record_by_record(tmp_path):
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\n"
              "property float y\nproperty float z\nelement face 2\n"
              "property list uchar int vertex_indices\nend_header\n").encode()
    verts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 2, 0]], "<f4").tobytes()
    quad = bytes([4]) + np.array([0, 1, 2, 3], "<i4").tobytes()
    tri = bytes([3]) + np.array([3, 2, 4], "<i4").tobytes()
    from symtorch._file_checks import check_ply

    elements = check_ply(header + verts + quad + tri).elements  # complete: accepted
    assert [(name, count) for name, count, _ in elements] == [("vertex", 5), ("face", 2)]
    (tmp_path / "cut.ply").write_bytes(header + verts + quad + tri[:-2])
    _raises_one_line(tmp_path / "cut.ply", r"truncated: header promises 2 faces, file holds 1$")


def test_stl_sizes_and_cuts(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=1)
    F = len(sphere.faces)
    binary = trimesh.exchange.stl.export_stl(sphere)
    (tmp_path / "cut.stl").write_bytes(binary[:-30])
    _raises_one_line(tmp_path / "cut.stl", rf"truncated: header promises {F} triangles, file holds {F - 1}")
    (tmp_path / "long.stl").write_bytes(binary + b"\x01" * 50)
    _raises_one_line(tmp_path / "long.stl", rf"binary STL header promises {F} triangles but 50 bytes follow")
    (tmp_path / "header.stl").write_bytes(binary[:60])
    _raises_one_line(tmp_path / "header.stl", r"binary STL cut inside its 84-byte header")
    text = trimesh.exchange.stl.export_stl_ascii(sphere)
    (tmp_path / "cut_ascii.stl").write_text(text[: len(text) * 2 // 3])
    _raises_one_line(tmp_path / "cut_ascii.stl", r"ASCII STL is cut: \d+ facets begun")


# ------------------------------------------------------------------------ orientation, degeneracy

def test_inconsistent_orientation_is_repaired_with_one_warning(tmp_path):
    from symtorch.shapes import mirror_blob

    verts, faces = mirror_blob(2)
    bad = faces.copy()
    bad[::2] = bad[::2][:, ::-1]  # half of the faces reversed
    write_mesh(tmp_path / "half.off", verts, bad)
    mesh, messages = read_warning(tmp_path / "half.off",
                                  rf"{len(faces) // 2} of {len(faces)} faces were oriented against "
                                  r"their neighbours; flipped to agree")
    assert len(messages) == 1, messages
    # every face wound as in the consistent original, or every face reversed (a tie: either side)

    def wound(f):  # each triangle rotated to start at its smallest index: the winding stays
        return np.stack([np.roll(r, -int(np.argmin(r))) for r in f])

    got = wound(mesh.faces)
    assert (got == wound(faces)).all() or (got == wound(faces[:, ::-1])).all()


def test_moebius_strip_is_reported_not_repaired(tmp_path):
    n = 24
    t = np.arange(n) * 2 * np.pi / n
    verts = []
    for a in t:  # a strip of width 0.4 around a unit circle, half a twist
        for w in (-0.2, 0.2):
            r = 1 + w * np.cos(a / 2)
            verts.append([r * np.cos(a), r * np.sin(a), w * np.sin(a / 2)])
    faces = []
    for i in range(n):
        a0, a1 = 2 * i, 2 * i + 1
        b0, b1 = (2 * (i + 1), 2 * (i + 1) + 1) if i < n - 1 else (1, 0)  # the twist: ends swapped
        faces += [[a0, b0, a1], [a1, b0, b1]]
    write_mesh(tmp_path / "moebius.obj", np.array(verts), np.array(faces))
    mesh, _ = read_warning(tmp_path / "moebius.obj", r"non-orientable piece .* left as they are")
    np.testing.assert_array_equal(mesh.faces, faces)


def test_collinear_vertices_are_refused_fast(tmp_path):
    """Zero area up to rounding: a spectrum of it ran 30 s and gave C1."""
    import time

    from symtorch.shapes import mirror_blob

    verts, faces = mirror_blob(3)
    direction = np.array([0.3, -1.1, 0.7])
    line = (verts @ [1.0, 0.5, 0.25])[:, None] * direction  # every vertex on one line, rounded
    write_mesh(tmp_path / "line.off", line, faces)
    t0 = time.perf_counter()
    _raises_one_line(tmp_path / "line.off", r"mesh has zero area up to rounding")
    assert time.perf_counter() - t0 < 5


def test_tiny_coordinates_give_the_spectrum_of_the_unscaled_mesh(tmp_path):
    from symtorch.shapes import mirror_blob
    from symtorch.spectrum import laplacian_spectrum

    verts, faces = mirror_blob(2)
    write_mesh(tmp_path / "tiny.off", verts * 1e-150, faces)
    mesh = read_quietly(tmp_path / "tiny.off")  # no "zero total area", no degenerate faces
    assert mesh_report(mesh.verts, mesh.faces)["n_degenerate_faces"] == 0
    tiny, ref = laplacian_spectrum(mesh.verts, mesh.faces, k=12), laplacian_spectrum(verts, faces, k=12)
    torch.testing.assert_close(tiny.evals, ref.evals, rtol=1e-9, atol=1e-9)
    assert tiny.scale * 1e-150 == pytest.approx(ref.scale, rel=1e-12)
    with pytest.raises(ValueError, match=r"coordinates too small to represent areas \(max \|x\| = "):
        laplacian_spectrum(mesh.verts, mesh.faces, k=12, normalize_area=False)


def test_one_huge_triangle_is_not_several_components():
    """The spectral test (second eigenvalue ~0) fired on one component of very different scales."""
    from symtorch.shapes import icosphere
    from symtorch.spectrum import laplacian_spectrum

    v, f = icosphere(2)
    a, b, c = f[0]
    far = (v[a] + v[b] + v[c]) / 3 * 1e4  # a huge pyramid in place of face 0
    verts = np.vstack([v, far])
    faces = np.vstack([f[1:], [[a, b, len(v)], [b, c, len(v)], [c, a, len(v)]]])
    assert mesh_report(verts, faces)["n_components"] == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        laplacian_spectrum(verts, faces, k=10)
