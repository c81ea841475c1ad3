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
                tol: float = DEFAULT_TOL, subset: np.ndarray | None = None) -> CertifyReport:
        """Check objects (typ (N,), matrices (N,4,4) local -> container frame, scale 1).

        subset: only pairs and walls involving these indices are checked (others trusted).
        """
        n = len(typ)
        lo, hi, depth = self._bounds_and_depth(typ, matrices)
        vol = self.volumes[typ] if n else np.zeros(0)
        check = np.ones(n, bool) if subset is None else np.isin(np.arange(n), subset)

        solid = _PlacedSolids(self.types, typ, matrices)

        rep = CertifyReport(True, tol, clearance, 0.0, None, 0.0, None,
                            None, None)
        # --- pairs
        if n >= 2:
            centre = (lo + hi) / 2
            half = (hi - lo) / 2
            reach = 2 * float(np.linalg.norm(half, axis=1).max()) + clearance
            tree = cKDTree(centre)
            for i, j in _near_first(tree, tree.query_pairs(reach, output_type="ndarray")):
                if not (check[i] or check[j]):
                    continue
                if np.any(lo[i] > hi[j] + clearance) or np.any(lo[j] > hi[i] + clearance):
                    continue
                rep.pairs_checked += 1
                oi, oj = solid(i), solid(j)
                bad = False
                if clearance > 0:
                    gap = oi.min_gap(oj, GAP_SEARCH * clearance)
                    rep.min_pair_gap = gap if rep.min_pair_gap is None else min(
                        rep.min_pair_gap, gap)
                    if gap < clearance * (1 - 1e-6):
                        bad = True
                        rep.pair_shortfall[(int(i), int(j))] = clearance - gap
                if clearance <= 0 or bad:  # a gap of at least c > 0: no intersection
                    ratio = (oi ^ oj).volume() / min(vol[i], vol[j])
                    bad = bad or ratio > tol
                    if ratio > rep.worst_overlap:
                        rep.worst_overlap = ratio
                        rep.worst_overlap_pair = (int(i), int(j))
                if bad:
                    rep.bad_pairs.append((int(i), int(j)))
        # --- wall
        g = self.container.grid
        grid_err = 0.5 * g.spacing
        for i in np.flatnonzero(check):
            if depth[i] >= clearance + self.max_edge[typ[i]] + grid_err:
                continue
            rep.walls_checked += 1
            if np.any(hi[i] < self.outside_box[0]) or np.any(lo[i] > self.outside_box[1]):
                rep.worst_outside = 1.0
                rep.worst_outside_object = int(i)
                rep.bad_wall.append(int(i))
                if clearance > 0:
                    rep.wall_shortfall[int(i)] = clearance
                continue
            oi = solid(i)
            bad = False
            if clearance > 0:
                gap = oi.min_gap(self.outside, GAP_SEARCH * clearance)
                rep.min_wall_gap = gap if rep.min_wall_gap is None else min(
                    rep.min_wall_gap, gap)
                if gap < clearance * (1 - 1e-6):
                    bad = True
                    rep.wall_shortfall[int(i)] = clearance - gap
            if clearance <= 0 or bad:
                ratio = (oi ^ self.outside).volume() / vol[i]
                bad = bad or ratio > tol
                if ratio > rep.worst_outside:
                    rep.worst_outside = ratio
                    rep.worst_outside_object = int(i)
            if bad:
                rep.bad_wall.append(int(i))
        rep.certified = not rep.bad_pairs and not rep.bad_wall
        return rep

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
