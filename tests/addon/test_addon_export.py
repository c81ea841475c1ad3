"""Export from the panel: the file written passes `jampacked validate`."""

from __future__ import annotations

import pytest

pytest.importorskip("bpy")

from addon_helpers import drive, runner, scale_in_edit_mode, scene_state  # noqa: E402


@pytest.fixture
def packed(bpy, scene):
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    return scene


def test_export_writes_a_valid_file(bpy, addon, packed, tmp_path):
    from jampacked.export.validate import validate_file

    s = packed.settings
    s.export_mode = 'CONNECT'
    s.file_format = '3MF'
    s.filepath = str(tmp_path / "out.stl")  # the extension follows the format
    before = scene_state(bpy)
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    out = tmp_path / "out.3mf"
    assert out.is_file()
    report = validate_file(out)
    assert report.passed and len(report.bodies) == 1
    message = bpy.context.window_manager.jampacked_job.last_message
    assert "PASS" in message and str(out) in message
    assert scene_state(bpy) == before  # export changes nothing in the scene


def test_export_through_the_modal_steps(bpy, addon, packed, tmp_path):
    from jampacked.export.validate import validate_file

    s = packed.settings
    s.export_mode = 'UNION'
    s.shell = 1.5
    s.opening = 'PLANE'
    s.opening_axis = 'PZ'
    s.opening_at = 0.8
    s.file_format = 'STL'
    s.filepath = str(tmp_path / "connected")
    run = runner(addon, "export")
    assert run.begin(bpy.context)
    assert drive(run, bpy.context) == {'FINISHED'}, run.reports
    # the test scene's box is 30 units of Blender's default metres: a 30 m print, which is
    # named, with the fix in Blender's words
    level, text = run.reports[-1]
    assert level == 'WARNING' and "Exported" in text, run.reports
    assert "x0.001 would make it 30.1 mm across" in text
    assert text.endswith("(the scene's Unit Scale, Scene Properties > Units) and pack again.")
    report = validate_file(tmp_path / "connected.stl")
    assert report.passed


def test_export_refuses_a_moved_container(bpy, addon, packed, tmp_path):
    packed.settings.filepath = str(tmp_path / "x.stl")
    packed.box.location.z += 5.0
    with pytest.raises(RuntimeError, match="'Box' was moved or edited after packing"):
        bpy.ops.jampacked.export()
    assert not (tmp_path / "x.stl").exists()


def test_export_refuses_a_type_mesh_being_edited(bpy, addon, packed, tmp_path):
    """An edit of a placed object's shared mesh, still in Edit Mode, is an edit: Export
    leaves Edit Mode first, so that it reads the mesh as the viewport shows it."""
    packed.settings.filepath = str(tmp_path / "x.stl")
    placed = next(o for o in packed.settings.result.objects if o.type == 'MESH')
    try:
        scale_in_edit_mode(bpy, placed, 1.5)
        with pytest.raises(RuntimeError, match=f"The mesh '{placed.data.name}' of type .* "
                                               "was edited after packing"):
            bpy.ops.jampacked.export()
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
    assert not (tmp_path / "x.stl").exists()


def test_export_errors_say_millimetres(bpy, addon, packed, tmp_path):
    """Export works in millimetres: its messages' lengths, which read "units" (the command
    line's container units), say mm."""
    packed.settings.filepath = str(tmp_path / "x.stl")
    placed = next(o for o in packed.settings.result.objects if o.type == 'MESH')
    placed.location.x += 1000.0
    with pytest.raises(RuntimeError, match=r"is up to [\d.e+]+ mm across, at \(") as caught:
        bpy.ops.jampacked.export()
    assert " units" not in str(caught.value)
    assert not (tmp_path / "x.stl").exists()


def test_export_needs_a_packing(bpy, addon, scene, tmp_path):
    scene.settings.filepath = str(tmp_path / "x.stl")
    with pytest.raises(RuntimeError, match="no packing to export: run Pack first"):
        bpy.ops.jampacked.export()


def test_export_path_takes_blend_relative_paths(bpy, addon, tmp_path):
    """The File setting declares '//' paths (Blender 4.5 warns on every assignment
    otherwise), and '//' is resolved against the saved .blend file before the job."""
    import warnings

    prop = bpy.types.Scene.bl_rna.properties["jampacked"].fixed_type.properties["filepath"]
    assert prop.is_path_supports_blend_relative
    s = bpy.context.scene.jampacked
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s.filepath = "//prints/out.stl"
    from jampacked.core.errors import InputError

    with pytest.raises(InputError, match="not saved yet"):
        addon.bridge.output_path(s.filepath, '3MF')
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    (tmp_path / "prints").mkdir()
    assert addon.bridge.output_path(bpy.context.scene.jampacked.filepath, '3MF') == \
        str(tmp_path / "prints" / "out.3mf")


