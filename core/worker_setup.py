"""Run in each local Dask worker process as it starts (`cluster.client_for`'s preload).

A Ctrl-C reaches the whole foreground process group: the workers of a LocalCluster got it
too, and each printed a KeyboardInterrupt traceback (or, while starting, died), while the
client process stops its attempts and the workers in order anyway. So a worker ignores it.
"""

from __future__ import annotations

import signal
import threading


def dask_setup(worker: object) -> None:
    """Dask's preload hook: ignore SIGINT in this worker process (main thread only, where
    the worker's event loop runs; elsewhere a handler cannot be set)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
