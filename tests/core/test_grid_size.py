"""The container grid's finest spacing (`core/grid_size.py`)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core.api import pack
from jampacked.core.grid_size import MAX_CELLS_PER_AXIS, PAD_NODES, THIN_CELLS, finest_spacing


@pytest.mark.parametrize("extents", [(100.0, 100.0, 100.0), (200.0, 155.0, 195.0),
                                     (10.0, 10.0, 40.0)])
def test_a_container_that_is_not_thin_keeps_the_per_axis_cap(extents):
    ext = np.array(extents)
    assert finest_spacing(ext) == ext.max() / MAX_CELLS_PER_AXIS


@pytest.mark.parametrize("extents", [(70.0, 70.0, 2.2), (30.0, 30.0, 2.1), (200.0, 12.0, 12.0),
                                     (500.0, 500.0, 1.0)])
def test_a_thin_container_gets_cells_across_within_a_cubes_nodes(extents):
    ext = np.array(extents)
    h = finest_spacing(ext)
    budget = (MAX_CELLS_PER_AXIS + PAD_NODES) ** 3
    assert np.prod(ext / h + PAD_NODES) <= budget * (1 + 1e-9)
    assert h <= ext.max() / MAX_CELLS_PER_AXIS
    # as many cells across the thinnest side as asked, or the node budget is spent
    assert ext.min() / h >= THIN_CELLS * (1 - 1e-9) or np.prod(ext / h + PAD_NODES) > 0.99 * budget


def test_balls_that_fit_a_long_tube_are_placed(tmp_path):
    # a 200 mm tube: at 220 cells along it the grid was 13 cells across and read its middle
    # 5.41 deep, and a radius-5 ball with a 0.5 clearance (5.5 of the tube's 5.79) was
    # refused as "so none fits"; 100 mm of the same tube took 9
    tube = trimesh.creation.cylinder(radius=5.8, height=200.0, sections=64)
    ball = trimesh.creation.icosphere(subdivisions=3, radius=5.0)
    tube.export(tmp_path / "tube.stl")
    ball.export(tmp_path / "ball.stl")
    p = pack(str(tmp_path / "tube.stl"), [str(tmp_path / "ball.stl")], clearance=0.5, seed=1,
             time_budget=3.0)
    assert p.n >= 10 and p.certificate["certified"]
    assert p.certificate["min_wall_gap"] >= 0.5
