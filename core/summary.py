"""What a packing's summary shows, as plain values: one source for the CLI and the add-on.

`summarize(packing)` reads only what the packing holds (metrics, certificate, inputs, report,
timings), so a packing loaded from a file summarises the same as one fresh from `pack()`.
Metrics and certificate are free dicts in a file: a value of the wrong kind reads as missing
(None), never as an error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .fidelity import Fidelity
from .packing_digest import only_clearance_changed, placements_status
from .packing_types import Packing
from .report import AttemptSummary, RepairStats


def number(value: Any) -> float | None:
    """`value` as a finite float, or None (missing, not a number, NaN or infinite)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        return None
    try:
        f = float(value)
    except (OverflowError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _count(value: Any) -> int | None:
    f = number(value)
    return None if f is None or f != int(f) else int(f)


@dataclass(frozen=True)
class TypeLine:
    """One object type: its placed count, achieved and target share, Clark-Evans NNI."""

    name: str
    count: int
    share: float | None  # of the placed objects; None when nothing was placed
    target: float
    nni: float | None


@dataclass(frozen=True)
class PhaseLine:
    """One stage's wall time (s) and, where known, objects and density after it."""

    key: str  # "load", "phase1", ..., "total", or another timing's own name
    label: str
    seconds: float | None
    count: int | None
    density: float | None


#: timing key -> label, in the order a run goes through them
PHASE_LABELS = {"load": "load meshes", "approximate": "approximate",
                "compile": "compile kernels", "phase1": "1 place & grow",
                "phase2": "2 fill cavities", "extra": "more cavity passes",
                "other_attempts": "attempts not kept", "certify": "certify & repair"}
#: phase 1's label where the kept attempt started from the types stacked in rows
STACKED_LABEL = "1 stacked in rows"


@dataclass(frozen=True)
class PackingSummary:
    """A packing's summary (definitions: DESIGN.md). Numbers are None where unknown."""

    types: list[TypeLine]
    count: int
    density: float | None
    tvd: float | None
    nni_mean: float | None
    seed: int
    fidelity: str  # the fidelity used ("" when not recorded)
    fidelity_detail: Fidelity | None
    stopped: str | None  # "deadline", "cancelled" or None
    certified: bool | None
    tol: float | None
    clearance: float
    worst_overlap: float | None
    worst_outside: float | None
    min_pair_gap: float | None
    min_wall_gap: float | None
    pairs_checked: int | None
    walls_checked: int | None
    repair: RepairStats | None  # None when the packing records no repair
    attempts: list[AttemptSummary] = field(default_factory=list)
    kept_attempt: int | None = None  # index of the kept attempt
    phases: list[PhaseLine] = field(default_factory=list)
    total_seconds: float | None = None
    # "as certified", "changed" (edited after certification: the certificate no longer
    # applies), "clearance changed" (only the clearance asked was) or "unrecorded"
    # (`packing_digest.placements_status`)
    placements: str = "unrecorded"


def summarize(packing: Packing) -> PackingSummary:
    """The summary of a packing (see the module doc)."""
    m = packing.metrics if isinstance(packing.metrics, dict) else {}
    cert = packing.certificate if isinstance(packing.certificate, dict) else {}
    timings = packing.timings if isinstance(packing.timings, dict) else {}
    run = packing.report
    n_types = len(packing.types)
    counts = np.bincount(packing.type_index, minlength=n_types) if n_types else np.zeros(0)
    total = int(counts.sum())
    nni = m.get("nni_per_type")
    nni = list(nni) if isinstance(nni, list) else []
    nni += [None] * (n_types - len(nni))
    types = [TypeLine(rec.name, int(counts[t]), counts[t] / total if total else None,
                      rec.share, number(nni[t])) for t, rec in enumerate(packing.types)]
    certified = cert.get("certified")
    clearance = number(cert.get("clearance"))
    attempts = list(run.attempts)
    # files written before runner-ups were certified record no kept one: the densest was
    kept = next((i for i, a in enumerate(attempts) if a.kept), None)
    if kept is None and attempts:
        kept = max(range(len(attempts)), key=lambda i: attempts[i].density)
    repaired = run.repair != RepairStats() or run.repair.first is not None
    return PackingSummary(
        types=types, count=total, density=number(m.get("density")), tvd=number(m.get("tvd")),
        nni_mean=number(m.get("nni_mean")), seed=packing.seed, fidelity=run.fidelity,
        fidelity_detail=run.fidelity_detail, stopped=run.stopped,
        certified=certified if isinstance(certified, bool) else None,
        tol=number(cert.get("tol")),
        clearance=clearance if clearance is not None else packing.inputs.clearance,
        worst_overlap=number(cert.get("worst_overlap")),
        worst_outside=number(cert.get("worst_outside")),
        min_pair_gap=number(cert.get("min_pair_gap")),
        min_wall_gap=number(cert.get("min_wall_gap")),
        pairs_checked=_count(cert.get("pairs_checked")),
        walls_checked=_count(cert.get("walls_checked")),
        repair=run.repair if repaired else None, attempts=attempts, kept_attempt=kept,
        phases=_phase_lines(m, timings, total, isinstance(run.phase1.extra, dict)
                            and run.phase1.extra.get("lattice") == "stacked"),
        total_seconds=number(timings.get("total")),
        placements=("clearance changed" if only_clearance_changed(packing)
                    else placements_status(packing)))


def _phase_lines(m: dict, timings: dict, total: int, stacked: bool = False
                 ) -> list[PhaseLine]:
    """Each stage's time with the objects and density after it, in run order; other
    timings after them; the total last. stacked: phase 1 started from stacked rows."""
    def after(key: str) -> tuple[int | None, float | None]:
        snap = m.get(f"after_{key}") if key != "certify" else {
            "count": total, "density": m.get("density")}
        if not isinstance(snap, dict):
            return None, None
        return _count(snap.get("count")), number(snap.get("density"))

    labels = {**PHASE_LABELS, **({"phase1": STACKED_LABEL} if stacked else {})}
    lines = [PhaseLine(k, label, number(timings[k]), *after(k))
             for k, label in labels.items() if k in timings]
    lines += [PhaseLine(str(k), str(k), number(v), None, None) for k, v in timings.items()
              if k not in PHASE_LABELS and k != "total"]
    if "total" in timings:
        lines.append(PhaseLine("total", "total", number(timings["total"]), total,
                               number(m.get("density"))))
    return lines
