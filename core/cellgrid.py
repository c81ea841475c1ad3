"""A uniform cell grid over object centres, so that contact and distance queries visit the
objects near a point instead of every object (the broad phase of the placement solver).

Frames and units: container frame, container units. Cells are cubes of side h over a box
(origin, dims cells per axis); an object lives in the cell of its centre, clamped to the box
(clamping keeps neighbours within one cell of each other, so nothing near is missed). Each
cell holds a doubly linked list of objects: head (cells,), nxt and prv (capacity,), -1 ends a
list; cell (capacity,) is an object's cell or -1 when it is in no list. Removed objects
(alive 0) are unlinked when a query meets them; the state never revives one.

`CellGrid` keeps the lists in step with a `PackState`; the numba functions below read and
update them from inside the solver's kernels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: the most cells a grid allocates: past it the cells grow (a thin shell container, or a
#: few objects in a large box), so memory follows the objects rather than the box
MAX_CELLS = 1 << 21
#: cells are this much wider than the largest contact reach, against rounding at a border
SLACK = 1.01


@njit(cache=True)
def cell_index(origin, h, dims, x, y, z):
    """Flat index of the cell holding point (x, y, z), clamped to the grid's box."""
    i = min(max(int(np.floor((x - origin[0]) / h)), 0), dims[0] - 1)
    j = min(max(int(np.floor((y - origin[1]) / h)), 0), dims[1] - 1)
    k = min(max(int(np.floor((z - origin[2]) / h)), 0), dims[2] - 1)
    return (i * dims[1] + j) * dims[2] + k


@njit(cache=True)
def link(grid, b, c):
    """Put object b at the front of cell c's list."""
    _, _, _, head, nxt, prv, cell = grid
    first = head[c]
    nxt[b] = first
    prv[b] = -1
    if first >= 0:
        prv[first] = b
    head[c] = b
    cell[b] = c


@njit(cache=True)
def unlink(grid, b):
    """Take object b out of its cell's list (nothing if it is in none)."""
    _, _, _, head, nxt, prv, cell = grid
    c = cell[b]
    if c < 0:
        return
    if prv[b] >= 0:
        nxt[prv[b]] = nxt[b]
    else:
        head[c] = nxt[b]
    if nxt[b] >= 0:
        prv[nxt[b]] = prv[b]
    nxt[b] = -1
    prv[b] = -1
    cell[b] = -1


@njit(cache=True)
def move(grid, b, x, y, z):
    """Object b's centre is now (x, y, z): relink it if its cell changed."""
    origin, h, dims, _, _, _, cell = grid
    c = cell_index(origin, h[0], dims, x, y, z)
    if c != cell[b]:
        unlink(grid, b)
        link(grid, b, c)


@njit(cache=True)
def insert_range(grid, pos, alive, start, stop):
    """Link the alive objects start..stop-1 (new to the grid) at their centres."""
    origin, h, dims, _, _, _, _ = grid
    for b in range(start, stop):
        if alive[b]:
            link(grid, b, cell_index(origin, h[0], dims, pos[b, 0], pos[b, 1], pos[b, 2]))


