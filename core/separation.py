"""Pairs a plane proves apart: the broad phase that spares certification their booleans.

Two placed objects whose vertices' convex hulls lie more than a margin apart cannot
intersect, so their exact boolean (manifold3d) would measure a volume of 0. GJK
(Gilbert-Johnson-Keerthi) on the hulls proposes a direction v; the pair is proven apart
when the support of the hulls' difference in -v, w, has v.w > margin |v|: every point of
one hull then lies at least that far beyond the other along v. The proof rests on exact
supports (a maximum over the hull's vertices), not on GJK converging; where GJK does not
find such a v (hulls that overlap or nearly touch, a degenerate simplex) the pair goes to
the boolean as before. Frames: hull points in each type's local frame, matrices local ->
container frame; container units.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from scipy.spatial import ConvexHull, QhullError

from .kernels import _rotate, _unrotate

#: GJK iterations before a pair is left to the boolean
MAX_ITERATIONS = 48


def hull_points(vertices: np.ndarray) -> np.ndarray:
    """The vertices (V, 3) of a solid's convex hull, float64, local frame; all of them
    where the hull is degenerate (flat or fewer than four points)."""
    v = np.asarray(vertices, np.float64)
    return np.ascontiguousarray(v[hull_rows(v)])


def hull_rows(vertices: np.ndarray) -> np.ndarray:
    """Which of the vertices (V, 3) make their convex hull (indices); all of them where
    the hull is degenerate. A rigid motion keeps them."""
    try:
        return ConvexHull(np.asarray(vertices, np.float64)).vertices
    except (QhullError, ValueError):
        return np.arange(len(vertices))


def hull_table(hulls: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Type t's hull points are rows off[t]:off[t+1] of pts: (pts (P, 3), off (T+1,))."""
    off = np.zeros(len(hulls) + 1, np.int64)
    off[1:] = np.cumsum([len(h) for h in hulls])
    pts = np.concatenate(hulls) if hulls else np.zeros((0, 3))
    return np.ascontiguousarray(pts, np.float64), off


def apart_pairs(pts: np.ndarray, off: np.ndarray, typ: np.ndarray, matrices: np.ndarray,
                pairs: np.ndarray, margin: float) -> np.ndarray:
    """Whether each pair (P, 2) of placed objects (typ (N,), matrices (N, 4, 4) rigid,
    local -> container frame) has hulls (`hull_table`) more than `margin` apart, proven;
    False means unproven, not touching."""
    pairs = np.ascontiguousarray(pairs, np.int64).reshape(-1, 2)
    return _apart_pairs(pts, off, np.ascontiguousarray(typ, np.int64),
                        np.ascontiguousarray(matrices, np.float64), pairs, float(margin))


@njit(cache=True, parallel=True)
def _apart_pairs(pts, off, typ, matrices, pairs, margin):
    out = np.zeros(len(pairs), np.bool_)
    for k in prange(len(pairs)):
        a, b = pairs[k, 0], pairs[k, 1]
        out[k] = _apart(pts, off[typ[a]], off[typ[a] + 1], matrices[a],
                        off[typ[b]], off[typ[b] + 1], matrices[b], margin)
    return out


@njit(cache=True)
def _support(pts, start, end, m, dx, dy, dz, out):
    """out[:] = the placed hull's (rows start:end, placed by m) point furthest along d."""
    lx, ly, lz = _unrotate(m, dx, dy, dz)  # m's top-left 3x3 is its rotation
    best = -np.inf
    k = start
    for i in range(start, end):
        s = pts[i, 0] * lx + pts[i, 1] * ly + pts[i, 2] * lz
        if s > best:
            best = s
            k = i
    x, y, z = _rotate(m, pts[k, 0], pts[k, 1], pts[k, 2])
    out[0], out[1], out[2] = x + m[0, 3], y + m[1, 3], z + m[2, 3]


@njit(cache=True)
def _difference_support(pts, sa, ea, ma, sb, eb, mb, dx, dy, dz, pa, pb, w):
    """w = the point of (hull A - hull B) furthest along d."""
    _support(pts, sa, ea, ma, dx, dy, dz, pa)
    _support(pts, sb, eb, mb, -dx, -dy, -dz, pb)
    for r in range(3):
        w[r] = pa[r] - pb[r]


