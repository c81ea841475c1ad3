"""Triangle-triangle intersection of a mesh with itself, and winding numbers (numba).

What is checked: every pair of non-degenerate triangles whose bounding boxes overlap (found
through a bounding volume hierarchy over Morton-ordered triangles) gets an exact-geometry
test in float64, in a frame centred on one of its vertices:

* no shared vertex: the interval test of Möller (1997) on the line where the two planes
  meet; a coplanar pair is tested in 2D (edge crossings and containment);
* one shared vertex p: they intersect beyond p exactly when the edge opposite p of one
  triangle meets the other triangle;
* a shared edge: they intersect beyond it only when they are coplanar and folded onto each
  other (both opposite vertices on the same side of the edge);
* three shared vertices (a duplicate face) are left to the duplicate-face check.

Touching counts as intersecting: a vertex on another face, or two edges that meet, is a
contact that slicers and booleans cannot resolve either. Signed distances and 2D
orientations whose size is at most ``TOL_REL`` times the pair's size are taken as zero, so
round-off in (nearly) coplanar neighbours does not produce false reports; the price is that
contacts closer than that tolerance are reported as contacts. The predicates are not
exact-arithmetic predicates: a pair closer than about 1e-12 of its size to touching may be
classified either way.

Vertices are indices into one shared vertex array; vertices at identical positions must have
been merged first (shared vertices are recognised by index). Units are the mesh's own.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

__all__ = ["TOL_REL", "intersecting_pairs", "ray_winding_numbers", "start_intersecting_pairs",
           "winding_numbers"]

#: distances at most this fraction of a triangle pair's size count as zero (contact)
TOL_REL = 1e-9
#: triangles per BVH leaf
LEAF_SIZE = 4


# --------------------------------------------------------------------------------------------
# small vector helpers on 3-tuples (no allocation inside the kernels)


@njit(cache=True, inline="always")
def _v(points, k):
    return (points[k, 0], points[k, 1], points[k, 2])


@njit(cache=True, inline="always")
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True, inline="always")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, inline="always")
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True, inline="always")
def _scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@njit(cache=True, inline="always")
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=True, inline="always")
def _norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@njit(cache=True, inline="always")
def _snap(x, tol):
    return 0.0 if abs(x) <= tol else x


@njit(cache=True)
def _unit_normal(a, b, c):
    n = _cross(_sub(b, a), _sub(c, a))
    length = _norm(n)
    if length == 0.0:
        return n, False
    return _scale(n, 1.0 / length), True


@njit(cache=True)
def _drop_axis(n):
    """Index of the largest |component| of n: the axis dropped to project onto a plane."""
    ax, ay, az = abs(n[0]), abs(n[1]), abs(n[2])
    if ax >= ay and ax >= az:
        return 0
    if ay >= az:
        return 1
    return 2


@njit(cache=True, inline="always")
def _p2(a, axis):
    if axis == 0:
        return (a[1], a[2])
    if axis == 1:
        return (a[2], a[0])
    return (a[0], a[1])


# --------------------------------------------------------------------------------------------
# 2D predicates with a distance tolerance


@njit(cache=True)
def _side(a, b, c, tol):
    """Sign of c against the line a->b: +1 left, -1 right, 0 within tol of the line."""
    ex, ey = b[0] - a[0], b[1] - a[1]
    o = ex * (c[1] - a[1]) - ey * (c[0] - a[0])
    # tol * |e| lies between tol * w and tol * w * sqrt(2) (w: the larger of |ex|, |ey|):
    # outside [0.99, 1.5] times tol * w the answer needs no square root (where no square
    # under- or overflows and tol * w is a normal number, so the bounds hold to an ulp)
    w = max(abs(ex), abs(ey))
    m = tol * w
    if 1e-140 < w < 1e140 and (m == 0.0 or m > 1e-290):
        if abs(o) > 1.5 * m:
            return 1 if o > 0 else -1
        if abs(o) < 0.99 * m:
            return 0
    if abs(o) <= tol * math.sqrt(ex * ex + ey * ey):
        return 0
    return 1 if o > 0 else -1


@njit(cache=True)
def _within_box(a, b, c, tol):
    return (min(a[0], b[0]) - tol <= c[0] <= max(a[0], b[0]) + tol
            and min(a[1], b[1]) - tol <= c[1] <= max(a[1], b[1]) + tol)


@njit(cache=True)
def _segments_meet(a, b, c, d, tol):
    """Closed segments ab and cd in 2D meet (crossing, touching or overlapping)."""
    o1 = _side(a, b, c, tol)
    o2 = _side(a, b, d, tol)
    o3 = _side(c, d, a, tol)
    o4 = _side(c, d, b, tol)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    if o1 == 0 and _within_box(a, b, c, tol):
        return True
    if o2 == 0 and _within_box(a, b, d, tol):
        return True
    if o3 == 0 and _within_box(c, d, a, tol):
        return True
    return o4 == 0 and _within_box(c, d, b, tol)


@njit(cache=True)
def _in_triangle(p, a, b, c, tol):
    """p lies in the closed 2D triangle abc (either winding)."""
    s1 = _side(a, b, p, tol)
    s2 = _side(b, c, p, tol)
    s3 = _side(c, a, p, tol)
    neg = s1 < 0 or s2 < 0 or s3 < 0
    pos = s1 > 0 or s2 > 0 or s3 > 0
    return not (neg and pos)


@njit(cache=True)
def _segment_triangle_2d(a, b, t0, t1, t2, tol):
    if _in_triangle(a, t0, t1, t2, tol) or _in_triangle(b, t0, t1, t2, tol):
        return True
    return (_segments_meet(a, b, t0, t1, tol) or _segments_meet(a, b, t1, t2, tol)
            or _segments_meet(a, b, t2, t0, tol))


@njit(cache=True)
def _triangles_2d(p0, p1, p2, q0, q1, q2, tol):
    """Closed coplanar triangles (already projected to 2D) meet."""
    return (_segment_triangle_2d(p0, p1, q0, q1, q2, tol)
            or _segment_triangle_2d(p1, p2, q0, q1, q2, tol)
            or _segment_triangle_2d(p2, p0, q0, q1, q2, tol)
            or _in_triangle(q0, p0, p1, p2, tol))


# --------------------------------------------------------------------------------------------
# 3D pair tests (all points relative to a vertex of the pair)


@njit(cache=True)
def _interval(p0, p1, p2, d0, d1, d2, direction):
    """[lo, hi] of the triangle's crossing with the other plane, projected on direction."""
    lo = np.inf
    hi = -np.inf
    pts = (p0, p1, p2)
    ds = (d0, d1, d2)
    for k in range(3):
        if ds[k] == 0.0:
            t = _dot(direction, pts[k])
            lo = min(lo, t)
            hi = max(hi, t)
        m = (k + 1) % 3
        if ds[k] * ds[m] < 0.0:
            x = _add(pts[k], _scale(_sub(pts[m], pts[k]), ds[k] / (ds[k] - ds[m])))
            t = _dot(direction, x)
            lo = min(lo, t)
            hi = max(hi, t)
    return lo, hi


