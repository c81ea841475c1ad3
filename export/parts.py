"""Parts mode: each object its own body, kept apart by the packing's clearance.

Frames: the packing's container frame, container units.

The gap check grows with the parts that are near one another, not with all pairs: a broad
phase on the parts' bounding boxes (a k-d tree of their centres) finds the pairs whose boxes
come within the clearance, and only those reach manifold3d's exact ``min_gap``. Its cost
grows steeply with the search length it is given (every triangle pair within that distance
is measured), so every call searches only a little beyond the clearance, or beyond the
smallest gap found so far.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import manifold3d as m3
import numpy as np
from scipy.spatial import cKDTree

from jampacked.core.errors import InputError, MeshError
from jampacked.core.exact_checks import span_scale
from jampacked.core.solids import solid_arrays, to_solid

__all__ = ["box_gaps", "near_pairs", "require_gap", "separate_parts", "smallest_gap"]

#: a gap within this fraction below the clearance is accepted (manifold3d's rounding)
GAP_TOLERANCE = 1e-6
#: ... and within this fraction as an STL or PLY stores it (0.2 um of a 0.2 mm clearance,
#: far below what a printer resolves): 32-bit positions 1 m from the origin move a gap by
#: up to 2e-4 mm, and a packing's smallest gap sits just above its clearance
F32_TOLERANCE = 1e-3
#: the exact checks search this much beyond the clearance, so that the smallest gap of a
#: dense packing (whose neighbours sit just beyond the clearance) comes out exactly
SEARCH_MARGIN = 0.2
#: the search grows by this factor while no pair comes within it
GROWTH = 1.5
#: nearest neighbours per part that the report's smallest gap also considers
NEIGHBOURS = 6


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


def box_gaps(lo: np.ndarray, hi: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """(E,) distance between the axis-aligned boxes ``lo[i]..hi[i]`` and ``lo[j]..hi[j]`` of
    each pair (i, j) of ``pairs`` (E, 2): 0 where they overlap; a lower bound on the gap
    between whatever the boxes hold."""
    i, j = pairs[:, 0], pairs[:, 1]
    apart = np.maximum(0.0, np.maximum(lo[i] - hi[j], lo[j] - hi[i]))
    return np.sqrt((apart * apart).sum(axis=1))


def near_pairs(lo: np.ndarray, hi: np.ndarray, distance: float) -> np.ndarray:
    """(E, 2) pairs i < j of boxes (N, 3) ``lo``..``hi`` at most ``distance`` apart, sorted.

    Broad phase: a k-d tree of the box centres finds, for each box, the centres within its
    half-diagonal plus the largest half-diagonal plus ``distance``; the box distance then
    keeps the pairs that are near. Time and memory grow with the pairs found, not with all
    N^2 pairs (for boxes of similar sizes).
    """
    n = len(lo)
    if n < 2:
        return np.zeros((0, 2), np.int64)
    centre = 0.5 * (lo + hi)
    half = 0.5 * np.linalg.norm(hi - lo, axis=1)
    tree = cKDTree(centre)
    reach = half + half.max() + distance
    found = tree.query_ball_point(centre, reach, return_sorted=False)
    counts = np.fromiter((len(f) for f in found), np.int64, n)
    i = np.repeat(np.arange(n), counts)
    j = np.fromiter((k for f in found for k in f), np.int64, int(counts.sum()))
    keep = i < j
    pairs = np.stack([i[keep], j[keep]], axis=1)
    pairs = pairs[box_gaps(lo, hi, pairs) <= distance]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def smallest_gap(gap: Callable[[int, int, float], float], pairs: np.ndarray,
                 lower: np.ndarray, upper: float, clearance: float
                 ) -> tuple[float | None, tuple[int, int] | None]:
    """The smallest exact gap over ``pairs``, checking that every pair keeps ``clearance``.

    gap(i, j, search): the exact gap between parts i and j when it is below ``search``, else
    ``search`` (manifold3d's ``min_gap``); lower: (E,) a lower bound on each pair's gap (the
    box distance); upper: no gap is larger (the farthest corners of the pairs' boxes).

    The search starts just beyond the clearance (SEARCH_MARGIN) and grows by GROWTH until a
    pair comes closer than it (or it passes ``upper``: None then); each round measures only
    the pairs whose lower bound is below the search, so a dense packing (neighbours just
    beyond the clearance) costs one round of short searches, and every pair that could be
    closer than the clearance is measured in the first. Returns (smallest gap, its pair),
    or (None, None) without pairs.
    """
    if len(pairs) == 0:
        return None, None
    search = clearance * (1.0 + SEARCH_MARGIN)
    while search <= upper * GROWTH:
        best, where = np.inf, None
        for k in np.flatnonzero(lower < search):
            i, j = int(pairs[k, 0]), int(pairs[k, 1])
            g = gap(i, j, search)
            if g < best:
                best, where = g, (i, j)
        if best < search:
            return float(best), where
        # no pair within the search: every gap is at least `search`
        search *= GROWTH
    return None, None


def separate_parts(solids: list[m3.Manifold], clearance: float, *,
                   float32: Sequence[str] = ()
                   ) -> tuple[list[tuple[np.ndarray, np.ndarray]], float | None]:
    """Each solid its own body: (bodies as (vertices, faces), smallest gap between near
    parts or None when no two parts are near). ``clearance`` > 0 (see :func:`require_gap`).

    Near parts: those whose bounding boxes come within the clearance (plus SEARCH_MARGIN) of
    each other, and each part's NEIGHBOURS nearest by their boxes' centres. Every pair that
    could be closer than the clearance is checked exactly (manifold3d ``min_gap``).
    float32: the outputs that store 32-bit positions (STL, PLY). Rounding to them moves
    each vertex by half a float32 step at most (at the parts' largest coordinate); where
    that could take a gap more than F32_TOLERANCE of the clearance below it, the near pairs
    reach that much further and their gaps are measured again on the positions rounded as
    those files store them, and those are the ones reported.

    Raises MeshError when two parts are closer than ``clearance`` (a coarse resolution can
    move surfaces by up to its value; 32-bit positions far from the origin by their step).
    """
    bodies = [solid_arrays(s) for s in solids]
    if len(bodies) < 2:
        return bodies, None
    lo = np.array([b[0].min(axis=0) for b in bodies])
    hi = np.array([b[0].max(axis=0) for b in bodies])
    reach = float(np.abs(np.concatenate([lo, hi])).max())
    # each of a gap's two ends moves by at most |x| 2^-24 per coordinate
    shift = 2.0 * np.sqrt(3.0) * reach * 2.0 ** -24
    rounded_too = bool(float32) and shift > F32_TOLERANCE * clearance
    pairs = near_pairs(lo, hi, clearance * (1.0 + SEARCH_MARGIN) + (shift if rounded_too
                                                                   else 0.0))
    pairs = np.unique(np.concatenate([pairs, _neighbours(0.5 * (lo + hi))]), axis=0)
    farthest = float(np.linalg.norm(np.maximum(hi[pairs[:, 0]], hi[pairs[:, 1]])
                                    - np.minimum(lo[pairs[:, 0]], lo[pairs[:, 1]]),
                                    axis=1).max())
    lower = box_gaps(lo, hi, pairs)

    # scaled up where parts are tiny, as certification does (`exact_checks.check_scale`)
    scale = span_scale(float((hi - lo).max(axis=1).min()))
    scaled: dict[int, m3.Manifold] = {}

    def at_scale(i: int) -> m3.Manifold:
        if scale == 1.0:
            return solids[i]
        if i not in scaled:
            scaled[i] = solids[i].scale([scale] * 3)
        return scaled[i]

    def gap(i: int, j: int, search: float) -> float:
        return float(at_scale(i).min_gap(at_scale(j), search * scale)) / scale

    worst, where = smallest_gap(gap, pairs, lower, farthest, clearance)
    _require(worst, where, clearance, GAP_TOLERANCE, "")
    if rounded_too and worst is not None:
        rounded: dict[int, m3.Manifold] = {}

        def solid32(i: int) -> m3.Manifold:
            if i not in rounded:
                rounded[i] = to_solid(bodies[i][0] * scale, bodies[i][1], double=False)
            return rounded[i]

        def gap32(i: int, j: int, search: float) -> float:
            return float(solid32(i).min_gap(solid32(j), search * scale)) / scale

        worst, where = smallest_gap(gap32, pairs, lower - shift, farthest, clearance)
        files = ", ".join(float32)
        _require(worst, where, clearance, F32_TOLERANCE, (
            f" as {files} would store them: 32-bit positions are "
            f"{float(np.spacing(np.float32(reach))):.2g} apart at coordinates up to "
            f"{reach:.4g}. Drop {files} and write .3mf, which keeps the positions' full "
            "precision, or move the container mesh near the origin and pack again"))
    return bodies, worst


def _require(worst: float | None, where: tuple[int, int] | None, clearance: float,
             tolerance: float, stored: str) -> None:
    """Raise MeshError if the smallest gap ``worst`` (between parts ``where``) is more than
    ``tolerance`` of the clearance below it; ``stored`` says how the positions were stored,
    and what to do, when they were rounded."""
    if worst is None or where is None or worst >= clearance * (1 - tolerance):
        return
    advice = stored or (". A coarse --resolution can move surfaces by up to its value: use "
                        "a finer one, or pack with a larger clearance")
    raise MeshError(f"parts closer than the packing's clearance {clearance:g}: objects "
                    f"{where[0]} and {where[1]} are {worst:.6g} apart{advice}.")


def _neighbours(centres: np.ndarray) -> np.ndarray:
    """(E, 2) pairs i < j: each centre with its NEIGHBOURS nearest."""
    n = len(centres)
    k = min(NEIGHBOURS, n - 1)
    _, nn = cKDTree(centres).query(centres, k=k + 1)
    pairs = np.sort(np.stack([np.repeat(np.arange(n), k), nn[:, 1:].ravel()], axis=1), axis=1)
    return pairs[pairs[:, 0] != pairs[:, 1]].astype(np.int64)
