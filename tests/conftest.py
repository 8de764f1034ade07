"""Shared test set-up: the tests folder on sys.path (for ``shapes``), the shared-data location."""
import sys
from pathlib import Path

import pytest
import torch

sys.path.insert(0, str(Path(__file__).parent))

from symtorch.paths import shared_data_dir  # noqa: E402


@pytest.fixture(scope="session")
def shared_data():
    """The shared benchmark data folder; skips the test where it is absent."""
    d = shared_data_dir()
    if d is None or not Path(d).is_dir():
        pytest.skip("shared data not found: set $SYMTORCH_SHARED or place it at ../shared/data")
    return Path(d)


DEVICES = ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(not torch.cuda.is_available(),
                                                                reason="no CUDA device"))]


@pytest.fixture(params=DEVICES)
def device(request):
    """Each torch device the library runs on: CPU, and CUDA where a GPU is present."""
    return torch.device("cuda:0" if request.param == "cuda" else request.param)  # as tensors report it


@pytest.fixture
def cuda_device():
    """A CUDA device, for tests that only compare a GPU result with the CPU one (skipped without)."""
    if not torch.cuda.is_available():
        pytest.skip("no CUDA device")
    return torch.device("cuda:0")
