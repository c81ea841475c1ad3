"""Validate selected meshes as `jampacked validate` does, and select what fails."""

from __future__ import annotations

import pytest

pytest.importorskip("bpy")

import numpy as np  # noqa: E402
from addon_helpers import CUBE_FACES, CUBE_VERTICES, cube_object, mesh_object  # noqa: E402


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
    # a negative scale reverses a closed cube's winding in world space, yet Blender shows
    # and exports it outward (it was reported inside out, and Make Manifold could not mend
    # it); a cube modelled inside out stays inside out under the mirror
    mirrored = cube_object(bpy, "Mirrored", scale=(-1.0, 1.0, 1.0))
    inside_out = cube_object(bpy, "Inside out", faces=[f[::-1] for f in CUBE_FACES],
                             scale=(-1.0, 1.0, 1.0), location=(-10.0, 0.0, 0.0))
    # a Solidify modifier makes the open cube closed (and changes its topology)
    holed = cube_object(bpy, "Holed", faces=CUBE_FACES[:-1], location=(10.0, 0.0, 0.0))
    holed.modifiers.new("Solidify", 'SOLIDIFY').thickness = 0.2
    _select_only(bpy, [mirrored, inside_out, holed])
    bpy.ops.jampacked.validate()
    reports = {r.object_name: r for r in bpy.context.window_manager.jampacked_validation.reports}
    assert reports["Mirrored"].passed, reports["Mirrored"].summary
    assert not reports["Inside out"].passed and "inside out" in reports["Inside out"].summary
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


def test_validate_selects_the_hole_and_make_manifold_fixes_it(bpy, addon):
    """A cube with a hole: Validate alone selects the hole's boundary edges in edit mode;
    Make Manifold (one undo step) closes it so that Validate passes."""
    holed = cube_object(bpy, "Holed", faces=CUBE_FACES[:-1])
    _select_only(bpy, [holed])
    bpy.ops.ed.undo_push(message="before validate")
    assert bpy.ops.jampacked.validate('EXEC_DEFAULT', True) == {'FINISHED'}
    (report,) = bpy.context.window_manager.jampacked_validation.reports
    assert not report.passed
    assert holed.mode == 'EDIT'
    assert _selected(bpy, holed) == (4, 4, 0)
    assert tuple(bpy.context.tool_settings.mesh_select_mode) == (False, True, False)
    bm = __import__("bmesh").from_edit_mesh(holed.data)
    assert all(e.is_boundary for e in bm.edges if e.select)

    bpy.ops.object.mode_set(mode='OBJECT')
    bpy.ops.ed.undo_push(message="before repair")
    assert bpy.ops.jampacked.make_manifold('EXEC_DEFAULT', True) == {'FINISHED'}
    assert len(holed.data.polygons) == 6
    assert bpy.ops.jampacked.validate() == {'FINISHED'}
    (report,) = bpy.context.window_manager.jampacked_validation.reports
    assert report.passed, report.summary
    assert holed.mode == 'OBJECT'  # nothing to select

    bpy.ops.ed.undo()  # one step undoes the repair
    assert len(bpy.data.objects["Holed"].data.polygons) == 5


def test_make_manifold_merges_and_turns_faces_outward(bpy, addon):
    """A cube whose faces do not share vertices (split seams) and with one face flipped:
    merged by distance and turned outward, it passes."""
    verts, faces = [], []
    for i, face in enumerate(CUBE_FACES):
        face = face[::-1] if i == 2 else face
        faces.append([len(verts) + k for k in range(4)])
        verts.extend(np.array(CUBE_VERTICES, float)[list(face)] * 3.0)
    split = mesh_object(bpy, "Split", verts, faces)
    _select_only(bpy, [split])
    bpy.ops.jampacked.validate()
    assert not bpy.context.window_manager.jampacked_validation.reports[0].passed
    assert split.mode == 'EDIT'  # with the open seams selected
    assert bpy.ops.jampacked.make_manifold() == {'FINISHED'}
    assert split.mode == 'EDIT'  # the repair keeps the mode it found
    bpy.ops.object.mode_set(mode='OBJECT')
    assert len(split.data.vertices) == 8
    bpy.ops.jampacked.validate()
    report = bpy.context.window_manager.jampacked_validation.reports[0]
    assert report.passed, report.summary


