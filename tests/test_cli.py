"""symtorch.cli.main: the parser, `detect` for people (a summary) and for pipes (JSON), its JSON schema."""
import json
import sys
import warnings

import numpy as np
import pytest

from symtorch.cli import build_parser, main
from symtorch.detect import DetectConfig


def test_build_parser_alone_has_every_subcommand():
    p = build_parser()  # as documentation generators and shell completion call it
    assert p.parse_args(["detect", "m.off", "--mode", "group"]).mode == "group"
    assert p.parse_args(["info", "--demo"]).command == "info"
    assert p.parse_args(["precompute", "src", "out", "--k", "40"]).k == 40
    assert p.parse_args(["show", "m.off", "--out", "m.png"]).out == "m.png"


def _run(argv, capsys, tty: bool, monkeypatch):
    """``symtorch`` with stdout a terminal (``tty``) or a pipe."""
    monkeypatch.setattr(sys.stdout, "isatty", lambda: tty)
    rc = main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


def test_detect_prints_a_summary_on_a_terminal(capsys, monkeypatch, tmp_path):
    rc, out, err = _run(["detect", "--demo"], capsys, True, monkeypatch)
    assert rc == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("demo:mirror_blob: 642 vertices") and "group Cs of order 2" in lines[0]
    assert any(line.split()[:5] == ["0", "e", "identity", "1", "1.00"] for line in lines), out
    assert any(line.split()[1:4] == ["s1", "reflection", "2"] for line in lines), out
    assert any(line.startswith("time ") and "spectrum" in line for line in lines), out
    assert "JSON with every vertex map: not written" in lines[-1]
    assert "{" not in out  # no JSON, and no vertex map, on the terminal
    path = tmp_path / "r.json"
    rc, out, _ = _run(["detect", "--demo", "--out", str(path)], capsys, True, monkeypatch)
    assert rc == 0 and out.splitlines()[-1] == f"JSON with every vertex map -> {path}"
    assert json.loads(path.read_text())["group"]["name"] == "Cs"


def test_detect_prints_json_in_a_pipe_or_when_asked(capsys, monkeypatch):
    for tty, argv in ((False, ["detect", "--demo"]), (True, ["detect", "--demo", "--json"])):
        rc, out, err = _run(argv, capsys, tty, monkeypatch)
        assert rc == 0, err
        d = json.loads(out)  # stdout is exactly one JSON document
        assert d["group"]["name"] == "Cs" and len(d["symmetries"]) == 2 and "timings" in d
        assert "group Cs of order 2" in err  # the summary line went to stderr


def test_continuous_symmetry_summary():
    from symtorch.cli.main import detect_summary

    out = {"mesh": "m", "n_vertices": 10, "k": 4, "continuous": True,
           "symmetries": [{"kind": "identity", "order": 1, "score": 1.0}],
           "group": {"name": "C1", "order": 1, "inverses": [0]}, "timings": {"spectrum": 0.1, "total": 0.2}}
    text = detect_summary(out)
    assert "continuous symmetry" in text and text.splitlines()[-1] == "time 0.20 s (spectrum 0.10)"


def test_cli_detect_json_schema(tmp_path, capsys):
    out, mats = tmp_path / "r.json", tmp_path / "r.npz"
    assert main(["detect", "--demo", "--out", str(out), "--matrices", str(mats)]) == 0
    d = json.loads(out.read_text())
    assert set(d) >= {"mesh", "n_vertices", "symmetries", "group", "timings"}
    V = d["n_vertices"]
    assert d["symmetries"][0]["kind"] == "identity"
    assert d["symmetries"][0]["p2p"] == list(range(V))
    for s in d["symmetries"]:
        assert set(s) >= {"kind", "order", "score", "confidence", "uncertain", "p2p"}
        assert len(s["p2p"]) == V and min(s["p2p"]) >= 0 and max(s["p2p"]) < V
        assert 0 <= s["confidence"] <= 1 and s["uncertain"] == (s["confidence"] < d["min_confidence"])
    assert d["uncertain"] == any(s["uncertain"] for s in d["symmetries"])
    assert d["group"]["order"] == len(d["symmetries"]) == 2
    assert "spectrum" in d["timings"]
    z = np.load(mats)
    assert z["fmaps"].shape == (2, int(z["k"]), int(z["k"])) == (2, d["k"], d["k"])
    assert z["p2ps"].shape == (2, V)
    assert "timings" in capsys.readouterr().err


def test_to_dict_and_cli_schema(tmp_path):
    out = tmp_path / "table.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["detect", "--demo", "table", "--mode", "group", "--k-refine", "40",
                     "--out", str(out)]) == 0
    d = json.loads(out.read_text())
    assert {"mesh", "n_vertices", "symmetries", "group", "timings"} <= set(d)
    g = d["group"]
    assert g["name"] == "C4v" and g["order"] == 8 == len(d["symmetries"])
    assert {"table", "inverses", "orders", "elements", "table_paper"} <= set(g)
    assert np.array_equal(np.array(g["table_paper"]), np.array(g["table"]).T)
    for s, e in zip(d["symmetries"], g["elements"]):
        assert {"kind", "order", "score", "p2p"} <= set(s) and len(s["p2p"]) == d["n_vertices"]
        assert e["kind"] == s["kind"]


def test_basis_size_help_states_the_detectors_defaults(capsys):
    """The defaults the help texts name are those of DetectConfig."""
    cfg = DetectConfig()
    for cmd in ("detect", "show", "precompute"):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert f"default {cfg.k_refine}" in text or f"{cfg.k_refine}, capped" in text, (cmd, text)
        assert "default 60" not in text, cmd


@pytest.mark.parametrize("ext", [".ply", ".xyz", ".off"])
def test_cli_detect_on_a_point_cloud_file(tmp_path, capsys, ext):
    """A file with vertices and no faces: the same JSON as for a mesh, with ``"input": "point_cloud"``."""
    from symtorch.io import write_mesh
    from symtorch.shapes import mirror_blob, symmetry_maps, true_symmetries

    v, _ = mirror_blob(3)
    mirror = symmetry_maps(v, true_symmetries("mirror_blob"))[1]
    path, out = tmp_path / f"cloud{ext}", tmp_path / "r.json"
    if ext == ".xyz":
        np.savetxt(path, v, fmt="%.17g")
    else:
        write_mesh(path, v, None)
    assert main(["detect", str(path), "--out", str(out), "--threads", "1"]) == 0
    err = capsys.readouterr().err
    assert f"{len(v)} points (a point cloud" in err
    d = json.loads(out.read_text())
    assert d["input"] == "point_cloud" and d["n_vertices"] == len(v)
    assert {"mesh", "k", "bands", "symmetries", "group", "timings"} <= set(d)
    assert d["group"]["name"] == "Cs"
    assert (np.array(d["symmetries"][1]["p2p"]) == mirror).mean() > 0.99  # fans are not exactly symmetric


def test_cli_detect_refuses_a_tiny_point_cloud(tmp_path, capsys):
    from symtorch.io import write_mesh

    path = tmp_path / "tiny.ply"
    write_mesh(path, np.random.default_rng(0).normal(size=(40, 3)), None)
    assert main(["detect", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 or all(not s.startswith("Traceback") for s in err.splitlines())
    line = [s for s in err.splitlines() if s.startswith("symtorch: error:")]
    assert len(line) == 1 and line[0] == (f"symtorch: error: {path}: a point cloud needs at least 100 "
                                          "points for symmetry detection, got 40"), err
