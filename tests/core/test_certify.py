"""Tests for jampacked.core.certify: exact checks on meshes, with bounds and depths computed
a type at a time in chunks (checked against a per-object numpy reference)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core import certify
from jampacked.core.certify import Certifier
from jampacked.core.container import build_container
from jampacked.core.kernels import sample_grid_many
from jampacked.core.rotations import quat_to_matrix


@pytest.fixture(scope="module")
def certifier():
    box = trimesh.creation.box(extents=(30.0, 30.0, 30.0))
    cont = build_container(box.vertices, box.faces, float(box.volume), 1.0)
    a = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    b = trimesh.creation.icosphere(subdivisions=2, radius=1.5)
    meshes = [a, b]
    return Certifier(cont, [np.asarray(m.vertices) for m in meshes],
                     [np.asarray(m.faces) for m in meshes],
                     np.array([m.volume for m in meshes]),
                     np.array([m.edges_unique_length.max() for m in meshes]))


def _matrices(rng, pos):
    q = rng.normal(size=(len(pos), 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    m = np.tile(np.eye(4), (len(pos), 1, 1))
    m[:, :3, :3] = quat_to_matrix(q)
    m[:, :3, 3] = pos
    return m


@pytest.mark.parametrize("chunk", [1 << 20, 100])  # one chunk per type, or several
def test_bounds_and_depth_match_each_objects_vertices(certifier, monkeypatch, chunk):
    monkeypatch.setattr(certify, "CHUNK_VERTICES", chunk)
    rng = np.random.default_rng(7)
    n = 40
    typ = rng.integers(0, 2, n)
    m = _matrices(rng, rng.uniform(-16, 16, (n, 3)))
    lo, hi, depth = certifier._bounds_and_depth(typ, m)
    g = certifier.container.grid
    for i in range(n):
        world = certifier.vertices[typ[i]] @ m[i, :3, :3].T + m[i, :3, 3]
        np.testing.assert_allclose(lo[i], world.min(axis=0), rtol=0, atol=1e-12)
        np.testing.assert_allclose(hi[i], world.max(axis=0), rtol=0, atol=1e-12)
        ref = sample_grid_many(g.values, g.origin, g.spacing, world).min()
        assert depth[i] == pytest.approx(ref, abs=1e-9)


def test_certify_finds_overlaps_and_objects_through_the_wall(certifier):
    rng = np.random.default_rng(8)
    # a grid of separated objects, then one overlapping pair and one through the wall
    pos = np.array([[x, y, z] for x in (-8.0, 0.0, 8.0) for y in (-8.0, 0.0, 8.0)
                    for z in (-8.0, 8.0)])
    typ = np.arange(len(pos)) % 2
    m = _matrices(rng, pos)
    rep = certifier.certify(typ, m)
    assert rep.certified and rep.worst_overlap == 0.0 and rep.bad_wall == []
    m2 = m.copy()
    m2[1, :3, 3] = m[0, :3, 3] + [0.5, 0.0, 0.0]  # objects 0 and 1 overlap
    m2[5, :3, 3] = [14.5, 0.0, 0.0]  # object 5 pokes out of the box
    rep = certifier.certify(typ, m2)
    assert not rep.certified
    assert rep.bad_pairs == [(0, 1)] and rep.bad_wall == [5]
    assert rep.worst_overlap > 0.1 and rep.worst_outside > 0.1
    # with a subset, only checks involving it run
    rep = certifier.certify(typ, m2, subset=np.array([5]))
    assert rep.bad_pairs == [] and rep.bad_wall == [5]