@njit(cache=True)
def _triangles_meet(p0, p1, p2, q0, q1, q2, tol):
    """Closed triangles with no vertex in common meet (Möller's interval test)."""
    n2, ok2 = _unit_normal(q0, q1, q2)
    n1, ok1 = _unit_normal(p0, p1, p2)
    if not (ok1 and ok2):
        return False
    a0 = _snap(_dot(n2, _sub(p0, q0)), tol)
    a1 = _snap(_dot(n2, _sub(p1, q0)), tol)
    a2 = _snap(_dot(n2, _sub(p2, q0)), tol)
    if (a0 > 0 and a1 > 0 and a2 > 0) or (a0 < 0 and a1 < 0 and a2 < 0):
        return False
    b0 = _snap(_dot(n1, _sub(q0, p0)), tol)
    b1 = _snap(_dot(n1, _sub(q1, p0)), tol)
    b2 = _snap(_dot(n1, _sub(q2, p0)), tol)
    if (b0 > 0 and b1 > 0 and b2 > 0) or (b0 < 0 and b1 < 0 and b2 < 0):
        return False
    direction = _cross(n1, n2)
    length = _norm(direction)
    coplanar = (a0 == 0.0 and a1 == 0.0 and a2 == 0.0) or (b0 == 0.0 and b1 == 0.0 and b2 == 0.0)
    if coplanar or length < 1e-300:
        axis = _drop_axis(n2)
        return _triangles_2d(_p2(p0, axis), _p2(p1, axis), _p2(p2, axis),
                             _p2(q0, axis), _p2(q1, axis), _p2(q2, axis), tol)
    if length < 1e-6:
        # nearly parallel planes: the line of intersection is ill-conditioned, so ask
        # instead whether any edge of one triangle meets the other (they meet iff one does)
        return (_segment_meets_triangle(p0, p1, q0, q1, q2, tol)
                or _segment_meets_triangle(p1, p2, q0, q1, q2, tol)
                or _segment_meets_triangle(p2, p0, q0, q1, q2, tol)
                or _segment_meets_triangle(q0, q1, p0, p1, p2, tol)
                or _segment_meets_triangle(q1, q2, p0, p1, p2, tol)
                or _segment_meets_triangle(q2, q0, p0, p1, p2, tol))
    direction = _scale(direction, 1.0 / length)
    lo1, hi1 = _interval(p0, p1, p2, a0, a1, a2, direction)
    lo2, hi2 = _interval(q0, q1, q2, b0, b1, b2, direction)
    return max(lo1, lo2) <= min(hi1, hi2) + tol


