"""Instanced results: points under a Geometry Nodes modifier draw the placements; Make Real.

What headless bpy allows: the evaluated instances are read from the depsgraph (as the
viewport and renderers get them), undo runs with ``ed.undo`` after an explicit first
``undo_push`` (background mode starts no undo system), Edit Mode selections are set on the
points' vertices directly (no viewport to box-select in).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bpy")

from addon_helpers import load_addon, scene_state  # noqa: E402

#: the engine's packing of the scene fixture per seed: these tests are about how a packing is
#: added to the scene, so each seed is packed once (a pack takes 1-20 s on a busy machine)
_OUTCOMES: dict = {}


@pytest.fixture(autouse=True)
def _pack_once(addon, monkeypatch):
    real = addon.engine.pack_triangles

    def pack_once(container, types, shares, *, seed, **kwargs):
        if seed not in _OUTCOMES:
            _OUTCOMES[seed] = real(container, types, shares, seed=seed, **kwargs)
        return _OUTCOMES[seed]

    monkeypatch.setattr(addon.engine, "pack_triangles", pack_once)


def _packing(addon, coll):
    return addon.engine.packing_from_json(coll["jampacked_packing"])


def _pack(bpy, kind: str, undo: bool = False) -> object:
    bpy.context.scene.jampacked.result_kind = kind
    args = ('EXEC_DEFAULT', True) if undo else ()
    assert bpy.ops.jampacked.pack(*args) == {'FINISHED'}
    return bpy.context.scene.jampacked.result


def _instances(bpy, points) -> list[tuple[str, np.ndarray]]:
    """(prototype name, world matrix) of every instance the points object draws."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = []
    for inst in depsgraph.object_instances:
        if inst.is_instance and inst.parent is not None and inst.parent.original == points:
            out.append((inst.instance_object.original.name,
                        np.array([list(r) for r in inst.matrix_world])))
    return out


def _check_instances(bpy, packing, points, indices=None) -> None:
    """The instances are exactly the placements ``indices`` (all by default): type and
    matrix of each, matched by position."""
    indices = np.arange(packing.n) if indices is None else np.asarray(indices)
    got = _instances(bpy, points)
    assert len(got) == len(indices)
    mats = packing.matrices()
    for name, matrix in got:
        d = np.linalg.norm(packing.translations[indices] - matrix[:3, 3], axis=1)
        i = int(indices[np.argmin(d)])
        assert d.min() < 1e-4
        assert name == f"Jampacked {packing.types[packing.type_index[i]].name}"
        np.testing.assert_allclose(matrix, mats[i], atol=1e-5)


def _matrix(obj) -> np.ndarray:
    return np.array([list(r) for r in obj.matrix_world], dtype=np.float64)


def _jam_node_groups(bpy) -> list[str]:
    return sorted(g.name for g in bpy.data.node_groups if g.name.startswith("Jampacked"))


def test_use_instances_follows_the_choice_and_threshold():
    inst = load_addon().instances
    assert inst.use_instances('AUTO', 2000, 2000)
    assert not inst.use_instances('AUTO', 2000, 1999)
    assert inst.use_instances('INSTANCES', 2000, 1)
    assert not inst.use_instances('OBJECTS', 10, 100000)


def test_instanced_result_draws_the_placements(bpy, addon, scene):
    """The depsgraph's instances have the packing's types and matrices [R * s | t]; the
    result holds one points object, the type meshes are the object result's."""
    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    assert packing.n > 5
    assert coll["jampacked_result_kind"] == "instances"
    (points,) = coll.objects
    assert points.name == "Jampacked Box instances" and len(points.data.vertices) == packing.n
    _check_instances(bpy, packing, points)
    # the prototypes use the shared type meshes, in the types' local frames
    protos = addon.instances.prototypes(points)
    assert sorted(p.data.name for p in protos) == ["Jampacked P4", "Jampacked P5"]
    assert all(not p.users_collection for p in protos)
    assert list(coll["jampacked_type_meshes"]) == ["Jampacked P5", "Jampacked P4"]
    rows = dict(addon.summary.panel_lines(coll))
    assert rows["Objects"] == str(packing.n)


