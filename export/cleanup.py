"""Remove zero-area faces from a closed mesh, changing its shape by at most a needle's
length (1e-3 of that face's size).

manifold3d's booleans can leave a few zero-area faces where intersection curves meet
(vertices that coincide, or a vertex on the far edge), and float32 files (STL) merge
vertices closer than float32 resolution. Two local, shape-preserving repairs fix them:

* a *needle* (two corners at, or within 1e-3 of the face's size of, the same position) is
  removed by collapsing that edge: its two faces go, one vertex replaces the other (allowed
  only when the two vertices share exactly those two neighbours, so the surface stays a
  2-manifold);
* a *cap* (a corner on the opposite edge ab) is removed by flipping ab: faces (a, b, c) and
  (b, a, d) become (c, a, d) and (d, b, c), the same region split at c.

A needle need not have zero area to fold over its neighbour once its positions are rounded
to float32: `collapse_needles` collapses the short edges of the needles among given faces
(those a float32 self-intersection test names).

Where two surfaces touch along an edge or at a point (two objects that only kiss),
manifold3d keeps them apart by index at one position; a file merges them there into a
non-manifold edge or vertex. `move_vertices` moves such vertices (`shared_vertices`) into
their own solid, or out of it (`union._apart` chooses), by a step far below any printer's
resolution.

Positions are tested as given and as float32 (the coarsest format written); faces keep
their winding.
"""

from __future__ import annotations

import heapq

import numpy as np
from numba import njit

from .validate import DEGENERATE_REL

#: a zero-area face whose shortest edge is at most this fraction of its longest is a needle
#: (collapsing that edge moves the surface by that edge's length at most)
NEEDLE_REL = 1e-3


@njit(cache=True)
def _zero_area_kernel(p: np.ndarray, f: np.ndarray, limit: float) -> np.ndarray:
    """(F,) faces whose doubled area is at most ``limit`` times their longest edge, at
    positions p (V,3). One pass in numba: numpy's temporaries were slow on the unions of
    thousands of objects (docs/notes-export.md); tests/export keep the numpy reference."""
    out = np.zeros(len(f), np.bool_)
    for k in range(len(f)):
        a, b, c = f[k, 0], f[k, 1], f[k, 2]
        ux = p[b, 0] - p[a, 0]
        uy = p[b, 1] - p[a, 1]
        uz = p[b, 2] - p[a, 2]
        wx = p[c, 0] - p[a, 0]
        wy = p[c, 1] - p[a, 1]
        wz = p[c, 2] - p[a, 2]
        cx = uy * wz - uz * wy
        cy = uz * wx - ux * wz
        cz = ux * wy - uy * wx
        area2 = np.sqrt(cx * cx + cy * cy + cz * cz)
        longest = 0.0
        for i, j in ((a, c), (b, a), (c, b)):
            dx = p[i, 0] - p[j, 0]
            dy = p[i, 1] - p[j, 1]
            dz = p[i, 2] - p[j, 2]
            longest = max(longest, np.sqrt(dx * dx + dy * dy + dz * dz))
        out[k] = area2 <= limit * longest
    return out


def _stored(v: np.ndarray, float32: bool) -> np.ndarray:
    """The positions as a file stores them: rounded to float32 with ``float32`` (STL, PLY),
    else as given (3MF, OBJ: float64)."""
    return v.astype(np.float32).astype(np.float64) if float32 else v


class _ZeroArea:
    """Which faces (rows of vertex indices into v) have zero area at the positions as given
    and, with ``float32``, also once rounded to float32; each position set's limit (from
    its bounding box) found once, so that rows can be judged a few at a time."""

    def __init__(self, v: np.ndarray, float32: bool):
        self.positions = [np.ascontiguousarray(p, np.float64)
                          for p in ([v, _stored(v, True)] if float32 else [v])]
        self.limits = [DEGENERATE_REL * float(np.linalg.norm(np.ptp(p, axis=0)))
                       if len(p) else 0.0 for p in self.positions]

    def __call__(self, rows: np.ndarray) -> np.ndarray:
        out = np.zeros(len(rows), bool)
        rows = np.ascontiguousarray(rows, np.int64)
        for p, limit in zip(self.positions, self.limits, strict=True):
            out |= _zero_area_kernel(p, rows, limit)
        return out


