"""Exports too large for the machine are refused up front, with the count it can do."""

from __future__ import annotations

import re

import numpy as np
import pytest
from testdata import mesh_path

import jampacked.export.cost as cost_module
from jampacked.core.errors import InputError
from jampacked.core.meshes import load_mesh
from jampacked.core.packing import Packing, TypeRecord
from jampacked.core.report import PackInputs
from jampacked.export import assemble
from jampacked.export.assemble import export_packing
from jampacked.export.cost import (
    BASE_BYTES,
    BYTES_PER_TRIANGLE,
    check_export_cost,
    estimate_export,
)
from jampacked.export.options import ExportOptions
from jampacked.export.scene import PlacedScene

LEMON = mesh_path("fruit/ycb_lowpoly/014_lemon.obj")
GiB = 2**30


def test_estimate_counts_each_objects_triangles(monkeypatch):
    monkeypatch.setattr(cost_module, "machine_memory", lambda: 8 * GiB)
    c = estimate_export("parts", [10, 100], np.array([0, 1, 1]))
    assert c.objects == 3 and c.triangles == 210
    assert c.memory == BASE_BYTES + BYTES_PER_TRIANGLE["parts"] * 210
    shell = estimate_export("union", [10, 100], np.array([0, 1, 1]), extra_triangles=40)
    assert shell.triangles == 250 and c.fits and c.machine == 8 * GiB


def test_connect_counts_a_strut_per_object(monkeypatch):
    # 17,924 balls of 80 triangles connected took 5.0 GiB at the peak against 3.3 GiB
    # estimated: the struts (44 triangles each) were not counted
    import manifold3d as m3

    from jampacked.export.connect import STRUT_SEGMENTS, strut

    monkeypatch.setattr(cost_module, "machine_memory", lambda: 64 * GiB)
    assert strut(np.zeros(3), np.array([0.0, 0.0, 5.0]), 1.0).num_tri() == \
        cost_module.STRUT_TRIANGLES == m3.Manifold.cylinder(5, 1, 1, STRUT_SEGMENTS).num_tri()
    c = estimate_export("connect", [80], np.zeros(17_924, int))
    assert c.triangles == 17_924 * (80 + cost_module.STRUT_TRIANGLES)
    assert 4.8 * GiB < c.memory < 5.6 * GiB


@pytest.mark.parametrize("mode", ["parts", "union", "connect"])
def test_affordable_objects_is_the_count_that_fits(monkeypatch, mode):
    monkeypatch.setattr(cost_module, "machine_memory", lambda: 4 * GiB)
    tri = [16384, 1000]
    index = np.zeros(100_000, int)  # objects of the first type: each costs the same
    c = estimate_export(mode, tri, index)
    assert not c.fits
    n = c.affordable_objects
    assert 0 < n < 100_000
    assert estimate_export(mode, tri, index[:n]).fits
    assert not estimate_export(mode, tri, index[:n + 1]).fits


def _lemons(n: int) -> Packing:
    """n lowpoly lemons (x300, ~20 units long) on a grid 30 units apart, clearance 1."""
    m = load_mesh(LEMON)
    lff = np.diag([300.0, 300, 300, 1])
    lff[:3, 3] = -300.0 * m.centroid
    rec = TypeRecord(name="lemon", path=str(LEMON), sha256=m.sha256, share=1.0,
                     local_from_file=lff, volume=m.volume * 300**3)
    side = int(np.ceil(n ** (1 / 3)))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)
    t = (grid[:n] - (side - 1) / 2) * 30.0
    box = side * 30.0 + 30
    return Packing(container_path=f"box:{box}x{box}x{box}", container_sha256=None,
                   frame_from_file=np.eye(4), container_volume=box**3, types=[rec],
                   type_index=np.zeros(n, int), rotations=np.tile([1.0, 0, 0, 0], (n, 1)),
                   translations=t, scales=np.ones(n), inputs=PackInputs(clearance=1.0))


@pytest.mark.parametrize("mode", ["parts", "union"])
def test_100k_objects_are_refused_before_any_solid_is_placed(tmp_path, monkeypatch, mode):
    monkeypatch.setattr(cost_module, "machine_memory", lambda: 16 * GiB)

    def no_work(*args, **kwargs):
        raise AssertionError("objects were made solid or certified before the refusal")

    monkeypatch.setattr(PlacedScene, "place_solids", no_work)
    # the lemons carry no certificate: a certification of 100,000 objects took 11 s here
    # before the refusal (minutes for a real packing's)
    monkeypatch.setattr(assemble, "certify_edited", no_work)
    out = tmp_path / "big.3mf"
    with pytest.raises(InputError) as err:
        export_packing(_lemons(100_000), out, ExportOptions(mode=mode))
    msg = str(err.value)
    assert f"cannot export 100,000 objects in {mode} mode" in msg
    assert "--resolution" in msg and "GiB" in msg
    can = int(re.search(r"can export about ([\d,]+) objects", msg).group(1).replace(",", ""))
    tri = load_mesh(LEMON).faces.shape[0]
    expected = estimate_export(mode, [tri], np.zeros(100_000, int)).affordable_objects
    # the type's solid may differ by a few triangles from the file's
    assert abs(can - expected) <= 0.01 * expected and 0 < can < 100_000
    assert not out.exists()


def test_an_export_that_fits_is_not_refused(monkeypatch):
    monkeypatch.setattr(cost_module, "machine_memory", lambda: 16 * GiB)
    check_export_cost(estimate_export("parts", [16384], np.zeros(104, int)))
