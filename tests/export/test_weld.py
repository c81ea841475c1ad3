"""Parts that touch face to face unite into one body (`export/weld.py`): their corners,
a rounding error apart, are given one position before the union."""

from __future__ import annotations

import manifold3d as m3
import numpy as np
import pytest
import trimesh

from jampacked.core.api import pack
from jampacked.core.errors import Cancelled, MeshError
from jampacked.core.packing_json import save_packing
from jampacked.core.solids import solid_arrays, to_solid
from jampacked.export import union
from jampacked.export.assemble import export_packing
from jampacked.export.options import ExportOptions
from jampacked.export.union import clean_bodies, union_arrays
from jampacked.export.weld import APART_REL, WELD_REL, weld_touching


def _cube(shift, size: float = 1.0):
    box = trimesh.creation.box(extents=(size, size, size))
    return to_solid(box.vertices + np.asarray(shift, float), box.faces)


def _pair(gap: float):
    """Two unit cubes side by side along x, the second's corners `gap` from the first's."""
    return [_cube((0.0, 0.0, 0.0)), _cube((1.0 + gap, 0.0, 0.0))]


def test_corners_a_rounding_error_apart_are_given_one_position():
    pieces, moved = weld_touching(_pair(3e-9))
    assert moved == 4
    a, _ = solid_arrays(pieces[0])
    b, _ = solid_arrays(pieces[1])
    shared = a[np.isclose(a[:, 0], 0.5)]
    assert len(shared) == 4
    # each of the first cube's +x corners is now exactly one of the second's -x corners
    assert all(np.any(np.all(b == corner, axis=1)) for corner in shared)
    assert np.allclose(b[b[:, 0] > 1.0][:, 0], 1.5 + 3e-9)  # the far side stays


def test_solids_apart_or_touching_exactly_are_returned_as_they_were():
    diagonal = np.linalg.norm([2.0, 1.0, 1.0])
    for gap in (0.0, 3.0 * WELD_REL * diagonal, 0.1):
        given = _pair(gap)
        pieces, moved = weld_touching(given)
        assert moved == 0
        assert all(p is q for p, q in zip(pieces, given, strict=True))


def test_a_cancel_stops_the_weld():
    calls = []

    def cancel():
        calls.append(1)
        if len(calls) == 2:  # after the pairs are found, before any solid is rebuilt
            raise Cancelled("export cancelled")

    with pytest.raises(Cancelled):
        weld_touching(_pair(3e-9), cancel)
    calls.clear()
    with pytest.raises(Cancelled):
        union_arrays(_pair(3e-9), None, check_cancel=cancel)


def test_empty_solids_have_nothing_to_weld():
    empty = m3.Manifold()
    pieces, moved = weld_touching([empty, empty])
    assert moved == 0 and all(p is empty for p in pieces)
    v, f, left = union_arrays([empty, empty], _cube((0.0, 0.0, 0.0)))
    assert len(f) == 12 and left == 0


@pytest.mark.parametrize("float32", [False, True])
def test_cubes_that_touch_within_a_rounding_error_unite_into_one_body(float32):
    v, f, left = union_arrays(_pair(3e-9), None, float32=float32)
    assert left == 0
    out = clean_bodies(v, f, fill_voids=True, closed_shell=False)
    assert out.bodies == 1
    assert out.volume == pytest.approx(2.0, abs=1e-6)


@pytest.fixture(scope="module")
def brick_grid(tmp_path_factory):
    """240 turned bricks, stored as a float32 STL, that fill a box as a grid of bricks
    touching face to face (`core/box_grid.py`)."""
    tmp = tmp_path_factory.mktemp("grid")
    brick = tmp / "brick.stl"
    turn = trimesh.transformations.rotation_matrix(0.4, [3.0, 1.0, -2.0])
    trimesh.creation.box(extents=(10.0, 5.0, 5.0)).apply_transform(turn).export(brick)
    packing = pack("box:50x30x40", [str(brick)], seed=1)
    assert packing.n == 240
    path = tmp / "packing.json"
    save_packing(packing, path)
    return path


