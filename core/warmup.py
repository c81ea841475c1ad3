"""The engine's first run, ahead of time: compile (or load from numba's cache) the kernels
a pack calls, and optionally the export's, by running them on a tiny scene. The add-on does
it in the background when it is enabled; ``jampacked warmup`` on the command line.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from .api import pack
from .meshes import box_mesh
from .numba_cache import COMPILE_MESSAGE, cache_is_cold

Progress = Callable[[float, str], None]


def warm_up(progress: Progress | None = None,
            then: Callable[[np.ndarray, np.ndarray], object] | None = None) -> float:
    """Compile (or load from the cache) every kernel a pack calls, by packing a tiny scene
    (a 1-unit box of 0.3-unit boxes, low fidelity, nothing written to the approximation
    cache); then `then(vertices, faces)` on a box mesh, e.g. the export's validation, so
    that its kernels compile too. Returns the seconds taken. Safe in a thread: numba holds
    a lock while it compiles, so a pack started meanwhile waits for it."""
    report = progress or (lambda f, m: None)
    t0 = time.perf_counter()
    cold = cache_is_cold()
    message = "loading the engine" if cold is False else COMPILE_MESSAGE
    report(0.0, message)
    small = box_mesh([0.3, 0.25, 0.2])
    pack(box_mesh([1.0, 1.0, 1.0]), [small], fidelity="low", use_cache=False,
         progress=lambda f, m: report((0.8 if then else 0.95) * f, message))
    if then is not None:
        report(0.8, message)
        then(small.vertices, small.faces)
    report(1.0, "engine ready")
    return time.perf_counter() - t0
