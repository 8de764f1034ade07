"""symtorch.paths: where the shared data is found, and None where it is absent."""
from __future__ import annotations

from symtorch.paths import shared_data_dir, shared_path


def test_environment_variable_wins(tmp_path, monkeypatch):
    (tmp_path / "data" / "SCAPE").mkdir(parents=True)
    monkeypatch.setenv("SYMTORCH_SHARED", str(tmp_path))
    assert shared_data_dir() == tmp_path / "data"
    assert shared_path("SCAPE") == tmp_path / "data" / "SCAPE"
    assert shared_path("no_such_set") is None


def test_missing_folder_falls_back_or_gives_none(tmp_path, monkeypatch):
    monkeypatch.setenv("SYMTORCH_SHARED", str(tmp_path / "absent"))
    root = shared_data_dir()
    # the variable names no folder: the project's sibling ../shared/data, where present, else None
    assert root is None or (root.name == "data" and root.parent.name == "shared")
    if root is None:
        assert shared_path("anything") is None
