"""Pack from Blender: the result matches the packing, cancel/errors change nothing, undo."""

from __future__ import annotations

import json
import re
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("bpy")

from addon_helpers import (  # noqa: E402
    BIG_BOX,
    CUBE_FACES,
    LONG_BUDGET,
    Event,
    Layout,
    cube_object,
    drive,
    runner,
    scene_state,
)


def _matrix(obj) -> np.ndarray:
    return np.array([list(r) for r in obj.matrix_world], dtype=np.float64)


def _packing(addon, coll):
    return addon.engine.packing_from_json(coll["jampacked_packing"])


def test_pack_operator_builds_the_packing(bpy, addon, scene):
    before = scene_state(bpy)
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    coll = scene.settings.result
    assert coll is not None and coll.name == "Jampacked Box"
    assert coll.name in bpy.context.scene.collection.children
    packing = _packing(addon, coll)
    assert packing.n > 5
    assert packing.certificate["certified"] is True
    assert coll["jampacked_certified"] is True or coll["jampacked_certified"] == 1
    # container frame = world space
    np.testing.assert_array_equal(packing.frame_from_file, np.eye(4))
    assert json.loads(coll["jampacked_packing"])["container"]["path"] == "blender:Box"

    objects = sorted(coll.objects, key=lambda o: int(o.name.rsplit(" ", 1)[1]))
    assert len(objects) == packing.n
    mats = packing.matrices()
    for i, obj in enumerate(objects):
        assert obj["jampacked_type"] == packing.type_index[i]
        np.testing.assert_allclose(_matrix(obj), mats[i], atol=1e-5)

    # one shared mesh (and material) per type; nothing else new in the scene
    for t, rec in enumerate(packing.types):
        meshes = {o.data.name for o, k in zip(objects, packing.type_index, strict=True)
                  if k == t}
        assert meshes == {f"Jampacked {rec.name}"}
        assert bpy.data.meshes[f"Jampacked {rec.name}"].materials[0].name == \
            f"Jampacked {rec.name}"
    new_meshes = set(m.name for m in bpy.data.meshes) - set(before["meshes"])
    assert new_meshes == {f"Jampacked {rec.name}" for rec in packing.types}
    assert set(o.name for o in bpy.data.objects) - set(before["objects"]) == \
        {o.name for o in objects}

    # placed geometry = packing matrix @ local_from_file @ (type object's world vertices)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for t, source in enumerate(scene.types):
        src = addon.bridge.object_triangles(source, depsgraph)
        i = int(np.flatnonzero(packing.type_index == t)[0])
        obj = objects[i]
        placed = addon.bridge.object_triangles(obj, depsgraph)
        expected = src.vertices @ (mats[i] @ packing.types[t].local_from_file)[:3, :3].T \
            + (mats[i] @ packing.types[t].local_from_file)[:3, 3]
        np.testing.assert_allclose(placed.vertices, expected, atol=1e-4)

    # metrics as custom properties, as the panel shows them
    assert coll["jampacked_count"] == packing.n
    assert list(coll["jampacked_count_per_type"]) == packing.metrics["count_per_type"]
    assert coll["jampacked_density"] == pytest.approx(packing.metrics["density"])
    assert coll["jampacked_tvd"] == pytest.approx(packing.metrics["tvd"])
    assert list(coll["jampacked_type_names"]) == ["P5", "P4"]
    rows = dict(addon.summary.panel_lines(coll))
    assert rows["Objects"] == str(packing.n) and rows["Certified"] == "yes"
    assert "Packed" in bpy.context.window_manager.jampacked_job.last_message
    assert not addon.worker.busy()


def test_mix_tolerance_reaches_the_engine(bpy, addon, scene):
    """The panel's Mix Tolerance starts at the engine's default and is what the late cavity
    passes get (the packing records it)."""
    from jampacked.core.options import CavityPassOptions

    assert scene.settings.mix_tolerance == pytest.approx(CavityPassOptions().max_tvd)
    scene.settings.mix_tolerance = 0.0
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    assert _packing(addon, scene.settings.result).inputs.options.cavity.max_tvd == 0.0