def test_instances_and_objects_place_the_same(bpy, addon, scene):
    """The same packing added as objects and as instances: the objects' matrices are the
    instances' matrices."""
    scene.settings.keep_previous = True
    objects = _pack(bpy, 'OBJECTS')
    assert objects["jampacked_result_kind"] == "objects"
    packing = _packing(addon, objects)
    matrices = {o.name: _matrix(o) for o in objects.objects}
    coll = _pack(bpy, 'INSTANCES')
    assert _packing(addon, coll).n == packing.n == len(matrices)
    points = addon.instances.points_object(coll)
    got = sorted(_instances(bpy, points), key=lambda x: tuple(np.round(x[1][:3, 3], 4)))
    want = sorted(matrices.values(), key=lambda m: tuple(np.round(m[:3, 3], 4)))
    for (_, a), b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-5)


def test_auto_instances_from_the_threshold(bpy, addon, scene):
    s = scene.settings
    s.result_kind = 'AUTO'
    n = _packing(addon, _pack(bpy, 'OBJECTS')).n
    s.instance_threshold = n + 1
    coll = _pack(bpy, 'AUTO')
    assert coll["jampacked_result_kind"] == "objects" and len(coll.objects) == n
    s.instance_threshold = n
    coll = _pack(bpy, 'AUTO')
    assert coll["jampacked_result_kind"] == "instances" and len(coll.objects) == 1


def test_a_pack_replaces_an_instanced_result_either_way(bpy, addon, scene):
    """Instances replace objects and objects replace instances: one result, the same names,
    no prototype, node group or points mesh left behind."""
    inputs = {o.name for o in bpy.data.objects}
    input_meshes = {m.name for m in bpy.data.meshes}
    _pack(bpy, 'OBJECTS')
    coll = _pack(bpy, 'INSTANCES')
    assert [c.name for c in bpy.context.scene.collection.children] == ["Jampacked Box"]
    points = addon.instances.points_object(coll)
    assert points.name == "Jampacked Box instances"
    assert {o.name for o in bpy.data.objects} == inputs | {
        points.name, "Jampacked P5", "Jampacked P4"}
    assert _jam_node_groups(bpy) == ["Jampacked Instances Box"]
    scene.settings.seed = 2
    coll = _pack(bpy, 'INSTANCES')  # instances replace instances: names kept
    assert addon.instances.points_object(coll).name == "Jampacked Box instances"
    assert _jam_node_groups(bpy) == ["Jampacked Instances Box"]
    assert {m.name for m in bpy.data.meshes} == input_meshes | {
        "Jampacked P5", "Jampacked P4", "Jampacked Box instances"}
    _check_instances(bpy, _packing(addon, coll), addon.instances.points_object(coll))
    coll = _pack(bpy, 'OBJECTS')
    assert _jam_node_groups(bpy) == []
    assert {o.name for o in bpy.data.objects} == inputs | {o.name for o in coll.objects}
    assert {m.name for m in bpy.data.meshes} == input_meshes | {
        "Jampacked P5", "Jampacked P4"}


def test_instanced_pack_is_one_undo_step(bpy, addon, scene):
    bpy.ops.ed.undo_push(message="before pack")
    before = scene_state(bpy)
    _pack(bpy, 'INSTANCES', undo=True)
    assert _jam_node_groups(bpy)
    bpy.ops.ed.undo()
    assert scene_state(bpy) == before
    assert _jam_node_groups(bpy) == []
    assert bpy.context.scene.jampacked.result is None


