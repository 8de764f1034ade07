"""``symtorch precompute``: a folder tree of meshes -> :class:`~symtorch.data.MeshDataset` caches.

Each mesh ``SRC/a/b/x.off`` becomes ``OUT/a/b/x.pt`` and an entry of ``OUT/a/b/meta.json``, written by
:func:`symtorch.data.dataset.process_file`, the function ``MeshDataset`` itself processes with. So
``MeshDataset(SRC/a/b, pre_transform, processed_dir=OUT/a/b)`` loads them without processing again,
provided ``pre_transform`` is the same (its repr is the cache key); :func:`open_dataset` rebuilds it
from ``OUT/precompute.json``::

    symtorch precompute data/FAUST cache/FAUST --k 64 --workers 4
    ds = open_dataset("data/FAUST", "cache/FAUST")            # MeshDataset over the meshes done

Properties:

- **resumable**: every file is written to a temporary file and moved into place (``os.replace``), and
  ``meta.json`` records a mesh only after its ``.pt`` exists (rewritten after every mesh, or, for
  folders so large that one rewrite takes over 0.2 s, a little less often). Killed at
  any moment (even ``kill -9``), a new run redoes only the meshes not yet recorded.
- **verified**: ``meta.json`` holds, per mesh, its file's stamp and SHA-256 and the size and SHA-256
  of its ``.pt`` (which carries the key and the mesh hash too). A mesh counts as done only when all
  of them verify: a truncated, emptied, damaged or copied-in ``.pt``, or a mesh edited behind a
  restored modification time, is processed again (with a warning for a damaged ``.pt``).
- **uncertain symmetries**: ``--on-uncertain flag`` gives each sample ``sym_uncertain`` and marks
  the shapes whose detected symmetry is uncertain (confidence below the detector's
  ``min_confidence``) ``"uncertain": true`` in ``meta.json``, counted in the summary line;
  ``--on-uncertain drop`` caches the identity alone for them (``DetectSymmetries``).
- **bad meshes** are skipped: one JSON line ``{"file", "error", "reason"}`` per mesh in
  ``OUT/failures.jsonl``; the file lists exactly the meshes still failing after the latest run.
- **deterministic**: every pool has one thread in every process (torch, BLAS: see
  :mod:`symtorch.threads`) and the detector a seeded generator, so a resumed, parallel or
  distributed run writes the same bytes as one uninterrupted run.
- **workers**: ``--workers N`` processes (spawn start method), one mesh per task. When a worker
  dies (out of memory, a crash in native code, ``kill -9``), the meshes it had in flight are
  retried one at a time; a mesh that kills its worker again is listed as failed, with how the
  worker ended. Ctrl-C stops the workers and ends the run with one line (exit status 130).
- **one run per folder**: a run holds ``OUT/.run.lock`` (an ``fcntl`` lock, which the kernel drops
  when its process dies: a killed run's lock is taken over); a second run on the same ``OUT``
  refuses with a message naming the holder's pid and host, and never touches the first one's
  temporary files.
- **several machines**: under ``torchrun`` (``RANK``, ``WORLD_SIZE`` in the environment) rank r takes
  the meshes ``r, r + W, r + 2W, ...`` of the sorted list and writes into the shared ``OUT``; the
  ranks of one job share the run lock (``meta.json`` updates take an ``fcntl`` lock on
  ``OUT/.lock``). At the end the ranks join a gloo process group, only to wait for one another and
  to print one summary, for at most ``--dist-timeout`` minutes; a rank whose agent dies (its parent
  process changes) leaves at once.

Layout of ``OUT``: the ``.pt`` files and ``meta.json`` per folder, ``precompute.json`` (the
settings), ``failures.jsonl``, ``.lock`` and ``.run.lock``.
"""
from __future__ import annotations

import contextlib
import datetime
import errno
import json
import logging
import os
import resource
import secrets
import signal
import socket
import sys
import threading
import time
import warnings
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch

from ..io import WriteError, _one_line, _write_error, atomic_write
from ..threads import limit_threads
from .dataset import (MESH_SUFFIXES, MeshDataset, _natural_key, cache_key, cache_problem,
                      process_entry, read_meta, write_meta)
from .transforms import (Compose, ComputeDescriptors, ComputeSpectrum, DetectSymmetries,
                              NormalizeArea)

log = logging.getLogger(__name__)

__all__ = ["default_pre_transform", "find_meshes", "precompute", "open_dataset", "done_names",
           "Summary", "FolderInUse"]

FAILURES = "failures.jsonl"
SETTINGS = "precompute.json"
LOCK = ".lock"          # held for moments: meta.json and failures.jsonl updates, the run lock's check
RUN_LOCK = ".run.lock"  # held for a whole run (shared by the ranks of one torchrun job)


