"""The ``jampacked`` command line: ``jampacked pack ...``, ``export ...``, ``info ...`` and
``validate ...``.

A thin front end over :func:`jampacked.core.api.pack`, :mod:`jampacked.export` and the
packing JSON file. Lengths are in container units (millimetres when the result is meant for
printing).

Exit status: 0 success; 1 the engine refused (a :class:`JampackedError`: unusable mesh, no
object fits, unreadable packing file...) or ``info`` found a missing/changed source file;
2 bad command-line arguments (missing file, bad share, bad box spec...); 130 interrupted
(after Ctrl-C during packing the best certified packing so far is still saved).
``validate``: 0 every file is watertight, 1 some file is not, 2 a file is missing or unreadable.
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Sequence

from jampacked.cli.args import UsageError
from jampacked.cli.exits import EXIT_ERROR, EXIT_INTERRUPTED, EXIT_USAGE, print_error
from jampacked.cli.interrupt import CancelOnInterrupt, TerminateCleanly, Terminated
from jampacked.core.errors import JampackedError


def _configure_logging(debug: bool) -> None:
    """Engine log messages: shown with --debug; otherwise the CLI prints the warnings
    itself (from the packing), so the library loggers are kept quiet."""
    log = logging.getLogger("jampacked")
    if debug:
        if not any(getattr(h, "_jampacked_cli", False) for h in log.handlers):
            handler = logging.StreamHandler(sys.stderr)
            handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
            handler._jampacked_cli = True  # type: ignore[attr-defined]
            log.addHandler(handler)
        log.setLevel(logging.DEBUG)
    elif not any(isinstance(h, logging.NullHandler) for h in log.handlers):
        log.addHandler(logging.NullHandler())



def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``jampacked`` command line; returns the exit status (never exits itself)."""
    # the engine's imports take a second or more: a Ctrl-C during them is only recorded, so
    # that no library's bare `except:` swallows it half-way through an import (the run then
    # went on as if never interrupted) and no traceback is printed
    try:
        with CancelOnInterrupt() as early:
            from jampacked.cli.parser import build_parser
    except KeyboardInterrupt:  # a second Ctrl-C
        early.requested = True
    if early.requested:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or argparse's own usage errors
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    _configure_logging(args.debug)
    try:
        with TerminateCleanly():
            return int(args.run(args))
    except Terminated as exc:
        print("terminated", file=sys.stderr)
        return 128 + exc.signum
    except UsageError as exc:
        if args.debug:
            raise
        print_error(exc)
        return EXIT_USAGE
    except JampackedError as exc:
        if args.debug:
            raise
        print_error(exc)
        return EXIT_ERROR
    except KeyboardInterrupt:
        if args.debug:
            raise
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # whatever read the output stopped reading (`jampacked validate --json | head`):
        # stop quietly, and let no flush at exit write to the closed pipe again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_ERROR
    except Exception as exc:
        # a signal that arrived while a compiled kernel called back into Python comes out
        # wrapped (numba: "SystemError: ... returned a result with an exception set")
        signum = _terminated_by(exc)
        if signum is None or args.debug:
            raise
        print("terminated", file=sys.stderr)
        return 128 + signum


def _terminated_by(exc: BaseException) -> int | None:
    """The signal of a :class:`Terminated` that ``exc`` was raised while handling."""
    seen: set[int] = set()
    cause: BaseException | None = exc
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, Terminated):
            return cause.signum
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return None


if __name__ == "__main__":
    sys.exit(main())