def test_the_runs_warnings_reach_the_user(bpy, addon, scene):
    """A type that fits nowhere is left out with a warning: Blender shows it in the status,
    the Info log and the Result panel, and keeps it on the result (it used to say only
    "Packed ... certified")."""
    rod = cube_object(bpy, "Rod", location=(0.0, 60.0, 0.0), scale=(30.0, 0.6, 0.6))
    item = scene.settings.types.add()
    item.object, item.share = rod, 1.0
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    coll = scene.settings.result
    (warning,) = addon.summary.warnings(coll)
    assert warning.startswith("Type Rod (share 25%) was left out: it is 60")
    # in the words of the scene and the panel, not of the command line
    assert "the type objects' scale" in warning and "--" not in warning
    state = bpy.context.window_manager.jampacked_job
    assert state.last_level == 'WARNING'
    assert "certified" in state.last_message and "1 warning(s)" in state.last_message
    calls: list = []
    addon.ui.JAMPACKED_PT_result.draw(SimpleNamespace(layout=Layout(calls)), bpy.context)
    shown = " ".join(kw.get("text", "") for name, _a, kw in calls if name == "label")
    assert "Type Rod (share 25%) was left out" in shown


def test_modal_path_and_second_pack_blocked(bpy, addon, scene):
    scene.settings.time_budget = LONG_BUDGET  # still running while a second Pack is tried
    run = runner(addon)
    assert run.begin(bpy.context)
    try:
        assert addon.worker.busy()
        assert not bpy.ops.jampacked.pack.poll()
        second = runner(addon)
        assert not second.begin(bpy.context)
        assert "still running" in second.reports[-1][1]
        assert bpy.context.window_manager.jampacked_job.running
        # other events pass through to Blender while the job runs
        assert run.modal(bpy.context, Event('MOUSEMOVE')) == {'PASS_THROUGH'}
        assert drive(run, bpy.context) == {'FINISHED'}
    finally:
        if run._job is not None:
            run._job.cancel()
    coll = scene.settings.result
    assert coll is not None and len(coll.objects) == coll["jampacked_count"] > 0
    assert not bpy.context.window_manager.jampacked_job.running
    assert not addon.worker.busy()


@pytest.mark.serial
def test_blender_stays_responsive_while_packing(bpy, addon, scene):
    """The main thread (Blender's UI) gets its turns while the engine runs in the thread."""
    scene.box.scale = BIG_BOX
    scene.settings.time_budget = LONG_BUDGET
    run = runner(addon)
    assert run.begin(bpy.context)
    gaps = []
    last = time.perf_counter()
    try:
        while time.perf_counter() - last < 60 and len(gaps) < 60:
            assert run.modal(bpy.context, Event('TIMER')) == {'RUNNING_MODAL'}
            time.sleep(0.02)
            now = time.perf_counter()
            gaps.append(now - last)
            last = now
        fraction = bpy.context.window_manager.jampacked_job.fraction
    finally:
        assert drive(run, bpy.context, events=[Event('ESC', 'PRESS')]) == {'CANCELLED'}
    assert max(gaps) < 1.0, f"the main thread waited {max(gaps):.2f} s for the engine"
    assert 0.0 < fraction < 1.0


def test_escape_cancels_and_changes_nothing(bpy, addon, scene):
    scene.box.scale = BIG_BOX
    scene.settings.time_budget = LONG_BUDGET
    before = scene_state(bpy)
    run = runner(addon)
    assert run.begin(bpy.context)
    assert run.modal(bpy.context, Event('TIMER')) == {'RUNNING_MODAL'}
    assert drive(run, bpy.context, events=[Event('ESC', 'PRESS')]) == {'CANCELLED'}
    assert run.reports[-1][0] == 'WARNING' and "cancelled" in run.reports[-1][1]
    assert scene_state(bpy) == before
    assert not addon.worker.busy()


