"""What a finished packing warns about (`core/run_warnings.py`)."""

from __future__ import annotations

import time

import numpy as np
import pytest
import trimesh
from testdata import cavity_passes

from jampacked.core import placement
from jampacked.core.api import pack
from jampacked.core.report import PhaseStats
from jampacked.core.run_warnings import run_warnings, slow_certification

NAMES = ["apple", "plum"]
HALF = np.array([0.5, 0.5])


def _warn(counts, tvd=0.0, phase1=None, budget=None, stopped=None, asked=None, ran=1,
          extra=True):
    return run_warnings(NAMES, HALF, np.array(counts), tvd, 0.04, phase1 or PhaseStats(),
                        budget, stopped, asked, ran, extra_passes_ran=extra)


def test_a_full_run_with_the_mix_kept_warns_about_nothing():
    assert _warn([50, 51], tvd=0.005) == []
    assert _warn([1, 2], tvd=1 / 6) == []  # three objects cannot hold 50/50 closer


def test_a_type_never_placed_is_named():
    (w,) = _warn([0, 40], tvd=0.5)
    assert w.startswith("type apple (share 50%) was not placed at all")
    # in both the command line's and a batch file's (or pack()'s) words
    assert "(--type-scale / type_scale)" in w and "(--container-size / container_size)" in w


def test_a_mix_far_from_the_shares_is_reported():
    (w,) = _warn([30, 70], tvd=0.2)
    assert "TVD 0.200" in w and "apple 30% (asked 50%)" in w
    # and how to bring it back: the short type named, what makes room for it
    assert "short of their share (apple)" in w and "--type-scale" in w
    assert "a smaller mix tolerance (--mix-tolerance)" in w
    # with a tolerance of 0 already, it is not advised
    (w,) = run_warnings(NAMES, HALF, np.array([30, 70]), 0.2, 0.0, PhaseStats(), None, None,
                        None, 1)
    assert "--type-scale" in w and "mix tolerance" not in w


def test_a_small_scenes_mix_one_object_off_says_why_and_what_keeps_it():
    """4 and 7 of 11 objects: one object beyond the best mix 11 allow (5 and 6), which the
    passes' one-object slack permits and a zero tolerance does not."""
    (w,) = _warn([4, 7], tvd=0.5 * (abs(4 / 11 - 0.5) + abs(7 / 11 - 0.5)))
    assert "With 11 objects one object moves the mix by about 0.09" in w
    assert "a mix tolerance of 0 (--mix-tolerance 0)" in w and "short of" not in w


def test_a_small_share_far_short_is_named_though_the_tvd_is_within_the_tolerance():
    """5% of big objects asked, 27 of 2,426 placed (1.1%): the TVD (0.039) is within the
    tolerance, as the small types make up the count, and nothing was said."""
    shares = np.array([0.05, 0.90, 0.05])
    counts = np.array([27, 2275, 124])
    tvd = 0.5 * float(np.abs(counts / counts.sum() - shares).sum())
    assert tvd < 0.04
    (w,) = run_warnings(["big", "small", "mid"], shares, counts, tvd, 0.04, PhaseStats(),
                        None, None, None, 1)
    assert "placed far below the share asked: big 1.1% (27 of 2,426) against the 5.0%" in w
    assert "mid" not in w and "The mix as a whole is within the tolerance" in w
    assert "--type-scale" in w and "a smaller mix tolerance (--mix-tolerance)" in w
    # above the tolerance but not off (within its 0.01 slack): "close to"; with a tolerance
    # of 0, no tolerance to advise
    for max_tvd, placed, share in ((0.04, [4, 96], 0.09), (0.0, [1, 999], 0.005)):
        counts = np.array(placed)
        shares = np.array([share, 1 - share])
        tvd = 0.5 * float(np.abs(counts / counts.sum() - shares).sum())
        near = "close to"
        (w,) = run_warnings(["big", "small"], shares, counts, tvd, max_tvd, PhaseStats(),
                            None, None, None, 1) or [""]
        assert f"is {near} the tolerance" in w, w
        assert ("mix tolerance" in w) == (max_tvd > 0)
    # a share of a few objects only (3 of 300 asked), or one more than half met, is not said
    for share, placed in ((0.01, 1), (0.05, 9)):
        counts = np.array([placed, 300 - placed])
        shares = np.array([share, 1 - share])
        tvd = 0.5 * float(np.abs(counts / 300 - shares).sum())
        assert run_warnings(["big", "small"], shares, counts, tvd, 0.04, PhaseStats(), None,
                            None, None, 1) == []