class FolderInUse(RuntimeError):
    """Another ``symtorch precompute`` run is writing into the output folder."""
_DTYPES = {"float32": torch.float32, "float64": torch.float64}
_FLUSH_SHARE = 0.05  # at most this share of the time goes to rewriting meta.json


def default_pre_transform(k: int = 64, detect: bool = True, seed: int = 0,
                          k_refine: int | None = None, on_uncertain: str = "keep") -> Compose:
    """``Compose([NormalizeArea(), ComputeSpectrum(k), ComputeDescriptors(), DetectSymmetries(seed)])``.

    Args:
        k: eigenpairs per mesh.
        detect: add :class:`~symtorch.data.DetectSymmetries` (``sym_p2p``, ``sym_fmap``, ``sym_score``).
        seed: of the detector's generator.
        k_refine: the detector's final basis size (default: ``detect_symmetries``'s, 100, capped by
            the ``k`` cached eigenpairs the detector reuses: at the default ``k=64`` it refines in
            ~56). ``k >= 108`` gives the detector its full default basis (lower dense error:
            TOSCA_Isometric 39.5 -> 33.4, SCAPE 45.4 -> 44.6 x1e-3) at ~0.45 s more a 12.5K mesh.
        on_uncertain: what a shape whose symmetry is uncertain gets (``DetectSymmetries``):
            ``"keep"``, ``"flag"`` (``sym_uncertain``) or ``"drop"`` (the identity alone).
    """
    transforms = [NormalizeArea(), ComputeSpectrum(k=k), ComputeDescriptors()]
    if detect:
        kw = {} if k_refine is None else {"k_refine": k_refine}
        transforms.append(DetectSymmetries(seed=seed, on_uncertain=on_uncertain, **kw))
    return Compose(transforms)


def find_meshes(src: str | os.PathLike, exclude: str | os.PathLike | None = None) -> list[Path]:
    """Mesh files under ``src`` (suffixes ``MESH_SUFFIXES``), in natural order of their relative path.

    Hidden files and folders (name starting with '.') and the folder ``exclude`` are skipped; symbolic
    links to folders are not followed.
    """
    src = Path(src)
    exclude = Path(exclude).resolve() if exclude is not None else None
    found = []
    for folder, dirs, files in os.walk(src):
        dirs[:] = [d for d in dirs if not d.startswith(".")
                   and (exclude is None or (Path(folder) / d).resolve() != exclude)]
        found += [Path(folder) / f for f in files
                  if not f.startswith(".") and Path(f).suffix.lower() in MESH_SUFFIXES]
    return sorted(found, key=lambda p: _natural_key(p.relative_to(src).as_posix()))


@dataclass
class Summary:
    """What one run (one rank) did; counts are meshes."""

    total: int = 0           # meshes this rank was given
    done: int = 0            # processed now
    skipped: int = 0         # already in the cache
    failed: int = 0          # listed in failures.jsonl
    seconds: float = 0.0
    peak_rss_mb: float = 0.0  # largest resident set of one process that processed meshes
    rank: int = 0
    world_size: int = 1
    failures: list = field(default_factory=list)  # [(file, reason)]
    uncertain: list = field(default_factory=list)  # files processed now whose symmetry is uncertain
    #                                                (on_uncertain="flag")
    ranks: list = field(default_factory=list)     # rank 0 under torchrun: every rank's summary

    def line(self) -> str:
        rate = 60.0 * self.done / self.seconds if self.seconds > 0 else 0.0
        flagged = f", {len(self.uncertain)} uncertain" if self.uncertain else ""
        return (f"{self.done} done{flagged}, {self.skipped} already done, {self.failed} failed, of "
                f"{self.total} in {_hms(self.seconds)} ({rate:.1f} meshes/min, peak "
                f"{self.peak_rss_mb:.0f} MB per process)")


@dataclass
class _Item:
    raw: Path
    rel: str      # posix path of the mesh relative to SRC (its id in failures.jsonl)
    folder: str   # posix path of its folder relative to SRC ("." at the top)
    name: str     # file stem: the sample name in MeshDataset
    out: Path


# ------------------------------------------------------------------------------------- worker side
_WORKER: dict = {}


def _init_worker(pre_transform, dtype, ground_truth, log_level, parent_pid) -> None:
    # Ctrl-C reaches the whole process group: the parent stops the workers, which must not each
    # print a KeyboardInterrupt traceback (they start with it blocked: _QuietSpawnProcess)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # a pending one is dropped
    torch.set_num_threads(1)
    _WORKER.update(pre_transform=pre_transform, dtype=dtype, ground_truth=ground_truth)
    logging.basicConfig(level=log_level, stream=sys.stderr,
                        format="symtorch: %(levelname)s: %(message)s")
    if parent_pid is not None:  # an orphaned worker (parent killed with -9) exits instead of waiting
        def watch():
            while os.getppid() == parent_pid:
                time.sleep(1.0)
            os._exit(1)

        threading.Thread(target=watch, daemon=True).start()


