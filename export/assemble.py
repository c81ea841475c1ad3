"""From a packing to printable meshes: union, connect or parts, with an optional shell.

Frames: the packing's container frame, container units (mm for printing); see
:mod:`jampacked.export.scene`. manifold3d does every boolean; results go straight from
manifold3d arrays to the writer (no trimesh processing), and every file is validated as
written before it is put in place (:func:`jampacked.export.io.write_meshes`): the files of
one export are put in place all together or not at all. A 3MF of parts stores each type's
mesh once and each part as a component: that mesh and its placement.

:func:`export_packing` runs the stages: read the packing and check the request and every
output path, load the sources (checked against their hashes), place the solids, build the
shell, then union, connect or separate the parts, clean the result, write and validate every
file, and only then put them all in place, report.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import manifold3d as m3
import numpy as np

from jampacked.core.errors import Cancelled, InputError, MeshError, OutputError
from jampacked.core.meshes import MeshData
from jampacked.core.packing import Packing, is_spec
from jampacked.core.packing_digest import claims_certified, uncertified_since
from jampacked.core.packing_json import load_packing
from jampacked.core.solids import solid_arrays

from .connect import connect_scene, default_diameter
from .cost import check_export_cost, estimate_export
from .io import FLOAT32_FORMATS, MeshOutput, check_output_paths, float32_breaks, write_meshes
from .mesh_write import Instances, name_too_long, short_name, write_format
from .openings import drain_cover, solid_boxes
from .options import ExportOptions, check_scale, print_size_warning, rotate_axis, up_rotation
from .parts import require_gap, separate_parts
from .recertify import certify_edited
from .report import ExportReport
from .scene import PlacedScene, load_sources, packing_clearance, place, smallest_object
from .union import UnionVolumeError, clean_bodies, crossing_pairs, loose_bodies, union_arrays
from .weld import shrunk_apart

__all__ = ["ExportReport", "export_packing"]

Progress = Callable[[float, str], None]
Bodies = list[tuple[np.ndarray, np.ndarray]]


def export_packing(packing: Packing | str | os.PathLike,
                   out_paths: str | os.PathLike | Sequence[str | os.PathLike],
                   options: ExportOptions | None = None, *,
                   meshes: tuple[MeshData, Sequence[MeshData]] | None = None,
                   progress: Progress | None = None,
                   should_cancel: Callable[[], bool] | None = None,
                   labels: Sequence[str] | None = None) -> ExportReport:
    """Export a packing as printable meshes and validate every file written.

    packing: a Packing or the path of its JSON file. out_paths: one or more output files
    (.3mf, .stl, .obj, .ply), all written with the same geometry. options: mode, shell,
    opening, drain, connector, resolution (see :class:`ExportOptions`). meshes: the container
    and type meshes in their file frames, to use instead of the files the packing names
    (e.g. from Blender). Lengths in container units. labels: what names each placement
    where the caller has names (Blender's objects), for messages.

    Every output path is checked before any work (format, not an input or the packing
    file, folder there, none named twice); the files are written beside their targets,
    validated, and renamed into place only when all of them passed, so a failure, a cancel
    or an interrupt leaves every previous file as it was.

    Raises InputError (bad options, missing/changed sources, an output that is an input,
    placements that cannot be exported, parts of a packing without clearance, an export
    that needs more memory than the machine has: see :mod:`jampacked.export.cost`), MeshError (a
    file cannot be written, or the result does not validate: nothing is put in place then;
    an STL or PLY whose 32-bit floats cannot hold the result watertight is named so before
    anything is written), Cancelled (should_cancel() said so; nothing is written).
    """
    t0 = time.perf_counter()
    options = options or ExportOptions()
    report = progress or (lambda f, m: None)
    cancel = should_cancel or (lambda: False)

    def check_cancel() -> None:
        if cancel():
            raise Cancelled("export cancelled; no file was written.")

    source = None
    if not isinstance(packing, Packing):
        source = os.fspath(packing)
        packing = load_packing(source)
    paths = _output_paths(out_paths)
    # STL and PLY store float32 positions: the union is checked as they will store it
    float32 = [p for p in paths if write_format(p) in FLOAT32_FORMATS]
    protect = [p for p in ([source, packing.container_path]
                           + [t.path for t in packing.types]) if p and not is_spec(p)]
    part_names = None
    if options.split_files:
        part_names = [f"{packing.types[k].name}_{i:03d}"
                      for i, k in enumerate(packing.type_index)]
    # every file this export writes, checked before any work
    if part_names is not None:
        _check_part_names(packing, paths, part_names)
    check_output_paths(_targets(paths, part_names), protect)
    if packing.n == 0 and options.shell is None:
        raise InputError("the packing has no objects and no shell was asked for: there is "
                         "nothing to export.")
    clearance = packing_clearance(packing, source)
    if options.mode == "parts":
        require_gap(clearance)

    report(0.0, "loading meshes")
    container, types = meshes if meshes is not None else load_sources(packing)
    if len(types) != len(packing.types):
        raise InputError(f"{len(types)} type meshes given for a packing of "
                         f"{len(packing.types)} types.")
    out = ExportReport(mode=options.mode, paths=paths, bodies=0, objects=packing.n,
                       triangles=0, clearance=clearance)
    scene = place(packing, container, types, source, labels)
    check_scale(options, scene.hi - scene.lo, smallest_object(packing))
    out.warnings += print_size_warning(scene.hi - scene.lo)
    scene.make_type_solids(packing, options.resolution)
    # refused here, before an edited packing's certification and before the objects are
    # made solid, when the machine cannot hold it
    cost = estimate_export(options.mode, [s.num_tri() for s in scene.type_solids],
                           packing.type_index,
                           2 * len(scene.container_faces) if options.shell is not None else 0)
    check_export_cost(cost)
    why = uncertified_since(packing)
    if why is not None:
        report(0.01, f"the packing {why}: certifying it")
        note = certify_edited(packing, scene, clearance, source, why,
                              lambda f, m: report(0.01 + 0.04 * f, m), check_cancel, labels,
                              refuse=claims_certified(packing))
        if note:
            out.warnings.append(note)
        check_cancel()
    report(0.05, f"exporting ~{cost.triangles:,.0f} triangles (estimated peak memory "
                 f"{cost.memory / 2**30:.2g} GiB)")
    scene.place_solids(packing, source)
    out.triangles_saved = scene.triangles_saved
    out.resolution_deviation = scene.resolution_deviation
    out.timings["load"] = time.perf_counter() - t0
    check_cancel()

    shell = None
    if options.shell is not None:
        t = time.perf_counter()
        shell, out.shell = _shell(scene, options, report)
        out.timings["shell"] = time.perf_counter() - t
        check_cancel()
        if out.shell.drain_at is not None and options.mode != "parts":
            out.warnings += _drain_warning(packing, scene, options, out.shell.drain_at)

    t = time.perf_counter()
    instances = None
    if options.mode == "parts":
        bodies, out.min_gap = separate_parts(scene.solids, clearance, float32=float32)
        names = [f"{packing.types[k].name}_{i:03d}" for i, k in enumerate(packing.type_index)]
        # a 3MF stores each type's mesh once and each part as that mesh and its placement
        instances = Instances([solid_arrays(s) for s in scene.type_solids],
                              [t.name for t in packing.types], scene.type_index,
                              scene.matrices)
        out.bodies = len(bodies)
        out.volume = float(sum(s.volume() for s in scene.solids))
    else:
        bodies, names = _one_body(packing, scene, shell, options, out, report, cancel,
                                  check_cancel, float32, len(paths))
    out.timings["assemble"] = time.perf_counter() - t
    out.triangles = int(sum(len(b[1]) for b in bodies))
    check_cancel()

    report(0.8, "writing and validating")
    t = time.perf_counter()
    out.paths = _write(bodies, names, paths, options.split_files, protect, out, check_cancel,
                       instances)
    out.timings["write_validate"] = time.perf_counter() - t
    if options.split_files:
        out.warnings += _stale_parts_warning(paths, out.paths)
    out.timings["total"] = time.perf_counter() - t0
    report(1.0, "done")
    return out


def _output_paths(out_paths: str | os.PathLike | Sequence[str | os.PathLike]) -> list[str]:
    """The output files as strings, each of a format the writer knows."""
    paths = [os.fspath(out_paths)] if isinstance(out_paths, (str, os.PathLike)) else [
        os.fspath(p) for p in out_paths]
    if not paths:
        raise InputError("no output file given: name at least one (-o out.3mf).")
    for p in paths:
        write_format(p)
    return paths


def _targets(paths: list[str], part_names: list[str] | None) -> list[str]:
    """Every file the export writes: the paths, or with ``part_names`` (--split) one file
    per part beside each path."""
    if part_names is None:
        return list(paths)
    return [_part_path(p, name) for p in paths for name in part_names]


def _check_part_names(packing: Packing, paths: list[str], part_names: list[str]) -> None:
    """Raise OutputError when a part's file (--split) has a name too long for its folder:
    said as the type's name and the output's, which make it (check_output_path would say
    only that the name is too long)."""
    for p in paths:
        for i, name in enumerate(part_names):
            too_long = name_too_long(_part_path(p, name))
            if too_long is None:
                continue
            part = os.path.basename(_part_path(p, name))
            kind = packing.types[packing.type_index[i]].name
            raise OutputError(
                f"cannot write the parts with --split: the file name of part {i} "
                f"('{short_name(part)}', {len(os.fsencode(part))} bytes) is too long for "
                f"the folder '{os.path.dirname(os.path.abspath(p))}', which takes names of "
                f"at most {too_long[1]} bytes, and each file is first written under a name "
                f"{too_long[0] - len(os.fsencode(part))} bytes longer. Each part's file is "
                f"named OUTPUT_<type>_<index>: shorten the type's name ('{short_name(kind)}',"
                f" {len(kind)} characters: its \"name\" in the packing file's \"types\") or "
                f"the output name '{short_name(os.path.basename(p))}', or export without "
                "--split.")


def _part_path(path: str, name: str) -> str:
    """The file of part `name` beside `path` (a type named "a/b", as Blender allows, stays
    in that folder: its separators become '_')."""
    stem = Path(path)
    safe = name.replace("/", "_").replace("\\", "_")
    return str(stem.with_name(f"{stem.stem}_{safe}{stem.suffix}"))


def _stale_parts_warning(paths: list[str], written: list[str]) -> list[str]:
    """A warning naming files beside the outputs that are named like this export's parts
    (NAME_<type>_<i>.EXT) but were not written by it: an earlier export's, which a slicer
    loading NAME_* would print with this one's."""
    done = {os.path.normcase(os.path.abspath(w)) for w in written}
    stale: set[str] = set()
    for p in paths:
        folder, stem = os.path.dirname(os.path.abspath(p)), Path(p).stem
        like = re.compile(rf"{re.escape(stem)}_.+_\d+{re.escape(Path(p).suffix)}",
                          re.IGNORECASE)
        with contextlib.suppress(OSError):
            stale |= {os.path.join(folder, n) for n in os.listdir(folder)
                      if like.fullmatch(n)
                      and os.path.normcase(os.path.join(folder, n)) not in done}
    if not stale:
        return []
    names = sorted(os.path.basename(s) for s in stale)
    shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    return [f"{len(names)} file{'s' if len(names) > 1 else ''} beside the parts written "
            f"{'are' if len(names) > 1 else 'is'} named like them but not from this export "
            f"({shown}): an earlier export's, left as they were. Remove them before loading "
            "the parts into a slicer, or export into an empty folder."]


def _shell(scene: PlacedScene, options: ExportOptions, report: Progress,
           simplify: bool = True):
    """The container's shell in the container frame, and its ShellReport (``simplify``: see
    :func:`make_shell`)."""
    from .shell import make_shell, opening_label  # only needed here

    report(0.1, "building the shell")
    # the shell is made with the print's up axis as +z (the drain goes down), then
    # turned back; rotations by signed permutations are exact in floating point
    rot = up_rotation(options.up)
    opening = options.opening
    if opening is not None:
        opening = dataclasses.replace(opening, axis=rotate_axis(opening.axis, rot))
    covered, reach = None, 0.0
    if options.drain is not None and options.mode != "parts" and scene.solids:
        # a drain under an object opens into it: it may move beside the objects, by up to
        # the largest object's size
        up = rot[2]  # the print's up axis in the container frame
        sizes = solid_boxes(scene.type_solids)
        reach = float(np.linalg.norm(sizes[:, 1] - sizes[:, 0], axis=1).max())
        boxes = solid_boxes(scene.solids)

        def covered(point: np.ndarray) -> bool:
            return bool(drain_cover(scene.solids, rot.T @ point, up, float(options.drain),
                                    boxes))
    shell, shell_report = make_shell(scene.container_vertices @ rot.T, scene.container_faces,
                                     options.shell, opening=opening, drain=options.drain,
                                     resolution=options.resolution,
                                     progress=lambda f, m: report(0.1 + 0.2 * f, m),
                                     drain_covered=covered, drain_reach=reach,
                                     simplify=simplify)
    shell = shell.transform(np.column_stack([rot.T, np.zeros(3)]))
    shell_report.opening = opening_label(options.opening)  # named in the caller's axes
    if shell_report.drain_at is not None:
        shell_report.drain_at = tuple(float(c) for c in
                                      rot.T @ np.asarray(shell_report.drain_at))
    return shell, shell_report


#: the drain warning's last advice (the add-on, which has no up axis, leaves it out)
DRAIN_UP_ADVICE = ", or give another --up (the drain goes under the cavity's lowest point)"


def _drain_warning(packing: Packing, scene: PlacedScene, options: ExportOptions,
                   at: tuple[float, float, float]) -> list[str]:
    """A warning when objects sit on the drain's mouth (`openings.drain_cover`)."""
    up = up_rotation(options.up)[2]  # the up axis in the container frame
    covered = drain_cover(scene.solids, np.asarray(at), up, float(options.drain))
    if not covered:
        return []
    names = ", ".join(f"{packing.types[packing.type_index[i]].name} #{i}" for i in covered[:3])
    more = f" and {len(covered) - 3} more" if len(covered) > 3 else ""
    where = ", ".join(f"{c:.4g}" for c in at)
    sit = "sits" if len(covered) == 1 else "sit"
    head = (f"the drain hole at ({where}) is covered: {names}{more} {sit} within its radius "
            f"above it, so liquid or powder may not reach it.")
    if options.opening is not None:  # the shell is open already: say so, not to open it
        what = "plane cut" if options.opening.kind == "plane" else "window"
        return [f"{head} The liquid or powder can leave through the shell's {what} instead"
                f"{DRAIN_UP_ADVICE}."]
    return [f"{head} Open the shell with --open-plane or --window{DRAIN_UP_ADVICE}."]


#: filled sealed voids more than this share of the print's volume are said: the space
#: between the objects and a shell whose drain they cover, made solid, hides them
LARGE_FILL = 0.1


def _large_fill_warning(filled: float, volume: float, shell: bool) -> list[str]:
    """A warning where filling the sealed voids made much of the print solid (`filled`
    and the print's `volume` after it, container units cubed; `shell`: it has one)."""
    if volume <= 0 or filled <= LARGE_FILL * volume:
        return []
    opening = ("open the shell with --open-plane or --window (or uncover its drain), or "
               if shell else "")
    return [f"filling the sealed voids made {filled / volume:.0%} of the print's volume "
            "solid: there the print is a solid block, with the objects hidden in it. To "
            f"see them, {opening}keep the voids hollow with --keep-voids."]


def _one_body(packing: Packing, scene: PlacedScene, shell: m3.Manifold | None,
              options: ExportOptions, out: ExportReport, report: Progress,
              cancel: Callable[[], bool], check_cancel: Callable[[], None],
              float32: list[str], count: int) -> tuple[Bodies, list[str]]:
    """Union (with struts in connect mode) of the objects and the shell, cleaned.
    ``float32``: the outputs that store 32-bit floats (STL, PLY), of ``count`` outputs."""
    for attempt in range(3 if options.mode == "connect" else 1):
        struts: list[m3.Manifold] = []
        if options.mode == "connect":
            struts = _struts(packing, scene, shell, options, out, report, cancel, attempt)
            check_cancel()
        report(0.6, "union")
        v, f, left = _union(scene.solids + struts, shell, options, float32, check_cancel)
        if left == 0:
            break
        # slivers the local repairs cannot remove: struts turned another way meet the
        # surfaces elsewhere (union mode has nothing to turn; validation names the faces)
    if (left > 0 and shell is not None and out.shell is not None and out.shell.tolerance > 0
            and crossing_pairs(v, f, float32=False)[1] > 0):
        # the booleans split the simplified inner surface's long thin faces where objects
        # meet it and can fold them (at full precision: float32 folds are not its doing):
        # the shell again with every triangle of its grid
        shell, out.shell = _shell(scene, options, lambda f, m: report(0.6, m),
                                  simplify=False)  # the bar stays where it is
        out.shell.notes.append("the inner surface keeps every triangle of its grid: the "
                               "simplified one folded where the objects meet it.")
        check_cancel()
        report(0.6, "union, with the shell unsimplified")
        v, f, left = _union(scene.solids + struts, shell, options, float32, check_cancel)
    if left > 0 and options.mode == "union" and options.resolution is None:
        # parts that touch face to face where their faces are split differently (a grid
        # of parts with a hole): a union cannot fuse them, so they are set apart instead
        # (with a --resolution, the folds of its coarser faces are said below)
        report(0.6, "union, the objects set apart")
        pieces, step = shrunk_apart(scene.solids)
        v2, f2, left2 = _union(pieces, shell, options, float32, check_cancel)
        if left2 < left:
            v, f, left = v2, f2, left2
            out.warnings.append(
                "some objects touch face to face where their surfaces are split into "
                "different triangles, which a union cannot fuse: every object was made "
                f"{step:.2g} smaller on each side so that they stand apart as separate "
                "bodies, far closer than a printer resolves. --mode parts (with a "
                "clearance) or a packing with --clearance keeps them apart on purpose.")
    if left > 0 and options.resolution is not None:
        crossing = crossing_pairs(v, f, float32=False)[1]
        if crossing > 0:  # the validator would refuse the file; say what helps before writing
            raise MeshError(
                f"the union of the objects simplified to --resolution {options.resolution:g} "
                f"has {crossing} face pairs that cross each other, so nothing was "
                "written. Coarser surfaces cross more easily where objects meet: a finer "
                f"--resolution (e.g. {options.resolution / 5:.2g}) or none may avoid it; "
                "--mode parts keeps every object apart.")
    closed_shell = shell is not None and options.opening is None and options.drain is None
    cleaned = clean_bodies(v, f, fill_voids=options.fill_voids, closed_shell=closed_shell)
    out.voids_filled = cleaned.voids_filled
    out.voids_filled_volume = cleaned.voids_filled_volume
    out.bodies = cleaned.bodies
    out.warnings += cleaned.warnings
    out.warnings += _large_fill_warning(cleaned.voids_filled_volume, cleaned.volume,
                                        shell is not None)
    out.volume = cleaned.volume
    if options.mode == "union" and shell is not None and out.bodies > 1:
        out.warnings += _loose_warning(cleaned.vertices, cleaned.faces, out.bodies, shell,
                                       options)
    if options.mode == "connect" and out.bodies != 1:
        d = out.connector_diameter
        if out.connectors_refused:  # the graph fell apart where struts would leave
            why = (f"{out.connectors_refused} struts would have left the container and were "
                   "refused, which left objects with no strut to the rest. Try thinner "
                   f"struts than these ({d:.3g} across), which fit narrower passages, e.g. "
                   f"--connector {d / 2:.2g}")
        else:
            why = ("every object had a strut, but some did not join what they touch. Try "
                   f"thicker struts than these ({d:.3g} across), e.g. --connector "
                   f"{2 * d:.2g}")
        raise MeshError(f"connect made {out.bodies} bodies instead of one; nothing was "
                        f"written: {why}, or export with --mode union or --mode parts.")
    if float32 and left > 0:
        _check_float32(cleaned.vertices, cleaned.faces, float32, count)
    return [(cleaned.vertices, cleaned.faces)], ["jampacked"]


def _loose_warning(v: np.ndarray, f: np.ndarray, bodies: int, shell: m3.Manifold,
                   options: ExportOptions) -> list[str]:
    """A warning when bodies of a union with a shell touch neither it nor anything joined
    to it: in the print they lie loose in its cavity (a print shop's question). Without a
    shell, separate bodies are what union mode makes of objects that do not touch."""
    loose = loose_bodies(v, f, solid_arrays(shell)[0])
    if not loose:
        return []
    if options.opening is not None:
        what = "plane cut" if options.opening.kind == "plane" else "window"
        fate = f"rattle in its cavity and can fall out through its {what}"
    else:
        fate = "rattle in its cavity" + ("" if options.drain is not None else ", sealed")
    lie = "lies" if loose == 1 else "lie"
    return [f"{loose} of the {bodies} bodies {lie} loose inside the shell: objects (alone or "
            "with those they touch) that touch neither the shell nor anything joined to it. "
            f"In the print they {fate}. To tie every object to the shell, export with "
            "--mode connect."]


def _union(pieces: list[m3.Manifold], shell: m3.Manifold | None, options: ExportOptions,
           float32: list[str], check_cancel: Callable[[], None]
           ) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`union_arrays`, with a wrong volume at a --resolution said as the resolution's.

    manifold3d's booleans reshape the long thin faces of surfaces simplified to a resolution
    (a YCB lemon at 0.5 mm gained 0.8 mm3 beside an object it did not touch, its vertices
    unmoved; fine at 0.2 and unsimplified), so there the parts are not to blame."""
    try:
        return union_arrays(pieces, shell, float32=bool(float32), check_cancel=check_cancel)
    except UnionVolumeError as e:
        if options.resolution is None:
            raise
        raise MeshError(
            f"the union of the objects simplified to --resolution {options.resolution:g} "
            f"came out with more volume ({e.volume:.6g}) than the sum of its parts "
            f"({e.parts:.6g}), so nothing was written. manifold3d's booleans can reshape "
            "the long thin faces of coarser surfaces: a finer --resolution (e.g. "
            f"{options.resolution / 5:.2g}) or none may avoid it; --mode parts keeps every "
            "object apart.") from None


def _check_float32(v: np.ndarray, f: np.ndarray, float32: list[str], count: int) -> None:
    """Raise MeshError, before anything is written, when the result is watertight but not
    once its positions are rounded to 32-bit floats as an STL or PLY stores them (far from
    the origin, where the rounding step nears the size of the booleans' slivers). A result
    that fails at full precision too is left to the validation of the files written."""
    failure = float32_breaks(float32[0], v, f, count)
    if failure:
        raise MeshError(failure)


def _struts(packing: Packing, scene: PlacedScene, shell: m3.Manifold | None,
            options: ExportOptions, out: ExportReport, report: Progress,
            cancel: Callable[[], bool], variant: int) -> list[m3.Manifold]:
    """Struts for connect mode (see export/connect.py), counted in the report."""
    diameter = options.connector
    if diameter is None:
        diameter = default_diameter([t.volume for t in packing.types])
    plan = connect_scene(scene, diameter, shell, options.shell or 0.0, should_cancel=cancel,
                         progress=lambda f, m: report(0.3 + 0.3 * f, m), variant=variant)
    out.connectors = len(plan.struts)
    out.connectors_refused = plan.refused
    out.connector_diameter = diameter
    out.connector_length = plan.total_length
    out.fused = plan.fused
    return plan.struts


def _write(bodies: Bodies, names: list[str], paths: list[str], split_files: bool,
           protect: list[str], out: ExportReport, check_cancel: Callable[[], None],
           instances: Instances | None = None) -> list[str]:
    """Write and validate every file (one per part with ``split_files``), then put them all
    in place (:func:`write_meshes`: all or none); the paths written. ``instances``: the same
    bodies as copies of the type meshes, for a 3MF of parts."""
    outputs: list[MeshOutput] = []
    for p in paths:
        if split_files:
            for (bv, bf), name in zip(bodies, names, strict=True):  # a 3MF's object, named
                outputs.append(MeshOutput(_part_path(p, name), bv, bf, names=[name]))
        elif len(bodies) > 1:
            data = instances if instances is not None and p.lower().endswith(".3mf") else bodies
            outputs.append(MeshOutput(p, data, names=names))
        else:
            outputs.append(MeshOutput(p, bodies[0][0], bodies[0][1], names=names[:1]))
    out.validation += write_meshes(outputs, protect=protect, check_cancel=check_cancel)
    return [os.fspath(o.path) for o in outputs]
