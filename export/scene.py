"""A packing made solid: its sources loaded and checked, its objects placed as manifold3d solids.

Frames: the packing's container frame, container units (mm for printing). A placed object's
vertices are ``matrix @ local_from_file @ v_file``; the container's ``frame_from_file @
v_file`` (the packing file's definitions).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field

import manifold3d as m3
import numpy as np

from jampacked.core.errors import InputError
from jampacked.core.meshes import MeshData, load_mesh
from jampacked.core.packing import Packing, container_mesh, verify_sources
from jampacked.core.packing_digest import only_clearance_changed, placements_status
from jampacked.core.phases import equivalent_radius
from jampacked.core.solids import to_solid

from .simplify import simplify_within
from .union import SPECK_REL

__all__ = [
    "PlacedScene",
    "check_placements",
    "load_sources",
    "packing_clearance",
    "place",
    "smallest_object",
    "transform_points",
]

#: how many objects an error names before it counts the rest
NAMED = 8
#: a source mesh's volume in the packing's frame may differ from the recorded one by this
#: (relative; rounding only)
VOLUME_REL = 1e-6


def load_sources(packing: Packing) -> tuple[MeshData, list[MeshData]]:
    """The container and type meshes a packing names, checked against their sha256 and
    against the volumes the packing recorded.

    Raises InputError when a file is missing, changed, reads at another size than when it
    was packed (a 3MF in inches read by a version that took it as millimetres), or a type
    has no file (a packing made in Blender: pass its meshes to :func:`export_packing`
    instead).
    """
    problems = verify_sources(packing)
    if problems:
        raise InputError("cannot export: " + "; ".join(problems) + ".")
    container = container_mesh(packing, "export")
    types = []
    for t in packing.types:
        if t.path is None:
            raise InputError(f"type {t.name!r} has no mesh file in the packing (it was made "
                             "from in-memory meshes); export it from where it was made.")
        types.append(load_mesh(t.path, role="object"))
    sizes = [("the container", container, packing.frame_from_file, packing.container_volume)]
    sizes += [(f"type {t.name!r}", m, t.local_from_file, t.volume)
              for t, m in zip(packing.types, types, strict=True)]
    for label, mesh, matrix, recorded in sizes:
        volume = mesh.volume * abs(float(np.linalg.det(matrix[:3, :3])))
        if volume == 0 or not math.isfinite(volume):
            continue  # a singular frame: refused later, by name (`PlacedScene`)
        if not math.isclose(volume, recorded, rel_tol=VOLUME_REL):
            cause = ("the packing file was edited after it was certified (its certificate's "
                     "digest no longer matches it): undo the edit, or re-run the packing"
                     if placements_status(packing) == "changed"
                     and not only_clearance_changed(packing) else
                     "it was packed by a version that read the file differently, or the "
                     "file's volumes were edited. Re-run the packing")
            raise InputError(
                f"cannot export: the mesh file of {label} reads as {volume:.6g} units^3 in the "
                f"packing's frame, but the packing recorded {recorded:.6g} (x"
                f"{(volume / recorded) ** (1 / 3):.4g} in size): {cause}.")
    return container, types


def transform_points(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Points (N, 3) moved by the affine part of the (4, 4) matrix ``m``."""
    return v @ m[:3, :3].T + m[:3, 3]


def packing_clearance(packing: Packing, source: str | None) -> float:
    """The packing's clearance (``inputs.clearance``, container units).

    source: the packing file, for the message. Raises InputError when the field holds
    anything but a finite number >= 0.
    """
    value = packing.inputs.clearance
    if (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and math.isfinite(value) and value >= 0):
        return float(value)
    where = f"the packing file {source}" if source else "the packing"
    raise InputError(f"{where} has inputs.clearance = {value!r}: it must be a number >= 0 "
                     "(container units; 0 for a packing without clearance). Fix that field, "
                     "or re-run the packing.")


def object_name(packing: Packing, i: int, labels: Sequence[str] | None = None) -> str:
    """'object 3 (lemon)', or the caller's name for it ('lemon 4' in Blender)."""
    if labels is not None:
        return f"'{labels[i]}'"
    return f"object {i} ({packing.types[packing.type_index[i]].name})"


def _objects(packing: Packing, indices: np.ndarray, labels: Sequence[str] | None = None
             ) -> str:
    """'object 3 (lemon), object 7 (lime) and 4 more' for an error message."""
    named = [object_name(packing, int(i), labels) for i in indices[:NAMED]]
    more = f" and {len(indices) - NAMED} more" if len(indices) > NAMED else ""
    return ", ".join(named) + more


