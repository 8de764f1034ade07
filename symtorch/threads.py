"""Thread pools of the solves: as many threads as there are free cores, or a fixed number.

OpenBLAS (numpy's and scipy's copies: ARPACK's Lanczos steps and the dense algebra around them) and
torch's OpenMP pool start one thread per core and split every call between them. Beside another
busy process one of those threads loses its core, and every call waits for it: the spectrum and the
detector then swing by an order of magnitude from one call to the next (BENCHMARKS.md, "Threads",
``python scripts/bench_threads.py``). CHOLMOD (through cholespy) is not concerned: it links a
single-threaded reference BLAS.

The solves (:func:`symtorch.laplacian_spectrum`, :func:`symtorch.spectrum.generalized_eigsh`) and
the command line run inside :func:`limit_threads`, which caps the BLAS pools and torch's intra-op
pool for the duration of the call at:

- the number set by :func:`set_num_threads` or the ``SYMTORCH_NUM_THREADS`` environment variable;
- otherwise the cores not busy at the start of the call: the cores this process may run on, less
  the threads of other processes running or waiting for a core at that moment
  (``/proc/loadavg``; without it, every core);

and never above what the pools had before (``OMP_NUM_THREADS``, ``threadpoolctl``,
``torch.set_num_threads`` stay in force). The thread count changes the order of floating-point sums,
so results can differ in their last bits from one count to another: fix the count
(``set_num_threads(1)``, ``--threads 1``) for bit-for-bit reproducible runs. ``symtorch precompute``
always uses one thread per process.
"""
from __future__ import annotations

import contextlib
import functools
import os
import threading
import time
from collections.abc import Callable, Iterator
from typing import TypeVar

__all__ = ["set_num_threads", "num_threads", "limit_threads", "bounded_threads", "free_cores"]

_F = TypeVar("_F", bound=Callable)
_ENV = "SYMTORCH_NUM_THREADS"
_setting: int | None = None
_lock = threading.Lock()
_depth = 0  # limit_threads() calls active in this process (nested or from several threads)
_active = 0  # the cap of the outermost active call


def _check(n, name: str = "n") -> int | None:
    if n is None:
        return None
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"{name} must be a positive int or None, got {n!r}")
    return n


def set_num_threads(n: int | None) -> None:
    """Fix the threads of symtorch's solves to ``n`` (``None``: the free cores, the default).

    Args:
        n: threads per solve (1: bit-for-bit reproducible; one process per core), or None.

    Raises:
        ValueError: ``n`` is not a positive int or None.
    """
    global _setting
    _setting = _check(n)


def _env_setting() -> int | None:
    raw = os.environ.get(_ENV, "").strip()
    if not raw:
        return None
    try:
        return _check(int(raw), _ENV)
    except ValueError:
        raise ValueError(f"{_ENV} must be a positive integer, got {raw!r}") from None


def _cores() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # not Linux
        return max(1, os.cpu_count() or 1)


def _running_elsewhere() -> int | None:
    """Threads of other processes running or runnable now (``/proc/loadavg``), or None."""
    try:
        with open("/proc/loadavg") as fh:
            running = int(fh.read().split()[3].split("/")[0])  # system-wide, this thread included
        own = 0
        for task in os.scandir("/proc/self/task"):
            try:
                with open(f"/proc/self/task/{task.name}/stat") as fh:
                    stat = fh.read()
            except OSError:  # the thread ended meanwhile
                continue
            own += stat[stat.rfind(")") + 2] == "R"
        return max(0, running - max(own, 1))
    except (OSError, ValueError, IndexError):
        return None


def free_cores(samples: int = 3) -> int:
    """Cores of this process not taken by other processes at this moment (at least 1).

    The smallest load of ``samples`` readings a millisecond apart, so that a short-lived process
    does not count and one that keeps a core busy does.
    """
    cores = _cores()
    loads = []
    for i in range(samples):
        if i:
            time.sleep(0.001)
        load = _running_elsewhere()
        if load is None:
            return cores
        loads.append(load)
    return max(1, cores - min(loads))


def num_threads() -> int:
    """Threads the next solve will use at most: the setting, else the free cores."""
    fixed = _setting if _setting is not None else _env_setting()
    return fixed if fixed is not None else free_cores()


@contextlib.contextmanager
def limit_threads(n: int | None = None) -> Iterator[int]:
    """Cap the BLAS pools and torch's intra-op pool at ``n`` threads inside the block.

    A block inside another one (or running beside it in another thread) keeps the outer cap unless
    it asks for fewer threads; the pools get back their own counts when the block ends. The cap
    never raises a pool above its count before the block.

    Args:
        n: the cap; None: :func:`num_threads` (the setting, else the free cores).

    Yields:
        the cap in force.
    """
    global _depth, _active
    n = _check(n)
    with _lock:
        # inside another block: keep its cap, unless this one asks for fewer threads
        outer = _depth > 0 and (n is None or n >= _active)
        _depth += 1
    try:
        if outer:
            yield _active
            return
        import torch
        from threadpoolctl import ThreadpoolController

        cap = n if n is not None else num_threads()
        blas = [lib for lib in ThreadpoolController().lib_controllers if lib.user_api == "blas"]
        before = [lib.num_threads for lib in blas]
        torch_before = torch.get_num_threads()
        try:
            for lib, count in zip(blas, before):
                if cap < count:  # lower, never raise, a pool
                    lib.set_num_threads(cap)
            if cap < torch_before:
                torch.set_num_threads(cap)
            _active = min([cap, torch_before, *before])
            yield _active
        finally:
            for lib, count in zip(blas, before):
                if lib.num_threads != count:
                    lib.set_num_threads(count)
            if torch.get_num_threads() != torch_before:
                torch.set_num_threads(torch_before)
    finally:
        with _lock:
            _depth -= 1


def bounded_threads(fn: _F) -> _F:
    """Run ``fn`` inside :func:`limit_threads` (the decorator form, for the solves)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with limit_threads():
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
