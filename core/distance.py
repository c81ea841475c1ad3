"""Signed distance grids of closed triangle meshes.

A `DistanceGrid` samples the signed distance to a closed mesh at the nodes of a regular grid,
in the mesh's own frame and units. Sign convention: **positive inside**, negative outside, so
the value at a point is its clearance from the surface for points inside the solid.

How it is built (exact where collisions happen, cheap elsewhere):
1. nodes within `band` cells of a triangle get the exact point-triangle distance (numba);
2. every other node takes the nearest triangle of its nearest band node (Euclidean distance
   transform with indices) and the exact distance to that triangle;
3. the sign is the majority vote of ray parity along x, y and z, with the rays nudged off the
   node by an irrational fraction of a cell so that they never graze an edge of an
   axis-aligned mesh.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import ndimage
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class DistanceGrid:
    """Signed distance samples: values[i, j, k] at origin + (i, j, k) * spacing.

    values: (nx, ny, nz) float64, positive inside. origin: (3,) float64. spacing: cell size.
    Units and frame are those of the mesh it was built from.
    """

    values: np.ndarray
    origin: np.ndarray
    spacing: float

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.values.shape  # type: ignore[return-value]

    def node_points(self) -> np.ndarray:
        """(nx*ny*nz, 3) node coordinates in C order of `values`."""
        axes = [self.origin[a] + self.spacing * np.arange(self.shape[a]) for a in range(3)]
        g = np.meshgrid(*axes, indexing="ij")
        return np.stack([x.ravel() for x in g], axis=1)


@njit(cache=True)
def point_segment_distance(p, a, b):
    """Exact Euclidean distance from point p to segment ab (a == b allowed)."""
    d0 = b[0] - a[0]
    d1 = b[1] - a[1]
    d2 = b[2] - a[2]
    dd = d0 * d0 + d1 * d1 + d2 * d2
    t = 0.0
    if dd > 0.0:
        t = ((p[0] - a[0]) * d0 + (p[1] - a[1]) * d1 + (p[2] - a[2]) * d2) / dd
        t = min(max(t, 0.0), 1.0)
    q0 = a[0] + t * d0 - p[0]
    q1 = a[1] + t * d1 - p[1]
    q2 = a[2] + t * d2 - p[2]
    return np.sqrt(q0 * q0 + q1 * q1 + q2 * q2)


@njit(cache=True)
def point_triangle_distance(p, a, b, c):
    """Exact Euclidean distance from point p to triangle abc (all (3,) float64).

    Degenerate (zero-area) triangles fall back to the distance to their edges.
    """
    ex0 = (b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1])
    ex1 = (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2])
    ex2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    area2 = ex0 * ex0 + ex1 * ex1 + ex2 * ex2
    l0 = (b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2
    l1 = (c[0] - b[0]) ** 2 + (c[1] - b[1]) ** 2 + (c[2] - b[2]) ** 2
    l2 = (a[0] - c[0]) ** 2 + (a[1] - c[1]) ** 2 + (a[2] - c[2]) ** 2
    lmax = max(l0, l1, l2)
    if area2 <= 1e-24 * lmax * lmax:
        return min(point_segment_distance(p, a, b), point_segment_distance(p, b, c),
                   point_segment_distance(p, c, a))
    ab0 = b[0] - a[0]
    ab1 = b[1] - a[1]
    ab2 = b[2] - a[2]
    ac0 = c[0] - a[0]
    ac1 = c[1] - a[1]
    ac2 = c[2] - a[2]
    ap0 = p[0] - a[0]
    ap1 = p[1] - a[1]
    ap2 = p[2] - a[2]
    d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
    d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    if d1 <= 0.0 and d2 <= 0.0:
        return np.sqrt(ap0 * ap0 + ap1 * ap1 + ap2 * ap2)
    bp0 = p[0] - b[0]
    bp1 = p[1] - b[1]
    bp2 = p[2] - b[2]
    d3 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2
    d4 = ac0 * bp0 + ac1 * bp1 + ac2 * bp2
    if d3 >= 0.0 and d4 <= d3:
        return np.sqrt(bp0 * bp0 + bp1 * bp1 + bp2 * bp2)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        q0 = ap0 - v * ab0
        q1 = ap1 - v * ab1
        q2 = ap2 - v * ab2
        return np.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    cp0 = p[0] - c[0]
    cp1 = p[1] - c[1]
    cp2 = p[2] - c[2]
    d5 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2
    d6 = ac0 * cp0 + ac1 * cp1 + ac2 * cp2
    if d6 >= 0.0 and d5 <= d6:
        return np.sqrt(cp0 * cp0 + cp1 * cp1 + cp2 * cp2)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        q0 = ap0 - w * ac0
        q1 = ap1 - w * ac1
        q2 = ap2 - w * ac2
        return np.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        q0 = bp0 - w * (c[0] - b[0])
        q1 = bp1 - w * (c[1] - b[1])
        q2 = bp2 - w * (c[2] - b[2])
        return np.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    q0 = ap0 - ab0 * v - ac0 * w
    q1 = ap1 - ab1 * v - ac1 * w
    q2 = ap2 - ab2 * v - ac2 * w
    return np.sqrt(q0 * q0 + q1 * q1 + q2 * q2)


@njit(cache=True)
def band_distances(vertices, faces, origin, spacing, shape, band):
    """Exact unsigned distance at nodes within `band` cells of any triangle.

    Returns (dist (nx,ny,nz) float64, inf outside the band; tri (nx,ny,nz) int64, -1 there).
    """
    nx, ny, nz = shape[0], shape[1], shape[2]
    dist = np.full((nx, ny, nz), np.inf)
    tri = np.full((nx, ny, nz), -1, np.int64)
    p = np.empty(3)
    pad = band * spacing
    for f in range(faces.shape[0]):
        a = vertices[faces[f, 0]]
        b = vertices[faces[f, 1]]
        c = vertices[faces[f, 2]]
        lo = np.empty(3, np.int64)
        hi = np.empty(3, np.int64)
        for ax in range(3):
            mn = min(a[ax], b[ax], c[ax]) - pad
            mx = max(a[ax], b[ax], c[ax]) + pad
            lo[ax] = max(0, int(np.ceil((mn - origin[ax]) / spacing)))
            hi[ax] = min(shape[ax] - 1, int(np.floor((mx - origin[ax]) / spacing)))
        for i in range(lo[0], hi[0] + 1):
            p[0] = origin[0] + i * spacing
            for j in range(lo[1], hi[1] + 1):
                p[1] = origin[1] + j * spacing
                for k in range(lo[2], hi[2] + 1):
                    p[2] = origin[2] + k * spacing
                    d = point_triangle_distance(p, a, b, c)
                    if d < dist[i, j, k]:
                        dist[i, j, k] = d
                        tri[i, j, k] = f
    return dist, tri


@njit(cache=True)
def _min_candidate_distance(points, starts, candidates, vertices, faces):
    """Per point m: min exact distance to triangles candidates[starts[m]:starts[m+1]]."""
    out = np.empty(points.shape[0])
    for m in range(points.shape[0]):
        best = np.inf
        for j in range(starts[m], starts[m + 1]):
            f = candidates[j]
            d = point_triangle_distance(points[m], vertices[faces[f, 0]],
                                        vertices[faces[f, 1]], vertices[faces[f, 2]])
            if d < best:
                best = d
        out[m] = best
    return out


def _candidates(points: np.ndarray, vertices: np.ndarray,
                faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles that can hold a point's nearest surface point, as CSR (starts, indices).

    The distance to the nearest vertex bounds the distance to the surface from above, and a
    triangle with a point within that bound has its centroid within bound + its circumradius
    (from the centroid), so the candidates found this way always contain the nearest.
    """
    tri = vertices[faces]
    centroid = tri.mean(axis=1)
    reach = float(np.sqrt(((tri - centroid[:, None]) ** 2).sum(axis=2)).max())
    bound, _ = cKDTree(vertices).query(points)
    lists = cKDTree(centroid).query_ball_point(points, bound + reach * (1 + 1e-9) + 1e-12)
    lengths = np.fromiter((len(c) for c in lists), np.int64, len(lists))
    starts = np.zeros(len(lists) + 1, np.int64)
    np.cumsum(lengths, out=starts[1:])
    flat = np.fromiter(itertools.chain.from_iterable(lists), np.int64, int(starts[-1]))
    return starts, flat


