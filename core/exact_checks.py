"""The exact checks of a certification, on placed manifold3d solids: pairs and walls.

A check is a row (a, b) of object indices: a pair of objects, or with b < 0 object a against
the container's wall (the `outside` solid, `solids.outside_of`). Its result is (gap, ratio):
the minimum gap (only with a clearance c > 0, else NaN) and the intersection volume over
the smaller object's (with the wall: the volume outside over the object's), NaN where a gap
of at least c proves the two apart and no boolean ran. The certifier runs checks here or in
worker processes (`check_pool`), with the same results: manifold3d is deterministic.
Frames and units: container frame, container units.

This module imports only numpy and manifold3d (through `solids`), so that worker
processes start quickly.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .solids import outside_of, to_solid

#: triangles of placed solids one run of checks keeps for its next checks
KEPT_FACES = 500_000
#: min_gap's search distance over the clearance: gaps beyond it read as this much, and
#: manifold3d's cost grows steeply with it (docs/notes-core.md)
GAP_SEARCH = 1.25


#: the exact checks scale a scene whose smallest mesh spans less than this many units up by
#: a power of two until it spans this much: manifold3d's triangle distance (PhysX's) takes a
#: triangle whose edges' cross product is shorter than about 3e-8 units for degenerate and
#: misreads the gap beside it, as 0 or too large (docs/notes-core.md); a power of two
#: scales floats exactly
CHECK_SPAN = 1.0


def check_scale(meshes: Sequence[np.ndarray]) -> float:
    """The power of two the exact checks scale lengths by, for meshes given by their (V, 3)
    vertices (the container's and each type's): 1 where the smallest spans CHECK_SPAN units
    or more along its longest axis."""
    return span_scale(min(float(np.ptp(v, axis=0).max()) for v in meshes))


def span_scale(span: float) -> float:
    """`check_scale` for the smallest mesh's span (units)."""
    if not 0.0 < span < CHECK_SPAN:
        return 1.0
    return 2.0 ** math.ceil(math.log2(CHECK_SPAN / span))


@dataclass
class CheckSolids:
    """The solids every check reads, in the container frame scaled by ``scale``: the
    container's outside and each type's solid (local frame)."""

    outside: object
    types: list
    scale: float


def check_solids(container: tuple[np.ndarray, np.ndarray],
                 types: list[tuple[np.ndarray, np.ndarray]]) -> CheckSolids:
    """The solids every check reads: the container's outside (from its (V, 3) vertices and
    (F, 3) faces) and each type's solid (local frame), in float32 as certification uses
    them, scaled by `check_scale`. The certifier and its workers both build them here, so
    they check the same solids."""
    scale = check_scale([container[0], *(v for v, _ in types)])
    return CheckSolids(outside_of(container[0] * scale, container[1], double=False,
                                  margin=scale),
                       [to_solid(v * scale, f, double=False) for v, f in types], scale)


def shortfall(gap: float | None, clearance: float) -> float | None:
    """How far a measured gap falls short of the clearance (None: unmeasured or not short;
    a relative 1e-6 of slack for manifold3d's rounding)."""
    if gap is None or gap >= clearance * (1 - 1e-6):
        return None
    return clearance - gap


def least_gap(candidates: Callable[[float], tuple[np.ndarray, Sequence]],
              measure: Callable[[object, float], float], start: float,
              limit: float, bound: float | None = None) -> float | None:
    """The exact least gap over a set of checks, or None where none is below `limit`.

    candidates(s) gives the checks whose gap may be below s: (K,) lower bounds on their
    gaps and their K keys; measure(key, search) gives a check's gap where it is below
    `search`, else `search` (manifold3d's min_gap, whose cost grows with the search). The
    check with the lowest bound within `start` (or within a doubled search, where none is)
    is searched until it reads a gap, doubling up to `limit`; that gap bounds the least,
    and the checks that may lie below it then run from the lowest bound up, each
    searching only below the least gap found so far. bound: a gap already measured among
    them, which bounds the least from the start (the check with the lowest bound may lie
    far beyond it, and searching it out costs most). Lengths in container units."""
    if bound is not None and bound < limit:
        return _least_below(candidates, measure, bound, limit)
    search = start
    while True:
        lower, keys = candidates(search)
        if len(lower):
            break
        if search >= limit:
            return None
        search = min(2.0 * search, limit)
    first = int(np.argmin(lower))
    best = measure(keys[first], search)
    while best >= search and search < limit:
        search = min(2.0 * search, limit)
        best = measure(keys[first], search)
    return _least_below(candidates, measure, min(best, search), limit)