def test_cancel_button_and_finish_now(bpy, addon, scene):
    scene.box.scale = BIG_BOX
    scene.settings.time_budget = LONG_BUDGET
    before = scene_state(bpy)
    run = runner(addon)
    assert run.begin(bpy.context)
    assert bpy.ops.jampacked.cancel(action='CANCEL') == {'FINISHED'}
    assert drive(run, bpy.context) == {'CANCELLED'}
    assert scene_state(bpy) == before

    # Finish Now keeps the best certified packing so far (once an object is placed: before
    # that there is nothing to keep, and the previous result stays)
    run = runner(addon)
    assert run.begin(bpy.context)
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline:
        run.modal(bpy.context, Event('TIMER'))
        grown = re.search(r"(\d+) placed", addon.worker.active_job().snapshot().message)
        if grown and int(grown.group(1)) > 0:  # full size (the live view shows seeds too)
            break
        time.sleep(0.05)
    assert bpy.ops.jampacked.cancel(action='FINISH') == {'FINISHED'}
    assert drive(run, bpy.context) == {'FINISHED'}
    coll = scene.settings.result
    packing = _packing(addon, coll)
    assert packing.certificate["certified"] is True
    assert packing.report.stopped == "cancelled"
    assert len(coll.objects) == packing.n



def test_finish_now_before_any_object_is_placed_keeps_the_previous_result(bpy, addon, scene,
                                                                          monkeypatch):
    """An engine stopped before its first object returns an empty packing: it replaced the
    previous result with an empty collection."""
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    previous = scene.settings.result
    real = addon.engine.pack_triangles

    def stopped_at_once(*args, should_cancel, **kwargs):
        return real(*args, should_cancel=lambda: True, **kwargs)

    monkeypatch.setattr(addon.engine, "pack_triangles", stopped_at_once)
    before = scene_state(bpy)
    run = runner(addon)
    assert run.begin(bpy.context)
    assert drive(run, bpy.context) == {'CANCELLED'}
    assert scene_state(bpy) == before and scene.settings.result == previous
    assert run.reports[-1] == ('WARNING', "Packing finished before any object was placed, so "
                                          "there was nothing to keep: nothing was changed.")


def test_finish_now_before_anything_is_kept_says_so(bpy, addon, scene, monkeypatch):
    """Finish Now while the engine still has nothing to keep (it was still starting) read
    "Packing cancelled", which the artist had not asked for."""
    from jampacked.core.errors import Cancelled

    def starting(progress, should_cancel):
        while not should_cancel():
            time.sleep(0.01)
        raise Cancelled("stopped before anything was placed")

    run = runner(addon)
    monkeypatch.setattr(run, "make_job", lambda context: addon.worker.Job("Packing", starting))
    before = scene_state(bpy)
    assert run.begin(bpy.context)
    assert bpy.ops.jampacked.cancel(action='FINISH') == {'FINISHED'}
    assert drive(run, bpy.context) == {'CANCELLED'}
    assert scene_state(bpy) == before
    assert run.reports[-1] == ('WARNING', "Packing finished before anything was done, so "
                                          "there was nothing to keep: nothing was changed.")


def test_cancel_in_blocking_mode(bpy, addon, scene):
    """bpy.ops in background mode runs the same steps in a loop; the cancel flag stops it."""
    scene.box.scale = BIG_BOX
    scene.settings.time_budget = LONG_BUDGET
    before = scene_state(bpy)
    timer = threading.Timer(1.0, lambda: addon.worker.active_job().cancel())
    timer.start()
    try:
        assert bpy.ops.jampacked.pack() == {'CANCELLED'}
    finally:
        timer.cancel()
    assert scene_state(bpy) == before


def test_non_mesh_and_missing_container_are_clear_errors(bpy, addon, scene):
    empty = bpy.data.objects.new("Empty Box", None)
    bpy.context.scene.collection.objects.link(empty)
    scene.settings.container = empty  # a script can bypass the picker's mesh-only poll
    before = scene_state(bpy)
    with pytest.raises(RuntimeError,
                       match=r"'Empty Box' is not a mesh object \(its type is Empty\)"):
        bpy.ops.jampacked.pack()
    assert scene_state(bpy) == before
    scene.settings.container = None
    with pytest.raises(RuntimeError, match="Pick a container: a closed mesh object"):
        bpy.ops.jampacked.pack()
    assert scene_state(bpy) == before
    assert not addon.worker.busy()


