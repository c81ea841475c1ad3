"""A printable shell of the container: the container minus its inward offset by T.

Frame and units: the container frame, container units (millimetres for printing); the
container mesh given is already scaled, closed and outward wound. The stages live in their
own modules: the offset (:mod:`jampacked.export.offset`), the openings and drain
(:mod:`jampacked.export.openings`) and the wall measurement (:mod:`jampacked.export.wall`).
The outer surface is the container's own mesh, untouched.
"""

from __future__ import annotations

import math
import numbers
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import manifold3d as m3
import numpy as np

from jampacked.core.errors import InputError
from jampacked.core.solids import to_solid

from .offset import MAX_GRID_NODES, grid_spacing, inner_solid
from .openings import cut_window, drill_drain, opening_label, plane_cut
from .options import Opening
from .wall import measure_wall_thickness, wall_thickness

__all__ = ["ShellReport", "make_shell", "measure_wall_thickness", "opening_label"]


@dataclass
class ShellReport:
    """What :func:`make_shell` made; lengths in container units (mm), volumes in units³.

    thickness: the wall thickness T asked for.
    measured_min/median/max: wall thickness measured on the result (exact distance from points
        on the inner surface to the container mesh; see :func:`measure_wall_thickness`).
    samples: how many random points of the inner surface that measurement used (the least
        is also measured at its vertices).
    opening: the opening cut, e.g. ``"plane +z@0.75"`` or ``"window +y 30 mm"``, or None.
    drain: drain hole diameter, or None.
    volume: volume of the shell solid.
    triangles: triangles of the shell solid.
    seconds: wall-clock time of :func:`make_shell`.
    grid_spacing: spacing of the distance grid the inner surface came from.
    tolerance: the simplification tolerance applied to the inner surface (0: none).
    cavities: closed cavities (inner surface components) kept.
    drain_at: (x, y, z) where the drain's axis leaves the cavity (its lowest point), or None.
    notes: warnings a user should read (e.g. a window that missed the wall).
    """

    thickness: float
    measured_min: float
    measured_median: float
    measured_max: float
    samples: int
    opening: str | None
    drain: float | None
    volume: float
    triangles: int
    seconds: float
    grid_spacing: float = 0.0
    tolerance: float = 0.0
    cavities: int = 0
    drain_at: tuple[float, float, float] | None = None
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """JSON-able dict of every field."""
        out = asdict(self)
        out["drain_at"] = None if self.drain_at is None else [float(c) for c in self.drain_at]
        out["notes"] = list(self.notes)
        return out


