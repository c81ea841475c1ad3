"""Load, check, repair and normalise triangle meshes.

Every mesh that enters jampacked goes through :func:`load_mesh` (or is made by
:func:`box_mesh`). The result, :class:`MeshData`, is guaranteed to be

* closed: every undirected edge is used by exactly two faces,
* 2-manifold along edges and consistently wound: every directed edge is used once,
* outward wound (counter-clockwise seen from outside), with positive volume,
* a single body (one edge-connected surface),
* accepted by manifold3d (``Manifold.status() == Error.NoError``).

Self-intersections are *not* detected here (manifold3d's status does not report them).

Units and frame are the file's own: nothing is scaled, rotated or moved. Vertices at identical
positions (or within 1e-9 of the bounding-box diagonal) are merged silently: Blender and
other tools split vertices at UV seams and STL stores a triangle soup, which is not a defect.
Unreferenced vertices are dropped silently.

Repairs (degenerate faces, duplicate faces, zero-volume sliver bodies, faces with reversed
winding, inside-out meshes) are recorded in :attr:`MeshData.warnings` as full sentences
naming the file, and each is also emitted once through the standard :mod:`logging` module at
level WARNING on the logger ``jampacked.core.meshes`` (this module's ``__name__``) when the
load succeeds. Front ends show them from ``MeshData.warnings``; scripts see them on stderr
through logging's last-resort handler unless they configure logging. Defects that cannot be
repaired safely raise :class:`~jampacked.core.errors.MeshError` with a message that names the
file, the defect with counts, and a fix.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import logging
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import manifold3d
import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError, cKDTree

from .errors import InputError, MeshError
from .solids import to_solid

__all__ = [
    "MeshData",
    "box_mesh",
    "file_sha256",
    "load_mesh",
    "mesh_volume_centroid",
    "parse_box_spec",
]

logger = logging.getLogger(__name__)

ROLES = ("object", "container")

# Vertices closer than this fraction of the bounding-box diagonal are the same vertex.
MERGE_TOLERANCE = 1e-9
# A face whose height is below MERGE_TOLERANCE * diagonal is degenerate (zero area).
# A connected piece whose area is below this fraction of the total area is a sliver.
SLIVER_AREA_FRACTION = 1e-6
# A closed body whose |volume| is below this fraction of the largest body's is a sliver.
SLIVER_VOLUME_FRACTION = 1e-6
# A mesh whose |volume| is below this fraction of diagonal**3 has zero volume.
ZERO_VOLUME_FRACTION = 1e-12
# Thin-wall container test: mean wall thickness 2V/A relative to the convex hull's size
# (cube root of its volume), and the share of the convex hull the solid fills. The shared
# test containers are >= 0.13 and >= 0.27; a 2 mm vase wall is 0.03 and 0.14.
THIN_WALL_THICKNESS = 0.08
THIN_WALL_HULL_FILL = 0.5

_BOX_SPEC = re.compile(r"^\s*box\s*:", re.IGNORECASE)
_OBJ_FACE_COMMENT = re.compile(rb"^[ \t]*f[ \t][^\n#]*#", re.MULTILINE)


# --------------------------------------------------------------------------------------------
# result type


@dataclass(frozen=True, eq=False)
class MeshData:
    """A checked triangle mesh: closed, 2-manifold, outward wound, one body, volume > 0.

    Attributes:
        vertices: (V, 3) float64, read-only; positions in the file's units and frame.
        faces: (F, 3) int64, read-only; vertex indices, counter-clockwise seen from outside.
        path: the file it came from, as given; None for generated meshes.
        sha256: sha256 hex digest of the file's bytes; None for generated meshes.
        volume: exact signed volume in file units cubed (> 0).
        warnings: repairs made while loading, each a full sentence naming the file.

    Equality and hashing are by identity (arrays do not compare as booleans).
    """

    vertices: np.ndarray
    faces: np.ndarray
    path: str | None
    sha256: str | None
    volume: float
    warnings: tuple[str, ...] = ()

    @property
    def extents(self) -> np.ndarray:
        """(3,) float64: axis-aligned bounding-box size in file units."""
        return self.vertices.max(axis=0) - self.vertices.min(axis=0)

    @cached_property
    def centroid(self) -> np.ndarray:
        """(3,) float64: volume centroid (centre of mass at uniform density), file frame."""
        return mesh_volume_centroid(self.vertices, self.faces)[1]


def _frozen(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


# --------------------------------------------------------------------------------------------
# small public helpers


def file_sha256(path: str | os.PathLike) -> str:
    """Return the sha256 hex digest of the bytes of the file at ``path``.

    Raises:
        MeshError: the file does not exist or cannot be read.
    """
    data = _read_bytes(os.fspath(path), "mesh")
    return hashlib.sha256(data).hexdigest()


def mesh_volume_centroid(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray]:
    """Exact signed volume and volume centroid of a closed triangle mesh (divergence theorem).

    Args:
        vertices: (V, 3) positions, any units.
        faces: (F, 3) vertex indices; outward (counter-clockwise) winding gives volume > 0.

    Returns:
        ``(volume, centroid)``: volume in units cubed (negative for an inside-out mesh) and the
        (3,) float64 centroid in the vertices' frame. The sum of signed tetrahedra is taken
        about the bounding-box centre for precision. If the volume is zero the centroid is
        undefined and the bounding-box centre is returned.
    """
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0 or len(vertices) == 0:
        return 0.0, np.zeros(3)
    origin = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    tri = vertices[faces] - origin
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    six_vol = np.einsum("ij,ij->i", a, np.cross(b, c))
    volume = float(six_vol.sum() / 6.0)
    if volume == 0.0:
        return 0.0, origin
    centroid = (six_vol[:, None] * (a + b + c)).sum(axis=0) / (24.0 * volume) + origin
    return volume, centroid


def box_mesh(extents: Sequence[float]) -> MeshData:
    """A closed box centred at the origin: 8 vertices, 12 outward-wound triangles.

    Args:
        extents: (3,) positive side lengths along x, y, z, in the scene's units.

    Raises:
        InputError: not three finite positive numbers.
    """
    try:
        ext = np.asarray(extents, dtype=np.float64).reshape(3)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"box extents {extents!r} are not three numbers: give width, depth and height, "
            "e.g. (40, 40, 45)."
        ) from exc
    if not np.all(np.isfinite(ext)) or np.any(ext <= 0):
        raise InputError(
            f"box extents {tuple(float(x) for x in ext)} must be finite and positive: "
            "give width, depth and height greater than zero."
        )
    corners = np.array(
        [[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    )
    vertices = corners * ext
    # corner index = 4*ix + 2*iy + iz
    faces = np.array(
        [
            [0, 1, 3], [0, 3, 2],  # x = -
            [4, 6, 7], [4, 7, 5],  # x = +
            [0, 4, 5], [0, 5, 1],  # y = -
            [2, 3, 7], [2, 7, 6],  # y = +
            [0, 2, 6], [0, 6, 4],  # z = -
            [1, 5, 7], [1, 7, 3],  # z = +
        ],
        dtype=np.int64,
    )
    volume = float(np.prod(ext))
    return MeshData(_frozen(vertices), _frozen(faces), None, None, volume, ())


def parse_box_spec(spec: str) -> tuple[float, float, float] | None:
    """Parse a box specification ``"box:WxDxH"`` (e.g. ``"box:43.4338x41.8435x45.0059"``).

    Returns:
        The three side lengths (scene units) as floats, or None if ``spec`` does not start
        with ``box:`` (case-insensitive), i.e. it is presumably a file path.

    Raises:
        InputError: it starts with ``box:`` but is not three finite positive numbers
        separated by ``x``.
    """
    if not isinstance(spec, str) or not _BOX_SPEC.match(spec):
        return None
    body = spec.split(":", 1)[1].strip()
    parts = re.split(r"\s*[xX×]\s*", body)
    values: list[float] = []
    try:
        if len(parts) != 3:
            raise ValueError
        values = [float(p) for p in parts]
    except ValueError:
        raise InputError(
            f"box spec {spec!r} is malformed: write box:WIDTHxDEPTHxHEIGHT with three numbers, "
            "e.g. box:40x40x45."
        ) from None
    if not all(math.isfinite(v) and v > 0 for v in values):
        raise InputError(
            f"box spec {spec!r} has a side that is zero, negative or not finite: "
            "all three sides must be positive, e.g. box:40x40x45."
        )
    return values[0], values[1], values[2]


# --------------------------------------------------------------------------------------------
# reading


def _read_bytes(path: str, role: str) -> bytes:
    p = Path(path)
    if not p.exists():
        raise MeshError(
            f"{role.capitalize()} mesh file '{path}' does not exist: check the path "
            "(relative paths are resolved from the current folder)."
        )
    if p.is_dir():
        raise MeshError(
            f"{role.capitalize()} mesh path '{path}' is a folder, not a file: "
            "give the mesh file itself (e.g. .stl, .obj, .ply)."
        )
    try:
        return p.read_bytes()
    except OSError as exc:
        raise MeshError(
            f"{role.capitalize()} mesh file '{path}' cannot be read ({exc.strerror or exc}): "
            "check its permissions, or copy it somewhere readable."
        ) from exc


def _extension(path: str) -> str:
    name = Path(path).name.lower()
    for compound in ("dato.gz", "post.gz", "vol.gz"):
        if name.endswith("." + compound):
            return compound
    return Path(name).suffix.lstrip(".")


def _trimesh_arrays(loaded: object) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(loaded, trimesh.Scene):
        geometries = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
        loaded = trimesh.util.concatenate(geometries) if geometries else trimesh.Trimesh()
    vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    faces = getattr(loaded, "faces", None)
    faces = np.zeros((0, 3), np.int64) if faces is None else np.asarray(faces, dtype=np.int64)
    return vertices.reshape(-1, 3), faces.reshape(-1, 3)


def _meshio_arrays(path: str) -> tuple[np.ndarray, np.ndarray]:
    import meshio

    # meshio prints to stdout/stderr and calls sys.exit(1) when no reader succeeds
    sink = io.StringIO()
    try:
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            mesh = meshio.read(path)
    except SystemExit:
        message = " ".join(sink.getvalue().split()) or "no reader succeeded"
        raise ValueError(message) from None
    tris = []
    for block in mesh.cells:
        data = np.asarray(block.data, dtype=np.int64)
        if block.type == "triangle":
            tris.append(data)
        elif block.type == "quad":
            tris.append(data[:, [0, 1, 2]])
            tris.append(data[:, [0, 2, 3]])
    faces = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim == 2 and points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    return points.reshape(-1, 3), faces


def _strip_obj_comments(data: bytes) -> bytes:
    return b"\n".join(line.split(b"#", 1)[0] for line in data.splitlines())


def _read_arrays(path: str, data: bytes, label: str) -> tuple[np.ndarray, np.ndarray]:
    """Read vertices and triangles: trimesh, tolerant OBJ, then meshio."""
    ext = _extension(path)
    trimesh_formats = set(trimesh.available_formats())
    import meshio

    meshio_formats = {e.lstrip(".") for e in meshio.extension_to_filetypes}
    if ext not in trimesh_formats and ext not in meshio_formats:
        shown = ", ".join(sorted({"stl", "obj", "ply", "off", "glb", "gltf"} & trimesh_formats))
        raise MeshError(
            f"{label} has an unknown file type '.{ext}' (no reader for it): "
            f"export it as one of {shown} (or another format meshio reads)."
        )
    errors: list[str] = []
    if ext == "obj" and _OBJ_FACE_COMMENT.search(data):
        # trimesh's OBJ reader fails on comments at the end of face lines.
        data = _strip_obj_comments(data)
        logger.debug("%s: comments on face lines ignored", label)
        try:
            loaded = trimesh.load(io.BytesIO(data), file_type="obj", force="mesh", process=False)
            return _trimesh_arrays(loaded)
        except Exception as exc:  # noqa: BLE001 - any reader failure falls through
            errors.append(f"trimesh: {exc}")
    elif ext in trimesh_formats:
        # materials and textures are not needed: skip them (and missing .mtl files quietly)
        extra = {"skip_materials": True} if ext in ("obj", "glb", "gltf") else {}
        try:
            return _trimesh_arrays(trimesh.load(path, force="mesh", process=False, **extra))
        except Exception as exc:  # noqa: BLE001
            errors.append(f"trimesh: {exc}")
        if ext == "obj":
            try:
                loaded = trimesh.load(
                    io.BytesIO(_strip_obj_comments(data)),
                    file_type="obj",
                    force="mesh",
                    process=False,
                )
                return _trimesh_arrays(loaded)
            except Exception as exc:  # noqa: BLE001
                errors.append(f"tolerant OBJ reader: {exc}")
    if ext in meshio_formats:
        try:
            return _meshio_arrays(path)
        except Exception as exc:  # noqa: BLE001
            errors.append(f"meshio: {exc}")
    detail = "; ".join(e.strip().replace("\n", " ")[:200] for e in errors)
    raise MeshError(
        f"{label} cannot be read as a .{ext} file ({detail}): the file is damaged or not "
        f"really .{ext}; export it again from your modelling tool, e.g. as binary STL or PLY."
    )


def _obj_malformed_polygons(data: bytes, limit: int = 3) -> list[str]:
    """Describe OBJ polygon lines (4 or more corners) that list the same vertex twice.

    Such a polygon has no well-defined surface: any triangulation of it is a guess. A
    triangle with a repeated vertex is merely degenerate and is removed as a repair.
    """
    found = []
    for number, raw in enumerate(data.splitlines(), start=1):
        line = raw.split(b"#", 1)[0].strip()
        if not (line.startswith(b"f ") or line.startswith(b"f\t")):
            continue
        refs = [t.split(b"/", 1)[0] for t in line.split()[1:]]
        if len(refs) < 4 or len(set(refs)) == len(refs):
            continue
        seen: set[bytes] = set()
        repeated = next(r for r in refs if r in seen or seen.add(r))
        text = line.decode("utf-8", "replace")
        found.append(
            f"line {number} ('{text}') lists vertex {repeated.decode('utf-8', 'replace')} twice"
        )
        if len(found) >= limit:
            break
    return found


# --------------------------------------------------------------------------------------------
# topology helpers (vectorised)


def _directed_edges(faces: np.ndarray) -> np.ndarray:
    """(3F, 2) directed edges; half-edge h belongs to face h // 3."""
    return faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)