@pytest.mark.parametrize("shell", [None, 2.0])
def test_a_grid_of_bricks_exports_as_one_solid_block(brick_grid, tmp_path, shell):
    out = export_packing(brick_grid, [tmp_path / "block.3mf", tmp_path / "block.stl"],
                         ExportOptions(mode="union", shell=shell))
    assert out.bodies == 1
    assert out.volume == pytest.approx(60000.0, rel=1e-6)
    # the thin wedges where the bricks' shared faces were split differently are no voids
    assert not any("void" in w or "stand apart" in w for w in out.warnings)
    for name in ("block.3mf", "block.stl"):
        mesh = trimesh.load(tmp_path / name, force="mesh")
        assert mesh.is_watertight and mesh.body_count == 1
        assert mesh.volume == pytest.approx(60000.0, rel=1e-5)


def test_without_the_weld_the_grid_is_no_one_body(brick_grid, tmp_path, monkeypatch):
    """What the weld mends: without it the bricks' union leaves faces that touch (refused
    by validation before the objects were set apart), so they are written apart."""
    monkeypatch.setattr(union, "weld_touching", lambda pieces, check=None: (pieces, 0))
    out = export_packing(brick_grid, tmp_path / "block.3mf", ExportOptions(mode="union"))
    assert out.bodies == 240 and any("stand apart" in w for w in out.warnings)


def _holed() -> m3.Manifold:
    """A 10 x 5 x 5 brick with two holes through it."""
    return (m3.Manifold.cube((10.0, 5.0, 5.0), True)
            - m3.Manifold.cylinder(12.0, 1.2, 1.2, 24, True).rotate((0.0, 90.0, 0.0))
            - m3.Manifold.cylinder(6.0, 0.8, 0.8, 16, True).rotate((90.0, 0.0, 0.0))
            .translate((2.0, 0.0, 0.0)))


@pytest.fixture(scope="module")
def holed_grid(tmp_path_factory):
    """240 holed bricks filling a box as a grid."""
    tmp = tmp_path_factory.mktemp("holed")
    v, f = solid_arrays(_holed())
    trimesh.Trimesh(v, f, process=False).export(tmp / "holed.stl")
    packing = pack("box:50x30x40", [str(tmp / "holed.stl")], seed=1)
    assert packing.n == 240
    save_packing(packing, tmp / "packing.json")
    return tmp / "packing.json"


def test_parts_whose_touching_faces_are_split_differently_are_set_apart(holed_grid,
                                                                         tmp_path):
    """A brick with a hole through it: its faces either side of a contact are triangulated
    differently, no corner meets a corner, and the weld cannot fuse them (refused with 130
    face pairs before): the objects are made a little smaller and written apart."""
    part = _holed()
    out = export_packing(holed_grid, [tmp_path / "block.3mf", tmp_path / "block.stl"],
                         ExportOptions(mode="union"))
    assert out.bodies == 240
    assert any("stand apart" in w for w in out.warnings)
    step = APART_REL * np.linalg.norm([50.0, 30.0, 40.0])
    # each object loses at most its surface times the few steps its faces moved in
    assert 0 < 240 * part.volume() - out.volume < 240 * part.surface_area() * 3 * step
    for name in ("block.3mf", "block.stl"):
        mesh = trimesh.load(tmp_path / name, force="mesh")
        assert mesh.is_watertight and mesh.body_count == 240


def test_with_a_resolution_the_folds_are_said_as_its_own(holed_grid, tmp_path):
    # coarser faces fold where objects meet: the advice names the resolution, and setting
    # the objects apart (which also helps without one) is not tried
    with pytest.raises(MeshError, match="simplified to --resolution 0.05.*or none"):
        export_packing(holed_grid, tmp_path / "block.3mf",
                       ExportOptions(mode="union", resolution=0.05))
    assert not (tmp_path / "block.3mf").exists()
