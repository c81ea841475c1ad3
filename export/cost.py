"""What an export will cost, estimated before any object is made solid.

:func:`jampacked.export.assemble.export_packing` calls :func:`estimate_export` once the type
meshes are solids (each type once) and before the objects are placed as solids, and
:func:`check_export_cost` refuses a request whose peak memory would exceed
``MEMORY_FRACTION`` of the machine's, with the numbers, the count of objects this machine
can export, and the fix. The per-triangle figures are peak resident memory and seconds
measured on whole exports (docs/benchmarks.md, "Parts export at scale"): the solids, the
arrays, the encoded file and its validation read back all scale with the triangles written.
Memory in bytes, time in seconds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from jampacked.core.cost import MEMORY_FRACTION, machine_memory
from jampacked.core.errors import InputError

from .connect import STRUT_SEGMENTS

__all__ = ["BYTES_PER_TRIANGLE", "SECONDS_PER_TRIANGLE", "ExportCost", "check_export_cost",
           "estimate_export"]

#: peak bytes per triangle written, per mode, beyond BASE_BYTES (parts: 1.82 kB measured on
#: 104 YCB scans, 1.7M triangles; union: 2.05 kB on 250 low-poly fruit; connect: 2.31 kB on
#: 17,924 balls of 80 triangles, counting a strut's triangles per object)
BYTES_PER_TRIANGLE = {"parts": 1900.0, "union": 2100.0, "connect": 2300.0}
#: triangles of one strut (a cylinder of STRUT_SEGMENTS sides): connect adds about one per
#: object (a spanning tree's edges, one more per further body of the shell), which on
#: low-poly objects is half as much again
STRUT_TRIANGLES = 4 * STRUT_SEGMENTS - 4
#: seconds per triangle written, per mode (parts: at a load of 11-14 on this 2-core machine
#: with every part's mesh written, as STL, OBJ and PLY are; a 3MF of instances took 1.9e-5;
#: union and connect: bench/export_bench.py with nothing else running)
SECONDS_PER_TRIANGLE = {"parts": 7e-5, "union": 2.1e-5, "connect": 4.1e-5}
#: bytes before the first triangle (the interpreter, numba, manifold3d, the loaded meshes:
#: 227 MiB measured after a warm-up export)
BASE_BYTES = 256 * 2.0**20


@dataclass(frozen=True)
class ExportCost:
    """An export's size and peak memory, estimated before it runs.

    objects: objects exported; triangles: triangles written (for union and connect, the sum
    over the objects: an upper bound, as the union removes what is inside); memory: peak
    bytes; seconds: roughly, on a machine like the one measured; machine: bytes this
    process may use.
    """

    mode: str
    objects: int
    triangles: float
    memory: float
    seconds: float
    machine: int

    @property
    def fits(self) -> bool:
        """Whether the peak memory fits in MEMORY_FRACTION of the machine."""
        return self.memory <= MEMORY_FRACTION * self.machine

    @property
    def affordable_objects(self) -> int:
        """Objects of this packing's mix the machine can export within MEMORY_FRACTION of
        its memory."""
        room = MEMORY_FRACTION * self.machine - BASE_BYTES
        per_object = (self.memory - BASE_BYTES) / max(self.objects, 1)
        if per_object <= 0:
            return self.objects
        return max(0, int(room // per_object))


def estimate_export(mode: str, type_triangles: Sequence[int], type_index: np.ndarray,
                    extra_triangles: int = 0) -> ExportCost:
    """The size and cost of exporting the objects of ``type_index`` (N,) whose types have
    ``type_triangles`` (T,) triangles each (after any simplification), plus
    ``extra_triangles`` (a shell) in ``mode`` ("parts", "union" or "connect", which counts
    a strut per object)."""
    counts = np.bincount(np.asarray(type_index, np.int64), minlength=len(type_triangles))
    struts = STRUT_TRIANGLES * len(type_index) if mode == "connect" else 0
    triangles = float(np.dot(counts, np.asarray(type_triangles, np.float64))
                      + extra_triangles + struts)
    return ExportCost(mode=mode, objects=int(len(type_index)), triangles=triangles,
                      memory=BASE_BYTES + BYTES_PER_TRIANGLE[mode] * triangles,
                      seconds=SECONDS_PER_TRIANGLE[mode] * triangles,
                      machine=machine_memory())


def check_export_cost(cost: ExportCost) -> None:
    """Refuse an export whose peak memory would exceed MEMORY_FRACTION of the machine's,
    before anything large is made, with the numbers and how to fit it."""
    if cost.fits:
        return
    per_object = cost.triangles / max(cost.objects, 1)
    raise InputError(
        f"cannot export {cost.objects:,} objects in {cost.mode} mode on this machine: the "
        f"result holds ~{cost.triangles:.3g} triangles (~{per_object:,.0f} per object) and "
        f"the export needs ~{_gib(cost.memory)} at its peak (~"
        f"{BYTES_PER_TRIANGLE[cost.mode]:,.0f} bytes per triangle for the solids, the file "
        f"and its validation), more than {MEMORY_FRACTION:.0%} of the {_gib(cost.machine)} "
        f"this process may use; it would also take ~{_duration(cost.seconds)}. "
        f"This machine can export about {cost.affordable_objects:,} objects of this "
        "packing. Simplify the objects (--resolution, e.g. 0.1 for 0.1 mm, or type meshes "
        "with fewer triangles) or export on a machine with more memory.")


def _gib(n: float) -> str:
    for unit, size in (("TiB", 2.0**40), ("GiB", 2.0**30)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 2.0**20:.3g} MiB"


def _duration(seconds: float) -> str:
    if seconds >= 3600:
        return f"{seconds / 3600:.2g} h"
    if seconds >= 60:
        return f"{seconds / 60:.2g} min"
    return f"{seconds:.2g} s"
