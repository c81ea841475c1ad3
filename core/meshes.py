"""Load, check, repair and normalise triangle meshes.

Every mesh that enters jampacked goes through :func:`load_mesh` (or is made by
:func:`box_mesh`). The result, :class:`MeshData`, is guaranteed to be

* closed: every undirected edge is used by exactly two faces,
* 2-manifold along edges and consistently wound: every directed edge is used once,
* outward wound (counter-clockwise seen from outside), with positive volume,
* a single body (one edge-connected surface),
* accepted by manifold3d (``Manifold.status() == Error.NoError``).

Self-intersections are *not* detected here (manifold3d's status does not report them).

This module is the public entry; the work is done by :mod:`jampacked.core.mesh_files`
(reading files into arrays), :mod:`jampacked.core.mesh_repair` (the checks and repairs),
:mod:`jampacked.core.mesh_geometry` and :mod:`jampacked.core.mesh_topology`.

Units and frame are the file's own: nothing is scaled, rotated or moved. Vertices at identical
positions (or within 1e-9 of the bounding-box diagonal) are merged silently: Blender and
other tools split vertices at UV seams and STL stores a triangle soup, which is not a defect.
Unreferenced vertices are dropped silently.

Repairs (degenerate faces, duplicate faces, zero-volume sliver bodies, faces with reversed
winding, inside-out meshes) are recorded in :attr:`MeshData.warnings` as full sentences
naming the file, and each is also emitted once through the standard :mod:`logging` module at
level WARNING on the logger ``jampacked.core.meshes`` (this module's ``__name__``) when the
load succeeds. Front ends show them from ``MeshData.warnings``; scripts see them on stderr
through logging's last-resort handler unless they configure logging. Defects that cannot be
repaired safely raise :class:`~jampacked.core.errors.MeshError` with a message that names the
file, the defect with counts, and a fix.
"""

from __future__ import annotations

import hashlib
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from .errors import InputError, MeshError
from .mesh_files import (
    extension,
    file_sha256,
    obj_absolute_indices,
    parse_box_spec,
    read_arrays,
    read_bytes,
)
from .mesh_geometry import mesh_volume_centroid, sample_surface
from .mesh_repair import MERGE_TOLERANCE, ZERO_VOLUME_FRACTION, check_and_repair

# the names other modules import from here; their homes are the modules named above
__all__ = [
    "MERGE_TOLERANCE",
    "ZERO_VOLUME_FRACTION",
    "MeshData",
    "box_mesh",
    "file_sha256",
    "load_mesh",
    "mesh_from_arrays",
    "mesh_volume_centroid",
    "parse_box_spec",
    "sample_surface",
]

logger = logging.getLogger(__name__)

ROLES = ("object", "container")


# --------------------------------------------------------------------------------------------
# result type


@dataclass(frozen=True, eq=False)
class MeshData:
    """A checked triangle mesh: closed, 2-manifold, outward wound, one body, volume > 0.

    Attributes:
        vertices: (V, 3) float64, read-only; positions in the file's units (a 3MF model's:
            millimetres) and frame.
        faces: (F, 3) int64, read-only; vertex indices, counter-clockwise seen from outside.
        path: the file it came from, as given; None for generated meshes.
        sha256: sha256 hex digest of the file's bytes; None for generated meshes.
        volume: exact signed volume in file units cubed (> 0).
        warnings: repairs made while loading (and a 3MF unit converted), each a full
            sentence naming the file.
        name: what messages call a mesh given as arrays (`mesh_from_arrays`); None for
            a file's.

    Equality and hashing are by identity (arrays do not compare as booleans).
    """

    vertices: np.ndarray
    faces: np.ndarray
    path: str | None
    sha256: str | None
    volume: float
    warnings: tuple[str, ...] = ()
    name: str | None = None

    @property
    def extents(self) -> np.ndarray:
        """(3,) float64: axis-aligned bounding-box size in file units."""
        return self.vertices.max(axis=0) - self.vertices.min(axis=0)

    @cached_property
    def centroid(self) -> np.ndarray:
        """(3,) float64: volume centroid (centre of mass at uniform density), file frame."""
        return mesh_volume_centroid(self.vertices, self.faces)[1]


def _frozen(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def _cap(text: str) -> str:
    return text[:1].upper() + text[1:]


# --------------------------------------------------------------------------------------------
# entry points


def box_mesh(extents: Sequence[float]) -> MeshData:
    """A closed box centred at the origin: 8 vertices, 12 outward-wound triangles.

    Args:
        extents: (3,) positive side lengths along x, y, z, in the scene's units.

    Raises:
        InputError: not three finite positive numbers.
    """
    try:
        ext = np.asarray(extents, dtype=np.float64).reshape(3)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"box extents {extents!r} are not three numbers: give width, depth and height, "
            "e.g. (40, 40, 45)."
        ) from exc
    if not np.all(np.isfinite(ext)) or np.any(ext <= 0):
        raise InputError(
            f"box extents {tuple(float(x) for x in ext)} must be finite and positive: "
            "give width, depth and height greater than zero."
        )
    corners = np.array(
        [[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    )
    vertices = corners * ext
    # corner index = 4*ix + 2*iy + iz
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2],  # x = -
            [4, 6, 7], [4, 7, 5],  # x = +
            [0, 4, 5], [0, 5, 1],  # y = -
            [2, 3, 7], [2, 7, 6],  # y = +
            [0, 2, 6], [0, 6, 4],  # z = -
            [1, 5, 7], [1, 7, 3],  # z = +
        ],
        dtype=np.int64,
    )
    volume = float(np.prod(ext))
    return MeshData(_frozen(vertices), _frozen(faces), None, None, volume, ())


