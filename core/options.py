"""The packing method's options: small frozen dataclasses, one concern each.

`PackOptions` gathers them; every default is the method's (the paper's where it has one).
Lengths are relative to object sizes unless a field says otherwise. Measurements behind the
defaults: docs/notes-core.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

from .errors import InputError


@dataclass(frozen=True)
class PhaseOptions:
    """Phase 1 (place & grow) and phase 2 (fill cavities), as in the paper."""

    phase1_density: float = 0.5  # lattice spacing = (mean type volume / this)^(1/3)
    # phase 1's lattice: "cubic" (the paper's, at phase1_density), "fcc" (face-centred
    # cubic at phase1_fcc_density), or None: cubic, and fcc where the cubic lattice holds
    # more than MANY_OBJECTS objects (`phases.phase1_lattice`). An fcc lattice keeps the
    # objects further apart at a higher count, so they grow without long pushes there
    phase1_lattice: str | None = None
    # the fcc lattice's objects' volume / container volume; None: 0.55, or 0.58 where the
    # cubic lattice holds more than 15,000 objects and 0.6 above 50,000
    # (`phases.phase1_fcc_density`)
    phase1_fcc_density: float | None = None
    phase1_iterations: int = 30  # solver iterations per growth step (paper: 25-30)
    # growth steps from scale 0 to 1; None: the paper's 30, or 6 with many objects
    # (`phases.phase1_growth_steps`)
    phase1_growth_steps: int | None = None
    phase2_spacing: float = 0.5  # phase 2 lattice spacing, fraction of phase 1's
    phase2_iterations: int = 80  # per growth step (paper: 55-150)
    phase2_retries: int = 2  # random smaller types tried after a failure
    # phase 1 grows, of the next this many lattice objects, the one furthest from the grown
    # objects of the type it takes (1: the paper's random order, which left each type's
    # clumping index near the bar; docs/notes-core.md)
    spread_window: int = 8

    def __post_init__(self) -> None:
        if self.phase1_lattice not in (None, "cubic", "fcc"):
            raise InputError(f"phase1_lattice must be 'cubic', 'fcc' or None (by the "
                             f"lattice's size), got {self.phase1_lattice!r}")
        d = self.phase1_fcc_density
        if d is not None and (isinstance(d, bool) or not isinstance(d, (int, float))
                              or not 0.0 < d < 1.0):
            raise InputError(f"phase1_fcc_density must be a fraction of the container "
                             f"between 0 and 1 (e.g. 0.55), or None (by the lattice's size), "
                             f"got {d!r}")


@dataclass(frozen=True)
class FidelityOverrides:
    """Overrides of the fidelity's choices (None: the fidelity decides; benchmarks sweep
    these)."""

    spheres: int | None = None  # inner spheres per type
    grid_cells: int | None = None  # object distance grid cells across its largest extent
    surface_points: int | None = None  # surface points per type
    container_cells: float | None = None  # container grid cells per smallest f(V)

    def given(self) -> dict[str, int | float]:
        """The overrides that are set, by name."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) is not None}


@dataclass(frozen=True)
class MarginOptions:
    """Contact margins beyond the clearance, in cells of the object's (the container's)
    grid, for surfaces the grid reproduces closely or not (`core/margins.py`): each costs
    density, too little leaves certification overlaps it cannot push apart."""

    safety: float = 0.025  # per object whose grid keeps its surface (smooth types)
    safety_sharp: float = 0.05  # per object with edges the grid rounds off
    wall_safety: float = 0.05  # extra wall distance, smooth container
    wall_safety_sharp: float = 0.1


@dataclass(frozen=True)
class CavityPassOptions:
    """Cavity passes beyond the paper: threshold = factor * smallest f(V), lattice spacing
    scaled by the factor too."""

    factors: tuple[float, ...] = (0.8, 0.6, 0.5, 0.4)
    retries: int = 1
    rounds: int = 8  # with a time budget: rounds of passes while they add objects
    patience: int = 60  # a pass ends after this many fruitless points in a row
    # no object is added that pushes TVD above this: late holes are small and the types
    # the mix then lacks are often the big ones that no longer fit, so a tighter cap ends
    # the passes with time left, a looser one gains nothing steady
    max_tvd: float = 0.04
    # objects here start at the free radius of their hole, so coarser growth steps cost
    # fewer solver calls per try
    growth_steps: int = 12
    iterations: int = 80  # solver iterations per growth step
    # a type is not tried in a hole where it would start below this scale (its free radius
    # over its bounding radius): such tries mostly fail, each after pushing the whole
    # packing through its growth steps. 0.4 helped a thin container with a clearance and
    # cost density elsewhere (docs/notes-core.md), so it is off unless asked for
    min_start: float = 0.0


