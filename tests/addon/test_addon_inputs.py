"""Pack with every kind of input a Blender user can give: a clear error naming the object or
a valid result; never a traceback, an internal error or a half-changed scene.

A seeded generator builds small scenes from kinds of container and object type (modifiers,
mirroring scales, parenting, curves, text, metaballs, cameras, empty and open meshes, hidden,
disabled and deleted objects, repeated rows, zero shares) and runs Pack in blocking mode;
each kind says what a user should get. Targeted tests below pin each fix.
"""

from __future__ import annotations

import math
import random
import re
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

pytest.importorskip("bpy")

from addon_helpers import CUBE_FACES, cube_object, scale_in_edit_mode, scene_state  # noqa: E402

#: what no message to a user may contain
NOT_CLEAR = re.compile(r"internal error|Traceback|this is a bug|please report", re.I)


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _link(bpy, obj, collection=None):
    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def _ico(bpy, name, *, radius=1.0, location=(0.0, 0.0, 30.0)):
    """An icosphere (closed, 20 triangles) as a plain mesh object."""
    import bmesh

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_icosphere(bm, subdivisions=1, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    obj = _link(bpy, bpy.data.objects.new(name, mesh))
    obj.location = location
    return obj


def _curve(bpy, name, *, bevel: float, text: bool = False):
    if text:
        data = bpy.data.curves.new(name, 'FONT')
        data.body = "I"
        data.size = 2.0
        data.extrude = bevel
    else:
        data = bpy.data.curves.new(name, 'CURVE')
        data.dimensions = '3D'
        spline = data.splines.new('BEZIER')
        spline.bezier_points.add(1)
        for point, x in zip(spline.bezier_points, (-0.8, 0.8), strict=True):
            point.co = (x, 0.0, 0.0)
            point.handle_left_type = point.handle_right_type = 'AUTO'
        data.bevel_depth = bevel
        data.use_fill_caps = True
    obj = _link(bpy, bpy.data.objects.new(name, data))
    obj.location = (0.0, 0.0, 40.0)
    return obj


# ------------------------------------------------------------------------------ kinds
# A kind builds one input object named `name` and returns it. `expect` is None when Pack
# must succeed with it, else a regular expression the error must match ({name}: the object);
# `stage` is when Pack finds the fault: picking the objects, reading their geometry, or the
# engine's mesh checks (in that order over all inputs, the container first).

@dataclass(frozen=True)
class Kind:
    name: str
    build: Callable
    expect: str | None
    stage: str = "engine"


def _modified(kind, **settings):
    def build(bpy, name, rng):
        obj = _ico(bpy, name)
        mod = obj.modifiers.new(kind, kind)
        for key, value in settings.items():
            setattr(mod, key, value)
        return obj
    return build


def _transformed(scale, parent=False, flat=False):
    def build(bpy, name, rng):
        obj = _ico(bpy, name)
        obj.rotation_euler = [rng.uniform(-3, 3) for _ in range(3)]
        obj.scale = scale
        if parent:
            empty = _link(bpy, bpy.data.objects.new(f"{name} parent", None))
            empty.scale = (0.6, 0.0 if flat else 0.9, 0.7)
            empty.rotation_euler = (0.4, -0.3, 1.1)
            obj.parent = empty
        return obj
    return build


def _inside_out(scale):
    """An icosphere with its faces turned inwards (and a scale, which may mirror it back)."""
    def build(bpy, name, rng):
        obj = _ico(bpy, name)
        obj.data.flip_normals()
        obj.scale = scale
        return obj
    return build


def _boolean_type(bpy, name, rng):
    obj = _ico(bpy, name)
    cutter = _ico(bpy, f"{name} cutter", radius=0.6, location=(0.8, 0.0, 30.0))
    cutter.hide_set(True)
    mod = obj.modifiers.new("Boolean", 'BOOLEAN')
    mod.object, mod.operation = cutter, 'DIFFERENCE'
    return obj


def _hidden(how):
    def build(bpy, name, rng):
        obj = _modified('SUBSURF', levels=1)(bpy, name, rng)
        if how == "H":
            obj.hide_set(True)
        elif how == "disabled":
            obj.hide_viewport = True
        else:  # "excluded": in a collection excluded from the view layer
            coll = bpy.data.collections.new(f"{name} library")
            bpy.context.scene.collection.children.link(coll)
            bpy.context.scene.collection.objects.unlink(obj)
            coll.objects.link(obj)
            bpy.context.view_layer.layer_collection.children[coll.name].exclude = True
        return obj
    return build


def _deleted(bpy, name, rng):
    obj = _ico(bpy, name)
    bpy.context.scene.collection.objects.unlink(obj)  # what Delete does to a used object
    return obj


def _metaball(bpy, name, rng):
    data = bpy.data.metaballs.new(name)
    data.resolution = 0.4
    data.elements.new().radius = 1.2
    obj = _link(bpy, bpy.data.objects.new(name, data))
    obj.location = (0.0, 10.0, 40.0)
    return obj


def _nurbs_surface(bpy, name, rng):
    bpy.ops.surface.primitive_nurbs_surface_sphere_add(location=(0.0, -10.0, 40.0))
    obj = bpy.context.active_object
    obj.name = name
    return obj


def _no_data(kind):
    def build(bpy, name, rng):
        if kind == 'CAMERA':
            data = bpy.data.cameras.new(name)
        elif kind == 'LIGHT':
            data = bpy.data.lights.new(name, 'POINT')
        else:
            data = None
        return _link(bpy, bpy.data.objects.new(name, data))
    return build


def _instance(bpy, name, rng):
    coll = bpy.data.collections.new(f"{name} source")
    coll.objects.link(_ico(bpy, f"{name} part"))
    empty = _link(bpy, bpy.data.objects.new(name, None))
    empty.instance_type = 'COLLECTION'
    empty.instance_collection = coll
    return empty


def _nodes_pass_through(build_object):
    """An object with a Geometry Nodes modifier that passes its geometry through: a curve's
    surface then shows as one instance of it, which Pack reads (not an instance to
    realize)."""
    def build(bpy, name, rng):
        obj = build_object(bpy, name, rng)
        tree = bpy.data.node_groups.new(f"{name} nodes", 'GeometryNodeTree')
        tree.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
        tree.interface.new_socket("Geometry", in_out='OUTPUT',
                                  socket_type='NodeSocketGeometry')
        tree.links.new(tree.nodes.new('NodeGroupInput').outputs[0],
                       tree.nodes.new('NodeGroupOutput').inputs[0])
        obj.modifiers.new("Pass", 'NODES').node_group = tree
        return obj
    return build


def _node_instances(keep_mesh: bool):
    """An icosphere whose Geometry Nodes draw an instance: of a cube above it beside its own
    mesh (a leaf on a fruit), or of its whole mesh (Geometry to Instance)."""
    def build(bpy, name, rng):
        obj = _ico(bpy, name)
        tree = bpy.data.node_groups.new(f"{name} nodes", 'GeometryNodeTree')
        tree.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
        tree.interface.new_socket("Geometry", in_out='OUTPUT',
                                  socket_type='NodeSocketGeometry')
        nodes, links = tree.nodes, tree.links
        given, out = nodes.new('NodeGroupInput'), nodes.new('NodeGroupOutput')
        to_instance = nodes.new('GeometryNodeGeometryToInstance')
        if keep_mesh:
            cube = nodes.new('GeometryNodeMeshCube')
            cube.inputs['Size'].default_value = (0.4, 0.4, 0.4)
            join = nodes.new('GeometryNodeJoinGeometry')
            links.new(cube.outputs[0], to_instance.inputs[0])
            links.new(given.outputs[0], join.inputs[0])
            links.new(to_instance.outputs[0], join.inputs[0])
            links.new(join.outputs[0], out.inputs[0])
        else:
            links.new(given.outputs[0], to_instance.inputs[0])
            links.new(to_instance.outputs[0], out.inputs[0])
        obj.modifiers.new("Leaf", 'NODES').node_group = tree
        return obj
    return build


def _other_scene(build_object):
    """An object linked only into another scene ("Library"), not the one Pack runs in."""
    def build(bpy, name, rng):
        obj = build_object(bpy, name, rng)
        library = bpy.data.scenes.get("Library") or bpy.data.scenes.new("Library")
        library.collection.objects.link(obj)
        for coll in list(obj.users_collection):
            if coll != library.collection:
                coll.objects.unlink(obj)
        obj.location = (40.0, 0.0, 0.0)
        return obj
    return build


def _arrays(vertices, faces, edges=()):
    def build(bpy, name, rng):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(vertices, list(edges), faces)
        mesh.update()
        return _link(bpy, bpy.data.objects.new(name, mesh))
    return build


def _nan(bpy, name, rng):
    obj = _ico(bpy, name)
    obj.data.vertices[rng.randrange(len(obj.data.vertices))].co.x = math.nan
    return obj


NOT_A_SOLID = r"'{name}'.*(separate bodies|not a watertight|not closed|zero volume)"
HUGE = r"'{name}' is [-+.e\d]+ x .* units across: Pack takes objects between 1e-06 and"
NO_SURFACE = r"'{name}' is not a mesh object \(its type is \w+\), it has no surface"
INSTANCES = (r"'{name}' draws 1 instance\(s\), which Pack cannot read as part of its "
             r"surface.*Realize Instances node at the end of its Geometry Nodes modifier "
             r"'Leaf'")
OTHER_SCENE = r"'{name}' is not in this scene \('Scene'\), only in 'Library': link it"

TYPE_KINDS = [
    Kind("plain", lambda bpy, name, rng: _ico(bpy, name), None),
    Kind("subdivision", _modified('SUBSURF', levels=1), None),
    Kind("boolean", _boolean_type, None),
    Kind("mirrored x", _transformed((-0.9, 0.9, 0.9)), None),
    Kind("mirrored xyz", _transformed((-0.8, -0.8, -0.8)), None),
    # the engine turns it outward (with a warning); the result's mesh was left inward
    Kind("inside out", _inside_out((1.0, 1.0, 1.0)), None),
    Kind("inside out, mirrored", _inside_out((-0.9, 0.9, 0.9)), None),
    Kind("non-uniform rotated", _transformed((1.2, 0.6, 0.9)), None),
    Kind("parented", _transformed((1.0, 1.0, 1.0), parent=True), None),
    Kind("parented mirrored", _transformed((1.0, -1.0, 1.0), parent=True), None),
    Kind("hidden (H)", _hidden("H"), None),
    Kind("bevelled curve", lambda bpy, name, rng: _curve(bpy, name, bevel=0.5), None),
    Kind("extruded text", lambda bpy, name, rng: _curve(bpy, name, bevel=0.3, text=True),
         None),
    Kind("metaball", _metaball, None),
    Kind("solidify", _modified('SOLIDIFY', thickness=0.3), NOT_A_SOLID),
    Kind("array", _modified('ARRAY', count=2, relative_offset_displace=(2.5, 0, 0)),
         NOT_A_SOLID),
    Kind("mirror modifier", _modified('MIRROR', use_bisect_axis=(False, False, False)),
         NOT_A_SOLID),
    Kind("flat curve", lambda bpy, name, rng: _curve(bpy, name, bevel=0.0),
         r"'{name}' is a flat curve with no volume", "read"),
    Kind("flat text", lambda bpy, name, rng: _curve(bpy, name, bevel=0.0, text=True),
         r"'{name}' is a flat text with no volume", "read"),
    Kind("nurbs surface", _nurbs_surface, NOT_A_SOLID),
    Kind("camera", _no_data('CAMERA'), NO_SURFACE, "pick"),
    Kind("light", _no_data('LIGHT'), NO_SURFACE, "pick"),
    Kind("empty", _no_data(None), NO_SURFACE, "pick"),
    Kind("collection instance", _instance, r"'{name}' is an instance of the collection",
         "pick"),
    Kind("no vertices", _arrays([], []), r"'{name}' has no faces \(0 vertices", "read"),
    Kind("loose edges", _arrays([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1), (1, 2)]),
         r"'{name}' has no faces \(3 vertices", "read"),
    Kind("open", _arrays([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)],
                         [(0, 2, 1), (0, 1, 3), (0, 3, 2)]), NOT_A_SOLID),
    Kind("nan vertex", _nan, r"'{name}' has non-finite vertex coordinates"),
    # its Scale named (it read "has zero volume ... Check that the right file was exported")
    Kind("flattened", _transformed((1.0, 0.0, 1.0)),
         r"'{name}' is flattened by its Scale \(1 x 0 x 1\): .*sidebar > Item", "read"),
    Kind("flattened by its parent", _transformed((1.0, 1.0, 1.0), parent=True, flat=True),
         r"'{name}' is flattened by the Scale of its parent '{name} parent' \(0.6 x 0 x 0.7\)",
         "read"),
    Kind("huge", _transformed((1e12, 1e12, 1e12)), HUGE, "read"),
    Kind("tiny", _transformed((1e-8, 2e-8, 1e-8)), HUGE, "read"),
    Kind("disabled in viewports", _hidden("disabled"),
         r"'{name}' is disabled in viewports or in an excluded", "read"),
    Kind("excluded collection", _hidden("excluded"),
         r"'{name}' is disabled in viewports or in an excluded", "read"),
    Kind("deleted", _deleted, r"'{name}' is in no scene \(it was deleted\)", "pick"),
    # Blender shows the instances; Pack packed the object without them, or said "no faces"
    Kind("nodes instance beside the mesh", _node_instances(True), INSTANCES, "read"),
    Kind("nodes instance only", _node_instances(False), INSTANCES, "read"),
    Kind("bevelled curve, nodes", _nodes_pass_through(
        lambda bpy, name, rng: _curve(bpy, name, bevel=0.5)), None),
    Kind("plain, nodes", _nodes_pass_through(lambda bpy, name, rng: _ico(bpy, name)), None),
    # read with the identity transform (no depsgraph of this scene holds it)
    Kind("in another scene", _other_scene(_transformed((0.8, 0.8, 0.8))), OTHER_SCENE,
         "pick"),
]