def test_make_all_real_gives_the_object_result(bpy, addon, scene):
    """Make Real (all): objects sharing the type meshes at the object result's matrices, no
    instances left, nor the points object (it stayed, empty); one undo step brings the
    instances back."""
    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    bpy.ops.ed.undo_push(message="before make real")
    assert bpy.ops.jampacked.make_real('EXEC_DEFAULT', True, which='ALL') == {'FINISHED'}
    real = [o for o in coll.objects if "jampacked_type" in o.keys()]
    assert len(real) == packing.n
    mats = packing.matrices()
    for obj in real:
        i = int(obj.name.rsplit(" ", 1)[1]) - 1
        t = int(packing.type_index[i])
        assert obj["jampacked_type"] == t
        assert obj.data.name == f"Jampacked {packing.types[t].name}"
        np.testing.assert_allclose(_matrix(obj), mats[i], atol=1e-6)
    assert addon.instances.points_object(coll) is None
    assert sorted(o.name for o in coll.objects) == sorted(o.name for o in real)
    assert coll["jampacked_result_kind"] == "objects" and not _jam_node_groups(bpy)
    assert sorted(o.name for o in bpy.context.selected_objects) == sorted(o.name for o in real)
    bpy.ops.ed.undo()
    coll = bpy.context.scene.jampacked.result
    assert [o.name for o in coll.objects] == ["Jampacked Box instances"]
    _check_instances(bpy, packing, addon.instances.points_object(coll))


def test_make_real_selected_points_and_one_type(bpy, addon, scene):
    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    points = addon.instances.points_object(coll)
    with pytest.raises(RuntimeError, match="No points of 'Jampacked Box instances' are "
                                           "selected"):
        bpy.ops.jampacked.make_real(which='SELECTED')
    # the Edit Mode selection, as Object Mode keeps it: the points of placements 0 and 3
    select = np.zeros(packing.n, bool)
    select[[0, 3]] = True
    points.data.vertices.foreach_set("select", select)
    assert bpy.ops.jampacked.make_real(which='SELECTED') == {'FINISHED'}
    # the panel shows it (it kept the Pack's message)
    job = bpy.context.window_manager.jampacked_job
    assert job.last_message.startswith("Made 2 object(s) real") and job.last_level == 'INFO'
    real = sorted(o.name for o in coll.objects if "jampacked_type" in o.keys())
    assert real == sorted(f"{packing.types[packing.type_index[i]].name} {i + 1}"
                          for i in (0, 3))
    left = np.setdiff1d(np.arange(packing.n), [0, 3])
    _check_instances(bpy, packing, points, left)
    # then every remaining instance of the second type (P4)
    assert bpy.ops.jampacked.make_real(which='TYPE', type_index=1) == {'FINISHED'}
    left = left[packing.type_index[left] != 1]
    _check_instances(bpy, packing, points, left)
    n_real = len([o for o in coll.objects if "jampacked_type" in o.keys()])
    assert n_real == packing.n - len(left)
    with pytest.raises(RuntimeError, match="There is no type 3 in 'Jampacked Box'"):
        bpy.ops.jampacked.make_real(which='TYPE', type_index=2)
    # a new Pack replaces instances and real objects alike
    scene.settings.seed = 2
    coll = _pack(bpy, 'INSTANCES')
    assert len(coll.objects) == 1


def test_export_of_instances_equals_export_of_objects(bpy, addon, scene, tmp_path):
    s = scene.settings
    s.export_mode, s.file_format = 'UNION', 'STL'
    files = []
    for kind in ('OBJECTS', 'INSTANCES'):
        _pack(bpy, kind)
        s.filepath = str(tmp_path / kind.lower())
        assert bpy.ops.jampacked.export() == {'FINISHED'}
        files.append((tmp_path / f"{kind.lower()}.stl").read_bytes())
    assert len(files[0]) > 1000 and files[0] == files[1]


def test_instanced_result_survives_save_and_reopen(bpy, addon, scene, tmp_path):
    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    path = tmp_path / "instanced.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    coll = bpy.context.scene.jampacked.result
    points = addon.instances.points_object(coll)
    _check_instances(bpy, packing, points)
    assert bpy.ops.jampacked.make_real(which='TYPE', type_index=0) == {'FINISHED'}
    left = np.flatnonzero(packing.type_index != 0)
    _check_instances(bpy, packing, points, left)