def _run_item(raw: str, out: str) -> dict:
    """Process one mesh in this process; never raises (the outcome is in the returned dict)."""
    t0 = time.perf_counter()
    res = {"raw": raw}
    # the reader logs each mesh warning; here they are collected and logged once by the parent (-v)
    io_log = logging.getLogger("symtorch.io")
    level = io_log.level
    if not io_log.isEnabledFor(logging.DEBUG):
        io_log.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(record=True) as caught, limit_threads(1):
            warnings.simplefilter("always")
            sample, res["entry"] = process_entry(raw, out, _WORKER["pre_transform"], _WORKER["dtype"],
                                                 _WORKER["ground_truth"])
            if "sym_uncertain" in sample:  # on_uncertain="flag": meta.json says which shapes are
                res["entry"]["uncertain"] = bool(sample["sym_uncertain"].any())
        res.update(ok=True, warnings=sorted({_one_line(w.message) for w in caught}))
    except WriteError as e:  # the output folder, not the mesh: the run stops (read-only, full)
        res.update(ok=False, fatal=True, error="WriteError", reason=str(e))
    except Exception as e:  # noqa: BLE001 -- any failure of one mesh is reported, not raised
        log.debug("%s failed", raw, exc_info=True)
        msg = _one_line(e)
        if not msg.startswith(raw):  # not the reader's message: say what is odd about the mesh
            msg = f"{raw}: {type(e).__name__}: {msg}{_mesh_problems(raw)}"
        res.update(ok=False, error=type(e).__name__, reason=msg)
    finally:
        io_log.setLevel(level)
    res["seconds"] = time.perf_counter() - t0
    res["rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB
    return res


def _mesh_problems(raw: str) -> str:
    """`` (mesh: 2 connected components; ...)`` for a mesh that broke processing, or ``""``."""
    from ..io import _problems, mesh_report, read_mesh

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mesh = read_mesh(raw)
        problems = ["a point cloud"] if mesh.faces is None else []
        problems += _problems(mesh_report(mesh.verts, mesh.faces))
        if len(mesh.verts) < 100:
            problems.append(f"only {len(mesh.verts)} vertices")
    except Exception:  # noqa: BLE001 -- only a hint
        return ""
    return f" (mesh: {'; '.join(problems)})" if problems else ""


# ------------------------------------------------------------------------------------- main side
@contextlib.contextmanager
def _locked(path: Path):
    """An exclusive ``fcntl`` lock on ``path`` (several processes or machines share ``OUT``)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: one process at a time is the user's business
        yield
        return
    try:
        fh = open(path, "a+")
    except OSError as e:
        raise _write_error(path, e) from None
    with fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


class _Progress:
    """``[####    ] 12/76 16% 3.1 meshes/min ETA 0:20:13 name`` on stderr: redrawn on a terminal,
    a line every 5 % or 30 s otherwise (logs, torchrun)."""

    def __init__(self, total: int, prefix: str = "", stream=None, enabled: bool = True):
        self.total, self.prefix, self.n = total, prefix, 0
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled and total > 0
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.t0 = self.last = time.perf_counter()
        self.next_n = 0

    def clear(self) -> None:
        """Blank the bar's line on a terminal, so that a log line can be printed."""
        if self.enabled and self.tty and self.n:
            self.stream.write("\r" + " " * 150 + "\r")
            self.stream.flush()

    def update(self, label: str = "") -> None:
        self.n += 1
        if not self.enabled:
            return
        now = time.perf_counter()
        if not self.tty and self.n < self.total and self.n < self.next_n and now - self.last < 30:
            return
        self.last, self.next_n = now, self.n + max(1, self.total // 20)
        elapsed = now - self.t0
        rate = self.n / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.n) / rate if rate > 0 else 0.0
        width = 24
        bar = "#" * int(width * self.n / self.total)
        msg = (f"{self.prefix}[{bar:<{width}}] {self.n}/{self.total} {100 * self.n / self.total:3.0f}% "
               f"{60 * rate:.1f} meshes/min ETA {_hms(eta)} {label[-40:]}")
        if self.tty:
            end = "\n" if self.n == self.total else ""
            self.stream.write("\r" + msg[:150].ljust(150) + end)
        else:
            self.stream.write(msg + "\n")
        self.stream.flush()


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


def _dist_env() -> tuple[int, int]:
    """(rank, world size) from the ``torchrun`` environment; (0, 1) outside it."""
    try:
        rank, world = int(os.environ.get("RANK", 0)), int(os.environ.get("WORLD_SIZE", 1))
    except ValueError:
        raise ValueError(f"RANK={os.environ.get('RANK')!r} and WORLD_SIZE="
                         f"{os.environ.get('WORLD_SIZE')!r} must be integers") from None
    if world < 1 or not 0 <= rank < world:
        raise ValueError(f"need 0 <= RANK < WORLD_SIZE, got RANK={rank} WORLD_SIZE={world}")
    return rank, world


class _Recorder:
    """Collects outcomes and writes them to ``meta.json`` / ``failures.jsonl`` under the lock."""

    def __init__(self, out: Path, key: dict, rank: int):
        self.out, self.key, self.rank = out, key, rank
        self.pending: dict[str, dict[str, list]] = {}
        self.last_flush, self.flush_cost = time.perf_counter(), 0.0

    def success(self, item: _Item, entry: dict) -> None:
        self.pending.setdefault(item.folder, {})[item.name] = entry
        # after every mesh while meta.json is cheap to rewrite (< 0.2 s); for huge folders, often
        # enough that the rewrites take at most _FLUSH_SHARE of the time (a kill loses that little)
        waited = time.perf_counter() - self.last_flush
        if self.flush_cost < 0.2 or waited >= self.flush_cost / _FLUSH_SHARE:
            self.flush()

    def failure(self, item: _Item, error: str, reason: str) -> None:
        line = json.dumps({"file": item.rel, "error": error, "reason": reason, "rank": self.rank,
                           "time": datetime.datetime.now().isoformat(timespec="seconds")})
        try:
            with _locked(self.out / LOCK), open(self.out / FAILURES, "a") as fh:
                fh.write(line + "\n")
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as e:
            raise _write_error(self.out / FAILURES, e) from None

    def flush(self) -> None:
        t0 = time.perf_counter()
        if self.pending:
            with _locked(self.out / LOCK):
                for folder, stamps in self.pending.items():
                    d = self.out / folder
                    meta = read_meta(d)
                    if meta is None or meta.get("key") != self.key:
                        meta = {"key": self.key, "files": {}}  # as MeshDataset does on a new key
                    meta["files"].update(stamps)
                    write_meta(d, meta)
            self.pending.clear()
        self.last_flush = time.perf_counter()
        self.flush_cost = self.last_flush - t0


def _is_done(item: _Item, meta: dict | None, key: dict, warn: bool = False) -> bool:
    """MeshDataset's rule, each cache file's checksum included; a file that does not verify warns."""
    try:
        problem = cache_problem(meta, key, item.name, item.raw, item.out)
    except OSError:  # the mesh vanished: processing it will say so
        return False
    if warn and problem not in (None, "not cached", "mesh changed"):
        log.warning("%s: %s; processing it again", item.out, problem)
    return problem is None


def precompute(src: str | os.PathLike, out: str | os.PathLike, *, k: int = 64, detect: bool = True,
               k_refine: int | None = None, workers: int = 1, dtype: torch.dtype = torch.float32, ground_truth: str | None = None,
               seed: int = 0, pre_transform: Callable[[dict], dict] | None = None,
               progress: bool = True, dist_timeout_min: float = 120.0,
               on_uncertain: str = "keep") -> Summary:
    """Process every mesh under ``src`` into ``MeshDataset`` caches under ``out`` (see module doc).

    Args:
        src: folder tree of meshes (``.off``, ``.obj``, ``.ply``, ``.stl``).
        out: cache folder (created); ``out/<folder>`` is the ``processed_dir`` of ``src/<folder>``.
        k, detect, seed, k_refine: build ``default_pre_transform(k, detect, seed, k_refine)`` unless
            ``pre_transform`` is given.
        workers: worker processes; 0 or 1 process in this process.
        dtype: of the cached ``verts`` (spectral keys follow it).
        ground_truth: ``None``, ``"template"`` or ``"vts"``, as for ``MeshDataset``.
        pre_transform: a deterministic transform to cache instead of the default.
        progress: draw a progress bar on stderr.
        dist_timeout_min: under torchrun, how long a rank waits for the others at the end.
        on_uncertain: ``"keep"``, ``"flag"`` or ``"drop"``: what a shape whose detected symmetry
            is uncertain gets (``DetectSymmetries``); ``"flag"`` also marks such shapes
            ``"uncertain": true`` in their ``meta.json`` entry and lists those processed now in
            ``Summary.uncertain``.

    Returns:
        Summary of this rank (under torchrun, rank 0's ``failures`` lists every rank's).

    Raises:
        FileNotFoundError: ``src`` does not exist or holds no mesh.
        NotADirectoryError: ``src`` is a file (or a symbolic link loop), not a folder.
        FolderInUse: another run is writing into ``out`` (the message names its pid).
        WriteError: ``out`` cannot be written (read-only, full), naming the file and the cause.
        ValueError: bad arguments.
    """
    src, out = Path(src), Path(out)
    _check_src(src)
    if workers < 0:
        raise ValueError(f"workers must be >= 0, got {workers}")
    if ground_truth not in (None, "template", "vts"):
        raise ValueError(f"ground_truth must be None, 'template' or 'vts', got {ground_truth!r}")
    if pre_transform is None:
        pre_transform = default_pre_transform(k, detect, seed, k_refine, on_uncertain)
    rank, world = _dist_env()
    t0 = time.perf_counter()
    files = find_meshes(src, exclude=out)
    if not files:
        raise FileNotFoundError(f"{src}: no {'/'.join(MESH_SUFFIXES)} files in this folder tree")
    _make_folder(out)
    if world > 1:
        _watch_agent(rank)
    with _run_lock(out, _run_id(world)):
        return _precompute_locked(src, out, files, k, detect, k_refine, workers, dtype, ground_truth,
                                  seed, pre_transform, progress, dist_timeout_min, rank, world, t0,
                                  on_uncertain)


def _precompute_locked(src, out, files, k, detect, k_refine, workers, dtype, ground_truth, seed,
                       pre_transform, progress, dist_timeout_min, rank, world, t0,
                       on_uncertain="keep") -> Summary:
    key = cache_key(pre_transform, dtype, ground_truth)
    if rank == 0:
        settings = {"src": str(src.resolve()), "k": k, "detect": detect, "seed": seed,
                    "k_refine": k_refine, "on_uncertain": on_uncertain,
                    "dtype": str(dtype).removeprefix("torch."), "ground_truth": ground_truth,
                    "default_pre_transform": repr(pre_transform) == repr(
                        default_pre_transform(k, detect, seed, k_refine, on_uncertain)), "key": key}
        atomic_write(out / SETTINGS, lambda tmp: Path(tmp).write_text(json.dumps(settings, indent=1)))
    if world == 1:
        _remove_temporaries(out)  # this run holds the folder alone: left by a killed run

    items, taken, collisions = [], {}, []
    for raw in files:
        rel = raw.relative_to(src)
        folder = rel.parent.as_posix()
        item = _Item(raw, rel.as_posix(), folder, raw.stem, out / folder / f"{raw.stem}.pt")
        first = taken.setdefault((folder, raw.stem), item)
        if first is not item:  # MeshDataset names samples by file stem: one file per stem
            collisions.append((item, first))
        items.append(item)
    mine = items[rank::world]
    collided = {id(c): f for c, f in collisions}
    summary = Summary(total=len(mine), rank=rank, world_size=world)
    rec = _Recorder(out, key, rank)
    todo, metas = [], {}
    for item in mine:
        if item.folder not in metas:  # once per folder
            _make_folder(out / item.folder)
            metas[item.folder] = read_meta(out / item.folder)
            meta = metas[item.folder]
            if meta is not None and meta.get("key") != key:
                log.warning("cache %s was made with other settings; processing it again",
                            out / item.folder)
        first = collided.get(id(item))
        if first is not None:
            reason = (f"{item.raw}: same name {item.name!r} as {first.raw.name} (MeshDataset names "
                      "samples by file stem); skipped")
            rec.failure(item, "NameCollision", reason)
            summary.failed += 1
            summary.failures.append((item.rel, reason))
        elif _is_done(item, metas[item.folder], key, warn=True):
            summary.skipped += 1
        else:
            todo.append(item)

    prefix = f"rank {rank}/{world}: " if world > 1 else ""
    bar = _Progress(len(todo), prefix=prefix, enabled=progress)
    if progress:
        print(f"symtorch: {prefix}{len(mine)} meshes, {summary.skipped} already done, "
              f"{len(todo)} to do, {max(workers, 1)} process(es)", file=sys.stderr, flush=True)

    def record(item: _Item, res: dict) -> None:
        if res.get("fatal"):
            raise WriteError(0, res["reason"])
        summary.peak_rss_mb = max(summary.peak_rss_mb, res.get("rss_mb", 0.0))
        if res["ok"]:
            summary.done += 1
            rec.success(item, res["entry"])
            if res["entry"].get("uncertain"):
                summary.uncertain.append(item.rel)
                log.info("%s: uncertain symmetry (confidence below min_confidence)", item.rel)
            for w in res.get("warnings", []):
                log.info("%s", w)
        else:
            summary.failed += 1
            reason = res["reason"]  # starts with the path of the mesh
            summary.failures.append((item.rel, reason))
            rec.failure(item, res["error"], reason)
            bar.clear()
            log.warning("%s", reason)
        bar.update(item.rel)

    try:
        if workers <= 1 or len(todo) <= 1:
            _run_here(todo, pre_transform, dtype, ground_truth, record)
        else:
            _run_pool(todo, min(workers, len(todo)), pre_transform, dtype, ground_truth, record)
    finally:
        rec.flush()
    summary.seconds = time.perf_counter() - t0
    if world > 1:
        _finish_distributed(summary, out, items, key, dist_timeout_min)
    else:
        _compact_failures(out, items, key)
    return summary


def _check_src(src: Path) -> None:
    """One-line errors for a ``src`` that is no folder."""
    if src.is_dir():
        return
    try:
        os.stat(src)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise NotADirectoryError(f"{src}: symbolic link loop") from None
        raise FileNotFoundError(f"{src}: no such folder") from None
    raise NotADirectoryError(f"{src}: is a file, not a folder (precompute takes the folder tree "
                             "that holds the meshes)")


def _make_folder(path: Path) -> None:
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise WriteError(e.errno or 0, f"cannot create folder {path}: "
                                       f"{(e.strerror or type(e).__name__).lower()}") from None


def _run_id(world: int) -> str:
    """Names this run in the run lock: the ranks of one torchrun job share it."""
    if world > 1:
        rdzv = os.environ.get("TORCHELASTIC_RUN_ID") or "none"
        return (f"torchrun:{rdzv}:{os.environ.get('MASTER_ADDR')}:{os.environ.get('MASTER_PORT')}"
                f":{world}")
    return f"{socket.gethostname()}:{os.getpid()}:{secrets.token_hex(4)}"


@contextlib.contextmanager
def _run_lock(out: Path, run_id: str):
    """Hold ``out/.run.lock`` for the run: a second run (another ``run_id``) is refused.

    An ``fcntl`` lock, shared by the ranks of one run: the kernel drops it when its process dies, so
    the lock of a killed run is taken over (its file still names the dead holder). The check runs
    under ``out/.lock``, so two runs starting together cannot both win.

    Raises:
        FolderInUse: another live run holds the lock (the message names its pid and host).
    """
    try:
        import fcntl
    except ImportError:  # not POSIX: one run at a time is the user's business
        yield
        return
    path = out / RUN_LOCK
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as e:
        raise _write_error(path, e) from None
    try:
        with _locked(out / LOCK):
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                free = True
            except BlockingIOError:
                free = False
            except OSError as e:  # a file system without locks
                log.warning("cannot lock %s (%s); make sure no other run writes into %s", path,
                            e.strerror, out)
                free = None
            holder = _read_holder(fd)
            if free:
                if holder:
                    log.info("%s: taking over the lock of pid %s on %s (no longer running)", out,
                             holder.get("pid"), holder.get("host"))
                info = {"run": run_id, "pid": os.getpid(), "host": socket.gethostname(),
                        "started": datetime.datetime.now().isoformat(timespec="seconds")}
                try:
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
                except OSError as e:
                    raise _write_error(path, e) from None
                fcntl.flock(fd, fcntl.LOCK_SH)  # the other ranks of this run join it
            elif free is False:
                if holder.get("run") != run_id:
                    raise FolderInUse(
                        f"{out}: in use by another symtorch precompute (pid {holder.get('pid')} on "
                        f"{holder.get('host')}, since {holder.get('started')}); wait for it to "
                        "finish, or choose another output folder")
                fcntl.flock(fd, fcntl.LOCK_SH)  # a rank of the run that holds it
        yield
    finally:
        os.close(fd)  # drops the lock


def _read_holder(fd: int) -> dict:
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
        return info if isinstance(info, dict) else {}
    except (OSError, ValueError):
        return {}


def _watch_agent(rank: int) -> None:
    """Leave when the parent (torchrun's agent) dies: its orphaned ranks would otherwise wait at the
    final barrier until the distributed timeout."""
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(0.5)
        print(f"symtorch: error: rank {rank}: the torchrun agent (pid {parent}) is gone; leaving",
              file=sys.stderr, flush=True)
        os._exit(1)

    threading.Thread(target=watch, name="symtorch-agent-watchdog", daemon=True).start()


def _run_here(todo, pre_transform, dtype, ground_truth, record) -> None:
    # one thread in every pool, as in the workers: the same floating-point sums, the same files
    _WORKER.update(pre_transform=pre_transform, dtype=dtype, ground_truth=ground_truth)
    try:
        with limit_threads(1):
            for item in todo:
                record(item, _run_item(str(item.raw), str(item.out)))
    finally:
        _WORKER.clear()


@contextlib.contextmanager
def _single_threaded_env():
    """Spawned workers inherit the environment: one BLAS / OpenMP thread each from the start."""
    names = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "SYMTORCH_NUM_THREADS")
    old = {n: os.environ.get(n) for n in names}
    os.environ.update({n: "1" for n in names})
    try:
        yield
    finally:
        for n, v in old.items():
            if v is None:
                os.environ.pop(n, None)
            else:
                os.environ[n] = v


def _quiet_process_class():
    import multiprocessing as mp

    class QuietSpawnProcess(mp.get_context("spawn").Process):
        """A spawned process started with SIGINT blocked (the signal mask survives the exec; the
        worker ignores SIGINT and unblocks it once running). Ctrl-C reaches the whole process group,
        and a worker still importing torch would print a KeyboardInterrupt traceback; the parent
        stops its workers itself. Blocked, not ignored, in the parent too: a Ctrl-C during the start
        is delivered after it, not lost (as multiprocessing starts its resource tracker)."""

        def start(self):
            old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
            try:
                return super().start()
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, old)

    QuietSpawnProcess.__qualname__ = QuietSpawnProcess.__name__ = "_QuietSpawnProcess"
    return QuietSpawnProcess


