"""A type that (almost) never grows no longer holds the others back (`core/type_give_up.py`,
`placement.place_once`): phase 1 gives it up, or the attempt starts again without it."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from testdata import cavity_passes, lemon_and_balls, rod_and_balls

from jampacked.core.api import pack
from jampacked.core.metrics import tvd_of_counts
from jampacked.core.packing_json import load_packing, save_packing
from jampacked.core.placement import RUNNERS_UP, is_denser, never_placed, ranked_with
from jampacked.core.solver import PackState
from jampacked.core.type_give_up import GIVE_UP_TRIES, RATIO, TypeFailures, shares_without

HALF = np.array([0.5, 0.5])


def test_a_type_failing_from_the_start_waits_for_the_others_then_is_given_up():
    f = TypeFailures(HALF)
    for _ in range(GIVE_UP_TRIES + 1):  # as phase 1 does: the mix asks for it again
        assert f.shares_now()[0] == 0.5
        f.record(0, False)
    # eleven failures against an unknown rate: it waits while the others try
    np.testing.assert_array_equal(f.shares_now(), [0.0, 1.0])
    assert not f.given_up.any()
    for _ in range(GIVE_UP_TRIES):
        f.record(1, True)
    assert f.given_up.tolist() == [True, False]
    np.testing.assert_array_equal(f.placement_shares(), [0.0, 1.0])
    assert f.report() == [{"type": 0, "tries": 11, "grown": 0, "against": 1,
                           "against_tries": 10, "against_grown": 10}]


def test_a_suspect_the_others_fail_as_often_as_is_not_given_up():
    """Late in phase 1 every type fails often: a type is judged against the others' rate."""
    f = TypeFailures(HALF)
    for _ in range(GIVE_UP_TRIES + 1):
        f.record(0, False)
    for i in range(3 * GIVE_UP_TRIES):
        f.record(1, i % 10 == 0)  # the others grow one in ten
    assert not f.given_up.any()
    np.testing.assert_array_equal(f.shares_now(), HALF)  # no longer waiting either


@pytest.mark.parametrize("grown, tries, given_up", [(1, 19, False), (1, 21, True),
                                                    (2, 29, False), (2, 31, True)])
def test_a_type_is_given_up_at_one_success_in_ratio_tries(grown, tries, given_up):
    f = TypeFailures(HALF)
    for _ in range(GIVE_UP_TRIES):
        f.record(1, True)
    for i in range(tries):
        f.record(0, i < grown)
    assert RATIO == 10.0
    assert bool(f.given_up[0]) is given_up


def test_the_last_type_with_a_share_is_never_given_up():
    f = TypeFailures(np.array([0.0, 1.0]))
    for _ in range(100):
        f.record(1, False)
    assert not f.given_up.any()
    np.testing.assert_array_equal(f.shares_now(), [0.0, 1.0])
    g = TypeFailures(np.full(3, 1 / 3))
    for _ in range(50):
        g.record(0, False)
        g.record(1, False)
        g.record(2, True)
    assert g.given_up.tolist() == [True, True, False]


def test_shares_without_the_given_up_types():
    q = np.array([0.5, 0.3, 0.2])
    assert shares_without(q, []) is q
    np.testing.assert_allclose(shares_without(q, [{"type": 0}]), [0.0, 0.6, 0.4])
    np.testing.assert_array_equal(shares_without(q, [{"type": t} for t in range(3)]), q)


def test_never_placed_types_are_those_with_a_share_and_no_full_size_object():
    s = PackState()
    for t, scale in ((1, 1.0), (2, 0.5), (3, 1.0)):
        s.add(t, np.zeros(3), np.array([1.0, 0, 0, 0]), scale, 0.0)
    shares = np.array([0.25, 0.25, 0.25, 0.25, 0.0])
    assert never_placed(s, shares) == [0, 2]
    s.alive[:] = 0
    assert never_placed(s, shares) == []  # nothing placed: nothing to give up for


