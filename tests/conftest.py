"""Shared test set-up: the tests folder on sys.path (for ``shapes``, ``prisms``), the shared-data
location, device fixtures, shared meshes, and the ``data`` marker.

A test is marked ``data`` here when it asks for the ``shared_data`` fixture or reads the shared data
through ``shared_path`` (itself or through a helper of its module): ``pytest -m "not data"`` runs
what needs nothing but the repository. A test that starts another process (a subprocess, a worker
pool, torchrun; itself or through a helper) is marked ``multiprocess`` the same way, where it does
not carry the marker already.
"""
import inspect
import os
import sys
from pathlib import Path

# One thread per test process, set before numpy and torch load their thread pools: the default run
# uses two xdist workers on a two-core machine, and the detectors' many small tensors run several
# times slower when intra-op threads contend (an explicit OMP_NUM_THREADS is kept).
os.environ.setdefault("OMP_NUM_THREADS", "1")

import pytest  # noqa: E402
import torch  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))

from symtorch.paths import shared_data_dir  # noqa: E402

torch.set_num_threads(int(os.environ["OMP_NUM_THREADS"]))


_DATA_CALLS = ("shared_path(", "shared_data_dir(")
#: what starts another process: a subprocess, a worker pool of precompute, torchrun
_PROCESS_CALLS = ("subprocess.", "Popen(", "workers=2", '"--workers"', "torchrun", "multiprocessing.")


def _source(fn) -> str:
    try:
        return inspect.getsource(fn)
    except (OSError, TypeError):
        return ""


def _helper_sources(module) -> dict[str, str]:
    """The source of each of the module's own functions that is not a test."""
    return {name: _source(fn) for name, fn in vars(module).items()
            if inspect.isfunction(fn) and fn.__module__ == module.__name__ and not name.startswith("test_")}


def _makes(src: str, calls, helpers: dict[str, str]) -> bool:
    """Whether ``src`` makes one of ``calls`` itself or through a helper whose source does."""
    return any(c in src for c in calls) or any(
        f"{name}(" in src and any(c in body for c in calls) for name, body in helpers.items())


def pytest_collection_modifyitems(config, items):
    helpers: dict[str, dict[str, str]] = {}
    for item in items:
        module = getattr(item, "module", None)
        if module is None:
            continue
        if module.__name__ not in helpers:
            helpers[module.__name__] = _helper_sources(module)
        src, own = _source(getattr(item, "function", None)), helpers[module.__name__]
        if "shared_data" in getattr(item, "fixturenames", ()) or _makes(src, _DATA_CALLS, own):
            item.add_marker(pytest.mark.data)
        if _makes(src, _PROCESS_CALLS, own) and item.get_closest_marker("multiprocess") is None:
            item.add_marker(pytest.mark.multiprocess)


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


@pytest.fixture(scope="session")
def d5h():
    """D5h on a pentagonal prism: 20 exact vertex permutations and their matrices (``tests/prisms.py``)."""
    from prisms import PrismGroup

    return PrismGroup(5)


@pytest.fixture(scope="session")
def d4h():
    """D4h on a square prism (``tests/prisms.py``)."""
    from prisms import PrismGroup

    return PrismGroup(4)


@pytest.fixture(scope="module")
def mirror3():
    """``mirror_blob(3)`` (642 vertices) as tensors, with its mirror permutation: (verts, faces, mirror)."""
    from symtorch.shapes import mirror_blob, symmetry_maps, true_symmetries

    v, f = mirror_blob(3)
    mirror = symmetry_maps(v, true_symmetries("mirror_blob"))[1]
    return torch.as_tensor(v), torch.as_tensor(f), torch.as_tensor(mirror)


@pytest.fixture(scope="module")
def one_thread():
    """One torch thread for a module of detections: the detector works on many small tensors, and
    intra-op threads only contend on a shared two-core machine. Restored after the module."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)