def _box(scale, **extra):
    def build(bpy, name, rng):
        obj = cube_object(bpy, name, scale=scale, location=(1.0, -2.0, 0.5), **extra)
        return obj
    return build


def _solidified_box(bpy, name, rng):
    box = _box((3.0, 3.0, 3.0))(bpy, name, rng)
    box.modifiers.new("Solidify", 'SOLIDIFY').thickness = 0.5
    return box


def _cut_box(bpy, name, rng):
    box = _box((3.2, 3.0, 3.4))(bpy, name, rng)
    cutter = cube_object(bpy, f"{name} cutter", scale=(1.5, 1.5, 1.5),
                         location=(4.0, 1.0, 3.5))
    cutter.hide_set(True)
    mod = box.modifiers.new("Boolean", 'BOOLEAN')
    mod.object, mod.operation = cutter, 'DIFFERENCE'
    return box


CONTAINER_KINDS = [
    Kind("box", _box((3.0, 3.2, 3.4)), None),
    Kind("mirrored box", _box((-3.2, 3.0, 3.3)), None),
    Kind("rotated box", _box((3.4, 3.0, 3.2), rotation_euler=(0.3, 0.5, -0.2)), None),
    Kind("boolean box", _cut_box, None),
    Kind("solidified box", _solidified_box, NOT_A_SOLID),
    Kind("open box", lambda bpy, name, rng: cube_object(bpy, name, faces=CUBE_FACES[:-1],
                                                        scale=(3.0, 3.0, 3.0)),
         NOT_A_SOLID),
    Kind("huge box", _box((3e12, 3e12, 3e12)), HUGE, "read"),
    Kind("flattened box", _box((3.0, 3.0, 0.0)),
         r"'{name}' is flattened by its Scale \(3 x 3 x 0\)", "read"),
    Kind("camera", _no_data('CAMERA'), NO_SURFACE, "pick"),
    Kind("no vertices", _arrays([], []), r"'{name}' has no faces \(0 vertices", "read"),
    Kind("deleted", _deleted, r"'{name}' is in no scene \(it was deleted\)", "pick"),
    Kind("in another scene", _other_scene(_box((3.0, 3.2, 3.4))), OTHER_SCENE, "pick"),
]


