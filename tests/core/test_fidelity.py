"""The automatic fidelity: each knob moves for its reason, and pack() records what it used."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from testdata import mesh_path

from jampacked.core.api import pack
from jampacked.core.fidelity import (
    CLEARANCE_POINTS,
    PRESETS,
    choose_fidelity,
    preset,
    thickness_ratio,
)
from jampacked.core.options import CavityPassOptions, FidelityOverrides, PackOptions


def _box(x: float, y: float, z: float, turn: bool = False) -> np.ndarray:
    v = trimesh.creation.box((x, y, z)).vertices
    if turn:  # the principal axes, not the coordinate axes, measure thickness
        rot = trimesh.transformations.rotation_matrix(0.7, [1.0, 2.0, 3.0])[:3, :3]
        v = v @ rot.T
    return v


def test_thickness_ratio_uses_principal_axes():
    assert thickness_ratio(_box(10, 1, 1)) == pytest.approx(10.0)
    assert thickness_ratio(_box(10, 2, 1, turn=True)) == pytest.approx(10.0, rel=1e-6)
    assert thickness_ratio(_box(3, 3, 3)) == pytest.approx(1.0)


def test_plain_scene_gets_medium_knobs():
    f = choose_fidelity([_box(20, 18, 16)], 200, 0.0, 6.0)
    med = PRESETS["medium"]
    assert f.name == "auto" and f.reasons == ()
    assert (f.spheres, f.grid_cells, f.surface_points, f.container_cells) == (
        med.spheres, med.grid_cells, med.surface_points, med.container_cells)


def test_many_objects_use_fewer_spheres():
    f = choose_fidelity([_box(20, 18, 16)], 4000, 0.0, 6.0)
    assert f.spheres < PRESETS["medium"].spheres
    assert "objects" in f.reasons[0]


def test_elongated_type_gets_a_finer_grid():
    f = choose_fidelity([_box(20, 18, 16), _box(60, 4, 4)], 200, 0.0, 6.0)
    assert f.grid_cells > PRESETS["medium"].grid_cells
    assert f.grid_cells <= PRESETS["high"].grid_cells


def test_small_clearance_gets_a_finer_grid_but_large_does_not():
    assert choose_fidelity([_box(20, 18, 16)], 200, 0.4, 6.0).grid_cells == 50
    assert choose_fidelity([_box(20, 18, 16)], 200, 2.0, 6.0).grid_cells == 40


def test_any_clearance_gets_denser_surface_points():
    assert choose_fidelity([_box(20, 18, 16)], 200, 0.0, 6.0).surface_points == 384
    for c in (0.4, 2.0):
        f = choose_fidelity([_box(20, 18, 16)], 200, c, 6.0)
        assert f.surface_points == CLEARANCE_POINTS > PRESETS["medium"].surface_points
        assert any("surface points" in r for r in f.reasons)


def test_tight_container_gets_a_finer_container_grid():
    med, high = PRESETS["medium"], PRESETS["high"]
    for f in (choose_fidelity([_box(20, 18, 16)], 200, 0.0, 1.5),  # smallest barely fits
              choose_fidelity([_box(20, 18, 16)], 200, 0.0, 6.0, 0.8)):  # largest cannot turn
        assert (f.spheres, f.grid_cells, f.container_cells) == (
            med.spheres, med.grid_cells, high.container_cells)
        assert "tight" in f.reasons[0]
    roomy = choose_fidelity([_box(20, 18, 16)], 200, 0.0, 6.0, 1.5)
    assert roomy.container_cells == PRESETS["medium"].container_cells


def test_pack_records_the_fidelity_and_applies_overrides():
    poly = [str(mesh_path(f"polyhedra/convex5/polytope{i}.obj")) for i in (1, 3)]
    p = pack("box:34x30x32", poly, seed=1, time_budget=2.0,
             options=PackOptions(fidelity=FidelityOverrides(spheres=12, container_cells=3.5),
                                 cavity=CavityPassOptions(factors=())))
    d = p.report.fidelity_detail
    assert d.name == "auto" and d.spheres == 12 and d.container_cells == 3.5
    assert max(p.report.spheres_per_type) <= 12
    assert any("overridden" in r for r in d.reasons)
    assert p.certificate["certified"]


def test_the_high_preset_takes_the_clearance_points_as_auto_does(tmp_path):
    # --fidelity high with a clearance kept its 384 points while auto took 1024
    assert preset("high", 0.5).surface_points == CLEARANCE_POINTS
    assert preset("high", 0.0) == PRESETS["high"]
    assert preset("low", 0.5) == PRESETS["low"]  # low stays the fast one
    p = pack("box:24x24x24", [str(mesh_path("polyhedra/convex5/polytope3.obj"))], seed=1,
             clearance=0.5, fidelity="high", time_budget=2.0)
    assert p.report.fidelity_detail.surface_points == CLEARANCE_POINTS
    assert p.certificate["certified"]


def test_the_low_preset_keeps_what_it_places():
    # with 96 surface points per type low let overlaps through that certification removed:
    # 11 of the 28 fruit placed in this box (low now keeps medium's points)
    fruit = [str(mesh_path(f"fruit/ycb_lowpoly/{n}.obj")) for n in ("017_orange", "014_lemon")]
    p = pack("box:20x20x20", fruit, seed=1, type_scale=100.0, fidelity="low")
    placed = len(p.type_index) + p.report.repair.removed
    assert p.report.fidelity_detail.spheres < PRESETS["medium"].spheres
    assert p.report.repair.removed <= 0.1 * placed, p.report.repair
    assert p.certificate["certified"]