def test_open_container_is_a_clear_error(bpy, addon, scene):
    holed = cube_object(bpy, "Holed Box", faces=CUBE_FACES[:-1],
                        scale=(15.0, 15.0, 15.0))
    scene.settings.container = holed
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match="Holed Box.*not closed"):
        bpy.ops.jampacked.pack()
    assert scene_state(bpy) == before
    state = bpy.context.window_manager.jampacked_job
    assert state.last_level == 'ERROR' and "Holed Box" in state.last_message
    assert not addon.worker.busy()


def test_a_container_disabled_while_packing_is_named_as_such(bpy, addon, scene):
    """Turned off in viewports during a Pack, a container with a modifier reads as its bare
    mesh: the end check called it moved or edited."""
    scene.box.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    run = runner(addon)
    assert run.begin(bpy.context)
    scene.box.hide_viewport = True
    before = scene_state(bpy)
    assert drive(run, bpy.context) == {'CANCELLED'}
    assert "'Box' was disabled in viewports while packing" in run.reports[-1][1]
    assert "enable it and pack again" in run.reports[-1][1]
    assert scene_state(bpy) == before


def test_input_moved_while_packing_changes_nothing(bpy, addon, scene):
    run = runner(addon)
    assert run.begin(bpy.context)
    scene.box.location.x += 1.0
    before = scene_state(bpy)
    assert drive(run, bpy.context) == {'CANCELLED'}
    assert "moved or edited while packing" in run.reports[-1][1]
    assert scene_state(bpy) == before


def test_one_undo_step_removes_the_result(bpy, addon, scene):
    bpy.ops.ed.undo_push(message="before pack")  # background mode: start the undo system
    before = scene_state(bpy)
    assert bpy.ops.jampacked.pack('EXEC_DEFAULT', True) == {'FINISHED'}
    assert bpy.context.scene.jampacked.result is not None
    assert scene_state(bpy) != before
    bpy.ops.ed.undo()
    assert scene_state(bpy) == before
    assert bpy.context.scene.jampacked.result is None


def _interrupt(*_args, **_kwargs):
    raise KeyboardInterrupt


def test_ctrl_c_in_a_blocking_pack_frees_the_job(bpy, addon, scene, monkeypatch):
    """Ctrl-C lands in the main thread while a blocking Pack waits for its thread: the job
    is cancelled, the slot freed and the scene unchanged, so the next Pack runs."""
    scene.box.scale = BIG_BOX
    scene.settings.time_budget = LONG_BUDGET
    before = scene_state(bpy)
    monkeypatch.setattr(addon.worker.Job, "wait", _interrupt)
    with pytest.raises((KeyboardInterrupt, RuntimeError)):
        bpy.ops.jampacked.pack()
    monkeypatch.undo()
    assert not addon.worker.busy()
    assert not bpy.context.window_manager.jampacked_job.running
    assert scene_state(bpy) == before
    scene.box.scale = (10.0, 9.5, 11.0)
    assert bpy.ops.jampacked.pack.poll()
    assert bpy.ops.jampacked.pack() == {'FINISHED'}


def test_interrupt_in_the_engine_frees_the_job(bpy, addon, scene, monkeypatch):
    """A KeyboardInterrupt (any BaseException) raised by the engine call ends the job as
    failed instead of leaving it running for ever; the next Pack runs."""
    before = scene_state(bpy)
    monkeypatch.setattr(addon.engine, "pack_triangles", _interrupt)
    run = runner(addon)
    assert run.begin(bpy.context)
    assert drive(run, bpy.context, timeout=30.0) == {'CANCELLED'}
    assert "KeyboardInterrupt" in run.reports[-1][1]
    assert not addon.worker.busy()
    with pytest.raises(RuntimeError, match="KeyboardInterrupt"):
        bpy.ops.jampacked.pack()  # the blocking path ends too
    monkeypatch.undo()
    assert scene_state(bpy) == before
    assert bpy.ops.jampacked.pack() == {'FINISHED'}


