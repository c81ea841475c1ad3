"""A box-shaped container filled as a grid of boxes that touch: one type, or types of one
part (the same part in colours) spread through the grid by their shares.

A maker sizes a box to hold N x M x K parts exactly. The stacked start (`stacking`) keeps
rows the solver's contact margins apart, so a box that fits the parts exactly lost a row
along each axis (240 bricks of 10 x 5 x 5 in a 50 x 30 x 40 box: 157 stacked). A part
lies inside its box, so boxes that touch (a clearance apart) never overlap, whatever the
part's shape: the grid needs no margin, and certification checks it on the real meshes
as any packing. `placement.place_once` lays it first: a closed grid that fills the box
is kept without an attempt, another where it holds more than the attempt did.

Frames: a type's local frame; the container frame, container units.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import permutations

import numpy as np
import trimesh

from .container import Container
from .metrics import rounded_counts
from .rotations import matrix_to_quat
from .stacking import Stack

#: a container is a box where its volume is its minimum-volume box's to this share (a box
#: saved as float32 STL and turned: 5.7e-7) and each face's corners lie, to HAIR of its
#: size, on the side its normal points to: a dent, a bevel or a moved corner, which each
#: put grid objects through the wall, make it no box
BOX_VOLUME = 1e-5
#: the share of the container's side that rows may overrun through rounding (the boxes of
#: a float32 STL), and that a vertex may lie off the box's sides
HAIR = 1e-6
#: the order in which a 2 x 2 x 2 block's cells take types (`_spread`): the first four
#: are a checkerboard's one colour, so two types in equal shares alternate in every row
BLOCK_ORDER = np.array([[[0, 5], [6, 3]], [[7, 2], [1, 4]]])


@dataclass(frozen=True)
class Grid:
    """A grid of boxes (`box_grid`): its objects (`stacking.Stack`), and whether it is
    closed: no slab it leaves along a side is as thick as the box's thinnest side and a
    clearance, so no object fits beside it in any turn."""

    stack: Stack
    closed: bool


def _oriented_box(vertices: np.ndarray, faces: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mesh's smallest box: axes (3, 3, columns, right-handed), half extents (3,) and
    centre (3,), in its own frame (trimesh's minimum-volume box, exact for a box, where
    `stacking.box_frame`'s one-degree sweep reads a 5 x 5 section 5.0001 wide). The axes
    go from the box's shortest side to its longest."""
    mesh = trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64),
                           process=False)
    to_origin, extents = trimesh.bounds.oriented_bounds(mesh)
    rot = to_origin[:3, :3]
    order = np.argsort(np.asarray(extents, np.float64), kind="stable")
    axes = rot.T[:, order]
    if np.linalg.det(axes) < 0:  # a box is the same with one axis reversed
        axes[:, 2] *= -1.0
    return axes, 0.5 * np.asarray(extents, np.float64)[order], -rot.T @ to_origin[:3, 3]


def _one_part(types: Sequence, live: np.ndarray) -> bool:
    """Whether the types `live` are one part (colours of it): as many vertices and faces
    each. Parts that differ only in how their faces are split touch where no corner meets a
    corner, which the union of an export cannot fuse (`export/weld.py`)."""
    shapes = {(len(types[t].vertices), len(types[t].faces)) for t in live}
    return len(shapes) == 1


def _spread(index: np.ndarray, count: np.ndarray) -> np.ndarray:
    """(N,) the type of each grid cell ((N, 3) integer indices) for `count` (T,) objects of
    each type, spread as an ordered dither does: the cells ranked by their place in the
    2 x 2 x 2 blocks at the finest scale first (BLOCK_ORDER), then the next, and each type
    given the next run of ranks. Each run is spread evenly through the grid, so no type
    clumps; two types in equal shares make a checkerboard."""
    bits = max(1, int(index.max()).bit_length())
    rank = np.zeros(len(index), np.int64)
    for b in range(bits):
        cell = (index >> b) & 1
        rank += BLOCK_ORDER[cell[:, 0], cell[:, 1], cell[:, 2]] * 8 ** (bits - 1 - b)
    typ = np.empty(len(index), np.int64)
    typ[np.argsort(rank, kind="stable")] = np.repeat(np.arange(len(count)), count)
    return typ


