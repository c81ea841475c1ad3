"""The two phases of the method: place & grow (phase 1), fill cavities (phase 2).

Both work on a `Solver` (container frame, container units) and stop early when the
deadline passes or `should_cancel()` says so; an object caught mid-growth is removed, so the
state left behind only holds full-size objects and objects never grown (removed by the caller).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from .container import deepest_points, interior_points
from .fidelity import MANY_OBJECTS
from .kernels import sample_grid_many
from .lie_flat import flat_quaternion, flat_spacing
from .metrics import best_tvd, density, equivalent_radius, mix_cap, tvd_of_counts
from .report import PhaseStats
from .rotations import random_quaternions
from .solver import Solver
from .stacking import Stack
from .type_give_up import TypeFailures
from .type_spread import TypeSpread, type_needed

START_SCALE = 0.05
GROWTH_STEPS = 30
#: phase 1's growth steps where its lattice holds more than MANY_OBJECTS objects: as dense
#: a phase 1 in a fifth to a third of the time (docs/notes-core.md), and at that count
#: phase 1 is a large share of a run
MANY_OBJECTS_STEPS = 6
#: the lattice phase 1 uses where its cubic lattice holds more than MANY_OBJECTS objects
MANY_OBJECTS_LATTICE = "fcc"
#: the fcc lattice's density (its objects' bare volume over the container's), and the
#: denser ones (cubic lattice objects above which, density), largest first: with that
#: many, phase 1 grows a denser lattice with few failures and fills what the cavity passes
#: would, sooner (docs/notes-core.md)
FCC_DENSITY = 0.55
DENSER_FCC = ((50_000, 0.6), (15_000, 0.58))
#: an fcc lattice of at least DENSE_FCC density keeps its points at least DENSE_FCC_DEPTH of
#: the objects' mean equivalent radius deep: an object nearer the wall must push the
#: lattice inwards to grow, and a dense one has no room for that (docs/notes-core.md); the
#: cavity passes fill the shell
DENSE_FCC = 0.6
DENSE_FCC_DEPTH = 0.5
#: phase 1's spread window is at most its lattice objects over this
SPREAD_QUEUE = 8


def _density(solver: Solver) -> float:
    """Volume of the full-size alive objects over the container volume."""
    s = solver.s
    n = s.n
    full = (s.alive[:n] == 1) & (s.scale[:n] >= 1.0)
    return density(solver.t.volume[s.typ[:n][full]], solver.c.volume)


def _counted_density(counts: np.ndarray, solver: Solver) -> float:
    """`_density` from the phase's (T,) counts of full-size objects per type: the progress
    messages' figure, at a cost that does not grow with the objects placed."""
    return float(counts @ solver.t.volume) / solver.c.volume


class Stop:
    """Deadline and cancel checks shared by the phases."""

    def __init__(self, deadline: float | None, should_cancel: Callable[[], bool] | None):
        self.deadline = deadline
        self.should_cancel = should_cancel
        self.reason = ""

    def __call__(self) -> bool:
        if self.reason:
            return True
        if self.should_cancel is not None and self.should_cancel():
            self.reason = "cancelled"
        elif self.deadline is not None and time.perf_counter() > self.deadline:
            self.reason = "deadline"
        return bool(self.reason)


def grow(solver: Solver, k: int, start: float, iters: int, stop: Stop,
         steps: int = GROWTH_STEPS) -> bool:
    """Grow object k from `start` to scale 1 in steps of 1/steps, resolving overlaps.

    On failure (or stop) object k is removed and every other object is back in its last
    overlap-free state. Returns True if k reached full size.
    """
    s = solver.s
    scale = start
    focus = np.array([k], np.int64)
    while scale < 1.0:
        if stop():
            s.alive[k] = 0
            return False
        scale = scale + 1.0 / steps
        if scale > 1.0 - 1e-9:  # float sums of 1/steps fall just short of 1
            scale = 1.0
        s.scale[k] = scale
        if not solver.resolve(focus, iters, rollback=True):
            s.alive[k] = 0
            return False
    return True


