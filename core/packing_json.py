"""The packing JSON file: `save_packing`, `load_packing`, `verify_sources`.

The file (``"format": "jampacked.packing"``, ``"version": 2``) names meshes by path, relative
to the JSON file's directory (POSIX separators), by absolute path ("absolute_path"; older
files lack it and still load) and by sha256. A mesh is looked for at its relative path
first, then at its absolute one (`_located`). Container spec strings such as
``"box:43.4x41.8x45.0"`` are stored verbatim. Version 2 writes what `pack()` was asked for as
"inputs" and what the run did as "report" (`core/report.py`); version-1 files, which held
both in one flat "params" object, are still read (unknown keys are ignored).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
import re
import typing
from pathlib import PurePath
from types import UnionType
from typing import Any

import numpy as np

from .atomic import atomic_output, missing_folder
from .errors import InputError, MeshError, OutputError
from .mesh_files import MESH_EXTENSIONS, extension
from .meshes import file_sha256
from .options import FLAT_KEYS
from .packing_types import Packing, TypeRecord, is_spec
from .report import PackInputs, RunReport
from .rotations import placement_matrices

FORMAT = "jampacked.packing"
VERSION = 2


def to_jsonable(value: Any, where: str = "value") -> Any:
    """Convert numpy scalars/arrays (and tuples, paths) inside `value` to plain JSON types.

    Dict keys become strings; non-finite floats become None (JSON has no NaN/Infinity).
    Raises InputError naming `where` (a dotted key path) for anything else unserialisable.
    """
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist(), where)
    if isinstance(value, dict):
        return {str(k): to_jsonable(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, PurePath):
        return value.as_posix()
    raise InputError(f"{where}: cannot be written to JSON (type {type(value).__name__})")


def _matrix_list(m: np.ndarray) -> list[list[float]]:
    return [[float(x) for x in row] for row in np.asarray(m, dtype=np.float64)]


def _relative(path: str, base_dir: str) -> str:
    """`path` relative to `base_dir` with POSIX separators; absolute if no relative path exists
    (e.g. another drive on Windows). As spelled, symlinks not resolved: a project reached
    through a link keeps its own meshes, and a mesh that is a link stays that link."""
    try:
        rel = os.path.relpath(os.path.abspath(path), base_dir)
    except ValueError:
        rel = os.path.abspath(path)
    return rel.replace(os.sep, "/")


def _same_file(a: str, b: str) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


# --------------------------------------------------------------------------- save


def save_packing(packing: Packing, path: str | os.PathLike) -> None:
    """Write `packing` as JSON to `path`, atomically (temp file + os.replace).

    Mesh paths are stored relative to the JSON file's directory and as absolute paths, as
    spelled (symlinks not resolved); spec strings verbatim.
    Raises InputError if `path` is the container or a type mesh file (inputs are never
    overwritten), if its directory does not exist, or if a value cannot be written;
    OutputError if the file system refuses the file (what was there stays).
    """
    out = os.path.abspath(os.fspath(path))
    out_dir = os.path.dirname(out)
    missing = missing_folder(out_dir)
    if missing:
        raise InputError(f"cannot write packing {out}: {missing}")
    inputs = [] if is_spec(packing.container_path) else [packing.container_path]
    inputs += [t.path for t in packing.types if t.path is not None]
    for src in inputs:
        if _same_file(out, src):
            raise InputError(
                f"refusing to write packing to {out}: it is the input mesh {src}; "
                "choose another output path (e.g. ending in .json)"
            )
    if not (
        np.all(np.isfinite(packing.rotations))
        and np.all(np.isfinite(packing.translations))
        and np.all(np.isfinite(packing.scales))
    ):
        raise InputError(f"cannot write packing {out}: a placement holds NaN or infinity")

    def rel(p: str | None) -> str | None:
        if p is None or is_spec(p):
            return p
        return _relative(p, out_dir)

    def absolute(p: str | None) -> str | None:
        if p is None or is_spec(p):
            return None
        return os.path.abspath(p).replace(os.sep, "/")

    mats = packing.matrices()
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "container": {
            "path": rel(packing.container_path),
            "absolute_path": absolute(packing.container_path),
            "sha256": packing.container_sha256,
            "frame_from_file": _matrix_list(packing.frame_from_file),
            "volume": float(packing.container_volume),
        },
        "types": [
            {
                "name": t.name,
                "path": rel(t.path),
                "absolute_path": absolute(t.path),
                "sha256": t.sha256,
                "share": float(t.share),
                "local_from_file": _matrix_list(t.local_from_file),
                "volume": float(t.volume),
            }
            for t in packing.types
        ],
        "placements": 0,  # spliced in below, one line each
        "inputs": to_jsonable(dataclasses.asdict(packing.inputs), "inputs"),
        "report": to_jsonable(dataclasses.asdict(packing.report), "report"),
        "seed": int(packing.seed),
        "metrics": to_jsonable(packing.metrics, "metrics"),
        "timings": to_jsonable(packing.timings, "timings"),
        "certificate": to_jsonable(packing.certificate, "certificate"),
    }
    text = _NUMBER_LIST_RE.sub(_one_line, json.dumps(doc, indent=1, allow_nan=False)) + "\n"
    # json's C encoder runs only without indent: each placement is dumped on its own line
    # (docs/notes-meshes-io.md)
    rows = ",\n  ".join(
        json.dumps({"type": t, "matrix": m, "rotation": r, "translation": x, "scale": s},
                   allow_nan=False)
        for t, m, r, x, s in zip(packing.type_index.tolist(), mats.tolist(),
                                 packing.rotations.tolist(), packing.translations.tolist(),
                                 packing.scales.tolist(), strict=True))
    slot = '\n "placements": 0,\n'  # top-level keys alone sit at an indent of one space
    text = text.replace(slot, f'\n "placements": [\n  {rows}\n ],\n' if rows
                        else '\n "placements": [],\n', 1)
    try:
        _atomic_write_text(out, text)
    except OSError as exc:  # a full disk, a folder made read-only during the run, ...
        raise OutputError(f"cannot write the packing '{out}' ({exc.strerror or exc}): "
                          "nothing was written there, and a file there before is as it "
                          "was. Free some space, or save it in a folder with room and "
                          "write permission.") from exc


#: An innermost indented JSON list holding only numbers. The raw newline after "[" can only
#: follow a structural bracket (JSON strings hold no raw newlines), so strings are never touched.
_NUMBER_LIST_RE = re.compile(r"\[\n\s*([-+0-9.eE,\s]+?)\n\s*\]")


def _one_line(m: re.Match) -> str:
    """Put a list of numbers on one line, so a matrix row or a vector reads as one line."""
    return "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]"


def _atomic_write_text(path: str, text: str) -> None:
    """Write `text` to `path` through a temp file in the same folder; never a partial file."""
    with atomic_output(path, "w") as f:
        f.write(text)


# --------------------------------------------------------------------------- load


class _Reader:
    """Field access on the parsed JSON with errors that name the file and the field."""

    def __init__(self, path: str) -> None:
        self.path = path

    def fail(self, msg: str, fix: str = "it was damaged or edited by hand: restore it, or "
                                         "pack again") -> InputError:
        return InputError(f"packing file {self.path}: {msg}" + (f"; {fix}." if fix else ""))

    def get(self, obj: Any, key: str, where: str) -> Any:
        if not isinstance(obj, dict):
            raise self.fail(f"{where} must be a JSON object")
        if key not in obj:
            raise self.fail(f"missing field {where}.{key}" if where else f"missing field {key}")
        return obj[key]

    def number(self, value: Any, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"{where} must be a number, got {_short(value)}")
        try:
            f = float(value)
        except OverflowError:
            f = math.inf
        if not math.isfinite(f):
            raise self.fail(f"{where} must be a finite number, got {_short(value)}")
        return f

    def integer(self, value: Any, where: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(f"{where} must be an integer, got {_short(value)}")
        return value

    def opt_str(self, value: Any, where: str) -> str | None:
        if value is not None and not isinstance(value, str):
            raise self.fail(f"{where} must be a string or null, got {_short(value)}")
        return value

    def mesh_path(self, value: Any, where: str) -> str | None:
        """A mesh path (or null): a string no file system refuses outright."""
        value = self.opt_str(value, where)
        if value is not None and "\x00" in value:
            raise self.fail(f"{where} holds a NUL character, which no file name can",
                            "write the mesh's path there, or pack again")
        return value

    def vector(self, value: Any, size: int, where: str) -> np.ndarray:
        if (
            not isinstance(value, list)
            or len(value) != size
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in value)
        ):
            raise self.fail(f"{where} must be a list of {size} numbers, got {_short(value)}")
        return np.array([self.number(x, where) for x in value], dtype=np.float64)

    def matrix(self, value: Any, where: str) -> np.ndarray:
        if not isinstance(value, list) or len(value) != 4:
            raise self.fail(f"{where} must be a 4x4 matrix (4 rows of 4 numbers)")
        try:
            return np.stack([self.vector(row, 4, where) for row in value])
        except InputError:
            raise self.fail(f"{where} must be a 4x4 matrix (4 rows of 4 numbers)") from None

    def dict_(self, value: Any, where: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(f"{where} must be a JSON object")
        return value


def _placement_arrays(raw: list, types: int) -> tuple[np.ndarray, ...] | None:
    """The placements as arrays (type index, matrices, rotations, translations, scales) in
    one pass over the whole list, or None if any placement is malformed: the reader then
    goes through them one by one and names the first bad field. The field-by-field reader
    took 0.2 ms a placement (docs/notes-meshes-io.md)."""
    if not all(type(p) is dict for p in raw):
        return None
    try:
        fields = [[p[key] for p in raw]
                  for key in ("type", "matrix", "rotation", "translation", "scale")]
        k = np.array(fields[0])
        arrays = [np.array(f, dtype=np.float64) for f in fields[1:]]
    except (KeyError, ValueError, TypeError, OverflowError):
        return None
    if (set(map(type, fields[0])) - {int} or k.shape != (len(raw),)
            or ((k < 0) | (k >= types)).any()):
        return None
    numbers = itertools.chain(fields[4], itertools.chain.from_iterable(fields[2]),
                              itertools.chain.from_iterable(fields[3]),
                              itertools.chain.from_iterable(
                                  itertools.chain.from_iterable(fields[1])))
    if set(map(type, numbers)) - {int, float}:
        return None
    m, q, t, s = arrays
    if (m.shape != (len(raw), 4, 4) or q.shape != (len(raw), 4) or t.shape != (len(raw), 3)
            or s.shape != (len(raw),) or not all(np.isfinite(a).all() for a in arrays)
            or not q.any(axis=1).all()):
        return None
    return k.astype(np.int64), m, q, t, s


def _located(p: str | None, absolute: str | None, src: str) -> str | None:
    """Where a mesh is, for a packing file opened as `src`: the first of these that is a
    file, else the first (so that a message names the path the user can edit):

    - its `path` against the folder `src` names (as written, so a project folder moved or
      copied with its meshes finds the meshes beside it; a `path` edited by hand wins);
    - its `path` against that folder's real location (the file written through a
      symlinked folder, opened from where it really is, or the other way round);
    - its `absolute_path` (older files have none): a packing file moved alone still finds
      meshes that stayed where they were."""
    if p is None or is_spec(p):
        return p
    candidates = [os.path.normpath(os.path.join(os.path.dirname(src), p))]
    if not os.path.isabs(p):
        candidates.append(os.path.normpath(os.path.join(
            os.path.dirname(os.path.realpath(src)), p)))
    if absolute and os.path.isabs(absolute):
        candidates.append(os.path.normpath(absolute))
    return next((c for c in candidates if os.path.isfile(c)), candidates[0])


def load_packing(path: str | os.PathLike) -> Packing:
    """Read a packing JSON file written by `save_packing`.

    Relative mesh paths are resolved against the JSON file's directory into absolute paths
    (`_located`: where no file is there, against its real directory, then the recorded
    absolute path).
    Raises InputError, naming the file, if it cannot be read or parsed, has another format or
    a newer version, or lacks a field / holds a bad value (matrix shape, type index, a
    placement matrix that disagrees with its rotation/translation/scale, ...).
    """
    src = os.path.abspath(os.fspath(path))
    r = _Reader(src)
    try:
        # utf-8-sig: a byte order mark (which Windows editors write) is skipped; without one
        # it reads as utf-8
        with open(src, encoding="utf-8-sig") as f:
            doc = json.load(f)
    except OSError as exc:
        raise InputError(f"cannot read packing file {src}: {exc.strerror or exc}") from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        if extension(src) in MESH_EXTENSIONS:
            raise r.fail(f"not valid JSON ({exc}): this is a mesh file, not a packing (the "
                         "JSON file `pack -o` writes); `jampacked validate` checks meshes",
                         "") from exc
        raise r.fail(f"not valid JSON ({exc}); was it truncated or edited?", "") from exc
    except RecursionError:
        raise r.fail("nested too deeply to be a packing (JSON lists or objects inside each "
                     "other hundreds of levels deep); was it edited?", "") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise r.fail(f"not a jampacked packing (format is {found!r}, expected {FORMAT!r})",
                     "give a file that `jampacked pack` wrote")
    version = r.integer(r.get(doc, "version", ""), "version")
    if version > VERSION:
        raise r.fail(
            f"written by a newer jampacked (version {version}); this one reads version "
            f"{VERSION}: upgrade jampacked", ""
        )
    if version < 1:
        raise r.fail(f"invalid version {version}")
    cont = r.dict_(r.get(doc, "container", ""), "container")
    cpath = r.mesh_path(r.get(cont, "path", "container"), "container.path")
    if not cpath:
        raise r.fail("container.path must be a non-empty string")
    container_path = _located(cpath, r.mesh_path(cont.get("absolute_path"),
                                                 "container.absolute_path"), src)
    container_sha = r.opt_str(r.get(cont, "sha256", "container"), "container.sha256")
    frame = r.matrix(r.get(cont, "frame_from_file", "container"), "container.frame_from_file")
    cvol = r.number(r.get(cont, "volume", "container"), "container.volume")

    raw_types = r.get(doc, "types", "")
    if not isinstance(raw_types, list):
        raise r.fail("types must be a list")
    types = []
    for i, t in enumerate(raw_types):
        w = f"types[{i}]"
        name = r.get(t, "name", w)
        if not isinstance(name, str):
            raise r.fail(f"{w}.name must be a string")
        types.append(
            TypeRecord(
                name=name,
                path=_located(r.mesh_path(r.get(t, "path", w), f"{w}.path"),
                              r.mesh_path(t.get("absolute_path"), f"{w}.absolute_path"),
                              src),
                sha256=r.opt_str(r.get(t, "sha256", w), f"{w}.sha256"),
                share=r.number(r.get(t, "share", w), f"{w}.share"),
                local_from_file=r.matrix(r.get(t, "local_from_file", w), f"{w}.local_from_file"),
                volume=r.number(r.get(t, "volume", w), f"{w}.volume"),
            )
        )

    raw_pl = r.get(doc, "placements", "")
    if not isinstance(raw_pl, list):
        raise r.fail("placements must be a list")
    n = len(raw_pl)
    fast = _placement_arrays(raw_pl, len(types))
    if fast is not None:
        type_index, matrices, rotations, translations, scales = fast
    else:
        type_index = np.zeros(n, dtype=np.int64)
        rotations = np.zeros((n, 4))
        translations = np.zeros((n, 3))
        scales = np.zeros(n)
        matrices = np.zeros((n, 4, 4))
    for i, p in enumerate(raw_pl if fast is None else ()):
        w = f"placements[{i}]"
        k = r.integer(r.get(p, "type", w), f"{w}.type")
        if not 0 <= k < len(types):
            raise r.fail(f"{w}.type is {k} but the file lists {len(types)} types")
        type_index[i] = k
        matrices[i] = r.matrix(r.get(p, "matrix", w), f"{w}.matrix")
        rotations[i] = r.vector(r.get(p, "rotation", w), 4, f"{w}.rotation")
        if not np.any(rotations[i]):
            raise r.fail(f"{w}.rotation must be a non-zero quaternion [w, x, y, z]")
        translations[i] = r.vector(r.get(p, "translation", w), 3, f"{w}.translation")
        scales[i] = r.number(r.get(p, "scale", w), f"{w}.scale")
    # A scale of 0 makes an object vanish and a negative one mirrors it (another shape than
    # the type that was packed, which certification and export would take as it is).
    bad = np.flatnonzero(~(scales > 0))
    if bad.size:
        i = int(bad[0])
        others = f" (and {bad.size - 1} more placements)" if bad.size > 1 else ""
        raise r.fail(f"placements[{i}].scale must be > 0, got {scales[i]:g}{others}: "
                     f"{'a negative scale mirrors' if scales[i] < 0 else '0 shrinks'} the "
                     "object", "a finished packing has scale 1: set it back (its matrix "
                     "with it) or remove the placement, or pack again")
    # The matrix is redundant; a hand-edited file must not say two different things.
    expected = placement_matrices(rotations, translations, scales)
    tol = 1e-6 * np.maximum(1.0, np.abs(expected).max(axis=(1, 2)))
    bad = np.flatnonzero(np.abs(matrices - expected).max(axis=(1, 2)) > tol)
    if bad.size:
        raise r.fail(
            f"placements[{bad[0]}].matrix does not match its rotation, translation and scale; "
            "edit them together or delete the file and re-run the packing"
        )

    return Packing(
        container_path=container_path,
        container_sha256=container_sha,
        frame_from_file=frame,
        container_volume=cvol,
        types=types,
        type_index=type_index,
        rotations=rotations,
        translations=translations,
        scales=scales,
        **_inputs_and_report(r, doc, version),
        seed=r.integer(r.get(doc, "seed", ""), "seed"),
        metrics=r.dict_(r.get(doc, "metrics", ""), "metrics"),
        timings=r.dict_(r.get(doc, "timings", ""), "timings"),
        certificate=r.dict_(r.get(doc, "certificate", ""), "certificate"),
    )

def _short(value: Any, limit: int = 60) -> str:
    """repr of a bad value, cut short (a huge number or a long list in a message helps no
    one)."""
    try:
        text = repr(value)
    except ValueError:  # an int beyond Python's digit limit for str()
        text = f"an integer of about {value.bit_length() * 0.30103:.0f} digits"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _inputs_and_report(r: _Reader, doc: dict, version: int) -> dict[str, Any]:
    """The typed inputs and report of a version-2 file, or mapped from a version-1 file's
    flat params. Inputs are checked (a bad value raises, naming the field); the report is
    informational: a field with a value of the wrong kind is left at its default."""
    if version >= 2:
        raw_inputs = r.dict_(r.get(doc, "inputs", ""), "inputs")
        raw_report = r.dict_(r.get(doc, "report", ""), "report")
    else:
        params = r.dict_(r.get(doc, "params", ""), "params")
        options: dict[str, dict[str, Any]] = {}
        for key, value in params.items():
            if key == "extra_passes" and not (
                    isinstance(value, list) and all(_is_number(v) for v in value)):
                continue  # pack() wrote the passes' statistics over the option's factors
            if key in FLAT_KEYS:
                group, name = FLAT_KEYS[key]
                options.setdefault(group, {})[name] = value
        if "tune_threads" in params:
            options["tune_threads"] = params["tune_threads"]  # type: ignore[assignment]
        raw_inputs = {k: params[k] for k in ("clearance", "time_budget", "container_size",
                                             "type_scale") if k in params}
        if "fidelity_requested" in params:
            raw_inputs["fidelity"] = params["fidelity_requested"]
        raw_inputs["options"] = options
        raw_report = {f.name: params[f.name] for f in dataclasses.fields(RunReport)
                      if f.name in params}
    try:
        inputs = from_plain(PackInputs, raw_inputs, "inputs", lenient=False)
    except _Bad as exc:
        raise r.fail(f"{exc.where} {exc.what}") from None
    return {"inputs": inputs,
            "report": from_plain(RunReport, raw_report, "report", lenient=True)}


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class _Bad(Exception):
    def __init__(self, where: str, what: str) -> None:
        super().__init__(f"{where} {what}")
        self.where = where
        self.what = what


def from_plain(tp: Any, value: Any, where: str, *, lenient: bool) -> Any:
    """A value of type `tp` (a dataclass, a number, str, bool, list/tuple/dict of them, or
    X | None) from parsed JSON. A dataclass's missing fields take their defaults, unknown
    keys are ignored. lenient: a field whose value is of the wrong kind takes its default;
    otherwise _Bad names it."""
    if tp is Any:
        return value
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise _Bad(where, "must be a JSON object")
        hints = typing.get_type_hints(tp)
        kwargs = {}
        for f in dataclasses.fields(tp):
            if not f.init or f.name not in value:
                continue
            try:
                kwargs[f.name] = from_plain(hints[f.name], value[f.name], f"{where}.{f.name}",
                                            lenient=lenient)
            except _Bad:
                if not lenient:
                    raise
        try:
            return tp(**kwargs)
        except (TypeError, ValueError) as exc:
            raise _Bad(where, f"holds bad values ({exc})") from None
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, UnionType):
        if value is None and type(None) in args:
            return None
        for arg in args:
            if arg is type(None):
                continue
            try:
                return from_plain(arg, value, where, lenient=lenient)
            except _Bad:
                pass
        raise _Bad(where, f"has the wrong kind of value: {_short(value)}")
    if origin is list or origin is tuple:
        if not isinstance(value, list):
            raise _Bad(where, f"must be a list, got {_short(value)}")
        item = args[0] if args else Any
        out = [from_plain(item, v, f"{where}[{i}]", lenient=lenient)
               for i, v in enumerate(value)]
        return tuple(out) if origin is tuple else out
    if origin is dict or tp is dict:
        if not isinstance(value, dict):
            raise _Bad(where, "must be a JSON object")
        item = args[1] if args else Any
        return {k: from_plain(item, v, f"{where}.{k}", lenient=lenient) for k, v in value.items()}
    if tp is bool:
        if not isinstance(value, bool):
            raise _Bad(where, f"must be true or false, got {_short(value)}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise _Bad(where, f"must be an integer, got {_short(value)}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _Bad(where, f"must be a number, got {_short(value)}")
        try:
            f = float(value)
        except OverflowError:
            f = math.inf
        if not math.isfinite(f):
            raise _Bad(where, f"must be a finite number, got {_short(value)}")
        return f
    if tp is str:
        if not isinstance(value, str):
            raise _Bad(where, f"must be a string, got {_short(value)}")
        return value
    raise TypeError(f"from_plain: unsupported type {tp!r}")  # a programming error


def verify_sources(packing: Packing) -> list[str]:
    """Check the mesh files a packing names; never raises.

    Returns:
        Human-readable problems (missing/unreadable file, sha256 mismatch); empty if all good.
        Spec containers and types without a path or without a recorded sha256 are only checked
        for existence where a path is given.
    """
    problems: list[str] = []
    entries: list[tuple[str, str | None, str | None]] = []
    if not is_spec(packing.container_path):
        entries.append(("container", packing.container_path, packing.container_sha256))
    entries += [(f"type {t.name!r}", t.path, t.sha256) for t in packing.types]
    missing: list[int] = []
    for label, p, sha in entries:
        if p is None:
            continue
        if not os.path.isfile(p):
            missing.append(len(problems))
            problems.append(f"{label}: mesh file {p} is missing")
            continue
        if sha is None:
            continue
        try:
            actual = file_sha256(p)
        except (OSError, MeshError) as exc:  # file_sha256 names a refused read as a MeshError
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
            problems.append(f"{label}: cannot read mesh file {p} ({why})")
            continue
        if actual.lower() != sha.lower():
            problems.append(
                f"{label}: mesh file {p} has changed since the packing was made "
                f"(sha256 {actual[:12]}... but the packing records {sha[:12]}...); "
                "re-run the packing or restore the original file"
            )
    if missing:  # the fix once, after the last missing file
        them, its = ("it", "its") if len(missing) == 1 else ("them", "each one's")
        problems[missing[-1]] += (
            f"; restore {them}, or edit {its} \"path\" in the packing file to point to where "
            "the file is now (absolute, or relative to the packing file's folder), or re-run "
            "the packing")
    return problems