def surface_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact unsigned distance from each point to a triangle mesh.

    points (N, 3), vertices (V, 3) float, faces (F, 3) int, all in one frame; returns (N,)
    float64 in those units.
    """
    points = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    vertices = np.ascontiguousarray(vertices, np.float64)
    faces = np.ascontiguousarray(faces, np.int64)
    if len(points) == 0:
        return np.zeros(0)
    starts, flat = _candidates(points, vertices, faces)
    return _min_candidate_distance(points, starts, flat, vertices, faces)


@njit(cache=True)
def distances_to_given_triangles(points, tri_index, vertices, faces):
    """Distance from points (M,3) to triangle tri_index[m] of the mesh, (M,) float64."""
    out = np.empty(points.shape[0])
    for m in range(points.shape[0]):
        f = tri_index[m]
        out[m] = point_triangle_distance(
            points[m], vertices[faces[f, 0]], vertices[faces[f, 1]], vertices[faces[f, 2]]
        )
    return out


@njit(cache=True)
def ray_parity(vertices, faces, origin, spacing, shape, axis, jitter_u, jitter_v):
    """Inside flags (odd crossing count) from rays cast along +axis through every node.

    The ray through node (i, j, k) is offset in the two other axes by (jitter_u, jitter_v)
    cells; crossings are counted below the node's coordinate along `axis`.
    """
    u_ax = (axis + 1) % 3
    v_ax = (axis + 2) % 3
    n_u = shape[u_ax]
    n_v = shape[v_ax]
    n_w = shape[axis]
    flips = np.zeros((n_u, n_v, n_w + 1), np.uint8)
    for f in range(faces.shape[0]):
        a = vertices[faces[f, 0]]
        b = vertices[faces[f, 1]]
        c = vertices[faces[f, 2]]
        au = (a[u_ax] - origin[u_ax]) / spacing - jitter_u
        bu = (b[u_ax] - origin[u_ax]) / spacing - jitter_u
        cu = (c[u_ax] - origin[u_ax]) / spacing - jitter_u
        av = (a[v_ax] - origin[v_ax]) / spacing - jitter_v
        bv = (b[v_ax] - origin[v_ax]) / spacing - jitter_v
        cv = (c[v_ax] - origin[v_ax]) / spacing - jitter_v
        aw = (a[axis] - origin[axis]) / spacing
        bw = (b[axis] - origin[axis]) / spacing
        cw = (c[axis] - origin[axis]) / spacing
        area = (bu - au) * (cv - av) - (bv - av) * (cu - au)
        if area == 0.0:
            continue
        i0 = max(0, int(np.ceil(min(au, bu, cu))))
        i1 = min(n_u - 1, int(np.floor(max(au, bu, cu))))
        j0 = max(0, int(np.ceil(min(av, bv, cv))))
        j1 = min(n_v - 1, int(np.floor(max(av, bv, cv))))
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                w0 = (bu - i) * (cv - j) - (bv - j) * (cu - i)
                w1 = (cu - i) * (av - j) - (cv - j) * (au - i)
                w2 = (au - i) * (bv - j) - (av - j) * (bu - i)
                if area > 0.0:
                    if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                        continue
                else:
                    if w0 > 0.0 or w1 > 0.0 or w2 > 0.0:
                        continue
                # inclusion is decided on the nudged ray, the crossing height on the
                # triangle's plane at the node itself
                x = i - jitter_u
                y = j - jitter_v
                w0 = (bu - x) * (cv - y) - (bv - y) * (cu - x)
                w1 = (cu - x) * (av - y) - (cv - y) * (au - x)
                w2 = (au - x) * (bv - y) - (av - y) * (bu - x)
                wz = (w0 * aw + w1 * bw + w2 * cw) / area
                kk = int(np.floor(wz)) + 1  # first node strictly above the crossing
                if kk < 0:
                    kk = 0
                if kk <= n_w:
                    flips[i, j, kk] ^= 1
    inside = np.zeros((n_u, n_v, n_w), np.uint8)
    for i in range(n_u):
        for j in range(n_v):
            acc = 0
            for k in range(n_w):
                acc ^= flips[i, j, k]
                inside[i, j, k] = acc
    return inside


def inside_mask(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray, spacing: float,
                shape: tuple[int, int, int]) -> np.ndarray:
    """(nx,ny,nz) bool: grid nodes inside the closed mesh (majority of three ray parities)."""
    shp = np.asarray(shape, np.int64)
    votes = np.zeros(shape, np.uint8)
    jit = ((1.234567e-4, 2.718281e-4), (3.141592e-4, 1.414213e-4), (1.732050e-4, 2.236067e-4))
    for axis in range(3):
        par = ray_parity(vertices, faces, origin, spacing, shp, axis, *jit[axis])
        # par is indexed (u, v, w) with u = axis+1, v = axis+2, w = axis: back to (x, y, z).
        order = [(axis + 1) % 3, (axis + 2) % 3, axis]
        votes += np.transpose(par, np.argsort(order))
    return votes >= 2


def distance_grid(vertices: np.ndarray, faces: np.ndarray, spacing: float, *,
                  pad: float = 0.0, band: int = 3) -> DistanceGrid:
    """Signed distance grid (positive inside) of a closed mesh over its bounds + `pad`.

    vertices (V,3) float64 and faces (F,3) int in any frame; `spacing` and `pad` in its units.
    """
    vertices = np.ascontiguousarray(vertices, np.float64)
    faces = np.ascontiguousarray(faces, np.int64)
    lo = vertices.min(axis=0) - pad - spacing
    hi = vertices.max(axis=0) + pad + spacing
    shape = tuple(int(n) for n in np.ceil((hi - lo) / spacing).astype(np.int64) + 1)
    origin = lo
    dist, tri = band_distances(vertices, faces, origin, float(spacing),
                               np.asarray(shape, np.int64), float(band))
    # A node inside the padded box of some far triangle may have missed its nearest one:
    # only distances within the band are exact.
    far = (tri < 0) | (dist > band * spacing)
    if far.any():
        if (~far).any():
            _, idx = ndimage.distance_transform_edt(far, return_indices=True)
            near_tri = tri[idx[0], idx[1], idx[2]]
        else:  # pragma: no cover - a mesh always has band nodes
            near_tri = np.zeros(shape, np.int64)
        g = DistanceGrid(dist, origin, float(spacing))
        pts = g.node_points()[far.ravel()]
        dist[far] = distances_to_given_triangles(pts, near_tri[far], vertices, faces)
    inside = inside_mask(vertices, faces, origin, float(spacing), shape)
    values = np.where(inside, dist, -dist)
    return DistanceGrid(np.ascontiguousarray(values), np.asarray(origin, np.float64),
                        float(spacing))


def min_pyramid(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower bounds of a grid's trilinear interpolant over blocks of cells, for culling.

    Level 0 holds each cell's smallest corner value (the interpolant inside a cell never goes
    below it); level L+1 the minimum of level L's 2x2x2 blocks, so a level-L entry bounds the
    2^L x 2^L x 2^L cells it covers. values: (nx,ny,nz) node samples. Returns (flat (M,)
    float64, offsets (L+1,) int64 into flat per level, shapes (L,3) int64 per level).
    """
    v = np.asarray(values, np.float64)
    level = v[:-1, :-1, :-1]
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                level = np.minimum(level, v[dx:dx + v.shape[0] - 1, dy:dy + v.shape[1] - 1,
                                            dz:dz + v.shape[2] - 1])
    levels = [np.ascontiguousarray(level)]
    while max(level.shape) > 1:
        pad = [(0, s % 2) for s in level.shape]
        p = np.pad(level, pad, constant_values=np.inf)
        level = p.reshape(p.shape[0] // 2, 2, p.shape[1] // 2, 2, p.shape[2] // 2, 2).min(
            axis=(1, 3, 5))
        levels.append(np.ascontiguousarray(level))
    flat = np.concatenate([lv.ravel() for lv in levels])
    off = np.cumsum([0] + [lv.size for lv in levels]).astype(np.int64)
    shapes = np.array([lv.shape for lv in levels], np.int64)
    return flat, off, shapes