def _is_box(container: Container, frame: np.ndarray, middle: np.ndarray,
            size: np.ndarray) -> bool:
    """The container is the box of `frame` (its axes, columns), `middle` (its centre) and
    `size` (its sides), all in the container frame (BOX_VOLUME, HAIR)."""
    if abs(float(np.prod(size)) - container.volume) > BOX_VOLUME * float(np.prod(size)):
        return False
    # every face lies in the side its normal points to: its three corners on that side
    tri = (container.vertices[container.faces] - middle) @ frame  # (F, 3 corners, 3 axes)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    keep = np.any(normal != 0.0, axis=1)  # a face of no area points nowhere
    tri, normal = tri[keep], normal[keep]
    axis = np.argmax(np.abs(normal), axis=1)
    rows = np.arange(len(tri))
    side = 0.5 * size[axis] * np.sign(normal[rows, axis])
    off = np.abs(tri[rows, :, axis] - side[:, None])
    return bool(off.max() <= HAIR * float(size.max()))


def box_grid(container: Container, types: Sequence, volumes: np.ndarray,
             shares: np.ndarray, clearance: float) -> Grid | None:
    """Where the container is a box (`_is_box`) and the types with a share are one part
    (`_one_part`, with boxes of one size to a HAIR), the most such boxes in a grid along
    the container's sides, `clearance` apart and from the walls, the grid centred in the
    container, the types spread through it by their shares (`_spread`); else None (and
    where not one box fits).

    types: each with .vertices and .faces (local frame); volumes (T,); shares (T,) by
    count; clearance in container units. Stack.room is each type's volume grown by its
    box's share of the clearance, as `stacking.stack_start` gives it."""
    shares = np.asarray(shares, np.float64)
    live = np.flatnonzero(shares > 0)
    if len(live) == 0:
        return None
    frame, size, middle = _oriented_box(container.vertices, container.faces)
    size = 2.0 * size
    if not _is_box(container, frame, middle, size):
        return None
    lo = frame.T @ middle - 0.5 * size  # frame coordinates
    if not _one_part(types, live):
        return None
    boxes = [_oriented_box(types[t].vertices, types[t].faces) for t in live]
    halves = np.array([b[1] for b in boxes])
    half = halves.max(axis=0)  # a cell holds each type's box (they differ by a HAIR)
    if halves.min() <= 0 or np.any(halves.min(axis=0) < (1.0 - HAIR) * half):
        return None
    best = None
    for perm in permutations(range(3)):
        side = 2.0 * half[list(perm)]  # the box's side along each frame axis
        # n sides and n + 1 clearances fit in the box's size (a hair of rounding allowed)
        n = np.floor((size - clearance + HAIR * size) / (side + clearance)).astype(np.int64)
        if np.all(n >= 1) and (best is None or np.prod(n) > np.prod(best[1])):
            best = (perm, n, side)
    if best is None:
        return None
    perm, n, side = best
    pitch = side + clearance
    first = lo + 0.5 * (size - (n * side + (n - 1) * clearance)) + 0.5 * side
    index = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"),
                     axis=-1).reshape(-1, 3)
    grid = first + pitch * index
    which = _spread(index, rounded_counts(shares[live] / shares[live].sum(), len(index)))
    swap = np.zeros((3, 3))
    swap[np.arange(3), list(perm)] = 1.0  # frame axis j <- box axis perm[j]
    pos = np.empty((len(index), 3))
    quat = np.empty((len(index), 4))
    room = np.zeros(len(volumes))
    for k, (t, (axes, own, centre)) in enumerate(zip(live, boxes, strict=True)):
        turn = frame @ swap @ axes.T
        if np.linalg.det(turn) < 0:  # a box is the same with one axis reversed
            turn = frame @ swap @ np.diag([1.0, 1.0, -1.0]) @ axes.T
        mine = which == k
        pos[mine] = grid[mine] @ frame.T - turn @ centre
        quat[mine] = matrix_to_quat(turn[None])
        room[t] = volumes[t] * float(np.prod(2.0 * own + clearance) / np.prod(2.0 * own))
    slab = size - n * side - (n + 1) * clearance
    closed = bool(np.all(slab < 2.0 * half.min() + clearance))
    return Grid(Stack(live[which], pos, quat, room), closed)