@njit(cache=True)
def near_pairs(a, n_pairs, pa, pb, typ, pos, scale, alive, active, margin, radius,
               clearance, grid):
    """`kernels._near_pairs` through the grid: append to (pa, pb) from n_pairs each alive b
    whose bounding sphere (plus the gaps to keep) reaches a's, skipping an active b < a,
    in increasing b (the order of a scan over every object, so results do not change);
    returns the new count, or -1 when pa and pb are full (grow them and call again). The
    cells must be at least the largest reach wide."""
    origin, h, dims, head, nxt, _, _ = grid
    ra = radius[typ[a]] * scale[a] + clearance + margin[a]
    ax = pos[a, 0]
    ay = pos[a, 1]
    az = pos[a, 2]
    hh = h[0]
    ci = min(max(int(np.floor((ax - origin[0]) / hh)), 0), dims[0] - 1)
    cj = min(max(int(np.floor((ay - origin[1]) / hh)), 0), dims[1] - 1)
    ck = min(max(int(np.floor((az - origin[2]) / hh)), 0), dims[2] - 1)
    start = n_pairs
    for i in range(max(ci - 1, 0), min(ci + 2, dims[0])):
        for j in range(max(cj - 1, 0), min(cj + 2, dims[1])):
            for k in range(max(ck - 1, 0), min(ck + 2, dims[2])):
                b = head[(i * dims[1] + j) * dims[2] + k]
                while b >= 0:
                    nb = nxt[b]
                    if not alive[b]:
                        unlink(grid, b)
                    elif b != a and not (active[b] and b < a):
                        lim = ra + radius[typ[b]] * scale[b] + margin[b]
                        dx = ax - pos[b, 0]
                        dy = ay - pos[b, 1]
                        dz = az - pos[b, 2]
                        if dx * dx + dy * dy + dz * dz <= lim * lim:
                            if n_pairs == pb.shape[0]:
                                return -1
                            pb[n_pairs] = b
                            n_pairs += 1
                    b = nb
    # insertion sort of the few new partners into increasing index
    for m in range(start + 1, n_pairs):
        v = pb[m]
        q = m - 1
        while q >= start and pb[q] > v:
            pb[q + 1] = pb[q]
            q -= 1
        pb[q + 1] = v
    for m in range(start, n_pairs):
        pa[m] = a
    return n_pairs


def empty_grid(lo: np.ndarray, hi: np.ndarray, reach: float, capacity: int) -> tuple:
    """Grid arrays over the box lo..hi (3,) whose cells are at least `reach` wide (the
    largest centre distance at which two objects can touch), with room for `capacity`
    objects: (origin (3,), h (1,), dims (3,), head, nxt, prv, cell)."""
    size = np.maximum(np.asarray(hi, float) - np.asarray(lo, float), 1e-9)
    h = max(float(reach) * SLACK, 1e-9)
    dims = np.maximum(np.ceil(size / h), 1).astype(np.int64)
    while int(np.prod(dims)) > MAX_CELLS:
        h *= (np.prod(dims) / MAX_CELLS) ** (1 / 3) * SLACK
        dims = np.maximum(np.ceil(size / h), 1).astype(np.int64)
    full = lambda m: np.full(m, -1, np.int64)  # noqa: E731
    return (np.asarray(lo, np.float64).copy(), np.array([h]), dims, full(int(np.prod(dims))),
            full(capacity), full(capacity), full(capacity))


class CellGrid:
    """Cell lists of a `PackState`'s objects, brought up to date by `sync` before each
    kernel call: new objects are linked, and the cells widen (the grid is rebuilt) when an
    object's reach exceeds them. The kernels relink the objects they move.

    lo, hi: (3,) box the cells cover (objects outside sit in the border cells); max_radius:
    the largest bounding radius of any type at full size; clearance: the gap kept between
    objects (container units)."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, max_radius: float, clearance: float):
        self.lo = np.asarray(lo, float)
        self.hi = np.asarray(hi, float)
        self.max_radius = float(max_radius)
        self.clearance = float(clearance)
        self.max_margin = -1.0
        self.arrays: tuple | None = None
        self.linked = 0  # objects 0..linked-1 have been seen

    def reach(self, max_margin: float) -> float:
        return 2.0 * (self.max_radius + max_margin) + self.clearance

    def sync(self, state, focus: np.ndarray) -> tuple:
        """Link objects added since the last call; rebuild when the new objects' or the
        focus objects' margins are wider than the cells allow. Returns the arrays."""
        n = state.n
        margin = state.margin
        widest = 0.0
        if n > self.linked:
            widest = float(margin[self.linked:n].max())
        if len(focus):
            widest = max(widest, float(margin[focus].max()))
        cap = len(state.typ)
        if (self.arrays is None or widest > self.max_margin
                or len(self.arrays[4]) < cap):
            self.max_margin = max(self.max_margin, widest,
                                  float(margin[:n].max()) if n else 0.0)
            self.arrays = empty_grid(self.lo, self.hi, self.reach(self.max_margin), cap)
            self.linked = 0
        if n > self.linked:
            insert_range(self.arrays, state.pos, state.alive, self.linked, n)
            self.linked = n
        return self.arrays
