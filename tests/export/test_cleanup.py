"""The zero-area face repair (`export/cleanup.py`) against its numpy reference: the same
collapses and flips in the same order, so the same faces, on meshes with many caps and
needles. The reference searches and copies the whole face array per repair (what the module
did before it edited faces locally)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.export.cleanup import (
    _edges,
    _needle_edge,
    _stored,
    collapse_needles,
    degenerate_faces,
    remove_degenerate_faces,
)
from jampacked.export.validate import validate_arrays


def _faces_with_edge(f, a, b):
    nxt = np.roll(f, -1, axis=1)
    return np.flatnonzero(np.any((f == a) & (nxt == b), axis=1))


def _neighbours(f, a):
    return set(np.unique(f[np.any(f == a, axis=1)])) - {a}


def _collapse(f, p, q):
    faces = np.flatnonzero(np.any(f == p, axis=1) & np.any(f == q, axis=1))
    if len(faces) != 2:
        return None
    opposite = {int(x) for x in f[faces].ravel()} - {p, q}
    if _neighbours(f, p) & _neighbours(f, q) != opposite:
        return None
    out = np.delete(f, faces, axis=0)
    out[out == q] = p
    return out


def _flip(f, face, a, b, c):
    across = _faces_with_edge(f, b, a)
    if len(across) != 1:
        return None
    g = f[across[0]]
    d = int(g[(list(g).index(a) + 1) % 3])
    if d in (a, b, c) or d in _neighbours(f, c):
        return None
    out = f.copy()
    out[face] = (c, a, d)
    out[across[0]] = (d, b, c)
    return out


def remove_reference(v, f, max_steps=1000, float32=True):
    f = np.array(f, dtype=np.int64, copy=True)
    p32 = _stored(v, float32)
    tried = set()
    for _ in range(max_steps):
        bad = [int(i) for i in degenerate_faces(v, f, float32) if tuple(f[i]) not in tried]
        if not bad:
            break
        i = bad[0]
        tri = [int(x) for x in f[i]]
        tried.add(tuple(tri))
        edges, lengths = _edges(p32, tri)
        new = None
        short = _needle_edge(p32, tri)
        if short is not None:
            new = _collapse(f, *short)
        if new is None:
            k = int(np.argmax(lengths))
            a, b = edges[k]
            new = _flip(f, i, a, b, tri[(k + 2) % 3])
        if new is not None:
            f = new
    return v, f, len(degenerate_faces(v, f, float32))


def collapse_reference(v, f, faces, rel=1e-3, max_length=np.inf, float32=True):
    f = np.array(f, dtype=np.int64, copy=True)
    p32 = _stored(v, float32)
    edges = [_needle_edge(p32, [int(x) for x in f[i]], rel, max_length)
             for i in np.unique(np.asarray(faces, np.int64))]
    done = 0
    for edge in edges:
        if edge is None:
            continue
        new = _collapse(f, *edge)
        if new is not None:
            f, done = new, done + 1
    return f, done


def _damaged_sphere(seed: int, caps: int):
    """An icosphere with `caps` faces split by a vertex on one edge, leaving a zero-area
    face along it: a cap (the vertex mid-edge, flipped away) or a needle (the vertex next
    to a corner, collapsed)."""
    rng = np.random.default_rng(seed)
    m = trimesh.creation.icosphere(subdivisions=3, radius=10.0)
    v, faces = m.vertices.copy(), [list(t) for t in m.faces]
    for k in rng.choice(len(faces), size=caps, replace=False):
        a, b, c = faces[k]
        t = rng.choice([0.5, 1e-7, 1.0 - 1e-7])
        mid = len(v)
        v = np.vstack([v, v[a] + t * (v[b] - v[a])])
        faces[k] = [a, mid, c]
        faces.append([mid, b, c])
        faces.append([a, b, mid])  # zero area: keeps edge a->b for the face across it
    return v, np.array(faces, np.int64)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("float32", [True, False])
def test_the_repair_matches_its_reference(seed, float32):
    v, f = _damaged_sphere(seed, caps=40)
    assert len(degenerate_faces(v, f, float32)) >= 40
    want = remove_reference(v, f, float32=float32)
    got = remove_degenerate_faces(v, f, float32=float32)
    np.testing.assert_array_equal(got[1], want[1])
    assert got[2] == want[2] == 0
    assert validate_arrays(*got[:2]).passed


@pytest.mark.parametrize("max_steps", [1, 7, 25])
def test_the_step_limit_matches_its_reference(max_steps):
    v, f = _damaged_sphere(3, caps=30)
    want = remove_reference(v, f, max_steps=max_steps)
    got = remove_degenerate_faces(v, f, max_steps=max_steps)
    np.testing.assert_array_equal(got[1], want[1])
    assert got[2] == want[2] > 0


def test_collapsing_needles_matches_its_reference():
    # every face's shortest edge counts as a needle's: collapses run until the 2-manifold
    # refuses them, in the reference's order
    v, f = _damaged_sphere(4, caps=20)
    faces = np.flatnonzero(np.random.default_rng(4).random(len(f)) < 0.2)
    want = collapse_reference(v, f, faces, rel=1.0)
    got = collapse_needles(v, f, faces, rel=1.0)
    np.testing.assert_array_equal(got[0], want[0])
    assert got[1] == want[1] > 10


def test_a_cap_no_flip_repairs_has_its_short_edge_collapsed_within_the_limit(monkeypatch):
    """A union's window cut at --resolution 0.05 left a strip of caps (edges 0.7, 3.9 and
    4.6 micrometres) whose flips only made more caps: "1 degenerate face", and the export
    was refused as a defect. Where faces are left, a cap's shortest edge is collapsed if it
    is at most max_collapse long (here every flip is refused, as along that strip)."""
    from jampacked.export import cleanup

    v = np.array([[0.0, 0.0, 0.0], [0.15e-3, 0.0, 0.0], [1e-3, 0.0, 0.0],
                  [0.5e-3, -1e-3, 0.0], [0.5e-3, 1e-3, 0.0]])
    a, p, b, x, y = range(5)
    f = np.array([[a, p, b], [p, a, x], [b, p, x], [a, b, y]])
    monkeypatch.setattr(cleanup._Faces, "flip", lambda *args: None)
    _, same, left = cleanup.remove_degenerate_faces(v, f, float32=False)
    assert left == 1 and np.array_equal(same, f)
    _, kept, left = cleanup.remove_degenerate_faces(v, f, float32=False, max_collapse=0.1e-3)
    assert left == 1 and np.array_equal(kept, f)  # 0.15e-3 is over the limit
    _, out, left = cleanup.remove_degenerate_faces(v, f, float32=False, max_collapse=0.2e-3)
    assert left == 0 and out.tolist() == [[b, a, x], [a, b, y]]