_QuietSpawnProcess = _quiet_process_class()  # module level: spawn pickles the process object


class _Spawn:
    """The spawn context, keeping the worker processes it starts: their exit codes name a death."""

    def __init__(self):
        import multiprocessing as mp

        self._ctx = mp.get_context("spawn")
        self.processes: list = []

    def __getattr__(self, name):
        return getattr(self._ctx, name)

    def Process(self, *args, **kwargs):  # noqa: N802 -- multiprocessing's name
        proc = _QuietSpawnProcess(*args, **kwargs)
        self.processes.append(proc)
        return proc

    def stop(self) -> None:
        """Terminate the workers still alive (SIGTERM: no traceback) and reap them."""
        started = [proc for proc in self.processes if proc.pid is not None]
        for proc in started:
            if proc.is_alive():
                proc.terminate()
        for proc in started:
            proc.join(timeout=10)

    def deaths(self) -> str:
        """How the workers that ended abnormally ended, e.g. ``killed by SIGKILL``."""
        out = []
        for proc in self.processes:
            if proc.pid is None:
                continue
            proc.join(timeout=5)
            code = proc.exitcode
            # The pool's manager thread may reap the same process at once: its waitpid wins and ours
            # sees no child (exitcode None) until that thread has stored the status; wait for it.
            deadline = time.monotonic() + 5
            while code is None and time.monotonic() < deadline:
                time.sleep(0.05)
                code = proc.exitcode
            if code is not None and code < 0:
                with contextlib.suppress(ValueError):
                    out.append(f"killed by {signal.Signals(-code).name}")
                    continue
            if code:
                out.append(f"exit status {code}")
        out = sorted(set(out))
        if len(out) > 1 and "killed by SIGTERM" in out:  # the pool ends the others itself
            out.remove("killed by SIGTERM")
        return ", ".join(out) or "ended"


