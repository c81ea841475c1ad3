"""Phase 1's growth steps: the paper's 30, or fewer where the lattice holds many objects
(as dense a phase 1 in a third of the time there: docs/notes-core.md)."""

from __future__ import annotations

import threading

import pytest
from testdata import mesh_path

from jampacked.core import phases
from jampacked.core.api import pack
from jampacked.core.options import PackOptions

FRUIT = [str(mesh_path(f"fruit/ycb_lowpoly/{n}.obj")) for n in ("017_orange", "014_lemon")]


def test_the_steps_follow_the_lattice_size_unless_given():
    many = phases.MANY_OBJECTS
    assert phases.phase1_growth_steps(None, many) == phases.GROWTH_STEPS == 30
    assert phases.phase1_growth_steps(None, many + 1) == phases.MANY_OBJECTS_STEPS == 6
    assert phases.phase1_growth_steps(20, many + 1) == 20
    assert phases.phase1_growth_steps(30, 5) == 30


def _phase1(**flat):
    options = PackOptions.from_flat({"extra_passes": [], "max_attempts": 1, **flat})
    p = pack("box:20x20x20", FRUIT, seed=1, type_scale=100.0, fidelity="low",
             options=options)
    return p.report.phase1


@pytest.mark.parametrize("many,given,steps", [(10_000, None, 30), (5, None, 6), (5, 30, 30)])
def test_phase1_grows_in_the_steps_chosen(monkeypatch, many, given, steps):
    monkeypatch.setattr(phases, "MANY_OBJECTS", many)
    calls = []
    grow = phases.grow
    here = threading.get_ident()  # not a packing another test left running in this process

    def counted(*a):
        if threading.get_ident() == here:
            calls.append(a[-1])
        return grow(*a)

    monkeypatch.setattr(phases, "grow", counted)
    flat = {} if given is None else {"phase1_growth_steps": given}
    st = _phase1(**flat)
    assert st.inserted > 5 and st.extra["growth_steps"] == steps
    assert st.grown > 5 and set(calls[: st.grown]) == {steps}  # phase 1 grows first
