"""Mesh files as arrays: read a file's bytes, pick a reader, give vertices and triangles.

Nothing here merges, removes or repairs anything: the arrays are the file's as stored (see
:mod:`jampacked.core.mesh_repair` for the checks). Readers, in order: 3MF with lxml
(:mod:`jampacked.core.threemf`), STL with trimesh's STL reader, OFF with the reader here
(:func:`.off_reader.off_arrays`: polygons of mixed sizes, a file cut short named), then trimesh
(``process=False``), a tolerant OBJ reader (comments on face lines), and meshio as the
fallback; the formats trimesh reads only through meshio (VTK, VTU, Gmsh, Medit, ...) are read
with meshio here first, as trimesh keeps their triangles only. meshio's quads and polygons
are fanned into triangles; a binary PLY with polygons of mixed sizes (Blender's n-gons),
which trimesh 5.2 refuses ("PLY is unexpected length!"), is read so. OBJ faces with
negative (relative) indices are resolved against the vertices defined before them, as the
OBJ format says. A file whose extension is missing or whose read by extension fails (or finds
no faces) is refused with what its content looks like (:func:`_sniff_format`).

Also here: a file's sha256 and the ``box:WxDxH`` specification that stands for a file.
Units and frame are the file's own, except that a 3MF model's declared unit is converted to
millimetres (the only format that declares one).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import logging
import math
import os
import re
import warnings
import zipfile
from pathlib import Path

import numpy as np
import trimesh

from .errors import InputError, MeshError
from .gltf_check import check_gltf
from .off_reader import PADDING, off_arrays, off_keyword
from .polygons import concave, polygons_to_triangles
from .threemf import UNIT_MM, ThreeMFError, read_3mf_model

__all__ = [
    "MESH_EXTENSIONS",
    "extension",
    "file_sha256",
    "obj_malformed_polygons",
    "parse_box_spec",
    "read_arrays",
    "read_bytes",
    "read_mesh_arrays",
]

logger = logging.getLogger(__name__)

_BOX_SPEC = re.compile(r"^\s*box\s*:", re.IGNORECASE)
_OBJ_FACE_COMMENT = re.compile(rb"^[ \t]*f[ \t][^\n#]*#", re.MULTILINE)
#: an OBJ face line with four corners or more (its polygon may be concave)
_OBJ_POLYGON = re.compile(rb"^[ \t]*f(?:[ \t]+[^ \t\r\n#]+){4,}", re.MULTILINE)
_OBJ_FACE_LINE = re.compile(rb"^f ([^\r\n]*)", re.MULTILINE)
_OBJ_VERTEX_LINE = re.compile(rb"^v ([^\r\n]*)", re.MULTILINE)
_OBJ_AFTER_SLASH = re.compile(rb"/[^ \n]*")
_OBJ_RELATIVE_INDEX = re.compile(rb"^[ \t]*[fl][ \t][^\n#]*(?<![\w.])-[0-9]", re.MULTILINE)

Arrays = tuple[np.ndarray, np.ndarray]

#: the formats meshio reads that trimesh has a reader of its own for (trimesh reads the other
#: meshio formats through meshio, triangles only)
_TRIMESH_OWN_READERS = frozenset({"stl", "obj", "ply", "off"})

#: the mesh file types people pass around (a file named so is taken for a mesh in messages;
#: any type trimesh or meshio reads is read)
MESH_EXTENSIONS = ("stl", "obj", "ply", "off", "3mf", "glb", "gltf")


# --------------------------------------------------------------------------------------------
# files


def read_bytes(path: str, role: str) -> bytes:
    """The bytes of the mesh file at ``path``; ``role`` names it in messages ("object", ...).

    Raises:
        MeshError: missing, a folder, or unreadable (the message names the file and a fix).
    """
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


def extension(path: str) -> str:
    """The lower-case file extension that picks the reader ("stl", "3mf", "vol.gz", ...)."""
    name = Path(path).name.lower()
    for compound in ("dato.gz", "post.gz", "vol.gz"):
        if name.endswith("." + compound):
            return compound
    return Path(name).suffix.lstrip(".")


def file_sha256(path: str | os.PathLike) -> str:
    """Return the sha256 hex digest of the bytes of the file at ``path``.

    Raises:
        MeshError: the file does not exist or cannot be read.
    """
    data = read_bytes(os.fspath(path), "mesh")
    return hashlib.sha256(data).hexdigest()


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
# OBJ text


def _obj_plain_spacing(data: bytes) -> bytes:
    """``data`` with single spaces between an OBJ line's fields and none before them (the
    same object where there is nothing to change)."""
    if not (data.startswith((b"\xef\xbb\xbf", b" ")) or b"\t" in data or b"\n " in data):
        return data
    data = data.removeprefix(b"\xef\xbb\xbf").replace(b"\t", b" ")
    return re.sub(rb"^ +", b"", data, flags=re.MULTILINE)


def _strip_obj_comments(data: bytes) -> bytes:
    """``data`` without comments, its lines ended by newlines alone."""
    if b"#" not in data and b"\r" not in data:
        return data
    return b"\n".join(line.split(b"#", 1)[0] for line in data.splitlines())


def _words_per_line(text: bytes) -> np.ndarray:
    """(L,) the number of words (as ``bytes.split`` cuts them) on each of the L lines of
    ``text``, which ends with a newline and has no other line ends."""
    chars = np.frombuffer(text, np.uint8)
    word = ~_WHITESPACE[chars]
    begins = np.cumsum(word & ~np.concatenate(([False], word[:-1])))
    return np.diff(begins[chars == ord("\n")], prepend=0)


_WHITESPACE = np.zeros(256, bool)
_WHITESPACE[list(b" \t\n\r\x0b\x0c")] = True


def obj_absolute_indices(data: bytes) -> bytes:
    """OBJ text with every negative (relative) index on face and line elements replaced by
    the absolute index it stands for: -1 is the last vertex (texture coordinate, normal)
    defined *before* that line. trimesh counts from the end of the whole file instead.

    Returns ``data`` itself when it has no negative index."""
    if not _minus_on_face_line(data) or not _OBJ_RELATIVE_INDEX.search(data):
        return data
    counts = {b"v": 0, b"vt": 0, b"vn": 0}
    out = []
    for line in data.splitlines():
        words = line.split()
        key = words[0] if words else b""
        if key in counts:
            counts[key] += 1
        elif key in (b"f", b"l") and b"-" in line:
            text, sep, comment = line.partition(b"#")
            fields = text.split()
            for k in range(1, len(fields)):
                refs = fields[k].split(b"/")
                for slot, kind in enumerate((b"v", b"vt", b"vn")[: len(refs)]):
                    ref = refs[slot]
                    if ref.startswith(b"-") and ref[1:].isdigit():
                        refs[slot] = str(counts[kind] + 1 + int(ref)).encode()
                fields[k] = b"/".join(refs)
            line = b" ".join(fields) + (sep + comment if sep else b"")
        out.append(line)
    return b"\n".join(out) + b"\n"


def _minus_on_face_line(data: bytes) -> bool:
    """Whether a minus sign may stand on an OBJ face or line element (f, l) of ``data``:
    False only where every minus is on a line that starts with something else (the
    regular expression that finds the negative indices takes seconds over a large file)."""
    chars = np.frombuffer(data, np.uint8)
    minus = np.flatnonzero(chars == ord("-"))
    if not len(minus):
        return False
    starts = np.concatenate(([0], np.flatnonzero(chars == ord("\n")) + 1))
    starts = np.unique(starts[np.searchsorted(starts, minus, side="right") - 1])
    head = chars[starts]
    second = chars[np.minimum(starts + 1, len(chars) - 1)]
    return bool(np.any(_WHITESPACE[head] | (np.isin(head, list(b"fl"))
                                            & np.isin(second, list(b" \t")))))


def obj_malformed_polygons(data: bytes, limit: int = 3) -> list[str]:
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
# readers


def _trimesh_arrays(loaded: object) -> Arrays:
    if isinstance(loaded, trimesh.Scene):
        geometries = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
        loaded = trimesh.util.concatenate(geometries) if geometries else trimesh.Trimesh()
    vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    faces = getattr(loaded, "faces", None)
    faces = np.zeros((0, 3), np.int64) if faces is None else np.asarray(faces, dtype=np.int64)
    return vertices.reshape(-1, 3), faces.reshape(-1, 3)


def _block_triangles(points: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """(N, k) polygons of one meshio block, k >= 3, as (N * (k - 2), 3) triangles (convex
    ones fanned from their first corner, concave ones ear-clipped: see
    :func:`polygons.polygons_to_triangles`), each polygon's first triangles, then their
    second ones, ...: the order quads were split in before polygons were read, kept so that
    a file reads as it did."""
    n, k = polygons.shape
    triangles = polygons_to_triangles(points, np.full(n, k, np.int64), polygons.ravel())
    return triangles.reshape(n, k - 2, 3).transpose(1, 0, 2).reshape(-1, 3)


#: meshio's surface cells by their corners: (type name, corners first). Higher-order cells
#: (triangle6, quad9, ...) list their corners before the nodes on edges and inside.
_MESHIO_SURFACE = re.compile(r"(triangle|quad)(\d*)")


def _block_array(block) -> np.ndarray | None:
    """A meshio cell block's vertex indices as one integer array, or None where its cells
    differ in size (polygons of several sizes in one block)."""
    try:
        return np.asarray(block.data, dtype=np.int64)
    except (ValueError, TypeError):
        return None


def _meshio_faces(points: np.ndarray, cells: list, label: str) -> np.ndarray:
    """Triangles of meshio's cell blocks (``points``: (V, 3) their vertices): triangles as
    they are, quads and polygons of any size (meshio gives one ``polygon`` block per run of
    one size) triangulated in their plane, higher-order
    triangles and quads by their corners; points, lines and volume cells left out.

    Raises:
        MeshError: a block of surface cells that cannot be read as polygons (none are
            dropped silently), a corner that is no vertex, or volume cells only (no surface
            to read).
    """
    tris: list[np.ndarray] = []
    volume: list[str] = []
    for block in cells:
        name = str(block.type)
        kind = _MESHIO_SURFACE.fullmatch(name)
        dim = getattr(block, "dim", None)
        if kind or name == "polygon":
            data = _block_array(block)
            if data is None or data.ndim != 2:  # one polygon at a time
                rows = [np.asarray(p, np.int64).reshape(1, -1) for p in block.data]
            else:
                corners = data.shape[1] if name == "polygon" else (
                    3 if kind[1] == "triangle" else 4)
                if data.shape[1] < corners or corners < 3:
                    raise MeshError(f"{label} has '{name}' cells of {data.shape[1]} nodes, "
                                    "which are not read as polygons: export it as STL, PLY "
                                    "or OBJ.")
                rows = [data[:, :corners]]
            for polygons in rows:
                if polygons.size and (polygons.min() < 0 or polygons.max() >= len(points)):
                    raise MeshError(f"{label} has a '{name}' cell whose corner is not one "
                                    f"of its {len(points):,} points: the file is damaged; "
                                    "export it again.")
                if polygons.shape[1] < 3:
                    raise MeshError(f"{label} has a '{name}' cell of {polygons.shape[1]} "
                                    "corners, which is no polygon: the file is damaged; "
                                    "export it again.")
                tris.append(_block_triangles(points, polygons))
        elif dim == 2:
            raise MeshError(f"{label} has {len(block.data):,} surface cells of type "
                            f"'{name}', which are not read: export it with triangles, "
                            "quads or polygons (or as STL, PLY or OBJ).")
        elif dim == 3:
            volume.append(name)
    if not tris and volume:
        raise MeshError(f"{label} holds volume cells only ({', '.join(sorted(set(volume)))}), "
                        "no surface: export its boundary surface (triangles or quads), or "
                        "save it as STL.")
    return np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)


def _meshio_read(path: str, data: bytes) -> tuple[np.ndarray, list]:
    """meshio's read of ``path`` (``data``: its bytes): its (V, 3) points (2D ones at
    z = 0) and cell blocks.

    Raises:
        ValueError: no meshio reader read it (what meshio said)."""
    import meshio

    renamed = _ply_face_list_renamed(data) if extension(path) == "ply" else None
    # meshio prints to stdout/stderr and calls sys.exit(1) when no reader succeeds
    sink = io.StringIO()
    try:
        with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
            mesh = (meshio.read(path) if renamed is None
                    else meshio.read(io.BytesIO(renamed), file_format="ply"))
    except SystemExit:
        message = " ".join(sink.getvalue().split()) or "no reader succeeded"
        raise ValueError(message) from None
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim == 2 and points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    return points.reshape(-1, 3), mesh.cells


def _meshio_arrays(path: str, data: bytes, label: str) -> Arrays:
    points, cells = _meshio_read(path, data)
    return points, _meshio_faces(points, cells, label)


def length_unit(path: str | None) -> str:
    """The unit of a mesh file's coordinates as read, for messages: "mm" for a 3MF (its
    declared unit is converted to millimetres), "units" for formats that carry none."""
    return "mm" if path and extension(path) == "3mf" else "units"


def _is_ascii_stl(data: bytes) -> bool:
    """An ASCII STL (a binary header may start with "solid" too; its numbers hold 0s)."""
    head = data[:4096].removeprefix(b"\xef\xbb\xbf").lstrip()
    return head[:5].lower() == b"solid" and b"\0" not in head


#: an ASCII STL solid's first line, with its name (the name up to the first facet)
_STL_SOLID_NAME = re.compile(rb"^[ \t]*solid\b[^\n]*?(?=\s+facet\b|\n|$)",
                             re.IGNORECASE | re.MULTILINE)
#: an ASCII STL keyword after any whitespace: where a line should start
_STL_KEYWORD = re.compile(rb"\s+(?=(?:facet|outer|vertex|endloop|endfacet|endsolid)\b)", re.I)


def _stl_damage(data: bytes) -> str | None:
    """What is wrong with an STL cut short (a download or copy): a binary one whose size
    does not match the triangle count in its header, an ASCII one without its closing
    ``endsolid``; None where neither is seen."""
    if _is_ascii_stl(data):
        lines = data.rstrip().splitlines() or [b""]  # a lone CR ends a line too
        if lines[-1].strip()[:8].lower() == b"endsolid":
            return None
        facets = data.lower().count(b"endfacet")
        return (f"it ends after {facets:,} whole facets without the 'endsolid' line that "
                "closes an ASCII STL, so it was cut short (if it is whole, its writer left "
                "that line out: add 'endsolid' as its last line)")
    if len(data) < 84:
        return f"it has {len(data)} bytes, fewer than a binary STL's 84-byte header"
    count = int.from_bytes(data[80:84], "little")
    expected = 84 + 50 * count
    if len(data) == expected:
        return None
    held = (len(data) - 84) / 50
    how = ("it was cut short or damaged" if len(data) < expected
           else "it holds more than its header says, so it is damaged")
    return (f"its header says {count:,} triangles ({expected:,} bytes), but it has "
            f"{len(data):,} bytes ({held:,.1f} triangles): {how}")


#: how messages name a PLY element's lines ("12 faces"); others as "3 'material' lines"
_PLY_ROWS = {b"vertex": "vertices", b"face": "faces", b"edge": "edges"}


def _ply_ascii_damage(data: bytes) -> str | None:
    """What is wrong with an ASCII PLY whose data lines are fewer or more than its header's
    element counts promise (trimesh reads the lines there are: a file cut short gave a mesh
    without its last faces, silently); None where they match, for a binary PLY (trimesh
    checks its length) and for a header this cannot follow (the readers then report it).

    One line an element, as the format has it; blank lines are not counted; a last line
    with fewer numbers than its properties need (cut inside) is "part of one more"."""
    head, found, body = data.partition(b"end_header")
    if not found or not _ply_ascii(data):
        return None
    body = body.translate(None, PADDING)
    elements: list[tuple[bytes, int, list[bool]]] = []  # name, count, which are lists
    for words in map(bytes.split, head.splitlines()):
        if words[:1] == [b"element"] and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[:1] == [b"property"] and elements:
            elements[-1][2].append(words[1:2] == [b"list"])
    if not elements:
        return None
    rows = [line for line in body.splitlines()[1:] if line.strip()]
    promised = [count for _, count, _ in elements]
    held, left = [], len(rows)
    for count in promised:
        held.append(min(count, left))
        left -= held[-1]
    last = max((k for k, h in enumerate(held) if h), default=0)  # the last line's element
    part = bool(rows) and not _ply_row_whole(rows[-1].split(), elements[last][2])
    if held == promised and not left and not part:
        return None

    def say(counts: list[int]) -> str:
        said = [f"{c:,} {noun}" if c else f"no {noun}" for c, noun in zip(counts, (
            _PLY_ROWS.get(name) or f"'{name.decode('latin-1')}' lines" for name, _, _ in
            elements), strict=True)]
        return ", ".join(said[:-1]) + " and " + said[-1] if len(said) > 1 else said[0]

    if left:
        return (f"its header promises {say(promised)}, but it holds {left:,} more line"
                f"{'s' if left > 1 else ''} after them: its counts are wrong or the file is "
                "damaged")
    held[last] -= int(part)
    return (f"its header promises {say(promised)}, but it holds {say(held)}"
            f"{' (and part of one more)' if part else ''}: it was cut short")


def _ply_ascii(data: bytes) -> bool:
    """Whether a PLY's header says its data is text (its ``format`` line)."""
    return any(line.split()[:2] == [b"format", b"ascii"]
               for line in data.partition(b"end_header")[0].splitlines())


