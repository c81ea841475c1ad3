"""Exact distances to a triangle mesh, and the wall thickness of a shell measured with them.

Frame and units: the caller's (the container frame and units for a shell).
"""

from __future__ import annotations

import itertools

import manifold3d as m3
import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from jampacked.core.distance import point_triangle_distance
from jampacked.core.meshes import sample_surface
from jampacked.core.solids import solid_arrays

__all__ = ["measure_wall_thickness", "surface_distance"]


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
