"""numba kernels behind :mod:`jampacked.export.validate`: merging identical positions, per-face
geometry, fans, winding patches, duplicate faces and per-body sums (the edge structure they
read is :mod:`jampacked.core.mesh_topology`'s).

Each kernel gives exactly (bit for bit) what the numpy formulation it replaced gave; the
tests hold those formulations as references. Faces are (F, 3) int64 vertex indices; corner
c = 3 * face + slot starts the half-edge to the next vertex of its face.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from jampacked.core.mesh_topology import uf_flatten, uf_union

# --------------------------------------------------------------------------------------------
# merging


@njit(cache=True)
def used_vertices(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices that faces use, sorted (as ``np.unique(faces)``), and faces re-indexed into
    that list (as ``np.searchsorted(used, faces)``)."""
    local = np.full(n_vertices, -1, np.int64)
    for f in range(faces.shape[0]):
        for k in range(3):
            local[faces[f, k]] = 0
    n = 0
    for v in range(n_vertices):
        if local[v] == 0:
            local[v] = n
            n += 1
    used = np.empty(n, np.int64)
    for v in range(n_vertices):
        if local[v] >= 0:
            used[local[v]] = v
    out = np.empty_like(faces)
    for f in range(faces.shape[0]):
        for k in range(3):
            out[f, k] = local[faces[f, k]]
    return used, out


@njit(cache=True, inline="always")
def _hash3(x, y, z):
    """A 64-bit hash of three uint64 (for the open-addressing tables below)."""
    h = x * np.uint64(0x9E3779B97F4A7C15)
    h ^= y * np.uint64(0xC2B2AE3D27D4EB4F) + (h >> np.uint64(29))
    h ^= z * np.uint64(0x165667B19E3779F9) + (h >> np.uint64(32))
    return h ^ (h >> np.uint64(31))