def _ply_face_count(data: bytes) -> int:
    """The faces a PLY's header promises (its ``element face`` count; 0 where none)."""
    head = data.partition(b"end_header")[0]
    found = re.search(rb"^element[ \t]+face[ \t]+(\d+)", head, re.MULTILINE)
    return int(found[1]) if found else 0


def _ply_polygons_in_plane(path: str, data: bytes, label: str, fanned: Arrays) -> Arrays:
    """A PLY (``data``: its bytes) that trimesh read with polygons of four corners or more
    (``fanned``: each fanned from its first corner, wrong on a concave one, whose faces then
    cross): where one of its polygons is concave, the polygons triangulated in their plane;
    else trimesh's read, as before. A binary PLY's polygons (all of one size: trimesh refuses
    mixed ones there, which meshio then reads) are taken from trimesh's parse before its fan;
    an ASCII PLY's from meshio's read (meshio reads a million binary quads in 2.5 s against
    trimesh's 0.4 s; trimesh fans an ASCII PLY's polygons of mixed sizes as it parses)."""
    if not _ply_ascii(data):
        return _ply_polygons_of_one_size(data, fanned)
    try:
        vertices, cells = _meshio_read(path, data)
    except Exception:  # noqa: BLE001 - trimesh's read stands
        return fanned
    if not any(_block_concave(vertices, block) for block in cells):
        return fanned  # as trimesh read it, as before
    try:
        return vertices, _meshio_faces(vertices, cells, label)
    except MeshError:
        return fanned


