"""Whether the container has room for the object types: its depth, the refusals up front
and after placing nothing, and the finer container grid a type that only just fits needs.

Frames and units: the container frame, container units. A type needs, at the container's
deepest interior point, at least its inner room (`mesh_geometry.inner_room`) plus the
clearance; the approximation also keeps its contact margins and reads the depth from a
grid, which can fall short of the true depth by about half a cell at its peak.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .container import Container, container_grid
from .cost import TypeSize
from .distance import DistanceGrid, surface_distance
from .errors import PackingError
from .grid_size import finest_spacing
from .margins import Margins
from .mesh_geometry import inner_room
from .meshes import MeshData
from .objects import ObjectType

#: a container grid with fewer cells than this across the container's thinnest extent
#: measures its depth again on a grid this fine (within the container grid's cap,
#: `grid_size.finest_spacing`) before refusing every type
DEPTH_CELLS = 64


def measured_depth(vertices: np.ndarray, faces: np.ndarray,
                   grid: DistanceGrid) -> tuple[float, DistanceGrid]:
    """The container's deepest interior distance and the grid it was measured on:
    DEPTH_CELLS cells across the container's thinnest extent, or as many as the container
    grid's cap allows (the approximation's grid follows the objects' size and is coarser
    than the container when they are far larger: its nodes may all lie outside, or a thin
    tray's few). vertices (V, 3), faces (F, 3): the container mesh; grid: its distance
    grid so far (`container.container_grid`), returned when it is as fine."""
    extents = np.ptp(vertices, axis=0)
    spacing = max(float(extents.min()) / DEPTH_CELLS, finest_spacing(extents))
    if grid.spacing <= spacing * (1 + 1e-12):  # as fine already: the same grid
        return float(grid.values.max()), grid
    fine = container_grid(vertices, faces, spacing)
    return max(float(fine.values.max()), 0.0), fine


def rounded_up(factor: float) -> str:
    """``factor`` to three significant digits, rounded up: a scale factor said "at least"
    that, followed, leaves the object a little smaller than the bound, not larger (2.4167
    said as 2.42, not 2.41)."""
    step = 10.0 ** (math.floor(math.log10(factor)) - 2)
    return f"{math.ceil(factor / step - 1e-9) * step:.3g}"


def refuse_no_room(label: str, vertices: np.ndarray, sizes: list[TypeSize], depth: float,
                   spacing: float, clearance: float) -> None:
    """Refuse a scene where even the smallest of the types asked for (``sizes``, with their
    inner room) cannot sit at the container's deepest point (``depth``, measured on a grid
    of ``spacing``: within a cell of the truth), naming the types (and files) that do not
    fit. label: the container for messages; vertices (V, 3): its mesh's."""
    c_ext = np.ptp(vertices, axis=0)
    dims = " x ".join(f"{x:.4g}" for x in c_ext)
    most = depth + spacing  # the deepest the container can be
    big = sorted([t for t in sizes if t.room + clearance >= most], key=lambda t: t.room)
    def needs(t: TypeSize) -> str:
        if not clearance:
            return (f"{t.room:.4g} units of depth (equivalent radius "
                    f"{t.equivalent_radius:.4g})")
        return (f"{t.room + clearance:.4g} units of depth ({t.room:.4g} of its own, "
                f"equivalent radius {t.equivalent_radius:.4g}, and the clearance "
                f"{clearance:g})")

    listed = "; ".join(
        f"{t.label}: needs at least {needs(t)}, "
        f"{' x '.join(f'{x:.4g}' for x in t.extents)} units across" for t in big[:5])
    more = f"; and {len(big) - 5} more" if len(big) > 5 else ""
    # the factor said is the least that takes a type within both bounds a placement needs:
    # the depth measured (not its upper bound, which left the type too deep) and the
    # container's diagonal (`refuse_too_long`), so that the next run is not refused again
    room = depth - clearance
    reach = float(np.linalg.norm(c_ext)) - 2.0 * clearance
    if room > 0 and reach > 0:
        first = min(big, key=lambda t: max(t.room / room, float(t.extents.max()) / reach))
        least = max(first.room / room, float(first.extents.max()) / reach)
        factor = (f"by a factor of more than {rounded_up(least)}, at which {first.label} "
                  "would only just fit, with no room to move")
    else:
        factor = "after lowering the clearance"
    plus = f" plus the clearance {clearance:g}" if clearance else ""
    # a clearance deeper than the container: most likely given in mm for a file in metres
    alone = (f" The clearance alone is more than the container's depth ({depth:.4g}): it is "
             f"in the container's units, and this container is {float(c_ext.max()):.4g} "
             "units across (--container-size / container_size sets that size)."
             if room <= 0 else "")
    raise PackingError(
        f"no object fits: the container {label} ({dims} units) is {depth:.4g} units "
        f"deep at its deepest interior point (within {spacing:.2g}), and each object needs "
        f"a depth of at least its own inner room{plus} there. Too large: {listed}{more}."
        f"{alone} Scale the objects down (--type-scale / "
        f"type_scale, {factor}) or the container up (--container-size / container_size)"
        f"{', or lower the clearance' if clearance else ''}.")