def test_panels_show_the_choice_and_make_real(bpy, addon, scene):
    from test_addon_register import _draw_all, _labels

    calls = _draw_all(bpy, addon)
    props = [args[1] for name, args, _kw in calls if name == "prop"]
    assert "result_kind" in props and "instance_threshold" in props
    scene.settings.result_kind = 'OBJECTS'
    assert "instance_threshold" not in [args[1] for name, args, _kw in _draw_all(bpy, addon)
                                        if name == "prop"]
    coll = _pack(bpy, 'INSTANCES')
    calls = _draw_all(bpy, addon)
    assert f"{coll['jampacked_count']} instances" in _labels(calls)
    texts = [kw.get("text") for name, args, kw in calls
             if name == "operator" and args[0] == "jampacked.make_real"]
    assert texts == ["Make All Real", "Selected Points", "Make P5 Real", "Make P4 Real"]
    assert bpy.ops.jampacked.make_real.poll()
    _pack(bpy, 'OBJECTS')
    assert not bpy.ops.jampacked.make_real.poll()
    assert not any(name == "operator" and args[0] == "jampacked.make_real"
                   for name, args, _kw in _draw_all(bpy, addon))


def test_the_panel_says_what_a_result_holds_after_deletions(bpy, addon, scene):
    """The Result panel's figures are the packing's; once objects or instances are deleted
    it adds what the result holds now (it kept showing the packing's count and density)."""
    from test_addon_register import _draw_all, _labels

    for kind, delete in (('INSTANCES', 3), ('OBJECTS', 2)):
        coll = _pack(bpy, kind)
        packing = _packing(addon, coll)
        count, cubes = addon.result_edits.held_now(coll)
        assert count == packing.n
        assert addon.summary.density_now(coll, cubes) == pytest.approx(
            coll["jampacked_density"], rel=1e-5)
        assert "Holds now" not in _labels(_draw_all(bpy, addon))
        gone = np.arange(delete)
        if kind == 'INSTANCES':
            mask = np.zeros(packing.n, bool)
            mask[gone] = True
            addon.instances.drop_points(addon.instances.points_object(coll), mask)
        else:
            for obj in [o for o in coll.objects if o["jampacked_index"] in gone]:
                bpy.data.objects.remove(obj)
        kept = np.setdiff1d(np.arange(packing.n), gone)
        volume = sum(packing.types[t].volume for t in packing.type_index[kept])
        labels = _labels(_draw_all(bpy, addon))
        assert "Holds now" in labels, kind
        assert (f"{packing.n - delete} objects, {volume / packing.container_volume:.1%}"
                in labels), (kind, labels)
        if kind == 'OBJECTS':  # a placed object rescaled shows at the next redraw
            placed = next(o for o in coll.objects if o.type == 'MESH')
            placed.scale = [0.5 * x for x in placed.scale]
            bpy.context.view_layer.update()
            t = int(placed["jampacked_type"])
            less = volume - 0.875 * packing.types[t].volume
            assert (f"{packing.n - delete} objects, {less / packing.container_volume:.1%}"
                    in _labels(_draw_all(bpy, addon)))
    # the same count at another density: the instances object scaled by half (and then
    # made real) holds an eighth of the volume
    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    addon.instances.points_object(coll).scale = (0.5, 0.5, 0.5)
    bpy.context.view_layer.update()
    eighth = f"{packing.n} objects, {coll['jampacked_density'] / 8:.1%}"
    assert eighth in _labels(_draw_all(bpy, addon))
    assert bpy.ops.jampacked.make_real(which='ALL') == {'FINISHED'}
    assert eighth in _labels(_draw_all(bpy, addon))
    # points whose attributes a script removed: the panel still draws the packing's
    # figures, and Make Real and Export say what is missing (they raised a KeyError)
    coll = _pack(bpy, 'INSTANCES')
    points = addon.instances.points_object(coll).data
    points.attributes.remove(points.attributes["jampacked_scale"])
    points.vertices.add(1)  # and a point added: the panel reads the points again
    labels = _labels(_draw_all(bpy, addon))
    assert "Density" in labels and "Holds now" not in labels
    with pytest.raises(RuntimeError, match="lack their attribute jampacked_scale, which "
                                           "hold where each object goes"):
        bpy.ops.jampacked.make_real(which='ALL')
    bpy.context.scene.jampacked.filepath = "//never.stl"
    with pytest.raises(RuntimeError, match="lack their attribute jampacked_scale"):
        bpy.ops.jampacked.export()


