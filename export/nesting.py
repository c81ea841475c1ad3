"""Which closed bodies of a mesh lie inside which: winding numbers of a point of each body
with respect to the closed bodies whose boxes contain it (ray crossings where the outer
body is consistently wound, else generalised winding numbers from solid angles).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .intersect import ray_winding_numbers, winding_numbers

__all__ = ["NESTING_BUDGET", "largest_faces", "nesting"]

#: skip the nesting test when it would sum more solid angles than this
NESTING_BUDGET = 300_000_000


@njit(cache=True)
def largest_faces(face_body: np.ndarray, areas: np.ndarray, n_bodies: int) -> np.ndarray:
    """The largest face of each body (the first of equal ones; NaN counts as smallest;
    -1 for a body without faces)."""
    best = np.full(n_bodies, -1, np.int64)
    for f in range(face_body.shape[0]):
        b = face_body[f]
        k = best[b]
        if k < 0:
            best[b] = f
            continue
        a, m = areas[f], areas[k]
        if a > m or (m != m and a == a):
            best[b] = f
    return best


def nesting(
    vertices: np.ndarray,
    faces: np.ndarray,
    face_body: np.ndarray,
    closed: np.ndarray,
    oriented: np.ndarray,
    areas: np.ndarray,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
) -> tuple[list[list[int]], np.ndarray, bool]:
    """For each closed body: the closed bodies containing it, and the winding number just
    outside it (sum over the others). Returns (inside lists, winding_outside, checked).

    ``oriented``: bodies whose every edge is used once each way (their winding numbers come
    from ray crossings); ``areas``: (F,) face areas (any scale), 0 for improper faces."""
    n = len(closed)
    inside: list[list[int]] = [[] for _ in range(n)]
    outside = np.zeros(n, np.int64)
    idx = np.flatnonzero(closed)
    if len(idx) < 2:
        return inside, outside, True
    lo, hi = box_lo[idx], box_hi[idx]
    contains = np.all(lo[:, None, :] <= lo[None, :, :], axis=2) & np.all(
        hi[None, :, :] <= hi[:, None, :], axis=2
    )  # contains[j, k]: box of idx[j] holds box of idx[k]
    np.fill_diagonal(contains, False)
    jj, kk = np.nonzero(contains)
    if len(jj) == 0:
        return inside, outside, True
    n_faces_body = np.bincount(face_body, minlength=n)
    if int(n_faces_body[idx[jj]].sum()) > NESTING_BUDGET:
        return inside, outside, False
    # a query point on each inner body: the centroid of its largest proper face
    first = largest_faces(face_body, areas, n)
    points = vertices[faces[first]].mean(axis=1)
    by_body = np.argsort(face_body, kind="stable")  # each body's faces, in order
    starts = np.searchsorted(face_body[by_body], np.arange(n + 1))
    for j in np.unique(jj):
        outer = idx[j]
        inner = idx[kk[jj == j]]
        outer_faces = faces[by_body[starts[outer]:starts[outer + 1]]]
        if oriented[outer]:
            # ray crossings give the same integer as the generalised winding number on a
            # closed, consistently wound surface, at a fraction of the cost; ambiguous rays
            # (grazing an edge, or a point on the surface) fall back to the solid angles
            w, ok = ray_winding_numbers(points[inner], vertices, outer_faces)
            if not np.all(ok):
                w[~ok] = np.rint(winding_numbers(points[inner[~ok]], vertices, outer_faces))
        else:
            w = np.rint(winding_numbers(points[inner], vertices, outer_faces)).astype(np.int64)
        for k, wk in zip(inner, w, strict=True):
            if wk != 0:
                inside[int(k)].append(int(outer))
                outside[int(k)] += wk
    return inside, outside, True
