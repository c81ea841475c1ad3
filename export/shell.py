"""A printable shell of the container: the container minus its inward offset by T.

Frame and units: the container frame, container units (millimetres for printing); the
container mesh given is already scaled, closed and outward wound.

How the offset is made (chosen by measurement, see bench/shell_accuracy.py):

1. a signed distance grid (positive inside) over the container's bounds, exact within
   ``T + 2`` cells of the surface (:mod:`jampacked.core.distance`: exact point-triangle
   distances in a band, ray parity for the sign); deeper nodes only need to be known deeper;
2. marching tetrahedra (6 Kuhn tetrahedra per cube, vectorised numpy) extracts the level set
   ``distance = T``. On a simplicial grid the level set of the piecewise-linear interpolant is
   a closed 2-manifold without self-intersections, so the inner surface is watertight by
   construction (vertices are shared per grid edge);
3. manifold3d simplifies it to a tolerance (far fewer triangles, every point moves less than
   the tolerance). Its simplification can fold triangles over (elalish/manifold #970), so
   each result is validated (:func:`jampacked.export.validate.validate_arrays`) and retried
   with smaller tolerances, the unsimplified surface last. The inner surface is then
   subtracted from the container: the outer surface is the container's own mesh, untouched.

Measured on Spot (150 mm, T = 2 mm, 2 shared cores; bench/shell_accuracy.py): about 4 s,
wall thickness 1.83 / 1.94 / 2.02 / 2.10 / 2.20 mm (min / 1% / median / 99% / max of 10000
points), 29k triangles. The alternatives, same container and T: manifold3d ``level_set``
calls a Python function at every grid point (3.95 M calls, 8.4 s at a 1 mm edge for the
level set alone, 202k triangles before any simplification; 1.90 / 2.00 / 2.36 mm);
``minkowski_difference`` with a polygonal sphere took 10.9 s with a 32-triangle sphere
(1.64 / 1.91 / 2.00 mm: the facets cut in) and 23.8 s with 128 triangles (1.91 / 1.97 / 2.00).

Parts of the container thinner than 2T have no inside after the offset: they stay solid.
Cavities smaller than T^3 (specks where the container is barely thicker than 2T) are filled,
since a sealed speck of a void only traps resin or powder.
"""

from __future__ import annotations

import itertools
import math
import numbers
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import manifold3d as m3
import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from jampacked.core.distance import band_distances, inside_mask, point_triangle_distance
from jampacked.core.errors import InputError
from jampacked.core.meshes import sample_surface
from jampacked.core.solids import solid_arrays, to_solid

from .options import Opening
from .validate import validate_arrays

__all__ = [
    "ShellReport",
    "make_shell",
    "march_tetrahedra",
    "measure_wall_thickness",
    "surface_distance",
]

#: the distance grid never has more nodes than this (memory about 40 bytes a node)
MAX_GRID_NODES = 4_000_000
#: default grid spacing as a fraction of the thickness
SPACING_PER_T = 0.25
#: cavities smaller than this times T^3 are filled (see the module docstring)
MIN_CAVITY_PER_T3 = 1.0
#: after simplification, triangles thinner than this fraction of the container's bounding-box
#: diagonal are removed (manifold3d set_tolerance)
SLIVER_REL = 1e-6
#: simplification attempts, as fractions of the tolerance asked (see _simplified)
SIMPLIFY_LADDER = (1.0, 0.6, 0.35)
#: segments of the cylinders cut for windows and drains
CYLINDER_SEGMENTS = 48
#: crossing points never come closer than this fraction of a grid edge to a node, so that no
#: two vertices of the inner surface coincide (moves the surface by at most 1e-3 cell)
_EDGE_CLAMP = 1e-3


