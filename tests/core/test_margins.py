"""Contact margins from the distance grids' surface error (core/margins.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core.container import build_container
from jampacked.core.distance import distance_grid, distances_to_given_triangles
from jampacked.core.kernels import sample_grid_many
from jampacked.core.margins import SMOOTH_ERROR, contact_margins, sampling_gap, surface_error
from jampacked.core.meshes import sample_surface
from jampacked.core.objects import build_type, surface_samples


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
    # with a clearance the same choice by grid error (the repair pushes short gaps apart)
    m = contact_margins([sphere], cont.grid, cont.vertices, cont.faces, 0.025, 0.05, 0.05, 0.1,
                        clearance=0.5)
    assert m.object_cells == [0.025] and m.wall_cells == 0.05
    # ... plus half the gap the surface points hide at that clearance
    gap = sampling_gap(sphere.grid, sphere.vertices, sphere.faces, sphere.surface_points,
                       sphere.equivalent_radius, 0.5)
    assert m.sampling_gaps == pytest.approx([gap]) and gap > 0
    assert m.objects == pytest.approx([0.025 * sphere.grid.spacing + 0.5 * gap])
    assert m.report().sampling_gaps == m.sampling_gaps
    # the wall is tested from the object's side only: it keeps the other half
    assert m.wall == pytest.approx(0.05 * cont.grid.spacing + 0.5 * gap)


def test_sampling_gap_shrinks_as_surface_points_get_denser():
    """A ball of radius r held g from a sphere of radius R: between surface points x apart
    the sphere comes closer to it by about x^2 (1/R + 1/r) / 8; the measure is relative to
    the surface, so a dense point set hides almost nothing."""
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=5.0)  # 2562 vertices
    sphere = _type(mesh, "sphere")
    v, f = sphere.vertices, sphere.faces
    gaps = [sampling_gap(sphere.grid, v, f, surface_samples(v, f, n), 5.0, 0.5)
            for n in (96, 384, 1536)]
    assert gaps[0] > gaps[1] > gaps[2] > 0
    # 96 points on a sphere of radius 5 lie about 1.8 apart: the gap is tenths of a unit
    assert 0.05 < gaps[0] < 0.5
    assert gaps[2] < 0.25 * gaps[0]
    assert sampling_gap(sphere.grid, v, f, v, 5.0, 0.5) < 0.01  # every vertex a point


def test_container_error_counts_room_the_grid_invents():
    """A grid that moves a container's wall outwards (a thin inward fin, rounded off by the
    grid) is not smooth; the same measure with solid=False reads that direction."""
    outer = trimesh.creation.box((40.0, 40.0, 40.0))
    fin = trimesh.creation.box((30.0, 0.2, 30.0))
    fin.apply_translation([5.0, 0.0, 0.0])
    shape = _turned(outer.difference(fin))
    v, f = np.asarray(shape.vertices), np.asarray(shape.faces)
    raw = distance_grid(v, f, 1.0, pad=2.0, band=4)
    assert surface_error(raw, v, f, solid=False) > SMOOTH_ERROR
    # the container's own grid is lowered where it invents room (core/container.py), and
    # then reads smooth: the fin's error no longer asks the whole wall for the sharp margin
    cont = build_container(v, f, shape.volume, 1.0)
    assert surface_error(cont.grid, cont.vertices, cont.faces, solid=False) < 0.01


def test_a_clearance_gets_a_grid_that_reaches_it():
    """Beyond its box a grid's distances are extrapolated and read too large; with a
    clearance the grid reaches past it, so a gap of that size is read true."""
    mesh = _turned(trimesh.creation.box((10.0, 6.0, 4.0)))
    near = _type(mesh, "near")
    far = build_type("far", mesh.vertices, mesh.faces, path=None, sha256=None, share=1.0,
                     fidelity="medium", use_cache=False, reach=5.0)
    v, f = far.vertices, far.faces
    at = sample_surface(v, f, 2000)
    centre = v.mean(axis=0)
    out = at + 5.0 * (at - centre) / np.linalg.norm(at - centre, axis=1, keepdims=True)
    true = np.min([distances_to_given_triangles(out, np.full(len(out), k, np.int64), v, f)
                   for k in range(len(f))], axis=0)
    errs = []
    for t in (near, far):
        d = sample_grid_many(t.grid.values, t.grid.origin, t.grid.spacing, out)
        errs.append(float(np.percentile(-d - true, 99)))  # how much further it reads
    assert errs[0] > 0.1 and errs[1] < 0.25 * errs[0]


def test_with_a_clearance_surface_points_cover_large_faces():
    """A low-poly type's points lie on its vertices and edges. With a clearance, a
    neighbour held off the middle of a large face is far from all of them, and the margin
    (half that gap) took a large part of a thin plate's room: with a clearance the points
    cover the faces too; without one they stay on the edges (packings unchanged)."""
    plate = _turned(trimesh.creation.box((11.0, 4.0, 14.0)))

    def plate_type(reach: float):
        return build_type("plate", plate.vertices, plate.faces, path=None, sha256=None,
                          share=1.0, fidelity="medium", use_cache=False, reach=reach)

    bare, clear = plate_type(0.0), plate_type(0.3)
    v, f = bare.vertices, bare.faces
    assert np.array_equal(bare.surface_points, surface_samples(v, f, 384))
    edges = trimesh.Trimesh(v, f).edges_unique
    a, b = v[edges[:, 0]], v[edges[:, 1]]

    def off_edges(points: np.ndarray) -> np.ndarray:
        """Each point's distance to the nearest edge of the plate."""
        ab = b - a
        t = np.clip(np.einsum("pej,ej->pe", points[:, None] - a, ab)
                    / np.einsum("ej,ej->e", ab, ab), 0.0, 1.0)
        near = a + t[..., None] * ab
        return np.linalg.norm(points[:, None] - near, axis=2).min(axis=1)

    assert off_edges(bare.surface_points).max() < 1e-9
    assert np.median(off_edges(clear.surface_points)) > 0.3
    gaps = [sampling_gap(t.grid, t.vertices, t.faces, t.surface_points, 2.0, 0.3)
            for t in (bare, clear)]
    assert gaps[0] > 1.0 and gaps[1] < 0.25 * gaps[0]
