"""How fine the container's distance grid may be: a bound on its nodes, not on one axis.

Lengths in container units. Free of numba, so that the cost estimate (`core/cost.py`) can
use it before anything is compiled.
"""

from __future__ import annotations

import numpy as np

#: grid cells across the container's largest extent, for a container that is not thin: memory
#: and time stay sane, and a cube's grid holds (MAX_CELLS_PER_AXIS + PAD_NODES)^3 nodes
MAX_CELLS_PER_AXIS = 220
#: nodes a grid has per axis beyond extent / spacing: its padding and the band on both sides
PAD_NODES = 8
#: a container thinner than this many cells at the per-axis cap (a slab, a long tube) may
#: have this many across its thinnest extent, within a cube's nodes: at the per-axis cap a
#: 70 x 70 x 2.2 box was 7 cells thick, read 0.95 deep where 2 mm cubes need 1, and took none
THIN_CELLS = 24


def finest_spacing(extents: np.ndarray, cells: int = MAX_CELLS_PER_AXIS,
                   thin: int = THIN_CELLS) -> float:
    """The finest spacing of a grid over a box of ``extents`` (3,): the largest extent over
    ``cells``, or, where the thinnest extent spans fewer than ``thin`` cells at that spacing,
    the thinnest extent over ``thin``, coarsened where needed to hold the grid (with its
    padding) to the nodes of a cube's at ``cells``."""
    ext = np.maximum(np.asarray(extents, np.float64), 1e-300)  # a flat box: no division by 0
    coarse = float(ext.max()) / cells
    if float(ext.min()) / coarse >= thin:
        return coarse
    budget = float(cells + PAD_NODES) ** 3
    lo, hi = float(ext.min()) / thin, coarse  # nodes fall as the spacing grows
    if float(np.prod(ext / lo + PAD_NODES)) <= budget:
        return lo
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if float(np.prod(ext / mid + PAD_NODES)) > budget:
            lo = mid
        else:
            hi = mid
    return hi