def test_a_duplicated_point_is_told_apart_from_its_original(bpy, addon, scene, tmp_path):
    """A point duplicated in place (Shift+D in Edit Mode) overlaps its original: Export
    named the pair as the same instance twice (and the change by its certificate's
    digest, which means nothing to an artist)."""
    import bmesh

    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    points = addon.instances.points_object(coll)
    bm = bmesh.new()
    bm.from_mesh(points.data)
    bm.verts.ensure_lookup_table()
    bmesh.ops.duplicate(bm, geom=[bm.verts[0]])
    bm.to_mesh(points.data)
    bm.free()
    name = f"{packing.types[packing.type_index[0]].name} 1"
    bpy.context.scene.jampacked.filepath = str(tmp_path / "twice.stl")
    with pytest.raises(RuntimeError, match=rf"the result's objects were moved, added or "
                                           rf"deleted since Pack certified them.*'{name}, an "
                                           rf"instance, point 0' and '{name}, an instance, "
                                           rf"point {packing.n}' overlap"):
        bpy.ops.jampacked.export()


def test_make_real_refuses_damaged_placements(bpy, addon, scene):
    """The points object's placements cut short (edited by a script): a clear error, no
    object made, the instances kept."""
    coll = _pack(bpy, 'INSTANCES')
    n = coll["jampacked_count"]
    points = addon.instances.points_object(coll)
    short = np.array(points["jampacked_placements"])[:18]
    del points["jampacked_placements"]  # an assignment keeps an array property's length
    points["jampacked_placements"] = short
    objects = {o.name for o in bpy.data.objects}
    with pytest.raises(RuntimeError, match="lacks its placements"):
        bpy.ops.jampacked.make_real(which='ALL')
    assert {o.name for o in bpy.data.objects} == objects
    assert len(points.data.vertices) == n


def test_make_real_places_objects_where_the_instances_are_drawn(bpy, addon, scene):
    """The points object moved and turned, and one point moved in Edit Mode: the objects
    made real are where the instances were drawn (they went back to the packing's places,
    where Export had refused the moved instances)."""
    import bmesh

    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    points = addon.instances.points_object(coll)
    points.location = (0.0, 0.0, 0.5)
    points.rotation_euler = (0.0, 0.0, 0.3)
    bpy.context.view_layer.objects.active = points
    points.select_set(True)
    bpy.ops.object.mode_set(mode='EDIT')
    bm = bmesh.from_edit_mesh(points.data)
    bm.verts.ensure_lookup_table()
    bm.verts[2].co.x += 0.25
    bmesh.update_edit_mesh(points.data)
    bpy.ops.object.mode_set(mode='OBJECT')
    drawn = _instances(bpy, points)
    assert len(drawn) == packing.n
    assert bpy.ops.jampacked.make_real(which='ALL') == {'FINISHED'}
    real = [o for o in coll.objects if "jampacked_type" in o.keys()]
    assert len(real) == packing.n
    for obj in real:
        m = _matrix(obj)
        d = [np.abs(m - mat).max() for _, mat in drawn]
        k = int(np.argmin(d))
        assert d[k] < 1e-5 and drawn[k][0] == obj.data.name
    # a points object scaled unevenly draws sheared instances, which no object placement
    # can be (they were made elsewhere, 0.78 off): refused by name, nothing made
    coll = _pack(bpy, 'INSTANCES')
    points = addon.instances.points_object(coll)
    points.scale = (1.0, 1.0, 2.0)
    points.rotation_euler = (0.0, 0.0, 0.3)
    bpy.context.view_layer.update()
    before = scene_state(bpy)
    with pytest.raises(RuntimeError, match=r"\(an instance of 'Jampacked Box instances'\) is "
                                           "scaled unevenly, sheared or mirrored.*make it "
                                           "real again"):
        bpy.ops.jampacked.make_real(which='ALL')
    assert scene_state(bpy) == before
    # where the points object sits still, the placement is the packing's, exactly
    coll = _pack(bpy, 'INSTANCES')
    assert bpy.ops.jampacked.make_real(which='ALL') == {'FINISHED'}
    mats = packing.matrices()
    for obj in coll.objects:
        i = obj["jampacked_index"]
        np.testing.assert_allclose(_matrix(obj), mats[i], atol=1e-6)


