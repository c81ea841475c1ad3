"""A packing of over a thousand objects without a time budget runs every extra cavity pass to
its end (the passes' solver work follows the objects near each hole, not all of them), and
the result is certified. Coarse solver settings keep it within the suite's time."""

from __future__ import annotations

from testdata import mesh_path

from jampacked.core.api import pack
from jampacked.core.options import PackOptions

POLY = [mesh_path(f"polyhedra/convex5/polytope{i}.obj") for i in (1, 2)]
#: polytope1's largest extent in its file's units: type_scale makes it 1
EXTENT = 21.0


def test_a_thousand_objects_run_the_extra_passes_to_their_end():
    opts = PackOptions.from_flat({
        "spheres": 4, "surface_points": 48, "grid_cells": 12,
        "phase1_iterations": 10, "phase1_growth_steps": 10, "phase2_iterations": 10,
        "extra_iterations": 8, "extra_growth_steps": 2, "extra_patience": 4,
        "extra_passes": [0.8], "repair_rounds": 1, "tune_threads": False})
    p = pack("box:7x7x7", POLY, seed=1, fidelity="low", type_scale=1.0 / EXTENT,
             options=opts)
    assert p.n >= 1000
    passes = p.report.extra_passes
    assert [e.factor for e in passes] == [0.8]
    assert all(e.stopped in ("", "patience") for e in passes)  # no deadline, no cancel
    assert sum(e.grown for e in passes) > 0
    assert p.report.stopped is None
    assert p.certificate["certified"]
    assert p.metrics["count"] == p.n