def _edge_keys(edges: np.ndarray, n_vertices: int, directed: bool) -> np.ndarray:
    n = np.int64(max(n_vertices, 1))
    if directed:
        return edges[:, 0] * n + edges[:, 1]
    return np.minimum(edges[:, 0], edges[:, 1]) * n + np.maximum(edges[:, 0], edges[:, 1])


@dataclass
class _Edges:
    directed: np.ndarray  # (3F, 2)
    inverse: np.ndarray  # (3F,) undirected edge id of each half-edge
    counts: np.ndarray  # (E,) faces using each undirected edge
    directed_dup: int  # directed edges used more than once


def _edges(faces: np.ndarray, n_vertices: int) -> _Edges:
    directed = _directed_edges(faces)
    _, inverse, counts = np.unique(
        _edge_keys(directed, n_vertices, False), return_inverse=True, return_counts=True
    )
    _, dcounts = np.unique(_edge_keys(directed, n_vertices, True), return_counts=True)
    return _Edges(directed, inverse.reshape(-1), counts, int(np.sum(dcounts > 1)))


def _face_components(faces: np.ndarray, edges: _Edges) -> tuple[int, np.ndarray]:
    """Label faces by edge-connected component (faces sharing an edge are connected)."""
    n_faces = len(faces)
    if n_faces == 0:
        return 0, np.zeros(0, np.int64)
    n_edges = len(edges.counts)
    rows = np.repeat(np.arange(n_faces), 3)
    cols = edges.inverse + n_faces
    graph = coo_matrix(
        (np.ones(len(rows), np.int8), (rows, cols)), shape=(n_faces + n_edges,) * 2
    )
    _, labels = connected_components(graph, directed=False)
    labels = labels[:n_faces]
    uniq, labels = np.unique(labels, return_inverse=True)
    return len(uniq), labels.reshape(-1)


