"""Certify a placement on the real meshes and repair what fails (container frame and units).

Failing objects are pushed apart one at a time (a bigger margin for that object, then the
solver, rolled back if it cannot settle) and what moved is checked again; what still fails
after the rounds, after the push-apart time cap (runs with a time budget only), or on
cancel is removed. Without a budget the rounds alone bound the work, so the result does not
depend on how busy the machine is: the same inputs and seed give the same packing.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from .certify import DEFAULT_TOL, Certifier, CertifyReport, CheckMemo
from .metrics import best_tvd, tvd_of_counts
from .options import RepairOptions
from .report import RepairStats
from .rotations import placement_matrices
from .solver import Solver

#: with a clearance, a failing object's margin grows by its gap's shortfall times this (the
#: certifier measures the shortfall; a pair's two objects both grow): a fixed step of a
#: fraction of the object's radius pushes its neighbours further than they need, and in a
#: jammed packing it could not settle and the object was removed (docs/notes-core.md)
SHORTFALL_STEP = 1.0
#: ... plus this fraction of the clearance, so a shortfall the solver reproduces exactly is
#: still cleared
SHORTFALL_EXTRA = 0.02
#: the removals may leave the mix's TVD this far above the mix tolerance (or the
#: placement's own TVD) before objects are removed for the mix alone: with the default
#: tolerance (0.04) that is the 0.05 a packing keeps; trimming down to the tolerance cost
#: the Armadillo 1-2 points (docs/notes-core.md)
MIX_SLACK = 0.01


def shortfalls(rep: CertifyReport, idx: np.ndarray) -> dict[int, float]:
    """Each failing object's largest gap shortfall (solver indices via idx; container
    units) from a report with a clearance; {} without one."""
    out: dict[int, float] = {}
    for (i, j), short in rep.pair_shortfall.items():
        for k in (int(idx[i]), int(idx[j])):
            out[k] = max(out.get(k, 0.0), short)
    for i, short in rep.wall_shortfall.items():
        k = int(idx[i])
        out[k] = max(out.get(k, 0.0), short)
    return out


def certify_and_repair(solver: Solver, certifier: Certifier, clearance: float,
                       options: RepairOptions, cancelled: Callable[[], bool], *,
                       timed: bool = True, shares: np.ndarray | None = None,
                       max_tvd: float = 0.0,
                       progress: Callable[[float, str], None] | None = None
                       ) -> tuple[dict, RepairStats]:
    """Certify the solver's alive objects; push failing objects apart for up to
    `options.rounds` rounds and, when `timed` (the run has a time budget),
    `options.seconds` from the first push (a first certification of detailed meshes can
    take longer than that); remove what still fails, minding the type mix (`shares`, (T,)
    summing to 1): the removals do not leave the mix's TVD more than MIX_SLACK above
    `max_tvd` or the placement's own, whichever is larger (`offenders_kept`, `mix_trim`).
    Mutates the solver's state. A check whose objects have not moved since it ran is not
    run again (`CheckMemo`). progress(fraction, message) is called now and then while
    checking; the fraction (of the first certification's checks) never falls.
    Returns (the final certificate as a dict, repair statistics)."""
    s = solver.s
    stats = RepairStats()
    target = 0.0 if shares is None else mix_target(s.typ[s.alive_indices()], shares, max_tvd)
    deadline = None  # from the first push: certifying is not push-apart work
    subset = None
    moved_ever: set[int] = set()
    memo = CheckMemo()

    high = 0.0  # the first certification fills the bar; a repair's later ones never
    # run it backwards (their checks, of what moved, are in the message)

    def tick(done: int, total: int) -> None:
        nonlocal high
        high = max(high, done / total if total else 1.0)
        progress(high, f"certifying on the real meshes: {done:,} of {total:,} exact checks")

    def certify(idx: np.ndarray, only: np.ndarray | None = None) -> CertifyReport:
        mats = placement_matrices(s.quat[idx], s.pos[idx], s.scale[idx])
        return certifier.certify(s.typ[idx], mats, clearance, DEFAULT_TOL, subset=only,
                                 memo=memo, ids=idx,
                                 progress=None if progress is None else tick)

    for rnd in range(options.rounds + 1):
        idx = s.alive_indices()
        rep = certify(idx, None if subset is None else np.flatnonzero(np.isin(idx, subset)))
        if stats.first is None:
            stats.first = rep.as_dict()
        bad = idx[sorted(rep.bad_objects())]
        if len(bad) == 0:
            break
        if rnd == options.rounds or stats.timed_out:
            _removed(stats, remove_offenders(solver, idx, rep, shares, target))
            break
        stats.rounds += 1
        before_pos = s.pos[: s.n].copy()
        before_q = s.quat[: s.n].copy()
        short = shortfalls(rep, idx)
        if deadline is None:
            deadline = time.perf_counter() + options.seconds if timed else np.inf
        for k in bad:
            if time.perf_counter() > deadline or cancelled():
                stats.timed_out = True
                break
            old = s.margin[k]
            if int(k) in short:  # a gap below the clearance: grow by what it lacks
                s.margin[k] = old + SHORTFALL_STEP * short[int(k)] + SHORTFALL_EXTRA * clearance
            else:  # an overlap: its depth is not measured
                s.margin[k] = 2.0 * old + options.margin * solver.t.radius[s.typ[k]]
            if not solver.resolve(np.array([k], np.int64), options.iterations,
                                  rollback=True, settle_every=options.settle_every):
                s.margin[k] = old
        moved = np.flatnonzero(np.any(s.pos[: s.n] != before_pos, axis=1)
                               | np.any(s.quat[: s.n] != before_q, axis=1))
        moved_ever.update(int(m) for m in moved)
        subset = np.union1d(moved, bad)
    stats.moved = len(moved_ever)
    while True:  # removal only removes violations; loop in case a check was trusted wrongly
        idx = s.alive_indices()
        final = certify(idx)
        if final.certified:
            if clearance > 0:  # the checks read gaps only up to their search distance
                final.min_pair_gap, final.min_wall_gap = certifier.least_gaps(
                    s.typ[idx], placement_matrices(s.quat[idx], s.pos[idx], s.scale[idx]),
                    clearance, memo, idx, (final.min_pair_gap, final.min_wall_gap))
            return final.as_dict(), stats
        _removed(stats, remove_offenders(solver, idx, final, shares, target))


def mix_target(typ: np.ndarray, shares: np.ndarray, max_tvd: float) -> float:
    """The TVD the removals may not make worse (they may add MIX_SLACK to it): the mix
    tolerance, or the placed objects' own TVD (typ (N,), shares (T,)) where that is larger."""
    return max(max_tvd, tvd_of_counts(np.bincount(typ, minlength=len(shares)), shares))


def _removed(stats: RepairStats, counts: tuple[int, int]) -> None:
    stats.removed += counts[0] + counts[1]
    stats.for_mix += counts[1]


def remove_offenders(solver: Solver, idx: np.ndarray, rep: CertifyReport,
                     shares: np.ndarray | None = None, max_tvd: float = 0.0
                     ) -> tuple[int, int]:
    """Remove what `removals` drops from the alive objects; idx maps the report's object
    indices to the solver's. Removing never makes a certified packing fail, and the caller
    certifies again. Returns (offenders removed, objects removed for the mix)."""
    s = solver.s
    alive = s.alive[idx].astype(bool)
    keep, for_mix = removals(s.typ[idx], solver.t.volume, rep.bad_pairs, rep.bad_wall,
                             shares, max_tvd, alive=alive)
    s.alive[idx[alive & ~keep]] = 0
    return int((alive & ~keep).sum()) - for_mix, for_mix


def removals(typ: np.ndarray, volumes: np.ndarray, bad_pairs: Sequence[tuple[int, int]],
             bad_wall: Sequence[int], shares: np.ndarray | None = None, max_tvd: float = 0.0,
             *, alive: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """The objects (N,) kept when a certificate's offenders are removed (`offenders_kept`,
    whose pair choice minds `max_tvd`: see `mix_target`) and then, with `shares`, those
    `mix_trim` picks to bring the mix's TVD back to max_tvd + MIX_SLACK (no more objects
    than the offenders); and how many of the removed went for the mix."""
    keep = offenders_kept(typ, volumes, bad_pairs, bad_wall, shares, max_tvd, alive=alive)
    before = np.ones(len(typ), bool) if alive is None else alive.astype(bool)
    offenders = int((before & ~keep).sum())
    if shares is None or offenders == 0:
        return keep, 0
    left = np.flatnonzero(keep)
    trim = left[mix_trim(typ[left], volumes, shares, max_tvd + MIX_SLACK, most=offenders)]
    keep[trim] = False
    return keep, len(trim)


def offenders_kept(typ: np.ndarray, volumes: np.ndarray,
                   bad_pairs: Sequence[tuple[int, int]], bad_wall: Sequence[int],
                   shares: np.ndarray | None = None, max_tvd: float = 0.0, *,
                   alive: np.ndarray | None = None) -> np.ndarray:
    """Mask of the objects (N,) kept when a certificate's offenders are removed.

    Each object through the wall goes first (that also settles its pairs); then, of each
    failing pair whose objects are both still kept, the smaller goes (the second on a tie),
    unless that leaves the type mix's TVD (by count, against `shares`) above `max_tvd` and
    removing the other leaves it lower. Always removing the smaller object removes the
    smallest type again and again, and the TVD ended above 0.05 (docs/notes-core.md).
    typ: (N,) type of each object; volumes: (T,) each type's volume; alive: (N,) bool,
    objects already gone (default: none).
    """
    keep = np.ones(len(typ), bool) if alive is None else alive.astype(bool).copy()
    counts = np.bincount(typ[keep], minlength=len(volumes)).astype(np.int64)

    def drop(k: int) -> None:
        keep[k] = False
        counts[typ[k]] -= 1

    for i in bad_wall:
        if keep[i]:
            drop(i)
    for i, j in bad_pairs:
        if not (keep[i] and keep[j]):
            continue
        small, big = (j, i) if volumes[typ[j]] <= volumes[typ[i]] else (i, j)
        if shares is not None and typ[small] != typ[big]:
            t_small = _tvd_one_fewer(counts, shares, typ[small])
            if t_small > max_tvd and _tvd_one_fewer(counts, shares, typ[big]) < t_small:
                small = big
        drop(small)
    return keep


def mix_trim(typ: np.ndarray, volumes: np.ndarray, shares: np.ndarray, target: float,
             most: int | None = None) -> np.ndarray:
    """Which objects (indices into typ (N,)) to remove so that the type mix's TVD (by count,
    against `shares` (T,)) comes down to `target`: one at a time, of the type whose removal
    lowers it most (the smaller type on a tie), the last such object, while a removal still
    lowers it and at most `most` of them. With few objects, where one object moves the TVD
    by about 1/n, it stops within one object of the best mix n objects allow (as the cavity
    passes' cap does). Removing the repair's offenders can leave the mix worse than the
    placement did, whatever their choice (objects through the wall must go); the caller
    caps the trim at as many objects as that removed, so that a mix the removals spoilt
    badly costs no more than twice their objects."""
    counts = np.bincount(typ, minlength=len(volumes)).astype(np.int64)
    order = [list(np.flatnonzero(typ == t)) for t in range(len(volumes))]
    now = tvd_of_counts(counts, shares)
    out: list[int] = []

    def allowed() -> float:
        n = int(counts.sum())
        return max(target, best_tvd(shares, n) + 1.0 / n) if n else target

    while now > allowed() + 1e-12 and (most is None or len(out) < most):
        best, best_t = now, -1
        for t in np.argsort(volumes, kind="stable"):
            if counts[t] == 0:
                continue
            after = _tvd_one_fewer(counts, shares, t)
            if after < best - 1e-12:
                best, best_t = after, int(t)
        if best_t < 0:
            break
        out.append(int(order[best_t].pop()))
        counts[best_t] -= 1
        now = best
    return np.array(sorted(out), np.int64)


def _tvd_one_fewer(counts: np.ndarray, shares: np.ndarray, t: int) -> float:
    """The TVD of `counts` (T,) with one object of type t fewer."""
    fewer = counts.copy()
    fewer[t] -= 1
    return tvd_of_counts(fewer, shares)
