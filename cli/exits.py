"""Exit statuses of the ``jampacked`` command and the one-line error message of a failure."""

from __future__ import annotations

import sys

#: exit status for bad command-line arguments (argparse uses the same)
EXIT_USAGE = 2
EXIT_ERROR = 1
EXIT_INTERRUPTED = 130


def print_error(message: object) -> None:
    """``error: MESSAGE`` on stderr, on one line (whitespace runs collapsed)."""
    text = " ".join(str(message).split()) or "unknown error"
    print(f"error: {text}", file=sys.stderr)