def _ply_polygons_of_one_size(data: bytes, fanned: Arrays) -> Arrays:
    """:func:`_ply_polygons_in_plane` for a binary PLY, by trimesh's parse of its faces
    before the fan (an (F, k) array where all have k corners)."""
    try:
        parsed = trimesh.exchange.ply.load_ply(io.BytesIO(data), skip_materials=True)
        vertices = np.asarray(parsed["vertices"], np.float64)
        polygons = np.asarray(parsed["faces"])
    except Exception:  # noqa: BLE001 - trimesh's read stands
        return fanned
    if (polygons.ndim != 2 or polygons.shape[1] < 4 or not polygons.size
            or not np.array_equal(vertices, fanned[0])):
        return fanned
    sizes = np.full(len(polygons), polygons.shape[1])
    corners = polygons.ravel().astype(np.int64)
    if (corners.min() < 0 or corners.max() >= len(vertices)
            or not concave(vertices, sizes, corners).any()):
        return fanned
    return vertices, polygons_to_triangles(vertices, sizes, corners)


def _ply_face_list_renamed(data: bytes) -> bytes | None:
    """A PLY whose face list is named ``vertex_index`` (as some writers name it; trimesh
    reads either name) with the name meshio knows, ``vertex_indices``; None where there is
    nothing to rename."""
    end = data.find(b"end_header")
    if end < 0 or b"vertex_indices" in data[:end]:
        return None
    header, count = _PLY_SINGULAR_LIST.subn(rb"\1vertex_indices\2", data[:end], count=1)
    return header + data[end:] if count else None


