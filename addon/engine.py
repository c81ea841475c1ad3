"""The add-on's calls into jampacked, on plain arrays (no bpy: safe in the worker thread).

Frames: the Blender side (:mod:`.bridge`) hands over world-space triangles, so a packing's
container frame is Blender's world space (``frame_from_file`` is the identity) and a type's
"file" coordinates are the type object's world-space vertices at packing time. Units are
Blender units throughout, until Export scales everything to millimetres (:func:`scaled`).

jampacked itself is imported inside the functions: registering the add-on stays fast, and a
missing engine (no wheels installed) becomes a clear message instead of a failed register.
"""

from __future__ import annotations

import copy
import hashlib
import os
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from jampacked.core.meshes import MeshData
    from jampacked.core.packing import Packing
    from jampacked.export.assemble import ExportReport
    from jampacked.export.options import ExportOptions
    from jampacked.export.validate import ValidationReport

    from .result_edits import Placements

Progress = Callable[[float, str], None]
ShouldCancel = Callable[[], bool]

#: how the packing JSON names a container that came from Blender (a spec string, which
#: jampacked keeps verbatim and never reads as a file)
CONTAINER_SPEC = "blender:"


def engine_missing() -> str | None:
    """None when jampacked can be imported, else a message saying how to fix it."""
    try:
        import jampacked.core.api  # noqa: F401
        import jampacked.export.validate  # noqa: F401
    except ImportError as exc:
        return (f"the jampacked engine cannot be imported ({exc}); install the extension "
                "from its zip (which bundles the engine and its wheels), or install "
                "jampacked into Blender's Python.")
    return None


@dataclass
class Triangles:
    """A triangle mesh read from Blender.

    Attributes:
        name: the object's (or mesh's) name, for messages.
        vertices: (V, 3) float64 positions (world space for objects).
        faces: (F, 3) int64 vertex indices (Blender's loop triangles).
        tri_polygon: (F,) int64 polygon of each triangle.
        n_polygons: polygons of the Blender mesh.
        modifiers: the object's modifiers shown in the viewport, which made these triangles
            (a defect they make is mended there, not in the mesh).
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    tri_polygon: np.ndarray
    n_polygons: int
    modifiers: tuple[str, ...] = ()

    def signature(self) -> str:
        """sha256 of the positions and triangles: equal means the same geometry."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.vertices, np.float64).tobytes())
        h.update(np.ascontiguousarray(self.faces, np.int64).tobytes())
        return h.hexdigest()

    def mesh_data(self, role: str) -> MeshData:
        """Checked (and repaired) engine mesh; raises MeshError naming the object (and its
        modifiers, where it has some: the advice's edits apply to the mesh they make)."""
        from jampacked.core.errors import MeshError
        from jampacked.core.meshes import mesh_from_arrays

        try:
            return mesh_from_arrays(self.vertices, self.faces, name=self.name, role=role)
        except MeshError as exc:
            if not self.modifiers:
                raise
            said = ", ".join(f"'{m}'" for m in self.modifiers)
            raise MeshError(f"{exc} This is the mesh its modifiers ({said}) make: where the "
                            "mesh itself is sound, change or remove the modifier that does "
                            "it, or apply the modifiers first (Object > Apply > Visual "
                            "Geometry to Mesh) and mend the result.") from None


#: the sizes (largest extent, Blender units) Pack takes: beyond them areas and volumes stop
#: being finite or the engine's tolerances stop being negligible, and no print or scene is
#: that large or small (1e9 BU is a million kilometres in metres)
MIN_EXTENT = 1e-6
MAX_EXTENT = 1e9


def is_inward(tris: Triangles) -> bool:
    """The triangles enclose a negative volume: wound inwards (inside out)."""
    from jampacked.core.mesh_geometry import signed_six_volumes

    return bool(len(tris.faces)) and float(signed_six_volumes(tris.vertices,
                                                              tris.faces).sum()) < 0


def check_extent(tris: Triangles, what: str) -> None:
    """Refuse a Pack input whose size (largest extent of its world-space vertices) lies
    outside MIN_EXTENT..MAX_EXTENT Blender units, naming it (InputError). Non-finite
    coordinates are left to the mesh checks, which name them."""
    from jampacked.core.errors import InputError

    if not len(tris.vertices) or not np.all(np.isfinite(tris.vertices)):
        return
    with np.errstate(over="ignore"):
        extents = np.ptp(tris.vertices, axis=0)
    size = float(extents.max())
    if MIN_EXTENT <= size <= MAX_EXTENT:
        return
    dims = " x ".join(f"{x:.3g}" for x in extents)
    raise InputError(
        f"{what} '{tris.name}' is {dims} units across: Pack takes objects between "
        f"{MIN_EXTENT:g} and {MAX_EXTENT:g} units. Check its Scale and its parents' (sidebar "
        "> Item) and the scene's units, or scale its mesh in Edit Mode.")


