"""Bad and odd input through the command line: it works, or fails with one line and a non-zero exit.

What works, and how (the documented behaviour):

- quads / polygons: triangulated fan-wise, with a warning;
- degenerate (zero-area) faces, duplicated vertices, non-manifold edges, several components,
  unreferenced vertices: read as they are, with one warning per problem; ``info`` reports them;
- a point cloud (no faces): ``info`` uses the point-cloud Laplacian, ``detect`` the point-cloud path;
- a single triangle: ``info`` computes the V - 1 eigenvalues there are;
- ``detect`` refuses what the detector cannot handle with one line: several components,
  unreferenced vertices, meshes too coarse for the spectrum (fewer than ~90 vertices), point clouds
  of fewer than 100 points.

Everything else (empty, binary garbage, NaN / inf / overflowing coordinates, face indices out of
range, zero total area, truncated files, OBJ index 0) fails while reading, naming the file.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from symtorch import cli, shapes
from symtorch.io import read_mesh, write_mesh


def _off(path, verts, faces) -> None:
    """ASCII OFF written by hand, so that invalid values (NaN, bad indices, polygons) get through."""
    with open(path, "w") as fh:
        fh.write(f"OFF\n{len(verts)} {len(faces)} 0\n")
        for p in verts:
            fh.write(" ".join(repr(float(x)) for x in p) + "\n")
        for face in faces:
            fh.write(f"{len(face)} " + " ".join(str(int(i)) for i in face) + "\n")


def _quad_sphere(n: int = 8) -> tuple[np.ndarray, list[list[int]]]:
    """A closed, stretched cube-sphere made of n x n quads per cube face."""
    g = np.linspace(-1, 1, n + 1)
    verts, quads, index = [], [], {}

    def vid(p):
        key = tuple(np.round(p, 9))
        if key not in index:
            index[key] = len(verts)
            verts.append(p)
        return index[key]

    for axis in range(3):
        for sgn in (-1, 1):
            for i in range(n):
                for j in range(n):
                    corners = []
                    for a, b in ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)):
                        p = np.zeros(3)
                        p[axis], p[(axis + 1) % 3], p[(axis + 2) % 3] = sgn, g[a], g[b]
                        corners.append(vid(p))
                    quads.append(corners if sgn > 0 else corners[::-1])
    v = np.array(verts)
    return v / np.linalg.norm(v, axis=1, keepdims=True) * np.array([1.0, 1.3, 0.8]), quads


def build_corpus(d) -> None:
    """Every odd input the hardening tests feed the CLI, in folder ``d`` (file names say what each one is)."""
    os.makedirs(d, exist_ok=True)
    rng = np.random.default_rng(0)
    ico_v, ico_f = shapes.icosphere(2)                 # 162 vertices
    blob_v, blob_f = shapes.mirror_blob(2)             # 162 vertices, mirror-symmetric
    V = len(blob_v)
    open(f"{d}/empty.off", "w").close()
    with open(f"{d}/garbage.off", "wb") as fh:
        fh.write(rng.bytes(4096))
    with open(f"{d}/garbage_binary.ply", "wb") as fh:
        fh.write(rng.bytes(4096))
    v = ico_v.copy()
    v[5, 1] = np.nan
    _off(f"{d}/nan_coordinates.off", v, ico_f)
    v = ico_v.copy()
    v[7, 0] = np.inf
    _off(f"{d}/inf_coordinates.off", v, ico_f)
    _off(f"{d}/huge_coordinates.off", ico_v * 1e300, ico_f)
    f = ico_f.copy()
    f[3, 2] = len(ico_v) + 10
    _off(f"{d}/faces_out_of_range.off", ico_v, f)
    f = ico_f.copy()
    f[0, 0] = -1
    _off(f"{d}/faces_negative.off", ico_v, f)
    with open(f"{d}/truncated.off", "w") as fh:
        fh.write("OFF\n100 200 0\n0 0 0\n1 1 1\n")
    with open(f"{d}/obj_index_zero.obj", "w") as fh:
        fh.write("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    _off(f"{d}/zero_area.off", [[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    _off(f"{d}/quads.off", *_quad_sphere())
    with open(f"{d}/polygons.obj", "w") as fh:  # hexagonal prism: two hexagons, six quads
        for z in (0, 1):
            for a in np.arange(6) * np.pi / 3:
                fh.write(f"v {np.cos(a)} {np.sin(a)} {z}\n")
        fh.write("f 6 5 4 3 2 1\nf 7 8 9 10 11 12\n")
        for i in range(6):
            fh.write(f"f {i + 1} {(i + 1) % 6 + 1} {(i + 1) % 6 + 7} {i + 7}\n")
    # degenerate faces, still one component: a collapsed face and a flat one on an edge midpoint
    a, b = blob_f[0, 0], blob_f[0, 1]
    _off(f"{d}/degenerate_faces.off", np.vstack([blob_v, (blob_v[a] + blob_v[b]) / 2]),
         np.vstack([blob_f, [[a, a, b], [a, V, b]]]))
    # duplicated vertices: every vertex twice, alternate faces use the copies
    f = blob_f.copy()
    f[::2] += V
    _off(f"{d}/duplicated_vertices.off", np.vstack([blob_v, blob_v]), f)
    _off(f"{d}/unreferenced_vertices.off", np.vstack([blob_v, rng.normal(size=(5, 3)) * 3]), blob_f)
    _off(f"{d}/two_components.off", np.vstack([blob_v, blob_v + [5, 0, 0]]),
         np.vstack([blob_f, blob_f + V]))
    _off(f"{d}/nonmanifold_edges.off", np.vstack([blob_v, (blob_v[a] + blob_v[b]) * 0.75]),
         np.vstack([blob_f, [[a, b, V]]]))  # a fin: edge (a, b) in three faces
    _off(f"{d}/point_cloud.off", blob_v, [])
    _off(f"{d}/single_triangle.off", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    write_mesh(f"{d}/good_blob.off", blob_v, blob_f)
    write_mesh(f"{d}/good_table.ply", *shapes.table(2))
    # cut files, degenerate geometry
    with open(f"{d}/good_blob.off", "rb") as fh:
        data = fh.read()
    with open(f"{d}/cut_last_face.off", "wb") as fh:
        fh.write(data[:-2])  # "3 70 81 16" of "3 70 81 161": a whole face, the wrong vertex
    ply = open(f"{d}/good_table.ply", "rb").read()
    with open(f"{d}/cut_in_header.ply", "wb") as fh:
        fh.write(ply[: ply.index(b"end_header") - 5])
    line = (blob_v @ [1.0, 0.5, 0.25])[:, None] * [0.3, -1.1, 0.7]
    write_mesh(f"{d}/collinear.off", line, blob_f)


# expected outcome per file and command: "ok" or the start of the one-line error after the path
READ_ERRORS = {
    "empty.off": "file is empty",
    "garbage.off": "binary data",
    "garbage_binary.ply": "trimesh cannot read it",
    "nan_coordinates.off": "verts has 1 vertices with NaN or inf",
    "inf_coordinates.off": "verts has 1 vertices with NaN or inf",
    "huge_coordinates.off": "mesh area overflows",
    "faces_out_of_range.off": "faces index out of range",
    "faces_negative.off": "faces index out of range",
    "truncated.off": "truncated",
    "obj_index_zero.obj": "line 4: face index 0",
    "zero_area.off": "mesh has zero total area",
    "cut_last_face.off": "has no newline at its end: the file looks cut",
    "cut_in_header.ply": "PLY header is cut",
    "collinear.off": "mesh has zero area up to rounding",
}
VALID = ["quads.off", "polygons.obj", "degenerate_faces.off", "duplicated_vertices.off",
         "unreferenced_vertices.off", "two_components.off", "nonmanifold_edges.off",
         "point_cloud.off", "single_triangle.off", "good_blob.off", "good_table.ply"]
DETECT_REFUSED = {
    "two_components.off": "has 2 connected components",
    "duplicated_vertices.off": "connected components",
    "unreferenced_vertices.off": "5 vertices are referenced by no face",
    "single_triangle.off": "symmetry detection failed",
    "polygons.obj": "symmetry detection failed",
}
DETECT_OK = ["quads.off", "degenerate_faces.off", "nonmanifold_edges.off", "good_blob.off",
             "good_table.ply", "point_cloud.off"]


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    d = tmp_path_factory.mktemp("corpus")
    build_corpus(d)
    return d


def test_corpus_is_complete(corpus):
    assert sorted(os.listdir(corpus)) == sorted([*READ_ERRORS, *VALID])
    assert sorted(DETECT_OK + list(DETECT_REFUSED)) == sorted(VALID)


def run_cli(argv, capsys) -> tuple[int, str, str]:
    rc = cli.main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


def assert_one_line_error(rc, err, path, reason, argv):
    lines = [s for s in err.splitlines() if s.startswith("symtorch: error:")]
    assert rc == 2, f"{argv}: exit {rc}, stderr {err!r}"
    assert len(lines) == 1 and "Traceback" not in err, f"{argv}: {err!r}"
    assert lines[0].startswith(f"symtorch: error: {path}") and reason in lines[0], \
        f"{argv}: expected {reason!r} in {lines[0]!r}"


@pytest.mark.parametrize("name", sorted(READ_ERRORS))
@pytest.mark.parametrize("command", ["info", "detect"])
def test_bad_input_fails_with_one_line(corpus, capsys, name, command):
    path = str(corpus / name)
    argv = [command, path]
    rc, _, err = run_cli(argv, capsys)
    assert_one_line_error(rc, err, path, READ_ERRORS[name], argv)


@pytest.mark.parametrize("name", VALID)
def test_info_works_on_odd_but_valid_input(corpus, capsys, name):
    argv = ["info", str(corpus / name), "--k", "6", "--json"]
    rc, out, err = run_cli(argv, capsys)
    assert rc == 0, f"{argv}: {err}"
    info = json.loads(out)
    mesh = read_mesh(corpus / name)
    assert info["n_vertices"] == len(mesh.verts), name
    assert info["n_faces"] == (0 if mesh.faces is None else len(mesh.faces)), name
    assert len(info["eigenvalues"]) == min(6, len(mesh.verts) - 1), name
    assert info["eigenvalues"][0] == pytest.approx(0.0, abs=1e-6), name
    expected = {"two_components.off": ("n_components", 2),
                "nonmanifold_edges.off": ("is_manifold", False),
                "unreferenced_vertices.off": ("n_unreferenced", 5),
                "duplicated_vertices.off": ("n_duplicated_vertices", 162),
                "degenerate_faces.off": ("n_degenerate_faces", 2),
                "good_blob.off": ("is_closed", True)}
    if name in expected:
        key, val = expected[name]
        assert info[key] == val, f"{name}: {key}={info[key]}, expected {val}"


@pytest.mark.parametrize("name", sorted(DETECT_REFUSED))
def test_detect_refuses_what_it_cannot_handle(corpus, capsys, name):
    path = str(corpus / name)
    argv = ["detect", path]
    rc, _, err = run_cli(argv, capsys)
    assert_one_line_error(rc, err, path, DETECT_REFUSED[name], argv)


@pytest.mark.parametrize("name", DETECT_OK)
def test_detect_works_on_odd_but_valid_input(corpus, capsys, tmp_path, name):
    out = tmp_path / "result.json"
    rc, _, err = run_cli(["detect", str(corpus / name), "--out", str(out)], capsys)
    assert rc == 0, f"{name}: {err}"
    res = json.loads(out.read_text())
    V = len(read_mesh(corpus / name).verts)
    assert res["symmetries"][0]["kind"] == "identity" and res["symmetries"][0]["p2p"] == list(range(V))
    assert res["group"]["order"] == len(res["symmetries"]), name
    for s in res["symmetries"]:
        assert len(s["p2p"]) == V and 0 <= min(s["p2p"]) and max(s["p2p"]) < V, name
    if name == "good_blob.off":  # built mirror-symmetric: its mirror must be found, not just survived
        assert res["group"]["name"] == "Cs", res["group"]


def test_missing_file_and_folder(tmp_path, capsys):
    for argv, reason in ((["info", str(tmp_path / "nope.off")], "no such file"),
                         (["detect", str(tmp_path)], "not a regular file")):
        rc, _, err = run_cli(argv, capsys)
        assert_one_line_error(rc, err, argv[1], reason, argv)


@pytest.mark.multiprocess
def test_real_entry_point_exit_status_and_no_traceback(corpus):
    """Through a real process (as a user runs it), with a timeout: no hang, one line, exit 2."""
    for name in ("garbage_binary.ply", "two_components.off"):
        proc = subprocess.run([sys.executable, "-m", "symtorch", "detect", str(corpus / name)],
                              capture_output=True, text=True, timeout=120)
        errors = [s for s in proc.stderr.splitlines() if s.startswith("symtorch: error:")]
        assert proc.returncode == 2 and len(errors) == 1, (name, proc.stderr)
        assert "Traceback" not in proc.stderr, (name, proc.stderr)


def test_unexpected_exception_is_one_line(monkeypatch, capsys):
    """A bug (not bad input) still ends with one line, exit 3; -v adds the traceback."""
    import symtorch.io

    def boom(*a, **k):
        raise KeyError("internal")

    monkeypatch.setattr(symtorch.io, "mesh_report", boom)
    rc, _, err = run_cli(["info", "--demo", "--k", "0"], capsys)
    assert rc == 3 and err.strip().count("\n") == 0 and "internal error (KeyError" in err, err


def test_precompute_over_the_corpus(corpus, tmp_path, capsys):
    """Good meshes done, bad ones in failures.jsonl with a one-line reason; the run finishes."""
    out = tmp_path / "cache"
    rc, _, err = run_cli(["precompute", str(corpus), str(out), "--k", "6", "--no-detect",
                          "--quiet"], capsys)
    assert rc == 0, err
    assert "Traceback" not in err
    failures = [json.loads(s) for s in (out / "failures.jsonl").read_text().splitlines()]
    failed = {f["file"] for f in failures}
    # without faces there is no area to normalise; a triangle has too few eigenpairs
    assert failed == set(READ_ERRORS) | {"point_cloud.off", "single_triangle.off"}
    assert all("\n" not in f["reason"] and f["reason"].startswith(str(corpus)) for f in failures)
    done = {p.stem for p in out.glob("*.pt")}
    assert done == {os.path.splitext(n)[0] for n in VALID} - {"point_cloud", "single_triangle"}
    # strict mode reports the failures in the exit status; a rerun redoes only the failed ones
    rc, _, err = run_cli(["precompute", str(corpus), str(out), "--k", "6", "--no-detect",
                          "--quiet", "--strict"], capsys)
    assert rc == 1 and f"0 done, {len(done)} already done, {len(failed)} failed" in err, err


def test_huge_mesh_info(tmp_path, capsys, monkeypatch):
    """A 202,500-vertex torus: read and reported, and with ``--k 0`` no spectrum is solved (the
    report is linear in the mesh; a wall-clock bound would only measure the shared machine)."""
    import symtorch.spectrum

    def no_spectrum(*a, **k):
        raise AssertionError("info --k 0 solved a spectrum")

    monkeypatch.setattr(symtorch.spectrum, "laplacian_spectrum", no_spectrum)
    n = 450
    u, v = np.meshgrid(np.arange(n) * 2 * np.pi / n, np.arange(n) * 2 * np.pi / n, indexing="ij")
    verts = np.stack([(2 + np.cos(v)) * np.cos(u), (2 + np.cos(v)) * np.sin(u), np.sin(v)], -1)
    idx = np.arange(n * n).reshape(n, n)
    a, b = idx, np.roll(idx, -1, 0)
    c, d = np.roll(b, -1, 1), np.roll(idx, -1, 1)
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)])
    path = tmp_path / "torus_202k.ply"
    write_mesh(path, verts.reshape(-1, 3), faces)
    rc, out, err = run_cli(["info", str(path), "--k", "0", "--json"], capsys)
    assert rc == 0, err
    info = json.loads(out)
    assert info["n_vertices"] == n * n and info["n_faces"] == 2 * n * n
    assert info["is_closed"] and info["genus"] == 1 and info["n_components"] == 1


# ------------------------------------------------------------------------------- the rough edges

def test_output_that_is_no_regular_file_is_refused(tmp_path, capsys):
    """--out onto a FIFO, a device node or a symbolic link: refused, the target left as it is."""
    import stat

    target = tmp_path / "keep.json"
    target.write_text("{}")
    os.mkfifo(tmp_path / "fifo")
    os.symlink(target, tmp_path / "link.json")
    cases = [("fifo", "is a FIFO"), ("link.json", "is a symbolic link")]
    try:
        os.mknod(tmp_path / "null", 0o666 | stat.S_IFCHR, os.makedev(1, 3))
        cases.append(("null", "is a character device"))
    except (PermissionError, OSError):
        pass  # no device node without CAP_MKNOD
    for name, reason in cases:
        path = str(tmp_path / name)
        for argv in (["detect", "--demo", "--out", path], ["detect", "--demo", "--matrices", path],
                     ["show", "--demo", "--out", path]):
            rc, _, err = run_cli(argv, capsys)
            assert_one_line_error(rc, err, path, reason, argv)
    assert os.path.islink(tmp_path / "link.json") and target.read_text() == "{}"
    assert stat.S_ISFIFO(os.lstat(tmp_path / "fifo").st_mode)


@pytest.mark.parametrize("argv,reason", [
    (["detect", "--demo", "--k", "-5"], "--k must be >= 2, got -5"),
    (["detect", "--demo", "--k", "0"], "--k must be >= 2, got 0"),
    (["detect", "--demo", "--k-refine", "1"], "--k-refine must be >= 2, got 1"),
    (["detect", "--demo", "--k", "30", "--k-refine", "10"], "--k-refine must be >= --k"),
    (["show", "--demo", "--k-refine", "1"], "--k-refine must be >= 2, got 1"),
    (["info", "--demo", "--k", "-5"], "--k must be >= 0 (0: no eigenvalues), got -5"),
])
def test_basis_sizes_out_of_range_are_refused(capsys, argv, reason):
    rc, _, err = run_cli(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and err.startswith(f"symtorch: error: {reason}"), (argv, err)


def _in_namespace(script: str) -> subprocess.CompletedProcess:
    """``script`` (sh) as root of a user and mount namespace, where tmpfs mounts are allowed."""
    proc = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True,
                          timeout=300, env={**os.environ, "PYTHONPATH": os.getcwd()})
    return proc


@pytest.mark.multiprocess
def test_read_only_and_full_output_folders_name_the_cause(tmp_path):
    probe = _in_namespace(f"mount -t tmpfs tmpfs {tmp_path}")
    if probe.returncode != 0:
        pytest.skip(f"no user namespaces with mounts here ({probe.stderr.strip()})")
    src = tmp_path / "src"
    src.mkdir()
    write_mesh(src / "blob.off", *shapes.mirror_blob(2))
    py = f"{sys.executable} -m symtorch"
    ro, full = tmp_path / "ro", tmp_path / "full"
    ro.mkdir()
    full.mkdir()
    script = f"""
