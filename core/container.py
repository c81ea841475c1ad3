"""The container: its mesh in the container frame, a signed distance grid, interior samples.

Container frame: the file's coordinates times `frame_from_file` (a uniform scale when
`--container-size` is given), container units (millimetres for printing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .distance import DistanceGrid, distance_grid, min_pyramid
from .kernels import sample_grid_many

#: grid cells across the container's largest extent are capped to keep memory and time sane
MAX_CELLS_PER_AXIS = 220
#: lattice points `interior_points` tests at a time
SLAB_POINTS = 1 << 20


@dataclass(frozen=True)
class Container:
    """Container mesh (container frame) with its signed distance grid (positive inside)."""

    vertices: np.ndarray  # (V,3)
    faces: np.ndarray  # (F,3)
    volume: float
    grid: DistanceGrid
    # lower bounds of the grid's interpolant over blocks of cells (see `min_pyramid`): lets
    # the contact kernels skip objects and point clusters that are far from the wall
    pyramid: tuple[np.ndarray, np.ndarray, np.ndarray]

    @property
    def bounds(self) -> np.ndarray:
        """(2,3) axis-aligned bounds."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])


def build_container(vertices: np.ndarray, faces: np.ndarray, volume: float,
                    spacing: float) -> Container:
    """Distance grid of the container at about `spacing` (coarsened if too many cells)."""
    vertices = np.ascontiguousarray(vertices, np.float64)
    extent = float(np.ptp(vertices, axis=0).max())
    spacing = max(float(spacing), extent / MAX_CELLS_PER_AXIS)
    grid = distance_grid(vertices, faces, spacing, pad=2 * spacing, band=4)
    return Container(vertices, np.ascontiguousarray(faces, np.int64), float(volume), grid,
                     min_pyramid(grid.values))


def interior_points(container: Container, spacing: float, min_depth: float,
                    rng: np.random.Generator | None = None) -> np.ndarray:
    """Points of a regular lattice (spacing, container units) at least `min_depth` inside.

    The lattice is offset by a random fraction of a cell when `rng` is given. Returns (M,3).
    """
    lo, hi = container.bounds
    off = rng.random(3) * spacing if rng is not None else np.full(3, 0.5 * spacing)
    axes = [np.arange(lo[a] + off[a], hi[a], spacing) for a in range(3)]
    if any(len(a) == 0 for a in axes):
        return np.zeros((0, 3))
    # slab by slab along x, in the order of the whole lattice: the bounding box's lattice
    # is never held at once, only the points inside (a thin or hollow container's box
    # holds many times more)
    yz = np.stack([x.ravel() for x in np.meshgrid(axes[1], axes[2], indexing="ij")], axis=1)
    per_slab = max(1, SLAB_POINTS // len(yz))
    kept = []
    for start in range(0, len(axes[0]), per_slab):
        xs = axes[0][start:start + per_slab]
        pts = np.empty((len(xs) * len(yz), 3))
        pts[:, 0] = np.repeat(xs, len(yz))
        pts[:, 1:] = np.tile(yz, (len(xs), 1))
        depth = sample_grid_many(container.grid.values, container.grid.origin,
                                 container.grid.spacing, pts)
        kept.append(pts[depth >= min_depth])
    return np.concatenate(kept)
