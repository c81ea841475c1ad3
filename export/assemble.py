"""From a packing to printable meshes: union, connect or parts, with an optional shell.

Frames: the packing's container frame, container units (mm for printing). A placed object's
vertices are ``matrix @ local_from_file @ v_file``; the container's ``frame_from_file @
v_file`` (the packing file's definitions). manifold3d does every boolean; results go
straight from manifold3d arrays to the writer (no trimesh processing), and every file is
validated as written before it is put in place (:func:`jampacked.export.io.write_mesh`).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import manifold3d as m3
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from jampacked.core.errors import Cancelled, InputError, MeshError
from jampacked.core.meshes import MeshData, load_mesh
from jampacked.core.packing import Packing, container_mesh, is_spec
from jampacked.core.packing_json import load_packing, verify_sources
from jampacked.core.solids import solid_arrays, to_solid

from .cleanup import remove_degenerate_faces
from .closest import Surface
from .connect import PlacedObject, candidate_pairs, plan_connectors
from .intersect import intersecting_pairs
from .io import WRITE_FORMATS, write_mesh
from .options import ExportOptions, rotate_axis, up_rotation
from .validate import ValidationReport, merge_identical

if TYPE_CHECKING:
    from .shell import ShellReport

Progress = Callable[[float, str], None]


@dataclass
class ExportReport:
    """What an export wrote and how it checked.

    paths: files written. bodies: bodies in the result (1 for a connected export).
    triangles: triangles of the result (per file for parts split into files: the sum).
    triangles_saved: triangles --resolution removed. connectors / connector_length: struts
    added (connect mode) and their total visible length (container units). fused: tree edges
    whose solids already overlapped. min_gap: smallest gap between parts (parts mode; None
    when no two parts are near), clearance: the packing's clearance. voids_filled /
    voids_filled_volume: sealed voids made solid (see ExportOptions.fill_voids) and their
    volume (container units cubed).
    """

    mode: str
    paths: list[str]
    bodies: int
    objects: int
    triangles: int
    triangles_saved: int = 0
    connectors: int = 0
    connector_length: float = 0.0
    fused: int = 0
    min_gap: float | None = None
    clearance: float = 0.0
    volume: float = 0.0
    voids_filled: int = 0
    voids_filled_volume: float = 0.0
    shell: ShellReport | None = None
    validation: list[ValidationReport] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        """Every written file validated."""
        return bool(self.validation) and all(v.passed for v in self.validation)

    def summary(self) -> str:
        """One paragraph for people."""
        parts = [f"{self.mode}: {self.objects} objects -> {self.bodies} "
                 f"bod{'y' if self.bodies == 1 else 'ies'}, {self.triangles:,} triangles"]
        if self.mode == "connect":
            parts.append(f"{self.connectors} connectors, {self.connector_length:.1f} long "
                         f"in all, {self.fused} contacts fused")
        if self.shell is not None:
            parts.append(f"shell {self.shell.thickness:g} thick (measured median "
                         f"{self.shell.measured_median:.3g}, min {self.shell.measured_min:.3g})")
        if self.min_gap is not None:
            parts.append(f"smallest gap between parts {self.min_gap:.3g} (clearance "
                         f"{self.clearance:g})")
        if self.triangles_saved:
            parts.append(f"--resolution saved {self.triangles_saved:,} triangles")
        if self.voids_filled:
            parts.append(f"{self.voids_filled} sealed void{'s' if self.voids_filled > 1 else ''}"
                         f" filled ({self.voids_filled_volume:.3g} in volume)")
        verdict = "PASS" if self.passed else "FAIL"
        parts.append(f"validation {verdict} for {len(self.validation)} file(s)")
        return "; ".join(parts) + "."

    def as_dict(self) -> dict[str, Any]:
        return {
            "mode": self.mode, "paths": self.paths, "bodies": self.bodies,
            "objects": self.objects, "triangles": self.triangles,
            "triangles_saved": self.triangles_saved, "connectors": self.connectors,
            "connector_length": self.connector_length, "fused": self.fused,
            "min_gap": self.min_gap, "clearance": self.clearance, "volume": self.volume,
            "voids_filled": self.voids_filled, "voids_filled_volume": self.voids_filled_volume,
            "shell": self.shell.as_dict() if self.shell else None,
            "validation": [v.as_dict(max_indices=20) for v in self.validation],
            "passed": self.passed, "timings": self.timings, "warnings": self.warnings,
        }


# --------------------------------------------------------------------------- sources


def load_sources(packing: Packing) -> tuple[MeshData, list[MeshData]]:
    """The container and type meshes a packing names, checked against their sha256.

    Raises InputError when a file is missing, changed, or a type has no file (a packing
    made in Blender: pass its meshes to :func:`export_packing` instead).
    """
    problems = verify_sources(packing)
    if problems:
        raise InputError("cannot export: " + "; ".join(problems) + ".")
    container = container_mesh(packing, "export")
    types = []
    for t in packing.types:
        if t.path is None:
            raise InputError(f"type {t.name!r} has no mesh file in the packing (it was made "
                             "from in-memory meshes); export it from where it was made.")
        types.append(load_mesh(t.path, role="object"))
    return container, types


def _apply(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    return v @ m[:3, :3].T + m[:3, 3]


# --------------------------------------------------------------------------- export


def export_packing(packing: Packing | str | os.PathLike,
                   out_paths: str | os.PathLike | Sequence[str | os.PathLike],
                   options: ExportOptions | None = None, *,
                   meshes: tuple[MeshData, Sequence[MeshData]] | None = None,
                   progress: Progress | None = None,
                   should_cancel: Callable[[], bool] | None = None) -> ExportReport:
    """Export a packing as printable meshes and validate every file written.

    packing: a Packing or the path of its JSON file. out_paths: one or more output files
    (.3mf, .stl, .obj, .ply), all written with the same geometry. options: mode, shell,
    opening, drain, connector, resolution (see :class:`ExportOptions`). meshes: the container
    and type meshes in their file frames, to use instead of the files the packing names
    (e.g. from Blender). Lengths in container units.

    Raises InputError (bad options, missing/changed sources, an output that is an input),
    MeshError (a file cannot be written, or the result does not validate: nothing is put in
    place then), Cancelled (should_cancel() said so; nothing is written).
    """
    t0 = time.perf_counter()
    options = options or ExportOptions()
    report = progress or (lambda f, m: None)
    cancel = should_cancel or (lambda: False)
    packing_path = None
    if not isinstance(packing, Packing):
        packing_path = os.fspath(packing)
        packing = load_packing(packing_path)
    paths = [os.fspath(out_paths)] if isinstance(out_paths, (str, os.PathLike)) else [
        os.fspath(p) for p in out_paths]
    if not paths:
        raise InputError("no output file given: name at least one (-o out.3mf).")
    for p in paths:
        ext = Path(p).suffix.lower().lstrip(".")
        if ext not in WRITE_FORMATS:
            raise InputError(f"cannot write '{p}': unknown mesh format '.{ext}'; use one of "
                             f"{', '.join('.' + e for e in WRITE_FORMATS)}.")
    # STL and PLY store float32 positions: the union is checked as they will store it
    float32 = any(Path(p).suffix.lower() in (".stl", ".ply") for p in paths)
    protect = [p for p in ([packing_path, packing.container_path]
                           + [t.path for t in packing.types]) if p and not is_spec(p)]
    if packing.n == 0 and options.shell is None:
        raise InputError("the packing has no objects and no shell was asked for: there is "
                         "nothing to export.")

    def check_cancel() -> None:
        if cancel():
            raise Cancelled("export cancelled; no file was written.")

    report(0.0, "loading meshes")
    container, types = meshes if meshes is not None else load_sources(packing)
    if len(types) != len(packing.types):
        raise InputError(f"{len(types)} type meshes given for a packing of "
                         f"{len(packing.types)} types.")
    timings: dict[str, float] = {}
    out = ExportReport(mode=options.mode, paths=paths, bodies=0, objects=packing.n,
                       triangles=0, clearance=float(packing.params.get("clearance", 0.0)))

    # --- object solids (each type once, in its local frame, then moved)
    local = [_apply(t.local_from_file, m.vertices) for t, m in zip(packing.types, types,
                                                                    strict=True)]
    type_solids = []
    saved_per_type = []
    for v, m in zip(local, types, strict=True):
        s = to_solid(v, m.faces)
        before = s.num_tri()
        if options.resolution is not None:
            s = s.simplify(options.resolution)
        saved_per_type.append(before - s.num_tri())
        type_solids.append(s)
    counts = np.bincount(packing.type_index, minlength=len(types))
    out.triangles_saved = int(np.dot(counts, saved_per_type))
    mats = packing.matrices()
    solids = [type_solids[t].transform(mats[i][:3, :]) for i, t in
              enumerate(packing.type_index)]
    timings["load"] = time.perf_counter() - t0
    check_cancel()

    # --- shell
    shell = None
    c_vertices = _apply(packing.frame_from_file, container.vertices)
    if options.shell is not None:
        from .shell import make_shell, opening_label  # only needed here

        report(0.1, "building the shell")
        t = time.perf_counter()
        # the shell is made with the print's up axis as +z (the drain goes down), then
        # turned back; rotations by signed permutations are exact in floating point
        rot = up_rotation(options.up)
        opening = options.opening
        if opening is not None:
            opening = dataclasses.replace(opening, axis=rotate_axis(opening.axis, rot))
        shell, out.shell = make_shell(c_vertices @ rot.T, container.faces, options.shell,
                                      opening=opening, drain=options.drain,
                                      resolution=options.resolution,
                                      progress=lambda f, m: report(0.1 + 0.2 * f, m))
        shell = shell.transform(np.column_stack([rot.T, np.zeros(3)]))
        out.shell.opening = opening_label(options.opening)  # named in the caller's axes
        if out.shell.drain_at is not None:
            out.shell.drain_at = tuple(float(c) for c in rot.T @ np.asarray(out.shell.drain_at))
        timings["shell"] = time.perf_counter() - t
        check_cancel()

    # --- assemble
    t = time.perf_counter()
    if options.mode == "parts":
        bodies, names = _parts(packing, solids, out)
    else:
        saved = out.triangles_saved
        for attempt in range(3 if options.mode == "connect" else 1):
            out.triangles_saved = saved
            extra: list[m3.Manifold] = []
            if options.mode == "connect":
                extra = _connect(packing, local, types, solids, shell, c_vertices, container,
                                 options, out, report, cancel, variant=attempt)
                check_cancel()
            report(0.6, "union")
            v, f, left = _union(solids + extra, shell, options, out, float32=float32)
            if left == 0:
                break
            # slivers the local repairs cannot remove: struts turned another way meet the
            # surfaces elsewhere (union mode has nothing to turn; validation names the faces)
        # specks of no volume (where a strut grazes a surface) are dropped; a closed void
        # inside a solid is a component of negative volume, not a body. Dropping a void's
        # surface fills it: the print then traps no resin or powder there. A closed shell's
        # cavity is sealed on purpose, so its voids stay.
        speck = 1e-9 * float(np.prod(np.ptp(v, axis=0))) if len(v) else 0.0
        closed_shell = shell is not None and options.opening is None and options.drain is None
        fill = options.fill_voids and not closed_shell
        v, f, volumes, filled = _drop_specks(v, f, speck, fill_voids=fill)
        out.voids_filled = len(filled)
        out.voids_filled_volume = float(-filled.sum())
        out.bodies = int(np.sum(volumes > 0))
        voids = int(np.sum(volumes < 0))
        if voids:
            why = ("the shell is closed" if closed_shell and options.fill_voids
                   else "filling was turned off (--keep-voids)")
            out.warnings.append(
                f"the result encloses {voids} sealed void{'s' if voids > 1 else ''} (space "
                f"shut in between objects, struts and shell), kept hollow because {why}; "
                "resin and powder printers cannot drain them.")
        out.volume = float(volumes.sum())
        bodies, names = [(v, f)], ["jampacked"]
        if options.mode == "connect" and out.bodies != 1:
            raise MeshError(f"connect made {out.bodies} bodies instead of one; nothing was "
                            "written. Try a larger --connector diameter, and please report "
                            "this with the packing file.")
    timings["assemble"] = time.perf_counter() - t
    out.triangles = int(sum(len(b[1]) for b in bodies))
    check_cancel()

    # --- write + validate
    report(0.8, "writing and validating")
    t = time.perf_counter()
    written: list[str] = []
    for p in paths:
        if options.split_files:
            stem = Path(p)
            for (bv, bf), name in zip(bodies, names, strict=True):
                part = str(stem.with_name(f"{stem.stem}_{name}{stem.suffix}"))
                out.validation.append(write_mesh(part, bv, bf, protect=protect))
                written.append(part)
        elif len(bodies) > 1:
            out.validation.append(write_mesh(p, bodies, names=names, protect=protect))
            written.append(p)
        else:
            out.validation.append(write_mesh(p, bodies[0][0], bodies[0][1], protect=protect))
            written.append(p)
        check_cancel()
    out.paths = written
    timings["write_validate"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t0
    out.timings = timings
    report(1.0, "done")
    return out


def _union(pieces: list[m3.Manifold], shell: m3.Manifold | None, options: ExportOptions,
           out: ExportReport, float32: bool = False) -> tuple[np.ndarray, np.ndarray, int]:
    """Union of the pieces and the shell: (vertices, faces, bad faces left; see
    :func:`_clean_arrays`)."""
    result = m3.Manifold.batch_boolean(pieces, m3.OpType.Add)
    if shell is not None:
        # a separate boolean: batch_boolean with a hollow shell among hundreds of pieces
        # returned the solid container (cavity filled) in manifold3d 3.x
        result = result + shell
    if result.status() != m3.Error.NoError:
        raise MeshError(f"the union failed in manifold3d ({result.status()}); please "
                        "report this with the packing file.")
    total = sum(p.volume() for p in pieces) + (shell.volume() if shell else 0.0)
    if result.volume() > total * (1 + 1e-6) + 1e-9:
        raise MeshError(f"the union's volume ({result.volume():.6g}) exceeds the sum of its "
                        f"parts ({total:.6g}): manifold3d returned a wrong result; nothing "
                        "was written. Please report this with the packing file.")
    if options.resolution is not None:
        before = result.num_tri()
        result = result.simplify(options.resolution)
        out.triangles_saved += before - result.num_tri()
    return _clean_arrays(result, float32=float32)


def _clean_arrays(result: m3.Manifold, float32: bool = False
                  ) -> tuple[np.ndarray, np.ndarray, int]:
    """The result's arrays without zero-area faces (see export/cleanup.py), and how many
    faces are left bad. With `float32` (an STL or PLY will be written) a face that
    intersects another once the positions are rounded to float32 is bad too: slivers
    from the booleans, a thousandth of a millimetre wide, can fold over there. Where the
    local repairs cannot remove them all, manifold3d first simplifies by a tolerance far
    below any printer's resolution (1e-7 to 1e-5 of the size)."""

    def cleaned(m: m3.Manifold) -> tuple[np.ndarray, np.ndarray, int]:
        v, f, left = remove_degenerate_faces(*solid_arrays(m))
        if float32 and left == 0 and len(f):
            # positions that round to the same float32 are one vertex, as the validator
            # merges them when it reads the file back
            p32 = v.astype(np.float32).astype(np.float64)
            first, remap = merge_identical(p32)
            _, crossing, _ = intersecting_pairs(p32[first], remap[f])
            left = int(crossing)
        return v, f, left

    v, f, left = cleaned(result)
    if left == 0 or len(v) == 0:
        return v, f, left
    diagonal = float(np.linalg.norm(np.ptp(v, axis=0)))
    for rel in (1e-7, 1e-6, 1e-5):
        cv, cf, left_here = cleaned(result.simplify(rel * diagonal))
        if left_here == 0:
            return cv, cf, 0
    return v, f, left


