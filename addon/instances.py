"""Instanced results: one points object drawn by a Geometry Nodes modifier, and Make Real.

An instanced result holds, instead of one object per placement, a mesh object of loose
points ("Jampacked <container> instances"), one point per placement at its translation
(container frame = world space, Blender units), carrying as point attributes:

- ``jampacked_type`` (INT): the type index (order of the packing's types);
- ``jampacked_rotation`` (QUATERNION, w x y z): the placement's rotation;
- ``jampacked_scale`` (FLOAT): its uniform scale;
- ``jampacked_index`` (INT): the placement's index in the packing (names of real objects).

Its Geometry Nodes modifier ("Jampacked Instances" group) puts on each point an instance of
its type's prototype: Instance on Points with Pick Instance, the instance list made by
Geometry to Instance from one Object Info (As Instance, original space) per type. The
prototypes are objects linked to no collection (the node group keeps them, and they are
saved with the .blend) whose data is the type's shared mesh, in the type's local frame, so
each instance's world matrix is the packing's matrix [R * s | t], as for object results.

Everything here runs on Blender's main thread; the arrays come from the packing.
"""

from collections.abc import Sequence
from typing import Any

import bpy
import numpy as np

from . import summary

#: custom property of the points object (and of the collection: the result's kind)
POINTS_KEY = "jampacked_instances"
KIND_KEY = summary.PREFIX + "result_kind"
TYPE_ATTR = "jampacked_type"
ROTATION_ATTR = "jampacked_rotation"
SCALE_ATTR = "jampacked_scale"
INDEX_ATTR = "jampacked_index"
#: custom property of the points object: every placement in double precision, 9 numbers
#: each (rotation w x y z, translation, scale, type), for Make Real to place objects exactly
#: as an object result does (the points hold single precision)
PLACEMENTS_KEY = "jampacked_placements"
PLACEMENT_WIDTH = 9
#: custom property of a prototype object: its type index
PROTOTYPE_KEY = "jampacked_prototype"
#: node group of the modifier (one per result, since it names that result's prototypes)
GROUP_NAME = "Jampacked Instances"


def use_instances(kind: str, threshold: int, count: int) -> bool:
    """Whether a result of ``count`` placements is instanced: 'INSTANCES' always,
    'OBJECTS' never, 'AUTO' from ``threshold`` placements on."""
    if kind == 'INSTANCES':
        return True
    if kind == 'OBJECTS':
        return False
    return count >= threshold


def write_points(mesh: bpy.types.Mesh, translations: np.ndarray, rotations: np.ndarray,
                 scales: np.ndarray, types: np.ndarray, indices: np.ndarray) -> None:
    """Replace the mesh's geometry with loose points carrying the placement attributes
    (translations (N, 3), rotations (N, 4) w x y z, scales (N,), types and indices (N,))."""
    n = len(translations)
    mesh.clear_geometry()
    for name in (TYPE_ATTR, ROTATION_ATTR, SCALE_ATTR, INDEX_ATTR):
        if name in mesh.attributes:
            mesh.attributes.remove(mesh.attributes[name])
    mesh.vertices.add(n)
    mesh.vertices.foreach_set("co", np.asarray(translations, np.float32).reshape(-1))
    mesh.vertices.foreach_set("select", np.zeros(n, bool))  # added vertices come selected
    for name, kind, key, values in (
            (TYPE_ATTR, 'INT', "value", np.asarray(types, np.int32)),
            (INDEX_ATTR, 'INT', "value", np.asarray(indices, np.int32)),
            (ROTATION_ATTR, 'QUATERNION', "value", np.asarray(rotations, np.float32)),
            (SCALE_ATTR, 'FLOAT', "value", np.asarray(scales, np.float32))):
        attr = mesh.attributes.new(name, kind, 'POINT')
        attr.data.foreach_set(key, values.reshape(-1))
    mesh.update()


def missing_attributes(mesh: bpy.types.Mesh) -> list[str]:
    """The placement attributes the points' mesh lacks (a script or the Attributes panel
    removed them, or the geometry was cleared)."""
    return [name for name in (TYPE_ATTR, INDEX_ATTR, ROTATION_ATTR, SCALE_ATTR)
            if name not in mesh.attributes]


