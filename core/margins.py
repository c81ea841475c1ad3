"""Contact margins: how much further than the clearance the solver keeps objects apart and
away from the wall, from how well each distance grid reproduces its true surface.

The solver sees objects and the container through trilinear distance grids. A smooth
surface is reproduced to a few hundredths of a cell; sharp edges and corners are rounded
off by up to half a cell, and there the approximations miss overlaps that certification
then finds on the real meshes. A margin covers that error, and every margin costs density,
so types whose grid reproduces their surface closely keep the smaller margin. The
container's grid is lowered where it sees room beyond the wall (`tighten_to_surface` in
container.py), so its error measured here is what remains between those samples.

Smooth types' grids err far less than sharp ones', and halved margins gained density on
smooth scenes but left overlaps on sharp ones, even where only one sharp type kept the
larger margin: so the smaller margins are for scenes whose every type is smooth
(measurements: docs/notes-core.md).

With a clearance the exact check is of gaps, with no tolerance, and a second error shows:
the solver measures a gap from the other object to a type's surface points, and between
those points the surface comes closer (with every vertex as a surface point no pair was
too close; docs/notes-core.md). So with a clearance each type's margin also covers half
that sampling gap (`sampling_gap`; a pair is tested from both sides, and the better side
misses at most the mean of the two). The wall is tested from the object's side only, so
the wall margin holds the other half (of the largest type's gap).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .distance import DistanceGrid
from .kernels import sample_grid_many
from .meshes import sample_surface
from .report import MarginReport

#: grid error (cells) at the 1st percentile of the surface up to which a surface is smooth
SMOOTH_ERROR = 0.17
#: surface samples per mesh for the error estimate
SAMPLES = 4096
#: the percentile of the sampling gap over a type's surface that its margin covers
GAP_PERCENTILE = 99.0


def surface_error(grid: DistanceGrid, vertices: np.ndarray, faces: np.ndarray,
                  solid: bool) -> float:
    """How far (in cells of `grid`) the grid moves the mesh's surface the unsafe way at
    its worst 1% of the surface.

    grid: the mesh's distance grid (positive inside, the mesh's frame and units). For an
    object (solid=True) the unsafe way is inwards (the grid sees the object smaller than it
    is); for a container (solid=False) outwards (the grid sees more room than there is).
    """
    d = sample_grid_many(grid.values, grid.origin, grid.spacing,
                         sample_surface(vertices, faces, SAMPLES)) / grid.spacing
    return max(float(-np.percentile(d, 1) if solid else np.percentile(d, 99)), 0.0)


def sampling_gap(grid: DistanceGrid, vertices: np.ndarray, faces: np.ndarray,
                 points: np.ndarray, probe_radius: float, gap: float) -> float:
    """How much further a type's surface `points` (P,3) say a neighbour is than its surface
    does, at the GAP_PERCENTILE of its surface (the type's frame and units).

    The neighbour is a ball of `probe_radius` (the scene's smallest object) held `gap` away
    from each of SAMPLES area-spread surface samples along the outward normal (the grid's
    gradient); the surface's own distance to the ball's centre is taken from the samples,
    the vertices and the points together. The ball stands for a convex neighbour: one
    flatter than it sees less of the error, a sharper one has its own points.
    """
    dense = sample_surface(vertices, faces, SAMPLES)
    at = sample_surface(vertices, faces, SAMPLES, seed=1)
    step = 0.25 * grid.spacing
    grad = np.stack([sample_grid_many(grid.values, grid.origin, grid.spacing, at + step * e)
                     - sample_grid_many(grid.values, grid.origin, grid.spacing, at - step * e)
                     for e in np.eye(3)], axis=1)
    norm = np.linalg.norm(grad, axis=1, keepdims=True)
    ok = norm[:, 0] > 1e-12
    centres = at[ok] - (probe_radius + gap) * grad[ok] / norm[ok]  # outward: -gradient
    seen, _ = cKDTree(points).query(centres)
    true, _ = cKDTree(np.concatenate([dense, vertices, points])).query(centres)
    return float(np.percentile(seen - true, GAP_PERCENTILE)) if len(centres) else 0.0


@dataclass
class Margins:
    """Per-type contact margins (T,) and the extra wall distance, container units, with the
    grid errors (cells) that chose them."""

    objects: np.ndarray
    wall: float
    object_cells: list[float]
    wall_cells: float
    object_errors: list[float]
    wall_error: float
    sampling_gaps: list[float] | None = None

    def report(self) -> MarginReport:
        """What the packing records (without the margins themselves)."""
        return MarginReport(object_cells=list(self.object_cells), wall_cells=self.wall_cells,
                            object_grid_errors_cells=list(self.object_errors),
                            container_grid_error_cells=self.wall_error,
                            sampling_gaps=self.sampling_gaps)


def contact_margins(types: list, container_grid: DistanceGrid, container_vertices: np.ndarray,
                    container_faces: np.ndarray, smooth: float, sharp: float,
                    wall_smooth: float, wall_sharp: float, clearance: float = 0.0) -> Margins:
    """Margins for object types (each with .grid, .vertices, .faces in its local frame) and
    the container: `smooth` cells of each type's grid where every type's grid surface
    error is at most SMOOTH_ERROR, else `sharp` cells (a sharp type's contacts are with the
    others too); `wall_smooth` or `wall_sharp` cells of the container grid by its own
    error, with a clearance as without: the sharp ones throughout with a clearance cost
    density and time, and the repair now pushes a gap that falls short apart by its
    shortfall (docs/notes-core.md). With a clearance each type's margin also holds half
    its `sampling_gap` at that clearance (container units, recorded as sampling_gaps), and
    the wall's margin half the largest of them.
    """
    errors = [surface_error(t.grid, t.vertices, t.faces, solid=True) for t in types]
    all_smooth = all(e <= SMOOTH_ERROR for e in errors)
    cells = [smooth if all_smooth else sharp for _ in errors]
    wall_error = surface_error(container_grid, container_vertices, container_faces,
                               solid=False)
    wall_cells = wall_smooth if wall_error <= SMOOTH_ERROR else wall_sharp
    objects = np.array([c * t.grid.spacing for c, t in zip(cells, types, strict=True)])
    wall = wall_cells * container_grid.spacing
    gaps = None
    if clearance > 0:
        probe = min(t.equivalent_radius for t in types)
        gaps = [sampling_gap(t.grid, t.vertices, t.faces, t.surface_points, probe, clearance)
                for t in types]
        objects = objects + 0.5 * np.array(gaps)
        wall += 0.5 * max(gaps)
    return Margins(
        objects=objects, wall=wall, object_cells=cells,
        wall_cells=wall_cells, object_errors=errors, wall_error=wall_error,
        sampling_gaps=gaps)
