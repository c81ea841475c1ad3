"""The container offset inward by the wall thickness T: the cavity a shell encloses.

Frame and units: the container frame, container units (millimetres for printing); the
container mesh given is already scaled, closed and outward wound.

How the offset is made (chosen by measurement: bench/shell_accuracy.py, figures in
docs/notes-export.md):

1. a signed distance grid (positive inside) over the container's bounds, exact within
   ``T + 2`` cells of the surface (:mod:`jampacked.core.distance`: exact point-triangle
   distances in a band, ray parity for the sign); deeper nodes only need to be known deeper;
2. marching tetrahedra (:mod:`jampacked.export.marching`) extracts the level set
   ``distance = T``, watertight by construction;
3. manifold3d simplifies it to a tolerance (far fewer triangles, every point moves less than
   the tolerance). Its simplification can fold triangles over (elalish/manifold #970), so
   each result is validated (:func:`jampacked.export.validate.validate_arrays`) and retried
   with smaller tolerances, the unsimplified surface last.

manifold3d's ``level_set`` (a Python call per grid point) and ``minkowski_difference`` with a
polygonal sphere (its facets cut into the wall) were slower and less accurate.

Parts of the container thinner than 2T have no inside after the offset: they stay solid.
Cavities smaller than T^3 (specks where the container is barely thicker than 2T) are filled,
since a sealed speck of a void only traps resin or powder.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import manifold3d as m3
import numpy as np
from numba import njit

from jampacked.core.distance import (
    band_distances,
    inside_mask,
    point_triangle_distance,
    surface_distance,
)
from jampacked.core.errors import InputError
from jampacked.core.kernels import sample_grid_many
from jampacked.core.solids import solid_arrays, to_solid

from .marching import march_tetrahedra
from .validate import validate_arrays

__all__ = ["MAX_GRID_NODES", "grid_spacing", "inner_solid", "offset_grid"]

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


def grid_spacing(lo: np.ndarray, hi: np.ndarray, thickness: float,
                 resolution: float | None) -> float:
    """Grid spacing: T/4 (or the printer resolution), coarsened to stay under the node cap."""
    h = resolution if resolution is not None else SPACING_PER_T * thickness
    h = max(h, float(np.prod(hi - lo) / MAX_GRID_NODES) ** (1.0 / 3.0))
    while np.prod(np.ceil((hi - lo) / h + 3.0)) > MAX_GRID_NODES:
        h *= 1.05
    return float(h)


def offset_grid(vertices: np.ndarray, faces: np.ndarray, thickness: float,
                spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (positive inside) on a grid over the bounds + 1 cell; (values, origin).

    Exact at every node within ``T + 2`` cells of the surface; deeper nodes read exactly that
    cap. That is all marching at level T needs: a grid edge is at most sqrt(3) cells long and
    the distance is 1-Lipschitz, so no edge that crosses T touches a capped node.
    """
    values, origin, _ = _offset_grid(vertices, faces, thickness, spacing)
    return values, origin


