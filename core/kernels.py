"""numba kernels: grid sampling, contacts (sphere-sphere, point-grid, wall) and the solver.

Frames: object k's local frame maps to the container frame by x -> R(q_k) * s_k * x + p_k.
All lengths are container units. Signed distance grids are positive inside.

Flat type table (T types), built by `solver.TypeTable`:
- radius (T,) bounding radius about the local origin
- sph_off (T+1,), sph_c (S,3), sph_r (S,): inner spheres of type t are rows sph_off[t]:sph_off[t+1]
- pts (P,3): surface points, cluster by cluster: type t's clusters are rows
  pc_off[t]:pc_off[t+1] of pcl (C,4) (ball centre xyz, radius), cluster c's points rows
  pcl_off[c]:pcl_off[c+1] of pts
- box (T,12): bounding box of the vertices in the local frame, lo xyz then hi xyz; then
  the centre xyz and half extents xyz of a box (local frame) that holds the vertices, the
  inner spheres and the surface points: everything a contact test reads
- g_off (T+1,), g_vals (G,) flattened C-order grids, g_shape (T,3), g_origin (T,3), g_h (T,)
Container grid: c_vals (nx,ny,nz), c_origin (3,), c_h; its min pyramid c_pyr, c_poff,
c_pshape (`distance.min_pyramid`); crease: the face planes its crease cells read
(`wall_planes.CreasePlanes.arrays`; the pyramid bounds the grid, which they only raise).
Penetration below `tol` (container units) is ignored.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import cellgrid


@njit(cache=True)
def quat_to_rot(q):
    """(4,) unit quaternion w,x,y,z -> (3,3) rotation matrix."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    r = np.empty((3, 3))
    r[0, 0] = 1 - 2 * (y * y + z * z)
    r[0, 1] = 2 * (x * y - w * z)
    r[0, 2] = 2 * (x * z + w * y)
    r[1, 0] = 2 * (x * y + w * z)
    r[1, 1] = 1 - 2 * (x * x + z * z)
    r[1, 2] = 2 * (y * z - w * x)
    r[2, 0] = 2 * (x * z - w * y)
    r[2, 1] = 2 * (y * z + w * x)
    r[2, 2] = 1 - 2 * (x * x + y * y)
    return r


@njit(cache=True)
def _rotate(R, x, y, z):
    """R (x, y, z): a local offset into the container frame's orientation."""
    return (R[0, 0] * x + R[0, 1] * y + R[0, 2] * z,
            R[1, 0] * x + R[1, 1] * y + R[1, 2] * z,
            R[2, 0] * x + R[2, 1] * y + R[2, 2] * z)


@njit(cache=True)
def _unrotate(R, x, y, z):
    """R^T (x, y, z): a container-frame offset into the local frame's orientation."""
    return (R[0, 0] * x + R[1, 0] * y + R[2, 0] * z,
            R[0, 1] * x + R[1, 1] * y + R[2, 1] * z,
            R[0, 2] * x + R[1, 2] * y + R[2, 2] * z)


@njit(cache=True)
def trilinear(vals, off, nx, ny, nz, ox, oy, oz, h, px, py, pz):
    """Trilinear value and gradient of a flat C-order grid at (px,py,pz).

    Outside the grid box the value continues as (value at the clamped point) minus the
    distance to the box, so it keeps decreasing away from the box (outside = negative).
    Returns (d, gx, gy, gz).
    """
    fx = (px - ox) / h
    fy = (py - oy) / h
    fz = (pz - oz) / h
    cx = min(max(fx, 0.0), nx - 1.0)
    cy = min(max(fy, 0.0), ny - 1.0)
    cz = min(max(fz, 0.0), nz - 1.0)
    i = min(int(cx), nx - 2)
    j = min(int(cy), ny - 2)
    k = min(int(cz), nz - 2)
    tx = cx - i
    ty = cy - j
    tz = cz - k
    b = off + (i * ny + j) * nz + k
    c000 = vals[b]
    c001 = vals[b + 1]
    c010 = vals[b + nz]
    c011 = vals[b + nz + 1]
    c100 = vals[b + ny * nz]
    c101 = vals[b + ny * nz + 1]
    c110 = vals[b + ny * nz + nz]
    c111 = vals[b + ny * nz + nz + 1]
    c00 = c000 + (c001 - c000) * tz
    c01 = c010 + (c011 - c010) * tz
    c10 = c100 + (c101 - c100) * tz
    c11 = c110 + (c111 - c110) * tz
    c0 = c00 + (c01 - c00) * ty
    c1 = c10 + (c11 - c10) * ty
    d = c0 + (c1 - c0) * tx
    gx = (c1 - c0) / h
    gy = ((c01 - c00) * (1.0 - tx) + (c11 - c10) * tx) / h
    z0 = (c001 - c000) + ((c011 - c010) - (c001 - c000)) * ty
    z1 = (c101 - c100) + ((c111 - c110) - (c101 - c100)) * ty
    gz = (z0 + (z1 - z0) * tx) / h
    ex = (fx - cx) * h
    ey = (fy - cy) * h
    ez = (fz - cz) * h
    e = np.sqrt(ex * ex + ey * ey + ez * ez)
    if e > 0.0:
        d -= e
        gx = -ex / e
        gy = -ey / e
        gz = -ez / e
    return d, gx, gy, gz


@njit(cache=True)
def sample_grid_many(vals3, origin, h, pts):
    """Trilinear samples of a 3D grid at points (M,3) -> (M,) (see `trilinear`)."""
    nx, ny, nz = vals3.shape
    flat = vals3.ravel()
    out = np.empty(pts.shape[0])
    for m in range(pts.shape[0]):
        d, _, _, _ = trilinear(flat, 0, nx, ny, nz, origin[0], origin[1], origin[2], h,
                               pts[m, 0], pts[m, 1], pts[m, 2])
        out[m] = d
    return out


@njit(cache=True, inline="always")
def crease_depth(px, py, pz, d, nx, ny, nz, ox, oy, oz, h, index, offsets, ids, planes,
                 reach):
    """The wall depth at (px, py, pz): the grid's d, or where the point's cell is a crease
    cell and its planes read more room, and some (the point is inside), their least depth
    (at most reach). Outside, a plane reads a corner's depth short (-0.35 for -0.6), so
    there the grid's reading stays. The push keeps the grid's gradient: the nearest plane's
    normal flips across a crease's bisector, and an object in a corner pushed along it
    cleared one wall at a time (docs/notes-core.md)."""
    if index.shape[0] == 0 or d >= reach or d <= -h:
        return d
    fx = (px - ox) / h
    fy = (py - oy) / h
    fz = (pz - oz) / h
    if fx < 0.0 or fy < 0.0 or fz < 0.0 or fx > nx - 1.0 or fy > ny - 1.0 or fz > nz - 1.0:
        return d
    i = min(int(fx), nx - 2)
    j = min(int(fy), ny - 2)
    k = min(int(fz), nz - 2)
    at = index[(i * (ny - 1) + j) * (nz - 1) + k]
    if at < 0:
        return d
    best = reach
    for u in range(offsets[at], offsets[at + 1]):
        pl = ids[u]
        v = planes[pl, 0] * px + planes[pl, 1] * py + planes[pl, 2] * pz + planes[pl, 3]
        if v < best:
            best = v
    if best <= d or best <= 0.0:
        return d
    return best