@njit(cache=True)
def _segment_meets_triangle(a, b, t0, t1, t2, tol):
    """Closed segment ab meets the closed triangle t0 t1 t2 (3D)."""
    n, ok = _unit_normal(t0, t1, t2)
    if not ok:
        return False
    da = _snap(_dot(n, _sub(a, t0)), tol)
    db = _snap(_dot(n, _sub(b, t0)), tol)
    if da * db > 0.0:
        return False
    axis = _drop_axis(n)
    u0, u1, u2 = _p2(t0, axis), _p2(t1, axis), _p2(t2, axis)
    if da == 0.0 and db == 0.0:
        return _segment_triangle_2d(_p2(a, axis), _p2(b, axis), u0, u1, u2, tol)
    if da == 0.0:
        x = a
    elif db == 0.0:
        x = b
    else:
        x = _add(a, _scale(_sub(b, a), da / (da - db)))
    return _in_triangle(_p2(x, axis), u0, u1, u2, tol)


@njit(cache=True)
def _beside(a, b, t0, t1, t2, tol):
    """Segment ab lies strictly on one side of the plane of t0 t1 t2, farther than tol
    (a quick test without square roots)."""
    n = _cross(_sub(t1, t0), _sub(t2, t0))
    da = _dot(n, _sub(a, t0))
    db = _dot(n, _sub(b, t0))
    if da * db <= 0.0:
        return False
    limit = tol * tol * _dot(n, n)
    return da * da > limit and db * db > limit


@njit(cache=True)
def _folded(a, b, c1, c2, tol):
    """Triangles (a, b, c1) and (a, b, c2) sharing edge ab lie folded onto each other."""
    n, ok = _unit_normal(a, b, c1)
    if not ok or abs(_dot(n, _sub(c2, a))) > tol:
        return False
    e = _sub(b, a)
    return _dot(_cross(e, _sub(c1, a)), _cross(e, _sub(c2, a))) > 0.0


@njit(cache=True)
def _pair_meets(vertices, faces, i, j, tol_rel):
    """Faces i and j of the mesh intersect or touch (beyond what they share)."""
    return _pair_core((faces[i, 0], faces[i, 1], faces[i, 2]),
                      (faces[j, 0], faces[j, 1], faces[j, 2]),
                      _v(vertices, faces[i, 0]), _v(vertices, faces[i, 1]),
                      _v(vertices, faces[i, 2]), _v(vertices, faces[j, 0]),
                      _v(vertices, faces[j, 1]), _v(vertices, faces[j, 2]), tol_rel)


@njit(cache=True)
def _pair_core(fi, fj, pi0, pi1, pi2, pj0, pj1, pj2, tol_rel):
    """:func:`_pair_meets` on the faces' vertex indices fi, fj and positions pi*, pj*."""
    fi0, fi1, fi2 = fi
    shared = 0
    si = -1  # slot in i of a shared vertex (the first found)
    sj = -1
    ui = 0  # bit mask of shared slots in i
    for k in range(3):
        for m in range(3):
            if fi[k] == fj[m]:
                shared += 1
                ui |= 1 << k
                if si < 0:
                    si = k
                    sj = m
    if shared == 3:
        return False
    origin = pj0
    p = (_sub(pi0, origin), _sub(pi1, origin), _sub(pi2, origin))
    q = (_sub(pj0, origin), _sub(pj1, origin), _sub(pj2, origin))
    size = 0.0
    for k in range(3):
        for m in range(3):
            size = max(size, abs(p[k][m] - q[0][m]), abs(q[k][m] - q[0][m]))
    tol = tol_rel * size
    if shared == 0:
        return _triangles_meet(p[0], p[1], p[2], q[0], q[1], q[2], tol)
    if shared == 1:
        # rotate so the shared vertex comes first in both
        pa, pb = p[(si + 1) % 3], p[(si + 2) % 3]
        qa, qb = q[(sj + 1) % 3], q[(sj + 2) % 3]
        if _beside(pa, pb, q[sj], qa, qb, tol) and _beside(qa, qb, p[si], pa, pb, tol):
            return False  # each opposite edge lies strictly on one side of the other plane
        return (_segment_meets_triangle(pa, pb, q[sj], qa, qb, tol)
                or _segment_meets_triangle(qa, qb, p[si], pa, pb, tol))
    # shared == 2: the edge; c1 is the slot of i not shared, c2 the vertex of j not in i
    k1 = 0 if not (ui & 1) else (1 if not (ui & 2) else 2)
    c2 = q[0]
    for m in range(3):
        if fj[m] != fi0 and fj[m] != fi1 and fj[m] != fi2:
            c2 = q[m]
    ea, eb = p[(k1 + 1) % 3], p[(k1 + 2) % 3]
    return _folded(ea, eb, p[k1], c2, tol)


