"""Tests for jampacked.core.kernels (and core.spheres) against plain numpy references.

House rule: every numba kernel is compared with a numpy reference on seeded random inputs.
Frames: object k maps local x to R(q_k) * s_k * x + p_k in the container frame; signed
distances are positive inside. Kernels are called by parameter name (see `call`) with the
flat arrays of `solver.TypeTable` / `solver.PackState`, so argument reordering or additions
with known names do not break the tests.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest
import trimesh
from testdata import mesh_path

from jampacked.core import cellgrid, kernels, solver
from jampacked.core.container import Container, build_container
from jampacked.core.distance import DistanceGrid, distance_grid, min_pyramid
from jampacked.core.objects import build_type, point_clusters
from jampacked.core.rotations import quat_to_matrix
from jampacked.core.spheres import inner_spheres, sphere_coverage
from jampacked.core.wall_planes import no_creases

HALF_CONTAINER = 15.0  # the container is the box |x_i| <= 15

# ---------------------------------------------------------------- numpy references


def quat_to_rot_ref(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w,x,y,z) via v -> q v q* (Hamilton product)."""

    def mul(p, r):
        w1, x1, y1, z1 = p
        w2, x2, y2, z2 = r
        return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                         w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                         w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                         w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])

    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    cols = [mul(mul(q, np.r_[0.0, e]), conj)[1:] for e in np.eye(3)]
    return np.stack(cols, axis=1)


def trilinear_ref(vals3: np.ndarray, origin: np.ndarray, h: float, pts: np.ndarray):
    """Trilinear value (M,) and gradient (M,3) of a grid at points (M,3).

    Outside the box: value at the clamped point minus the distance to the box, gradient the
    unit vector pointing back to the box (matching `kernels.trilinear`'s contract).
    """
    n = np.array(vals3.shape)
    f = (pts - origin) / h
    c = np.clip(f, 0.0, n - 1.0)
    i = np.minimum(np.floor(c).astype(np.int64), n - 2)
    t = c - i
    value = np.zeros(len(pts))
    grad = np.zeros((len(pts), 3))
    for corner in np.ndindex(2, 2, 2):
        cv = np.asarray(corner)
        v = vals3[i[:, 0] + cv[0], i[:, 1] + cv[1], i[:, 2] + cv[2]]
        w = np.where(cv == 1, t, 1.0 - t)  # (M,3) per-axis weights
        dw = np.where(cv == 1, 1.0, -1.0)  # d weight / d t per axis
        value += v * w.prod(axis=1)
        for ax in range(3):
            others = np.delete(w, ax, axis=1).prod(axis=1)
            grad[:, ax] += v * dw[ax] * others / h
    e = (f - c) * h
    en = np.linalg.norm(e, axis=1)
    out = en > 0
    value = value - en
    grad[out] = -e[out] / en[out, None]
    return value, grad


def type_grids(table: solver.TypeTable) -> list[np.ndarray]:
    """Per-type 3D grids unflattened from the type table."""
    return [table.g_vals[table.g_off[t]:table.g_off[t + 1]].reshape(table.g_shape[t])
            for t in range(len(table.g_h))]


def point_range(table, t) -> slice:
    """Rows of type t's surface points in table.pts: its clusters' points."""
    return slice(int(table.pcl_off[table.pc_off[t]]), int(table.pcl_off[table.pc_off[t + 1]]))


def posed(table, t, kind, R, s, p):
    """Type t's spheres ('sph': centres, radii) or surface points ('pts') in the container
    frame, and their offsets from the object's centre."""
    if kind == "sph":
        loc = table.sph_c[table.sph_off[t]:table.sph_off[t + 1]]
        rad = table.sph_r[table.sph_off[t]:table.sph_off[t + 1]] * s
    else:
        loc = table.pts[point_range(table, t)]
        rad = None
    off = loc @ R.T * s
    return off + p, off, rad


def pair_contact_ref(a, b, table, grids, typ, pos, quat, scale, margin, clearance, tol):
    """Deepest penetration of objects a and b, and the forces/torques pair_contact adds.

    Sphere pairs: pen = ra + rb + delta - |ca - cb|, pushing a along (ca - cb).
    Surface points of one object in the other's grid: pen = d * s_other + delta, pushing the
    point out along the other's outward normal. Each contact adds w = pen^2 times its unit
    direction to F[.,:3] (opposite for the other object), pen to F[.,3], and the torque of
    that force about each object's centre. No pruning: every pair and point is evaluated.
    """
    n = len(typ)
    F = np.zeros((n, 4))
    Tq = np.zeros((n, 3))
    delta = clearance + margin[a] + margin[b]
    R = {k: quat_to_rot_ref(quat[k]) for k in (a, b)}
    worst = 0.0
    ca, ua, ra = posed(table, typ[a], "sph", R[a], scale[a], pos[a])
    cb, vb, rb = posed(table, typ[b], "sph", R[b], scale[b], pos[b])
    diff = ca[:, None, :] - cb[None, :, :]
    dist = np.linalg.norm(diff, axis=2)
    pen = ra[:, None] + rb[None, :] + delta - dist
    for iu, iv in zip(*np.nonzero(pen > tol), strict=True):
        p = pen[iu, iv]
        nrm = diff[iu, iv] / dist[iu, iv] if dist[iu, iv] > 1e-12 else np.array([1.0, 0, 0])
        f = p * p * nrm
        F[a, :3] += f
        F[b, :3] -= f
        F[a, 3] += p
        F[b, 3] += p
        Tq[a] += np.cross(ua[iu], f)
        Tq[b] -= np.cross(vb[iv], f)
        worst = max(worst, p)
    for x, y in ((a, b), (b, a)):
        wp, w_off, _ = posed(table, typ[x], "pts", R[x], scale[x], pos[x])
        r = wp - pos[y]
        local = r @ R[y] / scale[y]
        d, g = trilinear_ref(grids[typ[y]], table.g_origin[typ[y]], table.g_h[typ[y]], local)
        pen = d * scale[y] + delta
        for m in np.flatnonzero(pen > tol):
            p = pen[m]
            nrm = -(R[y] @ g[m])
            if np.linalg.norm(nrm) < 1e-12:
                nrm = pos[x] - pos[y]
            nrm = nrm / np.linalg.norm(nrm)
            f = p * p * nrm
            F[x, :3] += f
            F[y, :3] -= f
            F[x, 3] += p
            F[y, 3] += p
            Tq[x] += np.cross(w_off[m], f)
            Tq[y] -= np.cross(r[m], f)
            worst = max(worst, p)
    return worst, F, Tq


def wall_depth_ref(container, pts: np.ndarray):
    """The wall depth (M,) and gradient (M,3) at points (M,3): the grid's interpolant, or in
    a crease cell whose planes read more and some room (where the grid reads between -1
    cell and their reach), the least of its planes' depths, at most the reach; the
    gradient is the grid's everywhere."""
    g, cp = container.grid, container.creases
    d, grad = trilinear_ref(g.values, g.origin, g.spacing, pts)
    n = np.array(g.values.shape)
    f = (pts - g.origin) / g.spacing
    for m in range(len(pts)):
        if not (-g.spacing < d[m] < cp.reach) or (f[m] < 0).any() or (f[m] > n - 1).any():
            continue
        i, j, k = np.minimum(f[m].astype(np.int64), n - 2)
        at = np.flatnonzero(cp.cells == (i * (n[1] - 1) + j) * (n[2] - 1) + k)
        if not len(at):
            continue
        planes = cp.planes[cp.ids[cp.offsets[at[0]]:cp.offsets[at[0] + 1]]]
        depth = planes[:, :3] @ pts[m] + planes[:, 3]
        best = min(float(depth.min()), cp.reach)
        if best > max(d[m], 0.0):
            d[m] = best
    return d, grad