@njit(cache=True, inline="always")
def wall_depth(c_flat, nx, ny, nz, c_origin, c_h, index, offsets, ids, planes, reach, px, py,
               pz):
    """The container's wall depth (positive inside) and its gradient at (px, py, pz): the
    grid's `trilinear` reading, or in a crease cell the larger reading of its face planes
    (`crease_depth`; index to reach: `wall_planes.CreasePlanes.arrays`, unpacked by the
    caller once, outside its loops). Both are inlined into their callers: a call per point
    cost more than the reading (docs/notes-core.md). Returns (d, gx, gy, gz)."""
    d, gx, gy, gz = trilinear(c_flat, 0, nx, ny, nz, c_origin[0], c_origin[1], c_origin[2],
                              c_h, px, py, pz)
    return (crease_depth(px, py, pz, d, nx, ny, nz, c_origin[0], c_origin[1], c_origin[2],
                         c_h, index, offsets, ids, planes, reach), gx, gy, gz)


@njit(cache=True)
def wall_depths(vals3, origin, h, crease, pts):
    """`wall_depth` at points (M,3) -> (M,)."""
    nx, ny, nz = vals3.shape
    flat = vals3.ravel()
    index, offsets, ids, planes, reach = crease
    out = np.empty(pts.shape[0])
    for m in range(pts.shape[0]):
        d, _, _, _ = wall_depth(flat, nx, ny, nz, origin, h, index, offsets, ids, planes,
                                reach, pts[m, 0], pts[m, 1], pts[m, 2])
        out[m] = d
    return out


@njit(cache=True)
def sample_type_grid(g_vals, g_off, g_shape, g_origin, g_h, t, px, py, pz):
    """Signed distance (local units, positive inside) and gradient of type t's grid."""
    return trilinear(g_vals, g_off[t], g_shape[t, 0], g_shape[t, 1], g_shape[t, 2],
                     g_origin[t, 0], g_origin[t, 1], g_origin[t, 2], g_h[t], px, py, pz)


@njit(cache=True)
def _push_pair(F, Tq, a, b, pen, nx, ny, nz, ax, ay, az, bx, by, bz):
    """Record a contact of depth pen pushing a along n (unit) and b the opposite way.

    F[k, :3] sums w * pen * n with weight w = pen and F[k, 3] sums w; the torque arms are
    (ax, ay, az) from a's centre and (bx, by, bz) from b's centre.
    """
    f = pen * pen
    F[a, 0] += f * nx
    F[a, 1] += f * ny
    F[a, 2] += f * nz
    F[a, 3] += pen
    F[b, 0] -= f * nx
    F[b, 1] -= f * ny
    F[b, 2] -= f * nz
    F[b, 3] += pen
    Tq[a, 0] += (ay * nz - az * ny) * f
    Tq[a, 1] += (az * nx - ax * nz) * f
    Tq[a, 2] += (ax * ny - ay * nx) * f
    Tq[b, 0] -= (by * nz - bz * ny) * f
    Tq[b, 1] -= (bz * nx - bx * nz) * f
    Tq[b, 2] -= (bx * ny - by * nx) * f


@njit(cache=True)
def _points_in_other(a, b, R_a, R_b, typ, pos, scale, radius, pc_off, pcl, pcl_off, box, pts,
                     g_off, g_vals, g_shape, g_origin, g_h, delta, tol, F, Tq):
    """Surface points of object a against the distance grid of object b.

    Adds forces (pushing a's points out of b) to F[a], reactions to F[b], torques to Tq.
    Returns the largest penetration depth (container units). Points are visited cluster by
    cluster (pc_off, pcl, pcl_off: see `TypeTable`). A point outside b's box by more than
    delta plus a grid cell cannot penetrate b (no grid node it is interpolated from lies
    within delta of b) and is skipped, and so is a cluster whose ball misses b's bounding
    sphere or lies wholly outside that padded box: the result equals visiting every point.
    """
    ta = typ[a]
    tb = typ[b]
    sa = scale[a]
    sb = scale[b]
    reach = radius[tb] * sb + delta
    pad = delta / sb + g_h[tb]
    lo_x = box[tb, 0] - pad
    lo_y = box[tb, 1] - pad
    lo_z = box[tb, 2] - pad
    hi_x = box[tb, 3] + pad
    hi_y = box[tb, 4] + pad
    hi_z = box[tb, 5] + pad
    ox = pos[a, 0] - pos[b, 0]
    oy = pos[a, 1] - pos[b, 1]
    oz = pos[a, 2] - pos[b, 2]
    worst = 0.0
    for cl in range(pc_off[ta], pc_off[ta + 1]):
        cx, cy, cz = _rotate(R_a, pcl[cl, 0], pcl[cl, 1], pcl[cl, 2])
        cx = cx * sa + ox
        cy = cy * sa + oy
        cz = cz * sa + oz
        rc = pcl[cl, 3] * sa
        lim = reach + rc
        if cx * cx + cy * cy + cz * cz > lim * lim:
            continue
        # the cluster's ball in b's local frame against b's box: every point would fail the
        # box test below
        qx, qy, qz = _unrotate(R_b, cx, cy, cz)
        qx /= sb
        qy /= sb
        qz /= sb
        rq = rc / sb
        if (qx < lo_x - rq or qx > hi_x + rq or qy < lo_y - rq or qy > hi_y + rq
                or qz < lo_z - rq or qz > hi_z + rq):
            continue
        for m in range(pcl_off[cl], pcl_off[cl + 1]):
            wx, wy, wz = _rotate(R_a, pts[m, 0], pts[m, 1], pts[m, 2])
            wx *= sa
            wy *= sa
            wz *= sa
            rx = wx + ox
            ry = wy + oy
            rz = wz + oz
            if rx * rx + ry * ry + rz * rz > reach * reach:
                continue
            # into b's local frame: R_b^T r / s_b
            qx, qy, qz = _unrotate(R_b, rx, ry, rz)
            qx /= sb
            qy /= sb
            qz /= sb
            if (qx < lo_x or qx > hi_x or qy < lo_y or qy > hi_y or qz < lo_z
                    or qz > hi_z):
                continue
            d, gx, gy, gz = sample_type_grid(g_vals, g_off, g_shape, g_origin, g_h, tb,
                                             qx, qy, qz)
            pen = d * sb + delta
            if pen <= tol:
                continue
            # outward normal of b in the container frame: -R_b grad
            nx = -(R_b[0, 0] * gx + R_b[0, 1] * gy + R_b[0, 2] * gz)
            ny = -(R_b[1, 0] * gx + R_b[1, 1] * gy + R_b[1, 2] * gz)
            nz = -(R_b[2, 0] * gx + R_b[2, 1] * gy + R_b[2, 2] * gz)
            nn = np.sqrt(nx * nx + ny * ny + nz * nz)
            if nn < 1e-12:
                nx = ox
                ny = oy
                nz = oz
                nn = np.sqrt(nx * nx + ny * ny + nz * nz) + 1e-300
            nx /= nn
            ny /= nn
            nz /= nn
            # torque about a's centre from its point, about b's centre from the reaction
            _push_pair(F, Tq, a, b, pen, nx, ny, nz, wx, wy, wz, rx, ry, rz)
            if pen > worst:
                worst = pen
    return worst


