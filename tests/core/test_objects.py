"""Object type approximations: local frame, surface samples, on-disk cache."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core.objects import build_type, surface_samples


@pytest.fixture()
def box():
    m = trimesh.creation.box((4.0, 2.0, 1.0))
    m.apply_translation([10.0, -3.0, 2.0])
    return m


def test_local_frame_centres_volume_centroid_and_scales(box):
    t = build_type("b", box.vertices, box.faces, path=None, sha256=None, share=1.0,
                   type_scale=2.0, fidelity="low", use_cache=False)
    assert t.volume == pytest.approx(8.0 * 8.0)
    assert np.allclose(t.vertices.mean(axis=0), 0.0, atol=1e-12)
    v_file = np.c_[box.vertices, np.ones(len(box.vertices))]
    assert np.allclose((t.local_from_file @ v_file.T).T[:, :3], t.vertices)
    assert t.radius == pytest.approx(np.linalg.norm([4, 2, 1]))


def test_surface_samples_keep_corners_and_spread(box):
    pts = surface_samples(np.asarray(box.vertices), np.asarray(box.faces), 40)
    assert len(pts) == 40
    # every corner of the box is kept (farthest point sampling starts from the corners)
    for v in box.vertices:
        assert np.min(np.linalg.norm(pts - v, axis=1)) < 1e-12


def test_cache_round_trip_and_corrupt_file(box, tmp_path, monkeypatch):
    monkeypatch.setenv("JAMPACKED_CACHE", str(tmp_path))
    a = build_type("b", box.vertices, box.faces, path=None, sha256=None, share=1.0,
                   fidelity="low")
    files = list(tmp_path.glob("type-*.npz"))
    assert len(files) == 1
    b = build_type("b", box.vertices, box.faces, path=None, sha256=None, share=1.0,
                   fidelity="low")
    assert np.array_equal(a.sphere_radii, b.sphere_radii)
    assert np.array_equal(a.grid.values, b.grid.values)
    # other parameters, other entry
    build_type("b", box.vertices, box.faces, path=None, sha256=None, share=1.0,
               fidelity="medium")
    assert len(list(tmp_path.glob("type-*.npz"))) == 2
    # a damaged cache file is rebuilt, not trusted
    files[0].write_bytes(b"not an npz")
    c = build_type("b", box.vertices, box.faces, path=None, sha256=None, share=1.0,
                   fidelity="low")
    assert np.array_equal(a.sphere_radii, c.sphere_radii)