def wall_contact_ref(a, table, container, typ, pos, quat, scale, margin, clearance, tol):
    """Deepest wall penetration of object a and its forces/torque (see pair_contact_ref)."""
    n = len(typ)
    F = np.zeros((n, 4))
    Tq = np.zeros((n, 3))
    delta = clearance + margin[a]
    R = quat_to_rot_ref(quat[a])
    worst = 0.0
    for kind in ("sph", "pts"):
        world, off, rad = posed(table, typ[a], kind, R, scale[a], pos[a])
        d, g = wall_depth_ref(container, world)
        pen = (rad if rad is not None else 0.0) + delta - d
        for m in np.flatnonzero(pen > tol):
            p = pen[m]
            f = p * p * g[m] / np.linalg.norm(g[m])
            F[a, :3] += f
            F[a, 3] += p
            Tq[a] += np.cross(off[m], f)
            worst = max(worst, p)
    return worst, F, Tq


def free_distance_ref(points, table, grids, container, typ, pos, quat, scale, alive):
    """Distance to the nearest alive object (its grid, bounded below by its bounding sphere)
    or the container wall (`wall_depth_ref`); negative inside an object or outside the
    container."""
    best, _ = wall_depth_ref(container, points)
    for b in np.flatnonzero(alive):
        t = typ[b]
        R = quat_to_rot_ref(quat[b])
        r = points - pos[b]
        d, _ = trilinear_ref(grids[t], table.g_origin[t], table.g_h[t], r @ R / scale[b])
        bound = np.linalg.norm(r, axis=1) - table.radius[t] * scale[b]
        best = np.minimum(best, np.maximum(-d * scale[b], bound))
    return best


def rotate_quat_ref(q, axis, angle):
    """Left-multiply q by the rotation (axis, angle) and renormalise."""
    r = np.r_[np.cos(angle / 2), np.sin(angle / 2) * np.asarray(axis)]
    w1, x1, y1, z1 = r
    w2, x2, y2, z2 = q
    out = np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                    w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                    w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                    w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])
    return out / np.linalg.norm(out)


