"""Blender <-> arrays: read objects as world-space triangles, turn packings into objects.

Frames (Blender units throughout):
- inputs are evaluated meshes (modifiers applied) in world space, triangulated with
  Blender's loop triangles; the packing's container frame is therefore world space;
- a type's "file" frame is its object's world space at packing time; the engine's
  ``local_from_file`` L moves it to the type's local frame (volume centroid at the origin);
- results: one mesh per type, made from the type object with modifiers applied and moved
  into the local frame (vertices ``L @ W @ v``, W the source's world matrix), shared by every
  placement of the type; each placement is an object with ``matrix_world`` = the packing's
  matrix [R | t] (rotation quaternion and location set exactly), or, for an instanced
  result (:mod:`.instances`), a point with the same rotation, location and scale.

Everything here runs on Blender's main thread.
"""

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import bpy
import numpy as np
from mathutils import Matrix

from . import instances, result_edits, results, summary, units
from .engine import PackOutcome, Triangles, check_extent, is_inward


def _input_error(message: str) -> Exception:
    from jampacked.core.errors import InputError

    return InputError(message)


def matrix_np(matrix: Matrix) -> np.ndarray:
    """A mathutils 4x4 matrix as a float64 numpy array (rows are rows)."""
    return np.array([list(row) for row in matrix], dtype=np.float64)