def check_placements(packing: Packing, type_radius: np.ndarray, lo: np.ndarray,
                     hi: np.ndarray, source: str | None,
                     labels: Sequence[str] | None = None) -> None:
    """Refuse placements that cannot be exported, naming the objects (by ``labels`` where
    the caller has names).

    type_radius: (T,) largest distance of each type's vertices from its local origin; lo, hi:
    the container's bounds, container frame and units. Singular transforms (a zero or
    non-finite scale, a zero or non-finite rotation, a non-finite translation) would make
    objects vanish from the export, a negative scale would mirror them, and an object far
    outside the container (its centre further from the container's bounds than its own
    size, or larger than the container) leaves manifold3d nothing it can compute with: all
    raise InputError.
    """
    where = f"the packing file {source}" if source else "the packing"
    q = packing.rotations
    s = packing.scales
    with np.errstate(over="ignore", invalid="ignore"):
        qnorm = np.linalg.norm(q, axis=1) if len(q) else np.zeros(0)
    problems = []
    for bad, what in (
        (~np.isfinite(s) | (s == 0), "a zero or non-finite scale"),
        (~np.all(np.isfinite(q), axis=1) | ~np.isfinite(qnorm) | (qnorm == 0),
         "a zero or non-finite rotation quaternion"),
        (~np.all(np.isfinite(packing.translations), axis=1), "a non-finite translation"),
    ):
        if bad.any():
            problems.append(f"{_objects(packing, np.flatnonzero(bad), labels)}: {what}")
    if problems:
        raise InputError(
            f"cannot export: {where} has singular placements, which would vanish from the "
            f"export: {'; '.join(problems)}. A finished packing has scale 1 and unit "
            "quaternions: re-run the packing, or fix or remove these placements.")
    # a negative scale mirrors the object: the export would hold a shape no type has
    mirrored = np.flatnonzero(s < 0)
    if mirrored.size:
        raise InputError(
            f"cannot export: {where} has mirrored placements (a negative scale): "
            f"{_objects(packing, mirrored, labels)}. A finished packing has scale 1: re-run "
            "the packing, or fix or remove these placements.")
    size = np.abs(s) * type_radius[packing.type_index]
    diagonal = float(np.linalg.norm(hi - lo))
    t = packing.translations
    far = np.flatnonzero((size > diagonal) | np.any(t < lo - size[:, None], axis=1)
                         | np.any(t > hi + size[:, None], axis=1))
    if far.size:
        i = int(far[0])
        raise InputError(
            f"cannot export: {where} places {_objects(packing, far, labels)} outside the "
            f"container ({object_name(packing, i, labels)} is up to {2.0 * size[i]:.4g} units "
            f"across, at "
            f"({', '.join(f'{c:.4g}' for c in t[i])}); the container spans "
            f"({', '.join(f'{c:.4g}' for c in lo)}) to ({', '.join(f'{c:.4g}' for c in hi)})). "
            "Every object must sit within the container: re-run the packing, or fix these "
            "placements.")


