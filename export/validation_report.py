"""The results of validating a mesh: per-body and whole-file reports, and their wording.

Field meanings are those of :mod:`jampacked.export.validate` (what is checked and how).
Lengths, areas and volumes are in the mesh's units; indices refer to the arrays validated.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from jampacked.core.errors import plural
from jampacked.core.mesh_files import length_unit

from .intersect import TOL_REL

__all__ = ["OFFENDING_KINDS", "SELF_INTERSECTION_METHOD", "BodyReport", "ValidationReport",
           "body_kind", "body_problems", "empty_report", "finite_list"]

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
            cavities = sum(b.kind == "cavity" for b in self.bodies)
            n = len(self.bodies) - cavities  # a cavity is the inside of a body, not one
            genus = sorted({b.genus for b in self.bodies if b.genus is not None})
            parts = [f"{n} bod{'y' if n == 1 else 'ies'}"]
            if cavities:
                parts.append(f"{cavities} cavit{'y' if cavities == 1 else 'ies'}")
            parts.append(f"volume {self.volume:.6g} {length_unit(self.path)}³")
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
            "bbox_min": finite_list(self.bbox_min),
            "bbox_max": finite_list(self.bbox_max),
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


def finite_list(values: tuple[float, ...]) -> list[float | None]:
    """JSON has no NaN: non-finite numbers become None."""
    return [float(v) if math.isfinite(v) else None for v in values]


def body_kind(open_edges: int, closed: bool, volume: float, outside: int, checked: bool
               ) -> str:
    """The body's kind for :attr:`BodyReport.kind` from its closure, signed volume and the
    winding number just outside it (``checked``: False when nesting was not tested)."""
    if not closed:
        return "open" if open_edges else "non-manifold"
    if not checked:
        return "unknown" if outside == 0 else ("solid" if volume > 0 else "inside-out")
    if outside == 0:
        return "solid" if volume > 0 else "inside-out"
    if outside == 1:
        return "cavity" if volume < 0 else "nested solid"
    return "nested solid" if volume > 0 else "nested cavity"


def body_problems(b: dict[str, Any], zero_volume: float) -> list[str]:
    """One short phrase per defect of a body given as the fields of a BodyReport."""
    out = []
    if b["open_edges"]:
        out.append(f"{plural(b['open_edges'], 'open edge')} around "
                   f"{plural(b['holes'], 'hole')}")
    if b["nonmanifold_edges"]:
        out.append(f"{plural(b['nonmanifold_edges'], 'non-manifold edge')} (used by more "
                   "than two faces)")
    if b["nonmanifold_vertices"]:
        n = b["nonmanifold_vertices"]
        out.append(f"{plural(n, 'non-manifold vertex', 'non-manifold vertices')} (surfaces "
                   "meet only at a point)")
    if not b["orientable"]:
        out.append("non-orientable (no consistent winding exists)")
    elif b["inconsistent_edges"]:
        out.append(f"{plural(b['flipped_faces'], 'face')} wound against "
                   f"{'its' if b['flipped_faces'] == 1 else 'their'} neighbours "
                   f"({plural(b['inconsistent_edges'], 'edge')} whose two faces run the same "
                   "way)")
    if b["degenerate_faces"]:
        out.append(f"{plural(b['degenerate_faces'], 'degenerate face')} (zero area or a "
                   "repeated vertex)")
    if b["duplicate_faces"]:
        out.append(f"{plural(b['duplicate_faces'], 'duplicate face')}")
    if b["self_intersections"]:
        out.append(f"self-intersecting ({plural(b['self_intersections'], 'face pair')} "
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


def empty_report(path: str | None, n_vertices: int, n_faces: int, problem: str,
                 seconds: dict[str, float]) -> ValidationReport:
    """The report of a mesh that cannot be checked at all (one file-level ``problem``)."""
    nan3 = (math.nan, math.nan, math.nan)
    return ValidationReport(
        path=path, n_vertices=n_vertices, n_faces=n_faces, n_positions=0, bodies=(),
        volume=0.0, area=0.0, bbox_min=nan3, bbox_max=nan3, intersecting_pairs=0,
        overlapping_bodies=(), nesting_checked=True, manifold_status="skipped",
        problems=(problem,), offending={k: np.zeros(0, np.int64) for k in OFFENDING_KINDS},
        face_body=np.full(n_faces, -1, np.int64), seconds=seconds)
