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

from jampacked.core.options import CavityPassOptions, PackOptions

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


def rod_and_balls(folder: Path, rod_length: float = 36.0,
                  rod_radius: float = 1.5) -> list[str]:
    """A rod and balls of radius 2.5 as STL files in `folder`: in box:24 a 36 mm rod of
    radius 1.5 fits only near the long diagonals, one of radius 2 nowhere."""
    import trimesh

    rod, ball = folder / "rod.stl", folder / "ball.stl"
    trimesh.creation.cylinder(radius=rod_radius, height=rod_length, sections=16).export(rod)
    trimesh.creation.icosphere(subdivisions=2, radius=2.5).export(ball)
    return [str(rod), str(ball)]


def lemon_and_balls(folder: Path, ball_radius: float = 5.0) -> list[str]:
    """The low-poly YCB lemon x750 and balls (of radius 5: about 60 fit) as mesh files in
    `folder`: the lemon fits box:40 with its margins, but only at the centre in one
    orientation."""
    import trimesh

    lemon, ball = folder / "lemon.stl", folder / "ball.stl"
    fruit = trimesh.load(mesh_path("fruit/ycb_lowpoly/014_lemon.obj"), force="mesh")
    fruit.apply_scale(750.0).export(lemon)
    trimesh.creation.icosphere(subdivisions=2, radius=ball_radius).export(ball)
    return [str(lemon), str(ball)]


class UlpUp:
    """A numpy ufunc whose results are one ulp larger, as numpy's SIMD cube root, log and
    exp differ from libm's on CPUs with AVX-512."""

    def __init__(self, ufunc):
        self.ufunc = ufunc

    def __call__(self, *args, **kwargs):
        return np.nextafter(self.ufunc(*args, **kwargs), np.inf)

    def __getattr__(self, name):
        return getattr(self.ufunc, name)


def cavity_passes(*factors: float) -> PackOptions:
    """Pack options that run only these late cavity passes (start scales, e.g. 0.8): the
    default four take most of a small test's time where the path it checks needs fewer."""
    return PackOptions(cavity=CavityPassOptions(factors=tuple(factors)))


class MeshType:
    """An object type as `stacking` and `box_grid` read one: a mesh's float64 vertices and
    int64 faces."""

    def __init__(self, mesh) -> None:
        self.vertices = np.asarray(mesh.vertices, np.float64)
        self.faces = np.asarray(mesh.faces, np.int64)


def turned(mesh, angle: float = 0.7, shift=(0.0, 0.0, 0.0)):
    """A copy of the trimesh `mesh` turned by `angle` (radians) about the axis (1, 2, 3)
    through the origin, then moved by `shift`."""
    import trimesh

    m = mesh.copy()
    m.apply_transform(trimesh.transformations.rotation_matrix(angle, [1, 2, 3]))
    m.apply_translation(shift)
    return m