# --------------------------------------------------------------------------------------------
# broad phase: a BVH over Morton-ordered triangles (implicit complete binary tree)


@njit(cache=True, inline="always")
def _spread_bits(x):
    """Spread the low 21 bits of a uint64 so two zero bits follow each bit."""
    x &= np.uint64(0x1FFFFF)
    x = (x | (x << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x1249249249249249)
    return x


@njit(cache=True)
def _radix_argsort(keys):
    """Stable argsort of uint64 keys (LSD radix, 11 bits a pass; passes where every key
    has the same digit are skipped)."""
    n = keys.shape[0]
    order = np.arange(n)
    scratch = np.empty(n, np.int64)
    digits = np.empty(n, np.int64)
    counts = np.empty(2049, np.int64)
    for shift in range(0, 64, 11):
        counts[:] = 0
        for k in range(n):
            d = np.int64((keys[order[k]] >> np.uint64(shift)) & np.uint64(0x7FF))
            digits[k] = d
            counts[d + 1] += 1
        if counts.max() == n:
            continue  # one digit for all: the order stands
        for d in range(2048):
            counts[d + 1] += counts[d]
        for k in range(n):
            d = digits[k]
            scratch[counts[d]] = order[k]
            counts[d] += 1
        order, scratch = scratch, order
    return order


@njit(cache=True)
def _face_boxes(vertices, faces, tol_rel):
    """Boxes of the faces, padded by a few ulps of the largest coordinate and grown by the
    contact tolerance (tol_rel times the largest box extent)."""
    n = faces.shape[0]
    size = 0.0
    for f in range(n):
        for k in range(3):
            for d in range(3):
                size = max(size, abs(vertices[faces[f, k], d]))
    pad = 4 * np.finfo(np.float64).eps * max(size, 1e-300)
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    extent = -np.inf
    for f in range(n):
        for d in range(3):
            a = vertices[faces[f, 0], d]
            b = vertices[faces[f, 1], d]
            c = vertices[faces[f, 2], d]
            lo[f, d] = min(a, b, c) - pad
            hi[f, d] = max(a, b, c) + pad
            extent = max(extent, hi[f, d] - lo[f, d])
    reach = tol_rel * extent
    for f in range(n):
        for d in range(3):
            lo[f, d] -= reach
            hi[f, d] += reach
    return lo, hi


@njit(cache=True)
def _morton_order(lo, hi, index):
    """The faces ``index`` sorted along a 3D Morton (Z-order) curve of their box centres."""
    m = index.shape[0]
    centres = np.empty((m, 3))
    c_lo = np.full(3, np.inf)
    c_hi = np.full(3, -np.inf)
    for k in range(m):
        for d in range(3):
            c = 0.5 * (lo[index[k], d] + hi[index[k], d])
            centres[k, d] = c
            c_lo[d] = min(c_lo[d], c)
            c_hi[d] = max(c_hi[d], c)
    span = np.empty(3)
    for d in range(3):
        span[d] = max(c_hi[d] - c_lo[d], np.finfo(np.float64).tiny)
    codes = np.empty(m, np.uint64)
    top = 2.0**21 - 1
    for k in range(m):
        code = np.uint64(0)
        for d in range(3):
            q = min(max((centres[k, d] - c_lo[d]) / span[d] * top, 0.0), top)
            code |= _spread_bits(np.uint64(q)) << np.uint64(2 - d)
        codes[k] = code
    return index[_radix_argsort(codes)]


@njit(cache=True)
def _build_tree(lo, hi, order, leaf_size):
    """Node boxes of an implicit complete binary tree over the ordered triangles.

    Node k has children 2k+1 and 2k+2; the P leaves are nodes P-1 ... 2P-2, leaf m holding
    ordered triangles [m*leaf_size, (m+1)*leaf_size). Returns (node_lo, node_hi, P). Empty
    subtrees have empty boxes (lo = +inf, hi = -inf).
    """
    n = order.shape[0]
    n_leaves = max(1, (n + leaf_size - 1) // leaf_size)
    p = 1
    while p < n_leaves:
        p *= 2
    node_lo = np.full((2 * p - 1, 3), np.inf)
    node_hi = np.full((2 * p - 1, 3), -np.inf)
    for s in range(n):
        leaf = p - 1 + s // leaf_size
        f = order[s]
        for d in range(3):
            node_lo[leaf, d] = min(node_lo[leaf, d], lo[f, d])
            node_hi[leaf, d] = max(node_hi[leaf, d], hi[f, d])
    for k in range(p - 2, -1, -1):
        for d in range(3):
            node_lo[k, d] = min(node_lo[2 * k + 1, d], node_lo[2 * k + 2, d])
            node_hi[k, d] = max(node_hi[2 * k + 1, d], node_hi[2 * k + 2, d])
    return node_lo, node_hi, p


@njit(cache=True)
def _leaf_pairs(tri, ids, order, lo, hi, nodes, a, b, first_leaf, leaf_size, tol_rel, pairs,
                hits, total):
    """Test the faces of leaf node a against those of leaf node b (a <= b); tri, ids, lo,
    hi: the faces' data in tree order; nodes: the node boxes (lo, hi side by side)."""
    n = order.shape[0]
    sa = (a - first_leaf) * leaf_size
    sb = (b - first_leaf) * leaf_size
    for s in range(sa, min(sa + leaf_size, n)):
        i = order[s]
        l0, l1, l2, h0, h1, h2 = lo[s, 0], lo[s, 1], lo[s, 2], hi[s, 0], hi[s, 1], hi[s, 2]
        if a != b and not ((l0 <= nodes[b, 3]) & (nodes[b, 0] <= h0) & (l1 <= nodes[b, 4])
                           & (nodes[b, 1] <= h1) & (l2 <= nodes[b, 5]) & (nodes[b, 2] <= h2)):
            continue  # misses the other leaf's box, so each of its faces
        for t in range(max(sb, s + 1) if a == b else sb, min(sb + leaf_size, n)):
            # & rather than `and`: no branches, the six comparisons are cheap
            if not ((l0 <= hi[t, 0]) & (lo[t, 0] <= h0) & (l1 <= hi[t, 1])
                    & (lo[t, 1] <= h1) & (l2 <= hi[t, 2]) & (lo[t, 2] <= h2)):
                continue
            j = order[t]
            fi = (ids[s, 0], ids[s, 1], ids[s, 2])
            fj = (ids[t, 0], ids[t, 1], ids[t, 2])
            p = ((tri[s, 0], tri[s, 1], tri[s, 2]), (tri[s, 3], tri[s, 4], tri[s, 5]),
                 (tri[s, 6], tri[s, 7], tri[s, 8]))
            q = ((tri[t, 0], tri[t, 1], tri[t, 2]), (tri[t, 3], tri[t, 4], tri[t, 5]),
                 (tri[t, 6], tri[t, 7], tri[t, 8]))
            if _pair_core(fi, fj, p[0], p[1], p[2], q[0], q[1], q[2], tol_rel):
                if total < pairs.shape[0]:
                    pairs[total, 0] = min(i, j)
                    pairs[total, 1] = max(i, j)
                total += 1
                hits[i] += 1
                hits[j] += 1
    return total


@njit(cache=True, inline="always")
def _nodes_overlap(nodes, a, b):
    # & rather than `and`: no branches, the six comparisons are cheap
    return ((nodes[a, 0] <= nodes[b, 3]) & (nodes[b, 0] <= nodes[a, 3])
            & (nodes[a, 1] <= nodes[b, 4]) & (nodes[b, 1] <= nodes[a, 4])
            & (nodes[a, 2] <= nodes[b, 5]) & (nodes[b, 2] <= nodes[a, 5]))


@njit(cache=True)
def _self_pairs(tri, ids, order, lo, hi, node_lo, node_hi, n_leaf_nodes, leaf_size, tol_rel,
                cap, n_faces):
    """All intersecting pairs among the ordered faces. Returns (pairs[:stored], total, hits).

    In tree order (face order[s] at s): tri[s] its nine coordinates, ids[s] its vertices,
    lo[s], hi[s] its box; read in sequence by the leaf tests.

    A simultaneous traversal of the tree against itself, depth first: each pair of
    overlapping nodes is visited once (all leaves are at the same depth, so both sides
    descend together). Children pairs whose boxes miss are not stacked, and leaf pairs are
    tested at once, in the order the stack would give them.
    pairs: (stored, 2) face indices (smaller first); total: pairs found (may exceed cap);
    hits: (n_faces,) number of intersecting partners of each face.
    """
    pairs = np.empty((cap, 2), np.int64)
    hits = np.zeros(n_faces, np.int64)
    total = 0
    first_leaf = n_leaf_nodes - 1
    nodes = np.empty((node_lo.shape[0], 6))  # lo and hi of a node side by side
    nodes[:, :3] = node_lo
    nodes[:, 3:] = node_hi
    stack = np.empty((4096, 2), np.int64)
    kids = np.empty((4, 2), np.int64)
    top = 0
    stack[0, 0] = 0
    stack[0, 1] = 0
    if first_leaf == 0:
        return (pairs[:0], 0, hits) if order.shape[0] < 2 else _single_leaf(
            tri, ids, order, lo, hi, nodes, leaf_size, tol_rel, pairs, hits)
    while top >= 0:
        a = stack[top, 0]
        b = stack[top, 1]
        top -= 1
        if a == b and not (nodes[a, 0] <= nodes[a, 3]):
            continue  # an empty subtree
        a1, a2, b1, b2 = 2 * a + 1, 2 * a + 2, 2 * b + 1, 2 * b + 2
        n_kids = 0
        if a == b:
            kids[0, 0], kids[0, 1] = a1, a1
            n_kids = 1
            if _nodes_overlap(nodes, a1, a2):
                kids[n_kids, 0], kids[n_kids, 1] = a1, a2
                n_kids += 1
            kids[n_kids, 0], kids[n_kids, 1] = a2, a2
            n_kids += 1
        else:
            if _nodes_overlap(nodes, a1, b1):
                kids[n_kids, 0], kids[n_kids, 1] = a1, b1
                n_kids += 1
            if _nodes_overlap(nodes, a1, b2):
                kids[n_kids, 0], kids[n_kids, 1] = a1, b2
                n_kids += 1
            if _nodes_overlap(nodes, a2, b1):
                kids[n_kids, 0], kids[n_kids, 1] = a2, b1
                n_kids += 1
            if _nodes_overlap(nodes, a2, b2):
                kids[n_kids, 0], kids[n_kids, 1] = a2, b2
                n_kids += 1
        if a1 >= first_leaf:  # leaves: the stack would pop them next, last first
            for k in range(n_kids - 1, -1, -1):
                total = _leaf_pairs(tri, ids, order, lo, hi, nodes, kids[k, 0], kids[k, 1],
                                    first_leaf, leaf_size, tol_rel, pairs, hits, total)
        else:
            for k in range(n_kids):
                top += 1
                stack[top, 0] = kids[k, 0]
                stack[top, 1] = kids[k, 1]
    return pairs[:min(total, cap)], total, hits


@njit(cache=True)
def _single_leaf(tri, ids, order, lo, hi, nodes, leaf_size, tol_rel, pairs, hits):
    """The tree of one leaf (at most leaf_size faces)."""
    total = _leaf_pairs(tri, ids, order, lo, hi, nodes, 0, 0, 0, leaf_size, tol_rel, pairs,
                        hits, 0)
    return pairs[:min(total, pairs.shape[0])], total, hits


def _prepared(vertices: np.ndarray, faces: np.ndarray, active: np.ndarray | None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Contiguous float64 vertices, int64 faces and the indices of the faces to test."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    index = np.arange(len(faces)) if active is None else np.flatnonzero(active)
    return vertices, faces, index


def _no_pairs(n_faces: int) -> tuple[np.ndarray, int, np.ndarray]:
    """The result of a test with fewer than two faces to test."""
    return np.zeros((0, 2), np.int64), 0, np.zeros(n_faces, np.int64)


def intersecting_pairs(
    vertices: np.ndarray,
    faces: np.ndarray,
    active: np.ndarray | None = None,
    *,
    tol_rel: float = TOL_REL,
    cap: int = 1_000_000,
) -> tuple[np.ndarray, int, np.ndarray]:
    """Pairs of faces that intersect or touch beyond their shared vertices or edge.

    Args:
        vertices: (V, 3) float positions, any units; identical positions already merged.
        faces: (F, 3) int vertex indices.
        active: optional (F,) bool; only active faces are tested (leave out degenerate faces:
            a zero-area face has no plane).
        tol_rel: distances below tol_rel times a pair's size count as contact.
        cap: at most this many pairs are returned (the count and hits stay exact; the
            report's per-body counts and overlapping bodies come from the pairs returned).

    Returns:
        ``(pairs, total, hits)``: (K, 2) int64 face indices, smaller first, K = min(total,
        cap); the number of intersecting pairs; (F,) int64 number of partners of each face.
    """
    vertices, faces, index = _prepared(vertices, faces, active)
    if len(index) < 2:
        return _no_pairs(len(faces))
    pairs, total, hits = _intersections(vertices, faces, index, float(tol_rel), LEAF_SIZE,
                                        int(cap), np.zeros(1, np.int64))
    return pairs, int(total), hits


def start_intersecting_pairs(
    vertices: np.ndarray,
    faces: np.ndarray,
    active: np.ndarray | None = None,
    *,
    tol_rel: float = TOL_REL,
    cap: int = 1_000_000,
) -> Callable[[], tuple[np.ndarray, int, np.ndarray]]:
    """:func:`intersecting_pairs` in a worker thread, so that the caller can do other work
    meanwhile (on another core: the test holds no GIL while it runs).

    Returns once the test runs without the GIL, so that the caller may then call code that
    holds the GIL for long (manifold3d does) without stalling the test. Call the function
    returned for ``(pairs, total, hits)``; it waits for the test and re-raises its errors.
    """
    vertices, faces, index = _prepared(vertices, faces, active)
    if len(index) < 2:
        empty = _no_pairs(len(faces))
        return lambda: empty
    started = np.zeros(1, np.int64)  # set by the kernel once it runs
    out: list[Any] = []

    def work() -> None:
        try:
            out.append(_intersections(vertices, faces, index, float(tol_rel), LEAF_SIZE,
                                      int(cap), started))
        except BaseException as exc:  # handed to the caller
            out.append(exc)

    thread = threading.Thread(target=work, name="jampacked-intersections", daemon=True)
    thread.start()
    while not started[0] and thread.is_alive():
        time.sleep(0.0002)  # sleeping lets the worker take the GIL to reach the kernel

    def result() -> tuple[np.ndarray, int, np.ndarray]:
        thread.join()
        if isinstance(out[0], BaseException):
            raise out[0]
        pairs, total, hits = out[0]
        return pairs, int(total), hits

    return result


@njit(cache=True, nogil=True)
def _intersections(vertices, faces, index, tol_rel, leaf_size, cap, started):
    """:func:`intersecting_pairs` of the faces ``index``, in one call that does not hold
    the GIL (so other Python threads run meanwhile). Sets started[0] on entry."""
    started[0] = 1
    # contact tolerance: the boxes grow by the largest tolerance a pair can have
    lo, hi = _face_boxes(vertices, faces, tol_rel)
    order = _morton_order(lo, hi, index)
    node_lo, node_hi, p = _build_tree(lo, hi, order, leaf_size)
    # the faces' data in tree order: the leaf tests read them in sequence
    n = order.shape[0]
    ids = np.empty((n, 3), np.int64)
    tri = np.empty((n, 9))
    lo_s = np.empty((n, 3))
    hi_s = np.empty((n, 3))
    for s in range(n):
        f = order[s]
        for k in range(3):
            ids[s, k] = faces[f, k]
            lo_s[s, k] = lo[f, k]
            hi_s[s, k] = hi[f, k]
            for d in range(3):
                tri[s, 3 * k + d] = vertices[faces[f, k], d]
    pairs, total, hits = _self_pairs(tri, ids, order, lo_s, hi_s, node_lo, node_hi, p,
                                     leaf_size, tol_rel, cap, faces.shape[0])
    return pairs.copy(), total, hits


# --------------------------------------------------------------------------------------------
# winding numbers (nesting of bodies)


@njit(cache=True)
def _winding(points, vertices, faces):
    out = np.zeros(points.shape[0])
    for k in range(points.shape[0]):
        x = _v(points, k)
        total = 0.0
        for f in range(faces.shape[0]):
            a = _sub(_v(vertices, faces[f, 0]), x)
            b = _sub(_v(vertices, faces[f, 1]), x)
            c = _sub(_v(vertices, faces[f, 2]), x)
            la, lb, lc = _norm(a), _norm(b), _norm(c)
            num = _dot(a, _cross(b, c))
            den = la * lb * lc + _dot(a, b) * lc + _dot(a, c) * lb + _dot(b, c) * la
            total += 2.0 * math.atan2(num, den)
        out[k] = total / (4.0 * math.pi)
    return out


def winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Generalised winding number of each point with respect to a triangle surface.

    Args:
        points: (P, 3) query positions, same units and frame as vertices.
        vertices: (V, 3); faces: (F, 3) vertex indices, counter-clockwise seen from outside.

    Returns:
        (P,) float64: about +1 inside a closed outward-wound surface, -1 inside an inside-out
        one, 0 outside (solid angle sum / 4π; exact integers for closed surfaces, up to
        round-off, when the point is not on the surface).
    """
    return _winding(np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3),
                    np.ascontiguousarray(vertices, dtype=np.float64),
                    np.ascontiguousarray(faces, dtype=np.int64))


@njit(cache=True)
def _ray_crossings(points, order, vertices, faces, rel):
    """Signed crossings of the ray from each point towards +z with the triangles.

    ``order`` sorts the points by x, so each face visits only the points whose x lies in its
    box. A crossing counts +1 where the face runs counter-clockwise seen from +z (the ray
    leaves an outward surface there), -1 otherwise. ``ok[k]`` is False where a decision was
    within ``rel`` of the face's size of going the other way: the ray grazes an edge or a
    vertex, or the point lies (nearly) on the face.
    """
    n = points.shape[0]
    w = np.zeros(n, np.int64)
    ok = np.ones(n, np.bool_)
    xs = np.empty(n)
    for k in range(n):
        xs[k] = points[order[k], 0]
    for f in range(faces.shape[0]):
        a = _v(vertices, faces[f, 0])
        b = _v(vertices, faces[f, 1])
        c = _v(vertices, faces[f, 2])
        x0 = min(a[0], b[0], c[0])
        x1 = max(a[0], b[0], c[0])
        y0 = min(a[1], b[1], c[1])
        y1 = max(a[1], b[1], c[1])
        z1 = max(a[2], b[2], c[2])
        ext2 = (x1 - x0) ** 2 + (y1 - y0) ** 2
        # the 2D cross products err by a few ulps of ext2; the heights by ulps of |z|
        tol_o = rel * ext2
        start = np.searchsorted(xs, x0, side="left")
        stop = np.searchsorted(xs, x1, side="right")
        for s in range(start, stop):
            k = order[s]
            px, py, pz = points[k, 0], points[k, 1], points[k, 2]
            if py < y0 or py > y1:
                continue  # the closed box misses the ray: exactly no crossing
            ra = (a[0] - px, a[1] - py, a[2] - pz)
            rb = (b[0] - px, b[1] - py, b[2] - pz)
            rc = (c[0] - px, c[1] - py, c[2] - pz)
            tol_z = rel * max(abs(ra[2]), abs(rb[2]), abs(rc[2]), math.sqrt(ext2))
            if z1 - pz < -tol_z:
                continue  # wholly below the point
            o1 = ra[0] * rb[1] - ra[1] * rb[0]  # side of the ray against edge ab
            o2 = rb[0] * rc[1] - rb[1] * rc[0]
            o3 = rc[0] * ra[1] - rc[1] * ra[0]
            pos = o1 > tol_o or o2 > tol_o or o3 > tol_o
            neg = o1 < -tol_o or o2 < -tol_o or o3 < -tol_o
            if pos and neg:
                continue  # clearly outside the projected triangle
            if abs(o1) <= tol_o or abs(o2) <= tol_o or abs(o3) <= tol_o:
                ok[k] = False  # through (or too near) an edge or a vertex
                continue
            total = o1 + o2 + o3
            z = (o2 * ra[2] + o3 * rb[2] + o1 * rc[2]) / total  # height of the hit over p
            if abs(z) <= tol_z:
                ok[k] = False  # the point is on the face
            elif z > 0.0:
                w[k] += 1 if total > 0.0 else -1
    return w, ok


def ray_winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                        rel: float = 1e-10) -> tuple[np.ndarray, np.ndarray]:
    """Winding numbers of points with respect to a closed, consistently wound surface, by
    counting signed crossings of a ray (much cheaper than :func:`winding_numbers`).

    The count equals the winding number only for a closed surface whose every edge is
    used once in each direction (it may self-intersect); on other surfaces it depends on the
    ray. Where the ray passes within ``rel`` of a face's size of an edge or a vertex, or the
    point is that close to a face, the count is not trusted.

    Args:
        points: (P, 3) query positions; vertices: (V, 3); faces: (F, 3) vertex indices,
            counter-clockwise seen from outside.
        rel: relative margin of every decision (far above float64 round-off).

    Returns:
        ``(w, ok)``: (P,) int64 winding numbers (+1 inside an outward surface) and (P,) bool,
        False where the ray was ambiguous (use :func:`winding_numbers` for those points).
    """
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(points[:, 0], kind="stable")
    return _ray_crossings(points, order, np.ascontiguousarray(vertices, dtype=np.float64),
                          np.ascontiguousarray(faces, dtype=np.int64), float(rel))
