"""Write mesh files atomically: no merging, no repair, no validation.

STL (binary), OBJ and PLY (binary) go through trimesh's exporters on
``trimesh.Trimesh(..., process=False)``; they hold one mesh, so the bodies are concatenated.
3MF is written by :func:`jampacked.core.threemf.encode_3mf`: one object per body, named when
names are given, one build item each, in millimetres. Units and frame are the caller's
(container units, mm for printing). Validating what was written is
:func:`jampacked.export.io.write_mesh`'s job.

A file is first written to a temporary beside its target (:func:`stage_mesh_file`) and
renamed over it later (:func:`replace_files`), so that several files of one export can be
checked before any of them replaces what was there.
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from jampacked.core.atomic import missing_folder, refusal_advice, staged_output, write_refusal
from jampacked.core.errors import InputError, MeshError, OutputError
from jampacked.core.mesh_files import extension
from jampacked.core.threemf import encode_3mf, encode_3mf_components

__all__ = ["WRITE_FORMATS", "Instances", "as_arrays", "check_output_path", "encode_mesh",
           "name_too_long", "remove_temporaries", "replace_files", "short_name",
           "stage_mesh_file", "write_mesh_file"]

#: file extensions write_mesh_file can write
WRITE_FORMATS = ("stl", "obj", "ply", "3mf")

Body = tuple[np.ndarray, np.ndarray]

#: the characters tempfile.mkstemp puts between a temporary's prefix and suffix
TEMP_RANDOM = 8
#: a folder's longest file name, in bytes, where the file system does not say (most
#: file systems' limit)
NAME_MAX_FALLBACK = 255


@dataclass(frozen=True)
class Instances:
    """Bodies that are copies of a few meshes, each moved by its own transform (the objects
    of a packing: one mesh per type). A 3MF stores each mesh once and each body as a
    component (:func:`jampacked.core.threemf.encode_3mf_components`); the other formats get
    the moved meshes (:meth:`bodies`).

    meshes: ``(vertices, faces)`` per mesh in its own frame; mesh_names: one per mesh;
    index: (N,) the mesh of each body; matrices: (N, 4, 4) each body's transform (column
    vectors: the mesh's frame to the file's).
    """

    meshes: Sequence[Body]
    mesh_names: Sequence[str]
    index: np.ndarray
    matrices: np.ndarray

    def bodies(self) -> list[Body]:
        """Each body's moved mesh, computed as a 3MF reader applies a component transform."""
        out = []
        for k, m in zip(self.index, self.matrices, strict=True):
            v, f = self.meshes[int(k)]
            out.append((v @ m[:3, :3].T + m[:3, 3], f))
        return out


def _as_bodies(vertices: object, faces: object) -> list[Body]:
    if isinstance(vertices, Instances):
        vertices, faces = vertices.bodies(), None
    if faces is None:
        items = list(vertices)  # type: ignore[call-overload]
    else:
        items = [(vertices, faces)]
    bodies = []
    for v, f in items:
        v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(f, dtype=np.int64).reshape(-1, 3)
        if len(f) and (f.min() < 0 or f.max() >= len(v)):
            raise InputError("a body's faces refer to vertices that do not exist: give faces "
                             "as indices into that body's own vertices.")
        bodies.append((v, f))
    if not bodies:
        raise InputError("nothing to write: give at least one body (vertices, faces).")
    return bodies


def _concatenate(bodies: Sequence[Body]) -> Body:
    offsets = np.cumsum([0] + [len(v) for v, _ in bodies[:-1]])
    return (np.concatenate([v for v, _ in bodies]),
            np.concatenate([f + o for (_, f), o in zip(bodies, offsets, strict=True)]))


def as_arrays(vertices: object, faces: object = None) -> Body:
    """One ``(vertices (V, 3) float64, faces (F, 3))`` pair of what the writers take (one
    mesh, a list of bodies, or :class:`Instances`): the bodies concatenated, as an STL, OBJ
    or PLY holds them."""
    return _concatenate(_as_bodies(vertices, faces))