def _boundary_loops(edges: _Edges, n_vertices: int) -> int:
    """Number of holes: connected groups of boundary edges (edges used by one face)."""
    boundary_half = np.flatnonzero(edges.counts[edges.inverse] == 1)
    if len(boundary_half) == 0:
        return 0
    e = edges.directed[boundary_half]
    used, local = np.unique(e, return_inverse=True)
    local = local.reshape(-1, 2)
    graph = coo_matrix(
        (np.ones(len(local), np.int8), (local[:, 0], local[:, 1])), shape=(len(used),) * 2
    )
    return int(connected_components(graph, directed=False)[0])


def sample_surface(vertices: np.ndarray, faces: np.ndarray, n: int,
                   seed: int = 0) -> np.ndarray:
    """(n, 3) points uniformly distributed by area over a triangle mesh (seeded)."""
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(faces), size=n, p=area / area.sum())
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    t = tri[pick]
    return (t[:, 0] * (1 - r1)[:, None] + t[:, 1] * (r1 * (1 - r2))[:, None]
            + t[:, 2] * (r1 * r2)[:, None])


def _face_areas2(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = vertices[faces]
    return np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def _signed_six_volumes(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    origin = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    tri = vertices[faces] - origin
    return np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))


# --------------------------------------------------------------------------------------------
# repair steps


