"""numba's cache of the engine's machine code: is it cold?

numba compiles the kernels on first use and caches the machine code (NUMBA_CACHE_DIR, else
``__pycache__`` beside the installed package, else a user folder). Compiling takes tens of
seconds (docs/benchmarks.md), loading from the cache about a second, so front ends tell the
user before the wait (`pack()` reports COMPILE_MESSAGE) and after it (`compile_hint`).
"""

from __future__ import annotations

#: the progress message while the kernels compile (cold cache)
COMPILE_MESSAGE = "compiling the engine (first run only, about half a minute)"
#: a warm-up this long (s) was a compile, not a load from the cache
SLOW_WARM_UP = 2.0


def placement_kernels() -> list:
    """The numba dispatchers a pack's warm-up compiles (`Solver.warm_up`)."""
    from . import cellgrid, kernels

    return [kernels.resolve, kernels.free_distances_near, cellgrid.insert_range]


def _has_code(dispatcher) -> bool | None:
    """The dispatcher has machine code in memory or in numba's cache index for its
    current source; None when numba's cache cannot be read (its API is private)."""
    if dispatcher.signatures:
        return True
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - any change in numba's internals: unknown
        return None


def cold_kernels() -> list[str] | None:
    """The names of the placement kernels with no machine code in memory or in numba's
    cache (their first call compiles them); None when that cannot be told. Cheap: reads
    numba's index files, compiles nothing."""
    kernels = placement_kernels()
    known = [_has_code(d) for d in kernels]
    if any(k is None for k in known):
        return None
    return [d.__name__ for d, k in zip(kernels, known, strict=True) if not k]


def cache_is_cold() -> bool | None:
    """True when a placement kernel has no machine code in memory or in numba's cache
    (first run, a new numba, a changed source): its first call compiles it. None when
    that cannot be told."""
    cold = cold_kernels()
    return None if cold is None else bool(cold)


def cache_loads_and_compiles() -> tuple[int, int]:
    """How often this process loaded the placement kernels from numba's on-disk cache, and
    how often it compiled them (a cache miss): workers of a cluster should only load."""
    stats = [d.stats for d in placement_kernels()]
    return (sum(sum(s.cache_hits.values()) for s in stats),
            sum(sum(s.cache_misses.values()) for s in stats))


def cache_location() -> str:
    """Where numba caches the kernels' machine code (a folder)."""
    from . import kernels

    try:
        return str(kernels.resolve._cache._cache_path)
    except Exception:  # noqa: BLE001 - numba's internals changed
        import numba

        return numba.config.CACHE_DIR or "__pycache__ beside the jampacked package"


def compile_hint(seconds: float) -> str | None:
    """After a pack whose kernels took `seconds` to be ready: a line for the user when that
    was a compile (None when it was a load from the cache), saying whether later runs will
    be quick."""
    if seconds < SLOW_WARM_UP:
        return None
    if cache_is_cold():
        return (f"compiling the engine took {seconds:.0f} s and numba could not cache it in "
                f"{cache_location()}: every run will compile again. Set NUMBA_CACHE_DIR to "
                "a writable folder.")
    return (f"compiling the engine took {seconds:.0f} s (first run only: it is cached in "
            f"{cache_location()}).")
