"""Shared test setup.

This file puts tests/ on sys.path (pytest's default import mode does that for a conftest.py
outside a package), so test modules in any sub-folder can ``from testdata import mesh_path``.
"""

from __future__ import annotations

from testdata import MESHES, REPO


def pytest_report_header(config) -> str:
    return f"test meshes: {MESHES.relative_to(REPO)} (sources and licences in its README.md)"