@pytest.mark.parametrize("modifiers", [True, False])
def test_validate_reads_edits_made_in_edit_mode(bpy, addon, modifiers):
    """An object being edited is validated as the viewport shows it: a face deleted in Edit
    Mode, not yet left, opens the cube (without Apply Modifiers, Validate reads the mesh
    data, which the edit reaches once written to it)."""
    import bmesh

    bpy.context.scene.jampacked.validate_modifiers = modifiers
    cube = cube_object(bpy, "Cube")
    _select_only(bpy, [cube])
    bpy.ops.object.mode_set(mode='EDIT')
    try:
        bm = bmesh.from_edit_mesh(cube.data)
        bm.faces.ensure_lookup_table()
        bmesh.ops.delete(bm, geom=[bm.faces[0]], context='FACES_ONLY')
        bmesh.update_edit_mesh(cube.data)
        bpy.ops.jampacked.validate()
    finally:
        if cube.mode == 'EDIT':
            bpy.ops.object.mode_set(mode='OBJECT')
    (report,) = bpy.context.window_manager.jampacked_validation.reports
    assert not report.passed and _counts(report)["open_edges"] == 4


def test_validate_refuses_to_read_a_disabled_object_without_its_modifiers(bpy, addon):
    """With Apply Modifiers on, a cube with Solidify (two shells) disabled in viewports
    passed as the bare cube: Blender does not evaluate its modifiers there. Validate now
    names it and changes nothing; enabled, the shells are checked."""
    shell = cube_object(bpy, "Shell")
    shell.modifiers.new("Solidify", 'SOLIDIFY').thickness = 0.2
    bpy.context.scene.jampacked.validate_modifiers = True
    _select_only(bpy, [shell])
    shell.hide_viewport = True
    with pytest.raises(RuntimeError, match="'Shell' is disabled in viewports.*turn off Apply "
                       "Modifiers"):
        bpy.ops.jampacked.validate()
    assert len(bpy.context.window_manager.jampacked_validation.reports) == 0
    shell.hide_viewport = False
    assert bpy.ops.jampacked.validate() == {'FINISHED'}
    [report] = bpy.context.window_manager.jampacked_validation.reports
    assert "24 faces" in report.summary  # both shells, not the bare 12
    # its modifier off in the viewport too: the bare mesh is what Blender shows
    shell.modifiers["Solidify"].show_viewport = False
    shell.hide_viewport = True
    assert bpy.ops.jampacked.validate() == {'FINISHED'}
    [report] = bpy.context.window_manager.jampacked_validation.reports
    assert "12 faces" in report.summary


def test_validate_and_make_manifold_replace_the_panels_last_message(bpy, addon):
    # an earlier Export's error stayed on the panel's status line after a Validate that
    # passed: the line now tells the last operation's outcome
    job = bpy.context.window_manager.jampacked_job
    job.last_message, job.last_level = "Cannot export: an earlier error", 'ERROR'
    good = cube_object(bpy, "Good")
    _select_only(bpy, [good])
    assert bpy.ops.jampacked.validate() == {'FINISHED'}
    assert job.last_message.startswith("1 mesh(es) pass") and job.last_level == 'INFO'
    holed = cube_object(bpy, "Holed", faces=CUBE_FACES[:-1], location=(10.0, 0.0, 0.0))
    _select_only(bpy, [holed])
    assert bpy.ops.jampacked.validate() == {'FINISHED'}
    bpy.ops.object.mode_set(mode='OBJECT')
    assert job.last_message.startswith("1 of 1 mesh(es) fail") and job.last_level == 'WARNING'
    assert bpy.ops.jampacked.make_manifold() == {'FINISHED'}
    assert job.last_message.startswith("Made manifold: ") and job.last_level == 'INFO'