#: a face list property named in the singular
_PLY_SINGULAR_LIST = re.compile(rb"(property[ \t]+list[ \t]+\S+[ \t]+\S+[ \t]+)vertex_index"
                                rb"([ \t]*\r?\n)")


def _block_concave(vertices: np.ndarray, block) -> bool:
    """Whether a meshio cell block holds a polygon of four corners or more that a fan from
    its first corner gets wrong (`polygons.concave`)."""
    data = _block_array(block)
    if data is None:
        return True
    if data.ndim != 2 or data.shape[1] < 4 or str(block.type) not in ("quad", "polygon"):
        return False
    if data.size and (data.min() < 0 or data.max() >= len(vertices)):
        return False
    return bool(concave(vertices, np.full(len(data), data.shape[1]), data.ravel()).any())


def _ply_row_whole(words: list[bytes], lists: list[bool]) -> bool:
    """Whether an ASCII PLY line holds all the numbers its element's properties need (``lists``:
    which are lists, each a count and that many numbers)."""
    need = 0
    for is_list in lists:
        if is_list:
            if need >= len(words):
                return False
            with contextlib.suppress(ValueError, OverflowError):  # not a count: readers say so
                need += int(float(words[need]))
        need += 1
    return len(words) >= need


def _stl_arrays(data: bytes) -> Arrays | None:
    """trimesh's STL reader without the Scene/Trimesh wrapping (several times faster), or
    None where it fails (the general readers then try). trimesh reads an ASCII STL line by
    line: one whose lines end in a carriage return alone (classic Mac) or that is all on
    one line read as a single triangle, so there each keyword is put on a line of its own
    and, where the facets still differ from the triangles read, None."""
    arrays = _trimesh_stl(data)
    if not _is_ascii_stl(data):
        return arrays
    facets = len(re.findall(rb"(?i)\bendfacet\b", data))
    if arrays is not None and len(arrays[1]) == facets:
        return arrays
    # line ends of a lone CR as LF, and the solids' names, which trimesh reads keywords in
    # ("solid outer vertex"), left out; then each keyword on a line of its own
    data = _STL_SOLID_NAME.sub(b"solid", data.replace(b"\r\n", b"\n").replace(b"\r", b"\n"))
    arrays = _trimesh_stl(data)
    if arrays is not None and len(arrays[1]) == facets:
        return arrays
    arrays = _trimesh_stl(_STL_KEYWORD.sub(b"\n", data))
    return arrays if arrays is not None and len(arrays[1]) == facets else None