def _results(bpy) -> list:
    return sorted((c for c in bpy.context.scene.collection.children_recursive
                   if "jampacked_packing" in c.keys()), key=lambda c: c.name)


def test_a_second_pack_replaces_the_first(bpy, addon, scene):
    """Trying another seed replaces the container's result (names reused, nothing left
    behind), in one undo step that brings the first result back."""
    inputs = {o.name for o in bpy.data.objects}
    bpy.ops.ed.undo_push(message="before pack")
    assert bpy.ops.jampacked.pack('EXEC_DEFAULT', True) == {'FINISHED'}
    first = scene_state(bpy)
    bpy.context.scene.jampacked.seed = 2
    assert bpy.ops.jampacked.pack('EXEC_DEFAULT', True) == {'FINISHED'}
    (coll,) = _results(bpy)
    assert coll.name == "Jampacked Box" and bpy.context.scene.jampacked.result == coll
    packing = _packing(addon, coll)
    assert packing.seed == 2 and len(coll.objects) == packing.n
    assert {o.name for o in bpy.data.objects} == inputs | {o.name for o in coll.objects}
    jam_meshes = {m.name for m in bpy.data.meshes if m.name.startswith("Jampacked")}
    assert jam_meshes == {"Jampacked P5", "Jampacked P4"}
    assert list(coll["jampacked_type_meshes"]) == ["Jampacked P5", "Jampacked P4"]
    assert {m.name for m in bpy.data.materials} == jam_meshes
    assert {o.data.name for o in coll.objects} == jam_meshes
    assert first != scene_state(bpy)
    bpy.ops.ed.undo()
    assert scene_state(bpy) == first
    assert _packing(addon, bpy.context.scene.jampacked.result).seed == 1


def test_a_second_pack_keeps_what_the_artist_put_in_the_result(bpy, addon, scene):
    # a light, a mesh and a child collection put in "Jampacked Box" left the scene (no
    # collection held them any more) when a second Pack replaced it
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    coll = scene.settings.result
    light = bpy.data.objects.new("Key", bpy.data.lights.new("Key", 'POINT'))
    plate = cube_object(bpy, "Label plate", location=(0.0, 80.0, 0.0))
    for obj in (light, plate):
        for c in list(obj.users_collection):
            c.objects.unlink(obj)
        coll.objects.link(obj)
    child = bpy.data.collections.new("Highlights")
    coll.children.link(child)
    # a Shift+D copy of a placed object: its custom properties, a mesh of its own
    placed = next(o for o in coll.objects if "jampacked_index" in o.keys())
    copy = placed.copy()
    copy.data = placed.data.copy()
    copy.name = "My copy"
    coll.objects.link(copy)
    scene.settings.seed = 2
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    (new,) = _results(bpy)
    assert new.name == "Jampacked Box" and _packing(addon, new).seed == 2
    assert {"Key", "Label plate", "My copy"} <= {o.name for o in new.objects}
    assert "Highlights" in new.children
    scene_objects = {o.name for o in bpy.context.scene.objects}
    assert {"Key", "Label plate"} <= scene_objects
    # the new result's objects take the names the old ones had ("P4 1", not "P4 1.001")
    assert not any(o.name.endswith(".001") for o in new.objects)
    message = bpy.context.window_manager.jampacked_job.last_message
    assert "Kept 4 object(s) or collection(s)" in message, message


def test_a_second_pack_takes_the_first_ones_place(bpy, addon, scene):
    """The artist renamed the result, moved it under a collection of their own and set it
    up per view layer: the next Pack's result took the default name at the scene's root,
    with default settings, and left the collection empty."""
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    coll = scene.settings.result
    renders = bpy.data.collections.new("Renders")
    bpy.context.scene.collection.children.link(renders)
    renders.children.link(coll)
    bpy.context.scene.collection.children.unlink(coll)
    coll.name = "My Packing"
    coll.hide_render = True
    coll.color_tag = 'COLOR_04'
    layer = bpy.context.view_layer.layer_collection.children["Renders"].children[coll.name]
    layer.holdout = True
    layer.indirect_only = True
    scene.settings.seed = 2
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    (new,) = _results(bpy)
    assert new.name == "My Packing" and _packing(addon, new).seed == 2
    assert list(renders.children) == [new]
    assert new.name not in bpy.context.scene.collection.children
    assert new.hide_render and new.color_tag == 'COLOR_04'
    layer = bpy.context.view_layer.layer_collection.children["Renders"].children[new.name]
    assert layer.holdout and layer.indirect_only and not layer.exclude


