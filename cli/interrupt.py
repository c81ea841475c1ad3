"""Ctrl-C while a command runs: the first asks the engine to stop, the second interrupts."""

from __future__ import annotations

import signal
import threading


class CancelOnInterrupt:
    """While active, the first Ctrl-C (SIGINT) only sets `requested` (the engine's
    should_cancel), so packing stops and certifies what it has; a second Ctrl-C raises
    KeyboardInterrupt as usual. Does nothing outside the main thread."""

    def __init__(self) -> None:
        self.requested = False
        self._previous = None
        self._installed = False

    def __call__(self) -> bool:
        return self.requested

    def _handler(self, signum, frame) -> None:
        self.requested = True
        signal.signal(signal.SIGINT, self._restore())

    def _restore(self):
        return signal.default_int_handler if self._previous is None else self._previous

    def __enter__(self) -> CancelOnInterrupt:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.getsignal(signal.SIGINT)
            signal.signal(signal.SIGINT, self._handler)
            self._installed = True
        return self

    def __exit__(self, *exc) -> None:
        if self._installed:
            signal.signal(signal.SIGINT, self._restore())
            self._installed = False


class Terminated(BaseException):  # noqa: N818 - a signal, as KeyboardInterrupt is
    """SIGTERM or SIGHUP arrived: the run stops as a second Ctrl-C stops it."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


class TerminateCleanly:
    """While active, SIGTERM (a process manager, `kill`) and SIGHUP (a closed terminal) raise
    :class:`Terminated` in the main thread, so that every ``finally`` and ``except
    BaseException`` runs: staged temporary files are removed, outputs stay as they were.
    By default these signals ended the process on the spot, leaving an export's staged
    files behind. A signal the process ignores (SIGHUP under ``nohup``) stays ignored.
    Does nothing outside the main thread."""

    SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP")
                    if hasattr(signal, name))

    def __init__(self) -> None:
        self._previous: dict[int, object] = {}

    @staticmethod
    def _handler(signum, frame) -> None:
        raise Terminated(signum)

    def __enter__(self) -> TerminateCleanly:
        if threading.current_thread() is threading.main_thread():
            for signum in self.SIGNALS:
                previous = signal.getsignal(signum)
                # ignored (nohup ignores SIGHUP: the run must outlive its terminal), or a
                # handler not installed from Python, which could not be put back
                if previous is None or previous == signal.SIG_IGN:
                    continue
                self._previous[signum] = previous
                signal.signal(signum, self._handler)
        return self

    def __exit__(self, *exc) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous.clear()