def _mesh_arrays(mesh: bpy.types.Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    mesh.calc_loop_triangles()
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    tris = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    poly = np.empty(len(mesh.loop_triangles), np.int32)
    mesh.loop_triangles.foreach_get("polygon_index", poly)
    return (co.reshape(-1, 3).astype(np.float64), tris.reshape(-1, 3).astype(np.int64),
            poly.astype(np.int64))


def _transform(vertices: np.ndarray, m: np.ndarray) -> np.ndarray:
    return vertices @ m[:3, :3].T + m[:3, 3]


def mesh_triangles(mesh: bpy.types.Mesh, name: str,
                   transform: np.ndarray | None = None) -> Triangles:
    """Triangles of a mesh datablock, optionally transformed by a 4x4 matrix."""
    v, f, poly = _mesh_arrays(mesh)
    if transform is not None:
        v = _transform(v, transform)
    return Triangles(name=name, vertices=v, faces=f, tri_polygon=poly,
                     n_polygons=len(mesh.polygons))


def object_triangles(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph, *,
                     apply_modifiers: bool = True, world: bool = True,
                     outward: bool = False) -> Triangles:
    """An object's surface as triangles: evaluated (modifiers applied) and in world space by
    default.

    The object must have geometry (:data:`GEOMETRY_TYPES`; curves, text, surfaces and
    metaballs give the mesh Blender shows). In world space a transform that mirrors (an odd
    number of negative scale factors) reverses the triangles' winding; with ``outward`` they
    are re-wound to face as Blender shows and exports them (Pack's and Validate's inputs);
    without it they keep the mesh's winding.
    """
    if not apply_modifiers and obj.type == 'MESH':
        m = matrix_np(obj.matrix_world) if world else None
        return _rewound(mesh_triangles(obj.data, obj.name, m), m, outward)
    ob_eval = obj.evaluated_get(depsgraph)
    mesh = ob_eval.to_mesh()
    try:
        m = matrix_np(ob_eval.matrix_world) if world else None
        return _rewound(mesh_triangles(mesh, obj.name, m), m, outward)
    finally:
        ob_eval.to_mesh_clear()


def _rewound(tris: Triangles, transform: np.ndarray | None, outward: bool) -> Triangles:
    """Reverse the winding when asked and ``transform`` mirrors (negative determinant)."""
    if outward and transform is not None and np.linalg.det(transform[:3, :3]) < 0:
        tris.faces = np.ascontiguousarray(tris.faces[:, ::-1])
    return tris


#: object types whose evaluated geometry is a surface Blender can turn into a mesh, with the
#: words messages use for them
GEOMETRY_TYPES = {'MESH': "mesh", 'CURVE': "curve", 'SURFACE': "surface", 'META': "metaball",
                  'FONT': "text"}


def _require_mesh(obj: bpy.types.Object | None, what: str,
                  scene: bpy.types.Scene) -> bpy.types.Object:
    """The object if Pack can read a surface from it in ``scene``, else InputError naming
    it."""
    if obj is None:
        raise _input_error(f"pick a {what}: a closed mesh object (Jampacked panel in the 3D "
                           "viewport's sidebar).")
    if obj.type not in GEOMETRY_TYPES:
        if obj.instance_type == 'COLLECTION' and obj.instance_collection is not None:
            raise _input_error(
                f"{what} '{obj.name}' is an instance of the collection "
                f"'{obj.instance_collection.name}', not a mesh: pick a mesh object in that "
                "collection, or make the instance real first (Object > Apply > Make "
                "Instances Real) and join the parts into one mesh.")
        raise _input_error(f"{what} '{obj.name}' is not a mesh object (its type is "
                           f"{obj.type.title()}), it has no surface: pick a mesh object (or "
                           "a curve, text, surface or metaball with volume).")
    if not obj.users_scene:
        raise _input_error(f"{what} '{obj.name}' is in no scene (it was deleted): pick an "
                           "object of the scene, or bring it back with undo.")
    if scene not in obj.users_scene[:]:
        # another scene's depsgraph holds its transform and modifiers: this one has neither
        others = ", ".join(f"'{sc.name}'" for sc in obj.users_scene)
        raise _input_error(f"{what} '{obj.name}' is not in this scene ('{scene.name}'), only "
                           f"in {others}: link it into this scene (Object > Link/Transfer "
                           "Data > Link Objects to Scene) or pick an object of this scene.")
    return obj


def _flat_curve(obj: bpy.types.Object) -> bool:
    """A curve or text object with no depth: no extrusion, bevel or modifier to give it one."""
    if obj.type not in {'CURVE', 'FONT'} or obj.modifiers:
        return False
    data = obj.data
    return (data.extrude == 0 and data.bevel_depth == 0
            and not (data.bevel_mode == 'OBJECT' and data.bevel_object is not None))


def _geometry_evaluated(obj: bpy.types.Object, view_layer: bpy.types.ViewLayer) -> bool:
    """Whether Blender evaluates the object's geometry (modifiers, curves to mesh) in the view
    layer: it is not disabled in viewports and lies in a collection that is neither
    excluded nor disabled in viewports. Hidden objects (H, the eye icon) are evaluated.

    ``evaluated_get`` cannot tell: an object the add-on's settings point to is in the
    depsgraph even when its geometry is not evaluated (it then gives the bare mesh).
    """
    if obj.hide_viewport:
        return False

    def walk(layer: bpy.types.LayerCollection) -> bool:
        if layer.exclude or layer.collection.hide_viewport:
            return False
        if obj.name in layer.collection.objects:
            return layer.collection.objects[obj.name] == obj
        return any(walk(child) for child in layer.children)

    return walk(view_layer.layer_collection)


def _instance_count(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> int:
    """How many instances with a surface the object's evaluated geometry draws beyond what
    ``to_mesh`` reads (Geometry Nodes instances not realized, particles, vertex or face
    instancing). A curve or text object with Geometry Nodes draws its own surface as one
    instance, which ``to_mesh`` does read; instances without faces (points, curves) have
    no surface to leave out."""
    if obj.instance_type == 'NONE' and not any(
            m.type in {'NODES', 'PARTICLE_SYSTEM'} for m in obj.modifiers):
        return 0  # nothing can instance: the scene's instances need not be walked
    surfaces = sum(1 for inst in depsgraph.object_instances
                   if inst.is_instance and inst.parent is not None
                   and inst.parent.original == obj.original
                   and inst.object.type == 'MESH' and len(inst.object.data.polygons))
    return max(0, surfaces - (obj.type != 'MESH'))


def unevaluated(obj: bpy.types.Object, view_layer: bpy.types.ViewLayer) -> bool:
    """Whether what Blender shows of the object is not what its mesh data holds (modifiers,
    shape keys, a curve's surface) and Blender does not evaluate it in ``view_layer``
    (:func:`_geometry_evaluated`): reading it would silently give the bare mesh."""
    stored_is_shown = (obj.type == 'MESH' and not any(m.show_viewport for m in obj.modifiers)
                       and obj.data.shape_keys is None)
    return not stored_is_shown and not _geometry_evaluated(obj, view_layer)


def require_evaluated(obj: bpy.types.Object, what: str, view_layer: bpy.types.ViewLayer,
                      reader: str) -> None:
    """InputError naming the object where it is :func:`unevaluated`. ``reader`` names who
    reads it ("Pack", "Export", "Validate")."""
    if not unevaluated(obj, view_layer):
        return
    read = ("its modifiers" if obj.type == 'MESH'
            else f"its {GEOMETRY_TYPES[obj.type]} as a surface")
    raise _input_error(
        f"{what} '{obj.name}' is disabled in viewports or in an excluded or disabled "
        f"collection, so Blender does not evaluate {read}: enable it (to keep it out of "
        f"sight hide it with H instead, which {reader} can read), or apply its modifiers.")


def _refuse_flattened(obj: bpy.types.Object, what: str) -> None:
    """Refuse an object flattened by a Scale (or Delta Scale) of 0 along an axis, its own or
    a parent's, naming that Scale, not the mesh (the engine would say its mesh has no
    volume, as of a file)."""
    holder = obj
    while holder is not None and all(x != 0 for x in (*holder.scale, *holder.delta_scale)):
        holder = holder.parent
    if holder is None:
        return
    whose = "its Scale" if holder == obj else f"the Scale of its parent '{holder.name}'"
    scale = " x ".join(f"{x:.3g}" for x in holder.scale)
    if all(x != 0 for x in holder.scale):
        whose, scale = whose.replace("Scale", "Delta Scale"), " x ".join(
            f"{x:.3g}" for x in holder.delta_scale)
    raise _input_error(
        f"{what} '{obj.name}' is flattened by {whose} ({scale}): with no thickness it has no "
        "volume. Give that Scale a value other than 0 on every axis (sidebar > Item; Delta "
        "Scale under Object Properties > Transform > Delta Transform).")


def read_input(obj: bpy.types.Object, what: str,
               depsgraph: bpy.types.Depsgraph) -> Triangles:
    """World-space triangles of a Pack input (container or type), modifiers applied.

    Raises InputError naming the object when Blender does not evaluate it (disabled in
    viewports or in an excluded collection: its modifiers would be silently left out), when
    it is a curve or text with no depth, when it has no faces at all, or when its size is
    absurd (:func:`.engine.check_extent`).
    """
    require_evaluated(obj, what, depsgraph.view_layer, "Pack")
    _refuse_flattened(obj, what)
    if _flat_curve(obj):
        raise _input_error(
            f"{what} '{obj.name}' is a flat {GEOMETRY_TYPES[obj.type]} with no volume: give "
            "it depth (Object Data Properties > Geometry > Extrude or Bevel Depth), or "
            "convert it to a closed mesh.")
    instanced = _instance_count(obj, depsgraph)
    if instanced:
        nodes = [m.name for m in obj.modifiers if m.type == 'NODES']
        fix = (f"add a Realize Instances node at the end of its Geometry Nodes modifier "
               f"'{nodes[-1]}', or apply it (Object > Apply > Visual Geometry to Mesh)"
               if nodes else "make them real (Object > Apply > Make Instances Real) and "
               "join them into one mesh, or turn its instancing off")
        raise _input_error(
            f"{what} '{obj.name}' draws {instanced} instance(s), which Pack cannot read as "
            f"part of its surface (it would pack the object without them): {fix}.")
    tris = object_triangles(obj, depsgraph, outward=True)
    tris.modifiers = tuple(m.name for m in obj.modifiers if m.show_viewport)
    if not len(tris.faces):
        raise _input_error(
            f"{what} '{obj.name}' has no faces ({len(tris.vertices)} vertices, only loose "
            "vertices or edges, or nothing at all): pick a closed mesh, or fill it (Edit "
            "Mode: select all, Face > Fill or Convex Hull).")
    check_extent(tris, what)
    return tris


# ------------------------------------------------------------------------------ pack


@dataclass
class PackRequest:
    """Everything a pack job needs, read from the scene on the main thread."""

    container_name: str
    type_names: list[str]
    container: Triangles
    types: list[Triangles]
    shares: list[float]
    seed: int
    clearance: float
    fidelity: str
    time_budget: float | None
    mix_tolerance: float
    signatures: list[str] = field(default_factory=list)


def flush_edit_mode(context: bpy.types.Context) -> None:
    """Write the edits of every object in Edit Mode to its data (it stays in Edit Mode), so
    that every reader sees what the viewport shows: the evaluated mesh Pack reads follows
    the edit, while the mesh data (the result's type meshes, what Export reads) held the
    mesh as it was on entering Edit Mode."""
    if context.view_layer is None or not context.mode.startswith('EDIT'):
        return
    for obj in context.view_layer.objects:
        if obj.mode == 'EDIT':
            obj.update_from_editmode()


def gather_pack(context: bpy.types.Context) -> PackRequest:
    """Read the Jampacked settings and the input meshes (world space, modifiers applied).

    Raises InputError with a message that names the object and says what to do.
    """
    flush_edit_mode(context)
    s = context.scene.jampacked
    container = _require_mesh(s.container, "container", context.scene)
    if not len(s.types):
        raise _input_error("add at least one object type (the + button under Object Types), "
                           "then pick a mesh object for it.")
    objects: list[bpy.types.Object] = []
    shares: list[float] = []
    for i, item in enumerate(s.types):
        obj = item.object
        if obj is None:
            raise _input_error(f"object type {i + 1} has no object: pick a mesh object for "
                               "it or remove the row.")
        _require_mesh(obj, f"object type {i + 1}", context.scene)
        if obj == container:
            raise _input_error(f"'{obj.name}' is both the container and object type {i + 1}: "
                               "pick different objects.")
        if obj in objects:
            raise _input_error(f"'{obj.name}' is listed twice as an object type: remove one "
                               "row and raise the other's share instead.")
        objects.append(obj)
        shares.append(float(item.share))
    if sum(shares) <= 0:
        raise _input_error("every object type has share 0: give at least one a share above "
                           "0.")
    depsgraph = context.evaluated_depsgraph_get()
    ctris = read_input(container, "container", depsgraph)
    ttris = [read_input(o, f"object type {i + 1}", depsgraph)
             for i, o in enumerate(objects)]
    return PackRequest(
        container_name=container.name, type_names=[o.name for o in objects],
        container=ctris, types=ttris, shares=shares, seed=int(s.seed),
        clearance=float(s.clearance), fidelity=s.fidelity.lower(),
        time_budget=float(s.time_budget) if s.time_budget > 0 else None,
        mix_tolerance=float(s.mix_tolerance),
        signatures=[t.signature() for t in [ctris, *ttris]])


def check_unchanged(context: bpy.types.Context, request: PackRequest) -> None:
    """Raise InputError if an input object was deleted, moved or edited during the job (the
    result would not match the scene)."""
    depsgraph = context.evaluated_depsgraph_get()
    names = [request.container_name, *request.type_names]
    for name, signature in zip(names, request.signatures, strict=True):
        obj = bpy.data.objects.get(name)
        if obj is None or obj.type not in GEOMETRY_TYPES or not obj.users_scene:
            raise _input_error(f"'{name}' was deleted or renamed while packing: nothing was "
                               "added; pack again.")
        if unevaluated(obj, context.view_layer):
            raise _input_error(
                f"'{name}' was disabled in viewports while packing, so Blender no longer "
                "evaluates its modifiers and the result cannot be checked against it: "
                "nothing was added; enable it and pack again (hide it with H instead, "
                "which Pack can read).")
        if object_triangles(obj, depsgraph, outward=True).signature() != signature:
            raise _input_error(f"'{name}' was moved or edited while packing: nothing was "
                               "added; pack again.")


def inputs_in_results(scene: bpy.types.Scene, request: PackRequest) -> list[str]:
    """Names of the request's input objects that belong to an earlier result of its
    container: replacing that result would delete them (keep it instead)."""
    names = {request.container_name, *request.type_names}
    return sorted({o.name for c in results.previous_results(scene, request.container_name)
                   for o in c.objects if o.name in names})


def _type_material(name: str, colour: tuple[float, float, float, float]
                   ) -> bpy.types.Material:
    mat = bpy.data.materials.new(f"Jampacked {name}")
    mat.diffuse_color = colour
    try:  # node-based look for the renderers; the viewport uses diffuse_color
        mat.use_nodes = True
        bsdf = mat.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Base Color"].default_value = colour
    except (AttributeError, KeyError, TypeError):
        pass
    return mat


def _set_descriptions(coll: bpy.types.Collection) -> None:
    for key, text in summary.DESCRIPTIONS.items():
        full = summary.PREFIX + key
        if full in coll.keys():
            try:
                coll.id_properties_ui(full).update(description=text)
            except TypeError:  # lists/strings without UI data in some versions
                pass


def place_object(coll: bpy.types.Collection, name: str, t: int, index: int, rotation: Any,
                 translation: Any, scale: float, mesh: bpy.types.Mesh,
                 colour: tuple[float, float, float, float]) -> bpy.types.Object:
    """An object of type ``t`` sharing the type's ``mesh``, at the packing's matrix of
    placement ``index``: the rotation quaternion (w x y z), location and uniform scale set
    exactly; linked to ``coll``."""
    obj = bpy.data.objects.new(name, mesh)
    obj.rotation_mode = 'QUATERNION'
    obj.rotation_quaternion = [float(x) for x in rotation]
    obj.location = [float(x) for x in translation]
    obj.scale = [float(scale)] * 3
    obj.color = colour
    obj["jampacked_type"] = t
    obj[result_edits.INDEX_KEY] = index
    coll.objects.link(obj)
    return obj


def build_result(context: bpy.types.Context, request: PackRequest,
                 outcome: PackOutcome) -> bpy.types.Collection:
    """Create the result collection: one shared mesh and material per type, one object per
    placement at the packing's matrix (or, when the settings ask for instances, one points
    object that instances the type meshes: :mod:`.instances`), metrics and the packing JSON
    as custom properties.

    On any failure everything created is removed again and the exception re-raised, so the
    scene is as it was.
    """
    packing = outcome.packing
    created: list[Any] = []
    try:
        coll = bpy.data.collections.new(f"Jampacked {request.container_name}")
        created.append(coll)
        depsgraph = context.evaluated_depsgraph_get()
        meshes = []
        signatures = []  # each type mesh's, as Export reads it
        for t, (obj_name, rec) in enumerate(zip(request.type_names, packing.types,
                                                strict=True)):
            source = bpy.data.objects[obj_name].evaluated_get(depsgraph)
            mesh = bpy.data.meshes.new_from_object(source, preserve_all_data_layers=True,
                                                   depsgraph=depsgraph)
            created.append(mesh)
            mesh.name = f"Jampacked {rec.name}"
            to_local = rec.local_from_file @ matrix_np(source.matrix_world)
            mesh.transform(Matrix(to_local.tolist()))
            # outward as the engine packed it: a mirroring transform, or a mesh modelled
            # inside out (the engine turns it with a warning), leaves it inward
            if is_inward(mesh_triangles(mesh, mesh.name)):
                mesh.flip_normals()
            colour = summary.type_colour(t)
            if not len(mesh.materials):
                mat = _type_material(rec.name, colour)
                created.append(mat)
                mesh.materials.append(mat)
            mesh.update()
            meshes.append((mesh, colour))
            signatures.append(mesh_triangles(mesh, rec.name,
                                             np.linalg.inv(rec.local_from_file)).signature())
        s = context.scene.jampacked
        if instances.use_instances(s.result_kind, s.instance_threshold, packing.n):
            instances.build(coll, request.container_name, packing, [m for m, _ in meshes],
                            [c for _, c in meshes], created)
        else:
            for i in range(packing.n):
                t = int(packing.type_index[i])
                created.append(place_object(
                    coll, f"{packing.types[t].name} {i + 1}", t, i, packing.rotations[i],
                    packing.translations[i], packing.scales[i], *meshes[t]))
            coll[instances.KIND_KEY] = "objects"
        props = summary.collection_properties(packing)
        for key, value in props.items():
            coll[summary.PREFIX + key] = value
        coll[summary.PREFIX + "packing"] = outcome.json_text
        coll[summary.PREFIX + "container"] = request.container_name
        coll[summary.PREFIX + "container_object"] = bpy.data.objects[request.container_name]
        coll[summary.PREFIX + "container_sha256"] = request.signatures[0]
        coll[summary.PREFIX + "type_objects"] = list(request.type_names)
        coll[summary.PREFIX + "type_meshes"] = [m.name for m, _ in meshes]
        coll[summary.PREFIX + "type_sha256"] = signatures
        _set_descriptions(coll)
        context.scene.collection.children.link(coll)
        context.scene.jampacked.result = coll
    except BaseException:
        _remove(created)
        raise
    return coll


def _remove(ids: list[Any]) -> None:
    """Remove datablocks created by a failed build, newest first."""
    for block in reversed(ids):
        for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials,
                     bpy.data.node_groups, bpy.data.collections):
            try:
                if block.name in coll and coll[block.name] == block:
                    coll.remove(block)
                    break
            except ReferenceError:
                break


def make_real(coll: bpy.types.Collection, which: str, type_index: int = -1
              ) -> list[bpy.types.Object]:
    """Turn instances of an instanced result into objects that share the type meshes, where
    the instances are drawn: an instance still at its placement is placed exactly as an
    object result places it (the points object's double-precision placements, not the
    points' single precision); one moved with the points object or its point, at its drawn
    matrix. Their points are removed, and the points object with the last of them.
    ``which``: 'ALL', 'SELECTED' (points selected in Edit Mode) or 'TYPE' (the instances of
    type ``type_index``). Returns the new objects."""
    obj = instances.points_object(coll)
    if obj is None:
        raise _input_error(f"'{coll.name}' has no instances: its objects are real already.")
    names = [str(n) for n in coll.get(summary.PREFIX + "type_names", [])]
    if which == 'TYPE' and not 0 <= type_index < len(names):
        raise _input_error(f"there is no type {type_index + 1} in '{coll.name}' (it has "
                           f"{len(names)}): pick one of {', '.join(names)}.")
    points = instances.read_points(obj.data)
    mask = instances.pick(points, which, type_index)
    if not mask.any():
        what = {'SELECTED': f"no points of '{obj.name}' are selected: select some in Edit "
                            "Mode (Tab) first",
                'TYPE': f"no instances of '{names[type_index] if names else ''}' are left"
                }.get(which, f"'{obj.name}' has no instances left")
        raise _input_error(what + ".")
    exact = instances.placements(obj)
    if exact is None or len(exact) <= int(points["indices"].max(initial=-1)) \
            or points["indices"].min(initial=0) < 0:
        raise _input_error(f"'{obj.name}' lacks its placements (property "
                           f"'{instances.PLACEMENTS_KEY}' missing or damaged): pack again.")
    meshes = []
    for t, mesh_name in enumerate(coll.get(summary.PREFIX + "type_meshes", [])):
        mesh = bpy.data.meshes.get(str(mesh_name))
        if mesh is None:
            raise _input_error(f"the mesh '{mesh_name}' of '{coll.name}' is gone: undo its "
                               "removal or pack again.")
        meshes.append((mesh, summary.type_colour(t)))
    if len(meshes) != len(names) or not np.isin(exact[:, 8], np.arange(len(names))).all():
        raise _input_error(f"'{coll.name}' does not record its types and meshes: pack "
                           "again.")
    picked = np.flatnonzero(mask)
    types = result_edits.point_types(obj, points, len(names), coll.name)[picked]
    index = points["indices"][picked].astype(np.int64)
    drawn = result_edits.instance_matrices(obj, points, picked)
    rows = exact[index].copy()
    same = (rows[:, 8].astype(np.int64) == types) & result_edits.same_placement(drawn, rows)
    moved = np.flatnonzero(~same)
    if len(moved):  # where it is drawn now; an uneven scale or a mirror is refused by name
        rows[moved, :8] = result_edits.decompose(
            drawn[moved], lambda j: f"'{names[types[moved[j]]]} {index[moved[j]] + 1}' (an "
                                    f"instance of '{obj.name}')", then="make it real again")
    made = []
    for k, i in enumerate(index.tolist()):
        t, p = int(types[k]), rows[k]
        made.append(place_object(coll, f"{names[t]} {i + 1}", t, i, p[:4], p[4:7], p[7],
                                 *meshes[t]))
    if mask.all():
        instances.remove(obj)
        coll[instances.KIND_KEY] = "objects"
    else:
        instances.drop_points(obj, mask)
    return made


# ------------------------------------------------------------------------------ export


@dataclass
class ExportRequest:
    """Everything an export job needs, read from the scene on the main thread."""

    packing_json: str
    container: Triangles
    types: list[Triangles]
    out_path: str
    options: Any
    scale: float = 1.0  # millimetres per Blender unit (the scene's units)
    #: the placements the result holds now where the artist changed them (deleted, moved,
    #: made real and moved: `result_edits.current_placements`), else None
    placements: Any = None
    #: mesh objects in the result that are no placed objects, left out
    left_out: list[str] = field(default_factory=list)
    collection: str = ""  # the result collection's name, for the report


FORMAT_EXTENSIONS = {'STL': ".stl", '3MF': ".3mf", 'OBJ': ".obj", 'PLY': ".ply"}


def output_path(filepath: str, file_format: str) -> str:
    """Absolute output path with the format's extension ('//' = the .blend file's folder)."""
    if not filepath:
        raise _input_error("give an output file (Export > File).")
    if filepath.startswith("//") and not bpy.data.filepath:
        raise _input_error(f"the output file '{filepath}' is relative to the .blend file, "
                           "which is not saved yet: save it first or give an absolute path.")
    path = bpy.path.abspath(filepath)
    stem, ext = os.path.splitext(path)
    if ext.lower() in FORMAT_EXTENSIONS.values():
        path = stem
    path += FORMAT_EXTENSIONS[file_format]
    from jampacked.core.atomic import missing_folder

    missing = missing_folder(os.path.dirname(path) or ".")
    if missing:
        raise _input_error(f"cannot write '{path}': {missing}, or pick another file.")
    return path


def result_collection(context: bpy.types.Context) -> bpy.types.Collection:
    """The result collection Export writes (:func:`.results.shown_result`)."""
    coll = results.shown_result(context)
    if coll is None:
        raise _input_error("there is no packing to export: run Pack first (or select an "
                           "object of a Jampacked result collection).")
    return coll


def gather_export(context: bpy.types.Context, options: Any) -> ExportRequest:
    """Read the packing of the result collection and its meshes for export.

    The container is read again from its object and must be unchanged since packing; the
    types come from the result's shared meshes, moved back to their packing "file" frame.
    """
    from jampacked.core.mesh_geometry import mesh_volume_centroid

    from .engine import packing_from_json

    s = context.scene.jampacked
    coll = result_collection(context)
    text = str(coll[summary.PREFIX + "packing"])
    packing = packing_from_json(text)
    cname = str(coll.get(summary.PREFIX + "container", ""))
    container = results.container_of(coll)
    if container is not None:
        cname = container.name
    if container is None:
        raise _input_error(f"the container '{cname}' of '{coll.name}' is gone: restore it "
                           "(undo) or pack again.")
    _require_mesh(container, "container", context.scene)
    require_evaluated(container, "the container", context.view_layer, "Export")
    ctris = object_triangles(container, context.evaluated_depsgraph_get(), outward=True)
    if ctris.signature() != coll.get(summary.PREFIX + "container_sha256"):
        raise _input_error(f"the container '{cname}' was moved or edited after packing "
                           f"'{coll.name}': pack again, or undo the change.")
    mesh_names = list(coll.get(summary.PREFIX + "type_meshes", []))
    if len(mesh_names) != len(packing.types):
        raise _input_error(f"'{coll.name}' does not record its type meshes: pack again.")
    signatures = list(coll.get(summary.PREFIX + "type_sha256", [None] * len(mesh_names)))
    types, meshes = [], []
    for rec, mesh_name, signature in zip(packing.types, mesh_names, signatures, strict=True):
        mesh = bpy.data.meshes.get(mesh_name)
        if mesh is None:
            raise _input_error(f"the mesh '{mesh_name}' of type '{rec.name}' is gone: undo "
                               "its removal or pack again.")
        tris = mesh_triangles(mesh, rec.name, np.linalg.inv(rec.local_from_file))
        # a result made before signatures were recorded: its volume, as the packing has it
        edited = (tris.signature() != signature if signature is not None
                  else not math.isclose(mesh_volume_centroid(tris.vertices, tris.faces)[0],
                                        rec.volume, rel_tol=1e-6))
        if edited:
            raise _input_error(f"the mesh '{mesh_name}' of type '{rec.name}' was edited after "
                               f"packing '{coll.name}', which was certified with it as it "
                               "was: undo the edit, or pack again.")
        types.append(tris)
        meshes.append(mesh)
    placements, left_out = result_edits.current_placements(coll, packing, meshes)
    unit = context.scene.unit_settings
    return ExportRequest(packing_json=text, container=ctris, types=types,
                         out_path=output_path(s.filepath, s.file_format), options=options,
                         scale=units.mm_per_unit(unit.system, unit.scale_length),
                         placements=placements, left_out=left_out, collection=coll.name)


# ------------------------------------------------------------------------------ validate

#: offending kind -> element type it selects
FACE_KINDS = ("flipped_faces", "degenerate_faces", "duplicate_faces", "intersecting_faces")
EDGE_KINDS = ("open_edges", "nonmanifold_edges", "inconsistent_edges")
VERTEX_KINDS = ("nonmanifold_vertices",)
SELECTABLE_KINDS = FACE_KINDS + EDGE_KINDS + VERTEX_KINDS


def _polygon_elements(mesh: bpy.types.Mesh, polygons: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, edges) used by the given polygons."""
    starts = np.empty(len(mesh.polygons), np.int32)
    totals = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", totals)
    loop_verts = np.empty(len(mesh.loops), np.int32)
    loop_edges = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", loop_verts)
    mesh.loops.foreach_get("edge_index", loop_edges)
    loops = np.concatenate([np.arange(starts[p], starts[p] + totals[p]) for p in polygons]
                           ) if len(polygons) else np.zeros(0, np.int64)
    return loop_verts[loops], loop_edges[loops]


def select_offending(context: bpy.types.Context, obj: bpy.types.Object,
                     offending: Mapping[str, np.ndarray], tris: Triangles,
                     groups: np.ndarray) -> int:
    """Select the offending elements of every kind in ``offending`` on ``obj`` (only those)
    and enter edit mode.

    offending: kind -> indices as the validation reports them (triangles, vertex pairs or
    vertices of ``tris``, which must have the topology of ``obj.data``); groups: (V,)
    position group of each vertex (coincident vertices share one), so that edges and
    vertices are found whichever of the coincident vertices they use. The select mode is
    that of the kinds (faces, edges, vertices). Returns the number of elements selected.
    """
    if context.object is not None and context.object.mode != 'OBJECT':
        bpy.ops.object.mode_set(mode='OBJECT')
    for other in context.selected_objects:
        other.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    mesh = obj.data
    vsel = np.zeros(len(mesh.vertices), bool)
    esel = np.zeros(len(mesh.edges), bool)
    fsel = np.zeros(len(mesh.polygons), bool)
    edge_verts = np.empty(len(mesh.edges) * 2, np.int32)
    mesh.edges.foreach_get("vertices", edge_verts)
    edge_verts = edge_verts.reshape(-1, 2)
    edge_groups = np.sort(groups[edge_verts], axis=1)
    mode = [False, False, False]
    count = 0
    for kind, indices in offending.items():
        indices = np.asarray(indices, np.int64)
        if kind in FACE_KINDS:
            polygons = np.unique(tris.tri_polygon[indices.reshape(-1)])
            fsel[polygons] = True
            verts, edges = _polygon_elements(mesh, polygons)
            vsel[verts] = True
            esel[edges] = True
            mode[2] = True
            count += len(polygons)
        elif kind in EDGE_KINDS:
            wanted = {(int(a), int(b))
                      for a, b in np.sort(groups[indices.reshape(-1, 2)], axis=1)}
            hit = np.fromiter(((int(a), int(b)) in wanted for a, b in edge_groups), bool,
                              count=len(edge_groups))
            esel |= hit
            vsel[edge_verts[hit].reshape(-1)] = True
            mode[1] = True
            count += int(hit.sum())
        elif kind in VERTEX_KINDS:
            hit = np.isin(groups, groups[indices.reshape(-1)])
            vsel |= hit
            mode[0] = True
            count += int(hit.sum())
        else:
            raise _input_error(f"unknown kind of defect {kind!r}.")
    mesh.vertices.foreach_set("select", vsel)
    mesh.edges.foreach_set("select", esel)
    mesh.polygons.foreach_set("select", fsel)
    context.tool_settings.mesh_select_mode = tuple(mode) if any(mode) else (True, False, False)
    bpy.ops.object.mode_set(mode='EDIT')
    return count