def test_a_result_linked_into_another_scene_stays_there(bpy, addon, scene):
    """The artist linked the result into a second scene (and a collection of it) and set it
    up there: the next Pack's result was linked in this scene only, and the other scene
    lost it (then got it back without its view layer's settings)."""
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    coll = scene.settings.result
    other = bpy.data.scenes.new("Scene2")
    shelf = bpy.data.collections.new("Shelf")
    other.collection.children.link(shelf)
    other.collection.children.link(coll)
    shelf.children.link(coll)
    layers = other.view_layers[0].layer_collection
    layers.children[coll.name].exclude = True  # and set up there: excluded at its root
    layers.children["Shelf"].children[coll.name].holdout = True
    try:
        scene.settings.seed = 2
        assert bpy.ops.jampacked.pack() == {'FINISHED'}
        (new,) = set(_results(bpy))
        assert _packing(addon, new).seed == 2
        assert list(other.collection.children) == [shelf, new]
        assert list(shelf.children) == [new]
        assert new.name in bpy.context.scene.collection.children
        layers = other.view_layers[0].layer_collection
        assert layers.children[new.name].exclude
        assert layers.children["Shelf"].children[new.name].holdout
        assert not bpy.context.view_layer.layer_collection.children[new.name].exclude
    finally:
        bpy.data.scenes.remove(other)


def test_a_result_linked_in_two_places_is_replaced_in_both(bpy, addon, scene):
    """A result linked at the root and under "Renders", and "Renders" itself linked at the
    root and under "Q": the collection listed twice was removed twice (ReferenceError), and
    a parent listed twice was linked twice, after the old result was gone."""
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    coll = scene.settings.result
    renders, q = bpy.data.collections.new("Renders"), bpy.data.collections.new("Q")
    root = bpy.context.scene.collection
    root.children.link(renders)
    root.children.link(q)
    q.children.link(renders)
    renders.children.link(coll)  # and it stays at the root
    layers = bpy.context.view_layer.layer_collection
    layers.children[coll.name].exclude = True
    layers.children["Renders"].children[coll.name].holdout = True
    layers.children["Q"].children["Renders"].children[coll.name].indirect_only = True
    scene.settings.seed = 2
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    (new,) = set(_results(bpy))
    assert _packing(addon, new).seed == 2
    assert new.name in root.children and new.name in renders.children
    layers = bpy.context.view_layer.layer_collection
    at_root, in_renders = layers.children[new.name], layers.children["Renders"].children[
        new.name]
    in_q = layers.children["Q"].children["Renders"].children[new.name]
    assert at_root.exclude and not at_root.holdout
    assert in_renders.holdout and not in_renders.indirect_only
    assert in_q.indirect_only and not in_q.holdout


def test_a_result_moved_into_one_it_replaces_goes_to_the_root(bpy, addon, scene):
    """The last result moved under a collection the artist made inside an earlier result
    that this Pack removes too: its place moves into the new result (a cycle)."""
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    earlier = scene.settings.result
    scene.settings.keep_previous = True
    scene.settings.seed = 2
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    last = scene.settings.result
    group = bpy.data.collections.new("X")
    earlier.children.link(group)
    group.children.link(last)
    bpy.context.scene.collection.children.unlink(last)
    scene.settings.keep_previous = False
    scene.settings.seed = 3
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    (new,) = set(_results(bpy))
    assert _packing(addon, new).seed == 3
    assert new.name in bpy.context.scene.collection.children
    assert "X" in new.children  # what the artist put in a removed result is kept


