"""The packing result type and its JSON file.

Frames (container units, e.g. mm, throughout):
- container frame: `frame_from_file @ v_file` maps container file coordinates into it.
- object local frame of a type: `local_from_file @ v_file` (volume centroid at the origin).
- a placed object's vertices in the container frame: `matrix @ local_from_file @ v_file`, with
  `matrix = [R(q) * s | t]` from its rotation q (unit quaternion w, x, y, z), scale s and
  translation t.

The JSON file (``"format": "jampacked.packing"``, ``"version": 1``) names meshes by path,
relative to the JSON file's directory (POSIX separators), plus sha256. Container spec strings
such as ``"box:43.4x41.8x45.0"`` are stored verbatim.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import PurePath
from typing import Any

import numpy as np

from .atomic import atomic_output
from .errors import InputError

FORMAT = "jampacked.packing"
VERSION = 1

#: A container spec like "box:43.4x41.8x45.0": a word of 2+ characters then a colon (two or
#: more characters so that Windows drive letters such as "C:" are not taken for specs).
_SPEC_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]+:")


# --------------------------------------------------------------------------- rotations


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices from quaternions.

    Args:
        q: (N, 4) quaternions (w, x, y, z); normalised here, must be non-zero.

    Returns:
        (N, 3, 3) float64 rotation matrices R with R @ v rotating column vectors v.
    """
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 4:
        raise InputError(f"quaternions must have shape (N, 4), got {q.shape}")
    norm = np.linalg.norm(q, axis=1)
    if np.any(~np.isfinite(norm)) or np.any(norm == 0):
        raise InputError("quaternions must be finite and non-zero")
    w, x, y, z = (q / norm[:, None]).T
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = 1 - 2 * (y * y + z * z)
    r[:, 0, 1] = 2 * (x * y - w * z)
    r[:, 0, 2] = 2 * (x * z + w * y)
    r[:, 1, 0] = 2 * (x * y + w * z)
    r[:, 1, 1] = 1 - 2 * (x * x + z * z)
    r[:, 1, 2] = 2 * (y * z - w * x)
    r[:, 2, 0] = 2 * (x * z - w * y)
    r[:, 2, 1] = 2 * (y * z + w * x)
    r[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """Quaternions from rotation matrices (Shepperd's method: stable for every rotation).

    Args:
        r: (N, 3, 3) rotation matrices.

    Returns:
        (N, 4) unit quaternions (w, x, y, z) with w >= 0.
    """
    m = np.asarray(r, dtype=np.float64)
    if m.ndim != 3 or m.shape[1:] != (3, 3):
        raise InputError(f"rotation matrices must have shape (N, 3, 3), got {m.shape}")
    m00, m01, m02 = m[:, 0, 0], m[:, 0, 1], m[:, 0, 2]
    m10, m11, m12 = m[:, 1, 0], m[:, 1, 1], m[:, 1, 2]
    m20, m21, m22 = m[:, 2, 0], m[:, 2, 1], m[:, 2, 2]
    # 4*w^2 - 1 = trace, 4*x^2 - 1 = m00 - m11 - m22, ...: build from the largest component.
    diag = np.stack([m00 + m11 + m22, m00 - m11 - m22, m11 - m00 - m22, m22 - m00 - m11], axis=1)
    pick = np.argmax(diag, axis=1)
    s = 2.0 * np.sqrt(np.maximum(1.0 + diag[np.arange(m.shape[0]), pick], 1e-300))
    cands = np.stack(
        [
            np.stack([s / 4, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s], axis=1),
            np.stack([(m21 - m12) / s, s / 4, (m01 + m10) / s, (m02 + m20) / s], axis=1),
            np.stack([(m02 - m20) / s, (m01 + m10) / s, s / 4, (m12 + m21) / s], axis=1),
            np.stack([(m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, s / 4], axis=1),
        ],
        axis=1,
    )
    q = cands[np.arange(m.shape[0]), pick]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1.0
    return q


def placement_matrices(
    rotations: np.ndarray, translations: np.ndarray, scales: np.ndarray
) -> np.ndarray:
    """Placement matrices [R(q) * s | t] taking object local frame to container frame.

    Args:
        rotations: (N, 4) quaternions (w, x, y, z).
        translations: (N, 3) container frame, container units.
        scales: (N,) uniform scales.

    Returns:
        (N, 4, 4) float64 homogeneous matrices.
    """
    q = np.asarray(rotations, dtype=np.float64).reshape(-1, 4)
    t = np.asarray(translations, dtype=np.float64).reshape(-1, 3)
    s = np.asarray(scales, dtype=np.float64).reshape(-1)
    if not q.shape[0] == t.shape[0] == s.shape[0]:
        raise InputError(
            f"rotations, translations and scales disagree on the number of objects: "
            f"{q.shape[0]}, {t.shape[0]}, {s.shape[0]}"
        )
    out = np.zeros((q.shape[0], 4, 4))
    out[:, :3, :3] = quat_to_matrix(q) * s[:, None, None]
    out[:, :3, 3] = t
    out[:, 3, 3] = 1.0
    return out


# --------------------------------------------------------------------------- result type


def _as_matrix4(value: Any, what: str) -> np.ndarray:
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what} must be a 4x4 matrix of numbers") from exc
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise InputError(f"{what} must be a finite 4x4 matrix, got shape {m.shape}")
    return m


@dataclass(eq=False)
class TypeRecord:
    """One object type of a packing.

    Attributes:
        name: type name (e.g. "lemon").
        path: absolute path of the mesh file, or None (e.g. a Blender object).
        sha256: hex digest of the mesh file, or None.
        share: target share (normalised over the packing's types).
        local_from_file: (4, 4) object local frame (volume centroid at origin, container
            units) from file coordinates.
        volume: exact mesh volume in the local frame (container units^3).
    """

    name: str
    path: str | None
    sha256: str | None
    share: float
    local_from_file: np.ndarray
    volume: float

    def __post_init__(self) -> None:
        self.local_from_file = _as_matrix4(
            self.local_from_file, f"type {self.name!r}: local_from_file"
        )
        self.share = float(self.share)
        self.volume = float(self.volume)


@dataclass(eq=False)
class Packing:
    """A packing: the container, the types and every placement, plus how it was made.

    Attributes:
        container_path: absolute path of the container mesh, or a spec string such as
            "box:43.4x41.8x45.0" (kept verbatim).
        container_sha256: hex digest of the container file, or None.
        frame_from_file: (4, 4) container frame from container file coordinates.
        container_volume: exact container mesh volume (container units^3).
        types: the object types, indexed by `type_index`.
        type_index: (N,) int64 type of each placed object.
        rotations: (N, 4) unit quaternions (w, x, y, z).
        translations: (N, 3) object local origins in the container frame (container units).
        scales: (N,) uniform scales, 1.0 in a finished packing.
        params, seed, metrics, timings, certificate: how it was made and how good it is
            (plain dicts; numpy values are converted when saved).
    """

    container_path: str
    container_sha256: str | None
    frame_from_file: np.ndarray
    container_volume: float
    types: list[TypeRecord]
    type_index: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    scales: np.ndarray
    params: dict = field(default_factory=dict)
    seed: int = 0
    metrics: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    certificate: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.frame_from_file = _as_matrix4(self.frame_from_file, "container frame_from_file")
        self.container_volume = float(self.container_volume)
        self.type_index = np.asarray(self.type_index, dtype=np.int64).reshape(-1)
        n = self.type_index.shape[0]
        for name, width in (("rotations", 4), ("translations", 3)):
            arr = np.asarray(getattr(self, name), dtype=np.float64)
            if arr.size == 0:
                arr = arr.reshape(0, width)
            if arr.shape != (n, width):
                raise InputError(f"{name} must have shape ({n}, {width}), got {arr.shape}")
            setattr(self, name, arr)
        self.scales = np.asarray(self.scales, dtype=np.float64).reshape(-1)
        if self.scales.shape != (n,):
            raise InputError(f"scales must have shape ({n},), got {self.scales.shape}")
        if n and (self.type_index.min() < 0 or self.type_index.max() >= len(self.types)):
            raise InputError(
                f"type_index values must be in [0, {len(self.types) - 1}] "
                f"({len(self.types)} types), got [{self.type_index.min()}, "
                f"{self.type_index.max()}]"
            )
        self.seed = int(self.seed)

    @property
    def n(self) -> int:
        """Number of placed objects N."""
        return int(self.type_index.shape[0])

    def matrices(self) -> np.ndarray:
        """(N, 4, 4) placement matrices [R * s | t], object local frame -> container frame."""
        return placement_matrices(self.rotations, self.translations, self.scales)


# --------------------------------------------------------------------------- helpers


def is_spec(path: str) -> bool:
    """True for a container spec string such as "box:43.4x41.8x45.0" (not a file path)."""
    return bool(_SPEC_RE.match(path))


def container_mesh(packing: Packing, action: str = "load"):
    """The container mesh a packing names (a box spec or a mesh file), in its file frame.

    Raises InputError for other specs (e.g. a container that came from Blender), MeshError
    for an unusable file. ``action`` words the error ("draw", "export").
    """
    from .meshes import box_mesh, load_mesh, parse_box_spec

    spec = packing.container_path
    if is_spec(spec):
        box = parse_box_spec(spec)
        if box is None:
            raise InputError(f"cannot {action} the container {spec!r}: only box:AxBxC specs "
                             "and mesh files are known")
        return box_mesh(box)
    return load_mesh(spec, role="container")


def file_sha256(path: str | os.PathLike) -> str:
    """Hex sha256 digest of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


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
    (e.g. another drive on Windows)."""
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

    Mesh paths are stored relative to the JSON file's directory; spec strings verbatim.
    Raises InputError if `path` is the container or a type mesh file (inputs are never
    overwritten), if its directory does not exist, or if a value cannot be written.
    """
    out = os.path.abspath(os.fspath(path))
    out_dir = os.path.dirname(out)
    if not os.path.isdir(out_dir):
        raise InputError(
            f"cannot write packing {out}: folder {out_dir} does not exist; create it first"
        )
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

    mats = packing.matrices()
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "container": {
            "path": rel(packing.container_path),
            "sha256": packing.container_sha256,
            "frame_from_file": _matrix_list(packing.frame_from_file),
            "volume": float(packing.container_volume),
        },
        "types": [
            {
                "name": t.name,
                "path": rel(t.path),
                "sha256": t.sha256,
                "share": float(t.share),
                "local_from_file": _matrix_list(t.local_from_file),
                "volume": float(t.volume),
            }
            for t in packing.types
        ],
        "placements": [
            {
                "type": int(packing.type_index[i]),
                "matrix": _matrix_list(mats[i]),
                "rotation": [float(x) for x in packing.rotations[i]],
                "translation": [float(x) for x in packing.translations[i]],
                "scale": float(packing.scales[i]),
            }
            for i in range(packing.n)
        ],
        "params": to_jsonable(packing.params, "params"),
        "seed": int(packing.seed),
        "metrics": to_jsonable(packing.metrics, "metrics"),
        "timings": to_jsonable(packing.timings, "timings"),
        "certificate": to_jsonable(packing.certificate, "certificate"),
    }
    text = _NUMBER_LIST_RE.sub(_one_line, json.dumps(doc, indent=1, allow_nan=False)) + "\n"
    _atomic_write_text(out, text)


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

    def fail(self, msg: str) -> InputError:
        return InputError(f"packing file {self.path}: {msg}")

    def get(self, obj: Any, key: str, where: str) -> Any:
        if not isinstance(obj, dict):
            raise self.fail(f"{where} must be a JSON object")
        if key not in obj:
            raise self.fail(f"missing field {where}.{key}" if where else f"missing field {key}")
        return obj[key]

    def number(self, value: Any, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"{where} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise self.fail(f"{where} must be finite, got {value!r}")
        return float(value)

    def integer(self, value: Any, where: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(f"{where} must be an integer, got {value!r}")
        return value

    def opt_str(self, value: Any, where: str) -> str | None:
        if value is not None and not isinstance(value, str):
            raise self.fail(f"{where} must be a string or null, got {value!r}")
        return value

    def vector(self, value: Any, size: int, where: str) -> np.ndarray:
        if (
            not isinstance(value, list)
            or len(value) != size
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in value)
        ):
            raise self.fail(f"{where} must be a list of {size} numbers, got {value!r}")
        arr = np.array(value, dtype=np.float64)
        if not np.all(np.isfinite(arr)):
            raise self.fail(f"{where} must be finite, got {value!r}")
        return arr

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


def _resolve(p: str | None, base_dir: str) -> str | None:
    if p is None or is_spec(p) or os.path.isabs(p):
        return p
    return os.path.normpath(os.path.join(base_dir, p))


def load_packing(path: str | os.PathLike) -> Packing:
    """Read a packing JSON file written by `save_packing`.

    Relative mesh paths are resolved against the JSON file's directory into absolute paths.
    Raises InputError, naming the file, if it cannot be read or parsed, has another format or
    a newer version, or lacks a field / holds a bad value (matrix shape, type index, a
    placement matrix that disagrees with its rotation/translation/scale, ...).
    """
    src = os.path.abspath(os.fspath(path))
    r = _Reader(src)
    try:
        with open(src, encoding="utf-8") as f:
            doc = json.load(f)
    except OSError as exc:
        raise InputError(f"cannot read packing file {src}: {exc.strerror or exc}") from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise r.fail(f"not valid JSON ({exc}); was it truncated or edited?") from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise r.fail(f"not a jampacked packing (format is {found!r}, expected {FORMAT!r})")
    version = r.integer(r.get(doc, "version", ""), "version")
    if version > VERSION:
        raise r.fail(
            f"written by a newer jampacked (version {version}); this one reads version "
            f"{VERSION}: upgrade jampacked"
        )
    if version < 1:
        raise r.fail(f"invalid version {version}")
    base_dir = os.path.dirname(src)

    cont = r.dict_(r.get(doc, "container", ""), "container")
    cpath = r.get(cont, "path", "container")
    if not isinstance(cpath, str) or not cpath:
        raise r.fail("container.path must be a non-empty string")
    container_path = _resolve(cpath, base_dir)
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
                path=_resolve(r.opt_str(r.get(t, "path", w), f"{w}.path"), base_dir),
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
    type_index = np.zeros(n, dtype=np.int64)
    rotations = np.zeros((n, 4))
    translations = np.zeros((n, 3))
    scales = np.zeros(n)
    matrices = np.zeros((n, 4, 4))
    for i, p in enumerate(raw_pl):
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
        params=r.dict_(r.get(doc, "params", ""), "params"),
        seed=r.integer(r.get(doc, "seed", ""), "seed"),
        metrics=r.dict_(r.get(doc, "metrics", ""), "metrics"),
        timings=r.dict_(r.get(doc, "timings", ""), "timings"),
        certificate=r.dict_(r.get(doc, "certificate", ""), "certificate"),
    )


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
    for label, p, sha in entries:
        if p is None:
            continue
        if not os.path.isfile(p):
            problems.append(f"{label}: mesh file {p} is missing; restore it or re-run the packing")
            continue
        if sha is None:
            continue
        try:
            actual = file_sha256(p)
        except OSError as exc:
            problems.append(f"{label}: cannot read mesh file {p} ({exc.strerror or exc})")
            continue
        if actual.lower() != sha.lower():
            problems.append(
                f"{label}: mesh file {p} has changed since the packing was made "
                f"(sha256 {actual[:12]}... but the packing records {sha[:12]}...); "
                "re-run the packing or restore the original file"
            )
    return problems
