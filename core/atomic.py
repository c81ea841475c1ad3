"""Atomic file output: write a temporary file beside the target, then rename it over.

A reader never sees a partial file, and a failure leaves any earlier file untouched.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterator
from typing import IO


def _umask() -> int:
    # os.umask can only be read by setting it: done once, at import, before any thread of
    # ours writes files
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: the permission bits of a new file, as open() would give it (0o644 under umask 022)
NEW_FILE_MODE = 0o666 & ~_umask()


def missing_folder(folder: str | os.PathLike) -> str | None:
    """Why ``folder`` cannot hold an output because it is not there: a file stands on its
    path (or on a folder above it), or it does not exist; None when it is a folder."""
    folder = os.path.abspath(os.fspath(folder))
    if os.path.isdir(folder):
        return None
    here = folder
    while here and not os.path.exists(here):
        parent = os.path.dirname(here)
        if parent == here:
            break
        here = parent
    if os.path.exists(here) and not os.path.isdir(here):
        return f"'{here}' is a file, not a folder: give an output in a folder"
    return f"the folder '{folder}' does not exist; create it first"


def write_refusal(folder: str | os.PathLike) -> str | None:
    """Why no new file can be made in ``folder`` (permissions, an immutable attribute, a
    read-only disk), or None when one can: a hidden probe file is created and removed, since
    `os.access` misses some of these."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".jampacked-write-test.", dir=os.fspath(folder))
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)
    return None


def refusal_advice(folder: str | os.PathLike) -> str:
    """How to make ``folder`` writable again (for messages that name a refusal)."""
    return (f"Make it writable (e.g. chmod u+w {folder}; 'lsattr -d {folder}' shows an "
            f"immutable 'i' flag, which 'chattr -i {folder}' removes)")


@contextlib.contextmanager
def staged_output(path: str | os.PathLike, mode: str = "wb", *, suffix: str = ".tmp"
                  ) -> Iterator[tuple[IO, str]]:
    """Open a temporary file in `path`'s folder, yielding it and its path; on success it is
    complete on disk (fsynced) with an existing target's permission bits (a new one's as
    the umask gives: `NEW_FILE_MODE`), and left for the caller to rename over `path` (or
    remove); on failure it is removed. `path` itself is never touched."""
    path = os.fspath(path)
    directory, name = os.path.split(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=suffix, dir=directory or ".")
    try:
        text = "b" not in mode
        with os.fdopen(fd, mode, **({"encoding": "utf-8", "newline": "\n"} if text else {})) as f:
            yield f, tmp
            f.flush()
            os.fsync(f.fileno())
        try:
            perm = os.stat(path).st_mode & 0o777
        except FileNotFoundError:
            perm = NEW_FILE_MODE
        os.chmod(tmp, perm)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, mode: str = "wb", *, suffix: str = ".tmp",
                  check: Callable[[str], None] | None = None) -> Iterator[IO]:
    """Open a temporary file in `path`'s folder; on success fsync and rename it to `path`
    (`staged_output`, then the rename).

    The file keeps an existing target's permission bits (a new one's follow the umask).
    ``check``, if given, is called with the temporary file's path once it is complete on
    disk and before it is renamed (e.g. to read it back); whatever it raises leaves `path`
    as it was.
    """
    with staged_output(path, mode, suffix=suffix) as (f, tmp):
        yield f
    try:
        if check is not None:
            check(tmp)
        os.replace(tmp, os.fspath(path))
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
