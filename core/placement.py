"""Placement: phase 1, phase 2 and the extra cavity rounds, as independent attempts.

One attempt runs the phases on a fresh state (container frame, container units). With a time
budget, an attempt often ends before it: its rounds of cavity passes stop adding objects.
The time left then goes to new attempts from scratch (each its own random stream), as long
as it is at least the shortest attempt so far, and the densest attempt is kept: attempts end
at densities that differ by points between random streams (docs/notes-core.md). The next
densest are kept too (RUNNERS_UP), for the case where the repair after certification removes
objects from the densest (`api._certify_ranked`). A budget is a ceiling, not a duration:
once an attempt that ran to its end repeats the best attempt's object count and density, the
scene is taken as full at that count (small scenes, where every stream reaches the same
count) and no further attempt starts; nor does one after a stacked start that filled
STACK_KEPT of the container (the attempts after it start at random rotations, which jam
below it). Asked for a fixed number of attempts (`AttemptOptions.count`), exactly that many
run (fewer only on cancel or the deadline), with no early stop, so that running them one
after another here or side by side on a cluster (`core/cluster.py`) keeps the same densest
one.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from .box_grid import box_grid
from .metrics import compute_metrics
from .options import PackOptions
from .phases import Stop, phase1, phase2, stacked_phase1
from .report import AttemptSummary, ExtraPassStats, PhaseStats
from .solver import PackState, Solver
from .stacking import Stack, stack_start
from .type_give_up import shares_without

#: attempts that ran to their end and repeated the best attempt's count and density (to
#: SAME_DENSITY) after which no further attempt starts. Between random streams, densities of
#: scenes with more than a few dozen objects differ by points (docs/notes-core.md), so an
#: exact repeat means the count is what the container holds at this fidelity.
REPEATS_TO_STOP = 1
SAME_DENSITY = 1e-9
#: why the attempts ended early (the last attempt's summary says it): not a stop reason of
#: the run (`RunReport.stopped`), which stays None as the placement ran to its end
REPEATED = "repeated the best attempt"
#: a stacked start (`stacking`) whose boxes, grown by the clearance, fill this share of the
#: container is kept without further attempts, which start at random rotations: random
#: packings jam below it for any convex shape (superballs, the densest known, about 0.76)
STACK_KEPT = 0.76
STACK_FULL = "the stacked start filled more of the container than random starts reach"
#: the least scale a cavity pass starts an object at after a stacked start
STACK_MIN_START = 0.5
#: the contact tests an insertion's push may run after a stacked start before it fails:
#: rows stand a gap apart, so a push runs through all of them, in one kernel call that
#: neither the budget nor Ctrl-C can end (docs/notes-core.md)
STACK_PUSH_TESTS = 100_000
#: attempts kept besides the densest, for certification: where the repair removes objects
#: from the densest, a runner-up denser before certification than what is left is certified
#: in turn, and the densest certified packing is kept (`api._certify_ranked`)
RUNNERS_UP = 2
#: after the deadline a grid of boxes (`box_grid`) replaces the attempt only where it
#: holds at most this many times the attempt's objects
GRID_LATE = 2.0
#: an attempt whose phase 2 ends below the best attempt's density by both this factor and
#: these points skips its extra passes, which cannot catch up: across the bench's recorded
#: attempts the passes multiplied phase 2's density by at most 1.64 and added at most 0.213
#: (docs/notes-core.md)
CATCH_UP_FACTOR = 2.0
CATCH_UP_POINTS = 0.3
BEHIND = "phase 2 ended too far below the best attempt for the passes to catch up"


@dataclass
class Attempt:
    """One run of the phases: its solver (and state), statistics and wall times (s)."""

    solver: Solver
    density: float  # full-size objects' volume over the container's, before certification
    after: dict = field(default_factory=dict)  # metrics after phase 1, phase 2, extra
    phase1: PhaseStats = field(default_factory=PhaseStats)
    phase2: PhaseStats = field(default_factory=PhaseStats)
    extra_passes: list[ExtraPassStats] = field(default_factory=list)
    timings: dict = field(default_factory=dict)  # phase1, phase2, extra
    #: the types the attempt gave up, as `type_give_up.TypeFailures.report` records: those
    #: phase 1 gave up, and those no pass placed ("restarted": their phase 1 tries), after
    #: which the attempt started again without them
    given_up: list[dict] = field(default_factory=list)
    index: int = 0  # the attempt's place among the run's attempts (its random stream)
    behind: bool = False  # its extra passes did not run: they could not catch up (BEHIND)

    @property
    def mix_held(self) -> int:
        """The holes where the mix refused a type that fit and nothing grew (`phase2`)."""
        return sum(st.extra.get("mix_held", 0) for st in (self.phase2, *self.extra_passes))

    def summary(self, stopped: str | None) -> AttemptSummary:
        return AttemptSummary(
            density=self.density, count=self.after["after_extra"]["count"],
            seconds=sum(self.timings.values()),
            stopped=stopped or (BEHIND if self.behind else None),
            **{k: self.timings[k] for k in ("phase1", "phase2", "extra")})


def snapshot_metrics(state: PackState, volume: np.ndarray, q: np.ndarray,
                     c_volume: float) -> dict:
    """Count, density, TVD and mean NNI of the full-size alive objects."""
    idx = np.flatnonzero(state.alive[: state.n] & (state.scale[: state.n] >= 1.0))
    m = compute_metrics(state.typ[idx], state.pos[idx], volume, q, c_volume)
    return {k: m[k] for k in ("count", "density", "tvd", "nni_mean")}


def place_once(solver: Solver, q: np.ndarray, s1: float, f_min: float,
               rng: np.random.Generator, stop: Stop, margin: np.ndarray, options: PackOptions,
               c_volume: float, budgeted: bool,
               report: Callable[[float, str], None], *, index: int,
               fresh: Callable[[], Solver] | None = None,
               given_up: tuple[dict, ...] = (), beat: float = 0.0) -> Attempt:
    """`_place_once`, but for attempt 0 where the types (one, or several of one box) fill
    a box-shaped container as a grid of their boxes (`box_grid`): a closed grid that fills
    STACK_KEPT of it is kept without the attempt (no slab beside it takes another row, and
    random starts jam below STACK_KEPT); another is kept, on `fresh()`, where it holds
    more than the attempt, and after the deadline only where it holds at most GRID_LATE
    times as many (its certification then takes about as long)."""
    t0 = time.perf_counter()
    grid = None
    if index == 0 and fresh is not None and not given_up:
        grid = box_grid(solver.c, solver.t.types, solver.t.volume, q, solver.p.clearance)
    if grid is not None and grid.closed and _filled(grid.stack, solver) >= STACK_KEPT:
        return _grid_attempt(grid.stack, solver, q, c_volume, report, index,
                             time.perf_counter() - t0)
    att = _place_once(solver, q, s1, f_min, rng, stop, margin, options, c_volume, budgeted,
                      report, index=index, fresh=fresh, given_up=given_up, beat=beat)
    if grid is None or stop.reason == "cancelled":
        return att
    late = stop.deadline is not None and time.perf_counter() > stop.deadline
    n, count = len(grid.stack.typ), att.after["after_extra"]["count"]
    if n <= count or (late and n > GRID_LATE * count):
        return att
    # the stacked start's time holds the attempt the grid replaces, which ran first
    return _grid_attempt(grid.stack, fresh(), q, c_volume, report, index,
                         time.perf_counter() - t0)


def _filled(stack: Stack, solver: Solver) -> float:
    """The share of the container the stack's objects take, each type's volume grown by
    its box's share of the clearance (`stacking.Stack.room`)."""
    return float(stack.room[stack.typ].sum() / solver.c.volume)


