"""What a packing was asked for (`PackInputs`) and what its run did (`RunReport`), as types.

Lengths in container units, times in seconds. `Packing.inputs` and `Packing.report` hold
them; the JSON file (version 2) writes them as its "inputs" and "report" sections.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .fidelity import Fidelity
from .options import PackOptions

#: a progress message starting with this is advice to keep in view (the command line prints
#: it as a note), not the stage the run is at
NOTE_PREFIX = "note: "


@dataclass(frozen=True)
class PackInputs:
    """The arguments of `pack()` that shaped the packing (besides meshes, shares, seed)."""

    clearance: float = 0.0  # minimum gap between objects and to the wall
    time_budget: float | None = None  # seconds for placement; None: no budget
    container_size: float | None = None  # container's largest extent after scaling
    type_scale: float = 1.0  # factor on the object files' coordinates
    fidelity: str = "auto"  # as requested: auto, low, medium or high
    options: PackOptions = field(default_factory=PackOptions)


@dataclass
class PhaseStats:
    """What a phase did: tries, successes, removals, wall time (s)."""

    inserted: int = 0
    grown: int = 0
    failed: int = 0
    seconds: float = 0.0
    stopped: str = ""  # "", "deadline", "cancelled" or "patience"
    # phase 1: growth_steps, lattice, given_up, never_grew; phase 2: candidates, threshold,
    # mix_held
    extra: dict = field(default_factory=dict)


@dataclass
class ExtraPassStats(PhaseStats):
    """One cavity pass beyond the paper: its round and threshold factor."""

    round: int = 0
    factor: float = 0.0


@dataclass
class AttemptSummary:
    """One attempt of the placement: density and count before certification, wall times;
    for an attempt certified (the densest, and a runner-up where the repair left less), the
    density after certification, and whether it was kept."""

    density: float = 0.0
    count: int = 0
    seconds: float = 0.0
    phase1: float = 0.0
    phase2: float = 0.0
    extra: float = 0.0
    stopped: str | None = None
    certified: float | None = None
    kept: bool = False


@dataclass
class MarginReport:
    """The contact margins chosen (`core/margins.py`): in grid cells, with the grid
    errors (cells) that chose them and, with a clearance, each type's sampling gap."""

    object_cells: list[float] = field(default_factory=list)
    wall_cells: float = 0.0
    object_grid_errors_cells: list[float] = field(default_factory=list)
    container_grid_error_cells: float = 0.0
    sampling_gaps: list[float] | None = None


@dataclass
class RepairStats:
    """Certify-and-repair (`core/repair.py`): push-apart rounds, objects moved and removed
    (`for_mix` of them to bring the type mix back within the tolerance), the certificate
    before any repair, and whether the push-apart time cap was reached."""

    rounds: int = 0
    moved: int = 0
    removed: int = 0
    for_mix: int = 0
    first: dict | None = None
    timed_out: bool = False


@dataclass
class ThreadReport:
    """The thread tuner (`core/threads.py`): thread counts used and for how long."""

    most: int = 1
    switches: int = 0
    probes: int = 0
    seconds_by_threads: dict[str, float] = field(default_factory=dict)


@dataclass
class RunReport:
    """What one run of `pack()` did."""

    fidelity: str = ""  # the fidelity used
    fidelity_detail: Fidelity | None = None
    stopped: str | None = None  # "deadline" or "cancelled"; None: ran to the end
    container_grid_spacing: float = 0.0
    phase1_spacing: float = 0.0  # phase 1 lattice spacing
    spheres_per_type: list[int] = field(default_factory=list)
    surface_points_per_type: list[int] = field(default_factory=list)
    sphere_coverage_per_type: list[float | None] = field(default_factory=list)
    phase1: PhaseStats = field(default_factory=PhaseStats)  # of the attempt kept
    phase2: PhaseStats = field(default_factory=PhaseStats)
    extra_passes: list[ExtraPassStats] = field(default_factory=list)
    attempts: list[AttemptSummary] = field(default_factory=list)
    margins: MarginReport = field(default_factory=MarginReport)
    repair: RepairStats = field(default_factory=RepairStats)
    threads: ThreadReport | None = None
    warnings: list[str] = field(default_factory=list)
    #: the types the kept attempt gave up (`placement.Attempt.given_up`): type, tries and
    #: grown in phase 1 ("restarted": no pass grew one, and the attempt started again)
    given_up: list[dict] = field(default_factory=list)
