"""Tests for jampacked.core.separation: hulls proven apart, against a numpy/scipy reference
(the distance between two hulls as a small quadratic programme)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from jampacked.core.rotations import quat_to_matrix
from jampacked.core.separation import apart_pairs, hull_points, hull_table


def _hull_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Distance between the convex hulls of point sets a (n, 3) and b (m, 3): the least
    |a^T x - b^T y| over convex weights x, y."""
    n, k = len(a), len(b)

    def f(z):
        d = a.T @ z[:n] - b.T @ z[n:]
        return d @ d, np.concatenate([2 * a @ d, -2 * b @ d])

    z0 = np.concatenate([np.full(n, 1 / n), np.full(k, 1 / k)])
    res = minimize(f, z0, jac=True, method="SLSQP", bounds=[(0, 1)] * (n + k),
                   constraints=[{"type": "eq", "fun": lambda z: z[:n].sum() - 1},
                                {"type": "eq", "fun": lambda z: z[n:].sum() - 1}],
                   options={"ftol": 1e-14, "maxiter": 500})
    return float(np.sqrt(max(res.fun, 0.0)))


def _placed(pts, off, t, m):
    return pts[off[t]:off[t + 1]] @ m[:3, :3].T + m[:3, 3]


def _scene(rng, n_pairs):
    """Random convex shapes (an elongated, a flat and a round one) placed in pairs at
    distances from overlapping to well apart."""
    shapes = [rng.normal(size=(30, 3)) * [3.0, 1.0, 1.0],
              rng.normal(size=(25, 3)) * [2.0, 2.0, 0.3],
              rng.normal(size=(40, 3))]
    shapes[2] /= np.linalg.norm(shapes[2], axis=1, keepdims=True)
    pts, off = hull_table([hull_points(s) for s in shapes])
    typ = rng.integers(0, 3, 2 * n_pairs)
    q = rng.normal(size=(2 * n_pairs, 4))
    m = np.tile(np.eye(4), (2 * n_pairs, 1, 1))
    m[:, :3, :3] = quat_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True))
    direction = rng.normal(size=(n_pairs, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    m[1::2, :3, 3] = direction * rng.uniform(0.5, 9.0, (n_pairs, 1))
    return pts, off, typ, m, np.arange(2 * n_pairs).reshape(-1, 2)


def test_apart_pairs_match_the_hull_distance():
    rng = np.random.default_rng(4)
    pts, off, typ, m, pairs = _scene(rng, 80)
    ref = np.array([_hull_distance(_placed(pts, off, typ[a], m[a]),
                                   _placed(pts, off, typ[b], m[b])) for a, b in pairs])
    for margin in (1e-9, 0.4):
        got = apart_pairs(pts, off, typ, m, pairs, margin)
        # proven pairs are apart by the margin; pairs clearly beyond it are found
        assert np.all(ref[got] > margin - 1e-6)
        assert np.all(got[ref > margin + 1e-4])
        assert not np.any(got[ref < margin - 1e-6])
        assert 10 < got.sum() < len(pairs) - 10  # both kinds occur


def test_apart_pairs_of_touching_coincident_and_flat_hulls():
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)  # no 3-d hull
    assert len(hull_points(flat)) == 4 and len(hull_points(cube)) == 8
    pts, off = hull_table([hull_points(cube), hull_points(flat)])
    m = np.tile(np.eye(4), (6, 1, 1))
    m[1, 0, 3] = 1.0  # a cube face to face with the first
    m[3, 0, 3] = 1.0 + 1e-3  # apart by 1e-3
    m[5, :3, 3] = [0.5, 0.5, 1.0 + 1e-3]  # the square 1e-3 above the cube at
    typ = np.array([0, 0, 0, 0, 0, 1])
    pairs = np.array([[0, 1], [0, 2], [2, 3], [4, 5]])  # touching, coincident, apart, apart
    assert apart_pairs(pts, off, typ, m, pairs, 1e-6).tolist() == [False, False, True, True]
    assert not apart_pairs(pts, off, typ, m, pairs, 2e-3).any()
    assert apart_pairs(pts, off, typ, m, pairs[:0], 1e-6).shape == (0,)
    # a type without points (an empty solid) proves nothing
    pts, off = hull_table([hull_points(cube), hull_points(np.zeros((0, 3)))])
    assert apart_pairs(pts, off, typ, m, pairs, 1e-6).tolist() == [False, False, True, False]
