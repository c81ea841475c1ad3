"""Exact wall depths in the container grid's cells that a crease of the wall passes.

Across a crease (a box's edge or corner, where the nearest wall changes) the trilinear
interpolant of the container grid reads less room than there is: up to 0.58 of a cell
near a box's corner (docs/notes-core.md, "A crease's cells read the wall's planes"). In
those cells the kernels also read the least depth below the planes of the container's faces
that come within `reach` of the cell, and take the larger of the two readings.

The planes are read only where they say the point is inside, and there they are a lower
bound of the true depth (positive inside), as the grid is, so their larger one is too: a
point at depth d <= reach has its nearest face within reach, and that face's plane is at
most d away. A point outside reads at least one plane negative: among the faces at its
nearest point, one whose plane it lies beyond (the angle-weighted pseudonormal's sign,
Baerentzen and Aanaes 2005), as long as that face is among the cell's; the kernels read the
planes only where the grid reads more than -1 cell, which keeps a point more than `reach`
outside away from them (a cell's nodes are within sqrt(3) cells of any point in it, so the
interpolant is within sqrt(3) cells of the true depth). Container frame and units; the
mesh closed (wound either way: `face_planes`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .distance import point_triangle_distance
from .kernels import trilinear
from .mesh_geometry import signed_six_volumes

#: the depth (cells) up to which the planes are read: the nodes within it hold exact
#: distances (`container.GRID_BAND`), and inner spheres this deep still touch the wall
REACH_CELLS = 4.0
#: a cell keeps at most this many distinct planes; a cell near more (a scanned, curved
#: wall's) keeps the grid alone, whose interpolant is close to the truth there
MAX_PLANES = 12
#: a cell is kept where its planes read at least this much (cells) more room than the grid
#: at one of its sample points
MIN_GAIN = 0.01
#: two face planes closer than this (unit normals; offsets in container lengths over the
#: container's size) are one plane
SAME_PLANE = 1e-9


@dataclass(frozen=True)
class CreasePlanes:
    """The cells whose wall depth the face planes read better than the grid.

    index: by flat cell index, (i * (ny - 1) + j) * (nz - 1) + k for the cell whose lowest
    node is (i, j, k) of the container grid's (nx, ny, nz), the row of each of the K crease
    cells, -1 for the others (empty when K is 0); offsets:
    (K + 1,) int64 into `ids`; ids: int64 plane indices of each cell; planes: (P, 4) inward
    unit normal n and offset c, depth n . p + c; reach: the depth (container units) beyond
    which the planes are not read.
    """

    index: np.ndarray
    offsets: np.ndarray
    ids: np.ndarray
    planes: np.ndarray
    reach: float

    @property
    def cells(self) -> np.ndarray:
        """(K,) the crease cells' flat indices, sorted (their rows' order)."""
        return np.flatnonzero(self.index >= 0)

    def arrays(self) -> tuple:
        """(index, offsets, ids, planes, reach), as the kernels take them."""
        return self.index, self.offsets, self.ids, self.planes, self.reach


def no_creases() -> CreasePlanes:
    """No cell reads planes: the grid alone."""
    return CreasePlanes(np.zeros(0, np.int32), np.zeros(1, np.int64), np.zeros(0, np.int64),
                        np.zeros((0, 4)), 0.0)


def face_planes(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each face's plane as an index into the distinct planes (F,) int64, -1 for a
    degenerate face, and the distinct planes (P, 4): inward unit normal and offset. A
    closed mesh wound inward (negative volume) has its normals turned, so that inward is
    towards its inside either way."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    a = v[f[:, 0]]
    cross = np.cross(v[f[:, 1]] - a, v[f[:, 2]] - a)
    if len(f) and signed_six_volumes(v, f).sum() < 0:
        cross = -cross
    norm = np.linalg.norm(cross, axis=1)
    size = max(float(np.ptp(v, axis=0).max()), 1e-300)
    edge = np.linalg.norm(v[f[:, 1]] - a, axis=1) + np.linalg.norm(v[f[:, 2]] - a, axis=1)
    ok = norm > 1e-12 * edge * edge
    plane_of = np.full(len(f), -1, np.int64)
    if not ok.any():
        return plane_of, np.zeros((0, 4))
    n_out = cross[ok] / norm[ok, None]
    planes = np.concatenate([-n_out, np.einsum("ij,ij->i", n_out, a[ok])[:, None]], axis=1)
    key = np.round(planes / np.array([SAME_PLANE] * 3 + [SAME_PLANE * size])).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    plane_of[ok] = inverse.ravel()
    return plane_of, np.ascontiguousarray(planes[first])


def crease_planes(vertices: np.ndarray, faces: np.ndarray, values: np.ndarray,
                  origin: np.ndarray, spacing: float) -> CreasePlanes:
    """The crease cells of a container grid (values (nx, ny, nz), positive inside, at
    origin + (i, j, k) * spacing) and the face planes each reads, for a closed mesh
    (container frame)."""
    values = np.ascontiguousarray(values, np.float64)
    if min(values.shape) < 2:
        return no_creases()
    reach = REACH_CELLS * spacing
    plane_of, planes = face_planes(vertices, faces)
    v = values
    lo = v[:-1, :-1, :-1].copy()
    hi = v[:-1, :-1, :-1].copy()
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                s = v[dx:dx + v.shape[0] - 1, dy:dy + v.shape[1] - 1, dz:dz + v.shape[2] - 1]
                np.minimum(lo, s, out=lo)
                np.maximum(hi, s, out=hi)
    # the kernels read the planes where the grid reads between -1 cell and reach
    candidate = (lo < reach) & (hi > -spacing)
    del lo, hi
    slot = np.full(candidate.shape, -1, np.int32)
    where = np.flatnonzero(candidate.ravel())
    slot.ravel()[where] = np.arange(len(where), dtype=np.int32)
    ids, full = _cell_planes(np.asarray(vertices, np.float64), np.asarray(faces, np.int64),
                             plane_of, np.asarray(origin, np.float64), float(spacing), reach,
                             slot, len(where))
    counts = (ids >= 0).sum(axis=1)
    keep = ~full & (counts >= 2)
    cells = where[keep]
    ids = ids[keep]
    counts = counts[keep]
    if len(cells):
        gain = _gain(values, np.asarray(origin, np.float64), float(spacing), cells, ids,
                     planes, reach)
        good = gain > MIN_GAIN * spacing
        cells, ids, counts = cells[good], ids[good], counts[good]
    if not len(cells):
        return no_creases()
    # `where` is increasing, so the kept cells are sorted
    flat_ids = ids[ids >= 0]  # row by row: each cell's planes together
    used, flat_ids = np.unique(flat_ids, return_inverse=True)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    index = np.full(slot.size, -1, np.int32)
    index[cells] = np.arange(len(cells), dtype=np.int32)
    return CreasePlanes(index, offsets, flat_ids.ravel().astype(np.int64),
                        np.ascontiguousarray(planes[used]), float(reach))


@njit(cache=True)
def _cell_planes(vertices, faces, plane_of, origin, h, reach, slot, n_slots):
    """Each candidate cell's (slot >= 0) planes: (n_slots, MAX_PLANES) plane indices (-1
    where unused) of the faces within reach plus half the cell's diagonal of its centre
    (every face within reach of a point of the cell, and few merely near it, so that
    neighbouring cells read nearly the same planes), and whether the faces whose bounding
    boxes, grown by reach, meet the cell lie on more than MAX_PLANES planes (a curved
    wall's cell: the grid alone reads it)."""
    ids = np.full((n_slots, MAX_PLANES), -1, np.int32)
    loose = np.full((n_slots, MAX_PLANES), -1, np.int32)
    full = np.zeros(n_slots, np.bool_)
    cx, cy, cz = slot.shape
    n = (cx, cy, cz)
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    centre = np.empty(3)
    near = reach + 0.5 * np.sqrt(3.0) * h
    for f in range(faces.shape[0]):
        pl = plane_of[f]
        if pl < 0:
            continue
        va = vertices[faces[f, 0]]
        vb = vertices[faces[f, 1]]
        vc = vertices[faces[f, 2]]
        for ax in range(3):
            mn = (min(va[ax], vb[ax], vc[ax]) - reach - origin[ax]) / h
            mx = (max(va[ax], vb[ax], vc[ax]) + reach - origin[ax]) / h
            lo[ax] = max(0, int(np.floor(mn)) - 1)
            hi[ax] = min(n[ax] - 1, int(np.floor(mx)))
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                for k in range(lo[2], hi[2] + 1):
                    s = slot[i, j, k]
                    if s < 0 or full[s]:
                        continue
                    if not _add_plane(loose, s, pl):
                        full[s] = True
                        continue
                    centre[0] = origin[0] + (i + 0.5) * h
                    centre[1] = origin[1] + (j + 0.5) * h
                    centre[2] = origin[2] + (k + 0.5) * h
                    if point_triangle_distance(centre, va, vb, vc) <= near:
                        _add_plane(ids, s, pl)  # a subset of loose's: it has room
    return ids, full


@njit(cache=True)
def _add_plane(ids, s, pl):
    """Plane pl into row s of ids (unused entries -1) unless there; False when full."""
    for u in range(ids.shape[1]):
        if ids[s, u] == pl:
            return True
        if ids[s, u] < 0:
            ids[s, u] = pl
            return True
    return False


@njit(cache=True)
def _gain(values, origin, h, cells, ids, planes, reach):
    """The most room (container units) each cell's planes read beyond the grid's
    interpolant, at the 27 points of a 3 x 3 x 3 lattice over the cell."""
    nx, ny, nz = values.shape
    flat = values.ravel()
    out = np.full(cells.shape[0], -np.inf)
    for m in range(cells.shape[0]):
        c = cells[m]
        k = c % (nz - 1)
        j = (c // (nz - 1)) % (ny - 1)
        i = c // ((nz - 1) * (ny - 1))
        for a in range(3):
            for b in range(3):
                for e in range(3):
                    px = origin[0] + (i + 0.5 * a) * h
                    py = origin[1] + (j + 0.5 * b) * h
                    pz = origin[2] + (k + 0.5 * e) * h
                    d, _, _, _ = trilinear(flat, 0, nx, ny, nz, origin[0], origin[1],
                                           origin[2], h, px, py, pz)
                    if d <= -h or d >= reach:
                        continue
                    best = reach
                    for u in range(ids.shape[1]):
                        pl = ids[m, u]
                        if pl < 0:
                            break
                        best = min(best, planes[pl, 0] * px + planes[pl, 1] * py
                                   + planes[pl, 2] * pz + planes[pl, 3])
                    out[m] = max(out[m], best - d)
    return out