def test_keep_previous_keeps_both(bpy, addon, scene):
    scene.settings.keep_previous = True
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    scene.settings.seed = 2
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    names = [c.name for c in _results(bpy)]
    assert names == ["Jampacked Box", "Jampacked Box.001"]
    assert scene.settings.result.name == "Jampacked Box.001"


def test_results_kept_side_by_side_stay_when_keep_previous_is_off_again(bpy, addon, scene):
    """Two results kept with Keep Previous, then a Pack without it: it replaces the last
    result, as its tooltip says; it removed both kept ones."""
    scene.settings.keep_previous = True
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    scene.settings.seed = 2
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    scene.settings.keep_previous = False
    scene.settings.seed = 3
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    seeds = sorted(_packing(addon, c).seed for c in _results(bpy))
    assert seeds == [1, 3]
    assert _packing(addon, scene.settings.result).seed == 3


def test_background_pack_prints_throttled_progress(bpy, addon, scene, capsys):
    """Blender in background mode (as here) has no panel: a blocking Pack prints progress
    lines to stdout, the fraction rising, at most one per 5% or 2 s."""
    assert bpy.app.background
    scene.box.scale = BIG_BOX
    scene.settings.time_budget = 4.0
    t0 = time.monotonic()
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    seconds = time.monotonic() - t0
    lines = [ln for ln in capsys.readouterr().out.splitlines()
             if ln.startswith("Jampacked packing:")]
    assert len(lines) >= 3, lines
    percents = [int(ln.split(":", 1)[1].split("%")[0]) for ln in lines]
    assert percents == sorted(percents) and percents[-1] > percents[0]
    assert len(lines) <= 21 + seconds / 2.0 + 1


# ------------------------------------------------------------ first run and live view


@pytest.fixture(autouse=True)
def _engine_warmed_up(addon):
    """The warm-up the add-on started when it was registered has ended (a Finish Now while
    a job still waits for it ends the job with nothing kept)."""
    addon.worker.wait_for_warm_up()


def test_enabling_the_addon_compiles_the_engine_in_the_background(addon):
    """register() started the warm-up thread (no bpy in it); it ended with the kernels
    ready, and enabling again does not start another."""
    snap = addon.worker.warm_up_snapshot()
    assert snap is not None and snap.state == addon.worker.DONE, snap
    assert snap.fraction == 1.0 and snap.message == "engine ready"
    from jampacked.core.numba_cache import cache_is_cold

    assert cache_is_cold() is False
    assert addon.worker.start_warm_up() is addon.worker.start_warm_up()


class _Layout:
    """Records what a panel's draw puts in a layout."""

    def __init__(self) -> None:
        self.items: list[tuple[str, dict]] = []

    def box(self):
        return self

    def progress(self, **kw) -> None:
        self.items.append(("progress", kw))

    def label(self, **kw) -> None:
        self.items.append(("label", kw))


def test_the_first_pack_shows_the_compile_step_before_its_budget(bpy, addon, scene,
                                                                 monkeypatch):
    """While the engine still compiles, the panel shows it with its progress, and a Pack
    started meanwhile shows the compile step as its own progress, waits, then packs."""
    release = threading.Event()
    message = "compiling the engine (first run only, about half a minute)"

    def slow_compile(progress):
        progress(0.4, message)
        assert release.wait(60)

    scene.settings.time_budget = 3.0  # a budget, whose clock must wait for the compile
    monkeypatch.setattr(addon.worker, "_warm_up", addon.worker.WarmUp(slow_compile).start())
    layout = _Layout()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and addon.worker.warm_up_snapshot().fraction < 0.4:
        time.sleep(0.01)
    addon.ui._draw_warm_up(layout)
    (kind, bar), (_, label) = layout.items
    assert kind == "progress" and bar["factor"] == pytest.approx(0.4)
    assert bar["text"].startswith("Preparing the engine (first run only)")
    assert label["text"].startswith(message)

    run = runner(addon)
    assert run.begin(bpy.context)
    try:
        for _ in range(40):
            assert run.modal(bpy.context, Event('TIMER')) == {'RUNNING_MODAL'}
            time.sleep(0.05)
        state = bpy.context.window_manager.jampacked_job
        assert state.message == f"Preparing the engine (first run only): {message}"
        assert state.fraction == 0.0  # the budget has not started
    finally:
        release.set()
    assert drive(run, bpy.context) == {'FINISHED'}
    assert scene.settings.result is not None
    layout = _Layout()
    addon.ui._draw_warm_up(layout)
    assert layout.items == []  # over: the panel shows nothing more