def random_quats(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# ---------------------------------------------------------------- fixtures and helpers


@pytest.fixture(scope="module")
def types():
    """Two small object types (local frame, extents about 4): a convex polytope and a box."""
    out = []
    m = trimesh.load(mesh_path("polyhedra/convex5/polytope1.obj"), force="mesh")
    out.append(build_type("poly", m.vertices, m.faces, path=None, sha256=None, share=0.5,
                          type_scale=4.0 / m.extents.max(), fidelity="low", use_cache=False))
    b = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    out.append(build_type("box", b.vertices, b.faces, path=None, sha256=None, share=0.5,
                          fidelity="low", use_cache=False))
    return out


@pytest.fixture(scope="module")
def table(types):
    return solver.TypeTable(types)


@pytest.fixture(scope="module")
def container():
    b = trimesh.creation.box(extents=(2 * HALF_CONTAINER,) * 3)
    return build_container(b.vertices, b.faces, float(b.volume), 1.0)


def make_state(typ, pos, quat, scale=None, margin=None) -> solver.PackState:
    s = solver.PackState(capacity=max(4, len(typ)))
    n = len(typ)
    scale = np.ones(n) if scale is None else scale
    margin = np.zeros(n) if margin is None else margin
    for k in range(n):
        s.add(int(typ[k]), pos[k], quat[k], float(scale[k]), float(margin[k]))
    return s


def env_for(table, container, state, clearance=0.0, tol=1e-6) -> dict:
    """Every array a kernel may ask for, by its parameter name."""
    typ, pos, quat, scale, alive, margin, vel = state.view()
    g = container.grid
    env = dict(typ=typ, pos=pos, quat=quat, scale=scale, alive=alive, margin=margin, vel=vel,
               clearance=clearance, tol=tol, c_vals=g.values, c_origin=g.origin,
               c_h=g.spacing, c_shape=np.array(g.values.shape, np.int64),
               c_pyr=container.pyramid[0], c_poff=container.pyramid[1],
               c_pshape=container.pyramid[2], crease=container.creases.arrays(),
               F=np.zeros((len(typ), 4)), Tq=np.zeros((len(typ), 3)))
    for name in ("radius", "sph_off", "sph_c", "sph_r", "pc_off", "pcl", "pcl_off", "box", "pts",
                 "g_off", "g_vals", "g_shape", "g_origin", "g_h"):
        env[name] = getattr(table, name)
    return env


def call(kernel, env: dict, **override):
    """Call a numba kernel with arguments looked up by its parameter names."""
    names = inspect.signature(kernel.py_func).parameters
    merged = {**env, **override}
    missing = [n for n in names if n not in merged]
    assert not missing, f"test helper does not know kernel arguments {missing}"
    return kernel(*(merged[n] for n in names))


def wall_matches_reference(table, container, state, clearance, tol, torque=True):
    """wall_contact of object 0 against the numpy reference (depth, forces and, with
    `torque`, torques); returns (depth, env) for further checks."""
    typ, pos, quat, scale, _, margin, _ = state.view()
    env = env_for(table, container, state, clearance, tol)
    worst = call(kernels.wall_contact, env, a=0, c_vals=container.grid.values.ravel())
    ref, F_ref, T_ref = wall_contact_ref(0, table, container, typ, pos, quat, scale,
                                         margin, clearance, tol)
    assert worst == pytest.approx(ref, rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(env["F"], F_ref, rtol=1e-10, atol=1e-12)
    if torque:
        np.testing.assert_allclose(env["Tq"], T_ref, rtol=1e-10, atol=1e-12)
    return worst, env


def pair_scene(rng, table, n_pairs: int, overlap: bool):
    """Random poses of two objects (types 0/1 mixed), overlapping or far apart."""
    for _ in range(n_pairs):
        typ = rng.integers(0, 2, 2)
        quat = random_quats(rng, 2)
        scale = rng.uniform(0.5, 1.0, 2)
        margin = rng.uniform(0.0, 0.05, 2)
        reach = table.radius[typ] * scale
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        gap = rng.uniform(0.2, 0.7) if overlap else rng.uniform(1.1, 3.0)
        pos = np.array([[0.0, 0, 0], d * gap * reach.sum()]) + rng.normal(size=3)
        yield typ, pos, quat, scale, margin


# ---------------------------------------------------------------- quaternions


def test_quat_to_rot_matches_reference_and_packing():
    rng = np.random.default_rng(0)
    qs = random_quats(rng, 200)
    qs[:4] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    mats = quat_to_matrix(qs)
    for q, m in zip(qs, mats, strict=True):
        r = kernels.quat_to_rot(q)
        np.testing.assert_allclose(r, quat_to_rot_ref(q), rtol=0, atol=1e-14)
        np.testing.assert_allclose(r, m, rtol=0, atol=1e-14)
        np.testing.assert_allclose(r @ r.T, np.eye(3), rtol=0, atol=1e-14)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-14)
        np.testing.assert_allclose(kernels.quat_to_rot(-q), r, rtol=0, atol=1e-15)


def test_rotate_quat_matches_reference():
    rng = np.random.default_rng(1)
    for q in random_quats(rng, 100):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = rng.uniform(-np.pi, np.pi)
        got = q.copy()
        kernels._rotate_quat(got, axis[0], axis[1], axis[2], angle)
        np.testing.assert_allclose(got, rotate_quat_ref(q, axis, angle), rtol=0, atol=1e-14)
        # as a matrix: rotation(axis, angle) applied after q
        c, s = np.cos(angle), np.sin(angle)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        rod = np.eye(3) + s * k + (1 - c) * k @ k
        np.testing.assert_allclose(kernels.quat_to_rot(got), rod @ kernels.quat_to_rot(q),
                                   rtol=0, atol=1e-13)


# ---------------------------------------------------------------- grid sampling


def _random_grid(rng):
    shape = tuple(rng.integers(2, 9, 3))
    vals = rng.normal(size=shape)
    origin = rng.normal(size=3)
    h = rng.uniform(0.2, 1.5)
    return vals, origin, h


def _kernel_trilinear(vals, origin, h, pts, off=0):
    flat = np.concatenate([np.full(off, np.nan), vals.ravel()])  # a type at offset `off`
    nx, ny, nz = vals.shape
    out = np.array([kernels.trilinear(flat, off, nx, ny, nz, origin[0], origin[1], origin[2],
                                      h, p[0], p[1], p[2]) for p in pts])
    return out[:, 0], out[:, 1:]


@pytest.mark.parametrize("seed", range(4))
def test_trilinear_matches_reference_inside(seed):
    rng = np.random.default_rng(seed)
    vals, origin, h = _random_grid(rng)
    size = (np.array(vals.shape) - 1) * h
    pts = origin + rng.random((500, 3)) * size
    # include exact nodes, the far faces and the far corner of the box
    pts[:3] = origin
    pts[3] = origin + size
    pts[4] = origin + size * np.array([1.0, 0.5, 0.0])
    d, g = _kernel_trilinear(vals, origin, h, pts, off=int(rng.integers(0, 7)))
    d_ref, g_ref = trilinear_ref(vals, origin, h, pts)
    np.testing.assert_allclose(d, d_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g, g_ref, rtol=0, atol=1e-11)
    # nodes are reproduced exactly
    node = rng.integers(0, vals.shape, size=(50, 3))
    dn, _ = _kernel_trilinear(vals, origin, h, origin + node * h)
    np.testing.assert_allclose(dn, vals[node[:, 0], node[:, 1], node[:, 2]], rtol=0,
                               atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_trilinear_gradient_matches_finite_differences(seed):
    rng = np.random.default_rng(10 + seed)
    vals, origin, h = _random_grid(rng)
    n = np.array(vals.shape)
    cells = rng.integers(0, n - 1, size=(300, 3))
    frac = rng.uniform(0.05, 0.95, size=(300, 3))  # away from cell faces
    pts = origin + (cells + frac) * h
    _, g = _kernel_trilinear(vals, origin, h, pts)
    eps = 1e-6 * h
    fd = np.empty_like(g)
    for ax in range(3):
        step = np.zeros(3)
        step[ax] = eps
        fd[:, ax] = (trilinear_ref(vals, origin, h, pts + step)[0]
                     - trilinear_ref(vals, origin, h, pts - step)[0]) / (2 * eps)
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("seed", range(3))
def test_trilinear_outside_the_box(seed):
    rng = np.random.default_rng(20 + seed)
    vals, origin, h = _random_grid(rng)
    size = (np.array(vals.shape) - 1) * h
    inner = origin + rng.random((300, 3)) * size
    inner[:50] = origin + np.round(rng.random((50, 3))) * size  # box corners
    direction = rng.normal(size=(300, 3))
    # push along directions that leave the box from `inner` projected onto its surface
    outer = inner + direction * rng.uniform(0.1, 3.0, (300, 1))
    clamped = np.clip(outer, origin, origin + size)
    dist = np.linalg.norm(outer - clamped, axis=1)
    keep = dist > 1e-9
    outer, clamped, dist = outer[keep], clamped[keep], dist[keep]
    d_out, g_out = _kernel_trilinear(vals, origin, h, outer)
    d_in, _ = _kernel_trilinear(vals, origin, h, clamped)
    np.testing.assert_allclose(d_out, d_in - dist, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g_out, -(outer - clamped) / dist[:, None], rtol=0, atol=1e-12)
    d_ref, g_ref = trilinear_ref(vals, origin, h, outer)
    np.testing.assert_allclose(d_out, d_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g_out, g_ref, rtol=0, atol=1e-12)
    # stepping further out lowers the value by exactly the extra distance
    d_far, _ = _kernel_trilinear(vals, origin, h, outer + (outer - clamped))
    np.testing.assert_allclose(d_far, d_out - dist, rtol=0, atol=1e-12)


def test_sample_grid_many_matches_reference():
    rng = np.random.default_rng(30)
    for _ in range(3):
        vals, origin, h = _random_grid(rng)
        size = (np.array(vals.shape) - 1) * h
        pts = origin - size + rng.random((400, 3)) * 3 * size  # inside and outside
        got = kernels.sample_grid_many(vals, origin, h, pts)
        np.testing.assert_allclose(got, trilinear_ref(vals, origin, h, pts)[0], rtol=0,
                                   atol=1e-12)


def test_free_distances_match_reference(table, container):
    rng = np.random.default_rng(40)
    n = 8
    typ = rng.integers(0, 2, n)
    pos = rng.uniform(-12, 12, (n, 3))
    quat = random_quats(rng, n)
    scale = rng.uniform(0.3, 1.0, n)
    state = make_state(typ, pos, quat, scale)
    state.alive[2] = 0  # a removed object is ignored
    points = np.concatenate([rng.uniform(-17, 17, (400, 3)),  # some outside the container
                             (pos[:, None, :] + rng.normal(size=(n, 50, 3))).reshape(-1, 3)])
    sv = solver.Solver(container, table, state, solver.SolverParams())
    got = sv.free_distances(points)
    ref = free_distance_ref(points, table, type_grids(table), container, *state.view()[:3],
                            state.scale[:n], state.alive[:n])
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
    assert (got < 0).any() and (got > 0).any()
    env = env_for(table, container, state)
    for m in range(0, len(points), 97):
        single = call(kernels.free_distance, env, px=points[m, 0], py=points[m, 1],
                      pz=points[m, 2])
        assert single == got[m]
    # with a clearance the room is the distance less the clearance (to objects and wall)
    sv_c = solver.Solver(container, table, state, solver.SolverParams(clearance=0.3))
    np.testing.assert_allclose(sv_c.free_distances(points), ref - 0.3, rtol=0, atol=1e-9)


# ---------------------------------------------------------------- contacts


@pytest.mark.parametrize("seed", range(3))
def test_pair_contact_matches_reference(table, container, seed):
    rng = np.random.default_rng(50 + seed)
    grids = type_grids(table)
    clearance, tol = 0.02, 1e-6
    found = 0
    for typ, pos, quat, scale, margin in pair_scene(rng, table, 12, overlap=True):
        worst, env = pair_matches_reference(table, container, grids, typ, pos, quat, scale,
                                            margin, clearance, tol)
        F = env["F"]
        # equal and opposite pushes on the two objects
        np.testing.assert_allclose(F[0, :3], -F[1, :3], rtol=0, atol=1e-12)
        found += worst > 0
        # the same contact seen from b
        env2 = env_for(table, container, make_state(typ, pos, quat, scale, margin),
                       clearance, tol)
        assert call(kernels.pair_contact, env2, a=1, b=0) == pytest.approx(worst, abs=1e-12)
        np.testing.assert_allclose(env2["F"], F, rtol=1e-10, atol=1e-12)
    assert found >= 8


def test_pair_contact_matches_reference_at_grazing_distances(table, container):
    # centres between 0.55 and 1.0 of the bounding radii apart: the contacts are at the
    # objects' tips, where skipping point clusters and points outside the other's box must
    # change nothing
    rng = np.random.default_rng(65)
    grids = type_grids(table)
    found = 0
    for _ in range(150):
        typ = rng.integers(0, 2, 2)
        quat = random_quats(rng, 2)
        scale = np.ones(2)
        margin = np.zeros(2)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        pos = np.array([[0.0, 0, 0], d * rng.uniform(0.55, 1.0) * table.radius[typ].sum()])
        found += pair_matches_reference(table, container, grids, typ, pos, quat, scale,
                                        margin, 0.0, 1e-9)[0] > 0
    assert found >= 30


def pair_matches_reference(table, container, grids, typ, pos, quat, scale, margin,
                           clearance, tol) -> tuple[float, dict]:
    """pair_contact of objects 0 and 1 against the numpy reference (depth, forces,
    torques); returns the depth and the kernel's arguments (with its forces)."""
    state = make_state(typ, pos, quat, scale, margin)
    env = env_for(table, container, state, clearance, tol)
    worst = call(kernels.pair_contact, env, a=0, b=1)
    ref, F_ref, T_ref = pair_contact_ref(0, 1, table, grids, typ, pos, quat, scale, margin,
                                         clearance, tol)
    assert worst == pytest.approx(ref, rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(env["F"], F_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(env["Tq"], T_ref, rtol=1e-10, atol=1e-12)
    return worst, env


def boxes_gap_ref(Ra, ca, ea, Rb, cb, eb) -> float:
    """The largest gap between two oriented boxes' projections over the 15 separating axes,
    normalised (numpy reference for `kernels.boxes_apart`): a lower bound of their distance,
    and positive only if they are apart."""
    corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    pa = ca + (corners * ea) @ Ra.T
    pb = cb + (corners * eb) @ Rb.T
    axes = [Ra[:, i] for i in range(3)] + [Rb[:, j] for j in range(3)]
    axes += [np.cross(Ra[:, i], Rb[:, j]) for i in range(3) for j in range(3)]
    best = -np.inf
    for ax in axes:
        n = np.linalg.norm(ax)
        if n < 1e-6:
            continue
        u, v = pa @ (ax / n), pb @ (ax / n)
        best = max(best, u.min() - v.max(), v.min() - u.max())
    return best


def test_boxes_apart_matches_reference():
    rng = np.random.default_rng(66)
    apart = near = 0
    for _ in range(3000):
        Ra, Rb = quat_to_matrix(random_quats(rng, 2))
        ea, eb = rng.uniform(0.1, 3.0, (2, 3))
        ca, cb = rng.normal(size=(2, 3)) * 3.0
        gap = rng.uniform(0.0, 0.5)
        got = kernels.boxes_apart(Ra, *ca, ea, Rb, *cb, eb, gap)
        ref = boxes_gap_ref(Ra, ca, ea, Rb, cb, eb)
        if got:  # never apart when the boxes come within the gap
            assert ref > gap
            apart += 1
        elif ref > 1.8 * gap + 1e-6:
            # its cross axes are not normalised (|a x b| >= sin 45 deg makes gap/0.7 at
            # most), so it misses only separations near the gap on cross axes
            n = [np.linalg.norm(np.cross(Ra[:, i], Rb[:, j])) for i in range(3) for j in range(3)]
            assert min(n) < 0.56, (ref, gap)
        near += ref <= gap
    assert apart > 500 and near > 500
    # face to face along an axis: apart just beyond the gap, not at it
    R = np.eye(3)
    e = np.ones(3)
    assert kernels.boxes_apart(R, 0.0, 0, 0, e, R, 2.5 + 1e-6, 0, 0, e, 0.5)
    assert not kernels.boxes_apart(R, 0.0, 0, 0, e, R, 2.5 - 1e-6, 0, 0, e, 0.5)


def test_pair_contact_box_test_skips_pairs_and_changes_nothing(table, container):
    # elongated configurations whose bounding spheres meet: the pairs the box test ends
    # early, checked against the reference, which has no such test
    rng = np.random.default_rng(67)
    grids = type_grids(table)
    skipped = touching = 0
    for _ in range(300):
        typ = np.array([1, 1])  # the 2 x 3 x 4 box type
        quat = random_quats(rng, 2)
        scale = rng.uniform(0.5, 1.0, 2)
        margin = rng.uniform(0.0, 0.05, 2)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        reach = (table.radius[typ] * scale).sum()
        pos = np.array([[0.0, 0, 0], d * rng.uniform(0.4, 1.0) * reach])
        worst, _ = pair_matches_reference(table, container, grids, typ, pos, quat, scale,
                                          margin, 0.01, 1e-9)
        R = quat_to_matrix(quat)
        boxes = [kernels._hull_box(table.box, 1, scale[k], R[k], *pos[k]) for k in range(2)]
        skipped += kernels.boxes_apart(R[0], *boxes[0], R[1], *boxes[1], 0.01 + margin.sum())
        touching += worst > 0
    assert skipped > 30 and touching > 30


@pytest.mark.parametrize("n", [1, 16, 17, 96, 384, 1000])
def test_point_clusters_list_every_point_once_inside_its_ball(n):
    pts = np.random.default_rng(n).normal(size=(n, 3)) * [3.0, 1.0, 0.5]
    order, balls, sizes = point_clusters(pts, leaf=16)
    assert sorted(order.tolist()) == list(range(n))
    assert sizes.sum() == n and sizes.max() <= 16 and sizes.min() >= 1
    start = np.concatenate([[0], np.cumsum(sizes)])
    for c in range(len(sizes)):
        q = pts[order[start[c]:start[c + 1]]]
        assert np.linalg.norm(q - balls[c, :3], axis=1).max() <= balls[c, 3] + 1e-12
    # halving keeps clusters compact: their balls are much smaller than the cloud
    if n >= 96:
        assert np.median(balls[:, 3]) < 0.5 * np.ptp(pts, axis=0).max() / 2


def test_type_table_clusters_index_each_types_points(table, types):
    for t, typ in enumerate(types):
        span = point_range(table, t)
        mine = table.pts[span]
        # the same points, reordered cluster by cluster
        np.testing.assert_array_equal(np.unique(mine, axis=0),
                                      np.unique(typ.surface_points, axis=0))
        for c in range(table.pc_off[t], table.pc_off[t + 1]):
            q = table.pts[table.pcl_off[c]:table.pcl_off[c + 1]]
            assert span.start <= table.pcl_off[c] < table.pcl_off[c + 1] <= span.stop
            assert np.linalg.norm(q - table.pcl[c, :3], axis=1).max() <= table.pcl[c, 3] + 1e-12
        np.testing.assert_allclose(table.box[t, :3], typ.vertices.min(axis=0))
        np.testing.assert_allclose(table.box[t, 3:6], typ.vertices.max(axis=0))
        # the contact box holds everything a contact test reads
        centre, half = table.box[t, 6:9], table.box[t, 9:12]
        r = typ.sphere_radii[:, None]
        for q in (typ.vertices, typ.surface_points, typ.sphere_centres - r,
                  typ.sphere_centres + r):
            assert np.all(np.abs(q - centre) <= half + 1e-12)


def test_pair_contact_far_apart_is_zero(table, container):
    rng = np.random.default_rng(60)
    for typ, pos, quat, scale, margin in pair_scene(rng, table, 10, overlap=False):
        state = make_state(typ, pos, quat, scale, margin)
        env = env_for(table, container, state, 0.02, 1e-6)
        assert call(kernels.pair_contact, env, a=0, b=1) == 0.0
        assert not env["F"].any() and not env["Tq"].any()
        ref, _, _ = pair_contact_ref(0, 1, table, type_grids(table), typ, pos, quat, scale,
                                     margin, 0.02, 1e-6)
        assert ref == 0.0


def test_pair_contact_clearance_counts(table, container):
    """Two boxes face to face with a gap g touch once clearance + margins exceed g."""
    quat = np.array([[1.0, 0, 0, 0]] * 2)
    gap = 0.3
    pos = np.array([[0.0, 0, 0], [2.0 + gap, 0, 0]])  # box type: x extent 2
    typ = np.array([1, 1])
    state = make_state(typ, pos, quat)
    env = env_for(table, container, state, clearance=0.0)
    assert call(kernels.pair_contact, env, a=0, b=1) == 0.0
    state.margin[:2] = 0.1
    env = env_for(table, container, state, clearance=0.15)
    pen = call(kernels.pair_contact, env, a=0, b=1)
    assert pen == pytest.approx(0.15 + 0.2 - gap, abs=1e-9)
    assert env["F"][0, 0] < 0 < env["F"][1, 0]  # pushed apart along x


@pytest.mark.parametrize("seed", range(3))
def test_wall_contact_matches_reference(table, container, seed):
    rng = np.random.default_rng(70 + seed)
    clearance, tol = 0.05, 1e-6
    hits = 0
    for trial in range(12):
        t = int(rng.integers(0, 2))
        quat = random_quats(rng, 1)
        scale = rng.uniform(0.5, 1.0, 1)
        margin = rng.uniform(0.0, 0.05, 1)
        r = table.radius[t] * scale[0]
        # near a face, an edge or a corner of the container, or well inside
        pos = rng.uniform(-5, 5, (1, 3))
        walls = rng.random(3) < (0.6 if trial % 4 else 0.0)
        sign = rng.choice([-1.0, 1.0], 3)
        pos[0, walls] = sign[walls] * (HALF_CONTAINER - rng.uniform(-0.3, 1.0) * r)
        state = make_state(np.array([t]), pos, quat, scale, margin)
        worst, env = wall_matches_reference(table, container, state, clearance, tol)
        if worst > 0:
            hits += 1
            # pushed back in: against the walls it touches
            push = env["F"][0, :3]
            assert (push[walls] * sign[walls] <= 1e-12).all()
            assert push @ (-pos[0]) > 0
        if not walls.any():
            assert worst == 0.0
    assert hits >= 4


def test_wall_contact_matches_reference_where_culling_decides(table, container):
    # depths from just touching to about one bounding radius from a face, and the corners'
    # diagonals: where the min pyramid decides whether the spheres, the point clusters or
    # the whole object can be skipped, the result must equal testing everything
    rng = np.random.default_rng(75)
    clearance, tol = 0.0, 1e-9
    hits = misses = 0
    for _ in range(200):
        t = int(rng.integers(0, 2))
        quat = random_quats(rng, 1)
        scale = np.ones(1)
        margin = np.zeros(1)
        r = table.radius[t]
        pos = rng.uniform(-3, 3, (1, 3))
        axes = rng.random(3) < 0.5
        axes[rng.integers(0, 3)] = True
        sign = rng.choice([-1.0, 1.0], 3)
        pos[0, axes] = sign[axes] * (HALF_CONTAINER - rng.uniform(0.3, 1.2) * r)
        state = make_state(np.array([t]), pos, quat, scale, margin)
        worst, env = wall_matches_reference(table, container, state, clearance, tol)
        hits += worst > 0
        misses += worst == 0
    assert hits >= 40 and misses >= 40


def test_wall_contact_culling_holds_on_a_grid_that_is_no_distance_field(table):
    # a bowl of values, lowest at one of the object's inner sphere centres or surface points,
    # is no distance field: only bounds that hold for any interpolant leave the result
    # unchanged (a culling test that relies on distance-field slopes fails here)
    rng = np.random.default_rng(80)
    box = trimesh.creation.box(extents=(20.0, 20.0, 20.0))
    h = 0.25
    axis = np.arange(-6.0, 6.01, h)
    nodes = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1)
    hits = misses = 0
    for _ in range(120):
        t = int(rng.integers(0, 2))
        state = make_state(np.array([t]), rng.uniform(-1, 1, (1, 3)), random_quats(rng, 1),
                           np.ones(1), np.zeros(1))
        _, pos, quat, _, _, _, _ = state.view()
        kind = "sph" if rng.random() < 0.5 else "pts"
        world, _, rad = posed(table, t, kind, quat_to_rot_ref(quat[0]), 1.0, pos[0])
        if kind == "sph":  # often the largest sphere: the whole-object bound is about it
            pick = int(np.argmax(rad) if rng.random() < 0.5 else rng.integers(0, len(world)))
            low = rng.uniform(0.4, 1.2) * rad[pick]
        else:  # a point's cluster is culled by its own bound: steep bowls test it
            pick = int(rng.integers(0, len(world)))
            low = rng.uniform(-0.4, 0.1)
        vals = rng.uniform(1.0, 40.0) * ((nodes - world[pick]) ** 2).sum(axis=-1)
        g = DistanceGrid(vals, np.full(3, -6.0), h)
        # the interpolant at the picked centre or point is `low`
        vals += low - trilinear_ref(vals, g.origin, h, world[pick:pick + 1])[0][0]
        cont = Container(box.vertices, box.faces, 8000.0, g, min_pyramid(g.values),
                         no_creases())
        worst, _ = wall_matches_reference(table, cont, state, 0.0, 1e-9, torque=False)
        hits += worst > 0
        misses += worst == 0
    assert hits >= 15 and misses >= 15


@pytest.mark.parametrize("seed", range(3))
def test_region_min_bounds_the_interpolant_over_the_box(seed):
    rng = np.random.default_rng(90 + seed)
    shape = tuple(int(x) for x in rng.integers(3, 20, 3))
    vals = rng.normal(size=shape)
    origin = rng.normal(size=3)
    h = float(rng.uniform(0.5, 2.0))
    pyr, off, shp = min_pyramid(vals)
    assert tuple(shp[0]) == tuple(n - 1 for n in shape) and tuple(shp[-1]) == (1, 1, 1)
    size = (np.array(shape) - 1) * h
    for _ in range(40):
        lo = origin + rng.random(3) * size
        hi = np.minimum(lo + rng.random(3) * size * rng.choice([0.05, 0.3, 1.0]),
                        origin + size * (1 - 1e-9))
        bound = kernels.region_min(pyr, off, shp, origin, h, *lo, *hi)
        pts = lo + rng.random((400, 3)) * (hi - lo)
        assert bound <= trilinear_ref(vals, origin, h, pts)[0].min() + 1e-12
        # exact for one cell: its smallest corner
        if (np.floor((hi - origin) / h) == np.floor((lo - origin) / h)).all():
            i, j, k = np.floor((lo - origin) / h).astype(int)
            assert bound == vals[i:i + 2, j:j + 2, k:k + 2].min()
    # a box reaching outside the grid's cells has no bound
    assert kernels.region_min(pyr, off, shp, origin, h, *(origin - h), *(origin + h)) == -np.inf
    assert kernels.region_min(pyr, off, shp, origin, h, *origin, *(origin + size + h)) == -np.inf


def test_wall_contact_single_face_pushes_along_its_normal(table, container):
    """Box type poking through the +x wall: the push is exactly -x, the depth analytic."""
    pos = np.array([[HALF_CONTAINER - 0.7, 0.3, -0.2]])  # box half extent 1 along x
    state = make_state(np.array([1]), pos, np.array([[1.0, 0, 0, 0]]))
    env = env_for(table, container, state, clearance=0.0)
    worst = call(kernels.wall_contact, env, a=0, c_vals=container.grid.values.ravel())
    assert worst == pytest.approx(0.3, abs=1e-9)
    f = env["F"][0, :3]
    assert f[0] < 0
    np.testing.assert_allclose(f[1:], 0.0, atol=1e-12 * abs(f[0]))


def test_max_penetrations_matches_reference(table, container):
    rng = np.random.default_rng(80)
    n = 10
    typ = rng.integers(0, 2, n)
    pos = rng.uniform(-13, 13, (n, 3))
    pos[1] = pos[0] + 1.5  # at least one overlapping pair
    pos[2, 0] = HALF_CONTAINER - 0.5  # and one object in the wall
    quat = random_quats(rng, n)
    scale = rng.uniform(0.6, 1.0, n)
    margin = rng.uniform(0, 0.05, n)
    state = make_state(typ, pos, quat, scale, margin)
    state.alive[5] = 0
    params = solver.SolverParams(clearance=0.02)
    sv = solver.Solver(container, table, state, params)
    pen = sv.penetrations()
    wall = sv.wall_penetrations()  # the same column in time linear in the objects
    grids = type_grids(table)
    ref = np.zeros((n, 2))
    for a in range(n):
        if not state.alive[a]:
            continue
        ref[a, 1] = wall_contact_ref(a, table, container, typ, pos, quat, scale, margin,
                                     params.clearance, params.tol)[0]
        for b in range(a + 1, n):
            if state.alive[b]:
                p = pair_contact_ref(a, b, table, grids, typ, pos, quat, scale, margin,
                                     params.clearance, params.tol)[0]
                ref[a, 0] = max(ref[a, 0], p)
                ref[b, 0] = max(ref[b, 0], p)
    np.testing.assert_allclose(pen, ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(wall, ref[:, 1], rtol=1e-12, atol=1e-12)
    assert pen[0, 0] > 0 and pen[1, 0] > 0 and pen[2, 1] > 0
    assert (pen[5] == 0).all()


# ---------------------------------------------------------------- resolve


def _solver_for(table, container, typ, pos, quat, scale=None):
    state = make_state(np.asarray(typ), np.asarray(pos, float), np.asarray(quat, float), scale)
    params = solver.SolverParams(clearance=0.01)
    return solver.Solver(container, table, state, params)


def _snapshot(state):
    return [a.copy() for a in state.view()]


def test_resolve_separates_two_objects(table, container):
    rng = np.random.default_rng(90)
    quat = random_quats(rng, 2)
    sv = _solver_for(table, container, [0, 1], [[0.0, 0, 0], [1.0, 0.5, 0.2]], quat)
    assert (sv.penetrations()[:, 0] > 0).all()
    assert sv.resolve(np.array([0, 1]), max_iter=300)
    pen = sv.penetrations()
    assert (pen == 0).all()
    # both are still inside the container, with all their surface points
    typ, pos, quat, scale = sv.s.view()[:4]
    for k in range(2):
        world, _, _ = posed(table, typ[k], "pts", kernels.quat_to_rot(quat[k]), scale[k],
                            pos[k])
        assert (np.abs(world) < HALF_CONTAINER).all()
    assert np.linalg.norm(pos[0] - pos[1]) > 1.0


def test_resolve_pushes_object_back_into_container(table, container):
    sv = _solver_for(table, container, [1], [[HALF_CONTAINER - 0.5, 0.0, 0.0]],
                     [[1.0, 0, 0, 0]])
    assert sv.penetrations()[0, 1] > 0
    assert sv.resolve(np.array([0]), max_iter=100)
    assert (sv.penetrations() == 0).all()
    assert sv.s.pos[0, 0] <= HALF_CONTAINER - 1.0 - 0.01 + 1e-6


def test_resolve_rollback_restores_state(table, container):
    rng = np.random.default_rng(93)
    n = 6  # a crowd of five deeply overlapping objects and one free object
    pos = rng.normal(size=(n, 3)) * 0.3
    pos[-1] = [8.0, 0, 0]
    sv = _solver_for(table, container, rng.integers(0, 2, n), pos, random_quats(rng, n))
    sv.s.vel[:n] = rng.normal(size=(n, 3)) * 0.1
    before = _snapshot(sv.s)
    crowd = np.arange(n - 1)
    # no iterations allowed: nothing may move
    assert not sv.resolve(crowd, max_iter=0, rollback=True)
    for x, y in zip(before, sv.s.view(), strict=True):
        np.testing.assert_array_equal(x, y)
    # two iterations are not enough: everything it moved is put back exactly
    assert not sv.resolve(crowd, max_iter=2, rollback=True)
    for x, y in zip(before, sv.s.view(), strict=True):
        np.testing.assert_array_equal(x, y)
    # without rollback the objects keep their partial moves
    assert not sv.resolve(crowd, max_iter=2, rollback=False)
    assert not np.array_equal(before[1], sv.s.view()[1])
    np.testing.assert_array_equal(before[1][-1], sv.s.pos[n - 1])  # the free one never moved


def _jostle(table, container, n):
    """n objects at 2.5x scale dropped at random into the box: 50 settle, 80 cannot."""
    rng = np.random.default_rng(7)
    return _solver_for(table, container, rng.integers(0, 2, n), rng.uniform(-12, 12, (n, 3)),
                       random_quats(rng, n), scale=np.full(n, 2.5))


def test_resolve_gives_up_after_its_contact_tests_and_rolls_back(table, container):
    """Solver.max_tests: a push over that many contact tests fails and is rolled back; a
    crowd that settles within it settles exactly as without the cap."""
    sv = _jostle(table, container, 80)
    before = _snapshot(sv.s)
    sv.max_tests = 2_000
    assert not sv.resolve(np.arange(80), max_iter=300, rollback=True)
    assert sv.iterations < 20
    for x, y in zip(before, sv.s.view(), strict=True):
        np.testing.assert_array_equal(x, y)
    results = []
    for cap in (0, 10_000_000):
        sv = _jostle(table, container, 50)
        sv.max_tests = cap
        assert sv.resolve(np.arange(50), max_iter=300, rollback=True)
        results.append((sv.iterations, _snapshot(sv.s)))
    assert results[0][0] == results[1][0]
    for x, y in zip(results[0][1], results[1][1], strict=True):
        np.testing.assert_array_equal(x, y)


def test_resolve_gives_up_on_a_push_that_stops_settling(table, container):
    """settle_every: a jam (80 objects) stops at the first check whose deepest penetration
    did not fall, and is rolled back; a crowd that settles (50) settles exactly as
    without the check."""
    sv = _jostle(table, container, 80)
    before = _snapshot(sv.s)
    assert not sv.resolve(np.arange(80), max_iter=300, rollback=True, settle_every=20)
    assert sv.iterations < 100  # gave up early
    for x, y in zip(before, sv.s.view(), strict=True):
        np.testing.assert_array_equal(x, y)
    sv = _jostle(table, container, 80)
    assert not sv.resolve(np.arange(80), max_iter=300, rollback=True)
    assert sv.iterations == 300  # without the check it runs to the end
    results = []
    for every in (0, 20):
        sv = _jostle(table, container, 50)
        assert sv.resolve(np.arange(50), max_iter=300, rollback=True, settle_every=every)
        results.append((sv.iterations, _snapshot(sv.s)))
    assert results[0][0] == results[1][0] > 20  # it passed checks on its way
    for x, y in zip(results[0][1], results[1][1], strict=True):
        np.testing.assert_array_equal(x, y)


def test_resolve_leaves_free_state_untouched(table, container):
    rng = np.random.default_rng(91)
    pos = [[-6.0, 0, 0], [0.0, 0, 0], [6.0, 0, 0]]
    sv = _solver_for(table, container, [0, 1, 0], pos, random_quats(rng, 3))
    sv.s.vel[:3] = 0.5  # stale velocities of free objects are zeroed, nothing else changes
    assert (sv.penetrations() == 0).all()
    before = _snapshot(sv.s)
    assert sv.resolve(np.array([0, 1, 2]), max_iter=50)
    assert sv.iterations == 0
    assert not sv.s.vel[:3].any()
    for name, x, y in zip(("typ", "pos", "quat", "scale", "alive", "margin"), before,
                          sv.s.view(), strict=False):
        np.testing.assert_array_equal(x, y, err_msg=name)


def test_resolve_is_deterministic(table, container):
    rng = np.random.default_rng(92)
    n = 6
    typ = rng.integers(0, 2, n)
    pos = rng.normal(size=(n, 3)) * 1.5
    quat = random_quats(rng, n)
    results = []
    for _ in range(2):
        sv = _solver_for(table, container, typ, pos.copy(), quat.copy())
        ok = sv.resolve(np.arange(n), max_iter=40, rollback=False)
        results.append((ok, sv.iterations, _snapshot(sv.s)))
    assert results[0][:2] == results[1][:2]
    for x, y in zip(results[0][2], results[1][2], strict=True):
        np.testing.assert_array_equal(x, y)


def _crowd(seed, n=7):
    rng = np.random.default_rng(seed)
    return (rng.integers(0, 2, n), rng.normal(size=(n, 3)) * 1.2, random_quats(rng, n))


def test_contacts_parallel_match_one_at_a_time(table, container):
    """The chunked contact tests give the same depths as pair_contact and wall_contact,
    and their chunks' forces add up to the one-at-a-time sums."""
    typ, pos, quat = _crowd(94)
    pos[0] = [HALF_CONTAINER - 0.8, 0.0, 0.0]  # one against the wall
    state = make_state(typ, pos, quat)
    env = env_for(table, container, state, clearance=0.01)
    n = len(typ)
    pa, pb = (np.array(x, np.int64) for x in zip(*[(a, b) for a in range(n)
                                                    for b in range(a + 1, n)], strict=True))
    wa = np.arange(n, dtype=np.int64)
    F = np.zeros((n, 4))
    Tq = np.zeros((n, 3))
    pair_ref = [call(kernels.pair_contact, env, a=a, b=b, F=F, Tq=Tq) for a, b in zip(pa, pb,
                                                                                      strict=True)]
    wall_ref = [call(kernels.wall_contact, env, a=a, F=F, Tq=Tq,
                     c_vals=container.grid.values.ravel()) for a in wa]
    assert max(pair_ref) > 0 and max(wall_ref) > 0
    chunks = kernels.CONTACT_CHUNKS
    Fc = np.zeros((chunks, n, 4))
    Tqc = np.zeros((chunks, n, 3))
    pen_pair = np.zeros(len(pa))
    pen_wall = np.zeros(n)
    c = container.grid
    kernels.contacts_parallel(
        pa, pb, len(pa), wa, n, env["typ"], env["pos"], env["quat"], env["scale"],
        env["margin"], 0.01, 0.01, env["tol"], table.radius, table.sph_off, table.sph_c,
        table.sph_r, table.pc_off, table.pcl, table.pcl_off, table.box, table.pts,
        table.g_off, table.g_vals, table.g_shape, table.g_origin, table.g_h,
        c.values.ravel(), np.array(c.values.shape, np.int64), c.origin, c.spacing,
        *container.pyramid, container.creases.arrays(), Fc, Tqc, pen_pair, pen_wall)
    np.testing.assert_array_equal(pen_pair, pair_ref)
    np.testing.assert_array_equal(pen_wall, wall_ref)
    np.testing.assert_allclose(Fc.sum(axis=0), F, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Tqc.sum(axis=0), Tq, rtol=1e-12, atol=1e-12)
    assert (np.abs(Fc).sum(axis=(1, 2)) > 0).sum() > 1  # the work was split


def _resolve_crowd(table, container, parallel_min, max_iter):
    typ, pos, quat = _crowd(95)
    state = make_state(typ, pos, quat)
    sv = solver.Solver(container, table, state,
                       solver.SolverParams(clearance=0.01, parallel_min=parallel_min))
    ok = sv.resolve(np.arange(len(typ)), max_iter=max_iter, rollback=False)
    return ok, sv


def test_resolve_in_parallel_matches_serial_up_to_rounding(table, container):
    _, serial = _resolve_crowd(table, container, 1 << 30, 3)
    _, par = _resolve_crowd(table, container, 1, 3)
    assert serial.iterations == par.iterations == 3
    np.testing.assert_allclose(par.s.pos[:7], serial.s.pos[:7], rtol=0, atol=1e-9)
    np.testing.assert_allclose(par.s.quat[:7], serial.s.quat[:7], rtol=0, atol=1e-9)
    ok, par = _resolve_crowd(table, container, 1, 300)
    assert ok and (par.penetrations() == 0).all()


def test_resolve_does_not_depend_on_the_thread_count(table, container):
    import numba

    before = numba.get_num_threads()
    runs = []
    try:
        for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
            numba.set_num_threads(threads)
            ok, sv = _resolve_crowd(table, container, 1, 60)
            runs.append((ok, sv.iterations, sv.s.pos[:7].copy(), sv.s.quat[:7].copy()))
    finally:
        numba.set_num_threads(before)
    for ok, its, pos, quat in runs[1:]:
        assert (ok, its) == runs[0][:2]
        np.testing.assert_array_equal(pos, runs[0][2])
        np.testing.assert_array_equal(quat, runs[0][3])


def test_the_solver_runs_on_the_tuners_count_and_restores_numbas(table, container):
    import numba

    from jampacked.core.threads import ThreadTuner

    def crowd(tuner):
        typ, pos, quat = _crowd(95)
        sv = solver.Solver(container, table, make_state(typ, pos, quat),
                           solver.SolverParams(clearance=0.01, parallel_min=1), tuner)
        ok = sv.resolve(np.arange(len(typ)), max_iter=60, rollback=False)
        return ok, sv

    before = numba.get_num_threads()
    tuner = ThreadTuner(before)
    tuner.threads = 1  # as during a probe or under load
    ok1, one = crowd(tuner)
    assert numba.get_num_threads() == before
    assert tuner.seconds[1] > 0 and tuner.seconds[before] == 0
    okn, every = crowd(None)
    assert ok1 == okn and one.iterations == every.iterations
    np.testing.assert_array_equal(one.s.pos, every.s.pos)
    np.testing.assert_array_equal(one.s.quat, every.s.quat)


# ---------------------------------------------------------------- inner spheres


def _convex_planes(v, f):
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return n, np.einsum("ij,ij->i", n, tri[:, 0])


@pytest.mark.parametrize("which", ["box", "poly"])
def test_inner_spheres(types, which):
    t = types[1] if which == "box" else types[0]
    grid = distance_grid(t.vertices, t.faces, t.grid.spacing, pad=2 * t.grid.spacing)
    centres, radii = inner_spheres(grid, 40)
    assert len(radii) >= 10
    assert (np.diff(radii) <= 0).all(), "largest first"
    assert radii[0] == pytest.approx(grid.values.max())
    # pairwise disjoint
    d = np.linalg.norm(centres[:, None] - centres[None], axis=2)
    iu = np.triu_indices(len(radii), 1)
    assert (d[iu] >= (radii[:, None] + radii[None])[iu] - 1e-9).all()
    # inside the (convex) mesh: exact depth of each centre >= its radius, up to the grid's
    # error (exact near the surface, an overestimate of at most a cell elsewhere)
    n, off = _convex_planes(t.vertices, t.faces)
    depth = (off[None] - centres @ n.T).min(axis=1)
    assert (depth >= radii - grid.spacing).all()
    assert (depth >= radii - 1e-9).mean() > 0.8
    # coverage grows with the number of spheres
    cov = [sphere_coverage(grid, centres[:k], radii[:k]) for k in (1, 5, 10, 20, len(radii))]
    assert all(b >= a for a, b in zip(cov, cov[1:], strict=False))
    assert cov[-1] > cov[0]
    more_c, more_r = inner_spheres(grid, 80)
    np.testing.assert_array_equal(more_r[:len(radii)], radii)  # greedy: a prefix
    assert sphere_coverage(grid, more_c, more_r) >= cov[-1]


@pytest.mark.parametrize("steps,calls", [(30, 15), (12, 6)])
def test_grow_takes_the_requested_growth_steps(table, container, steps, calls):
    """grow() from scale 0.5 to 1 resolves once per step of 1/steps (the extra passes use
    coarser steps than phase 1's 1/30)."""
    from jampacked.core.phases import Stop, grow

    state = make_state([0], np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]]), scale=[0.5])
    sv = solver.Solver(container, table, state, solver.SolverParams())
    assert grow(sv, 0, 0.5, 20, Stop(None, None), steps)
    assert state.scale[0] == 1.0 and sv.calls == calls


# ---------------------------------------------------------------- broad phase (cell lists)


def _cells_consistent(sv) -> None:
    """Every alive object is listed once, in the cell of its centre."""
    origin, h, dims, head, nxt, _, cell = sv.cells.arrays
    seen = np.zeros(sv.s.n, int)
    for c in range(len(head)):
        b = head[c]
        while b >= 0:
            assert cell[b] == c
            seen[b] += 1
            b = nxt[b]
    for b in np.flatnonzero(sv.s.alive[: sv.s.n]):
        p = sv.s.pos[b]
        assert cell[b] == cellgrid.cell_index(origin, h[0], dims, p[0], p[1], p[2])
        assert seen[b] == 1


def test_near_pairs_through_cells_match_a_scan_of_every_object(table, container):
    rng = np.random.default_rng(120)
    n = 400
    typ = rng.integers(0, 2, n)
    pos = rng.uniform(-16, 16, (n, 3))  # some past the container's grid box
    scale = rng.uniform(0.05, 1.0, n)
    state = make_state(typ, pos, random_quats(rng, n), scale, rng.uniform(0, 0.2, n))
    state.alive[rng.choice(n, 40, replace=False)] = 0
    sv = solver.Solver(container, table, state, solver.SolverParams(clearance=0.1))
    grid = sv.cells.sync(state, np.zeros(0, np.int64))
    assert np.prod(grid[2]) > 27  # more cells than one neighbourhood
    t, p, _, s, alive, margin, _ = state.view()
    active = (rng.random(n) < 0.3).astype(np.uint8)
    total = 0
    for a in range(n):
        want = (np.empty(n, np.int64), np.empty(n, np.int64))
        got = (np.empty(n, np.int64), np.empty(n, np.int64))
        k_ref = kernels._near_pairs(a, 0, *want, t, p, s, alive, active, margin, table.radius,
                                    0.1)
        k = cellgrid.near_pairs(a, 0, *got, t, p, s, alive, active, margin, table.radius, 0.1,
                                grid)
        assert k == k_ref
        np.testing.assert_array_equal(got[1][:k], want[1][:k])
        assert (got[0][:k] == a).all()
        total += k
    assert total > n  # the scene has contacts to find
    # a full pair buffer is reported, not overrun
    full = (np.empty(0, np.int64), np.empty(0, np.int64))
    busy = int(np.argmax([kernels._near_pairs(a, 0, np.empty(n, np.int64),
                                              np.empty(n, np.int64), t, p, s, alive,
                                              np.zeros(n, np.uint8), margin, table.radius, 0.1)
                          for a in range(n)]))
    assert cellgrid.near_pairs(busy, 0, *full, t, p, s, alive, np.zeros(n, np.uint8), margin,
                               table.radius, 0.1, grid) == -1


def test_free_distances_through_cells_equal_every_object(table, container):
    rng = np.random.default_rng(121)
    n = 300
    typ = rng.integers(0, 2, n)
    pos = rng.uniform(-14, 14, (n, 3))
    state = make_state(typ, pos, random_quats(rng, n), rng.uniform(0.2, 1.0, n))
    state.alive[::7] = 0
    sv = solver.Solver(container, table, state, solver.SolverParams())
    points = np.concatenate([rng.uniform(-20, 20, (500, 3)),  # some outside the box
                             pos[:50] + rng.normal(size=(50, 3))])
    got = sv.free_distances(points)
    t, p, q, s, alive, _, _ = state.view()
    g = container.grid
    ref = kernels.free_distances(points, t, p, q, s, alive, table.radius, table.g_off,
                                 table.g_vals, table.g_shape, table.g_origin, table.g_h,
                                 g.values, g.origin, g.spacing, container.creases.arrays())
    np.testing.assert_array_equal(got, ref)
    # with a floor: exact where the room reaches it, below it elsewhere, with and without a
    # clearance (the floor is on the room, the distance less the clearance)
    for clearance in (0.0, 0.3):
        sv_c = solver.Solver(container, table, state, solver.SolverParams(clearance=clearance))
        room = ref - clearance if clearance else ref
        for floor in np.percentile(room, [10, 50, 90]):
            cut = sv_c.free_distances(points, at_least=floor)
            reach = room >= floor
            assert 0 < reach.sum() < len(points)
            np.testing.assert_array_equal(cut[reach], room[reach])
            assert (cut[~reach] < floor).all()
            assert (cut[~reach] >= room[~reach]).all()  # a distance found, not made up
        _cells_consistent(sv_c)
    # an empty state: the container's distance alone
    empty = solver.Solver(container, table, solver.PackState(), solver.SolverParams())
    np.testing.assert_array_equal(empty.free_distances(points), container.depth(points))
    _cells_consistent(sv)  # the removed objects met were unlinked, none other


def test_resolve_through_cells_matches_one_cell_and_keeps_them(table, container):
    rng = np.random.default_rng(122)
    n = 60
    typ = rng.integers(0, 2, n)
    pos = rng.uniform(-12, 12, (n, 3))
    quat = random_quats(rng, n)
    runs = []
    for one_cell in (False, True):
        sv = _solver_for(table, container, typ, pos.copy(), quat.copy())
        if one_cell:  # cells wider than the container: every object is a candidate
            sv.cells.max_radius = 100.0
        ok = sv.resolve(np.arange(n), max_iter=200, rollback=False)
        assert (np.prod(sv.cells.arrays[2]) == 1) == one_cell
        _cells_consistent(sv)
        runs.append((ok, sv.iterations, _snapshot(sv.s)))
    assert runs[0][:2] == runs[1][:2]
    for x, y in zip(runs[0][2], runs[1][2], strict=True):
        np.testing.assert_array_equal(x, y)


def test_resolve_leaves_its_working_arrays_as_it_found_them(table, container):
    typ, pos, quat = _crowd(123, n=12)
    sv = _solver_for(table, container, typ, pos * 0.3, quat)
    assert not sv.resolve(np.arange(12), max_iter=3, rollback=True)  # fails mid-contact
    _cells_consistent(sv)
    work = sv._work
    for k in (0, 1, 2, 7, 8, 9, 10, 11, 12):  # Fc, Tqc, moved, F, Tq, pens, active, hit
        assert not work[k].any(), k
    # the same call on fresh arrays and cells gives the same result
    again = _solver_for(table, container, typ, pos * 0.3, quat)
    assert not again.resolve(np.arange(12), max_iter=3, rollback=True)
    for x, y in zip(_snapshot(sv.s), _snapshot(again.s), strict=True):
        np.testing.assert_array_equal(x, y)


def test_cells_widen_for_a_wider_margin(table, container):
    typ, pos, quat = _crowd(124, n=5)
    sv = _solver_for(table, container, typ, pos, quat)
    sv.free_distances(np.zeros((1, 3)))
    h = sv.cells.arrays[1][0]
    sv.s.margin[2] = 3.0  # repair widens a failing object's margin, then resolves it
    sv.resolve(np.array([2]), max_iter=5)
    assert sv.cells.arrays[1][0] >= 2 * (table.radius.max() + 3.0) + 0.01
    assert sv.cells.arrays[1][0] > h
    _cells_consistent(sv)