# a setting a user can get wrong, applied after the objects exist


def _share_zero(s, objects):
    if len(s.types) > 1:
        s.types[0].share = 0.0


def _shares_negative(s, objects):
    for item in s.types:
        item.share = -3.0  # the field clamps to 0
        assert item.share == 0.0


def _repeated(s, objects):
    s.types.add().object = objects[0]


def _container_as_type(s, objects):
    s.types.add().object = s.container


def _empty_row(s, objects):
    s.types.add()


def _removed(s, objects):
    import bpy

    bpy.data.objects.remove(objects[-1])  # the row's pointer is cleared


def _none(s, objects):
    pass


#: settings and how often the generator picks them (mostly right, as users mostly are)
SETTINGS = {_none: 6, _share_zero: 2, _shares_negative: 1, _repeated: 1,
            _container_as_type: 1, _empty_row: 1, _removed: 1}
#: how much more often the generator picks a kind that must pack than one that must fail
VALID_WEIGHT = 4


def _pick(rng: random.Random, kinds: list[Kind]) -> Kind:
    return rng.choices(kinds, [VALID_WEIGHT if k.expect is None else 1 for k in kinds])[0]


def _expected(s, kinds: dict) -> str | None:
    """The error Pack must give for the settings ``s`` (None: it must pack), checking in
    Pack's order; kinds: object name -> its Kind."""
    def error(obj):
        kind = kinds[obj.name]
        return None if kind.expect is None else kind.expect.format(name=re.escape(obj.name))

    container = s.container
    if kinds[container.name].stage == "pick":
        return error(container)
    rows = []
    for i, item in enumerate(s.types, 1):
        obj = item.object
        if obj is None:
            return rf"object type {i} has no object"
        if kinds[obj.name].stage == "pick":
            return error(obj)
        if obj == container:
            return rf"'{re.escape(obj.name)}' is both the container and object type {i}"
        if obj in rows:
            return rf"'{re.escape(obj.name)}' is listed twice as an object type"
        rows.append(obj)
    if sum(item.share for item in s.types) <= 0:
        return r"every object type has share 0"
    for stage in ("read", "engine"):
        for obj in (container, *rows):
            if kinds[obj.name].stage == stage and kinds[obj.name].expect is not None:
                return error(obj)
    return None


