"""What a packing request will cost, estimated before anything large is allocated.

`pack()` calls `check_sizes` and `check_cost` right after the meshes are loaded and scaled,
before the container grid, the phase-1 lattice, the cavity passes' lattices or the object
types' grids exist. A request that needs more memory than the machine has, or more objects
than the engine places in any sensible time, is refused at once with the numbers and the
fix. Lengths in container units; memory in bytes. The per-item byte counts below are the
arrays each item costs in the stages named (docs/notes-robustness.md has the breakdown and a
measured run).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .errors import InputError, PackingError
from .grid_size import finest_spacing

#: lengths (container units) outside this window are refused: below it the solver's absolute
#: tolerances (1e-12) stop being negligible; above it nothing overflows yet (a cube's volume
#: does beyond 1e102), but no scene to print or simulate is that large and such a file is
#: most likely in the wrong units. In millimetres: 1 nm to 1000 km.
MIN_LENGTH = 1e-6
MAX_LENGTH = 1e9
#: no request may place more objects than this, whatever the memory (phase 1 alone grows
#: each object in tens of solver steps: ~1 ms each, docs/notes-robustness.md)
MAX_OBJECTS = 1e8
#: bytes per object in the solver's state, with the capacity doubling, plus phase 1's queue
BYTES_PER_OBJECT = 600
#: bytes per point of an interior lattice while a cavity pass sorts and filters it
BYTES_PER_LATTICE_POINT = 100
#: bytes per node of the container's distance grid while it is built
BYTES_PER_GRID_NODE = 100
#: fraction of the machine's memory a request may plan to use
MEMORY_FRACTION = 0.8


def machine_memory() -> int:
    """Bytes of memory this process may use: the physical memory, lowered by an address
    space limit (ulimit -v) or a cgroup limit when one is set; 8 GiB when the platform
    says nothing (no sysconf, e.g. Windows)."""
    limits = []
    try:
        limits.append(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        pass
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft not in (resource.RLIM_INFINITY, -1) and soft > 0:
            limits.append(int(soft))
    except (ImportError, OSError, ValueError):
        pass
    try:
        with open("/sys/fs/cgroup/memory.max") as fh:
            text = fh.read().strip()
        if text.isdigit():
            limits.append(int(text))
    except OSError:
        pass
    limits = [x for x in limits if x > 0]
    return min(limits) if limits else 8 << 30


@dataclass(frozen=True)
class TypeSize:
    """An object type as the size checks see it: name, file, extents and volume after the
    type scale (container units)."""

    name: str
    path: str | None
    extents: np.ndarray  # (3,)
    volume: float
    #: a lower bound of its inscribed radius (`mesh_geometry.inner_room`), the depth it needs;
    #: measured only where the container's depth check needs it (0 otherwise)
    room: float = 0.0

    @property
    def label(self) -> str:
        """``name (file)`` or ``name`` for messages."""
        return f"{self.name} ({self.path})" if self.path else self.name

    @property
    def equivalent_radius(self) -> float:
        """Radius of the sphere of the type's volume."""
        return (3.0 * self.volume / (4.0 * math.pi)) ** (1.0 / 3.0)


@dataclass(frozen=True)
class CostEstimate:
    """What a request will allocate, before it does (counts are estimates, upper bounds
    where they feed the memory figure)."""

    objects: float  # objects a dense packing holds (density ~0.64)
    state_objects: float  # objects the solver's state may hold (a full container)
    container_grid_nodes: float
    phase1_points: float  # interior points of phase 1's lattice
    cavity_points: float  # interior points of the finest cavity pass's lattice
    memory: float  # bytes at the peak
    machine: int  # bytes this process may use

    @property
    def bytes_per_object(self) -> float:
        """The peak memory spread over the objects: what each costs."""
        return self.memory / max(self.objects, 1.0)

    @property
    def affordable_objects(self) -> float:
        """Objects the engine can place within MEMORY_FRACTION of the machine."""
        return min(MAX_OBJECTS, MEMORY_FRACTION * self.machine / self.bytes_per_object)