@njit(cache=True)
def boxes_apart(R_a, ax, ay, az, ea, R_b, bx, by, bz, eb, gap):
    """True if two oriented boxes are more than `gap` apart along one of their 15
    separating axes (Gottschalk's test); False if they may be nearer. Box k: centre
    (kx, ky, kz) and half extents e_k (3,) along the columns of R_k (container frame and
    units). The cross axes are not normalised, so their gap test asks for more room than
    `gap`, and every |R_a^T R_b| term is padded: both only make True rarer."""
    eps = 1e-9
    tx = bx - ax
    ty = by - ay
    tz = bz - az
    t = np.empty(3)
    r = np.empty((3, 3))
    ar = np.empty((3, 3))
    for i in range(3):
        t[i] = R_a[0, i] * tx + R_a[1, i] * ty + R_a[2, i] * tz
        for j in range(3):
            r[i, j] = R_a[0, i] * R_b[0, j] + R_a[1, i] * R_b[1, j] + R_a[2, i] * R_b[2, j]
            ar[i, j] = abs(r[i, j]) + eps
    for i in range(3):  # a's axes
        if abs(t[i]) > ea[i] + eb[0] * ar[i, 0] + eb[1] * ar[i, 1] + eb[2] * ar[i, 2] + gap:
            return True
    for j in range(3):  # b's axes
        tb = t[0] * r[0, j] + t[1] * r[1, j] + t[2] * r[2, j]
        if abs(tb) > ea[0] * ar[0, j] + ea[1] * ar[1, j] + ea[2] * ar[2, j] + eb[j] + gap:
            return True
    for i in range(3):  # a's axis i x b's axis j
        i1 = (i + 1) % 3
        i2 = (i + 2) % 3
        for j in range(3):
            j1 = (j + 1) % 3
            j2 = (j + 2) % 3
            ra = ea[i1] * ar[i2, j] + ea[i2] * ar[i1, j]
            rb = eb[j1] * ar[i, j2] + eb[j2] * ar[i, j1]
            if abs(t[i2] * r[i1, j] - t[i1] * r[i2, j]) > ra + rb + gap:
                return True
    return False


@njit(cache=True)
def _hull_box(box, t, s, R, px, py, pz):
    """Centre (container frame) and (3,) half extents of type t's contact box
    (`box[t, 6:]`) for an object at (px, py, pz) with rotation R and scale s."""
    cx, cy, cz = _rotate(R, box[t, 6] * s, box[t, 7] * s, box[t, 8] * s)
    e = np.empty(3)
    for d in range(3):
        e[d] = box[t, 9 + d] * s
    return cx + px, cy + py, cz + pz, e


@njit(cache=True)
def pair_contact(a, b, typ, pos, quat, scale, margin, clearance, tol, radius, sph_off, sph_c,
                 sph_r, pc_off, pcl, pcl_off, box, pts, g_off, g_vals, g_shape, g_origin, g_h,
                 F, Tq):
    """Penetration of objects a and b (inner spheres + surface points), forces accumulated.

    Objects must keep `clearance + margin[a] + margin[b]` apart. Returns the largest
    penetration depth found (0 if none above tol).
    """
    ta = typ[a]
    tb = typ[b]
    sa = scale[a]
    sb = scale[b]
    delta = clearance + margin[a] + margin[b]
    R_a = quat_to_rot(quat[a])
    R_b = quat_to_rot(quat[b])
    # elongated or flat objects whose bounding spheres meet are mostly far apart: their
    # boxes show it for a fraction of the tests below. A grid value is interpolated from
    # nodes up to sqrt(3) cells from its point, hence the two cells of room
    ax, ay, az, ea = _hull_box(box, ta, sa, R_a, pos[a, 0], pos[a, 1], pos[a, 2])
    bx, by, bz, eb = _hull_box(box, tb, sb, R_b, pos[b, 0], pos[b, 1], pos[b, 2])
    gap = delta + tol + 2.0 * max(g_h[ta] * sa, g_h[tb] * sb)
    if boxes_apart(R_a, ax, ay, az, ea, R_b, bx, by, bz, eb, gap):
        return 0.0
    worst = 0.0
    reach_b = radius[tb] * sb + delta
    reach_a = radius[ta] * sa + delta
    # b's spheres relative to b's centre, and a's relative to b's centre, each transformed
    # once per pair (not once per sphere pair)
    nb = 0
    vb = np.empty((sph_off[tb + 1] - sph_off[tb], 4))
    bx = pos[b, 0] - pos[a, 0]
    by = pos[b, 1] - pos[a, 1]
    bz = pos[b, 2] - pos[a, 2]
    for v in range(sph_off[tb], sph_off[tb + 1]):
        vx = (R_b[0, 0] * sph_c[v, 0] + R_b[0, 1] * sph_c[v, 1] + R_b[0, 2] * sph_c[v, 2]) * sb
        vy = (R_b[1, 0] * sph_c[v, 0] + R_b[1, 1] * sph_c[v, 1] + R_b[1, 2] * sph_c[v, 2]) * sb
        vz = (R_b[2, 0] * sph_c[v, 0] + R_b[2, 1] * sph_c[v, 1] + R_b[2, 2] * sph_c[v, 2]) * sb
        rb = sph_r[v] * sb
        lim = rb + reach_a
        ex = vx + bx
        ey = vy + by
        ez = vz + bz
        if ex * ex + ey * ey + ez * ez > lim * lim:
            continue  # this sphere of b is out of a's reach
        vb[nb, 0] = vx
        vb[nb, 1] = vy
        vb[nb, 2] = vz
        vb[nb, 3] = rb
        nb += 1
    for u in range(sph_off[ta], sph_off[ta + 1]):
        if nb == 0:
            break
        ux = (R_a[0, 0] * sph_c[u, 0] + R_a[0, 1] * sph_c[u, 1] + R_a[0, 2] * sph_c[u, 2]) * sa
        uy = (R_a[1, 0] * sph_c[u, 0] + R_a[1, 1] * sph_c[u, 1] + R_a[1, 2] * sph_c[u, 2]) * sa
        uz = (R_a[2, 0] * sph_c[u, 0] + R_a[2, 1] * sph_c[u, 1] + R_a[2, 2] * sph_c[u, 2]) * sa
        ra = sph_r[u] * sa
        cx = ux - bx
        cy = uy - by
        cz = uz - bz
        lim = ra + reach_b
        if cx * cx + cy * cy + cz * cz > lim * lim:
            continue
        for m in range(nb):
            vx = vb[m, 0]
            vy = vb[m, 1]
            vz = vb[m, 2]
            rb = vb[m, 3]
            dx = cx - vx
            dy = cy - vy
            dz = cz - vz
            dist = np.sqrt(dx * dx + dy * dy + dz * dz)
            pen = ra + rb + delta - dist
            if pen <= tol:
                continue
            if dist > 1e-12:
                nx = dx / dist
                ny = dy / dist
                nz = dz / dist
            else:
                nx = 1.0
                ny = 0.0
                nz = 0.0
            _push_pair(F, Tq, a, b, pen, nx, ny, nz, ux, uy, uz, vx, vy, vz)
            if pen > worst:
                worst = pen
    p1 = _points_in_other(a, b, R_a, R_b, typ, pos, scale, radius, pc_off, pcl, pcl_off, box,
                          pts, g_off, g_vals, g_shape, g_origin, g_h, delta, tol, F, Tq)
    p2 = _points_in_other(b, a, R_b, R_a, typ, pos, scale, radius, pc_off, pcl, pcl_off, box,
                          pts, g_off, g_vals, g_shape, g_origin, g_h, delta, tol, F, Tq)
    return max(worst, p1, p2)


