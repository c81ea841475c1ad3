"""Phase 1's wall layer (`core/wall_layer.py`): seeds on the wall's offset, the lattice
behind them, and objects turned flat side to the wall."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial.distance import cdist
from testdata import mesh_path

from jampacked.core.api import pack
from jampacked.core.container import build_container
from jampacked.core.options import PackOptions, WallLayerOptions
from jampacked.core.rotations import quat_to_matrix
from jampacked.core.wall_layer import (
    flattest_direction,
    layered_seeds,
    offset_points,
    poisson_disk,
    wall_quaternion,
)

HALF = 10.0


def box_container():
    b = trimesh.creation.box(extents=(2 * HALF,) * 3)
    return build_container(b.vertices, b.faces, float(b.volume), 0.5)


def test_poisson_disk_keeps_points_apart_and_leaves_no_gap():
    pts = np.random.default_rng(0).random((400, 3)) * 10
    keep = poisson_disk(pts, 1.5, np.arange(400))
    d = cdist(pts[keep], pts[keep])
    np.fill_diagonal(d, np.inf)
    assert d.min() > 1.5
    # every dropped point is within the radius of a kept one (the thinning is maximal)
    assert cdist(pts, pts[keep]).min(axis=1).max() <= 1.5
    assert keep[0] == 0  # the first point visited is always kept


def test_offset_points_lie_at_the_depth_with_outward_normals():
    c = box_container()
    pts, normals = offset_points(c, 3.0, 4.0, np.random.default_rng(1))
    assert len(pts) > 20
    depth = HALF - np.abs(pts).max(axis=1)  # a point's distance to the box's nearest face
    assert np.abs(depth - 3.0).max() < 0.3
    d = cdist(pts, pts)
    np.fill_diagonal(d, np.inf)
    assert d.min() > 4.0
    # away from the box's edges the normal is the nearest face's outward normal
    flat = np.sort(np.abs(pts), axis=1)
    face = flat[:, 2] - flat[:, 1] > 1.0
    assert face.sum() > 5
    axis = np.argmax(np.abs(pts), axis=1)
    expected = np.zeros_like(pts)
    expected[np.arange(len(pts)), axis] = np.sign(pts[np.arange(len(pts)), axis])
    assert np.abs(normals[face] - expected[face]).max() < 0.05


def test_layered_seeds_put_the_lattice_behind_the_layer():
    c = box_container()
    s = layered_seeds(c, 4.0, 0.1, 3.0, 4.0, np.random.default_rng(2))
    wall = s.wall
    assert 0 < wall.sum() < len(s.points)
    assert len(s.normals) == len(s.spin) == len(s.points)
    assert not np.all(wall[: wall.sum()])  # mixed order
    inner = s.points[~wall]
    assert (HALF - np.abs(inner).max(axis=1)).min() >= 3.0
    assert cdist(inner, s.points[wall]).min() >= 4.0
    flat = np.array([1.0, 0, 0])
    assert s.orientation(int(np.flatnonzero(~wall)[0]), flat) is None  # a lattice seed
    assert s.orientation(int(np.flatnonzero(wall)[0]), None) is None
    assert s.orientation(int(np.flatnonzero(wall)[0]), flat) is not None
    first = layered_seeds(c, 4.0, 0.1, 3.0, 4.0, np.random.default_rng(2), wall_first=True)
    n = int(first.wall.sum())
    assert np.all(first.wall[:n]) and not np.any(first.wall[n:])


def test_flattest_direction_is_the_nearest_face_of_a_box():
    b = trimesh.creation.box(extents=(1.0, 2.0, 4.0))
    d = flattest_direction(np.asarray(b.vertices))
    assert np.allclose(np.abs(d), [1.0, 0.0, 0.0])


def test_wall_quaternion_turns_the_direction_onto_the_normal():
    rng = np.random.default_rng(3)
    for _ in range(20):
        flat, normal = rng.normal(size=(2, 3))
        flat /= np.linalg.norm(flat)
        normal /= np.linalg.norm(normal)
        spin = rng.random() * 6
        q = wall_quaternion(flat, normal, spin)
        assert abs(np.linalg.norm(q) - 1) < 1e-12 and q[0] >= 0
        r = quat_to_matrix(q[None])[0]
        assert np.allclose(r @ flat, normal, atol=1e-9)
    # the spin turns about the normal: the same direction, other rotations
    a = quat_to_matrix(wall_quaternion(flat, normal, 0.0)[None])[0]
    b = quat_to_matrix(wall_quaternion(flat, normal, 1.0)[None])[0]
    assert not np.allclose(a, b)


def test_pack_with_the_wall_layer_is_certified_and_repeats(tmp_path):
    poly = [str(mesh_path("polyhedra/convex5/polytope1.obj")),
            str(mesh_path("polyhedra/convex5/polytope3.obj"))]
    options = PackOptions(wall=WallLayerOptions(layer=True))
    a = pack("box:22x20x24", poly, seed=2, fidelity="low", options=options)
    b = pack("box:22x20x24", poly, seed=2, fidelity="low", options=options)
    off = pack("box:22x20x24", poly, seed=2, fidelity="low")
    assert a.certificate["certified"]
    assert a.n > 0 and a.n == b.n
    assert np.array_equal(a.translations, b.translations)
    assert not (a.n == off.n and np.allclose(a.translations, off.translations))
