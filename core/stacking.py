"""A stacked start: boxy types in rows along the container's axes, at full size.

Plates, tiles, bricks and coins fill a box almost solid when stacked, and a quarter to a
half when grown from random rotations, which the penalty pushes never turn into stacks
(docs/notes-core.md). Where a lattice of the types' boxes, turned onto the container's
axes, holds at least STACKED of the container (by the types' volumes, each grown by its
box's share of the clearance, which costs a stack and a random packing alike), the first
attempt starts from that lattice at full size instead of phase 1's grown one; the cavity
passes then fill what the rows leave. Only types that fill BOXY of their boxes are
stacked: round and irregular ones (fruit, dice of many faces) pack as before. Types of
unlike length along one of their box's axes stand in rows whose sites are each as long as
their type (`_Mixed`).

Frames: a type's local frame; the container frame, container units.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import permutations, product

import numpy as np
import trimesh

from .container import Container
from .metrics import mix_cap, tvd_of_counts
from .options import CavityPassOptions
from .rotations import matrix_to_quat
from .type_spread import TypeSpread, type_needed

#: the least share of the container's volume the stacked objects must hold for the first
#: attempt to start from them. A stack is a candidate: below STACK_KEPT (`placement`) an
#: attempt from phase 1 follows, also without a budget, and the denser is kept
STACKED = 0.3
#: the least share of their boxes the types (by the mix) must fill to be stacked: a
#: cylinder fills 0.79 of its box; a ball 0.52 and the YCB apple scan 0.61, whose random
#: packings fill more than rows of their boxes would
BOXY = 0.7
#: a type is round about a box axis where the cylinder about it that holds its vertices is
#: at most this much wider than the box's sides across it (a 48-sided coin: 0.2%)
ROUND = 1.01
#: moments of inertia within this share of the largest are taken as equal (the body has
#: no axes of its own across them)
EQUAL_MOMENTS = 0.02
#: the steps a box is turned in about a mesh's one distinct axis of inertia (degrees)
SWEEP_DEGREES = 1.0
#: the most lattice sites (of one choice of axes and offsets) the search tests at once;
#: beyond it only two offsets per axis are tried
MANY_SITES = 20_000
#: the most blocks of rows in the slabs the first block's rows leave
LEFTOVER_BLOCKS = 6
#: the sites ahead among which a type takes the one furthest from its others, and the
#: most sites spread so
SPREAD_WINDOW = 16
SPREAD_SITES = 20_000
#: types of unlike length along one box axis stand in rows whose sites are each as long as
#: their type (`_Mixed`) where that takes at most this share of the room the largest box
#: along each axis takes
MIXED = 0.95
#: points on a ring of a round type's cylinder for the wall test
_RING = 24
#: sample points per box side for the wall test, at most
_SIDE_SAMPLES = 5


@dataclass(frozen=True)
class Stack:
    """The objects of a stacked start: (N,) types, (N,3) positions and (N,4) rotations
    (w, x, y, z) of each type's local frame (container frame, container units), and
    (T,) each type's volume grown by its box's share of the clearance (what `stack_start`
    judges a stack by, over the container's volume)."""

    typ: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    room: np.ndarray


def _candidate_axes(mesh: trimesh.Trimesh) -> list[np.ndarray]:
    """Frames (3, 3, columns) a mesh's box may follow: the mesh frame's axes, its principal
    axes of inertia, and where two of its moments are equal (a square tile, a square box
    turned in its file) those turned about the third to the smallest box (`_swept`), where
    all three are (a cube), the minimal box's (trimesh's, of the hull)."""
    frames = [np.eye(3)]
    inertia = np.asarray(mesh.principal_inertia_vectors, np.float64).T
    moments = np.asarray(mesh.principal_inertia_components, np.float64)
    if not (np.all(np.isfinite(inertia)) and abs(abs(np.linalg.det(inertia)) - 1.0) < 1e-6):
        return frames
    frames.append(inertia)
    scale = max(float(np.abs(moments).max()), 1e-300)
    same = [abs(moments[i] - moments[j]) <= EQUAL_MOMENTS * scale
            for i, j in ((1, 2), (0, 2), (0, 1))]  # pair without axis k, for k = 0, 1, 2
    if all(same):
        to_box, _ = trimesh.bounds.oriented_bounds(mesh.convex_hull.vertices)
        frames.append(np.asarray(to_box, np.float64)[:3, :3].T.copy())
    elif any(same):
        frames.append(_swept(np.asarray(mesh.vertices, np.float64), inertia,
                             int(np.argmax(same))))
    return frames


def _swept(vertices: np.ndarray, inertia: np.ndarray, k: int) -> np.ndarray:
    """The inertia axes (3, 3, columns) turned about axis k to the smallest box: in steps
    of SWEEP_DEGREES, then of a hundredth of that about the best."""
    u, w = inertia[:, (k + 1) % 3], inertia[:, (k + 2) % 3]
    across = np.stack([vertices @ u, vertices @ w], axis=1)

    def area(angles: np.ndarray) -> np.ndarray:
        c, s = np.cos(angles), np.sin(angles)
        x = across[:, :1] * c + across[:, 1:] * s
        y = -across[:, :1] * s + across[:, 1:] * c
        return np.ptp(x, axis=0) * np.ptp(y, axis=0)

    step = np.radians(SWEEP_DEGREES)
    coarse = np.arange(0.0, 0.5 * np.pi, step)
    best = coarse[int(np.argmin(area(coarse)))]
    fine = best + np.linspace(-step, step, 201)
    angle = fine[int(np.argmin(area(fine)))]
    turned = inertia.copy()
    turned[:, (k + 1) % 3] = np.cos(angle) * u + np.sin(angle) * w
    turned[:, (k + 2) % 3] = -np.sin(angle) * u + np.cos(angle) * w
    return turned


def _smallest_box(vertices: np.ndarray, frames: list[np.ndarray]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of the boxes along `frames`, the smallest (the earliest of equal ones): its axes,
    low and high corners in them."""
    best = None
    for axes in frames:
        proj = vertices @ axes
        lo, hi = proj.min(axis=0), proj.max(axis=0)
        size = float(np.prod(hi - lo))
        if best is None or size < best[0] * (1.0 - 1e-9):
            best = (size, axes, lo, hi)
    return best[1], best[2], best[3]


def box_frame(vertices: np.ndarray, faces: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mesh's box: axes (3, 3, columns, longest first, right-handed), half extents (3,)
    and centre (3,), all in its own frame: the smallest along the frames of
    `_candidate_axes`. A plate or a rod drawn at any angle is measured along its own
    sides; linear in the mesh's size but for a mesh whose three moments of inertia are
    equal (a cube, a ball)."""
    v = np.asarray(vertices, np.float64)
    mesh = trimesh.Trimesh(v, np.asarray(faces, np.int64), process=False)
    axes, lo, hi = _smallest_box(v, _candidate_axes(mesh))
    half = 0.5 * (hi - lo)
    centre = axes @ (0.5 * (lo + hi))
    order = np.argsort(-half, kind="stable")
    axes, half = axes[:, order].copy(), half[order]
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1.0
    return axes, half, centre


def _container_frames(container: Container) -> list[np.ndarray]:
    """The frames a stack's rows may follow: the container frame's axes, and those of the
    container's smallest box of `_candidate_axes` (a box drawn at an angle)."""
    mesh = trimesh.Trimesh(container.vertices, container.faces, process=False)
    axes, _, _ = _smallest_box(container.vertices, _candidate_axes(mesh))
    same = np.abs(np.abs(axes).max(axis=0) - 1.0).max() <= 1e-6
    return [np.eye(3)] if same else [np.eye(3), axes]


def _offsets(lo: float, hi: float, cell: float, low: float, high: float, few: bool
             ) -> list[float]:
    """A row's first site, for each offset tried along one axis from lo to hi, its sites
    at least `low` from lo and `high` from hi: flush with the low end, with the high one,
    centred, and centred half a cell over (`few`: the first two)."""
    first = lo + low
    last = hi - high
    centred = 0.5 * (lo + hi)
    choices = [first, first + (last - first) % cell]
    if not few:
        choices += [first + (centred - first) % cell,
                    first + (centred + 0.5 * cell - first) % cell]
    return choices


def _box_samples(half: np.ndarray, spacing: float) -> np.ndarray:
    """(S, 3) points on and in a box of half extents `half` (its own frame, centred): a
    grid of at most _SIDE_SAMPLES per side, about `spacing` apart."""
    axes = [np.linspace(-h, h, int(np.clip(np.ceil(2 * h / spacing) + 1, 2, _SIDE_SAMPLES)))
            for h in half]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _cylinder_samples(radius: float, half: np.ndarray, axis: int, spacing: float
                      ) -> np.ndarray:
    """(S, 3) points on a cylinder of `radius` about frame axis `axis` through the origin,
    as long as the box of half extents `half` along it: rings of _RING points at up to
    _SIDE_SAMPLES heights about `spacing` apart, and the axis's two ends."""
    across = [j for j in range(3) if j != axis]
    h = float(half[axis])
    heights = np.linspace(-h, h, int(np.clip(np.ceil(2 * h / spacing) + 1, 2, _SIDE_SAMPLES)))
    angles = np.arange(_RING) * (2.0 * np.pi / _RING)
    ring = radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    out = np.zeros((len(heights) * _RING + 2, 3))
    out[: len(heights) * _RING, across[0]] = np.tile(ring[:, 0], len(heights))
    out[: len(heights) * _RING, across[1]] = np.tile(ring[:, 1], len(heights))
    out[: len(heights) * _RING, axis] = np.repeat(heights, _RING)
    out[-2:, axis] = (-h, h)
    return out


def _inside(container: Container, sites: np.ndarray, turn: np.ndarray,
            samples: np.ndarray, depth: float) -> np.ndarray:
    """(M,) whether the box sampled by `samples` (its frame), turned by `turn` (3, 3) and
    centred at each of `sites` (M, 3), lies at least `depth` inside the container."""
    reach = float(np.linalg.norm(samples, axis=1).max())
    centre = container.depth(sites)
    # a site deeper than its box's reach (and a cell) holds it; only the rest are sampled
    ok = centre >= depth + reach + container.grid.spacing
    near = np.flatnonzero(~ok & (centre >= depth))
    if len(near):
        pts = (sites[near, None, :] + (samples @ turn.T)[None]).reshape(-1, 3)
        d = container.depth(pts).reshape(len(near), -1)
        ok[near] = d.min(axis=1) >= depth
    return ok


def round_about(vertices: np.ndarray, axes: np.ndarray, half: np.ndarray,
                centre: np.ndarray) -> tuple[int, float] | None:
    """The box axis (0-2, of `box_frame`'s) a mesh is round about, and the radius of the
    cylinder about it through the box's centre that holds its vertices (local frame): a
    coin, a can or a rod of round section. None where that cylinder is wider than
    ROUND of the box's sides across it (a box's is 41% wider)."""
    proj = (np.asarray(vertices, np.float64) - centre) @ axes
    for k in range(3):
        across = [i for i in range(3) if i != k]
        radius = float(np.linalg.norm(proj[:, across], axis=1).max())
        if radius <= ROUND * float(half[across].min()):
            return k, radius
    return None


def _staggered(first: np.ndarray, end: np.ndarray, step: np.ndarray,
               layout: tuple[int, int, int]) -> np.ndarray:
    """(M, 3) sites from `first` up to `end` (frame coordinates), `step` apart along each
    axis: the rows along layout[1], step apart along layout[0], those whose index is odd
    (layout[2] 1) or even (0) shifted half a step (disks of diameter step[layout[1]] in
    rows step * sqrt(3) / 2 apart each touch six)."""
    a, b, shifted = layout
    c = 3 - a - b
    cols = [(x, y) for i, x in enumerate(np.arange(first[a], end[a], step[a]))
            for y in np.arange(first[b] + (0.5 * step[b] if i % 2 == shifted else 0.0),
                               end[b], step[b])]
    zs = np.arange(first[c], end[c], step[c])
    if not cols or len(zs) == 0:
        return np.zeros((0, 3))
    xy = np.repeat(np.array(cols), len(zs), axis=0)
    out = np.empty((len(xy), 3))
    out[:, a], out[:, b] = xy[:, 0], xy[:, 1]
    out[:, c] = np.tile(zs, len(cols))
    return out


@dataclass(frozen=True)
class _Rows:
    """One block of rows: its sites (M, 3, in the frame's coordinates), which box axis
    each frame axis holds, and the block's bounds (2, 3) around the sites' boxes; in rows
    of types of unlike length (`_Mixed`) also each site's type (M,) and how they were
    laid."""

    sites: np.ndarray
    perm: tuple[int, int, int]
    bounds: np.ndarray
    typ: np.ndarray | None = None
    # (geometry, lines, rows, share, spans) the typed rows were laid by
    # (`_RowGeometry.laid`)
    laid: tuple | None = None


@dataclass
class _Mixed:
    """Rows along box axis `axis` whose sites are each as long as their type there: each
    row's types in turn the one the mix needs (of those the row still has room for),
    none that would take the mix's TVD beyond max_tvd (`metrics.mix_cap`: a slab beside
    the rows may fit one type only). live (L,): the type of each of the search's boxes;
    shares (T,); by_volume: the live types, largest first; counts (T,): the objects of
    the blocks taken so far."""

    axis: int
    live: np.ndarray
    shares: np.ndarray
    by_volume: np.ndarray
    counts: np.ndarray
    max_tvd: float

    def __post_init__(self) -> None:
        self.at = {int(t): i for i, t in enumerate(self.live)}  # type -> index into live
        self.one_more = np.eye(len(self.shares))  # row t: one object of type t

    def row(self, room: float, length: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """(K,) indices into `live` of a row's types, whose lengths (L,) sum to at most
        `room`; adds them to `counts` (T,)."""
        at = self.at
        out: list[int] = []
        used = 0.0
        while True:
            fits = [t for t in self.by_volume if used + length[at[int(t)]] <= room]
            if not fits:
                break
            t = type_needed(counts, self.shares, fits, within=True)
            if counts[t] >= self.shares[t] * max(float(counts.sum()), 1.0):  # not needed
                after = tvd_of_counts(counts + self.one_more[t], self.shares)
                if (after > self.max_tvd
                        and after > mix_cap(counts, self.shares, self.max_tvd)):
                    break
            counts[t] += 1
            used += length[at[t]]
            out.append(at[t])
        return np.array(out, np.int64)


def _row_axis(halves: np.ndarray, q: np.ndarray, gap: float) -> int | None:
    """The box axis along which sites as long as their types (`_Mixed`) save the most room
    against sites as large as the largest box along every axis, where they take at most
    MIXED of it; None elsewhere (types of one size). halves (L, 3), q (L,) their shares."""
    cells = 2.0 * halves + gap
    top = cells.max(axis=0)
    best: tuple[float, int] | None = None
    for k in range(3):
        v = float(np.prod(np.delete(top, k))) * float(q @ cells[:, k])
        if v <= MIXED * float(np.prod(top)) and (best is None or v < best[0]):
            best = (v, k)
    return None if best is None else best[1]


class _RowGeometry:
    """Rows of types of unlike length (`_Mixed`) within lo..hi (frame coordinates), with
    frame axis j holding box axis perm[j]: where their sites lie, and which lie inside."""

    def __init__(self, search: _Search, lo: np.ndarray, hi: np.ndarray,
                 perm: tuple[int, int, int]):
        self.search = search
        self.perm = perm
        self.half = search.halves[:, perm]  # (L, 3) each type's half extents, frame axes
        top = self.half.max(axis=0)
        self.jr = perm.index(search.mixed.axis)
        self.cross = [j for j in range(3) if j != self.jr]
        self.cell = 2.0 * top + search.gap + search.slack
        self.low = np.where(lo <= search.lo, search.wall + search.hair, 0.0) + top
        self.high = np.where(hi >= search.hi, search.wall + search.hair, 0.0) + top
        self.end = hi - self.high + 1e-9 * self.cell
        self.length = 2.0 * self.half[:, self.jr] + search.gap + search.slack
        # a row's boxes from edge to edge, less the gap after its last
        self.edge = lo[self.jr] + self.low[self.jr] - top[self.jr]
        self.room = (hi[self.jr] - self.high[self.jr] + top[self.jr] - self.edge
                     + search.gap + search.slack)
        self.samples = [_box_samples(h, search.c.grid.spacing) for h in self.half]

    def sites(self, lines: np.ndarray, rows: list[np.ndarray], share: float,
              spans: tuple[np.ndarray, np.ndarray] | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """(M, 3) the sites of `rows` (indices into live, one row per line (K, 2) across
        the rows) and (M,) their types' indices: each row `share` of its room's slack from
        its low edge; spans: each line's own (K,) low edge and room, where not the
        block's."""
        kinds = np.concatenate(rows) if rows else np.zeros(0, np.int64)
        local = np.empty((len(kinds), 3))
        if len(kinds) == 0:
            return local, kinds
        edge, room = spans if spans is not None else (np.full(len(rows), self.edge),
                                                      np.full(len(rows), self.room))
        line_of = np.repeat(np.arange(len(rows)), [len(r) for r in rows])
        used = np.array([self.length[r].sum() for r in rows])
        before = np.concatenate([np.cumsum(self.length[r]) - self.length[r] for r in rows])
        local[:, self.cross] = lines[line_of]
        local[:, self.jr] = ((edge + share * (room - used))[line_of] + before
                             + self.half[kinds, self.jr])
        return local, kinds

    def fits(self, local: np.ndarray, kinds: np.ndarray, taken: list[_Rows]) -> np.ndarray:
        """(M,) whether each site's box lies inside the container and apart from the
        `taken` blocks."""
        s = self.search
        ok = np.zeros(len(kinds), bool)
        for i in range(len(self.half)):
            here = kinds == i
            if here.any():
                ok[here] = _inside(s.c, local[here] @ s.frame.T, s.frame, self.samples[i],
                                   s.wall)
        h = self.half[kinds]
        for block in taken:
            apart = ((local + h + s.gap <= block.bounds[0] + s.slack)
                     | (local - h - s.gap >= block.bounds[1] - s.slack))
            ok &= apart.any(axis=1)
        return ok

    def block(self, lines: np.ndarray, rows: list[np.ndarray], share: float,
              taken: list[_Rows]) -> _Rows | None:
        """The block of the sites of `rows` that lie inside and apart from `taken`, each
        line then typed again by the mix (`_Mixed.row`) over the stretch its sites inside
        span, centred there: a row typed for the block's whole length loses its ends to a
        round wall, and with them the mix (a cone: TVD 0.25)."""
        local, kinds = self.sites(lines, rows, share)
        ok = self.fits(local, kinds, taken)
        line_of = np.repeat(np.arange(len(rows)), [len(r) for r in rows])
        r = local[:, self.jr]
        h = self.half[kinds, self.jr]
        keep, edge, room = [], [], []
        for i in np.unique(line_of[ok]):
            mine = ok & (line_of == i)
            keep.append(i)
            edge.append(float((r - h)[mine].min()))
            room.append(float((r + h)[mine].max()) - edge[-1] + self.search.gap
                        + self.search.slack)
        if not keep:
            return None
        counts = self.search.mixed.counts.copy()
        retyped = [self.search.mixed.row(w, self.length, counts) for w in room]
        return self.laid(lines[keep], retyped, 0.5, (np.array(edge), np.array(room)), taken)

    def laid(self, lines: np.ndarray, rows: list[np.ndarray], share: float,
             spans: tuple[np.ndarray, np.ndarray], taken: list[_Rows]) -> _Rows | None:
        """The block of the sites of `rows` laid in `spans` (`sites`) that lie inside and
        apart from `taken`."""
        local, kinds = self.sites(lines, rows, share, spans)
        return self._block(local, kinds, self.fits(local, kinds, taken),
                           (self, lines, rows, share, spans))

    def _block(self, local: np.ndarray, kinds: np.ndarray, ok: np.ndarray, laid: tuple
               ) -> _Rows | None:
        """The block of the sites `local` (M, 3) of types `kinds` (M,) that are `ok`."""
        if not ok.any():
            return None
        h = self.half[kinds[ok]]
        bounds = np.stack([(local[ok] - h).min(axis=0), (local[ok] + h).max(axis=0)])
        return _Rows(local[ok], self.perm, bounds, self.search.mixed.live[kinds[ok]], laid)

    def spread(self, block: _Rows, taken: list[_Rows], n_types: int) -> _Rows | None:
        """`block` laid again with each row turned by the number of places (of its first
        SPREAD_WINDOW) whose sites lie furthest, summed, from the sites of their own type
        in the rows before and the `taken` blocks: rows typed in turn by the mix repeat
        one pattern, which would line a type up across rows. A row whose turn leaves
        fewer of its sites inside stays as it was; a block of more than SPREAD_SITES, as
        it is."""
        _, lines, rows, share, spans = block.laid
        if len(block.sites) > SPREAD_SITES:  # as `_mix`: the mix's own turns alone
            return block
        live = self.search.mixed.live
        spread = TypeSpread(n_types)
        for b in taken:
            for t in np.unique(b.typ):
                spread.add_many(int(t), b.sites[b.typ == t])
        out = []
        for i, (line, row) in enumerate(zip(lines, rows, strict=True)):
            if self.search.stop():
                return None
            one = (spans[0][i: i + 1], spans[1][i: i + 1])
            best, score = row, -np.inf
            for k in range(min(len(row), SPREAD_WINDOW)):
                turned = np.roll(row, k)
                local, _ = self.sites(line[None], [turned], share, one)
                d = sum(float(np.minimum(spread.nearest(int(live[j]), local[turned == j]),
                                         1e9).sum()) for j in np.unique(turned))
                if d > score:
                    best, score = turned, d
            local, _ = self.sites(line[None], [best], share, one)
            for j in np.unique(best):
                spread.add_many(int(live[j]), local[best == j])
            out.append(best)
        # a turn keeps each row's types, so the sites of both lie in the same order of lines
        line_of = np.repeat(np.arange(len(rows)), [len(r) for r in rows])
        was, was_kinds = self.sites(lines, rows, share, spans)
        now, now_kinds = self.sites(lines, out, share, spans)
        was_ok, now_ok = self.fits(was, was_kinds, taken), self.fits(now, now_kinds, taken)
        take = (np.bincount(line_of, now_ok, len(rows))
                >= np.bincount(line_of, was_ok, len(rows)))  # (K,) per line
        out = [o if t else r for o, r, t in zip(out, rows, take, strict=True)]
        turn = take[line_of]
        return self._block(np.where(turn[:, None], now, was),
                           np.where(turn, now_kinds, was_kinds),
                           np.where(turn, now_ok, was_ok), (self, lines, out, share, spans))


class _Search:
    """The rows of one frame: the container's bounds in it, the types' boxes, the gaps."""

    def __init__(self, container: Container, frame: np.ndarray, halves: np.ndarray,
                 gap: float, wall: float, round_about: tuple[int, float] | None,
                 stop: Callable[[], bool], mixed: _Mixed | None = None):
        self.c = container
        self.stop = stop
        self.mixed = mixed
        # (box axis, radius): every type lies within a cylinder of that radius about it
        self.round = round_about
        self.frame = frame
        proj = container.vertices @ frame
        self.lo, self.hi = proj.min(axis=0), proj.max(axis=0)
        self.halves = halves
        self.gap = gap
        self.wall = wall
        self.slack = 1e-9 * float(halves.max())
        self.hair = 1e-6 * container.grid.spacing

    def rows(self, lo: np.ndarray, hi: np.ndarray, taken: list[_Rows], perms, few: bool,
             ) -> _Rows | None:
        """The block of rows with the most sites inside the container, within the bounds
        lo..hi (frame coordinates) and apart from the `taken` blocks, over `perms`; where
        the types are round about one box axis (`self.round`), also with the rows across
        it staggered (each column's neighbours at the disks' diameter); for types of unlike
        length, rows of sites each as long as its type (`typed_rows`)."""
        if self.mixed is not None:
            return self.typed_rows(lo, hi, taken, perms, few)
        best = None
        for perm in perms:
            half = self.halves[:, perm].max(axis=0)  # frame axis j holds box axis perm[j]
            cell = 2.0 * half + self.gap + self.slack
            # from the container's sides the wall's distance, from a block's the gap
            # already left
            # (and a hair: a box flush with a wall samples its depth to the last bit)
            low = np.where(lo <= self.lo, self.wall + self.hair, 0.0) + half
            high = np.where(hi >= self.hi, self.wall + self.hair, 0.0) + half
            samples = _box_samples(half, self.c.grid.spacing)
            if self.round is not None:  # the cylinder that holds them, not the box
                samples = _cylinder_samples(self.round[1], half, perm.index(self.round[0]),
                                            self.c.grid.spacing)
            layouts: list[tuple[tuple[int, int, int] | None, np.ndarray]] = [(None, cell)]
            if self.round is not None:
                plane = [j for j in range(3) if perm[j] != self.round[0]]
                spacing = 2.0 * self.round[1] + self.gap + self.slack
                for (a, b), shifted in product((plane, plane[::-1]), (1, 0)):
                    step = cell.copy()
                    step[a], step[b] = spacing * np.sqrt(3.0) / 2.0, spacing
                    layouts.append(((a, b, shifted), step))
            end = hi - high + 1e-9 * cell
            for layout, step in layouts:
                rows = [_offsets(lo[j], hi[j], step[j], low[j], high[j], few)
                        for j in range(3)]
                for first in product(*rows):
                    if self.stop():
                        return None
                    if layout is None:
                        axes = [np.arange(f, end[j], cell[j]) for j, f in enumerate(first)]
                        if any(len(a) == 0 for a in axes):
                            continue
                        local = np.stack(np.meshgrid(*axes, indexing="ij"),
                                         axis=-1).reshape(-1, 3)
                    else:
                        local = _staggered(np.array(first), end, step, layout)
                        if len(local) == 0:
                            continue
                    ok = _inside(self.c, local @ self.frame.T, self.frame, samples,
                                 self.wall)
                    for block in taken:  # boxes along the same axes: apart along one
                        apart = ((local + half + self.gap <= block.bounds[0] + self.slack)
                                 | (local - half - self.gap >= block.bounds[1] - self.slack))
                        ok &= apart.any(axis=1)
                    if best is None or ok.sum() > len(best.sites):
                        sites = local[ok]
                        if len(sites) == 0:
                            continue
                        bounds = np.stack([sites.min(axis=0) - half,
                                           sites.max(axis=0) + half])
                        best = _Rows(sites, perm, bounds)
        return best

    def typed_rows(self, lo: np.ndarray, hi: np.ndarray, taken: list[_Rows], perms,
                   few: bool) -> _Rows | None:
        """As `rows`, for types of unlike length along box axis `self.mixed.axis`: each row
        along it is filled by `_Mixed.row`, flush with its low end, its high one or
        centred (`few`: the first two); across it the rows are as far apart as the largest
        box (each type centred there). The block's rows are turned apart
        (`_RowGeometry.spread`) once it is chosen."""
        mix = self.mixed
        best, most = None, 0
        for perm in perms:
            geo = _RowGeometry(self, lo, hi, perm)
            layouts = [np.stack(np.meshgrid(
                *[np.arange(f, geo.end[j], geo.cell[j]) for f, j in zip(first, geo.cross,
                                                                     strict=True)],
                indexing="ij"), axis=-1).reshape(-1, 2)
                for first in product(*[_offsets(lo[j], hi[j], geo.cell[j], geo.low[j],
                                                geo.high[j], few) for j in geo.cross])]
            # the layouts are judged with one row typed for the block's length on every
            # line; the chosen one's lines are typed each over its own stretch (`block`)
            template = mix.row(geo.room, geo.length, mix.counts.copy())
            for lines in layouts:
                if self.stop():
                    return None
                rows = [template] * len(lines)
                for share in (0.0, 1.0, 0.5)[: 2 if few else 3]:
                    local, kinds = geo.sites(lines, rows, share)
                    ok = geo.fits(local, kinds, taken)
                    if ok.sum() > most:
                        best, most = (geo, lines, rows, share), int(ok.sum())
        if best is None:
            return None
        geo, lines, rows, share = best
        return geo.block(lines, rows, share, taken)

    def leftovers(self, taken: list[_Rows]) -> _Rows | None:
        """The block of rows with the most sites in a slab the taken blocks leave between
        the last one and the container's side, along each axis and on either side."""
        block = taken[-1].bounds
        best = None
        for j in range(3):
            for side in (0, 1):
                lo, hi = self.lo.copy(), self.hi.copy()
                if side == 0:
                    hi[j] = block[0, j] - self.gap
                else:
                    lo[j] = block[1, j] + self.gap
                if hi[j] - lo[j] < 2.0 * self.halves.min():
                    continue
                got = self.rows(lo, hi, taken, list(permutations(range(3))), few=True)
                if got is not None and (best is None or len(got.sites) > len(best.sites)):
                    best = got
        return best


def stack_start(container: Container, types: Sequence, volumes: np.ndarray,
                shares: np.ndarray, margin: np.ndarray, clearance: float,
                wall_margin: float, rng: np.random.Generator,
                stop: Callable[[], bool] = lambda: False, *,
                max_tvd: float = CavityPassOptions().max_tvd) -> Stack | None:
    """The densest stack of the types' boxes in rows along the container's axes, or None
    where it holds less than STACKED of the container's volume (each type's volume taken
    with its box grown by the clearance: 0.3 mm costs a 0.5 mm plate 40% of its room in
    any packing).

    types: each with .vertices and .faces (local frame); volumes (T,); shares (T,) target
    shares by count (types with share 0 are left out); margin (T,) contact margins,
    clearance and wall_margin (container units) as the solver keeps them. Every site takes
    the largest box of the types along each axis, the types' longest sides along the same
    axis; the sites are typed in random order (rng), each the type furthest below its share.
    Types of unlike length along one axis (bricks 20 and 10 mm long) instead stand in rows
    along it whose sites are each as long as their type, typed as they are laid (`_Mixed`;
    max_tvd: how far the mix may drift for a slab that fits one type only). The slabs the
    rows leave beside them (a 4 mm strip beside rows of 12 mm tiles) take rows of their
    own, turned as fits them best, up to LEFTOVER_BLOCKS of them.
    """
    live = np.flatnonzero(np.asarray(shares) > 0)
    if len(live) == 0:
        return None
    boxes = {int(t): box_frame(types[t].vertices, types[t].faces) for t in live}
    halves = np.array([boxes[int(t)][1] for t in live])
    if halves.min() <= 0:
        return None
    m = float(np.max(margin[live]))
    gap = clearance + 2.0 * m
    wall = clearance + wall_margin + m
    grown = np.prod(2.0 * halves + clearance, axis=1) / np.prod(2.0 * halves, axis=1)
    q = shares[live] / np.sum(shares[live])
    mean_volume = float(np.sum(q * volumes[live] * grown))
    rounds = [round_about(types[t].vertices, *boxes[int(t)]) for t in live]
    roundness = None  # coins or cans stand staggered where all are round about one axis
    if all(r is not None for r in rounds) and len({r[0] for r in rounds}) == 1:
        roundness = (rounds[0][0], max(r[1] for r in rounds))
    # round and irregular types (by the mix, each in its own box): a random packing fills
    # more. Sites larger than a type (the largest one's) count against STACKED instead
    if mean_volume < BOXY * float(q @ np.prod(2.0 * halves + clearance, axis=1)):
        return None
    shares = np.asarray(shares, np.float64)
    mixed = None  # types of unlike length along one box axis: rows of sites each as long
    axis = _row_axis(halves, q, gap) if roundness is None else None
    if axis is not None:
        by_volume = live[np.argsort(-volumes[live], kind="stable")]
        mixed = _Mixed(axis, live, shares, by_volume, np.zeros(len(shares)), max_tvd)
    best: tuple[_Search, _Rows] | None = None
    for frame in _container_frames(container):
        search = _Search(container, frame, halves, gap, wall, roundness, stop, mixed)
        for perm in permutations(range(3)):
            half = halves[:, perm].max(axis=0)
            cell = 2.0 * half + gap
            if mixed is not None:  # along the rows each type's own length, by the mix
                cell[perm.index(mixed.axis)] = float(
                    q @ (2.0 * halves[:, mixed.axis] + gap))
            n = np.floor((search.hi - search.lo - 2.0 * (wall + half)) / cell + 1e-9) + 1
            if np.any(n < 1) or float(np.prod(n)) * mean_volume < STACKED * container.volume:
                continue  # not even the container's box holds enough
            got = search.rows(search.lo, search.hi, [], [perm], few=float(np.prod(n)) > MANY_SITES)
            if got is not None and (best is None or len(got.sites) > len(best[1].sites)):
                best = (search, got)
    if (stop() or best is None
            or len(best[1].sites) * mean_volume < STACKED * container.volume):
        return None
    search, first = best
    blocks: list[_Rows] = []
    for _ in range(LEFTOVER_BLOCKS + 1):
        more = first if not blocks else search.leftovers(blocks)
        if more is not None and more.laid is not None:  # typed rows: turned apart
            more = more.laid[0].spread(more, blocks, len(shares))
        if stop():
            return None
        if more is None:
            break
        blocks.append(more)
        if mixed is not None:
            mixed.counts = np.bincount(np.concatenate([b.typ for b in blocks]),
                                       minlength=len(shares)).astype(np.float64)
    if not blocks:  # the first block's rows, turned apart, left no site inside
        return None
    frame = search.frame
    sites = np.concatenate([b.sites for b in blocks]) @ frame.T
    block_of = np.concatenate([np.full(len(b.sites), i) for i, b in enumerate(blocks)])
    if mixed is not None:  # typed as their rows were laid
        typ = np.concatenate([b.typ for b in blocks])
    else:
        order = rng.permutation(len(sites))
        typ, sites, block_of = _mix(sites[order], block_of[order], live, shares, volumes)
    pos = np.empty_like(sites)
    quat = np.empty((len(sites), 4))
    for i, block in enumerate(blocks):
        swap = np.zeros((3, 3))
        swap[np.arange(3), block.perm] = 1.0  # frame axis j <- box axis perm[j]
        for t in live:
            axes, _, centre = boxes[int(t)]
            turn = frame @ swap @ axes.T
            if np.linalg.det(turn) < 0:  # a box is the same with one axis reversed
                turn = frame @ swap @ np.diag([1.0, 1.0, -1.0]) @ axes.T
            here = (typ == t) & (block_of == i)
            pos[here] = sites[here] - turn @ centre
            quat[here] = matrix_to_quat(turn[None])[0]
    room = np.zeros(len(volumes))
    room[live] = volumes[live] * grown
    return Stack(typ, pos, quat, room)


def _mix(sites: np.ndarray, block_of: np.ndarray, live: np.ndarray, shares: np.ndarray,
         volumes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Types for the sites (M, 3, in random order) and the sites and their blocks (M,)
    reordered to match: each in turn the type the mix needs (`type_spread.type_needed`,
    as in phase 1), at the one of the next few sites furthest from that type's
    (`type_spread`), so that no type clumps in the rows."""
    n = len(sites)
    sites, block_of = sites.copy(), block_of.copy()
    typ = np.full(n, int(live[0]), np.int64)
    if len(live) == 1:
        return typ, sites, block_of
    # beyond SPREAD_SITES the random order alone spreads them (a k-d tree query a site
    # took a minute for 137,000)
    window = max(1, min(SPREAD_WINDOW, n // 8)) if n <= SPREAD_SITES else 1
    counts = np.zeros(len(shares))
    by_volume = live[np.argsort(-volumes[live], kind="stable")]
    spread = TypeSpread(len(shares))
    for i in range(n):
        t = type_needed(counts, shares, by_volume)
        if window > 1:
            far = i + int(np.argmax(spread.nearest(t, sites[i: i + window])))
            sites[[i, far]] = sites[[far, i]]
            block_of[[i, far]] = block_of[[far, i]]
            spread.add(t, sites[i])
        typ[i] = t
        counts[t] += 1
    return typ, sites, block_of
