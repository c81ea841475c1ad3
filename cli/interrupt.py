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