def test_the_live_view_follows_the_pack_and_goes_on_every_exit(bpy, addon, scene):
    """A pack adds the viewport draw handler, the worker's snapshots (the objects placed so
    far) reach the main thread while it runs, and the handler is removed when it ends:
    finished, cancelled (Esc) or failed."""
    view = addon.live_view.VIEW
    scene.box.scale = BIG_BOX
    scene.settings.time_budget = 3.0
    run = runner(addon)
    assert run.begin(bpy.context)
    handle = view.handle
    assert handle is not None
    seen = []  # (objects, their summed radius) of each snapshot the view held
    deadline = time.monotonic() + 120
    result = {'RUNNING_MODAL'}
    while result == {'RUNNING_MODAL'} and time.monotonic() < deadline:
        result = run.modal(bpy.context, Event('TIMER'))
        if view.placed is not None:
            count = len(view.placed.types)
            seen.append((count, float(view.placed.radii.sum())))
            lines = view.lines_by_type()
            assert sum(len(v) for v in lines.values()) == \
                count * 3 * addon.live_view.SEGMENTS * 2
        time.sleep(0.05)
    assert result == {'FINISHED'}
    # it changed while we watched: objects added or removed, or the placed ones grown (in
    # phase 1 the lattice's objects are all there from the start and only grow, so a
    # budget that ends there shows one count throughout)
    assert len(set(seen)) >= 2 and max(n for n, _ in seen) > 0, seen
    assert view.handle is None and view.placed is None
    with pytest.raises(ValueError):  # Blender no longer has it
        bpy.types.SpaceView3D.draw_handler_remove(handle, 'WINDOW')

    run = runner(addon)
    assert run.begin(bpy.context)
    assert view.handle is not None
    assert drive(run, bpy.context, events=[Event('ESC', 'PRESS')]) == {'CANCELLED'}
    assert view.handle is None

    run = runner(addon)
    assert run.begin(bpy.context)
    with pytest.raises(KeyboardInterrupt), run.guard(bpy.context):
        raise KeyboardInterrupt
    assert view.handle is None and not addon.worker.busy()


def test_circles_of_the_live_view_lie_on_the_spheres(addon):
    centres = np.array([[1.0, 2.0, 3.0], [-4.0, 0.0, 0.5]])
    radii = np.array([0.5, 2.0])
    pts = addon.live_view.circle_lines(centres, radii, segments=8).reshape(2, -1, 3)
    assert pts.shape == (2, 3 * 8 * 2, 3)
    for c, r, p in zip(centres, radii, pts, strict=True):
        np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), r, rtol=1e-5)


def test_a_long_certification_runs_on_worker_processes_from_blender(bpy, addon, scene,
                                                                     monkeypatch):
    """A long certification spawns worker processes from the add-on's engine thread
    (`core/check_pool.py`): they must start inside Blender, give a certified packing and
    be gone afterwards."""
    import multiprocessing

    from jampacked.core import certify, check_pool

    monkeypatch.setattr(certify, "POOL_PROBE_SECONDS", 0.0)
    monkeypatch.setattr(certify, "POOL_MIN_SECONDS", 0.0)
    monkeypatch.setattr(check_pool, "CHUNK_CHECKS", 4)
    monkeypatch.setattr(certify, "usable_processes", lambda requested: 2)  # any machine
    runs = []
    run_here = check_pool.CheckPool.run
    monkeypatch.setattr(check_pool.CheckPool, "run",
                        lambda self, *a, **k: runs.append(self.processes)
                        or run_here(self, *a, **k))
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    packing = _packing(addon, scene.settings.result)
    assert runs and set(runs) == {2} and packing.certificate["certified"] is True
    assert packing.n > 5 and multiprocessing.active_children() == []
