"""What a result holds now: the placements Export writes, read back from the scene.

An artist may delete placed objects or instances, move or turn them, or make some real
before exporting; Export writes what the result holds (hidden objects too). Each placed
object (one whose mesh is a type mesh of the result) and each point left in an instanced
result gives a placement at its world matrix. Where it still sits where the packing put it
(within single precision: Blender keeps matrices and point attributes in 32-bit floats) the
packing's double-precision placement is used, else the scene's. A result whose placements
are all where the packing put them, each once, exports the packing as it is (None here);
any other is a changed packing, which the export certifies again before it writes anything
(`jampacked.export.recertify`).

Frames: the container frame is world space (Blender units). Runs on the main thread.
"""

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import bpy
import numpy as np

from . import instances, summary

#: custom property of a placed object: its placement's index in the packing
INDEX_KEY = "jampacked_index"
#: how far a matrix may lie from its placement's and still be that placement: far below any
#: edit, above single precision's rounding (relative to the translation's size)
SAME_REL = 1e-5


@dataclass
class Placements:
    """The placements a result holds now (N of them), in the packing's arrays' forms, with
    what names each in Blender."""

    type_index: np.ndarray  # (N,) int64
    rotations: np.ndarray  # (N, 4) w x y z
    translations: np.ndarray  # (N, 3)
    scales: np.ndarray  # (N,)
    labels: list[str]
    #: each is one of the packing's placements where it put it, none twice: some were only
    #: removed, and the rest stays as certified
    removed_only: bool = False


def _error(message: str) -> Exception:
    from jampacked.core.errors import InputError

    return InputError(message)


def instance_matrices(points: bpy.types.Object, pts: dict[str, np.ndarray],
                      picked: np.ndarray | None = None) -> np.ndarray:
    """(K, 4, 4) world matrices of the instances the points object draws (those
    ``picked``, all by default): its own world matrix times each point's placement.
    ``pts``: the points' arrays (`instances.read_points`)."""
    from jampacked.core.rotations import placement_matrices

    sel = slice(None) if picked is None else picked
    local = placement_matrices(pts["rotations"][sel], pts["translations"][sel],
                               pts["scales"][sel])
    return np.einsum("ij,kjl->kil", np.array(points.matrix_world, np.float64), local)


