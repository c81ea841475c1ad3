"""What a result holds now: the placements Export writes, read back from the scene.

An artist may delete placed objects or instances, move or turn them, or make some real
before exporting; Export writes what the viewport shows. Each placed object (one whose mesh
is a type mesh of the result) and each point left in an instanced result gives a placement
at its world matrix. Where it still sits where the packing put it (within single precision:
Blender keeps matrices and point attributes in 32-bit floats) the packing's double-precision
placement is used, else the scene's. A result whose placements are all where the packing
put them, each once, exports the packing as it is (None here); any other is a changed
packing, which the export certifies again before it writes anything
(`jampacked.export.recertify`).

Frames: the container frame is world space (Blender units). Runs on the main thread.
"""

from dataclasses import dataclass
from typing import Any

import bpy
import numpy as np

from . import instances

#: custom property of a placed object: its placement's index in the packing
INDEX_KEY = "jampacked_index"
#: how far a matrix may lie from its placement's and still be that placement: far below any
#: edit, above single precision's rounding (relative to the translation's size)
SAME_REL = 1e-5


@dataclass
class Placements:
    """The placements a result holds now (N of them), in the packing's arrays' forms, with
    what names them in Blender and the mesh objects Export leaves out."""

    type_index: np.ndarray  # (N,) int64
    rotations: np.ndarray  # (N, 4) w x y z
    translations: np.ndarray  # (N, 3)
    scales: np.ndarray  # (N,)
    labels: list[str]


def _error(message: str) -> Exception:
    from jampacked.core.errors import InputError

    return InputError(message)


def _matrix(q: np.ndarray, t: np.ndarray, s: float) -> np.ndarray:
    from jampacked.core.rotations import quat_to_matrix

    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(np.asarray(q, np.float64)[None])[0] * s
    m[:3, 3] = t
    return m


def _same(m: np.ndarray, exact: np.ndarray) -> bool:
    """Whether matrix m (4, 4) is the placement ``exact`` (9: w x y z, t, s, type) up to
    single precision."""
    want = _matrix(exact[:4], exact[4:7], float(exact[7]))
    size = max(1.0, float(np.abs(exact[4:7]).max()), float(exact[7]))
    return bool(np.abs(m[:3, :3] - want[:3, :3]).max() <= SAME_REL * max(1.0, exact[7])
                and np.abs(m[:3, 3] - want[:3, 3]).max() <= SAME_REL * size)


def _decompose(m: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray, float]:
    """(rotation w x y z, translation, uniform scale) of a world matrix; refuses a scale
    that differs between axes, a shear or a mirror, which a packing cannot place."""
    from jampacked.core.rotations import matrix_to_quat

    a = m[:3, :3]
    det = float(np.linalg.det(a))
    s = abs(det) ** (1.0 / 3.0)
    r = a / s if s > 0 else a
    if det <= 0 or np.abs(r.T @ r - np.eye(3)).max() > 1e-4:
        raise _error(
            f"'{label}' is scaled unevenly, sheared or mirrored: a packing places each object "
            "at one scale along every axis. Undo that change (or set its scale the same on "
            "X, Y and Z), then export again.")
    return matrix_to_quat(r[None])[0], m[:3, 3].copy(), s


def current_placements(coll: bpy.types.Collection, packing: Any,
                       type_meshes: list[bpy.types.Mesh]
                       ) -> tuple[Placements | None, list[str]]:
    """The placements the result collection ``coll`` holds now (None when they are the
    packing's, each once, where it put them), and the names of the mesh objects in it that
    are not placed objects (whose mesh is no type mesh: left out of the export).
    type_meshes: the result's shared mesh of each type (the packing's order)."""
    exact = np.concatenate([packing.rotations, packing.translations,
                            np.reshape(packing.scales, (-1, 1)),
                            np.reshape(packing.type_index, (-1, 1))], axis=1)
    mesh_type = {m.as_pointer(): t for t, m in enumerate(type_meshes)}
    names = [t.name for t in packing.types]
    rows: list[tuple[int, np.ndarray, str]] = []  # (index or -1, the 9 numbers, label)
    left_out: list[str] = []
    points = instances.points_object(coll)
    for obj in coll.all_objects:
        if obj == points or obj.type != 'MESH':
            continue
        t = mesh_type.get(obj.data.as_pointer()) if obj.data is not None else None
        if t is None:
            left_out.append(obj.name)
            continue
        m = np.array(obj.matrix_world, np.float64)
        i = obj.get(INDEX_KEY)
        i = int(i) if isinstance(i, int) and 0 <= i < packing.n else -1
        if i >= 0 and int(exact[i, 8]) == t and _same(m, exact[i]):
            rows.append((i, exact[i], obj.name))
        else:
            q, tr, s = _decompose(m, obj.name)
            rows.append((-1, np.concatenate([q, tr, [s, t]]), obj.name))
    if points is not None:
        pts = instances.read_points(points.data)
        w = np.array(points.matrix_world, np.float64)
        moved = not np.allclose(w, np.eye(4), rtol=0.0, atol=1e-7)
        for k in range(len(pts["indices"])):
            i, t = int(pts["indices"][k]), int(pts["types"][k])
            label = f"{names[t] if 0 <= t < len(names) else 'type ' + str(t)} {i + 1} " \
                    f"(an instance in '{points.name}')"
            if not 0 <= t < len(type_meshes):
                raise _error(f"{label} has type {t}, which '{coll.name}' does not "
                                   "have: undo the edit of its points, or pack again.")
            m = w @ _matrix(pts["rotations"][k] / max(np.linalg.norm(pts["rotations"][k]),
                                                      1e-30),
                            pts["translations"][k].astype(np.float64),
                            float(pts["scales"][k]))
            if not moved and 0 <= i < packing.n and int(exact[i, 8]) == t \
                    and _same(m, exact[i]):
                rows.append((i, exact[i], label))
            else:
                q, tr, s = _decompose(m, label)
                rows.append((-1, np.concatenate([q, tr, [s, t]]), label))
    if sorted(i for i, _, _ in rows) == list(range(packing.n)):
        return None, left_out
    rows.sort(key=lambda r: (r[0] < 0, r[0]))
    arr = np.array([r[1] for r in rows], np.float64).reshape(-1, 9)
    return Placements(type_index=arr[:, 8].astype(np.int64), rotations=arr[:, :4],
                      translations=arr[:, 4:7], scales=arr[:, 7],
                      labels=[r[2] for r in rows]), left_out