def _trimesh_stl(data: bytes) -> Arrays | None:
    """trimesh's STL arrays, an ASCII file's solids (one per body, as some CAD tools write)
    in file order, or None."""
    with contextlib.suppress(Exception), warnings.catch_warnings():
        # numpy's "could not be read to its end" on lines trimesh splits wrongly: the
        # caller counts the facets read
        warnings.simplefilter("ignore", DeprecationWarning)
        loaded = trimesh.exchange.stl.load_stl(io.BytesIO(data))
        solids = list(loaded["geometry"].values()) if "geometry" in loaded else [loaded]
        vs, fs, offset = [], [], 0
        for solid in solids:
            v = np.asarray(solid["vertices"], dtype=np.float64).reshape(-1, 3)
            f = np.asarray(solid["faces"], dtype=np.int64).reshape(-1, 3)
            if not len(f) or f.min() < 0 or f.max() >= len(v):
                return None
            vs.append(v)
            fs.append(f + offset)
            offset += len(v)
        if fs:
            return np.concatenate(vs), np.concatenate(fs)
    return None


def _obj_concave_arrays(data: bytes) -> Arrays | None:
    """Vertices and triangles of OBJ text (plain spacing, absolute indices, no comments)
    where a polygon is concave, each polygon triangulated in its plane (trimesh fans every
    polygon from its first corner, which on a concave one makes faces that cross); None
    where every polygon is convex or the text is not plain enough to read here (trimesh
    then reads it). Only the vertices the faces use are kept, in the file's order."""
    faces = b"\n".join(_OBJ_FACE_LINE.findall(data)) + b"\n"
    points = b"\n".join(_OBJ_VERTEX_LINE.findall(data)) + b"\n"
    sizes = _words_per_line(faces)
    numbers = _words_per_line(points)  # x y z [w|r g b]
    if b"/" in faces:
        faces = _OBJ_AFTER_SLASH.sub(b"", faces)
    with warnings.catch_warnings():  # a token that is no number ends the numbers read
        warnings.simplefilter("ignore", DeprecationWarning)
        flat = np.fromstring(faces.decode("latin-1"), np.float64, sep=" ")
        values = np.fromstring(points.decode("latin-1"), np.float64, sep=" ")
    # anything but numbers (three or more a vertex) and whole indices is left to trimesh
    if (len(values) != numbers.sum() or (len(numbers) and numbers.min() < 3)
            or len(flat) != sizes.sum() or not len(flat) or sizes.min() < 3
            or np.any(flat != np.round(flat))):
        return None
    vertices = values[(np.cumsum(numbers) - numbers)[:, None] + np.arange(3)]
    flat = flat.astype(np.int64) - 1
    if flat.min() < 0 or flat.max() >= len(vertices):
        return None
    if not concave(vertices, sizes, flat).any():
        return None
    used, flat = np.unique(flat, return_inverse=True)
    vertices = vertices[used]
    return vertices, polygons_to_triangles(vertices, sizes, flat)