def _grid_attempt(grid: Stack, solver: Solver, q: np.ndarray, c_volume: float,
                  report: Callable[[float, str], None], index: int,
                  seconds: float) -> Attempt:
    """An attempt of `grid`'s objects on the empty `solver`, at full size and without a
    contact margin (the boxes keep them apart); `seconds` is all its time."""
    for t, p, quat in zip(grid.typ, grid.pos, grid.quat, strict=True):
        solver.s.add(int(t), p, quat, 1.0, 0.0)
    report(0.95, f"a grid of {len(grid.typ)} along the container's sides")
    st1 = PhaseStats(inserted=len(grid.typ), grown=len(grid.typ), seconds=seconds)
    st1.extra = {"lattice": "stacked", "grid": True,
                 "stack_density": float(solver.t.volume[grid.typ].sum() / solver.c.volume),
                 "stack_filled": _filled(grid, solver)}
    after = snapshot_metrics(solver.s, solver.t.volume, q, c_volume)
    return Attempt(solver=solver, density=after["density"],
                   after={"after_phase1": after, "after_phase2": after, "after_extra": after},
                   phase1=st1, timings={"phase1": seconds, "phase2": 0.0, "extra": 0.0},
                   index=index)


def _place_once(solver: Solver, q: np.ndarray, s1: float, f_min: float,
                rng: np.random.Generator, stop: Stop, margin: np.ndarray,
                options: PackOptions, c_volume: float, budgeted: bool,
                report: Callable[[float, str], None], *, index: int,
                fresh: Callable[[], Solver] | None = None,
                given_up: tuple[dict, ...] = (), beat: float = 0.0) -> Attempt:
    """Phase 1, phase 2 and the extra cavity passes on `solver`'s (empty) state.

    q: (T,) target shares; s1: phase 1's lattice spacing; f_min: the smallest type's
    equivalent radius (container units); margin: (T,) contact margins. With `budgeted`,
    the extra passes run again on new lattices while a round adds objects. Attempt `index`
    0 starts from the types stacked in rows where they fill the container so
    (`stacking.stack_start`); the others, and every attempt elsewhere, from phase 1's
    grown lattice. The types of `given_up` (`Attempt.given_up`) are not packed; where no
    pass placed a type of a share over the mix tolerance that phase 1 tried and never grew
    (`TypeFailures.never_grew`; any type, where phase 1 tried nothing), and the mix held
    the others back from holes they fit (`phase2`'s "mix_held"), the attempt starts again
    without it on `fresh()`, a new solver, and keeps the denser run (its timings then hold
    both runs, its phase statistics the kept one's). Where phase 2 ends so far below
    `beat`, the best attempt's density so far, that the passes cannot catch up
    (CATCH_UP_FACTOR and CATCH_UP_POINTS), they do not run and `Attempt.behind` says so.
    """
    vol = solver.t.volume
    ph, cav = options.phases, options.cavity
    t0 = time.perf_counter()
    q_asked, q = q, shares_without(q, list(given_up))
    stack = None
    if index == 0:
        # a search of seconds: cancel ends it; the deadline leaves its stack to keep
        stack = stack_start(solver.c, solver.t.types, vol, q, margin, solver.p.clearance,
                            solver.p.wall_margin, rng,
                            lambda: stop.should_cancel is not None and stop.should_cancel(),
                            max_tvd=cav.max_tvd)
    if stack is not None:
        report(0.05, f"stacked start: {len(stack.typ)} objects in rows")
        st1 = stacked_phase1(solver, stack, margin, q, cav.max_tvd)
    else:
        st1 = phase1(solver, q, s1, rng, stop, iters=ph.phase1_iterations, margin=margin,
                     growth_steps=ph.phase1_growth_steps, spread_window=ph.spread_window,
                     lattice=ph.phase1_lattice, cubic_density=ph.phase1_density,
                     fcc_density=ph.phase1_fcc_density,
                     progress=lambda f, m: report(0.05 + 0.55 * f, m))
    after1 = snapshot_metrics(solver.s, vol, q_asked, c_volume)
    given_up = (*given_up, *st1.extra.get("given_up", []))
    q_packed = shares_without(q_asked, list(given_up))  # and not the types phase 1 gave up
    t1 = time.perf_counter()
    # between stacked rows the holes are slivers: an object started there at a small
    # fraction of its size pushes whole rows and fails (docs/notes-core.md)
    floor = STACK_MIN_START if stack is not None else 0.0
    if stack is not None:
        solver.max_tests = STACK_PUSH_TESTS
    st2 = phase2(solver, q_packed, s1 * ph.phase2_spacing, rng, stop,
                 iters=ph.phase2_iterations, margin=margin, retries=ph.phase2_retries,
                 max_tvd=cav.max_tvd, min_start=floor,
                 progress=lambda f, m: report(0.6 + 0.2 * f, m))
    after2 = snapshot_metrics(solver.s, vol, q_asked, c_volume)
    t2 = time.perf_counter()
    # beyond the paper: further cavity passes at lower thresholds (objects grown there push
    # their neighbours aside), while the time budget allows. Each pass ends after
    # `patience` fruitless points; with time left, the passes run again on freshly
    # jittered lattices (other holes), for as long as a round still adds objects.
    extra: list[ExtraPassStats] = []
    n_extra = max(len(cav.factors), 1)
    if solver.flat.any():  # their holes are as deep as they are thick (`lie_flat`)
        f_min = min(f_min, float(solver.flat_half[solver.flat, 2].min()))
    rounds = cav.rounds if budgeted else 1
    d2 = after2["density"]
    behind = d2 * CATCH_UP_FACTOR < beat and d2 + CATCH_UP_POINTS < beat
    for rnd in range(0 if behind else rounds):
        grown = 0
        for i, factor in enumerate(cav.factors):
            if stop():
                break
            lo = 0.8 + 0.1 * (i + rnd * n_extra) / (n_extra * rounds)
            st = phase2(
                solver, q_packed, s1 * ph.phase2_spacing * factor, rng, stop,
                iters=cav.iterations, margin=margin, retries=cav.retries,
                growth_steps=cav.growth_steps, min_start=max(cav.min_start, floor),
                threshold=factor * f_min, fit_factor=factor, patience=cav.patience,
                flat_lattice=True,
                max_tvd=cav.max_tvd,
                progress=lambda f, m, lo=lo: report(lo + 0.1 * f / (n_extra * rounds), m))
            grown += st.grown
            extra.append(ExtraPassStats(**asdict(st), round=rnd, factor=factor))
        if grown == 0 or stop():
            break
    solver.max_tests = 0  # certification's repair pushes as far as it needs
    after3 = snapshot_metrics(solver.s, vol, q_asked, c_volume)
    t3 = time.perf_counter()
    att = Attempt(
        solver=solver, density=after3["density"],
        after={"after_phase1": after1, "after_phase2": after2, "after_extra": after3},
        phase1=st1, phase2=st2, extra_passes=extra,
        timings={"phase1": t1 - t0, "phase2": t2 - t1, "extra": t3 - t2},
        given_up=list(given_up), index=index, behind=behind)
    tried = dict(map(tuple, st1.extra.get("never_grew", [])))
    # a phase 1 that tried nothing (a thin tray's lattice may hold no point) says nothing of
    # any type: then each type no pass placed counts
    never = [t for t in never_placed(solver.s, q_packed) if t in tried or not st1.inserted]
    if (fresh is None or not never or not att.mix_held
            or q_packed[never].sum() <= cav.max_tvd or stop()):
        return att
    # the mix held the others back for a type that grew in no try: again without it
    report(0.05, f"{len(never)} type(s) never grew: the attempt starts again without them")
    given_up = (*given_up, *({"type": t, "tries": tried.get(t, 0), "grown": 0,
                              "restarted": True} for t in never))
    q_next = shares_without(q_asked, list(given_up))
    s1 = s1 * (float(q_next @ vol) / float(q @ vol)) ** (1.0 / 3.0)  # their mean volume
    again = place_once(fresh(), q_asked, s1, f_min, rng, stop, margin, options, c_volume,
                       budgeted, report, index=index, fresh=fresh, given_up=given_up,
                       beat=beat)
    kept = again if again.density > att.density else att  # the same types never grew
    kept.timings = {k: v + att.timings[k] for k, v in again.timings.items()}
    return kept


