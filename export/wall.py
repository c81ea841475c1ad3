"""The wall thickness of a shell, measured with exact distances to the container
(`core.distance.surface_distance`).

Frame and units: the caller's (the container frame and units for a shell).
"""

from __future__ import annotations

import manifold3d as m3
import numpy as np

from jampacked.core.distance import surface_distance
from jampacked.core.meshes import sample_surface
from jampacked.core.solids import solid_arrays

__all__ = ["measure_wall_thickness", "vertex_wall_thickness"]


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


def vertex_wall_thickness(shell_outer_vertices: np.ndarray, shell_outer_faces: np.ndarray,
                          inner: m3.Manifold) -> np.ndarray:
    """Wall thickness at each vertex of the inner surface, (vertices,) float64: where the
    thinnest spots are, which random points in faces miss (the inner surface is made
    exactly T thick at its vertices, and faces between them can cut only a little inside:
    `offset._thickened`). Arguments as :func:`measure_wall_thickness`."""
    if inner.is_empty():
        return np.zeros(0)
    v, _ = solid_arrays(inner)
    return surface_distance(v, shell_outer_vertices, shell_outer_faces)