def test_export_path_names_a_file_in_the_folders_way(bpy, addon, tmp_path):
    """A file where the output's folder should be read as a folder that does not exist."""
    from jampacked.core.errors import InputError

    (tmp_path / "afile").write_text("x")
    with pytest.raises(InputError, match="afile' is a file, not a folder"):
        addon.bridge.output_path(str(tmp_path / "afile" / "out.stl"), 'STL')
    with pytest.raises(InputError, match="does not exist; create it first, or pick another"):
        addon.bridge.output_path(str(tmp_path / "nope" / "out.stl"), 'STL')


def test_a_scene_in_metres_exports_in_millimetres(bpy, addon, scene, tmp_path):
    """Blender's default units (1 BU = 1 m): a 6 cm box modelled as 0.06 BU, filled and
    exported with a 2 mm shell (typed as 0.002 m), prints 60 mm wide; the panel says so.
    (6 cm, not 12: the shell's distance grid, at T/4, has an eighth of the nodes.)"""
    import numpy as np
    import trimesh

    units = bpy.context.scene.unit_settings
    assert (units.system, units.scale_length) == ('METRIC', 1.0)
    k = 0.002  # the fixture's turned box spans 30 units: 0.06 m across
    scene.box.scale = tuple(k * np.array(scene.box.scale))
    scene.box.location = tuple(k * np.array(scene.box.location))
    for obj in scene.types:
        obj.scale = tuple(k * np.array(obj.scale))
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    box = addon.bridge.object_triangles(scene.box, depsgraph).vertices
    assert np.ptp(box, axis=0).max() == pytest.approx(0.06, abs=0.0025)
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    assert scene.settings.result["jampacked_count"] > 5
    s = scene.settings
    s.export_mode, s.shell, s.file_format = 'UNION', 0.002, 'STL'
    s.filepath = str(tmp_path / "cow.stl")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    # its lengths said in millimetres (they were bare numbers, and an STL's volume "units³")
    message = bpy.context.window_manager.jampacked_job.last_message
    assert "shell 2 mm thick" in message and "units" not in message, message
    assert "mm³" in message
    s.file_format = '3MF'
    s.filepath = str(tmp_path / "cow.3mf")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    printed = trimesh.load(tmp_path / "cow.3mf", force="mesh")
    np.testing.assert_allclose(printed.bounds, 1000.0 * np.array([box.min(0), box.max(0)]),
                               atol=4.0)  # mm: the shell's 2 mm, out at the box's corners
    assert "PASS" in bpy.context.window_manager.jampacked_job.last_message

    from test_addon_register import _draw_all, _labels

    assert "Units: 1 BU = 1 m, exported in mm" in _labels(_draw_all(bpy, addon))


def _result_objects(bpy):
    coll = bpy.context.scene.jampacked.result
    return coll, sorted((o for o in coll.objects if "jampacked_index" in o.keys()),
                        key=lambda o: o["jampacked_index"])


def test_export_writes_the_result_as_the_scene_has_it(bpy, addon, packed, tmp_path):
    # deleted objects were exported anyway, at the packing's places, as "PASS"
    from jampacked.export.validate import validate_file

    coll, objs = _result_objects(bpy)
    n = len(objs)
    assert n >= 4
    for obj in objs[:2]:
        bpy.data.objects.remove(obj)
    s = packed.settings
    s.export_mode = 'UNION'
    s.file_format = '3MF'
    s.filepath = str(tmp_path / "cut")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    report = validate_file(tmp_path / "cut.3mf")
    assert report.passed
    message = bpy.context.window_manager.jampacked_job.last_message
    # what is left of a certified packing is certified: nothing to check again
    assert f"union: {n - 2} objects" in message, message
    assert f"Exported the {n - 2} objects the result holds now" in message, message
    assert "certified again" not in message, message
    # one moved (a little, into no other): the packing is certified again
    objs = _result_objects(bpy)[1]
    objs[0].location.x += 1e-3
    s.filepath = str(tmp_path / "moved")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    message = bpy.context.window_manager.jampacked_job.last_message
    assert f"its {n - 2} placements were certified again before export" in message, message