def read_points(mesh: bpy.types.Mesh) -> dict[str, np.ndarray]:
    """The points' arrays: ``translations``, ``rotations``, ``scales``, ``types``,
    ``indices`` and ``selected`` (the Edit Mode selection, as last left in Object Mode).
    Raises InputError, naming the mesh, where a placement attribute is gone."""
    missing = missing_attributes(mesh)
    if missing:
        from jampacked.core.errors import InputError

        raise InputError(f"the instances' points ('{mesh.name}') lack their attribute"
                         f"{'s' if len(missing) > 1 else ''} {', '.join(missing)}, which "
                         "hold where each object goes: undo their removal, or pack again.")
    n = len(mesh.vertices)
    out: dict[str, np.ndarray] = {}
    co = np.empty(n * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    out["translations"] = co.reshape(-1, 3)
    sel = np.zeros(n, bool)
    mesh.vertices.foreach_get("select", sel)
    out["selected"] = sel
    for key, name, dtype, width in (("types", TYPE_ATTR, np.int32, 1),
                                    ("indices", INDEX_ATTR, np.int32, 1),
                                    ("rotations", ROTATION_ATTR, np.float32, 4),
                                    ("scales", SCALE_ATTR, np.float32, 1)):
        values = np.empty(n * width, dtype)
        mesh.attributes[name].data.foreach_get("value", values)
        out[key] = values.reshape(-1, width) if width > 1 else values
    return out


def _node_group(name: str, prototypes: Sequence[bpy.types.Object]) -> bpy.types.NodeTree:
    """Points in, instances out: Instance on Points picks the prototype of each point's type
    and gives it the point's rotation and scale."""
    group = bpy.data.node_groups.new(name, 'GeometryNodeTree')
    group.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
    group.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    nodes, links = group.nodes, group.links
    gin = nodes.new('NodeGroupInput')
    gout = nodes.new('NodeGroupOutput')
    on_points = nodes.new('GeometryNodeInstanceOnPoints')
    on_points.inputs["Pick Instance"].default_value = True
    to_instance = nodes.new('GeometryNodeGeometryToInstance')
    # a multi-input socket lists its newest link first: link the last type first so that
    # instance i is type i (the tests check the instanced types)
    for i, proto in reversed(list(enumerate(prototypes))):
        info = nodes.new('GeometryNodeObjectInfo')
        info.transform_space = 'ORIGINAL'
        info.inputs["Object"].default_value = proto
        info.inputs["As Instance"].default_value = True
        info.location = (-600, -200 * i)
        links.new(info.outputs["Geometry"], to_instance.inputs["Geometry"])
    for socket, attr, data_type in (("Instance Index", TYPE_ATTR, 'INT'),
                                    ("Rotation", ROTATION_ATTR, 'QUATERNION'),
                                    ("Scale", SCALE_ATTR, 'FLOAT')):
        named = nodes.new('GeometryNodeInputNamedAttribute')
        named.data_type = data_type
        named.inputs["Name"].default_value = attr
        links.new(named.outputs["Attribute"], on_points.inputs[socket])
    links.new(gin.outputs[0], on_points.inputs["Points"])
    links.new(to_instance.outputs[0], on_points.inputs["Instance"])
    links.new(on_points.outputs["Instances"], gout.inputs[0])
    gin.location, to_instance.location, on_points.location, gout.location = \
        (-400, 200), (-300, -100), (0, 0), (300, 0)
    return group


def build(coll: bpy.types.Collection, name: str, packing: Any,
          meshes: Sequence[bpy.types.Mesh], colours: Sequence[Sequence[float]],
          created: list[Any]) -> bpy.types.Object:
    """Add the instanced form of ``packing`` to ``coll``: prototypes of the type ``meshes``
    (in the types' local frames), the points object and its modifier. Everything made is
    appended to ``created`` (for the caller to remove on failure). Returns the points
    object."""
    prototypes = []
    for t, (mesh, colour) in enumerate(zip(meshes, colours, strict=True)):
        proto = bpy.data.objects.new(mesh.name, mesh)
        created.append(proto)
        proto[PROTOTYPE_KEY] = t
        proto.color = colour
        prototypes.append(proto)
    group = _node_group(f"{GROUP_NAME} {name}", prototypes)
    created.append(group)
    points_mesh = bpy.data.meshes.new(f"Jampacked {name} instances")
    created.append(points_mesh)
    write_points(points_mesh, packing.translations, packing.rotations, packing.scales,
                 packing.type_index, np.arange(packing.n))
    obj = bpy.data.objects.new(points_mesh.name, points_mesh)
    created.append(obj)
    obj[POINTS_KEY] = True
    obj[PLACEMENTS_KEY] = np.concatenate(
        [packing.rotations, packing.translations, np.reshape(packing.scales, (-1, 1)),
         np.reshape(packing.type_index, (-1, 1))], axis=1).astype(np.float64).reshape(-1)
    modifier = obj.modifiers.new("Jampacked Instances", 'NODES')
    modifier.node_group = group
    coll.objects.link(obj)
    coll[KIND_KEY] = "instances"
    return obj


def points_object(coll: bpy.types.Collection) -> bpy.types.Object | None:
    """The points object of an instanced result (None for an object result)."""
    for obj in coll.objects:
        if POINTS_KEY in obj.keys() and obj.type == 'MESH':
            return obj
    return None


def prototypes(obj: bpy.types.Object) -> list[bpy.types.Object]:
    """The prototype objects the points object's modifier instances."""
    out = []
    for modifier in obj.modifiers:
        if modifier.type == 'NODES' and modifier.node_group is not None:
            for node in modifier.node_group.nodes:
                if node.bl_idname == 'GeometryNodeObjectInfo':
                    proto = node.inputs["Object"].default_value
                    if proto is not None and PROTOTYPE_KEY in proto.keys():
                        out.append(proto)
    return out


def remove(obj: bpy.types.Object) -> None:
    """Remove a points object with its mesh, node group and prototypes (the type meshes
    stay: the caller removes them once unused)."""
    mesh = obj.data
    groups = [m.node_group for m in obj.modifiers
              if m.type == 'NODES' and m.node_group is not None]
    protos = prototypes(obj)
    bpy.data.objects.remove(obj)
    if mesh is not None and not mesh.users:
        bpy.data.meshes.remove(mesh)
    for group in groups:
        if not group.users:
            bpy.data.node_groups.remove(group)
    for proto in protos:
        if not proto.users:
            bpy.data.objects.remove(proto)


def rename(obj: bpy.types.Object, name: str) -> None:
    """Give the points object, its mesh, node group and prototypes the names of a result
    of container ``name`` (after the previous result was removed)."""
    obj.name = obj.data.name = f"Jampacked {name} instances"
    for proto in prototypes(obj):
        proto.name = proto.data.name
    for modifier in obj.modifiers:
        if modifier.type == 'NODES' and modifier.node_group is not None:
            modifier.node_group.name = f"{GROUP_NAME} {name}"


def placements(obj: bpy.types.Object) -> np.ndarray | None:
    """(N, 9) placements of the points object (see :data:`PLACEMENTS_KEY`), None if the
    property is missing or not a whole number of placements."""
    values = obj.get(PLACEMENTS_KEY)
    if values is None:
        return None
    arr = np.asarray(values, np.float64).reshape(-1)
    if len(arr) % PLACEMENT_WIDTH:
        return None
    return arr.reshape(-1, PLACEMENT_WIDTH)


def pick(points: dict[str, np.ndarray], which: str, type_index: int = -1) -> np.ndarray:
    """Mask of the points to make real: 'ALL', 'SELECTED' (the Edit Mode selection) or
    'TYPE' (those of ``type_index``)."""
    if which == 'ALL':
        return np.ones(len(points["types"]), bool)
    if which == 'SELECTED':
        return points["selected"].copy()
    if which == 'TYPE':
        return points["types"] == type_index
    raise ValueError(f"unknown choice {which!r}: ALL, SELECTED or TYPE")


def drop_points(obj: bpy.types.Object, mask: np.ndarray) -> None:
    """Remove the masked points from the points object (they became real objects)."""
    points = read_points(obj.data)
    keep = ~mask
    write_points(obj.data, points["translations"][keep], points["rotations"][keep],
                 points["scales"][keep], points["types"][keep], points["indices"][keep])
