"""One exception family for everything jampacked reports to a user.

Messages name the file or object, say what is wrong, and how to fix it.
"""

from __future__ import annotations


class JampackedError(Exception):
    """Base of every error jampacked raises on purpose."""


class MeshError(JampackedError):
    """A mesh file cannot be read, or its geometry is unusable (open, inverted, empty...)."""


class InputError(JampackedError):
    """Bad arguments: shares, sizes, clearance, unknown file formats, bad packing files."""


class OutputError(InputError):
    """An output file that cannot be asked for: an unknown format, an input file, a name
    given twice. Found before any work; the command line reports it as a usage error."""


class PackingError(JampackedError):
    """The packing itself cannot be done (e.g. no object fits the container)."""


class Cancelled(JampackedError):
    """The user cancelled a job that has nothing worth keeping yet (e.g. an export)."""


def plural(n: int, word: str, many: str | None = None) -> str:
    """A count and its noun for messages: ``"1 edge"``, ``"3 edges"``, ``"2 vertices"``."""
    return f"{n} {word if n == 1 else (many or word + 's')}"
