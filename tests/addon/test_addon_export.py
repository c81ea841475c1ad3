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
    assert run.reports[-1][0] == 'INFO', run.reports
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