def encode_mesh(ext: str, bodies: Sequence[Body] | Instances,
                names: Sequence[str] | None = None) -> bytes:
    """The bytes of a mesh file of format ``ext`` (one of ``WRITE_FORMATS``) holding
    ``bodies``, each ``(vertices (V, 3), faces (F, 3))``, or :class:`Instances`; ``names``
    name 3MF objects."""
    if isinstance(bodies, Instances):
        if ext == "3mf":
            return encode_3mf_components([(np.asarray(v, np.float64), f)
                                          for v, f in bodies.meshes], bodies.mesh_names,
                                         bodies.index, bodies.matrices, names)
        bodies = _as_bodies(bodies, None)
    if ext == "3mf":
        return encode_3mf(bodies, names)
    v, f = _concatenate(bodies)
    mesh = trimesh.Trimesh(vertices=v, faces=f, process=False, validate=False)
    if ext == "stl":
        return mesh.export(file_type="stl")
    if ext == "ply":
        return mesh.export(file_type="ply", encoding="binary")
    text = mesh.export(file_type="obj", include_normals=False, include_color=False,
                       include_texture=False, digits=12)
    return text.encode("utf-8") if isinstance(text, str) else text


def _same_file(a: str, b: str) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    with contextlib.suppress(OSError):
        return os.path.samefile(a, b)
    return False


def write_format(path: str) -> str:
    """The format a file name asks for (its extension, lower case), or OutputError."""
    ext = extension(path)
    if ext not in WRITE_FORMATS:
        what = f"unknown mesh format '.{ext}'" if ext else "no extension to name its format"
        raise OutputError(f"cannot write '{path}': {what}; use one of "
                         f"{', '.join('.' + e for e in WRITE_FORMATS)}.")
    return ext


def _staged_name(name: str, ext: str) -> str:
    """The name of the temporary a file named ``name`` is first written as
    (:func:`stage_mesh_file`), its random part as long as tempfile makes it: longer than
    ``name``, so it is the one that reaches the file system's limit first."""
    return f".{name}.{'x' * TEMP_RANDOM}.tmp.{ext}"


@functools.lru_cache(maxsize=64)
def name_limit(folder: str) -> int:
    """The longest file name, in bytes, that ``folder``'s file system takes (asked once per
    folder: a --split export checks each part's name twice)."""
    try:
        limit = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):  # no pathconf (Windows), or not known
        return NAME_MAX_FALLBACK
    return limit if limit > 0 else NAME_MAX_FALLBACK


def name_too_long(path: str) -> tuple[int, int] | None:
    """(the length in bytes of the temporary that ``path`` is first written as, the
    longest name its folder takes) when that is too long for the folder, else None."""
    folder, name = os.path.split(os.path.abspath(path))
    staged = len(os.fsencode(_staged_name(name, write_format(path))))
    limit = name_limit(folder)
    return (staged, limit) if staged > limit else None


def short_name(name: str, keep: int = 40) -> str:
    """``name`` cut to its first ``keep`` characters, for a message about a long name."""
    return name if len(name) <= keep else f"{name[:keep]}..."


def check_output_path(path: str | os.PathLike,
                      protect: Iterable[str | os.PathLike] = (),
                      probed: set[str] | None = None) -> str:
    """Check that a mesh file can be written at ``path`` before anything is built for it;
    returns its format (the extension, lower case).

    Raises OutputError (unknown format, ``path`` is one of ``protect``: the inputs, compared
    as resolved paths, or its name is too long for its folder) or MeshError (its folder does
    not exist or takes no new file, or it is a folder). ``probed``: folders already found
    to take new files (this one is added), so that many outputs in one folder probe it once.
    """
    path_str = os.fspath(path)
    ext = write_format(path_str)
    for p in protect:
        if _same_file(path_str, os.fspath(p)):
            raise OutputError(f"refusing to write '{path_str}': it is an input file "
                              f"('{os.fspath(p)}'); choose another output name.")
    folder = os.path.dirname(os.path.abspath(path_str))
    missing = missing_folder(folder)
    if missing:
        raise MeshError(f"cannot write '{path_str}': {missing}.")
    if os.path.isdir(path_str):
        raise MeshError(f"cannot write '{path_str}': it is a folder; give a file name.")
    too_long = name_too_long(path_str)
    if too_long:  # else ENAMETOOLONG once everything was built
        name = os.path.basename(path_str)
        raise OutputError(
            f"cannot write '{short_name(name)}': its file name is too long for the folder "
            f"'{folder}', which takes names of at most {too_long[1]} bytes: the file is first "
            f"written under a name of {too_long[0]} bytes (its own {len(os.fsencode(name))} "
            "and a temporary's additions). Give a shorter output name.")
    if probed is None or folder not in probed:
        refused = write_refusal(folder)
        if refused:
            raise MeshError(f"cannot write '{path_str}': the folder '{folder}' takes no new "
                            f"file ({refused}). {refusal_advice(folder)}, or give another "
                            "output file.")
        if probed is not None:
            probed.add(folder)
    return ext


