"""bench/density_profile.py: the packed fraction against depth from the wall, on a packing
whose answer is known, and its flat-wall reference."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import trimesh
from testdata import bench_module

from jampacked.core.meshes import load_mesh
from jampacked.core.packing import Packing, TypeRecord
from jampacked.core.packing_json import save_packing


def _load():
    return bench_module("density_profile", siblings=True)


dp = _load()


def test_hex_layer_reference():
    r = 3.0
    z = np.linspace(0, r, 200001)
    f = dp.hex_layer_fraction(z, r)
    mean = float(np.sum((f[1:] + f[:-1]) * np.diff(z)) / 2 / r)  # trapezoids
    assert mean == pytest.approx(np.pi / (3 * np.sqrt(3)), rel=1e-6)
    # at the spheres' equator the layer covers the hexagonal disc packing's fraction
    assert dp.hex_layer_fraction(r, r) == pytest.approx(np.pi / (2 * np.sqrt(3)))
    assert dp.hex_layer_fraction(0.0, r) == 0.0


def _cubes_packing(tmp_path):
    """Eight 10-unit cubes filling the central 20-unit cube of a 40-unit box, saved."""
    cube = tmp_path / "cube.obj"
    trimesh.creation.box(extents=(10.0, 10.0, 10.0)).export(cube)
    m = load_mesh(cube)
    rec = TypeRecord(name="cube", path=str(cube), sha256=m.sha256, share=1.0,
                     local_from_file=np.eye(4), volume=m.volume)
    pos = np.array(list(itertools.product([-5.0, 5.0], repeat=3)))
    p = Packing(container_path="box:40x40x40", container_sha256=None,
                frame_from_file=np.eye(4), container_volume=40.0 ** 3, types=[rec],
                type_index=np.zeros(8, np.int64), rotations=np.tile([1.0, 0, 0, 0], (8, 1)),
                translations=pos, scales=np.ones(8),
                metrics={"density": 8000 / 64000})
    path = tmp_path / "cubes.json"
    save_packing(p, path)
    return path


def test_profile_of_a_known_packing(tmp_path):
    """The cubes are there exactly where the depth from the wall is >= 10, 1/8 of the
    volume."""
    data = dp.profile(_cubes_packing(tmp_path), target=0.2, samples=100_000)
    r = (3 * 1000 / (4 * np.pi)) ** (1 / 3)
    assert data["mean_equivalent_radius"] == pytest.approx(r)
    assert data["estimate"] == pytest.approx(0.125, abs=0.005)
    for band in data["bands"]:
        lo = band["from_r"] * r
        hi = np.inf if band["to_r"] is None else band["to_r"] * r
        if lo >= 20.0:  # deeper than the box's centre: no such points
            assert band["volume_share"] == 0.0 and band["density"] is None
        elif hi <= 10.0 - 0.3:
            assert band["density"] < 0.01, band  # no cube this near the wall
        elif lo >= 10.0 + 0.3:
            assert band["density"] > 0.99, band  # all cube this deep
    # the band within one radius of the wall is empty: the target needs it at
    # (0.2 - what the rest holds) / its share
    fb = data["first_band"]
    assert fb["density"] == 0.0
    rest = 1.0 - fb["volume_share"]
    assert data["first_band_density_for_target"] == pytest.approx(
        (0.2 - data["beyond_first_band_density"] * rest) / fb["volume_share"], rel=1e-6)


def test_a_packing_of_ones_own_keeps_the_benchs_record(tmp_path, monkeypatch):
    """--out takes the profile and its chart; the bench's own files are not written."""
    results = tmp_path / "results"
    results.mkdir()
    monkeypatch.setattr(dp, "RESULTS", results)
    mine = tmp_path / "mine" / "profile.json"
    mine.parent.mkdir()
    assert dp.main(["--packing", str(_cubes_packing(tmp_path)), "--out", str(mine)]) == 0
    assert mine.is_file() and mine.with_suffix(".png").is_file()
    assert list(results.iterdir()) == []
    # without --out, beside the packing; never over it, nor a .png for the JSON
    packing = _cubes_packing(tmp_path)
    assert dp.main(["--packing", str(packing)]) == 0
    assert (tmp_path / "cubes-profile.json").is_file()
    assert (tmp_path / "cubes-profile.png").is_file() and list(results.iterdir()) == []
    for bad in (packing, tmp_path / "p.png"):
        with pytest.raises(SystemExit):
            dp.main(["--packing", str(packing), "--out", str(bad)])
