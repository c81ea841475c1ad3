"""Shared test setup.

This file puts tests/ on sys.path (pytest's default import mode does that for a conftest.py
outside a package), so test modules in any sub-folder can ``from testdata import mesh_path``.
"""

from __future__ import annotations

from testdata import MESHES, REPO


def pytest_report_header(config) -> str:
    return f"test meshes: {MESHES.relative_to(REPO)} (sources and licences in its README.md)"


#: marks the test that compiles the engine from an empty numba cache: it runs first, so on
#: a fresh checkout the placement kernels it compiles are loaded, not compiled again, by
#: the rest of the suite (see tests/core/test_api.py)
FIRST_RUN = "first_run"


def pytest_configure(config) -> None:
    config.addinivalue_line("markers", f"{FIRST_RUN}: runs before every other test (it "
                                       "fills numba's empty cache on a fresh checkout)")


def pytest_collection_modifyitems(config, items) -> None:
    """Move the first_run tests to the front, keeping the order of the rest."""
    first = [item for item in items if item.get_closest_marker(FIRST_RUN)]
    rest = [item for item in items if not item.get_closest_marker(FIRST_RUN)]
    items[:] = first + rest
