"""Contact margins from the distance grids' surface error (core/margins.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core.container import build_container
from jampacked.core.margins import SMOOTH_ERROR, contact_margins, surface_error
from jampacked.core.meshes import sample_surface
from jampacked.core.objects import build_type


def _turned(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh in a general orientation (an axis-aligned face or edge lies on grid lines,
    where the grid is exact)."""
    mesh = mesh.copy()
    mesh.apply_transform(trimesh.transformations.euler_matrix(0.3, 0.7, 1.1))
    return mesh


def _type(mesh: trimesh.Trimesh, name: str):
    return build_type(name, mesh.vertices, mesh.faces, path=None, sha256=None, share=1.0,
                      fidelity="medium", use_cache=False)


def test_surface_samples_lie_on_the_surface_spread_by_area():
    box = trimesh.creation.box((10.0, 10.0, 1.0))
    pts = sample_surface(np.asarray(box.vertices), np.asarray(box.faces), 20000)
    # every point on a face: at the box's half extent along some axis
    on_face = np.isclose(np.abs(pts), [5.0, 5.0, 0.5]).any(axis=1)
    assert on_face.all()
    # the two big faces hold 200 of the 240 units of area
    assert np.mean(np.isclose(np.abs(pts[:, 2]), 0.5)) == pytest.approx(200 / 240, abs=0.02)
    again = sample_surface(np.asarray(box.vertices), np.asarray(box.faces), 20000)
    assert np.array_equal(pts, again)


def test_smooth_types_keep_the_small_margin_a_sharp_one_gives_all_the_large():
    sphere = _type(trimesh.creation.icosphere(subdivisions=4, radius=5.0), "sphere")
    cube = _type(_turned(trimesh.creation.box((10.0, 10.0, 10.0))), "cube")
    e_sphere = surface_error(sphere.grid, sphere.vertices, sphere.faces, solid=True)
    e_cube = surface_error(cube.grid, cube.vertices, cube.faces, solid=True)
    assert e_sphere < SMOOTH_ERROR < e_cube  # the cube's edges are rounded off
    box = trimesh.creation.box((40.0, 40.0, 40.0))
    cont = build_container(np.asarray(box.vertices), np.asarray(box.faces), box.volume, 1.0)
    m = contact_margins([sphere], cont.grid, cont.vertices, cont.faces, 0.025, 0.05, 0.05, 0.1)
    assert m.object_cells == [0.025]
    assert m.objects == pytest.approx([0.025 * sphere.grid.spacing])
    m = contact_margins([sphere, cube], cont.grid, cont.vertices, cont.faces, 0.025, 0.05,
                        0.05, 0.1)
    assert m.object_cells == [0.05, 0.05]
    assert m.objects == pytest.approx([0.05 * sphere.grid.spacing, 0.05 * cube.grid.spacing])
    # inside a box the grid never sees more room than there is (its planes are exact)
    assert m.wall_error <= 1e-9 and m.wall == pytest.approx(0.05 * cont.grid.spacing)
    # with a clearance the exact gap check has no tolerance: the larger margins throughout
    m = contact_margins([sphere], cont.grid, cont.vertices, cont.faces, 0.025, 0.05, 0.05, 0.1,
                        clearance=0.5)
    assert m.object_cells == [0.05] and m.wall_cells == 0.1


def test_container_error_counts_room_the_grid_invents():
    """A container whose wall the grid moves outwards (a thin inward fin, rounded off by
    the grid) is not smooth; the same measure with solid=False reads that direction."""
    outer = trimesh.creation.box((40.0, 40.0, 40.0))
    fin = trimesh.creation.box((30.0, 0.2, 30.0))
    fin.apply_translation([5.0, 0.0, 0.0])
    shape = _turned(outer.difference(fin))
    cont = build_container(np.asarray(shape.vertices), np.asarray(shape.faces),
                           shape.volume, 1.0)
    err = surface_error(cont.grid, cont.vertices, cont.faces, solid=False)
    assert err > SMOOTH_ERROR