# ------------------------------------------------------------------------------ running


def _settings(bpy, container, types):
    s = bpy.context.scene.jampacked
    s.container = container
    for obj in types:
        s.types.add().object = obj
    s.fidelity = 'LOW'
    s.time_budget = 1.0
    s.seed = 3
    return s


def _pack(bpy, expect: str | None, context: str) -> None:
    """Run Pack; check the error (and that nothing changed) or the result."""
    before = scene_state(bpy)
    try:
        outcome = bpy.ops.jampacked.pack()
    except RuntimeError as exc:
        message = str(exc)
        assert expect is not None, f"{context}: Pack failed: {message}"
        assert re.search(expect, message, re.I | re.S), f"{context}: {message}"
        assert not NOT_CLEAR.search(message), f"{context}: {message}"
        assert scene_state(bpy) == before, f"{context}: the failed Pack changed the scene"
        return
    assert expect is None, f"{context}: Pack gave {outcome}, expected an error /{expect}/"
    assert outcome == {'FINISHED'}, context
    _check_result(bpy, before, context)


def _check_result(bpy, before: dict, context: str) -> None:
    """A valid result: the packing's objects in one new collection, outward type meshes, the
    inputs untouched, the shares honoured."""
    import jampacked_blender_addon as addon

    s = bpy.context.scene.jampacked
    coll = s.result
    packing = addon.engine.packing_from_json(coll["jampacked_packing"])
    assert packing.n > 0 and len(coll.objects) == packing.n, context
    assert packing.certificate["certified"] is True, context
    after = scene_state(bpy)
    assert set(after["objects"]) - set(before["objects"]) == {o.name for o in coll.objects}
    assert set(before["objects"]) <= set(after["objects"]), context
    assert set(after["collections"]) - set(before["collections"]) == {coll.name}, context
    for name, matrix in before["matrices"].items():
        assert after["matrices"][name] == matrix, f"{context}: '{name}' moved"
    for name in coll["jampacked_type_meshes"]:
        mesh = bpy.data.meshes[name]
        tris = addon.bridge.mesh_triangles(mesh, name)
        assert _signed_volume(tris.vertices, tris.faces) > 0, f"{context}: {name} inward"
    counts = packing.metrics["count_per_type"]
    for item, count in zip(s.types, counts, strict=True):
        if item.share == 0:
            assert count == 0, f"{context}: a type with share 0 was placed"


