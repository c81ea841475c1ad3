"""Parts mode's gap check: the broad phase finds exactly the near pairs, and the exact
checks search only a little beyond the clearance (their cost grows with the search)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from jampacked.export.parts import (
    GROWTH,
    SEARCH_MARGIN,
    box_gaps,
    near_pairs,
    smallest_gap,
)


def _brute_near(lo: np.ndarray, hi: np.ndarray, distance: float) -> set[tuple[int, int]]:
    """numpy reference: every pair's box distance, all N^2 pairs."""
    out = set()
    for i, j in itertools.combinations(range(len(lo)), 2):
        apart = np.maximum(0.0, np.maximum(lo[i] - hi[j], lo[j] - hi[i]))
        if np.sqrt((apart * apart).sum()) <= distance:
            out.add((i, j))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_near_pairs_match_all_pairs_reference(seed):
    rng = np.random.default_rng(seed)
    n = 300
    lo = rng.uniform(0, 100, (n, 3))
    hi = lo + rng.uniform(0.5, 12.0, (n, 3))  # boxes of mixed sizes and shapes
    for distance in (0.0, 0.7, 5.0):
        got = near_pairs(lo, hi, distance)
        assert {tuple(p) for p in got.tolist()} == _brute_near(lo, hi, distance)
        assert np.all(got[:, 0] < got[:, 1])
        assert len(np.unique(got, axis=0)) == len(got)


def test_near_pairs_of_fewer_than_two_boxes_are_none():
    assert near_pairs(np.zeros((1, 3)), np.ones((1, 3)), 1.0).shape == (0, 2)


def test_box_gaps_are_euclidean_between_boxes():
    lo = np.array([[0.0, 0, 0], [3, 4, 0], [0.5, 0.5, 0.5]])
    hi = np.array([[1.0, 1, 1], [4, 5, 1], [2, 2, 2]])
    got = box_gaps(lo, hi, np.array([[0, 1], [0, 2]]))
    np.testing.assert_allclose(got, [np.hypot(2.0, 3.0), 0.0])


class _Gaps:
    """A fake exact gap: the true gap of each pair, returned as manifold3d's min_gap does
    (the gap when below the search, else the search); records every search asked for."""

    def __init__(self, true: dict[tuple[int, int], float]):
        self.true = true
        self.calls: list[tuple[int, int, float]] = []

    def __call__(self, i: int, j: int, search: float) -> float:
        self.calls.append((i, j, search))
        return min(self.true[(i, j)], search)


def test_dense_packing_measures_near_pairs_once_with_short_searches():
    clearance = 0.5
    pairs = np.array([[0, 1], [0, 2], [1, 2], [2, 3]])
    true = {(0, 1): 0.53, (0, 2): 0.58, (1, 2): 4.0, (2, 3): 9.0}
    lower = np.array([0.2, 0.4, 3.0, 8.5])  # box distances: lower bounds
    gaps = _Gaps(true)
    best, where = smallest_gap(gaps, pairs, lower, 20.0, clearance)
    assert best == pytest.approx(0.53) and where == (0, 1)
    # one round: only the pairs whose boxes come near, searching just past the clearance
    assert {(i, j) for i, j, _ in gaps.calls} == {(0, 1), (0, 2)}
    assert max(s for _, _, s in gaps.calls) == pytest.approx(clearance * (1 + SEARCH_MARGIN))


def test_sparse_packing_finds_the_exact_smallest_gap_by_growing_the_search():
    clearance = 0.5
    pairs = np.array([[0, 1], [1, 2], [0, 2]])
    true = {(0, 1): 3.1, (1, 2): 2.2, (0, 2): 7.0}
    lower = np.array([2.9, 2.0, 6.0])
    gaps = _Gaps(true)
    best, where = smallest_gap(gaps, pairs, lower, 50.0, clearance)
    assert best == pytest.approx(2.2) and where == (1, 2)
    searches = sorted({s for _, _, s in gaps.calls})
    assert searches[-1] < 2.2 * GROWTH  # never far beyond the smallest gap
    assert all((i, j) != (0, 2) for i, j, _ in gaps.calls)  # its box is beyond every search


def test_a_pair_closer_than_the_clearance_is_found_in_the_first_round():
    pairs = np.array([[0, 1], [1, 2]])
    gaps = _Gaps({(0, 1): 0.8, (1, 2): 0.31})
    best, where = smallest_gap(gaps, pairs, np.array([0.1, 0.0]), 10.0, 0.5)
    assert best == pytest.approx(0.31) and where == (1, 2)
    assert len(gaps.calls) == 2


def test_no_pairs_no_gap():
    assert smallest_gap(_Gaps({}), np.zeros((0, 2), np.int64), np.zeros(0), 1.0, 0.5) == (
        None, None)


