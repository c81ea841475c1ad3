"""Validate selected meshes as `jampacked validate` does, and select what fails."""

from __future__ import annotations

import pytest

pytest.importorskip("bpy")

from addon_helpers import CUBE_FACES, cube_object  # noqa: E402


def _select_only(bpy, objects) -> None:
    bpy.context.view_layer.update()  # new objects get their view layer bases here
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj in objects)
    bpy.context.view_layer.objects.active = objects[0]


def _counts(entry) -> dict[str, int]:
    return {c.kind: c.count for c in entry.checks}


def _selected(bpy, obj) -> tuple[int, int, int]:
    import bmesh

    bm = bmesh.from_edit_mesh(obj.data)
    return (sum(v.select for v in bm.verts), sum(e.select for e in bm.edges),
            sum(f.select for f in bm.faces))


def test_validate_finds_and_selects_a_hole_and_a_flipped_face(bpy, addon):
    good = cube_object(bpy, "Good", location=(10.0, 0.0, 0.0))
    holed = cube_object(bpy, "Holed", faces=CUBE_FACES[:-1], scale=(2.0, 2.0, 2.0))
    flipped_faces = list(CUBE_FACES)
    flipped_faces[1] = tuple(reversed(flipped_faces[1]))
    flipped = cube_object(bpy, "Flipped", faces=flipped_faces, location=(-10.0, 0.0, 0.0))
    _select_only(bpy, [holed, flipped, good])
    assert bpy.ops.jampacked.validate() == {'FINISHED'}
    reports = {r.object_name: r for r in bpy.context.window_manager.jampacked_validation.reports}
    assert set(reports) == {"Good", "Holed", "Flipped"}
    assert reports["Good"].passed and reports["Good"].summary.startswith("PASS Good")

    hole = reports["Holed"]
    assert not hole.passed and "FAIL" in hole.summary
    assert _counts(hole)["open_edges"] == 4 and _counts(hole)["holes"] == 1
    flip = reports["Flipped"]
    assert not flip.passed
    assert _counts(flip)["flipped_faces"] == 2  # one quad = two triangles
    assert _counts(flip)["inconsistent_edges"] == 4

    assert bpy.ops.jampacked.select_defects(object_name="Holed", kind="open_edges") == \
        {'FINISHED'}
    assert holed.mode == 'EDIT'
    assert _selected(bpy, holed) == (4, 4, 0)
    assert tuple(bpy.context.tool_settings.mesh_select_mode) == (False, True, False)
    bpy.ops.object.mode_set(mode='OBJECT')

    assert bpy.ops.jampacked.select_defects(object_name="Flipped", kind="flipped_faces") == \
        {'FINISHED'}
    assert flipped.mode == 'EDIT' and bpy.context.active_object == flipped
    assert _selected(bpy, flipped) == (4, 4, 1)
    bpy.ops.object.mode_set(mode='OBJECT')
    assert flipped.data.polygons[1].select


def test_validate_uses_world_space_and_modifiers(bpy, addon):
    # a negative scale turns a closed cube inside out in world space
    mirrored = cube_object(bpy, "Mirrored", scale=(-1.0, 1.0, 1.0))
    # a Solidify modifier makes the open cube closed (and changes its topology)
    holed = cube_object(bpy, "Holed", faces=CUBE_FACES[:-1], location=(10.0, 0.0, 0.0))
    holed.modifiers.new("Solidify", 'SOLIDIFY').thickness = 0.2
    _select_only(bpy, [mirrored, holed])
    bpy.ops.jampacked.validate()
    reports = {r.object_name: r for r in bpy.context.window_manager.jampacked_validation.reports}
    assert not reports["Mirrored"].passed and "inside out" in reports["Mirrored"].summary
    assert reports["Holed"].passed
    assert "Apply Modifiers" in reports["Holed"].note  # cannot select on a changed topology
    with pytest.raises(RuntimeError, match="turn off Apply Modifiers"):
        bpy.ops.jampacked.select_defects(object_name="Holed", kind="open_edges")

    bpy.context.scene.jampacked.validate_modifiers = False
    bpy.ops.jampacked.validate()
    reports = {r.object_name: r for r in bpy.context.window_manager.jampacked_validation.reports}
    assert not reports["Holed"].passed and _counts(reports["Holed"])["open_edges"] == 4
    assert bpy.ops.jampacked.select_defects(object_name="Holed", kind="open_edges") == \
        {'FINISHED'}
