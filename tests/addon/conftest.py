"""Fixtures for the Blender add-on tests: real Blender as the ``bpy`` module, headless.

The add-on package (addon/) is registered once per session; every test starts from
``read_factory_settings(use_empty=True)``. Blender's user folders go to a temporary folder
(``BLENDER_USER_RESOURCES``), never the user's own. Tests that need bpy skip themselves where
it is not installed. Plain helpers are in addon_helpers.py.
"""

from __future__ import annotations

import atexit
import os
import tempfile
from types import ModuleType, SimpleNamespace

import pytest
from addon_helpers import cube_object, load_addon, shared_mesh_object

# before bpy is imported anywhere: keep Blender's preferences and extensions out of ~/.config
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="jampacked-blender-"))

_registered: list[ModuleType] = []

#: marks the test that builds the extension zip with its wheels (a download of about
#: 100 MB unless addon/wheels/ has them) and packs with it; run only with JAMPACKED_TEST_ZIP=1
ZIP_MARKER = "extension_zip"


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", f"{ZIP_MARKER}: builds and installs the extension zip with its linux-x64 "
                   "wheels (downloads about 100 MB once); deselected unless "
                   "JAMPACKED_TEST_ZIP=1")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Deselect (counted in pytest's summary, not skipped silently) the zip test unless
    JAMPACKED_TEST_ZIP=1."""
    if os.environ.get("JAMPACKED_TEST_ZIP") == "1":
        return
    zip_tests = [item for item in items if item.get_closest_marker(ZIP_MARKER)]
    if zip_tests:
        config.hook.pytest_deselected(items=zip_tests)
        items[:] = [item for item in items if item not in zip_tests]


def _unregister_at_exit() -> None:
    # Blender hangs at exit while Python callbacks (pointer polls) are still registered
    while _registered:
        _registered.pop().unregister()


@pytest.fixture(scope="session")
def addon() -> ModuleType:
    """The add-on, registered for the session (unregistered at the end)."""
    pytest.importorskip("bpy")
    module = load_addon()
    module.register()
    _registered.append(module)
    atexit.register(_unregister_at_exit)
    yield module
    _unregister_at_exit()


@pytest.fixture
def bpy(addon: ModuleType):
    """bpy with an empty factory scene and the add-on registered."""
    import bpy as _bpy

    _bpy.ops.wm.read_factory_settings(use_empty=True)
    # what an earlier test left: a job slot, a validation cache, a progress bar
    addon.worker.abandon(timeout=10.0)
    addon.operators.validation_cache().clear()
    yield _bpy
    addon.worker.abandon(timeout=10.0)


@pytest.fixture
def scene(bpy):
    """A small packing scene: a rotated, moved, non-uniformly scaled box (20 x 19 x 22 units,
    from Blender's cube) and two convex polyhedra of tests/data/meshes as types, one scaled
    by 0.8 in the scene. Low fidelity and no time budget: a pack is one attempt that places
    about ten objects in a second, the same on every run (with a budget, attempts follow one
    another until one repeats the best: seconds per pack). ``BIG_BOX`` with ``LONG_BUDGET``
    makes a pack that runs long."""
    box = cube_object(bpy, "Box", location=(5.0, -3.0, 2.0), rotation_euler=(0.3, 0.2, 0.1),
                      scale=(10.0, 9.5, 11.0))
    p5 = shared_mesh_object(bpy, "polyhedra/convex5/polytope5.obj", "P5",
                            location=(60.0, 0.0, 0.0), scale=(0.8, 0.8, 0.8))
    p4 = shared_mesh_object(bpy, "polyhedra/convex5/polytope4.obj", "P4",
                            location=(80.0, 0.0, 0.0), rotation=(0.0, 0.5, 0.0))
    s = bpy.context.scene.jampacked
    s.container = box
    for obj, share in ((p5, 1.0), (p4, 2.0)):
        item = s.types.add()
        item.object = obj
        item.share = share
    s.fidelity = 'LOW'
    s.time_budget = 0.0  # none
    s.seed = 1
    return SimpleNamespace(box=box, types=[p5, p4], settings=s)
