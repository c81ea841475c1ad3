"""How finely the solver models a scene: sphere counts, grid resolutions, surface points.

Three presets (low, medium, high) and `choose_fidelity`, which picks the resolution from the
scene ("model no more than the scene needs"). Certification and export always use the real
meshes; only the solver's approximations depend on the fidelity. Lengths in container units.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Fidelity:
    """Resolution of the solver's approximations.

    spheres: inner spheres per type; grid_cells: cells of a type's distance grid across its
    largest extent; surface_points: surface samples per type; container_cells: container
    grid cells per equivalent radius f(V) of the smallest type.
    """

    name: str
    spheres: int
    grid_cells: int
    surface_points: int
    container_cells: float
    reasons: tuple[str, ...] = ()


#: low saves on spheres and grids but keeps medium's surface points: with fewer, the solver
#: missed overlaps that certification then removed (a third to a half of the objects,
#: docs/notes-core.md "The low preset")
PRESETS = {
    "low": Fidelity("low", 24, 28, 384, 3.0),
    "medium": Fidelity("medium", 64, 40, 384, 4.0),
    "high": Fidelity("high", 160, 64, 384, 6.0),
}

#: above this many expected objects the auto choice uses fewer spheres per object
MANY_OBJECTS = 1500
#: a type this many times longer than thick gets a finer grid (its thickness in >= 8 cells)
CELLS_ACROSS_THICKNESS = 8
#: a container whose deepest point is within this many smallest radii of its wall is tight
TIGHT_DEPTH = 2.0
#: surface points per type with a clearance: between points the surface comes closer to a
#: neighbour than the points say, and an exact gap check has no tolerance (more points
#: shrink that gap several times over, docs/notes-core.md; `core/margins.py` covers the rest)
CLEARANCE_POINTS = 1024


def preset(name: str, clearance: float) -> Fidelity:
    """The preset `name` for a scene with this clearance (container units): "high" then
    takes CLEARANCE_POINTS surface points as the automatic choice does. With its own 384,
    the finest preset kept the larger sampling gaps, and so margins, of fewer points
    (docs/notes-core.md)."""
    fid = PRESETS[name]
    if name == "high" and clearance > 0 and fid.surface_points < CLEARANCE_POINTS:
        fid = replace(fid, surface_points=CLEARANCE_POINTS, reasons=fid.reasons + (
            f"clearance {clearance:g}: {CLEARANCE_POINTS} surface points per type",))
    return fid


def thickness_ratio(vertices: np.ndarray) -> float:
    """Largest over smallest extent along the principal axes of a vertex cloud (V,3)."""
    v = vertices - vertices.mean(axis=0)
    _, _, axes = np.linalg.svd(v, full_matrices=False)
    ext = np.ptp(v @ axes.T, axis=0)
    return float(ext.max() / max(ext.min(), 1e-12 * ext.max()))


def choose_fidelity(type_vertices: list[np.ndarray], expected_objects: float,
                    clearance: float, depth_over_radius: float,
                    depth_over_largest: float = np.inf) -> Fidelity:
    """The automatic fidelity for a scene.

    type_vertices: each type's vertices in container units (local frame).
    expected_objects: objects a half-full container would hold. clearance: container units.
    depth_over_radius: the container's deepest interior distance over the smallest type's
    equivalent radius (how much room the tightest object has); depth_over_largest: the same
    depth over the largest type's bounding radius (below 1 the largest objects cannot turn
    freely anywhere).
    Starts from `medium` and moves each knob for a reason:
    - many objects: fewer spheres (the solver's cost per contact is spheres squared; with
      thousands of objects, time per object matters more than the last percent);
    - elongated or flat types (banana): a finer grid, so their thickness spans enough cells;
    - a clearance smaller than a grid cell: a finer grid, so the grid's error stays below it;
    - any clearance: CLEARANCE_POINTS surface points per type;
    - a tight container (the smallest object only just fits its deepest point, or the
      largest cannot turn freely anywhere, like fruit in a torus's tube): high's container
      grid, since nearly every contact is a wall contact, with medium's spheres and object
      grid (on the torus it beat high's resolution throughout, in less time:
      docs/notes-core.md).
    """
    tight = depth_over_radius < TIGHT_DEPTH or depth_over_largest < 1.0
    base = PRESETS["medium"]
    container_cells = PRESETS["high"].container_cells if tight else base.container_cells
    reasons = [f"tight container: {container_cells:g} container grid cells per radius"
               ] if tight else []
    spheres = base.spheres
    if expected_objects > MANY_OBJECTS:
        spheres = PRESETS["low"].spheres
        reasons.append(f"about {expected_objects:.0f} objects: {spheres} spheres per type")
    cells = base.grid_cells
    extents = [float(np.ptp(v, axis=0).max()) for v in type_vertices]
    ratio = max(thickness_ratio(v) for v in type_vertices)
    want = int(np.ceil(CELLS_ACROSS_THICKNESS * ratio))
    if want > cells:
        cells = min(want, PRESETS["high"].grid_cells)
        reasons.append(f"a type {ratio:.1f} times longer than thick: {cells} grid cells")
    points = base.surface_points
    if clearance > 0:
        want = int(np.ceil(max(extents) / clearance))
        if want > cells:
            cells = min(want, PRESETS["high"].grid_cells)
            reasons.append(f"clearance {clearance:g}: {cells} grid cells")
        points = max(points, CLEARANCE_POINTS)
        reasons.append(f"clearance {clearance:g}: {points} surface points per type")
    return replace(base, name="auto", spheres=spheres, grid_cells=cells,
                   surface_points=points, container_cells=container_cells,
                   reasons=tuple(reasons))