def _merge_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge identical positions, then positions within MERGE_TOLERANCE * diagonal.

    Keeps the order of first occurrence. Faces are re-indexed; nothing is removed here.
    """
    if len(vertices) == 0:
        return vertices, faces
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    vertices = vertices[first[order]]
    faces = rank[inverse.reshape(-1)][faces]
    diagonal = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    tol = MERGE_TOLERANCE * diagonal
    if tol > 0 and len(vertices) > 1:
        pairs = cKDTree(vertices).query_pairs(tol, output_type="ndarray")
        if len(pairs):
            n = len(vertices)
            graph = coo_matrix(
                (np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n)
            )
            _, labels = connected_components(graph, directed=False)
            _, first, labels = np.unique(labels, return_index=True, return_inverse=True)
            order = np.argsort(first)
            rank = np.empty_like(order)
            rank[order] = np.arange(len(order))
            vertices = vertices[first[order]]
            faces = rank[labels.reshape(-1)][faces]
    return vertices, faces


def _split_needles(
    vertices: np.ndarray, faces: np.ndarray, needle: np.ndarray
) -> tuple[np.ndarray, int]:
    """Remove zero-area faces with three distinct vertices, keeping the surface closed.

    A needle (a, b, c) has c on the segment ab. The face across edge ab is split at c,
    which closes the gap the needle leaves (a T-junction repair). Needles whose neighbour
    cannot be found (open or non-manifold there) are left in place.
    """
    faces = faces.copy()
    alive = np.ones(len(faces), bool)
    extra: list[np.ndarray] = []
    removed = 0
    for index in np.flatnonzero(needle):
        if not alive[index]:
            continue
        face = faces[index]
        tri = vertices[face]
        lengths = np.linalg.norm(tri[[1, 2, 0]] - tri, axis=1)  # edge k: face[k] -> face[k+1]
        k = int(np.argmax(lengths))
        a, b, c = face[k], face[(k + 1) % 3], face[(k + 2) % 3]
        # the neighbour holds the directed edge b -> a
        cand = np.flatnonzero(
            alive
            & (((faces[:, 0] == b) & (faces[:, 1] == a))
               | ((faces[:, 1] == b) & (faces[:, 2] == a))
               | ((faces[:, 2] == b) & (faces[:, 0] == a)))
        )
        cand = cand[cand != index]
        if len(cand) != 1 or needle[cand[0]]:
            continue
        other = faces[cand[0]]
        j = int(np.flatnonzero(other == b)[0])
        d = other[(j + 2) % 3]
        if d == c:
            continue
        alive[index] = False
        alive[cand[0]] = False
        extra.append(np.array([[b, c, d], [c, a, d]], dtype=np.int64))
        removed += 1
    if extra:
        faces = np.concatenate([faces[alive], *extra])
    else:
        faces = faces[alive]
    return faces, removed


def _remove_duplicates(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, int, int]:
    """Drop repeated faces. Returns (faces, same-orientation copies, opposite pairs removed).

    Faces on the same three vertices are grouped; copies with the same orientation collapse
    to one, and a face and its reverse cancel (together they are a zero-volume sliver).
    """
    srt = np.sort(faces, axis=1)
    if n_vertices < 2_000_000:  # n**3 fits in int64
        n = np.int64(max(n_vertices, 1))
        keys = (srt[:, 0] * n + srt[:, 1]) * n + srt[:, 2]
        _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    else:
        _, inverse, counts = np.unique(srt, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    if np.all(counts == 1):
        return faces, 0, 0
    # orientation sign: rotate the smallest index first, then compare the other two
    rot = np.argmin(faces, axis=1)
    second = faces[np.arange(len(faces)), (rot + 1) % 3]
    third = faces[np.arange(len(faces)), (rot + 2) % 3]
    sign = np.where(second < third, 1, -1)
    keep = np.ones(len(faces), bool)
    same = opposite = 0
    for group in np.flatnonzero(counts > 1):
        members = np.flatnonzero(inverse == group)
        plus = members[sign[members] > 0]
        minus = members[sign[members] < 0]
        pairs = min(len(plus), len(minus))
        opposite += pairs
        rest = plus[pairs:] if len(plus) > len(minus) else minus[pairs:]
        same += max(len(rest) - 1, 0)
        keep[members] = False
        if len(rest):
            keep[rest[0]] = True
    return faces[keep], same, opposite


def _orient(
    faces: np.ndarray, edges: _Edges, labels: np.ndarray, n_comp: int
) -> tuple[np.ndarray | None, int, int]:
    """Make winding consistent per component, flipping the minority of faces.

    Requires every undirected edge to be used by exactly two faces.
    Returns (faces or None if non-orientable, faces flipped, faces in non-orientable parts).
    """
    n_faces = len(faces)
    order = np.argsort(edges.inverse, kind="stable")
    h1, h2 = order[0::2], order[1::2]
    f1, f2 = h1 // 3, h2 // 3
    same_direction = edges.directed[h1, 0] == edges.directed[h2, 0]
    if not np.any(same_direction):
        return faces, 0, 0
    # double cover: node f is "face kept", node f + F is "face flipped"
    a = np.where(same_direction, f2 + n_faces, f2)
    b = np.where(same_direction, f2, f2 + n_faces)
    rows = np.concatenate([f1, f1 + n_faces])
    cols = np.concatenate([a, b])
    graph = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(2 * n_faces,) * 2)
    _, cover = connected_components(graph, directed=False)
    bad = cover[:n_faces] == cover[n_faces:]
    if np.any(bad):
        return None, 0, int(np.sum(bad))
    _, roots = np.unique(labels, return_index=True)
    flip = cover[:n_faces] != cover[roots[labels]]
    flipped_per = np.bincount(labels, weights=flip, minlength=n_comp)
    size = np.bincount(labels, minlength=n_comp)
    invert = flipped_per * 2 > size
    flip ^= invert[labels]
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out, int(np.sum(flip)), 0


def _count_nested(
    vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray, n_comp: int
) -> int:
    """Number of components whose bounding box lies inside another component's box."""
    if n_comp > 2000:
        return 0
    tri = vertices[faces]
    lo = np.full((n_comp, 3), np.inf)
    hi = np.full((n_comp, 3), -np.inf)
    np.minimum.at(lo, labels, tri.min(axis=1))
    np.maximum.at(hi, labels, tri.max(axis=1))
    inside = np.all(lo[None, :, :] <= lo[:, None, :], axis=2) & np.all(
        hi[:, None, :] <= hi[None, :, :], axis=2
    )  # inside[k, j]: box k within box j
    np.fill_diagonal(inside, False)
    return int(np.sum(inside.any(axis=1)))


