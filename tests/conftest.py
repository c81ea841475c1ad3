"""Shared test setup.

This file puts tests/ on sys.path (pytest's default import mode does that for a conftest.py
outside a package), so test modules in any sub-folder can ``from testdata import mesh_path``.
"""

from __future__ import annotations

from testdata import MESHES, REPO


def pytest_report_header(config) -> str:
    return f"test meshes: {MESHES.relative_to(REPO)} (sources and licences in its README.md)"


def pytest_addoption(parser) -> None:
    parser.addoption("--wheels", action="store_true",
                     help="also run the tests marked 'wheels' (the Blender zip with its wheels "
                          "from PyPI, in the bare Blender Python that "
                          "JAMPACKED_BARE_BLENDER_PYTHON names)")


def pytest_configure(config) -> None:
    config.addinivalue_line(
        "markers", "wheels: downloads the add-on's wheels and installs the zip in a bare Blender "
                   "Python (needs the network and JAMPACKED_BARE_BLENDER_PYTHON); deselected "
                   "unless pytest --wheels")


def pytest_collection_modifyitems(config, items) -> None:
    """A release check, not a unit test: out of the default run (deselected, not skipped)."""
    if config.getoption("--wheels"):
        return
    wheels = [item for item in items if item.get_closest_marker("wheels")]
    if wheels:
        config.hook.pytest_deselected(items=wheels)
        items[:] = [item for item in items if not item.get_closest_marker("wheels")]
