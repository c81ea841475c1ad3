"""bench: issue 19's clearance rows: the physical cost of a scene's types and the comparison
with the scene without the clearance."""

from __future__ import annotations

import pytest
from testdata import MESHES, bench_module


def _scenes():
    return bench_module("scenes")


def test_clearance_row_compares_with_the_scene_without():
    row = _scenes().clearance_row(0.2, 0.04, 0.46, 0.50)
    assert row["density_lost"] == pytest.approx(0.08)
    assert row["target"] == pytest.approx(0.50 * 0.96 - 0.01)
    assert row["meets_target"] is False
    assert _scenes().clearance_row(0.2, 0.04, 0.471, 0.50)["meets_target"] is True
    unrun = _scenes().clearance_row(0.2, 0.04, 0.46, None)
    assert unrun["density_lost"] is None and unrun["meets_target"] is None


def test_physical_cost_of_carried_fruit():
    """The carried low-poly lemon and orange at x300 with 0.5 mm: a few percent each, the
    smaller fruit paying more, the mix between them."""
    types = ["fruit/ycb_lowpoly/014_lemon.obj", "fruit/ycb_lowpoly/017_orange.obj"]
    cost = _scenes().physical_cost(types, 300.0, 0.5, meshes=MESHES)
    lemon, orange = cost["per_type"]
    assert 0.03 < orange < lemon < 0.15
    assert orange < cost["scene"] < lemon


def test_every_clearance_scene_names_a_scene_without():
    scenes = _scenes().SCENES
    with_c = [n for n, s in scenes.items() if s["kwargs"].get("clearance")]
    assert with_c
    for name in with_c:
        without = scenes[scenes[name]["without"]]
        assert without["types"] == scenes[name]["types"]
        assert without["container"] == scenes[name]["container"]
        same = {k: v for k, v in scenes[name]["kwargs"].items() if k != "clearance"}
        assert same == without["kwargs"]


def test_median_phase_seconds_of_runs_with_and_without_other_attempts():
    # a run of one attempt has no other_attempts: the scene row's summary raised KeyError
    # when seed 1 made two attempts and seed 2 one
    runs = [{"timings": {"phase1": 1.0, "other_attempts": 4.0}}, {"timings": {"phase1": 3.0}},
            {"timings": {"phase1": 2.0, "other_attempts": 6.0}}]
    assert _scenes().median_phase_seconds(runs) == {"phase1": 2.0, "other_attempts": 4.0}