@njit(cache=True)
def _push_wall(F, Tq, a, pen, gx, gy, gz, ax, ay, az):
    """Record a wall contact of depth pen pushing a along the container grid's gradient
    (gx, gy, gz), inward; (ax, ay, az) is the torque arm from a's centre. Same weights as
    `_push_pair`."""
    gn = np.sqrt(gx * gx + gy * gy + gz * gz) + 1e-300
    w = pen * pen
    F[a, 0] += w * gx / gn
    F[a, 1] += w * gy / gn
    F[a, 2] += w * gz / gn
    F[a, 3] += pen
    Tq[a, 0] += (ay * gz - az * gy) * w / gn
    Tq[a, 1] += (az * gx - ax * gz) * w / gn
    Tq[a, 2] += (ax * gy - ay * gx) * w / gn


@njit(cache=True)
def region_min(pyr, p_off, p_shape, c_origin, c_h, lx, ly, lz, ux, uy, uz):
    """A lower bound of the container grid's interpolant over the box [l, u] (container
    frame), from the min pyramid (pyr, p_off, p_shape: see `distance.min_pyramid`); -inf
    where the box reaches outside the grid's cells."""
    i0 = int(np.floor((lx - c_origin[0]) / c_h))
    j0 = int(np.floor((ly - c_origin[1]) / c_h))
    k0 = int(np.floor((lz - c_origin[2]) / c_h))
    i1 = int(np.floor((ux - c_origin[0]) / c_h))
    j1 = int(np.floor((uy - c_origin[1]) / c_h))
    k1 = int(np.floor((uz - c_origin[2]) / c_h))
    if (i0 < 0 or j0 < 0 or k0 < 0 or i1 >= p_shape[0, 0] or j1 >= p_shape[0, 1]
            or k1 >= p_shape[0, 2]):
        return -np.inf
    span = max(i1 - i0, j1 - j0, k1 - k0) + 1
    lev = 0
    while (1 << lev) < span and lev + 1 < p_shape.shape[0]:
        lev += 1  # the box covers at most 2 blocks per axis at this level
    ny = p_shape[lev, 1]
    nz = p_shape[lev, 2]
    o = p_off[lev]
    lo = np.inf
    for i in range(i0 >> lev, (i1 >> lev) + 1):
        for j in range(j0 >> lev, (j1 >> lev) + 1):
            for k in range(k0 >> lev, (k1 >> lev) + 1):
                v = pyr[o + (i * ny + j) * nz + k]
                if v < lo:
                    lo = v
    return lo


