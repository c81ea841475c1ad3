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
how a slicer reads it). Nothing else is merged, removed or repaired. Offending elements are
reported like Blender's 3D-Print Toolbox, as indices into the arrays given (or the arrays
read from the file): faces by index, edges as pairs of vertex indices, vertices by index
(the first vertex at that position).

Units and frame are the mesh's own (container units, mm for printing).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from jampacked.core.errors import InputError
from jampacked.core.meshes import MERGE_TOLERANCE, ZERO_VOLUME_FRACTION, _manifold_status

from . import meshcheck
from .intersect import (
    TOL_REL,
    intersecting_pairs,
    ray_winding_numbers,
    start_intersecting_pairs,
    winding_numbers,
)

__all__ = ["BodyReport", "ValidationReport", "validate_arrays", "validate_file"]

#: a face whose height is at most this fraction of the bounding-box diagonal is degenerate
DEGENERATE_REL = MERGE_TOLERANCE
#: skip the nesting test when it would sum more solid angles than this
NESTING_BUDGET = 300_000_000
#: what the self-intersection test is, in words (reports carry it)
SELF_INTERSECTION_METHOD = (
    "float64 triangle-triangle tests (Möller intervals; shared vertex/edge cases; coplanar "
    f"pairs in 2D) on all face pairs with overlapping boxes (BVH); contacts within {TOL_REL:g} "
    "of a pair's size count"
)

OFFENDING_KINDS = (
    "open_edges",
    "nonmanifold_edges",
    "inconsistent_edges",
    "nonmanifold_vertices",
    "flipped_faces",
    "degenerate_faces",
    "duplicate_faces",
    "intersecting_faces",
    "intersecting_pairs",
)


# --------------------------------------------------------------------------------------------
# result types


