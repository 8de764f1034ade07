"""symtorch show: f∘g colourings, the group table panel, PNG and GLB output."""
from __future__ import annotations

import numpy as np
import pytest

from symtorch import cli, shapes
from symtorch.cli.show import (colour_function, element_labels, export_glb, render_figure, save_png,
                               source_vertex, transfer, view_rotation)
from shapes import mirror_mesh


def test_transfer_is_composition_and_source_is_not_symmetric():
    verts, faces, mirror = (x.numpy() for x in mirror_mesh())
    p2ps = np.stack([np.arange(len(verts)), mirror])
    s = source_vertex(verts, p2ps)
    f = colour_function(verts, faces, s)
    assert f.min() == 0.0 and f.max() == pytest.approx(1.0) and f[s] == 0.0
    np.testing.assert_array_equal(transfer(f, p2ps[0]), f)
    g = transfer(f, mirror)
    assert np.abs(g - f).max() > 0.5, "f is (nearly) mirror-symmetric: the picture would show nothing"
    np.testing.assert_array_equal(transfer(g, mirror), f)  # (f∘g)∘g = f for an involution
    assert g[mirror[s]] == 0.0  # the source's image carries the source's value


def test_views_turn_about_the_vertical_axis():
    verts, _ = shapes.mirror_blob(2)
    R0, R90, R180 = (view_rotation(verts, t) for t in (0, 90, 180))
    for R in (R0, R90, R180):
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
    # a half turn shows the other side: the depth axis of the first view, reversed
    np.testing.assert_allclose(R180.T @ R0 @ R180.T @ R0, np.eye(3), atol=1e-9)
    assert not np.allclose(R90, R0)


def test_element_labels():
    assert element_labels(["identity", "reflection", "rotation", "rotation", "rotoreflection"],
                          [1, 2, 4, 2, 4]) == ["e", "s1", "r1", "r2", "m1"]


def test_render_and_glb(tmp_path):
    verts, faces = shapes.mirror_blob(2)
    mirror = shapes.symmetry_maps(verts, shapes.true_symmetries("mirror_blob"))[1]
    p2ps = np.stack([np.arange(len(verts)), mirror])
    fig = render_figure(verts, faces, p2ps, ["identity", "reflection"], [1, 2], [1.0, 0.9],
                        np.array([[0, 1], [1, 0]]), title="blob", max_faces=200)  # coarsened
    assert len(fig.axes) == 2 * 3 + 1  # each element from three sides, then the table
    save_png(fig, tmp_path / "fig.png")
    data = (tmp_path / "fig.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) < 300_000
    from PIL import Image

    width, height = Image.open(tmp_path / "fig.png").size
    assert width >= 1600 and height >= 1000, (width, height)  # large enough to judge a map
    export_glb(str(tmp_path / "c.glb"), verts, faces, p2ps, ["e", "s1"])
    import trimesh

    scene = trimesh.load(tmp_path / "c.glb")
    assert sorted(scene.geometry) == ["f_e", "f_s1"]
    assert all(g.visual.kind == "vertex" and len(g.vertices) == len(verts)
               for g in scene.geometry.values())


def test_cli_show(tmp_path, capsys):
    from symtorch.io import write_mesh

    write_mesh(tmp_path / "blob.off", *shapes.mirror_blob(2))  # 162 vertices: a quick detection
    png, glb = tmp_path / "blob.png", tmp_path / "blob.glb"
    rc = cli.main(["show", str(tmp_path / "blob.off"), "--out", str(png), "--glb", str(glb)])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert png.stat().st_size < 300_000 and glb.stat().st_size > 0
    assert "figure ->" in err and "group Cs of order 2: identity, reflection" in err


def test_cli_show_point_cloud_is_one_line(tmp_path, capsys):
    from symtorch.io import write_mesh

    write_mesh(tmp_path / "pc.off", shapes.icosphere(1)[0])
    rc = cli.main(["show", str(tmp_path / "pc.off"), "--out", str(tmp_path / "x.png")])
    err = capsys.readouterr().err
    assert rc == 2 and "is a point cloud" in err and "Traceback" not in err


def test_a_precomputed_colour_gives_the_same_output(tmp_path):
    """``show`` solves f once for the PNG and the GLB: passing it equals passing its source."""
    import trimesh

    verts, faces = shapes.mirror_blob(2)
    mirror = shapes.symmetry_maps(verts, shapes.true_symmetries("mirror_blob"))[1]
    p2ps = np.stack([np.arange(len(verts)), mirror])
    s = source_vertex(verts, p2ps)
    export_glb(str(tmp_path / "a.glb"), verts, faces, p2ps, ["e", "s1"], source=s)
    export_glb(str(tmp_path / "b.glb"), verts, faces, p2ps, ["e", "s1"], colour=colour_function(verts, faces, s))
    a, b = trimesh.load(tmp_path / "a.glb"), trimesh.load(tmp_path / "b.glb")
    for name in ("f_e", "f_s1"):
        np.testing.assert_array_equal(a.geometry[name].visual.vertex_colors, b.geometry[name].visual.vertex_colors)
    assert not np.array_equal(a.geometry["f_e"].visual.vertex_colors, a.geometry["f_s1"].visual.vertex_colors)