@njit(cache=True)
def wall_contact(a, typ, pos, quat, scale, margin, clearance, tol, radius, sph_off, sph_c,
                 sph_r, pc_off, pcl, pcl_off, pts, c_vals, c_shape, c_origin, c_h, c_pyr,
                 c_poff, c_pshape, crease, F, Tq):
    """Penetration of object a into the container wall (spheres and surface points), the
    wall read by `wall_depth`.

    The min pyramid skips work that cannot find a contact: the whole object when the
    grid's lower bound over its bounding sphere exceeds its largest inner sphere plus the
    gap to keep, its surface points when that bound exceeds the gap, and each point cluster
    whose own bound does; the result equals testing every sphere and point.
    """
    t = typ[a]
    s = scale[a]
    delta = clearance + margin[a]
    px = pos[a, 0]
    py = pos[a, 1]
    pz = pos[a, 2]
    ro = radius[t] * s
    near = region_min(c_pyr, c_poff, c_pshape, c_origin, c_h, px - ro, py - ro, pz - ro,
                      px + ro, py + ro, pz + ro)
    if near > delta + tol:  # else no inner sphere can clear it either
        r_max = 0.0
        for u in range(sph_off[t], sph_off[t + 1]):
            r_max = max(r_max, sph_r[u])
        if near > r_max * s + delta + tol:
            return 0.0
    R = quat_to_rot(quat[a])
    worst = 0.0
    nx_, ny_, nz_ = c_shape[0], c_shape[1], c_shape[2]
    w_index, w_off, w_ids, w_planes, w_reach = crease
    for u in range(sph_off[t], sph_off[t + 1]):
        ux = (R[0, 0] * sph_c[u, 0] + R[0, 1] * sph_c[u, 1] + R[0, 2] * sph_c[u, 2]) * s
        uy = (R[1, 0] * sph_c[u, 0] + R[1, 1] * sph_c[u, 1] + R[1, 2] * sph_c[u, 2]) * s
        uz = (R[2, 0] * sph_c[u, 0] + R[2, 1] * sph_c[u, 1] + R[2, 2] * sph_c[u, 2]) * s
        d, gx, gy, gz = wall_depth(c_vals, nx_, ny_, nz_, c_origin, c_h, w_index, w_off,
                                   w_ids, w_planes, w_reach, ux + px, uy + py, uz + pz)
        pen = sph_r[u] * s + delta - d
        if pen <= tol:
            continue
        _push_wall(F, Tq, a, pen, gx, gy, gz, ux, uy, uz)
        if pen > worst:
            worst = pen
    if near > delta + tol:
        return worst
    for cl in range(pc_off[t], pc_off[t + 1]):
        cx, cy, cz = _rotate(R, pcl[cl, 0], pcl[cl, 1], pcl[cl, 2])
        cx = cx * s + px
        cy = cy * s + py
        cz = cz * s + pz
        rc = pcl[cl, 3] * s
        if region_min(c_pyr, c_poff, c_pshape, c_origin, c_h, cx - rc, cy - rc, cz - rc,
                      cx + rc, cy + rc, cz + rc) > delta + tol:
            continue
        for m in range(pcl_off[cl], pcl_off[cl + 1]):
            wx = (R[0, 0] * pts[m, 0] + R[0, 1] * pts[m, 1] + R[0, 2] * pts[m, 2]) * s
            wy = (R[1, 0] * pts[m, 0] + R[1, 1] * pts[m, 1] + R[1, 2] * pts[m, 2]) * s
            wz = (R[2, 0] * pts[m, 0] + R[2, 1] * pts[m, 1] + R[2, 2] * pts[m, 2]) * s
            d, gx, gy, gz = wall_depth(c_vals, nx_, ny_, nz_, c_origin, c_h, w_index, w_off,
                                       w_ids, w_planes, w_reach, wx + px, wy + py, wz + pz)
            pen = delta - d
            if pen <= tol:
                continue
            _push_wall(F, Tq, a, pen, gx, gy, gz, wx, wy, wz)
            if pen > worst:
                worst = pen
    return worst


@njit(cache=True)
def _rotate_quat(q, ax, ay, az, angle):
    """q <- rotation(axis, angle) * q, renormalised."""
    h = 0.5 * angle
    s = np.sin(h)
    rw = np.cos(h)
    rx = ax * s
    ry = ay * s
    rz = az * s
    w = rw * q[0] - rx * q[1] - ry * q[2] - rz * q[3]
    x = rw * q[1] + rx * q[0] + ry * q[3] - rz * q[2]
    y = rw * q[2] - rx * q[3] + ry * q[0] + rz * q[1]
    z = rw * q[3] + rx * q[2] - ry * q[1] + rz * q[0]
    n = np.sqrt(w * w + x * x + y * y + z * z)
    q[0] = w / n
    q[1] = x / n
    q[2] = y / n
    q[3] = z / n


@njit(cache=True)
def _near_pairs(a, n_pairs, pa, pb, typ, pos, scale, alive, active, margin, radius,
                clearance):
    """Append to (pa, pb) from n_pairs on each alive b whose bounding sphere (plus the gaps
    to keep) reaches a's, skipping an active b < a (its own scan has the pair); returns the
    new count. pa and pb must have room for every object."""
    ra = radius[typ[a]] * scale[a] + clearance + margin[a]
    ax = pos[a, 0]
    ay = pos[a, 1]
    az = pos[a, 2]
    for b in range(typ.shape[0]):
        if b == a or not alive[b] or (active[b] and b < a):
            continue
        lim = ra + radius[typ[b]] * scale[b] + margin[b]
        dx = ax - pos[b, 0]
        dy = ay - pos[b, 1]
        dz = az - pos[b, 2]
        if dx * dx + dy * dy + dz * dz <= lim * lim:
            pa[n_pairs] = a
            pb[n_pairs] = b
            n_pairs += 1
    return n_pairs


@njit(cache=True)
def _add_chunks(F, Tq, Fc, Tqc, rows, count):
    """F[r] += Fc[c, r] and Tq[r] += Tqc[c, r] chunk by chunk for r in rows[:count], then
    zero those chunk rows for the next iteration (a row listed twice adds zero the second
    time)."""
    for i in range(count):
        r = rows[i]
        for c in range(Fc.shape[0]):
            for d in range(4):
                F[r, d] += Fc[c, r, d]
                Fc[c, r, d] = 0.0
            for d in range(3):
                Tq[r, d] += Tqc[c, r, d]
                Tqc[c, r, d] = 0.0


CONTACT_CHUNKS = 4  # fixed, so that a packing does not depend on the machine's core count


@njit(cache=True, parallel=True)
def contacts_parallel(pa, pb, n_pairs, wa, n_wall, typ, pos, quat, scale, margin, clearance,
                      wall_clearance, tol, radius, sph_off, sph_c, sph_r, pc_off, pcl,
                      pcl_off, box, pts, g_off, g_vals, g_shape, g_origin, g_h, c_flat,
                      c_shape, c_origin, c_h, c_pyr, c_poff, c_pshape, crease, Fc, Tqc,
                      pen_pair, pen_wall):
    """Pair contacts (pa[k], pb[k]) for k < n_pairs and wall contacts of wa[k] for
    k < n_wall in Fc.shape[0] chunks run in parallel: chunk c takes every c-th pair and
    wall test and accumulates forces in Fc[c] (N,4) and torques in Tqc[c] (N,3), so no two
    threads write the same memory. Depths go to pen_pair (n_pairs,) and pen_wall (n_wall,).
    The split is by index: the result depends neither on timing nor on the thread count."""
    nc = Fc.shape[0]
    for c in prange(nc):
        F = Fc[c]
        Tq = Tqc[c]
        for k in range(c, n_wall, nc):
            pen_wall[k] = wall_contact(wa[k], typ, pos, quat, scale, margin, wall_clearance,
                                       tol, radius, sph_off, sph_c, sph_r, pc_off, pcl,
                                       pcl_off, pts, c_flat, c_shape, c_origin, c_h, c_pyr,
                                       c_poff, c_pshape, crease, F, Tq)
        for k in range(c, n_pairs, nc):
            pen_pair[k] = pair_contact(pa[k], pb[k], typ, pos, quat, scale, margin,
                                       clearance, tol, radius, sph_off, sph_c, sph_r, pc_off,
                                       pcl, pcl_off, box, pts, g_off, g_vals, g_shape,
                                       g_origin, g_h, F, Tq)


