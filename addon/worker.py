"""Background jobs for the add-on: one thread at a time, never touching bpy.

A :class:`Job` runs ``fn(progress, should_cancel)`` in a daemon thread. The thread only sees
what ``fn`` closes over (numpy arrays, plain values): everything Blender-side is read before
the job starts and written after it ends, on Blender's main thread, by the modal operator in
:mod:`.operators`, which polls :meth:`Job.snapshot` from a timer.

Placement snapshots: a job may publish what it has placed so far (:meth:`Job.publish`,
numpy arrays, a few times a second); the main thread reads the latest with
:meth:`Job.placed` for the live view (:mod:`.live_view`).

The engine's first run: numba compiles the kernels on first use (tens of seconds). The
add-on starts :func:`start_warm_up` when it is enabled, a thread that compiles them ahead of
time; a job waits for it before its own work (two threads in the kernels at once are not safe
with every numba threading layer), showing its progress as its own.

Stopping: :meth:`Job.cancel` (Esc, the Cancel button) asks the engine to stop and throws the
result away; :meth:`Job.finish_early` asks it to stop and keeps the best certified result so
far. Both only set a flag that the engine polls through ``should_cancel``; the thread ends
when the engine returns (it certifies what it has first, which can take a moment).

This module imports no bpy, so that the thread cannot call into Blender by accident.
"""

from __future__ import annotations

import logging
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

logger = logging.getLogger("jampacked.addon")

Progress = Callable[[float, str], None]
ShouldCancel = Callable[[], bool]
JobFunction = Callable[[Progress, ShouldCancel], Any]

#: job states
RUNNING, DONE, CANCELLED, FAILED = "running", "done", "cancelled", "failed"


class BusyError(RuntimeError):
    """Another job is still running: one job at a time."""


@dataclass(frozen=True)
class Snapshot:
    """What the main thread reads from a job: progress and, once over, its outcome.

    Attributes:
        state: RUNNING, DONE, CANCELLED or FAILED.
        fraction: progress in [0, 1].
        message: the engine's last progress message (phase, objects placed, density).
        stopping: a cancel or finish-early request is pending.
        elapsed: seconds since the job started.
        notes: the engine's advice so far (progress messages with its note prefix, which
            the next message would hide), oldest first.
    """

    state: str
    fraction: float
    message: str
    stopping: bool
    elapsed: float
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Placed:
    """The objects a running pack has placed so far (a snapshot for the live view).

    Attributes:
        positions: (N, 3) float64 centres (world space, Blender units).
        radii: (N,) float64 bounding radii (Blender units).
        types: (N,) int64 type indices (the order of the panel's type list).
        at: seconds since the job started.
    """

    positions: Any
    radii: Any
    types: Any
    at: float


