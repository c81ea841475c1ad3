"""Watertightness validation of a mesh, as written to a file and read back.

**Watertight** (DESIGN.md): one or more closed 2-manifold bodies, every edge shared by exactly
two faces with opposite orientation, consistent outward winding, positive volume, no
self-intersections; checked on the file as written and read back.

What is checked, per body (an edge-connected set of faces):

* open edges (used by one face) and the holes they surround; non-manifold edges (used by
  more than two faces); non-manifold vertices (whose faces form more than one fan: bodies
  touching at a vertex, or a pinched surface);
* winding: edges whose two faces run the same way, the faces that disagree with the majority
  of their patch (``flipped_faces``), and non-orientable patches;
* degenerate faces (a repeated vertex, or zero area: height at most ``DEGENERATE_REL`` of the
  bounding-box diagonal) and duplicate faces (the same three vertices, either winding);
* signed volume, area, bounding box, genus (from the Euler characteristic of a closed,
  orientable body);
* self-intersections: exact-geometry float64 triangle-triangle tests on every pair of faces
  whose boxes overlap (see :mod:`jampacked.export.intersect` for what counts and the
  tolerance). Contacts count: two faces that touch beyond their shared vertices or edge.

And over the whole file: the number of bodies; bodies whose surfaces intersect or touch
(``overlapping_bodies``); nesting (the winding number of a point of each closed body with
respect to the closed bodies whose boxes contain it: signed crossings of a ray where that
body's every edge is used once each way, else, or where the ray grazes an edge or the point
lies on the surface, the generalised winding number from solid angles; the two agree on such
bodies), so that a body is *outward* when it is a solid (volume > 0, outside every other
solid) or a cavity (volume < 0, inside exactly one solid). An inside-out body, or a solid
inside a solid, fails. manifold3d's status of the whole mesh is recorded as an independent
check (``check_manifold3d=False`` skips it: the report then says "skipped").

Reading: vertices at exactly identical positions are merged (STL is a triangle soup; that is
how a slicer reads it). Nothing else is merged, removed or repaired. A 3MF package is read
as lib3mf reads it (:mod:`jampacked.core.threemf`): the model part its relationship names,
and one that breaks the core specification where lib3mf refuses it (no content types or
relationships, a duplicate object id, a build item of a missing object, ...) is not
validated but refused as unreadable, like a damaged one. Offending elements are
reported like Blender's 3D-Print Toolbox, as indices into the arrays given (or the arrays
read from the file): faces by index, edges as pairs of vertex indices, vertices by index
(the first vertex at that position).

Units and frame are the mesh's own (container units, mm for printing). The report types are
:mod:`jampacked.export.validation_report`; the structure
:mod:`jampacked.export.validation_topology`; nesting :mod:`jampacked.export.nesting`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from jampacked.core.errors import InputError, plural
from jampacked.core.mesh_files import read_mesh_arrays
from jampacked.core.mesh_repair import (
    CRACK_TOLERANCE,
    MAX_COORDINATE,
    MERGE_TOLERANCE,
    UNWELDED_SHARE,
    ZERO_VOLUME_FRACTION,
    manifold_status,
    unwelded_share,
)
from jampacked.core.mesh_topology import EdgeTopology, edge_topology

from . import meshcheck
from .intersect import intersecting_pairs, start_intersecting_pairs
from .nesting import nesting
from .thread_policy import spare_core
from .validation_report import (
    BodyReport,
    ValidationReport,
    body_kind,
    body_problems,
    empty_report,
)
from .validation_topology import (
    duplicate_faces,
    face_bodies,
    flipped_faces,
    holes_per_body,
    merge_identical,
    vertex_fans,
)

__all__ = ["BodyReport", "ValidationReport", "validate_arrays", "validate_file"]

#: a face whose height is at most this fraction of the bounding-box diagonal is degenerate
DEGENERATE_REL = MERGE_TOLERANCE

Pairs = tuple[np.ndarray, int, np.ndarray]  # (K, 2) face pairs, their count, hits per face


def _as_arrays(vertices: Any, faces: Any) -> tuple[np.ndarray, np.ndarray]:
    try:
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces)
    except (TypeError, ValueError) as exc:
        raise InputError(f"mesh arrays cannot be read as numbers ({exc}): give vertices as "
                         "(V, 3) floats and faces as (F, 3) integers.") from exc
    if v.size == 0:
        v = v.reshape(0, 3)
    if f.size == 0:
        f = f.reshape(0, 3)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise InputError(f"mesh arrays have shapes {v.shape} and {f.shape}: give vertices "
                         "as (V, 3) floats and faces as (F, 3) integers (triangles).")
    if f.dtype.kind not in "iu":
        if not np.all(np.equal(np.mod(f, 1), 0)):
            raise InputError("mesh faces hold non-integer vertex indices: give (F, 3) integers.")
    return v, f.astype(np.int64)


@dataclass
class _Merged:
    """Faces re-indexed into distinct positions (unreferenced vertices dropped)."""

    positions: np.ndarray  # (U, 3) distinct positions
    faces: np.ndarray  # (F, 3) indices into positions
    first: np.ndarray  # (U,) index into the given vertices of each position


def _merge(vertices: np.ndarray, used: np.ndarray, local: np.ndarray) -> _Merged:
    """``used``: the vertices faces use; ``local``: the faces as indices into ``used``."""
    # unreferenced vertices are ignored; `first` maps back to indices into `vertices`
    first_used, remap = merge_identical(vertices[used])
    first = used[first_used]
    return _Merged(vertices[first], remap[local], first)


@dataclass
class _Faces:
    """Per-face geometry and the faces that take part in the topology."""

    lo: np.ndarray  # (3,) bounding box of the positions
    hi: np.ndarray
    diagonal: float
    proper: np.ndarray  # (F,) three distinct vertices
    area2: np.ndarray  # (F,) twice the area
    six: np.ndarray  # (F,) six times the signed volume about the box centre
    degenerate: np.ndarray  # (F,) repeated vertex or zero area


def _face_measures(m: _Merged) -> _Faces:
    lo, hi = m.positions.min(axis=0), m.positions.max(axis=0)
    diagonal = float(np.linalg.norm(hi - lo))
    # repeated vertex, |cross| (as mesh_geometry.face_areas2), longest edge, 6 x signed
    # volume (as mesh_geometry.signed_six_volumes, about the box centre)
    repeated, area2, longest, six = meshcheck.face_geometry(m.positions, m.faces,
                                                           0.5 * (lo + hi))
    height = area2 / np.maximum(longest, np.finfo(float).tiny)
    degenerate = repeated | (height <= DEGENERATE_REL * diagonal)
    return _Faces(lo, hi, diagonal, ~repeated, area2, six, degenerate)


def _start_intersections(m: _Merged, fg: _Faces, duplicates: np.ndarray, enabled: bool,
                         in_thread: bool) -> Callable[[], Pairs]:
    """Start the self-intersection test on the faces that are neither degenerate nor copies;
    returns what gives its result. In a thread (numba, without the GIL) it runs alongside
    the stages that follow; otherwise it runs here."""
    active = ~fg.degenerate
    active[duplicates] = False
    if not enabled:
        n_faces = len(m.faces)
        return lambda: (np.zeros((0, 2), np.int64), 0, np.zeros(n_faces, np.int64))
    if in_thread:
        return start_intersecting_pairs(m.positions, m.faces, active)
    result = intersecting_pairs(m.positions, m.faces, active)
    return lambda: result


@dataclass
class _Structure:
    n_bodies: int
    face_body: np.ndarray  # (F,) body of each face
    fan_vertex: np.ndarray  # vertex of each fan
    fan_face: np.ndarray  # a proper face of each fan
    nm_vertices: np.ndarray  # vertices with more than one fan
    flipped: np.ndarray  # faces wound against their patch
    nonorientable: np.ndarray  # faces on non-orientable patches


def _structure(m: _Merged, fg: _Faces, topo: EdgeTopology) -> _Structure:
    n_bodies, face_body = face_bodies(m.faces, fg.proper, topo)
    fan_vertex, fan_face = vertex_fans(m.faces, fg.proper, topo)
    fans_per_vertex = np.bincount(fan_vertex, minlength=len(m.positions))
    flipped, nonorientable = flipped_faces(len(m.faces), topo)
    return _Structure(n_bodies, face_body, fan_vertex, fan_face,
                      np.flatnonzero(fans_per_vertex > 1), flipped, nonorientable)


def _body_sums(m: _Merged, fg: _Faces, topo: EdgeTopology, st: _Structure,
               duplicates: np.ndarray) -> dict[str, np.ndarray]:
    """Per-body counts and sums, each an (n_bodies,) array keyed by its BodyReport field
    (plus the helpers ``proper_faces``, ``fans`` and the box corners ``lo``, ``hi``)."""
    n, face_body = st.n_bodies, st.face_body
    edge_body = face_body[topo.face_of_edge]

    def count(mask: np.ndarray, labels: np.ndarray) -> np.ndarray:
        return np.bincount(labels[mask], minlength=n).astype(np.int64)

    nm_vertex_mask = np.zeros(len(m.positions), bool)
    nm_vertex_mask[st.nm_vertices] = True
    # distinct vertices, non-manifold ones and the box of each body
    verts, nm_verts, lo, hi = meshcheck.body_vertices(m.faces, face_body, n, m.positions,
                                                      nm_vertex_mask)
    return {
        "volume": np.bincount(face_body, weights=fg.six, minlength=n) / 6.0,
        "area": np.bincount(face_body, weights=fg.area2, minlength=n) / 2.0,
        "faces": count(np.ones(len(m.faces), bool), face_body),
        "proper_faces": count(fg.proper, face_body),
        "edges": count(topo.counts > 0, edge_body),
        "open_edges": count(topo.counts == 1, edge_body),
        "nonmanifold_edges": count(topo.counts > 2, edge_body),
        "inconsistent_edges": count(topo.inconsistent, edge_body),
        "fans": np.bincount(face_body[st.fan_face], minlength=n),
        "vertices": verts,
        "nonmanifold_vertices": nm_verts,
        "lo": lo,
        "hi": hi,
        "flipped_faces": np.bincount(face_body[st.flipped], minlength=n),
        "nonorientable_faces": np.bincount(face_body[st.nonorientable], minlength=n),
        "degenerate_faces": count(fg.degenerate, face_body),
        "duplicate_faces": np.bincount(face_body[duplicates], minlength=n),
        "holes": holes_per_body(topo, face_body, n),
    }


def _body_reports(sums: dict[str, np.ndarray], closed: np.ndarray, self_body: np.ndarray,
                  inside: list[list[int]], outside: np.ndarray, nesting_checked: bool,
                  zero_volume: float) -> list[BodyReport]:
    bodies = []
    for k in range(len(closed)):
        is_closed = bool(closed[k])
        orientable = bool(sums["nonorientable_faces"][k] == 0)
        genus = None
        if is_closed and orientable and sums["inconsistent_edges"][k] == 0:
            chi = (int(sums["fans"][k]) - int(sums["edges"][k])
                   + int(sums["proper_faces"][k]))
            genus = (2 - chi) // 2 if chi % 2 == 0 else None
        volume = float(sums["volume"][k])
        fields: dict[str, Any] = dict(
            index=k, faces=int(sums["faces"][k]), vertices=int(sums["vertices"][k]),
            edges=int(sums["edges"][k]), volume=volume, area=float(sums["area"][k]),
            bbox_min=tuple(float(x) for x in sums["lo"][k]),
            bbox_max=tuple(float(x) for x in sums["hi"][k]),
            open_edges=int(sums["open_edges"][k]), holes=int(sums["holes"][k]),
            nonmanifold_edges=int(sums["nonmanifold_edges"][k]),
            nonmanifold_vertices=int(sums["nonmanifold_vertices"][k]),
            inconsistent_edges=int(sums["inconsistent_edges"][k]),
            flipped_faces=int(sums["flipped_faces"][k]),
            orientable=orientable, degenerate_faces=int(sums["degenerate_faces"][k]),
            duplicate_faces=int(sums["duplicate_faces"][k]),
            self_intersections=int(self_body[k]),
            inside=tuple(inside[k]),
            kind=body_kind(int(sums["open_edges"][k]), is_closed, volume, int(outside[k]),
                           nesting_checked),
            genus=genus,
        )
        fields["problems"] = tuple(body_problems(fields, zero_volume))
        bodies.append(BodyReport(**fields))
    return bodies


def _file_problems(overlapping: list[tuple[int, int]], status: str,
                   bodies: list[BodyReport]) -> list[str]:
    problems = []
    if overlapping:
        shown = ", ".join(f"{a}-{b}" for a, b in overlapping[:5])
        more = f" and {len(overlapping) - 5} more" if len(overlapping) > 5 else ""
        problems.append(f"{plural(len(overlapping), 'pair')} of bodies intersect or touch "
                        f"(bodies {shown}{more})")
    if status not in ("NoError", "skipped") and not any(b.problems for b in bodies):
        problems.append(f"manifold3d refuses it (status {status})")
    return problems


def _offending(m: _Merged, fg: _Faces, topo: EdgeTopology, st: _Structure,
               duplicates: np.ndarray, pairs: np.ndarray, hits: np.ndarray
               ) -> dict[str, np.ndarray]:
    def edges_where(mask: np.ndarray) -> np.ndarray:
        return m.first[topo.edge_vertices[mask]].reshape(-1, 2)

    return {
        "open_edges": edges_where(topo.counts == 1),
        "nonmanifold_edges": edges_where(topo.counts > 2),
        "inconsistent_edges": edges_where(topo.inconsistent),
        "nonmanifold_vertices": m.first[st.nm_vertices],
        "flipped_faces": st.flipped.astype(np.int64),
        "degenerate_faces": np.flatnonzero(fg.degenerate),
        "duplicate_faces": duplicates.astype(np.int64),
        "intersecting_faces": np.flatnonzero(hits),
        "intersecting_pairs": pairs.astype(np.int64).reshape(-1, 2),
    }


def validate_arrays(
    vertices: Any,
    faces: Any,
    *,
    path: str | os.PathLike | None = None,
    check_intersections: bool = True,
    check_manifold3d: bool = True,
) -> ValidationReport:
    """Validate a triangle mesh given as arrays (see the module docstring for the checks).

    Args:
        vertices: (V, 3) positions in file units, file frame.
        faces: (F, 3) vertex indices; counter-clockwise seen from outside is outward.
        path: the file the arrays came from, for messages and the report (optional).
        check_intersections: run the self-intersection test (the slowest check).
        check_manifold3d: ask manifold3d for its status of the whole mesh (an independent
            second opinion, a sizeable share of the time on large meshes). With False the
            report's ``manifold_status`` is "skipped".

    Returns:
        A :class:`ValidationReport`; ``report.passed`` says whether it is watertight.

    Raises:
        InputError: the arrays are not (V, 3) numbers and (F, 3) integers.
    """
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    path_str = None if path is None else os.fspath(path)
    vertices, faces = _as_arrays(vertices, faces)
    n_vertices, n_faces = len(vertices), len(faces)
    if n_faces == 0:
        return empty_report(path_str, n_vertices, 0, "no triangles (empty, points or lines "
                            "only)", seconds)
    if faces.min() < 0 or faces.max() >= n_vertices:
        return empty_report(path_str, n_vertices, n_faces, "faces refer to vertices that do "
                            "not exist (the file is damaged)", seconds)
    used, local = meshcheck.used_vertices(faces, n_vertices)  # np.unique, searchsorted
    if not np.all(np.isfinite(vertices[used])):
        bad = int(np.sum(~np.all(np.isfinite(vertices[used]), axis=1)))
        return empty_report(path_str, n_vertices, n_faces,
                            f"{plural(bad, 'vertex', 'vertices')} with NaN or infinite "
                            "coordinates", seconds)
    largest = float(np.abs(vertices[used]).max())
    if largest > MAX_COORDINATE:  # lengths cubed overflow: volumes and areas would be NaN
        return empty_report(path_str, n_vertices, n_faces,
                            f"coordinates as large as {largest:.3g} (beyond "
                            f"{MAX_COORDINATE:g} volumes overflow; wrong units?)", seconds)
    m = _merge(vertices, used, local)
    seconds["merge"] = time.perf_counter() - t0

    t = time.perf_counter()
    fg = _face_measures(m)
    topo = edge_topology(m.faces, len(m.positions), fg.proper)
    duplicates = duplicate_faces(m.faces, fg.proper, topo)
    seconds["topology"] = time.perf_counter() - t

    # where a core is free the test runs alongside the stages below and manifold3d (which
    # holds the GIL); its seconds are then its own wall time, until its result is taken
    t_pairs = time.perf_counter()
    in_thread = check_intersections and check_manifold3d and spare_core()
    pending = _start_intersections(m, fg, duplicates, check_intersections, in_thread)
    if check_intersections and not in_thread:
        seconds["self_intersections"] = time.perf_counter() - t_pairs

    t = time.perf_counter()
    st = _structure(m, fg, topo)
    seconds["topology"] += time.perf_counter() - t

    t = time.perf_counter()
    sums = _body_sums(m, fg, topo, st, duplicates)
    seconds["bodies"] = time.perf_counter() - t

    t = time.perf_counter()
    closed = (sums["open_edges"] == 0) & (sums["nonmanifold_edges"] == 0) & (
        sums["proper_faces"] > 0)
    oriented = closed & (sums["inconsistent_edges"] == 0) & (sums["nonorientable_faces"] == 0)
    inside, outside, nesting_checked = nesting(m.positions, m.faces, st.face_body, closed,
                                               oriented, fg.area2 * fg.proper, sums["lo"],
                                               sums["hi"])
    seconds["nesting"] = time.perf_counter() - t

    # manifold3d's view of the whole mesh (while the intersection test goes on, if it does)
    status = "skipped"
    if check_manifold3d:
        t = time.perf_counter()
        status = manifold_status(m.positions, m.faces).name
        seconds["manifold3d"] = time.perf_counter() - t

    pairs, n_pairs, hits = pending()
    if in_thread:
        seconds["self_intersections"] = time.perf_counter() - t_pairs
    pair_body = st.face_body[pairs]
    same = pair_body[:, 0] == pair_body[:, 1]
    self_body = np.bincount(pair_body[same, 0], minlength=st.n_bodies)
    overlapping = sorted({(int(a), int(b)) for a, b in np.sort(pair_body[~same], axis=1)})

    bodies = _body_reports(sums, closed, self_body, inside, outside, nesting_checked,
                           ZERO_VOLUME_FRACTION * fg.diagonal**3)
    problems = _file_problems(overlapping, status, bodies)
    if unwelded_share(m.positions, topo, fg.diagonal) >= UNWELDED_SHARE:
        # one body per triangle, each "holed": say what it is and how to fix it
        problems.insert(0, "its faces are not joined: the open edges' corners lie within "
                        f"{CRACK_TOLERANCE * fg.diagonal:.3g} units of another face's (its "
                        "vertices were never welded, or were rounded apart); merge the "
                        "vertices by distance")
    offending = _offending(m, fg, topo, st, duplicates, pairs, hits)
    seconds["total"] = time.perf_counter() - t0
    return ValidationReport(
        path=path_str, n_vertices=n_vertices, n_faces=n_faces, n_positions=len(m.positions),
        bodies=tuple(bodies), volume=float(sums["volume"].sum()),
        area=float(sums["area"].sum()),
        bbox_min=tuple(float(x) for x in fg.lo), bbox_max=tuple(float(x) for x in fg.hi),
        intersecting_pairs=int(n_pairs), overlapping_bodies=tuple(overlapping),
        nesting_checked=nesting_checked, manifold_status=status, problems=tuple(problems),
        offending=offending, face_body=st.face_body, seconds=seconds,
    )


def validate_file(path: str | os.PathLike, *, check_intersections: bool = True,
                  check_manifold3d: bool = True) -> ValidationReport:
    """Read a mesh file as written (see :func:`jampacked.core.mesh_files.read_mesh_arrays`: no
    merging or repair) and validate it with :func:`validate_arrays` (the flags are its).

    Raises:
        MeshError: the file is missing, unreadable, or of an unknown type, or a 3MF package
            that breaks the 3MF core specification (the message names the file and what is
            wrong).
    """
    t = time.perf_counter()
    vertices, faces = read_mesh_arrays(path)
    read_seconds = time.perf_counter() - t
    report = validate_arrays(vertices, faces, path=path,
                             check_intersections=check_intersections,
                             check_manifold3d=check_manifold3d)
    report.seconds["read"] = read_seconds
    return report
