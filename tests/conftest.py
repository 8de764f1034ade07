"""Shared test set-up: the tests folder on sys.path (for ``shapes``), the shared-data location."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from symtorch.paths import shared_data_dir  # noqa: E402


@pytest.fixture(scope="session")
def shared_data():
    """The shared benchmark data folder; skips the test where it is absent."""
    d = shared_data_dir()
    if d is None or not Path(d).is_dir():
        pytest.skip("shared data not found: set $SYMTORCH_SHARED or place it at ../shared/data")
    return Path(d)