@njit(cache=True)
def resolve(focus, state, table, cont, scratch, grid, params, max_iter, rollback, par_min,
            settle_every, max_tests):
    """Penalty-force overlap resolution starting from the objects in `focus`.

    state: (typ, pos, quat, scale, alive, margin, vel) of every inserted object; table: the
    flat type table (radius, sph_off, sph_c, sph_r, pc_off, pcl, pcl_off, box, pts, g_off,
    g_vals, g_shape, g_origin, g_h); cont: the container grid (c_vals, c_origin, c_h, c_pyr,
    c_poff, c_pshape) and its crease planes (`wall_planes.CreasePlanes.arrays`); scratch:
    `resolve_scratch(N)`, the call's working arrays, zero (or -1) where the call expects it
    and left so; grid: the cell lists of the objects
    (`cellgrid`), cells at least the largest contact reach wide, updated as objects move;
    params: (clearance, tol, k_obj, k_wall, k_rot, damping, wall_extra). See the module doc
    for the arrays. Work per iteration follows the objects in contact, not N.

    Only objects in contact move: each gets the sum of its contact forces, normalised,
    scaled by its deepest penetration times the stiffness (k_obj for object contacts, k_wall
    for the wall), added to its velocity (damped by `damping`, zeroed once free), and a
    rotation about its torque axis (k_rot). The state before the call is assumed free of
    overlaps except near `focus`, so only moved objects need re-checking.

    wall_extra is added to the wall distance each object must keep (grid error allowance).

    settle_every > 0: every settle_every iterations the call gives up (fails) unless the
    deepest penetration of the objects in contact fell below what it was settle_every
    iterations before (at the first iteration for the first check), so a long `max_iter`
    is spent on a push that is settling, not on one that jams; 0: no check.

    max_tests > 0: the call gives up (fails) once it has run that many contact tests
    without resolving; 0: no cap.

    An iteration with at least `par_min` contact tests (pairs plus walls) splits them into
    Fc.shape[0] chunks that run on numba's threads (`contacts_parallel`) and sums the
    chunks' forces in chunk order: the result does not depend on the number of threads, and
    differs from testing them one after the other only by rounding. Fc (C,>=N,4) and
    Tqc (C,>=N,3) are the chunks' zeroed scratch force and torque rows, zero again on return
    (kept by the caller, so that no call allocates C x N rows, nor the N-long arrays).

    Mutates pos, quat, vel. With `rollback`, a failed call restores every object it moved to
    its state at the call (the last overlap-free state). Returns (resolved, iterations used,
    contact tests run: the work the caller's thread tuner times, `core/threads.py`).
    """
    typ, pos, quat, scale, alive, margin, vel = state
    (radius, sph_off, sph_c, sph_r, pc_off, pcl, pcl_off, box, pts, g_off, g_vals, g_shape,
     g_origin, g_h) = table
    c_vals, c_origin, c_h, c_pyr, c_poff, c_pshape, crease = cont
    (Fc, Tqc, moved, moved_list, bpos, bquat, bvel, F, Tq, pen_obj, pen_wall, active, hit,
     act_list, hit_list, pen_w) = scratch
    clearance, tol, k_obj, k_wall, k_rot, damping, wall_extra = params
    n_moved = 0
    n_hit = 0
    c_shape = np.array(c_vals.shape, np.int64)
    c_flat = c_vals.ravel()
    n_act = 0
    for f in focus:
        if alive[f] and not active[f]:
            active[f] = 1
            act_list[n_act] = f
            n_act += 1
    # the contact tests of one iteration: pairs (pa, pb) grouped by their active object
    # in act_list order, each group after that object's wall test
    cap = 256
    pa = np.empty(cap, np.int64)
    pb = np.empty(cap, np.int64)
    pen_pair = np.empty(cap)
    tests = 0
    ok = False
    its = max_iter
    settle_ref = 0.0
    for it in range(max_iter + 1):
        n_pairs = 0
        for ii in range(n_act):
            a = act_list[ii]
            while True:
                got = cellgrid.near_pairs(a, n_pairs, pa, pb, typ, pos, scale, alive, active,
                                          margin, radius, clearance, grid)
                if got >= 0:
                    n_pairs = got
                    break
                cap *= 2  # out of room for a's pairs: grow and scan a again
                pa2 = np.empty(cap, np.int64)
                pb2 = np.empty(cap, np.int64)
                pa2[:n_pairs] = pa[:n_pairs]
                pb2[:n_pairs] = pb[:n_pairs]
                pa = pa2
                pb = pb2
                pen_pair = np.empty(cap)
        tests += n_pairs + n_act
        if n_pairs + n_act >= par_min:
            contacts_parallel(pa, pb, n_pairs, act_list, n_act, typ, pos, quat, scale,
                              margin, clearance, clearance + wall_extra, tol, radius, sph_off,
                              sph_c, sph_r, pc_off, pcl, pcl_off, box, pts, g_off, g_vals,
                              g_shape, g_origin, g_h, c_flat, c_shape, c_origin, c_h, c_pyr,
                              c_poff, c_pshape, crease, Fc, Tqc, pen_pair, pen_w)
            _add_chunks(F, Tq, Fc, Tqc, act_list, n_act)  # pa's rows are act_list's
            _add_chunks(F, Tq, Fc, Tqc, pb, n_pairs)
        else:
            kp = 0
            for ii in range(n_act):
                a = act_list[ii]
                pen_w[ii] = wall_contact(a, typ, pos, quat, scale, margin,
                                         clearance + wall_extra, tol, radius, sph_off, sph_c,
                                         sph_r, pc_off, pcl, pcl_off, pts, c_flat, c_shape,
                                         c_origin, c_h, c_pyr, c_poff, c_pshape, crease, F,
                                         Tq)
                while kp < n_pairs and pa[kp] == a:
                    pen_pair[kp] = pair_contact(a, pb[kp], typ, pos, quat, scale, margin,
                                               clearance, tol, radius, sph_off, sph_c, sph_r,
                                               pc_off, pcl, pcl_off, box, pts, g_off, g_vals,
                                               g_shape, g_origin, g_h, F, Tq)
                    kp += 1
        n_hit = 0
        kp = 0
        for ii in range(n_act):
            a = act_list[ii]
            pw = pen_w[ii]
            if pw > 0.0:
                pen_wall[a] = max(pen_wall[a], pw)
                if not hit[a]:
                    hit[a] = 1
                    hit_list[n_hit] = a
                    n_hit += 1
            while kp < n_pairs and pa[kp] == a:
                b = pb[kp]
                p = pen_pair[kp]
                kp += 1
                if p > 0.0:
                    pen_obj[a] = max(pen_obj[a], p)
                    pen_obj[b] = max(pen_obj[b], p)
                    for c in (a, b):
                        if not hit[c]:
                            hit[c] = 1
                            hit_list[n_hit] = c
                            n_hit += 1
        # objects that were active but are free now stop
        for ii in range(n_act):
            a = act_list[ii]
            active[a] = 0
            if not hit[a]:
                vel[a, 0] = 0.0
                vel[a, 1] = 0.0
                vel[a, 2] = 0.0
        if n_hit == 0:
            ok = True
            its = it
            break
        if it == max_iter or (max_tests > 0 and tests >= max_tests):
            its = it
            break
        if settle_every > 0 and it % settle_every == 0:
            deepest = 0.0  # the hit objects hold this iteration's deepest penetrations
            for ii in range(n_hit):
                a = hit_list[ii]
                deepest = max(deepest, pen_obj[a], pen_wall[a])
            if it > 0 and deepest >= settle_ref:
                its = it
                break
            settle_ref = deepest
        n_act = 0
        for ii in range(n_hit):
            a = hit_list[ii]
            if not moved[a]:
                moved[a] = 1
                moved_list[n_moved] = a
                n_moved += 1
                bpos[a] = pos[a]
                bquat[a] = quat[a]
                bvel[a] = vel[a]
            fn = np.sqrt(F[a, 0] ** 2 + F[a, 1] ** 2 + F[a, 2] ** 2)
            step = max(k_obj * pen_obj[a], k_wall * pen_wall[a])
            if fn > 1e-300:  # the paper: normalised force times stiffness * deepest penetration
                for d in range(3):
                    vel[a, d] = damping * vel[a, d] + step * F[a, d] / fn
            for d in range(3):
                pos[a, d] += vel[a, d]
            cellgrid.move(grid, a, pos[a, 0], pos[a, 1], pos[a, 2])
            tn = np.sqrt(Tq[a, 0] ** 2 + Tq[a, 1] ** 2 + Tq[a, 2] ** 2)
            if tn > 1e-300 and k_rot > 0.0:
                ang = k_rot * step / (radius[typ[a]] * scale[a])
                _rotate_quat(quat[a], Tq[a, 0] / tn, Tq[a, 1] / tn, Tq[a, 2] / tn, ang)
            F[a, 0] = 0.0
            F[a, 1] = 0.0
            F[a, 2] = 0.0
            F[a, 3] = 0.0
            Tq[a, 0] = 0.0
            Tq[a, 1] = 0.0
            Tq[a, 2] = 0.0
            pen_obj[a] = 0.0
            pen_wall[a] = 0.0
            hit[a] = 0
            active[a] = 1
            act_list[n_act] = a
            n_act += 1
    # leave the scratch as the next call expects it: the last iteration's hit objects
    # still hold their forces and flags
    for ii in range(n_hit):
        a = hit_list[ii]
        hit[a] = 0
        pen_obj[a] = 0.0
        pen_wall[a] = 0.0
        for d in range(4):
            F[a, d] = 0.0
        for d in range(3):
            Tq[a, d] = 0.0
    for ii in range(n_moved):
        a = moved_list[ii]
        moved[a] = 0
        if rollback and not ok:
            pos[a] = bpos[a]
            quat[a] = bquat[a]
            vel[a] = bvel[a]
            cellgrid.move(grid, a, pos[a, 0], pos[a, 1], pos[a, 2])
    return ok, its, tests


