"""What an export is asked to do (shared by the CLI, the add-on and the benchmarks).

Lengths are in container units (millimetres for printing); frames are the packing's
container frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jampacked.core.errors import InputError

MODES = ("union", "connect", "parts")
AXES = ("+x", "-x", "+y", "-y", "+z", "-z")


def up_rotation(up: str) -> np.ndarray:
    """(3, 3) proper rotation (a signed permutation) taking the axis ``up`` ("+x" ... "-z")
    to +z."""
    if up not in AXES:
        raise InputError(f"the up axis must be one of {', '.join(AXES)}, got {up!r}.")
    k = "xyz".index(up[-1])
    z = np.eye(3)[k] * (-1.0 if up.startswith("-") else 1.0)
    x = np.eye(3)[(k + 1) % 3]
    return np.array([x, np.cross(z, x), z])  # rows: the new axes in old coordinates


def rotate_axis(axis: str, rotation: np.ndarray) -> str:
    """The axis name ("+x" ... "-z") that ``axis`` becomes under a signed permutation."""
    v = rotation @ (np.eye(3)["xyz".index(axis[-1])] * (-1.0 if axis.startswith("-") else 1.0))
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] > 0 else "-") + "xyz"[k]


@dataclass(frozen=True)
class Opening:
    """An opening in the shell so the packed objects show.

    kind: "plane" removes the shell beyond a plane perpendicular to ``axis`` placed at
        fraction ``at`` (0..1) of the container's extent along that axis, measured from the
        side ``axis`` points away from (``+z`` at 0.75: the top quarter of the shell goes).
    kind: "window" cuts a round hole of diameter ``size`` (container units) through the
        shell's side that faces ``axis``, centred on the container's bounding-box centre, or
        where the line through it meets no wall (the hole of a torus) beside it, where the
        wall is flattest (`openings.cut_window`).
    """

    kind: str = "plane"
    axis: str = "+z"
    at: float = 0.75
    size: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ("plane", "window"):
            raise InputError(f"opening kind must be 'plane' or 'window', got {self.kind!r}.")
        if self.axis not in AXES:
            raise InputError(f"opening axis must be one of {', '.join(AXES)}, got "
                             f"{self.axis!r}.")
        if self.kind == "plane" and not 0.0 < self.at < 1.0:
            raise InputError(f"the opening plane must lie inside the container: give a "
                             f"fraction between 0 and 1 of its height, got {self.at}.")
        if self.kind == "window" and not self.size > 0:
            raise InputError(f"a window needs a diameter > 0 (container units), got "
                             f"{self.size}.")


@dataclass(frozen=True)
class ExportOptions:
    """mode: "union" (one watertight body where objects touch), "connect" (one body: floating
    objects tied in by struts) or "parts" (one body per object, kept apart).

    shell: wall thickness of the container shell, or None for no shell (not with "parts").
    opening: an opening in the shell (plane cut or window), or None.
    drain: diameter of a drainage/escape hole through the shell's lowest point (-z), or None.
    connector: strut diameter for "connect"; None picks 0.2 x the smallest object's
        equivalent diameter.
    resolution: simplify every mesh to this tolerance (the printer's resolution), or None.
    split_files: "parts" only: one file per part (out_stem_<type>_<i>.<ext>) instead of one
        file with one object per part.
    up: the axis that points up when printing ("+z" by default; "+y" for Y-up models): the
        drain hole goes through the lowest point along it.
    fill_voids: "union" and "connect": fill the sealed voids (pockets shut in between
        objects, struts and shell) so no resin or powder is trapped in the print. A closed
        shell (no opening, no drain) is a sealed print by choice: its voids stay hollow.
    """

    mode: str = "connect"
    shell: float | None = None
    opening: Opening | None = None
    drain: float | None = None
    connector: float | None = None
    resolution: float | None = None
    split_files: bool = False
    up: str = "+z"
    fill_voids: bool = True

    def __post_init__(self) -> None:
        up_rotation(self.up)  # checks the axis name
        if self.mode not in MODES:
            raise InputError(f"export mode must be one of {', '.join(MODES)}, got "
                             f"{self.mode!r}.")
        for name in ("shell", "drain", "connector", "resolution"):
            value = getattr(self, name)
            if value is not None and not (value > 0 and value < float("inf")):
                raise InputError(f"{name} must be a positive length (container units), got "
                                 f"{value}.")
        if self.mode == "parts" and self.shell is not None:
            raise InputError("parts mode writes the objects only: a shell would trap them. "
                             "Drop --shell, or use --mode union or connect.")
        if (self.opening is not None or self.drain is not None) and self.shell is None:
            raise InputError("an opening or drain hole needs a shell: give --shell "
                             "THICKNESS too.")
        if self.split_files and self.mode != "parts":
            raise InputError("one file per part only applies to --mode parts.")


#: a resolution coarser than this fraction of an object's (or the container's) size would
#: simplify it out of shape, or to nothing
RESOLUTION_PER_SIZE = 0.25


#: prints smaller or larger than this (largest extent, mm) are named in a warning: most likely
#: a scene modelled in metres or micrometres (or millimetres that Blender took for metres),
#: written to the file as millimetres
PRINT_MM = (1.0, 5000.0)


def print_size_warning(extents: np.ndarray) -> list[str]:
    """A warning when the print, its lengths read as millimetres as 3MF and slicers read
    them, would be under a millimetre or over five metres across; else none. extents: (3,)
    the container's bounding-box extents (container units)."""
    size = " x ".join(f"{e:.3g}" for e in extents)
    largest = float(np.max(extents))
    if PRINT_MM[0] <= largest <= PRINT_MM[1]:
        return []
    factor = 1000 if largest < PRINT_MM[0] else 0.001
    return [f"the print is {size} mm: the packing's lengths are written as millimetres, "
            f"and this looks like a scene in another unit (x{factor:g} would make it "
            f"{largest * factor:.3g} mm across). If so, scale the container and the objects "
            "to millimetres (--container-size and --type-scale) and pack again."]


def check_scale(options: ExportOptions, extents: np.ndarray,
                smallest_object: float | None) -> None:
    """Refuse lengths that cannot work at the scene's scale, naming the option and the fix.

    extents: (3,) the container's bounding-box extents; smallest_object: the smallest type's
    equivalent diameter, or None when there are no objects. Container units. Run before any
    heavy work: a shell, a strut or a drain wider than the container, or a resolution
    coarser than the objects, would otherwise end deep inside the geometry.
    """
    small = float(np.min(extents))
    if options.shell is not None and options.shell >= 0.5 * small:
        raise InputError(
            f"--shell {options.shell:g} is too thick for this container: its smallest extent "
            f"is {small:.4g}, so walls that thick from both sides leave no cavity. Give a "
            f"thickness well below {0.5 * small:.3g} (e.g. {0.05 * small:.2g}).")
    for name, value in (("--drain", options.drain), ("--connector", options.connector)):
        if value is not None and value >= small:
            raise InputError(
                f"{name} {value:g} is wider than the container (its smallest extent is "
                f"{small:.4g}). Give a diameter well below that (e.g. {0.05 * small:.2g}).")
    opening = options.opening
    if opening is not None and opening.kind == "window":
        across = [float(e) for i, e in enumerate(extents) if i != AXES.index(opening.axis) // 2]
        if opening.size >= min(across):
            raise InputError(
                f"--window {opening.axis}@{opening.size:g} is wider than the container's "
                f"{opening.axis} side ({across[0]:.4g} x {across[1]:.4g}): it would cut the "
                f"side away. Give a diameter below {min(across):.4g} (e.g. "
                f"{0.5 * min(across):.2g}), or --open-plane to open a whole side.")
    if options.resolution is None:
        return
    size, what = small, "the container's smallest extent"
    if smallest_object is not None and smallest_object < size:
        size, what = smallest_object, "the smallest object's equivalent diameter"
    if options.resolution > RESOLUTION_PER_SIZE * size:
        raise InputError(
            f"--resolution {options.resolution:g} is coarser than the scene: {what} is "
            f"{size:.4g}, and simplifying by the resolution would wear it out of shape or to "
            f"nothing. Give your printer's resolution, below {RESOLUTION_PER_SIZE * size:.3g} "
            "(e.g. 0.05 for 0.05 mm).")