def _compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    used = np.zeros(len(vertices), bool)
    used[faces.ravel()] = True
    if np.all(used):
        return vertices, faces
    remap = np.cumsum(used) - 1
    return vertices[used], remap[faces]


def _closed_manifold_problems(faces: np.ndarray, n_vertices: int) -> list[str]:
    """Own edge-use count: every edge used by two faces, every directed edge once."""
    edges = _edges(faces, n_vertices)
    problems = []
    if np.any(edges.counts == 1):
        problems.append(f"{int(np.sum(edges.counts == 1))} edges used by one face")
    if np.any(edges.counts > 2):
        problems.append(f"{int(np.sum(edges.counts > 2))} edges used by more than two faces")
    if edges.directed_dup:
        problems.append(f"{edges.directed_dup} directed edges used twice")
    return problems


def _manifold_status(vertices: np.ndarray, faces: np.ndarray) -> manifold3d.Error:
    return to_solid(vertices, faces, double=False).status()


# --------------------------------------------------------------------------------------------
# the pipeline


def _cap(text: str) -> str:
    return text[:1].upper() + text[1:]


def _plural(n: int, word: str, plural: str | None = None) -> str:
    return f"{n} {word if n == 1 else (plural or word + 's')}"


def _check_and_repair(
    vertices: np.ndarray,
    faces: np.ndarray,
    label: str,
    role: str,
    obj_data: bytes | None = None,
) -> tuple[np.ndarray, np.ndarray, float, tuple[str, ...]]:
    """Run every check and safe repair; return (vertices, faces, volume, warnings).

    ``obj_data``: the raw bytes of an OBJ file, to name malformed polygons in errors.
    """
    warns: list[str] = []
    cap = _cap(label)
    fix_reexport = "re-export it from your modelling tool as a closed solid"

    if len(faces) == 0 or len(vertices) == 0:
        raise MeshError(
            f"{cap} contains no triangles (it is empty, a point cloud or only lines): "
            "export the surface of a solid (faces), e.g. as STL or PLY."
        )
    if not np.all(np.isfinite(vertices)):
        bad = int(np.sum(~np.all(np.isfinite(vertices), axis=1)))
        raise MeshError(
            f"{cap} has {_plural(bad, 'vertex', 'vertices')} with NaN or infinite coordinates: "
            f"{fix_reexport}."
        )
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(
            f"{cap} has faces that refer to vertices that do not exist: the file is damaged; "
            f"{fix_reexport}."
        )

    raw_repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (
        faces[:, 2] == faces[:, 0]
    )
    if obj_data is not None and np.any(raw_repeated):
        malformed = _obj_malformed_polygons(obj_data)
        if malformed:
            raise MeshError(
                f"{cap} has malformed polygons: {'; '.join(malformed)}, so the surface that "
                "face stands for is unknown (any triangulation of it leaves a hole or a "
                "spike). Fix: correct those face lines so that each lists its corners once, "
                "in order around the face, or re-export the mesh."
            )

    vertices, faces = _merge_vertices(vertices, faces)
    diagonal = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))

    # degenerate faces: repeated vertex, or zero area (a needle: one vertex on the opposite edge)
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (
        faces[:, 2] == faces[:, 0]
    )
    n_degenerate = int(np.sum(repeated))
    faces = faces[~repeated]
    if len(faces):
        tri = vertices[faces]
        longest = np.linalg.norm(tri[:, [1, 2, 0]] - tri, axis=2).max(axis=1)
        height = _face_areas2(vertices, faces) / np.maximum(longest, np.finfo(float).tiny)
        needle = height <= MERGE_TOLERANCE * diagonal
        if np.any(needle):
            faces, fixed = _split_needles(vertices, faces, needle)
            n_degenerate += fixed
    if n_degenerate:
        warns.append(
            f"{cap}: removed {_plural(n_degenerate, 'degenerate face')} (zero area)."
        )

    faces, n_same, n_opposite = _remove_duplicates(faces, len(vertices))
    if n_same:
        warns.append(f"{cap}: removed {_plural(n_same, 'duplicate face')}.")

    if len(faces) == 0:
        raise MeshError(
            f"{cap} has zero volume: all its faces are degenerate or cancel out. "
            f"Check that the right file was exported; {fix_reexport}."
        )

    # zero-area pieces (slivers) by edge-connected component
    edges = _edges(faces, len(vertices))
    n_comp, labels = _face_components(faces, edges)
    areas = _face_areas2(vertices, faces)
    comp_area = np.bincount(labels, weights=areas, minlength=n_comp)
    sliver_comp = comp_area <= SLIVER_AREA_FRACTION * comp_area.sum()
    if n_opposite:
        warns.append(
            f"{cap}: removed {_plural(n_opposite, 'zero-volume sliver')} (pairs of coincident "
            f"faces facing opposite ways, {_plural(2 * n_opposite, 'face')} in all)."
        )
    n_sliver_bodies = n_sliver_faces = 0
    if np.any(sliver_comp) and not np.all(sliver_comp):
        drop = sliver_comp[labels]
        n_sliver_bodies += int(np.sum(sliver_comp))
        n_sliver_faces += int(np.sum(drop))
        faces = faces[~drop]
        edges = _edges(faces, len(vertices))
        n_comp, labels = _face_components(faces, edges)

    # closed and manifold along edges?
    n_open = int(np.sum(edges.counts == 1))
    n_nonmanifold = int(np.sum(edges.counts > 2))
    if n_open or n_nonmanifold:
        defects = []
        fixes = []
        if n_open:
            holes = _boundary_loops(edges, len(vertices))
            defects.append(
                f"it is not closed ({_plural(n_open, 'open boundary edge')} "
                f"around {_plural(holes, 'hole')})"
            )
            fixes.append(
                "fill the holes (Blender: Select > Select All by Trait > Non Manifold, then "
                "Face > Fill, or the 3D-Print Toolbox's Make Manifold; MeshLab: Close Holes)"
            )
        if n_nonmanifold:
            defects.append(
                f"it has {_plural(n_nonmanifold, 'non-manifold edge')}, each used by more than "
                "two faces (internal faces, or bodies that touch along an edge)"
            )
            fixes.append(
                "delete the internal faces or join the parts into one solid with a boolean "
                "union (Blender: Select All by Trait > Interior Faces, then delete)"
            )
        raise MeshError(
            f"{cap} is not a watertight solid: {'; and '.join(defects)}. jampacked needs a "
            f"watertight, 2-manifold mesh. Fix: {'; '.join(fixes)}; then export again."
        )

    # consistent winding
    oriented, n_flipped, n_bad = _orient(faces, edges, labels, n_comp)
    if oriented is None:
        raise MeshError(
            f"{cap} has a winding that cannot be made consistent: the surface is "
            f"non-orientable ({_plural(n_bad, 'face')} lie on a Moebius-strip-like part, "
            "which has no inside). Fix: remodel that part as a closed solid; "
            f"{fix_reexport}."
        )
    faces = oriented
    if n_flipped:
        warns.append(
            f"{cap}: flipped {_plural(n_flipped, 'face')} whose winding disagreed with their "
            "neighbours."
        )

    # zero-volume bodies and the overall volume
    six = _signed_six_volumes(vertices, faces)
    comp_volume = np.bincount(labels, weights=six, minlength=n_comp) / 6.0
    largest = float(np.max(np.abs(comp_volume)))
    if largest <= ZERO_VOLUME_FRACTION * diagonal**3:
        raise MeshError(
            f"{cap} has zero volume (it is flat or its faces enclose nothing): jampacked "
            f"needs a solid. Fix: give the surface thickness (Blender: Solidify modifier) or "
            f"{fix_reexport}."
        )
    sliver_comp = np.abs(comp_volume) <= SLIVER_VOLUME_FRACTION * largest
    if np.any(sliver_comp):
        drop = sliver_comp[labels]
        n_sliver_bodies += int(np.sum(sliver_comp))
        n_sliver_faces += int(np.sum(drop))
        faces = faces[~drop]
        comp_volume = comp_volume[~sliver_comp]
        keep_labels = np.flatnonzero(~sliver_comp)
        relabel = np.full(n_comp, -1)
        relabel[keep_labels] = np.arange(len(keep_labels))
        labels = relabel[labels[~drop]]
        n_comp = len(keep_labels)
    if n_sliver_bodies:
        bodies = _plural(n_sliver_bodies, "zero-volume sliver body", "zero-volume sliver bodies")
        warns.append(
            f"{cap}: removed {bodies} ({_plural(n_sliver_faces, 'face')}) beside the main body."
        )

    if n_comp > 1:
        nested = _count_nested(vertices, faces, labels, n_comp)
        vols = ", ".join(f"{abs(v):.4g}" for v in sorted(comp_volume, key=abs, reverse=True)[:5])
        nested_text = (
            f"; {_plural(nested, 'body lies', 'bodies lie')} inside another (a hollow solid "
            "with an inner surface, or a part inside a part)"
            if nested
            else ""
        )
        if role == "container":
            fix = (
                "a container must be one closed surface: join the parts with a boolean union, "
                "or delete the extra surfaces (keep only the surface that bounds the space to "
                "fill)"
            )
        else:
            fix = (
                "an object type must be one solid: join the parts with a boolean union "
                "(Blender: Boolean modifier, Union), or export each body as its own file"
            )
        raise MeshError(
            f"{cap} has {n_comp} separate bodies (volumes {vols}){nested_text}. Fix: {fix}."
        )

    volume = float(comp_volume.sum())
    if volume < 0:
        faces = faces[:, ::-1].copy()
        volume = -volume
        warns.append(
            f"{cap}: the mesh was inside out (negative volume, normals pointing in); "
            "its faces were inverted."
        )

    vertices, faces = _compact(vertices, faces)

    # guarantees, checked with our own edge counting and with manifold3d
    problems = _closed_manifold_problems(faces, len(vertices))
    if problems:
        raise MeshError(
            f"{cap} could not be repaired into a closed 2-manifold ({'; '.join(problems)}): "
            f"{fix_reexport}."
        )
    status = _manifold_status(vertices, faces)
    if status != manifold3d.Error.NoError:
        raise MeshError(
            f"{cap} is refused by manifold3d (status {status.name}): the surface is not a "
            "valid 2-manifold solid in single precision (e.g. vertices too close together). "
            f"Fix: clean it up (Blender 3D-Print Toolbox: Make Manifold) or {fix_reexport}."
        )

    if role == "container":
        _check_container_thickness(vertices, faces, volume, cap)
    volume = mesh_volume_centroid(vertices, faces)[0]
    return vertices, faces, volume, tuple(warns)


