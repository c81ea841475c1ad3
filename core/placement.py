"""Placement: phase 1, phase 2 and the extra cavity rounds, as independent attempts.

One attempt runs the phases on a fresh state (container frame, container units). With a
time budget, an attempt often ends before it: its rounds of cavity passes stop adding
objects. The time left then goes to new attempts from scratch (each its own random
stream), as long as it is at least the shortest attempt so far, and the densest attempt is
kept: attempts end at densities that differ by points between random streams (fruit in the
torus: 43.0-49.4% over five attempts; in the knight 49.9% and 53.3%).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .metrics import compute_metrics
from .phases import Stop, phase1, phase2
from .solver import PackState, Solver

if TYPE_CHECKING:
    from .api import PackParams


@dataclass
class Attempt:
    """One run of the phases: its solver (and state), statistics and wall times (s)."""

    solver: Solver
    density: float  # full-size objects' volume over the container's, before certification
    after: dict = field(default_factory=dict)  # metrics after phase 1, phase 2, extra
    stats: dict = field(default_factory=dict)  # phase1, phase2, extra_passes
    timings: dict = field(default_factory=dict)  # phase1, phase2, extra

    def summary(self) -> dict:
        return {"density": self.density, "count": self.after["after_extra"]["count"],
                "seconds": sum(self.timings.values()), **{k: self.timings[k] for k in
                                                          ("phase1", "phase2", "extra")}}


def snapshot_metrics(state: PackState, volume: np.ndarray, q: np.ndarray,
                     c_volume: float) -> dict:
    """Count, density, TVD and mean NNI of the full-size alive objects."""
    idx = np.flatnonzero(state.alive[: state.n] & (state.scale[: state.n] >= 1.0))
    m = compute_metrics(state.typ[idx], state.pos[idx], volume, q, c_volume)
    return {k: m[k] for k in ("count", "density", "tvd", "nni_mean")}


def place_once(solver: Solver, q: np.ndarray, s1: float, f_min: float,
               rng: np.random.Generator, stop: Stop, margin: np.ndarray, params: PackParams,
               c_volume: float, budgeted: bool,
               report: Callable[[float, str], None]) -> Attempt:
    """Phase 1, phase 2 and the extra cavity passes on `solver`'s (empty) state.

    q: (T,) target shares; s1: phase 1's lattice spacing; f_min: the smallest type's
    equivalent radius (container units); margin: (T,) contact margins. With `budgeted`,
    the extra passes run again on new lattices while a round adds objects.
    """
    vol = solver.t.volume
    t0 = time.perf_counter()
    st1 = phase1(solver, q, s1, rng, stop, iters=params.phase1_iterations, margin=margin,
                 growth_steps=params.phase1_growth_steps,
                 progress=lambda f, m: report(0.05 + 0.55 * f, m))
    after1 = snapshot_metrics(solver.s, vol, q, c_volume)
    t1 = time.perf_counter()
    st2 = phase2(solver, q, s1 * params.phase2_spacing, rng, stop,
                 iters=params.phase2_iterations, margin=margin, retries=params.phase2_retries,
                 progress=lambda f, m: report(0.6 + 0.2 * f, m))
    after2 = snapshot_metrics(solver.s, vol, q, c_volume)
    t2 = time.perf_counter()
    # beyond the paper: further cavity passes at lower thresholds (objects grown there push
    # their neighbours aside), while the time budget allows. Each pass ends after
    # `extra_patience` fruitless points; with time left, the passes run again on freshly
    # jittered lattices (other holes), for as long as a round still adds objects.
    extra = []
    n_extra = max(len(params.extra_passes), 1)
    rounds = params.extra_rounds if budgeted else 1
    for rnd in range(rounds):
        grown = 0
        for i, factor in enumerate(params.extra_passes):
            if stop():
                break
            lo = 0.8 + 0.1 * (i + rnd * n_extra) / (n_extra * rounds)
            st = phase2(
                solver, q, s1 * params.phase2_spacing * factor, rng, stop,
                iters=params.extra_iterations, margin=margin, retries=params.extra_retries,
                growth_steps=params.extra_growth_steps,
                threshold=factor * f_min, fit_factor=factor, patience=params.extra_patience,
                max_tvd=params.extra_max_tvd,
                progress=lambda f, m, lo=lo: report(lo + 0.1 * f / (n_extra * rounds), m))
            grown += st.grown
            extra.append({**asdict(st), "round": rnd, "factor": factor})
        if grown == 0 or stop():
            break
    after3 = snapshot_metrics(solver.s, vol, q, c_volume)
    t3 = time.perf_counter()
    return Attempt(
        solver=solver, density=after3["density"],
        after={"after_phase1": after1, "after_phase2": after2, "after_extra": after3},
        stats={"phase1": asdict(st1), "phase2": asdict(st2), "extra_passes": extra},
        timings={"phase1": t1 - t0, "phase2": t2 - t1, "extra": t3 - t2})


def place(new_solver: Callable[[], Solver], q: np.ndarray, s1: float, f_min: float,
          seed: int, stop: Stop, margin: np.ndarray, params: PackParams, c_volume: float,
          report: Callable[[float, str], None]) -> tuple[Attempt, list[dict]]:
    """Attempts of `place_once`, each on a fresh solver from `new_solver()`; returns the
    densest and a summary of every attempt. Without a deadline there is one attempt. The
    first uses the random stream of `seed` itself, attempt a > 0 that of (seed, a).
    """
    best: Attempt | None = None
    done: list[dict] = []
    shortest = np.inf
    high = 0.0  # the progress bar never runs backwards across attempts

    def monotone(fraction: float, message: str) -> None:
        nonlocal high
        high = max(high, fraction)
        report(high, message if not done else f"attempt {len(done) + 1}: {message}")

    while True:
        rng = np.random.default_rng(seed if not done else [seed, len(done)])
        t0 = time.perf_counter()
        att = place_once(new_solver(), q, s1, f_min, rng, stop, margin, params, c_volume,
                         stop.deadline is not None, monotone)
        shortest = min(shortest, time.perf_counter() - t0)
        done.append({**att.summary(), "stopped": stop.reason or None})
        if best is None or att.density > best.density:
            best = att
        if (stop.deadline is None or stop() or len(done) >= params.max_attempts
                or stop.deadline - time.perf_counter() < shortest):
            return best, done
