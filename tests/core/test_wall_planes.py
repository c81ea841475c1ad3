"""The crease cells' face planes: never more room than the container has, and the room the
grid's interpolant misses along a box's edges and corners (`core/wall_planes.py`)."""

from __future__ import annotations

import manifold3d as m3
import numpy as np
import pytest
import trimesh

from jampacked.core import kernels
from jampacked.core.container import build_container
from jampacked.core.kernels import sample_grid_many
from jampacked.core.meshes import box_mesh
from jampacked.core.wall_planes import REACH_CELLS, crease_planes, face_planes


def _l_shape() -> trimesh.Trimesh:
    """An L-shaped prism: two boxes joined, so its inner edge is a reflex one."""
    a = m3.Manifold.cube([30.0, 10.0, 12.0])
    b = m3.Manifold.cube([10.0, 25.0, 12.0])
    mesh = (a + b).to_mesh()
    return trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts))


def _containers() -> dict[str, trimesh.Trimesh]:
    box = trimesh.creation.box(extents=(23.0, 17.0, 13.0))
    turned = box.copy()
    turned.apply_transform(trimesh.transformations.random_rotation_matrix(
        np.random.default_rng(5).random(3)))
    inward = box.copy()
    inward.faces = inward.faces[:, ::-1]  # a closed mesh wound inward, as a caller may pass
    return {"box": box, "turned box": turned, "L": _l_shape(),
            "cylinder": trimesh.creation.cylinder(radius=9.0, height=14.0, sections=24),
            "box wound inward": inward}


def _outward(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    return trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1], process=False)


def _near_wall_points(mesh: trimesh.Trimesh, h: float, rng: np.random.Generator) -> np.ndarray:
    """Points from 1.5 cells outside to REACH_CELLS + 1 inside the wall, crowded towards
    the edges and corners (where the creases are), and some anywhere in the box."""
    on, face = trimesh.sample.sample_surface(mesh, 3000, seed=int(rng.integers(1 << 30)))
    depth = rng.uniform(-1.5 * h, (REACH_CELLS + 1) * h, len(on))
    pts = on - mesh.face_normals[face] * depth[:, None]
    corners = mesh.vertices[rng.integers(0, len(mesh.vertices), 1500)]
    near_corner = corners + rng.normal(scale=1.5 * h, size=corners.shape)
    lo, hi = mesh.bounds
    return np.concatenate([pts, near_corner, rng.uniform(lo - h, hi + h, (1500, 3))])


def _signed_distance(mesh: trimesh.Trimesh, pts: np.ndarray) -> np.ndarray:
    """Exact signed distance (positive inside): the nearest point over every triangle, and
    the side by the winding number (solid angles, Van Oosterom and Strackee)."""
    tri = mesh.triangles
    out = np.empty(len(pts))
    for s in range(0, len(pts), 200):
        p = pts[s:s + 200]
        near = trimesh.triangles.closest_point(np.tile(tri, (len(p), 1, 1)),
                                               np.repeat(p, len(tri), axis=0))
        dist = np.linalg.norm(near - np.repeat(p, len(tri), axis=0), axis=1)
        r = tri[None] - p[:, None, None, :]  # (P, F, 3, 3)
        n = np.linalg.norm(r, axis=-1)
        det = np.einsum("pfi,pfi->pf", r[:, :, 0], np.cross(r[:, :, 1], r[:, :, 2]))
        dots = (n[..., 0] * n[..., 1] * n[..., 2]
                + np.einsum("pfi,pfi->pf", r[:, :, 0], r[:, :, 1]) * n[..., 2]
                + np.einsum("pfi,pfi->pf", r[:, :, 1], r[:, :, 2]) * n[..., 0]
                + np.einsum("pfi,pfi->pf", r[:, :, 2], r[:, :, 0]) * n[..., 1])
        winding = np.arctan2(det, dots).sum(axis=1) / (2.0 * np.pi)
        out[s:s + 200] = np.where(winding > 0.5, 1.0, -1.0) * dist.reshape(len(p), -1).min(axis=1)
    return out


@pytest.mark.parametrize("name", sorted(_containers()))
def test_the_planes_never_read_more_room_than_there_is(name):
    mesh = _containers()[name]
    rng = np.random.default_rng(11)
    cont = build_container(mesh.vertices, mesh.faces, abs(float(mesh.volume)), 1.3)
    assert len(cont.creases.cells)  # each of these has creases the grid under-reads
    g = cont.grid
    pts = _near_wall_points(mesh, g.spacing, rng)
    grid = sample_grid_many(g.values, g.origin, g.spacing, pts)
    depth = cont.depth(pts)
    assert (depth >= grid).all()  # the planes only ever add room
    raised = depth > grid
    assert raised.sum() > 50
    # only points inside are raised (outside, a plane reads a corner's depth short), and
    # never beyond their true depth
    true = _signed_distance(mesh if mesh.volume > 0 else _outward(mesh), pts[raised])
    assert (true >= -1e-9).all() and (depth[raised] <= true + 1e-9).all()