@dataclass
class PackOutcome:
    """What a pack job returns to the main thread."""

    packing: Packing
    json_text: str


def packing_to_json(packing: Packing) -> str:
    """The packing file's text (as ``jampacked pack -o`` writes it)."""
    from jampacked.core.packing_json import save_packing

    with tempfile.TemporaryDirectory(prefix="jampacked-") as tmp:
        path = os.path.join(tmp, "packing.json")
        save_packing(packing, path)
        with open(path, encoding="utf-8") as f:
            return f.read()


def packing_from_json(text: str) -> Packing:
    """Read a packing from its JSON text (InputError on a damaged text)."""
    from jampacked.core.packing_json import load_packing

    with tempfile.TemporaryDirectory(prefix="jampacked-") as tmp:
        path = os.path.join(tmp, "packing.json")
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        return load_packing(path)


def pack_triangles(container: Triangles, types: Sequence[Triangles], shares: Sequence[float],
                   *, seed: int, clearance: float, fidelity: str, time_budget: float | None,
                   mix_tolerance: float | None = None,
                   progress: Progress, should_cancel: ShouldCancel,
                   snapshot: Callable[..., None] | None = None) -> PackOutcome:
    """Check the meshes and pack; runs in the worker thread.

    Returns the certified packing (container frame = world space) and its JSON text, in
    which the container is named ``blender:<object name>`` and the types have no path.
    mix_tolerance caps the type mix error the late cavity passes may reach (None: the
    engine's default). snapshot(positions, radii, types) sees the objects placed so far
    (world space, Blender units; :func:`jampacked.core.api.pack`). Raises JampackedError
    subclasses (MeshError naming the object,
    InputError, ...).
    """
    from jampacked.core.api import pack
    from jampacked.core.options import CavityPassOptions, PackOptions
    from jampacked.core.packing_digest import record_digest

    progress(0.0, f"checking {container.name}")
    cmesh = container.mesh_data("container")
    tmeshes = [t.mesh_data("object") for t in types]
    packing = pack(cmesh, tmeshes, list(shares), seed=seed, clearance=clearance,
                   fidelity=fidelity, time_budget=time_budget, progress=progress,
                   should_cancel=should_cancel, names=[t.name for t in types],
                   snapshot=snapshot,
                   options=None if mix_tolerance is None
                   else PackOptions(cavity=CavityPassOptions(max_tvd=mix_tolerance)))
    packing.container_path = CONTAINER_SPEC + container.name
    record_digest(packing)  # the certified packing under the container's Blender name
    return PackOutcome(packing=packing, json_text=packing_to_json(packing))


def scaled(packing: Packing, container: Triangles, types: Sequence[Triangles],
           options: ExportOptions, k: float
           ) -> tuple[Packing, Triangles, list[Triangles], ExportOptions]:
    """The packing, its meshes and the export lengths with every length multiplied by k
    (e.g. Blender units to millimetres): the same print at another scale.

    Positions and translations scale by k, frames are conjugated by the scaling (a frame's
    rotation stays, its offset scales), volumes scale by k cubed; the clearance and the
    options' lengths (shell, drain, connector, resolution, window size) scale by k.
    """
    import dataclasses

    from jampacked.core.packing_digest import placements_status, record_digest

    s = np.diag([k, k, k, 1.0])
    s_inv = np.diag([1.0 / k, 1.0 / k, 1.0 / k, 1.0])
    certified = placements_status(packing) == "as certified"
    out = copy.deepcopy(packing)
    out.translations = packing.translations * k
    out.frame_from_file = s @ packing.frame_from_file @ s_inv
    out.container_volume = packing.container_volume * k ** 3
    for rec in out.types:
        rec.local_from_file = s @ rec.local_from_file @ s_inv
        rec.volume *= k ** 3
    out.inputs = dataclasses.replace(out.inputs, clearance=out.inputs.clearance * k)
    for key in ("clearance", "min_pair_gap", "min_wall_gap"):
        if isinstance(out.certificate.get(key), int | float):
            out.certificate[key] *= k
    out.report = dataclasses.replace(
        out.report, container_grid_spacing=out.report.container_grid_spacing * k)
    if certified:  # the same certified packing in other units
        record_digest(out)

    def length(v: float | None) -> float | None:
        return None if v is None else v * k

    opening = options.opening
    if opening is not None:
        opening = dataclasses.replace(opening, size=opening.size * k)
    options = dataclasses.replace(
        options, shell=length(options.shell), drain=length(options.drain),
        connector=length(options.connector), resolution=length(options.resolution),
        opening=opening)
    return (out, dataclasses.replace(container, vertices=container.vertices * k),
            [dataclasses.replace(t, vertices=t.vertices * k) for t in types], options)