def test_a_suspect_still_waiting_when_the_lattice_runs_out_is_judged_on_the_others_tries():
    """A small lattice: the others had six tries, not ten, when phase 1 ended."""
    f = TypeFailures(HALF)
    for i in range(21):
        f.record(0, i == 0)
    for _ in range(6):
        f.record(1, True)
    assert not f.given_up.any()
    f.finish()
    assert f.report() == [{"type": 0, "tries": 21, "grown": 1, "against": 1,
                           "against_tries": 6, "against_grown": 6}]
    g = TypeFailures(HALF)  # the others failed as often: not given up
    for i in range(21):
        g.record(0, i == 0)
    for i in range(6):
        g.record(1, i == 0)
    g.finish()
    assert not g.given_up.any()


def test_the_rate_in_a_record_is_the_one_the_type_was_judged_against():
    f = TypeFailures(np.full(3, 1 / 3))
    for _ in range(GIVE_UP_TRIES):
        f.record(2, True)
    for _ in range(GIVE_UP_TRIES + 1):
        f.record(0, False)
    assert f.given_up.tolist() == [True, False, False]
    for _ in range(GIVE_UP_TRIES + 1):
        f.record(1, False)
    # type 1 is judged against type 2, which grows most often: 10 of 10
    assert f.report()[1] == {"type": 1, "tries": 11, "grown": 0, "against": 2,
                             "against_tries": 10, "against_grown": 10}
    for _ in range(5):
        f.record(2, False)
    assert f.report()[0]["against_tries"] == 10  # as it stood then


def test_two_types_that_never_grow_do_not_shield_each_other():
    """Each was judged against the others together, the other's failures among them: at
    (0 + 1) / (1 + 1) neither was given up, and the two types that grow never got a try."""
    f = TypeFailures(np.full(4, 0.25))
    f.record(0, False)
    for _ in range(GIVE_UP_TRIES + 1):
        f.record(1, False)
    assert f.shares_now()[1] == 0.0  # waits: the types it is judged against never tried
    for _ in range(GIVE_UP_TRIES):
        f.record(0, False)
    np.testing.assert_array_equal(f.shares_now(), [0.0, 0.0, 0.5, 0.5])
    for _ in range(GIVE_UP_TRIES):
        f.record(2, True)
    assert f.given_up.tolist() == [True, True, False, False]
    assert [r["against"] for r in f.report()] == [2, 2]


def test_finish_judges_against_a_type_that_tried():
    """A review: type 2 never tried, so at (0 + 1) / (0 + 1) it was the type judged
    against, and the warning read "against 0 of 0"."""
    f = TypeFailures(np.array([0.4, 0.3, 0.3]))
    for i in range(21):
        f.record(0, i == 0)
    for i in range(4):
        f.record(1, i < 3)
    f.finish()
    assert f.report() == []  # judged against type 1's 3 of 4: not ten times as often
    g = TypeFailures(np.array([0.4, 0.3, 0.3]))
    for i in range(21):
        g.record(0, i == 0)
    for _ in range(9):
        g.record(1, True)
    g.finish()
    assert g.report() == [{"type": 0, "tries": 21, "grown": 1, "against": 1,
                           "against_tries": 9, "against_grown": 9}]


def test_types_that_tried_and_never_grew_are_named_for_the_restart():
    f = TypeFailures(np.full(3, 1 / 3))
    f.record(0, False)
    f.record(1, True)
    f.record(1, False)
    assert f.never_grew() == [[0, 1]]  # type 2 never tried: the count may explain it


def test_after_a_give_up_most_objects_take_the_kept_shares():
    f = TypeFailures(HALF)
    for _ in range(GIVE_UP_TRIES):
        f.record(1, True)
    for _ in range(GIVE_UP_TRIES + 1):
        f.record(0, False)
    a, b = f.shares_now(), f.shares_now()
    assert a is b and a.tolist() == [0.0, 1.0]  # no recomputing per object


