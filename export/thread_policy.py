"""Whether validation's self-intersection test gets a thread of its own."""

from __future__ import annotations

import os

__all__ = ["spare_core"]


def spare_core() -> bool:
    """Whether a second thread is likely to get a core of its own: two or more CPUs and a
    1-minute load average (this process included) below their number by a quarter CPU; True
    where there is no load average (Windows). On a busy machine the intersection test and
    manifold3d only slow each other down, so they then run one after the other."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:
        cpus = os.cpu_count() or 1
    if cpus < 2:
        return False
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        return True
    return load < cpus - 0.25
