"""A certification's exact checks in worker processes.

manifold3d's calls hold the GIL, so threads do not run checks side by side
(docs/notes-core.md); processes do. Each worker builds the container's outside solid and
the types' solids once, from arrays, with the certifier's own call
(`exact_checks.check_solids`), then runs chunks of checks (`exact_checks.run_checks`) and
sends back their results, which are the ones the certifier's process would get. Workers
are spawned, not forked (the caller may be a thread of Blender or hold numba's threads),
and without the caller's main script: spawned workers import it again, so a script that
calls `pack` with no main guard would pack again in each of them.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path, PureWindowsPath

import numpy as np

from .exact_checks import PlacedSolids, check_solids, run_checks

#: checks sent to a worker at a time: tens of milliseconds of booleans against a
#: fraction of one to pickle the chunk; consecutive checks share objects
CHUNK_CHECKS = 64
#: chunks in flight per worker, so that no worker waits for the next
AHEAD = 4
#: seconds a started worker waits for the others (a pool whose worker died is broken
#: anyway, and ends the others)
START_SECONDS = 60.0

#: cgroup v2's CPU quota for this process's container: "max", or "<quota> <period>" (us)
CPU_MAX = Path("/sys/fs/cgroup/cpu.max")

_WORKER: dict = {}


def usable_processes(requested: int) -> int:
    """Worker processes a certification may use: `requested`, or with 0 one per core this
    process may run on (within its container's CPU quota); 1 where this process cannot
    have children (a daemonic process, such as a Dask worker's: its scenes already run
    side by side) or would not spawn a Python interpreter."""
    if multiprocessing.current_process().daemon or not _spawns_python():
        return 1
    if requested > 0:
        return requested
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    quota = _cpu_quota()
    return cores if quota is None else min(cores, quota)


def _spawns_python() -> bool:
    """Whether spawned workers would start a Python interpreter: an application that
    embeds Python may name itself as `sys.executable` (Blender did before 2.91), and
    spawning it would open the application again."""
    from multiprocessing import spawn

    # either separator: the name is all that matters, and Windows paths use both
    name = PureWindowsPath(os.fsdecode(spawn.get_executable() or "")).name.lower()
    return name.startswith(("python", "pypy"))


def _cpu_quota() -> int | None:
    """The cores a container's CPU quota allows (cgroup v2), rounded up; None where there
    is no quota or it cannot be read. A container limited to 2 CPUs on a 64-core host
    still sees all 64 in its affinity."""
    try:
        quota, period = CPU_MAX.read_text().split()[:2]
        return None if quota == "max" else max(1, math.ceil(int(quota) / int(period)))
    except (OSError, ValueError, ZeroDivisionError):
        return None


def _start(container: tuple[np.ndarray, np.ndarray], types: list[tuple], counter) -> None:
    # Ctrl-C in a terminal reaches the whole process group: the caller decides what it
    # means (the command line's first one only cancels the placement), not the workers
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # one core per worker: manifold3d spreads a boolean over the cores it may use, which
    # on small meshes gains less than a process per core (docs/notes-core.md)
    with counter.get_lock():
        k = counter.value
        counter.value += 1
    _WORKER["started"] = counter
    if hasattr(os, "sched_setaffinity"):
        cores = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cores[k % len(cores)]})
    _WORKER["solids"] = check_solids(container, types)


def _ready(processes: int) -> bool:
    """Returns once `processes` workers have started (each holds one of these calls
    meanwhile, so every worker takes one)."""
    counter = _WORKER["started"]
    give_up = time.monotonic() + START_SECONDS
    while counter.value < processes and time.monotonic() < give_up:
        time.sleep(0.005)
    return True


@contextlib.contextmanager
def _main_script_hidden() -> Iterator[None]:
    """Processes spawned in this block do not import the main script (`spawn` imports
    it by its module spec or file name, when the main module has one)."""
    main = sys.modules.get("__main__")
    saved = {k: main.__dict__[k] for k in ("__spec__", "__file__")
             if main is not None and k in main.__dict__}
    try:
        if main is not None:
            main.__spec__ = None
            main.__dict__.pop("__file__", None)
        yield
    finally:
        if main is not None:
            main.__dict__.update(saved)


def _chunk(typ: np.ndarray, matrices: np.ndarray, volume: np.ndarray, checks: np.ndarray,
           clearance: float) -> np.ndarray:
    return run_checks(PlacedSolids(_WORKER["solids"], typ, matrices), volume, checks,
                      clearance)


class CheckPool:
    """`processes` worker processes holding the solids of one container and its types.
    Close it (or use it as a context manager) to end them."""

    def __init__(self, processes: int, container: tuple[np.ndarray, np.ndarray],
                 types: list[tuple[np.ndarray, np.ndarray]]):
        self.processes = processes
        ctx = multiprocessing.get_context("spawn")
        self._pool = ProcessPoolExecutor(
            processes, mp_context=ctx,
            initializer=_start, initargs=(container, types, ctx.Value("i", 0)))
        # the pool spawns its workers as tasks arrive: start them all while the main
        # script is hidden, and return when all have started
        try:
            with _main_script_hidden():
                ready = [self._pool.submit(_ready, processes) for _ in range(processes)]
                for fut in ready:
                    fut.result()
        except BaseException:
            self.close()
            raise

    def run(self, typ: np.ndarray, matrices: np.ndarray, volume: np.ndarray,
            checks: np.ndarray, clearance: float,
            tick: Callable[[int], None] | None = None) -> np.ndarray:
        """`exact_checks.run_checks` of checks (K, 2) on objects typ (N,), matrices
        (N, 4, 4) and volumes (N,), in chunks on the workers. tick(count) is called as
        each chunk's results arrive, in order. Raises what a worker raised, or
        BrokenProcessPool when a worker died."""
        out = np.empty((len(checks), 2))
        starts = range(0, len(checks), CHUNK_CHECKS)
        waiting: deque[tuple[int, int, Future]] = deque()
        todo = iter(starts)
        for start in todo:
            waiting.append(self._submit(typ, matrices, volume, checks, clearance, start))
            if len(waiting) >= AHEAD * self.processes:
                break
        while waiting:
            lo, hi, fut = waiting.popleft()
            out[lo:hi] = fut.result()
            if tick is not None:
                tick(hi - lo)
            nxt = next(todo, None)
            if nxt is not None:
                waiting.append(self._submit(typ, matrices, volume, checks, clearance, nxt))
        return out

    def _submit(self, typ, matrices, volume, checks, clearance, start
                ) -> tuple[int, int, Future]:
        part = checks[start:start + CHUNK_CHECKS]
        objects, local = np.unique(part[part >= 0], return_inverse=True)
        ab = np.full(part.shape, -1, np.int64)
        ab[part >= 0] = local
        fut = self._pool.submit(_chunk, typ[objects], matrices[objects], volume[objects], ab,
                                clearance)
        return start, start + len(part), fut

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> CheckPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