@dataclass
class PlacedScene:
    """The packing's geometry in the container frame.

    container_vertices / container_faces: the container mesh. type_index: (N,) each
    object's type; local / type_faces: each type's vertices in its local frame and its
    faces; matrices: (N, 4, 4) local -> container frame. After :meth:`make_solids`:
    type_solids, each type once as a solid in its local frame (simplified by the resolution
    asked); solids, each object's solid moved into place; triangles_saved, the triangles the
    resolution removed over every object; resolution_deviation, how far the simplification
    moved a type's surface at most (measured, container units).
    """

    container_vertices: np.ndarray
    container_faces: np.ndarray
    type_index: np.ndarray
    local: list[np.ndarray]
    type_faces: list[np.ndarray]
    matrices: np.ndarray
    type_solids: list[m3.Manifold] = field(default_factory=list)
    solids: list[m3.Manifold] = field(default_factory=list)
    triangles_saved: int = 0
    resolution_deviation: float = 0.0

    @property
    def lo(self) -> np.ndarray:
        return self.container_vertices.min(axis=0)

    @property
    def hi(self) -> np.ndarray:
        return self.container_vertices.max(axis=0)

    def outside(self) -> m3.Manifold:
        """The region around the container: its bounding box, padded, minus the container."""
        lo, hi = self.lo, self.hi
        pad = 0.1 * float((hi - lo).max()) + 1.0
        box = m3.Manifold.cube(tuple(hi - lo + 2 * pad)).translate(tuple(lo - pad))
        return box - to_solid(self.container_vertices, self.container_faces)

    def make_solids(self, packing: Packing, resolution: float | None,
                    source: str | None = None) -> None:
        """Every object as a solid: each type made solid once in its local frame (simplified
        to ``resolution`` when given), then moved by its placement matrix.

        Raises InputError for a type or an object that comes out empty, so that no object is
        dropped silently.
        """
        self.make_type_solids(packing, resolution)
        self.place_solids(packing, source)

    def make_type_solids(self, packing: Packing, resolution: float | None) -> None:
        """Each type as a solid in its local frame, simplified to ``resolution`` when given
        (``type_solids``; the objects are placed by :meth:`place_solids`).

        Raises InputError for a type that comes out empty.
        """
        type_solids = []
        saved_per_type = []
        deviation = 0.0
        for v, f, rec in zip(self.local, self.type_faces, packing.types, strict=True):
            s = to_solid(v, f)
            before = s.num_tri()
            if resolution is not None:
                s, moved = simplify_within(s, resolution)
                deviation = max(deviation, moved)
            if not s.volume() > 0:
                why = (f"simplified by --resolution {resolution:g}; give a finer one"
                       if to_solid(v, f).volume() > 0 and resolution is not None else
                       "its local_from_file in the packing is singular, or its mesh has no "
                       "volume; re-run the packing")
                raise InputError(f"type {rec.name!r} comes out empty: {why}. Its objects "
                                 "would vanish from the export.")
            saved_per_type.append(before - s.num_tri())
            type_solids.append(s)
        counts = np.bincount(self.type_index, minlength=len(type_solids))
        self.type_solids = type_solids
        self.triangles_saved = int(np.dot(counts, saved_per_type))
        self.resolution_deviation = deviation

    def place_solids(self, packing: Packing, source: str | None = None) -> None:
        """Every object's solid (``solids``): its type's solid moved by its placement matrix.

        Raises InputError for an object that comes out empty (scaled to nothing).
        """
        solids = [self.type_solids[t].transform(self.matrices[i][:3, :]) for i, t in
                  enumerate(self.type_index)]
        # the union drops components this small as specks: such an object would vanish
        speck = SPECK_REL * float(np.prod(self.hi - self.lo))
        vanished = np.flatnonzero([not abs(s.volume()) > speck for s in solids])
        if vanished.size:
            where = f"the packing file {source}" if source else "the packing"
            scales = ", ".join(f"{packing.scales[i]:.3g}" for i in vanished[:NAMED])
            raise InputError(
                f"cannot export: {where} scales {_objects(packing, vanished)} to nothing "
                f"(scales {scales}); they would vanish from the export. A finished packing "
                "has scale 1: re-run the packing, or fix these placements.")
        self.solids = solids


def place(packing: Packing, container: MeshData, types: Sequence[MeshData],
          source: str | None = None, labels: Sequence[str] | None = None) -> PlacedScene:
    """The packing's container and types in the container frame, its placements checked.

    container, types: the meshes in their file frames. source: the packing file, labels:
    each placement's name where the caller has names, for messages. Raises InputError for
    placements that cannot be exported (see
    :func:`check_placements`); the solids come from :meth:`PlacedScene.make_solids`.
    """
    c_vertices = transform_points(packing.frame_from_file, container.vertices)
    local = [transform_points(t.local_from_file, m.vertices)
             for t, m in zip(packing.types, types, strict=True)]
    radius = np.array([float(np.sqrt((v * v).sum(axis=1)).max()) for v in local])
    check_placements(packing, radius, c_vertices.min(axis=0), c_vertices.max(axis=0), source,
                     labels)
    return PlacedScene(container_vertices=c_vertices, container_faces=container.faces,
                       type_index=packing.type_index, local=local,
                       type_faces=[m.faces for m in types], matrices=packing.matrices())


def smallest_object(packing: Packing) -> float | None:
    """The equivalent diameter of the smallest type placed (container units), or None."""
    volumes = [packing.types[t].volume for t in np.unique(packing.type_index)]
    volumes = [v for v in volumes if math.isfinite(v) and v > 0]
    return 2.0 * float(equivalent_radius(min(volumes))) if volumes else None