def _case(bpy, rng: random.Random, case: int) -> tuple[str | None, str]:
    """Build one generated scene; returns the error Pack must give (None: it must pack) and
    a label naming the case."""
    ckind = _pick(rng, CONTAINER_KINDS)
    tkinds = [_pick(rng, TYPE_KINDS) for _ in range(rng.choice((1, 1, 2)))]
    container = ckind.build(bpy, "Container", rng)
    types = [k.build(bpy, f"Type{i}", rng) for i, k in enumerate(tkinds)]
    kinds = {o.name: k for o, k in zip([container, *types], [ckind, *tkinds], strict=True)}
    setting = rng.choices(list(SETTINGS), list(SETTINGS.values()))[0]
    s = _settings(bpy, container, types)
    setting(s, types)
    label = (f"case {case}: container {ckind.name}, types {[k.name for k in tkinds]}, "
             f"settings {setting.__name__}")
    return _expected(s, kinds), label


#: generated scenes per seed
CASES = 20


@pytest.mark.parametrize("seed", [0, 1])
def test_generated_inputs(bpy, addon, seed):
    """Seeded scenes of every kind of input: a clear error naming the object, the scene
    unchanged, or a valid result."""
    rng = random.Random(seed)
    for case in range(CASES):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        expect, label = _case(bpy, rng, case)
        _pack(bpy, expect, f"seed {seed} {label}")
        assert not addon.worker.busy(), label


