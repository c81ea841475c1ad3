"""The rigid-body peer benchmark (bench/peer_bullet.py): its counting with pack()'s
certification and its spawning need no Blender; a short pour in real Blender (bpy) runs
where bpy is installed and is skipped elsewhere."""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest
from testdata import bench_module


def _load():
    return bench_module("peer_bullet")


pb = _load()


def _cube(edge: float) -> tuple[np.ndarray, np.ndarray]:
    from jampacked.core.meshes import box_mesh

    m = box_mesh((edge, edge, edge))
    return m.vertices, m.faces


def _octahedron(r: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.array([[r, 0, 0], [-r, 0, 0], [0, r, 0], [0, -r, 0], [0, 0, r], [0, 0, -r]], float)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                  [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return v, f


def _placed(centres) -> np.ndarray:
    m = np.tile(np.eye(4), (len(centres), 1, 1))
    m[:, :3, 3] = centres
    return m


@pytest.fixture(scope="module")
def box_scene():
    """A 40 mm box container with two types: a 10 mm cube and an octahedron (radius 6)."""
    cv, cf = _cube(40.0)
    geom = pb.make_geometry(cv, cf, [_cube(10.0), _octahedron(6.0)], names=["cube", "oct"])
    _, certifier = pb.build_certifier(geom, grid_spacing=1.0)
    return geom, certifier


def test_counting_overlap_escape_and_wall(box_scene):
    geom, certifier = box_scene
    typ = np.array([0, 0, 0, 0, 0, 1])
    mats = _placed([[0, 0, 0],  # 0 and 1 overlap by half a cube
                    [5, 0, 0],
                    [0, 0, 12],  # clean
                    [100, 0, 0],  # escaped: far outside
                    [-12, 0, 17],  # through the wall: 2 of its 10 mm outside (20%)
                    [-12, 0, -12]])  # octahedron, clean
    c = pb.certify_placements(geom, certifier, typ, mats)
    assert c["objects"] == 6
    assert c["escaped"] == 1 and c["escaped_indices"] == [3]
    assert c["inside"] == 5
    assert c["overlapping_pairs"] == 1
    assert c["worst_overlap"] == pytest.approx(0.5, rel=1e-3)
    assert c["through_wall"] == 1
    assert c["worst_outside"] == pytest.approx(0.2, rel=1e-3)
    assert c["worst_outside_incl_escaped"] == pytest.approx(1.0)
    assert not c["certified_as_is"]
    # offenders removed as pack() removes them: the second of an equal pair, the wall one
    assert c["removed"] == 2
    assert c["kept_indices"] == [0, 2, 5]
    assert c["certificate_after_removal"]["certified"]
    vol = geom.type_volumes
    assert c["certified_density"] == pytest.approx((2 * vol[0] + vol[1]) / 40.0 ** 3)
    assert c["raw_density"] == pytest.approx((4 * vol[0] + vol[1]) / 40.0 ** 3)


def test_counting_clean_placement(box_scene):
    geom, certifier = box_scene
    c = pb.certify_placements(geom, certifier, np.array([0, 1]), _placed([[-8, 0, 0], [8, 0, 0]]))
    assert c["certified_as_is"]
    assert c["escaped"] == c["overlapping_pairs"] == c["through_wall"] == c["removed"] == 0
    assert c["certified_density"] == c["raw_density"]


def test_removals_match_pack():
    vols = np.array([1.0, 2.0])
    typ = np.array([0, 1, 0])
    # the smaller of a pair goes; a pair whose member is already gone removes nothing more
    keep, _ = pb.removals(typ, vols, [(0, 1), (0, 2)], [])
    assert keep.tolist() == [False, True, True]
    assert pb.removals(typ, vols, [], [1])[0].tolist() == [True, False, True]


def test_winding_numbers():
    cv, cf = _cube(2.0)
    w = pb.winding_numbers(cv, cf, np.array([[0, 0, 0], [0.9, 0.9, -0.9], [3, 0, 0]]))
    assert w == pytest.approx([1.0, 1.0, 0.0], abs=1e-9)


def test_spawns_are_free_and_poured(box_scene):
    from jampacked.core.container import interior_points

    geom, certifier = box_scene
    container = certifier.container
    hulls = pb.type_hulls(geom)
    rng = np.random.default_rng(0)
    cand = interior_points(container, 3.0, float(hulls.r_in.min()) + 0.5, rng)
    counts = np.zeros(2, np.int64)
    spawns = pb.choose_spawns(geom, hulls, container, cand, [], np.zeros((0, 4, 4)), counts, rng,
                              batch=20, margin=0.5, max_tvd=0.0)
    assert 2 <= len(spawns) <= 20
    typ = np.array([t for t, _ in spawns])
    mats = np.array([m for _, m in spawns])
    assert counts.tolist() == np.bincount(typ, minlength=2).tolist()
    assert abs(int(counts[0]) - int(counts[1])) <= 1  # the mix is kept (max_tvd 0)
    c = pb.certify_placements(geom, certifier, typ, mats)
    assert c["certified_as_is"]
    # a second pour puts nothing under what is there (nothing directly above a new spawn)
    more = pb.choose_spawns(geom, hulls, container, cand, typ, mats, counts.copy(), rng,
                            batch=20, margin=0.5)
    for t, m in more:
        assert not pb.covered(hulls, geom.up, m[:3, 3], t, typ, mats)
    both = np.concatenate([mats, [m for _, m in more]]) if more else mats
    assert pb.certify_placements(geom, certifier, np.concatenate(
        [typ, [t for t, _ in more]]).astype(int), both)["certified_as_is"]


def test_covered():
    cv, cf = _cube(100.0)
    geom = pb.make_geometry(cv, cf, [_cube(10.0)])
    hulls = pb.type_hulls(geom)
    top = _placed([[0, 20, 0]])
    assert pb.covered(hulls, geom.up, np.array([0.0, 0, 0]), 0, [0], top)  # right under
    assert pb.covered(hulls, geom.up, np.array([4.0, 0, 0]), 0, [0], top)  # under an edge
    assert not pb.covered(hulls, geom.up, np.array([12.0, 0, 0]), 0, [0], top)  # beside
    assert not pb.covered(hulls, geom.up, np.array([0.0, 40, 0]), 0, [0], top)  # above


def test_mix_allows():
    q = np.array([0.5, 0.5])
    assert pb.mix_allows(np.array([3, 5]), q, 0, 0.0)  # the type furthest below its share
    assert not pb.mix_allows(np.array([3, 5]), q, 1, 0.1)
    assert pb.mix_allows(np.array([50, 50]), q, 1, 0.01)


def test_bullet_pour_in_blender(box_scene):
    """A 6-second pour of the two types into the box in real Blender: fruit are spawned,
    fall, stay inside, and come back in the container frame."""
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="jampacked-blender-"))
    pytest.importorskip("bpy")
    geom, certifier = box_scene
    params = pb.BulletParams(batch=4, spawn_every=6, max_settle_frames=48)
    run = pb.run_bullet(geom, certifier.container, params, seed=0, time_cap=6.0,
                        log=lambda msg: None)
    n = run["spawned"]
    assert n >= 4 and len(run["type_index"]) == n and run["matrices"].shape == (n, 4, 4)
    assert run["frames"] > 6 and run["timeline"][0]["event"] == "pour"
    rot = run["matrices"][:, :3, :3]
    assert np.allclose(rot @ rot.transpose(0, 2, 1), np.eye(3), atol=1e-6)
    c = pb.certify_placements(geom, certifier, run["type_index"], run["matrices"])
    assert c["escaped"] == 0
    # everything fell: the lowest fruit rests near the floor (box from -20 to 20 along y)
    low = run["matrices"][:, 1, 3].min()
    assert low < -20 + 2 * float(geom.type_radius.max())
