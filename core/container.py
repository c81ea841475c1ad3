"""The container: its mesh in the container frame, a signed distance grid, interior samples.

Container frame: the file's coordinates times `frame_from_file` (a uniform scale when
`--container-size` is given), container units (millimetres for printing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .distance import DistanceGrid, distance_grid, min_pyramid
from .grid_size import finest_spacing
from .kernels import sample_grid_many, wall_depths
from .mesh_geometry import face_areas2, sample_surface
from .wall_planes import CreasePlanes, crease_planes

#: lattice points `interior_points` tests at a time
SLAB_POINTS = 1 << 20
#: surface samples per cell face's area (spacing^2) that `tighten_to_surface` tests, and
#: their bounds
WALL_SAMPLES_PER_CELL = 16
WALL_SAMPLES = (20_000, 1_000_000)
#: overshoot (cells) below which the grid is taken as exact: a wall on grid planes
ROUNDOFF = 1e-9
#: cells from the wall within which the container grid's nodes hold exact distances; a
#: node beyond holds a distance to some triangle, at least the true one
#: (`distance.distance_grid`)
GRID_BAND = 4


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
    # the face planes the grid's crease cells read (a box's edges and corners), where its
    # interpolant reads less room than there is
    creases: CreasePlanes

    def depth(self, points: np.ndarray) -> np.ndarray:
        """(M,) the wall depth (positive inside) at points (M,3), as the solver reads it:
        the grid, and the face planes in its crease cells (`kernels.wall_depth`)."""
        g = self.grid
        return wall_depths(g.values, g.origin, g.spacing, self.creases.arrays(),
                           np.ascontiguousarray(points, np.float64).reshape(-1, 3))

    @property
    def bounds(self) -> np.ndarray:
        """(2,3) axis-aligned bounds."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])


def build_container(vertices: np.ndarray, faces: np.ndarray, volume: float,
                    spacing: float) -> Container:
    """The container with its distance grid at about `spacing` (`container_grid`)."""
    return container_on(vertices, faces, volume, container_grid(vertices, faces, spacing))


def container_grid(vertices: np.ndarray, faces: np.ndarray, spacing: float) -> DistanceGrid:
    """The container's signed distance grid (positive inside) at about `spacing`, coarsened
    if too many cells (`grid_size.finest_spacing`), lowered where its interpolant sees room
    beyond the wall (`tighten_to_surface`). vertices (V,3), faces (F,3): the container mesh
    (container frame and units)."""
    vertices = np.ascontiguousarray(vertices, np.float64)
    spacing = grid_spacing(vertices, spacing)
    return tighten_to_surface(distance_grid(vertices, faces, spacing, pad=2 * spacing,
                                              band=GRID_BAND),
                              vertices, faces)


def grid_spacing(vertices: np.ndarray, spacing: float) -> float:
    """The spacing `container_grid` builds for a requested one: no finer than the cap on
    cells (`grid_size.finest_spacing`) for the container's vertices (V,3)."""
    return max(float(spacing), finest_spacing(np.ptp(vertices, axis=0)))


def container_on(vertices: np.ndarray, faces: np.ndarray, volume: float,
                 grid: DistanceGrid) -> Container:
    """The container on a grid of `container_grid`'s: with what the solver reads beside it
    (the grid's block minima and the crease cells' face planes)."""
    vertices = np.ascontiguousarray(vertices, np.float64)
    faces = np.ascontiguousarray(faces, np.int64)
    return Container(vertices, faces, float(volume), grid, min_pyramid(grid.values),
                     crease_planes(vertices, faces, grid.values, grid.origin, grid.spacing))


def tighten_to_surface(grid: DistanceGrid, vertices: np.ndarray,
                       faces: np.ndarray) -> DistanceGrid:
    """The container grid lowered where its interpolant sees room beyond the wall.

    The nodes hold exact distances, but between them the trilinear interpolant of a curved
    wall can lie outside the true surface by a tenth of a cell or more (the Armadillo's
    limbs: docs/notes-core.md), where the solver then places objects that certification
    finds through the wall. Each cell holding surface samples where the interpolant is
    positive has its eight nodes lowered by the largest such value: lowering a cell's
    corners by d lowers the interpolant inside it by exactly d, so at every sample the grid
    sees no room beyond the wall. Same frame and units as the grid (positive inside).
    """
    area = 0.5 * float(face_areas2(vertices, faces).sum())
    lo, hi = WALL_SAMPLES
    n = int(min(hi, max(lo, WALL_SAMPLES_PER_CELL * area / grid.spacing ** 2)))
    pts = sample_surface(vertices, faces, n)
    over = sample_grid_many(grid.values, grid.origin, grid.spacing, pts)
    keep = over > ROUNDOFF * grid.spacing
    if not keep.any():
        return grid
    shape = np.asarray(grid.values.shape)
    cell = np.clip(np.floor((pts[keep] - grid.origin) / grid.spacing).astype(np.int64), 0,
                   shape - 2)
    by_cell = np.zeros(tuple(shape - 1))
    np.maximum.at(by_cell, (cell[:, 0], cell[:, 1], cell[:, 2]), over[keep])
    drop = np.zeros(tuple(shape))
    nx, ny, nz = by_cell.shape
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                view = drop[dx:dx + nx, dy:dy + ny, dz:dz + nz]
                np.maximum(view, by_cell, out=view)
    return DistanceGrid(np.ascontiguousarray(grid.values - drop), grid.origin, grid.spacing)


#: the face-centred cubic lattice: a cubic cell's corner and its three face centres
FCC_BASIS = np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5], [0.5, 0.5, 0.0]])


def interior_points(container: Container, spacing: float, min_depth: float,
                    rng: np.random.Generator | None = None,
                    lattice: str = "cubic") -> np.ndarray:
    """Points of a regular lattice at least `min_depth` inside (container frame and units).

    The lattice holds one point per spacing^3 of volume: "cubic" with that spacing, or
    "fcc", face-centred cubic (cells of side 4^(1/3) spacing, each point's 12 nearest
    1.12 spacing away). It is offset by a random fraction of a cell when `rng` is given.
    Returns (M,3).
    """
    if lattice == "fcc":
        cell = spacing * 4.0 ** (1.0 / 3.0)
        off = rng.random(3) * cell if rng is not None else np.full(3, 0.5 * cell)
        return np.concatenate([_cubic_points(container, cell, min_depth, (off + b * cell) % cell)
                               for b in FCC_BASIS])
    if lattice != "cubic":
        raise ValueError(f"unknown lattice {lattice!r}: 'cubic' or 'fcc'")
    off = rng.random(3) * spacing if rng is not None else np.full(3, 0.5 * spacing)
    return _cubic_points(container, spacing, min_depth, off)


def deepest_points(container: Container, points: np.ndarray, count: int) -> np.ndarray:
    """The `count` points of `points` (M,3, container frame) deepest inside the container,
    in their given order (ties: the earlier first); all of them when M <= count."""
    if len(points) <= count:
        return points
    depth = container.depth(points)
    return points[np.sort(np.argsort(-depth, kind="stable")[:max(count, 0)])]


def _cubic_points(container: Container, spacing: float, min_depth: float,
                  off: np.ndarray) -> np.ndarray:
    """The cubic lattice's points offset by `off` from the container's lower bounds that lie
    at least `min_depth` inside."""
    lo, hi = container.bounds
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
        depth = container.depth(pts)
        kept.append(pts[depth >= min_depth])
    return np.concatenate(kept)