def test_make_real_from_edit_mode(bpy, addon, scene):
    """The user's way: Tab into the points object, select points, Make Real (Selected
    Points): Blender leaves Edit Mode with the selection and the points become objects."""
    import bmesh

    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    points = addon.instances.points_object(coll)
    bpy.context.view_layer.objects.active = points
    points.select_set(True)
    bpy.ops.object.mode_set(mode='EDIT')
    bm = bmesh.from_edit_mesh(points.data)
    bm.verts.ensure_lookup_table()
    for v in bm.verts:
        v.select_set(v.index in (1, 2))
    bmesh.update_edit_mesh(points.data)
    assert bpy.ops.jampacked.make_real(which='SELECTED') == {'FINISHED'}
    assert points.mode == 'OBJECT'
    real = sorted(o.name for o in coll.objects if "jampacked_type" in o.keys())
    assert real == sorted(f"{packing.types[packing.type_index[i]].name} {i + 1}"
                          for i in (1, 2))
    _check_instances(bpy, packing, points, np.setdiff1d(np.arange(packing.n), [1, 2]))


def test_export_writes_the_instances_and_real_objects_the_scene_has(bpy, addon, scene,
                                                                     tmp_path):
    # points removed from an instanced result were still exported; made real and
    # unchanged, nothing is certified again
    from jampacked.export.validate import validate_file

    s = scene.settings
    s.export_mode, s.file_format = 'UNION', '3MF'
    coll = _pack(bpy, 'INSTANCES')
    packing = _packing(addon, coll)
    points = addon.instances.points_object(coll)
    select = np.zeros(packing.n, bool)
    select[[0, 3]] = True
    points.data.vertices.foreach_set("select", select)
    assert bpy.ops.jampacked.make_real(which='SELECTED') == {'FINISHED'}
    s.filepath = str(tmp_path / "mixed")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    message = bpy.context.window_manager.jampacked_job.last_message
    assert "certified again" not in message, message
    # two instances deleted in Edit Mode (where Make Real's selection is made; the export
    # read no attributes there and failed with a traceback)
    import bmesh

    bpy.context.view_layer.objects.active = points
    points.select_set(True)
    bpy.ops.object.mode_set(mode='EDIT')
    bm = bmesh.from_edit_mesh(points.data)
    bm.verts.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.verts[0], bm.verts[1]], context='VERTS')
    bmesh.update_edit_mesh(points.data)
    s.filepath = str(tmp_path / "fewer")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    message = bpy.context.window_manager.jampacked_job.last_message
    assert f"union: {packing.n - 2} objects" in message, message
    assert f"Exported the {packing.n - 2} objects the result holds now" in message
    assert validate_file(tmp_path / "fewer.3mf").passed
    # the points object moved: every instance with it, certified again
    points.location.x += 1e-3
    s.filepath = str(tmp_path / "moved")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    message = bpy.context.window_manager.jampacked_job.last_message
    assert f"its {packing.n - 2} placements were certified again" in message, message