def _zero_area(p: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(F,) faces of zero area at positions p as given (the kernel's numpy reference is in
    tests/export/test_validate_kernels.py)."""
    return _ZeroArea(p, False)(f)


def degenerate_faces(v: np.ndarray, f: np.ndarray, float32: bool = True) -> np.ndarray:
    """Indices of faces of zero area, with the positions as given (float64: 3MF, OBJ) or,
    with ``float32``, also rounded to float32 (STL, PLY). Far from the origin float32's
    step is coarse (8 micrometres at 1e5 mm): faces that only float32 flattens are sound in
    a 3MF, and repairing them there folds the surface."""
    if len(f) == 0:
        return np.zeros(0, np.int64)
    return np.flatnonzero(_ZeroArea(v, float32)(f))


class _Faces:
    """A closed mesh's faces under local edits (edge collapses and flips), each found and
    made in time proportional to the faces around it, not to the mesh: removed faces are
    only marked, so the others keep their order (as np.delete would), and a vertex's faces
    are those it had at the start plus those it gained since, checked against the faces'
    corners now. One collapse or flip used to search and copy the whole face array, which
    made the cleanup of a union of hundreds of detailed objects take tens of seconds
    (docs/notes-export.md)."""

    def __init__(self, f: np.ndarray):
        self.f = np.array(f, dtype=np.int64, copy=True).reshape(-1, 3)
        self.alive = np.ones(len(self.f), dtype=bool)
        flat = self.f.ravel()
        order = np.argsort(flat, kind="stable")
        self._faces = order // 3
        n = int(flat.max()) + 1 if len(flat) else 0
        self._start = np.searchsorted(flat[order], np.arange(n + 1))
        self._gained: dict[int, list[int]] = {}

    def faces_of(self, x: int) -> np.ndarray:
        """The live faces that hold vertex x, in order."""
        base = (self._faces[self._start[x]:self._start[x + 1]]
                if x + 1 < len(self._start) else np.zeros(0, np.int64))
        extra = self._gained.get(x)
        cand = np.unique(np.concatenate([base, extra]) if extra else base)
        return cand[self.alive[cand] & (self.f[cand] == x).any(axis=1)]

    def neighbours(self, x: int) -> set[int]:
        return set(np.unique(self.f[self.faces_of(x)]).tolist()) - {x}

    def faces(self) -> np.ndarray:
        return self.f[self.alive]

    def collapse(self, p: int, q: int) -> np.ndarray | None:
        """Collapse edge pq onto p; returns the faces changed (p's, after), or None when
        that would break the 2-manifold (and nothing changes)."""
        of_p, of_q = self.faces_of(p), self.faces_of(q)
        both = np.intersect1d(of_p, of_q)
        if len(both) != 2:
            return None
        opposite = {int(x) for x in self.f[both].ravel()} - {p, q}
        if self.neighbours(p) & self.neighbours(q) != opposite:
            return None
        self.alive[both] = False
        moved = of_q[self.alive[of_q]]
        rows = self.f[moved]
        rows[rows == q] = p
        self.f[moved] = rows
        self._gained.setdefault(p, []).extend(int(g) for g in moved)
        return self.faces_of(p)

    def flip(self, face: int, a: int, b: int, c: int) -> np.ndarray | None:
        """Flip edge ab of face (a, b, c) with the face across it; returns the faces of a,
        b, c and d (after), or None when edge cd exists or ab has no single face across."""
        cand = np.intersect1d(self.faces_of(a), self.faces_of(b))
        rows = self.f[cand]
        across = cand[((rows == b) & (np.roll(rows, -1, axis=1) == a)).any(axis=1)]
        if len(across) != 1:
            return None
        g = self.f[across[0]]
        d = int(g[(list(g).index(a) + 1) % 3])  # g is (b, a, d) up to rotation
        if d in (a, b, c) or d in self.neighbours(c):
            return None
        self.f[face] = (c, a, d)
        self.f[across[0]] = (d, b, c)
        self._gained.setdefault(d, []).append(face)
        self._gained.setdefault(c, []).append(int(across[0]))
        return np.unique(np.concatenate([self.faces_of(x) for x in (a, b, c, d)]))


def _edges(p: np.ndarray, tri: list[int]) -> tuple[list[tuple[int, int]], list[float]]:
    """A face's three edges (a, b) and their lengths at positions p."""
    edges = [(tri[k], tri[(k + 1) % 3]) for k in range(3)]
    return edges, [float(np.linalg.norm(p[a] - p[b])) for a, b in edges]


def _needle_edge(p: np.ndarray, tri: list[int], rel: float = NEEDLE_REL,
                 max_length: float = np.inf) -> tuple[int, int] | None:
    """A needle's short edge: the face's shortest edge when it is at most ``rel`` of its
    longest and at most ``max_length`` long, at positions p; None for a face that is no
    needle."""
    edges, lengths = _edges(p, tri)
    k = int(np.argmin(lengths))
    return edges[k] if lengths[k] <= min(rel * max(lengths), max_length) else None


def remove_degenerate_faces(v: np.ndarray, f: np.ndarray, max_steps: int = 1000,
                            float32: bool = True, max_collapse: float = 0.0
                            ) -> tuple[np.ndarray, np.ndarray, int]:
    """Repair zero-area faces of a closed, consistently wound mesh (zero area as given, and
    with ``float32`` also once rounded to float32: see :func:`degenerate_faces`), the
    lowest-numbered face first, each face at most once as it stands, up to ``max_steps``
    faces; after each repair only the faces around it are judged again. Where faces are
    left (a strip of caps whose flips only make more caps), each has its shortest edge
    collapsed if that edge is at most ``max_collapse`` long.

    Returns (vertices, faces, faces still degenerate). Vertices are unchanged (a collapsed
    vertex is simply no longer used); faces keep their winding and order.
    """
    faces = _Faces(f)
    p32 = _stored(v, float32)
    zero = _ZeroArea(v, float32)
    zero_now = zero(faces.f)
    heap = np.flatnonzero(zero_now).tolist()  # sorted: a heap already
    tried: set[tuple[int, ...]] = set()
    steps = 0
    while heap and steps < max_steps:
        i = heapq.heappop(heap)
        tri = [int(x) for x in faces.f[i]]
        if not (faces.alive[i] and zero_now[i]) or tuple(tri) in tried:
            continue
        steps += 1
        tried.add(tuple(tri))
        edges, lengths = _edges(p32, tri)
        changed = None
        short = _needle_edge(p32, tri)
        if short is not None:  # a needle: its short edge goes
            changed = faces.collapse(*short)
        if changed is None:  # a cap (or a needle that cannot collapse): flip the long edge
            k = int(np.argmax(lengths))
            a, b = edges[k]
            changed = faces.flip(i, a, b, tri[(k + 2) % 3])
        if changed is not None:
            zero_now[changed] = zero(faces.f[changed])
            for j in changed[zero_now[changed]]:
                heapq.heappush(heap, int(j))
    if max_collapse > 0.0:
        left = set(np.flatnonzero(faces.alive & zero(faces.f)).tolist())
        while left and steps < max_steps:
            changed = None
            for i in sorted(left):
                tri = [int(x) for x in faces.f[i]]
                edges, lengths = _edges(p32, tri)
                k = int(np.argmin(lengths))
                if lengths[k] <= max_collapse:
                    changed = faces.collapse(*edges[k])
                    if changed is not None:
                        break
            if changed is None:
                break
            steps += 1
            # only the faces around the collapse changed: judged again, as above
            now = zero(faces.f[changed])
            left = {j for j in left if faces.alive[j]} - set(changed[~now].tolist())
            left |= set(changed[now].tolist())
    out = faces.faces()
    return v, out, len(degenerate_faces(v, out, float32))


def collapse_needles(v: np.ndarray, f: np.ndarray, faces: np.ndarray, *,
                     rel: float = NEEDLE_REL, max_length: float = np.inf,
                     float32: bool = True) -> tuple[np.ndarray, int]:
    """Collapse the short edge of each needle among `faces` (indices into f): a face whose
    shortest edge, with positions as stored (rounded to float32 with ``float32``), is at
    most ``rel`` of its longest (and at most ``max_length`` long), where the 2-manifold
    allows it (`_collapse`). Returns (faces, edges collapsed); vertices are unchanged and
    faces keep their winding."""
    editor = _Faces(f)
    p32 = _stored(v, float32)
    edges = [_needle_edge(p32, [int(x) for x in editor.f[i]], rel, max_length)
             for i in np.unique(np.asarray(faces, np.int64))]
    done = 0
    for edge in edges:
        # None too when an earlier collapse took a or b
        if edge is not None and editor.collapse(*edge) is not None:
            done += 1
    return editor.faces(), done


def move_vertices(v: np.ndarray, f: np.ndarray, vertices: np.ndarray, step: float
                  ) -> np.ndarray:
    """The positions with ``vertices`` (indices into v) moved by ``step`` against their own
    area-weighted normal, into their solid (a negative step moves them out of it); faces
    are unchanged."""
    vertices = np.asarray(vertices, np.int64)
    near = f[np.isin(f, vertices).any(axis=1)]
    tri = v[near]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(v)
    for k in range(3):
        np.add.at(vn, near[:, k], normals)
    n = vn[vertices]
    length = np.linalg.norm(n, axis=1, keepdims=True)
    v = v.copy()
    v[vertices] -= step * n / np.where(length > 0, length, 1.0)
    return v


def shared_vertices(remap: np.ndarray) -> np.ndarray:
    """The vertices that share a position with another (remap: each vertex's merged index,
    from `merge_identical`)."""
    return np.flatnonzero(np.bincount(remap)[remap] > 1)