def test_a_budget_ending_in_phase_1_and_attempts_cut_short():
    cut = PhaseStats(inserted=1724, grown=217, stopped="deadline")
    w = _warn([100, 101], phase1=cut, budget=30.0, stopped="deadline", asked=3, ran=1)
    assert len(w) == 2
    assert "217 of 1724 grew" in w[0] and "--time-budget / time_budget" in w[0]
    assert w[1].startswith("1 of the 3 attempts")
    # cancelled, not the budget: the command line says it was interrupted instead
    assert _warn([100, 101], stopped="cancelled", asked=3, ran=1) == []


def test_a_budget_ending_before_the_cavity_passes():
    # a sweep's scene (non-convex polytopes in Spot, 20 s): phase 1 grew 130 of 310 objects
    # (19%) in 18.5 s, the budget ended in phase 2, and nothing said the holes were unfilled
    grown = PhaseStats(inserted=310, grown=130)
    (w,) = _warn([66, 67], phase1=grown, budget=20.0, stopped="deadline", extra=False)
    assert "ended before the cavity passes ran" in w and "130 of 310" in w
    assert "--time-budget / time_budget" in w
    # once the passes started, the budget ending them is how a budget works: no warning
    assert _warn([66, 67], phase1=grown, budget=20.0, stopped="deadline", extra=True) == []
    # phase 1 cut short says so once, not twice
    cut = PhaseStats(inserted=310, grown=100, stopped="deadline")
    assert len(_warn([50, 50], phase1=cut, budget=20.0, stopped="deadline",
                     extra=False)) == 1


def test_a_budget_ending_as_the_cavity_passes_began_is_said():
    """An independent check: the knight with four YCB fruit, 25 s under load: phase 1 took
    24.97 s, the passes 0.03 s (2 tries), 184 objects at 43.2% and no warning (207 at 48.1%
    with 30 s); a pass had started, so they counted as run."""
    grown = PhaseStats(inserted=230, grown=184)

    def warn(seconds):
        return run_warnings(NAMES, HALF, np.array([92, 92]), 0.0, 0.04, grown, 25.0,
                            "deadline", None, 1, extra_passes_ran=True,
                            passes_seconds=seconds)

    (w,) = warn(0.03)
    assert w.startswith("the time budget (25 s) ended 0.03 s into the cavity passes: the first "
                        "objects grew (184 of 230)")
    assert warn(2.6) == []  # a tenth of the budget: the passes ran


def test_pack_warns_when_the_budget_ends_before_the_cavity_passes(tmp_path, monkeypatch):
    # the clock is made to run out right after the paper's phase 2, as a 20 s budget did
    paper_phase2 = placement.phase2

    def phase2_then_deadline(solver, q, spacing, rng, stop, **kw):
        st = paper_phase2(solver, q, spacing, rng, stop, **kw)
        stop.deadline = time.perf_counter() - 1.0
        return st

    monkeypatch.setattr(placement, "phase2", phase2_then_deadline)
    ball = tmp_path / "ball.stl"
    trimesh.creation.icosphere(2, radius=2.0).export(ball)
    p = pack("box:14x14x14", [str(ball)], seed=1, time_budget=600.0)
    assert p.certificate["certified"] and p.report.stopped == "deadline"
    assert p.report.extra_passes == []
    warned = [w for w in p.report.warnings if "before the cavity passes ran" in w]
    assert len(warned) == 1 and "600 s" in warned[0]


def test_pack_warns_when_a_type_fits_nowhere(tmp_path):
    # a 40 mm rod passes the inscribed-sphere check of a 20 mm box but fits no orientation;
    # it used to be left out of the packing without a word, and then kept in the mix, where
    # the balls waited for it (in a 40 mm box: 3 balls where 517 fit)
    rod, ball = tmp_path / "rod.stl", tmp_path / "ball.stl"
    trimesh.creation.box((40.0, 3.0, 3.0)).export(rod)
    trimesh.creation.icosphere(2, radius=2.5).export(ball)
    # without the last cavity pass (factor 0.4: the most time, for one ball more): the
    # balls still pack past 50, where they waited for the rod before
    three_passes = cavity_passes(0.8, 0.6, 0.5)
    p = pack("box:20x20x20", [str(rod), str(ball)], seed=1, fidelity="low",
             options=three_passes)
    assert p.certificate["certified"]
    assert np.all(p.type_index == 1) and p.n >= 50
    [warned] = p.report.warnings
    assert warned.startswith("type rod (share 50%) was left out: it is 40 units long, longer "
                             "than the container is across (34.64, its box's diagonal), so "
                             "it fits in no orientation; the other types were packed at their "
                             "shares among themselves. Scale the objects down")


