"""A stacked start: boxy types in rows along the container's axes, at full size.

Plates, tiles, bricks and coins fill a box almost solid when stacked, and about a quarter
when grown from random rotations, which the penalty pushes never turn into stacks
(docs/notes-core.md). Where a lattice of the types' boxes, turned onto the container's
axes, holds at least STACKED of the container (by the types' volumes, each grown by its
box's share of the clearance, which costs a stack and a random packing alike), the first attempt
starts from that lattice at full size instead of phase 1's grown one; the cavity passes
then fill what the rows leave. Round and irregular types (fruit, dice of many faces) never
reach STACKED this way (a ball fills 52% of its box), so their packings are unchanged.

Frames: a type's local frame; the container frame, container units.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import permutations, product

import numpy as np
import trimesh

from .container import Container
from .kernels import sample_grid_many
from .rotations import matrix_to_quat
from .type_spread import TypeSpread

#: the least share of the container's volume the stacked objects must hold for the first
#: attempt to start from them: above what a random packing of such types reaches
STACKED = 0.6
#: the most lattice sites (of one choice of axes and offsets) the search tests at once;
#: beyond it only two offsets per axis are tried
MANY_SITES = 20_000
#: the sites ahead among which a type takes the one furthest from its others
SPREAD_WINDOW = 16
#: sample points per box side for the wall test, at most
_SIDE_SAMPLES = 5


@dataclass(frozen=True)
class Stack:
    """The objects of a stacked start: (N,) types, (N,3) positions and (N,4) rotations
    (w, x, y, z) of each type's local frame (container frame, container units), and the
    share of the container's volume they hold."""

    typ: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    density: float


def box_frame(vertices: np.ndarray, faces: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mesh's box: axes (3, 3, columns, longest first, right-handed), half extents (3,)
    and centre (3,), all in its own frame. Of the box along the frame's axes and the one
    along the principal axes of inertia, the smaller: a plate or a rod drawn at any
    angle is measured along its own sides, a cube along the file's (its inertia has no
    axes of its own). Linear in the mesh's size, unlike a minimal box."""
    v = np.asarray(vertices, np.float64)
    frames = [np.eye(3)]
    mesh = trimesh.Trimesh(v, np.asarray(faces, np.int64), process=False)
    inertia = np.asarray(mesh.principal_inertia_vectors, np.float64).T
    if np.all(np.isfinite(inertia)) and abs(abs(np.linalg.det(inertia)) - 1.0) < 1e-6:
        frames.append(inertia)
    best = None
    for axes in frames:
        proj = v @ axes
        lo, hi = proj.min(axis=0), proj.max(axis=0)
        size = float(np.prod(hi - lo))
        if best is None or size < best[0] * (1.0 - 1e-9):
            best = (size, axes, lo, hi)
    _, axes, lo, hi = best
    half = 0.5 * (hi - lo)
    centre = axes @ (0.5 * (lo + hi))
    order = np.argsort(-half, kind="stable")
    axes, half = axes[:, order].copy(), half[order]
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1.0
    return axes, half, centre


def _container_frames(container: Container) -> list[np.ndarray]:
    """The frames a stack's rows may follow: the container frame's axes, and its
    principal axes of inertia (a box drawn at an angle)."""
    frames = [np.eye(3)]
    mesh = trimesh.Trimesh(container.vertices, container.faces, process=False)
    inertia = np.asarray(mesh.principal_inertia_vectors, np.float64).T
    if np.all(np.isfinite(inertia)) and abs(abs(np.linalg.det(inertia)) - 1.0) < 1e-6:
        if np.abs(np.abs(inertia).max(axis=0) - 1.0).max() > 1e-6:  # not the same axes
            frames.append(inertia)
    return frames


def _offsets(lo: float, hi: float, cell: float, edge: float, few: bool) -> list[float]:
    """A row's first site, for each offset tried along one axis: flush with the low wall,
    with the high one, centred, and centred half a cell over (`few`: the first two)."""
    first = lo + edge
    high = hi - edge
    centred = 0.5 * (lo + hi)
    choices = [first, first + (high - first) % cell]
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


def _inside(container: Container, sites: np.ndarray, turn: np.ndarray,
            samples: np.ndarray, depth: float) -> np.ndarray:
    """(M,) whether the box sampled by `samples` (its frame), turned by `turn` (3, 3) and
    centred at each of `sites` (M, 3), lies at least `depth` inside the container."""
    g = container.grid
    reach = float(np.linalg.norm(samples, axis=1).max())
    centre = sample_grid_many(g.values, g.origin, g.spacing, sites)
    # a site deeper than its box's reach (and a cell) holds it; only the rest are sampled
    ok = centre >= depth + reach + g.spacing
    near = np.flatnonzero(~ok & (centre >= depth))
    if len(near):
        pts = (sites[near, None, :] + (samples @ turn.T)[None]).reshape(-1, 3)
        d = sample_grid_many(g.values, g.origin, g.spacing, pts).reshape(len(near), -1)
        ok[near] = d.min(axis=1) >= depth
    return ok