def resolve_scratch(n: int) -> tuple:
    """Working arrays for `resolve` on states of up to n objects, in the state it expects
    and leaves them: (Fc, Tqc, moved, moved_list, bpos, bquat, bvel, F, Tq, pen_obj,
    pen_wall, active, hit, act_list, hit_list, pen_w)."""
    return (np.zeros((CONTACT_CHUNKS, n, 4)), np.zeros((CONTACT_CHUNKS, n, 3)),
            np.zeros(n, np.uint8), np.empty(n, np.int64), np.empty((n, 3)),
            np.empty((n, 4)), np.empty((n, 3)), np.zeros((n, 4)), np.zeros((n, 3)),
            np.zeros(n), np.zeros(n), np.zeros(n, np.uint8), np.zeros(n, np.uint8),
            np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n))


@njit(cache=True)
def wall_penetrations(state, table, cont, clearance, tol, wall_extra):
    """Deepest object-wall penetration of every alive object, (N,), in time linear in the
    objects. state, table and cont as `resolve` takes them (vel unused)."""
    typ, pos, quat, scale, alive, margin, _ = state
    radius, sph_off, sph_c, sph_r, pc_off, pcl, pcl_off, _, pts = table[:9]
    c_vals, c_origin, c_h, c_pyr, c_poff, c_pshape, crease = cont
    n = typ.shape[0]
    F = np.zeros((n, 4))
    Tq = np.zeros((n, 3))
    out = np.zeros(n)
    c_shape = np.array(c_vals.shape, np.int64)
    c_flat = c_vals.ravel()
    for a in range(n):
        if alive[a]:
            out[a] = wall_contact(a, typ, pos, quat, scale, margin, clearance + wall_extra,
                                  tol, radius, sph_off, sph_c, sph_r, pc_off, pcl, pcl_off,
                                  pts, c_flat, c_shape, c_origin, c_h, c_pyr, c_poff,
                                  c_pshape, crease, F, Tq)
    return out


@njit(cache=True)
def max_penetrations(state, table, cont, clearance, tol, wall_extra):
    """Deepest object-object and object-wall penetration (`wall_penetrations`) of every
    alive object, (N,2). state, table and cont as `resolve` takes them (vel unused)."""
    typ, pos, quat, scale, alive, margin, _ = state
    (radius, sph_off, sph_c, sph_r, pc_off, pcl, pcl_off, box, pts, g_off, g_vals, g_shape,
     g_origin, g_h) = table
    n = typ.shape[0]
    F = np.zeros((n, 4))
    Tq = np.zeros((n, 3))
    out = np.zeros((n, 2))
    out[:, 1] = wall_penetrations(state, table, cont, clearance, tol, wall_extra)
    for a in range(n):
        if not alive[a]:
            continue
        ra = radius[typ[a]] * scale[a]
        for b in range(a + 1, n):
            if not alive[b]:
                continue
            lim = ra + radius[typ[b]] * scale[b] + clearance + margin[a] + margin[b]
            dx = pos[a, 0] - pos[b, 0]
            dy = pos[a, 1] - pos[b, 1]
            dz = pos[a, 2] - pos[b, 2]
            if dx * dx + dy * dy + dz * dz > lim * lim:
                continue
            p = pair_contact(a, b, typ, pos, quat, scale, margin, clearance, tol, radius,
                             sph_off, sph_c, sph_r, pc_off, pcl, pcl_off, box, pts, g_off,
                             g_vals, g_shape, g_origin, g_h, F, Tq)
            out[a, 0] = max(out[a, 0], p)
            out[b, 0] = max(out[b, 0], p)
    return out