def refuse_too_long(label: str, vertices: np.ndarray, sizes: Sequence[TypeSize],
                    shares: np.ndarray, clearance: float) -> None:
    """Refuse a scene where every object type asked for is longer than the container could
    hold in any direction: its extent along an axis of its file (a lower bound of its
    length) plus the clearance at both ends is more than the diagonal of the container's
    box (an upper bound of the container's). Such a type, thin-walled or slender, can have
    little inner room and pass the depth checks, and then "no object could be placed";
    where another type fits, the run goes on and warns that this one was not placed.
    vertices (V, 3): the container mesh's; sizes, shares: the types'."""
    c_ext = np.ptp(vertices, axis=0)
    reach = float(np.linalg.norm(c_ext))
    live = [t for t, q in zip(sizes, shares, strict=True) if q > 0]
    if not live or any(float(t.extents.max()) + 2.0 * clearance <= reach * (1 + 1e-9)
                       for t in live):
        return
    listed = "; ".join(f"{t.label}: {' x '.join(f'{x:.4g}' for x in t.extents)} units"
                       for t in live[:5])
    more = f"; and {len(live) - 5} more" if len(live) > 5 else ""
    least = min(float(t.extents.max()) for t in live)
    plus = f" (with the clearance {clearance:g} at both ends)" if clearance else ""
    # the clearance does not scale with the objects: they need the room it leaves
    room = reach - 2.0 * clearance
    objects = (f"by a factor of at least {rounded_up(least / room)}" if room > 0
               else "after lowering the clearance")
    raise PackingError(
        f"no object fits: the container {label} is {' x '.join(f'{x:.4g}' for x in c_ext)} "
        f"units, at most {reach:.4g} across (its box's diagonal), and the object type"
        f"{'s' if len(live) > 1 else ''} {listed}{more} {'are' if len(live) > 1 else 'is'} "
        f"longer than that{plus}. Scale the objects down (--type-scale / type_scale, "
        f"{objects}) or the container up (--container-size / container_size, by a factor "
        f"of at least {rounded_up((least + 2.0 * clearance) / reach)})"
        f"{', or lower the clearance' if clearance else ''}.")


def tight_fit_spacing(vertices: np.ndarray, faces: np.ndarray, types: Sequence[MeshData],
                      sizes: list[TypeSize], live: list[int], grid: DistanceGrid,
                      depth: float, spacing: float, clearance: float, type_scale: float,
                      measured: tuple[float, DistanceGrid] | None = None
                      ) -> tuple[float, tuple[float, DistanceGrid] | None]:
    """The container grid's spacing, finer where a type only just fits: at most a third of the
    room its deepest point leaves around the type's inner room (container units).

    Between its nodes the grid's interpolant reads up to about half a cell less than the
    true distance where the wall's distance peaks (the medial axis: the middle of a box),
    so an object with less room to spare than a cell fitted nowhere for the solver: a
    radius-2 ball in a 4.2 box, a 9 mm cube in a 9.5 mm or a 10 mm one, refused as "no
    object could be placed" (docs/notes-robustness.md). vertices, faces: the container
    mesh; grid: its distance grid so far; types: the object meshes (their files' units,
    scaled by type_scale); ``depth``: the container's depth on the first grid;
    ``spacing``: the fidelity's; ``measured``: the fine grid's depth and that grid
    (`measured_depth`) when the caller has them already. Returns (the spacing, the
    measured depth and grid, or None where no type only just fits and none was given)."""
    near = [i for i in live if float(sizes[i].extents.min()) / 2 + clearance > depth - spacing]
    if not near:
        return spacing, measured
    measured = measured if measured is not None else measured_depth(vertices, faces, grid)
    deepest = measured[0]
    slack = []
    for i in near:
        room = inner_room(types[i].vertices, types[i].faces) * type_scale
        # the fine grid's deepest node: beyond its exact band it can read high
        # (docs/notes-robustness.md), which the third taken below still covers; the first
        # grid's can read far low
        left = deepest - room - clearance
        if 0.0 < left < spacing:
            slack.append(left)
    return (min(spacing, min(slack) / 3.0) if slack else spacing), measured