@dataclass
class ShellReport:
    """What :func:`make_shell` made; lengths in container units (mm), volumes in units³.

    thickness: the wall thickness T asked for.
    measured_min/median/max: wall thickness measured on the result (exact distance from points
        on the inner surface to the container mesh; see :func:`measure_wall_thickness`).
    samples: how many points that measurement used.
    opening: the opening cut, e.g. ``"plane +z@0.75"`` or ``"window +y 30 mm"``, or None.
    drain: drain hole diameter, or None.
    volume: volume of the shell solid.
    triangles: triangles of the shell solid.
    seconds: wall-clock time of :func:`make_shell`.
    grid_spacing: spacing of the distance grid the inner surface came from.
    tolerance: the simplification tolerance applied to the inner surface (0: none).
    cavities: closed cavities (inner surface components) kept.
    drain_at: (x, y, z) where the drain's axis leaves the cavity (its lowest point), or None.
    notes: warnings a user should read (e.g. a window that missed the wall).
    """

    thickness: float
    measured_min: float
    measured_median: float
    measured_max: float
    samples: int
    opening: str | None
    drain: float | None
    volume: float
    triangles: int
    seconds: float
    grid_spacing: float = 0.0
    tolerance: float = 0.0
    cavities: int = 0
    drain_at: tuple[float, float, float] | None = None
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """JSON-able dict of every field."""
        out = asdict(self)
        out["drain_at"] = None if self.drain_at is None else [float(c) for c in self.drain_at]
        out["notes"] = list(self.notes)
        return out


# --------------------------------------------------------------------------------------------
# marching tetrahedra


def _kuhn_tables() -> list[tuple[tuple[int, ...], dict[int, list[list[tuple[int, int]]]]]]:
    """Triangles of the level set in each of the 6 Kuhn tetrahedra of a unit cube.

    A cube corner is a 3-bit code (bit a: +1 along axis a). Tetrahedron π runs 0 -> e_π0 ->
    e_π0 + e_π1 -> 111; its edges always go from a code to a superset code, so an edge is named
    (lower corner, upper corner). For each case (bit i: tet vertex i inside) the table gives
    triangles as three edges, wound so the normal points from inside to outside; the winding
    is found geometrically on the tetrahedron itself, which is non-degenerate.
    """
    corner = np.array([[(c >> a) & 1 for a in range(3)] for c in range(8)], float)
    tables = []
    for perm in itertools.permutations(range(3)):
        codes = [0]
        for a in perm:
            codes.append(codes[-1] | (1 << a))
        p = corner[codes]
        cases: dict[int, list[list[tuple[int, int]]]] = {}
        for case in range(1, 15):
            ins = [i for i in range(4) if case >> i & 1]
            out = [i for i in range(4) if not case >> i & 1]
            if len(ins) == 1:
                polys = [[(ins[0], o) for o in out]]
            elif len(ins) == 3:
                polys = [[(i, out[0]) for i in ins]]
            else:  # a quad (i1o1, i1o2, i2o2, i2o1) split along one diagonal
                (i1, i2), (o1, o2) = ins, out
                polys = [[(i1, o1), (i1, o2), (i2, o2)], [(i1, o1), (i2, o2), (i2, o1)]]
            tris = []
            for poly in polys:
                pts = np.array([(p[a] + p[b]) / 2 for a, b in poly])
                normal = np.cross(pts[1] - pts[0], pts[2] - pts[0])
                if normal @ (p[out].mean(axis=0) - p[ins].mean(axis=0)) < 0:
                    poly = [poly[0], poly[2], poly[1]]
                tris.append([(codes[min(a, b)], codes[max(a, b)]) for a, b in poly])
            cases[case] = tris
        tables.append((tuple(codes), cases))
    return tables


_TABLES = _kuhn_tables()