@pytest.mark.parametrize("kind", TYPE_KINDS, ids=lambda k: k.name)
def test_every_type_kind(bpy, addon, kind):
    """Each kind of object type once, in a plain box, next to a plain icosphere type."""
    box = cube_object(bpy, "Box", scale=(2.6, 2.6, 2.6))
    obj = kind.build(bpy, "Odd", random.Random(5))
    _settings(bpy, box, [obj, _ico(bpy, "Ico", radius=0.8)])
    expect = None if kind.expect is None else kind.expect.format(name="Odd")
    _pack(bpy, expect, kind.name)


@pytest.mark.parametrize("kind", CONTAINER_KINDS, ids=lambda k: k.name)
def test_every_container_kind(bpy, addon, kind):
    container = kind.build(bpy, "Odd", random.Random(6))
    _settings(bpy, container, [_ico(bpy, "Ico", radius=0.9)])
    expect = None if kind.expect is None else kind.expect.format(name="Odd")
    _pack(bpy, expect, kind.name)


# ------------------------------------------------------------------------------ the fixes


def test_a_defect_its_modifiers_make_names_them(bpy, addon):
    """A container whose Array modifier makes internal faces was told to select Interior
    Faces and delete them, which finds nothing in the mesh itself; a Solidify one to delete
    the extra surfaces. The message now names the modifiers; a mesh without any is told
    as before."""
    box = cube_object(bpy, "Arrayed", scale=(3.0, 3.0, 3.0))
    mod = box.modifiers.new("Array", 'ARRAY')
    mod.count, mod.relative_offset_displace, mod.use_merge_vertices = 2, (1.0, 0, 0), True
    hidden = box.modifiers.new("Hidden Bevel", 'BEVEL')
    hidden.show_viewport = False  # not what Blender shows: not named
    _settings(bpy, box, [_ico(bpy, "Ico", radius=0.9)])
    with pytest.raises(RuntimeError) as info:
        bpy.ops.jampacked.pack()
    text = str(info.value)
    assert "'Arrayed'" in text and "This is the mesh its modifiers ('Array') make" in text
    assert "Hidden Bevel" not in text
    bpy.ops.wm.read_factory_settings(use_empty=True)
    box = cube_object(bpy, "Open", faces=CUBE_FACES[:-1], scale=(3.0, 3.0, 3.0))
    _settings(bpy, box, [_ico(bpy, "Ico", radius=0.9)])
    with pytest.raises(RuntimeError) as info:
        bpy.ops.jampacked.pack()
    assert "'Open'" in str(info.value) and "modifiers" not in str(info.value)