def _run_pool(todo, workers, pre_transform, dtype, ground_truth, record) -> None:
    """Run ``todo`` on ``workers`` spawned processes, at most one mesh in flight per worker.

    When a worker dies, the meshes in flight (every mesh whose result did not come back) are retried
    one at a time in a fresh worker each; one that kills its worker again is listed as failed, with
    the way the worker ended (``killed by SIGKILL``: out of memory, or killed from outside). On
    Ctrl-C (the workers ignore it) or any error the workers are terminated.
    """
    init = (pre_transform, dtype, ground_truth, logging.getLogger().level, os.getpid())
    queue = list(reversed(todo))
    with _single_threaded_env():
        while queue:
            suspects = []
            ctx = _Spawn()
            with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker,
                                     initargs=init) as pool:
                running: dict = {}
                try:
                    while queue or running:
                        while queue and len(running) < workers:
                            fut = pool.submit(_run_item, str(queue[-1].raw), str(queue[-1].out))
                            running[fut] = queue.pop()  # popped once submitted: never lost
                        finished, _ = wait(running, return_when=FIRST_COMPLETED)
                        for fut in finished:
                            res = fut.result()  # BrokenProcessPool: the item stays in running
                            record(running.pop(fut), res)
                except BrokenProcessPool:
                    for fut, item in running.items():
                        if fut.done() and not fut.cancelled() and fut.exception() is None:
                            record(item, fut.result())  # came back before the pool broke
                        else:
                            suspects.append(item)
                    log.warning("a worker process died (%s); retrying %d mesh(es) one at a time",
                                ctx.deaths(), len(suspects))
                except BaseException:
                    pool.shutdown(wait=False, cancel_futures=True)
                    with contextlib.suppress(Exception):
                        ctx.stop()
                    raise
            for item in suspects:  # alone in a fresh pool each, so a second death names the culprit
                record(item, _run_alone(item, init))