def _check_container_thickness(
    vertices: np.ndarray, faces: np.ndarray, volume: float, cap: str
) -> None:
    """Raise if the container's solid is a thin wall around a cavity (e.g. a vase shell)."""
    try:
        hull_volume = float(ConvexHull(vertices).volume)
    except QhullError:
        return
    if hull_volume <= 0:
        return
    area = float(_face_areas2(vertices, faces).sum()) / 2.0
    thickness = 2.0 * volume / area  # mean wall thickness, exact for a thin slab
    size = hull_volume ** (1.0 / 3.0)
    fill = volume / hull_volume
    if thickness < THIN_WALL_THICKNESS * size and fill < THIN_WALL_HULL_FILL:
        raise MeshError(
            f"{cap}: the container's solid is a thin wall (mean thickness about "
            f"{thickness:.3g} units, {100 * thickness / size:.1f}% of its size; it fills only "
            f"{100 * fill:.0f}% of its convex hull), but the packing fills the solid, and here "
            "it needs the cavity the wall encloses. Fix: close the opening and use the inside "
            "surface as the container (Blender: separate the inner faces, Fill the rim, "
            "recalculate normals outside), or model the cavity as a closed solid."
        )


# --------------------------------------------------------------------------------------------
# public entry point


def load_mesh(path: str | os.PathLike, *, role: str = "object") -> MeshData:
    """Load a mesh file, check it, repair what is safe to repair, and return it.

    Args:
        path: mesh file (STL, OBJ, PLY, OFF, GLB/GLTF, or any format meshio reads). Scenes
            with several meshes are concatenated (their transforms applied).
        role: ``"object"`` (an object type to pack) or ``"container"``; used in messages,
            and containers also get the thin-wall check.

    Returns:
        A :class:`MeshData` in the file's units and frame, closed, 2-manifold, outward wound,
        one body, volume > 0, accepted by manifold3d. Repairs made are listed in
        ``warnings`` and logged (see the module docstring).

    Raises:
        InputError: ``role`` is not "object" or "container".
        MeshError: the file is missing, unreadable, of unknown type or empty; or the mesh is
            open, non-manifold, non-orientable, has zero volume or several bodies, is refused
            by manifold3d, or (container) is a thin wall. The message names the file, the
            defect with counts, and a fix.
    """
    if role not in ROLES:
        raise InputError(f"mesh role {role!r} is unknown: use 'object' or 'container'.")
    path_str = os.fspath(path)
    label = f"{role} mesh '{path_str}'"
    data = _read_bytes(path_str, role)
    digest = hashlib.sha256(data).hexdigest()
    if not data.strip():
        raise MeshError(
            f"{_cap(label)} is an empty file: export the mesh again (the export may "
            "have been interrupted)."
        )
    vertices, faces = _read_arrays(path_str, data, _cap(label))
    obj_data = data if _extension(path_str) == "obj" else None
    return _checked(vertices, faces, label, role, obj_data, path_str, digest)


