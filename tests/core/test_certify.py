"""Tests for jampacked.core.certify: exact checks on meshes, with bounds and depths computed
a type at a time in chunks (checked against a per-object numpy reference)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core import certify, exact_checks
from jampacked.core.certify import Certifier
from jampacked.core.container import GRID_BAND, build_container
from jampacked.core.kernels import sample_grid_many
from jampacked.core.rotations import quat_to_matrix


@pytest.fixture(scope="module")
def certifier():
    box = trimesh.creation.box(extents=(30.0, 30.0, 30.0))
    cont = build_container(box.vertices, box.faces, float(box.volume), 1.0)
    a = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    b = trimesh.creation.icosphere(subdivisions=2, radius=1.5)
    meshes = [a, b]
    return Certifier(cont, [np.asarray(m.vertices) for m in meshes],
                     [np.asarray(m.faces) for m in meshes],
                     np.array([m.volume for m in meshes]),
                     np.array([m.edges_unique_length.max() for m in meshes]))


def _matrices(rng, pos):
    q = rng.normal(size=(len(pos), 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    m = np.tile(np.eye(4), (len(pos), 1, 1))
    m[:, :3, :3] = quat_to_matrix(q)
    m[:, :3, 3] = pos
    return m


@pytest.mark.parametrize("chunk", [1 << 20, 100])  # one chunk per type, or several
def test_bounds_and_depth_match_each_objects_vertices(certifier, monkeypatch, chunk):
    monkeypatch.setattr(certify, "CHUNK_VERTICES", chunk)
    rng = np.random.default_rng(7)
    n = 40
    typ = rng.integers(0, 2, n)
    m = _matrices(rng, rng.uniform(-16, 16, (n, 3)))
    lo, hi, depth = certifier._bounds_and_depth(typ, m)
    g = certifier.container.grid
    for i in range(n):
        world = certifier.vertices[typ[i]] @ m[i, :3, :3].T + m[i, :3, 3]
        np.testing.assert_allclose(lo[i], world.min(axis=0), rtol=0, atol=1e-12)
        np.testing.assert_allclose(hi[i], world.max(axis=0), rtol=0, atol=1e-12)
        # nodes beyond the grid's exact band read as the band's depth
        clipped = np.minimum(g.values, GRID_BAND * g.spacing)
        ref = sample_grid_many(clipped, g.origin, g.spacing, world).min()
        assert depth[i] == pytest.approx(ref, abs=1e-9)


def test_certify_finds_overlaps_and_objects_through_the_wall(certifier):
    rng = np.random.default_rng(8)
    # a grid of separated objects, then one overlapping pair and one through the wall
    pos = np.array([[x, y, z] for x in (-8.0, 0.0, 8.0) for y in (-8.0, 0.0, 8.0)
                    for z in (-8.0, 8.0)])
    typ = np.arange(len(pos)) % 2
    m = _matrices(rng, pos)
    rep = certifier.certify(typ, m)
    assert rep.certified and rep.worst_overlap == 0.0 and rep.bad_wall == []
    m2 = m.copy()
    m2[1, :3, 3] = m[0, :3, 3] + [0.5, 0.0, 0.0]  # objects 0 and 1 overlap
    m2[5, :3, 3] = [14.5, 0.0, 0.0]  # object 5 pokes out of the box
    rep = certifier.certify(typ, m2)
    assert not rep.certified
    assert rep.bad_pairs == [(0, 1)] and rep.bad_wall == [5]
    assert rep.worst_overlap > 0.1 and rep.worst_outside > 0.1
    # with a subset, only checks involving it run
    rep = certifier.certify(typ, m2, subset=np.array([5]))
    assert rep.bad_pairs == [] and rep.bad_wall == [5]


def _reference(certifier, typ, m, clearance):
    """Every pair and wall, each solid made afresh, every boolean run and min_gap searched to
    twice the clearance (the checks before solids were kept and booleans skipped)."""
    solids = [certifier.solids.types[t].transform(m[i, :3, :4].tolist()) for i, t in enumerate(typ)]
    vol = certifier.volumes[typ]
    pairs, overlap, gaps = set(), 0.0, []
    for i in range(len(typ)):
        for j in range(i + 1, len(typ)):
            ratio = (solids[i] ^ solids[j]).volume() / min(vol[i], vol[j])
            gap = solids[i].min_gap(solids[j], 2 * clearance)
            overlap = max(overlap, ratio)
            gaps.append(gap)
            if ratio > certify.DEFAULT_TOL or gap < clearance * (1 - 1e-6):
                pairs.add((i, j))
    walls = {i for i, s in enumerate(solids)
             if (s ^ certifier.solids.outside).volume() / vol[i] > certify.DEFAULT_TOL
             or s.min_gap(certifier.solids.outside, 2 * clearance) < clearance * (1 - 1e-6)}
    return pairs, walls, overlap, min(gaps)


def _clearance_scene():
    """Separated objects, two at gaps just under and over the clearance, an overlapping pair
    and one object through the wall (clearance 0.5)."""
    rng = np.random.default_rng(11)
    pos = np.array([[x, y, z] for x in (-9.0, 0.0, 9.0) for y in (-9.0, 0.0, 9.0)
                    for z in (-8.0, 8.0)])
    typ = np.arange(len(pos)) % 2
    typ[[2, 3, 6, 7]] = 1  # icospheres: a gap along x is their centre distance less 2r
    m = _matrices(rng, pos)
    r = 1.5  # the icosphere's vertices
    m[3, :3, 3] = m[2, :3, 3] + [2 * r + 0.3, 0.0, 0.0]  # 0.3 < 0.5: a gap short
    m[7, :3, 3] = m[6, :3, 3] + [2 * r + 0.55, 0.0, 0.0]  # 0.55: kept
    m[1, :3, 3] = m[0, :3, 3] + [0.5, 0.0, 0.0]  # overlapping
    m[5, :3, 3] = [14.5, 0.0, 0.0]  # through the wall
    return typ, m


@pytest.mark.parametrize("kept_faces", [exact_checks.KEPT_FACES, 0])  # solids kept, or remade
def test_clearance_checks_match_the_every_boolean_reference(certifier, monkeypatch,
                                                            kept_faces):
    monkeypatch.setattr(exact_checks, "KEPT_FACES", kept_faces)
    typ, m = _clearance_scene()
    pairs, walls, overlap, gap = _reference(certifier, typ, m, 0.5)
    rep = certifier.certify(typ, m, clearance=0.5)
    assert set(rep.bad_pairs) == pairs and set(rep.bad_wall) == walls
    assert {(0, 1), (2, 3)} <= pairs and (6, 7) not in pairs and 5 in walls
    # the booleans skipped were of pairs a gap proves apart: the worst overlap is the same
    assert rep.worst_overlap == pytest.approx(overlap, rel=1e-9) and overlap > 0.1
    assert rep.worst_outside > 0.1
    assert rep.min_pair_gap == pytest.approx(gap, abs=1e-9)
    assert 0.0 < rep.pair_shortfall[(2, 3)] <= 0.2 + 1e-9  # facets lie inside r


def test_near_first_orders_every_pair_once():
    rng = np.random.default_rng(3)
    centre = rng.uniform(0, 50, (300, 3))
    tree = certify.cKDTree(centre)
    pairs = tree.query_pairs(6.0, output_type="ndarray")
    got = certify._near_first(tree, pairs)
    assert sorted(map(tuple, got)) == sorted(map(tuple, pairs))
    assert certify._near_first(tree, pairs[:0]).shape == (0, 2)


def test_placed_solids_stay_within_the_face_budget_and_match_fresh_ones(certifier,
                                                                       monkeypatch):
    faces = [s.num_tri() for s in certifier.solids.types]
    monkeypatch.setattr(exact_checks, "KEPT_FACES", 3 * max(faces))
    rng = np.random.default_rng(5)
    typ = rng.integers(0, 2, 12)
    m = _matrices(rng, rng.uniform(-10, 10, (12, 3)))
    solids = exact_checks.PlacedSolids(certifier.solids, typ, m)
    for i in rng.integers(0, 12, 60):
        s = solids(i)
        fresh = certifier.solids.types[typ[i]].transform(m[i, :3, :4].tolist())
        assert (s ^ fresh).volume() == pytest.approx(s.volume(), rel=1e-9)
        assert solids.kept_faces == sum(faces[typ[k]] for k in solids.kept)
        assert solids.kept_faces <= exact_checks.KEPT_FACES and int(i) in solids.kept
    assert 1 < len(solids.kept) <= 3


@pytest.mark.parametrize("clearance", [0.0, 0.5])
def test_an_object_wholly_beyond_the_outside_solid_fails(certifier, clearance):
    # the outside solid is a padded box minus the container: an object past the box misses
    # it, so neither its boolean nor its gap sees the object as outside
    rng = np.random.default_rng(9)
    typ = np.array([0, 1])
    m = _matrices(rng, np.array([[0.0, 0.0, 0.0], [200.0, 0.0, 0.0]]))
    rep = certifier.certify(typ, m, clearance=clearance)
    assert not rep.certified and rep.bad_wall == [1]
    assert rep.worst_outside == 1.0 and rep.worst_outside_object == 1
    assert rep.wall_shortfall == ({1: clearance} if clearance else {})


def _dense_scene(rng, n=40, spread=8.0):
    """Objects of both types packed closely enough that many pairs touch or overlap, and
    some poke through the wall."""
    typ = rng.integers(0, 2, n)
    return typ, _matrices(rng, rng.uniform(-spread, spread, (n, 3)) * [1.0, 1.0, 1.8])


def _same_report(a, b):
    assert a.as_dict() == b.as_dict()
    assert a.bad_pairs == b.bad_pairs and a.bad_wall == b.bad_wall
    assert a.pair_shortfall == b.pair_shortfall and a.wall_shortfall == b.wall_shortfall


@pytest.mark.parametrize("clearance", [0.0, 0.5])
def test_a_memo_reruns_only_the_checks_of_what_moved_and_reports_the_same(certifier,
                                                                         clearance,
                                                                         monkeypatch):
    rng = np.random.default_rng(21)
    typ, m = _dense_scene(rng)
    ids = np.arange(100, 100 + len(typ))  # ids other than the positions
    memo = certify.CheckMemo()
    bounded = []  # objects whose bounds and depths were computed, call by call
    bounds = certifier._bounds_and_depth
    monkeypatch.setattr(certifier, "_bounds_and_depth",
                        lambda t, mats: bounded.append(len(t)) or bounds(t, mats))
    first = certifier.certify(typ, m, clearance, memo=memo, ids=ids)
    assert bounded == [len(typ)]
    _same_report(first, certifier.certify(typ, m, clearance))
    assert not first.certified and first.bad_pairs and first.bad_wall
    assert memo.run == first.pairs_checked + first.walls_checked
    # nothing moved: no check runs again, no bounds are computed, the report is the same
    bounded.clear()
    _same_report(certifier.certify(typ, m, clearance, memo=memo, ids=ids), first)
    assert memo.run == first.pairs_checked + first.walls_checked and bounded == []
    # move one object and drop another (as a repair does): only the moved one's checks run
    m2 = m.copy()
    m2[3, :3, 3] += [0.7, -0.4, 0.2]
    keep = np.delete(np.arange(len(typ)), 8)
    before = memo.run
    got = certifier.certify(typ[keep], m2[keep], clearance, memo=memo, ids=ids[keep])
    assert bounded == [1]  # the moved one's
    fresh = certifier.certify(typ[keep], m2[keep], clearance)
    _same_report(got, fresh)
    k = 3  # object 3 keeps its position in keep (8 > 3)
    lo, hi, depth = certifier._bounds_and_depth(typ[keep], m2[keep])
    touching = sum(1 for j in range(len(keep)) if j != k
                   and not (np.any(lo[k] > hi[j] + clearance)
                            or np.any(lo[j] > hi[k] + clearance)))
    walls = int(depth[k] < clearance + certifier.max_edge[typ[keep][k]]
                + 0.5 * certifier.container.grid.spacing)
    assert memo.run - before == touching + walls > 0
    # a changed type or a changed clearance is not taken from the memo
    typ3 = typ[keep].copy()
    typ3[k] = 1 - typ3[k]
    _same_report(certifier.certify(typ3, m2[keep], clearance, memo=memo, ids=ids[keep]),
                 certifier.certify(typ3, m2[keep], clearance))
    other = 0.25 if clearance else 0.5
    _same_report(certifier.certify(typ3, m2[keep], other, memo=memo, ids=ids[keep]),
                 certifier.certify(typ3, m2[keep], other))


def test_certify_reports_progress_up_to_every_check(certifier, monkeypatch):
    monkeypatch.setattr(certify, "PROGRESS_SECONDS", 0.0)
    rng = np.random.default_rng(22)
    typ, m = _dense_scene(rng)
    calls = []
    rep = certifier.certify(typ, m, progress=lambda done, total: calls.append((done, total)))
    total = calls[-1][1]
    # every check not proven apart by a plane runs, and reports progress
    assert calls[-1] == (total, total) and 0 < total <= rep.pairs_checked + rep.walls_checked
    assert [d for d, _ in calls] == sorted(d for d, _ in calls) and len(calls) > total // 2


def _no_planes(pts, off, typ, matrices, pairs, margin):
    return np.zeros(len(pairs), bool)


@pytest.mark.parametrize("clearance", [0.0, 0.5])
def test_pairs_a_plane_proves_apart_skip_their_checks_with_the_same_report(
        certifier, monkeypatch, clearance):
    rng = np.random.default_rng(23)
    typ, m = _dense_scene(rng, n=60, spread=10.0)
    runs = []
    real = certify.run_checks
    monkeypatch.setattr(certify, "run_checks",
                        lambda solid, vol, checks, *a: runs.append(len(checks))
                        or real(solid, vol, checks, *a))
    with_planes = certifier.certify(typ, m, clearance)
    ran = sum(runs)
    runs.clear()
    monkeypatch.setattr(certify, "apart_pairs", _no_planes)
    without = certifier.certify(typ, m, clearance)
    _same_report(with_planes, without)
    assert not without.certified and without.bad_pairs
    assert sum(runs) == without.pairs_checked + without.walls_checked > ran
    assert sum(runs) - ran >= without.pairs_checked // 4  # planes spared many checks


def test_a_pair_in_a_hollow_gets_its_boolean():
    # a cup (a box less a pocket) and a ball in its pocket: the hulls overlap, the solids
    # do not; and the ball pushed into the cup's wall overlaps
    box = trimesh.creation.box(extents=(40.0, 40.0, 40.0))
    cont = build_container(box.vertices, box.faces, float(box.volume), 1.0)
    cup = trimesh.creation.box(extents=(6.0, 6.0, 6.0)).difference(
        trimesh.creation.box(extents=(4.0, 4.0, 8.0)).apply_translation([0, 0, 3.0]))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=1.5)
    meshes = [cup, ball]
    cert = Certifier(cont, [np.asarray(x.vertices) for x in meshes],
                     [np.asarray(x.faces) for x in meshes], np.array([x.volume for x in meshes]),
                     np.array([x.edges_unique_length.max() for x in meshes]))
    m = np.tile(np.eye(4), (2, 1, 1))
    m[1, :3, 3] = [0.0, 0.0, 1.5]  # in the pocket, whose floor is at z = -1
    typ = np.array([0, 1])
    assert not certify.apart_pairs(*cert.hulls, typ, m, np.array([[0, 1]]), 1e-9).any()
    rep = cert.certify(typ, m)
    assert rep.certified and rep.pairs_checked == 1 and rep.worst_overlap == 0.0
    m[1, :3, 3] = [1.5, 0.0, 1.5]  # 0.5 into the pocket's side
    rep = cert.certify(typ, m)
    assert rep.bad_pairs == [(0, 1)] and rep.worst_overlap > 1e-3


@pytest.mark.parametrize("seed", range(6))
def test_least_gap_is_the_brute_force_minimum(seed):
    rng = np.random.default_rng(seed)
    gaps = rng.uniform(1.0, 12.0, 50)
    lower = gaps * rng.uniform(0.0, 1.0, 50)  # bounds no larger than each gap
    searched = []

    def candidates(s):
        k = np.flatnonzero(lower < s)
        return lower[k], k.tolist()

    def measure(k, search):
        searched.append((lower[k], search))
        return min(gaps[k], search)

    limit = 20.0 if seed % 2 else 0.8 * gaps.min()  # odd seeds: the least gap lies within
    got = exact_checks.least_gap(candidates, measure, 0.5, limit)
    if seed % 2:
        assert got == gaps.min()
        # no check whose bound reached the least gap ran
        assert all(lo < search for lo, search in searched)
    else:
        assert got is None


@pytest.mark.parametrize("seed", range(4))
def test_least_gap_from_a_known_gap_searches_no_check_beyond_it(seed):
    """The check with the lowest bound was searched first, out to its own gap: a pair 10
    clearances apart whose boxes overlap took 9.4 s of min_gap where the certification had
    measured a gap of 1.0 clearance already. From a known gap no search reaches past it."""
    rng = np.random.default_rng(seed)
    gaps = rng.uniform(1.0, 12.0, 50)
    lower = gaps * rng.uniform(0.0, 1.0, 50)
    lower[int(np.argmax(gaps))] = 0.0  # the farthest check has the lowest bound
    searched = []

    def candidates(s):
        k = np.flatnonzero(lower < s)
        return lower[k], k.tolist()

    def measure(k, search):
        searched.append(search)
        return min(gaps[k], search)

    known = float(np.sort(gaps)[3])  # a gap measured already, not the least
    assert exact_checks.least_gap(candidates, measure, 0.5, 20.0, known) == gaps.min()
    assert max(searched) <= known
    searched.clear()
    assert exact_checks.least_gap(candidates, measure, 0.5, 20.0) == gaps.min()
    assert max(searched) >= gaps.max()  # without it, the farthest was searched out


def test_least_gaps_are_measured_beyond_the_checks_search(certifier):
    """Balls 4 c apart and 2.6 c from the wall: the checks read 1.25 c for every gap, the
    least gaps are each the exact min_gap."""
    c = 0.5
    r = 1.5
    pos = np.array([[0.0, 0.0, 0.0], [2 * r + 4 * c, 0.0, 0.0], [0.0, 15.0 - r - 2.6 * c, 0.0]])
    typ = np.ones(len(pos), np.int64)
    m = _matrices(np.random.default_rng(3), pos)
    memo = certify.CheckMemo()
    ids = np.arange(len(pos))
    rep = certifier.certify(typ, m, c, memo=memo, ids=ids)
    assert rep.certified and rep.min_wall_gap == pytest.approx(1.25 * c)
    solids = [certifier.solids.types[t].transform(m[i, :3, :4].tolist()) for i, t in enumerate(typ)]
    wall = min(s.min_gap(certifier.solids.outside, 30.0) for s in solids)
    pair = min(solids[i].min_gap(solids[j], 30.0) for i in range(3) for j in range(i + 1, 3))
    assert wall > 2 * c and pair > 3 * c
    got = certifier.least_gaps(typ, m, c, memo, ids)
    assert got == (pytest.approx(pair, abs=1e-9), pytest.approx(wall, abs=1e-9))
    # one ball at the centre of the 30 mm box: no pair, and the wall further than twice
    # the largest bounding radius (and 16 clearances)
    memo = certify.CheckMemo()
    one = m[:1].copy()
    one[0, :3, 3] = 0.0
    assert certifier.certify(typ[:1], one, 0.1, memo=memo, ids=ids[:1]).certified
    assert certifier.least_gaps(typ[:1], one, 0.1, memo, ids[:1]) == (None, None)


def test_an_object_pierced_by_a_wall_thinner_than_a_cell_gets_its_wall_check(monkeypatch):
    # a cavity reached by a tunnel 0.01 wide, with grid cells of 1: the interpolant read the
    # tunnel 0.70 deep from nodes 0.7 away, above the half-cell allowance (0.67 with the
    # ball's edges), so the ball around the cavity skipped its wall check and was certified
    # with 12% of it outside. The grid's lowering where surface samples see room beyond the
    # wall catches the tunnel only where a sample lands in it (3 of 10 variants did not):
    # without it, the nodes' true distances alone must keep the check
    import manifold3d as m3

    from jampacked.core import container

    monkeypatch.setattr(container, "tighten_to_surface", lambda grid, v, f: grid)

    from jampacked.core.mesh_repair import check_and_repair
    from jampacked.core.solids import solid_arrays

    cave = (m3.Manifold.sphere(2.0, 48).translate([0.5, 0.5, 0.0])
            + m3.Manifold.cylinder(30.0, 0.005, 0.005, 12).translate([0.5, 0.5, 0.0]))
    cv, cf = solid_arrays(m3.Manifold.cube([40.0, 40.0, 40.0], True) - cave)
    # as `pack` loads it: the load checks accept it
    cv, cf, volume, _ = check_and_repair(cv, cf, "container 'tunnel'", "container")
    cont = build_container(cv, cf, volume, 1.0)
    ball = trimesh.creation.icosphere(subdivisions=5, radius=4.0)
    cert = Certifier(cont, [np.asarray(ball.vertices)], [np.asarray(ball.faces)],
                     np.array([ball.volume]), np.array([ball.edges_unique_length.max()]))
    m = np.eye(4)[None].copy()
    m[0, :3, 3] = [0.5, 0.5, 0.0]
    for clearance in (0.0, 0.02):
        rep = cert.certify(np.array([0]), m, clearance=clearance)
        assert rep.walls_checked == 1 and not rep.certified
    assert rep.worst_outside > 0.1


def test_a_node_beyond_the_exact_band_does_not_skip_a_wall_check():
    # beyond GRID_BAND cells the grid holds the distance to some triangle, up to 0.7 cell
    # deeper than the true one on Spot at 40 cells: a small ball there skipped its wall check
    # with a clearance of 4 cells although its gap was 1.8% short
    from importlib import resources

    from scipy.spatial import cKDTree

    from jampacked.core.distance import band_distances
    from jampacked.core.meshes import load_mesh
    from jampacked.core.solids import outside_of, to_solid

    md = load_mesh(str(resources.files("jampacked.core").joinpath(
        "data", "default_scene", "spot.obj")), role="container")
    v, f = np.asarray(md.vertices), np.asarray(md.faces)
    cont = build_container(v, f, md.volume, float(np.ptp(v, axis=0).max()) / 40)
    g = cont.grid
    # no inside node is further from the surface than from its nearest vertex: a band that
    # wide gives the exact distance at every inside node, as an unbounded one did (in an
    # eighth of the time); only inside nodes are read below
    inside = g.origin + np.argwhere(g.values > 0) * g.spacing
    reach = float(cKDTree(v).query(inside)[0].max())
    exact, _ = band_distances(v, f, g.origin, float(g.spacing),
                              np.asarray(g.values.shape, np.int64), reach / g.spacing + 1.0)
    over = np.where(g.values > 0, g.values - exact, -np.inf)
    node = np.array(np.unravel_index(np.argmax(over), over.shape))
    assert over.max() > 0.3 * g.spacing  # the grid reads this node too deep
    p = g.origin + node * g.spacing
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.1 * g.spacing)
    cert = Certifier(cont, [np.asarray(ball.vertices)], [np.asarray(ball.faces)],
                     np.array([ball.volume]), np.array([ball.edges_unique_length.max()]))
    m = np.eye(4)[None].copy()
    m[0, :3, 3] = p
    clearance = float(exact[tuple(node)]) - 0.05 * g.spacing  # the ball's gap falls short
    gap = to_solid(np.asarray(ball.vertices) + p, np.asarray(ball.faces)).min_gap(
        outside_of(v, f), 2 * clearance)
    assert gap < clearance
    rep = cert.certify(np.array([0]), m, clearance=clearance)
    assert rep.walls_checked == 1 and not rep.certified


def test_touching_pairs_are_every_pair_whose_boxes_come_within_the_clearance():
    # sizes over two orders of magnitude: several size classes, each with its own reach
    rng = np.random.default_rng(5)
    n = 400
    centre = rng.uniform(0, 40, (n, 3))
    half = np.exp(rng.uniform(np.log(0.1), np.log(8.0), (n, 1))) * rng.uniform(0.5, 1, (n, 3))
    lo, hi = centre - half, centre + half
    check = rng.random(n) < 0.7
    for clearance in (0.0, 0.4):
        got = Certifier._touching_pairs(lo, hi, check, clearance)
        i, j = np.triu_indices(n, 1)
        near = ~(np.any(lo[i] > hi[j] + clearance, axis=1)
                 | np.any(lo[j] > hi[i] + clearance, axis=1))
        want = {(a, b) for a, b in zip(i[near], j[near], strict=True) if check[a] or check[b]}
        assert {tuple(sorted(p)) for p in got.tolist()} == want
        assert len(got) == len(want)  # each pair once


def test_near_pairs_lookup_does_not_take_every_small_neighbour_of_a_large_object(monkeypatch):
    # one reach for all, the largest object's, made every small object within it a
    # candidate of every other: 1,001 objects gave 500,500 candidates (and 8,001 took 8.5 s
    # and 1.6 GB) for no touching pair
    seen = []
    original = certify._near_first
    monkeypatch.setattr(certify, "_near_first",
                        lambda tree, pairs: seen.append(len(pairs)) or original(tree, pairs))
    side = np.arange(10) * 2.2
    lattice = np.stack(np.meshgrid(side, side, side, indexing="ij"), -1).reshape(-1, 3)
    centre = np.vstack([lattice, [[-11.2, 0.0, 0.0]]])
    half = np.ones((len(centre), 3))
    half[-1] = 10.0
    pairs = Certifier._touching_pairs(centre - half, centre + half,
                                      np.ones(len(centre), bool), 0.0)
    assert len(pairs) == 0
    assert seen[0] < 20 * len(centre)


@pytest.mark.parametrize("size", [1e-4, 1e-5])
def test_a_tiny_scene_reads_the_gaps_of_the_same_scene_at_full_size(size):
    """manifold3d's triangle distance takes a triangle whose edges' cross product is shorter
    than about 3e-8 units for degenerate: in a scene this small its wall gaps read wrong
    (here larger than they are; in a 3.4-unit Spot with lemons, 0, and certification
    removed 39 of 164 objects). The checks now scale such a scene up first."""
    gaps = []
    for k in (1.0, size):
        sphere = trimesh.creation.icosphere(subdivisions=3, radius=10.0 * k)
        cont = build_container(sphere.vertices, sphere.faces, float(sphere.volume), 0.5 * k)
        ball = trimesh.creation.icosphere(subdivisions=3, radius=3.0 * k)
        cert = Certifier(cont, [np.asarray(ball.vertices)], [np.asarray(ball.faces)],
                         np.array([ball.volume]), np.array([ball.edges_unique_length.max()]))
        m = np.tile(np.eye(4), (6, 1, 1))
        m[:, :3, 3] = np.vstack([np.eye(3), -np.eye(3)]) * 6.42 * k  # 0.58 from the wall
        rep = cert.certify(np.zeros(6, np.int64), m, clearance=0.5 * k)
        assert rep.certified
        gaps.append(rep.min_wall_gap / k)
    assert gaps[1] == pytest.approx(gaps[0], rel=1e-5) and 0.5 < gaps[0] < 0.6


def test_a_tiny_scene_measures_an_object_outside_as_at_full_size():
    """The outside solid's padding (a tenth of the container and one unit) was one unit of
    the scaled frame: 1/256 of a unit around a 0.01 cube, so a ball wholly outside that
    straddled the padded box's face counted only its part inside the box (about half)."""
    ratios = []
    for k in (1.0, 0.01):
        cube = trimesh.creation.box(extents=(k, k, k))
        cont = build_container(cube.vertices, cube.faces, float(cube.volume), 0.05 * k)
        ball = trimesh.creation.icosphere(subdivisions=3, radius=0.2 * k)
        cert = Certifier(cont, [np.asarray(ball.vertices)], [np.asarray(ball.faces)],
                         np.array([ball.volume]), np.array([ball.edges_unique_length.max()]))
        m = np.eye(4)[None].copy()
        m[0, 0, 3] = (0.6 + 1.0 / 256 / 0.01) * k  # wholly outside; at 0.01 (scale 256, for
        # the ball) on the face of the padding's box
        ratios.append(cert.certify(np.zeros(1, np.int64), m).worst_outside)
    assert ratios == [pytest.approx(1.0, abs=1e-6)] * 2