@dataclass(frozen=True)
class AttemptOptions:
    """With a time budget: independent attempts while the time left is at least the
    shortest attempt so far; the densest is kept (`core/placement.py`). `count` asks for
    exactly that many attempts instead (with or without a budget), which a Dask cluster can
    run side by side (`core/cluster.py`)."""

    max_attempts: int = 8
    count: int | None = None  # None: one attempt without a budget, as many as fit with one


@dataclass(frozen=True)
class RepairOptions:
    """Certify -> push apart -> remove (`core/repair.py`)."""

    rounds: int = 3  # certify -> push apart rounds before removing offenders
    margin: float = 0.01  # margin added per round, fraction of bounding radius
    # solver iterations per push: a push in a jammed packing moves a chain of neighbours, and
    # 100 often ended before it settled, so the object was removed (docs/notes-core.md)
    iterations: int = 1000
    # ... but a push gives up when its deepest penetration has not fallen in this many
    # iterations: one that jams the whole packing then costs what 100 iterations did
    settle_every: int = 100
    seconds: float = 20.0  # push-apart cap with a time budget; what still fails is removed
    # worker processes for a long certification's exact checks (`core/check_pool.py`):
    # 0 one per core, 1 none; the results are the same either way
    processes: int = 0


@dataclass(frozen=True)
class PhysicsOptions:
    """The solver's stiffnesses and damping: the one place their defaults live."""

    k_obj: float = 1.0  # step per iteration / deepest object-object penetration
    k_wall: float = 1.05  # step per iteration / deepest wall penetration
    k_rot: float = 1.0  # rotation per iteration, as arc length at the bounding radius
    damping: float = 0.5  # velocity kept from one iteration to the next


@dataclass(frozen=True)
class PackOptions:
    """Every option of the method, by concern."""

    phases: PhaseOptions = field(default_factory=PhaseOptions)
    fidelity: FidelityOverrides = field(default_factory=FidelityOverrides)
    margins: MarginOptions = field(default_factory=MarginOptions)
    cavity: CavityPassOptions = field(default_factory=CavityPassOptions)
    attempts: AttemptOptions = field(default_factory=AttemptOptions)
    repair: RepairOptions = field(default_factory=RepairOptions)
    physics: PhysicsOptions = field(default_factory=PhysicsOptions)
    # time the contact tests on one thread against all of numba's and keep the faster
    # (`core/threads.py`); False: always all of them
    tune_threads: bool = True

    @classmethod
    def from_flat(cls, flat: Mapping[str, Any], *, strict: bool = True) -> PackOptions:
        """Options from the flat keys of version-1 packing files and bench configs (e.g.
        ``{"spheres": 12, "extra_max_tvd": 0.01}``). Lists become tuples. strict: an
        unknown key raises InputError; otherwise it is ignored."""
        groups: dict[str, dict[str, Any]] = {}
        top: dict[str, Any] = {}
        for key, value in flat.items():
            if key == "tune_threads":
                top[key] = value
                continue
            if key not in FLAT_KEYS:
                if strict:
                    raise InputError(f"unknown packing option {key!r}; known: "
                                     f"{', '.join(sorted([*FLAT_KEYS, 'tune_threads']))}")
                continue
            group, name = FLAT_KEYS[key]
            groups.setdefault(group, {})[name] = (tuple(value) if isinstance(value, list)
                                                  else value)
        base = cls()
        return replace(base, **top, **{g: replace(getattr(base, g), **kw)
                                       for g, kw in groups.items()})



def _flat_keys() -> dict[str, tuple[str, str]]:
    """Version-1 flat name -> (group, field). The phase, fidelity, margin and physics
    fields kept their names; the other groups' had a prefix."""
    prefix = {"cavity": "extra_", "repair": "repair_", "attempts": ""}
    renamed = {("cavity", "factors"): "extra_passes", ("attempts", "count"): "attempt_count"}
    out: dict[str, tuple[str, str]] = {}
    for group in fields(PackOptions):
        if group.name == "tune_threads":
            continue
        for f in fields(group.default_factory()):  # type: ignore[misc]
            flat = renamed.get((group.name, f.name), prefix.get(group.name, "") + f.name)
            out[flat] = (group.name, f.name)
    return out


#: Version-1 flat option name -> (PackOptions group, field name).
FLAT_KEYS: dict[str, tuple[str, str]] = _flat_keys()