def test_the_densest_attempt_is_kept_whatever_it_gave_up():
    def att(density, given_up):
        return SimpleNamespace(density=density, given_up=[{"type": t} for t in given_up])

    assert is_denser(att(0.5, [0]), att(0.1, []))
    assert not is_denser(att(0.1, []), att(0.5, [0]))
    assert not is_denser(att(0.4, []), att(0.4, [1]))  # ties keep the earlier


def test_the_runner_ups_are_ranked_densest_first_ties_the_earlier_first():
    def att(density, index):
        return SimpleNamespace(density=density, index=index)

    ranked = []
    for i, density in enumerate([0.40, 0.45, 0.40, 0.30, 0.45, 0.50]):
        ranked = ranked_with(ranked, att(density, i))
    assert [a.index for a in ranked] == [5, 1, 4, 0, 2, 3][: 1 + RUNNERS_UP]


def test_a_type_that_fits_only_along_the_diagonal_no_longer_starves_the_others(tmp_path):
    """A 36 mm rod in a 24 mm cube fits only near its long diagonals: phase 1 gave nearly
    every lattice object the rod, which the mix lacked, and 4 objects were packed (3.2%)."""
    p = pack("box:24x24x24", rod_and_balls(tmp_path), seed=0)
    counts = np.bincount(p.type_index, minlength=2)
    assert counts[1] >= 80 and counts[0] <= 3
    assert p.metrics["density"] > 0.4
    [w] = p.report.warnings
    assert w.startswith("type rod (share 50%) was given up: in the first phase 1 of its 21 "
                        "tries grew, against 10 of 10 of ball's")
    assert "the other types were packed at their shares among themselves" in w.lower()
    assert p.report.phase1.extra["given_up"][0]["type"] == 0
    # the TVD is still measured against the shares asked
    assert p.metrics["tvd"] == pytest.approx(tvd_of_counts(counts, HALF))


def test_with_several_attempts_none_starves(tmp_path):
    """Seed 0's second attempt ran out of lattice while the rod waited for the balls' tenth
    try, so it gave nothing up and packed 7 objects, and was kept (an attempt that gave up
    fewer types was kept first)."""
    # two cavity passes, not four: each attempt still packs its balls past 80
    two_passes = cavity_passes(0.8, 0.6)
    p = pack("box:24x24x24", rod_and_balls(tmp_path), seed=0, attempts=2, options=two_passes)
    assert [a.count for a in p.report.attempts][1] >= 80
    assert p.n >= 80 and p.report.given_up[0]["type"] == 0


def test_two_types_that_never_grow_are_both_given_up(tmp_path):
    """A 36 mm rod and a 34 x 34 x 1 plate in a 24 mm cube, with balls and 6 mm cubes: 3
    objects (2.5%); the passes always tried a type that never grows, so the mix never
    refused a hole outright."""
    plate, cube = tmp_path / "plate.stl", tmp_path / "cube.stl"
    trimesh.creation.box((34.0, 34.0, 1.0)).export(plate)
    trimesh.creation.box((6.0, 6.0, 6.0)).export(cube)
    rod, ball = rod_and_balls(tmp_path, rod_radius=2.0)  # no room, even along a diagonal
    # two cavity passes, not four: the mix is refused no hole, and they fill the balls and
    # cubes past 20 each
    two_passes = cavity_passes(0.8, 0.6)
    p = pack("box:24x24x24", [rod, str(plate), ball, str(cube)], seed=0, options=two_passes)
    counts = np.bincount(p.type_index, minlength=4)
    assert counts[:2].tolist() == [0, 0] and counts[2:].min() >= 20
    assert sorted(g["type"] for g in p.report.given_up) == [0, 1]
    assert len(p.report.warnings) == 2


