"""Export from the panel: the file written passes `jampacked validate`."""

from __future__ import annotations

import pytest

pytest.importorskip("bpy")

from addon_helpers import drive, runner, scene_state  # noqa: E402


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


def test_a_scene_in_metres_exports_in_millimetres(bpy, addon, scene, tmp_path):
    """Blender's default units (1 BU = 1 m): a 12 cm box modelled as 0.12 BU, filled and
    exported with a 2 mm shell (typed as 0.002 m), prints 120 mm wide; the panel says so."""
    import numpy as np
    import trimesh

    units = bpy.context.scene.unit_settings
    assert (units.system, units.scale_length) == ('METRIC', 1.0)
    k = 0.004  # the fixture's turned box spans 30 units: 0.12 m across
    scene.box.scale = tuple(k * np.array(scene.box.scale))
    scene.box.location = tuple(k * np.array(scene.box.location))
    for obj in scene.types:
        obj.scale = tuple(k * np.array(obj.scale))
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    box = addon.bridge.object_triangles(scene.box, depsgraph).vertices
    assert np.ptp(box, axis=0).max() == pytest.approx(0.12, abs=0.005)
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    assert scene.settings.result["jampacked_count"] > 5
    s = scene.settings
    s.export_mode, s.shell, s.file_format = 'UNION', 0.002, '3MF'
    s.filepath = str(tmp_path / "cow.3mf")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    printed = trimesh.load(tmp_path / "cow.3mf", force="mesh")
    np.testing.assert_allclose(printed.bounds, 1000.0 * np.array([box.min(0), box.max(0)]),
                               atol=4.0)  # mm: the shell's 2 mm, out at the box's corners
    assert "PASS" in bpy.context.window_manager.jampacked_job.last_message

    from test_addon_register import _draw_all, _labels

    assert "Units: 1 BU = 1 m, exported in mm" in _labels(_draw_all(bpy, addon))
