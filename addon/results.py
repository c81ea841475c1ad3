"""Result collections of earlier Packs: find them and remove them when a Pack replaces them.

A result is a collection "Jampacked <container>" made by :func:`.bridge.build_result`: its
custom properties name the container (``jampacked_container``) and the type meshes it made
(``jampacked_type_meshes``). Runs on Blender's main thread, inside the Pack operator, so the
removal is part of Pack's one undo step.
"""

from dataclasses import dataclass

import bpy

from . import instances, summary

#: a result made with Keep Previous: a later Pack without it leaves it (but the last)
KEPT = summary.PREFIX + "kept"


def is_result(coll: bpy.types.Collection) -> bool:
    """True for a collection made by Pack (it holds the packing JSON)."""
    return summary.PREFIX + "packing" in coll.keys()


def shown_result(context: bpy.types.Context) -> bpy.types.Collection | None:
    """The result the Result panel shows and Make Real and Export act on: the active
    object's result collection where it is in one (its instances object, one of its
    objects; of several, the last Pack's), else the last Pack's (the scene's Result); None
    where neither is a result."""
    last = context.scene.jampacked.result
    active = context.active_object
    holders = [c for c in (active.users_collection if active is not None else ())
               if is_result(c)]
    coll = last if last in holders or not holders else holders[0]
    return coll if coll is not None and is_result(coll) else None


def make_shown(context: bpy.types.Context, coll: bpy.types.Collection) -> None:
    """After a Pack made ``coll``: where the active object is in another result, which
    :func:`shown_result` would show, make one of ``coll``'s objects active instead (as
    Blender makes an added object active), so the panel and Export show the new one; not
    where the active object is in Edit Mode (its result stays shown)."""
    active = context.view_layer.objects.active
    # an object in Edit Mode stays active: made inactive it stays in Edit Mode unseen, and
    # what leaves Edit Mode first (Export, Make Real) would pass it by
    if active is None or active.mode != 'OBJECT' or shown_result(context) in (None, coll):
        return
    first = instances.points_object(coll) or next(iter(coll.objects), None)
    if first is not None and context.view_layer.objects.get(first.name) == first:
        context.view_layer.objects.active = first


def container_of(coll: bpy.types.Collection) -> bpy.types.Object | None:
    """The container object of a result: the one it points to (``jampacked_container_object``,
    which follows a rename), else, for a result made before that was kept, the object of
    the recorded name; None when it is gone."""
    obj = coll.get(summary.PREFIX + "container_object")
    if isinstance(obj, bpy.types.Object):
        return obj
    return bpy.data.objects.get(str(coll.get(summary.PREFIX + "container", "")))


def previous_results(scene: bpy.types.Scene, container_name: str
                     ) -> list[bpy.types.Collection]:
    """The results of the container object ``container_name`` (renamed since or not)
    linked anywhere in the scene's collection tree."""
    target = bpy.data.objects.get(container_name)
    found = [c for c in scene.collection.children_recursive if is_result(c) and (
        container_of(c) == target if target is not None
        else c.get(summary.PREFIX + "container") == container_name)]
    # a collection linked in two places is listed twice: once each, in order
    return [c for k, c in enumerate(found) if c not in found[:k]]


def remove_result(coll: bpy.types.Collection, keep_in: bpy.types.Collection) -> int:
    """Remove a result: its placed objects and its instances (those in no other
    collection), then the type meshes and their materials once nothing else uses them,
    then the collection. What the artist put in it (other objects, child collections) is
    linked to ``keep_in`` first, so that nothing leaves the scene; returns how many."""
    points = instances.points_object(coll)
    meshes = [bpy.data.meshes.get(str(name))
              for name in coll.get(summary.PREFIX + "type_meshes", [])]
    # placed: sharing a type mesh (a Shift+D copy has the custom properties, not the mesh)
    placed = {o for o in coll.objects if o.type == 'MESH' and o.data in meshes}
    kept = [o for o in coll.objects if o not in placed and o != points]
    for obj in kept:
        if obj.name not in keep_in.objects:
            keep_in.objects.link(obj)
    for child in coll.children:
        if child.name not in keep_in.children:
            keep_in.children.link(child)
    kept_count = len(kept) + len(coll.children)
    objects = [o for o in placed if len(o.users_collection) == 1]
    if objects:
        bpy.data.batch_remove(objects)
    if points is not None and len(points.users_collection) == 1:
        instances.remove(points)  # with its prototypes, which use the type meshes
    for mesh in meshes:
        if mesh is None or mesh.users:
            continue
        materials = [m for m in mesh.materials if m is not None]
        bpy.data.meshes.remove(mesh)
        for mat in materials:
            if not mat.users and mat.name.startswith("Jampacked "):
                bpy.data.materials.remove(mat)
    bpy.data.collections.remove(coll)
    return kept_count


#: a result's own settings and those of its place in each view layer that a replacing
#: result takes over, so that the artist's choices (hidden, excluded, holdout) stay
COLLECTION_FLAGS = ("hide_select", "hide_viewport", "hide_render", "color_tag")
LAYER_FLAGS = ("exclude", "hide_viewport", "holdout", "indirect_only")


