"""Solids that touch at their corners made to touch exactly, so that a union fuses them.

Parts that touch face to face (a grid of bricks, `core/box_grid.py`) meet where their
corners almost coincide: the packing's rotations and positions, and sources stored as 32-bit
floats, leave them apart by 1e-15 to 1e-7 of the scene. manifold3d's union fuses faces that
coincide exactly and keeps those a rounding error apart as separate surfaces, which touch:
a file the validator refuses. Giving such corners one position makes the faces coincide.

Frames: the caller's (the packing's container frame, container units).
"""

from __future__ import annotations

from collections.abc import Callable

import manifold3d as m3
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from jampacked.core.solids import solid_arrays, to_solid

__all__ = ["APART_REL", "WELD_REL", "shrunk_apart", "weld_touching"]

#: vertices of different solids closer than this fraction of the scene's diagonal are made
#: one position (0.2 micrometre at 200 mm: far below any printer's resolution, above the
#: rounding of float32 sources)
WELD_REL = 1e-6
#: how far (of the scene's diagonal) `shrunk_apart` moves every face of a solid in at
#: least: 0.6 micrometre at 200 mm
APART_REL = 3e-6


def weld_touching(pieces: list[m3.Manifold],
                  check_cancel: Callable[[], None] | None = None
                  ) -> tuple[list[m3.Manifold], int]:
    """The pieces with every vertex that lies within WELD_REL of the scene's diagonal of a
    vertex of another piece moved onto one position shared by all of them (the first such
    vertex in the pieces' order), and how many vertices moved.

    A group that holds two vertices of the same piece is left as it is (moving them together
    would fold that piece). Pieces with nothing to weld are returned as they were, so a
    packing whose objects do not touch at corners unites exactly as before.
    ``check_cancel`` (which raises to cancel) runs between the steps."""
    if len(pieces) < 2:
        return pieces, 0
    check = check_cancel or (lambda: None)
    arrays = [solid_arrays(p) for p in pieces]
    check()
    sizes = np.array([len(v) for v, _ in arrays])
    v = np.concatenate([a[0] for a in arrays])
    if len(v) == 0:
        return pieces, 0
    owner = np.repeat(np.arange(len(pieces)), sizes)
    reach = WELD_REL * float(np.linalg.norm(np.ptp(v, axis=0)))
    pairs = cKDTree(v).query_pairs(reach, output_type="ndarray")
    pairs = pairs[owner[pairs[:, 0]] != owner[pairs[:, 1]]]
    if len(pairs) == 0:
        return pieces, 0
    check()
    n = len(v)
    _, group = connected_components(
        coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
        directed=False)
    members = np.unique(pairs)
    # a group with two vertices of one piece: as many owners as members, or it stays
    g, o = group[members], owner[members]
    owners = np.unique(np.stack([g, o], axis=1), axis=0)[:, 0]
    whole = np.bincount(owners, minlength=n) == np.bincount(g, minlength=n)
    members = members[whole[g]]
    if len(members) == 0:
        return pieces, 0
    first = np.full(n, n)
    np.minimum.at(first, group[members], members)  # members are sorted: the first index
    target = v[first[group[members]]]
    moved = members[np.any(target != v[members], axis=1)]
    v[members] = target
    starts = np.concatenate([[0], np.cumsum(sizes)])
    out = list(pieces)
    for k, i in enumerate(np.unique(owner[moved])):
        if k % 256 == 0:
            check()
        solid = to_solid(v[starts[i]:starts[i + 1]], arrays[i][1])
        if solid.status() == m3.Error.NoError:
            out[i] = solid
    return out, int(len(moved))


def shrunk_apart(pieces: list[m3.Manifold]) -> tuple[list[m3.Manifold], float]:
    """Each piece scaled about its box's centre so that every face moves in by at least
    APART_REL of the scene's diagonal, and that distance: solids that touch face to face
    then stand apart, for a union whose faces touch where no corner meets a corner (faces
    split differently either side, which `weld_touching` cannot fuse). Empty pieces stay."""
    boxes = np.array([np.asarray(p.bounding_box(), np.float64) for p in pieces])
    full = np.array([p.num_tri() > 0 for p in pieces])
    if not full.any():
        return pieces, 0.0
    lo, hi = boxes[full, :3].min(axis=0), boxes[full, 3:].max(axis=0)
    step = APART_REL * float(np.linalg.norm(hi - lo))
    out = []
    for p, box, solid in zip(pieces, boxes, full, strict=True):
        half = 0.5 * float(np.min(box[3:] - box[:3]))
        if not solid or half <= step:
            out.append(p)
            continue
        centre = tuple(0.5 * (box[:3] + box[3:]))
        k = 1.0 - step / half  # a face `h` from the centre moves in h / half >= 1 steps
        out.append(p.translate(tuple(-c for c in centre)).scale((k, k, k)).translate(centre))
    return out, step