def same_placement(m: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """(K,) whether each matrix m (K, 4, 4) is its placement ``exact`` (K, 9: w x y z, t,
    s, type) up to single precision."""
    from jampacked.core.rotations import placement_matrices

    want = placement_matrices(exact[:, :4], exact[:, 4:7], exact[:, 7])
    scale = np.maximum(1.0, exact[:, 7])
    size = np.maximum(scale, np.abs(exact[:, 4:7]).max(axis=1))
    return ((np.abs(m[:, :3, :3] - want[:, :3, :3]).max(axis=(1, 2)) <= SAME_REL * scale)
            & (np.abs(m[:, :3, 3] - want[:, :3, 3]).max(axis=1) <= SAME_REL * size))


def decompose(m: np.ndarray, label: Callable[[int], str], then: str = "export again"
              ) -> np.ndarray:
    """(K, 8) rotation w x y z, translation and uniform scale of world matrices (K, 4, 4);
    refuses (naming ``label(k)``, and ending with what to do ``then``) a scale that differs
    between axes, a shear or a mirror, which a packing cannot place."""
    from jampacked.core.rotations import matrix_to_quat

    a = m[:, :3, :3]
    det = np.linalg.det(a)
    s = np.abs(det) ** (1.0 / 3.0)
    r = a / np.where(s > 0, s, 1.0)[:, None, None]
    off = np.abs(np.einsum("kji,kjl->kil", r, r) - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero((det <= 0) | (off > 1e-4))
    if len(bad):
        raise _error(
            f"{label(int(bad[0]))} is scaled unevenly, sheared or mirrored: a packing places "
            "each object at one scale along every axis. Undo that change (or set its scale "
            f"the same on X, Y and Z), then {then}.")
    return np.concatenate([matrix_to_quat(r), m[:, :3, 3], s[:, None]], axis=1)


def point_types(points: bpy.types.Object, pts: dict[str, np.ndarray], n_types: int,
                result: str) -> np.ndarray:
    """The points' types (int64), each checked to be one of the result's ``n_types``."""
    pt = pts["types"].astype(np.int64)
    if len(pt) and not ((pt >= 0) & (pt < n_types)).all():
        k = int(np.flatnonzero((pt < 0) | (pt >= n_types))[0])
        raise _error(f"point {k} of '{points.name}' has type {pt[k]}, which '{result}' does "
                     "not have: undo the edit of its points, or pack again.")
    return pt


def held_now(coll: bpy.types.Collection) -> tuple[int, dict[int, float]]:
    """How many placed objects and instances the result ``coll`` holds now, and each type's
    sum of their scales cubed (their volume over the type's at scale 1). Placed objects are
    those whose mesh is a type mesh of the result; a scale is the cube root of a world
    matrix's determinant."""
    meshes = {}
    for t, name in enumerate(coll.get(summary.PREFIX + "type_meshes", [])):
        mesh = bpy.data.meshes.get(str(name))
        if mesh is not None:
            meshes[mesh.as_pointer()] = t
    points = instances.points_object(coll)
    cubes: dict[int, float] = {}
    count = 0
    for obj in coll.all_objects:
        if obj == points or obj.type != 'MESH' or obj.data is None:
            continue
        t = meshes.get(obj.data.as_pointer())
        if t is not None:
            count += 1
            cubes[t] = cubes.get(t, 0.0) + abs(obj.matrix_world.to_3x3().determinant())
    if points is not None:
        pts = instances.read_points(points.data)
        det = abs(points.matrix_world.to_3x3().determinant())
        scale3 = pts["scales"].astype(np.float64) ** 3 * det
        for t in np.unique(pts["types"]).tolist():
            cubes[int(t)] = cubes.get(int(t), 0.0) + float(scale3[pts["types"] == t].sum())
        count += len(scale3)
    return count, cubes


def _index_by_name(obj: bpy.types.Object, names: list[str]) -> int:
    """The placement index of an object of a result made before objects recorded it, from
    its name ("<type> <index + 1>"), or -1."""
    t = obj.get("jampacked_type")
    head, _, tail = obj.name.rpartition(" ")
    if isinstance(t, int) and 0 <= t < len(names) and head == names[t] and tail.isdigit():
        return int(tail) - 1
    return -1


def current_placements(coll: bpy.types.Collection, packing: Any,
                       type_meshes: list[bpy.types.Mesh]
                       ) -> tuple[Placements | None, list[str]]:
    """The placements the result collection ``coll`` holds now (None when they are the
    packing's, each once, where it put them), and the names of the mesh objects in it that
    are not placed objects (whose mesh is no type mesh: left out of the export).
    type_meshes: the result's shared mesh of each type (the packing's order). Vectorised
    over an instanced result's points (100,000 of them in a second)."""
    exact = np.concatenate([packing.rotations, packing.translations,
                            np.reshape(packing.scales, (-1, 1)),
                            np.reshape(packing.type_index, (-1, 1))], axis=1)
    mesh_type = {m.as_pointer(): t for t, m in enumerate(type_meshes)}
    names = [t.name for t in packing.types]
    left_out: list[str] = []
    points = instances.points_object(coll)
    objects, obj_types, obj_index = [], [], []
    for obj in coll.all_objects:
        if obj == points or obj.type != 'MESH':
            continue
        t = mesh_type.get(obj.data.as_pointer()) if obj.data is not None else None
        if t is None:
            left_out.append(obj.name)
            continue
        i = obj.get(INDEX_KEY)
        objects.append(obj)
        obj_types.append(t)
        obj_index.append(int(i) if isinstance(i, int) else _index_by_name(obj, names))
    m = np.array([np.array(o.matrix_world, np.float64) for o in objects]).reshape(-1, 4, 4)
    types = np.asarray(obj_types, np.int64)
    index = np.asarray(obj_index, np.int64)
    n_objects = len(objects)
    if points is not None:
        pts = instances.read_points(points.data)
        pt = point_types(points, pts, len(type_meshes), coll.name)
        m = np.concatenate([m, instance_matrices(points, pts)])
        types = np.concatenate([types, pt])
        index = np.concatenate([index, pts["indices"].astype(np.int64)])

    # a point duplicated in Edit Mode shares its placement's index: its number tells them
    # apart ("'Cube 7, an instance' and 'Cube 7, an instance' overlap")
    values, counts = np.unique(index[n_objects:], return_counts=True)
    twice = set(values[counts > 1].tolist())

    def point(k: int) -> str:
        return f", point {k - n_objects}" if int(index[k]) in twice else ""

    def plain(k: int) -> str:
        if k < n_objects:
            return objects[k].name
        return f"{names[types[k]]} {index[k] + 1}, an instance{point(k)}"

    def label(k: int) -> str:
        return f"'{plain(k)}'" if k < n_objects else \
            f"'{names[types[k]]} {index[k] + 1}' (an instance of '{points.name}'{point(k)})"

    known = (index >= 0) & (index < packing.n)
    rows = exact[np.where(known, index, 0)]
    same = known & (rows[:, 8].astype(np.int64) == types) & same_placement(m, rows)
    if same.all() and np.array_equal(np.sort(index), np.arange(packing.n)):
        return None, left_out
    removed_only = bool(same.all()) and len(np.unique(index)) == len(index)
    out = np.empty((len(m), 9))
    out[same] = rows[same]
    moved = np.flatnonzero(~same)
    if len(moved):
        out[moved, :8] = decompose(m[moved], lambda j: label(int(moved[j])))
        out[moved, 8] = types[moved]
    order = np.lexsort((np.where(same, index, 0), ~same))  # the packing's order, then edits
    return Placements(type_index=out[order, 8].astype(np.int64), rotations=out[order, :4],
                      translations=out[order, 4:7], scales=out[order, 7],
                      labels=[plain(int(k)) for k in order],
                      removed_only=removed_only), left_out
