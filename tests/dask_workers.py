"""Helpers for tests on a real Dask LocalCluster (tests/ is on sys.path: see conftest.py)."""

from __future__ import annotations

import contextlib
import os
import time


def kill_a_busy_worker(client, wait: float = 120.0) -> str | None:
    """Kill (os._exit) the first worker seen running a task, once the task has started
    there; its address, or None if none was busy within `wait` seconds."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < wait:
        busy = [w for w, keys in client.processing().items() if keys]
        if busy:
            time.sleep(0.3)  # the task has started there
            with contextlib.suppress(Exception):
                client.run(os._exit, 1, workers=[busy[0]])
            return busy[0]
        time.sleep(0.05)
    return None


def transitions(client) -> int:
    """How many task transitions the scheduler has logged so far."""
    return client.run_on_scheduler(_count_transitions)


def task_starts(client, prefix: str, since: int) -> dict[str, int]:
    """How many times each task whose key starts with `prefix` went to a worker, counting
    the scheduler's transitions after the first `since` (`transitions`)."""
    return client.run_on_scheduler(_starts, prefix, since)


def _count_transitions(dask_scheduler=None) -> int:
    return len(dask_scheduler.transition_log)


def _starts(prefix: str, since: int, dask_scheduler=None) -> dict[str, int]:
    out: dict[str, int] = {}
    for key, _start, finish, *_ in list(dask_scheduler.transition_log)[since:]:
        if str(key).startswith(prefix) and finish == "processing":
            out[str(key)] = out.get(str(key), 0) + 1
    return out