def export_triangles(packing_json: str, container: Triangles, types: Sequence[Triangles],
                     out_path: str, options: ExportOptions, *, progress: Progress,
                     should_cancel: ShouldCancel, scale: float = 1.0,
                     placements: Placements | None = None) -> ExportReport:
    """Export a packing made in Blender; runs in the worker thread.

    container: world-space triangles of the container object; types: each type's triangles
    in its packing "file" frame (world space at packing time); lengths (these, the
    packing's and the options') in Blender units. scale: millimetres per Blender unit
    (:func:`.units.mm_per_unit`): the file is written in millimetres. placements: what the
    result holds now where the artist changed it (`result_edits.current_placements`): the
    export then certifies them again and names failures by their Blender names. Raises
    JampackedError subclasses (Cancelled when should_cancel() said so).
    """
    from jampacked.core.packing_digest import placements_status, record_digest
    from jampacked.export.assemble import export_packing

    packing = packing_from_json(packing_json)
    as_certified = placements_status(packing) == "as certified"
    labels = None
    if placements is not None:
        packing.type_index = np.asarray(placements.type_index, np.int64)
        packing.rotations = np.asarray(placements.rotations, np.float64)
        packing.translations = np.asarray(placements.translations, np.float64)
        packing.scales = np.asarray(placements.scales, np.float64)
        labels = placements.labels
        if placements.removed_only and as_certified:
            # what is left of a certified packing is certified: nothing to check again
            record_digest(packing)
    if scale != 1.0:
        packing, container, types, options = scaled(packing, container, types, options,
                                                    scale)
    meshes = (container.mesh_data("container"), [t.mesh_data("object") for t in types])
    return export_packing(packing, out_path, options, meshes=meshes, progress=progress,
                          should_cancel=should_cancel, labels=labels)


def export_options(mode: str, shell: float, opening: str, axis: str, at: float, size: float,
                   drain: float, connector: float, resolution: float,
                   split_files: bool, fill_voids: bool = True) -> ExportOptions:
    """ExportOptions from the panel's values (0 means "none"/"auto" for lengths).

    The shell, opening and drain only apply with a shell, and never in parts mode (the
    panel hides them then). Raises InputError for values ExportOptions refuses.
    """
    from jampacked.export.options import ExportOptions, Opening

    mode = mode.lower()
    with_shell = mode != "parts" and shell > 0
    hole = None
    if with_shell and opening != "NONE":
        hole = Opening(kind=opening.lower(), axis=axis, at=at,
                       size=size if opening == "WINDOW" else 0.0)
    return ExportOptions(
        mode=mode, shell=shell if with_shell else None, opening=hole,
        drain=drain if with_shell and drain > 0 else None,
        connector=connector if connector > 0 else None,
        resolution=resolution if resolution > 0 else None,
        split_files=split_files and mode == "parts", fill_voids=fill_voids)


def validate_triangles(tris: Triangles) -> ValidationReport:
    """The checks of ``jampacked validate`` on a Blender mesh."""
    from jampacked.export.validate import validate_arrays

    return validate_arrays(tris.vertices, tris.faces, path=None)


def position_groups(vertices: np.ndarray) -> np.ndarray:
    """(V,) group of each vertex: vertices at exactly the same position share a group (as
    the validation merges them)."""
    from jampacked.export.validate import merge_identical

    return merge_identical(vertices)[1]


def validation_counts(report: ValidationReport) -> list[tuple[str, str, int]]:
    """(kind, label, count) for every offending-element kind with a count, plus the number of
    holes and of bodies; kinds are keys of ``report.offending``."""
    labels = {
        "open_edges": "Open edges",
        "nonmanifold_edges": "Non-manifold edges",
        "inconsistent_edges": "Inconsistent edges",
        "nonmanifold_vertices": "Non-manifold vertices",
        "flipped_faces": "Flipped faces",
        "degenerate_faces": "Degenerate faces",
        "duplicate_faces": "Duplicate faces",
        "intersecting_faces": "Intersecting faces",
    }
    out: list[tuple[str, str, int]] = []
    for kind, label in labels.items():
        arr = report.offending.get(kind)
        count = 0 if arr is None else int(len(arr))
        out.append((kind, label, count))
    holes = sum(b.holes for b in report.bodies)
    out.append(("holes", "Holes", int(holes)))
    out.append(("bodies", "Bodies", len(report.bodies)))
    return out