@dataclass(frozen=True)
class BodyReport:
    """Checks of one body (edge-connected faces). Lengths in file units.

    Attributes:
        index: body number, in the order of each body's first face.
        faces, vertices, edges: counts (vertices: distinct positions; edges: undirected).
        volume: signed volume, units³ (negative: faces point inwards); area: units².
        bbox_min, bbox_max: (3,) corners of its axis-aligned bounding box.
        open_edges, holes, nonmanifold_edges, nonmanifold_vertices, inconsistent_edges,
        flipped_faces, degenerate_faces, duplicate_faces: defect counts (see the module).
        orientable: False if some patch of the surface has no consistent winding.
        self_intersections: intersecting (or touching) face pairs inside this body.
        inside: indices of the closed bodies that contain it (by winding number).
        kind: "solid" (outward, outside every solid), "cavity" (inward, inside one solid),
            "inside-out", "nested solid" (a solid inside a solid), "nested cavity", "open"
            (open edges), "non-manifold" (edges used by more than two faces), "unknown"
            (closed, but its nesting was not checked).
        genus: handles of a closed, orientable, edge-manifold body, else None.
        problems: one short phrase per defect, empty when it passes.
    """

    index: int
    faces: int
    vertices: int
    edges: int
    volume: float
    area: float
    bbox_min: tuple[float, float, float]
    bbox_max: tuple[float, float, float]
    open_edges: int
    holes: int
    nonmanifold_edges: int
    nonmanifold_vertices: int
    inconsistent_edges: int
    flipped_faces: int
    orientable: bool
    degenerate_faces: int
    duplicate_faces: int
    self_intersections: int
    inside: tuple[int, ...]
    kind: str
    genus: int | None
    problems: tuple[str, ...]

    @property
    def closed(self) -> bool:
        """Every edge used by exactly two faces."""
        return self.open_edges == 0 and self.nonmanifold_edges == 0

    @property
    def outward(self) -> bool:
        """Its winding is right for its place: a solid outward, a cavity inward."""
        return self.kind in ("solid", "cavity")

    @property
    def passed(self) -> bool:
        """Closed, 2-manifold, consistently and outward wound, clean, no self-intersection."""
        return not self.problems

    def as_dict(self) -> dict[str, Any]:
        """JSON-able dict of every attribute plus closed/outward/passed."""
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out["bbox_min"] = list(self.bbox_min)
        out["bbox_max"] = list(self.bbox_max)
        out["inside"] = list(self.inside)
        out["problems"] = list(self.problems)
        out.update(closed=self.closed, outward=self.outward, passed=self.passed)
        return out


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """The result of validating one mesh (a file as read back, or arrays).

    Attributes:
        path: the file validated, or None for arrays.
        n_vertices, n_faces: as given (or read); n_positions: distinct positions of the
            vertices that faces use (unreferenced vertices are ignored).
        bodies: one :class:`BodyReport` per body.
        volume: sum of the bodies' signed volumes, units³ (solids minus cavities).
        area: total surface area, units².
        bbox_min, bbox_max: (3,) bounding box of all vertices used by faces, file frame.
        intersecting_pairs: face pairs that intersect or touch, within and between bodies.
        overlapping_bodies: pairs of bodies whose surfaces intersect or touch.
        nesting_checked: False when the nesting test was skipped (too large).
        manifold_status: manifold3d's status name for the whole mesh ("NoError" when it
            accepts it), or "skipped".
        problems: file-level problems (empty file, bad indices, overlapping bodies, ...).
        offending: offending element indices by kind (see ``OFFENDING_KINDS``): faces and
            vertices (K,), edges and pairs (K, 2), int64, indices into the arrays given.
        face_body: (n_faces,) body of each face.
        seconds: time taken per stage.
    """

    path: str | None
    n_vertices: int
    n_faces: int
    n_positions: int
    bodies: tuple[BodyReport, ...]
    volume: float
    area: float
    bbox_min: tuple[float, float, float]
    bbox_max: tuple[float, float, float]
    intersecting_pairs: int
    overlapping_bodies: tuple[tuple[int, int], ...]
    nesting_checked: bool
    manifold_status: str
    problems: tuple[str, ...]
    offending: dict[str, np.ndarray] = field(repr=False)
    face_body: np.ndarray = field(repr=False)
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """True when the mesh is watertight (see the module docstring) in every body."""
        return not self.problems and bool(self.bodies) and all(b.passed for b in self.bodies)

    @property
    def name(self) -> str:
        return os.path.basename(self.path) if self.path else "mesh"

    def failures(self) -> list[str]:
        """Every problem as a phrase: file-level first, then 'body k: ...'."""
        out = list(self.problems)
        many = len(self.bodies) > 1
        for b in self.bodies:
            out += [f"body {b.index}: {p}" if many else p for p in b.problems]
        return out

    def summary(self) -> str:
        """One line: ``PASS name: ...`` or ``FAIL name: ...``."""
        if self.passed:
            n = len(self.bodies)
            cavities = sum(b.kind == "cavity" for b in self.bodies)
            genus = sorted({b.genus for b in self.bodies if b.genus is not None})
            parts = [f"{n} bod{'y' if n == 1 else 'ies'}"]
            if cavities:
                parts.append(f"{cavities} cavit{'y' if cavities == 1 else 'ies'}")
            parts.append(f"volume {self.volume:.6g} units³")
            parts.append("genus " + "/".join(str(g) for g in genus))
            parts.append(f"{self.n_faces} faces")
            return f"PASS {self.name}: " + ", ".join(parts) + "; watertight"
        failures = self.failures()
        shown = "; ".join(failures[:4])
        if len(failures) > 4:
            shown += f"; and {len(failures) - 4} more"
        return f"FAIL {self.name}: {shown}"

    def as_dict(self, max_indices: int | None = 1000) -> dict[str, Any]:
        """JSON-able dict. Offending index lists are cut to ``max_indices`` each (None: all);
        ``offending_counts`` gives the full lengths."""
        offending = {}
        for kind, arr in self.offending.items():
            arr = arr if max_indices is None else arr[:max_indices]
            offending[kind] = arr.tolist()
        return {
            "format": "jampacked.validation",
            "version": 1,
            "path": self.path,
            "passed": self.passed,
            "summary": self.summary(),
            "n_vertices": self.n_vertices,
            "n_faces": self.n_faces,
            "n_positions": self.n_positions,
            "n_bodies": len(self.bodies),
            "volume": self.volume,
            "area": self.area,
            "bbox_min": _finite_list(self.bbox_min),
            "bbox_max": _finite_list(self.bbox_max),
            "intersecting_pairs": self.intersecting_pairs,
            "overlapping_bodies": [list(p) for p in self.overlapping_bodies],
            "nesting_checked": self.nesting_checked,
            "manifold_status": self.manifold_status,
            "problems": list(self.problems),
            "bodies": [b.as_dict() for b in self.bodies],
            "offending": offending,
            "offending_counts": {k: int(len(v)) for k, v in self.offending.items()},
            "self_intersection_method": SELF_INTERSECTION_METHOD,
            "seconds": {k: round(v, 4) for k, v in self.seconds.items()},
        }