def test_a_box_reads_its_exact_depth_by_its_edges_and_corners():
    # the crate of the independent check: 1.55 mm cells, a point 0.6 mm from three walls
    # read 0.057 mm, one 0.6 mm from two 0.193 mm (docs/notes-core.md)
    m = box_mesh([101.0, 61.0, 51.0])
    cont = build_container(m.vertices, m.faces, float(m.volume), 1.551)
    g = cont.grid
    pts = np.array([[49.9, 29.9, 24.9], [0.0, 29.9, 24.9], [45.0, 25.0, 20.0]])
    exact = np.array([0.6, 0.6, 5.5])
    assert (sample_grid_many(g.values, g.origin, g.spacing, pts) < exact - 0.3).all()
    np.testing.assert_allclose(cont.depth(pts), exact, rtol=0, atol=1e-9)


def test_the_push_by_an_edge_turns_smoothly_across_its_bisector():
    # the planes' depth came with the nearest plane's normal, which flips by 90 degrees
    # across an edge's bisector: an object in a corner was pushed off one wall at a time,
    # grew into its room less often, and nonconvex10-box lost 3 points (docs/notes-core.md)
    m = box_mesh([101.0, 61.0, 51.0])
    cont = build_container(m.vertices, m.faces, float(m.volume), 1.551)
    g = cont.grid
    nx, ny, nz = g.values.shape
    # 1 mm from the x and y walls' edge, across its bisector, in steps of 0.028 mm
    t = np.linspace(-0.3, 0.3, 31)
    pts = np.stack([49.5 + t, 29.5 - t, np.full_like(t, 3.0)], axis=1)
    assert cont.creases.index[_cell(g, pts[15])] >= 0  # the planes read there
    grads = np.array([kernels.wall_depth(g.values.ravel(), nx, ny, nz, g.origin, g.spacing,
                                         *cont.creases.arrays(), *p)[1:] for p in pts])
    unit = grads / np.linalg.norm(grads, axis=1, keepdims=True)
    turn = np.degrees(np.arccos(np.clip((unit[1:] * unit[:-1]).sum(axis=1), -1.0, 1.0)))
    assert turn.max() < 10.0, turn.max()
    np.testing.assert_allclose(cont.depth(pts), 1.0 - np.abs(t), atol=1e-9)


def _cell(g, p: np.ndarray) -> int:
    """The dense index of the grid cell holding point p (3,)."""
    n = np.array(g.values.shape)
    i, j, k = np.minimum(((p - g.origin) / g.spacing).astype(np.int64), n - 2)
    return int((i * (n[1] - 1) + j) * (n[2] - 1) + k)


def test_smooth_scans_keep_the_grid_alone():
    # a curved wall is near more planes than a cell keeps, and its interpolant is near the
    # truth: no crease cells, so the solver reads the grid as before
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=20.0)
    cont = build_container(sphere.vertices, sphere.faces, float(sphere.volume), 1.5)
    assert len(cont.creases.cells) == 0
    pts = np.random.default_rng(2).uniform(-21, 21, (2000, 3))
    g = cont.grid
    np.testing.assert_array_equal(cont.depth(pts),
                                  sample_grid_many(g.values, g.origin, g.spacing, pts))


def test_coplanar_faces_share_one_plane_and_degenerate_faces_none():
    box = box_mesh([4.0, 3.0, 2.0])
    faces = np.concatenate([box.faces, [[0, 0, 1]]])  # a zero-area face
    plane_of, planes = face_planes(box.vertices, faces)
    assert len(planes) == 6 and plane_of[-1] == -1
    np.testing.assert_allclose(np.abs(planes[:, :3]).sum(axis=1), 1.0)
    centre_depth = planes[:, 3]  # the box's centre is the origin
    np.testing.assert_allclose(np.sort(centre_depth), [1.0, 1.0, 1.5, 1.5, 2.0, 2.0])


def test_a_grid_too_small_for_a_cell_has_no_creases():
    box = box_mesh([1.0, 1.0, 1.0])
    planes = crease_planes(box.vertices, box.faces, np.zeros((1, 4, 4)), np.zeros(3), 1.0)
    assert len(planes.cells) == 0