def _offset_grid(vertices: np.ndarray, faces: np.ndarray, thickness: float,
                 spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`offset_grid`, and each node's nearest triangle (-1 beyond the band)."""
    band = math.ceil(thickness / spacing) + 2
    origin = vertices.min(axis=0) - spacing
    shape = tuple(int(n) for n in np.ceil((vertices.max(axis=0) + spacing - origin) / spacing)
                  .astype(np.int64) + 1)
    dist, tri = band_distances(vertices, faces, origin, spacing, np.asarray(shape, np.int64),
                               float(band))
    np.minimum(dist, band * spacing, out=dist)
    inside = inside_mask(vertices, faces, origin, spacing, shape)
    return np.where(inside, dist, -dist), origin, tri


@njit(cache=True)
def _near_distances(points, tri, origin, spacing, vertices, faces):
    """Distance from points (M, 3) to the nearest of the triangles nearest the grid nodes
    around each (its cell's 8 corners), (M,) float64: the true distance where the point's
    nearest triangle is one of those, as in the grid's band it nearly always is (at least
    the true distance otherwise); inf where none is known."""
    nx, ny, nz = tri.shape
    out = np.empty(points.shape[0])
    for m in range(points.shape[0]):
        best = np.inf
        i0 = int(np.floor((points[m, 0] - origin[0]) / spacing))
        j0 = int(np.floor((points[m, 1] - origin[1]) / spacing))
        k0 = int(np.floor((points[m, 2] - origin[2]) / spacing))
        for i in range(max(i0, 0), min(i0 + 2, nx)):
            for j in range(max(j0, 0), min(j0 + 2, ny)):
                for k in range(max(k0, 0), min(k0 + 2, nz)):
                    f = tri[i, j, k]
                    if f >= 0:
                        d = point_triangle_distance(points[m], vertices[faces[f, 0]],
                                                    vertices[faces[f, 1]],
                                                    vertices[faces[f, 2]])
                        if d < best:
                            best = d
        out[m] = best
    return out


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
                diagonal: float, marched: m3.Manifold | None = None,
                thick_enough: Callable[[np.ndarray, np.ndarray], bool] | None = None
                ) -> tuple[list[m3.Manifold], float]:
    """The cavities, simplified to ``tolerance`` where that provably keeps them watertight
    and the wall T thick.

    manifold3d's simplification can fold triangles over or leave slivers (elalish/manifold
    #970; how often: docs/notes-export.md), and its tolerance bounds how far vertices move,
    not faces: a long face across a saddle (a torus's inner equator) cut into the wall by
    more than the tolerance. So each attempt is validated (closed, no degenerate faces, no
    self-intersections), with smaller tolerances next, and the first that also keeps
    ``thick_enough(vertices, faces)`` is taken, else the first valid one (on a grid coarse
    for T the unsimplified surface's own faces cut in as far, with ten times the
    triangles), else the unsimplified surface: `raw` where it validates, else `marched`
    (the surface as marched, watertight by construction, where `raw` moved its vertices).
    Returns (cavities, the tolerance used, 0.0 for none).
    """
    exact = raw.get_tolerance()
    valid: tuple[list[m3.Manifold], float] | None = None
    for factor in SIMPLIFY_LADDER if tolerance > 0 else ():
        # simplify; remove the slivers it leaves (far below print precision); restore the
        # tolerance so that later booleans keep the container's own mesh exact
        candidate = (raw.simplify(factor * tolerance).set_tolerance(SLIVER_REL * diagonal)
                     .set_tolerance(exact))
        parts = _drop_specks(candidate, thickness)
        if not parts:
            return parts, factor * tolerance
        v, f = solid_arrays(m3.Manifold.compose(parts))
        if not validate_arrays(v, f).passed:
            continue
        if thick_enough is None or thick_enough(v, f):
            return parts, factor * tolerance
        valid = valid or (parts, factor * tolerance)
    if valid is not None:
        return valid
    if marched is not None and not validate_arrays(*solid_arrays(raw)).passed:
        raw = marched  # the push folded the surface somewhere: as marched
    return _drop_specks(raw, thickness), 0.0


#: no part of the wall ends thinner than T: the inner surface is marched at T plus the
#: simplification's tolerance, and its vertices short of that pushed out (`_thickened`);
#: False: marched at T, as before 2026-11-30
AT_LEAST_T = True
#: a marched vertex closer to the container than this fraction of its level is pushed out
THIN_VERTEX = 0.999
#: Newton steps of that push (each along the distance grid's gradient, by the exact
#: distance's shortfall)
THICKEN_STEPS = 2