def _run_alone(item: _Item, init: tuple) -> dict:
    ctx = _Spawn()
    with ProcessPoolExecutor(1, mp_context=ctx, initializer=_init_worker, initargs=init) as alone:
        try:
            return alone.submit(_run_item, str(item.raw), str(item.out)).result()
        except BrokenProcessPool:
            return {"ok": False, "error": "WorkerDied",
                    "reason": f"{item.raw}: the worker process died on this mesh twice "
                              f"({ctx.deaths()}: out of memory, a crash in native code, or killed "
                              "from outside)"}
        except BaseException:
            alone.shutdown(wait=False, cancel_futures=True)
            with contextlib.suppress(Exception):
                ctx.stop()
            raise


def _compact_failures(out: Path, items: list[_Item], key: dict) -> None:
    """Keep in ``failures.jsonl`` the latest line of each mesh of SRC that is still not done."""
    path = out / FAILURES
    with _locked(out / LOCK):
        if not path.exists():
            return
        latest = {}
        for line in path.read_text().splitlines():
            with contextlib.suppress(ValueError, KeyError, TypeError):
                latest[json.loads(line)["file"]] = line
        by_rel = {it.rel: it for it in items}
        first = {}  # the file each sample name belongs to (a later one of the same stem collides)
        for it in items:
            first.setdefault((it.folder, it.name), it.rel)
        metas = {f: read_meta(out / f) for f in {it.folder for it in items}}
        # a mesh no longer in SRC, or done by now, is not failing any more
        keep = [line for rel, line in latest.items()
                if rel in by_rel and (first[by_rel[rel].folder, by_rel[rel].name] != rel
                                      or not _is_done(by_rel[rel], metas[by_rel[rel].folder], key))]
        if keep:
            atomic_write(path, lambda tmp: Path(tmp).write_text("".join(s + "\n" for s in keep)))
        else:
            path.unlink()


