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

__all__ = ["measure_wall_thickness", "wall_thickness"]


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
    return wall_thickness(shell_outer_vertices, shell_outer_faces, inner, n, seed)[0]


def wall_thickness(shell_outer_vertices: np.ndarray, shell_outer_faces: np.ndarray,
                   inner: m3.Manifold, n: int = 2000, seed: int = 0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The wall thickness at ``n`` random points of the inner surface (as
    :func:`measure_wall_thickness`) and at each of its vertices, (n,) and (vertices,)
    float64. The vertices hold the thinnest spots, which random points in faces miss (the
    inner surface is made at least T thick at its vertices, and faces between them cut only
    a little inside: `offset._thickened`)."""
    if inner.is_empty():
        return np.zeros(0), np.zeros(0)
    v, f = solid_arrays(inner)
    points = sample_surface(v, f, n, seed) if n > 0 else np.zeros((0, 3))
    d = surface_distance(np.vstack([points, v]), shell_outer_vertices, shell_outer_faces)
    return d[:len(points)], d[len(points):]