def make_shell(vertices: np.ndarray, faces: np.ndarray, thickness: float, *,
               opening: Opening | None = None, drain: float | None = None,
               resolution: float | None = None,
               progress: Callable[[float, str], None] | None = None,
               samples: int = 2000,
               drain_covered: Callable[[np.ndarray], bool] | None = None,
               drain_reach: float = 0.0,
               simplify: bool = True) -> tuple[m3.Manifold, ShellReport]:
    """Shell of the container with wall thickness ``thickness``: container minus its offset.

    Args:
        vertices: (V, 3) container vertices, container frame, container units (mm), already
            scaled; the mesh must be closed and outward wound (as :func:`load_mesh` returns).
        faces: (F, 3) int vertex indices.
        thickness: wall thickness T (> 0).
        opening: cut the shell open (plane or window, see :class:`Opening`), or None.
        drain: diameter of a drain hole through the bottom wall under the cavity's lowest
            point, or None. Resin and powder printers need one so that uncured resin or loose
            powder can escape from the cavity.
        resolution: the printer's resolution: the inner surface is made on a grid of this
            spacing and simplified to min(resolution/2, T/10). Default: spacing T/4,
            simplified to min(spacing/10, T/20). Either way the grid is coarsened to stay
            under ``MAX_GRID_NODES`` nodes. T is the wall's least thickness (as slicers'
            hollowing takes it): the inner surface keeps T plus the simplification's
            tolerance from the container, its vertices at least that far.
        progress: ``progress(fraction, message)`` called as the work goes on.
        samples: random points used to measure the wall thickness (its least also at the
            inner surface's vertices).
        drain_covered, drain_reach: whether objects sit on a drain at a point (this
            function's frame), and how far from the cavity's lowest point the drain may
            move to open beside them (`openings.drill_drain`).
        simplify: False keeps every triangle of the inner surface's grid (heavier, but with
            no long thin faces for a later union to fold).

    Returns:
        (shell, report): the shell solid (its outer surface is the container mesh itself, its
        inner surface the offset) and a :class:`ShellReport` with the measured thickness.

    Raises:
        InputError: T or a diameter is not a positive length, or T is too large for the
            container (no cavity would be left; the message gives the largest T that works),
            or a window misses the shell.
    """
    t0 = time.perf_counter()
    report_progress = progress or (lambda fraction, message: None)
    v, f = _checked_input(vertices, faces, thickness, drain, resolution)
    lo, hi = v.min(axis=0), v.max(axis=0)
    spacing = grid_spacing(lo, hi, thickness, resolution)
    if not simplify:
        tolerance = 0.0
    elif resolution is not None:
        tolerance = min(0.5 * resolution, 0.1 * thickness)
    else:
        tolerance = min(0.1 * spacing, 0.05 * thickness)
    report_progress(0.0, f"shell: distance grid at {spacing:.3g} spacing")
    inner, cavities, used = inner_solid(v, f, thickness, spacing, tolerance)
    notes: list[str] = []
    if used == 0.0 and simplify:
        notes.append(f"the inner surface could not be simplified watertight, so it keeps all "
                     f"{inner.num_tri()} triangles of the grid.")
    report_progress(0.6, "shell: subtracting the inner surface")
    shell = to_solid(v, f) - inner
    drain_at = None
    if drain is not None:
        report_progress(0.7, "shell: drain hole")
        shell, drain_at = drill_drain(shell, inner, drain, thickness, drain_covered,
                                      drain_reach, notes, level=max(used, 0.01 * spacing))
        if cavities > 1:
            notes.append(f"the shell has {cavities} separate cavities; the drain opens only "
                         "the lowest one.")
    if opening is not None:
        report_progress(0.75, f"shell: {opening.kind} opening")
        if opening.kind == "plane":
            shell = plane_cut(shell, opening, lo, hi)
        else:
            shell = cut_window(shell, opening, lo, hi, thickness, notes)
    report_progress(0.85, "shell: measuring the wall thickness")
    measured, at_vertices = wall_thickness(v, f, inner, n=samples)
    least = float(min(measured.min(initial=math.inf), at_vertices.min(initial=math.inf)))
    notes += _accuracy_notes(least, measured, thickness, spacing, resolution, tolerance)
    report = ShellReport(
        thickness=float(thickness),
        measured_min=least if measured.size else math.nan,
        measured_median=float(np.median(measured)) if measured.size else math.nan,
        measured_max=float(measured.max()) if measured.size else math.nan,
        samples=int(measured.size),
        opening=opening_label(opening),
        drain=None if drain is None else float(drain),
        volume=float(shell.volume()),
        triangles=int(shell.num_tri()),
        seconds=time.perf_counter() - t0,
        grid_spacing=spacing,
        tolerance=float(used),
        cavities=cavities,
        drain_at=drain_at,
        notes=notes,
    )
    report_progress(1.0, "shell: done")
    return shell, report


def _checked_input(vertices: np.ndarray, faces: np.ndarray, thickness: float,
                   drain: float | None, resolution: float | None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The container as contiguous float64 / int64 arrays, once the lengths are checked."""
    for name, value, optional in (("shell thickness", thickness, False),
                                  ("drain diameter", drain, True),
                                  ("resolution", resolution, True)):
        if value is None and optional:
            continue
        if not (isinstance(value, numbers.Real) and math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive length (container units), got "
                             f"{value}.")
    v = np.ascontiguousarray(vertices, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InputError(f"the container must be (V, 3) vertices and (F, 3) triangles, got "
                         f"{v.shape} and {f.shape}.")
    return v, f


#: a wall measured thinner than this fraction of T is said to be under T
THINNEST_SAID = 0.999


def _accuracy_notes(least: float, measured: np.ndarray, thickness: float, spacing: float,
                    resolution: float | None, tolerance: float) -> list[str]:
    """A note where the measured wall is under T at its thinnest by more than 0.1% (said
    to four digits, so that the figure reads under T: the grid was coarse for it; `--shell`
    promises at least T), or more than 10% over T at its median (T plus a simplification
    tolerance asked by a coarse --resolution)."""
    if not measured.size:
        return []
    median = float(np.median(measured))
    fix = ("give a finer --resolution" if resolution is not None and spacing == resolution
           else f"the distance grid is capped at {MAX_GRID_NODES:,} nodes: use a thicker "
           "wall or a smaller container")
    if least < THINNEST_SAID * thickness:
        return [f"the wall is {least:.4g} thick at its thinnest, under the {thickness:g} "
                f"asked: the grid spacing {spacing:.3g} is coarse for this thickness; {fix}."]
    if median > 1.1 * thickness:
        return [f"the wall is {median:.3g} thick at its median, {median / thickness - 1:.0%} "
                f"over the {thickness:g} asked: no part of it may be thinner than "
                f"{thickness:g}, and the inner surface is simplified by up to {tolerance:.2g} "
                f"(grid spacing {spacing:.3g}); {fix}."]
    return []
