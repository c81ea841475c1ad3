"""Shared test setup.

This file puts tests/ on sys.path (pytest's default import mode does that for a conftest.py
outside a package), so test modules in any sub-folder can ``from testdata import mesh_path``.
"""

from __future__ import annotations

import errno
import tempfile
from pathlib import Path

import pytest
from testdata import MESHES, REPO


def pytest_report_header(config) -> str:
    return f"test meshes: {MESHES.relative_to(REPO)} (sources and licences in its README.md)"


#: marks the test that compiles the engine from an empty numba cache: it runs first, so on
#: a fresh checkout the placement kernels it compiles are loaded, not compiled again, by
#: the rest of the suite (see tests/core/test_api.py)
FIRST_RUN = "first_run"


#: marks a test that bounds a phase's seconds or the main thread's waits: `make test` runs
#: these (and the first_run test) on their own before the rest, which runs on two processes
SERIAL = "serial"


def pytest_configure(config) -> None:
    config.addinivalue_line("markers", f"{FIRST_RUN}: runs before every other test (it "
                                       "fills numba's empty cache on a fresh checkout)")
    config.addinivalue_line("markers", f"{SERIAL}: bounds seconds; `make test` runs it "
                                       "alone, not beside another test process")


def pytest_collection_modifyitems(config, items) -> None:
    """Move the first_run tests to the front, keeping the order of the rest."""
    first = [item for item in items if item.get_closest_marker(FIRST_RUN)]
    rest = [item for item in items if not item.get_closest_marker(FIRST_RUN)]
    items[:] = first + rest


@pytest.fixture
def read_only_folder(tmp_path, monkeypatch) -> Path:
    """A folder that takes no new file, as on a read-only disk (tests run as root, whom
    permission bits do not stop): every temporary made in it fails with EROFS."""
    folder = tmp_path / "ro"
    folder.mkdir()
    real = tempfile.mkstemp

    def mkstemp(*args, dir=None, **kwargs):  # noqa: A002 (tempfile's own name)
        if dir is not None and Path(dir).resolve() == folder.resolve():
            raise OSError(errno.EROFS, "Read-only file system")
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    return folder