def test_a_mirrored_object_is_read_outward(bpy, addon):
    """A negative scale mirrors the mesh and reverses its winding in world space: the
    triangles Pack hands to the engine face outward (the engine had to repair them
    inverted), as do the result's meshes."""
    ico = _ico(bpy, "Ico")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    plain = addon.bridge.object_triangles(ico, depsgraph, outward=True)
    for scale in ((-1.0, 1.0, 1.0), (-1.0, -1.0, -1.0), (1.0, -2.0, 0.5)):
        ico.scale = scale
        bpy.context.view_layer.update()
        depsgraph = bpy.context.evaluated_depsgraph_get()
        tris = addon.bridge.object_triangles(ico, depsgraph, outward=True)
        assert _signed_volume(tris.vertices, tris.faces) > 0, scale
        mesh = tris.mesh_data("object")
        assert not mesh.warnings, mesh.warnings
        assert mesh.volume == pytest.approx(
            _signed_volume(plain.vertices, plain.faces) * abs(np.prod(scale)))


def test_a_bevelled_curve_packs_as_its_surface(bpy, addon):
    """A curve with depth is packed as the mesh Blender shows (it was refused as 'not a
    mesh'); its result mesh has the curve's surface."""
    curve = _curve(bpy, "Rod", bevel=0.5)
    _settings(bpy, cube_object(bpy, "Box", scale=(3.0, 3.0, 3.0)), [curve])
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    depsgraph = bpy.context.evaluated_depsgraph_get()
    shown = addon.bridge.object_triangles(curve, depsgraph)
    mesh = bpy.data.meshes["Jampacked Rod"]
    assert len(mesh.polygons) == shown.n_polygons > 0


def test_modifiers_blender_does_not_evaluate_are_refused(bpy, addon):
    """An object disabled in viewports gives its bare mesh without its modifiers (it was
    packed so, silently); hidden with H it is evaluated and packs with them."""
    box = cube_object(bpy, "Box", scale=(3.0, 3.0, 3.0))
    ico = _modified('SUBSURF', levels=1)(bpy, "Ico", None)
    s = _settings(bpy, box, [ico])
    ico.hide_viewport = True
    with pytest.raises(RuntimeError, match="'Ico' is disabled in viewports"):
        bpy.ops.jampacked.pack()
    ico.hide_viewport = False
    ico.hide_set(True)
    request = addon.bridge.gather_pack(bpy.context)
    assert request.types[0].n_polygons == 60  # 20 triangles, each 3 quads once subdivided
    assert s.container == box


def test_a_deleted_object_is_refused(bpy, addon):
    """Deleting a type in the viewport unlinks it but the row keeps it: Pack used to pack
    the deleted object."""
    box = cube_object(bpy, "Box", scale=(3.0, 3.0, 3.0))
    ico = _ico(bpy, "Ico")
    _settings(bpy, box, [ico])
    bpy.context.view_layer.objects.active = ico
    for obj in bpy.context.selected_objects:
        obj.select_set(False)
    ico.select_set(True)
    with bpy.context.temp_override(selected_objects=[ico], active_object=ico):
        bpy.ops.object.delete()
    assert bpy.context.scene.jampacked.types[0].object is None or not ico.users_scene
    with pytest.raises(RuntimeError, match="'Ico' is in no scene|object type 1 has no "
                                           "object"):
        bpy.ops.jampacked.pack()
    # the deletion the operator does not do in every version: unlinked, still referenced
    ico = _ico(bpy, "Ico2")
    bpy.context.scene.jampacked.types[0].object = ico
    bpy.context.scene.collection.objects.unlink(ico)
    with pytest.raises(RuntimeError, match=r"Object type 1 'Ico2' is in no scene"):
        bpy.ops.jampacked.pack()


def test_edits_in_edit_mode_are_read(bpy, addon):
    """A type being edited is packed as the viewport shows it (the evaluated mesh follows
    the edit), not as its mesh data was on entering edit mode; the result's objects are
    what was packed (they were made from the mesh data as it was: a flattened type gave
    overlapping full-size objects under a "certified" result)."""
    box = cube_object(bpy, "Box", scale=(3.0, 3.0, 3.0))
    ico = _ico(bpy, "Ico")
    s = _settings(bpy, box, [ico])
    try:
        scale_in_edit_mode(bpy, ico, 0.5)
        request = addon.bridge.gather_pack(bpy.context)
        assert bpy.ops.jampacked.pack() == {'FINISHED'}
        assert ico.mode == 'EDIT'  # the artist's edit goes on
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
    extent = np.ptp(request.types[0].vertices, axis=0)
    assert extent.max() == pytest.approx(1.0, rel=0.1)  # radius 1 scaled by 0.5
    placed = [o for o in s.result.objects if o.type == 'MESH']
    assert placed
    local = np.array([v.co for v in placed[0].data.vertices])
    assert np.ptp(local, axis=0).max() * placed[0].scale[0] == pytest.approx(extent.max(),
                                                                         rel=1e-4)


