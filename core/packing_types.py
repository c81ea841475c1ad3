"""The packing result types: the container, the object types and every placement.

Frames (container units, e.g. mm, throughout):
- container frame: `frame_from_file @ v_file` maps container file coordinates into it.
- object local frame of a type: `local_from_file @ v_file` (volume centroid at the origin).
- a placed object's vertices in the container frame: `matrix @ local_from_file @ v_file`, with
  `matrix = [R(q) * s | t]` from its rotation q (unit quaternion w, x, y, z), scale s and
  translation t.

Its JSON file: `core/packing_json.py`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import InputError
from .report import PackInputs, RunReport
from .rotations import placement_matrices

#: A container spec like "box:43.4x41.8x45.0": a word of 2+ characters then a colon (two or
#: more characters so that Windows drive letters such as "C:" are not taken for specs).
_SPEC_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]+:")


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
        inputs: what `pack()` was asked for (clearance, budget, scales, options).
        report: what the run did (attempts, repair, margins, threads, warnings, ...).
        seed: the random seed.
        metrics, timings, certificate: how good it is and how long it took (plain dicts;
            numpy values are converted when saved).
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
    inputs: PackInputs = field(default_factory=PackInputs)
    report: RunReport = field(default_factory=RunReport)
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


def distinct_names(stems: list[str]) -> list[str]:
    """The type names given these file stems: a stem that repeats an earlier name followed
    by "-2", "-3"... (the names `pack` gives types read from files)."""
    out: list[str] = []
    for stem in stems:
        name, k = stem, 1
        while name in out:
            k += 1
            name = f"{stem}-{k}"
        out.append(name)
    return out
