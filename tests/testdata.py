"""Paths of the test data carried in tests/data (sources and licences of the meshes:
tests/data/meshes/README.md). Test modules import from here: tests/ is on sys.path through
tests/conftest.py."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

import numpy as np

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


def bench_module(stem: str, siblings: bool = False) -> ModuleType:
    """bench/<stem>.py imported once as ``jampacked_bench_<stem>`` (bench/ is no package);
    with `siblings`, bench/ goes on sys.path first, for a script that imports its siblings."""
    name = f"jampacked_bench_{stem}"
    if name not in sys.modules:
        if siblings:
            sys.path.insert(0, str(REPO / "bench"))
        spec = importlib.util.spec_from_file_location(name, REPO / "bench" / f"{stem}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def warm_cache_env(folder: str) -> dict:
    """For a bench's `fresh_cache_env`: this session's numba cache (its kernels already
    compiled; a fresh one costs each test a 40 s compile) and an empty approximation cache
    under `folder`."""
    return dict(os.environ, JAMPACKED_CACHE=os.path.join(folder, "jampacked"))


class UlpUp:
    """A numpy ufunc whose results are one ulp larger, as numpy's SIMD cube root, log and
    exp differ from libm's on CPUs with AVX-512."""

    def __init__(self, ufunc):
        self.ufunc = ufunc

    def __call__(self, *args, **kwargs):
        return np.nextafter(self.ufunc(*args, **kwargs), np.inf)

    def __getattr__(self, name):
        return getattr(self.ufunc, name)
