"""Overlap resolution over a growing set of objects: state arrays plus the numba solver.

`PackState` holds every object ever inserted (alive or removed) in flat arrays so the numba
kernels can read them directly; `TypeTable` flattens the object types. Frames and units:
container frame, container units.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numba
import numpy as np

from . import kernels
from .cellgrid import CellGrid, insert_range
from .container import Container
from .lie_flat import flat_types
from .objects import ObjectType, point_clusters
from .options import PhysicsOptions
from .threads import ThreadTuner

_PHYSICS = PhysicsOptions()


def _boxes(t: ObjectType) -> np.ndarray:
    """(12,) type t's vertex box (lo, hi) and the centre and half extents of the box
    around its vertices, inner spheres and surface points (local frame)."""
    r = t.sphere_radii[:, None]
    every = np.concatenate([t.vertices, t.sphere_centres - r, t.sphere_centres + r,
                            t.surface_points])
    lo, hi = every.min(axis=0), every.max(axis=0)
    return np.concatenate([t.vertices.min(axis=0), t.vertices.max(axis=0),
                           (lo + hi) / 2, (hi - lo) / 2])


class TypeTable:
    """Object types flattened into the arrays the kernels read (see kernels' module doc)."""

    def __init__(self, types: list[ObjectType]):
        self.types = types
        self.radius = np.array([t.radius for t in types], np.float64)
        self.volume = np.array([t.volume for t in types], np.float64)
        self.sph_off = np.cumsum([0] + [len(t.sphere_radii) for t in types]).astype(np.int64)
        self.sph_c = np.ascontiguousarray(np.concatenate([t.sphere_centres for t in types]))
        self.sph_r = np.ascontiguousarray(np.concatenate([t.sphere_radii for t in types]))
        # surface points grouped into clusters of nearby points, so that the contact kernels
        # can skip a cluster whose bounding ball is out of reach: pcl (C,4) ball centre and
        # radius (local frame), pcl_off (C+1) its points' range in pts, pc_off (T+1) each
        # type's range of clusters
        clusters = [point_clusters(t.surface_points) for t in types]
        self.pts = np.ascontiguousarray(np.concatenate(
            [t.surface_points[order] for t, (order, _, _) in zip(types, clusters, strict=True)]))
        self.pc_off = np.cumsum([0] + [len(b) for _, b, _ in clusters]).astype(np.int64)
        self.pcl = np.ascontiguousarray(np.concatenate([b for _, b, _ in clusters]))
        self.pcl_off = np.concatenate([[0], np.cumsum(np.concatenate(
            [n for _, _, n in clusters]))]).astype(np.int64)
        # (T,12) each type's bounding box (local frame): lo xyz, hi xyz; then the centre
        # and half extents of the box that holds everything the contact tests read
        self.box = np.array([_boxes(t) for t in types], np.float64).reshape(len(types), 12)
        self.g_off = np.cumsum([0] + [t.grid.values.size for t in types]).astype(np.int64)
        self.g_vals = np.ascontiguousarray(
            np.concatenate([t.grid.values.ravel() for t in types]), np.float64)
        self.g_shape = np.array([t.grid.values.shape for t in types], np.int64)
        self.g_origin = np.array([t.grid.origin for t in types], np.float64)
        self.g_h = np.array([t.grid.spacing for t in types], np.float64)

    def arrays(self) -> tuple:
        """The table as the kernels take it: (radius, sph_off, sph_c, sph_r, pc_off, pcl,
        pcl_off, box, pts, g_off, g_vals, g_shape, g_origin, g_h)."""
        return (self.radius, self.sph_off, self.sph_c, self.sph_r, self.pc_off, self.pcl,
                self.pcl_off, self.box, self.pts, self.g_off, self.g_vals, self.g_shape,
                self.g_origin, self.g_h)


@dataclass
class SolverParams:
    """Solver constants. Lengths in container units. The stiffness and damping defaults
    are the method's (`options.PhysicsOptions`)."""

    clearance: float = 0.0
    tol: float = 1e-6  # penetration ignored below this
    k_obj: float = _PHYSICS.k_obj  # step per iteration / deepest object-object penetration
    k_wall: float = _PHYSICS.k_wall  # step per iteration / deepest wall penetration
    k_rot: float = _PHYSICS.k_rot  # rotation per iteration, as arc length at bounding radius
    damping: float = _PHYSICS.damping  # velocity kept from one iteration to the next
    wall_margin: float = 0.0  # extra distance kept from the wall (container grid error)
    # contact tests in one solver iteration from which they run on numba's threads
    # (NUMBA_NUM_THREADS); below it the thread start-up costs more than it saves
    parallel_min: int = 4


class PackState:
    """Objects placed so far: type, position, rotation (w,x,y,z), scale, alive, margin."""

    def __init__(self, capacity: int = 256):
        self.n = 0
        self.typ = np.zeros(capacity, np.int64)
        self.pos = np.zeros((capacity, 3))
        self.quat = np.zeros((capacity, 4))
        self.quat[:, 0] = 1.0
        self.scale = np.ones(capacity)
        self.alive = np.zeros(capacity, np.uint8)
        self.margin = np.zeros(capacity)
        self.vel = np.zeros((capacity, 3))

    def _grow(self) -> None:
        cap = 2 * len(self.typ)
        for name in ("typ", "pos", "quat", "scale", "alive", "margin", "vel"):
            old = getattr(self, name)
            new = np.zeros((cap,) + old.shape[1:], old.dtype)
            new[: len(old)] = old
            setattr(self, name, new)

    def add(self, t: int, pos: np.ndarray, quat: np.ndarray, scale: float,
            margin: float) -> int:
        if self.n == len(self.typ):
            self._grow()
        k = self.n
        self.typ[k] = t
        self.pos[k] = pos
        self.quat[k] = quat
        self.scale[k] = scale
        self.alive[k] = 1
        self.margin[k] = margin
        self.vel[k] = 0.0
        self.n += 1
        return k

    def view(self):
        """Arrays trimmed to the objects inserted so far (views, not copies)."""
        n = self.n
        return (self.typ[:n], self.pos[:n], self.quat[:n], self.scale[:n], self.alive[:n],
                self.margin[:n], self.vel[:n])

    def alive_indices(self) -> np.ndarray:
        return np.flatnonzero(self.alive[: self.n])


class Solver:
    """Binds a container, the type table and the state to the numba kernels."""

    def __init__(self, container: Container, table: TypeTable, state: PackState,
                 params: SolverParams, tuner: ThreadTuner | None = None):
        self.c = container
        self.t = table
        self.s = state
        self.p = params
        # shared by the solvers of one packing; None: every thread numba was given
        self.tuner = tuner
        self.calls = 0
        self.iterations = 0
        # the contact tests a `resolve` call may run before it fails (0: no cap)
        self.max_tests = 0
        self._work = kernels.resolve_scratch(0)
        # broad phase: cell lists over the container's grid box (objects pushed past it
        # sit in the border cells)
        g = container.grid
        self.cells = CellGrid(g.origin, g.origin + g.spacing * (np.array(g.values.shape) - 1),
                              float(table.radius.max()) if len(table.radius) else 0.0,
                              params.clearance)
        # (T,) types that fit only lying down, inserted so (`lie_flat`), with (T,3,3) their
        # box axes and (T,3) half extents (identity and zeros for the other types)
        self.flat, self.flat_axes, self.flat_half = flat_types(table.types, table.radius, g)

    def resolve(self, focus: np.ndarray, max_iter: int, rollback: bool = True,
                settle_every: int = 0) -> bool:
        """Resolve overlaps around `focus` (object indices); False if still overlapping.
        settle_every > 0: give up early on a push that stops settling (`kernels.resolve`)."""
        p = self.p
        # numba's thread count is per calling thread: set it for this call only
        before = numba.get_num_threads()
        threads = before if self.tuner is None else self.tuner.threads
        if threads != before:
            numba.set_num_threads(threads)
        start = time.perf_counter()
        focus = np.asarray(focus, np.int64)
        try:
            ok, its, tests = kernels.resolve(
                focus, self.s.view(), self.t.arrays(),
                self.container_arrays(), self._scratch(), self.cells.sync(self.s, focus),
                (p.clearance, p.tol, p.k_obj, p.k_wall, p.k_rot, p.damping, p.wall_margin),
                int(max_iter), rollback, p.parallel_min, int(settle_every),
                int(self.max_tests))
        finally:
            if threads != before:
                numba.set_num_threads(before)
        if self.tuner is not None:
            self.tuner.record(tests, time.perf_counter() - start)
        self.calls += 1
        self.iterations += int(its)
        return bool(ok)

    def _scratch(self) -> tuple:
        """`resolve`'s working arrays (`kernels.resolve_scratch`) for every object the state
        can hold, kept between calls (resolve leaves them as it found them)."""
        cap = len(self.s.typ)
        if len(self._work[2]) < cap:
            self._work = kernels.resolve_scratch(cap)
        return self._work

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the kernels the phases call, on empty input,
        so that a time budget starts with them ready (compiling takes seconds on a fresh
        install)."""
        self.resolve(np.zeros(0, np.int64), 1, rollback=True)
        self.free_distances(np.zeros((1, 3)))
        # the cell lists link new objects from Python: compile that too (an empty range)
        insert_range(self.cells.sync(self.s, np.zeros(0, np.int64)), self.s.pos,
                     self.s.alive, 0, 0)

    def container_arrays(self) -> tuple:
        """The container's grid and its min pyramid, as the kernels take them:
        (values, origin, spacing, pyramid, pyramid offsets, pyramid shapes, crease planes)."""
        c = self.c.grid
        return (c.values, c.origin, c.spacing, *self.c.pyramid, self.c.creases.arrays())

    def penetrations(self) -> np.ndarray:
        """(n,2) deepest object and wall penetration of each inserted object (0 if removed)."""
        p = self.p
        return kernels.max_penetrations(self.s.view(), self.t.arrays(),
                                        self.container_arrays(),
                                        p.clearance, p.tol, p.wall_margin)

    def wall_penetrations(self) -> np.ndarray:
        """(n,) deepest wall penetration of each inserted object (0 if removed)."""
        p = self.p
        return kernels.wall_penetrations(self.s.view(), self.t.arrays(),
                                         self.container_arrays(), p.clearance, p.tol,
                                         p.wall_margin)

    def free_distances(self, points: np.ndarray, at_least: float = -np.inf) -> np.ndarray:
        """The room at each point (M,3): its distance to the nearest object or the wall,
        less the clearance (M,): an object there must keep the clearance from both, so it
        is what the phases compare an object's size with (a hole judged by the bare distance
        took growth attempts that could not succeed: docs/notes-core.md). Exact where it
        is at least `at_least` (container units); elsewhere some value below it, found
        sooner."""
        typ, pos, quat, scale, alive, _, _ = self.s.view()
        t, c = self.t, self.c.grid
        grid = self.cells.sync(self.s, np.zeros(0, np.int64))
        # a hair below, so that rounding in adding the clearance cannot cut short a point
        # whose room is at_least to the last bit
        floor = float(at_least) + self.p.clearance
        floor -= 1e-9 * max(1.0, abs(floor)) if np.isfinite(floor) else 0.0
        d = kernels.free_distances_near(
            np.ascontiguousarray(points, np.float64), floor,
            grid, typ, pos, quat, scale, alive, t.radius, t.g_off, t.g_vals, t.g_shape,
            t.g_origin, t.g_h, c.values, c.origin, c.spacing, self.c.creases.arrays())
        return d - self.p.clearance if self.p.clearance > 0 else d