class Job:
    """One background computation with progress, cancel and a result or an error.

    Args:
        title: what the job does, for messages ("Packing", "Export").
        fn: ``fn(progress, should_cancel) -> result``; runs in the thread. It must not touch
            bpy. ``jampacked`` errors (JampackedError) become the job's error message as they
            are; any other exception becomes "internal error" with the traceback logged.
    """

    def __init__(self, title: str, fn: JobFunction) -> None:
        self.title = title
        self._fn = fn
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._keep = True  # keep the result when stopped (finish early) or not (cancel)
        self._fraction = 0.0
        self._message = "starting"
        self._notes: list[str] = []
        self._state = RUNNING
        self._result: Any = None
        self._error: str | None = None
        self._started = time.perf_counter()
        self._ended: float | None = None
        self._placed: Placed | None = None
        self._thread = threading.Thread(target=self._run, name=f"jampacked {title}",
                                        daemon=True)

    # ---------------------------------------------------------------- thread side

    def _progress(self, fraction: float, message: str) -> None:
        from jampacked.core.report import NOTE_PREFIX

        message = str(message)
        with self._lock:
            if message.startswith(NOTE_PREFIX):
                self._notes.append(message[len(NOTE_PREFIX):])
                return
            self._fraction = min(max(float(fraction), self._fraction), 1.0)
            self._message = message

    def _should_cancel(self) -> bool:
        return self._stop.is_set()

    def publish(self, positions: Any, radii: Any, types: Any) -> None:
        """Thread side: the objects placed so far, (N, 3) positions, (N,) bounding radii and
        (N,) type indices (numpy arrays the caller no longer changes; world space and
        Blender units in the add-on). The main thread sees the latest."""
        with self._lock:
            self._placed = Placed(positions, radii, types, time.perf_counter() - self._started)

    def _run(self) -> None:
        from jampacked.core import errors

        try:
            wait_for_warm_up(self._progress, self._should_cancel)
            if self._stop.is_set():  # stopped while the engine compiled: nothing to keep
                self._end(CANCELLED)
                return
            result = self._fn(self._progress, self._should_cancel)
        except errors.JampackedError as exc:
            cancelled = getattr(errors, "Cancelled", ())
            if isinstance(exc, cancelled) and self._stop.is_set():
                self._end(CANCELLED)
            else:
                self._end(FAILED, error=str(exc))
        except BaseException as exc:  # noqa: BLE001 - reported to the user, logged in full
            # BaseException too (KeyboardInterrupt, SystemExit): a job left RUNNING would
            # never be handled and would hold the slot for good
            logger.error("%s failed:\n%s", self.title, traceback.format_exc())
            self._end(FAILED, error=f"{self.title} failed with an internal error "
                                    f"({type(exc).__name__}: {exc}); see the system console.")
        else:
            if self._stop.is_set() and not self._keep:
                self._end(CANCELLED)
            else:
                self._end(DONE, result=result)

    def _end(self, state: str, *, result: Any = None, error: str | None = None) -> None:
        with self._lock:
            self._result = result
            self._error = error
            self._ended = time.perf_counter()
            if state == DONE:
                self._fraction = 1.0
            self._state = state

    # ---------------------------------------------------------------- main thread side

    def start(self) -> Job:
        """Start the thread; raises BusyError if another job is still running."""
        _claim(self)
        self._started = time.perf_counter()
        try:
            self._thread.start()
        except BaseException:
            _release(self)
            raise
        return self

    def cancel(self) -> None:
        """Stop as soon as the engine allows and discard the result."""
        with self._lock:
            self._keep = False
        self._stop.set()

    def finish_early(self) -> None:
        """Stop as soon as the engine allows and keep the best (certified) result so far."""
        self._stop.set()

    @property
    def finish_requested(self) -> bool:
        """True once :meth:`finish_early` was called (and not :meth:`cancel`)."""
        with self._lock:
            return self._stop.is_set() and self._keep

    @property
    def cancel_requested(self) -> bool:
        """True once :meth:`cancel` was called (not :meth:`finish_early`)."""
        with self._lock:
            return self._stop.is_set() and not self._keep

    def snapshot(self) -> Snapshot:
        """Progress and state, read consistently."""
        with self._lock:
            end = self._ended if self._ended is not None else time.perf_counter()
            return Snapshot(state=self._state, fraction=self._fraction, message=self._message,
                            stopping=self._stop.is_set() and self._state == RUNNING,
                            elapsed=end - self._started, notes=tuple(self._notes))

    def placed(self) -> Placed | None:
        """The latest snapshot :meth:`publish` gave, or None."""
        with self._lock:
            return self._placed

    @property
    def over(self) -> bool:
        """The thread has finished (done, cancelled or failed)."""
        with self._lock:
            return self._state != RUNNING

    @property
    def result(self) -> Any:
        """The function's return value (DONE only)."""
        with self._lock:
            return self._result

    @property
    def error(self) -> str | None:
        """The message of a FAILED job."""
        with self._lock:
            return self._error

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the thread ends or ``timeout`` passes; True when it ended."""
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def release(self) -> None:
        """Let another job start (call once this job's outcome has been handled)."""
        _release(self)


class ProgressLog:
    """Progress lines for a console (Blender in background mode), throttled: a line when
    the fraction has moved by ``step`` since the last line or ``seconds`` have passed, and
    the first one.

    Args:
        title: the job, e.g. "Packing".
        step: fraction between lines.
        seconds: at most this long without a line while the job runs.
        clock: seconds, monotonic (a test passes its own).
    """

    def __init__(self, title: str, *, step: float = 0.05, seconds: float = 2.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.title = title
        self.step = step
        self.seconds = seconds
        self._clock = clock
        self._fraction: float | None = None
        self._at = 0.0

    def line(self, snap: Snapshot) -> str | None:
        """The line to print for this snapshot, or None (too soon since the last one)."""
        now = self._clock()
        if self._fraction is not None and snap.fraction - self._fraction < self.step and \
                now - self._at < self.seconds:
            return None
        self._fraction, self._at = snap.fraction, now
        return (f"Jampacked {self.title.lower()}: {snap.fraction:4.0%} {snap.message} "
                f"({snap.elapsed:.1f} s)")


# ---------------------------------------------------------------- one job at a time

_active_lock = threading.Lock()
_active: Job | None = None


def _claim(job: Job) -> None:
    global _active
    with _active_lock:
        if _active is not None and _active is not job:
            raise BusyError(f"{_active.title} is still running: wait for it or cancel it "
                            "(Esc, or Cancel in the Jampacked panel).")
        _active = job


def _release(job: Job) -> None:
    global _active
    with _active_lock:
        if _active is job:
            _active = None


def active_job() -> Job | None:
    """The job that holds the slot (running, or over but not yet handled), or None."""
    with _active_lock:
        return _active


def busy() -> bool:
    """True while a job holds the slot: a second Pack or Export cannot start."""
    return active_job() is not None


def abandon(timeout: float = 0.0) -> None:
    """Cancel the active job and free the slot (file loaded, add-on disabled).

    The thread ends by itself once the engine returns; its result is dropped.
    """
    job = active_job()
    if job is None:
        return
    job.cancel()
    job.wait(timeout)
    job.release()


# ---------------------------------------------------------------- the engine's first run

#: the panel's line while the warm-up runs
WARM_UP_TITLE = "Preparing the engine (first run only)"


class WarmUp(Job):
    """A thread that compiles the engine's kernels (or loads them from numba's cache):
    ``fn(progress)``, no bpy. Its progress, state and seconds are read with :meth:`snapshot`,
    as a job's; unlike a job it holds no slot, waits for nothing and cannot be stopped.
    """

    def __init__(self, fn: Callable[[Progress], Any]) -> None:
        super().__init__(WARM_UP_TITLE, lambda progress, _should_cancel: fn(progress))

    def _run(self) -> None:
        try:
            self._fn(self._progress, self._should_cancel)
        except BaseException as exc:  # noqa: BLE001 - the first job reports it again
            logger.warning("jampacked warm-up failed: %s", exc)
            self._end(FAILED, error=f"{type(exc).__name__}: {exc}")
        else:
            self._end(DONE)

    def start(self) -> WarmUp:
        self._thread.start()
        return self


def _warm_up_engine(progress: Progress) -> None:
    """Compile what Pack, Export and Validate call (no bpy: runs in the warm-up thread)."""
    from jampacked.core.warmup import warm_up

    try:
        from jampacked.export.validate import validate_arrays
    except ImportError:  # the engine without its export part: Pack still warms up
        validate_arrays = None
    warm_up(progress, then=validate_arrays)


_warm_up: WarmUp | None = None


def start_warm_up(fn: Callable[[Progress], Any] | None = None) -> WarmUp:
    """Start the warm-up thread unless one ran or runs already (enabling the add-on again
    in the same session finds the kernels compiled); returns it."""
    global _warm_up
    with _active_lock:
        if _warm_up is None or _warm_up.snapshot().state == FAILED:
            _warm_up = WarmUp(fn or _warm_up_engine).start()
        return _warm_up


def warm_up_snapshot() -> Snapshot | None:
    """The warm-up's progress and state, or None when none was started."""
    with _active_lock:
        warm = _warm_up
    return None if warm is None else warm.snapshot()


def wait_for_warm_up(progress: Progress | None = None,
                     should_cancel: ShouldCancel | None = None, poll: float = 0.1) -> None:
    """Block until the warm-up (if any) ends, passing its progress on as
    ``progress(0, "<WARM_UP_TITLE>: message")``; returns early when ``should_cancel()``
    (the job then stops as it would anyway). A failed warm-up is not an error here: the
    job compiles what it needs itself and reports any real failure."""
    with _active_lock:
        warm = _warm_up
    if warm is None:
        return
    while not warm.wait(poll):
        if progress is not None:
            progress(0.0, f"{WARM_UP_TITLE}: {warm.snapshot().message}")
        if should_cancel is not None and should_cancel():
            return