def never_placed(state: PackState, shares: np.ndarray) -> list[int]:
    """The types with a share in (T,) `shares` of which no object is alive at full size,
    where another type has one (none where nothing is)."""
    n = state.n
    full = (state.alive[:n] == 1) & (state.scale[:n] >= 1.0)
    counts = np.bincount(state.typ[:n][full], minlength=len(shares))
    if counts.sum() == 0:
        return []
    return [int(t) for t in np.flatnonzero((shares > 0) & (counts == 0))]


class Snapshots:
    """Passes the objects of a placement state on as `fn(positions, radii, types)`: (N, 3)
    centres, (N,) bounding radii at their current scale and (N,) type indices of the alive
    objects (copies; container frame, container units), at most once per `period` seconds
    (a live view needs a few a second; copying costs little next to a solver call)."""

    def __init__(self, fn: Callable[[np.ndarray, np.ndarray, np.ndarray], None],
                 radius: np.ndarray, period: float = 0.25):
        self.fn = fn
        self.radius = radius  # (T,) bounding radius of each type at full size
        self.period = period
        self._last = -np.inf

    def __call__(self, state: PackState) -> None:
        now = time.perf_counter()
        if now - self._last < self.period:
            return
        self._last = now
        idx = np.flatnonzero(state.alive[: state.n])
        typ = state.typ[idx].copy()
        self.fn(state.pos[idx].copy(), self.radius[typ] * state.scale[idx], typ)