def _drop_specks(v: np.ndarray, f: np.ndarray, speck: float, fill_voids: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Split a mesh into its connected components (by shared vertices, as manifold3d
    writes them), drop those whose |volume| <= speck, with `fill_voids` also every void
    (a component of negative volume: the inward surface of a sealed cavity), and unused
    vertices. Returns (vertices, faces, signed volume of each kept component, signed
    volume of each void filled)."""
    n = len(v)
    if len(f) == 0:
        return v, f, np.zeros(0), np.zeros(0)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    face_label = label[f[:, 0]]
    tri = v[f]
    six = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    volumes = np.bincount(face_label, six, minlength=count) / 6.0
    used = np.zeros(count, bool)
    used[face_label] = True
    keep = used & (np.abs(volumes) > speck)
    filled = keep & (volumes < 0) if fill_voids else np.zeros(count, bool)
    keep &= ~filled
    if not np.all(keep[used]) or len(np.unique(f)) < n:
        f = f[keep[face_label]]
        verts, inverse = np.unique(f, return_inverse=True)
        v, f = v[verts], inverse.reshape(-1, 3)
    return v, f, volumes[keep], volumes[filled]


def _parts(packing: Packing, solids: list[m3.Manifold], out: ExportReport
           ) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[str]]:
    """Each object its own body; measures the smallest gap between near parts."""
    names = [f"{packing.types[t].name}_{i:03d}" for i, t in enumerate(packing.type_index)]
    bodies = [solid_arrays(s) for s in solids]
    out.bodies = len(bodies)
    out.volume = float(sum(s.volume() for s in solids))
    # every pair whose bounds, grown by the clearance, touch is checked exactly; the
    # nearest neighbours too, so the report gives the smallest gap even when all keep it
    probe = max(out.clearance, 1e-3 * _scale(bodies))
    lo = np.array([b[0].min(axis=0) for b in bodies]) - probe
    hi = np.array([b[0].max(axis=0) for b in bodies]) + probe
    pairs = {tuple(p) for p in candidate_pairs(np.array([b[0].mean(axis=0) for b in bodies]))}
    for i in range(len(bodies)):
        near = np.flatnonzero(np.all(lo[i + 1:] <= hi[i], axis=1)
                              & np.all(hi[i + 1:] >= lo[i], axis=1)) + i + 1
        pairs.update((i, int(j)) for j in near)
    trees = {j: cKDTree(bodies[j][0]) for j in {j for _, j in pairs}}
    worst = None
    for i, j in sorted(pairs):
        upper = float(trees[j].query(bodies[i][0])[0].min())
        g = float(solids[i].min_gap(solids[j], upper * 1.001 + 1e-9))
        if worst is None or g < worst:
            worst = g
    out.min_gap = worst
    if worst is not None and out.clearance == 0 and worst < probe:
        out.warnings.append(
            f"some parts touch or nearly touch (smallest gap {worst:.3g}); they may fuse in a "
            "powder bed. Pack with --clearance (e.g. 0.3 mm) for separate parts.")
    if worst is not None and worst < out.clearance * (1 - 1e-6):
        raise MeshError(f"parts closer than the packing's clearance {out.clearance:g}: the "
                        f"smallest gap is {worst:.4g}. A coarse --resolution can move surfaces "
                        "by up to its value: use a finer one, or pack with a larger clearance.")
    return bodies, names


def _scale(bodies: list[tuple[np.ndarray, np.ndarray]]) -> float:
    v = np.concatenate([b[0] for b in bodies])
    return float(np.ptp(v, axis=0).max())


def _connect(packing: Packing, local: list[np.ndarray], types: Sequence[MeshData],
             solids: list[m3.Manifold], shell: m3.Manifold | None, c_vertices: np.ndarray,
             container: MeshData, options: ExportOptions, out: ExportReport,
             report: Progress, cancel: Callable[[], bool], variant: int = 0
             ) -> list[m3.Manifold]:
    """Struts for connect mode (see export/connect.py)."""
    mats = packing.matrices()
    surfaces = [Surface(v, m.faces) for v, m in zip(local, types, strict=True)]
    placed = [PlacedObject(solid=s, vertices=_apply(mats[i], local[t]),
                           world_from_local=mats[i], surface=surfaces[t])
              for i, (s, t) in enumerate(zip(solids, packing.type_index, strict=True))]
    diameter = options.connector
    if diameter is None:
        # 0.2 x the smallest type's equivalent diameter: sturdy but small beside the objects
        vol = min(t.volume for t in packing.types)
        diameter = 0.2 * 2 * (3 * vol / (4 * np.pi)) ** (1 / 3)
    shells = [(part, Surface(*solid_arrays(part))) for part in
              (shell.decompose() if shell is not None else [])]
    cont = to_solid(c_vertices, container.faces)
    lo, hi = c_vertices.min(axis=0), c_vertices.max(axis=0)
    pad = 0.1 * float((hi - lo).max()) + 1.0
    box = m3.Manifold.cube(tuple(hi - lo + 2 * pad)).translate(tuple(lo - pad))
    outside = box - cont
    plan = plan_connectors(placed, diameter, shells=shells,
                           shell_thickness=options.shell or 0.0, outside=outside,
                           should_cancel=cancel,
                           progress=lambda f, m: report(0.3 + 0.3 * f, m), variant=variant)
    out.connectors = len(plan.struts)
    out.connector_length = plan.total_length
    out.fused = plan.fused
    return plan.struts
