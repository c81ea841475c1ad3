"""Inner sphere packings of object types (the paper's object approximation).

Greedy largest inscribed sphere on a signed distance grid: repeatedly take the node with the
largest free radius (distance to the surface and to every sphere already placed), add that
sphere, update the free radius. The spheres are disjoint and inside the mesh (to the grid's
accuracy), so sums of their pairwise lens volumes measure object-object penetration.
"""

from __future__ import annotations

import numpy as np

from .distance import DistanceGrid


def inner_spheres(grid: DistanceGrid, max_spheres: int, *,
                  min_radius_fraction: float = 0.04) -> tuple[np.ndarray, np.ndarray]:
    """Greedy inner sphere packing.

    grid: signed distance grid (positive inside) in the object's local frame.
    Returns centres (S, 3) and radii (S,) in the same frame and units, largest first;
    stops early when the largest free radius is below `min_radius_fraction` of the first.
    """
    pts = grid.node_points()
    free = grid.values.ravel().copy()
    inside = free > 0
    pts = pts[inside]
    free = free[inside]
    centres = []
    radii = []
    if free.size == 0:
        return np.zeros((0, 3)), np.zeros(0)
    r_first = float(free.max())
    for _ in range(max_spheres):
        k = int(np.argmax(free))
        r = float(free[k])
        if r <= 0 or r < min_radius_fraction * r_first:
            break
        c = pts[k].copy()
        centres.append(c)
        radii.append(r)
        gap = np.sqrt(((pts - c) ** 2).sum(axis=1)) - r
        np.minimum(free, gap, out=free)
    return np.asarray(centres, np.float64).reshape(-1, 3), np.asarray(radii, np.float64)


def sphere_coverage(grid: DistanceGrid, centres: np.ndarray, radii: np.ndarray) -> float:
    """Fraction of the grid's interior nodes covered by the spheres (0..1)."""
    pts = grid.node_points()[grid.values.ravel() > 0]
    if pts.size == 0:
        return 0.0
    covered = np.zeros(len(pts), bool)
    for c, r in zip(centres, radii, strict=True):
        covered |= ((pts - c) ** 2).sum(axis=1) <= r * r
    return float(covered.mean())