@njit(cache=True)
def merge_bits(bits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Group equal rows of (V, 3) uint64 (the bits of positions) with a hash table.

    Returns ``(first, remap)``: (U,) first row of each group, in order of first occurrence,
    and (V,) the group of each row.
    """
    n = bits.shape[0]
    size = 1
    while size < 2 * n:
        size *= 2
    mask = np.uint64(size - 1)
    table = np.full(size, -1, np.int64)
    first = np.empty(n, np.int64)
    remap = np.empty(n, np.int64)
    n_groups = 0
    for i in range(n):
        x, y, z = bits[i, 0], bits[i, 1], bits[i, 2]
        slot = _hash3(x, y, z) & mask
        while True:
            g = table[slot]
            if g < 0:
                table[slot] = n_groups
                first[n_groups] = i
                remap[i] = n_groups
                n_groups += 1
                break
            j = first[g]
            if bits[j, 0] == x and bits[j, 1] == y and bits[j, 2] == z:
                remap[i] = g
                break
            slot = (slot + np.uint64(1)) & mask
    return first[:n_groups].copy(), remap


# --------------------------------------------------------------------------------------------
# per-face geometry


@njit(cache=True)
def face_geometry(positions: np.ndarray, faces: np.ndarray, origin: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per face: a repeated vertex; twice the area (norm of the edge cross product); the
    longest edge; six times the signed volume of the tetrahedron with ``origin``.

    The arithmetic follows numpy's ``np.cross``, ``np.linalg.norm`` and ``np.einsum`` in the
    same order, so the results are bit for bit those of the vectorised formulas.
    """
    n = faces.shape[0]
    repeated = np.empty(n, np.bool_)
    area2 = np.empty(n)
    longest = np.empty(n)
    six = np.empty(n)
    ox, oy, oz = origin[0], origin[1], origin[2]
    for f in range(n):
        i, j, k = faces[f, 0], faces[f, 1], faces[f, 2]
        repeated[f] = i == j or j == k or k == i
        ax, ay, az = positions[i, 0], positions[i, 1], positions[i, 2]
        bx, by, bz = positions[j, 0], positions[j, 1], positions[j, 2]
        cx, cy, cz = positions[k, 0], positions[k, 1], positions[k, 2]
        ux, uy, uz = bx - ax, by - ay, bz - az
        vx, vy, vz = cx - ax, cy - ay, cz - az
        nx = uy * vz - uz * vy
        ny = uz * vx - ux * vz
        nz = ux * vy - uy * vx
        area2[f] = np.sqrt(nx * nx + ny * ny + nz * nz)
        e0x, e0y, e0z = bx - ax, by - ay, bz - az
        e1x, e1y, e1z = cx - bx, cy - by, cz - bz
        e2x, e2y, e2z = ax - cx, ay - cy, az - cz
        l0 = np.sqrt(e0x * e0x + e0y * e0y + e0z * e0z)
        l1 = np.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
        l2 = np.sqrt(e2x * e2x + e2y * e2y + e2z * e2z)
        if l0 != l0 or l1 != l1 or l2 != l2:
            longest[f] = np.nan  # as numpy's max
        else:
            longest[f] = max(l0, l1, l2)
        px, py, pz = ax - ox, ay - oy, az - oz
        qx, qy, qz = bx - ox, by - oy, bz - oz
        rx, ry, rz = cx - ox, cy - oy, cz - oz
        wx = qy * rz - qz * ry
        wy = qz * rx - qx * rz
        wz = qx * ry - qy * rx
        # np.einsum sums the three products as (x + z) + y (its SIMD lanes, which start at
        # +0.0: an all-zero sum is +0.0)
        six[f] = ((px * wx + pz * wz) + py * wy) + 0.0
    return repeated, area2, longest, six


# --------------------------------------------------------------------------------------------
# edges


@njit(cache=True)
def fans(faces: np.ndarray, proper: np.ndarray, first_corner: np.ndarray,
         second_corner: np.ndarray, inconsistent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fans of faces around each vertex, joined across edges used by exactly two faces.
    Returns (vertex of each fan, a proper face of each fan), fans in corner order."""
    n_corners = 3 * faces.shape[0]
    parent = np.arange(n_corners)
    for e in range(first_corner.shape[0]):
        s1 = first_corner[e]
        if s1 < 0:
            continue
        s2 = second_corner[e]
        e1 = s1 - s1 % 3 + (s1 % 3 + 1) % 3
        e2 = s2 - s2 % 3 + (s2 % 3 + 1) % 3
        # s1 runs a->b; s2 runs b->a (consistent) or a->b (same way)
        if inconsistent[e]:
            uf_union(parent, s1, s2)
            uf_union(parent, e1, e2)
        else:
            uf_union(parent, s1, e2)
            uf_union(parent, e1, s2)
    uf_flatten(parent)
    n = 0
    for c in range(n_corners):
        if proper[c // 3] and parent[c] == c:
            n += 1
    vertex = np.empty(n, np.int64)
    face = np.empty(n, np.int64)
    n = 0
    for c in range(n_corners):
        if proper[c // 3] and parent[c] == c:
            vertex[n] = faces[c // 3, c % 3]
            face[n] = c // 3
            n += 1
    return vertex, face


@njit(cache=True)
def flipped_faces(n_faces: int, first_corner: np.ndarray, second_corner: np.ndarray,
                  inconsistent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces whose winding disagrees with the majority of their patch, and faces on
    non-orientable patches (a patch: faces joined across edges used by exactly two faces).

    A double cover: node f is "f as is", f + F is "f flipped"."""
    parent = np.arange(2 * n_faces)
    for e in range(first_corner.shape[0]):
        if first_corner[e] < 0:
            continue
        f1 = first_corner[e] // 3
        f2 = second_corner[e] // 3
        if inconsistent[e]:
            uf_union(parent, f1, f2 + n_faces)
            uf_union(parent, f1 + n_faces, f2)
        else:
            uf_union(parent, f1, f2)
            uf_union(parent, f1 + n_faces, f2 + n_faces)
    uf_flatten(parent)
    size = np.zeros(2 * n_faces, np.int64)
    n_flipped = np.zeros(2 * n_faces, np.int64)
    for f in range(n_faces):
        keep, flip = parent[f], parent[f + n_faces]
        patch = min(keep, flip)
        size[patch] += 1
        if keep != patch and keep != flip:
            n_flipped[patch] += 1
    out_flipped = np.empty(n_faces, np.int64)
    out_bad = np.empty(n_faces, np.int64)
    n1 = 0
    n2 = 0
    for f in range(n_faces):
        keep, flip = parent[f], parent[f + n_faces]
        if keep == flip:
            out_bad[n2] = f
            n2 += 1
            continue
        patch = min(keep, flip)
        flipped = keep != patch
        if n_flipped[patch] * 2 > size[patch]:
            flipped = not flipped
        if flipped:
            out_flipped[n1] = f
            n1 += 1
    return out_flipped[:n1].copy(), out_bad[:n2].copy()


@njit(cache=True, inline="always")
def _sorted3(a, b, c):
    """Three integers in increasing order."""
    if a > b:
        a, b = b, a
    if b > c:
        b, c = c, b
    if a > b:
        a, b = b, a
    return a, b, c


@njit(cache=True)
def duplicate_faces(faces: np.ndarray, proper: np.ndarray, corner_edge: np.ndarray,
                    counts: np.ndarray, first_corner: np.ndarray, second_corner: np.ndarray
                    ) -> np.ndarray:
    """Proper faces on the same three vertices as an earlier proper face (any winding), in
    face order; from the edge structure (:func:`edge_structure`).

    Two such faces share all three edges. Where those are used by exactly two faces, a face
    is a copy when the face across each of its edges is one and the same; faces with an
    edge of their own (used once) are not; faces with an edge used more often are compared
    among themselves by their sorted vertices (a copy of such a face has that edge too).
    """
    n = faces.shape[0]
    is_copy = np.zeros(n, np.bool_)
    crowded = np.empty(n, np.int64)
    n_crowded = 0
    for f in range(n):
        if not proper[f]:
            continue
        single = False
        many = False
        for k in range(3):
            c = counts[corner_edge[3 * f + k]]
            single |= c == 1
            many |= c > 2
        if single:
            continue
        if many:
            crowded[n_crowded] = f
            n_crowded += 1
            continue
        other = -1
        same = True
        for k in range(3):
            e = corner_edge[3 * f + k]
            g = first_corner[e] // 3
            if g == f:
                g = second_corner[e] // 3
            if other >= 0 and g != other:
                same = False
            other = g
        if same and other < f:
            is_copy[f] = True
    size = 1
    while size < 2 * n_crowded:
        size *= 2
    mask = np.uint64(size - 1)
    table = np.full(size, -1, np.int64)
    for t in range(n_crowded):
        f = crowded[t]
        a, b, c = _sorted3(faces[f, 0], faces[f, 1], faces[f, 2])
        slot = _hash3(np.uint64(a), np.uint64(b), np.uint64(c)) & mask
        while True:
            g = table[slot]
            if g < 0:
                table[slot] = f
                break
            x, y, z = _sorted3(faces[g, 0], faces[g, 1], faces[g, 2])
            if x == a and y == b and z == c:
                is_copy[f] = True
                break
            slot = (slot + np.uint64(1)) & mask
    return np.flatnonzero(is_copy)


# --------------------------------------------------------------------------------------------
# bodies


@njit(cache=True, inline="always")
def _grow_box(positions, v, b, lo, hi, lo_at, hi_at):
    """Extend body b's box by vertex v; of equal values the one of the larger vertex wins
    (numpy's minimum.reduceat over vertices in order keeps the last: it decides the sign
    of a zero)."""
    for d in range(3):
        x = positions[v, d]
        if x < lo[b, d] or (x == lo[b, d] and v > lo_at[b, d]):
            lo[b, d] = x
            lo_at[b, d] = v
        if x > hi[b, d] or (x == hi[b, d] and v > hi_at[b, d]):
            hi[b, d] = x
            hi_at[b, d] = v


@njit(cache=True)
def body_vertices(faces: np.ndarray, face_body: np.ndarray, n_bodies: int,
                  positions: np.ndarray, marked: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per body: distinct vertices, how many of them are marked, and the bounding box of
    its vertices (lo, hi). A vertex shared by several bodies counts in each."""
    n_vertices = positions.shape[0]
    owner = np.full(n_vertices, -1, np.int64)
    count = np.zeros(n_bodies, np.int64)
    n_marked = np.zeros(n_bodies, np.int64)
    lo = np.full((n_bodies, 3), np.inf)
    hi = np.full((n_bodies, 3), -np.inf)
    lo_at = np.full((n_bodies, 3), -1, np.int64)
    hi_at = np.full((n_bodies, 3), -1, np.int64)
    extra = np.empty(16, np.int64)  # body * V + vertex of vertices in more than one body
    n_extra = 0
    for f in range(faces.shape[0]):
        b = face_body[f]
        for k in range(3):
            v = faces[f, k]
            o = owner[v]
            if o == b:
                continue
            if o >= 0:  # a vertex of another body too (rare): resolved below
                if n_extra == extra.shape[0]:
                    grown = np.empty(2 * n_extra, np.int64)
                    grown[:n_extra] = extra
                    extra = grown
                extra[n_extra] = b * n_vertices + v
                n_extra += 1
                continue
            owner[v] = b
            count[b] += 1
            if marked[v]:
                n_marked[b] += 1
            _grow_box(positions, v, b, lo, hi, lo_at, hi_at)
    if n_extra:
        keys = np.unique(extra[:n_extra])
        for t in range(keys.shape[0]):
            b = keys[t] // n_vertices
            v = keys[t] % n_vertices
            if owner[v] == b:
                continue
            count[b] += 1
            if marked[v]:
                n_marked[b] += 1
            _grow_box(positions, v, b, lo, hi, lo_at, hi_at)
    return count, n_marked, lo, hi