def inscribed_lower_bound(t: ObjectType) -> float:
    """A lower bound of the type's inscribed radius (local units, as scaled): its inner room
    or the exact distance from its deepest inner sphere centre to its surface, whichever is
    more. The spheres' radii are no bound: they come from the type's grid, whose nodes far
    from the surface read at least the true distance (a radius 2.0 where 1.64 fits)."""
    centres = np.asarray(t.sphere_centres, np.float64).reshape(-1, 3)
    at_centres = (float(surface_distance(centres, t.vertices, t.faces).max())
                  if len(centres) else 0.0)
    return max(inner_room(t.vertices, t.faces), at_centres)


def check_types_fit(objtypes: list[ObjectType], cont: Container, clearance: float) -> None:
    """A type whose inscribed radius (plus the clearance) is deeper than the container fits
    nowhere, and is refused (`inscribed_lower_bound`); the grid's depth is within a cell of
    the true depth, and where that leaves it open, `has_depth` settles it on the container
    mesh."""
    grid = cont.grid
    depth = float(grid.values.max())
    no_room = []
    for t in objtypes:
        if t.share <= 0:
            continue
        need = inscribed_lower_bound(t) + clearance
        if need > depth + grid.spacing:
            no_room.append((f"{t.name} ({t.path})" if t.path else t.name, need, depth))
        elif need > depth - grid.spacing:
            found, deepest = has_depth(cont.vertices, cont.faces, grid, need)
            if found is False:
                no_room.append((f"{t.name} ({t.path})" if t.path else t.name, need,
                                deepest))
    if no_room:
        deepest = max(d for _, _, d in no_room)
        names = ", ".join(n for n, _, _ in no_room)
        needs = " and ".join(f"{need:.4g}" for _, need, _ in no_room)
        raise PackingError(
            f"object type{'s' if len(no_room) > 1 else ''} {names} cannot fit: the "
            f"container's deepest interior point is about {deepest:.4g} units from its "
            f"wall, and the type{'s need' if len(no_room) > 1 else ' needs'} at least {needs} "
            "(the inscribed radius"
            f"{' plus the clearance' if clearance else ''}). Scale the container up "
            "(--container-size / container_size) or the objects down (--type-scale / "
            f"type_scale){', lower the clearance' if clearance else ''}, or remove the type.")


@dataclass(frozen=True)
class OutOfReach:
    """A type the solver cannot place anywhere (`out_of_reach`): its index, and
    what it needs against what the container has (container units): with `why` "depth",
    the depth of its inscribed radius, the clearance and its contact margins against the
    container's depth found; with "length", its length and the clearance at both
    ends against the container box's diagonal."""

    type: int
    need: float
    has: float
    why: str = "depth"


def out_of_reach(objtypes: Sequence[ObjectType], cont: Container, margins: Margins,
                 clearance: float) -> list[OutOfReach]:
    """The types (with a share) that the solver can place nowhere: no point of the container
    is as deep as the type's inscribed radius (`inscribed_lower_bound`) plus the clearance
    and the contact margins the solver keeps from the wall (its own and the wall's), which
    `has_depth` proves on the container mesh; or it is longer than the container could hold
    in any direction (`refuse_too_long`). Run without them, the others pack at their shares
    among themselves instead of starving while the mix waits for a type that never grows.
    None where every type is out of reach (the run then says why nothing was placed)."""
    grid = cont.grid
    top = float(grid.values.max())
    across = float(np.linalg.norm(np.ptp(cont.vertices, axis=0)))
    live = [i for i, t in enumerate(objtypes) if t.share > 0]
    out = []
    for i in live:
        t = objtypes[i]
        length = float(np.ptp(t.vertices, axis=0).max()) + 2.0 * clearance
        if length > across * (1 + 1e-9):
            out.append(OutOfReach(i, length, across, "length"))
            continue
        need = (inscribed_lower_bound(t) + clearance + float(margins.objects[i])
                + float(margins.wall))
        if need > top - grid.spacing:  # within a cell of the grid's depth: settle it
            found, deepest = has_depth(cont.vertices, cont.faces, grid, need)
            if found is False:
                out.append(OutOfReach(i, need, deepest))
    return out if len(out) < len(live) else []


#: `has_depth`'s limits: points measured in all, and halvings of the first cells
DEPTH_SEARCH_POINTS = 500_000
DEPTH_SEARCH_LEVELS = 12


