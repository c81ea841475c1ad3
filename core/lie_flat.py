"""Types that fit only lying down start lying down: plates flat, rods along.

A type whose middle half extent (along its bounding box's axes) exceeds the container's deepest
interior distance fits nowhere across the container's thin direction: a 20 x 20 x 1 plate in
a 2 mm slab, a tile in a thin frame. A rod longer than a tube is wide fits only along it: at
the container's deepest point it fits at few rotations drawn at random, and lying down.
Drawn at a random rotation such a type almost never grows, and the solver's rotation does
not turn it in time (such plates needed a slab 2.5 times their thickness:
docs/notes-robustness.md). Such a type is inserted with its thinnest axis along the
container's thinnest direction at the point and its longest along the roomiest, up to the
frame's symmetries (drawn at random). Every other type keeps its random rotation, so scenes
without such a type pack as before; one that fits only across a box's diagonal too.

Frames: a type's local frame; the container frame, container units.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from .container import Container
from .distance import DistanceGrid
from .kernels import sample_grid_many
from .rotations import matrix_to_quat, quat_to_matrix, random_quaternions

#: the most lattice points a cavity pass spaced for a flat-only type may have
MAX_FLAT_POINTS = 2_000_000
#: a type that fits at the container's deepest point at fewer than this share of rotations
#: drawn at random fits only lying down
RARE_FIT = 0.125
#: the rotations and the most vertices that share is measured with
_FIT_ROTATIONS = 64
_FIT_VERTICES = 2000
#: the turns that keep a box's axes (signs of its columns, right-handed)
_FLIPS = np.array([[1, 1, 1], [-1, -1, 1], [-1, 1, -1], [1, -1, -1]], np.float64)
#: directions the container's room at a point is probed along (one of each opposite pair)
_PROBES = np.array([d for d in np.ndindex(3, 3, 3) if d > (1, 1, 1)], np.float64) - 1.0
_PROBES /= np.linalg.norm(_PROBES, axis=1, keepdims=True)


def principal_frame(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A mesh's box axes (3, 3), columns longest first, right-handed, and its half extents
    (3,) along them (local frame): those of its oriented bounding box (trimesh's, about the
    smallest), which, unlike the axes of the vertices' spread, do not turn with the file
    for a cube or a regular solid (their spread is the same in every direction)."""
    to_box, extents = trimesh.bounds.oriented_bounds(np.asarray(vertices, np.float64))
    axes = np.asarray(to_box, np.float64)[:3, :3].T.copy()  # box axes in the local frame
    half = 0.5 * np.asarray(extents, np.float64)
    order = np.argsort(-half, kind="stable")
    axes, half = axes[:, order], half[order]
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1.0
    return axes, half


def flat_only(half_extents: np.ndarray, depth: float) -> np.ndarray:
    """(T,) whether each type (half extents (T, 3), longest first) fits the container,
    ``depth`` deep at its deepest, only lying flat."""
    return np.asarray(half_extents, np.float64)[:, 1] > depth


def _deepest(grid: DistanceGrid) -> np.ndarray:
    """(3,) the container's deepest point: of the nodes within half a cell of the greatest
    depth (a tube's axis, a slab's middle), the one nearest their centroid, not an end."""
    idx = np.argwhere(grid.values >= grid.values.max() - 0.5 * grid.spacing)
    nodes = grid.origin + grid.spacing * idx.astype(np.float64)
    return nodes[int(np.argmin(((nodes - nodes.mean(axis=0)) ** 2).sum(axis=1)))]


