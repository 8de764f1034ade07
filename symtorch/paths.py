"""Where the shared benchmark data lives (never inside the package).

The data under ``shared/data`` is academic-licensed: tests and scripts read it in place and skip with a
clear reason where it is absent.
"""
from __future__ import annotations

import os
from pathlib import Path

_PROJECT_ROOT = Path(__file__).resolve().parent.parent


def shared_data_dir() -> Path | None:
    """The folder holding the shared meshes, or None where it is absent.

    ``$SYMTORCH_SHARED/data`` when the variable is set, else ``../shared/data`` beside the project root.
    """
    env = os.environ.get("SYMTORCH_SHARED")
    candidates = [Path(env) / "data"] if env else []
    candidates.append(_PROJECT_ROOT.parent / "shared" / "data")
    for path in candidates:
        if path.is_dir():
            return path
    return None


def shared_path(*parts: str) -> Path | None:
    """A path inside the shared data folder, or None where the folder or the file is absent."""
    root = shared_data_dir()
    if root is None:
        return None
    path = root.joinpath(*parts)
    return path if path.exists() else None
