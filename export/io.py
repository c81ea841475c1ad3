"""Write mesh files and validate them as written, before any is put in place.

Writing is :mod:`jampacked.export.mesh_write`; reading a file as stored is
:func:`jampacked.core.mesh_files.read_mesh_arrays` (also importable from here); validating is
:mod:`jampacked.export.validate`. Units and frame are the caller's (container units, mm for
printing); 3MF files declare millimetres.

Several files of one export are written all or none (:func:`write_meshes`): a file that fails,
an interrupt or a cancel leaves every output as it was.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from jampacked.core.errors import InputError, MeshError, OutputError
from jampacked.core.mesh_files import read_mesh_arrays

from .mesh_write import (
    WRITE_FORMATS,
    as_arrays,
    check_output_path,
    remove_temporaries,
    replace_files,
    stage_mesh_file,
    write_format,
)
from .validate import ValidationReport, validate_arrays, validate_file

__all__ = ["FLOAT32_FORMATS", "WRITE_FORMATS", "MeshOutput", "float32_breaks", "float32_failure",
           "read_mesh_arrays", "write_mesh", "write_meshes"]

#: formats that store positions as 32-bit floats (3MF and OBJ keep full precision)
FLOAT32_FORMATS = {"stl": "STL", "ply": "PLY"}


@dataclass(frozen=True)
class MeshOutput:
    """One file to write: ``path`` and what :func:`write_mesh` takes for it (``vertices``
    and ``faces``, or ``vertices`` a list of bodies or an Instances with ``faces`` None;
    ``names`` for 3MF objects)."""

    path: str | os.PathLike
    vertices: object
    faces: object = None
    names: Sequence[str] | None = None


def write_mesh(
    path: str | os.PathLike,
    vertices: object,
    faces: object = None,
    *,
    names: Sequence[str] | None = None,
    protect: Iterable[str | os.PathLike] = (),
    validate: bool = True,
    require_valid: bool = True,
) -> ValidationReport | None:
    """Write a mesh atomically, then (by default) validate the file as written.

    Call as ``write_mesh(path, vertices, faces)`` for one mesh, or ``write_mesh(path,
    bodies)`` with a list of ``(vertices, faces)`` bodies (3MF: one object each) or a
    :class:`jampacked.export.mesh_write.Instances` (3MF: each mesh stored once).

    Args:
        path: output file; its extension picks the format: .stl (binary), .obj, .ply
            (binary), .3mf. Positions are written in the caller's units (mm for printing).
        vertices: (V, 3) positions, or the list of bodies when ``faces`` is None.
        faces: (F, 3) vertex indices, counter-clockwise seen from outside.
        names: one name per body for 3MF objects (ignored by the other formats).
        protect: input files the output must not replace (compared as resolved paths).
        validate: read the written file back and validate it (:func:`validate_file`).
        require_valid: with ``validate``, a file that fails validation is not put in place
            and MeshError is raised; with False it is written and the report returned.

    Returns:
        The :class:`ValidationReport` of the file as written (its path is ``path``), or
        None when ``validate`` is False.

    Raises:
        InputError: unknown format, a protected input path, names that do not match the
            bodies, or bad arrays.
        MeshError: the file cannot be written, or (``require_valid``) it fails validation;
            an STL or PLY that fails only because its 32-bit floats round the positions is
            named as such, with the way out.

    The data goes to a temporary file in the same folder, which is flushed, synced,
    validated and renamed over ``path``; on any failure the temporary file is removed and
    ``path`` is left as it was.
    """
    reports = write_meshes([MeshOutput(path, vertices, faces, names)], protect=protect,
                           validate=validate, require_valid=require_valid)
    return reports[0] if reports else None


def write_meshes(
    outputs: Sequence[MeshOutput],
    *,
    protect: Iterable[str | os.PathLike] = (),
    validate: bool = True,
    require_valid: bool = True,
    check_cancel: Callable[[], None] | None = None,
) -> list[ValidationReport]:
    """Write several mesh files all or none; the reports of the files as written (in the
    order given; empty when ``validate`` is False).

    Every path is checked first (format, not an input in ``protect``, not named twice, its
    folder exists); then each file is written to a temporary beside its target and (with
    ``validate``) read back and validated; ``check_cancel`` (which raises to cancel, e.g.
    Cancelled) is called after each. Only when every file passed are the temporaries
    renamed over their targets, with Ctrl-C held back meanwhile. Anything raised before
    that (a failed file, a cancel, a KeyboardInterrupt) removes the temporaries and leaves
    every target as it was; a rename that fails half-way raises MeshError naming the files
    already replaced (:func:`jampacked.export.mesh_write.replace_files`).

    Raises InputError and MeshError as :func:`write_mesh`.
    """
    protect = [os.fspath(p) for p in protect]
    paths = [os.fspath(o.path) for o in outputs]
    if not paths:
        raise InputError("no output file given: name at least one (-o out.3mf).")
    check_output_paths(paths, protect)
    staged: list[tuple[str, str]] = []
    reports: list[ValidationReport] = []
    try:
        for out, path in zip(outputs, paths, strict=True):
            tmp = stage_mesh_file(path, out.vertices, out.faces, names=out.names)
            staged.append((tmp, path))
            if validate:
                reports.append(_validated(tmp, path, out, require_valid, len(paths)))
            if check_cancel is not None:
                check_cancel()
        replace_files(staged)
    finally:
        remove_temporaries(staged)
    return reports


def check_output_paths(paths: Sequence[str], protect: Iterable[str | os.PathLike] = ()
                       ) -> None:
    """Check every output path before anything is built or written: a format the writer
    knows, not an input (``protect``), its folder there, not a folder, a name short enough
    for its folder, and no file named twice. Raises OutputError or MeshError (see
    :func:`jampacked.export.mesh_write.check_output_path`)."""
    protect = [os.fspath(p) for p in protect]
    seen: dict[str, str] = {}
    probed: set[str] = set()
    for p in paths:
        check_output_path(p, protect, probed)
        key = os.path.normcase(os.path.realpath(p))
        if sys.platform == "darwin":  # macOS volumes ignore case too, as a rule
            key = key.lower()
        if key in seen:
            raise OutputError(f"'{p}' is named twice among the output files (also as "
                              f"'{seen[key]}'); give each output once.")
        seen[key] = p


def _validated(tmp: str, path: str, out: MeshOutput, require_valid: bool,
               count: int) -> ValidationReport:
    """Validate the temporary ``tmp`` written for ``path``; its report, named ``path``."""
    nothing = "it was not saved" if count == 1 else "no file was written"
    try:
        report = replace(validate_file(tmp), path=path)
    except MeshError as exc:
        raise MeshError(f"the mesh written to '{path}' cannot be read back, so {nothing} "
                        f"({exc}). Check that the folder has room and try again, or write "
                        "another format (.stl, .3mf, .obj, .ply).") from exc
    if not require_valid or report.passed:
        return report
    if write_format(path) in FLOAT32_FORMATS:
        v, f = as_arrays(out.vertices, out.faces)
        failure = float32_breaks(path, v, f, count)
        if failure:
            raise MeshError(failure)
    raise MeshError(f"the mesh written to '{path}' is not watertight, so {nothing}: "
                    f"{report.summary()}. Check the input meshes with `jampacked validate`; "
                    "if they pass, this is a defect: report it with the packing file.")


def float32_breaks(path: str, vertices: np.ndarray, faces: np.ndarray, count: int = 1
                   ) -> str:
    """The message (:func:`float32_failure`) when the mesh is watertight as given but not
    once its positions are rounded to 32-bit floats, as ``path``'s format (STL or PLY)
    stores them; "" otherwise (a mesh that fails at full precision too fails for another
    reason)."""
    rounded = validate_arrays(vertices.astype(np.float32).astype(np.float64), faces,
                              check_manifold3d=False)
    if rounded.passed or not validate_arrays(vertices, faces, check_manifold3d=False).passed:
        return ""
    return float32_failure(path, vertices, rounded.failures(), count)


def float32_failure(path: str, vertices: np.ndarray, failures: Sequence[str],
                    count: int = 1) -> str:
    """The message for a mesh, watertight at full precision, that ``path``'s format (STL or
    PLY: 32-bit floats) cannot store watertight: the format, the coordinates' magnitude and
    rounding step, what the rounding breaks (``failures``), and the way out. ``count``: how
    many files the export writes (none of them is)."""
    ext = os.path.splitext(path)[1].lower().lstrip(".")
    fmt = FLOAT32_FORMATS.get(ext, ext.upper())
    largest = float(np.abs(vertices).max()) if len(vertices) else 0.0
    step = float(np.spacing(np.float32(largest)))
    broken = "; ".join(failures[:2]) or "faces that cross"
    nothing = "it was not saved" if count == 1 else "no file was written"
    return (f"'{path}' cannot hold this mesh watertight, so {nothing}: {fmt} stores "
            f"positions as 32-bit floats, and at coordinates up to {largest:.0e} units (mm) "
            f"they round in steps of {step:.1g}, which makes surfaces that nearly touch "
            f"meet or cross ({broken}); at full precision the mesh is watertight. Write 3MF "
            "(.3mf keeps full precision), or move the container mesh near the origin and "
            "pack again.")
