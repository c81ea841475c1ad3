"""Write a mesh file and validate it as written, before it is put in place.

Writing is :mod:`jampacked.export.mesh_write`; reading a file as stored is
:func:`jampacked.core.mesh_files.read_mesh_arrays` (also importable from here); validating is
:mod:`jampacked.export.validate`. Units and frame are the caller's (container units, mm for
printing); 3MF files declare millimetres.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import replace

from jampacked.core.errors import MeshError
from jampacked.core.mesh_files import read_mesh_arrays

from .mesh_write import WRITE_FORMATS, write_mesh_file
from .validate import ValidationReport, validate_file

__all__ = ["WRITE_FORMATS", "read_mesh_arrays", "write_mesh"]


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
        MeshError: the file cannot be written, or (``require_valid``) it fails validation.

    The data goes to a temporary file in the same folder, which is flushed, synced,
    validated and renamed over ``path``; on any failure the temporary file is removed and
    ``path`` is left as it was.
    """
    path_str = os.fspath(path)
    reports: list[ValidationReport] = []

    def check(tmp: str) -> None:
        try:
            report = replace(validate_file(tmp), path=path_str)
        except MeshError as exc:
            raise MeshError(f"the mesh written to '{path_str}' cannot be read back, so it "
                            f"was not saved ({exc}). Check that the folder has room and try "
                            "again, or write another format (.stl, .3mf, .obj, .ply).") from exc
        if require_valid and not report.passed:
            raise MeshError(f"the mesh written to '{path_str}' is not watertight, so it "
                            f"was not saved: {report.summary()}. Check the input meshes with "
                            "`jampacked validate`; parts (--mode parts) of a packing without "
                            "a clearance can touch along non-manifold edges: re-pack with "
                            "--clearance, or export with --mode union or connect. A union or "
                            "connect export that fails here is a defect: report it with the "
                            "packing file.")
        reports.append(report)

    write_mesh_file(path_str, vertices, faces, names=names, protect=protect,
                    check=check if validate else None)
    return reports[0] if reports else None