def _obj_arrays(data: bytes, errors: list[str], reader: str) -> Arrays | None:
    try:
        loaded = trimesh.load(io.BytesIO(data), file_type="obj", force="mesh", process=False)
        return _trimesh_arrays(loaded)
    except Exception as exc:  # noqa: BLE001 - any reader failure falls through
        errors.append(f"{reader}: {exc}")
        return None


#: a first OBJ vertex or face line (indented lines, tabs, as :func:`_obj_plain_spacing` reads)
_OBJ_VERTEX = re.compile(rb"^[ \t]*v[ \t]", re.MULTILINE)
_OBJ_FACE = re.compile(rb"^[ \t]*f[ \t]", re.MULTILINE)


def _sniff_format(data: bytes) -> tuple[str, str] | None:
    """The mesh format a file's bytes look like, whatever its name: ``(extension, how
    messages describe it)``, or None where none is recognised. For messages about a file
    whose extension is missing or wrong, never to pick a reader: a read by extension that
    succeeds stands."""
    head = data[:4096]
    if head[:4] == b"PK\x03\x04":
        with contextlib.suppress(Exception):  # any zip that is not a readable package: None
            names = {n.lower() for n in zipfile.ZipFile(io.BytesIO(data)).namelist()}
            if "3d/3dmodel.model" in names:
                return "3mf", "a 3MF file (a zip with 3D/3dmodel.model)"
        return None
    if head[:4] == b"glTF":
        return "glb", "a GLB file (binary glTF: 'glTF' in its first bytes)"
    text = head.removeprefix(b"\xef\xbb\xbf")
    if text.split(b"\n", 1)[0].strip().lower() == b"ply":
        return "ply", "a PLY file ('ply' on its first line)"
    if b"\0" not in text:  # the text formats
        if text.lstrip()[:1] == b"{" and b'"asset"' in text:
            return "gltf", "a glTF file (JSON with an 'asset')"
        if _is_ascii_stl(data) and re.search(rb"(?i)\bfacet\b", text):
            return "stl", "an ASCII STL file ('solid', then 'facet' lines)"
        words = next((w for line in text.splitlines()
                      if (w := line.split(b"#", 1)[0].split())), [b""])
        if off_keyword(words[0]):
            return "off", "an OFF file ('OFF' on its first line)"
        if _OBJ_VERTEX.search(text) and _OBJ_FACE.search(data):
            return "obj", "an OBJ file ('v' and 'f' lines)"
    if len(data) >= 84 and len(data) == 84 + 50 * int.from_bytes(data[80:84], "little"):
        return "stl", "a binary STL file (its size matches the triangle count in its header)"
    return None