def _thickened(v: np.ndarray, vertices: np.ndarray, faces: np.ndarray, level: float,
               values: np.ndarray, nearest: np.ndarray, origin: np.ndarray, spacing: float
               ) -> np.ndarray:
    """The inner surface's vertices `v`, marched at distance `level`, with each closer than
    that to the container (vertices, faces) pushed away from it to `level`. Marching
    interpolates the distance linearly along a grid edge, which cuts inside the curved level
    set where the container folds inward (a concave edge, a limb's crotch): on a coarse
    grid (a large print, where the grid is capped) walls came out a fifth thinner there.
    The push goes along the grid's gradient (`values`), by the shortfall of the distance to
    the triangles nearest the grid's nodes around (`nearest`: `_near_distances`)."""
    d = _near_distances(v, nearest, origin, spacing, vertices, faces)
    thin = np.flatnonzero(d < THIN_VERTEX * level)
    if len(thin) == 0:
        return v
    out = v.copy()
    grid = np.ascontiguousarray(values, np.float64)
    for _ in range(THICKEN_STEPS):
        p = out[thin]
        g = np.empty_like(p)
        for axis in range(3):  # central differences of the trilinear grid, half a cell
            step = np.zeros(3)
            step[axis] = 0.5 * spacing
            g[:, axis] = (sample_grid_many(grid, origin, spacing, p + step)
                          - sample_grid_many(grid, origin, spacing, p - step)) / spacing
        norm = np.linalg.norm(g, axis=1)
        # a distance's gradient is a unit vector: far less is a ridge, or the grid's cap
        ok = norm > 0.5
        short = level - _near_distances(p, nearest, origin, spacing, vertices, faces)
        move = np.where(ok & (short > 0), short, 0.0) / np.where(ok, norm, 1.0)
        out[thin] = p + move[:, None] * g
    return out


def inner_solid(vertices: np.ndarray, faces: np.ndarray, thickness: float, spacing: float,
                tolerance: float) -> tuple[m3.Manifold, int, float]:
    """The container offset inward by T (the cavities): (solid, cavities, tolerance used).

    vertices (V, 3) / faces (F, 3): the container, closed and outward wound; thickness T,
    grid ``spacing`` and simplification ``tolerance`` in its units. Raises InputError when T
    leaves no cavity (the message gives the largest T that works).
    """
    # T is the wall's least thickness (as slicers' hollowing takes it): simplifying moves the
    # surface by up to the tolerance, so the level keeps that much more
    level = thickness + (tolerance if AT_LEAST_T else 0.0)
    values, origin, nearest = _offset_grid(vertices, faces, level, spacing)
    if float(values.max()) <= level:
        raise _too_thick(thickness, _deepest(values, origin, spacing, vertices, faces))
    v, f = march_tetrahedra(values, level, origin, spacing)
    marched = to_solid(v, f)
    if marched.status() != m3.Error.NoError:  # pragma: no cover - marching output is manifold
        raise RuntimeError(f"inner shell surface rejected by manifold3d: {marched.status()}")
    pushed = (_thickened(v, vertices, faces, level, values, nearest, origin, spacing)
              if AT_LEAST_T else v)
    raw = marched if pushed is v else to_solid(pushed, f)
    diagonal = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    grid = np.ascontiguousarray(values, np.float64)

    def thick_enough(v: np.ndarray, f: np.ndarray) -> bool:
        """The distance grid at least T at each face's centre and edges' midpoints."""
        corners = v[f]
        points = np.vstack([corners.mean(axis=1),
                            (0.5 * (corners + np.roll(corners, -1, axis=1))).reshape(-1, 3)])
        return float(sample_grid_many(grid, origin, spacing, points).min()) >= thickness

    parts, used = _simplified(raw, thickness, tolerance, diagonal,
                              None if raw is marched else marched,
                              thick_enough if AT_LEAST_T else None)
    if not parts:
        raise _too_thick(thickness, _deepest(values, origin, spacing, vertices, faces))
    return m3.Manifold.compose(parts), len(parts), used