def test_a_type_no_pass_grows_makes_the_attempt_start_again_without_it(tmp_path):
    """A lemon that fits the 40 mm cube with its margins, but only at its centre in one
    orientation: nothing grew it, and the mix held the balls back (3 objects, 2.4%)."""
    # one cavity pass, not four: it still grows no lemon while the mix holds the balls back,
    # and the restart's one pass still packs the balls (62 against 40 asked)
    one_pass = cavity_passes(0.8)
    p = pack("box:40x40x40", lemon_and_balls(tmp_path), seed=0, options=one_pass)
    counts = np.bincount(p.type_index, minlength=2)
    assert counts[0] == 0 and counts[1] >= 40
    [w] = p.report.warnings
    tries = p.report.given_up[0]["tries"]
    assert w.startswith(f"type lemon (share 50%) was given up: none of its {tries} tries in "
                        "the first phase grew, nor one in the cavity passes, while the mix "
                        "held the other types back")
    assert "remove the type" in w
    assert p.metrics["tvd"] == pytest.approx(0.5)
    # the attempt that was kept is the one without the lemon: its first phase grew balls
    assert p.report.phase1.grown > 0 and p.certificate["certified"] is True
    assert p.report.given_up == [{"type": 0, "tries": tries, "grown": 0, "restarted": True}]
    assert tries >= 1
    path = tmp_path / "p.json"
    save_packing(p, path)
    assert load_packing(path).report.given_up == p.report.given_up


def test_a_stop_as_the_attempt_starts_again_keeps_the_first_run(tmp_path):
    """Ctrl-C as the lemon's attempt started again left no object (the first run's were
    dropped before the second had placed any)."""
    again = []

    def progress(fraction, message):
        if "starts again" in message:
            again.append(message)

    p = pack("box:40x40x40", lemon_and_balls(tmp_path), seed=0, progress=progress,
             should_cancel=lambda: bool(again))
    assert again and p.report.stopped == "cancelled"
    assert p.n == 3 and p.report.given_up == []


def _star_prism(path) -> str:
    """A five-pointed star 10 across and 2 thick (closed, outward)."""
    angle = np.linspace(0, 2 * np.pi, 11)[:-1]
    radius = np.where(np.arange(10) % 2 == 0, 5.0, 2.0)
    rim = np.c_[radius * np.cos(angle), radius * np.sin(angle)]
    v = np.vstack([np.c_[rim, np.zeros(10)], np.c_[rim, np.full(10, 2.0)], [[0, 0, 0],
                                                                              [0, 0, 2]]])
    f = []
    for i in range(10):
        j = (i + 1) % 10
        f += [[20, j, i], [21, 10 + i, 10 + j], [i, j, 10 + j], [i, 10 + j, 10 + i]]
    star = trimesh.Trimesh(v, f)
    trimesh.repair.fix_normals(star)
    star.export(path)
    return str(path)


def test_a_type_phase_1_never_tried_and_no_pass_placed_is_given_up(tmp_path):
    """A tray 3.1 deep with a 0.5 clearance: phase 1's lattice holds no point, the star
    (2 thick) fits no cavity with its margins, and the mix held the plates back for it: 5
    plates (10.1%), where 10 fit. The restart waited for a type phase 1 tried and never
    grew; where phase 1 tried nothing at all, every type no pass placed counts."""
    plate = tmp_path / "plate.stl"
    trimesh.creation.box((10.0, 10.0, 1.0)).export(plate)
    # two cavity passes, not four (the other two took most of the first run's time): they
    # still place no star while the mix holds the plates back; the restart packs 10 plates
    two_passes = cavity_passes(0.8, 0.6)
    p = pack("box:40x40x3.1", [str(plate), _star_prism(tmp_path / "star.stl")], [0.7, 0.3],
             seed=1, clearance=0.5, options=two_passes)
    assert np.bincount(p.type_index, minlength=2).tolist() == [10, 0]
    assert p.report.given_up == [{"type": 1, "tries": 0, "grown": 0, "restarted": True}]
    [w] = p.report.warnings
    assert ("was given up: the first phase tried none of it, and no cavity pass placed one, "
            "while the mix held the other types back") in w
