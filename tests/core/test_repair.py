"""Certification's repair: without a time budget its work is bounded by rounds, not seconds,
so a busy machine cannot change the packing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from testdata import mesh_path

from jampacked.core.api import pack
from jampacked.core.options import PackOptions

FRUIT = [str(mesh_path(f"fruit/ycb_lowpoly/{n}.obj")) for n in ("017_orange", "014_lemon")]


def _pack(**kwargs):
    # low fidelity at this size leaves many overlaps for the repair (about 50 bad pairs)
    return pack("box:24x24x24", FRUIT, seed=1, type_scale=100.0, fidelity="low", **kwargs)


def test_without_a_budget_the_repair_ignores_its_time_cap():
    ref = _pack()
    assert ref.report.repair.rounds > 0 and ref.report.repair.moved > 0
    base = PackOptions()
    # a cap already spent: with a budget it would stop pushing at once and remove instead
    spent = replace(base, repair=replace(base.repair, seconds=-1.0))
    p = _pack(options=spent)
    assert not p.report.repair.timed_out
    assert p.type_index.tolist() == ref.type_index.tolist()
    np.testing.assert_array_equal(p.translations, ref.translations)


def test_with_a_budget_the_repair_keeps_its_time_cap():
    base = PackOptions()
    spent = replace(base, repair=replace(base.repair, seconds=-1.0),
                    attempts=replace(base.attempts, max_attempts=1))
    p = _pack(options=spent, time_budget=60.0)
    assert p.report.repair.timed_out and p.certificate["certified"]