def phase1_growth_steps(requested: int | None, lattice_objects: int) -> int:
    """Phase 1's growth steps: `requested`, or by default the paper's GROWTH_STEPS, and
    MANY_OBJECTS_STEPS where the lattice holds more than MANY_OBJECTS objects."""
    if requested is not None:
        return int(requested)
    return MANY_OBJECTS_STEPS if lattice_objects > MANY_OBJECTS else GROWTH_STEPS


def phase1_lattice(requested: str | None, lattice_objects: int) -> str:
    """Phase 1's lattice: `requested`, or by default "cubic" (the paper's), and
    MANY_OBJECTS_LATTICE where the cubic lattice holds more than MANY_OBJECTS objects."""
    if requested is not None:
        return requested
    return MANY_OBJECTS_LATTICE if lattice_objects > MANY_OBJECTS else "cubic"


def phase1_fcc_density(requested: float | None, lattice_objects: int) -> float:
    """The fcc lattice's density: `requested`, or by default FCC_DENSITY, and a DENSER_FCC
    one where the cubic lattice holds more than its count of objects."""
    if requested is not None:
        return float(requested)
    for above, denser in DENSER_FCC:
        if lattice_objects > above:
            return denser
    return FCC_DENSITY


def fcc_points(solver: Solver, fcc_spacing: float, fcc_density: float, mean_volume: float,
               min_depth: float, rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """Phase 1's fcc lattice points (container frame) at least min_depth inside, offset by
    rng, and how many were dropped. From DENSE_FCC density none lies within DENSE_FCC_DEPTH
    equivalent radii of mean_volume (container units^3) of the wall, and there are at most
    the container's volume over fcc_spacing^3, the deepest: the random offset decides
    whether a layer lies just inside each flat wall, where its objects must push the rest
    inwards to grow, and more than the density asks for jam phase 1 (docs/notes-core.md)."""
    if fcc_density >= DENSE_FCC:
        min_depth = max(min_depth, DENSE_FCC_DEPTH * equivalent_radius(mean_volume))
    pts = interior_points(solver.c, fcc_spacing, min_depth, rng, lattice="fcc")
    cap = int(solver.c.volume / fcc_spacing ** 3)
    return deepest_points(solver.c, pts, cap), max(0, len(pts) - cap)


def phase1(solver: Solver, shares: np.ndarray, spacing: float, rng: np.random.Generator,
           stop: Stop, *, iters: int = 30, margin: np.ndarray,
           growth_steps: int | None = None, spread_window: int = 1,
           lattice: str | None = None, cubic_density: float = 0.5,
           fcc_density: float | None = None,
           progress: Callable[[float, str], None] | None = None) -> PhaseStats:
    """Place one shrunken object per interior lattice point and grow them one at a time.

    spacing: the cubic lattice's spacing (container units), which holds cubic_density of
    the container in the objects' mean volume. shares: (T,) target shares by count. margin:
    (T,) per-type safety margin (container units). growth_steps: steps from scale 0 to 1;
    None: `phase1_growth_steps` of the cubic lattice's size. lattice: "cubic", "fcc" (its
    point density set for fcc_density, or `phase1_fcc_density` of the cubic lattice's size
    when None; at most the container's volume over a point's volume, the deepest; from
    DENSE_FCC, none within DENSE_FCC_DEPTH mean equivalent radii of the wall), or
    None: `phase1_lattice` of the cubic lattice's size.
    The next object to grow takes the largest type that is below its target share (or, when
    none is, the type furthest below it); it is the first ungrown one, or with
    spread_window > 1 the one of the next spread_window (at most a SPREAD_QUEUE-th of the
    lattice) ungrown ones furthest from the grown objects of that type. A type that grows
    far less often than the others is given up (`type_give_up`), and the phase's
    `extra["given_up"]` says which, with its tries.
    """
    t0 = time.perf_counter()
    st = PhaseStats()
    table = solver.t
    n_types = len(shares)
    min_depth = START_SCALE * table.radius.max() + solver.p.clearance + margin.max()
    pts = interior_points(solver.c, spacing, min_depth, rng)
    growth_steps = phase1_growth_steps(growth_steps, len(pts))
    lattice = phase1_lattice(lattice, len(pts))
    nearest = spacing  # between lattice points
    if lattice == "fcc":
        fcc_density = phase1_fcc_density(fcc_density, len(pts))
        fcc_spacing = spacing * (cubic_density / fcc_density) ** (1.0 / 3.0)
        mean_volume = cubic_density * spacing ** 3
        pts, st.extra["fcc_dropped"] = fcc_points(solver, fcc_spacing, fcc_density,
                                                  mean_volume, min_depth, rng)
        nearest = fcc_spacing * 4.0 ** (1.0 / 3.0) / math.sqrt(2.0)
        st.extra["fcc_density"] = fcc_density
    st.extra["growth_steps"] = growth_steps
    st.extra["lattice"] = lattice
    rng.shuffle(pts)
    types = rng.choice(n_types, size=len(pts), p=shares)
    quats = random_quaternions(rng, len(pts))
    queue: list[int] = []
    for p, t, q in zip(pts, types, quats, strict=True):
        queue.append(solver.s.add(int(t), p, q, START_SCALE, float(margin[t])))
    st.inserted = len(pts)
    # tiny objects near each other or the wall: settle them before growing anything. A
    # resolve pass costs (objects it starts from) x (all objects): on a lattice wider than
    # two shrunken objects only those near the wall can touch anything, so only they start
    # it (100000 lattice objects took a minute otherwise); none once the budget is spent.
    focus = np.asarray(queue, np.int64)
    r0 = START_SCALE * table.radius.max()
    if len(pts) and 2 * (r0 + margin.max()) + solver.p.clearance < nearest:
        g = solver.c.grid
        depth = sample_grid_many(g.values, g.origin, g.spacing, pts)
        # trilinear depth changes by at most sqrt(3) per unit length: 2 * r0 covers it
        near = min_depth + 2 * r0 + solver.p.wall_margin + g.spacing
        focus = focus[depth < near]
    if len(focus) and not stop():
        solver.resolve(focus, 50, rollback=False)
    order_by_volume = np.argsort(-table.volume)
    total = len(queue)
    spread = TypeSpread(n_types)
    failures = TypeFailures(shares)
    counts = failures.grown  # (T,) objects grown per type, as the failures count them
    # a few lattice points: a window over most of them would fix the order, and the
    # attempts of a small scene would all grow alike
    window = max(1, min(spread_window, total // SPREAD_QUEUE))
    for done in range(1, total + 1):
        if stop():
            break
        k = queue[done - 1]
        if not solver.s.alive[k]:
            continue
        t = type_needed(counts, failures.shares_now(), order_by_volume)
        # an ungrown object takes the type the mix needs now (the paper draws types up
        # front; typing on demand keeps the mix when big types fail more often); the
        # queue is in random order, and of its next few the one furthest from its type
        # spreads the type
        if window > 1:
            ahead = [j for j in range(done - 1, min(done - 1 + window, total))
                     if solver.s.alive[queue[j]]]
            gaps = spread.nearest(t, solver.s.pos[[queue[j] for j in ahead]])
            far = ahead[int(np.argmax(gaps))]
            queue[done - 1], queue[far] = queue[far], queue[done - 1]
            k = queue[done - 1]
        solver.s.typ[k] = t
        solver.s.margin[k] = margin[t]
        if solver.flat[t]:
            solver.s.quat[k] = flat_quaternion(solver.flat_axes[t], solver.s.pos[k],
                                               solver.c.grid, rng)
        grew = grow(solver, k, solver.s.scale[k], iters, stop, growth_steps)
        if grew:
            st.grown += 1
            spread.add(t, solver.s.pos[k])
        else:
            st.failed += 1
        if grew or not stop():
            failures.record(t, grew)
        if progress is not None and done % 4 == 0:
            progress(done / max(total, 1), f"phase 1: {st.grown} placed, density "
                     f"{_counted_density(counts, solver):.1%}")
    # objects never grown (stopped early) do not belong in the result
    for k in queue:
        if solver.s.scale[k] < 1.0:
            solver.s.alive[k] = 0
    if not stop():
        failures.finish()
    if failures.given_up.any():
        st.extra["given_up"] = failures.report()
    never_grew = failures.never_grew()
    if never_grew:
        st.extra["never_grew"] = never_grew
    st.stopped = stop.reason
    st.seconds = time.perf_counter() - t0
    return st


def phase2(solver: Solver, shares: np.ndarray, spacing: float, rng: np.random.Generator,
           stop: Stop, *, iters: int = 80, margin: np.ndarray, retries: int = 2,
           threshold: float | None = None, fit_factor: float = 1.0,
           patience: int | None = None, max_tvd: float = 0.04,
           growth_steps: int = GROWTH_STEPS, min_start: float = 0.0, flat_lattice: bool = False,
           progress: Callable[[float, str], None] | None = None) -> PhaseStats:
    """Fill cavities: at lattice points far enough from every object and the wall, insert
    the largest type whose equivalent radius f(V) is below that distance and grow it; on
    failure try up to `retries` random smaller types. The distance threshold is the paper's
    (f(Vbar) + f(Vmin)) / 2 unless `threshold` (container units) is given; a type fits
    where fit_factor * f(V) is below the distance (1 in the paper; < 1 lets an object start
    in a smaller hole and push its neighbours aside as it grows). With fit_factor < 1 the type
    tried first is the fitting one the mix lacks most, not the largest. No type is tried
    that would push the type mix error above `max_tvd` (`mix_cap`). With `patience`, the
    pass ends after that many candidate points in a row where nothing could be added.
    Objects grow in steps of 1/growth_steps. A type is not tried where it would start below
    `min_start` of its size (the scale its room allows: free radius less two margins, over
    bounding radius). flat_lattice: where a type fits only lying flat, the lattice is no
    wider than the band of points deep enough for it (`lie_flat.flat_spacing`; the extra
    passes, which end on patience).
    """
    t0 = time.perf_counter()
    st = PhaseStats()
    if stop():  # the candidate search below costs (points x objects): not after the budget
        st.stopped = stop.reason
        return st
    table = solver.t
    # a type that fits only lying flat needs its half thickness of room, not its radius
    f = np.where(solver.flat, solver.flat_half[:, 2], equivalent_radius(table.volume))
    # libm's log and exp, as equivalent_radius's cube root: numpy's differ on AVX-512 CPUs
    logs = np.fromiter(map(math.log, table.volume.tolist()), np.float64, len(table.volume))
    vbar = math.exp(float(np.sum(shares * logs)))
    if threshold is None:
        f_bar = float(equivalent_radius(vbar))
        if solver.flat.any():  # the mean of the room each type needs, flat ones flat
            live = shares > 0
            f_bar = math.exp(float(np.sum(shares[live] * np.log(f[live]))))
        threshold = 0.5 * (f_bar + float(f.min()))
    if flat_lattice and solver.flat.any():
        spacing = flat_spacing(spacing, solver.c, threshold)
    pts = interior_points(solver.c, spacing, threshold, rng)
    if len(pts) == 0:
        st.seconds = time.perf_counter() - t0
        return st
    d = solver.free_distances(pts, at_least=threshold)
    keep = d >= threshold
    pts, d = pts[keep], d[keep]
    order = np.argsort(-d, kind="stable")
    pts = pts[order]
    by_size = [int(t) for t in np.argsort(-f) if shares[t] > 0]  # zero share: never placed
    one_more = np.eye(len(shares))  # row t: one object of type t
    misses = 0
    held = 0  # candidate points where the mix refused a type that fits, and none grew
    n = solver.s.n
    full = np.flatnonzero((solver.s.alive[:n] == 1) & (solver.s.scale[:n] >= 1.0))
    counts = np.bincount(solver.s.typ[full], minlength=len(shares)).astype(np.float64)
    for n_done, p in enumerate(pts):
        if stop():
            break
        if patience is not None and misses >= patience:
            st.stopped = "patience"
            break
        dist = float(solver.free_distances(p[None], at_least=threshold)[0])
        if dist < threshold:
            continue
        fits = [int(t) for t in by_size if fit_factor * f[t] < dist]
        if not fits:
            continue
        misses += 1
        # only types that keep the mix within max_tvd (or improve it): where the holes fit
        # only a small type, filling each with it would leave the shares far behind
        cap = mix_cap(counts, shares, max_tvd)
        fitting = len(fits)
        fits = [t for t in fits if tvd_of_counts(counts + one_more[t], shares) <= cap]
        refused = len(fits) < fitting
        if fit_factor < 1.0:
            # extra passes: the one the mix lacks most first, larger first on ties
            n_now = counts.sum() + 1.0
            need = sorted(fits, key=lambda t: (counts[t] - shares[t] * n_now, -f[t]))
            tries = need[: 1 + retries]
        else:
            tries = fits[:1]
            smaller = fits[1:]
            if smaller:
                tries += list(rng.choice(smaller, size=min(retries, len(smaller)),
                                         replace=False))
        added = False
        for t in tries:
            q = random_quaternions(rng, 1)[0]
            if solver.flat[t]:
                q = flat_quaternion(solver.flat_axes[t], p, solver.c.grid, rng)
            # steps below the free radius are collision free: start growing there (dist
            # is already less the clearance: `Solver.free_distances`)
            room = (dist - 2 * margin[t]) / table.radius[t]
            if min_start > 0 and room < min_start:
                continue
            start = float(np.clip(room, START_SCALE, 1.0))
            k = solver.s.add(t, p, q, start, float(margin[t]))
            st.inserted += 1
            if not solver.resolve(np.array([k], np.int64), iters, rollback=True):
                solver.s.alive[k] = 0
                st.failed += 1
                continue
            if start >= 1.0 or grow(solver, k, start, iters, stop, growth_steps):
                st.grown += 1
                counts[t] += 1
                misses = 0
                added = True
                break
            st.failed += 1
        held += refused and not added
        if progress is not None and n_done % 8 == 0:
            progress(n_done / len(pts), f"phase 2: {st.grown} added, density "
                     f"{_counted_density(counts, solver):.1%}")
    st.stopped = stop.reason or st.stopped
    st.seconds = time.perf_counter() - t0
    st.extra = {"candidates": int(len(pts)), "threshold": threshold, "mix_held": held}
    return st


def stacked_phase1(solver: Solver, stack: Stack, margin: np.ndarray, shares: np.ndarray,
                   max_tvd: float) -> PhaseStats:
    """Phase 1 from a stacked start (`stacking.stack_start`): its objects at full size,
    less any the solver finds through the wall (its wall samples are finer than the
    stack's) and, where those leave the mix further than max_tvd from the (T,) shares
    (or the best the count allows), the last stacked of the type furthest over its share
    until it is not. margin: (T,) contact margins (container units)."""
    t0 = time.perf_counter()
    st = PhaseStats()
    s = solver.s
    first = s.n
    for t, p, q in zip(stack.typ, stack.pos, stack.quat, strict=True):
        s.add(int(t), p, q, 1.0, float(margin[t]))
    st.inserted = len(stack.typ)
    # the rows keep the objects apart by construction; the wall is sampled coarser there
    bad = first + np.flatnonzero(solver.wall_penetrations()[first:] > solver.p.tol)
    s.alive[bad] = 0
    trimmed = _trim_to_mix(s.typ[first: s.n], s.alive[first: s.n], shares, max_tvd)
    st.failed = len(bad) + trimmed
    st.grown = st.inserted - st.failed
    kept = stack.typ[s.alive[first: s.n] == 1]
    st.extra = {"lattice": "stacked", "mix_trimmed": trimmed,
                "stack_density": float(solver.t.volume[kept].sum() / solver.c.volume),
                "stack_filled": float(stack.room[kept].sum() / solver.c.volume)}
    st.stopped = ""  # nothing is left growing, whenever the deadline passed
    st.seconds = time.perf_counter() - t0
    return st


def _trim_to_mix(typ: np.ndarray, alive: np.ndarray, shares: np.ndarray,
                 max_tvd: float) -> int:
    """Remove (alive 0, in place) the last alive object of the type furthest over its share
    while the mix of the alive ones (`typ`, `alive`: (N,)) is further than max_tvd from
    the (T,) shares and than the best mix their count allows; returns how many."""
    counts = np.bincount(typ[alive == 1], minlength=len(shares)).astype(np.float64)
    removed = 0
    while counts.sum() > 1:
        n = counts.sum()
        if tvd_of_counts(counts, shares) <= max(max_tvd, best_tvd(shares, int(n))) + 1e-12:
            break
        t = int(np.argmax(counts / n - shares))
        k = int(np.flatnonzero((typ == t) & (alive == 1))[-1])
        alive[k] = 0
        counts[t] -= 1
        removed += 1
    return removed
