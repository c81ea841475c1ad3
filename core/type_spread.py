"""Where each type's objects already are, for spreading a type out (container frame and
units): the distance from candidate points to the nearest object of a type.

Phase 1 grows the objects of its lattice in a random order; picking, among the next few, the
one furthest from its type's grown objects spreads each type more evenly than the random
order alone (the clumping index per type; docs/notes-core.md).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: a type's k-d tree is rebuilt once this many points were added since: those are searched
#: directly, so a query costs at most this many distances beyond the tree's
REBUILD_AFTER = 128


class TypeSpread:
    """Points (container frame) per type, growing; `nearest` answers from a k-d tree of most
    of them plus a direct search of the latest."""

    def __init__(self, n_types: int):
        self.points: list[list[np.ndarray]] = [[] for _ in range(n_types)]
        self.trees: list[cKDTree | None] = [None] * n_types
        self.in_tree = [0] * n_types

    def add(self, t: int, point: np.ndarray) -> None:
        """Record an object of type t at `point` (3,)."""
        pts = self.points[t]
        pts.append(np.asarray(point, np.float64).copy())
        if len(pts) - self.in_tree[t] >= REBUILD_AFTER:
            self.trees[t] = cKDTree(np.array(pts))
            self.in_tree[t] = len(pts)

    def add_many(self, t: int, points: np.ndarray) -> None:
        """Record objects of type t at `points` (K, 3), the k-d tree rebuilt once."""
        pts = self.points[t]
        pts.extend(np.asarray(points, np.float64).reshape(-1, 3).copy())
        if len(pts) - self.in_tree[t] >= REBUILD_AFTER:
            self.trees[t] = cKDTree(np.array(pts))
            self.in_tree[t] = len(pts)

    def nearest(self, t: int, query: np.ndarray) -> np.ndarray:
        """Distance from each of `query` (Q,3) to the nearest recorded object of type t
        (inf where the type has none)."""
        query = np.asarray(query, np.float64).reshape(-1, 3)
        best = np.full(len(query), np.inf)
        if self.trees[t] is not None:
            best = self.trees[t].query(query)[0]
        recent = self.points[t][self.in_tree[t]:]
        if recent:
            d = np.linalg.norm(query[:, None, :] - np.array(recent)[None], axis=2).min(axis=1)
            best = np.minimum(best, d)
        return best


def type_needed(counts: np.ndarray, shares: np.ndarray, by_volume: np.ndarray, *,
                within: bool = False) -> int:
    """The type the mix needs next: of the types in `by_volume` (largest first) the first
    below its share of the (T,) counts so far, or, when none is, the one furthest below
    it; a type with a zero share (T,) never. within: that one too from `by_volume` (the
    types that fit), not from every type with a share."""
    g = max(float(counts.sum()), 1.0)
    for t in by_volume:
        if counts[t] < shares[t] * g:
            return int(t)
    if within:
        return int(min(by_volume, key=lambda t: (counts[t] / shares[t], t)))
    return int(np.argmin(np.where(shares > 0, counts / np.maximum(shares, 1e-12), np.inf)))
