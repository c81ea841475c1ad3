"""Exact checks of a packing on the real meshes (manifold3d).

A packing is certified when every pair's intersection volume and every object's volume
outside the container are at most `tol` (1e-4) of the object's volume, and, with a clearance
c > 0, every pair's and every object-wall minimum gap is at least c. The report gives the
worst values, not only a flag. Frames: container frame, container units.

Which checks run: every pair whose axis-aligned bounds (grown by c) touch gets an exact
boolean intersection, or with c > 0 a min_gap first and the boolean only where the gap falls
short (a gap of c > 0 proves the two apart). Every object gets the exact volume outside
the container, except objects the container's distance grid proves deep inside: all its
vertices at depth >= c + its longest edge + the grid's interpolation error (every surface
point of a triangle lies within an edge length of a vertex, so the surface then cannot reach
the wall).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from .container import Container
from .kernels import sample_grid_many
from .solids import outside_of, to_solid

DEFAULT_TOL = 1e-4
#: triangles of placed solids one certification keeps for its next checks
KEPT_FACES = 500_000
#: vertices placed at once when bounding and depth-testing objects
CHUNK_VERTICES = 1 << 20
#: min_gap's search distance over the clearance: gaps beyond it read as this much, and
#: manifold3d's cost grows steeply with it (docs/notes-core.md)
GAP_SEARCH = 1.25
#: seconds between a certification's progress calls
PROGRESS_SECONDS = 0.5


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
    min_pair_gap: float | None  # only with clearance > 0 (None when no pair was near)
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
    """Holds the manifolds of the container's outside and of each type (local frame)."""

    def __init__(self, container: Container, type_vertices: list[np.ndarray],
                 type_faces: list[np.ndarray], type_volumes: np.ndarray,
                 type_max_edge: np.ndarray):
        self.container = container
        # intersections with it are volume outside, and min_gap to it is the wall gap
        self.outside = outside_of(container.vertices, container.faces, double=False)
        # an object wholly beyond this box misses `outside` too: it is outside entirely
        self.outside_box = np.asarray(self.outside.bounding_box(), np.float64).reshape(2, 3)
        self.types = [to_solid(v, f, double=False)
                      for v, f in zip(type_vertices, type_faces, strict=True)]
        self.vertices = type_vertices
        self.volumes = np.asarray(type_volumes, np.float64)
        self.max_edge = np.asarray(type_max_edge, np.float64)

    def certify(self, typ: np.ndarray, matrices: np.ndarray, clearance: float = 0.0,
                tol: float = DEFAULT_TOL, subset: np.ndarray | None = None, *,
                memo: CheckMemo | None = None, ids: np.ndarray | None = None,
                progress: Callable[[int, int], None] | None = None) -> CertifyReport:
        """Check objects (typ (N,), matrices (N,4,4) local -> container frame, scale 1).

        subset: only pairs and walls involving these indices are checked (others trusted).
        memo: results of earlier certifications of the same objects, read and extended:
        a check whose objects (ids (N,), stable between calls; default 0..N-1) have the
        same type and placement as when it ran is not run again. The report is the same
        as without it. progress(done, total) is called now and then with the checks done.
        """
        n = len(typ)
        lo, hi, depth = self._bounds_and_depth(typ, matrices)
        vol = self.volumes[typ] if n else np.zeros(0)
        check = np.ones(n, bool) if subset is None else np.isin(np.arange(n), subset)
        ids = np.arange(n) if ids is None else np.asarray(ids, np.int64)
        if memo is None:
            memo = CheckMemo()
        memo.update(ids, typ, matrices, clearance, tol)

        solid = _PlacedSolids(self.types, typ, matrices)

        rep = CertifyReport(True, tol, clearance, 0.0, None, 0.0, None,
                            None, None)
        pairs = np.zeros((0, 2), np.int64)
        if n >= 2:
            centre = (lo + hi) / 2
            half = (hi - lo) / 2
            reach = 2 * float(np.linalg.norm(half, axis=1).max()) + clearance
            tree = cKDTree(centre)
            pairs = _near_first(tree, tree.query_pairs(reach, output_type="ndarray"))
        g = self.container.grid
        grid_err = 0.5 * g.spacing
        walls = [i for i in np.flatnonzero(check)
                 if depth[i] < clearance + self.max_edge[typ[i]] + grid_err]
        ticker = _Ticker(progress, len(pairs) + len(walls))
        # --- pairs
        for i, j in pairs:
            ticker.step()
            if not (check[i] or check[j]):
                continue
            if np.any(lo[i] > hi[j] + clearance) or np.any(lo[j] > hi[i] + clearance):
                continue
            rep.pairs_checked += 1
            key = (int(min(ids[i], ids[j])), int(max(ids[i], ids[j])))
            found = memo.pairs.get(key)
            if found is None:
                found = memo.add_pair(key, *self._pair(solid(i), solid(j), vol[i], vol[j],
                                                       clearance))
            gap, ratio = found
            rep.min_pair_gap = _least(rep.min_pair_gap, gap)
            short = _shortfall(gap, clearance)
            if short is not None:
                rep.pair_shortfall[(int(i), int(j))] = short
            if ratio is not None and ratio > rep.worst_overlap:
                rep.worst_overlap = ratio
                rep.worst_overlap_pair = (int(i), int(j))
            if short is not None or (ratio is not None and ratio > tol):
                rep.bad_pairs.append((int(i), int(j)))
        # --- wall
        for i in walls:
            ticker.step()
            rep.walls_checked += 1
            key = int(ids[i])
            found = memo.walls.get(key)
            if found is None:
                found = memo.add_wall(key, *self._wall(solid, i, lo[i], hi[i], vol[i],
                                                       clearance))
            gap, ratio, beyond = found
            if beyond:
                rep.worst_outside = 1.0
                rep.worst_outside_object = int(i)
                rep.bad_wall.append(int(i))
                if clearance > 0:
                    rep.wall_shortfall[int(i)] = clearance
                continue
            rep.min_wall_gap = _least(rep.min_wall_gap, gap)
            short = _shortfall(gap, clearance)
            if short is not None:
                rep.wall_shortfall[int(i)] = short
            if ratio is not None and ratio > rep.worst_outside:
                rep.worst_outside = ratio
                rep.worst_outside_object = int(i)
            if short is not None or (ratio is not None and ratio > tol):
                rep.bad_wall.append(int(i))
        ticker.finish()
        rep.certified = not rep.bad_pairs and not rep.bad_wall
        return rep

    @staticmethod
    def _pair(oi, oj, vi: float, vj: float, clearance: float
              ) -> tuple[float | None, float | None]:
        """(min gap (with a clearance, else None), intersection volume over the smaller
        volume (None where a gap of at least the clearance proves the two apart))."""
        gap = None
        if clearance > 0:
            gap = oi.min_gap(oj, GAP_SEARCH * clearance)
            if _shortfall(gap, clearance) is None:  # a gap of at least c > 0: no intersection
                return gap, None
        return gap, (oi ^ oj).volume() / min(vi, vj)

    def _wall(self, solid: _PlacedSolids, i: int, lo: np.ndarray, hi: np.ndarray,
              vol: float, clearance: float
              ) -> tuple[float | None, float | None, bool]:
        """(gap to the wall (with a clearance, else None), volume outside over the
        object's (None where the gap proves it inside), whether it lies wholly beyond the
        outside's bounds: wholly outside, nothing measured)."""
        if np.any(hi < self.outside_box[0]) or np.any(lo > self.outside_box[1]):
            return None, None, True
        oi = solid(i)
        gap = None
        if clearance > 0:
            gap = oi.min_gap(self.outside, GAP_SEARCH * clearance)
            if _shortfall(gap, clearance) is None:
                return gap, None, False
        return gap, (oi ^ self.outside).volume() / vol, False

    def _bounds_and_depth(self, typ: np.ndarray, matrices: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each object's bounding box lo, hi (N,3) and the container grid's smallest value at
        its vertices (N,), container frame; a type's objects at a time, in chunks of at
        most CHUNK_VERTICES vertices, so that memory does not grow with the count."""
        n = len(typ)
        lo, hi, depth = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
        g = self.container.grid
        for t, verts in enumerate(self.vertices):
            idx = np.flatnonzero(typ == t)
            step = max(1, CHUNK_VERTICES // max(len(verts), 1))
            for c in range(0, len(idx), step):
                part = idx[c:c + step]
                m = matrices[part]
                world = (np.einsum("kij,vj->kvi", m[:, :3, :3], verts)
                         + m[:, None, :3, 3])  # (k, V, 3)
                lo[part] = world.min(axis=1)
                hi[part] = world.max(axis=1)
                d = sample_grid_many(g.values, g.origin, g.spacing, world.reshape(-1, 3))
                depth[part] = d.reshape(len(part), -1).min(axis=1)
        return lo, hi, depth


def _least(a: float | None, b: float | None) -> float | None:
    """The smaller of two gaps, either of which may be unmeasured (None)."""
    return b if a is None else a if b is None else min(a, b)


def _shortfall(gap: float | None, clearance: float) -> float | None:
    """How far a measured gap falls short of the clearance (None: unmeasured or not short;
    a relative 1e-6 of slack for manifold3d's rounding)."""
    if gap is None or gap >= clearance * (1 - 1e-6):
        return None
    return clearance - gap


def _near_first(tree: cKDTree, pairs: np.ndarray) -> np.ndarray:
    """The pairs (E, 2) in the k-d tree's leaf order of their objects, so that consecutive
    checks share objects and a kept solid serves the next ones."""
    if len(pairs) == 0:
        return pairs
    rank = np.empty(len(tree.indices), np.int64)
    rank[tree.indices] = np.arange(len(tree.indices))
    r = np.sort(rank[pairs], axis=1)
    return pairs[np.lexsort((r[:, 1], r[:, 0]))]


class _PlacedSolids:
    """Object i's solid in the container frame, made when a check needs it and kept while
    the kept ones hold at most KEPT_FACES triangles (the latest one always), least recently
    used out first: making (transforming) a solid costs several times a gap query with it,
    and holding every object's would grow memory by a mesh per object."""

    def __init__(self, types: list, typ: np.ndarray, matrices: np.ndarray):
        self.types, self.typ, self.matrices = types, typ, matrices
        self.faces = [s.num_tri() for s in types]
        self.kept: dict[int, object] = {}  # insertion order is use order
        self.kept_faces = 0

    def __call__(self, i: int):
        i = int(i)
        got = self.kept.pop(i, None)
        if got is None:
            got = self.types[self.typ[i]].transform(self.matrices[i, :3, :4].tolist())
            self.kept_faces += self.faces[self.typ[i]]
            while self.kept and self.kept_faces > KEPT_FACES:
                old = next(iter(self.kept))
                del self.kept[old]
                self.kept_faces -= self.faces[self.typ[old]]
        self.kept[i] = got
        return got


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
        # (gap or None, overlap ratio or None) by (smaller id, larger id)
        self.pairs: dict[tuple[int, int], tuple[float | None, float | None]] = {}
        # (gap or None, outside ratio or None, wholly beyond the outside's bounds) by id
        self.walls: dict[int, tuple[float | None, float | None, bool]] = {}
        self._partners: dict[int, list[int]] = {}

    def update(self, ids: np.ndarray, typ: np.ndarray, matrices: np.ndarray,
               clearance: float, tol: float) -> None:
        """Forget the checks of every object (ids (N,)) whose type or placement (matrices
        (N,4,4)) is not the one recorded, then record these."""
        if (clearance, tol) != self.key:
            self._clear()
            self.key = (clearance, tol)
        if len(ids) == 0:
            return
        need = int(ids.max()) + 1
        if need > len(self.typ):
            self.typ = np.concatenate([self.typ, np.full(need - len(self.typ), -1)])
            self.placed = np.concatenate([self.placed,
                                          np.full((need - len(self.placed), 3, 4), np.nan)])
        now = matrices[:, :3, :4]
        same = (self.typ[ids] == typ) & np.all(self.placed[ids] == now, axis=(1, 2))
        for k in ids[~same]:
            self._forget(int(k))
        self.typ[ids] = typ
        self.placed[ids] = now

    def _forget(self, k: int) -> None:
        self.walls.pop(k, None)
        for other in self._partners.pop(k, []):
            self.pairs.pop((min(k, other), max(k, other)), None)

    def add_pair(self, key: tuple[int, int], gap: float | None, ratio: float | None
                 ) -> tuple[float | None, float | None]:
        self.run += 1
        self.pairs[key] = (gap, ratio)
        self._partners.setdefault(key[0], []).append(key[1])
        self._partners.setdefault(key[1], []).append(key[0])
        return gap, ratio

    def add_wall(self, key: int, gap: float | None, ratio: float | None, beyond: bool
                 ) -> tuple[float | None, float | None, bool]:
        self.run += 1
        self.walls[key] = (gap, ratio, beyond)
        return gap, ratio, beyond


class _Ticker:
    """Calls progress(done, total) at most every PROGRESS_SECONDS, and once at the end."""

    def __init__(self, progress: Callable[[int, int], None] | None, total: int):
        self.progress, self.total, self.count = progress, total, 0
        self.next = time.perf_counter() + PROGRESS_SECONDS

    def step(self) -> None:
        self.count += 1
        if self.progress is not None and time.perf_counter() >= self.next:
            self.progress(self.count, self.total)
            self.next = time.perf_counter() + PROGRESS_SECONDS

    def finish(self) -> None:
        if self.progress is not None:
            self.progress(self.total, self.total)