def test_messages_for_objects_without_a_surface(bpy, addon):
    """Flat curves and text, meshes without faces and collection instances are named with
    what to do in Blender (they were 'not a mesh object' or a message about files)."""
    box = cube_object(bpy, "Box", scale=(3.0, 3.0, 3.0))
    s = _settings(bpy, box, [_curve(bpy, "Label", bevel=0.0, text=True)])
    with pytest.raises(RuntimeError, match="'Label' is a flat text with no volume: give it "
                                           "depth"):
        bpy.ops.jampacked.pack()
    s.types[0].object = _arrays([(0, 0, 0), (1, 0, 0)], [], [(0, 1)])(bpy, "Wire", None)
    with pytest.raises(RuntimeError, match=r"'Wire' has no faces \(2 vertices"):
        bpy.ops.jampacked.pack()
    s.types[0].object = _instance(bpy, "Group", None)
    with pytest.raises(RuntimeError, match="'Group' is an instance of the collection 'Group "
                                           "source'"):
        bpy.ops.jampacked.pack()


def test_curves_can_be_picked_and_added(bpy, addon):
    """The pickers and the + button take objects Pack can read: curves, text, metaballs."""
    curve = _curve(bpy, "Rod", bevel=0.5)
    camera = _no_data('CAMERA')(bpy, "Cam", None)
    s = bpy.context.scene.jampacked
    assert addon.props.is_mesh_object(s, curve)
    assert not addon.props.is_mesh_object(s, camera)
    for obj in (curve, camera):
        obj.select_set(True)
    with bpy.context.temp_override(selected_objects=[curve, camera]):
        assert bpy.ops.jampacked.type_add() == {'FINISHED'}
    assert [item.object for item in s.types] == [curve]


def test_a_placed_object_picked_as_a_type_survives_the_next_pack(bpy, addon):
    """A placed object of a result, picked as a type, is an input: the next Pack keeps the
    result that holds it (replacing it deleted the user's type object)."""
    box = cube_object(bpy, "Box", scale=(3.0, 3.0, 3.0))
    s = _settings(bpy, box, [_ico(bpy, "Ico")])
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    first = s.result
    placed = sorted(first.objects, key=lambda o: o.name)[0]
    name = placed.name
    s.types[0].object = placed
    s.seed = 4
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    assert bpy.data.objects.get(name) is not None and s.types[0].object.name == name
    assert first.name in bpy.context.scene.collection.children and s.result != first
    # without such an input, the earlier results are replaced as before
    s.types[0].object = bpy.data.objects["Ico"]
    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    assert [c.name for c in bpy.context.scene.collection.children
            if "jampacked_packing" in c.keys()] == ["Jampacked Box"] == [s.result.name]


def test_the_add_button_says_why_it_added_nothing(bpy, addon):
    # an object already listed, or a collection-instance empty, gave a blank row and no word
    ico = _ico(bpy, "Ico")
    group = bpy.data.objects.new("Group", None)
    group.instance_type = 'COLLECTION'
    group.instance_collection = bpy.data.collections.new("Group source")
    bpy.context.scene.collection.objects.link(group)
    s = bpy.context.scene.jampacked
    s.types.add().object = ico
    with bpy.context.temp_override(selected_objects=[ico, group]):
        assert bpy.ops.jampacked.type_add() == {'CANCELLED'}
    assert [item.object for item in s.types] == [ico]  # no blank row
    with bpy.context.temp_override(selected_objects=[]):
        assert bpy.ops.jampacked.type_add() == {'FINISHED'}  # nothing selected: a row to fill
    assert len(s.types) == 2 and s.types[1].object is None