def has_depth(vertices: np.ndarray, faces: np.ndarray, grid: DistanceGrid,
              depth: float) -> tuple[bool | None, float]:
    """Whether some point inside the closed mesh (V, 3) / (F, 3) lies `depth` or more from
    its surface: True (one was found), False (none can: proven) or None (not settled
    within the search's limits, or `depth` under two cells); and the deepest distance
    found (a lower bound of the mesh's depth; the grid's largest value where none was
    measured). The distance to the surface changes by at most the distance moved, so a
    cube of half side h whose centre is d from the surface holds no point deeper than
    d + sqrt(3) h: the cells of the grid's nodes deep enough to matter are halved until
    each either holds such a point or cannot (branch and bound on the mesh's exact
    distances). grid: the mesh's distance grid (positive inside), whose nodes read at
    least their distance, or within a cell of it."""
    h = grid.spacing
    deepest = float(grid.values.max())
    if depth < 2.0 * h:  # a cell of a node inside may reach outside: not settled here
        return None, deepest
    root3 = float(np.sqrt(3.0))
    # inside (positive) and no further below `depth` than a cell's reach and a cell's slack
    nodes = np.argwhere(grid.values >= depth - (0.5 * root3 + 1.0) * h)
    v = np.ascontiguousarray(vertices, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    centres = grid.origin + nodes * h
    half = 0.5 * h
    measured = 0
    found = -np.inf
    for _ in range(DEPTH_SEARCH_LEVELS):
        if len(centres) == 0:
            return False, found if np.isfinite(found) else deepest
        measured += len(centres)
        if measured > DEPTH_SEARCH_POINTS:
            return None, deepest
        # a kept cell's centre lies within sqrt(3)/2 h of a node inside: where it is
        # outside, its (unsigned) distance is below a cell and its cell is dropped
        d = surface_distance(centres, v, f)
        found = max(found, float(d.max()))
        if found >= depth:
            return True, found
        keep = d + root3 * half >= depth
        half *= 0.5
        offsets = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)],
                           float) * half
        centres = (centres[keep][:, None, :] + offsets[None]).reshape(-1, 3)
    return None, deepest


def nothing_placed_message(depth: float, objtypes: list[ObjectType], margins: Margins,
                           cont: Container, vertices: np.ndarray, clearance: float,
                           fidelity: str) -> str:
    """Why a run that was not stopped placed no object, and what to change: the container's
    depth (``depth``, measured finer than the approximation's grid) against the room the
    type needing the least takes there: its inner room, the clearance, the contact margins
    (``margins``) and half a cell of the container grid, whose interpolant reads the depth's
    peak up to that much low. vertices (V, 3): the container mesh's, for the size to ask
    for; fidelity: the run's preset name."""
    spacing = cont.grid.spacing
    half_cell = 0.5 * spacing
    need = []
    for i, t in enumerate(objtypes):
        if t.share > 0:
            room = inner_room(t.vertices, t.faces)
            kept = float(margins.objects[i] + margins.wall)
            need.append((room + clearance + kept + half_cell, room, kept, t.name))
    total, room, kept, name = min(need)
    plus = f" plus the clearance {clearance:g}" if clearance else ""
    extra = (f", and the approximation up to {kept + half_cell:.2g} more (contact margins "
             f"{kept:.2g} and half a container grid cell, {half_cell:.2g})")
    if depth < room + clearance:
        verdict = "so none fits"
    elif depth < total:
        verdict = "so none fits the approximation"
    else:
        verdict = "and no object fitted anywhere"
    # a finer preset refines the objects' approximation, and the container grid and the
    # margins unless the grid is at its cap already
    extents = np.ptp(vertices, axis=0)
    size = float(extents.max())
    capped = spacing <= finest_spacing(extents) * (1 + 1e-9)
    useful = depth >= total or (depth >= room + clearance and not capped)
    finer = ("Try --fidelity high / fidelity='high' (finer grids, smaller margins), or "
             if fidelity != "high" and useful else "")
    larger = ""
    if depth > 0:
        factor = total / depth * 1.001
        larger = (f" by at least {(factor - 1) * 100:.3g}% (--container-size "
                  f"{size * factor:.4g} / container_size)" if factor > 1 else "")
    if not larger:
        larger = " (--container-size / container_size)"
    return (
        f"no object could be placed: the container's deepest interior point is {depth:.4g} "
        f"units from its wall; {name}, the type needing the least depth, needs at least "
        f"{room:.4g} (its inner room){plus}{extra}, {verdict}. {finer}"
        f"{'s' if finer else 'S'}cale the container up{larger} or the objects down "
        f"(--type-scale / type_scale){' or lower the clearance' if clearance else ''}.")
