"""The phases with a clearance: a hole is judged by the room an object there has, its
distance to the nearest object or wall less the clearance (`Solver.free_distances`)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core import phases
from jampacked.core.container import build_container
from jampacked.core.objects import build_type
from jampacked.core.solver import PackState, Solver, SolverParams, TypeTable


def test_cavity_object_starts_at_the_scale_its_room_allows(monkeypatch):
    """One ball in a box too small for it at full size: the cavity pass inserts it at the
    box's centre and starts growing it at (distance to the wall - clearance - 2 margins)
    / bounding radius, the clearance counted once."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=5.0)
    typ = build_type("ball", ball.vertices, ball.faces, path=None, sha256=None, share=1.0,
                     fidelity="medium", use_cache=False)
    box = trimesh.creation.box((8.0, 8.0, 8.0))
    cont = build_container(np.asarray(box.vertices), np.asarray(box.faces), box.volume, 0.5)
    c, m = 0.3, 0.01
    solver = Solver(cont, TypeTable([typ]), PackState(), SolverParams(clearance=c))
    starts, added = [], []
    add = solver.s.add

    def recording_add(t, pos, quat, scale, margin):
        added.append(np.array(pos, np.float64))
        return add(t, pos, quat, scale, margin)

    def fake_grow(solver, k, start, iters, stop, steps=phases.GROWTH_STEPS):
        starts.append(start)
        solver.s.alive[k] = 0  # as a failed growth leaves it
        return False

    monkeypatch.setattr(solver.s, "add", recording_add)
    monkeypatch.setattr(phases, "grow", fake_grow)
    phases.phase2(solver, np.array([1.0]), 1.0, np.random.default_rng(0),
                  phases.Stop(None, None), margin=np.array([m]), retries=0, threshold=0.5,
                  fit_factor=0.1, patience=1)
    assert starts and added
    # the room at the insertion point is its distance to the wall less c (test_kernels
    # checks that): the start subtracts the two margins from it, not the clearance again
    room = float(solver.free_distances(added[0][None])[0])
    assert starts[0] == pytest.approx((room - 2 * m) / typ.radius, rel=1e-9)
    assert starts[0] < 1.0
