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


def _ball_and_box():
    """A ball of radius 5 (an icosphere) and an 8 mm box, too small for it at full size."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=5.0)
    typ = build_type("ball", ball.vertices, ball.faces, path=None, sha256=None, share=1.0,
                     fidelity="medium", use_cache=False)
    box = trimesh.creation.box((8.0, 8.0, 8.0))
    return typ, build_container(np.asarray(box.vertices), np.asarray(box.faces), box.volume,
                                0.5)


def test_cavity_object_starts_at_the_scale_its_room_allows(monkeypatch):
    """One ball in a box too small for it at full size: the cavity pass inserts it at the
    box's centre and starts growing it at (distance to the wall - clearance - 2 margins)
    / bounding radius, the clearance counted once."""
    typ, cont = _ball_and_box()
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


def test_no_try_where_the_object_would_start_below_min_start(monkeypatch):
    """The same ball and box: the ball would start at s0 of its size; a cavity pass with
    min_start just below s0 tries it there, one just above does not."""
    typ, cont = _ball_and_box()
    starts = []

    def fake_grow(solver, k, start, iters, stop, steps=phases.GROWTH_STEPS):
        starts.append(start)
        solver.s.alive[k] = 0
        return False

    monkeypatch.setattr(phases, "grow", fake_grow)

    def tries(min_start):
        solver = Solver(cont, TypeTable([typ]), PackState(), SolverParams(clearance=0.3))
        return phases.phase2(solver, np.array([1.0]), 1.0, np.random.default_rng(0),
                             phases.Stop(None, None), margin=np.array([0.01]), retries=0,
                             threshold=0.5, fit_factor=0.1, patience=1,
                             min_start=min_start).inserted

    assert tries(0.0) == 1
    s0 = starts[0]
    assert 0.1 < s0 < 1.0
    assert tries(s0 - 0.01) == 1 and starts[1] == s0
    assert tries(s0 + 0.01) == 0 and len(starts) == 2


def test_asked_for_the_extra_passes_try_no_object_below_min_start(monkeypatch):
    """Oranges and lemons in a small box with 0.2 mm: with `cavity.min_start` 0.4 no
    extra-pass try starts below 0.4; by default (0) some do, so the check can fail. Only
    the 0.4 pass tries any below 0.4: it alone runs, with a patience of 20 (of 60)."""
    from testdata import mesh_path

    from jampacked.core import api
    from jampacked.core.options import CavityPassOptions, PackOptions

    fruit = [str(mesh_path(f"fruit/ycb_lowpoly/{n}.obj")) for n in ("017_orange", "014_lemon")]
    tried = []

    def pack(options):
        tried.clear()
        p = api.pack("box:25x25x25", fruit, seed=3, type_scale=100.0, clearance=0.2,
                     fidelity="low", options=options)
        n = p.report.phase1.inserted + p.report.phase2.inserted
        return p, tried[n:]

    add = PackState.add

    def recording_add(self, t, pos, quat, scale, margin):
        tried.append(scale)
        return add(self, t, pos, quat, scale, margin)

    monkeypatch.setattr(PackState, "add", recording_add)
    def cavity(min_start):
        return PackOptions(cavity=CavityPassOptions(factors=(0.4,), patience=20,
                                                    min_start=min_start))

    p, extra = pack(cavity(0.4))
    assert extra and min(extra) >= 0.4
    assert p.certificate["certified"]
    _, extra = pack(cavity(CavityPassOptions().min_start))  # the default
    assert min(extra) < 0.4
