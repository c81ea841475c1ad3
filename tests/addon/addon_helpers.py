"""Helpers of the Blender add-on tests (the fixtures are in conftest.py).

The add-on package (addon/) is loaded under the module name ``jampacked_blender_addon``;
its bpy-free modules can be loaded on their own (no Blender needed).
"""

from __future__ import annotations

import importlib.util
import sys
import time
from types import ModuleType, SimpleNamespace

import numpy as np
import pytest
from testdata import REPO, mesh_path

ADDON = REPO / "addon"
MODULE = "jampacked_blender_addon"


def load_addon() -> ModuleType:
    """Import addon/ as a package (its relative imports need one)."""
    if MODULE in sys.modules:
        return sys.modules[MODULE]
    spec = importlib.util.spec_from_file_location(
        MODULE, ADDON / "__init__.py", submodule_search_locations=[str(ADDON)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[MODULE] = module
    spec.loader.exec_module(module)
    return module


def load_standalone(name: str) -> ModuleType:
    """Import one bpy-free module of addon/ (worker, engine, summary, build) on its own."""
    key = f"jampacked_addon_{name}"
    if key in sys.modules:
        return sys.modules[key]
    spec = importlib.util.spec_from_file_location(key, ADDON / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[key] = module
    spec.loader.exec_module(module)
    return module


def mesh_object(bpy, name: str, vertices, faces, *, location=(0.0, 0.0, 0.0),
                rotation=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0)):
    """A mesh object made from arrays, linked to the scene."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(np.asarray(vertices, float).tolist(), [],
                     np.asarray(faces, int).tolist())
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = rotation
    obj.scale = scale
    return obj


def shared_mesh_object(bpy, relative: str, name: str, **transform):
    """A mesh object from a test mesh of tests/data/meshes (read with trimesh, not processed)."""
    trimesh = pytest.importorskip("trimesh")
    m = trimesh.load(mesh_path(relative), process=False, force="mesh")
    return mesh_object(bpy, name, m.vertices, m.faces, **transform)


CUBE_VERTICES = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1),
                 (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
#: outward quads of CUBE_VERTICES
CUBE_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6),
              (3, 0, 4, 7)]


def cube_object(bpy, name: str, faces=CUBE_FACES, **transform):
    """A cube of side 2 made of quads (faces may be edited to break it)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(CUBE_VERTICES, [], [list(f) for f in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    for key, value in transform.items():
        setattr(obj, key, value)
    return obj


#: a box scale for the scene fixture's container that takes more than 60 s to fill
BIG_BOX = (15.0, 14.0, 16.0)
#: a time budget for a pack that must still run while a test acts on it (cancel, a second
#: Pack): attempts follow one another until it is spent
LONG_BUDGET = 60.0


def scene_state(bpy) -> dict:
    """What must not change when a job is cancelled or fails: every datablock by name, the
    scene's collections and objects, and every object's transform."""
    bpy.context.view_layer.update()
    return {
        "objects": sorted(o.name for o in bpy.data.objects),
        "meshes": sorted(m.name for m in bpy.data.meshes),
        "materials": sorted(m.name for m in bpy.data.materials),
        "collections": sorted(c.name for c in bpy.data.collections),
        "scene_objects": sorted(o.name for o in bpy.context.scene.objects),
        "children": sorted(c.name for c in bpy.context.scene.collection.children),
        "matrices": {o.name: [list(r) for r in o.matrix_world] for o in bpy.data.objects},
        "result": getattr(bpy.context.scene.jampacked.result, "name", None),
    }


class Event(SimpleNamespace):
    """A stand-in for a window manager event passed to ``modal``."""

    def __init__(self, type: str, value: str = 'NOTHING') -> None:  # noqa: A002
        super().__init__(type=type, value=value)


def runner(addon: ModuleType, kind: str = "pack"):
    """A Pack (or Export) runner outside Blender's operator machinery, with the same modal
    steps as the operator; ``reports`` collects what it reports."""
    base = {"pack": addon.operators.PackRunner, "export": addon.operators.ExportRunner}[kind]

    class Runner(base):
        def __init__(self) -> None:
            self.reports: list[tuple[str, str]] = []

        def report(self, levels, message) -> None:
            self.reports.extend((level, message) for level in levels)

    return Runner()


def drive(run, context, *, events=(), timeout: float = 120.0) -> set:
    """Feed ``modal`` the given events, then TIMER events until the runner ends."""
    for event in events:
        result = run.modal(context, event)
        if result != {'RUNNING_MODAL'}:
            return result
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        result = run.modal(context, Event('TIMER'))
        if result != {'RUNNING_MODAL'}:
            return result
        time.sleep(0.05)
    raise AssertionError("the job did not end in time")


class Layout:
    """A stand-in for bpy.types.UILayout that checks what panels ask for: every property
    drawn exists on its data, every operator is registered."""

    def __init__(self, calls: list) -> None:
        self.calls = calls

    def __getattr__(self, name: str):
        def method(*args, **kwargs):
            self.calls.append((name, args, kwargs))
            if name == "prop":
                data, prop = args[0], args[1]
                assert prop in data.bl_rna.properties, f"{type(data).__name__}.{prop}"
            if name == "operator":
                import bpy

                category, op = args[0].split(".")
                assert hasattr(bpy.types, f"{category.upper()}_OT_{op}"), args[0]
                return SimpleNamespace()
            if name == "template_list":
                assert hasattr(__import__("bpy").types, args[0]), args[0]
            return Layout(self.calls)

        return method


def scale_in_edit_mode(bpy, obj, factor: float) -> None:
    """Enter Edit Mode on ``obj`` and scale its vertices by ``factor`` there, staying in it:
    the edit is in the edit mesh, not yet in the mesh data."""
    import bmesh

    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode='EDIT')
    bm = bmesh.from_edit_mesh(obj.data)
    bmesh.ops.scale(bm, vec=(factor, factor, factor), verts=bm.verts)
    bmesh.update_edit_mesh(obj.data)
