"""The clearance's physical cost: dilated volumes against answers known in closed form and
against manifold3d's Minkowski sum."""

from __future__ import annotations

import manifold3d as m3
import numpy as np
import pytest

from jampacked.core.dilation import clearance_cost, dilated_volume
from jampacked.core.solids import solid_arrays


def test_box_dilation_is_exact():
    v, f = solid_arrays(m3.Manifold.cube([2.0, 3.0, 4.0]))
    r = 0.3
    # box + ball: the box, its faces' slabs, quarter cylinders on the edges, corner octants
    exact = 24 + 2 * (6 + 12 + 8) * r + np.pi * 9 * r * r + 4 / 3 * np.pi * r ** 3
    assert dilated_volume(v, f, r) == pytest.approx(exact, rel=1e-12)


def test_sphere_dilation_matches_the_grown_sphere():
    v, f = solid_arrays(m3.Manifold.sphere(5.0, 256))
    # a tessellated sphere: only the tessellation's own volume error (3.5e-4) remains
    assert dilated_volume(v, f, 0.25) == pytest.approx(4 / 3 * np.pi * 5.25 ** 3, rel=5e-4)


def test_concave_solid_close_to_minkowski_sum():
    """An L of two boxes (one concave edge, where the r^2 term is approximate) against
    manifold3d's Minkowski sum with a fine ball scaled to the true ball's volume."""
    solid = m3.Manifold.cube([4.0, 1.0, 1.0]) + m3.Manifold.cube([1.0, 4.0, 1.0])
    r = 0.1
    ball = m3.Manifold.sphere(r, 64)
    ball = ball.scale([(4 / 3 * np.pi * r ** 3 / ball.volume()) ** (1 / 3)] * 3)
    reference = solid.minkowski_sum(ball).volume()
    v, f = solid_arrays(solid)
    grown = dilated_volume(v, f, r)
    # the dilation itself (3.29 volume units) to within 0.3%: a concave edge counted as
    # convex would be 0.5% off
    assert grown - solid.volume() == pytest.approx(reference - solid.volume(), rel=3e-3)


def test_clearance_cost_of_spheres():
    small = solid_arrays(m3.Manifold.sphere(2.0, 256))
    big = solid_arrays(m3.Manifold.sphere(4.0, 256))
    cost = clearance_cost([small, big], [3, 1], 0.4)
    want = [1 - (2 / 2.2) ** 3, 1 - (4 / 4.2) ** 3]
    assert cost["per_type"] == pytest.approx(want, rel=2e-3)
    # by count shares 3:1 the big type's volume (8 times the small's) dominates
    scene = 1 - (3 * 8 + 64) / (3 * 2.2 ** 3 + 4.2 ** 3)
    assert cost["scene"] == pytest.approx(scene, rel=2e-3)
    assert clearance_cost([small], [1], 0.0)["scene"] == pytest.approx(0.0, abs=1e-12)


def test_bad_arguments():
    v, f = solid_arrays(m3.Manifold.cube([1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="radius"):
        dilated_volume(v, f, -0.1)
    with pytest.raises(ValueError, match="shares"):
        clearance_cost([(v, f)], [1, 2], 0.1)