def test_separate_parts_reports_the_exact_smallest_gap_of_real_solids():
    from testdata import mesh_path

    from jampacked.core.meshes import load_mesh
    from jampacked.core.solids import to_solid
    from jampacked.export.parts import separate_parts

    m = load_mesh(mesh_path("polyhedra/convex5/polytope1.obj"))
    base = to_solid(m.vertices - m.centroid, m.faces)
    size = float(np.ptp(m.vertices, axis=0).max())
    # a row of parts 1.3, 2.0 and 3.5 units of free space apart along x (the box widths)
    offsets = np.cumsum([0.0, size + 1.3, size + 2.0, size + 3.5])
    solids = [base.translate((float(x), 0.0, 0.0)) for x in offsets]
    bodies, gap = separate_parts(solids, 0.5)
    want = min(a.min_gap(b, 10 * size) for a, b in itertools.combinations(solids, 2))
    assert len(bodies) == 4
    assert gap == pytest.approx(want, rel=1e-12) and 1.0 < gap < 10 * size


def test_parts_far_from_the_origin_keep_the_clearance_as_stl_stores_them():
    """Two cubes 0.2028 apart at x = 3e6 (a packing 3 km from the origin in mm): the 3MF keeps
    the gap, but an STL's 32-bit positions (a step of 0.25 there) closed it, and the export
    reported 0.2028 and PASS. With a 32-bit output the gaps are measured as stored."""
    import manifold3d as m3

    from jampacked.core.errors import MeshError
    from jampacked.export.parts import separate_parts

    x = 3e6
    a = m3.Manifold.cube((5.0, 5.0, 5.0)).translate((x + 10.13 - 5.0, 0.0, 0.0))
    b = m3.Manifold.cube((5.0, 5.0, 5.0)).translate((x + 10.3328, 0.0, 0.0))
    # what an STL stores: the faces 0.2028 apart round onto the same float32 value
    assert np.float32(x + 10.13) == np.float32(x + 10.3328)
    bodies, gap = separate_parts([a, b], 0.2)
    assert gap == pytest.approx(0.2028, abs=1e-6)
    with pytest.raises(MeshError, match="as out.stl would store them") as err:
        separate_parts([a, b], 0.2, float32=["out.stl"])
    assert "Drop out.stl and write .3mf" in str(err.value)


def test_a_pair_the_rounding_closes_is_checked_though_not_among_the_near_ones():
    """0.248 apart at 3e6, each cube with seven small ones nearer its centre: the pair was
    neither within the clearance's reach nor among each part's nearest, so it was never
    measured as stored (both faces at 3000000.25 in 32 bits)."""
    import manifold3d as m3

    from jampacked.core.errors import MeshError
    from jampacked.export.parts import separate_parts

    x = 3e6
    a = m3.Manifold.cube((5.0, 5.0, 5.0)).translate((x - 5.0 + 0.126, 0.0, 0.0))
    b = m3.Manifold.cube((5.0, 5.0, 5.0)).translate((x + 0.374, 0.0, 0.0))
    assert np.float32(x + 0.126) == np.float32(x + 0.374)
    # seven small cubes 0.3 above each, nearer its centre than the other cube's
    small = [m3.Manifold.cube((0.5, 0.5, 0.5)).translate((x + cx - 0.25, 5.3, 0.8 * k))
             for cx in (-2.374, 2.874) for k in range(7)]
    assert separate_parts([a, b] + small, 0.2)[1] >= 0.2  # kept at full precision
    with pytest.raises(MeshError, match="would store them"):
        separate_parts([a, b] + small, 0.2, float32=["out.stl"])


def test_near_the_origin_a_gap_just_above_the_clearance_is_kept_as_stored():
    """A dense packing's smallest gap sits just above its clearance (0.20017 for 0.2 in a
    bench run): rounding to 32 bits 128 mm from the origin moves it by far less than a
    printer resolves, and such exports were refused."""
    import manifold3d as m3

    from jampacked.export.parts import separate_parts

    for gap in (0.2000001, 0.200003):
        a = m3.Manifold.cube((5.0, 5.0, 5.0)).translate((128.0 - 5.0, 0.0, 0.0))
        b = m3.Manifold.cube((5.0, 5.0, 5.0)).translate((128.0 + gap, 0.0, 0.0))
        assert separate_parts([a, b], 0.2, float32=["out.stl"])[1] == pytest.approx(
            gap, abs=1e-5)


@pytest.mark.parametrize("size", [1e-4, 1e-5])
def test_tiny_parts_report_the_gap_of_the_same_parts_at_full_size(size):
    """manifold3d's triangle distance takes a triangle whose edges' cross product is below
    about 3e-8 units for degenerate: two balls 6e-4 across read a gap 0.6% too large (the
    unsafe way). The check now scales tiny parts up, as certification does."""
    from scipy.spatial.transform import Rotation

    from jampacked.core.solids import to_solid
    from jampacked.export.parts import separate_parts

    ball = _ball()
    rng = np.random.default_rng(0)
    for t in range(3):
        turn = Rotation.random(2, random_state=t).as_matrix()
        d = rng.normal(size=3)
        offset = 6.6 * d / np.linalg.norm(d)
        gaps = []
        for k in (1.0, size):
            solids = [to_solid((ball.vertices @ turn[0].T) * k, ball.faces),
                      to_solid((ball.vertices @ turn[1].T + offset) * k, ball.faces)]
            gaps.append(separate_parts(solids, 0.5 * k)[1] / k)
        assert gaps[1] == pytest.approx(gaps[0], rel=1e-6) and 0.6 < gaps[0] < 0.62


def _ball():
    import trimesh

    return trimesh.creation.icosphere(subdivisions=3, radius=3.0)