mount -t tmpfs -o ro tmpfs {ro}
mount -t tmpfs -o size=64k tmpfs {full}
dd if=/dev/zero of={full}/filler bs=4k count=100 2>/dev/null
{py} detect --demo --out {ro}/result.json; echo "rc=$?"
{py} precompute {src} {ro}/cache --k 6 --no-detect --quiet; echo "rc=$?"
{py} detect --demo --out {full}/result.json --matrices {full}/m.npz; echo "rc=$?"
mkdir {full}/cache 2>/dev/null; {py} precompute {src} {full}/cache --k 6 --no-detect --quiet; echo "rc=$?"
"""
    proc = _in_namespace(script)
    err = proc.stderr
    assert "Traceback" not in err and "internal error" not in err and "unexpected pos" not in err, err
    assert proc.stdout.split().count("rc=2") == 4, (proc.stdout, err)
    errors = [s for s in err.splitlines() if s.startswith("symtorch: error:")]
    assert len(errors) == 4, err
    assert errors[0] == f"symtorch: error: cannot write {ro}/result.json: read-only file system"
    assert f"cannot create folder {ro}/cache: read-only file system" in errors[1], errors[1]
    assert f"cannot write {full}/" in errors[2] and "no space left on device" in errors[2], errors[2]
    assert f"cannot write {full}/cache" in errors[3] and "no space left on device" in errors[3], errors[3]


def test_symbolic_link_loop_and_file_for_folder(tmp_path, capsys):
    loop = tmp_path / "loop.off"
    os.symlink(loop, loop)
    for argv in (["info", str(loop)], ["detect", str(loop)]):
        rc, _, err = run_cli(argv, capsys)
        assert_one_line_error(rc, err, str(loop), "symbolic link loop", argv)
    folder_loop = tmp_path / "meshes"
    os.symlink(folder_loop, folder_loop)
    argv = ["precompute", str(folder_loop), str(tmp_path / "out")]
    rc, _, err = run_cli(argv, capsys)
    assert_one_line_error(rc, err, str(folder_loop), "symbolic link loop", argv)
    mesh = tmp_path / "blob.off"
    write_mesh(mesh, *shapes.mirror_blob(1))
    argv = ["precompute", str(mesh), str(tmp_path / "out")]
    rc, _, err = run_cli(argv, capsys)
    assert_one_line_error(rc, err, str(mesh), "is a file, not a folder", argv)


def test_precompute_reads_stl_files(tmp_path, capsys):
    import trimesh

    src = tmp_path / "src"
    src.mkdir()
    v, f = shapes.mirror_blob(1)
    (src / "blob.stl").write_bytes(trimesh.exchange.stl.export_stl(trimesh.Trimesh(v, f, process=False)))
    write_mesh(src / "other.off", v * [1.0, 1.2, 1.0], f)
    rc, _, err = run_cli(["precompute", str(src), str(tmp_path / "out"), "--k", "6", "--no-detect",
                          "--quiet"], capsys)
    assert rc == 0 and "2 done, 0 already done, 0 failed, of 2" in err, err
    assert (tmp_path / "out" / "blob.pt").exists()


def test_inconsistent_orientation_is_repaired_before_detection(tmp_path, capsys):
    """Half of the faces reversed gave a rotation (C2) instead of the mirror, with no warning."""
    v, f = shapes.mirror_blob(2)
    f = f.copy()
    f[::2] = f[::2][:, ::-1]
    write_mesh(tmp_path / "half.off", v, f)
    from symtorch.io import MeshWarning

    with pytest.warns(MeshWarning, match="160 of 320 faces were oriented against their neighbours; "
                                         "flipped to agree"):
        rc, _, err = run_cli(["detect", str(tmp_path / "half.off"), "--out", str(tmp_path / "r.json")],
                             capsys)
    assert rc == 0, err
    kinds = [s["kind"] for s in json.loads((tmp_path / "r.json").read_text())["symmetries"]]
    assert kinds == ["identity", "reflection"], kinds


def test_tiny_coordinates_are_detected_like_the_mesh(tmp_path, capsys):
    v, f = shapes.mirror_blob(2)
    write_mesh(tmp_path / "tiny.off", v * 1e-150, f)
    rc, _, err = run_cli(["detect", str(tmp_path / "tiny.off"), "--out", str(tmp_path / "r.json")], capsys)
    assert rc == 0, err
    kinds = [s["kind"] for s in json.loads((tmp_path / "r.json").read_text())["symmetries"]]
    assert kinds == ["identity", "reflection"], kinds