def test_make_real_acts_on_the_active_instances_objects_result(bpy, addon, scene):
    """Two containers, each packed as instances: points selected in Edit Mode on the first
    result's instances object were made real in the last Pack's result (the second), or
    refused as "no points selected" there. Make Real, the Result panel and Export now follow
    the active object's result, else the last Pack's; an appended result (the scene's Result
    empty) can be made real from its instances object."""
    from addon_helpers import cube_object

    s = scene.settings
    s.seed = 41
    coll_a = _pack(bpy, 'INSTANCES')
    box_b = cube_object(bpy, "Box B", location=(200.0, 0.0, 0.0), scale=(10.0, 9.5, 11.0))
    s.container, s.seed = box_b, 42
    coll_b = _pack(bpy, 'INSTANCES')
    assert coll_a.name in bpy.data.collections and coll_b != coll_a
    points_a = addon.instances.points_object(coll_a)
    points_b = addon.instances.points_object(coll_b)
    n_a, n_b = len(points_a.data.vertices), len(points_b.data.vertices)
    select = np.zeros(n_b, bool)
    select[:1] = True  # a stale selection on the second result's points
    points_b.data.vertices.foreach_set("select", select)
    select = np.zeros(n_a, bool)
    select[:2] = True
    points_a.data.vertices.foreach_set("select", select)
    bpy.context.view_layer.objects.active = points_a
    assert addon.results.shown_result(bpy.context) == coll_a
    assert bpy.ops.jampacked.make_real(which='SELECTED') == {'FINISHED'}
    job = bpy.context.window_manager.jampacked_job
    assert job.last_message == (f"Made 2 object(s) real in '{coll_a.name}'; {n_a - 2} "
                                "instance(s) left.")
    assert len(points_b.data.vertices) == n_b
    # an appended result: the scene's Result points nowhere, its instances object is active
    s.result = None
    bpy.context.view_layer.objects.active = points_b
    assert bpy.ops.jampacked.make_real.poll()
    assert bpy.ops.jampacked.make_real(which='ALL') == {'FINISHED'}
    assert addon.instances.points_object(coll_b) is None
    assert len([o for o in coll_b.objects if "jampacked_type" in o.keys()]) == n_b


def test_a_fresh_pack_is_shown_though_an_older_results_object_was_active(bpy, addon, scene,
                                                                          tmp_path):
    """With Keep Previous, an object of the first result active: after the second Pack the
    panel and Export followed the first result (the active object's), where Pack's message
    pointed to the new one. Pack now makes one of the new result's objects active; an
    object in both results shows the last Pack's; Export's message names what it wrote."""
    s = scene.settings
    s.seed, s.keep_previous = 43, True
    first = _pack(bpy, 'OBJECTS')
    placed = next(o for o in first.objects if "jampacked_type" in o.keys())
    bpy.context.view_layer.objects.active = placed
    s.seed = 44
    second = _pack(bpy, 'OBJECTS')
    assert second != first and first.name in bpy.data.collections
    assert addon.results.shown_result(bpy.context) == second
    assert bpy.context.view_layer.objects.active.name in second.objects
    s.export_mode, s.file_format, s.filepath = 'UNION', 'STL', str(tmp_path / "x")
    assert bpy.ops.jampacked.export() == {'FINISHED'}
    message = bpy.context.window_manager.jampacked_job.last_message
    assert message.startswith(f"Exported '{second.name}' to "), message
    # an object linked into both results: the last Pack's is shown
    second.objects.link(placed)
    bpy.context.view_layer.objects.active = placed
    assert addon.results.shown_result(bpy.context) == second
    bpy.context.scene.jampacked.result = first
    assert addon.results.shown_result(bpy.context) == first
    # the older result's points object in Edit Mode stays active (and in Edit Mode) through
    # a Pack: made inactive, it stayed in Edit Mode unseen by what leaves Edit Mode first
    s.seed = 45
    s.result_kind = 'INSTANCES'
    third = _pack(bpy, 'INSTANCES')
    points = addon.instances.points_object(third)
    bpy.context.view_layer.objects.active = points
    bpy.ops.object.mode_set(mode='EDIT')
    s.seed = 46
    fourth = _pack(bpy, 'INSTANCES')
    assert fourth != third
    assert bpy.context.view_layer.objects.active == points and points.mode == 'EDIT'
    assert addon.results.shown_result(bpy.context) == third
    bpy.ops.object.mode_set(mode='OBJECT')