def load_mesh(path: str | os.PathLike, *, role: str = "object") -> MeshData:
    """Load a mesh file, check it, repair what is safe to repair, and return it.

    Args:
        path: mesh file (STL, OBJ, PLY, OFF, GLB/GLTF, 3MF, or any format meshio reads). Scenes
            with several meshes are concatenated (their transforms applied).
        role: ``"object"`` (an object type to pack) or ``"container"``; used in messages,
            and containers also get the thin-wall check.

    Returns:
        A :class:`MeshData` in the file's units (a 3MF model's: millimetres) and frame,
        closed, 2-manifold, outward wound, one body, volume > 0, accepted by manifold3d.
        Repairs made, and a 3MF unit converted, are listed in ``warnings`` and logged (see
        the module docstring).

    Raises:
        InputError: ``role`` is not "object" or "container".
        MeshError: the file is missing, unreadable, of unknown type or empty; or the mesh is
            open, non-manifold, non-orientable, has zero volume or several bodies, is refused
            by manifold3d, or (container) is a thin wall. The message names the file, the
            defect with counts, and a fix.
    """
    if role not in ROLES:
        raise InputError(f"mesh role {role!r} is unknown: use 'object' or 'container'.")
    path_str = os.fspath(path)
    label = f"{role} mesh '{path_str}'"
    data = read_bytes(path_str, role)
    digest = hashlib.sha256(data).hexdigest()
    if not data.strip():
        raise MeshError(
            f"{_cap(label)} is an empty file: export the mesh again (the export may "
            "have been interrupted)."
        )
    notes: list[str] = []
    vertices, faces = read_arrays(path_str, data, _cap(label), notes)
    obj_data = obj_absolute_indices(data) if extension(path_str) == "obj" else None
    return _checked(vertices, faces, label, role, obj_data, path_str, digest, notes)


def _checked(vertices: np.ndarray, faces: np.ndarray, label: str, role: str,
             obj_data: bytes | None, path: str | None, digest: str | None,
             notes: list[str] | None = None) -> MeshData:
    """Check and repair (logging each repair and each of the reader's `notes`) and freeze
    the result as MeshData."""
    vertices, faces, volume, warns = check_and_repair(vertices, faces, label, role, obj_data)
    warns = (*(notes or ()), *warns)
    for message in warns:
        logger.warning(message)
    return MeshData(
        vertices=_frozen(np.ascontiguousarray(vertices, dtype=np.float64)),
        faces=_frozen(np.ascontiguousarray(faces, dtype=np.int64)),
        path=path,
        sha256=digest,
        volume=volume,
        warnings=warns,
    )


def mesh_from_arrays(vertices: np.ndarray, faces: np.ndarray, *, name: str,
                     role: str = "object") -> MeshData:
    """Check and repair a mesh given as arrays (e.g. a Blender object), as :func:`load_mesh`.

    Args:
        vertices: (V, 3) positions in the caller's frame and units.
        faces: (F, 3) vertex indices (triangles; triangulate polygons first).
        name: what the messages call the mesh (e.g. the Blender object's name).
        role: ``"object"`` or ``"container"``.

    Returns:
        A :class:`MeshData` with ``path`` and ``sha256`` None.

    Raises:
        InputError: bad ``role`` or arrays of the wrong shape.
        MeshError: the same defects :func:`load_mesh` refuses, naming ``name``.
    """
    if role not in ROLES:
        raise InputError(f"mesh role {role!r} is unknown: use 'object' or 'container'.")
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise InputError(f"{role} mesh '{name}': vertices must be (V, 3) and faces (F, 3) "
                         f"triangles, got {v.shape} and {f.shape}.")
    if not np.all(np.isfinite(v)):
        raise MeshError(f"{role.capitalize()} mesh '{name}' has non-finite vertex "
                        "coordinates: fix or delete those vertices.")
    if f.size and (not np.issubdtype(f.dtype, np.integer) or f.min() < 0
                   or f.max() >= len(v)):
        raise InputError(f"{role} mesh '{name}': face indices must be integers in "
                         f"[0, {len(v) - 1}].")
    return replace(
        _checked(v, f.astype(np.int64), f"{role} mesh '{name}'", role, None, None, None),
        name=name)
