"""Paths of the test data carried in tests/data (sources and licences of the meshes:
tests/data/meshes/README.md). Test modules import from here: tests/ is on sys.path through
tests/conftest.py."""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent
DATA = TESTS / "data"
MESHES = DATA / "meshes"


def mesh_path(relative: str) -> Path:
    """A carried test mesh, e.g. ``mesh_path("containers/spot.obj")``; a missing file is an
    error (tests never skip for want of data)."""
    path = MESHES / relative
    if not path.is_file():
        raise FileNotFoundError(f"test mesh {relative!r} is not in {MESHES}")
    return path


def mesh_paths(pattern: str) -> list[str]:
    """The carried meshes matching a glob pattern, relative to MESHES, sorted."""
    found = sorted(str(p.relative_to(MESHES)) for p in MESHES.glob(pattern))
    if not found:
        raise FileNotFoundError(f"no test mesh matches {pattern!r} in {MESHES}")
    return found
