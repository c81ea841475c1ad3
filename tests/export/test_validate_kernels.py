"""The numba kernels behind validation against the numpy formulations they replaced.

Each reference below is the vectorised code the kernel replaced (kept here, not in the
package): the kernels must give the same arrays, bit for bit, on real and random meshes.
"""

from __future__ import annotations

import io
import math
import zipfile

import numpy as np
import pytest
import trimesh
from testdata import mesh_path

from jampacked.core import threemf
from jampacked.core.mesh_geometry import face_areas2, signed_six_volumes
from jampacked.core.mesh_topology import edge_topology, union_roots
from jampacked.export import intersect, meshcheck
from jampacked.export import io as mesh_io
from jampacked.export.nesting import largest_faces
from jampacked.export.validate import validate_arrays
from jampacked.export.validation_topology import (
    duplicate_faces,
    face_bodies,
    flipped_faces,
    merge_identical,
    vertex_fans,
)

# ------------------------------------------------------------------------------------------
# meshes: real ones (closed, open, non-manifold, several bodies) and random soups


def _merged(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    first, remap = merge_identical(v)
    return v[first], remap[f]


def _meshes() -> list[tuple[str, np.ndarray, np.ndarray]]:
    out = []
    s = trimesh.creation.icosphere(subdivisions=3)
    out.append(("icosphere", np.array(s.vertices), np.array(s.faces)))
    t = trimesh.creation.torus(major_radius=2.0, minor_radius=0.5)
    out.append(("torus", np.array(t.vertices), np.array(t.faces)))
    b = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    v = np.vstack([s.vertices, np.array(b.vertices) + [5.0, 0, 0], np.array(s.vertices) * 0.3])
    f = np.vstack([s.faces, np.array(b.faces) + len(s.vertices),
                   np.array(s.faces)[:, ::-1] + len(s.vertices) + len(b.vertices)])
    out.append(("three bodies, a cavity", v, f))
    # defects: a flipped face, a duplicate, a fin, a repeated vertex, a hole
    v, f = np.array(s.vertices), np.array(s.faces).copy()
    f[3] = f[3, ::-1]
    f = np.vstack([f, f[10:11], [[f[20, 0], f[20, 1], len(v)]], [[f[30, 0], f[30, 0], f[31, 2]]]])
    v = np.vstack([v, [[0.0, 0.0, 2.0]]])
    out.append(("defects", v, np.delete(f, 50, axis=0)))
    for name in ("broken/spot_with_holes.obj", "broken/pear_five_bodies.ply",
                 "broken/polytope_internal_faces.obj", "containers/torus.obj"):
        v, f = mesh_io.read_mesh_arrays(mesh_path(name))
        out.append((name, v, f))
    # lone copies: a face and its reverse (edges used twice), three copies (three times)
    v = np.arange(27, dtype=float).reshape(9, 3) ** 1.5
    f = np.array([[0, 1, 2], [2, 1, 0], [3, 4, 5], [3, 4, 5], [5, 3, 4], [6, 7, 8],
                  [6, 6, 7], [1, 0, 2]])
    out.append(("copies", v, f))
    rng = np.random.default_rng(7)
    for k in range(3):  # soups: shared vertices, repeated vertices, duplicates, everything
        v = rng.integers(-3, 4, size=(40, 3)).astype(float) * (0.5 if k else -0.0 + 1)
        f = rng.integers(0, 40, size=(300, 3))
        f[:20, 1] = f[:20, 0]
        f[20:40] = f[40:60, ::-1]
        out.append((f"soup {k}", v, f))
    return out


MESHES = _meshes()
IDS = [m[0] for m in MESHES]


# ------------------------------------------------------------------------------------------
# numpy references (the code the kernels replaced)


def ref_merge_identical(vertices):
    v = np.ascontiguousarray(vertices, dtype=np.float64) + 0.0
    bits = v.view(np.uint64).reshape(-1, 3)
    order = np.lexsort((bits[:, 2], bits[:, 1], bits[:, 0]))
    sorted_bits = bits[order]
    new = np.ones(len(v), bool)
    new[1:] = np.any(sorted_bits[1:] != sorted_bits[:-1], axis=1)
    group = np.cumsum(new) - 1
    first_of_group = order[new]
    rank = np.empty(len(first_of_group), np.int64)
    by_first = np.argsort(first_of_group, kind="stable")
    rank[by_first] = np.arange(len(first_of_group))
    remap = np.empty(len(v), np.int64)
    remap[order] = rank[group]
    return first_of_group[by_first], remap


def ref_topology(faces, proper, n_vertices):
    """Half-edge form: (half_corner, half_face, directed, edge, edge_vertices, counts,
    first_half, second_half, inconsistent)."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    keep = directed[:, 0] != directed[:, 1]
    directed = directed[keep]
    half_corner = np.flatnonzero(keep)
    half_face = half_corner // 3
    n = np.int64(max(n_vertices, 1))
    keys = np.minimum(directed[:, 0], directed[:, 1]) * n + np.maximum(directed[:, 0],
                                                                        directed[:, 1])
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    new = np.ones(len(keys), bool)
    new[1:] = sorted_keys[1:] != sorted_keys[:-1]
    edge_sorted = np.cumsum(new) - 1
    edge = np.empty(len(keys), np.int64)
    edge[order] = edge_sorted
    n_edges = int(edge_sorted[-1]) + 1 if len(keys) else 0
    edge_vertices = np.sort(directed[order[new]], axis=1)
    is_proper = proper[half_face]
    counts = np.bincount(edge[is_proper], minlength=n_edges)
    sel = is_proper[order]
    order_p, edge_p = order[sel], edge_sorted[sel]
    two = np.flatnonzero(counts == 2)
    start = np.searchsorted(edge_p, two)
    h1, h2 = order_p[start], order_p[start + 1]
    first_half = np.full(n_edges, -1, np.int64)
    second_half = np.full(n_edges, -1, np.int64)
    first_half[two] = h1
    second_half[two] = h2
    inconsistent = np.zeros(n_edges, bool)
    inconsistent[two] = directed[h1, 0] == directed[h2, 0]
    return (half_corner, half_face, directed, edge, edge_vertices, counts, first_half,
            second_half, inconsistent)


def ref_bodies(faces, proper, half_face, edge, n_edges):
    n_faces = len(faces)
    hp = proper[half_face]
    root = union_roots(n_faces + n_edges, half_face[hp], edge[hp] + n_faces)[:n_faces]
    if not np.all(proper):
        vertex_root = np.full(int(faces.max()) + 1, -1, np.int64)
        vertex_root[faces[proper].reshape(-1)] = np.repeat(root[proper], 3)
        lines = np.flatnonzero(~proper)
        owner = vertex_root[faces[lines]].max(axis=1)
        root[lines[owner >= 0]] = owner[owner >= 0]
    is_root = np.zeros(n_faces, bool)
    is_root[root] = True
    rank = np.cumsum(is_root) - 1
    return int(is_root.sum()), rank[root]


def ref_fans(faces, proper, half_corner, first_half, second_half, inconsistent):
    two = np.flatnonzero(first_half >= 0)
    s1, s2 = half_corner[first_half[two]], half_corner[second_half[two]]
    e1, e2 = s1 - s1 % 3 + (s1 % 3 + 1) % 3, s2 - s2 % 3 + (s2 % 3 + 1) % 3
    same = inconsistent[two]
    rows = np.concatenate([s1, e1])
    cols = np.concatenate([np.where(same, s2, e2), np.where(same, e2, s2)])
    root = union_roots(3 * len(faces), rows, cols)
    corners = np.flatnonzero(np.repeat(proper, 3))
    fan_corners = corners[root[corners] == corners]
    return faces.reshape(-1)[fan_corners], fan_corners // 3


def ref_flipped(n_faces, half_face, first_half, second_half, inconsistent):
    two = np.flatnonzero(first_half >= 0)
    f1, f2 = half_face[first_half[two]], half_face[second_half[two]]
    same = inconsistent[two]
    a = np.concatenate([f1, f1 + n_faces])
    b = np.concatenate([np.where(same, f2 + n_faces, f2), np.where(same, f2, f2 + n_faces)])
    root = union_roots(2 * n_faces, a, b)
    keep, flip = root[:n_faces], root[n_faces:]
    bad = keep == flip
    patch = np.minimum(keep, flip)
    flipped = (keep != patch) & ~bad
    size = np.bincount(patch, minlength=2 * n_faces)
    minority = np.bincount(patch, weights=flipped, minlength=2 * n_faces) * 2 > size
    flipped ^= minority[patch] & ~bad
    return np.flatnonzero(flipped), np.flatnonzero(bad)


def ref_duplicates(faces, proper):
    index = np.flatnonzero(proper)
    if len(index) < 2:
        return np.zeros(0, np.int64)
    srt = np.sort(faces[index], axis=1)
    _, first = np.unique(srt, axis=0, return_index=True)
    is_first = np.zeros(len(index), bool)
    is_first[first] = True
    return index[~is_first]


def ref_body_vertices(faces, face_body, n_bodies, positions, marked):
    n_pos = np.int64(len(positions))
    vb = np.unique(np.repeat(face_body, 3) * n_pos + faces.reshape(-1))
    vb_body, vb_vertex = vb // n_pos, vb % n_pos
    count = np.bincount(vb_body, minlength=n_bodies)
    n_marked = np.bincount(vb_body[marked[vb_vertex]], minlength=n_bodies)
    starts = np.searchsorted(vb_body, np.arange(n_bodies))
    lo = np.minimum.reduceat(positions[vb_vertex], starts, axis=0)
    hi = np.maximum.reduceat(positions[vb_vertex], starts, axis=0)
    return count, n_marked, lo, hi


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return False
    if a.dtype.kind == "f":
        return a.dtype == b.dtype and np.array_equal(a.view(np.uint64), b.view(np.uint64))
    return np.array_equal(a, b)


# ------------------------------------------------------------------------------------------
# merging, geometry, edges, fans, patches, bodies


@pytest.mark.parametrize(("name", "v", "f"), MESHES, ids=IDS)
def test_merge_and_used_vertices_match_numpy(name, v, f):
    first, remap = merge_identical(v)
    ref_first, ref_remap = ref_merge_identical(v)
    assert same_bits(first, ref_first) and same_bits(remap, ref_remap)
    used, local = meshcheck.used_vertices(np.asarray(f, np.int64), len(v))
    ref_used = np.unique(f)
    assert same_bits(used, ref_used) and same_bits(local, np.searchsorted(ref_used, f))


def test_merge_signed_zeros_and_many_duplicates():
    rng = np.random.default_rng(1)
    v = rng.integers(-2, 3, size=(5000, 3)).astype(float) * 0.0  # +-0 only
    v[::7] = rng.integers(-2, 3, size=(len(v[::7]), 3))
    first, remap = merge_identical(v)
    ref_first, ref_remap = ref_merge_identical(v)
    assert same_bits(first, ref_first) and same_bits(remap, ref_remap)


@pytest.mark.parametrize(("name", "v", "f"), MESHES, ids=IDS)
def test_face_geometry_matches_numpy(name, v, f):
    p, mf = _merged(v, f)
    origin = 0.5 * (p.min(axis=0) + p.max(axis=0))
    repeated, area2, longest, six = meshcheck.face_geometry(p, mf, origin)
    tri = p[mf]
    assert same_bits(repeated, (mf[:, 0] == mf[:, 1]) | (mf[:, 1] == mf[:, 2])
                     | (mf[:, 2] == mf[:, 0]))
    assert same_bits(area2, face_areas2(p, mf))
    assert same_bits(longest, np.linalg.norm(tri[:, [1, 2, 0]] - tri, axis=2).max(axis=1))
    assert same_bits(six, signed_six_volumes(p, mf))


def _as_half_edges(topo, faces):
    """The corner form of meshcheck.edge_structure in the half-edge form of the reference."""
    half_corner = np.flatnonzero(topo.corner_edge >= 0)
    h_of_corner = np.full(3 * len(faces), -1, np.int64)
    h_of_corner[half_corner] = np.arange(len(half_corner))
    first = np.where(topo.first_corner >= 0, h_of_corner[topo.first_corner], -1)
    second = np.where(topo.second_corner >= 0, h_of_corner[topo.second_corner], -1)
    return half_corner, topo.corner_edge[half_corner], first, second


@pytest.mark.parametrize(("name", "v", "f"), MESHES, ids=IDS)
def test_edges_fans_patches_duplicates_bodies_match_numpy(name, v, f):
    p, mf = _merged(v, f)
    repeated = (mf[:, 0] == mf[:, 1]) | (mf[:, 1] == mf[:, 2]) | (mf[:, 2] == mf[:, 0])
    proper = ~repeated
    topo = edge_topology(mf, len(p), proper)
    (half_corner, half_face, _, edge, edge_vertices, counts, first_half, second_half,
     inconsistent) = ref_topology(mf, proper, len(p))
    got_corner, got_edge, got_first, got_second = _as_half_edges(topo, mf)
    assert same_bits(got_corner, half_corner) and same_bits(got_edge, edge)
    assert same_bits(topo.edge_vertices, edge_vertices) and same_bits(topo.counts, counts)
    assert same_bits(got_first, first_half) and same_bits(got_second, second_half)
    assert same_bits(topo.inconsistent, inconsistent)
    face_of_edge = np.zeros(len(counts), np.int64)
    face_of_edge[edge] = half_face  # the last half-edge's face
    assert same_bits(topo.face_of_edge, face_of_edge)

    n_bodies, face_body = face_bodies(mf, proper, topo)
    ref_n, ref_body = ref_bodies(mf, proper, half_face, edge, len(counts))
    assert n_bodies == ref_n and same_bits(face_body, ref_body)
    for got, ref in zip(vertex_fans(mf, proper, topo),
                        ref_fans(mf, proper, half_corner, first_half, second_half,
                                 inconsistent), strict=True):
        assert same_bits(got, ref)
    for got, ref in zip(flipped_faces(len(mf), topo),
                        ref_flipped(len(mf), half_face, first_half, second_half, inconsistent),
                        strict=True):
        assert same_bits(got, ref)
    assert same_bits(duplicate_faces(mf, proper, topo), ref_duplicates(mf, proper))

    marked = np.zeros(len(p), bool)
    marked[::3] = True
    for got, ref in zip(meshcheck.body_vertices(mf, face_body, n_bodies, p, marked),
                        ref_body_vertices(mf, face_body, n_bodies, p, marked), strict=True):
        assert same_bits(got, ref)


def test_body_boxes_keep_numpys_signed_zero():
    """numpy's reduceat keeps the last of equal values: the sign of a zero corner."""
    v = np.array([[0.0, -0.0, 1], [-0.0, 0.0, 1], [1, 1, -0.0], [1, 0, 0.0], [0, 1, 1]])
    f = np.array([[0, 1, 2], [1, 3, 4], [0, 3, 4]])
    body = np.zeros(3, np.int64)
    marked = np.zeros(5, bool)
    for order in ([0, 1, 2], [2, 1, 0], [1, 2, 0]):
        got = meshcheck.body_vertices(f[order], body, 1, v, marked)
        ref = ref_body_vertices(f[order], body, 1, v, marked)
        for a, b in zip(got, ref, strict=True):
            assert same_bits(a, b)
    # vertices shared by two bodies count in both
    f2 = np.array([[0, 1, 2], [2, 3, 4]])
    got = meshcheck.body_vertices(f2, np.array([0, 1]), 2, v, marked)
    ref = ref_body_vertices(f2, np.array([0, 1]), 2, v, marked)
    for a, b in zip(got, ref, strict=True):
        assert same_bits(a, b)


def test_largest_faces_match_lexsort():
    rng = np.random.default_rng(2)
    body = rng.integers(0, 30, 2000)
    body[:30] = np.arange(30)
    areas = rng.integers(0, 5, 2000).astype(float)  # many ties
    areas[::17] = np.nan
    order = np.lexsort((-areas, body))
    ref = order[np.searchsorted(body[order], np.arange(30))]
    assert same_bits(largest_faces(body, areas, 30), ref)


# ------------------------------------------------------------------------------------------
# nesting: ray crossings against solid angles


@pytest.mark.parametrize(("name", "v", "f"), MESHES[:4], ids=IDS[:4])
def test_ray_winding_matches_solid_angles(name, v, f):
    p, mf = _merged(v, f)
    rng = np.random.default_rng(4)
    lo, hi = p.min(axis=0), p.max(axis=0)
    points = lo + rng.random((400, 3)) * (hi - lo) * 1.2 - 0.1 * (hi - lo)
    points = np.vstack([points, p[mf[:50]].mean(axis=1), p[:20]])  # on the surface too
    w, ok = intersect.ray_winding_numbers(points, p, mf)
    exact = intersect.winding_numbers(points, p, mf)
    if name in ("icosphere", "torus", "three bodies, a cavity"):  # closed, consistent
        assert np.all(ok[:400])
        assert not np.any(ok[400:])  # centroids and vertices lie on the surface
        assert same_bits(w[ok], np.rint(exact[ok]).astype(np.int64))
    assert w.dtype == np.int64 and ok.dtype == np.bool_


def test_ray_winding_grazing_an_edge_is_not_trusted():
    v, f = trimesh.creation.box().vertices, trimesh.creation.box().faces
    # straight up through a diagonal edge of the bottom face, and through a vertex
    points = np.array([[0.0, 0.0, -1.0], [0.5, 0.5, -1.0], [0.1, 0.3, 0.0]])
    w, ok = intersect.ray_winding_numbers(points, np.array(v), np.array(f))
    assert list(ok) == [False, False, True] and w[2] == 1


def test_nesting_report_unchanged_by_ray_crossings(monkeypatch):
    """Bodies in the cavity of a shell, in its wall, and overlapping it: the report is the
    one of the solid angles alone."""
    s = trimesh.creation.icosphere(subdivisions=3, radius=10.0)
    bodies = [(np.array(s.vertices), np.array(s.faces)),
              (np.array(s.vertices) * 0.8, np.array(s.faces)[:, ::-1])]
    rng = np.random.default_rng(5)
    for radius in [3.0] * 6 + [8.8] * 6 + [9.8] * 3:  # cavity, wall, poking out
        d = rng.normal(size=3)
        b = trimesh.creation.icosphere(subdivisions=1, radius=0.5)
        bodies.append((np.array(b.vertices) + radius * d / np.linalg.norm(d),
                       np.array(b.faces)))
    vs, fs, n = [], [], 0
    for v, f in bodies:
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    v, f = np.vstack(vs), np.vstack(fs)
    r = validate_arrays(v, f, check_intersections=False)
    kinds = [b.kind for b in r.bodies]
    assert kinds[:2] == ["solid", "cavity"] and kinds[2:8] == ["solid"] * 6
    assert kinds[8:14] == ["nested solid"] * 6

    def solid_angles_only(points, vertices, faces):
        w, ok = intersect.ray_winding_numbers(points, vertices, faces)
        return w, np.zeros_like(ok)

    monkeypatch.setattr("jampacked.export.nesting.ray_winding_numbers", solid_angles_only)
    ref = validate_arrays(v, f, check_intersections=False)
    a, b = r.as_dict(), ref.as_dict()
    a.pop("seconds")
    b.pop("seconds")
    assert a == b


# ------------------------------------------------------------------------------------------
# the broad phase of the intersection test


def ref_spread_bits(x):
    x = x.astype(np.uint64) & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF),
                        (8, 0x100F00F00F00F00F), (4, 0x10C30C30C30C30C3),
                        (2, 0x1249249249249249)):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def ref_broad_phase(vertices, faces, index, tol_rel=intersect.TOL_REL, leaf_size=4):
    tri = vertices[faces]
    size = np.abs(tri).max()
    pad = 4 * np.finfo(float).eps * max(size, 1e-300)
    lo = tri.min(axis=1) - pad
    hi = tri.max(axis=1) + pad
    reach = tol_rel * float((hi - lo).max())
    lo -= reach
    hi += reach
    centres = 0.5 * (lo[index] + hi[index])
    c_lo = centres.min(axis=0)
    span = np.maximum(centres.max(axis=0) - c_lo, np.finfo(float).tiny)
    q = np.clip(((centres - c_lo) / span * (2**21 - 1)), 0, 2**21 - 1).astype(np.uint64)
    code = (ref_spread_bits(q[:, 0]) << np.uint64(2)) | (ref_spread_bits(q[:, 1])
                                                         << np.uint64(1)) \
        | ref_spread_bits(q[:, 2])
    order = index[np.argsort(code, kind="stable")]
    n = len(order)
    n_leaves = max(1, -(-n // leaf_size))
    p = 1 << max(0, (n_leaves - 1).bit_length())
    node_lo = np.full((2 * p - 1, 3), np.inf)
    node_hi = np.full((2 * p - 1, 3), -np.inf)
    starts = np.arange(0, n, leaf_size)
    node_lo[p - 1:p - 1 + len(starts)] = np.minimum.reduceat(lo[order], starts, axis=0)
    node_hi[p - 1:p - 1 + len(starts)] = np.maximum.reduceat(hi[order], starts, axis=0)
    first = p - 1
    while first > 0:
        parents = np.arange((first - 1) // 2, first)
        node_lo[parents] = np.minimum(node_lo[2 * parents + 1], node_lo[2 * parents + 2])
        node_hi[parents] = np.maximum(node_hi[2 * parents + 1], node_hi[2 * parents + 2])
        first = (first - 1) // 2
    return lo, hi, order, node_lo, node_hi, p


@pytest.mark.parametrize(("name", "v", "f"), MESHES, ids=IDS)
def test_broad_phase_matches_numpy(name, v, f):
    p, mf = _merged(v, f)
    index = np.flatnonzero(np.arange(len(mf)) % 5 != 1)
    lo, hi = intersect._face_boxes(p, mf, intersect.TOL_REL)
    order = intersect._morton_order(lo, hi, index)
    node_lo, node_hi, n_leaves = intersect._build_tree(lo, hi, order, intersect.LEAF_SIZE)
    ref = ref_broad_phase(p, mf, index)
    for got, want in zip((lo, hi, order, node_lo, node_hi, n_leaves), ref, strict=True):
        assert same_bits(got, want)


def test_radix_argsort_is_numpys_stable_argsort():
    rng = np.random.default_rng(6)
    for keys in (rng.integers(0, 2**63, 5000).astype(np.uint64),
                 rng.integers(0, 50, 5000).astype(np.uint64) << np.uint64(40),
                 np.zeros(10, np.uint64), np.zeros(0, np.uint64)):
        assert same_bits(intersect._radix_argsort(keys), np.argsort(keys, kind="stable"))


def _brute_pairs(v, f, active):
    idx = np.flatnonzero(active)
    out = []
    for a in range(len(idx)):
        for b in range(a + 1, len(idx)):
            i, j = idx[a], idx[b]
            if intersect._pair_meets(v, f, min(i, j), max(i, j), intersect.TOL_REL) \
                    or intersect._pair_meets(v, f, max(i, j), min(i, j), intersect.TOL_REL):
                out.append((min(i, j), max(i, j)))
    return out


def test_intersecting_pairs_in_a_thread_agree_with_direct_call():
    s = trimesh.creation.icosphere(subdivisions=2)
    v = np.array(s.vertices)
    v[0] *= -1.3  # a spike through the far side
    f = np.array(s.faces)
    direct = intersect.intersecting_pairs(v, f)
    threaded = intersect.start_intersecting_pairs(v, f)()
    assert direct[1] > 0 and direct[1] == threaded[1]
    assert same_bits(direct[0], threaded[0]) and same_bits(direct[2], threaded[2])
    # every pair found meets; all pairs found by brute force over overlapping boxes
    assert all(intersect._pair_meets(v, f, i, j, intersect.TOL_REL) for i, j in direct[0])
    tri = v[f]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    found = {tuple(p) for p in direct[0].tolist()}
    for i, j in {tuple(p) for p in _brute_pairs(v, f, np.ones(len(f), bool))}:
        if np.all(lo[i] <= hi[j] + 1e-9) and np.all(lo[j] <= hi[i] + 1e-9):
            assert (i, j) in found
    assert intersect.start_intersecting_pairs(v, f[:1])()[1] == 0


# ------------------------------------------------------------------------------------------
# reading 3MF


def _float_tokens(rng: np.random.Generator, n: int) -> list[str]:
    x = rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n)
    bits = rng.integers(0, 2**63, n, dtype=np.uint64)
    anything = bits.view(np.float64)
    tokens = [repr(float(a)) for a in x] + [repr(float(a)) for a in anything
                                             if np.isfinite(a)]
    digits = np.array(list("0123456789"))
    for _ in range(n):
        s = "".join(rng.choice(digits, rng.integers(1, 22)))
        dot = int(rng.integers(0, len(s) + 1))
        s = s[:dot] + "." + s[dot:] if rng.random() < 0.7 else s
        if rng.random() < 0.5:
            s += rng.choice(["e", "E"]) + rng.choice(["", "+", "-"]) \
                + str(int(rng.integers(0, 330)))
        s = rng.choice(["", "-", "+"]) + s
        tokens.append("0" if s.strip("+-") == "." else s)
    from decimal import Decimal, getcontext
    getcontext().prec = 60
    for a in x[:500]:  # halfway between two doubles, and just off it
        a = abs(float(a)) or 1.0
        mid = (Decimal(a) + Decimal(float(np.nextafter(a, np.inf)))) / 2
        tokens += [format(mid, f".{k}e") for k in (16, 17, 18, 19, 25)]
    tokens += ["1.", ".5", "+1", "1E5", "-0", "-0.0", "0e0", "00012.5000", "1e-5", "5e-324",
               "1.7976931348623157e308", "2.2250738585072014e-308", "1e400", "1e-400",
               "9007199254740993", "123456789012345678901", "0.000000000000000000001"]
    return tokens


def _model(vertex_lines: list[str], triangle_lines: list[str], sep: str = "\n") -> bytes:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" '
            f'xmlns="{threemf.CORE_NAMESPACE}">\n<resources>\n<object id="1" type="model">\n'
            f"<mesh>{sep}<vertices>{sep}" + sep.join(vertex_lines) + f"{sep}</vertices>{sep}"
            f"<triangles>{sep}" + sep.join(triangle_lines) + f"{sep}</triangles>{sep}</mesh>\n"
            '</object>\n</resources>\n<build>\n<item objectid="1"/>\n</build>\n</model>\n'
            ).encode()


def _package(model: bytes) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("[Content_Types].xml", threemf.CONTENT_TYPES)
        archive.writestr("_rels/.rels", threemf.RELATIONSHIPS)
        archive.writestr("3D/3dmodel.model", model)
    return buffer.getvalue()


def _general_read(model: bytes) -> tuple[np.ndarray, np.ndarray]:
    """The reference read: the standard library's XML parser, Python's float() and int()."""
    from xml.etree import ElementTree

    root = ElementTree.fromstring(model)
    ns = {"m": threemf.CORE_NAMESPACE}
    v = [[float(e.get(a)) for a in "xyz"] for e in root.iterfind(".//m:vertex", ns)]
    f = [[int(e.get(a)) for a in ("v1", "v2", "v3")]
         for e in root.iterfind(".//m:triangle", ns)]
    v = np.array(v, dtype=np.float64).reshape(-1, 3)
    m = np.eye(4)  # the build item's transform: the identity
    return v @ m[:3, :3].T + m[:3, 3], np.array(f, dtype=np.int64).reshape(-1, 3)


@pytest.mark.filterwarnings("ignore:invalid value encountered in matmul")  # 1e400 * 0
@pytest.mark.parametrize("case", ["plain", "odd numbers", "spacing", "attribute order",
                                  "float indices", "single line", "bad number"])
def test_3mf_reader_reads_numbers_as_python_does(case):
    rng = np.random.default_rng(9)
    tokens = _float_tokens(rng, 300)[:900]
    vertex_lines = [f'<vertex x="{a}" y="{b}" z="{c}"/>'
                    for a, b, c in zip(tokens[0::3], tokens[1::3], tokens[2::3], strict=True)]
    n = len(vertex_lines)
    tri = rng.integers(0, n, size=(400, 3))
    triangle_lines = [f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in tri]
    sep = "\n"
    if case == "plain":
        v = rng.standard_normal((n, 3)) * 50
        vertex_lines = [f'<vertex x="{a!r}" y="{b!r}" z="{c!r}"/>' for a, b, c in v.tolist()]
    elif case == "spacing":
        vertex_lines[5] = vertex_lines[5].replace('" y', '"  y')
        sep = "\r\n\t "
    elif case == "attribute order":
        triangle_lines[3] = '<triangle v2="1" v1="2" v3="0"/>'
    elif case == "float indices":
        triangle_lines[3] = '<triangle v1="1.0" v2="2" v3="0"/>'
    elif case == "single line":
        sep = ""
    elif case == "bad number":
        vertex_lines[7] = '<vertex x="1.2.3" y="0" z="0"/>'
    model = _model(vertex_lines, triangle_lines, sep)
    if case == "bad number":
        with pytest.raises(threemf.ThreeMFError, match="cannot be read"):
            threemf.read_3mf(_package(model))
        return
    got = threemf.read_3mf(_package(model))
    if case == "float indices":  # an integral decimal index is read as that integer
        model = model.replace(b'v1="1.0"', b'v1="1"')
    want = _general_read(model)
    assert same_bits(got[0], want[0]) and same_bits(got[1], want[1])
    assert got[1].dtype == np.int64


def test_3mf_written_bodies_read_back_exactly(tmp_path):
    rng = np.random.default_rng(10)
    bodies = []
    for k in range(3):
        s = trimesh.creation.icosphere(subdivisions=2, radius=1.0 + k)
        v = np.array(s.vertices) * rng.uniform(0.5, 2.0) + rng.normal(size=3) * 100
        v[0, 0] = -0.0
        bodies.append((v, np.array(s.faces)))
    path = tmp_path / "bodies.3mf"
    mesh_io.write_mesh(path, bodies, validate=False)
    v, f = mesh_io.read_mesh_arrays(path)
    offsets = np.cumsum([0] + [len(bv) for bv, _ in bodies[:-1]])
    assert same_bits(v, np.concatenate([bv + 0.0 for bv, _ in bodies]))
    assert same_bits(f, np.concatenate([bf + o for (_, bf), o in zip(bodies, offsets,
                                                                    strict=True)]))


def test_small_trees_find_what_brute_force_finds():
    """Meshes of 2 to 40 faces (a single leaf, or a few): every pair with overlapping boxes
    is tested, in either orientation the tree puts them."""
    rng = np.random.default_rng(11)
    for n in (2, 3, 4, 5, 9, 17, 40):
        v = rng.normal(size=(3 * n, 3))
        f = np.arange(3 * n).reshape(-1, 3)
        f[1::2, 0] = f[0::2, 0][: len(f[1::2])]  # some pairs share a vertex
        pairs, total, hits = intersect.intersecting_pairs(v, f)
        assert total == len(pairs) and hits.sum() == 2 * total
        tri = v[f]
        lo, hi = tri.min(axis=1), tri.max(axis=1)
        for i in range(n):
            for j in range(i + 1, n):
                overlap = np.all(lo[i] <= hi[j]) and np.all(lo[j] <= hi[i])
                meets = intersect._pair_meets(v, f, i, j, intersect.TOL_REL) \
                    and intersect._pair_meets(v, f, j, i, intersect.TOL_REL)
                apart = not intersect._pair_meets(v, f, i, j, intersect.TOL_REL) \
                    and not intersect._pair_meets(v, f, j, i, intersect.TOL_REL)
                if overlap and meets:
                    assert [i, j] in pairs.tolist()
                if apart:
                    assert [i, j] not in pairs.tolist()


def test_manifold3d_can_be_skipped():
    s = trimesh.creation.icosphere(subdivisions=2)
    full = validate_arrays(s.vertices, s.faces)
    quick = validate_arrays(s.vertices, s.faces, check_manifold3d=False)
    assert full.manifold_status == "NoError" and quick.manifold_status == "skipped"
    a, b = full.as_dict(), quick.as_dict()
    for d in (a, b):
        d.pop("seconds")
        d.pop("manifold_status")
    assert a == b and quick.passed


def _side_reference(a, b, c, tol):
    """intersect._side as it was: with the square root always."""
    ex, ey = b[0] - a[0], b[1] - a[1]
    o = ex * (c[1] - a[1]) - ey * (c[0] - a[0])
    if abs(o) <= tol * math.sqrt(ex * ex + ey * ey):
        return 0
    return 1 if o > 0 else -1


def test_side_without_square_roots_decides_as_before():
    rng = np.random.default_rng(12)
    for scale in (1e-150, 1e-20, 1.0, 1e3, 1e150):
        for _ in range(3000):
            a = tuple(rng.normal(size=2) * scale)
            b = tuple(np.array(a) + rng.normal(size=2) * scale * 10.0 ** rng.uniform(-3, 1))
            e = np.array(b) - np.array(a)
            length = float(np.hypot(*e))
            tol = scale * 10.0 ** rng.uniform(-12, 0)
            # the point at a distance near the tolerance from the line, either side
            normal = np.array([-e[1], e[0]]) / max(length, 1e-300)
            dist = tol * rng.choice([rng.uniform(0.5, 2.0), 1.0, 0.99, 1.5, 1 / 1.4142])
            c = tuple(np.array(a) + e * rng.uniform(-1, 2) + normal * dist * rng.choice([-1, 1]))
            assert intersect._side(a, b, c, tol) == _side_reference(a, b, c, tol)
    assert intersect._side((0.0, 0.0), (1.0, 0.0), (0.5, 0.0), 0.0) == 0
    assert intersect._side((0.0, 0.0), (1.0, 0.0), (0.5, 1e-300), 0.0) == 1


@pytest.mark.parametrize("spare", [True, False])
def test_report_is_the_same_with_and_without_the_thread(monkeypatch, spare):
    """The intersection test in a thread beside manifold3d, or before it: one report."""
    s = trimesh.creation.icosphere(subdivisions=3)
    v = np.array(s.vertices)
    v[0] *= -1.3
    b = trimesh.creation.box()
    vv, ff = np.vstack([v, np.array(b.vertices) * 0.3]), np.vstack([s.faces, b.faces + len(v)])
    monkeypatch.setattr("jampacked.export.validate.spare_core", lambda: spare)
    r = validate_arrays(vv, ff)
    monkeypatch.setattr("jampacked.export.validate.spare_core", lambda: not spare)
    ref = validate_arrays(vv, ff)
    assert r.intersecting_pairs > 0 and "self_intersections" in r.seconds
    a, b = r.as_dict(max_indices=None), ref.as_dict(max_indices=None)
    a.pop("seconds")
    b.pop("seconds")
    assert a == b


def test_identity_transform_shortcut_is_the_product():
    """read_3mf adds 0.0 where the transform is the identity: what the product gives."""
    rng = np.random.default_rng(13)
    v = rng.normal(size=(3000, 3)) * 10.0 ** rng.integers(-300, 300, size=(3000, 1))
    v[::5, 0] = -0.0
    v[::7] = 0.0
    v[::11, 1] = -0.0
    v[::13] = [5e-324, -5e-324, -0.0]
    m = np.eye(4)
    assert same_bits(v + 0.0, v @ m[:3, :3].T + m[:3, 3])


def ref_zero_area(p, f):
    """export/cleanup.py's zero-area test before its kernel."""
    from jampacked.export.validate import DEGENERATE_REL

    tri = p[f]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    longest = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1)
    diagonal = float(np.linalg.norm(np.ptp(p, axis=0)))
    return area2 <= DEGENERATE_REL * diagonal * longest


def test_zero_area_kernel_matches_numpy():
    from jampacked.export.cleanup import _zero_area

    rng = np.random.default_rng(5)
    p = rng.normal(size=(2000, 3)) * 50.0
    f = rng.integers(0, 2000, (20000, 3))
    f[:50, 2] = f[:50, 1]  # a repeated corner
    t = rng.random((50, 1))  # corners on one line, and a hair off it
    p[f[50:100, 2]] = p[f[50:100, 0]] * t + p[f[50:100, 1]] * (1 - t)
    p[f[75:100, 2]] += 1e-9 * rng.normal(size=(25, 3))
    pear = mesh_path("fruit/ycb/016_pear.ply")
    m = trimesh.load(pear, process=False)
    for pos, faces in ((p, f), (p.astype(np.float32).astype(np.float64), f),
                       (np.asarray(m.vertices) * 250.0, np.asarray(m.faces, np.int64))):
        got = _zero_area(pos, faces)
        np.testing.assert_array_equal(got, ref_zero_area(pos, faces))
    zero = ref_zero_area(p, f)  # the cases are there: repeated corners, corners on a line
    assert zero[:50].all() and zero[50:75].sum() >= 20
