"""Polygons of a mesh file as triangles: convex ones fanned, concave ones ear-clipped.

A file's polygon of four or more corners must be cut into triangles. A fan from the first
corner is right only for a convex polygon; on a concave one (an L-shaped or star-shaped
face, which modelling tools write when they do not triangulate) its triangles overlap and
leave part of the polygon uncovered, so the mesh crosses itself. Concave polygons are
triangulated by manifold3d's ear clipping in their own plane instead. Frames and units are
the file's; nothing is merged or moved.
"""

from __future__ import annotations

import manifold3d
import numpy as np


def fan(sizes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For polygons of ``sizes`` corners laid end to end, the triangles of a fan from each
    polygon's first corner: ((F, 3) positions in the corner list, (F,) polygon of each)."""
    sizes = np.asarray(sizes, np.int64)
    fans = np.maximum(sizes - 2, 0)
    polygon = np.repeat(np.arange(len(sizes)), fans)
    first = (np.cumsum(sizes) - sizes)[polygon]
    k = np.arange(len(polygon)) - np.repeat(np.cumsum(fans) - fans, fans) + 1
    return np.column_stack([first, first + k, first + k + 1]), polygon


def concave(vertices: np.ndarray, sizes: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(P,) bool: the polygons of four corners or more that a fan would get wrong: those that
    turn against their own normal (Newell's) at some corner, and those of five corners or
    more with an edge of no length (a corner repeated, or two at one place), where the turn
    there cannot be told.

    vertices: (V, 3) positions; sizes: (P,) corner counts (each >= 3); corners: (sum of
    sizes,) vertex indices, polygon after polygon. Corners on a straight line (no turn) do
    not make a polygon concave."""
    sizes = np.asarray(sizes, np.int64)
    out = np.zeros(len(sizes), bool)
    big = np.flatnonzero(sizes > 3)
    if not len(big):
        return out
    if len(big) == len(sizes) and sizes.min() == sizes.max():  # all of one size
        return _concave_of_one_size(vertices[np.asarray(corners).reshape(len(sizes), -1)])
    start = np.cumsum(sizes) - sizes
    n = sizes[big]
    polygon = np.repeat(np.arange(len(big)), n)  # among the big ones
    first = np.cumsum(n) - n
    local = np.arange(len(polygon)) - first[polygon]
    at = start[big][polygon] + local  # each big polygon's corners in `corners`
    nxt = first[polygon] + (local + 1) % n[polygon]  # the next corner, among the big ones
    p = vertices[corners[at]]
    q = p[nxt]
    x, y, z = p.T
    qx, qy, qz = q.T
    # Newell's normal: the sum over edges of p x q (twice the area vector)
    normal = np.add.reduceat(np.column_stack([y * qz - z * qy, z * qx - x * qz,
                                              x * qy - y * qx]), first, axis=0)
    ex, ey, ez = (q - p).T
    fx, fy, fz = ex[nxt], ey[nxt], ez[nxt]
    nx, ny, nz = normal[polygon].T
    along = (ey * fz - ez * fy) * nx + (ez * fx - ex * fz) * ny + (ex * fy - ey * fx) * nz
    e2 = ex * ex + ey * ey + ez * ez
    # a turn against the normal beyond rounding, measured against the sizes of the edges
    # and of the normal (squared, so without square roots)
    against = (along < 0) & (along * along > 1e-18 * e2 * e2[nxt] * (nx * nx + ny * ny
                                                                      + nz * nz))
    # a quad with an edge of no length is a triangle, which its fan covers (and a
    # triangle of no area): flagged, such "quads" (as some writers pad triangles) were
    # ear-clipped one by one, 85 s a million
    bad = against | ((e2 == 0) & (n[polygon] > 4))
    out[big] = np.bincount(polygon, bad, minlength=len(big)) > 0
    return out


def _concave_of_one_size(p: np.ndarray) -> np.ndarray:
    """:func:`concave` for (P, k, 3) corners of polygons all of k > 3 corners, by the same
    arithmetic in the same order on (P, k) arrays (1.5-1.7 times as fast as the gathers)."""
    k = p.shape[1]
    q = np.roll(p, -1, axis=1)
    x, y, z = np.moveaxis(p, 2, 0)
    qx, qy, qz = np.moveaxis(q, 2, 0)
    cross = np.stack([y * qz - z * qy, z * qx - x * qz, x * qy - y * qx], axis=-1)
    # summed by np.add.reduceat over the same runs of k as the general path, in its order
    nx, ny, nz = np.add.reduceat(cross.reshape(-1, 3), np.arange(0, p.shape[0] * k, k),
                                 axis=0).T
    ex, ey, ez = qx - x, qy - y, qz - z
    fx, fy, fz = (np.roll(e, -1, axis=1) for e in (ex, ey, ez))
    nx, ny, nz = nx[:, None], ny[:, None], nz[:, None]
    along = (ey * fz - ez * fy) * nx + (ez * fx - ex * fz) * ny + (ex * fy - ey * fx) * nz
    e2 = ex * ex + ey * ey + ez * ez
    against = (along < 0) & (along * along > 1e-18 * e2 * np.roll(e2, -1, axis=1) * (
        nx * nx + ny * ny + nz * nz))
    bad = against | ((e2 == 0) & (k > 4))
    return bad.any(axis=1)


def polygons_to_triangles(vertices: np.ndarray, sizes: np.ndarray, corners: np.ndarray
                          ) -> np.ndarray:
    """(F, 3) vertex indices of the triangles of the polygons (file order, each polygon's
    triangles in its winding): a fan for a convex polygon, ear clipping in the polygon's
    plane (manifold3d.triangulate) for a concave one.

    vertices: (V, 3) positions; sizes: (P,) corner counts (each >= 3); corners: (sum of
    sizes,) vertex indices, polygon after polygon."""
    vertices = np.asarray(vertices, np.float64)
    sizes = np.asarray(sizes, np.int64)
    corners = np.asarray(corners, np.int64)
    at, _ = fan(sizes)
    triangles = corners[at]
    bent = np.flatnonzero(concave(vertices, sizes, corners))
    if not len(bent):
        return triangles
    start = np.cumsum(sizes) - sizes
    fans = sizes - 2
    first = np.cumsum(fans) - fans  # each polygon's first triangle
    # a concave quad's one reflex corner sees the whole quad: the fan from there is right
    quads = bent[sizes[bent] == 4]
    if len(quads):
        ring = corners[start[quads][:, None] + np.arange(4)]
        reflex = _one_reflex_corner(vertices[ring])
        done_quads = reflex >= 0
        k = (reflex[done_quads, None] + np.arange(4)) % 4
        turned = np.take_along_axis(ring[done_quads], k, axis=1)
        rows = first[quads[done_quads]]
        triangles[rows] = turned[:, [0, 1, 2]]
        triangles[rows + 1] = turned[:, [0, 2, 3]]
        bent = np.setdiff1d(bent, quads[done_quads])
    out, done = [], 0
    for p in bent:
        ring = corners[start[p]:start[p] + sizes[p]]
        out += [triangles[done:first[p]], ring[_ear_clipped(vertices[ring])]]
        done = first[p] + fans[p]
    out.append(triangles[done:])
    return np.concatenate(out).astype(np.int64)


def _one_reflex_corner(points: np.ndarray) -> np.ndarray:
    """(m,) the corner (0-3) of each quad of ``points`` ((m, 4, 3)) that turns against the
    quad's normal, where exactly one does and no edge has zero length; else -1."""
    nxt = np.roll(points, -1, axis=1)
    normal = np.cross(points, nxt).sum(axis=1)
    edge = nxt - points
    turn = np.einsum("mij,mj->mi", np.cross(np.roll(edge, 1, axis=1), edge), normal)
    against = turn < 0  # at corner i: from the edge into it to the edge out of it
    ok = (against.sum(axis=1) == 1) & (np.einsum("mij,mij->mi", edge, edge) > 0).all(axis=1)
    return np.where(ok, np.argmax(against, axis=1), -1)


def _ear_clipped(points: np.ndarray) -> np.ndarray:
    """(n - 2, 3) positions in ``points`` ((n, 3), one polygon's corners in order) of its
    triangles, wound as the polygon is."""
    normal = np.cross(points, np.roll(points, -1, axis=0)).sum(axis=0)
    size = float(np.linalg.norm(normal))
    if not size > 0:  # no area (its corners on a line): the fan, of triangles of no area
        return fan(np.array([len(points)]))[0]
    normal /= size
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    flat = np.column_stack([(points - points[0]) @ u, (points - points[0]) @ v])
    # (u, v, normal) is right-handed, so a polygon wound about its normal is CCW in (u, v)
    return np.asarray(manifold3d.triangulate([flat]), np.int64)