def _checked(vertices: np.ndarray, faces: np.ndarray, label: str, role: str,
             obj_data: bytes | None, path: str | None, digest: str | None) -> MeshData:
    """Check and repair (logging each repair) and freeze the result as MeshData."""
    vertices, faces, volume, warns = _check_and_repair(vertices, faces, label, role, obj_data)
    for message in warns:
        logger.warning(message)
    return MeshData(
        vertices=_frozen(np.ascontiguousarray(vertices, dtype=np.float64)),
        faces=_frozen(np.ascontiguousarray(faces, dtype=np.int64)),
        path=path,
        sha256=digest,
        volume=volume,
        warnings=warns,
    )


def mesh_from_arrays(vertices: np.ndarray, faces: np.ndarray, *, name: str,
                     role: str = "object") -> MeshData:
    """Check and repair a mesh given as arrays (e.g. a Blender object), as :func:`load_mesh`.

    Args:
        vertices: (V, 3) positions in the caller's frame and units.
        faces: (F, 3) vertex indices (triangles; triangulate polygons first).
        name: what the messages call the mesh (e.g. the Blender object's name).
        role: ``"object"`` or ``"container"``.

    Returns:
        A :class:`MeshData` with ``path`` and ``sha256`` None.

    Raises:
        InputError: bad ``role`` or arrays of the wrong shape.
        MeshError: the same defects :func:`load_mesh` refuses, naming ``name``.
    """
    if role not in ROLES:
        raise InputError(f"mesh role {role!r} is unknown: use 'object' or 'container'.")
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise InputError(f"{role} mesh '{name}': vertices must be (V, 3) and faces (F, 3) "
                         f"triangles, got {v.shape} and {f.shape}.")
    if not np.all(np.isfinite(v)):
        raise MeshError(f"{role.capitalize()} mesh '{name}' has non-finite vertex "
                        "coordinates: fix or delete those vertices.")
    if f.size and (not np.issubdtype(f.dtype, np.integer) or f.min() < 0
                   or f.max() >= len(v)):
        raise InputError(f"{role} mesh '{name}': face indices must be integers in "
                         f"[0, {len(v) - 1}].")
    return _checked(v, f.astype(np.int64), f"{role} mesh '{name}'", role, None, None, None)