def test_export_refuses_an_object_moved_onto_another_by_its_name(bpy, addon, packed,
                                                                 tmp_path):
    coll, objs = _result_objects(bpy)
    objs[0].location = objs[1].location.copy()
    objs[0].rotation_quaternion = objs[1].rotation_quaternion.copy()
    packed.settings.filepath = str(tmp_path / "x.stl")
    with pytest.raises(RuntimeError, match=r"certified again its placements fail: .*"
                       r"overlap") as err:
        bpy.ops.jampacked.export()
    assert f"'{objs[0].name}'" in str(err.value) and f"'{objs[1].name}'" in str(err.value)
    assert not (tmp_path / "x.stl").exists()


def test_export_refuses_an_unevenly_scaled_object(bpy, addon, packed, tmp_path):
    coll, objs = _result_objects(bpy)
    objs[0].scale = (1.0, 1.0, 1.3)
    packed.settings.filepath = str(tmp_path / "x.stl")
    with pytest.raises(RuntimeError, match=rf"'{objs[0].name}' is scaled unevenly"):
        bpy.ops.jampacked.export()


@pytest.mark.parametrize("older", [False, True])
def test_export_of_an_unchanged_result_certifies_nothing_again(bpy, addon, packed,
                                                               tmp_path, older):
    # a result made before placed objects recorded their index (older): every object read
    # as moved, certified again from 32-bit matrices, "changed after it was certified"
    if older:
        for obj in _result_objects(bpy)[1]:
            del obj["jampacked_index"]
    s = packed.settings
    s.file_format = '3MF'
    s.filepath = str(tmp_path / "same")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    message = bpy.context.window_manager.jampacked_job.last_message
    assert "certified again" not in message and "left out" not in message, message
    assert "holds now" not in message, message


@pytest.mark.parametrize("older", [False, True])
def test_export_refuses_an_edited_type_mesh(bpy, addon, packed, tmp_path, older):
    # a type's shared mesh scaled by 1.4 in Edit Mode: the union was written (427 pairs
    # overlapping) and read "validation PASS"; a result made before the meshes'
    # signatures were recorded (older) is checked by the volume
    coll, objs = _result_objects(bpy)
    if older:
        del coll["jampacked_type_sha256"]
    mesh = objs[0].data
    mesh.transform(__import__("mathutils").Matrix.Scale(1.4, 4))
    mesh.update()
    packed.settings.filepath = str(tmp_path / "x.stl")
    with pytest.raises(RuntimeError, match=rf"(?i)the mesh '{mesh.name}' of type .* was edited "
                       r"after packing"):
        bpy.ops.jampacked.export()


def test_a_renamed_container_exports_and_packs_again_in_place(bpy, addon, packed,
                                                              tmp_path):
    # Export read "the container 'Box' ... is gone", and a second Pack left both results
    packed.box.name = "Crate"
    s = packed.settings
    s.file_format = '3MF'
    s.filepath = str(tmp_path / "renamed")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    assert (tmp_path / "renamed.3mf").is_file()
    s.seed = 2
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    results = [c for c in bpy.data.collections if "jampacked_packing" in c.keys()]
    assert [c.name for c in results] == ["Jampacked Crate"]


def test_an_object_moved_out_is_named_by_its_blender_name(bpy, addon, packed, tmp_path):
    # it read "places object 12 (P4) outside the container", an index of the re-sorted list
    coll, objs = _result_objects(bpy)
    handle = bpy.data.objects.new("Handle", None)
    bpy.context.scene.collection.objects.link(handle)
    objs[0].parent = handle
    handle.location = (0.0, 0.0, 500.0)
    packed.settings.filepath = str(tmp_path / "x.stl")
    with pytest.raises(RuntimeError, match=rf"places '{objs[0].name}' outside the container"):
        bpy.ops.jampacked.export()
    # what to do, in Blender's words (it read "re-run the packing, or fix these placements")
    message = bpy.context.window_manager.jampacked_job.last_message
    assert message.endswith("within the container: move these objects back inside, or pack "
                            "again."), \
        message


def test_export_names_a_container_disabled_in_viewports(bpy, addon, scene, tmp_path):
    """A container with a modifier, turned off in viewports (the monitor icon) to see the
    result: Blender no longer evaluates its modifier, so Export read its bare mesh and said
    it "was moved or edited after packing". It now says what happened and what to do; hidden
    with H it exports."""
    scene.box.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    scene.settings.filepath = str(tmp_path / "x.stl")
    scene.box.hide_viewport = True
    with pytest.raises(RuntimeError, match="container 'Box' is disabled in viewports.*"
                       "hide it with H instead, which Export can read"):
        bpy.ops.jampacked.export()
    assert not (tmp_path / "x.stl").exists()
    scene.box.hide_viewport = False
    scene.box.hide_set(True)
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    assert (tmp_path / "x.stl").is_file()