@njit(cache=True)
def _closest_on_simplex(W, m, v, keep):
    """v = the point of the hull of W[:m] (m <= 4) nearest the origin; keep[i]: W[i] is a
    vertex of the face it lies on. Returns the face's vertex count, 0 if none solved."""
    best = np.inf
    best_n = 0
    E = np.empty((3, 3))
    G = np.empty((3, 4))
    lam = np.empty(3)
    x = np.empty(3)
    idx = np.empty(4, np.int64)
    for mask in range(1, 1 << m):
        n = 0
        for i in range(m):
            if mask & (1 << i):
                idx[n] = i
                n += 1
        o = idx[0]
        for i in range(1, n):
            for r in range(3):
                E[i - 1, r] = W[idx[i], r] - W[o, r]
        k = n - 1
        ok = True
        for i in range(k):  # the normal equations G lam = -E W[o]
            for j in range(k):
                G[i, j] = E[i, 0] * E[j, 0] + E[i, 1] * E[j, 1] + E[i, 2] * E[j, 2]
            G[i, k] = -(E[i, 0] * W[o, 0] + E[i, 1] * W[o, 1] + E[i, 2] * W[o, 2])
        scale = 0.0
        for i in range(k):
            scale = max(scale, G[i, i])
        for c in range(k):  # Gaussian elimination with partial pivoting
            p = c
            for r in range(c + 1, k):
                if abs(G[r, c]) > abs(G[p, c]):
                    p = r
            if abs(G[p, c]) <= 1e-12 * scale:
                ok = False
                break
            if p != c:
                for j in range(k + 1):
                    G[c, j], G[p, j] = G[p, j], G[c, j]
            for r in range(c + 1, k):
                f = G[r, c] / G[c, c]
                for j in range(c, k + 1):
                    G[r, j] -= f * G[c, j]
        if not ok:
            continue
        for c in range(k - 1, -1, -1):
            s = G[c, k]
            for j in range(c + 1, k):
                s -= G[c, j] * lam[j]
            lam[c] = s / G[c, c]
        first = 1.0
        for i in range(k):
            first -= lam[i]
            if lam[i] <= 0.0:
                ok = False
        if not ok or first <= 0.0:
            continue
        for r in range(3):
            x[r] = W[o, r]
            for i in range(k):
                x[r] += lam[i] * E[i, r]
        d = x[0] * x[0] + x[1] * x[1] + x[2] * x[2]
        if d < best:
            best = d
            best_n = n
            v[:] = x
            for i in range(m):
                keep[i] = False
            for i in range(n):
                keep[idx[i]] = True
    return best_n


@njit(cache=True)
def _apart(pts, sa, ea, ma, sb, eb, mb, margin):
    """Whether placed hulls A and B are proven more than margin apart (module doc)."""
    if sa == ea or sb == eb:  # a type without points proves nothing
        return False
    pa = np.empty(3)
    pb = np.empty(3)
    w = np.empty(3)
    v = np.empty(3)
    W = np.empty((4, 3))
    keep = np.zeros(4, np.bool_)
    dx, dy, dz = ma[0, 3] - mb[0, 3], ma[1, 3] - mb[1, 3], ma[2, 3] - mb[2, 3]
    if dx == 0.0 and dy == 0.0 and dz == 0.0:
        dx = 1.0
    _difference_support(pts, sa, ea, ma, sb, eb, mb, dx, dy, dz, pa, pb, v)
    m = 0
    for _ in range(MAX_ITERATIONS):
        vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
        if vv <= margin * margin:
            return False
        _difference_support(pts, sa, ea, ma, sb, eb, mb, -v[0], -v[1], -v[2], pa, pb, w)
        vw = v[0] * w[0] + v[1] * w[1] + v[2] * w[2]
        if vw > margin * np.sqrt(vv):
            return True
        if vv - vw <= 1e-12 * vv or m == 4:
            return False  # converged short of the margin, or the origin is enclosed
        W[m] = w
        m += 1
        n = _closest_on_simplex(W, m, v, keep)
        if n == 0:
            return False
        j = 0
        for i in range(m):
            if keep[i]:
                W[j] = W[i]
                j += 1
        m = j
    return False