def stack_start(container: Container, types: Sequence, volumes: np.ndarray,
                shares: np.ndarray, margin: np.ndarray, clearance: float,
                wall_margin: float, rng: np.random.Generator) -> Stack | None:
    """The densest stack of the types' boxes in rows along the container's axes, or None
    where it holds less than STACKED of the container's volume (each type's volume taken
    with its box grown by the clearance: 0.3 mm costs a 0.5 mm plate 40% of its room in
    any packing).

    types: each with .vertices and .faces (local frame); volumes (T,); shares (T,) target
    shares by count (types with share 0 are left out); margin (T,) contact margins,
    clearance and wall_margin (container units) as the solver keeps them. Every site takes
    the largest box of the types along each axis, the types' longest sides along the same
    axis; the sites are typed in random order (rng), each the type furthest below its share.
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
    slack = 1e-9 * float(halves.max())
    best = None  # (count, frame, perm, sites)
    for frame in _container_frames(container):
        proj = container.vertices @ frame
        lo, hi = proj.min(axis=0), proj.max(axis=0)
        for perm in permutations(range(3)):
            half = halves[:, perm].max(axis=0)  # frame axis j holds box axis perm[j]
            cell = 2.0 * half + gap + slack
            if mean_volume < STACKED * float(np.prod(2.0 * half + clearance)):
                continue  # no stack of these boxes fills STACKED (a ball fills 52%)
            edge = wall + half
            n = np.floor((hi - lo - 2.0 * edge) / cell + 1e-9).astype(np.int64) + 1
            if np.any(n < 1):
                continue
            if float(np.prod(n)) * mean_volume < STACKED * container.volume:
                continue  # not even the container's box holds enough
            few = float(np.prod(n)) > MANY_SITES
            rows = [_offsets(lo[j], hi[j], cell[j], edge[j], few) for j in range(3)]
            samples = _box_samples(half, container.grid.spacing)
            for first in product(*rows):
                axes = [np.arange(f, hi[j] - edge[j] + 1e-9 * cell[j], cell[j])
                        for j, f in enumerate(first)]
                if any(len(a) == 0 for a in axes):
                    continue
                local = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
                sites = local @ frame.T
                ok = _inside(container, sites, frame, samples, wall)
                count = int(ok.sum())
                if best is None or count > best[0]:
                    best = (count, frame, perm, sites[ok])
    if best is None or best[0] * mean_volume < STACKED * container.volume:
        return None
    _, frame, perm, sites = best
    typ, sites = _mix(sites[rng.permutation(len(sites))], live,
                      np.asarray(shares, np.float64), volumes)
    swap = np.zeros((3, 3))
    swap[np.arange(3), perm] = 1.0  # frame axis j <- box axis perm[j]
    pos = np.empty_like(sites)
    quat = np.empty((len(sites), 4))
    for t in live:
        axes, _, centre = boxes[int(t)]
        turn = frame @ swap @ axes.T
        if np.linalg.det(turn) < 0:  # a box is the same with one axis reversed
            turn = frame @ swap @ np.diag([1.0, 1.0, -1.0]) @ axes.T
        here = typ == t
        pos[here] = sites[here] - turn @ centre
        quat[here] = matrix_to_quat(turn[None])[0]
    return Stack(typ, pos, quat, float(volumes[typ].sum() / container.volume))


def _mix(sites: np.ndarray, live: np.ndarray, shares: np.ndarray,
         volumes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Types for the sites (M, 3, in random order) and the sites reordered to match: each
    in turn the largest type below its share of those typed so far, or the one furthest
    below it (phase 1's rule), at the one of the next few sites furthest from that type's
    (`type_spread`), so that no type clumps in the rows."""
    n = len(sites)
    sites = sites.copy()
    typ = np.full(n, int(live[0]), np.int64)
    if len(live) == 1:
        return typ, sites
    counts = np.zeros(len(shares))
    by_volume = live[np.argsort(-volumes[live], kind="stable")]
    spread = TypeSpread(len(shares))
    window = max(1, min(SPREAD_WINDOW, n // 8))
    for i in range(n):
        g = max(counts.sum(), 1.0)
        below = [int(t) for t in by_volume if counts[t] < shares[t] * g]
        t = below[0] if below else int(live[np.argmin(counts[live] / shares[live])])
        ahead = sites[i: i + window]
        far = i + int(np.argmax(spread.nearest(t, ahead)))
        sites[[i, far]] = sites[[far, i]]
        typ[i] = t
        counts[t] += 1
        spread.add(t, sites[i])
    return typ, sites