def stage_mesh_file(
    path: str | os.PathLike,
    vertices: object,
    faces: object = None,
    *,
    names: Sequence[str] | None = None,
) -> str:
    """Write the mesh for ``path`` to a temporary file beside it and return the
    temporary's path; ``path`` itself is not touched (:func:`replace_files` puts it in
    place). The temporary is hidden (``.NAME.XXXX.tmp.EXT``), ends in the real extension so
    it reads back, is flushed to disk and has the permissions ``path`` has (a new file's
    follow the umask). The path must have been checked (:func:`check_output_path`); other
    arguments and errors as :func:`write_mesh_file`; on an error no temporary is left.
    """
    path_str = os.fspath(path)
    ext = write_format(path_str)
    # a 3MF of instances is written without moving every mesh
    bodies: Sequence[Body] | Instances = (
        vertices if isinstance(vertices, Instances) and ext == "3mf"
        else _as_bodies(vertices, faces))
    count = len(bodies.index) if isinstance(bodies, Instances) else len(bodies)
    if names is not None and len(names) != count:
        raise InputError(f"{len(names)} names for {count} bodies writing '{path_str}': "
                         "give one name per body.")
    data = encode_mesh(ext, bodies, names)
    try:
        # named as _staged_name says, which check_output_path measured
        with staged_output(os.path.abspath(path_str), "wb", suffix=f".tmp.{ext}") as (
                handle, tmp):
            handle.write(data)
    except OSError as exc:
        raise MeshError(f"cannot write '{path_str}' ({exc.strerror or exc}): check the "
                        "folder's permissions and free space.") from exc
    return tmp


def remove_temporaries(staged: Iterable[tuple[str, str]]) -> None:
    """Remove the temporary files of ``(temporary, target)`` pairs that are still there."""
    for tmp, _ in staged:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


#: signals held back during the renames: Ctrl-C, and the SIGTERM and SIGHUP the command
#: line turns into an exception (`jampacked.cli.interrupt.TerminateCleanly`)
DEFERRED_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                         if hasattr(signal, name))


@contextlib.contextmanager
def _interrupts_deferred() -> Iterator[None]:
    """Hold Ctrl-C (SIGINT), and SIGTERM and SIGHUP where Python code handles them, back
    until the block ends, so that they cannot stop a set of renames half-way: in the main
    thread their handlers only record them meanwhile, and once the block has completed each
    is raised again for the handler that was there (a KeyboardInterrupt, if that handler
    raises one, comes out of this block's end). When the block fails, the error already
    says what is on disk and the signals are dropped."""
    previous: dict[int, object] = {}
    if threading.current_thread() is threading.main_thread():
        for signum in DEFERRED_SIGNALS:
            handler = signal.getsignal(signum)
            # a handler not installed from Python (None) cannot be put back; an ignored or
            # default SIGTERM or SIGHUP is left as the caller set it
            if handler is not None and (signum == signal.SIGINT or callable(handler)):
                previous[signum] = handler
    if not previous:
        yield
        return
    held: list[int] = []
    for signum in previous:
        signal.signal(signum, lambda got, frame: held.append(got))
    try:
        yield
    except BaseException:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        raise
    for signum, handler in previous.items():
        signal.signal(signum, handler)
    for signum in dict.fromkeys(held):
        signal.raise_signal(signum)


def replace_files(staged: Sequence[tuple[str, str]]) -> None:
    """Rename each ``(temporary, target)`` temporary over its target, all of them or none,
    with Ctrl-C held back meanwhile.

    Each target that exists is first hard-linked to a hidden backup beside it; when a rename
    fails (no space, an immutable file), the targets already replaced are put back from
    their backups (a new one is removed), so every output is as it was. Raises MeshError
    then, naming what failed and, where a file system without hard links or a failed
    restore left part of the export on disk, exactly which files. A Ctrl-C (or a SIGTERM
    or SIGHUP the command line handles) held back meanwhile surfaces afterwards as its
    exception, whose ``replaced`` attribute lists the targets replaced (all of them), for
    a true message.
    """
    done: list[str] = []
    backups: dict[str, str | None] = {}
    try:
        with _interrupts_deferred():
            for k, (tmp, path) in enumerate(staged):
                backups[path] = _backup(path)
                try:
                    os.replace(tmp, path)
                except OSError as exc:
                    remove_temporaries(staged[k:])
                    _discard(backups.pop(path, None))
                    undone = _restore(done, backups)
                    saved = {p: b for p, b in backups.items() if b and p in done}
                    raise MeshError(_rename_failure(path, exc, [p for p in done if p not in
                                                                undone],
                                                    [p for _, p in staged[k:]], undone,
                                                    saved)) from exc
                done.append(path)
            for backup in backups.values():
                _discard(backup)
    except BaseException as exc:
        if not isinstance(exc, Exception):  # a signal held back (Ctrl-C, SIGTERM, SIGHUP)
            exc.replaced = list(done)  # type: ignore[attr-defined]
        raise


