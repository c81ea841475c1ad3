"""The cost estimate and the size window (`core/cost.py`), and the container's lattice."""

from __future__ import annotations

import numpy as np
import pytest

from jampacked.core import container as container_module
from jampacked.core import cost
from jampacked.core.container import build_container, interior_points
from jampacked.core.errors import InputError, PackingError
from jampacked.core.grid_size import MAX_CELLS_PER_AXIS, PAD_NODES
from jampacked.core.meshes import box_mesh


def _cube_type(side: float) -> cost.TypeSize:
    return cost.TypeSize("cube", "cube.stl", np.full(3, side), side ** 3)


def test_machine_memory_is_positive_and_bounded_by_the_address_space_limit():
    import resource

    mem = cost.machine_memory()
    assert mem > 0
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        assert mem <= soft


def test_estimate_counts_follow_the_volumes():
    est = cost.estimate_cost(np.full(3, 100.0), 1e6, np.array([1.0]), np.array([1.0]), 4.0,
                             0.5, 0.5, (0.8, 0.4))
    assert est.objects == pytest.approx(0.64e6)
    assert est.phase1_points == pytest.approx(0.5e6)
    assert est.cavity_points == pytest.approx(0.5e6 / (0.5 * 0.4) ** 3)
    # the grid's cap bounds its nodes whatever the objects' size
    assert est.container_grid_nodes <= (MAX_CELLS_PER_AXIS + PAD_NODES) ** 3 * (1 + 1e-9)
    assert est.memory > est.cavity_points * cost.BYTES_PER_LATTICE_POINT


def test_check_cost_passes_a_small_request_and_refuses_a_huge_one():
    small = cost.estimate_cost(np.full(3, 30.0), 2.7e4, np.array([100.0]), np.array([1.0]),
                               4.0, 0.5, 0.5, (0.4,))
    cost.check_cost(small, "box", np.full(3, 30.0), _cube_type(100.0 ** (1 / 3)))
    huge = cost.estimate_cost(np.full(3, 1e4), 1e12, np.array([1e-3]), np.array([1.0]),
                              4.0, 0.5, 0.5, (0.4,))
    with pytest.raises(PackingError, match=r"holds about 6\.4e\+14 objects.*cube \(cube\.stl\)"):
        cost.check_cost(huge, "box", np.full(3, 1e4), _cube_type(0.1))


@pytest.mark.parametrize("side", [np.inf, 0.0, 1e-9, 1e10])
def test_check_sizes_refuses_types_outside_the_window(side):
    with np.errstate(over="ignore"):
        t = _cube_type(side)
    with pytest.raises(InputError, match=r"object type cube \(cube\.stl\)"):
        cost.check_sizes("box:10x10x10", np.full(3, 10.0), 1e3, [t], 1.0, None)


def test_interior_points_slab_by_slab_are_the_whole_lattice(monkeypatch):
    m = box_mesh([30.0, 20.0, 40.0])
    c = build_container(m.vertices, m.faces, m.volume, 1.0)
    whole = interior_points(c, 0.7, 2.0, np.random.default_rng(1))
    monkeypatch.setattr(container_module, "SLAB_POINTS", 3000)
    slabs = interior_points(c, 0.7, 2.0, np.random.default_rng(1))
    assert len(whole) > 10000
    np.testing.assert_array_equal(whole, slabs)
