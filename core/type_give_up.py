"""Phase 1's tries and successes per type, and the types it gives up on.

Phase 1 gives each lattice object the type the mix lacks most, so a type that (almost)
never grows is always the one lacking, takes nearly every object and fails, and the others
wait (docs/notes-core.md). A type that grew in at most one in RATIO of its tries, where
another type grew in most of its own, is given up for the rest of the attempt; the others
then pack at their shares among themselves. Until that type has tried GIVE_UP_TRIES times
its success rate is unknown: a suspect type then waits while the others try, and is judged
on their tries so far where the lattice runs out first.
"""

from __future__ import annotations

import numpy as np

#: a type that tried this often in phase 1 and never grew, nor in a later pass, may be left
#: out of the attempt, which then starts again (a large type's lattice may hold two points)
NEVER_GREW_TRIES = 1
#: the tries of a type, and of the type it is judged against, before it can be given up
GIVE_UP_TRIES = 10
#: a type is given up where (its successes + 1) x RATIO is below its tries x the success
#: rate of the other type that grows most often: ten times less likely to grow, counting
#: one success more
RATIO = 10.0


class TypeFailures:
    """Tries and successes of each of T types in phase 1; which types it stopped trying."""

    def __init__(self, shares: np.ndarray):
        self.shares = np.asarray(shares, np.float64)
        n = len(self.shares)
        self.tries = np.zeros(n, np.int64)
        self.grown = np.zeros(n, np.int64)
        self.given_up = np.zeros(n, bool)
        #: the given-up types' records (`report`), as they stood when each was given up
        self.records: list[dict] = []
        #: types that failed so often that they are suspects at any rate of the others,
        #: not given up: phase 1 calls this for every object, so it is cheap while none is
        self.failing: set[int] = set()
        self._placement = self.shares  # `placement_shares`, kept for `shares_now`

    def record(self, t: int, grew: bool) -> None:
        """One growth of type t ended, full size or not; gives up each type that fails so."""
        self.tries[t] += 1
        self.grown[t] += int(grew)
        if (self.grown[t] + 1) * RATIO < self.tries[t] and self.tries[t] >= GIVE_UP_TRIES:
            self.failing.add(t)
        else:
            self.failing.discard(t)
        for u in sorted(self.failing):
            if self._suspect(u) and self._judged(u):
                self._give_up(u)

    def finish(self) -> None:
        """Phase 1 ran out of lattice objects: a type still waiting for the others' tries
        is judged on those they had, against a type that tried, where one of them grew."""
        for u in sorted(self.failing):
            if self._suspect(u, tried=True) and self.grown[self._others(u)].sum() > 0:
                self._give_up(u, tried=True)

    def shares_now(self) -> np.ndarray:
        """The (T,) shares phase 1 types its next object by: zero for the given-up types
        and for suspects while the type they are judged against has not tried enough
        (never all zero)."""
        waiting = [t for t in sorted(self.failing) if self._suspect(t) and not self._judged(t)]
        if not waiting:  # suspects are failing types: most objects end here
            return self._placement
        q = self._placement.copy()
        q[waiting] = 0.0
        if q.sum() <= 0:
            return self._placement
        return q / q.sum()

    def never_grew(self) -> list[list[int]]:
        """[type, tries] of the types not given up that tried at least NEVER_GREW_TRIES
        times and never grew: where no later pass grows one either, the attempt may start
        again without them (`placement.place_once`)."""
        return [[int(t), int(self.tries[t])] for t in range(len(self.shares))
                if not self.given_up[t] and self.tries[t] >= NEVER_GREW_TRIES
                and self.grown[t] == 0]

    def placement_shares(self) -> np.ndarray:
        """The (T,) shares the rest of the attempt packs for: the given-up types at 0."""
        return shares_without(self.shares, self.records)

    def report(self) -> list[dict]:
        """The given-up types as JSON-ready records: type, its tries and how many grew, and
        the type it was judged against ("against") with the same, when it was given up."""
        return [dict(r) for r in self.records]

    def _give_up(self, t: int, tried: bool = False) -> None:
        u = self._best_other(t, tried)
        self.records.append({"type": int(t), "tries": int(self.tries[t]),
                             "grown": int(self.grown[t]), "against": u,
                             "against_tries": int(self.tries[u]),
                             "against_grown": int(self.grown[u])})
        self.given_up[t] = True
        self.failing.discard(t)
        self._placement = self.placement_shares()

    def _others(self, t: int) -> np.ndarray:
        live = (self.shares > 0) & ~self.given_up
        live[t] = False
        return live

    def _judged(self, t: int) -> bool:
        """The type t is judged against has tried enough for its rate to count."""
        return bool(self.tries[self._best_other(t)] >= GIVE_UP_TRIES)

    def _rate(self, t: int) -> float:
        return float(self.grown[t] + 1) / float(self.tries[t] + 1)  # 1 before any try

    def _best_other(self, t: int, tried: bool = False) -> int:
        """The other type with a share, not given up, that grows most often (of those as
        often, the one tried most); with `tried`, of those that tried (t's first other
        where none did)."""
        others = np.flatnonzero(self._others(t))
        if tried and (self.tries[others] > 0).any():
            others = others[self.tries[others] > 0]
        return int(max(others, key=lambda u: (self._rate(u), self.tries[u], -u)))

    def _suspect(self, t: int, tried: bool = False) -> bool:
        """t failed so often against the other type that grows most often that it may
        never grow; never the last type with a share. Against the best, not all the others
        together: two types that never grow would otherwise shield each other."""
        if not self._others(t).any() or self.tries[t] < GIVE_UP_TRIES:
            return False
        u = self._best_other(t, tried)
        return (self.grown[t] + 1) * RATIO < self.tries[t] * self._rate(u)


def shares_without(shares: np.ndarray, given_up: list[dict]) -> np.ndarray:
    """The (T,) shares less the types of the `given_up` records (`TypeFailures.report`),
    renormalised; the shares themselves where none is."""
    if not given_up:
        return shares
    q = np.asarray(shares, np.float64).copy()
    q[[g["type"] for g in given_up]] = 0.0
    return q / q.sum() if q.sum() > 0 else np.asarray(shares, np.float64)