def _inside(grid: DistanceGrid, p: np.ndarray, turns: np.ndarray,
            vertices: np.ndarray) -> np.ndarray:
    """(R,) whether the mesh (vertices in its local frame; up to 2,000 of them are read)
    turned by each of ``turns`` (R, 3, 3) with its origin at p lies inside the container,
    by the grid's interpolated depth at its vertices."""
    v = np.asarray(vertices, np.float64)
    v = v[:: max(1, -(-len(v) // _FIT_VERTICES))]
    pts = (p + np.einsum("rij,vj->rvi", turns, v)).reshape(-1, 3)
    depth = sample_grid_many(grid.values, grid.origin, grid.spacing, pts)
    return depth.reshape(len(turns), -1).min(axis=1) >= 0.0


def fit_share(grid: DistanceGrid, vertices: np.ndarray, p: np.ndarray | None = None
              ) -> float:
    """The share of rotations (drawn from a fixed stream) at which a mesh (vertices in its
    local frame, about its origin) lies inside the container with its origin at p (3,),
    the grid's deepest node (`_deepest`) by default."""
    turns = quat_to_matrix(random_quaternions(np.random.default_rng(0), _FIT_ROTATIONS))
    return float(_inside(grid, _deepest(grid) if p is None else p, turns, vertices).mean())


def fits_lying_down(grid: DistanceGrid, type_axes: np.ndarray, vertices: np.ndarray,
                    p: np.ndarray | None = None) -> bool:
    """Whether a mesh lies inside the container at p (its deepest node by default) turned
    onto the room frame there (`room_frame`) in one of the four turns that keep it: a type
    that fits only across a box's diagonal does not, and is left to turn at random."""
    p = _deepest(grid) if p is None else p
    frame = room_frame(grid, p)
    turns = np.array([frame @ np.diag(s) @ type_axes.T for s in _FLIPS])
    return bool(_inside(grid, p, turns, vertices).any())


def flat_types(types: Sequence, radius: np.ndarray, grid: DistanceGrid
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T,) which of the types (each with .vertices, local frame; bounding radius (T,))
    fit the container (its distance grid) only lying down, and (T, 3, 3) / (T, 3) their
    box axes and half extents: identity and zeros for a type that can turn anywhere its
    bounding ball fits (radius <= the container's depth), whose box is not measured (0.3 s
    for an 8,000-vertex scan). Lying down: wider than the container is deep (`flat_only`),
    or longer than it is deep, fitting at its deepest point at fewer than RARE_FIT of
    random rotations and there lying down (`fits_lying_down`)."""
    n = len(types)
    depth = float(grid.values.max())
    axes = np.tile(np.eye(3), (n, 1, 1))
    half = np.zeros((n, 3))
    rare = np.zeros(n, bool)
    deepest = None
    for i, t in enumerate(types):
        if radius[i] > depth:
            axes[i], half[i] = principal_frame(t.vertices)
            # a type no longer than the container is deep fits turned (a cube in a slab a
            # little thicker than it is packed densest turned as the solver turns it)
            if half[i, 0] > depth:
                deepest = _deepest(grid) if deepest is None else deepest
                rare[i] = (fit_share(grid, t.vertices, deepest) < RARE_FIT
                           and fits_lying_down(grid, axes[i], t.vertices, deepest))
    return flat_only(half, depth) | rare, axes, half


def flat_spacing(spacing: float, container: Container, threshold: float) -> float:
    """A cavity pass's lattice spacing where a type fits only lying flat: no wider than the
    band of points at least ``threshold`` deep (the container's deepest, less it, twice),
    so that the lattice cannot miss a thin container's middle (a 1.1 mm slab's band is 0.3
    mm thick, and a lattice of 3 mm missed it on a quarter of the seeds), within
    MAX_FLAT_POINTS points."""
    band = 2.0 * (float(container.grid.values.max()) - threshold)
    floor = (container.volume / MAX_FLAT_POINTS) ** (1.0 / 3.0)
    return max(min(spacing, band), floor, container.grid.spacing)


def room_frame(grid: DistanceGrid, p: np.ndarray) -> np.ndarray:
    """The container's directions at point p (3,), columns roomiest first and thinnest
    last (right-handed). Across: the wall's normal (the grid's slope) where p is nearer one
    wall than the others, else the direction of least room, the grid's depth at p plus and
    minus twice p's depth along it (least across the middle of a slab or a tube). The
    roomiest is taken the same way across that."""
    h = grid.spacing
    steps = np.concatenate([p + h * np.eye(3), p - h * np.eye(3), p[None]])
    d = sample_grid_many(grid.values, grid.origin, h, steps)
    slope = (d[:3] - d[3:6]) / (2.0 * h)
    depth = max(float(d[6]), h)
    reach = 2.0 * depth

    def room(dirs: np.ndarray) -> np.ndarray:
        probes = np.concatenate([p + reach * dirs, p - reach * dirs])
        d = sample_grid_many(grid.values, grid.origin, grid.spacing, probes)
        return d[: len(dirs)] + d[len(dirs):]

    if np.linalg.norm(slope) > 0.5:
        # nearer one wall than the others: across is along the wall's normal (the probes
        # tie there, every direction reading twice the depth)
        thin = slope / np.linalg.norm(slope)
    else:
        thin = _PROBES[int(np.argmin(room(_PROBES)))]
    # the roomiest of 12 directions across the thin one
    u = np.cross(thin, [1.0, 0.0, 0.0] if abs(thin[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(thin, u)
    angles = np.arange(12) * (np.pi / 12)
    ring = np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * w
    long = ring[int(np.argmax(room(ring)))]
    return np.stack([long, np.cross(thin, long), thin], axis=1)


def flat_quaternion(type_axes: np.ndarray, p: np.ndarray, grid: DistanceGrid,
                    rng: np.random.Generator) -> np.ndarray:
    """(4,) rotation (w, x, y, z) taking a type's box axes (3, 3) onto the
    container's room frame at p, with one of the four turns that keep it (random)."""
    s = _FLIPS[int(rng.integers(4))]
    r = room_frame(grid, p) @ np.diag(s) @ type_axes.T
    return matrix_to_quat(r[None])[0]