def test_a_long_certification_of_a_heavy_mesh_names_its_faces():
    # 155 s of certification after a 20 s budget, with an 81,920-face sphere, said nothing
    warned = slow_certification(155.0, 20.0, ["cube", "sphere"], [12, 81_920])
    assert len(warned) == 1
    assert "sphere has 81,920 faces" in warned[0] and "20 s" in warned[0]
    assert slow_certification(155.0, 20.0, ["cube", "ball"], [12, 1_280]) == []  # light
    assert slow_certification(25.0, None, ["sphere"], [81_920]) == []  # quick
    assert slow_certification(100.0, 300.0, ["sphere"], [81_920]) == []  # within the budget


def test_pack_passes_its_certification_time_and_faces(tmp_path, monkeypatch):
    import jampacked.core.api as api

    seen = {}

    def spy(seconds, budget, names, faces):
        seen.update(seconds=seconds, budget=budget, names=list(names), faces=list(faces))
        return ["spied"]

    monkeypatch.setattr(api, "slow_certification", spy)
    ball = tmp_path / "ball.stl"
    trimesh.creation.icosphere(2, radius=2.0).export(ball)
    p = pack("box:14x14x14", [str(ball)], seed=1, time_budget=2.0)
    assert "spied" in p.report.warnings
    assert seen["budget"] == 2.0 and seen["faces"] == [320] and seen["names"] == ["ball"]
    assert seen["seconds"] == p.timings["certify"]


@pytest.mark.parametrize("fidelity, advised", [("medium", True), ("high", False)])
def test_a_type_left_out_for_depth_is_advised_high_fidelity_unless_it_ran_so(fidelity,
                                                                             advised):
    [w] = run_warnings(["ball", "cube"], np.array([0.5, 0.5]), np.array([0, 9]), 0.5, 0.04,
                       PhaseStats(), None, None, None, 1, left_out=[(0, 20.03, 20.0, "depth")],
                       fidelity=fidelity)
    assert w.startswith("type ball (share 50%) was left out: with its contact margins it "
                        "needs at least 20.03 units of depth")
    assert ("--fidelity high" in w) is advised and "remove the type." in w


def test_a_mix_held_back_by_a_type_that_found_no_room_also_advises_a_larger_tolerance():
    """A 26 mm ball (10%) fits a 30 mm box once, and the mix held the 6 mm balls to 20:
    the advice was only a tolerance of 0, which would hold them back further. A first fix
    dropped that advice wherever the mix held a hole back, which is most scenes at the
    mix cap, where a tolerance of 0 is the one that keeps the mix."""
    shares = np.array([0.1, 0.9])
    counts = np.array([1, 20])
    tvd = 0.5 * (abs(1 / 21 - 0.1) + abs(20 / 21 - 0.9))

    def warn(mix_held, max_tvd=0.04):
        [w] = run_warnings(["big", "small"], shares, counts, tvd, max_tvd, PhaseStats(), None,
                           None, None, 1, mix_held=mix_held)
        return w

    assert "a mix tolerance of 0 (--mix-tolerance 0) keeps the mix" in warn(151)
    assert warn(151).endswith("; a larger one (--mix-tolerance) lets the other types fill "
                              "the holes the mix held them back from, further from the "
                              "shares.")
    assert "a larger one" not in warn(0)
    # types far short, where the count is not the cause: both ways named
    w = run_warnings(["big", "small"], shares, np.array([10, 300]), 0.068, 0.04, PhaseStats(),
                     None, None, None, 1, mix_held=40)[0]
    assert "a smaller mix tolerance (--mix-tolerance) holds the other types back" in w
    assert "; a larger one lets the other types fill the holes the mix held them back" in w
    w = run_warnings(["big", "small"], shares, np.array([10, 300]), 0.068, 0.0, PhaseStats(),
                     None, None, None, 1, mix_held=40)[0]
    assert "a mix tolerance above 0 (--mix-tolerance) lets the other types fill" in w