def _refuse_misnamed(ext: str, data: bytes, label: str,
                     cause: Exception | None = None) -> None:
    """Raise a MeshError that says what a file looks like and to rename it, where its
    extension is missing or another format's (its read by extension failed or found no
    faces); return where its content says nothing else."""
    found = _sniff_format(data)
    if found is None or found[0] == ext or (found[0], ext) == ("stl", "stl_ascii"):
        return
    kind, what = found
    if ext:
        message = f"{label} looks like {what}, not {ext.upper()}: rename it to .{kind}."
    else:
        message = f"{label} has no file extension, and it looks like {what}: rename it to .{kind}."
    raise MeshError(message) from cause


def read_arrays(path: str, data: bytes, label: str, notes: list[str] | None = None) -> Arrays:
    """Vertices and triangles of the file ``path`` whose bytes are ``data``, as stored (a
    3MF model in another unit than millimetres: converted to millimetres).

    Args:
        path: the file (its extension picks the reader; meshio and trimesh's scenes read it
            by path).
        data: its bytes (for OBJ and OBJ with negative indices resolved, see
            :func:`obj_absolute_indices`).
        label: what messages call it, capitalised (e.g. "Object mesh 'a.stl'").
        notes: where given, a sentence for the user is appended when a unit was converted.

    Raises:
        MeshError: unknown type, or no reader can read it (damaged, or not really that type).
    """
    ext = extension(path)
    try:
        arrays = _read_by_extension(ext, path, data, label, notes)
    except MeshError as exc:
        _refuse_misnamed(ext, data, label, exc)
        raise
    if not len(arrays[1]):  # a reader that takes other bytes for no faces (OBJ's)
        _refuse_misnamed(ext, data, label)
    return arrays


