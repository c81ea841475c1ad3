"""Read and write mesh files exactly as they are: no merging, no repair; atomic writes.

Reading (:func:`read_mesh_arrays`) goes through the same readers as
:mod:`jampacked.core.meshes` (trimesh with ``process=False``, a tolerant OBJ reader, meshio as
the fallback), except 3MF, which is read here with the standard library (every object of
every build item, with its transforms). Writing (:func:`write_mesh`) uses trimesh's exporters
on ``trimesh.Trimesh(..., process=False)`` for STL (binary), OBJ and PLY (binary), and a
standard-library writer for 3MF (trimesh's 3MF code needs lxml, which jampacked does not
depend on): one 3MF object per body, named when names are given. STL, OBJ and PLY hold one
mesh: the bodies are concatenated.

Units and frame are the caller's (container units, mm for printing); 3MF files declare
millimetres.
"""

from __future__ import annotations

import contextlib
import io
import os
import secrets
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from xml.etree import ElementTree
from xml.sax.saxutils import quoteattr

import numpy as np
import trimesh

from jampacked.core.errors import InputError, MeshError
from jampacked.core.meshes import _extension, _read_arrays, _read_bytes

from .validate import ValidationReport, validate_file
from .xmlmesh import POW5, scan_triangles, scan_vertices, skip_space

__all__ = ["WRITE_FORMATS", "read_mesh_arrays", "write_mesh"]

#: file extensions write_mesh can write
WRITE_FORMATS = ("stl", "obj", "ply", "3mf")

_3MF_CORE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
_3MF_REL_TYPE = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
_3MF_CONTENT_TYPES = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
    '<Default Extension="rels" '
    'ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
    '<Default Extension="model" '
    'ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
    "</Types>\n"
)
_3MF_RELS = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
    f'<Relationship Target="/3D/3dmodel.model" Id="rel0" Type="{_3MF_REL_TYPE}"/>'
    "</Relationships>\n"
)

Body = tuple[np.ndarray, np.ndarray]


# --------------------------------------------------------------------------------------------
# reading