def _finite_list(values: tuple[float, ...]) -> list[float | None]:
    """JSON has no NaN: non-finite numbers become None."""
    return [float(v) if math.isfinite(v) else None for v in values]


# --------------------------------------------------------------------------------------------
# topology helpers (vectorised; faces are (F, 3) int64 into merged positions)


def _plural(n: int, word: str, plural: str | None = None) -> str:
    return f"{n} {word if n == 1 else (plural or word + 's')}"


def merge_identical(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices at exactly identical positions (0.0 and -0.0 are the same).

    Args:
        vertices: (V, 3) float64.

    Returns:
        ``(first, remap)``: (U,) index of the first vertex at each distinct position, in
        order of first occurrence, and (V,) the distinct position of each vertex.
    """
    v = np.ascontiguousarray(vertices, dtype=np.float64) + 0.0  # turns -0.0 into 0.0
    if len(v) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    # a hash table on the coordinates' bits: one pass, groups numbered as they appear
    return meshcheck.merge_bits(v.view(np.uint64).reshape(-1, 3))


@dataclass
class _Topology:
    """Edge structure (see :func:`jampacked.export.meshcheck.edge_structure`). Corner
    c = 3 * face + slot starts the half-edge to the next vertex of its face; self-loops
    (a->a) have no edge. Use counts and pairing come from the faces with three distinct
    vertices ("proper" faces) only."""

    corner_edge: np.ndarray  # (3F,) edge of each corner, -1 for a self-loop
    edge_vertices: np.ndarray  # (E, 2) smaller, larger vertex
    counts: np.ndarray  # (E,) proper faces using each edge
    first_corner: np.ndarray  # (E,) first proper corner of edges used twice, else -1
    second_corner: np.ndarray  # (E,) second proper corner of edges used twice, else -1
    inconsistent: np.ndarray  # (E,) bool: used by two faces running the same way
    face_of_edge: np.ndarray  # (E,) the face of each edge's last corner


def _topology(faces: np.ndarray, proper: np.ndarray, n_vertices: int) -> _Topology:
    """Undirected edges, their use counts, and the two corners of each edge used twice."""
    return _Topology(*meshcheck.edge_structure(faces, proper, n_vertices))


@njit(cache=True)
def _roots(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Union-find over n nodes joined by edges a-b: each node's root, the smallest node of
    its connected component."""
    parent = np.arange(n)
    for k in range(a.shape[0]):
        x = a[k]
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        y = b[k]
        while parent[y] != y:
            parent[y] = parent[parent[y]]
            y = parent[y]
        if x < y:
            parent[y] = x
        elif y < x:
            parent[x] = y
    for i in range(n):  # parent[i] <= i, so parents are final when i is reached
        parent[i] = parent[parent[i]]
    return parent


def _bodies(faces: np.ndarray, proper: np.ndarray, topo: _Topology) -> tuple[int, np.ndarray]:
    """Body of each face, numbered in the order of each body's first proper face.

    Proper faces sharing an edge are in one body. A face with a repeated vertex (a line or a
    point) joins the body of a proper face at one of its vertices, or is a body of its own.
    """
    if len(faces) == 0:
        return 0, np.zeros(0, np.int64)
    n, body = meshcheck.face_bodies(len(faces), proper, faces, topo.corner_edge,
                                    len(topo.counts))
    return int(n), body


def _fans(faces: np.ndarray, proper: np.ndarray, topo: _Topology) -> tuple[np.ndarray, np.ndarray]:
    """Fans of faces around each vertex, joined across edges used by exactly two faces.

    Returns (vertex of each fan, a proper face of each fan).
    """
    return meshcheck.fans(faces, proper, topo.first_corner, topo.second_corner,
                          topo.inconsistent)


def _flipped(n_faces: int, topo: _Topology) -> tuple[np.ndarray, np.ndarray]:
    """Faces whose winding disagrees with the majority of their patch, and faces on
    non-orientable patches. A patch: faces joined across edges used by exactly two faces."""
    return meshcheck.flipped_faces(n_faces, topo.first_corner, topo.second_corner,
                                   topo.inconsistent)


def _duplicates(faces: np.ndarray, proper: np.ndarray, topo: _Topology) -> np.ndarray:
    """Indices of proper faces on the same three vertices as an earlier face (any winding)."""
    return meshcheck.duplicate_faces(faces, proper, topo.corner_edge, topo.counts,
                                     topo.first_corner, topo.second_corner)


def _holes(topo: _Topology, face_body: np.ndarray, n_bodies: int) -> np.ndarray:
    """Boundary loops (connected groups of open edges) per body."""
    open_edges = np.flatnonzero(topo.counts == 1)
    if len(open_edges) == 0:
        return np.zeros(n_bodies, np.int64)
    ev = topo.edge_vertices[open_edges]
    used, local = np.unique(ev, return_inverse=True)
    local = local.reshape(-1, 2)
    loop = _roots(len(used), local[:, 0], local[:, 1])[local[:, 0]]
    # the body of an open edge: the body of a face using it
    body = face_body[topo.face_of_edge[open_edges]]
    keys = np.unique(body * np.int64(len(used)) + loop)
    return np.bincount(keys // len(used), minlength=n_bodies)


@njit(cache=True)
def _largest_faces(face_body: np.ndarray, areas: np.ndarray, n_bodies: int) -> np.ndarray:
    """The largest face of each body (the first of equal ones; NaN counts as smallest;
    -1 for a body without faces)."""
    best = np.full(n_bodies, -1, np.int64)
    for f in range(face_body.shape[0]):
        b = face_body[f]
        k = best[b]
        if k < 0:
            best[b] = f
            continue
        a, m = areas[f], areas[k]
        if a > m or (m != m and a == a):
            best[b] = f
    return best


def _nesting(
    vertices: np.ndarray,
    faces: np.ndarray,
    face_body: np.ndarray,
    closed: np.ndarray,
    oriented: np.ndarray,
    areas: np.ndarray,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
) -> tuple[list[list[int]], np.ndarray, bool]:
    """For each closed body: the closed bodies containing it, and the winding number just
    outside it (sum over the others). Returns (inside lists, winding_outside, checked).

    ``oriented``: bodies whose every edge is used once each way (their winding numbers come
    from ray crossings); ``areas``: (F,) face areas (any scale), 0 for improper faces."""
    n = len(closed)
    inside: list[list[int]] = [[] for _ in range(n)]
    outside = np.zeros(n, np.int64)
    idx = np.flatnonzero(closed)
    if len(idx) < 2:
        return inside, outside, True
    lo, hi = box_lo[idx], box_hi[idx]
    contains = np.all(lo[:, None, :] <= lo[None, :, :], axis=2) & np.all(
        hi[None, :, :] <= hi[:, None, :], axis=2
    )  # contains[j, k]: box of idx[j] holds box of idx[k]
    np.fill_diagonal(contains, False)
    jj, kk = np.nonzero(contains)
    if len(jj) == 0:
        return inside, outside, True
    n_faces_body = np.bincount(face_body, minlength=n)
    if int(n_faces_body[idx[jj]].sum()) > NESTING_BUDGET:
        return inside, outside, False
    # a query point on each inner body: the centroid of its largest proper face
    first = _largest_faces(face_body, areas, n)
    points = vertices[faces[first]].mean(axis=1)
    by_body = np.argsort(face_body, kind="stable")  # each body's faces, in order
    starts = np.searchsorted(face_body[by_body], np.arange(n + 1))
    for j in np.unique(jj):
        outer = idx[j]
        inner = idx[kk[jj == j]]
        outer_faces = faces[by_body[starts[outer]:starts[outer + 1]]]
        if oriented[outer]:
            # ray crossings give the same integer as the generalised winding number on a
            # closed, consistently wound surface, at a fraction of the cost; ambiguous rays
            # (grazing an edge, or a point on the surface) fall back to the solid angles
            w, ok = ray_winding_numbers(points[inner], vertices, outer_faces)
            if not np.all(ok):
                w[~ok] = np.rint(winding_numbers(points[inner[~ok]], vertices, outer_faces))
        else:
            w = np.rint(winding_numbers(points[inner], vertices, outer_faces)).astype(np.int64)
        for k, wk in zip(inner, w, strict=True):
            if wk != 0:
                inside[int(k)].append(int(outer))
                outside[int(k)] += wk
    return inside, outside, True


# --------------------------------------------------------------------------------------------
# the validation


def _body_kind(open_edges: int, closed: bool, volume: float, outside: int, checked: bool
               ) -> str:
    if not closed:
        return "open" if open_edges else "non-manifold"
    if not checked:
        return "unknown" if outside == 0 else ("solid" if volume > 0 else "inside-out")
    if outside == 0:
        return "solid" if volume > 0 else "inside-out"
    if outside == 1:
        return "cavity" if volume < 0 else "nested solid"
    return "nested solid" if volume > 0 else "nested cavity"


def _body_problems(b: dict[str, Any], zero_volume: float) -> list[str]:
    out = []
    if b["open_edges"]:
        out.append(f"{_plural(b['open_edges'], 'open edge')} around "
                   f"{_plural(b['holes'], 'hole')}")
    if b["nonmanifold_edges"]:
        out.append(f"{_plural(b['nonmanifold_edges'], 'non-manifold edge')} (used by more "
                   "than two faces)")
    if b["nonmanifold_vertices"]:
        n = b["nonmanifold_vertices"]
        out.append(f"{_plural(n, 'non-manifold vertex', 'non-manifold vertices')} (surfaces "
                   "meet only at a point)")
    if not b["orientable"]:
        out.append("non-orientable (no consistent winding exists)")
    elif b["inconsistent_edges"]:
        out.append(f"{_plural(b['flipped_faces'], 'face')} wound against "
                   f"{'its' if b['flipped_faces'] == 1 else 'their'} neighbours "
                   f"({_plural(b['inconsistent_edges'], 'edge')} whose two faces run the same "
                   "way)")
    if b["degenerate_faces"]:
        out.append(f"{_plural(b['degenerate_faces'], 'degenerate face')} (zero area or a "
                   "repeated vertex)")
    if b["duplicate_faces"]:
        out.append(f"{_plural(b['duplicate_faces'], 'duplicate face')}")
    if b["self_intersections"]:
        out.append(f"self-intersecting ({_plural(b['self_intersections'], 'face pair')} "
                   "intersect or touch)")
    kind = b["kind"]
    if kind not in ("open", "non-manifold") and abs(b["volume"]) <= zero_volume:
        out.append(f"zero volume ({b['volume']:.3g} units³)")
    elif kind == "inside-out":
        out.append(f"inside out (volume {b['volume']:.6g} units³: normals point inwards)")
    elif kind == "nested solid":
        out.append(f"a solid inside body {b['inside'][0]} (overlapping solids)")
    elif kind == "nested cavity":
        out.append("a cavity inside a cavity or nested more than one deep")
    return out


def _finish_empty(path: str | None, n_vertices: int, n_faces: int, problem: str,
                  seconds: dict[str, float]) -> ValidationReport:
    nan3 = (math.nan, math.nan, math.nan)
    return ValidationReport(
        path=path, n_vertices=n_vertices, n_faces=n_faces, n_positions=0, bodies=(),
        volume=0.0, area=0.0, bbox_min=nan3, bbox_max=nan3, intersecting_pairs=0,
        overlapping_bodies=(), nesting_checked=True, manifold_status="skipped",
        problems=(problem,), offending={k: np.zeros(0, np.int64) for k in OFFENDING_KINDS},
        face_body=np.full(n_faces, -1, np.int64), seconds=seconds)


def _spare_core() -> bool:
    """Whether a second thread is likely to get a core of its own: two or more CPUs and a
    1-minute load average (this process included) below their number by a quarter CPU; True
    where there is no load average (Windows). On a busy machine the intersection test and
    manifold3d only slow each other down, so they then run one after the other."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:
        cpus = os.cpu_count() or 1
    if cpus < 2:
        return False
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        return True
    return load < cpus - 0.25


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
            second opinion; about a third of the time on large meshes). With False the
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
        return _finish_empty(path_str, n_vertices, 0, "no triangles (empty, points or lines "
                             "only)", seconds)
    if faces.min() < 0 or faces.max() >= n_vertices:
        return _finish_empty(path_str, n_vertices, n_faces, "faces refer to vertices that do "
                             "not exist (the file is damaged)", seconds)
    used, local = meshcheck.used_vertices(faces, n_vertices)  # np.unique, searchsorted
    if not np.all(np.isfinite(vertices[used])):
        bad = int(np.sum(~np.all(np.isfinite(vertices[used]), axis=1)))
        return _finish_empty(path_str, n_vertices, n_faces, f"{_plural(bad, 'vertex', 'vertices')} "
                             "with NaN or infinite coordinates", seconds)

    # unreferenced vertices are ignored; `first` maps back to indices into `vertices`
    first_used, remap = merge_identical(vertices[used])
    first = used[first_used]
    positions = vertices[first]
    mf = remap[local]
    seconds["merge"] = time.perf_counter() - t0

    t = time.perf_counter()
    lo_all, hi_all = positions.min(axis=0), positions.max(axis=0)
    diagonal = float(np.linalg.norm(hi_all - lo_all))
    # repeated vertex, |cross| (as _face_areas2), longest edge, 6 x signed volume (as
    # _signed_six_volumes, about the box centre)
    repeated, area2, longest, six = meshcheck.face_geometry(positions, mf,
                                                           0.5 * (lo_all + hi_all))
    proper = ~repeated
    height = area2 / np.maximum(longest, np.finfo(float).tiny)
    degenerate = repeated | (height <= DEGENERATE_REL * diagonal)

    topo = _topology(mf, proper, len(positions))
    duplicates = _duplicates(mf, proper, topo)
    seconds["topology"] = time.perf_counter() - t

    # self-intersections. Where a core is free the test (numba, without the GIL) runs in a
    # thread from here on, alongside the stages below and manifold3d (which holds the GIL);
    # its seconds are then its own wall time, until its result is taken.
    t_pairs = time.perf_counter()
    active = ~degenerate
    active[duplicates] = False
    pending = None
    pairs, n_pairs, hits = np.zeros((0, 2), np.int64), 0, np.zeros(n_faces, np.int64)
    if check_intersections and check_manifold3d and _spare_core():
        pending = start_intersecting_pairs(positions, mf, active)
    elif check_intersections:
        pairs, n_pairs, hits = intersecting_pairs(positions, mf, active)
        seconds["self_intersections"] = time.perf_counter() - t_pairs

    t = time.perf_counter()
    n_bodies, face_body = _bodies(mf, proper, topo)
    fan_vertex, fan_face = _fans(mf, proper, topo)
    fans_per_vertex = np.bincount(fan_vertex, minlength=len(positions))
    nm_vertices = np.flatnonzero(fans_per_vertex > 1)
    flipped, nonorientable = _flipped(n_faces, topo)
    seconds["topology"] += time.perf_counter() - t

    # per-body sums
    t = time.perf_counter()
    edge_body = face_body[topo.face_of_edge]
    used_edge = topo.counts > 0

    def per_body(values: np.ndarray, labels: np.ndarray) -> np.ndarray:
        return np.bincount(labels, weights=values, minlength=n_bodies)

    def count(mask: np.ndarray, labels: np.ndarray) -> np.ndarray:
        return np.bincount(labels[mask], minlength=n_bodies).astype(np.int64)

    volume = per_body(six, face_body) / 6.0
    area = per_body(area2, face_body) / 2.0
    n_face_body = count(np.ones(n_faces, bool), face_body)
    n_proper_body = count(proper, face_body)
    n_edge_body = count(used_edge, edge_body)
    open_body = count(topo.counts == 1, edge_body)
    nm_edge_body = count(topo.counts > 2, edge_body)
    incons_body = count(topo.inconsistent, edge_body)
    fan_body = face_body[fan_face]
    fans_body = np.bincount(fan_body, minlength=n_bodies)
    nm_vertex_mask = np.zeros(len(positions), bool)
    nm_vertex_mask[nm_vertices] = True
    # distinct vertices, non-manifold ones and the box of each body
    verts_body, nm_vert_body, box_lo, box_hi = meshcheck.body_vertices(
        mf, face_body, n_bodies, positions, nm_vertex_mask)
    flipped_body = np.bincount(face_body[flipped], minlength=n_bodies)
    nonorientable_body = np.bincount(face_body[nonorientable], minlength=n_bodies)
    degenerate_body = count(degenerate, face_body)
    duplicate_body = np.bincount(face_body[duplicates], minlength=n_bodies)
    holes_body = _holes(topo, face_body, n_bodies)
    seconds["bodies"] = time.perf_counter() - t

    # nesting and orientation
    t = time.perf_counter()
    closed = (open_body == 0) & (nm_edge_body == 0) & (n_proper_body > 0)
    oriented = closed & (incons_body == 0) & (nonorientable_body == 0)
    inside, outside, nesting_checked = _nesting(positions, mf, face_body, closed, oriented,
                                                area2 * proper, box_lo, box_hi)
    seconds["nesting"] = time.perf_counter() - t

    # manifold3d's view of the whole mesh (while the intersection test goes on, if it does)
    status = "skipped"
    if check_manifold3d:
        t = time.perf_counter()
        status = _manifold_status(positions, mf).name
        seconds["manifold3d"] = time.perf_counter() - t

    if pending is not None:
        pairs, n_pairs, hits = pending()
        seconds["self_intersections"] = time.perf_counter() - t_pairs
    pair_body = face_body[pairs]
    same = pair_body[:, 0] == pair_body[:, 1]
    self_body = np.bincount(pair_body[same, 0], minlength=n_bodies)
    overlapping = sorted({(int(a), int(b)) for a, b in np.sort(pair_body[~same], axis=1)})

    zero_volume = ZERO_VOLUME_FRACTION * diagonal**3
    bodies = []
    for k in range(n_bodies):
        is_closed = bool(closed[k])
        orientable = bool(nonorientable_body[k] == 0)
        genus = None
        if is_closed and orientable and incons_body[k] == 0:
            chi = int(fans_body[k]) - int(n_edge_body[k]) + int(n_proper_body[k])
            genus = (2 - chi) // 2 if chi % 2 == 0 else None
        fields = dict(
            index=k, faces=int(n_face_body[k]), vertices=int(verts_body[k]),
            edges=int(n_edge_body[k]), volume=float(volume[k]), area=float(area[k]),
            bbox_min=tuple(float(x) for x in box_lo[k]),
            bbox_max=tuple(float(x) for x in box_hi[k]),
            open_edges=int(open_body[k]), holes=int(holes_body[k]),
            nonmanifold_edges=int(nm_edge_body[k]), nonmanifold_vertices=int(nm_vert_body[k]),
            inconsistent_edges=int(incons_body[k]), flipped_faces=int(flipped_body[k]),
            orientable=orientable, degenerate_faces=int(degenerate_body[k]),
            duplicate_faces=int(duplicate_body[k]), self_intersections=int(self_body[k]),
            inside=tuple(inside[k]),
            kind=_body_kind(int(open_body[k]), is_closed, float(volume[k]), int(outside[k]),
                            nesting_checked),
            genus=genus,
        )
        fields["problems"] = tuple(_body_problems(fields, zero_volume))
        bodies.append(BodyReport(**fields))

    problems = []
    if overlapping:
        shown = ", ".join(f"{a}-{b}" for a, b in overlapping[:5])
        more = f" and {len(overlapping) - 5} more" if len(overlapping) > 5 else ""
        problems.append(f"{_plural(len(overlapping), 'pair')} of bodies intersect or touch "
                        f"(bodies {shown}{more})")

    if status not in ("NoError", "skipped") and not any(b.problems for b in bodies):
        problems.append(f"manifold3d refuses it (status {status})")

    def edges_where(mask: np.ndarray) -> np.ndarray:
        return first[topo.edge_vertices[mask]].reshape(-1, 2)

    offending = {
        "open_edges": edges_where(topo.counts == 1),
        "nonmanifold_edges": edges_where(topo.counts > 2),
        "inconsistent_edges": edges_where(topo.inconsistent),
        "nonmanifold_vertices": first[nm_vertices],
        "flipped_faces": flipped.astype(np.int64),
        "degenerate_faces": np.flatnonzero(degenerate),
        "duplicate_faces": duplicates.astype(np.int64),
        "intersecting_faces": np.flatnonzero(hits),
        "intersecting_pairs": pairs.astype(np.int64).reshape(-1, 2),
    }
    seconds["total"] = time.perf_counter() - t0
    return ValidationReport(
        path=path_str, n_vertices=n_vertices, n_faces=n_faces, n_positions=len(positions),
        bodies=tuple(bodies), volume=float(volume.sum()), area=float(area.sum()),
        bbox_min=tuple(float(x) for x in lo_all), bbox_max=tuple(float(x) for x in hi_all),
        intersecting_pairs=int(n_pairs), overlapping_bodies=tuple(overlapping),
        nesting_checked=nesting_checked, manifold_status=status, problems=tuple(problems),
        offending=offending, face_body=face_body, seconds=seconds,
    )


def validate_file(path: str | os.PathLike, *, check_intersections: bool = True,
                  check_manifold3d: bool = True) -> ValidationReport:
    """Read a mesh file as written (see :func:`jampacked.export.io.read_mesh_arrays`: no
    merging or repair) and validate it with :func:`validate_arrays` (the flags are its).

    Raises:
        MeshError: the file is missing, unreadable, or of an unknown type (the message names
            the file).
    """
    from .io import read_mesh_arrays

    t = time.perf_counter()
    vertices, faces = read_mesh_arrays(path)
    read_seconds = time.perf_counter() - t
    report = validate_arrays(vertices, faces, path=path,
                             check_intersections=check_intersections,
                             check_manifold3d=check_manifold3d)
    report.seconds["read"] = read_seconds
    return report
