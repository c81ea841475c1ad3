"""What a finished packing should tell the user to act on, beyond its numbers: a type asked
for and never placed, a type mix far from the shares, a time budget that ended before the
first objects had grown, fewer attempts than asked. Pure: counts and reports in, sentences
out (`RunReport.warnings`; the command line prints them)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .metrics import best_tvd, tvd_of_counts
from .report import PhaseStats

#: what fits a type the container cannot hold, in the command line's and the API's words
SCALE = ("scale the objects down (--type-scale / type_scale), the container up "
         "(--container-size / container_size), or remove the type.")
#: cavity passes the time budget ended before they ran this share of it count as not run
PASSES_CUT = 0.1
#: how far above the mix tolerance (or the best TVD the count allows) a packing's TVD may be
#: before the mix is reported off; the cavity passes keep it within the tolerance, and the
#: repair's removals may add up to 0.01 (`core/repair.py` MIX_SLACK)
MIX_WARN_SLACK = 0.01


def run_warnings(names: Sequence[str], shares: np.ndarray, counts: np.ndarray, tvd: float,
                 max_tvd: float, phase1: PhaseStats, time_budget: float | None,
                 stopped: str | None, attempts_asked: int | None,
                 attempts_run: int, extra_passes_ran: bool = True,
                 left_out: Sequence[tuple[int, float, float, str]] = (),
                 clearance: float = 0.0, fidelity: str = "",
                 given_up: Sequence[dict] = (), mix_held: int = 0,
                 passes_seconds: float | None = None) -> list[str]:
    """Warnings for a packing of counts (T,) objects per type against shares (T,) summing
    to 1, whose TVD is `tvd` (the mix tolerance `max_tvd`); `phase1` is the kept attempt's
    first phase and `extra_passes_ran` whether any of its extra cavity passes started;
    `stopped` the run's stop reason ("deadline", "cancelled" or None); `attempts_asked`
    None when the count of attempts was left to the budget; `left_out` the types the run
    packed without, as (type, need, the container's, "depth" or "length")
    (`room.out_of_reach`), with the run's `clearance` (container units) and `fidelity`
    (the preset it used); `given_up` the types the kept attempt gave up
    (`placement.Attempt.given_up`). The mix is judged among the other types. `mix_held`:
    the holes where the kept attempt's mix refused a type that fit (`phases.phase2`).
    `passes_seconds`: how long its cavity passes ran (s); under PASSES_CUT of the budget,
    cut by it, they count as not run."""
    out = []
    missing = [i for i, (s, c) in enumerate(zip(shares, counts, strict=True))
               if s > 0 and c == 0]
    plus = " and the clearance" if clearance > 0 else ""
    scale_up = SCALE[:1].upper() + SCALE[1:]
    for i, need, has, why in left_out:
        if why == "length":
            ends = " with the clearance at both ends" if clearance > 0 else ""
            lacks = (f"it is {need:.4g} units long{ends}, longer than the container is across "
                     f"({has:.4g}, its box's diagonal), so it fits in no orientation")
            advice = scale_up
        else:
            lacks = (f"with its contact margins{plus} it needs at least {need:.4g} units of "
                     f"depth, and the container's deepest point is about {has:.4g} from its "
                     "wall, so the engine can place it nowhere")
            advice = (scale_up if fidelity == "high" else
                      "--fidelity high / fidelity='high' (finer grids, smaller margins) may "
                      f"place it; or {SCALE}")
        out.append(f"type {names[i]} (share {shares[i]:.0%}) was left out: {lacks}; the other "
                   f"types were packed at their shares among themselves. {advice}")
    for g in given_up:
        i = g["type"]
        if g.get("restarted"):
            first = (f"none of its {g['tries']} tries in the first phase grew, nor one in "
                     "the cavity passes" if g["tries"] else
                     "the first phase tried none of it, and no cavity pass placed one")
            why = (f"{first}, while the mix held the other types back from holes they fit, "
                   "so the packing started again without it")
        else:
            why = (f"in the first phase {g['grown']} of its {g['tries']} tries grew, "
                   f"against {g['against_grown']} of {g['against_tries']} of "
                   f"{names[g['against']]}'s")
        out.append(
            f"type {names[i]} (share {shares[i]:.0%}) was given up: {why}. It fits the "
            "container in few places or orientations, or only where the others already are "
            f"({int(counts[i])} placed); the other types were packed at their shares among "
            f"themselves. {scale_up}")
    said = {i for i, *_ in left_out} | {g["type"] for g in given_up}
    if counts.sum() > 0:
        for i in [i for i in missing if i not in said]:
            out.append(
                f"type {names[i]} (share {shares[i]:.0%}) was not placed at all: it may not "
                "fit the container in any orientation, or only where the other types already "
                f"are. {scale_up}")
    rest = [i for i in range(len(shares)) if i not in said]
    if said and shares[rest].sum() > 0:  # the mix of the others, at their shares
        names = [names[i] for i in rest]
        shares = shares[rest] / shares[rest].sum()
        counts = counts[rest]
        missing = [rest.index(i) for i in missing if i in rest]
        tvd = tvd_of_counts(counts, shares) if counts.sum() > 0 else 0.0
    allowed = max(max_tvd, best_tvd(shares, int(counts.sum()))) + MIX_WARN_SLACK
    if not missing and counts.sum() > 0 and tvd > allowed:
        placed = ", ".join(f"{n} {c / counts.sum():.0%} (asked {s:.0%})"
                           for n, c, s in zip(names, counts, shares, strict=True))
        among = " among the other types" if said else ""
        out.append(f"the type mix{among} is off: TVD {tvd:.3f} against the tolerance "
                   f"{max_tvd:g}; placed {placed}. "
                   + _mix_advice(names, shares, counts, tvd, max_tvd, mix_held))
    elif not missing and counts.sum() > 0:
        out += _types_far_short(names, shares, counts, tvd, max_tvd, mix_held)
    cut_short = (passes_seconds is not None and time_budget is not None
                 and passes_seconds < PASSES_CUT * time_budget)
    if phase1.stopped == "deadline":
        out.append(
            f"the time budget ({time_budget:g} s) ended while the first objects were still "
            f"growing: {phase1.grown} of {phase1.inserted} grew, and the cavity passes did not "
            "run, so the container is far from full. Give a larger --time-budget / "
            "time_budget, or none.")
    elif (stopped == "deadline" and (not extra_passes_ran or cut_short)
          and phase1.extra.get("lattice") != "stacked"):  # rows leave slivers, not holes
        when = (f"{passes_seconds:.3g} s into the cavity passes" if extra_passes_ran
                else "before the cavity passes ran")
        out.append(
            f"the time budget ({time_budget:g} s) ended {when}: the "
            f"first objects grew ({phase1.grown} of {phase1.inserted}), but the holes between "
            "them were left unfilled, so the container is far from full. Give a larger "
            "--time-budget / time_budget, or none.")
    if stopped == "deadline" and attempts_asked is not None \
            and attempts_run < attempts_asked:
        out.append(
            f"{attempts_run} of the {attempts_asked} attempts asked for ran before the time "
            "budget ended; the same attempts give the same packing only when all of them "
            "run. Give a larger --time-budget / time_budget, or none.")
    return out


#: certification longer than this (s) and than the time budget, with a type of more faces
#: than HEAVY_FACES, gets a word on the faces
SLOW_CERTIFY = 30.0
HEAVY_FACES = 20_000


def slow_certification(seconds: float, time_budget: float | None, names: Sequence[str],
                       faces: Sequence[int]) -> list[str]:
    """A warning when certification (``seconds``) ran long beside the time budget, which
    bounds placement only, and a type's mesh (``faces`` per type) is what makes the exact
    checks slow."""
    if seconds <= max(SLOW_CERTIFY, time_budget or 0.0) or not len(faces):
        return []
    heavy = int(np.argmax(faces))
    if faces[heavy] <= HEAVY_FACES:
        return []
    budget = (f" (the time budget, {time_budget:g} s, bounds placement only)"
              if time_budget else "")
    return [f"certification took {seconds:.0f} s{budget}: type {names[heavy]} has "
            f"{faces[heavy]:,} faces, and the exact checks' time grows with them. A copy "
            "simplified to a few thousand faces (Blender: Decimate modifier) certifies far "
            "faster and looks the same in print at most sizes."]


#: a type placed at less than this fraction of its share is said even where the TVD is
#: within the tolerance (a small share far short moves the TVD little) ...
SHORT_SHARE = 0.5
#: ... when its share of the count is at least this many objects
SHORT_OBJECTS = 4


def _types_far_short(names: Sequence[str], shares: np.ndarray, counts: np.ndarray,
                     tvd: float, max_tvd: float, mix_held: int = 0) -> list[str]:
    """A warning naming the types whose share of the placed objects is below SHORT_SHARE of
    their target share, where the mix as a whole (its TVD) is not reported off."""
    n = int(counts.sum())
    short = [i for i, (s, c) in enumerate(zip(shares, counts, strict=True))
             if s * n >= SHORT_OBJECTS and c < SHORT_SHARE * s * n]
    if not short:
        return []
    said = ", ".join(f"{names[i]} {counts[i] / n:.1%} ({int(counts[i])} of {n:,}) against "
                     f"the {shares[i]:.1%} asked" for i in short)
    near = "within" if tvd <= max_tvd + 1e-12 else "close to"
    return [f"{'a type is' if len(short) == 1 else 'types are'} placed far below the share "
            f"asked: {said}. The mix as a whole is {near} the tolerance (TVD {tvd:.3f}, "
            f"tolerance {max_tvd:g}), as the other types make up the count. "
            + _room_advice(max_tvd, mix_held)]


def _room_advice(max_tvd: float, mix_held: int = 0) -> str:
    """What fits more of the types short of their share, and (with a tolerance above 0)
    what holds the others back; where the mix held them back from holes (`mix_held` > 0),
    also what lets them fill those."""
    hold = ("; a smaller mix tolerance (--mix-tolerance) holds the other types back to "
            "their shares, with fewer objects (far fewer where the short types find little "
            "room)" if max_tvd > 0 else "")
    if mix_held > 0 and max_tvd < 1:
        larger = "a larger one" if max_tvd > 0 else "a mix tolerance above 0 (--mix-tolerance)"
        hold += _fill_held(larger)
    return ("Smaller objects of the short types (--type-scale / type_scale) or a larger "
            f"container (--container-size / container_size) fit more of them{hold}.")


def _fill_held(larger: str) -> str:
    """The advice clause that names `larger`, a larger mix tolerance, for the holes the
    mix held the other types back from."""
    return (f"; {larger} lets the other types fill the holes the mix held them back from, "
            "further from the shares")


def _mix_advice(names: Sequence[str], shares: np.ndarray, counts: np.ndarray, tvd: float,
                max_tvd: float, mix_held: int = 0) -> str:
    """How to bring an off mix back, by its cause: with few objects the cavity passes may
    take one object beyond the best mix the count allows (`metrics.mix_cap`), which a zero
    tolerance does not; otherwise the types short of their share found no room."""
    n = int(counts.sum())
    if max_tvd > 0 and tvd <= best_tvd(shares, n) + 1.0 / n + 1e-9:
        larger = (_fill_held("a larger one (--mix-tolerance)") if mix_held > 0 and max_tvd < 1
                  else "")
        return (f"With {n} objects one object moves the mix by about {1.0 / n:.2f}, and the "
                "cavity passes may take one more object of a type to fill a hole; a mix "
                "tolerance of 0 (--mix-tolerance 0) keeps the mix as close as the count "
                "allows, at the cost of the objects the mix cannot take (in a small scene, "
                f"maybe several){larger}.")
    short = [names[i] for i in np.flatnonzero(counts / n < shares - 1e-12)]
    return f"The types short of their share ({', '.join(short)}) found no more room. " \
        + _room_advice(max_tvd, mix_held)
