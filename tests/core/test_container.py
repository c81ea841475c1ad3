"""The container grid lowered where it sees room beyond the wall (core/container.py)."""

from __future__ import annotations

import numpy as np
import trimesh

from jampacked.core.container import build_container, tighten_to_surface
from jampacked.core.distance import distance_grid, min_pyramid
from jampacked.core.kernels import sample_grid_many
from jampacked.core.mesh_geometry import sample_surface


def _shell() -> trimesh.Trimesh:
    """The room between two spheres: from inside, the inner sphere's wall bulges into the
    container, where a signed distance is convex and its trilinear interpolant overshoots."""
    outer = trimesh.creation.icosphere(subdivisions=4, radius=20.0)
    inner = trimesh.creation.icosphere(subdivisions=4, radius=3.0)
    inner.apply_translation([0.31, -0.17, 0.23])  # off the grid's symmetry
    return trimesh.Trimesh(np.vstack([outer.vertices, inner.vertices]),
                           np.vstack([outer.faces, inner.faces[:, ::-1] + len(outer.vertices)]),
                           process=False)


def _over(grid, mesh: trimesh.Trimesh, seed: int) -> np.ndarray:
    """The grid's value (cells) at points of the surface: > 0 where it sees room beyond it."""
    pts = sample_surface(np.asarray(mesh.vertices), np.asarray(mesh.faces), 200_000, seed=seed)
    return sample_grid_many(grid.values, grid.origin, grid.spacing, pts) / grid.spacing


def test_tightened_grid_sees_no_room_beyond_a_bulging_wall():
    mesh = _shell()
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    raw = distance_grid(v, f, 1.5, pad=3.0, band=4)
    tight = tighten_to_surface(raw, v, f)
    before, after = _over(raw, mesh, seed=7), _over(tight, mesh, seed=7)
    # the exact node values overshoot the wall by more than the solver's wall margin (0.05
    # cell for smooth containers) ...
    assert before.max() > 0.1
    # ... and no longer, at surface points other than those the tightening tested
    assert after.max() < 0.02
    assert np.percentile(after, 99.9) <= 1e-3
    # it only lowers, and only next to the wall: nodes two cells or more away are exact
    drop = raw.values - tight.values
    assert drop.min() >= 0.0
    assert drop.max() > 0.0
    assert np.all(drop[np.abs(raw.values) > 2 * np.sqrt(3) * raw.spacing] == 0.0)


def test_a_grid_already_inside_the_wall_is_left_as_it_is():
    box = trimesh.creation.box(extents=(10.0, 8.0, 6.0))  # planes on grid lines: exact
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    raw = distance_grid(v, f, 1.0, pad=2.0, band=4)
    assert tighten_to_surface(raw, v, f) is raw


def test_build_container_uses_the_tightened_grid():
    mesh = _shell()
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    cont = build_container(v, f, float(mesh.volume), 1.5)
    assert _over(cont.grid, mesh, seed=3).max() < 0.02
    # the culling pyramid is that of the grid the kernels sample
    np.testing.assert_array_equal(cont.pyramid[0], min_pyramid(cont.grid.values)[0])