def read_mesh_arrays(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of a mesh file, as stored: nothing merged, nothing repaired.

    Args:
        path: STL, OBJ, PLY, OFF, GLB/GLTF, 3MF, or any format meshio reads. Files with
            several meshes or objects give all of them, transforms applied, concatenated.

    Returns:
        ``(vertices, faces)``: (V, 3) float64 in the file's units and frame, (F, 3) int64
        vertex indices in file order (an STL gives three vertices per face).

    Raises:
        MeshError: missing, a folder, unreadable, of unknown type, or damaged (the message
            names the file).
    """
    path_str = os.fspath(path)
    data = _read_bytes(path_str, "input")
    label = f"Mesh file '{path_str}'"
    if not data.strip():
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    if _extension(path_str) == "3mf":
        try:
            return _read_3mf(data)
        except (zipfile.BadZipFile, KeyError, ValueError, ElementTree.ParseError) as exc:
            raise MeshError(
                f"{label} cannot be read as a 3MF file ({exc}): the file is damaged or not "
                "really 3MF; export it again."
            ) from exc
    if _extension(path_str) == "stl":
        # trimesh's STL reader without the Scene/Trimesh wrapping (several times faster)
        with contextlib.suppress(Exception):
            loaded = trimesh.exchange.stl.load_stl(io.BytesIO(data))
            v = np.asarray(loaded["vertices"], dtype=np.float64).reshape(-1, 3)
            f = np.asarray(loaded["faces"], dtype=np.int64).reshape(-1, 3)
            if len(f) and 0 <= f.min() and f.max() < len(v):
                return v, f
    return _read_arrays(path_str, data, label)


def _matrix(text: str | None) -> np.ndarray:
    """A 3MF transform ("m00 m01 m02 m10 ... m32", row vectors) as a 4x4 column matrix."""
    m = np.eye(4)
    if text:
        values = np.array(text.split(), dtype=np.float64)
        if len(values) != 12:
            raise ValueError(f"transform {text!r} does not have 12 numbers")
        m[:3, :4] = values.reshape(4, 3).T
    return m


_NUMBER_BYTES = b"0123456789.eE+- \t\r\n"


def _plain_numbers(block: bytes, tag: bytes, attributes: tuple[bytes, bytes, bytes]
                   ) -> np.ndarray | None:
    """The numbers of a block of plain elements (e.g. ``<vertex x="1" y="2" z="3"/>``), or
    None if any element has another form (other attributes, order, quotes or spacing)."""
    a, b, c = attributes
    text = block
    for old in (b"<" + tag + b" " + a + b'="', b'" ' + b + b'="', b'" ' + c + b'="', b'"/>'):
        text = text.replace(old, b" ")
    if text.translate(None, _NUMBER_BYTES):
        return None
    values = np.array(text.split(), dtype=np.float64)
    return values if len(values) == 3 * block.count(b"<" + tag) else None


def _element_span(xml: bytes, tag: bytes, start: int, stop: int
                  ) -> tuple[int, int, int] | None:
    """Start and stop of the content of the first <tag>...</tag> in xml[start:stop], and the
    index after it."""
    i = xml.find(b"<" + tag + b">", start, stop)
    if i < 0:
        return None
    i += len(tag) + 2
    j = xml.find(b"</" + tag + b">", i, stop)
    return (i, j, j + len(tag) + 3) if j >= 0 else None


_VERTEX_WORDS = tuple(np.frombuffer(w, np.uint8)
                      for w in (b'<vertex x="', b'" y="', b'" z="', b'"/>'))
_TRIANGLE_WORDS = tuple(np.frombuffer(w, np.uint8)
                        for w in (b'<triangle v1="', b'" v2="', b'" v3="', b'"/>'))


def _scanned_vertices(xml: bytes, buf: np.ndarray, start: int, stop: int) -> np.ndarray | None:
    """The numbers of xml[start:stop] if it holds only plain vertex elements (numba scan, the
    few numbers it leaves converted by numpy as :func:`_plain_numbers` does), else None."""
    values, spans, end, ok = scan_vertices(buf, start, stop, *_VERTEX_WORDS, POW5)
    if not ok or end != stop:
        return None
    return _fill_spans(xml, values, spans)


def _fill_spans(xml: bytes, values: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """The numbers the scanner left (NaN, at ``spans``) converted as
    :func:`_plain_numbers` converts them."""
    if len(spans):
        nan = np.flatnonzero(np.isnan(values))  # in order, one per span
        values[nan] = np.array([xml[a:b] for a, b in spans], dtype=np.float64)
    return values


def _strict_meshes(xml: bytes, buf: np.ndarray
                   ) -> tuple[list[Body], list[tuple[int, int]]] | None:
    """What :func:`_fast_meshes` gives, and the span of each mesh element, for documents
    whose every <mesh> holds exactly what this module writes: whitespace, <vertices> of
    plain vertex elements, whitespace, <triangles> of plain triangle elements, whitespace.
    Each mesh is scanned once (no searches through the whole document for its closing
    tags); None for anything else (then :func:`_fast_meshes` goes on)."""
    out: list[Body] = []
    spans: list[tuple[int, int]] = []
    n_tags = 0  # "<mesh" in the document, as _fast_meshes counts them
    pos = 0
    while True:
        i = xml.find(b"<mesh>", pos)
        if i < 0:
            n_tags += xml.count(b"<mesh", pos)
            break
        n_tags += xml.count(b"<mesh", pos, i) + 1
        k = skip_space(buf, i + len(b"<mesh>"), len(xml))
        if not xml.startswith(b"<vertices>", k):
            return None
        v, v_spans, end, ok = scan_vertices(buf, k + len(b"<vertices>"), len(xml),
                                            *_VERTEX_WORDS, POW5)
        if not ok or not xml.startswith(b"</vertices>", end):
            return None
        k = skip_space(buf, end + len(b"</vertices>"), len(xml))
        if not xml.startswith(b"<triangles>", k):
            return None
        f, end, ok = scan_triangles(buf, k + len(b"<triangles>"), len(xml), *_TRIANGLE_WORDS)
        if not ok or not xml.startswith(b"</triangles>", end):
            return None
        k = skip_space(buf, end + len(b"</triangles>"), len(xml))
        if not xml.startswith(b"</mesh>", k):
            return None
        pos = k + len(b"</mesh>")
        spans.append((i, pos))
        out.append((_fill_spans(xml, v, v_spans).reshape(-1, 3), f.reshape(-1, 3)))
    return (out, spans) if len(out) == n_tags else None


def _fast_meshes(xml: bytes) -> tuple[list[Body], list[tuple[int, int]] | None] | None:
    """Vertices and triangles of each <mesh> element, in document order, parsed without
    building an element tree, and where the mesh elements are (None: not known); None
    unless every mesh, vertex and triangle element has the plain form this module (and most
    slicers) write: then the general parser is used.

    The numba scanners of :mod:`jampacked.export.xmlmesh` read the strict form this module
    writes (:func:`_strict_meshes`); other spacing or attribute order falls back to
    :func:`_plain_numbers`."""
    buf = np.frombuffer(xml, np.uint8)
    strict = _strict_meshes(xml, buf)
    if strict is not None:
        return strict
    out: list[Body] = []
    n_meshes = xml.count(b"<mesh")
    pos = 0
    while True:
        mesh = _element_span(xml, b"mesh", pos, len(xml))
        if mesh is None:
            break
        m0, m1, pos = mesh
        vs = _element_span(xml, b"vertices", m0, m1)
        ts = _element_span(xml, b"triangles", m0, m1)
        if vs is None or ts is None:
            return None
        v = _scanned_vertices(xml, buf, vs[0], vs[1])
        if v is None:
            v = _plain_numbers(xml[vs[0]:vs[1]], b"vertex", (b"x", b"y", b"z"))
        f_int, end, ok = scan_triangles(buf, ts[0], ts[1], *_TRIANGLE_WORDS)
        if ok and end == ts[1]:
            f = f_int
        else:
            f = _plain_numbers(xml[ts[0]:ts[1]], b"triangle", (b"v1", b"v2", b"v3"))
            if f is not None and np.any(f != np.floor(f)):
                return None
        if v is None or f is None:
            return None
        out.append((v.reshape(-1, 3), f.astype(np.int64, copy=False).reshape(-1, 3)))
    return (out, None) if len(out) == n_meshes else None


def _strip_meshes(xml: bytes, spans: list[tuple[int, int]] | None = None) -> bytes:
    """The document with every <mesh>...</mesh> emptied (to parse only its structure);
    ``spans``: where the mesh elements are, if known."""
    if spans is None:
        spans = []
        pos = 0
        while True:
            i = xml.find(b"<mesh>", pos)
            if i < 0:
                break
            pos = xml.find(b"</mesh>", i) + len(b"</mesh>")
            spans.append((i, pos))
    parts = []
    pos = 0
    for i, j in spans:
        parts.append(xml[pos:i] + b"<mesh/>")
        pos = j
    parts.append(xml[pos:])
    return b"".join(parts)


def _read_3mf(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """All build items of a 3MF package (root model only), transforms applied."""
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        names = archive.namelist()
        model_name = next((n for n in names if n.lower() == "3d/3dmodel.model"), None)
        if model_name is None:
            model_name = next(n for n in names if n.lower().endswith(".model"))
        xml = archive.read(model_name)
    fast = _fast_meshes(xml)
    if fast is not None:
        # parse the structure without the mesh bodies (the bulk of the file)
        it = iter(fast[0])
        xml = _strip_meshes(xml, fast[1])
    root = ElementTree.fromstring(xml)
    ns = root.tag[1:].split("}")[0] if root.tag.startswith("{") else ""

    def q(tag: str) -> str:
        return f"{{{ns}}}{tag}" if ns else tag

    meshes: dict[str, Body] = {}
    components: dict[str, list[tuple[str, np.ndarray]]] = {}
    resources = root.find(q("resources"))
    for obj in (resources if resources is not None else []):
        if obj.tag != q("object"):
            continue
        oid = obj.get("id")
        mesh = obj.find(q("mesh"))
        if mesh is not None and fast is not None:
            meshes[oid] = next(it)
        elif mesh is not None:
            vs = mesh.find(q("vertices"))
            ts = mesh.find(q("triangles"))
            v = np.array([[float(e.get("x")), float(e.get("y")), float(e.get("z"))]
                          for e in (vs if vs is not None else [])], dtype=np.float64)
            f = np.array([[int(e.get("v1")), int(e.get("v2")), int(e.get("v3"))]
                          for e in (ts if ts is not None else [])], dtype=np.int64)
            meshes[oid] = (v.reshape(-1, 3), f.reshape(-1, 3))
        comps = obj.find(q("components"))
        if comps is not None:
            components[oid] = [(c.get("objectid"), _matrix(c.get("transform")))
                               for c in comps if c.tag == q("component")]

    out_v: list[np.ndarray] = []
    out_f: list[np.ndarray] = []
    offset = 0

    def emit(oid: str, transform: np.ndarray, depth: int) -> None:
        nonlocal offset
        if depth > 32:
            raise ValueError("components nest more than 32 deep (a cycle?)")
        if oid in meshes:
            v, f = meshes[oid]
            if np.array_equal(transform, np.eye(4)) and np.all(np.isfinite(v)):
                # what the product with the identity gives for finite numbers (-0.0 -> 0.0)
                out_v.append(v + 0.0)
            else:
                out_v.append(v @ transform[:3, :3].T + transform[:3, 3])
            out_f.append(f + offset)
            offset += len(v)
        for child, m in components.get(oid, []):
            emit(child, transform @ m, depth + 1)

    build = root.find(q("build"))
    for item in (build if build is not None else []):
        if item.tag == q("item"):
            emit(item.get("objectid"), _matrix(item.get("transform")), 0)
    if not out_f:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    if len(out_f) == 1:  # already new arrays
        return out_v[0], out_f[0]
    return np.concatenate(out_v), np.concatenate(out_f)


# --------------------------------------------------------------------------------------------
# writing


def _as_bodies(vertices: object, faces: object) -> list[Body]:
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


def _encode_3mf(bodies: Sequence[Body], names: Sequence[str] | None) -> bytes:
    parts = [
        '<?xml version="1.0" encoding="UTF-8"?>\n',
        f'<model unit="millimeter" xml:lang="en-US" xmlns="{_3MF_CORE}">\n<resources>\n',
    ]
    for k, (v, f) in enumerate(bodies):
        name = quoteattr(str(names[k]) if names is not None else f"body {k + 1}")
        parts.append(f'<object id="{k + 1}" type="model" name={name}>\n<mesh>\n<vertices>\n')
        # repr-exact float64 text (numpy prints the shortest round-trip digits)
        parts.append("".join(f'<vertex x="{x!r}" y="{y!r}" z="{z!r}"/>\n'
                             for x, y, z in v.tolist()))
        parts.append("</vertices>\n<triangles>\n")
        parts.append("".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>\n'
                             for a, b, c in f.tolist()))
        parts.append("</triangles>\n</mesh>\n</object>\n")
    parts.append("</resources>\n<build>\n")
    parts += [f'<item objectid="{k + 1}"/>\n' for k in range(len(bodies))]
    parts.append("</build>\n</model>\n")
    buffer = io.BytesIO()
    # level 1: a quarter of level 6's time on big meshes for a file ~25% larger
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED,
                         compresslevel=1) as archive:
        archive.writestr("[Content_Types].xml", _3MF_CONTENT_TYPES)
        archive.writestr("_rels/.rels", _3MF_RELS)
        archive.writestr("3D/3dmodel.model", "".join(parts))
    return buffer.getvalue()


def _encode(ext: str, bodies: Sequence[Body], names: Sequence[str] | None) -> bytes:
    if ext == "3mf":
        return _encode_3mf(bodies, names)
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
    bodies)`` with a list of ``(vertices, faces)`` bodies (3MF: one object each).

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
    validated and renamed over ``path`` with :func:`os.replace`; on any failure the temporary
    file is removed and ``path`` is left as it was.
    """
    path_str = os.fspath(path)
    ext = _extension(path_str)
    if ext not in WRITE_FORMATS:
        raise InputError(f"cannot write '{path_str}': unknown mesh format '.{ext}'; use one "
                         f"of {', '.join('.' + e for e in WRITE_FORMATS)}.")
    for p in protect:
        if _same_file(path_str, os.fspath(p)):
            raise InputError(f"refusing to write '{path_str}': it is an input file "
                             f"('{os.fspath(p)}'); choose another output name.")
    bodies = _as_bodies(vertices, faces)
    if names is not None and len(names) != len(bodies):
        raise InputError(f"{len(names)} names for {len(bodies)} bodies writing '{path_str}': "
                         "give one name per body.")
    folder = os.path.dirname(os.path.abspath(path_str))
    if not os.path.isdir(folder):
        raise MeshError(f"cannot write '{path_str}': the folder '{folder}' does not exist; "
                        "create it first.")
    if os.path.isdir(path_str):
        raise MeshError(f"cannot write '{path_str}': it is a folder; give a file name.")
    data = _encode(ext, bodies, names)

    # a hidden name in the same folder, ending in the real extension so it reads back
    tmp = os.path.join(folder, f".{Path(path_str).name}.{secrets.token_hex(4)}.tmp.{ext}")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                     0o666)  # the umask applies, as for a plain open()
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        report = None
        if validate:
            try:
                report = replace(validate_file(tmp), path=path_str)
            except MeshError as exc:
                raise MeshError(f"the mesh written to '{path_str}' cannot be read back, so it "
                                f"was not saved ({exc}). This is a bug in the export; please "
                                "report it.") from exc
            if require_valid and not report.passed:
                raise MeshError(f"the mesh written to '{path_str}' is not watertight, so it "
                                f"was not saved: {report.summary()}. This is a bug in the "
                                "export or in its input meshes; please report it.")
        os.replace(tmp, path_str)
    except OSError as exc:
        raise MeshError(f"cannot write '{path_str}' ({exc.strerror or exc}): check the "
                        "folder's permissions and free space.") from exc
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
    return report

