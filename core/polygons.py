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
    """(P,) bool: which polygons turn against their own normal (Newell's) at some corner.

    vertices: (V, 3) positions; sizes: (P,) corner counts (each >= 3); corners: (sum of
    sizes,) vertex indices, polygon after polygon. A triangle is never concave; corners on
    a straight line (no turn) do not make a polygon concave."""
    sizes = np.asarray(sizes, np.int64)
    if not len(sizes) or sizes.max(initial=0) <= 3:
        return np.zeros(len(sizes), bool)
    start = np.cumsum(sizes) - sizes
    polygon = np.repeat(np.arange(len(sizes)), sizes)
    local = np.arange(len(corners)) - start[polygon]
    nxt = start[polygon] + (local + 1) % sizes[polygon]
    p = vertices[corners]
    q = p[nxt]
    normal = np.add.reduceat(np.cross(p, q), start, axis=0)  # Newell: twice the area vector
    edge = q - p
    turn = np.cross(edge, edge[nxt])
    along = np.einsum("ij,ij->i", turn, normal[polygon])
    # a turn against the normal beyond rounding, measured against the edges' own sizes
    scale = np.linalg.norm(edge, axis=1) * np.linalg.norm(edge[nxt], axis=1)
    scale = scale * np.linalg.norm(normal[polygon], axis=1)
    against = along < -1e-9 * scale
    return (np.bincount(polygon, against, minlength=len(sizes)) > 0) & (sizes > 3)


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
    out, done = [], 0
    for p in bent:
        ring = corners[start[p]:start[p] + sizes[p]]
        out += [triangles[done:first[p]], ring[_ear_clipped(vertices[ring])]]
        done = first[p] + fans[p]
    out.append(triangles[done:])
    return np.concatenate(out).astype(np.int64)


def _ear_clipped(points: np.ndarray) -> np.ndarray:
    """(n - 2, 3) positions in ``points`` ((n, 3), one polygon's corners in order) of its
    triangles, wound as the polygon is."""
    normal = np.cross(points, np.roll(points, -1, axis=0)).sum(axis=0)
    normal /= np.linalg.norm(normal)
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    flat = np.column_stack([(points - points[0]) @ u, (points - points[0]) @ v])
    # (u, v, normal) is right-handed, so a polygon wound about its normal is CCW in (u, v)
    return np.asarray(manifold3d.triangulate([flat]), np.int64)