def _remove_temporaries(out: Path) -> None:
    """Temporary files left by a killed run (``.<name>.<random>.tmp``); only safe with no other writer."""
    for tmp in out.rglob(".*.tmp"):
        with contextlib.suppress(OSError):
            tmp.unlink()


def _finish_distributed(summary: Summary, out: Path, items, key, timeout_min: float) -> None:
    """Wait for every rank (gloo), gather the summaries on rank 0, tidy ``out`` there."""
    import torch.distributed as dist

    if "MASTER_ADDR" not in os.environ or not dist.is_available():
        log.warning("WORLD_SIZE > 1 without torchrun's MASTER_ADDR: no final barrier; rank %d "
                    "reports only itself", summary.rank)
        return
    own = dist.is_initialized()
    try:
        if not own:
            dist.init_process_group("gloo", timeout=datetime.timedelta(minutes=timeout_min))
        gathered = [None] * dist.get_world_size()
        dist.all_gather_object(gathered, asdict(summary))
        if summary.rank == 0:
            _compact_failures(out, items, key)
            _remove_temporaries(out)  # every rank has finished writing
            summary.failures = [tuple(f) for s in gathered for f in s["failures"]]
            summary.ranks = gathered
        dist.barrier()
    except Exception as e:  # noqa: BLE001 -- the work is done; only the joint summary is lost
        log.warning("rank %d: no joint summary (%s: %s)", summary.rank, type(e).__name__, _one_line(e))
    finally:
        if not own and dist.is_initialized():
            dist.destroy_process_group()


