"""Openings in a shell: a plane cut, a round window, and a drain hole.

Frame and units: the container frame, container units (millimetres for printing), with +z
up (the drain goes down); :func:`jampacked.export.shell.make_shell` is given the container
already turned that way.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import manifold3d as m3
import numpy as np

from jampacked.core.errors import InputError
from jampacked.core.solids import solid_arrays

from .options import Opening

__all__ = ["cut_window", "drain_cover", "drill_drain", "opening_label", "plane_cut",
           "solid_boxes"]

#: segments of the cylinders cut for windows and drains
CYLINDER_SEGMENTS = 48


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


def plane_cut(shell: m3.Manifold, opening: Opening, lo: np.ndarray,
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


def _wall_depths(shell: m3.Manifold, centre: np.ndarray, offsets: list[np.ndarray],
                 unit: np.ndarray, reach: float) -> list[float]:
    """Where rays along ``-unit`` through ``centre`` + each offset, cast from ``reach``
    beyond it, first leave the shell: one depth per ray that meets a wall."""
    depths = []
    for off in offsets:
        exit_at, _ = _first_exit(_ray_hits(shell, centre + off + reach * unit, -unit, reach))
        if exit_at is not None:
            depths.append(exit_at)
    return depths


#: candidate window centres per ring around the side's middle, and rings across the side
RING_POINTS = 32
RINGS = 64


def _nearest_wall(shell: m3.Manifold, centre: np.ndarray, offsets: list[np.ndarray],
                  unit: np.ndarray, e1: np.ndarray, e2: np.ndarray, reach: float,
                  span: float) -> tuple[np.ndarray, list[float]] | None:
    """A window centre near ``centre`` (in the plane across the axis, within ``span``)
    whose whole disc lies over a wall: from the first ring of candidates where one does,
    out to a window's diameter further, the one where the wall is flattest (the least
    spread of depths across the disc: a tube's crest rather than its edge), nearest first
    on ties. Else the one with the most of its disc over a wall, nearest first; None when
    no ray meets a wall anywhere."""
    diameter = 2.0 * max(float(np.linalg.norm(o)) for o in offsets)
    best: tuple[int, np.ndarray, list[float]] | None = None
    flattest: tuple[float, np.ndarray, list[float]] | None = None
    last = RINGS
    for ring in range(1, RINGS + 1):
        if ring > last:
            break
        distance = span * ring / RINGS
        for k in range(RING_POINTS):
            angle = 2 * math.pi * k / RING_POINTS + 0.0731  # off the axes, as the disc's rays
            at = centre + distance * (math.cos(angle) * e1 + math.sin(angle) * e2)
            depths = _wall_depths(shell, at, offsets, unit, reach)
            if len(depths) == len(offsets):
                spread = max(depths) - min(depths)
                if flattest is None:
                    last = min(RINGS, ring + math.ceil(diameter * RINGS / span))
                if flattest is None or spread < flattest[0]:
                    flattest = (spread, at, depths)
            elif depths and (best is None or len(depths) > best[0]):
                best = (len(depths), at, depths)
    if flattest is not None:
        return flattest[1], flattest[2]
    return None if best is None else (best[1], best[2])


def cut_window(shell: m3.Manifold, opening: Opening, lo: np.ndarray, hi: np.ndarray,
               thickness: float, notes: list[str]) -> m3.Manifold:
    """Cut a round window through the first wall seen from outside along ``opening.axis``.

    The window is centred on the bounding-box centre where the wall is there; where the line
    through it meets no wall (the hole of a torus), near it over a wall (`_nearest_wall`; a
    note says how far it moved). The cylinder runs from outside the bounds inward and stops a
    little past where rays across its disc leave that wall (never past the bounding-box
    centre's plane), so walls further in (the far side, or the inner ring of a torus) stay
    intact.
    """
    a, _, unit = _axis(opening.axis)
    radius = 0.5 * opening.size
    centre = 0.5 * (lo + hi)
    e1 = np.zeros(3)
    e1[(a + 1) % 3] = 1.0
    e2 = np.cross(unit, e1)
    reach = 0.5 * (hi[a] - lo[a]) + thickness + radius + 1.0  # centre to beyond the bounds
    offsets = _disc_offsets(radius, e1, e2)
    depths = _wall_depths(shell, centre, offsets, unit, reach)
    if not depths:
        span = 0.5 * max(float(hi[i] - lo[i]) for i in range(3) if i != a)
        found = _nearest_wall(shell, centre, offsets, unit, e1, e2, reach, span)
        if found is None:
            raise InputError(
                "the window misses the shell: no line along its axis within the "
                "container's bounds meets a wall. Fix: pick another axis or a plane opening.")
        moved, depths = found
        # no axis named: ``opening`` is in the print frame (turned by --up), not the user's
        notes.append("the line through the container's middle along the window's axis meets "
                     f"no wall, so the window is centred {np.linalg.norm(moved - centre):.3g} "
                     "mm from it, over the wall.")
        centre = moved
    inward = max(depths) + 0.5 * thickness  # a little into the cavity
    if inward >= reach:
        inward = reach
        notes.append("the window reaches the bounding-box centre: the "
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


def _free_site(inner: m3.Manifold, low: np.ndarray, radius: float, reach: float,
               covered: Callable[[np.ndarray], bool], level: float = 0.0
               ) -> np.ndarray | None:
    """The lowest point of the cavity's floor within `reach` of `low` (across, and at most
    `reach` above it) that no object covers (`covered(point)`), the nearest of those within
    `level` of its height (the inner surface's accuracy: a flat floor simplified to a
    tolerance is not quite flat); None where every one is covered. The floor is found under
    the points of a grid `radius` apart, where rays cast down through the cavity (`inner`,
    its solid) from above it leave it; a ray from a fixed height missed every floor of a
    cavity less tall than `reach` (a flat box or dish), and the drain stayed under the
    object."""
    n = max(1, int(reach / radius))
    grid = [(i * i + j * j, i, j) for i in range(-n, n + 1) for j in range(-n, n + 1)
            if 0 < i * i + j * j <= n * n]
    up = np.array([0.0, 0.0, 1.0])
    # the floor of the cavity the lowest point is on (the drain under another cavity's
    # floor would open into this one, not out)
    inner = _cavity_at(inner, low)
    lo, hi = np.reshape(inner.bounding_box(), (2, 3))
    length = float(hi[2] - lo[2]) + 2.0 * radius + 1.0
    floors = []
    for _, i, j in sorted(grid):
        start = low + np.array([i * radius, j * radius, 0.0])
        start[2] = hi[2] + radius + 0.5
        for t, entering in _ray_hits(inner, start, -up, length):
            floor = start - t * up
            if not entering and floor[2] <= low[2] + reach:  # leaving the cavity: a floor
                floors.append(floor)
    # each `covered` call is a boolean against the objects near it: as few as will do, the
    # lowest first to find the lowest free height, then nearest first within `level` of it
    free: dict[int, bool] = {}

    def is_free(k: int) -> bool:
        if k not in free:
            free[k] = not covered(floors[k])
        return free[k]

    by_height = sorted(range(len(floors)), key=lambda k: floors[k][2])
    lowest = next((floors[k][2] for k in by_height if is_free(k)), None)
    if lowest is None:
        return None
    return next((floors[k] for k in range(len(floors))
                 if floors[k][2] <= lowest + level and is_free(k)), None)


def _cavity_at(inner: m3.Manifold, point: np.ndarray) -> m3.Manifold:
    """The cavity of `inner` (its solid, one or more bodies) whose surface holds `point`:
    the body with the lowest bottom among those whose box holds it (`inner` with one)."""
    parts = inner.decompose()
    if len(parts) < 2:
        return inner
    boxes = [np.reshape(p.bounding_box(), (2, 3)) for p in parts]
    slack = 1e-6 * float(np.ptp(np.reshape(inner.bounding_box(), (2, 3)), axis=0).max())
    holding = [k for k, (lo, hi) in enumerate(boxes)
               if np.all(lo - slack <= point) and np.all(point <= hi + slack)]
    return parts[min(holding, key=lambda k: boxes[k][0, 2])] if holding else inner


def drill_drain(shell: m3.Manifold, inner: m3.Manifold, diameter: float,
                thickness: float, covered: Callable[[np.ndarray], bool] | None = None,
                reach: float = 0.0, notes: list[str] | None = None, level: float = 0.0
                ) -> tuple[m3.Manifold, tuple[float, float, float]]:
    """Drill a vertical drain hole from the cavity's lowest point down through the wall.

    Resin and powder printers need it: uncured resin or loose powder trapped in a closed
    cavity cannot escape (resin also causes suction and cracking). The hole sits under the
    lowest point of the cavities, where liquid pools with the container standing as modelled
    (-z down). It starts a little above that point (short of the ceiling) and ends a margin
    below where the wall is left, but never reaches a part of the container further below.
    covered(point): whether objects sit on a drain there (`drain_cover`); where they sit on
    the lowest point, the hole goes under the lowest free point of the floor within `reach`
    of it (`_free_site`), so that it opens beside the object rather than under it, and
    `notes` says so. level: how far apart two heights of the floor must be to count as
    different (the inner surface's accuracy), in container units; at most a tenth of the
    drain's radius.
    """
    v, _ = solid_arrays(inner)
    radius = 0.5 * diameter
    up = np.array([0.0, 0.0, 1.0])
    size = float(np.ptp(v[:, 2])) + 4.0 * thickness + diameter + 1.0
    low = _drain_site(shell, v, thickness, size)
    if covered is not None and reach > 0 and covered(low):
        # no further than a tenth of the drain's radius, so that on a sloping floor the
        # drain stays where liquid pools
        level = min(max(level, 1e-9 * size), 0.1 * radius)
        free = _free_site(inner, low, radius, reach, covered, level)
        if free is not None:
            if notes is not None:
                rise = float(free[2] - low[2])
                # the floor's sample can lie a little below the lowest point found
                height = (" on the same level" if abs(rise) <= level else
                          f" and {abs(rise):.3g} {'lower' if rise < 0 else 'higher'}")
                notes.append(f"objects sit on the cavity's lowest point: the drain opens "
                             f"{np.linalg.norm((free - low)[:2]):.3g} away from it{height}, "
                             "at the lowest point of the floor they leave free.")
            low = free
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


def solid_boxes(solids: list[m3.Manifold]) -> np.ndarray:
    """(N, 2, 3) each solid's bounding box: lo, hi."""
    return np.array([np.reshape(s.bounding_box(), (2, 3)) for s in solids],
                    np.float64).reshape(-1, 2, 3)


def drain_cover(solids: list[m3.Manifold], at: np.ndarray, up: np.ndarray,
                diameter: float, boxes: np.ndarray | None = None) -> list[int]:
    """The objects (indices into solids, placed) that sit on a drain's mouth: within the
    drain's radius of where it leaves the cavity (`at`) and up to a radius above it, along
    the unit `up`. Liquid and powder reach the hole only through the gap such an object
    leaves. boxes: the solids' `solid_boxes`, when known. Container frame and units."""
    radius = 0.5 * diameter
    mouth = _cylinder(np.asarray(at, np.float64), np.asarray(up, np.float64), radius, radius)
    lo, hi = np.reshape(mouth.bounding_box(), (2, 3))
    boxes = solid_boxes(solids) if boxes is None else boxes
    near = np.flatnonzero(np.all(boxes[:, 0] <= hi, axis=1) & np.all(lo <= boxes[:, 1], axis=1))
    return [int(i) for i in near if (solids[i] ^ mouth).volume() > 0]


def opening_label(opening: Opening | None) -> str | None:
    """How a report names an opening: ``"plane +z@0.75"``, ``"window +y 30 mm"`` or None."""
    if opening is None:
        return None
    if opening.kind == "plane":
        return f"plane {opening.axis}@{opening.at:g}"
    return f"window {opening.axis} {opening.size:g} mm"