#: the backup of a target that exists but could not be linked (no hard links there): it
#: cannot be put back
_NO_BACKUP = ""


def _backup(path: str) -> str | None:
    """A hidden hard link to ``path`` beside it; None where ``path`` does not exist (a new
    file), :data:`_NO_BACKUP` where the file system refuses the link."""
    if not os.path.lexists(path):
        return None
    folder, name = os.path.split(os.path.abspath(path))
    try:
        fd, backup = tempfile.mkstemp(prefix=f".{name}.", suffix=".old", dir=folder)
        os.close(fd)
        os.unlink(backup)
        os.link(path, backup)
    except OSError:
        return _NO_BACKUP
    return backup


def _discard(backup: str | None) -> None:
    if backup:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(backup)


def _restore(done: list[str], backups: dict[str, str | None]) -> list[str]:
    """Put each replaced target of ``done`` back as it was (a new one removed); the targets
    restored. A backup that cannot be put back is kept (``backups`` still names it)."""
    undone = []
    for path in done:
        backup = backups.get(path)
        if backup == _NO_BACKUP:
            continue
        try:
            if backup is None:
                os.unlink(path)
            else:
                os.replace(backup, path)
        except OSError:
            continue
        backups.pop(path)
        undone.append(path)
    return undone


def _rename_failure(path: str, exc: OSError, done: list[str], left: list[str],
                    restored: Sequence[str] = (), saved: dict[str, str] | None = None
                    ) -> str:
    """The message for a rename onto ``path`` that failed after ``done`` were renamed (and
    not put back); ``left`` (``path`` first) were not touched; ``restored`` were put back as
    they were; ``saved``: the backups of replaced targets that could not be put back."""
    first = (f"cannot put '{path}' in place ({exc.strerror or exc}): check the folder's "
             "permissions and free space.")
    if not done:
        return first + " No file was written; every output file is as it was."

    def names(paths: Sequence[str]) -> str:
        return ", ".join(f"'{p}'" for p in paths)

    kept = [p for p in left if os.path.lexists(p)]
    absent = [p for p in left if p not in kept]
    parts = [f"{names(done)} {'was' if len(done) == 1 else 'were'} replaced by the new "
             "export"]
    if kept:
        parts.append(f"{names(kept)} kept {'its' if len(kept) == 1 else 'their'} previous "
                     "contents")
    if absent:
        parts.append(f"{names(absent)} {'was' if len(absent) == 1 else 'were'} not written")
    if restored:
        parts.append(f"{names(restored)} {'was' if len(restored) == 1 else 'were'} put "
                     "back as before")
    parts += [f"the previous contents of '{p}' are in '{b}'" for p, b in (saved or {}).items()]
    return (f"{first} Only part of the export is on disk: {'; '.join(parts)}. Export again "
            "to make the files agree.")


def write_mesh_file(
    path: str | os.PathLike,
    vertices: object,
    faces: object = None,
    *,
    names: Sequence[str] | None = None,
    protect: Iterable[str | os.PathLike] = (),
    check: Callable[[str], None] | None = None,
) -> None:
    """Write a mesh atomically.

    Call as ``write_mesh_file(path, vertices, faces)`` for one mesh, or
    ``write_mesh_file(path, bodies)`` with a list of ``(vertices, faces)`` bodies or an
    :class:`Instances` (a 3MF then stores each mesh once).

    Args:
        path: output file; its extension picks the format: .stl (binary), .obj, .ply
            (binary), .3mf.
        vertices: (V, 3) positions, or the list of bodies when ``faces`` is None.
        faces: (F, 3) vertex indices, counter-clockwise seen from outside.
        names: one name per body for 3MF objects (ignored by the other formats).
        protect: input files the output must not replace (compared as resolved paths).
        check: called with the path of the complete temporary file (which ends in the
            real extension, so it reads back) before it is renamed over ``path``; what it
            raises leaves ``path`` as it was.

    Raises:
        InputError: unknown format, a protected input path, names that do not match the
            bodies, or bad arrays.
        MeshError: the file cannot be written (missing folder, permissions, disk full).
    """
    path_str = os.fspath(path)
    check_output_path(path_str, protect)
    tmp = stage_mesh_file(path_str, vertices, faces, names=names)
    staged = [(tmp, path_str)]
    try:
        if check is not None:
            check(tmp)
        replace_files(staged)
    finally:
        remove_temporaries(staged)