# ------------------------------------------------------------------------------------- reading back
def done_names(processed_dir: str | os.PathLike) -> list[str]:
    """Names recorded in ``processed_dir/meta.json`` whose ``.pt`` exists, in natural order."""
    d = Path(processed_dir)
    meta = read_meta(d) or {}
    return sorted((n for n in meta.get("files", {}) if (d / f"{n}.pt").exists()), key=_natural_key)


def open_dataset(src: str | os.PathLike, out: str | os.PathLike, folder: str = ".",
                 transform: Callable[[dict], dict] | None = None) -> MeshDataset:
    """``MeshDataset`` over the meshes of ``src/folder`` that ``symtorch precompute src out`` did.

    Rebuilds the pre-transform from ``out/precompute.json`` (so the cache key matches and nothing is
    processed again) and passes ``names=done_names(out/folder)``: failed meshes are left out.

    Raises:
        ValueError: ``out`` was made with a custom ``pre_transform`` (build ``MeshDataset`` yourself).
    """
    try:
        s = json.loads((Path(out) / SETTINGS).read_text())
    except (OSError, ValueError):
        raise FileNotFoundError(f"{Path(out) / SETTINGS}: not a symtorch precompute folder") from None
    if not s.get("default_pre_transform", False):
        raise ValueError(f"{out} was made with a custom pre_transform; build MeshDataset with it")
    names = done_names(Path(out) / folder)
    if not names:
        raise FileNotFoundError(f"{Path(out) / folder}: no precomputed meshes")
    return MeshDataset(Path(src) / folder,
                       default_pre_transform(s["k"], s["detect"], s["seed"], s.get("k_refine"),
                                             s.get("on_uncertain", "keep")),
                       transform, processed_dir=Path(out) / folder, names=names,
                       ground_truth=s["ground_truth"], dtype=_DTYPES[s["dtype"]])
