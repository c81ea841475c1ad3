"""Parts mode: each object its own body, kept apart by the packing's clearance.

Frames: the packing's container frame, container units.
"""

from __future__ import annotations

import manifold3d as m3
import numpy as np
from scipy.spatial import cKDTree

from jampacked.core.errors import InputError, MeshError
from jampacked.core.solids import solid_arrays

from .connect import candidate_pairs

__all__ = ["require_gap", "separate_parts"]


def require_gap(clearance: float) -> None:
    """Refuse parts mode for a packing without clearance, before any work is done.

    The objects of a dense packing touch; parts that touch fuse in a powder bed or print as
    one, and the written file does not validate as separate bodies.
    """
    if clearance > 0:
        return
    raise InputError(
        "parts mode needs a gap between the objects, and this packing has none (its "
        "clearance is 0: the objects of a dense packing touch). Re-pack with --clearance "
        "(e.g. --clearance 0.2 for 0.2 mm), or export with --mode union or --mode connect.")


def separate_parts(solids: list[m3.Manifold], clearance: float
                   ) -> tuple[list[tuple[np.ndarray, np.ndarray]], float | None]:
    """Each solid its own body: (bodies as (vertices, faces), smallest gap between near
    parts or None when no two parts are near). ``clearance`` > 0 (see :func:`require_gap`).

    Raises MeshError when two parts are closer than ``clearance`` (a coarse resolution can
    move surfaces by up to its value).
    """
    bodies = [solid_arrays(s) for s in solids]
    # every pair whose bounds, grown by the clearance, touch is checked exactly; the
    # nearest neighbours too, so the report gives the smallest gap even when all keep it
    probe = max(clearance, 1e-3 * _scale(bodies))
    lo = np.array([b[0].min(axis=0) for b in bodies]) - probe
    hi = np.array([b[0].max(axis=0) for b in bodies]) + probe
    pairs = {tuple(p) for p in candidate_pairs(np.array([b[0].mean(axis=0) for b in bodies]))}
    for i in range(len(bodies)):
        near = np.flatnonzero(np.all(lo[i + 1:] <= hi[i], axis=1)
                              & np.all(hi[i + 1:] >= lo[i], axis=1)) + i + 1
        pairs.update((i, int(j)) for j in near)
    trees = {j: cKDTree(bodies[j][0]) for j in {j for _, j in pairs}}
    worst = None
    for i, j in sorted(pairs):
        upper = float(trees[j].query(bodies[i][0])[0].min())
        g = float(solids[i].min_gap(solids[j], upper * 1.001 + 1e-9))
        if worst is None or g < worst:
            worst = g
    if worst is not None and worst < clearance * (1 - 1e-6):
        raise MeshError(f"parts closer than the packing's clearance {clearance:g}: the "
                        f"smallest gap is {worst:.4g}. A coarse --resolution can move surfaces "
                        "by up to its value: use a finer one, or pack with a larger clearance.")
    return bodies, worst


def _scale(bodies: list[tuple[np.ndarray, np.ndarray]]) -> float:
    v = np.concatenate([b[0] for b in bodies])
    return float(np.ptp(v, axis=0).max())
