"""Simplify a solid to a printer's resolution, with the surface kept within it (measured).

manifold3d's ``simplify(tolerance)`` checks each edge collapse against the mesh as it is
then, so successive collapses add up: on the YCB fruit the surface moved by up to 1.7x the
tolerance (docs/notes-export.md, "A resolution kept"). Here each result is measured against
the original and simplified again with a smaller tolerance until it keeps the bound.

Frames and units: the solid's own (an object type's local frame, container units).
"""

from __future__ import annotations

import manifold3d as m3
import numpy as np

from jampacked.core.distance import surface_distance
from jampacked.core.solids import solid_arrays

from .union import crossing_pairs

__all__ = ["simplify_within", "surface_deviation"]

#: simplifications tried, each with a smaller tolerance, before the solid is kept as it is
TRIES = 6
#: each retry asks for this fraction of what the last measured deviation allows
RETRY_MARGIN = 0.9
#: ... or, after a result that folded through itself, this fraction of the last tolerance
FOLD_RETRY = 0.5


def _probe_points(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """A coarse mesh's vertices, face centres and edge midpoints (each edge once): where the
    distance from its surface to another one is measured."""
    edges = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    return np.vstack([vertices, vertices[faces].mean(axis=1),
                      vertices[edges].mean(axis=1)])


def surface_deviation(v0: np.ndarray, f0: np.ndarray, v1: np.ndarray, f1: np.ndarray) -> float:
    """How far a simplified surface (v1, f1) lies from its original (v0, f0), both ways: the
    largest exact distance from the original's vertices to the simplified mesh (the
    original is the dense one), and from the simplified mesh's vertices, face centres and
    edge midpoints to the original. Same frame and units for both."""
    if len(f0) == 0 or len(f1) == 0:
        return float("inf")
    return float(max(surface_distance(v0, v1, f1).max(),
                     surface_distance(_probe_points(v1, f1), v0, f0).max()))


def simplify_within(solid: m3.Manifold, tolerance: float) -> tuple[m3.Manifold, float]:
    """``solid`` simplified by manifold3d so that no measured point of either surface lies
    further than ``tolerance`` from the other and no face crosses another; returns (the
    solid, its measured deviation). When no try keeps both, the solid is returned as it was
    (deviation 0).

    manifold3d's simplify can fold a coarse surface through itself, and every copy of such
    a type then made the union self-intersecting (YCB scans: docs/notes-export.md)."""
    v0, f0 = solid_arrays(solid)
    asked = tolerance
    for _ in range(TRIES):
        simple = solid.simplify(asked)
        if simple.num_tri() == solid.num_tri():
            break
        v1, f1 = solid_arrays(simple)
        deviation = surface_deviation(v0, f0, v1, f1)
        if deviation > tolerance:
            asked *= RETRY_MARGIN * tolerance / deviation
        elif crossing_pairs(v1, f1, float32=False)[1]:
            asked *= FOLD_RETRY
        else:
            return simple, deviation
    return solid, 0.0
