"""Closest points on triangle meshes (numpy, vectorised).

Used to place connector struts between the exact closest points of two objects, or of an
object and the shell. All positions are in one frame (the packing's container frame in
container units, or an object's local frame), float64.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
                         ) -> np.ndarray:
    """Closest point to p[k] on triangle (a[k], b[k], c[k]), for every k.

    p, a, b, c: (K, 3) float64. Returns (K, 3). Degenerate triangles give a point on their
    edges (the barycentric regions below never divide by zero there).
    """
    ab, ac, ap = b - a, c - a, p - a
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3 = np.einsum("ij,ij->i", ab, bp)
    d4 = np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5 = np.einsum("ij,ij->i", ab, cp)
    d6 = np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2

    out = np.empty_like(p)
    todo = np.ones(len(p), dtype=bool)

    def take(mask: np.ndarray, value: np.ndarray) -> None:
        m = mask & todo
        out[m] = value[m]
        todo[m] = False

    with np.errstate(divide="ignore", invalid="ignore"):
        take((d1 <= 0) & (d2 <= 0), a)  # vertex regions
        take((d3 >= 0) & (d4 <= d3), b)
        take((d6 >= 0) & (d5 <= d6), c)
        v = d1 / (d1 - d3)
        take((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + v[:, None] * ab)  # edge ab
        w = d2 / (d2 - d6)
        take((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + w[:, None] * ac)  # edge ac
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        take((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + w[:, None] * (c - b))  # bc
        denom = va + vb + vc
        inside = todo & (np.abs(denom) > 0)
        v = vb / denom
        w = vc / denom
        take(inside, a + v[:, None] * ab + w[:, None] * ac)
    # zero-area triangles can land in a region whose formula divides 0 by 0
    todo |= ~np.isfinite(out).all(axis=1)
    if np.any(todo):  # zero-area leftovers: nearest of the three edges
        idx = np.flatnonzero(todo)
        best = np.full(len(idx), np.inf)
        for s, e in ((a, b), (b, c), (c, a)):
            d = e[idx] - s[idx]
            ll = np.einsum("ij,ij->i", d, d)
            t = np.einsum("ij,ij->i", p[idx] - s[idx], d) / np.where(ll > 0, ll, 1.0)
            q = s[idx] + np.clip(t, 0, 1)[:, None] * d
            dist = np.linalg.norm(q - p[idx], axis=1)
            better = dist < best
            out[idx[better]] = q[better]
            best[better] = dist[better]
    return out


class Surface:
    """A triangle mesh that answers closest-point queries.

    vertices (V, 3), faces (F, 3), in the frame the queries use. Candidate triangles are
    found with k-d trees over triangle centroids: a triangle can hold the closest point
    only if its centroid is within (an upper bound of the distance + its centroid-to-corner
    radius) of the query, so the answer is exact. The triangles are grouped by that radius
    (within a factor of 2), one tree each, so that a few large triangles (a shell's flat
    cut) do not widen every query to most of a fine mesh.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        tris = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
        self.a, self.b, self.c = tris[:, 0].copy(), tris[:, 1].copy(), tris[:, 2].copy()
        centroids = tris.mean(axis=1)
        self._centroids = centroids
        radii = np.linalg.norm(tris - centroids[:, None], axis=2).max(axis=1)
        largest = float(radii.max()) if len(radii) else 0.0
        self.tree = cKDTree(centroids)
        level = np.floor(np.log2(np.maximum(radii, largest * 1e-9 + 1e-300)))
        self._groups = [(idx, cKDTree(centroids[idx]), float(radii[idx].max()))
                        for idx in (np.flatnonzero(level == lv) for lv in np.unique(level))]

    def centroid(self, index: np.ndarray) -> np.ndarray:
        """Centroids of the triangles given by index."""
        return self._centroids[index]

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(K, 3) query points -> ((K, 3) closest surface points, (K,) distances)."""
        points = np.atleast_2d(np.asarray(points, np.float64))
        _, near = self.tree.query(points)
        out = np.empty_like(points)
        dist = np.empty(len(points))
        for k, p in enumerate(points):
            # the nearest centroid's triangle bounds the answer from above
            bound = float(np.linalg.norm(closest_on_triangles(
                p[None], self.a[near[k], None], self.b[near[k], None],
                self.c[near[k], None])[0] - p))
            cand = np.sort(np.concatenate(
                [idx[np.asarray(tree.query_ball_point(p, bound + radius), np.int64)]
                 for idx, tree, radius in self._groups]))
            if len(cand) == 0:
                cand = np.array([near[k]])
            q = closest_on_triangles(np.repeat(p[None], len(cand), 0), self.a[cand],
                                     self.b[cand], self.c[cand])
            d = np.linalg.norm(q - p, axis=1)
            j = int(np.argmin(d))
            out[k], dist[k] = q[j], d[j]
        return out, dist