@dataclass
class _Place:
    """Where a result sits and how it is set: its name, the collections it is linked in,
    its own flags and, by (scene, view layer, the names of the collections above it), each
    of its layer collections' flags (a collection linked in two places has two)."""

    name: str
    parents: list
    flags: dict
    layers: dict


def _layer_children(view_layer: bpy.types.ViewLayer):
    """(names of the collections above, layer collection) of every layer collection of the
    view layer below its root."""
    stack = [((), view_layer.layer_collection)]
    while stack:
        path, parent = stack.pop()
        path = (*path, parent.collection.name)
        for child in parent.children:
            yield path, child
            stack.append((path, child))


def _place_of(scene: bpy.types.Scene, coll: bpy.types.Collection) -> _Place:
    # every scene's: the artist may have linked the result into another scene too
    layers = {(sc.name, vl.name, path): {k: getattr(child, k) for k in LAYER_FLAGS}
              for sc in bpy.data.scenes for vl in sc.view_layers
              for path, child in _layer_children(vl) if child.collection == coll}
    parents = []
    for c in (scene.collection, *scene.collection.children_recursive):
        if c.children.get(coll.name) == coll and c not in parents:
            parents.append(c)
    # and where the artist linked it elsewhere: another scene, a collection in no scene
    for c in (*(s.collection for s in bpy.data.scenes if s != scene), *bpy.data.collections):
        if c.children.get(coll.name) == coll and c not in parents:
            parents.append(c)
    return _Place(coll.name, parents, {k: getattr(coll, k) for k in COLLECTION_FLAGS},
                  layers)


def _put_in_place(scene: bpy.types.Scene, new: bpy.types.Collection, place: _Place) -> None:
    """Link ``new`` where the replaced result was, with its settings; keep the name the
    artist gave it (a "Jampacked ..." name follows the container instead). A parent that
    moved into ``new`` with the removed results' contents is left out (a cycle)."""
    inside = set(new.children_recursive)
    parents = [c for c in place.parents if c != new and c not in inside]
    for parent in parents:
        if parent.children.get(new.name) is None:
            parent.children.link(new)
    if parents and scene.collection not in parents:
        scene.collection.children.unlink(new)
    if not place.name.startswith("Jampacked "):
        new.name = place.name
    for key, value in place.flags.items():
        setattr(new, key, value)
    for sc in bpy.data.scenes:
        for vl in sc.view_layers:
            for path, child in _layer_children(vl):
                flags = place.layers.get((sc.name, vl.name, path))
                if child.collection == new and flags is not None:
                    for key, value in flags.items():
                        setattr(child, key, value)


def replace_previous(scene: bpy.types.Scene, new: bpy.types.Collection,
                     last: bpy.types.Collection | None = None) -> int:
    """Remove the earlier results of ``new``'s container in the scene but those made with
    Keep Previous (marked ``jampacked_kept``), which stay side by side, and of them only the
    last: ``last`` (the scene's result before this Pack) where it is one, else the one
    linked last. Then give ``new`` and its type meshes and materials the names the removed
    ones had (no ".001" suffixes) where they are free. What the artist put in a removed
    result moves to ``new``, and ``new`` takes the replaced result's place: the collections
    it was linked in, its flags and those in each view layer, and the name the artist gave
    it. Returns the number of objects and collections so moved."""
    container = str(new.get(summary.PREFIX + "container", ""))
    others = [c for c in previous_results(scene, container) if c != new]
    newest = last if last is not None and last in others else (others or [None])[-1]
    old = [c for c in others if c == newest or not c.get(KEPT, False)]
    place = _place_of(scene, newest) if newest in old else None
    if place is not None:
        place.parents = [c for c in place.parents if c not in old]
    kept = 0
    for coll in old:
        kept += remove_result(coll, new)
    new.name = f"Jampacked {container}"
    if place is not None:
        _put_in_place(scene, new, place)
    names = []
    for mesh_name, type_name in zip(new.get(summary.PREFIX + "type_meshes", []),
                                    new.get(summary.PREFIX + "type_names", []), strict=True):
        mesh = bpy.data.meshes[str(mesh_name)]
        base = f"Jampacked {type_name}"
        mesh.name = base
        for mat in mesh.materials:
            if mat is not None and mat.name.startswith(base + "."):
                mat.name = base
        names.append(mesh.name)
    new[summary.PREFIX + "type_meshes"] = names
    type_names = [str(n) for n in new.get(summary.PREFIX + "type_names", [])]
    meshes = [bpy.data.meshes[n] for n in names]
    for obj in new.objects:  # made beside the old ones: "P4 1.001"
        t, i = obj.get("jampacked_type"), obj.get("jampacked_index")
        if isinstance(t, int) and isinstance(i, int) and 0 <= t < len(type_names) \
                and obj.type == 'MESH' and obj.data == meshes[t]:  # not an artist's copy
            obj.name = f"{type_names[t]} {i + 1}"
    points = instances.points_object(new)
    if points is not None:
        instances.rename(points, container)
    return kept
