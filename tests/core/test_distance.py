"""Tests for jampacked.core.distance: the numba distance kernels against numpy references.

House rule: every numba kernel is compared with a plain numpy reference on seeded random
inputs. Sign convention everywhere: signed distance is positive inside.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core import distance
from jampacked.core.distance import (
    band_distances,
    distance_grid,
    inside_mask,
    point_triangle_distance,
)

# ---------------------------------------------------------------- numpy references


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", u, v)


def segment_distance_ref(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points p (...,3) to segments ab (...,3), zero-length segments allowed."""
    ab = b - a
    length2 = _dot(ab, ab)
    t = _dot(p - a, ab) / np.where(length2 > 0, length2, 1.0)
    t = np.clip(np.where(length2 > 0, t, 0.0), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def point_triangle_distance_ref(p, a, b, c) -> np.ndarray:
    """Exact point-triangle distance, vectorised over (...,3) arrays.

    The nearest point is either the projection onto the plane (when it falls inside the
    triangle) or the nearest point of one of the three edges. Taking the minimum of the
    plane distance (only where the projection is inside) and the three clamped edge
    distances is robust: a projection misclassified near an edge gives (almost) the edge
    distance anyway, and zero-area triangles reduce to their edges.
    """
    n = np.cross(b - a, c - a)
    nn = np.linalg.norm(n, axis=-1)
    ok = nn > 1e-300
    u = n / np.where(ok, nn, 1.0)[..., None]
    h = _dot(p - a, u)
    q = p - h[..., None] * u
    s0 = _dot(np.cross(b - a, q - a), n)
    s1 = _dot(np.cross(c - b, q - b), n)
    s2 = _dot(np.cross(a - c, q - c), n)
    inside = ok & (s0 >= 0) & (s1 >= 0) & (s2 >= 0)
    edges = np.minimum(np.minimum(segment_distance_ref(p, a, b), segment_distance_ref(p, b, c)),
                       segment_distance_ref(p, c, a))
    return np.where(inside, np.minimum(np.abs(h), edges), edges)


def mesh_distance_ref(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                      chunk: int = 512) -> np.ndarray:
    """Brute-force unsigned distance from points (M,3) to a triangle mesh: min over faces."""
    tri = vertices[faces]  # (F,3,3)
    a, b, c = tri[None, :, 0], tri[None, :, 1], tri[None, :, 2]
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        p = points[s:s + chunk, None, :]
        out[s:s + chunk] = point_triangle_distance_ref(p, a, b, c).min(axis=1)
    return out


def box_sdf(points: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Analytic signed distance to an axis-aligned box |x_i| <= half_i, positive inside."""
    q = np.abs(points) - half
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = np.minimum(q.max(axis=1), 0.0)
    return -(outside + inside)


def torus_sdf(points: np.ndarray, major: float, minor: float) -> np.ndarray:
    """Analytic signed distance to a torus about the z axis, positive inside."""
    ring = np.hypot(points[:, 0], points[:, 1]) - major
    return minor - np.hypot(ring, points[:, 2])


def kernel_distances(p, a, b, c) -> np.ndarray:
    return np.array([point_triangle_distance(p[i], a[i], b[i], c[i]) for i in range(len(p))])


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


# ---------------------------------------------------------------- point_triangle_distance


def _triangle_cases(rng: np.random.Generator, n: int):
    """Seeded random triangles: generic, needles, slivers, tiny, short edges, obtuse."""
    p = rng.normal(size=(n, 3)) * 2.0
    a = rng.normal(size=(n, 3))
    b = rng.normal(size=(n, 3))
    c = rng.normal(size=(n, 3))
    yield "generic", p, a, b, c
    # points very close to the triangle: on the plane, slightly above it, on edges/vertices
    w = rng.dirichlet([1, 1, 1], n)
    on = w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c
    nrm = np.cross(b - a, c - a)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    yield "on plane", on + nrm * rng.normal(size=(n, 1)) * 1e-3, a, b, c
    t = rng.random((n, 1))
    yield "on edge", a + t * (b - a) + rng.normal(size=(n, 3)) * 1e-7, a, b, c
    yield "at vertex", c + rng.normal(size=(n, 3)) * 1e-7, a, b, c
    for width in (1e-4, 1e-7, 1e-10):
        # needle: c near the line ab, inside or beyond the segment
        cn = a + (b - a) * rng.uniform(-1.0, 2.0, (n, 1)) + rng.normal(size=(n, 3)) * width
        yield f"needle {width:g}", p, a, b, cn
    for size in (1e-4, 1e-8, 1e-12):
        yield f"short edge {size:g}", p, a, a + rng.normal(size=(n, 3)) * size, c
        yield f"tiny {size:g}", p, a, a + rng.normal(size=(n, 3)) * size, \
            a + rng.normal(size=(n, 3)) * size
    # large coordinates far from the origin
    off = rng.normal(size=(n, 3)) * 1e3
    yield "far offset", p + off, a + off, b + off, c + off


@pytest.mark.parametrize("seed", [0, 1])
def test_point_triangle_distance_matches_reference(seed):
    rng = np.random.default_rng(seed)
    for name, p, a, b, c in _triangle_cases(rng, 3000):
        got = kernel_distances(p, a, b, c)
        ref = point_triangle_distance_ref(p, a, b, c)
        scale = 1.0 + np.abs(p).max()
        err = np.abs(got - ref).max()
        assert err <= 1e-9 * scale, f"{name}: max error {err:g}"


def test_point_triangle_distance_vertex_order_invariant():
    rng = np.random.default_rng(5)
    p, a, b, c = (rng.normal(size=(2000, 3)) for _ in range(4))
    d0 = kernel_distances(p, a, b, c)
    for perm in ((b, c, a), (c, a, b), (b, a, c), (a, c, b), (c, b, a)):
        np.testing.assert_allclose(kernel_distances(p, *perm), d0, rtol=0, atol=1e-12)


def test_point_triangle_distance_simple_values():
    a, b, c = np.array([0.0, 0, 0]), np.array([2.0, 0, 0]), np.array([0.0, 2, 0])
    cases = {
        (0.5, 0.5, 3.0): 3.0,  # above the face
        (-1.0, -1.0, 0.0): np.sqrt(2.0),  # vertex a region
        (1.0, -2.0, 0.0): 2.0,  # edge ab region
        (2.0, 2.0, 0.0): np.sqrt(2.0),  # edge bc region
        (0.2, 0.3, 0.0): 0.0,  # in the triangle
    }
    for p, want in cases.items():
        assert point_triangle_distance(np.array(p), a, b, c) == pytest.approx(want, abs=1e-15)


def test_point_triangle_distance_zero_area_triangles():
    rng = np.random.default_rng(7)
    n = 2000
    p, a, b = (rng.normal(size=(n, 3)) for _ in range(3))
    p = p * 2.0
    collinear = a + (b - a) * 0.3
    for name, tri in (("repeated vertex", (a, a.copy(), b)), ("collinear", (a, b, collinear))):
        ref = np.minimum(np.minimum(segment_distance_ref(p, tri[0], tri[1]),
                                    segment_distance_ref(p, tri[1], tri[2])),
                         segment_distance_ref(p, tri[2], tri[0]))
        got = kernel_distances(p, *tri)
        assert np.abs(got - ref).max() <= 1e-9, name


# ---------------------------------------------------------------- band_distances


def _grid_for(vertices: np.ndarray, spacing: float, pad: float):
    lo = vertices.min(axis=0) - pad
    hi = vertices.max(axis=0) + pad
    shape = np.ceil((hi - lo) / spacing).astype(np.int64) + 1
    return lo, shape


@pytest.mark.parametrize("seed", [0, 1])
def test_band_distances_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    v = mesh.vertices * rng.uniform(0.6, 1.4, 3) @ random_rotation(rng).T + rng.normal(size=3)
    v = np.ascontiguousarray(v)
    f = np.ascontiguousarray(mesh.faces, np.int64)
    spacing = 0.13
    band = 2.0
    origin, shape = _grid_for(v, spacing, 0.5)
    dist, tri = band_distances(v, f, origin, spacing, shape, band)
    assert dist.shape == tuple(shape) and tri.shape == tuple(shape)
    g = distance.DistanceGrid(dist, origin, spacing)
    pts = g.node_points()
    ref = mesh_distance_ref(pts, v, f)
    d = dist.ravel()
    t = tri.ravel()
    in_band = ref <= band * spacing
    assert in_band.sum() > 100
    # every node within the band has the exact minimum and the index of a nearest triangle
    np.testing.assert_allclose(d[in_band], ref[in_band], rtol=0, atol=1e-9)
    assert (t[in_band] >= 0).all()
    tri_d = point_triangle_distance_ref(pts[in_band], *(v[f[t[in_band]]].transpose(1, 0, 2)))
    np.testing.assert_allclose(tri_d, ref[in_band], rtol=0, atol=1e-9)
    # elsewhere: either untouched (inf, -1) or the distance to a real triangle (>= exact)
    untouched = t < 0
    assert np.isinf(d[untouched]).all()
    assert (d[~untouched] >= ref[~untouched] - 1e-9).all()


# ---------------------------------------------------------------- distance_grid


def test_distance_grid_box_exact_in_band_and_signs():
    half = np.array([2.0, 3.0, 4.0])
    box = trimesh.creation.box(extents=2 * half)
    spacing = 0.25  # faces lie exactly on grid planes
    g = distance_grid(box.vertices, box.faces, spacing, pad=0.5, band=3)
    pts = g.node_points()
    exact = box_sdf(pts, half)
    v = g.values.ravel()
    band = np.abs(exact) <= 3 * spacing
    np.testing.assert_allclose(v[band], exact[band], rtol=0, atol=1e-9)
    # outside the band the value is the distance to some triangle: never below the truth
    assert (np.abs(v) >= np.abs(exact) - 1e-9).all()
    clear = np.abs(exact) > 1e-6
    assert (np.sign(v[clear]) == np.sign(exact[clear])).all()


def _rotated_box_grid(seed: int):
    rng = np.random.default_rng(seed)
    half = np.array([1.5, 2.5, 1.0])
    rot = random_rotation(rng)
    shift = rng.normal(size=3)
    box = trimesh.creation.box(extents=2 * half)
    v = box.vertices @ rot.T + shift
    spacing = 0.17
    g = distance_grid(v, box.faces, spacing, pad=0.4, band=3)
    exact = box_sdf((g.node_points() - shift) @ rot, half)
    return g, exact


@pytest.mark.parametrize("seed", [1, 3])
def test_distance_grid_rotated_box(seed):
    g, exact = _rotated_box_grid(seed)
    vals = g.values.ravel()
    band = np.abs(exact) <= 3 * g.spacing
    np.testing.assert_allclose(np.abs(vals[band]), np.abs(exact[band]), rtol=0, atol=1e-9)
    assert (np.abs(vals) >= np.abs(exact) - 1e-9).all()
    # the parity rays are nudged by up to ~3e-4 cells: on tilted faces the sign is only
    # guaranteed beyond about that distance from the surface
    clear = np.abs(exact) > 1e-3 * g.spacing
    assert (np.sign(vals[clear]) == np.sign(exact[clear])).all()


def test_distance_grid_rotated_box_sign_near_surface():
    g, exact = _rotated_box_grid(0)
    vals = g.values.ravel()
    clear = np.abs(exact) > 1e-6
    assert (np.sign(vals[clear]) == np.sign(exact[clear])).all()


def test_distance_grid_icosphere():
    radius = 10.0
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    normals = mesh.face_normals
    offsets = np.einsum("ij,ij->i", normals, mesh.triangles_center)
    sagitta = radius - offsets.min()  # largest gap between the facets and the sphere
    assert 0 < sagitta < 0.1
    spacing = 0.5
    g = distance_grid(mesh.vertices, mesh.faces, spacing, pad=1.0, band=3)
    pts = g.node_points()
    vals = g.values.ravel()
    analytic = radius - np.linalg.norm(pts, axis=1)
    band = np.abs(analytic) <= 3 * spacing - sagitta
    assert np.abs(vals - analytic)[band].max() <= sagitta + 1e-9
    # the polyhedron is convex: inside <=> on the inner side of every face plane, and
    # inside it the exact signed distance is the smallest plane distance
    plane = np.concatenate([(offsets[None, :] - pts[s:s + 4096] @ normals.T).min(axis=1)
                            for s in range(0, len(pts), 4096)])
    inside = plane > 0
    np.testing.assert_allclose(vals[inside & band], plane[inside & band], rtol=0, atol=1e-9)
    clear = np.abs(plane) > 1e-6
    assert (np.sign(vals[clear]) == np.sign(plane[clear])).all()
    # every node clearly in or out of the sphere has that sign
    far = np.abs(analytic) > sagitta + 1e-6
    assert (np.sign(vals[far]) == np.sign(analytic[far])).all()


def test_distance_grid_torus_signs_and_values():
    major, minor, n_major, n_minor = 6.0, 2.0, 48, 24
    mesh = trimesh.creation.torus(major_radius=major, minor_radius=minor,
                                  major_sections=n_major, minor_sections=n_minor)
    # the facets lie within the two polygon sagittas of the smooth surface
    tol = (major + minor) * (1 - np.cos(np.pi / n_major)) + minor * (1 - np.cos(np.pi / n_minor))
    spacing = 0.3
    g = distance_grid(mesh.vertices, mesh.faces, spacing, pad=0.6, band=3)
    pts = g.node_points()
    vals = g.values.ravel()
    analytic = torus_sdf(pts, major, minor)
    band = np.abs(analytic) <= 3 * spacing - tol
    assert band.sum() > 1000
    assert np.abs(vals - analytic)[band].max() <= tol + 1e-9
    clear = np.abs(analytic) > tol
    assert (analytic[clear] > 0).sum() > 100  # the hole and the tube are both sampled
    assert (np.sign(vals[clear]) == np.sign(analytic[clear])).all()


# ---------------------------------------------------------------- inside_mask


@pytest.mark.parametrize("offset_cells", [(0, 0, 0), (1, 2, 3), (0.5, 0.5, 0.5)])
def test_inside_mask_box_on_grid_planes(offset_cells):
    spacing = 0.25
    origin = np.array([-3.0, -3.0, -3.0])
    shape = (25, 29, 33)
    half = np.array([1.5, 2.0, 2.5])  # multiples of the spacing
    centre = np.asarray(offset_cells) * spacing
    box = trimesh.creation.box(extents=2 * half)
    v = np.ascontiguousarray(box.vertices + centre)
    f = np.ascontiguousarray(box.faces, np.int64)
    mask = inside_mask(v, f, origin, spacing, shape)
    assert mask.shape == shape
    pts = distance.DistanceGrid(np.zeros(shape), origin, spacing).node_points()
    rel = np.abs(pts - centre) - half
    strictly_in = (rel < -1e-9).all(axis=1).reshape(shape)
    strictly_out = (rel > 1e-9).any(axis=1).reshape(shape)
    assert strictly_in.sum() > 1000
    assert mask[strictly_in].all()
    assert not mask[strictly_out].any()
    # every single-axis ray parity must agree too (a majority vote could hide one bad axis)
    shp = np.asarray(shape, np.int64)
    for axis in range(3):
        par = distance.ray_parity(v, f, origin, spacing, shp, axis, 1.234567e-4, 2.718281e-4)
        order = [(axis + 1) % 3, (axis + 2) % 3, axis]
        par = np.transpose(par, np.argsort(order)).astype(bool)
        assert par[strictly_in].all(), f"axis {axis}: inside node marked outside"
        assert not par[strictly_out].any(), f"axis {axis}: outside node marked inside"