def march_tetrahedra(values: np.ndarray, level: float, origin: np.ndarray,
                     spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed surface around ``{values > level}`` on a regular grid (marching tetrahedra).

    Args:
        values: (nx, ny, nz) samples at ``origin + (i, j, k) * spacing``.
        level: the iso value; nodes equal to it count as outside.
        origin: (3,) position of node (0, 0, 0), in the grid's frame and units.
        spacing: grid cell size.

    Returns:
        vertices (V, 3) float64 and faces (F, 3) int64, outward wound (normals point towards
        smaller values). When every border node is at most ``level`` the surface is closed,
        2-manifold and free of self-intersections: it is the level set of the piecewise-linear
        interpolant over the Kuhn tetrahedra, and vertices are shared per grid edge.
    """
    s = np.asarray(values, np.float64)
    nx, ny, nz = s.shape
    above = s > level
    cube = np.zeros((nx - 1, ny - 1, nz - 1), np.uint8)
    for c in range(8):
        dx, dy, dz = c & 1, c >> 1 & 1, c >> 2 & 1
        cube |= above[dx:nx - 1 + dx, dy:ny - 1 + dy, dz:nz - 1 + dz].astype(np.uint8) << c
    active = np.nonzero((cube != 0) & (cube != 255))
    bits = cube[active]
    base = (active[0].astype(np.int64) * ny + active[1]) * nz + active[2]
    offset = np.array([((c & 1) * ny + (c >> 1 & 1)) * nz + (c >> 2 & 1) for c in range(8)])
    keys = []
    for codes, cases in _TABLES:
        case = np.zeros(bits.shape, np.uint8)
        for i, c in enumerate(codes):
            case |= ((bits >> c) & 1) << i
        for value, tris in cases.items():
            cubes = base[case == value]
            if cubes.size == 0:
                continue
            for tri in tris:
                # a vertex is named by its grid edge: lower node * 8 + direction bits
                keys.append(np.stack([(cubes + offset[lo]) * 8 + (lo ^ hi) for lo, hi in tri],
                                     axis=1))
    if not keys:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    unique, inverse = np.unique(np.concatenate(keys), return_inverse=True)
    faces = inverse.reshape(-1, 3).astype(np.int64)
    lo_node = unique // 8
    step = unique % 8
    hi_node = lo_node + (step & 1) * ny * nz + (step >> 1 & 1) * nz + (step >> 2 & 1)
    flat = s.ravel()
    s_lo, s_hi = flat[lo_node], flat[hi_node]
    t = np.clip((level - s_lo) / (s_hi - s_lo), _EDGE_CLAMP, 1.0 - _EDGE_CLAMP)
    ijk = np.stack(np.unravel_index(lo_node, s.shape), axis=1)
    direction = np.stack([step & 1, step >> 1 & 1, step >> 2 & 1], axis=1)
    vertices = np.asarray(origin, np.float64) + spacing * (ijk + t[:, None] * direction)
    return vertices, faces


# --------------------------------------------------------------------------------------------
# exact distances to a mesh


@njit(cache=True)
def _min_candidate_distance(points, starts, candidates, vertices, faces):
    """Per point m: min exact distance to triangles candidates[starts[m]:starts[m+1]]."""
    out = np.empty(points.shape[0])
    for m in range(points.shape[0]):
        best = np.inf
        for j in range(starts[m], starts[m + 1]):
            f = candidates[j]
            d = point_triangle_distance(points[m], vertices[faces[f, 0]],
                                        vertices[faces[f, 1]], vertices[faces[f, 2]])
            if d < best:
                best = d
        out[m] = best
    return out


def _candidates(points: np.ndarray, vertices: np.ndarray,
                faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles that can hold a point's nearest surface point, as CSR (starts, indices).

    The distance to the nearest vertex bounds the distance to the surface from above, and a
    triangle with a point within that bound has its centroid within bound + its circumradius
    (from the centroid), so the candidates found this way always contain the nearest.
    """
    tri = vertices[faces]
    centroid = tri.mean(axis=1)
    reach = float(np.sqrt(((tri - centroid[:, None]) ** 2).sum(axis=2)).max())
    bound, _ = cKDTree(vertices).query(points)
    lists = cKDTree(centroid).query_ball_point(points, bound + reach * (1 + 1e-9) + 1e-12)
    lengths = np.fromiter((len(c) for c in lists), np.int64, len(lists))
    starts = np.zeros(len(lists) + 1, np.int64)
    np.cumsum(lengths, out=starts[1:])
    flat = np.fromiter(itertools.chain.from_iterable(lists), np.int64, int(starts[-1]))
    return starts, flat


def surface_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact unsigned distance from each point to a triangle mesh.

    points (N, 3), vertices (V, 3) float, faces (F, 3) int, all in one frame; returns (N,)
    float64 in those units.
    """
    points = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    vertices = np.ascontiguousarray(vertices, np.float64)
    faces = np.ascontiguousarray(faces, np.int64)
    if len(points) == 0:
        return np.zeros(0)
    starts, flat = _candidates(points, vertices, faces)
    return _min_candidate_distance(points, starts, flat, vertices, faces)


def measure_wall_thickness(shell_outer_vertices: np.ndarray, shell_outer_faces: np.ndarray,
                           inner: m3.Manifold, n: int = 2000, seed: int = 0) -> np.ndarray:
    """Wall thickness at ``n`` random points of the inner surface, (n,) float64.

    Args:
        shell_outer_vertices, shell_outer_faces: the container mesh (the shell's outer
            surface), container frame and units.
        inner: the inner solid (the cavity the shell encloses), same frame.
        n: number of points, spread uniformly by area over the inner surface.
        seed: seeds the sampling.

    Each value is the exact distance from a point on the inner surface to the outer mesh: the
    thickness of the wall there, as a caliper pressed against the inner face would read it.
    Empty when ``inner`` is empty.
    """
    if inner.is_empty() or n <= 0:
        return np.zeros(0)
    v, f = solid_arrays(inner)
    points = sample_surface(v, f, n, seed)
    return surface_distance(points, shell_outer_vertices, shell_outer_faces)


# --------------------------------------------------------------------------------------------
# the inner solid


def _grid_spacing(lo: np.ndarray, hi: np.ndarray, thickness: float,
                  resolution: float | None) -> float:
    """Grid spacing: T/4 (or the printer resolution), coarsened to stay under the node cap."""
    h = resolution if resolution is not None else SPACING_PER_T * thickness
    h = max(h, float(np.prod(hi - lo) / MAX_GRID_NODES) ** (1.0 / 3.0))
    while np.prod(np.ceil((hi - lo) / h + 3.0)) > MAX_GRID_NODES:
        h *= 1.05
    return float(h)


def _offset_grid(vertices: np.ndarray, faces: np.ndarray, thickness: float,
                 spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (positive inside) on a grid over the bounds + 1 cell; (values, origin).

    Exact at every node within ``T + 2`` cells of the surface; deeper nodes read exactly that
    cap. That is all marching at level T needs: a grid edge is at most sqrt(3) cells long and
    the distance is 1-Lipschitz, so no edge that crosses T touches a capped node.
    """
    band = math.ceil(thickness / spacing) + 2
    origin = vertices.min(axis=0) - spacing
    shape = tuple(int(n) for n in np.ceil((vertices.max(axis=0) + spacing - origin) / spacing)
                  .astype(np.int64) + 1)
    dist, _ = band_distances(vertices, faces, origin, spacing, np.asarray(shape, np.int64),
                             float(band))
    np.minimum(dist, band * spacing, out=dist)
    inside = inside_mask(vertices, faces, origin, spacing, shape)
    return np.where(inside, dist, -dist), origin


def _deepest(values: np.ndarray, origin: np.ndarray, spacing: float, vertices: np.ndarray,
             faces: np.ndarray, candidates: int = 4, steps: int = 5, rounds: int = 6) -> float:
    """The container's largest inscribed distance, refined from the grid's deepest nodes.

    Around each of the ``candidates`` deepest nodes, exact distances on a local grid of
    ``steps``³ points; the best point becomes the next centre and the local grid shrinks by
    ``steps - 1`` / 2 each round. Local points stay within the ball of their centre's depth,
    so they are inside the container. Used for the error message only.
    """
    flat = values.ravel()
    k = min(candidates, flat.size)
    best = np.argpartition(flat, -k)[-k:]
    best = best[flat[best] > 0]
    if best.size == 0:
        return 0.0
    centres = origin + spacing * np.stack(np.unravel_index(best, values.shape), axis=1)
    depth = flat[best]
    axis = np.linspace(-1.0, 1.0, steps)
    local = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    reach = spacing
    for _ in range(rounds):
        r = np.minimum(reach, 0.999 * depth / math.sqrt(3.0))
        points = centres[:, None, :] + r[:, None, None] * local[None]
        d = surface_distance(points.reshape(-1, 3), vertices, faces).reshape(len(centres), -1)
        pick = d.argmax(axis=1)
        better = d[np.arange(len(centres)), pick] > depth
        centres[better] = points[better, pick[better]]
        depth = np.maximum(depth, d[np.arange(len(centres)), pick])
        reach *= 2.0 / (steps - 1)
    return float(depth.max())


def _too_thick(thickness: float, deepest: float) -> InputError:
    """The error for an offset with no cavity left; ``deepest``: largest inscribed distance."""
    if deepest <= thickness:
        why = (f"its deepest inside point is only {deepest:.3g} units from its surface, so "
               f"offsetting the wall inward by {thickness:g} leaves no cavity")
    else:
        why = (f"its deepest inside point is {deepest:.3g} units from its surface, so "
               f"offsetting the wall inward by {thickness:g} leaves at most a speck of cavity "
               f"(cavities under {MIN_CAVITY_PER_T3:g} T³ are filled)")
    return InputError(
        f"shell thickness {thickness:g} is too thick for this container: {why}. Fix: give a "
        f"thickness below {deepest:.3g} (in practice well below it, e.g. "
        f"{0.5 * deepest:.2g}, so the cavity can hold objects), or scale the container up."
    )


def _drop_specks(inner: m3.Manifold, thickness: float) -> list[m3.Manifold]:
    """The cavities of ``inner`` worth keeping (volume at least MIN_CAVITY_PER_T3 T³)."""
    return [p for p in inner.decompose() if p.volume() >= MIN_CAVITY_PER_T3 * thickness ** 3]


def _simplified(raw: m3.Manifold, thickness: float, tolerance: float,
                diagonal: float) -> tuple[list[m3.Manifold], float]:
    """The cavities, simplified to ``tolerance`` where that provably keeps them watertight.

    manifold3d's simplification can fold triangles over or leave slivers (elalish/manifold
    #970); in our runs about one surface in six came out so. So each attempt is validated
    (closed, no degenerate faces, no self-intersections), with smaller tolerances next, and
    the unsimplified surface (watertight by construction) last. Returns (cavities, the
    tolerance used, 0.0 for none).
    """
    exact = raw.get_tolerance()
    for factor in SIMPLIFY_LADDER:
        # simplify; remove the slivers it leaves (far below print precision); restore the
        # tolerance so that later booleans keep the container's own mesh exact
        candidate = (raw.simplify(factor * tolerance).set_tolerance(SLIVER_REL * diagonal)
                     .set_tolerance(exact))
        parts = _drop_specks(candidate, thickness)
        if not parts:
            return parts, factor * tolerance
        v, f = solid_arrays(m3.Manifold.compose(parts))
        if validate_arrays(v, f).passed:
            return parts, factor * tolerance
    return _drop_specks(raw, thickness), 0.0


def _inner_solid(vertices: np.ndarray, faces: np.ndarray, thickness: float, spacing: float,
                 tolerance: float) -> tuple[m3.Manifold, int, float]:
    """The container offset inward by T (the cavities): (solid, cavities, tolerance used)."""
    values, origin = _offset_grid(vertices, faces, thickness, spacing)
    if float(values.max()) <= thickness:
        raise _too_thick(thickness, _deepest(values, origin, spacing, vertices, faces))
    v, f = march_tetrahedra(values, thickness, origin, spacing)
    raw = to_solid(v, f)
    if raw.status() != m3.Error.NoError:  # pragma: no cover - marching output is manifold
        raise RuntimeError(f"inner shell surface rejected by manifold3d: {raw.status()}")
    diagonal = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    parts, used = _simplified(raw, thickness, tolerance, diagonal)
    if not parts:
        raise _too_thick(thickness, _deepest(values, origin, spacing, vertices, faces))
    return m3.Manifold.compose(parts), len(parts), used


# --------------------------------------------------------------------------------------------
# openings and the drain


def _axis(axis: str) -> tuple[int, float, np.ndarray]:
    """'+x' -> (0, +1.0, unit vector)."""
    a = "xyz".index(axis[1])
    sign = 1.0 if axis[0] == "+" else -1.0
    unit = np.zeros(3)
    unit[a] = sign
    return a, sign, unit


def _cylinder(start: np.ndarray, direction: np.ndarray, length: float,
              radius: float) -> m3.Manifold:
    """Solid cylinder of ``radius`` from ``start`` along unit ``direction`` for ``length``."""
    cyl = m3.Manifold.cylinder(length, radius, radius, CYLINDER_SEGMENTS)
    d = direction / np.linalg.norm(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, d)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    # manifold3d's affine: 3x4 [R | t], columns of R = images of x, y, z
    mat = np.column_stack([e1, e2, d, np.asarray(start, np.float64)])
    return cyl.transform(mat)


def _disc_offsets(radius: float, e1: np.ndarray, e2: np.ndarray) -> list[np.ndarray]:
    """Points of a disc (centre, two rings) to cast rays through: the wall across the disc."""
    out = [np.zeros(3)]
    for r in (0.5 * radius, radius):
        for k in range(8):
            angle = 2 * math.pi * k / 8 + 0.1234  # off the axes: no ray along a box edge
            out.append(r * (math.cos(angle) * e1 + math.sin(angle) * e2))
    return out


def _plane_cut(shell: m3.Manifold, opening: Opening, lo: np.ndarray,
               hi: np.ndarray) -> m3.Manifold:
    """Remove the shell beyond the opening plane (see :class:`Opening`)."""
    a, sign, unit = _axis(opening.axis)
    at = lo[a] + opening.at * (hi[a] - lo[a]) if sign > 0 else hi[a] - opening.at * (hi[a] - lo[a])
    # trim keeps the side the normal points to: {-sign x_a >= -sign at}
    return shell.trim_by_plane(tuple(-unit), float(-sign * at))


def _ray_hits(shell: m3.Manifold, start: np.ndarray, direction: np.ndarray,
              length: float) -> list[tuple[float, bool]]:
    """Surface crossings along a ray: (distance from ``start``, entering the solid?), sorted.

    Entering when the surface's outward normal faces the ray. Crossings closer together than
    1e-9 of ``length`` (a ray through an edge meets both triangles) count once.
    """
    hits = shell.ray_cast(tuple(start), tuple(start + length * direction))
    out: list[tuple[float, bool]] = []
    for h in sorted(hits, key=lambda h: h.distance):
        t = h.distance * length
        if out and t - out[-1][0] <= 1e-9 * length:
            continue
        out.append((t, float(np.dot(h.normal, direction)) < 0.0))
    return out


def _first_exit(hits: list[tuple[float, bool]]) -> tuple[float | None, float]:
    """(where the solid is first left, where it is entered again after that or inf)."""
    for i, (t, entering) in enumerate(hits):
        if not entering:
            later = [u for u, e in hits[i + 1:] if e]
            return t, later[0] if later else math.inf
    return None, math.inf


def _window(shell: m3.Manifold, opening: Opening, lo: np.ndarray, hi: np.ndarray,
            thickness: float, notes: list[str]) -> m3.Manifold:
    """Cut a round window through the first wall seen from outside along ``opening.axis``.

    The cylinder runs from outside the bounds inward and stops a little past where rays
    across its disc leave that wall (never past the bounding-box centre), so walls further
    in (the far side, or the inner ring of a torus) stay intact.
    """
    a, _, unit = _axis(opening.axis)
    radius = 0.5 * opening.size
    centre = 0.5 * (lo + hi)
    e1 = np.zeros(3)
    e1[(a + 1) % 3] = 1.0
    e2 = np.cross(unit, e1)
    reach = 0.5 * (hi[a] - lo[a]) + thickness + radius + 1.0  # centre to beyond the bounds
    depths = []
    for off in _disc_offsets(radius, e1, e2):
        exit_at, _ = _first_exit(_ray_hits(shell, centre + off + reach * unit, -unit, reach))
        if exit_at is not None:
            depths.append(exit_at)
    if not depths:
        raise InputError(
            f"the window along {opening.axis} misses the shell: the line through the "
            "container's bounding-box centre along that axis meets no wall within the window's "
            "diameter. Fix: pick another axis, a larger window, or a plane opening."
        )
    inward = max(depths) + 0.5 * thickness  # a little into the cavity
    if inward >= reach:
        inward = reach
        notes.append(f"the window along {opening.axis} reaches the bounding-box centre: the "
                     "wall there is thicker than the window is deep, or it is solid.")
    start = centre + (reach - inward) * unit
    return shell - _cylinder(start, unit, inward + 1.0, radius)


def _drain_site(shell: m3.Manifold, cavity_vertices: np.ndarray, thickness: float,
                size: float) -> np.ndarray:
    """Where the drain leaves the cavity: its lowest point, or the middle of a flat floor.

    A flat floor's lowest vertex is a corner, where the hole would cut the side walls: so the
    middle (mean x, y) of the vertices within T/20 of the lowest is used when the floor is
    really there (just above it is cavity, just below it is wall).
    """
    z = cavity_vertices[:, 2]
    lowest = cavity_vertices[np.argmin(z)]
    low = cavity_vertices[z <= z.min() + 0.05 * thickness]
    middle = np.array([low[:, 0].mean(), low[:, 1].mean(), z.min()])
    eps = 0.05 * thickness + 1e-6 * size
    start = middle + np.array([0.0, 0.0, 2.0 * eps])
    hits = _ray_hits(shell, start, np.array([0.0, 0.0, -1.0]), size)
    if hits and hits[0][1] and hits[0][0] <= 3.0 * eps:  # the first crossing enters the wall
        return start - np.array([0.0, 0.0, hits[0][0]])
    return lowest


def _drain(shell: m3.Manifold, inner: m3.Manifold, diameter: float,
           thickness: float) -> tuple[m3.Manifold, tuple[float, float, float]]:
    """Drill a vertical drain hole from the cavity's lowest point down through the wall.

    Resin and powder printers need it: uncured resin or loose powder trapped in a closed
    cavity cannot escape (resin also causes suction and cracking). The hole sits under the
    lowest point of the cavities, where liquid pools with the container standing as modelled
    (-z down). It starts a little above that point (short of the ceiling) and ends a margin
    below where the wall is left, but never reaches a part of the container further below.
    """
    v, _ = solid_arrays(inner)
    radius = 0.5 * diameter
    up = np.array([0.0, 0.0, 1.0])
    size = float(np.ptp(v[:, 2])) + 4.0 * thickness + diameter + 1.0
    low = _drain_site(shell, v, thickness, size)
    # the cavity's floor rises across the disc: start up to radius + T/4 above, short of the
    # ceiling
    ceiling = [t for t, _ in _ray_hits(shell, low, up, size) if t > 1e-6 * size]
    rise = radius + 0.25 * thickness
    if ceiling:
        rise = min(rise, 0.5 * ceiling[0])
    top = low + rise * up
    exit_at, below = _first_exit(_ray_hits(shell, top, -up, size))
    if exit_at is None:  # pragma: no cover - a point in a closed cavity always gets out
        exit_at = rise + thickness
    depth = exit_at + radius + thickness  # clear the outer surface's slope across the disc
    for off in _disc_offsets(radius, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
        _, next_entry = _first_exit(_ray_hits(shell, top + off, -up, size))
        below = min(below, next_entry)
    depth = min(depth, 0.5 * (exit_at + below))
    hole = _cylinder(top, -up, depth, radius)
    return shell - hole, (float(low[0]), float(low[1]), float(low[2]))


def opening_label(opening: Opening | None) -> str | None:
    if opening is None:
        return None
    if opening.kind == "plane":
        return f"plane {opening.axis}@{opening.at:g}"
    return f"window {opening.axis} {opening.size:g} mm"


# --------------------------------------------------------------------------------------------
# public entry point


def make_shell(vertices: np.ndarray, faces: np.ndarray, thickness: float, *,
               opening: Opening | None = None, drain: float | None = None,
               resolution: float | None = None,
               progress: Callable[[float, str], None] | None = None,
               samples: int = 2000) -> tuple[m3.Manifold, ShellReport]:
    """Shell of the container with wall thickness ``thickness``: container minus its offset.

    Args:
        vertices: (V, 3) container vertices, container frame, container units (mm), already
            scaled; the mesh must be closed and outward wound (as :func:`load_mesh` returns).
        faces: (F, 3) int vertex indices.
        thickness: wall thickness T (> 0).
        opening: cut the shell open (plane or window, see :class:`Opening`), or None.
        drain: diameter of a drain hole through the bottom wall under the cavity's lowest
            point, or None. Resin and powder printers need one so that uncured resin or loose
            powder can escape from the cavity.
        resolution: the printer's resolution: the inner surface is made on a grid of this
            spacing and simplified to min(resolution/2, T/10), so the wall thickness stays
            within about that of T. Default: spacing T/4, simplified to min(spacing/10, T/20).
            Either way the grid is coarsened to stay under ``MAX_GRID_NODES`` nodes.
        progress: ``progress(fraction, message)`` called as the work goes on.
        samples: points used to measure the wall thickness.

    Returns:
        (shell, report): the shell solid (its outer surface is the container mesh itself, its
        inner surface the offset) and a :class:`ShellReport` with the measured thickness.

    Raises:
        InputError: T or a diameter is not a positive length, or T is too large for the
            container (no cavity would be left; the message gives the largest T that works),
            or a window misses the shell.
    """
    t0 = time.perf_counter()
    report_progress = progress or (lambda fraction, message: None)
    for name, value, optional in (("shell thickness", thickness, False),
                                  ("drain diameter", drain, True),
                                  ("resolution", resolution, True)):
        if value is None and optional:
            continue
        if not (isinstance(value, numbers.Real) and math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive length (container units), got "
                             f"{value}.")
    v = np.ascontiguousarray(vertices, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InputError(f"the container must be (V, 3) vertices and (F, 3) triangles, got "
                         f"{v.shape} and {f.shape}.")
    lo, hi = v.min(axis=0), v.max(axis=0)
    spacing = _grid_spacing(lo, hi, thickness, resolution)
    if resolution is not None:
        tolerance = min(0.5 * resolution, 0.1 * thickness)
    else:
        tolerance = min(0.1 * spacing, 0.05 * thickness)
    report_progress(0.0, f"shell: distance grid at {spacing:.3g} spacing")
    inner, cavities, used = _inner_solid(v, f, thickness, spacing, tolerance)
    notes: list[str] = []
    if used == 0.0:
        notes.append(f"the inner surface could not be simplified watertight, so it keeps all "
                     f"{inner.num_tri()} triangles of the grid.")
    report_progress(0.6, "shell: subtracting the inner surface")
    shell = to_solid(v, f) - inner
    drain_at = None
    if drain is not None:
        report_progress(0.7, "shell: drain hole")
        shell, drain_at = _drain(shell, inner, drain, thickness)
        if cavities > 1:
            notes.append(f"the shell has {cavities} separate cavities; the drain opens only "
                         "the lowest one.")
    if opening is not None:
        report_progress(0.75, f"shell: {opening.kind} opening")
        if opening.kind == "plane":
            shell = _plane_cut(shell, opening, lo, hi)
        else:
            shell = _window(shell, opening, lo, hi, thickness, notes)
    report_progress(0.85, "shell: measuring the wall thickness")
    measured = measure_wall_thickness(v, f, inner, n=samples)
    if measured.size and abs(float(np.median(measured)) - thickness) > 0.1 * thickness:
        fix = ("give a finer --resolution" if resolution is not None and spacing == resolution
               else f"the distance grid is capped at {MAX_GRID_NODES:,} nodes: use a thicker "
               "wall or a smaller container")
        notes.append(f"the measured median wall thickness {np.median(measured):.3g} is more "
                     f"than 10% off {thickness:g}: the grid spacing {spacing:.3g} is coarse "
                     f"for this thickness; {fix}.")
    report = ShellReport(
        thickness=float(thickness),
        measured_min=float(measured.min()) if measured.size else math.nan,
        measured_median=float(np.median(measured)) if measured.size else math.nan,
        measured_max=float(measured.max()) if measured.size else math.nan,
        samples=int(measured.size),
        opening=opening_label(opening),
        drain=None if drain is None else float(drain),
        volume=float(shell.volume()),
        triangles=int(shell.num_tri()),
        seconds=time.perf_counter() - t0,
        grid_spacing=spacing,
        tolerance=float(used),
        cavities=cavities,
        drain_at=drain_at,
        notes=notes,
    )
    report_progress(1.0, "shell: done")
    return shell, report