def attempt_rng(seed: int, index: int) -> np.random.Generator:
    """The random stream of attempt `index` of a packing with `seed`."""
    return np.random.default_rng(seed if index == 0 else [seed, index])


def is_denser(att: Attempt, best: Attempt | None) -> bool:
    """`att` replaces `best` as the kept attempt: strictly denser (ties keep the earlier)."""
    return best is None or att.density > best.density


def ranked_with(ranked: list, att) -> list:
    """`ranked` (densest first, ties: the earlier first) with `att` in its place, cut to
    the densest 1 + RUNNERS_UP."""
    i = next((k for k, other in enumerate(ranked) if is_denser(att, other)), len(ranked))
    return [*ranked[:i], att, *ranked[i:]][: 1 + RUNNERS_UP]


def place(new_solver: Callable[[], Solver], q: np.ndarray, s1: float, f_min: float,
          seed: int, stop: Stop, margin: np.ndarray, options: PackOptions, c_volume: float,
          report: Callable[[float, str], None],
          watch: Callable[[PackState], None] | None = None
          ) -> tuple[list[Attempt], list[AttemptSummary]]:
    """Attempts of `place_once`, each on a fresh solver from `new_solver()`; returns the
    densest ones, densest first (`ranked_with`), and a summary of every attempt. Without a
    deadline there is one attempt, or two where the first started stacked and filled less
    than STACK_KEPT. The first uses the random stream of `seed` itself, attempt a > 0 that
    of (seed, a). The attempts end early, the last one's summary saying REPEATED, once
    REPEATS_TO_STOP attempts in a row ran to their end with the best attempt's count and
    density, or saying STACK_FULL after a stacked start that filled STACK_KEPT of the
    container. With `options.attempts.count` set, exactly that many run (fewer on cancel or
    deadline). watch(state), when given, sees the running attempt's state at every progress
    report.
    """
    ranked: list[Attempt] = []
    done: list[AttemptSummary] = []
    shortest = np.inf
    repeats = 0
    high = 0.0  # the progress bar never runs backwards across attempts
    current: Solver | None = None  # the running attempt's

    def monotone(fraction: float, message: str) -> None:
        nonlocal high
        high = max(high, fraction)
        report(high, message if not done else f"attempt {len(done) + 1}: {message}")
        if watch is not None and current is not None:
            watch(current.s)

    def restart() -> Solver:  # an attempt that starts again: the live view follows it
        nonlocal current
        current = new_solver()
        return current

    while True:
        rng = attempt_rng(seed, len(done))
        t0 = time.perf_counter()
        current = new_solver()
        # a fixed count runs every attempt in full, as the cluster does side by side
        beat = ranked[0].density if ranked and options.attempts.count is None else 0.0
        att = place_once(current, q, s1, f_min, rng, stop, margin, options, c_volume,
                         stop.deadline is not None, monotone, index=len(done),
                         fresh=restart, beat=beat)
        shortest = min(shortest, time.perf_counter() - t0)
        summary = att.summary(stop.reason or None)
        done.append(summary)
        if ranked and not stop.reason and _repeats(att, ranked[0]):
            repeats += 1
        else:
            repeats = 0
        ranked = ranked_with(ranked, att)
        if options.attempts.count is not None:  # a fixed count: no early stop
            if stop() or len(done) >= options.attempts.count:
                return ranked, done
            continue
        if repeats >= REPEATS_TO_STOP and stop.deadline is not None:
            summary.stopped = REPEATED
            return ranked, done
        stacked = att.phase1.extra.get("stack_filled")
        if stacked is not None and stacked >= STACK_KEPT and not stop.reason:
            summary.stopped = STACK_FULL
            return ranked, done
        if stop.deadline is None:
            # a stack that leaves room is a candidate: one attempt from phase 1 follows
            if stacked is None or stop():
                return ranked, done
            continue
        if (stop() or len(done) >= options.attempts.max_attempts
                or stop.deadline - time.perf_counter() < shortest):
            return ranked, done


def _repeats(att: Attempt, best: Attempt) -> bool:
    """`att` ended with the same object count and density as `best`."""
    return (att.after["after_extra"]["count"] == best.after["after_extra"]["count"]
            and abs(att.density - best.density) <= SAME_DENSITY)
