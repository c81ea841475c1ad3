"""TypeSpread (core/type_spread.py) against a direct numpy search, across its k-d tree
rebuilds, and phase 1's spread window on a real placement."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from testdata import mesh_path

from jampacked.core import type_spread
from jampacked.core.type_spread import TypeSpread


def _reference(points: list[np.ndarray], query: np.ndarray) -> np.ndarray:
    if not points:
        return np.full(len(query), np.inf)
    return np.linalg.norm(query[:, None] - np.array(points)[None], axis=2).min(axis=1)


@pytest.mark.parametrize("rebuild", [type_spread.REBUILD_AFTER, 5])
def test_nearest_matches_a_direct_search(monkeypatch, rebuild):
    monkeypatch.setattr(type_spread, "REBUILD_AFTER", rebuild)
    rng = np.random.default_rng(3)
    spread = TypeSpread(3)
    added: list[list[np.ndarray]] = [[], [], []]
    query = rng.uniform(-10, 10, (7, 3))
    for step in range(400):
        t = int(rng.integers(0, 2))  # type 2 stays empty
        p = rng.uniform(-10, 10, 3)
        spread.add(t, p)
        added[t].append(p)
        if step % 37 == 0 or step == 399:
            for u in range(3):
                np.testing.assert_allclose(spread.nearest(u, query),
                                           _reference(added[u], query), rtol=0, atol=1e-12)
    assert spread.trees[0] is not None and spread.in_tree[0] > 0
    assert np.all(np.isinf(spread.nearest(2, query)))


@pytest.mark.parametrize("rebuild", [type_spread.REBUILD_AFTER, 5])
def test_points_added_at_once_match_a_direct_search(monkeypatch, rebuild):
    monkeypatch.setattr(type_spread, "REBUILD_AFTER", rebuild)
    rng = np.random.default_rng(4)
    spread = TypeSpread(2)
    added: list[np.ndarray] = []
    query = rng.uniform(-10, 10, (9, 3))
    for k in (1, 3, 2, 40, 7, 150):
        pts = rng.uniform(-10, 10, (k, 3))
        spread.add_many(0, pts)
        added.extend(pts)
        np.testing.assert_allclose(spread.nearest(0, query), _reference(added, query),
                                   rtol=0, atol=1e-12)
    assert spread.trees[0] is not None
    assert np.all(np.isinf(spread.nearest(1, query)))


def test_the_type_needed_among_those_that_fit():
    shares = np.array([0.5, 0.5])
    by_volume = np.array([0, 1])
    # both at their share: any type with a share may be needed; within, only one that fits
    assert type_spread.type_needed(np.array([3.0, 3.0]), shares, by_volume) == 0
    assert type_spread.type_needed(np.array([3.0, 3.0]), shares, [1], within=True) == 1
    # type 0 is behind: still the one needed, unless only type 1 fits
    assert type_spread.type_needed(np.array([2.0, 5.0]), shares, [1]) == 0
    assert type_spread.type_needed(np.array([2.0, 5.0]), shares, [1], within=True) == 1


def test_the_recorded_point_is_a_copy():
    spread = TypeSpread(1)
    p = np.array([1.0, 2.0, 3.0])
    spread.add(0, p)
    p[:] = 100.0  # the solver moves its objects in place
    assert spread.nearest(0, np.zeros(3))[0] == pytest.approx(np.sqrt(14.0))


def test_phase1_spread_window_spreads_each_type():
    """Four polytope types in a box, phase 1 alone (no cavity passes), the same seed: the
    window raises every type's clumping index over the random order's, at the same mix.
    Coarse growth (10 steps of 10 iterations) keeps it within the suite's time: the window
    picks which lattice object grows, however finely it then grows (seeds 1-5 all show it)."""
    from jampacked.core.api import pack
    from jampacked.core.options import PackOptions

    types = [str(mesh_path(f"polyhedra/convex5/polytope{i}.obj")) for i in range(1, 5)]
    base = PackOptions()
    runs = {}
    for window in (1, 8):
        opts = replace(base, phases=replace(base.phases, spread_window=window,
                                            phase1_growth_steps=10, phase1_iterations=10),
                       cavity=replace(base.cavity, factors=()))
        p = pack("box:30x30x30", types, seed=2, type_scale=0.6, fidelity="low", options=opts)
        # the window is capped at a SPREAD_QUEUE-th of the lattice: here it is all 8
        assert p.report.phase1.inserted >= 8 * window
        runs[window] = p.metrics
    assert runs[8]["nni_mean"] > runs[1]["nni_mean"] + 0.1
    assert min(runs[8]["nni_per_type"]) > 1.1
    assert runs[8]["tvd"] <= 0.05 and runs[1]["tvd"] <= 0.05