@njit(cache=True)
def free_distance(px, py, pz, typ, pos, quat, scale, alive, radius, g_off, g_vals, g_shape,
                  g_origin, g_h, c_vals, c_origin, c_h, crease):
    """Distance from a point to the nearest alive object's surface or the container wall
    (`wall_depth`).

    Negative if the point is inside an object or outside the container.
    """
    nx_, ny_, nz_ = c_vals.shape
    w_index, w_off, w_ids, w_planes, w_reach = crease
    best, _, _, _ = wall_depth(c_vals.ravel(), nx_, ny_, nz_, c_origin, c_h, w_index, w_off,
                               w_ids, w_planes, w_reach, px, py, pz)
    for b in range(typ.shape[0]):
        if alive[b]:
            best = _object_distance(px, py, pz, b, best, typ, pos, quat, scale, radius, g_off,
                                    g_vals, g_shape, g_origin, g_h)
    return best


@njit(cache=True)
def free_distances(points, typ, pos, quat, scale, alive, radius, g_off, g_vals, g_shape,
                   g_origin, g_h, c_vals, c_origin, c_h, crease):
    """`free_distance` for many points (M,3) -> (M,), every object tested (the reference
    of `free_distances_near`)."""
    out = np.empty(points.shape[0])
    for m in range(points.shape[0]):
        out[m] = free_distance(points[m, 0], points[m, 1], points[m, 2], typ, pos, quat, scale,
                               alive, radius, g_off, g_vals, g_shape, g_origin, g_h, c_vals,
                               c_origin, c_h, crease)
    return out


@njit(cache=True)
def _object_distance(px, py, pz, b, best, typ, pos, quat, scale, radius, g_off, g_vals,
                     g_shape, g_origin, g_h):
    """min(best, distance from the point to object b's surface), as `free_distance`."""
    rx = px - pos[b, 0]
    ry = py - pos[b, 1]
    rz = pz - pos[b, 2]
    dc = np.sqrt(rx * rx + ry * ry + rz * rz)
    rb = radius[typ[b]] * scale[b]
    if dc - rb >= best:
        return best
    R = quat_to_rot(quat[b])
    sb = scale[b]
    qx = (R[0, 0] * rx + R[1, 0] * ry + R[2, 0] * rz) / sb
    qy = (R[0, 1] * rx + R[1, 1] * ry + R[2, 1] * rz) / sb
    qz = (R[0, 2] * rx + R[1, 2] * ry + R[2, 2] * rz) / sb
    d, _, _, _ = sample_type_grid(g_vals, g_off, g_shape, g_origin, g_h, typ[b], qx, qy, qz)
    d = max(-d * sb, dc - rb)
    return min(d, best)


@njit(cache=True)
def _cell_distances(px, py, pz, c, best, grid, typ, pos, quat, scale, alive, radius, g_off,
                    g_vals, g_shape, g_origin, g_h):
    """min(best, distance to each alive object in cell c); unlinks removed objects met."""
    _, _, _, head, nxt, _, _ = grid
    b = head[c]
    while b >= 0:
        nb = nxt[b]
        if not alive[b]:
            cellgrid.unlink(grid, b)
        else:
            best = _object_distance(px, py, pz, b, best, typ, pos, quat, scale, radius, g_off,
                                    g_vals, g_shape, g_origin, g_h)
        b = nb
    return best


@njit(cache=True)
def _free_distance_near(px, py, pz, floor, grid, typ, pos, quat, scale, alive, radius, r_max,
                        g_off, g_vals, g_shape, g_origin, g_h, c_flat, c_shape, c_origin, c_h,
                        crease):
    """`free_distances_near` for one point; r_max: the largest bounding radius."""
    origin, hs, dims, _, _, _, _ = grid
    h = hs[0]
    w_index, w_off, w_ids, w_planes, w_reach = crease
    best, _, _, _ = wall_depth(c_flat, c_shape[0], c_shape[1], c_shape[2], c_origin, c_h,
                               w_index, w_off, w_ids, w_planes, w_reach, px, py, pz)
    if best < floor:
        return best
    ci = min(max(int(np.floor((px - origin[0]) / h)), 0), dims[0] - 1)
    cj = min(max(int(np.floor((py - origin[1]) / h)), 0), dims[1] - 1)
    ck = min(max(int(np.floor((pz - origin[2]) / h)), 0), dims[2] - 1)
    for r in range(max(dims[0], max(dims[1], dims[2]))):
        if (r - 1) * h - r_max >= best:
            break
        for i in range(max(ci - r, 0), min(ci + r + 1, dims[0])):
            edge_i = i == ci - r or i == ci + r
            for j in range(max(cj - r, 0), min(cj + r + 1, dims[1])):
                if edge_i or j == cj - r or j == cj + r:
                    k_step = 1
                    k_lo = max(ck - r, 0)
                    k_hi = min(ck + r + 1, dims[2])
                else:  # inside the shell's faces in i and j: only its two k faces
                    k_step = 2 * r
                    k_lo = ck - r
                    k_hi = ck + r + 1
                for k in range(k_lo, k_hi, k_step):
                    if k < 0 or k >= dims[2]:
                        continue
                    best = _cell_distances(px, py, pz, (i * dims[1] + j) * dims[2] + k, best,
                                           grid, typ, pos, quat, scale, alive, radius, g_off,
                                           g_vals, g_shape, g_origin, g_h)
                    if best < floor:
                        return best
    return best


@njit(cache=True)
def free_distances_near(points, floor, grid, typ, pos, quat, scale, alive, radius, g_off,
                        g_vals, g_shape, g_origin, g_h, c_vals, c_origin, c_h, crease):
    """`free_distances` through the cell grid (`cellgrid`): for each point (M,3), cells in
    shells of growing Chebyshev distance r from its cell, until no object centre beyond
    shell r (at least (r - 1) h away) can come nearer than the best distance so far. Equal
    to `free_distances` where that is at least `floor`; elsewhere some value below `floor`
    (the search stops at the first one: a phase that keeps only points with room >= floor
    needs no more, and most points of its lattice lie inside objects). floor = -inf: equal
    everywhere (a minimum does not depend on the order of its terms)."""
    c_shape = np.array(c_vals.shape, np.int64)
    c_flat = c_vals.ravel()
    r_max = radius.max()
    out = np.empty(points.shape[0])
    for m in range(points.shape[0]):
        out[m] = _free_distance_near(points[m, 0], points[m, 1], points[m, 2], floor, grid,
                                     typ, pos, quat, scale, alive, radius, r_max, g_off,
                                     g_vals, g_shape, g_origin, g_h, c_flat, c_shape, c_origin,
                                     c_h, crease)
    return out
