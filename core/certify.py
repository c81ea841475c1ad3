"""Exact checks of a packing on the real meshes (manifold3d).

A packing is certified when every pair's intersection volume and every object's volume
outside the container are at most `tol` (1e-4) of the object's volume, and, with a clearance
c > 0, every pair's and every object-wall minimum gap is at least c. The report gives the
worst values, not only a flag. Frames: container frame, container units.

Which checks run: every pair whose axis-aligned bounds (grown by c) touch gets an exact
boolean intersection, or with c > 0 a min_gap first and the boolean only where the gap falls
short (a gap of c > 0 proves the two apart), unless a plane proves the pair's convex hulls
apart (`separation`): by more than min_gap's search distance with c > 0, when min_gap would
read that distance, else by any margin, when the boolean would measure 0; the memo then
holds the values those checks would have given. Every object gets the exact volume outside
the container, except objects the container's distance grid proves deep inside: all its
vertices at depth >= c + its longest edge + the grid's interpolation error (every surface
point of a triangle lies within an edge length of a vertex, so the surface then cannot reach
the wall). That error is at most sqrt(3)/2 of a cell wherever the nodes hold true
distances (the distance is 1-Lipschitz and a cell's trilinear weights keep their nodes
that near on average), also beside a wall feature thinner than a cell, which a flat wall's
half cell misses; nodes beyond the grid's exact band hold distances too deep, so the test
reads them as the band's depth, which every such node lies beyond.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from .check_pool import CheckPool, usable_processes
from .container import GRID_BAND, Container
from .exact_checks import (
    GAP_SEARCH,
    PlacedSolids,
    check_solids,
    least_gap,
    run_checks,
    shortfall,
)
from .kernels import sample_grid_many
from .separation import apart_pairs, hull_points, hull_table

log = logging.getLogger(__name__)

DEFAULT_TOL = 1e-4
#: vertices placed at once when bounding and depth-testing objects
CHUNK_VERTICES = 1 << 20
#: seconds between a certification's progress calls
PROGRESS_SECONDS = 0.5
#: checks run here between looks at whether worker processes would pay
PROBE_CHECKS = 16
#: checks run here for at least this long (s) before the rate is taken as known ...
POOL_PROBE_SECONDS = 0.5
#: ... and worker processes start only where the rest would take this long (s) here:
#: starting two took 0.2 s on a warm machine, more where imports are cold
#: (docs/notes-core.md)
POOL_MIN_SECONDS = 3.0
#: hulls proven apart by less than this, relative to the coordinates' size, still get
#: their exact check: many times the rounding of the supports' and manifold3d's doubles
APART_MARGIN = 1e-9
#: objects whose boxes' half-diagonals lie within this factor share a size class, and a
#: reach, when near pairs are looked up
SIZE_CLASS = 2.0
#: the container grid's interpolation error (cells) where its nodes hold true distances
WALL_READ_ERROR = 0.5 * 3 ** 0.5


@dataclass
class CertifyReport:
    """Worst values found and the offending objects (indices into the placements given)."""

    certified: bool
    tol: float
    clearance: float
    worst_overlap: float  # max pair intersection volume / smaller object volume
    worst_overlap_pair: tuple[int, int] | None
    worst_outside: float  # max object volume outside the container / object volume
    worst_outside_object: int | None
    # only with clearance > 0: the least gaps the checks read, which read a gap beyond
    # GAP_SEARCH x c as that much (None when no pair was near); `least_gaps` measures them
    min_pair_gap: float | None
    min_wall_gap: float | None
    bad_pairs: list[tuple[int, int]] = field(default_factory=list)
    bad_wall: list[int] = field(default_factory=list)
    # with clearance > 0: how much each failing gap falls short of the clearance, by pair
    # (as in bad_pairs) and by object through the wall (0 where the objects overlap)
    pair_shortfall: dict[tuple[int, int], float] = field(default_factory=dict)
    wall_shortfall: dict[int, float] = field(default_factory=dict)
    pairs_checked: int = 0
    walls_checked: int = 0

    def bad_objects(self) -> set[int]:
        return {i for p in self.bad_pairs for i in p} | set(self.bad_wall)

    def as_dict(self) -> dict:
        return {
            "certified": self.certified, "tol": self.tol, "clearance": self.clearance,
            "worst_overlap": self.worst_overlap,
            "worst_overlap_pair": list(self.worst_overlap_pair)
            if self.worst_overlap_pair else None,
            "worst_outside": self.worst_outside,
            "worst_outside_object": self.worst_outside_object,
            "min_pair_gap": self.min_pair_gap, "min_wall_gap": self.min_wall_gap,
            "bad_pairs": len(self.bad_pairs), "bad_wall": len(self.bad_wall),
            "pairs_checked": self.pairs_checked, "walls_checked": self.walls_checked,
        }


class Certifier:
    """Holds the manifolds of the container's outside and of each type (local frame), and
    the worker processes of long certifications once started: close it to end them."""

    def __init__(self, container: Container, type_vertices: list[np.ndarray],
                 type_faces: list[np.ndarray], type_volumes: np.ndarray,
                 type_max_edge: np.ndarray, *, processes: int = 1):
        """processes: worker processes a long certification may use (`check_pool`);
        0: one per core (`check_pool.usable_processes`); 1: none."""
        self.container = container
        # intersections with `outside` are volume outside, and min_gap to it is the wall gap
        self.solids = check_solids((container.vertices, container.faces),
                                   list(zip(type_vertices, type_faces, strict=True)))
        scale = self.solids.scale
        # an object wholly beyond this box misses `outside` too: it is outside entirely
        self.outside_box = np.asarray(self.solids.outside.bounding_box(),
                                      np.float64).reshape(2, 3) / scale
        self.vertices = type_vertices
        self.faces = type_faces
        self.processes = usable_processes(processes)
        self._pool: CheckPool | None = None
        self._pool_broken = False
        self.volumes = np.asarray(type_volumes, np.float64)
        self.max_edge = np.asarray(type_max_edge, np.float64)
        # the grid as the wall test reads it: nodes beyond the exact band at its depth
        g = container.grid
        self._wall_values = np.minimum(g.values, GRID_BAND * g.spacing)
        # hulls of the solids' own (float32) vertices: the points the exact checks read
        self.hulls = hull_table([
            hull_points(np.asarray(s.to_mesh().vert_properties, np.float64)[:, :3] / scale)
            for s in self.solids.types])
        self.coordinate_size = float(np.abs(container.vertices).max()
                                     + np.linalg.norm(self.hulls[0], axis=1).max(initial=0.0))

    def certify(self, typ: np.ndarray, matrices: np.ndarray, clearance: float = 0.0,
                tol: float = DEFAULT_TOL, subset: np.ndarray | None = None, *,
                memo: CheckMemo | None = None, ids: np.ndarray | None = None,
                progress: Callable[[int, int], None] | None = None) -> CertifyReport:
        """Check objects (typ (N,), matrices (N,4,4) local -> container frame, scale 1).

        subset: only pairs and walls involving these indices are checked (others trusted).
        memo: results of earlier certifications of the same objects, read and extended:
        a check whose objects (ids (N,), stable between calls; default 0..N-1) have the
        same type and placement as when it ran is not run again. The report is the same
        as without it. progress(done, total) is called now and then with the exact checks
        run so far and the number this call runs.
        """
        typ = np.asarray(typ, np.int64)
        n = len(typ)
        vol = self.volumes[typ]
        check = np.ones(n, bool) if subset is None else np.isin(np.arange(n), subset)
        ids = np.arange(n) if ids is None else np.asarray(ids, np.int64)
        if memo is None:
            memo = CheckMemo()
        known = memo.update(ids, typ, matrices, clearance, tol)
        if not known.all():
            memo.set_bounds(ids[~known], *self._bounds_and_depth(typ[~known],
                                                                matrices[~known]))
        lo, hi, depth = memo.lo[ids], memo.hi[ids], memo.depth[ids]
        pairs = self._touching_pairs(lo, hi, check, clearance)
        g = self.container.grid
        walls = np.flatnonzero(check & (depth < clearance + self.max_edge[typ]
                                        + WALL_READ_ERROR * g.spacing))
        # an object wholly beyond the outside solid's box misses it: outside entirely
        beyond = (np.any(hi[walls] < self.outside_box[0], axis=1)
                  | np.any(lo[walls] > self.outside_box[1], axis=1))
        pair_keys = [(int(min(a, b)), int(max(a, b))) for a, b in ids[pairs]]
        for i in walls[beyond]:
            if int(ids[i]) not in memo.walls:
                memo.add_wall(int(ids[i]), None, None, True)
        run_pairs = [k for k, key in enumerate(pair_keys) if key not in memo.pairs]
        run_pairs = self._spare_apart(typ, matrices, pairs, pair_keys, run_pairs, clearance,
                                      memo)
        run_walls = [i for i in walls[~beyond] if int(ids[i]) not in memo.walls]
        checks = np.concatenate([pairs[run_pairs].reshape(-1, 2),
                                 np.stack([np.asarray(run_walls, np.int64),
                                           np.full(len(run_walls), -1, np.int64)], axis=1)])
        found = self._run(typ, matrices, vol, checks, clearance, progress)
        for k, (gap, ratio) in zip(run_pairs, found[:len(run_pairs)], strict=True):
            memo.add_pair(pair_keys[k], _value(gap), _value(ratio))
        for i, (gap, ratio) in zip(run_walls, found[len(run_pairs):], strict=True):
            memo.add_wall(int(ids[i]), _value(gap), _value(ratio), False)
        return self._report(pairs, pair_keys, walls, ids, memo, clearance, tol)

    def _spare_apart(self, typ: np.ndarray, matrices: np.ndarray, pairs: np.ndarray,
                     pair_keys: list[tuple[int, int]], run_pairs: list[int], clearance: float,
                     memo: CheckMemo) -> list[int]:
        """The pairs to run (indices into pairs (P, 2)) less those a plane proves apart
        (module doc), whose results go into the memo as their checks would give them."""
        if not run_pairs:
            return run_pairs
        search = GAP_SEARCH * clearance if clearance > 0 else 0.0
        margin = search + APART_MARGIN * self.coordinate_size
        run = np.asarray(run_pairs, np.int64)
        apart = apart_pairs(*self.hulls, typ, matrices, pairs[run], margin)
        gap, ratio = (search, None) if clearance > 0 else (None, 0.0)
        for k in run[apart].tolist():
            memo.add_pair(pair_keys[k], gap, ratio)
        return run[~apart].tolist()

    @staticmethod
    def _report(pairs: np.ndarray, pair_keys: list[tuple[int, int]], walls: np.ndarray,
                ids: np.ndarray, memo: CheckMemo, clearance: float, tol: float
                ) -> CertifyReport:
        """The report of checks (pairs (P, 2) with their memo keys, walls (W,)) whose
        results are all in the memo, in the order of the checks."""
        rep = CertifyReport(True, tol, clearance, 0.0, None, 0.0, None, None, None,
                            pairs_checked=len(pairs), walls_checked=len(walls))
        for (i, j), key in zip(pairs.tolist(), pair_keys, strict=True):
            gap, ratio = memo.pairs[key]
            rep.min_pair_gap = _least(rep.min_pair_gap, gap)
            short = shortfall(gap, clearance)
            if short is not None:
                rep.pair_shortfall[(i, j)] = short
            if ratio is not None and ratio > rep.worst_overlap:
                rep.worst_overlap = ratio
                rep.worst_overlap_pair = (i, j)
            if short is not None or (ratio is not None and ratio > tol):
                rep.bad_pairs.append((i, j))
        for i in walls.tolist():
            gap, ratio, beyond = memo.walls[int(ids[i])]
            if beyond:
                rep.worst_outside = 1.0
                rep.worst_outside_object = i
                rep.bad_wall.append(i)
                if clearance > 0:
                    rep.wall_shortfall[i] = clearance
                continue
            rep.min_wall_gap = _least(rep.min_wall_gap, gap)
            short = shortfall(gap, clearance)
            if short is not None:
                rep.wall_shortfall[i] = short
            if ratio is not None and ratio > rep.worst_outside:
                rep.worst_outside = ratio
                rep.worst_outside_object = i
            if short is not None or (ratio is not None and ratio > tol):
                rep.bad_wall.append(i)
        rep.certified = not rep.bad_pairs and not rep.bad_wall
        return rep

    def least_gaps(self, typ: np.ndarray, matrices: np.ndarray, clearance: float,
                   memo: CheckMemo, ids: np.ndarray,
                   known: tuple[float | None, float | None] = (None, None)
                   ) -> tuple[float | None, float | None]:
        """The exact least gap between two objects and between an object and the wall
        (container units) of objects (typ (N,), matrices (N,4,4)) just certified with
        clearance > 0, `memo` and `ids`. The checks read gaps only up to GAP_SEARCH x the
        clearance; these are searched further (`exact_checks.least_gap`), from bounds no
        larger than each gap: a pair's boxes apart, an object's least vertex depth less
        its longest edge and the grid's error (as `certify` proves objects deep inside).
        None: no pair, or no object and the wall, within twice the largest object's
        bounding radius (or 16 clearances, if more). known: the certification's least pair
        and wall gaps (its report's), which bound the least where below GAP_SEARCH x the
        clearance (measured there exactly)."""
        base = GAP_SEARCH * clearance
        bounds = [g if g is not None and g < base else None for g in known]
        reach = np.linalg.norm(self.hulls[0], axis=1).max(initial=0.0)
        limit = max(16.0 * clearance, 2.0 * float(reach))
        lo, hi, depth = memo.lo[ids], memo.hi[ids], memo.depth[ids]
        # the solids are float32: bounds from the float64 vertices may be off by its rounding
        slack = 1e-6 * self.coordinate_size
        solid = PlacedSolids(self.solids, typ, matrices)
        everyone = np.ones(len(typ), bool)

        def known(gap: float | None, search: float) -> float | None:
            """A memo's gap as measure() gives it: exact below `base`, a floor above."""
            if gap is None:
                return None
            if gap < base:
                return min(gap, search)
            return search if search <= base else None

        def pairs_within(search: float) -> tuple[np.ndarray, list]:
            pairs = self._touching_pairs(lo, hi, everyone, search)
            i, j = pairs[:, 0], pairs[:, 1]
            apart = np.maximum(lo[i] - hi[j], lo[j] - hi[i]).max(axis=1, initial=0.0)
            return apart - slack, pairs.tolist()

        def pair_gap(pair: list[int], search: float) -> float:
            i, j = pair
            a, b = int(ids[i]), int(ids[j])
            got = known(memo.pairs.get((min(a, b), max(a, b)), (None, None))[0], search)
            return got if got is not None else solid.gap(i, j, search)

        wall_lower = (depth - self.max_edge[typ] - WALL_READ_ERROR * self.container.grid.spacing
                      - slack)

        def walls_within(search: float) -> tuple[np.ndarray, list]:
            near = np.flatnonzero(wall_lower < search)
            return wall_lower[near], near.tolist()

        def wall_gap(i: int, search: float) -> float:
            got = known(memo.walls.get(int(ids[i]), (None, None, False))[0], search)
            return got if got is not None else solid.gap(i, -1, search)

        return (least_gap(pairs_within, pair_gap, base, limit, bounds[0]),
                least_gap(walls_within, wall_gap, base, limit, bounds[1]))

    @staticmethod
    def _touching_pairs(lo: np.ndarray, hi: np.ndarray, check: np.ndarray,
                        clearance: float) -> np.ndarray:
        """The pairs (P, 2) whose bounding boxes (lo, hi (N, 3)) come within the clearance
        of each other and that involve an object to check (N,), near ones together."""
        if len(lo) < 2:
            return np.zeros((0, 2), np.int64)
        centre = (lo + hi) / 2
        half = np.linalg.norm((hi - lo) / 2, axis=1)
        tree = cKDTree(centre)
        pairs = _near_first(tree, _pairs_within_reach(centre, half, clearance, tree))
        i, j = pairs[:, 0], pairs[:, 1]
        apart = (np.any(lo[i] > hi[j] + clearance, axis=1)
                 | np.any(lo[j] > hi[i] + clearance, axis=1))
        return pairs[(check[i] | check[j]) & ~apart].astype(np.int64)

    def _run(self, typ: np.ndarray, matrices: np.ndarray, vol: np.ndarray,
             checks: np.ndarray, clearance: float,
             progress: Callable[[int, int], None] | None) -> np.ndarray:
        """`exact_checks.run_checks` on these objects: here for the first
        POOL_PROBE_SECONDS, then, where the rest would take POOL_MIN_SECONDS or more at
        that rate (or the workers run already) and more than one process may run, in
        worker processes (`check_pool`), or here again should they fail."""
        ticker = _Ticker(progress, len(checks))
        out = np.empty((len(checks), 2))
        solid = PlacedSolids(self.solids, typ, matrices)
        start = time.perf_counter()
        done = 0
        while done < len(checks):
            if self._pool_worth(done, len(checks), time.perf_counter() - start):
                try:
                    pool = self._open_pool()
                    out[done:] = pool.run(typ, matrices, vol, checks[done:], clearance,
                                          ticker.advance)
                    done = len(checks)
                    break
                except Exception as exc:  # a check's own error comes again here
                    self._pool_failed(exc)
                    ticker.count = done
            part = checks[done:done + PROBE_CHECKS]
            out[done:done + len(part)] = run_checks(solid, vol, part, clearance,
                                                    ticker.step)
            done += len(part)
        ticker.finish()
        return out

    def _pool_worth(self, done: int, total: int, seconds: float) -> bool:
        """Whether to hand the rest of a run's checks to the workers, after `done` of
        `total` took `seconds` here."""
        if self._pool_broken or self.processes < 2 or done == 0:
            return False
        if self._pool is not None:  # started for an earlier certification: no start-up
            return True
        if seconds < POOL_PROBE_SECONDS:
            return False
        return seconds / done * (total - done) >= POOL_MIN_SECONDS

    def _open_pool(self) -> CheckPool:
        if self._pool is None:
            self._pool = CheckPool(self.processes,
                                   (self.container.vertices, self.container.faces),
                                   list(zip(self.vertices, self.faces, strict=True)))
        return self._pool

    def _pool_failed(self, exc: BaseException) -> None:
        """Worker processes failed (none could start, or one died): the checks run here
        from now on, with the same results."""
        log.warning("certification's worker processes failed (%s); checking in this "
                    "process", exc)
        self._pool_broken = True
        self.close()

    def close(self) -> None:
        """End the worker processes, if any were started."""
        if self._pool is not None:
            pool, self._pool = self._pool, None
            pool.close()

    def __enter__(self) -> Certifier:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _bounds_and_depth(self, typ: np.ndarray, matrices: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each object's bounding box lo, hi (N,3) and the container grid's smallest value at
        its vertices (N,) as the wall test reads the grid (`_wall_values`), container frame;
        a type's objects at a time, in chunks of at most CHUNK_VERTICES vertices, so that
        memory does not grow with the count."""
        n = len(typ)
        lo, hi, depth = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
        g = self.container.grid
        for t, verts in enumerate(self.vertices):
            idx = np.flatnonzero(typ == t)
            step = max(1, CHUNK_VERTICES // max(len(verts), 1))
            for c in range(0, len(idx), step):
                part = idx[c:c + step]
                m = matrices[part]
                world = (np.matmul(verts, m[:, :3, :3].transpose(0, 2, 1))
                         + m[:, None, :3, 3])  # (k, V, 3)
                lo[part] = world.min(axis=1)
                hi[part] = world.max(axis=1)
                d = sample_grid_many(self._wall_values, g.origin, g.spacing,
                                     world.reshape(-1, 3))
                depth[part] = d.reshape(len(part), -1).min(axis=1)
        return lo, hi, depth


def _least(a: float | None, b: float | None) -> float | None:
    """The smaller of two gaps, either of which may be unmeasured (None)."""
    return b if a is None else a if b is None else min(a, b)


def _value(x: float) -> float | None:
    """A check's measured value, or None where it was not measured (NaN)."""
    return None if np.isnan(x) else float(x)


def _pairs_within_reach(centre: np.ndarray, half: np.ndarray, clearance: float,
                        tree: cKDTree) -> np.ndarray:
    """Every pair (E, 2), smaller index first, whose boxes' centres (N, 3) lie within the sum
    of their half-diagonals (N,) plus the clearance, and some farther ones. Objects are
    queried by size class (half-diagonals within a factor SIZE_CLASS of each other), each
    class pair with its own reach: one reach for all, the largest object's, made every small
    neighbour of a small object a candidate, and with a 10:1 size ratio 8,001 objects took
    21.7 million candidates, 8.5 s and 1.6 GB (docs/notes-core.md). tree: over ``centre``."""
    smallest = max(float(half.min()), 1e-300)
    cls = np.floor(np.log(np.maximum(half, smallest) / smallest) / np.log(SIZE_CLASS))
    kinds = np.unique(cls)
    if len(kinds) == 1:
        return tree.query_pairs(2 * float(half.max()) + clearance, output_type="ndarray")
    members = [np.flatnonzero(cls == k) for k in kinds]
    trees = [cKDTree(centre[m]) for m in members]
    largest = [float(half[m].max()) for m in members]
    found = []
    for a, (ma, ta) in enumerate(zip(members, trees, strict=True)):
        found.append(ma[ta.query_pairs(2 * largest[a] + clearance, output_type="ndarray")])
        for b in range(a + 1, len(members)):
            near = ta.sparse_distance_matrix(trees[b], largest[a] + largest[b] + clearance,
                                             output_type="ndarray")
            found.append(np.stack([ma[near["i"]], members[b][near["j"]]], axis=1))
    pairs = np.concatenate(found).reshape(-1, 2)
    return np.sort(pairs, axis=1)


def _near_first(tree: cKDTree, pairs: np.ndarray) -> np.ndarray:
    """The pairs (E, 2) in the k-d tree's leaf order of their objects, so that consecutive
    checks share objects and a kept solid serves the next ones."""
    if len(pairs) == 0:
        return pairs
    rank = np.empty(len(tree.indices), np.int64)
    rank[tree.indices] = np.arange(len(tree.indices))
    r = np.sort(rank[pairs], axis=1)
    return pairs[np.lexsort((r[:, 1], r[:, 0]))]


class CheckMemo:
    """The exact checks' results for one packing across its certifications, by object id,
    with the type and placement each object had when checked: manifold3d's checks are
    deterministic, so a check whose objects are where they were need not run again, and a
    certification after a repair costs the checks of what moved."""

    def __init__(self):
        self.key: tuple[float, float] | None = None  # (clearance, tol) the results are for
        self.run = 0  # checks run (pairs and walls)
        self._clear()

    def _clear(self) -> None:
        self.typ = np.zeros(0, np.int64)
        self.placed = np.zeros((0, 3, 4))
        # each object's bounding box and least vertex depth at its recorded placement
        self.lo, self.hi, self.depth = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
        # (gap or None, overlap ratio or None) by (smaller id, larger id)
        self.pairs: dict[tuple[int, int], tuple[float | None, float | None]] = {}
        # (gap or None, outside ratio or None, wholly beyond the outside's bounds) by id
        self.walls: dict[int, tuple[float | None, float | None, bool]] = {}
        self._partners: dict[int, list[int]] = {}

    def update(self, ids: np.ndarray, typ: np.ndarray, matrices: np.ndarray,
               clearance: float, tol: float) -> np.ndarray:
        """Forget the checks and bounds of every object (ids (N,)) whose type or placement
        (matrices (N,4,4)) is not the one recorded, then record these. Returns (N,) whether
        each object's bounds are known (`set_bounds`)."""
        if (clearance, tol) != self.key:
            self._clear()
            self.key = (clearance, tol)
        if len(ids) == 0:
            return np.zeros(0, bool)
        need = int(ids.max()) + 1
        if need > len(self.typ):
            more = need - len(self.typ)
            self.typ = np.concatenate([self.typ, np.full(more, -1)])
            self.placed = np.concatenate([self.placed, np.full((more, 3, 4), np.nan)])
            self.lo = np.concatenate([self.lo, np.zeros((more, 3))])
            self.hi = np.concatenate([self.hi, np.zeros((more, 3))])
            self.depth = np.concatenate([self.depth, np.zeros(more)])
        now = matrices[:, :3, :4]
        same = (self.typ[ids] == typ) & np.all(self.placed[ids] == now, axis=(1, 2))
        for k in ids[~same]:
            self._forget(int(k))
        self.typ[ids] = typ
        self.placed[ids] = now
        return same

    def set_bounds(self, ids: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                   depth: np.ndarray) -> None:
        """Record objects' bounds (N,3) and least vertex depths (N,) at their placements."""
        self.lo[ids], self.hi[ids], self.depth[ids] = lo, hi, depth

    def _forget(self, k: int) -> None:
        self.walls.pop(k, None)
        for other in self._partners.pop(k, []):
            self.pairs.pop((min(k, other), max(k, other)), None)

    def add_pair(self, key: tuple[int, int], gap: float | None, ratio: float | None
                 ) -> None:
        self.run += 1
        self.pairs[key] = (gap, ratio)
        self._partners.setdefault(key[0], []).append(key[1])
        self._partners.setdefault(key[1], []).append(key[0])

    def add_wall(self, key: int, gap: float | None, ratio: float | None, beyond: bool
                 ) -> None:
        self.run += 1
        self.walls[key] = (gap, ratio, beyond)


class _Ticker:
    """Calls progress(done, total) at most every PROGRESS_SECONDS, and once at the end."""

    def __init__(self, progress: Callable[[int, int], None] | None, total: int):
        self.progress, self.total, self.count = progress, total, 0
        self.next = time.perf_counter() + PROGRESS_SECONDS

    def step(self) -> None:
        self.advance(1)

    def advance(self, count: int) -> None:
        self.count += count
        if self.progress is not None and time.perf_counter() >= self.next:
            self.progress(self.count, self.total)
            self.next = time.perf_counter() + PROGRESS_SECONDS

    def finish(self) -> None:
        if self.progress is not None:
            self.progress(self.total, self.total)
