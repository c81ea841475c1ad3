"""Phase 1's tries and successes per type, and the types it gives up on.

Phase 1 gives each lattice object the type the mix lacks most, so a type that (almost)
never grows is always the one lacking, takes nearly every object and fails, and the others
wait (docs/notes-core.md). A type that grew in at most one in RATIO of its tries, where the
other types grew in most of theirs, is given up for the rest of the attempt; the others
then pack at their shares among themselves. Until the others have tried GIVE_UP_TRIES times
their success rate is unknown: a suspect type then waits while they try, and is judged on
their tries so far where the lattice runs out first.
"""

from __future__ import annotations

import numpy as np

#: the tries of a type, and of the others together, before a type can be given up
GIVE_UP_TRIES = 10
#: a type is given up where (its successes + 1) x RATIO is below its tries x the others'
#: success rate: ten times less likely to grow than the others, counting one success more
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

    def record(self, t: int, grew: bool) -> None:
        """One growth of type t ended, full size or not; gives up each type that fails so."""
        self.tries[t] += 1
        self.grown[t] += int(grew)
        if (self.grown[t] + 1) * RATIO < self.tries[t] and self.tries[t] >= GIVE_UP_TRIES:
            self.failing.add(t)
        else:
            self.failing.discard(t)
        for u in sorted(self.failing):
            if self._suspect(u) and self._others_tried(u) >= GIVE_UP_TRIES:
                self._give_up(u)

    def finish(self) -> None:
        """Phase 1 ran out of lattice objects: a type still waiting for the others' tries
        is judged on those they had."""
        for u in sorted(self.failing):
            if self._suspect(u):
                self._give_up(u)

    def shares_now(self) -> np.ndarray:
        """The (T,) shares phase 1 types its next object by: zero for the given-up types
        and for suspects while the others have not tried enough (never all zero)."""
        if not self.failing and not self.given_up.any():
            return self.shares
        waiting = self.given_up.copy()
        for t in np.flatnonzero(~self.given_up & (self.shares > 0)):
            if self._suspect(t) and self._others_tried(t) < GIVE_UP_TRIES:
                waiting[t] = True
        if not waiting.any():
            return self.shares
        q = np.where(waiting, 0.0, self.shares)
        if q.sum() <= 0:
            return self.placement_shares()
        return q / q.sum()

    def placement_shares(self) -> np.ndarray:
        """The (T,) shares the rest of the attempt packs for: the given-up types at 0."""
        return shares_without(self.shares, self.records)

    def report(self) -> list[dict]:
        """The given-up types as JSON-ready records: type, its tries and how many grew, and
        the same of the other types it was judged against, when it was given up."""
        return [dict(r) for r in self.records]

    def _give_up(self, t: int) -> None:
        others = self._others(t)
        self.records.append({"type": int(t), "tries": int(self.tries[t]),
                             "grown": int(self.grown[t]),
                             "others_tries": int(self.tries[others].sum()),
                             "others_grown": int(self.grown[others].sum())})
        self.given_up[t] = True
        self.failing.discard(t)

    def _others(self, t: int) -> np.ndarray:
        live = (self.shares > 0) & ~self.given_up
        live[t] = False
        return live

    def _others_tried(self, t: int) -> int:
        return int(self.tries[self._others(t)].sum())

    def _suspect(self, t: int) -> bool:
        """t failed so often against the others' rate (1 before they tried) that it may
        never grow; never the last type with a share."""
        others = self._others(t)
        if not others.any() or self.tries[t] < GIVE_UP_TRIES:
            return False
        rate = (self.grown[others].sum() + 1) / (self.tries[others].sum() + 1)
        return (self.grown[t] + 1) * RATIO < self.tries[t] * rate


def shares_without(shares: np.ndarray, given_up: list[dict]) -> np.ndarray:
    """The (T,) shares less the types of the `given_up` records (`TypeFailures.report`),
    renormalised; the shares themselves where none is."""
    if not given_up:
        return shares
    q = np.asarray(shares, np.float64).copy()
    q[[g["type"] for g in given_up]] = 0.0
    return q / q.sum() if q.sum() > 0 else np.asarray(shares, np.float64)