def _read_by_extension(ext: str, path: str, data: bytes, label: str,
                       notes: list[str] | None) -> Arrays:
    """:func:`read_arrays` by the extension ``ext`` alone."""
    if ext == "3mf":
        try:
            arrays, unit = read_3mf_model(data)
            if unit != "millimeter" and notes is not None:
                notes.append(f"{label} declares its unit as {unit}: read in millimetres "
                             f"(x{UNIT_MM[unit]:g}), as slicers read it.")
            return arrays
        except ThreeMFError as exc:
            raise MeshError(
                f"{label} cannot be read as a 3MF file ({exc}): the file is damaged or not "
                "really 3MF; export it again."
            ) from exc
    if ext == "stl":
        arrays = _stl_arrays(data)
        if arrays is not None:
            return arrays
        damage = _stl_damage(data)  # worded only for a file no reader took
        if damage:
            raise MeshError(f"{label} is not a whole STL file: {damage}. Copy or export it "
                            "again.")
    if ext == "off":
        return off_arrays(data, label)
    if ext == "ply" and (damage := _ply_ascii_damage(data)):
        raise MeshError(f"{label} is not a whole PLY file: {damage}. Copy or export it again.")
    trimesh_formats = set(trimesh.available_formats())
    import meshio

    meshio_formats = {e.lstrip(".") for e in meshio.extension_to_filetypes}
    if ext not in trimesh_formats and ext not in meshio_formats:
        shown = ", ".join(sorted(set(MESH_EXTENSIONS) & (trimesh_formats | {"3mf"})))
        what = f"an unknown file type '.{ext}'" if ext else "no file extension"
        raise MeshError(
            f"{label} has {what} (no reader for it), and its content is not one that is "
            f"recognised: export it as one of {shown} (or another format meshio reads)."
        )
    if ext in ("glb", "gltf"):
        check_gltf(path, data, label)
    errors: list[str] = []
    if ext == "obj":
        absolute = obj_absolute_indices(_obj_plain_spacing(data))
        if _OBJ_POLYGON.search(absolute):
            arrays = _obj_concave_arrays(_strip_obj_comments(absolute))
            if arrays is not None:
                return arrays
        if absolute is not data or (b"#" in data and _OBJ_FACE_COMMENT.search(data)):
            # trimesh's OBJ reader fails on comments at the end of face lines, counts
            # relative indices from the end of the file and skips indented lines
            logger.debug("%s: read with comments and relative indices resolved", label)
            arrays = _obj_arrays(_strip_obj_comments(absolute), errors, "trimesh")
            if arrays is not None:
                return arrays
    # trimesh reads the meshio formats it has no reader of its own for through meshio,
    # keeping the triangles and dropping quads and polygons: read those here first
    meshio_own = ext in meshio_formats and ext not in _TRIMESH_OWN_READERS
    if ext in trimesh_formats and not errors and not meshio_own:
        # materials and textures are not needed: skip them (and missing .mtl files quietly)
        extra = {"skip_materials": True} if ext in ("obj", "glb", "gltf") else {}
        try:
            arrays = _trimesh_arrays(trimesh.load(path, force="mesh", process=False, **extra))
        except Exception as exc:  # noqa: BLE001 - any reader failure falls through
            errors.append(f"trimesh: {exc}")
        else:
            if ext == "ply" and len(arrays[1]) > _ply_face_count(data):
                return _ply_polygons_in_plane(path, data, label, arrays)
            return arrays
        if ext == "obj":
            arrays = _obj_arrays(_strip_obj_comments(data), errors, "tolerant OBJ reader")
            if arrays is not None:
                return arrays
    if ext in meshio_formats:
        try:
            return _meshio_arrays(path, data, label)
        except MeshError:
            raise
        except Exception as exc:  # noqa: BLE001
            errors.append(f"meshio: {exc}")
    detail = "; ".join(e.strip().replace("\n", " ")[:200] for e in errors)
    raise MeshError(
        f"{label} cannot be read as a .{ext} file ({detail}): the file is damaged or not "
        f"really .{ext}; export it again from your modelling tool, e.g. as binary STL or PLY."
    )


def read_mesh_arrays(path: str | os.PathLike) -> Arrays:
    """Vertices and triangles of a mesh file, as stored: nothing merged, nothing repaired.

    Args:
        path: STL, OBJ, PLY, OFF, GLB/GLTF, 3MF, or any format meshio reads. Files with
            several meshes or objects give all of them, transforms applied, concatenated.

    Returns:
        ``(vertices, faces)``: (V, 3) float64 in the file's units and frame, (F, 3) int64
        vertex indices in file order (an STL gives three vertices per face); empty arrays
        for an empty file.

    Raises:
        MeshError: missing, a folder, unreadable, of unknown type, or damaged (the message
            names the file).
    """
    path_str = os.fspath(path)
    data = read_bytes(path_str, "input")
    if not data.strip():
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return read_arrays(path_str, data, f"Mesh file '{path_str}'")
