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

import numpy as np
from numba import njit

__all__ = ["TOL_REL", "intersecting_pairs", "winding_numbers"]

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
    fi0, fi1, fi2 = faces[i, 0], faces[i, 1], faces[i, 2]
    fj = (faces[j, 0], faces[j, 1], faces[j, 2])
    fi = (fi0, fi1, fi2)
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
    origin = _v(vertices, fj[0])
    p = (_sub(_v(vertices, fi[0]), origin), _sub(_v(vertices, fi[1]), origin),
         _sub(_v(vertices, fi[2]), origin))
    q = (_sub(_v(vertices, fj[0]), origin), _sub(_v(vertices, fj[1]), origin),
         _sub(_v(vertices, fj[2]), origin))
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


def _spread_bits(x: np.ndarray) -> np.ndarray:
    """Spread the low 21 bits of each uint64 so two zero bits follow each bit."""
    x = x.astype(np.uint64) & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF),
                        (8, 0x100F00F00F00F00F), (4, 0x10C30C30C30C30C3),
                        (2, 0x1249249249249249)):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def _morton_order(centres: np.ndarray) -> np.ndarray:
    """Permutation sorting (N, 3) points along a 3D Morton (Z-order) curve."""
    lo = centres.min(axis=0)
    span = np.maximum(centres.max(axis=0) - lo, np.finfo(float).tiny)
    q = np.clip(((centres - lo) / span * (2**21 - 1)), 0, 2**21 - 1).astype(np.uint64)
    code = (_spread_bits(q[:, 0]) << np.uint64(2)) | (_spread_bits(q[:, 1]) << np.uint64(1)) \
        | _spread_bits(q[:, 2])
    return np.argsort(code, kind="stable")


def _build_tree(lo: np.ndarray, hi: np.ndarray, order: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, int]:
    """Node boxes of an implicit complete binary tree over the ordered triangles.

    Node k has children 2k+1 and 2k+2; the P leaves are nodes P-1 ... 2P-2, leaf m holding
    ordered triangles [m*LEAF_SIZE, (m+1)*LEAF_SIZE). Returns (node_lo, node_hi, P). Empty
    subtrees have empty boxes (lo = +inf, hi = -inf).
    """
    n = len(order)
    n_leaves = max(1, -(-n // LEAF_SIZE))
    p = 1 << max(0, (n_leaves - 1).bit_length())
    node_lo = np.full((2 * p - 1, 3), np.inf)
    node_hi = np.full((2 * p - 1, 3), -np.inf)
    starts = np.arange(0, n, LEAF_SIZE)
    node_lo[p - 1:p - 1 + len(starts)] = np.minimum.reduceat(lo[order], starts, axis=0)
    node_hi[p - 1:p - 1 + len(starts)] = np.maximum.reduceat(hi[order], starts, axis=0)
    first = p - 1
    while first > 0:
        parents = np.arange((first - 1) // 2, first)
        node_lo[parents] = np.minimum(node_lo[2 * parents + 1], node_lo[2 * parents + 2])
        node_hi[parents] = np.maximum(node_hi[2 * parents + 1], node_hi[2 * parents + 2])
        first = (first - 1) // 2
    return node_lo, node_hi, p


@njit(cache=True)
def _boxes_overlap(alo, ahi, k, blo, bhi, m):
    for d in range(3):
        if alo[k, d] > bhi[m, d] or blo[m, d] > ahi[k, d]:
            return False
    return True


@njit(cache=True)
def _leaf_pairs(vertices, faces, order, lo, hi, a, b, first_leaf, leaf_size, tol_rel, pairs,
                hits, total):
    """Test the faces of leaf node a against those of leaf node b (a <= b)."""
    n = order.shape[0]
    sa = (a - first_leaf) * leaf_size
    sb = (b - first_leaf) * leaf_size
    for s in range(sa, min(sa + leaf_size, n)):
        i = order[s]
        for t in range(max(sb, s + 1) if a == b else sb, min(sb + leaf_size, n)):
            j = order[t]
            if not _boxes_overlap(lo, hi, i, lo, hi, j):
                continue
            if _pair_meets(vertices, faces, i, j, tol_rel):
                if total < pairs.shape[0]:
                    pairs[total, 0] = min(i, j)
                    pairs[total, 1] = max(i, j)
                total += 1
                hits[i] += 1
                hits[j] += 1
    return total


@njit(cache=True)
def _self_pairs(vertices, faces, order, lo, hi, node_lo, node_hi, n_leaf_nodes, leaf_size,
                tol_rel, cap):
    """All intersecting pairs among the ordered faces. Returns (pairs[:stored], total, hits).

    A simultaneous traversal of the tree against itself: each pair of overlapping nodes is
    visited once (all leaves are at the same depth, so both sides descend together).
    pairs: (stored, 2) face indices (smaller first); total: pairs found (may exceed cap);
    hits: (n_faces,) number of intersecting partners of each face.
    """
    pairs = np.empty((cap, 2), np.int64)
    hits = np.zeros(faces.shape[0], np.int64)
    total = 0
    first_leaf = n_leaf_nodes - 1
    stack = np.empty((4096, 2), np.int64)
    top = 0
    stack[0, 0] = 0
    stack[0, 1] = 0
    while top >= 0:
        a = stack[top, 0]
        b = stack[top, 1]
        top -= 1
        if a != b and not _boxes_overlap(node_lo, node_hi, a, node_lo, node_hi, b):
            continue
        if a >= first_leaf:
            total = _leaf_pairs(vertices, faces, order, lo, hi, a, b, first_leaf, leaf_size,
                                tol_rel, pairs, hits, total)
            continue
        if not (node_lo[a, 0] <= node_hi[a, 0]) or not (node_lo[b, 0] <= node_hi[b, 0]):
            continue  # an empty subtree
        a1, a2, b1, b2 = 2 * a + 1, 2 * a + 2, 2 * b + 1, 2 * b + 2
        if a == b:
            top += 1
            stack[top, 0], stack[top, 1] = a1, a1
            top += 1
            stack[top, 0], stack[top, 1] = a1, a2
            top += 1
            stack[top, 0], stack[top, 1] = a2, a2
        else:
            top += 1
            stack[top, 0], stack[top, 1] = a1, b1
            top += 1
            stack[top, 0], stack[top, 1] = a1, b2
            top += 1
            stack[top, 0], stack[top, 1] = a2, b1
            top += 1
            stack[top, 0], stack[top, 1] = a2, b2
    return pairs[:min(total, cap)], total, hits


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
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    index = np.arange(len(faces)) if active is None else np.flatnonzero(active)
    if len(index) < 2:
        return np.zeros((0, 2), np.int64), 0, np.zeros(len(faces), np.int64)
    tri = vertices[faces]
    size = np.abs(tri).max() if tri.size else 0.0
    pad = 4 * np.finfo(float).eps * max(size, 1e-300)
    lo = tri.min(axis=1) - pad
    hi = tri.max(axis=1) + pad
    # contact tolerance: grow the boxes by the largest tolerance a pair can have
    reach = tol_rel * float((hi - lo).max())
    lo -= reach
    hi += reach
    order = index[_morton_order(0.5 * (lo[index] + hi[index]))]
    node_lo, node_hi, p = _build_tree(lo, hi, order)
    pairs, total, hits = _self_pairs(vertices, faces, order, lo, hi, node_lo, node_hi, p,
                                     LEAF_SIZE, float(tol_rel), int(cap))
    return pairs.copy(), int(total), hits


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