def _least_below(candidates: Callable[[float], tuple[np.ndarray, Sequence]],
                 measure: Callable[[object, float], float], best: float,
                 limit: float) -> float | None:
    """`least_gap` once a gap `best` bounds the least: the checks that may lie below it,
    from the lowest bound up, each searching below the least found so far."""
    lower, keys = candidates(best)
    for k in np.argsort(lower, kind="stable").tolist():
        if lower[k] >= best:
            break
        best = min(best, measure(keys[k], best))
    return float(best) if best < limit else None


class PlacedSolids:
    """Object i's solid in the container frame (scaled as the solids are), made when a check
    needs it and kept while the kept ones hold at most KEPT_FACES triangles (the latest one
    always), least recently used out first: making (transforming) a solid costs several
    times a gap query with it, and holding every object's would grow memory by a mesh per
    object."""

    def __init__(self, solids: CheckSolids, typ: np.ndarray, matrices: np.ndarray):
        self.types, self.typ, self.scale = solids.types, typ, solids.scale
        self.outside = solids.outside
        self.matrices = np.array(matrices[:, :3, :4], np.float64)
        self.matrices[:, :, 3] *= self.scale
        self.faces = [s.num_tri() for s in solids.types]
        self.kept: dict[int, object] = {}  # insertion order is use order
        self.kept_faces = 0

    def __call__(self, i: int):
        i = int(i)
        got = self.kept.pop(i, None)
        if got is None:
            got = self.types[self.typ[i]].transform(self.matrices[i].tolist())
            self.kept_faces += self.faces[self.typ[i]]
            while self.kept and self.kept_faces > KEPT_FACES:
                old = next(iter(self.kept))
                del self.kept[old]
                self.kept_faces -= self.faces[self.typ[old]]
        self.kept[i] = got
        return got

    def gap(self, i: int, j: int, search: float) -> float:
        """manifold3d's least gap between objects i and j (j < 0: i and the wall), where
        below `search`, else `search`; container units."""
        a = self(i)
        other = self.outside if j < 0 else self(j)
        return float(a.min_gap(other, search * self.scale)) / self.scale

    def overlap(self, i: int, j: int) -> float:
        """The volume objects i and j share (j < 0: of i outside the container)."""
        a = self(i)
        other = self.outside if j < 0 else self(j)
        return float((a ^ other).volume()) / self.scale ** 3


def run_checks(solid: PlacedSolids, volume: np.ndarray, checks: np.ndarray,
               clearance: float, tick: Callable[[], None] | None = None) -> np.ndarray:
    """Run checks (K, 2) (module doc) on the placed solids; volume (N,) each object's
    volume. Returns (K, 2): gap and ratio of each, NaN where not measured. tick() is called
    after each check."""
    out = np.full((len(checks), 2), np.nan)
    for k, (a, b) in enumerate(checks):
        least = volume[a] if b < 0 else min(volume[a], volume[b])
        if clearance > 0:
            gap = solid.gap(a, b, GAP_SEARCH * clearance)
            out[k, 0] = gap
            if shortfall(gap, clearance) is None:  # a gap of at least c > 0: apart
                if tick is not None:
                    tick()
                continue
        out[k, 1] = solid.overlap(a, b) / least
        if tick is not None:
            tick()
    return out