def check_sizes(container_label: str, container_extents: np.ndarray, container_volume: float,
                types: Sequence[TypeSize], type_scale: float,
                container_size: float | None) -> None:
    """Refuse lengths and volumes that are not finite, zero, or outside the window the
    engine computes in (MIN_LENGTH..MAX_LENGTH container units), naming the container or the
    type and the argument that sets its size."""
    ext = np.asarray(container_extents, np.float64)
    how = ("--container-size / container_size" if container_size is not None
           else "a smaller or larger container, or --container-size / container_size")
    if not _in_window(ext, container_volume):
        raise InputError(
            f"the container {container_label} is {_dims(ext)} units (volume "
            f"{container_volume:.3g}): sizes must lie between {MIN_LENGTH:g} and "
            f"{MAX_LENGTH:g} units, where areas and volumes are finite and the solver's "
            f"tolerances hold. Give {how} within that range.")
    for t in types:
        if not _in_window(t.extents, t.volume):
            raise InputError(
                f"object type {t.label} is {_dims(t.extents)} units after the type scale "
                f"{type_scale:g} (volume {t.volume:.3g}): sizes must lie between "
                f"{MIN_LENGTH:g} and {MAX_LENGTH:g} units, where areas and volumes are "
                "finite and the solver's tolerances hold. Use a --type-scale / type_scale "
                "that brings it within that range.")


def _in_window(extents: np.ndarray, volume: float) -> bool:
    return bool(np.all(np.isfinite(extents)) and math.isfinite(volume) and volume > 0
                and extents.max() <= MAX_LENGTH and extents.max() >= MIN_LENGTH)


def _dims(ext: np.ndarray) -> str:
    return " x ".join(f"{x:.4g}" for x in ext)


def estimate_cost(container_extents: np.ndarray, container_volume: float,
                  type_volumes: np.ndarray, shares: np.ndarray, container_cells: float,
                  phase1_density: float, phase2_spacing: float,
                  cavity_factors: Sequence[float]) -> CostEstimate:
    """The counts and peak memory of a request, from the container's size and the types'.

    container_cells: container grid cells per smallest equivalent radius (the fidelity's);
    phase1_density, phase2_spacing, cavity_factors: the placement's lattice settings
    (`options.PhaseOptions`, `options.CavityPassOptions`).
    """
    ext = np.asarray(container_extents, np.float64)
    volumes = np.asarray(type_volumes, np.float64)
    mean_volume = float(np.sum(shares * volumes))
    full = container_volume / mean_volume
    s1 = (mean_volume / phase1_density) ** (1.0 / 3.0)
    phase1 = container_volume / s1 ** 3
    finest = phase2_spacing * min([1.0, *cavity_factors])
    cavity = container_volume / (s1 * finest) ** 3
    f_min = float((3.0 * volumes[shares > 0].min() / (4.0 * math.pi)) ** (1.0 / 3.0))
    h = max(f_min / container_cells, finest_spacing(ext))
    nodes = float(np.prod(ext / h + 8.0))  # padding and the band on both sides
    memory = (nodes * BYTES_PER_GRID_NODE + full * BYTES_PER_OBJECT
              + max(phase1, cavity) * BYTES_PER_LATTICE_POINT)
    return CostEstimate(objects=0.64 * full, state_objects=full, container_grid_nodes=nodes,
                        phase1_points=phase1, cavity_points=cavity, memory=memory,
                        machine=machine_memory())


def check_cost(cost: CostEstimate, container_label: str, container_extents: np.ndarray,
               smallest: TypeSize) -> None:
    """Refuse a request that needs more than MEMORY_FRACTION of the machine's memory or more
    than MAX_OBJECTS objects, with the numbers and the fix."""
    too_many = cost.objects > MAX_OBJECTS
    too_big = cost.memory > MEMORY_FRACTION * cost.machine
    if not (too_many or too_big):
        return
    need = (f"more than the {cost.affordable_objects:.2g} the engine can place on this "
            f"machine (each costs ~{cost.bytes_per_object:.3g} bytes at the peak: "
            f"~{_gib(cost.memory)} in all, of {_gib(cost.machine)})")
    if too_many and cost.affordable_objects >= MAX_OBJECTS:
        need = f"more than the {MAX_OBJECTS:.0e} any request may place"
    factor = (cost.objects / max(min(cost.affordable_objects, MAX_OBJECTS), 1.0)) ** (1 / 3)
    raise PackingError(
        f"the container {container_label} ({_dims(np.asarray(container_extents))} units) "
        f"holds about {cost.objects:.2g} objects of this mix (the smallest type, "
        f"{smallest.label}, has equivalent radius {smallest.equivalent_radius:.3g} units): "
        f"{need}; the phase-1 lattice has ~{cost.phase1_points:.2g} points and the finest "
        f"cavity pass ~{cost.cavity_points:.2g}. Scale the objects up (--type-scale / "
        f"type_scale, by a factor of at least {factor:.3g}) or the container down "
        "(--container-size / container_size).")


def _gib(n: float) -> str:
    for unit, size in (("TiB", 2.0 ** 40), ("GiB", 2.0 ** 30), ("MiB", 2.0 ** 20)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 2.0 ** 20:.2g} MiB"
